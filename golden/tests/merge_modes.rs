//! Every merging mode (paragraphs 53-55) on bunny + teapot: the level each
//! mode picks against an independent computation of the candidate range and
//! the overlap counts; the checker, leaf reachability and closest hits
//! (against the separate inputs and brute force) on every result; the
//! created nodes' references and boxes against their definition.

mod merge_support;

use std::collections::{BTreeMap, BTreeSet};

use golden::build::quantize::child_cells_in_parent;
use golden::merge::{MergeError, MergeMode, MergeResult};
use golden::params::Params;
use golden::store::{Hierarchy, NodeRecord, Reference};
use golden::translate::translate_node;
use merge_support::{load, normalized, Scene};

fn scene() -> Scene {
    let mut s = Scene::new(Params::new(16, 8, 24, 4).unwrap(), 1.0 / 64.0);
    s.add(1, normalized(&load("bunny.obj"), 8.0, 1.0), [10, 10, 10]);
    s.add(2, normalized(&load("teapot.obj"), 8.0, 3.0), [10, 10, 10]);
    s
}

/// Every node reachable in `h`, translated, as (LOD, voxel) per input.
fn occupied(s: &Scene, id: u8) -> BTreeSet<(u8, u32, u32, u32)> {
    let h = s.store.get(id).unwrap();
    let t = s.table.read(id as u32).unwrap();
    let mut out = BTreeSet::new();
    let mut stack: Vec<u32> = (0..h.root_count).collect();
    while let Some(i) = stack.pop() {
        let n = &h.nodes[i as usize];
        let v = translate_node(n.voxel, &t, &h.params).unwrap();
        out.insert((v.lod, v.x, v.y, v.z));
        stack.extend(h.children_of(n).iter().map(|r| r.node));
    }
    out
}

/// The candidate range and `(lod, shared, union)` per candidate level,
/// computed from sets (not streams).
/// `(lod, shared, union)`.
type Overlaps = Vec<(u8, u64, u64)>;

fn reference_overlap(s: &Scene, inputs: &[u8]) -> ((u8, u8), Overlaps) {
    let hs: Vec<&Hierarchy> = inputs.iter().map(|i| s.store.get(*i).unwrap()).collect();
    let lo = hs.iter().map(|h| h.top_lod).max().unwrap();
    let deep = |h: &Hierarchy| {
        h.nodes
            .iter()
            .filter(|n| !n.leaf)
            .map(|n| n.voxel.lod)
            .max()
            .unwrap_or(h.top_lod)
    };
    let hi = hs.iter().map(|h| deep(h)).min().unwrap().max(lo);
    let sets: Vec<_> = inputs.iter().map(|i| occupied(s, *i)).collect();
    let mut out = Vec::new();
    for l in lo..=hi {
        let mut count: BTreeMap<(u8, u32, u32, u32), u32> = BTreeMap::new();
        for set in &sets {
            for v in set.iter().filter(|v| v.0 == l) {
                *count.entry(*v).or_default() += 1;
            }
        }
        let shared = count.values().filter(|&&c| c >= 2).count() as u64;
        out.push((l, shared, count.len() as u64));
    }
    ((lo, hi), out)
}

/// Fine-unit box of a record.
fn fine(n: &NodeRecord, p: &Params) -> ([u64; 3], [u64; 3]) {
    golden::store::node_box_fine(n, p)
}

/// Every created record at the merging level: its references are exactly
/// the children of the input inner nodes at its voxel (two or more), and
/// its box is the union of its children's boxes re-quantized outward.
fn check_created(s: &Scene, r: &MergeResult, inputs: &[u8]) -> u64 {
    let Some(m) = r.level else { return 0 };
    let merged = &r.merged;
    let p = merged.params;
    let mut checked = 0;
    for n in merged.nodes.iter().filter(|n| n.voxel.lod == m) {
        let refs = merged.children_of(n);
        if refs.iter().any(|c| c.hier == merged.id) {
            continue; // not at the base
        }
        // The input inner nodes at this voxel.
        let mut expected: Vec<Reference> = Vec::new();
        let mut holders = 0;
        for &i in inputs {
            let h = s.store.get(i).unwrap();
            let t = s.table.read(i as u32).unwrap();
            for (k, x) in h.nodes.iter().enumerate() {
                if !x.leaf
                    && x.voxel.lod == m
                    && translate_node(x.voxel, &t, &p).unwrap() == n.voxel
                {
                    holders += 1;
                    expected.extend_from_slice(h.children_of(x));
                    let _ = k;
                }
            }
        }
        if holders < 2 {
            continue; // a materialized root
        }
        assert_eq!(refs, expected.as_slice(), "created node at {:?}", n.voxel);
        // Box: union of the children's cells in the parent, per axis.
        let mut lo = [u16::MAX; 3];
        let mut hi = [0u16; 3];
        for c in refs {
            let h = s.store.get(c.hier).unwrap();
            let t = s.table.read(c.hier as u32).unwrap();
            let cn = &h.nodes[c.node as usize];
            let v = translate_node(cn.voxel, &t, &p).unwrap();
            let odd = [v.x & 1 == 1, v.y & 1 == 1, v.z & 1 == 1];
            for a in 0..3 {
                let (l, hh) = child_cells_in_parent(cn.lo[a], cn.hi[a], odd[a], p.quant_bits);
                lo[a] = lo[a].min(l);
                hi[a] = hi[a].max(hh);
            }
        }
        assert_eq!((n.lo, n.hi), (lo, hi), "created node box at {:?}", n.voxel);
        let _ = fine(n, &p);
        checked += 1;
    }
    checked
}

/// Merges with `mode` into `out`, then checks, counts leaves, traces.
fn run(s: &mut Scene, mode: MergeMode, out: u8) -> MergeResult {
    let r = s.merge(&[1, 2], mode, out);
    let rep = s.check(out, &[1, 2]);
    let leaves = s.leaves_once(out, &[1, 2]);
    assert_eq!(rep.leaves, leaves);
    let rays = s.compare(out, &[1, 2], 3_000, out as u64, 3);
    rays.print(&format!("{mode:?}"));
    println!("{mode:?}: level {:?} {:?}", r.level, r.stats);
    assert_eq!(
        r.stats.refs_to_inputs as usize,
        r.merged.refs.iter().filter(|c| c.hier != out).count()
    );
    r
}

#[test]
fn overlap_mode_picks_the_deepest_level_above_the_threshold() {
    let mut s = scene();
    let ((lo, hi), reference) = reference_overlap(&s, &[1, 2]);
    assert!(
        hi > lo + 2,
        "the test needs several candidate levels: {lo}..{hi}"
    );
    for (num, den, out) in [
        (1u32, 2u32, 3u8),
        (0, 1, 4),
        (1, 1, 5),
        (1, 10, 6),
        (9, 10, 7),
    ] {
        let r = run(&mut s, MergeMode::Overlap { num, den }, out);
        assert_eq!(r.stats.candidates, (lo, hi));
        let got: Vec<(u8, u64, u64)> = r
            .stats
            .overlap
            .iter()
            .map(|o| (o.lod, o.shared, o.union))
            .collect();
        assert_eq!(got, reference);
        let expected = reference
            .iter()
            .filter(|(_, sh, un)| (*sh as u128) * den as u128 > num as u128 * *un as u128)
            .map(|x| x.0)
            .max()
            .unwrap_or(lo);
        assert_eq!(r.level, Some(expected), "{num}/{den}");
        let created = check_created(&s, &r, &[1, 2]);
        assert_eq!(created, r.stats.merge_level.created, "{num}/{den}");
    }
}

#[test]
fn fixed_below_top_and_proportion_levels() {
    let mut s = scene();
    let ((lo, hi), _) = reference_overlap(&s, &[1, 2]);
    let mut out = 3u8;
    for l in lo..=hi {
        let r = run(&mut s, MergeMode::Fixed(l), out);
        assert_eq!(r.level, Some(l));
        assert!(r.stats.overlap.is_empty());
        assert_eq!(check_created(&s, &r, &[1, 2]), r.stats.merge_level.created);
        out += 1;
    }
    for k in [0u8, 1, hi - lo] {
        let r = run(&mut s, MergeMode::BelowTop(k), out);
        assert_eq!(r.level, Some(lo + k));
        out += 1;
    }
    for (num, den) in [(0u32, 1u32), (1, 3), (2, 3), (1, 1)] {
        let r = run(&mut s, MergeMode::Proportion { num, den }, out);
        let expected = lo as u32 + (hi - lo) as u32 * num / den;
        assert_eq!(r.level, Some(expected as u8), "{num}/{den}");
        out += 1;
        if out > 15 {
            break;
        }
    }
    let m = |mode| golden::merge::merge(&s.store, &[1, 2], &s.table, mode, 0).unwrap_err();
    assert_eq!(
        m(MergeMode::Fixed(hi + 1)),
        MergeError::LevelNotCandidate {
            level: hi + 1,
            lo,
            hi
        }
    );
    assert_eq!(
        m(MergeMode::Fixed(lo - 1)),
        MergeError::LevelNotCandidate {
            level: lo - 1,
            lo,
            hi
        }
    );
    assert_eq!(
        m(MergeMode::BelowTop(hi - lo + 1)),
        MergeError::BelowTopTooDeep {
            k: hi - lo + 1,
            lo,
            hi
        }
    );
    for mode in [
        MergeMode::Proportion { num: 3, den: 2 },
        MergeMode::Overlap { num: 1, den: 0 },
        MergeMode::PerNode { num: 2, den: 1 },
    ] {
        assert!(matches!(m(mode), MergeError::BadRatio { .. }), "{mode:?}");
        assert!(m(mode).to_string().contains("den"));
    }
}

#[test]
fn per_node_mode_merges_at_several_levels() {
    let mut s = scene();
    // Threshold 0: descend wherever children overlap at all.
    let deep = run(&mut s, MergeMode::PerNode { num: 0, den: 1 }, 3);
    assert_eq!(deep.level, None);
    assert!(deep.stats.per_node.descents > 0, "{:?}", deep.stats);
    // Threshold 1: never descend: the same as merging at the shallowest candidate.
    let flat = run(&mut s, MergeMode::PerNode { num: 1, den: 1 }, 4);
    assert_eq!(flat.stats.per_node.descents, 0);
    let fixed = run(&mut s, MergeMode::Fixed(flat.stats.candidates.0), 5);
    assert_eq!(flat.merged.nodes, fixed.merged.nodes);
    assert_eq!(
        flat.merged
            .refs
            .iter()
            .map(|r| (r.hier == 4, r.node))
            .collect::<Vec<_>>(),
        fixed
            .merged
            .refs
            .iter()
            .map(|r| (r.hier == 5, r.node))
            .collect::<Vec<_>>()
    );
    let half = run(&mut s, MergeMode::PerNode { num: 1, den: 2 }, 6);
    // Created nodes at more than one LOD when descending stops at different depths.
    let created_lods: BTreeSet<u8> = deep
        .merged
        .nodes
        .iter()
        .filter(|n| deep.merged.children_of(n).iter().all(|c| c.hier != 3))
        .map(|n| n.voxel.lod)
        .collect();
    println!(
        "per-node created LODs {created_lods:?}, half {:?}",
        half.stats.per_node
    );
    assert!(deep.stats.per_node.deepest_created > flat.stats.candidates.0);
}
