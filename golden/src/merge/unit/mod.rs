//! The merging module's stages as the RTL sees them (SPEC.md section 8,
//! "Merging module RTL"): the beat formats of each stage's ready/valid
//! streams, packed with [`crate::layout`], and each stage's transaction,
//! whose expected outputs come from the golden stage functions
//! ([`super::level_merge::merge_level`], [`super::level::overlap_counts`],
//! [`super::level::above_threshold`]), never from a second model.
//!
//! One file per stage, beside its generator in `rtl_gen::merge` (each with
//! its seeded stimulus); every item is re-exported here:
//! - **S614, merge level** ([`level`], unit 506): in, the merging-level nodes of all
//!   inputs in *delivery order* ([`level_stream`]): per voxel, Morton order,
//!   the inner nodes (input order), then the leaves (input order), then the
//!   child references of those inner nodes (same order), then one `End`
//!   beat after the last voxel. Out, the base nodes in golden order (per
//!   voxel: the created or reused inner node, then the leaves), each created
//!   node's references right after that voxel's leaves, then `End`.
//! - **S608, overlap counter** ([`overlap`], unit 508): in, one level's `(voxel, rank)`
//!   beats in `(Morton, rank)` order then `End`; out, one beat: `shared`,
//!   `union`, whether `shared * den > num * union`, and a count overflow flag.
//!
//! - **S616, one upper level** ([`upper`]): a level's records in, their
//!   parents out, grouped by parent voxel.
//! - **Root sorter** ([`sorter`]): one input's roots back in Morton order
//!   after a translation.
//!
//! The stimulus is seeded and reaches the hard cases on purpose (shared
//! voxels, lone inner nodes, inner + leaf at one voxel, two inner nodes of
//! one input, `count` overflow at small `I`, voxels at the grid's edges).

pub mod level;
pub mod overlap;
pub mod sorter;
pub mod upper;

pub use level::*;
pub use overlap::*;
pub use sorter::*;
pub use upper::*;

use crate::params::Params;
use crate::translate::stimulus::SplitMix64;

// The random draws every stage's stimulus uses.

fn random_coord(rng: &mut SplitMix64, lod: u8) -> u32 {
    let n = 1u64 << lod;
    match rng.below(8) {
        0 => 0,
        1 => (n - 1) as u32,
        _ => rng.below(n) as u32,
    }
}

fn random_box(rng: &mut SplitMix64, p: &Params) -> ([u16; 3], [u16; 3]) {
    let cells = p.quant_cells() as u64;
    let mut lo = [0u16; 3];
    let mut hi = [0u16; 3];
    for a in 0..3 {
        let (x, y) = match rng.below(6) {
            0 => (0, cells - 1),
            1 => (cells - 1, cells - 1),
            _ => (rng.below(cells), rng.below(cells)),
        };
        lo[a] = x.min(y) as u16;
        hi[a] = x.max(y) as u16;
    }
    (lo, hi)
}

fn random_index(rng: &mut SplitMix64, p: &Params, at_least: u64) -> u32 {
    let cap = p.index_capacity();
    match rng.below(4) {
        0 => (cap - 1) as u32,
        _ => rng.below(cap - at_least).saturating_add(at_least) as u32,
    }
}
