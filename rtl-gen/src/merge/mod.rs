//! Generators of the hierarchy merging module (issue 5; SPEC.md section 8,
//! "Merging module RTL"): each stage a module with ready/valid streams whose
//! beat formats are defined by `golden::merge` (each unit beside its golden model: the same module names) and whose widths come
//! from `golden::params` / `golden::layout` only.
//!
//! - [`merge_level_unit`]: S614 (unit 506), merged nodes at the merging level.
//! - [`overlap_counter_unit`]: S608's overlap counts and threshold (unit 508).
//! - [`upper_level_unit`]: S616, one level up (grouping by parent voxel).
//! - [`root_sorter_unit`]: Morton order of an input's translated roots.
//! - [`morton_merge_unit`]: the k-way Morton merge of the inputs' streams.
//! - [`merge_module_unit`]: the merging module as one unit: `cfg`, `k`
//!   input streams, `report`, `out` around the merge network, the overlap
//!   counter (overlap mode only) and S614, with the mode's level choice.
//! - [`per_node_module_unit`]: the merging module of a `per-node:N/D`
//!   configuration (what `merge_module_unit` builds for it): breadth-first
//!   LOD passes through a probe-aware merge network, the per-node decider
//!   and S614 (SPEC 8.14).
//! - [`fetcher_unit`]: S610 + S612 for one input: walks it in the store
//!   (node and reference read ports), translating, into an input stream.
//! - [`fetcher_per_node_unit`]: the fetcher with the per-node command (the
//!   per-node module's input stream of one input, pass after pass, from the
//!   module's `report`; a `probe` read port), built only for per-node
//!   merging (SPEC 8.13).
//! - [`upper_builder_unit`]: every S616 level above the base at once (a
//!   chain of grouping and Morton-merge stages, the top rule in flight).
//! - [`record_writer_unit`]: S618, the merged hierarchy's records,
//!   references and header from the builder's levels (buffered per level,
//!   one level module instance each).
//! - [`hierarchy_merger_unit`]: S610-S618 as one top module: `k` fetchers,
//!   the merging module, the upper builder and the record writer, with the
//!   controller, the routing of S614's out and the leaf FIFOs (SPEC 8.15).

mod fetcher;
mod hierarchy_unit;
mod level_choice;
mod merge_level;
mod merge_module;
mod merger;
mod network;
mod per_node;
mod record_writer;
mod upper_builder;

pub use fetcher::{
    fetcher_name, fetcher_per_node_name, fetcher_per_node_unit, fetcher_prefetch_phases,
    fetcher_unit,
};
pub use fetcher::{root_sorter_name, root_sorter_unit};
pub use hierarchy_unit::{hierarchy_unit, hierarchy_unit_name, HierarchyUnitConfig};
pub use level_choice::{overlap_counter_name, overlap_counter_unit};
pub use merge_level::{merge_level_name, merge_level_unit};
pub use merge_module::{merge_module_name, merge_module_unit};
pub use merger::{
    hierarchy_merger_name, hierarchy_merger_unit, store_port_name, store_port_unit, MergerConfig,
    StorePortConfig,
};
pub use network::{morton_code, morton_merge_name, morton_merge_unit};
pub use per_node::{
    per_node_decider_name, per_node_decider_unit, per_node_module_unit, per_node_network_name,
    per_node_network_unit,
};
pub use record_writer::{
    record_writer_buffers, record_writer_level_name, record_writer_name, record_writer_unit,
    WriterBuffer,
};
pub use upper_builder::{upper_builder_name, upper_builder_unit};
pub use upper_builder::{upper_level_name, upper_level_unit};

use std::path::{Path, PathBuf};

use crate::{write_design, DesignError, Module};

/// The merging module's configuration (grid parameters, inputs, overlap
/// threshold, root-sorter capacity) is golden's [`MergeDesign`](golden::merge::merge_module::MergeDesign): the one
/// definition the vectors, the generators and the harness share.
pub use golden::merge::merge_module::MergeDesign as MergeConfig;

/// The top modules a configuration `c` emits, in a fixed order: the merging
/// module (whose instances, the merge network, the overlap counter in
/// overlap mode and S614, come with it), the upper builder (every S616 level
/// above the base, SPEC 8.11; its `upper_level` instances come with it),
/// then S616's one-level unit and the root sorter; then the fetcher (S610 +
/// S612, 8.13; per-node configurations: the fetcher with the per-node
/// command) and the record writer (S618, 8.12) with the sizes of
/// [`MergerConfig::new`], the hierarchy merger that instantiates them
/// all (8.15), and the hierarchy unit (8.16: that merger and a translation
/// unit with lookup ports, [`HierarchyUnitConfig::new`]). `c` must pass
/// `c.validate()`.
pub fn merge_units(c: &MergeConfig) -> Result<Vec<Module>, String> {
    let merger = MergerConfig::new(*c);
    let mut units = vec![
        merge_module_unit(c),
        upper_builder_unit(&c.params),
        upper_level_unit(&c.params),
        root_sorter_unit(&c.params, c.roots),
        fetcher_of(c, &merger),
        record_writer_unit(&c.params, merger.sizes.capacity_bits).map_err(|e| e.to_string())?,
    ];
    units.push(hierarchy_merger_unit(&merger)?);
    units.push(hierarchy_unit(&HierarchyUnitConfig::new(merger))?);
    Ok(units)
}

/// The fetcher a configuration needs: with the per-node command only for
/// per-node merging (a configuration holds only what it asks for).
fn fetcher_of(c: &MergeConfig, merger: &MergerConfig) -> Module {
    match c.mode {
        golden::merge::MergeMode::PerNode { .. } => {
            fetcher_per_node_unit(&c.params, &merger.fetch_sizes())
        }
        _ => fetcher_unit(&c.params, &merger.fetch_sizes()),
    }
}

/// Writes the Verilog of every module of `c` into `dir` (one `<module>.v`
/// per module, instances included, each once); returns the files written,
/// sorted. Refuses a configuration `c.validate()` refuses.
pub fn emit_merge(c: &MergeConfig, dir: &Path) -> Result<Vec<PathBuf>, DesignError> {
    c.validate().map_err(DesignError::Config)?;
    let mut files = std::collections::BTreeSet::new();
    for m in merge_units(c).map_err(DesignError::Config)? {
        files.extend(write_design(&m, dir)?);
    }
    Ok(files.into_iter().collect())
}
