//! S608, the merging level determining unit (508), paragraphs 53-55.
//!
//! `occupied(i, l)` is the set of LOD-`l` voxels holding a node (inner or
//! leaf) of input `i` at LOD `l`, after translation. For `l` at or below an
//! input's top every deeper node has its ancestor at `l` among the input's
//! nodes (children are exactly one LOD below their parent), so this is also
//! "the voxels the input covers at `l`", and one LOD's nodes are one stream.
//! `shared(l)` counts voxels occupied by two or more inputs, `union(l)` by
//! any ([`overlap_counts`], a k-way merge of Morton-sorted streams;
//! [`overlaps`] runs it on every candidate level of fully walked inputs, the
//! reference for [`overlaps_pruned`], which `merge` runs: it translates only
//! the nodes below voxels where inputs meet, and takes the union from a
//! per-input [`census`]).

pub mod unit;

use crate::merge::error::MergeError;
use crate::merge::fetcher::walk::WalkedInput;
use crate::merge::MergeMode;
use crate::store::Hierarchy;

/// The overlap at one candidate level.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct LevelOverlap {
    /// The candidate level (LOD) the counts are for.
    pub lod: u8,
    /// Voxels occupied by two or more inputs.
    pub shared: u64,
    /// Voxels occupied by any input.
    pub union: u64,
}

/// The candidate merging levels `[lo, hi]`: `lo` is the deepest top LOD of
/// the inputs (every input has its top at or above it), `hi` is
/// `max(lo, min_i deep(i))` where `deep(i)` is the deepest LOD of an inner
/// node of input `i` (its top LOD when it has none): the deepest level at
/// which every input that has inner nodes still has one.
pub fn candidate_range(inputs: &[&Hierarchy]) -> (u8, u8) {
    let lo = inputs.iter().map(|h| h.top_lod).max().unwrap_or(0);
    let deep = inputs.iter().map(|h| deep_lod(h)).min().unwrap_or(lo);
    (lo, deep.max(lo))
}

/// `deep(i)` of [`candidate_range`]: the deepest LOD of an inner node of
/// `h` (over its `nodes` array), its top LOD when it has none. A header
/// field of a stored hierarchy, so that hardware reads the range off the
/// headers (the hierarchy unit, docs/hardware.md 8.16).
pub fn deep_lod(h: &Hierarchy) -> u8 {
    h.nodes
        .iter()
        .filter(|n| !n.leaf)
        .map(|n| n.voxel.lod)
        .max()
        .unwrap_or(h.top_lod)
}

/// `(shared, union)` over `k` streams of voxel keys of one LOD, each sorted
/// ascending (repeats allowed: an inner node and a leaf at one voxel). The
/// hardware shape: each step takes the smallest head, consumes it from every
/// stream whose head equals it, and counts one voxel; the voxel is shared
/// when two or more streams held it.
pub fn overlap_counts<I: Iterator<Item = u128>>(streams: Vec<I>) -> (u64, u64) {
    let mut streams: Vec<std::iter::Peekable<I>> =
        streams.into_iter().map(|s| s.peekable()).collect();
    let (mut shared, mut union) = (0u64, 0u64);
    loop {
        let Some(v) = streams.iter_mut().filter_map(|s| s.peek().copied()).min() else {
            return (shared, union);
        };
        let mut holders = 0;
        for s in streams.iter_mut() {
            let mut held = false;
            while s.peek() == Some(&v) {
                s.next();
                held = true;
            }
            holders += held as u32;
        }
        union += 1;
        shared += (holders >= 2) as u64;
    }
}

/// The Morton-sorted translated voxel stream of input `w` at LOD `lod`
/// (sorting restores the order a translation may break).
pub fn occupied_stream(w: &WalkedInput, lod: u8) -> Vec<u128> {
    let mut v: Vec<u128> = w
        .by_lod
        .get(lod as usize)
        .map(|l| {
            l.iter()
                .map(|n| crate::merge::fetcher::walk::morton(&n.record.voxel))
                .collect()
        })
        .unwrap_or_default();
    v.sort_unstable();
    v
}

/// The overlap of every level in `[lo, hi]`, from inputs walked down to `hi`.
pub fn overlaps(walked: &[WalkedInput], lo: u8, hi: u8) -> Vec<LevelOverlap> {
    (lo..=hi)
        .map(|lod| {
            let streams = walked
                .iter()
                .map(|w| occupied_stream(w, lod).into_iter())
                .collect();
            let (shared, union) = overlap_counts(streams);
            LevelOverlap { lod, shared, union }
        })
        .collect()
}

/// The number of distinct LOD-`l` voxels holding a node of `h`, for every
/// `l` in `top_lod..=hi` (index `l`; 0 elsewhere): a walk from the roots
/// that follows references and compares stored voxels only. A translation
/// at `L <= l` moves all LOD-`l` voxels by one vector, so the count is that
/// of the translated voxels too.
pub fn census(h: &Hierarchy, hi: u8) -> Result<Vec<u64>, MergeError> {
    let mut out = vec![0u64; hi as usize + 1];
    let roots = (h.root_count as usize).min(h.nodes.len());
    let mut level: Vec<u32> = (0..roots as u32).collect();
    let mut keys: Vec<u128> = Vec::new();
    let mut lod = h.top_lod;
    while !level.is_empty() && lod <= hi {
        keys.clear();
        let mut next = Vec::new();
        for &i in &level {
            let n = &h.nodes[i as usize];
            if n.voxel.lod != lod {
                return Err(MergeError::BadInput {
                    input: h.id,
                    node: Some(i),
                    field: "lod",
                    expected: format!("{lod} (its parent's plus one, or top_lod for a root)"),
                    found: n.voxel.lod.to_string(),
                });
            }
            keys.push(crate::merge::fetcher::walk::morton(&n.voxel));
            if !n.leaf && lod < hi {
                next.extend(
                    crate::merge::fetcher::walk::children(h, i, n)?
                        .iter()
                        .map(|c| c.node),
                );
            }
        }
        if !keys.is_sorted() {
            keys.sort_unstable();
        }
        out[lod as usize] = 1 + keys.windows(2).filter(|w| w[0] != w[1]).count() as u64;
        level = next;
        lod += 1;
    }
    Ok(out)
}

/// The overlap of every level in `[lo, hi]` without walking everything
/// below `lo` translated: `shared(l)` and the voxels' extra holders are
/// counted over the *contested* nodes only (at `lo` all nodes, from `at_lo`;
/// at `l > lo` the children of the nodes at voxels shared at `l - 1`: a
/// voxel held by two inputs at `l` has its parent voxel held by both at
/// `l - 1`, since for `l - 1 >= lo` every node's parent is a node of its
/// input at the parent voxel), and `union(l) = sum_i distinct_i(l) -
/// sum over shared voxels of (holders - 1)` with `distinct_i` from
/// [`census`]. Equal to [`overlaps`] (tested).
pub fn overlaps_pruned(
    inputs: &[&Hierarchy],
    translations: &[crate::translate::Translation],
    at_lo: Vec<crate::merge::fetcher::walk::PlacedNode>,
    lo: u8,
    hi: u8,
) -> Result<Vec<LevelOverlap>, MergeError> {
    use crate::merge::merge_level::{sort_stream, voxel_groups};
    let mut distinct = vec![0u64; hi as usize + 1];
    for h in inputs {
        for (l, c) in census(h, hi)?.iter().enumerate() {
            distinct[l] += c;
        }
    }
    let mut out = Vec::with_capacity((hi - lo) as usize + 1);
    let mut contested = at_lo;
    for lod in lo..=hi {
        sort_stream(&mut contested);
        let (mut shared, mut extra) = (0u64, 0u64);
        let mut next = Vec::new();
        for g in voxel_groups(&contested) {
            let group = &contested[g];
            let holders = 1 + group.windows(2).filter(|w| w[0].rank != w[1].rank).count() as u64;
            if holders < 2 {
                continue;
            }
            shared += 1;
            extra += holders - 1;
            if lod == hi {
                continue;
            }
            for n in group.iter().filter(|n| !n.record.leaf) {
                let h = inputs[n.rank as usize];
                let t = &translations[n.rank as usize];
                for c in crate::merge::fetcher::walk::children(
                    h,
                    n.at.node,
                    &h.nodes[n.at.node as usize],
                )? {
                    next.push(crate::merge::fetcher::walk::place_node(
                        h, n.rank, t, c.node,
                    )?);
                }
            }
        }
        out.push(LevelOverlap {
            lod,
            shared,
            union: distinct[lod as usize] - extra,
        });
        contested = next;
    }
    Ok(out)
}

/// `shared * den > num * union`, exactly.
pub fn above_threshold(o: &LevelOverlap, num: u32, den: u32) -> bool {
    o.shared as u128 * den as u128 > num as u128 * o.union as u128
}

/// Checks `0 <= num <= den`, `den >= 1`.
pub fn check_ratio(mode: &'static str, num: u32, den: u32) -> Result<(), MergeError> {
    if den == 0 || num > den {
        return Err(MergeError::BadRatio { mode, num, den });
    }
    Ok(())
}

/// The merging level of a level mode over candidates `[lo, hi]`; `overlap`
/// is needed by (and only read in) [`MergeMode::Overlap`]. `None` for
/// [`MergeMode::PerNode`], which has no single level.
pub fn choose_level(
    mode: &MergeMode,
    lo: u8,
    hi: u8,
    overlap: &[LevelOverlap],
) -> Result<Option<u8>, MergeError> {
    match *mode {
        MergeMode::Overlap { num, den } => {
            check_ratio("Overlap", num, den)?;
            let deepest = overlap
                .iter()
                .filter(|o| above_threshold(o, num, den))
                .map(|o| o.lod)
                .max();
            Ok(Some(deepest.unwrap_or(lo)))
        }
        MergeMode::Fixed(level) => {
            if level < lo || level > hi {
                return Err(MergeError::LevelNotCandidate { level, lo, hi });
            }
            Ok(Some(level))
        }
        MergeMode::BelowTop(k) => {
            if lo as u16 + k as u16 > hi as u16 {
                return Err(MergeError::BelowTopTooDeep { k, lo, hi });
            }
            Ok(Some(lo + k))
        }
        MergeMode::Proportion { num, den } => {
            check_ratio("Proportion", num, den)?;
            let depth = (hi - lo) as u64 * num as u64 / den as u64;
            Ok(Some(lo + depth as u8))
        }
        MergeMode::PerNode { num, den } => {
            check_ratio("PerNode", num, den)?;
            Ok(None)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overlap_counts_groups_by_voxel_across_streams() {
        let s = vec![
            vec![1u128, 3, 3, 7].into_iter(),
            vec![3u128, 4, 7].into_iter(),
            vec![].into_iter(),
            vec![7u128, 9].into_iter(),
        ];
        // voxels 1, 3, 4, 7, 9; shared: 3 (two), 7 (three).
        assert_eq!(overlap_counts(s), (2, 5));
        assert_eq!(
            overlap_counts(Vec::<std::vec::IntoIter<u128>>::new()),
            (0, 0)
        );
    }

    #[test]
    fn thresholds_are_strict_and_exact() {
        let o = LevelOverlap {
            lod: 3,
            shared: 1,
            union: 2,
        };
        assert!(!above_threshold(&o, 1, 2));
        assert!(above_threshold(&o, 49, 100));
        assert!(above_threshold(&o, 0, 1));
        let full = LevelOverlap {
            lod: 3,
            shared: 5,
            union: 5,
        };
        assert!(!above_threshold(&full, 1, 1));
        assert_eq!(
            check_ratio("x", 3, 2),
            Err(MergeError::BadRatio {
                mode: "x",
                num: 3,
                den: 2
            })
        );
        assert!(check_ratio("x", 0, 0).is_err());
    }
}
