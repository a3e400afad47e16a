//! Errors of the translation unit. Each names what was wrong and where: the
//! axis, the value, the range it had to lie in.

use std::fmt;

use crate::params::ParamError;

/// One of the three grid axes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Axis {
    /// The x axis, index 0.
    X,
    /// The y axis, index 1.
    Y,
    /// The z axis, index 2.
    Z,
}

impl Axis {
    /// The axes in the order every per-axis loop visits them (x, y, z).
    pub const ALL: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];

    /// Index of the axis in `[x, y, z]` arrays.
    pub fn index(self) -> usize {
        self as usize
    }
}

impl fmt::Display for Axis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Axis::X => "x",
            Axis::Y => "y",
            Axis::Z => "z",
        })
    }
}

/// Everything the translation unit can refuse.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TranslateError {
    /// The placement on `axis` is a NaN (`bits` is the raw encoding).
    NotANumber {
        /// The first axis at fault (x, y, z order).
        axis: Axis,
        /// The placement's raw encoding on that axis.
        bits: u64,
    },
    /// The placement on `axis` is an infinity.
    Infinite {
        /// The first axis at fault (x, y, z order).
        axis: Axis,
        /// True for negative infinity.
        negative: bool,
    },
    /// A binary32 placement given in a 64-bit field had bits set above bit 31.
    PlacementTooWide {
        /// The first axis at fault (x, y, z order).
        axis: Axis,
        /// The 64-bit placement field as given.
        bits: u64,
    },
    /// `round(p / 2^(D-L))` on `axis` does not fit the signed translation
    /// field (`field_bits` bits, magnitude at most `2^(field_bits-1) - 1`).
    /// `bits` is the placement's encoding: the rounded value may not even fit
    /// in 64 bits, so it is not restated.
    TranslationTooLarge {
        /// The first axis at fault (x, y, z order).
        axis: Axis,
        /// The placement's raw encoding on that axis.
        bits: u64,
        /// Width of the signed translation field, `D + 1` (SPEC 7.3).
        field_bits: u32,
    },
    /// A translation component outside the signed field (for a translation
    /// built by hand, read from a record or written to the table).
    TranslationOutOfField {
        /// The component's axis.
        axis: Axis,
        /// The component; for a code with bits above the field, the raw code.
        value: i64,
        /// Width of the signed translation field, `D + 1` (SPEC 7.3).
        field_bits: u32,
    },
    /// The translation level `L` is deeper than the grid (`L > D`).
    LodAboveMax {
        /// The LOD asked for: a translation level, or the LOD of extents.
        lod: u8,
        /// `D`, the deepest LOD of the grid.
        max_lod: u8,
    },
    /// The hierarchy extents are given at a LOD other than the translation level.
    ExtentsLodMismatch {
        /// The LOD the extents are given at.
        extents_lod: u8,
        /// The translation level `L`.
        lod: u8,
    },
    /// Hierarchy extents that are not a voxel range at their LOD
    /// (`lo > hi`, or `hi >= 2^lod`).
    BadExtents {
        /// The first axis at fault (x, y, z order).
        axis: Axis,
        /// The lowest voxel of the extents on that axis.
        lo: u32,
        /// The highest voxel of the extents on that axis (inclusive).
        hi: u32,
        /// The LOD of the extents.
        lod: u8,
    },
    /// Extents asked of an empty node list.
    NoNodes,
    /// The scene-extents rule: the translated voxel range `[lo, hi]` at LOD
    /// `lod` leaves `[0, 2^lod)` on `axis`.
    OutsideScene {
        /// The first failing axis (x, y, z order).
        axis: Axis,
        /// `lo + t`: the translated lowest voxel, at LOD `lod`.
        lo: i64,
        /// `hi + t`: the translated highest voxel, at LOD `lod`.
        hi: i64,
        /// The translation level `L`.
        lod: u8,
    },
    /// A node address that is not a voxel of the grid.
    InvalidNode {
        /// The node's LOD.
        lod: u8,
        /// The node's x coordinate, in LOD-`lod` voxels.
        x: u32,
        /// The node's y coordinate, in LOD-`lod` voxels.
        y: u32,
        /// The node's z coordinate, in LOD-`lod` voxels.
        z: u32,
    },
    /// A box cell bound outside `0..2^Q`, or `lo > hi`.
    InvalidBox {
        /// The first axis at fault (x, y, z order).
        axis: Axis,
        /// The lowest cell on that axis.
        lo: u32,
        /// The highest cell on that axis (inclusive).
        hi: u32,
        /// Q: cells run `0..2^Q`.
        quant_bits: u8,
    },
    /// The translated node coordinate `value` at LOD `lod` leaves `[0, 2^lod)`.
    NodeOutsideScene {
        /// The first failing axis (x, y, z order).
        axis: Axis,
        /// The translated coordinate, not wrapped.
        value: i64,
        /// The node's LOD `d`.
        lod: u8,
    },
    /// The translated box `[lo, hi]` (fine units, SPEC section 3) leaves the
    /// scene `[0, limit]` on `axis`.
    BoxOutsideScene {
        /// The first failing axis (x, y, z order).
        axis: Axis,
        /// `a'`, the moved box's minimum, in fine units.
        lo: i128,
        /// `b'`, the moved box's maximum, in fine units.
        hi: i128,
        /// `2^(D+Q)`, the scene's edge in fine units.
        limit: i128,
    },
    /// The aligned unit cannot move a node above the translation level
    /// (`d < L`) without splitting it: see the expanding variant.
    AboveTranslationLevel {
        /// The node's LOD `d`.
        node_lod: u8,
        /// The translation level `L`.
        translation_lod: u8,
    },
    /// A table depth outside `1..=2^H`.
    BadTableDepth {
        /// The depth asked for.
        depth: usize,
        /// `2^H`, the number of hierarchy ids.
        max: u64,
    },
    /// A hierarchy id at or beyond the table depth.
    IdOutOfRange {
        /// The hierarchy id.
        id: u32,
        /// The table's depth; ids run `0..depth`.
        depth: usize,
    },
    /// A table read of an entry that holds no translation.
    EmptyEntry {
        /// The hierarchy id read.
        id: u32,
    },
    /// A packed value with bits set at or above its width.
    PackedTooWide {
        /// The value or port, e.g. `"read_id"` or `"translation table entry"`.
        what: &'static str,
        /// The width it had to fit, in bits (0 for a port the design lacks).
        width: u32,
    },
    /// The unit's parameters are out of range.
    BadParams(ParamError),
}

impl fmt::Display for TranslateError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use TranslateError::*;
        match self {
            NotANumber { axis, bits } => {
                write!(f, "placement {axis} is NaN (bits {bits:#x}): expected a finite number")
            }
            Infinite { axis, negative } => write!(
                f,
                "placement {axis} is {}infinity: expected a finite number",
                if *negative { "-" } else { "+" }
            ),
            PlacementTooWide { axis, bits } => write!(
                f,
                "placement {axis} bits {bits:#x} set bits above bit 31: expected a binary32 encoding"
            ),
            TranslationTooLarge { axis, bits, field_bits } => write!(
                f,
                "placement {axis} (bits {bits:#x}) rounds to a translation beyond the {field_bits}-bit signed field: expected |t| <= 2^{} - 1",
                field_bits - 1
            ),
            TranslationOutOfField { axis, value, field_bits } => write!(
                f,
                "translation {axis} = {value} is outside the {field_bits}-bit signed field: expected |t| <= 2^{} - 1",
                field_bits - 1
            ),
            LodAboveMax { lod, max_lod } => {
                write!(f, "translation LOD {lod} is deeper than max_lod {max_lod}: expected 0..={max_lod}")
            }
            ExtentsLodMismatch { extents_lod, lod } => write!(
                f,
                "hierarchy extents are at LOD {extents_lod}: expected the translation LOD {lod}"
            ),
            BadExtents { axis, lo, hi, lod } => write!(
                f,
                "hierarchy extents {axis} = [{lo}, {hi}] at LOD {lod}: expected lo <= hi < 2^{lod}"
            ),
            NoNodes => write!(f, "hierarchy extents of an empty node list: expected at least one node"),
            OutsideScene { axis, lo, hi, lod } => write!(
                f,
                "translated hierarchy {axis} range [{lo}, {hi}] at LOD {lod} leaves the scene: expected inside [0, 2^{lod} - 1]"
            ),
            InvalidNode { lod, x, y, z } => write!(
                f,
                "node ({lod}, {x}, {y}, {z}) is not a voxel of the grid: expected coordinates below 2^lod and lod <= max_lod"
            ),
            InvalidBox { axis, lo, hi, quant_bits } => write!(
                f,
                "box {axis} cells [{lo}, {hi}]: expected lo <= hi < 2^{quant_bits}"
            ),
            NodeOutsideScene { axis, value, lod } => write!(
                f,
                "translated node {axis} = {value} at LOD {lod} leaves the scene: expected 0 <= {axis} < 2^{lod}"
            ),
            BoxOutsideScene { axis, lo, hi, limit } => write!(
                f,
                "translated box {axis} = [{lo}, {hi}] (fine units) leaves the scene: expected inside [0, {limit}]"
            ),
            AboveTranslationLevel { node_lod, translation_lod } => write!(
                f,
                "node at LOD {node_lod} is above the translation LOD {translation_lod}: the aligned unit moves only nodes with LOD >= {translation_lod} (use the expanding variant)"
            ),
            BadTableDepth { depth, max } => {
                write!(f, "translation table depth {depth}: expected 1..={max} (2^hier_bits)")
            }
            IdOutOfRange { id, depth } => write!(
                f,
                "hierarchy id {id} is outside the translation table: expected 0..{depth}"
            ),
            EmptyEntry { id } => write!(
                f,
                "translation table entry {id} holds no translation: expected a written entry"
            ),
            PackedTooWide { what, width } => {
                write!(f, "{what} has bits set at or above bit {width}: expected a {width}-bit value")
            }
            BadParams(e) => write!(f, "translation unit: {e}"),
        }
    }
}

impl std::error::Error for TranslateError {}
