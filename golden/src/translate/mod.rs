//! The translation unit (FIG. 15, claims 1-20, paragraphs 71-91; SPEC.md
//! section 7).
//!
//! A hierarchy is built in its own local grid coordinates and placed in the
//! scene by a voxel-aligned translation `T = (L, tx, ty, tz)`:
//! - [`determine()`]: from an IEEE-754 placement, `t = round_half_even(p / 2^(D-L))`
//!   exactly from the encoding's bits, the exact residual, the scene-extents
//!   rule ([`extents`]);
//! - [`table`]: the translation table indexed by hierarchy id;
//! - [`apply`]: the aligned move of a node at `d >= L`;
//! - [`expand`]: the expanding variant for finer translations, and its cost;
//! - [`records`]: the same on hierarchy-store records and whole hierarchies;
//! - [`stimulus`]: hard cases and seeded random transactions for vectors;
//! - [`mod@unit`]: the RTL-facing transaction (ports, flags) shared with the
//!   vector writer and the RTL generator.

pub mod apply;
pub mod determine;
pub mod error;
pub mod expand;
pub mod extents;
pub mod float;
pub mod model;
pub mod records;
pub mod stimulus;
pub mod table;
pub mod translation;
pub mod unit;

pub use apply::translate_node;
pub use determine::{determine, round_placement, Determined, Placement};
pub use error::{Axis, TranslateError};
pub use expand::{
    expand_node, expand_voxel, expansion_cost, expansion_cost_voxels, ExpansionCost, NodeBox,
};
pub use extents::{check_scene_extents, VoxelRange};
pub use float::Format;
pub use records::{hierarchy_expansion_cost, hierarchy_extents, translate_record};
pub use table::TranslationTable;
pub use translation::{trans_bits, Translation};
pub use unit::{
    TranslateInputs, TranslateOutputs, TranslateRecord, TranslateUnit, TranslateUnitConfig,
};
