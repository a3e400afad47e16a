//! The voxel-aligned translation `T = (L, tx, ty, tz)` and its signed field.

use serde::{Deserialize, Serialize};

use super::error::{Axis, TranslateError};
use crate::params::Params;

/// Width of one signed translation component: `D + 1` bits, two's complement.
///
/// At level `L` a hierarchy that stays in the scene moves by at most
/// `2^L - 1` voxels; `L <= D`, so `D + 1` bits hold every useful value at
/// every level. Components are kept symmetric, `|t| <= 2^D - 1`: the most
/// negative code `-2^D` is never produced and is refused when read.
pub fn trans_bits(p: &Params) -> u32 {
    p.max_lod as u32 + 1
}

/// Largest magnitude of a translation component: `2^D - 1`.
pub fn trans_max(p: &Params) -> i64 {
    (1i64 << p.max_lod) - 1
}

/// A voxel-aligned translation: every node at LOD `d >= lod` moves by
/// `t[axis] * 2^(d - lod)` voxels, i.e. by `t[axis] * 2^(D - lod)` grid units.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Translation {
    /// `L`: the level whose voxel edge is the unit of `t`.
    pub lod: u8,
    /// `(tx, ty, tz)` in LOD-`L` voxels.
    pub t: [i64; 3],
}

impl Translation {
    /// A translation by zero voxels at LOD `lod`.
    pub fn zero(lod: u8) -> Translation {
        Translation { lod, t: [0; 3] }
    }

    /// Checks `L <= D` and every component within the signed field.
    pub fn validate(&self, p: &Params) -> Result<(), TranslateError> {
        if self.lod > p.max_lod {
            return Err(TranslateError::LodAboveMax {
                lod: self.lod,
                max_lod: p.max_lod,
            });
        }
        for axis in Axis::ALL {
            let v = self.t[axis.index()];
            if v.unsigned_abs() > trans_max(p) as u64 {
                return Err(TranslateError::TranslationOutOfField {
                    axis,
                    value: v,
                    field_bits: trans_bits(p),
                });
            }
        }
        Ok(())
    }

    /// The move on `axis` in grid units: `t << (D - L)` (exact: below 2^62).
    /// For a valid translation (table entries and determine results are);
    /// see [`Translation::try_grid_offset`] for one of unknown origin.
    pub fn grid_offset(&self, axis: Axis, p: &Params) -> i64 {
        debug_assert!(
            self.validate(p).is_ok(),
            "grid_offset of an invalid translation"
        );
        // Saturating: an invalid translation gives a meaningless value, never a panic.
        self.t[axis.index()].saturating_mul(1i64 << p.max_lod.saturating_sub(self.lod).min(62))
    }

    /// [`Translation::grid_offset`], checking the translation first.
    pub fn try_grid_offset(&self, axis: Axis, p: &Params) -> Result<i64, TranslateError> {
        self.validate(p)?;
        Ok(self.grid_offset(axis, p))
    }
}

/// The `D+1`-bit two's-complement code of a component (as the ports carry it).
pub fn encode_component(v: i64, p: &Params) -> u64 {
    (v as u64) & ((1u64 << trans_bits(p)) - 1)
}

/// Reads a `D+1`-bit two's-complement code; bits above the field or the
/// unused code `-2^D` are errors.
pub fn decode_component(axis: Axis, code: u64, p: &Params) -> Result<i64, TranslateError> {
    let w = trans_bits(p);
    let out_of_field = |value| TranslateError::TranslationOutOfField {
        axis,
        value,
        field_bits: w,
    };
    if code >> w != 0 {
        return Err(out_of_field(code as i64));
    }
    // Sign-extend from bit w-1.
    let v = ((code << (64 - w)) as i64) >> (64 - w);
    if v.unsigned_abs() > trans_max(p) as u64 {
        return Err(out_of_field(v));
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn component_codes_round_trip_and_refuse_the_unused_code() {
        let p = Params::new(31, 8, 24, 4).unwrap();
        assert_eq!(trans_bits(&p), 32);
        for v in [0i64, 1, -1, (1 << 31) - 1, -((1 << 31) - 1), -12345] {
            let c = encode_component(v, &p);
            assert!(c < 1 << 32);
            assert_eq!(decode_component(Axis::Y, c, &p), Ok(v));
        }
        assert!(decode_component(Axis::X, 1 << 31, &p).is_err());
        assert!(decode_component(Axis::X, 1 << 32, &p).is_err());
        let p = Params::new(3, 0, 8, 1).unwrap();
        assert_eq!(encode_component(-1, &p), 0b1111);
        assert_eq!(decode_component(Axis::Z, 0b1001, &p), Ok(-7));
    }
}
