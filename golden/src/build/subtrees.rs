//! The parallel [`assemble`](super::upper::assemble): the levels from the
//! deepest LOD up to LOD [`SPLIT`] built one subtree at a time on the
//! threads of the current rayon pool, the few levels above them as
//! `assemble` builds them. The same hierarchy, bit for bit, or the same
//! error.
//!
//! Why the levels can be cut: a node of LOD `L >= SPLIT` and everything
//! grouped into it lie in one voxel of LOD `SPLIT`, its subtree. Grouping
//! by parent voxel never joins two subtrees at or below `SPLIT`, and in
//! each LOD the sorted entries, the leaves and the level's nodes are in
//! Morton order, whose high bits name the subtree. So each level at or
//! below `SPLIT` is the subtrees' own levels one after the other; only an
//! inner node's `first` (its first child's index in the level below) moves,
//! by the children of the subtrees before its own. Where the top rule stops
//! depends only on the levels' lengths.

use std::ops::Range;

use rayon::prelude::*;

use super::leaves::{LeafEntry, LeafKey};
use super::upper::{self, LevelNode};
use super::BuildError;
use crate::params::Params;
use crate::store::{Hierarchy, NodeRecord};

/// The LOD the levels are cut at: `8^2 = 64` subtrees, enough for the
/// threads to share them evenly when a scene fills only part of the cube,
/// few enough that a subtree's levels are not mostly setup (512 made the
/// building's assemble slower).
const SPLIT: usize = 2;

/// Fewest entries for the parallel assemble: below it the threads' setup
/// costs more than it saves, and [`upper::assemble`] runs.
const PARALLEL_MIN: usize = 1 << 15;

/// One subtree's records of the LODs `SPLIT..=deepest` (index `LOD -
/// SPLIT`, each level in store order; an inner node's `first` indexes the
/// subtree's own level below), and its nodes of LOD `SPLIT`.
struct Subtree {
    records: Vec<Vec<NodeRecord>>,
    split_level: Vec<LevelNode>,
}

/// [`upper::assemble`] on the threads of the current rayon pool.
pub(super) fn assemble_parallel<K: LeafKey>(
    entries: &[LeafEntry<K>],
    p: &Params,
    id: u8,
) -> Result<Hierarchy, BuildError> {
    let ranges = upper::entry_ranges_by_lod(entries, p);
    let (Some(deepest), Some(shallowest_base)) = (
        ranges.iter().rposition(|r| !r.is_empty()),
        ranges.iter().position(|r| !r.is_empty()),
    ) else {
        return Err(BuildError::EmptyMesh);
    };
    if entries.len() < PARALLEL_MIN || rayon::current_num_threads() < 2 || deepest <= SPLIT {
        return upper::assemble(entries, p, id);
    }
    assemble_split(entries, &ranges, p, id, deepest, shallowest_base)
}

/// [`assemble_parallel`]'s work, for entries whose deepest LOD is deeper
/// than `SPLIT` (`ranges`: each LOD's entries).
fn assemble_split<K: LeafKey>(
    entries: &[LeafEntry<K>],
    ranges: &[Range<usize>],
    p: &Params,
    id: u8,
    deepest: usize,
    shallowest_base: usize,
) -> Result<Hierarchy, BuildError> {
    let bounds = subtree_bounds(entries, ranges, p, deepest);
    let subtrees: Vec<Subtree> = (0..1usize << (3 * SPLIT))
        .into_par_iter()
        .map(|s| {
            subtree(entries, p, deepest, |lod| {
                let b = &bounds[lod - SPLIT];
                b[s]..b[s + 1]
            })
        })
        .collect();

    // The top rule, as `assemble`'s loop meets it going up.
    let stops = |d: usize, len: usize| d == 0 || (len == 1 && d <= shallowest_base);
    let len_of =
        |lod: usize| -> usize { subtrees.iter().map(|t| t.records[lod - SPLIT].len()).sum() };
    let (upper_records, top) = match (SPLIT..=deepest).rev().find(|&d| stops(d, len_of(d))) {
        Some(d) => (Vec::new(), d),
        None => {
            let level = subtrees
                .iter()
                .flat_map(|t| t.split_level.iter().copied())
                .collect();
            levels_above_split(level, entries, ranges, p, stops)
        }
    };
    let level_len = |lod: usize| match lod < SPLIT {
        true => upper_records[lod].len(),
        false => len_of(lod),
    };

    let mut offset = vec![0u64; deepest + 2];
    for lod in top..=deepest {
        offset[lod + 1] = offset[lod] + level_len(lod) as u64;
    }
    let total_nodes = offset[deepest + 1];
    let root_count = level_len(top) as u64;
    upper::check_index("node count - 1", total_nodes.saturating_sub(1), p)?;
    upper::check_index(
        "prims length - 1",
        (entries.len() as u64).saturating_sub(1),
        p,
    )?;

    // Every run of records in store order, with what its inner nodes'
    // `first` gains: the level below's place in the store, less the roots
    // (no reference names a root), plus the children of the subtrees before.
    let mut runs: Vec<(&[NodeRecord], u64)> = Vec::new();
    for lod in top..=deepest {
        let below = offset[lod + 1] - root_count;
        if lod < SPLIT {
            runs.push((&upper_records[lod], below));
            continue;
        }
        let mut before = 0u64;
        for t in &subtrees {
            runs.push((&t.records[lod - SPLIT], below + before));
            if lod < deepest {
                before += t.records[lod + 1 - SPLIT].len() as u64;
            }
        }
    }
    let nodes = write_runs(&runs, total_nodes as usize, p)?;
    let prims = entries.par_iter().map(|e| e.prim).collect();
    upper::finish(nodes, prims, root_count, top, p, id)
}

/// Where each subtree's entries of each LOD `SPLIT..=deepest` lie:
/// `bounds[LOD - SPLIT][s]..bounds[LOD - SPLIT][s + 1]` are subtree `s`'s
/// (the Morton code of a LOD-`L` voxel has `3L` bits, the subtree its top
/// `3 * SPLIT`).
fn subtree_bounds<K: LeafKey>(
    entries: &[LeafEntry<K>],
    ranges: &[Range<usize>],
    p: &Params,
    deepest: usize,
) -> Vec<Vec<usize>> {
    let morton_mask = (1u128 << (3 * p.max_lod as u32)) - 1;
    (SPLIT..=deepest)
        .map(|lod| {
            let r = ranges[lod].clone();
            let of_lod = &entries[r.clone()];
            let below = 3 * (lod - SPLIT) as u32;
            let subtree = |e: &LeafEntry<K>| ((e.key.to_u128() & morton_mask) >> below) as usize;
            (0..=1usize << (3 * SPLIT))
                .map(|s| r.start + of_lod.partition_point(|e| subtree(e) < s))
                .collect()
        })
        .collect()
}

/// One subtree's levels from `deepest` up to `SPLIT`, as `assemble` builds
/// every level: its leaves of the LOD, then the grouping of the level below
/// merged with them. `range(lod)`: the subtree's entries of that LOD.
fn subtree<K: LeafKey>(
    entries: &[LeafEntry<K>],
    p: &Params,
    deepest: usize,
    range: impl Fn(usize) -> Range<usize>,
) -> Subtree {
    let records_of = |level: &[LevelNode], lod: usize| -> Vec<NodeRecord> {
        level.iter().map(|n| upper::record_of(n, lod)).collect()
    };
    let mut records = vec![Vec::new(); deepest + 1 - SPLIT];
    let (mut level, mut parents, mut leaves) = (Vec::new(), Vec::new(), Vec::new());
    upper::leaves_of_lod_into(entries, range(deepest), p, &mut level);
    for d in (SPLIT + 1..=deepest).rev() {
        records[d - SPLIT] = records_of(&level, d);
        upper::group_by_parent_into(&level, p.quant_bits, &mut parents);
        upper::leaves_of_lod_into(entries, range(d - 1), p, &mut leaves);
        if leaves.is_empty() {
            std::mem::swap(&mut level, &mut parents);
        } else {
            upper::merge_level_into(&parents, &leaves, &mut level);
        }
    }
    records[0] = records_of(&level, SPLIT);
    Subtree {
        records,
        split_level: level,
    }
}

/// The levels above `SPLIT`, given the nodes of LOD `SPLIT` (where the top
/// rule did not stop): their records (index = LOD) and the top LOD, as
/// `assemble` makes them, the top rule's exception included.
fn levels_above_split<K: LeafKey>(
    mut level: Vec<LevelNode>,
    entries: &[LeafEntry<K>],
    ranges: &[Range<usize>],
    p: &Params,
    stops: impl Fn(usize, usize) -> bool,
) -> (Vec<Vec<NodeRecord>>, usize) {
    let records_of = |level: &[LevelNode], lod: usize| -> Vec<NodeRecord> {
        level.iter().map(|n| upper::record_of(n, lod)).collect()
    };
    let mut records = vec![Vec::new(); SPLIT];
    let (mut parents, mut leaves) = (Vec::new(), Vec::new());
    let mut d = SPLIT;
    loop {
        upper::group_by_parent_into(&level, p.quant_bits, &mut parents);
        upper::leaves_of_lod_into(entries, ranges[d - 1].clone(), p, &mut leaves);
        if leaves.is_empty() {
            std::mem::swap(&mut level, &mut parents);
        } else {
            upper::merge_level_into(&parents, &leaves, &mut level);
        }
        d -= 1;
        if stops(d, level.len()) {
            break;
        }
        records[d] = records_of(&level, d);
    }
    // Only a grouped root can give way to its children: they are level 1.
    if d == 0
        && level.len() == 1
        && !level[0].base
        && upper::covers_most_of_scene(&level[0], p.quant_bits)
    {
        return (records, 1);
    }
    records[d] = records_of(&level, d);
    (records, d)
}

/// The store's node array: the runs one after the other, each inner node's
/// `first` raised by its run's gain; in parallel, run by run. The error of
/// the first node in store order whose `count` does not fit, as
/// `assemble` checks them.
fn write_runs(
    runs: &[(&[NodeRecord], u64)],
    total: usize,
    p: &Params,
) -> Result<Vec<NodeRecord>, BuildError> {
    let mut nodes: Vec<NodeRecord> = Vec::with_capacity(total);
    let mut slots = Vec::with_capacity(runs.len());
    let mut rest = &mut nodes.spare_capacity_mut()[..total];
    for (run, _) in runs {
        let (head, tail) = rest.split_at_mut(run.len());
        slots.push(head);
        rest = tail;
    }
    let written: Vec<Result<(), BuildError>> = slots
        .into_par_iter()
        .zip(runs.par_iter())
        .map(|(dst, (run, gain))| {
            for (d, n) in dst.iter_mut().zip(run.iter()) {
                upper::check_index("count", n.count as u64, p)?;
                let mut n = *n;
                if !n.leaf {
                    n.first = (gain + n.first as u64) as u32;
                }
                d.write(n);
            }
            Ok(())
        })
        .collect();
    written.into_iter().collect::<Result<(), _>>()?;
    // SAFETY: the runs' slots cover the first `total` slots, each written
    // above (every run returned Ok).
    unsafe { nodes.set_len(total) };
    Ok(nodes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::build::{check_grid_triangle, place_range, radix};
    use glam::DVec3;

    /// Both assembles over the sorted entries of `tris` (grid units), the
    /// split one forced (whatever the entry count) on two threads.
    fn both(
        tris: &[[DVec3; 3]],
        p: &Params,
    ) -> (Result<Hierarchy, BuildError>, Result<Hierarchy, BuildError>) {
        let triangle = |i: usize| {
            check_grid_triangle(&tris[i], i, p)?;
            Ok(tris[i])
        };
        let mut entries = place_range::<u128>(0..tris.len(), p, &triangle).unwrap();
        radix::radix_sort(
            &mut entries,
            &mut Vec::new(),
            super::super::leaves::leaf_key_bits(p),
            |e| e.key,
        );
        let ranges = upper::entry_ranges_by_lod(&entries, p);
        let deepest = ranges.iter().rposition(|r| !r.is_empty()).unwrap();
        let shallowest = ranges.iter().position(|r| !r.is_empty()).unwrap();
        assert!(deepest > SPLIT, "the case must reach below the split");
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let split = pool.install(|| assemble_split(&entries, &ranges, p, 3, deepest, shallowest));
        (upper::assemble(&entries, p, 3), split)
    }

    /// Triangles of about `size` grid units, spread over the cube
    /// `[at, at + span)^3` by a fixed generator.
    fn soup(n: usize, at: f64, span: f64, size: f64, seed: u64) -> Vec<[DVec3; 3]> {
        let mut s = seed;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n)
            .map(|_| {
                let c = DVec3::new(next(), next(), next()) * (span - size) + DVec3::splat(at);
                let mut corner = || c + DVec3::new(next(), next(), next()) * size;
                [corner(), corner(), corner()]
            })
            .collect()
    }

    /// The split assemble gives `assemble`'s hierarchy: over the whole
    /// cube (the top above the split, Q = 0's top rule at LOD 0 included),
    /// inside one voxel of a LOD below the split (the top there), with
    /// large triangles whose leaves lie above the split, and the same
    /// error when the node count overflows `I`.
    #[test]
    fn the_split_assemble_is_the_one_thread_assemble() {
        let floor = |n, seed| -> Vec<[DVec3; 3]> {
            soup(n, 0.0, 1024.0, 3.0, seed)
                .into_iter()
                .map(|t| t.map(|v| DVec3::new(v.x, v.y, v.z * 0.01)))
                .collect()
        };
        // (case, parameters, triangles, the top LOD that shows the path taken)
        let cases = [
            (
                "whole cube, Q = 0: LOD 0 gives way",
                Params::new(8, 0, 24, 4),
                soup(3000, 0.0, 256.0, 2.0, 1),
                1,
            ),
            (
                "whole cube, D = 16",
                Params::new(16, 8, 24, 4),
                soup(3000, 0.0, 65536.0, 40.0, 2),
                1,
            ),
            (
                "a floor: the top at LOD 0",
                Params::new(10, 4, 24, 4),
                floor(3000, 7),
                0,
            ),
            (
                "one LOD-5 voxel: the top below the split",
                Params::new(12, 4, 24, 4),
                soup(2000, 640.0, 128.0, 1.5, 3),
                5,
            ),
            (
                "leaves above the split",
                Params::new(10, 3, 24, 4),
                {
                    let mut t = soup(1500, 0.0, 1024.0, 3.0, 4);
                    t.extend(soup(40, 0.0, 1024.0, 400.0, 5));
                    t
                },
                1,
            ),
        ];
        for (what, p, tris, top) in cases {
            let p = p.unwrap();
            let (one, split) = both(&tris, &p);
            assert_eq!(split, one, "{what}");
            assert_eq!(one.map(|h| h.top_lod).ok(), Some(top), "{what}");
        }
        let p = Params::new(16, 8, 12, 4).unwrap();
        let (one, split) = both(&soup(3000, 0.0, 65536.0, 40.0, 6), &p);
        assert!(
            matches!(one, Err(BuildError::IndexOverflow { .. })),
            "{one:?}"
        );
        assert_eq!(split, one);
    }
}
