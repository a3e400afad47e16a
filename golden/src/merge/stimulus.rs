//! Stimulus of the merging hardware's tests and long runs: random and real
//! merge cases for the record writer (8.12) and the hierarchy merger
//! (8.15), built from golden's own builder and merge steps. Test fixtures,
//! not part of the model: every value they give is checked by the units'
//! transactions, which take them as input.

use crate::build::{build, GridMap};
use crate::merge::error::MergeError;
use crate::merge::fetcher::walk::{collect, walk_input, WalkedInput};
use crate::merge::level_choice::candidate_range;
use crate::merge::merge_level::{BaseKind, BaseNode, MergeLevelCounts};
use crate::merge::per_node::{PerNode, PerNodeCounts};
use crate::params::Params;
use crate::scenes::random_soup;
use crate::store::{Hierarchy, HierarchyStore, NodeRecord, Reference};
use crate::translate::stimulus::SplitMix64;
use crate::translate::{Translation, TranslationTable};

/// A random writer case: `upper_builder::unit::random_base` (every top rule,
/// leaves above the merging level) with each created node's `count` its
/// number of references (as S614 makes it) and every reused inner node
/// pointing at a node of small synthetic stored inputs (ids from 1, never
/// `out_id`), so a materialized root has references to read. Returns the
/// base and the inputs.
pub fn random_case(
    rng: &mut crate::translate::stimulus::SplitMix64,
    p: &Params,
    n: usize,
    out_id: u8,
) -> (Vec<BaseNode>, Vec<Hierarchy>) {
    let ids: Vec<u8> = (0..p.hier_capacity())
        .map(|i| i as u8)
        .filter(|&i| i != out_id)
        .take(3)
        .collect();
    // Records per input: few, so `first` and the refs fit at small I.
    let per_input = (p.index_capacity() / 2).clamp(1, 4) as u32;
    let inputs: Vec<Hierarchy> = ids
        .iter()
        .map(|&id| synthetic_input(rng, p, id, per_input))
        .collect();
    let mut base = crate::merge::upper_builder::unit::random_base(rng, p, n);
    // Sometimes created nodes at shallower LODs too, as per-node merging
    // (8.5) makes them.
    if rng.below(3) == 0 {
        for _ in 0..1 + rng.below(3) {
            let lod = rng.below(p.max_lod as u64 + 1) as u8;
            let v = [0; 3].map(|_| rng.below(1u64 << lod) as u32);
            let refs: Vec<Reference> = (0..1 + rng.below(3))
                .map(|_| Reference {
                    hier: ids[rng.below(ids.len() as u64) as usize],
                    node: rng.below(per_input as u64) as u32,
                })
                .collect();
            let record = NodeRecord {
                leaf: false,
                voxel: crate::grid::VoxelAddr::new(lod, v[0], v[1], v[2]),
                lo: [0; 3],
                hi: [0; 3],
                first: 0,
                count: refs.len() as u32,
            };
            base.push(BaseNode {
                record,
                kind: BaseKind::Created { refs },
            });
        }
    }
    for b in &mut base {
        match &mut b.kind {
            BaseKind::Created { refs } => b.record.count = refs.len() as u32,
            BaseKind::Reused { at } if !b.record.leaf => {
                let h = &inputs[rng.below(inputs.len() as u64) as usize];
                let node = rng.below(per_input as u64) as u32;
                *at = Reference { hier: h.id, node };
                // A reused node's record carries its stored first/count.
                b.record.first = h.nodes[node as usize].first;
                b.record.count = h.nodes[node as usize].count;
            }
            BaseKind::Reused { .. } => {}
        }
    }
    (base, inputs)
}

/// An input holding `n` inner records, each with 1 or 2 references to its
/// own records (what a materialized root's references may be).
fn synthetic_input(
    rng: &mut crate::translate::stimulus::SplitMix64,
    p: &Params,
    id: u8,
    n: u32,
) -> Hierarchy {
    let mut nodes = Vec::new();
    let mut refs = Vec::new();
    for _ in 0..n {
        let count = 1 + rng.below(2) as u32;
        nodes.push(NodeRecord {
            leaf: false,
            voxel: crate::grid::VoxelAddr::new(0, 0, 0, 0),
            lo: [0; 3],
            hi: [0; 3],
            first: refs.len() as u32,
            count,
        });
        for _ in 0..count {
            refs.push(Reference {
                hier: id,
                node: rng.below(n as u64) as u32,
            });
        }
    }
    Hierarchy {
        id,
        params: *p,
        nodes,
        refs,
        prims: Vec::new(),
        root_count: 1,
        top_lod: 0,
    }
}

/// A soup hierarchy `id` of `n` triangles in the scene's `2^-3` corner.
/// Panics where the soup does not build: for tests at fixed parameters.
pub fn soup(p: &Params, id: u8, n: usize, size: f32, seed: u64) -> Hierarchy {
    try_soup(p, id, n, size, seed).expect("the soup builds")
}

/// [`soup`], or why it does not build at `p` (for example more records
/// than `index_bits` can number): for stimulus at parameters a user chose.
pub fn try_soup(
    p: &Params,
    id: u8,
    n: usize,
    size: f32,
    seed: u64,
) -> Result<Hierarchy, crate::build::BuildError> {
    let mesh = random_soup(n, size, seed);
    let (lo, hi) = mesh.bounds();
    let fitted = GridMap::fit(lo, hi, p);
    let grid = GridMap {
        origin: fitted.origin * 0.0,
        unit: 1.0 / (p.scene_edge() >> 3) as f64,
    };
    build(&mesh, &grid, p, id)
}

/// A translation at `h`'s top LOD by `frac` of the room left.
pub fn place(h: &Hierarchy, frac: [f64; 3]) -> Translation {
    let l = h.top_lod;
    let max = [0, 1, 2].map(|a| {
        h.roots()
            .iter()
            .map(|n| [n.voxel.x, n.voxel.y, n.voxel.z][a] as i64)
            .max()
            .unwrap_or(0)
    });
    let room = [0, 1, 2].map(|a| (1i64 << l) - 1 - max[a]);
    Translation {
        lod: l,
        t: [0, 1, 2].map(|a| (room[a] as f64 * frac[a]) as i64),
    }
}

/// S610-S614 in per-node mode (8.5) as `merge` runs them: the reused
/// leaves above `lo`, then the per-node decider's base (created and reused
/// nodes at several LODs).
pub fn per_node_base(
    inputs: &[(&Hierarchy, Translation)],
    num: u32,
    den: u32,
    p: &Params,
) -> Result<Vec<BaseNode>, MergeError> {
    let hs: Vec<&Hierarchy> = inputs.iter().map(|(h, _)| *h).collect();
    let ts: Vec<Translation> = inputs.iter().map(|(_, t)| *t).collect();
    let (lo, _) = candidate_range(&hs);
    let walked: Vec<WalkedInput> = inputs
        .iter()
        .enumerate()
        .map(|(r, (h, t))| walk_input(h, r as u16, t, lo))
        .collect::<Result<_, _>>()?;
    let (above, first) = collect(&walked, lo);
    let mut base: Vec<BaseNode> = above.iter().map(BaseNode::reused).collect();
    let decider = PerNode {
        inputs: &hs,
        translations: &ts,
        params: *p,
        num,
        den,
    };
    let mut counts = MergeLevelCounts::default();
    base.extend(decider.merge_from(first, &mut counts, &mut PerNodeCounts::default())?);
    Ok(base)
}

/// Real merges for the writer's and the merger's tests (golden here, RTL in
/// cosim): stored soups: overlapping, disjoint, single-triangle inputs with
/// a big one, one input alone, two overlapping in part; the store, the
/// table and the input ids of each case.
/// Fails, naming why, where the parameters cannot hold the soups.
pub fn real_cases(p: &Params) -> Result<Vec<RealCase>, String> {
    let soup = |id: u8, n: usize, size: f32, seed: u64| {
        try_soup(p, id, n, size, seed).map_err(|e| {
            format!(
                "a soup of {n} triangles does not build at D = {}, I = {}: {e}",
                p.max_lod, p.index_bits
            )
        })
    };
    let same = [0.4, 0.5, 0.6];
    let hs = (1..=3)
        .map(|i| soup(i, 60, 0.2, i as u64))
        .collect::<Result<Vec<Hierarchy>, String>>()?;
    let overlapping: Vec<(Hierarchy, Translation)> =
        hs.iter().map(|h| (h.clone(), place(h, same))).collect();
    let disjoint: Vec<(Hierarchy, Translation)> = hs
        .iter()
        .enumerate()
        .map(|(i, h)| {
            let f = [0.1 + 0.3 * i as f64, 0.9 - 0.3 * i as f64, 0.3];
            (h.clone(), place(h, f))
        })
        .collect();
    let mut single = (1..=2)
        .map(|i| {
            let h = soup(i, 1, 0.001, 10 + i as u64)?;
            let t = place(&h, if i < 2 { same } else { [0.9, 0.1, 0.2] });
            Ok((h, t))
        })
        .collect::<Result<Vec<(Hierarchy, Translation)>, String>>()?;
    let big = soup(3, 80, 0.3, 99)?;
    single.push((big.clone(), place(&big, same)));
    // One input alone: its root is reused at the top (materialized).
    let alone = vec![(big.clone(), place(&big, same))];
    // Two inputs overlapping in part: per-node merging creates nodes at
    // several LODs.
    let partial: Vec<(Hierarchy, Translation)> = hs[..2]
        .iter()
        .zip([[0.4, 0.5, 0.6], [0.45, 0.5, 0.6]])
        .map(|(h, f)| (h.clone(), place(h, f)))
        .collect();
    [overlapping, disjoint, single, alone, partial]
        .into_iter()
        .map(|case| {
            let mut store = HierarchyStore::new();
            let mut table = TranslationTable::new(p.hier_capacity() as usize, p)
                .map_err(|e| format!("translation table: {e}"))?;
            let ids = case.iter().map(|(h, _)| h.id).collect();
            for (h, t) in case {
                table
                    .write(h.id as u32, t)
                    .map_err(|e| format!("translation of hierarchy {}: {e}", h.id))?;
                store.insert(h).map_err(|e| format!("store: {e}"))?;
            }
            Ok((store, table, ids))
        })
        .collect()
}

/// One case of [`real_cases`]: the store, the table and the input ids.
pub type RealCase = (HierarchyStore, TranslationTable, Vec<u8>);

/// A soup of `n` triangles with the grid fitted to it, so it fills the
/// scene: its LOD-0 root gives way to several roots (4.7).
pub fn try_scene_soup(
    p: &Params,
    id: u8,
    n: usize,
    size: f32,
    seed: u64,
) -> Result<Hierarchy, crate::build::BuildError> {
    let mesh = random_soup(n, size, seed);
    let (lo, hi) = mesh.bounds();
    build(&mesh, &GridMap::fit(lo, hi, p), p, id)
}

/// The several-roots case: `big` (id 1, filling the scene, untranslated)
/// beside `small` (id 2, placed at (0.7, 0.2, 0.5) of its room), the
/// inputs in the order `ids`.
pub fn several_roots_case(
    p: &Params,
    big: Hierarchy,
    small: Hierarchy,
    ids: Vec<u8>,
) -> Result<RealCase, String> {
    let mut store = HierarchyStore::new();
    let mut table = TranslationTable::new(p.hier_capacity() as usize, p)
        .map_err(|e| format!("translation table: {e}"))?;
    let at = |e: crate::translate::TranslateError| format!("translation: {e}");
    table.write(1, Translation::zero(big.top_lod)).map_err(at)?;
    table.write(2, place(&small, [0.7, 0.2, 0.5])).map_err(at)?;
    store.insert(big).map_err(|e| format!("store: {e}"))?;
    store.insert(small).map_err(|e| format!("store: {e}"))?;
    Ok((store, table, ids))
}

// The random draws every stage's stimulus uses.

pub(crate) fn random_coord(rng: &mut SplitMix64, lod: u8) -> u32 {
    let n = 1u64 << lod;
    match rng.below(8) {
        0 => 0,
        1 => (n - 1) as u32,
        _ => rng.below(n) as u32,
    }
}

pub(crate) fn random_box(rng: &mut SplitMix64, p: &Params) -> ([u16; 3], [u16; 3]) {
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

pub(crate) fn random_index(rng: &mut SplitMix64, p: &Params, at_least: u64) -> u32 {
    let cap = p.index_capacity();
    match rng.below(4) {
        0 => (cap - 1) as u32,
        _ => rng.below(cap - at_least).saturating_add(at_least) as u32,
    }
}
