//! The parameters of a hierarchy unit, defined once.
//!
//! Every width in the project (node-record fields, RTL ports, test-vector
//! fields) is derived from a [`Params`] by the functions here and in
//! [`crate::layout`]. Nothing else restates a width.

use serde::{Deserialize, Serialize};
use std::fmt;

/// Deepest LOD the grid may have (SPEC 1: `max_lod` in 1..=31).
pub const MAX_LOD_LIMIT: u8 = 31;
/// Most bits per quantized box bound (`quant_bits` in 0..=16).
pub const QUANT_BITS_LIMIT: u8 = 16;
/// Most bits of a node or primitive index.
pub const INDEX_BITS_LIMIT: u8 = 32;
/// Most bits of a hierarchy id.
pub const HIER_BITS_LIMIT: u8 = 8;

/// The parameters that fix the grid and the node-record layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Params {
    /// `D`: the deepest level of the octree. A voxel at LOD `d` has edge
    /// `2^(D-d)` grid units; LOD 0 is the whole scene.
    pub max_lod: u8,
    /// `Q`: bits per quantized box bound per axis; 0 means the box is the voxel.
    pub quant_bits: u8,
    /// Bits of a node index, a reference index or a primitive index.
    pub index_bits: u8,
    /// Bits of a hierarchy id (input hierarchies and merged ones share the space).
    pub hier_bits: u8,
}

impl Default for Params {
    fn default() -> Self {
        Params {
            max_lod: 16,
            quant_bits: 8,
            index_bits: 24,
            hier_bits: 4,
        }
    }
}

/// A parameter outside its legal range.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParamError {
    /// The parameter: `max_lod`, `quant_bits`, `index_bits` or `hier_bits`.
    pub field: &'static str,
    /// The value given.
    pub value: u64,
    /// The legal range, e.g. `1..=31`.
    pub expected: String,
}

impl fmt::Display for ParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "parameter `{}` = {} is out of range: expected {}",
            self.field, self.value, self.expected
        )
    }
}

impl std::error::Error for ParamError {}

impl Params {
    /// Builds and validates a parameter set.
    pub fn new(
        max_lod: u8,
        quant_bits: u8,
        index_bits: u8,
        hier_bits: u8,
    ) -> Result<Params, ParamError> {
        let p = Params {
            max_lod,
            quant_bits,
            index_bits,
            hier_bits,
        };
        p.validate()?;
        Ok(p)
    }

    /// Checks every field against its legal range.
    pub fn validate(&self) -> Result<(), ParamError> {
        check_range("max_lod", self.max_lod, 1, MAX_LOD_LIMIT)?;
        check_range("quant_bits", self.quant_bits, 0, QUANT_BITS_LIMIT)?;
        check_range("index_bits", self.index_bits, 1, INDEX_BITS_LIMIT)?;
        check_range("hier_bits", self.hier_bits, 1, HIER_BITS_LIMIT)?;
        Ok(())
    }

    /// The parameters as a short name for modules and files:
    /// `d16_q8_i24_h4` (`D`, `Q`, index bits, hierarchy-id bits).
    pub fn tag(&self) -> String {
        format!(
            "d{}_q{}_i{}_h{}",
            self.max_lod, self.quant_bits, self.index_bits, self.hier_bits
        )
    }

    /// Bits of a LOD field: enough to hold `0..=D`.
    pub fn lod_bits(&self) -> u32 {
        bits_to_hold(self.max_lod as u64)
    }

    /// Bits of one voxel coordinate: `D` (a LOD-`D` coordinate is below `2^D`).
    pub fn coord_bits(&self) -> u32 {
        self.max_lod as u32
    }

    /// Edge of a LOD-`d` voxel in grid units: `2^(D-d)`.
    pub fn voxel_edge(&self, lod: u8) -> u64 {
        debug_assert!(lod <= self.max_lod);
        1u64 << (self.max_lod - lod)
    }

    /// Edge of the whole scene cube in grid units: `2^D`.
    pub fn scene_edge(&self) -> u64 {
        1u64 << self.max_lod
    }

    /// Number of quantization cells per voxel edge: `2^Q`.
    pub fn quant_cells(&self) -> u32 {
        1u32 << self.quant_bits
    }

    /// Largest hierarchy id plus one.
    pub fn hier_capacity(&self) -> u64 {
        1u64 << self.hier_bits
    }

    /// Largest index plus one.
    pub fn index_capacity(&self) -> u64 {
        1u64 << self.index_bits
    }
}

/// Bits needed to hold every value in `0..=max`. At least 1.
pub fn bits_to_hold(max: u64) -> u32 {
    (64 - max.leading_zeros()).max(1)
}

fn check_range(field: &'static str, value: u8, lo: u8, hi: u8) -> Result<(), ParamError> {
    if value < lo || value > hi {
        return Err(ParamError {
            field,
            value: value as u64,
            expected: format!("{lo}..={hi}"),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derived_widths() {
        let p = Params::new(31, 16, 32, 8).unwrap();
        assert_eq!(p.lod_bits(), 5);
        assert_eq!(p.coord_bits(), 31);
        assert_eq!(p.voxel_edge(0), 1 << 31);
        assert_eq!(p.voxel_edge(31), 1);
        let p = Params::new(1, 0, 1, 1).unwrap();
        assert_eq!(p.lod_bits(), 1);
        assert_eq!(p.quant_cells(), 1);
    }

    #[test]
    fn out_of_range_is_an_error_naming_the_field() {
        let e = Params::new(32, 8, 24, 4).unwrap_err();
        assert_eq!(e.field, "max_lod");
        assert!(e.to_string().contains("1..=31"));
        assert_eq!(Params::new(16, 17, 24, 4).unwrap_err().field, "quant_bits");
        assert_eq!(Params::new(16, 8, 0, 4).unwrap_err().field, "index_bits");
        assert_eq!(Params::new(16, 8, 24, 9).unwrap_err().field, "hier_bits");
    }

    #[test]
    fn bits_to_hold_edges() {
        assert_eq!(bits_to_hold(0), 1);
        assert_eq!(bits_to_hold(1), 1);
        assert_eq!(bits_to_hold(2), 2);
        assert_eq!(bits_to_hold(31), 5);
        assert_eq!(bits_to_hold(32), 6);
        assert_eq!(bits_to_hold(u64::MAX), 64);
    }
}
