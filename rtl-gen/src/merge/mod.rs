//! Generators of the hierarchy merging module (issue 5; SPEC.md section 8,
//! "Merging module RTL"): each stage a module with ready/valid streams whose
//! beat formats are defined by `golden::merge::unit` and whose widths come
//! from `golden::params` / `golden::layout` only.
//!
//! - [`merge_level_unit`]: S614 (unit 506), merged nodes at the merging level.
//! - [`overlap_counter_unit`]: S608's overlap counts and threshold (unit 508).
//! - [`upper_level_unit`]: S616, one level up (grouping by parent voxel).
//! - [`root_sorter_unit`]: Morton order of an input's translated roots.

mod fields;
mod level;
mod overlap;
mod sorter;
mod upper;

pub use level::{merge_level_name, merge_level_unit};
pub use overlap::{overlap_counter_name, overlap_counter_unit};
pub use sorter::{root_sorter_name, root_sorter_unit};
pub use upper::{upper_level_name, upper_level_unit};

use std::path::{Path, PathBuf};

use crate::{write_design, DesignError, Module};

/// The merging module's configuration (grid parameters, inputs, overlap
/// threshold, root-sorter capacity) is golden's [`MergeDesign`](golden::vectors::merge::MergeDesign): the one
/// definition the vectors, the generators and the harness share.
pub use golden::vectors::merge::MergeDesign as MergeConfig;

/// Every merging-module stage for `c`, top modules in a fixed order.
pub fn merge_units(c: &MergeConfig) -> Vec<Module> {
    vec![
        merge_level_unit(&c.params),
        overlap_counter_unit(&c.params, c.inputs, c.num, c.den),
        upper_level_unit(&c.params),
        root_sorter_unit(&c.params, c.roots),
    ]
}

/// Writes the Verilog of every merging-module stage for `c` into `dir`
/// (one `<module>.v` per module); returns the files written.
pub fn emit_merge(c: &MergeConfig, dir: &Path) -> Result<Vec<PathBuf>, DesignError> {
    let mut files = Vec::new();
    for m in merge_units(c) {
        files.extend(write_design(&m, dir)?);
    }
    Ok(files)
}
