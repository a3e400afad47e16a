//! The root sorter: one input's roots back in (translated Morton code,
//! inner before leaf) order after a translation. Its transaction and its
//! stimulus.

use std::collections::BTreeSet;

use crate::grid::VoxelAddr;
use crate::merge::fetcher::walk::PlacedNode;
use crate::merge::merge_level::unit::LevelBeat;
use crate::merge::stimulus::{random_box, random_coord, random_index};
use crate::params::Params;
use crate::store::{NodeRecord, Reference};
use crate::translate::stimulus::SplitMix64;

/// Why sorting the roots is enough: a translation at level `L` moves a node
/// at LOD `d >= L` by `t << (d - L)`, so a child moves by exactly twice its
/// parent's move and keeps its octant. Below the top, a breadth-first walk
/// that visits the roots in translated Morton order therefore meets every
/// level in translated Morton order (a voxel's descendants are contiguous
/// in Morton order at every LOD). Only the roots (`root_count`, at most 16
/// for a builder-made input: 8 octants of the root voxel, an inner node and
/// a leaf each) can come out of order; the root sorter orders them by
/// (translated Morton code, inner before leaf), stably, as golden's
/// [`crate::merge::merge_level::sort_stream`] orders one input.
///
/// The transaction: the roots of one input as [`LevelBeat::Inner`] /
/// [`LevelBeat::Leaf`] beats in stored order, then `End`; out, the first
/// `capacity` of them sorted, then `End` with `err` set when there were more
/// than `capacity` (those are dropped, never silently: the flag says so).
pub fn root_sort_transaction(
    roots: &[PlacedNode],
    capacity: usize,
) -> (Vec<LevelBeat>, Vec<(LevelBeat, bool)>) {
    let beat = LevelBeat::of_node;
    let mut inputs: Vec<LevelBeat> = roots.iter().map(beat).collect();
    inputs.push(LevelBeat::End);
    let mut kept: Vec<PlacedNode> = roots.iter().take(capacity).copied().collect();
    crate::merge::merge_level::sort_stream(&mut kept);
    let mut outputs: Vec<(LevelBeat, bool)> = kept.iter().map(|n| (beat(n), false)).collect();
    outputs.push((LevelBeat::End, roots.len() > capacity));
    (inputs, outputs)
}

/// Random roots of one input, translated so that Morton order breaks: up
/// to `most` nodes (sometimes more, to reach the overflow flag) at one LOD,
/// an inner node and/or a leaf per voxel, in Morton order of the untranslated
/// voxels, then moved by a random offset per axis (wrapping inside the LOD,
/// as a translation near the edge of a large top does to the order).
pub fn random_roots(rng: &mut SplitMix64, p: &Params, most: usize) -> Vec<PlacedNode> {
    let lod = match rng.below(4) {
        0 => 0,
        1 => p.max_lod,
        _ => rng.below(p.max_lod as u64 + 1) as u8,
    };
    let n = if rng.below(8) == 0 {
        most + 1 + rng.below(4) as usize
    } else {
        1 + rng.below(most as u64) as usize
    };
    let side = 1u64 << lod;
    let base = [0; 3].map(|_| random_coord(rng, lod));
    let mut voxels = BTreeSet::new();
    for _ in 0..n {
        // Near one corner so that Morton codes share high bits, then moved.
        let v = base.map(|b| ((b as u64 + rng.below(4)) % side) as u32);
        voxels.insert(VoxelAddr::new(lod, v[0], v[1], v[2]));
    }
    let mut sorted: Vec<VoxelAddr> = voxels.into_iter().collect();
    sorted.sort_by_key(|v| v.morton());
    let shift = [0; 3].map(|_| rng.below(side));
    let mut out = Vec::new();
    for v in sorted {
        let moved = VoxelAddr::new(
            lod,
            ((v.x as u64 + shift[0]) % side) as u32,
            ((v.y as u64 + shift[1]) % side) as u32,
            ((v.z as u64 + shift[2]) % side) as u32,
        );
        let kinds: &[bool] = match rng.below(4) {
            0 => &[false, true],
            1 => &[true],
            _ => &[false],
        };
        for &leaf in kinds {
            if out.len() >= n {
                break;
            }
            let (lo, hi) = random_box(rng, p);
            let node = (out.len() as u64 % p.index_capacity()) as u32;
            out.push(PlacedNode {
                rank: 0,
                at: Reference { hier: 0, node },
                record: NodeRecord {
                    leaf,
                    voxel: moved,
                    lo,
                    hi,
                    first: random_index(rng, p, 0),
                    count: random_index(rng, p, 1),
                },
            });
        }
    }
    out
}
