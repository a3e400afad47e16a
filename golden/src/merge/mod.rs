//! The hierarchy merging module (FIG. 5/6, paragraphs 53-68; SPEC.md
//! section 8): merges translated input hierarchies into a new hierarchy
//! whose records reference the inputs' nodes, leaving the inputs untouched.
//!
//! One module per unit of the patent, each holding the algorithm (the
//! module itself) and, where the unit is built in hardware, its transaction
//! model as the RTL sees it (beat layouts, expected outputs from the
//! algorithm, seeded stimulus). The same names are used by the generators
//! (`rtl_gen::merge`), the benches (`cosim::units`) and docs/hardware.md:
//! 1. [`level_choice`]: S608, the merging level (unit 508): candidate
//!    levels, the overlap counts per level, the mode's choice;
//!    [`level_choice::unit`] is the overlap counter.
//! 2. [`fetcher`]: S610 + S612: each input walked from its top down to the
//!    merging level, every node translated ([`fetcher::walk`]); the leaves
//!    above the level and the nodes at it collected; [`fetcher::root_sorter`].
//! 3. [`merge_level`]: S614 (unit 506): merged nodes at the merging level,
//!    grouped by voxel over the Morton-sorted union of the inputs' nodes;
//!    [`merge_level::unit`] holds the merging module's beat format.
//!    [`per_node`] is the per-node mode of paragraph 55.
//! 4. [`upper_builder`]: S616: the upper levels, with the mesh builder's
//!    grouping and top rule (shared code), and the records' layout;
//!    [`upper_builder::level_unit`] one level in hardware,
//!    [`upper_builder::unit`] every level at once.
//! 5. [`record_writer`]: S618 in hardware; [`merge`] / [`merge_into`]: the
//!    merged hierarchy (and its statistics); [`merge_into`] stores it.
//!
//! The assemblies: [`merge_module`] (S608 + S614 + per-node behind one
//! `cfg`), [`merger`] (the merger top: fetchers, merging module, upper
//! builder, record writer, its store port [`merger::store_port`]) and
//! [`hierarchy_unit`] (the translation unit's table feeding the merger
//! top). [`view`] gives the checker and traversal what they need to read a
//! merged hierarchy through its inputs' translations.

pub mod error;
pub mod fetcher;
pub mod hierarchy_unit;
pub mod instances;
pub mod level_choice;
pub mod merge_level;
pub mod merge_module;
pub mod merger;
pub mod per_node;
pub mod record_writer;
pub mod stimulus;
pub mod upper_builder;
pub mod view;

pub use error::MergeError;
pub use level_choice::{overlap_counts, LevelOverlap};
pub use view::MergedCheckView;

use serde::Serialize;

use crate::params::Params;
use crate::store::{Hierarchy, HierarchyStore};
use crate::translate::{Translation, TranslationTable};
use fetcher::walk::{collect, walk_input, WalkedInput};
use merge_level::MergeLevelCounts;
use per_node::{PerNode, PerNodeCounts};

/// How the merging level is chosen (paragraphs 53-55).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum MergeMode {
    /// The deepest candidate level whose overlap is above `num / den`
    /// (strictly: `shared * den > num * union`); the shallowest candidate
    /// when none is. Default 1/2 (53).
    Overlap {
        /// Numerator of the threshold (`num <= den`).
        num: u32,
        /// Denominator of the threshold (`den >= 1`).
        den: u32,
    },
    /// A user-specified level (54); an error unless it is a candidate.
    Fixed(u8),
    /// `k` levels below the top: `lo + k` (54); an error beyond `hi`.
    BelowTop(u8),
    /// A proportion of the depth: `lo + floor((hi - lo) num / den)` (54).
    Proportion {
        /// Numerator of the fraction of `hi - lo` (`num <= den`).
        num: u32,
        /// Denominator of the fraction (`den >= 1`).
        den: u32,
    },
    /// No single level: the merged sub-hierarchies' roots are chosen per
    /// node by the overlap of their children (55, [`per_node`]).
    PerNode {
        /// Numerator of the descent threshold `S * den > num * U` (`num <= den`).
        num: u32,
        /// Denominator of the descent threshold (`den >= 1`).
        den: u32,
    },
}

impl std::fmt::Display for MergeMode {
    /// The command line's spelling: `overlap:1/2`, `fixed:5`, `below-top:2`,
    /// `proportion:1/2`, `per-node:1/2`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MergeMode::Overlap { num, den } => write!(f, "overlap:{num}/{den}"),
            MergeMode::Fixed(l) => write!(f, "fixed:{l}"),
            MergeMode::BelowTop(k) => write!(f, "below-top:{k}"),
            MergeMode::Proportion { num, den } => write!(f, "proportion:{num}/{den}"),
            MergeMode::PerNode { num, den } => write!(f, "per-node:{num}/{den}"),
        }
    }
}

impl Default for MergeMode {
    fn default() -> Self {
        MergeMode::Overlap { num: 1, den: 2 }
    }
}

/// What a merge did.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct MergeStats {
    /// Candidate merging levels `[lo, hi]`.
    pub candidates: (u8, u8),
    /// Overlap at every candidate level (overlap mode only; empty otherwise).
    pub overlap: Vec<LevelOverlap>,
    /// Input nodes walked and translated down to the merging level
    /// (S610-S612; per-node mode: down to `lo`).
    pub nodes_walked: u64,
    /// Input leaves above the merging level, taken as they are (S610).
    pub leaves_above: u64,
    /// S614: created merged nodes, reused input inner nodes and leaves.
    pub merge_level: MergeLevelCounts,
    /// Per-node mode: descents and the deepest created node.
    pub per_node: PerNodeCounts,
    /// Records made by S616's grouping.
    pub upper_nodes: u64,
    /// Reused inner nodes copied to be roots.
    pub materialized: u64,
    /// Extra groupings because a reused leaf reached the top.
    pub lifted: u64,
    /// Records of the merged hierarchy per LOD, `(lod, count)`, top first.
    pub nodes_per_level: Vec<(u8, u64)>,
    /// References of the merged hierarchy naming an input.
    pub refs_to_inputs: u64,
}

impl MergeStats {
    /// Records created by the merge (S614 + S616 + materialized roots).
    pub fn created(&self) -> u64 {
        self.merge_level.created + self.upper_nodes + self.materialized
    }

    /// Input nodes the merged hierarchy references directly instead of
    /// making a node for them: reused inner nodes and leaves at the merging
    /// level(s), and leaves above it.
    pub fn reused(&self) -> u64 {
        self.merge_level.reused_inner + self.merge_level.reused_leaves + self.leaves_above
    }
}

/// The merged hierarchy, its merging level (`None` in per-node mode) and
/// what the merge did.
#[derive(Clone, Debug, PartialEq)]
pub struct MergeResult {
    /// The merged hierarchy `out_id`; its references name its own records
    /// and the inputs' nodes.
    pub merged: Hierarchy,
    /// The merging level `m`; `None` in per-node mode (the base spans several LODs).
    pub level: Option<u8>,
    /// The counts of every stage.
    pub stats: MergeStats,
}

/// The inputs and their translations, checked.
fn resolve_inputs<'a>(
    store: &'a HierarchyStore,
    inputs: &[u8],
    table: &TranslationTable,
    out_id: u8,
) -> Result<(Vec<&'a Hierarchy>, Vec<Translation>, Params), MergeError> {
    let first = *inputs.first().ok_or(MergeError::NoInputs)?;
    let params = store
        .get(first)
        .ok_or(MergeError::UnknownInput(first))?
        .params;
    let mut hs: Vec<&Hierarchy> = Vec::with_capacity(inputs.len());
    let mut ts = Vec::with_capacity(inputs.len());
    for (k, &id) in inputs.iter().enumerate() {
        if inputs[..k].contains(&id) {
            return Err(MergeError::DuplicateInput(id));
        }
        let h = store.get(id).ok_or(MergeError::UnknownInput(id))?;
        if h.params != params {
            return Err(MergeError::ParamsMismatch {
                input: id,
                expected: params,
                found: h.params,
            });
        }
        let t = table
            .read(id as u32)
            .map_err(|error| MergeError::Translation { input: id, error })?;
        hs.push(h);
        ts.push(t);
    }
    if out_id as u64 >= params.hier_capacity() {
        return Err(MergeError::OutIdOutOfRange {
            id: out_id,
            hier_bits: params.hier_bits,
        });
    }
    if store.get(out_id).is_some() {
        return Err(MergeError::OutIdInUse(out_id));
    }
    Ok((hs, ts, params))
}

fn walk_all(
    hs: &[&Hierarchy],
    ts: &[Translation],
    down_to: u8,
) -> Result<Vec<WalkedInput>, MergeError> {
    hs.iter()
        .zip(ts)
        .enumerate()
        .map(|(rank, (h, t))| walk_input(h, rank as u16, t, down_to))
        .collect()
}

/// Merges hierarchies `inputs` of `store`, each placed by its entry in
/// `table`, into a new hierarchy with id `out_id` (S608-S618; SPEC.md
/// section 8). Reads the store only: see [`merge_into`] to store the result.
pub fn merge(
    store: &HierarchyStore,
    inputs: &[u8],
    table: &TranslationTable,
    mode: MergeMode,
    out_id: u8,
) -> Result<MergeResult, MergeError> {
    let (hs, ts, p) = resolve_inputs(store, inputs, table, out_id)?;
    let (lo, hi) = level_choice::candidate_range(&hs);
    let mut stats = MergeStats {
        candidates: (lo, hi),
        ..MergeStats::default()
    };
    let (base, level) = match mode {
        MergeMode::PerNode { num, den } => {
            level_choice::check_ratio("PerNode", num, den)?;
            let walked = walk_all(&hs, &ts, lo)?;
            let (above, first_level) = collect(&walked, lo);
            stats.nodes_walked = walked_count(&walked);
            stats.leaves_above = above.len() as u64;
            let decider = PerNode {
                inputs: &hs,
                translations: &ts,
                params: p,
                num,
                den,
            };
            let mut base: Vec<_> = above.iter().map(merge_level::BaseNode::reused).collect();
            base.extend(decider.merge_from(
                first_level,
                &mut stats.merge_level,
                &mut stats.per_node,
            )?);
            (base, None)
        }
        _ => {
            let walked;
            let m = if let MergeMode::Overlap { num, den } = mode {
                level_choice::check_ratio("Overlap", num, den)?;
                let to_lo = walk_all(&hs, &ts, lo)?;
                let (_, at_lo) = collect(&to_lo, lo);
                stats.overlap = level_choice::overlaps_pruned(&hs, &ts, at_lo, lo, hi)?;
                let m = level_choice::choose_level(&mode, lo, hi, &stats.overlap)?.unwrap_or(lo);
                walked = if m == lo {
                    to_lo
                } else {
                    walk_all(&hs, &ts, m)?
                };
                m
            } else {
                let m = level_choice::choose_level(&mode, lo, hi, &[])?.unwrap_or(lo);
                walked = walk_all(&hs, &ts, m)?;
                m
            };
            stats.nodes_walked = walked_count(&walked);
            let (above, at_level) = collect(&walked, m);
            stats.leaves_above = above.len() as u64;
            let mut base: Vec<_> = above.iter().map(merge_level::BaseNode::reused).collect();
            base.extend(merge_level::merge_level(
                at_level,
                &hs,
                &p,
                &mut stats.merge_level,
            )?);
            (base, Some(m))
        }
    };
    let (merged, upper) = upper_builder::build_upper(&base, &hs, &p, out_id)?;
    stats.upper_nodes = upper.grouped;
    stats.materialized = upper.materialized;
    stats.lifted = upper.lifted;
    stats.nodes_per_level = upper.nodes_per_level;
    stats.refs_to_inputs = merged.refs.iter().filter(|r| r.hier != out_id).count() as u64;
    Ok(MergeResult {
        merged,
        level,
        stats,
    })
}

fn walked_count(walked: &[WalkedInput]) -> u64 {
    walked
        .iter()
        .map(|w| w.by_lod.iter().map(|l| l.len() as u64).sum::<u64>())
        .sum()
}

/// [`merge`], then S618: the merged hierarchy is stored under `out_id`; the
/// inputs stay in the store untouched (paragraph 66). Returns the result
/// (its `merged` is a copy of what was stored).
pub fn merge_into(
    store: &mut HierarchyStore,
    inputs: &[u8],
    table: &TranslationTable,
    mode: MergeMode,
    out_id: u8,
) -> Result<MergeResult, MergeError> {
    let r = merge(store, inputs, table, mode, out_id)?;
    store.insert(r.merged.clone()).map_err(MergeError::Store)?;
    Ok(r)
}
