//! The hierarchy merger's hard merges: the named cases a run of
//! [`Merges::Hard`] sends before its random merges over every scale, and
//! that the merger tests run on every engine. Each is a golden transaction
//! like a random merge's, so a bench checks it bit for bit.

use crate::build::quantize::child_cells_in_parent;
use crate::build::{build, BuildError, GridMap};
use crate::grid::VoxelAddr;
use crate::merge::fetcher::{
    fetch_err, fetch_transaction_with_reports, FetchCfg, FetchOut, FetchTransaction,
};
use crate::merge::level_choice::candidate_range;
use crate::merge::merger::MergerSizes;
use crate::merge::merger::{
    merger_transaction, merger_transaction_in_range, MergerTransaction, ModulePass,
};
use crate::merge::stimulus::{
    place, real_cases, several_roots_case, try_scene_soup, try_soup, RealCase,
};
use crate::mesh::Mesh;
use crate::params::Params;
use crate::scenes::push_triangle;
use crate::scenes::random_soup;
use crate::store::{Hierarchy, HierarchyStore, NodeRecord, Reference};
use crate::translate::stimulus::SplitMix64;
use crate::translate::{Translation, TranslationTable};
use glam::{DVec3, Vec3};

#[cfg(doc)]
use super::streams::Merges;
use crate::merge::merge_module::MergeDesign;

fn golden_err(what: impl std::fmt::Display) -> String {
    format!("hard merges: {what}")
}

type Result<T> = std::result::Result<T, String>;

/// The hard merges of a merger and what the list holds.
#[derive(Clone, Debug, Default)]
pub struct HardMerges {
    /// In the order a run sends them.
    pub merges: Vec<MergerTransaction>,
    /// Merges left out because a FIFO drops what golden does not model
    /// ([`MergerTransaction::exact`]: per-node mode's nodes).
    pub overflowing: usize,
    /// Merges whose leaves overflow a leaf FIFO (`leaf_overflow`), expected
    /// bit for bit with the leaves the FIFOs keep
    /// ([`kept_leaves`](crate::merge::merger::kept_leaves)).
    pub leaf_overflows: usize,
    /// Merges with an input of several roots.
    pub several_root_inputs: usize,
}

/// The fetcher errors of the hard merges, one merge each: those the
/// fetcher finds in its `cfg` beat before any store read (8.13: an invalid
/// translation entry, a `root_count` of 0 or above `nodes`, more roots than
/// the root sorter holds), so the input sends its error beat and `End`s and
/// the rest is golden's merge of the other inputs, bit for bit. The other
/// codes (`RECORD` to `ORDER`) are met mid-walk, after store reads: that
/// input's level streams stop at the error with part of its nodes already
/// sent, and golden's merger chain refuses such an input (`fetch_passes`)
/// rather than model a merge of truncated streams, so no merge can expect
/// them bit for bit (the fetcher's own tests check every code).
pub const CFG_ERRORS: [u64; 3] = [
    fetch_err::ENTRY,
    fetch_err::ROOT_COUNT,
    fetch_err::ROOT_CAPACITY,
];

/// The hard merges of the merger `d` (sizes `sizes`): the real cases of `golden::merge::stimulus`
/// (overlapping, disjoint, single-triangle soups, one input alone, inputs
/// overlapping in part), an input filling the scene (several roots), one
/// whose top holds 16 roots (a leaf and an inner node in each LOD-1
/// voxel: every entry of the default root sorter), the same stored in
/// reverse (every entry of the sorter moves), sixteen roots at LOD 5
/// stored against Morton order, [`ROOT_CUTS`] merges of soups cut into up to
/// as many roots as the sorter holds, in a random order (`root_cuts`),
/// a ladder of leaves
/// at every LOD above the merging level, an input stored depth first
/// with indices near `2^I`, three merges of two inputs under LOD-0 roots
/// (the merged top at LOD 0), the deep tops and the deep clusters, each
/// through `d`'s mode, and at their end the capacity clusters
/// (`capacity_clusters`: levels of hundreds of nodes, which a writer of
/// `2^5` entries a buffer refuses) and, at `I = 12` and less, the huge
/// clusters (`huge_clusters`: levels of a thousand nodes and more); per code of [`CFG_ERRORS`] a merge
/// whose last input's `cfg` makes its fetcher refuse it, and one whose first input's
/// entry is invalid; and two bad ranges from
/// software, which the merging module refuses (`lo > hi`, `hi > D`), on
/// the first case of the most inputs; and a flood of leaves ([`leaf_flood`])
/// that overflows the leaf FIFOs of five LODs, and one from two inputs
/// ([`flood_of_two`]) at LOD 2. Merges of more than `k`
/// inputs, and those golden does not model bit for bit
/// ([`MergerTransaction::exact`]: per-node mode's FIFOs dropping nodes),
/// are left out.
pub fn hard_merges(d: &MergeDesign, sizes: MergerSizes) -> Result<HardMerges> {
    let p = &d.params;
    let k = d.inputs;
    let out_id = out_id(p);
    let mut out = HardMerges::default();
    let mut cases = real_cases(p).map_err(golden_err)?;
    cases.push(several_roots(p)?);
    cases.push(sixteen_roots(p)?);
    cases.push(sixteen_roots_reversed(p)?);
    cases.push(leaf_ladder(p)?);
    cases.push(depth_first_store(p)?);
    cases.extend(sixteen_deep_roots(p)?);
    cases.extend(root_cuts(p, d.roots)?);
    cases.extend(lod0_tops(p)?);
    cases.retain(|(_, _, ids)| ids.len() <= k);
    for (store, table, ids) in &cases {
        let tx =
            merger_transaction(store, table, ids, d.mode, out_id, k, sizes).map_err(golden_err)?;
        if !tx.exact {
            out.overflowing += 1;
            continue;
        }
        out.leaf_overflows += tx.header.leaf_overflow as usize;
        out.several_root_inputs +=
            ids.iter()
                .any(|i| store.get(*i).is_some_and(|h| h.root_count > 1)) as usize;
        out.merges.push(tx);
    }
    let floods = leaf_floods(p, sizes.leaf_bits)?;
    for (store, table, ids) in deep_cases(p)?
        .iter()
        .chain(&floods)
        .chain(&capacity_clusters(p)?)
        .chain(&huge_clusters(p)?)
        .filter(|c| c.2.len() <= k)
    {
        let tx =
            merger_transaction(store, table, ids, d.mode, out_id, k, sizes).map_err(golden_err)?;
        if !tx.exact {
            out.overflowing += 1;
        } else {
            out.leaf_overflows += tx.header.leaf_overflow as usize;
            out.merges.push(tx);
        }
    }
    // Each code on the last input, and an invalid entry on the first
    // (`fetch_rank` 0).
    let errors = CFG_ERRORS.into_iter().map(|code| (code, usize::MAX));
    for (code, rank) in errors.chain([(fetch_err::ENTRY, 0)]).rev() {
        for (store, table, ids) in &cases {
            let rank = rank.min(ids.len().saturating_sub(1));
            if let Some(tx) = cfg_error_merge(d, sizes, store, table, ids, (code, rank))? {
                out.merges.insert(1.min(out.merges.len()), tx);
                break;
            }
        }
    }
    // The bad ranges on the first case of the most inputs: a refused merge
    // sends each used input its closing command.
    let most = cases.iter().map(|c| c.2.len()).max();
    let Some((store, table, ids)) = cases.iter().find(|c| Some(c.2.len()) == most) else {
        return Ok(out);
    };
    // `hi > D` when the field holds it (not at D = 31: 5 bits).
    let beyond = if (1u64 << p.lod_bits()) - 1 > p.max_lod as u64 {
        (2, p.max_lod + 1)
    } else {
        (5, 2)
    };
    for range in [(4, 3), beyond] {
        let tx =
            merger_transaction_in_range(store, table, ids, d.mode, out_id, k, sizes, Some(range))
                .map_err(golden_err)?;
        out.merges.insert(1.min(out.merges.len()), tx);
    }
    Ok(out)
}

/// The merged hierarchy's id of every hard merge.
pub fn out_id(p: &Params) -> u8 {
    (9 % p.hier_capacity()) as u8
}

/// The named cases of [`hard_merges`] whose inputs are all valid, in its
/// order: the real cases, an input filling the scene, the 16-root input,
/// the leaf ladder, the depth-first store, the sixteen deep roots, the
/// root cuts, the deep tops and clusters, the capacity clusters, those of at most `k`
/// inputs (what the hierarchy unit's hard merges write into its table by determine
/// commands: a case's translations are its table's).
pub fn hard_cases(d: &MergeDesign) -> Result<Vec<RealCase>> {
    let p = &d.params;
    let mut cases = real_cases(p).map_err(golden_err)?;
    cases.push(several_roots(p)?);
    cases.push(sixteen_roots(p)?);
    cases.push(leaf_ladder(p)?);
    cases.push(depth_first_store(p)?);
    cases.extend(sixteen_deep_roots(p)?);
    cases.extend(root_cuts(p, d.roots)?);
    cases.extend(lod0_tops(p)?);
    cases.extend(deep_cases(p)?);
    cases.extend(capacity_clusters(p)?);
    cases.extend(huge_clusters(p)?);
    cases.retain(|(_, _, ids)| ids.len() <= d.inputs);
    Ok(cases)
}

/// Two inputs filling the scene, each under a LOD-0 root: `lo` is 0, so
/// the merge may choose LOD 0, and its merged top is then the created
/// LOD-0 node. The builder drops a LOD-0 root at Q = 0 (4.7: it always
/// covers more than half the scene there), but a store may hold one: no
/// built input reaches a top at LOD 0 at Q = 0, nor the upper builder's and
/// the writer's LOD-0 levels.
/// Three such merges, of 10, 3 and 6 triangles an input, so that the
/// LOD-0 records' fields take several values.
fn lod0_tops(p: &Params) -> Result<Vec<RealCase>> {
    let input = |id: u8, n: usize, seed: u64| -> Result<(Hierarchy, Translation)> {
        let h = under_lod0_root(try_scene_soup(p, id, n, 0.3, seed).map_err(golden_err)?);
        let top = h.top_lod;
        Ok((h, Translation::zero(top)))
    };
    [(10, 91), (3, 93), (6, 95)]
        .into_iter()
        .map(|(n, seed)| case_of(p, vec![input(1, n, seed)?, input(2, n, seed + 1)?]))
        .collect()
}

/// `h` with its top at LOD 1 put under one LOD-0 root whose children are
/// its roots (`h` unchanged at any other top): the root first in `nodes`
/// and its references first in `refs`, every other index moved along; the
/// root's box the roots' boxes in its own cells, as a grouping makes it.
fn under_lod0_root(h: Hierarchy) -> Hierarchy {
    if h.top_lod != 1 {
        return h;
    }
    let roots = h.root_count;
    let q = h.params.quant_bits;
    let (mut lo, mut hi) = ([u16::MAX; 3], [0u16; 3]);
    for r in h.roots() {
        let odd = [r.voxel.x & 1 == 1, r.voxel.y & 1 == 1, r.voxel.z & 1 == 1];
        for a in 0..3 {
            let (l, u) = child_cells_in_parent(r.lo[a], r.hi[a], odd[a], q);
            lo[a] = lo[a].min(l);
            hi[a] = hi[a].max(u);
        }
    }
    let root = NodeRecord {
        leaf: false,
        voxel: VoxelAddr::new(0, 0, 0, 0),
        lo,
        hi,
        first: 0,
        count: roots,
    };
    let moved = |n: &NodeRecord| NodeRecord {
        first: n.first + if n.leaf { 0 } else { roots },
        ..*n
    };
    let refs = (0..roots)
        .map(|i| Reference {
            hier: h.id,
            node: 1 + i,
        })
        .chain(h.refs.iter().map(|r| Reference {
            node: r.node + 1,
            ..*r
        }))
        .collect();
    Hierarchy {
        nodes: std::iter::once(root)
            .chain(h.nodes.iter().map(moved))
            .collect(),
        refs,
        root_count: 1,
        top_lod: 0,
        ..h
    }
}

/// The deep tops, then the deep clusters.
fn deep_cases(p: &Params) -> Result<Vec<RealCase>> {
    let mut cases = deep_tops(p)?;
    cases.extend(deep_clusters(p)?);
    Ok(cases)
}

/// Merges whose top lies at the deepest LODs, which the soups of the other
/// cases (spread over the scene's `2^-3` corner) never reach
/// ([`tops_across_voxels`] of one tiny triangle: the top at its own LOD `t`
/// and at the four LODs above). So the upper builder's and the writer's
/// deepest levels hold the top.
fn deep_tops(p: &Params) -> Result<Vec<RealCase>> {
    let tiny = |id: u8| try_soup(p, id, 1, 0.001, 21).map_err(golden_err);
    tops_across_voxels(p, tiny(1)?, tiny(2)?)
}

/// Per `c` in `D - 4..D - 1` (`c >= 1`), two small soups filling the same
/// LOD-`c` voxel: the merged top at `c`, and created records at every LOD
/// from it down to the merging level, several per LOD, where the deep
/// tops' single triangles write one. (At `c = D - 1` the merging level is
/// `D - 1` too, and its one created node is all that is written.)
fn deep_clusters(p: &Params) -> Result<Vec<RealCase>> {
    let lods = p.max_lod.saturating_sub(4).max(1)..p.max_lod.saturating_sub(1);
    clusters(p, lods, 8, [31, 32])
}

/// Per `c` in `D - 5..D` (`c >= 1`), two soups of 128 triangles filling
/// the same LOD-`c` voxel: hundreds of nodes an input, far more a level
/// than any other case, so the indices within a level, the records'
/// `first` and `count` and the builder's and the writer's level counters
/// set their upper bits. Where a level holds more than the writer's `2^C`
/// entries the writer refuses the merge (`CAPACITY`), after the fetchers,
/// the module and the builder have run it whole.
fn capacity_clusters(p: &Params) -> Result<Vec<RealCase>> {
    clusters(
        p,
        p.max_lod.saturating_sub(5).max(1)..p.max_lod,
        128,
        [41, 42],
    )
}

/// Per `c` in `D - 5..D` (`c >= 1`), two soups of [`HUGE_TRIANGLES`]
/// triangles filling the same LOD-`c` voxel, at `I = 12` and less: at D = 8
/// inputs of up to 1,277 nodes and 3,693 prims, levels of up to 469 nodes
/// an input, so the leaves' `first`, the node indices and references, and
/// the levels' indices and the builder's counters set upper bits of 12-bit
/// fields that the capacity clusters' hundreds leave clear (the writer of
/// `2^5` entries refuses most as `CAPACITY`, after the fetchers, the module
/// and the builder have run them whole). None above `I = 12`, where they
/// would not reach the upper bits and their levels would cost Icarus
/// minutes a run; a cluster that outgrows the index at its `D` is left out.
fn huge_clusters(p: &Params) -> Result<Vec<RealCase>> {
    if p.index_bits > HUGE_MOST_INDEX_BITS {
        return Ok(Vec::new());
    }
    let mut out = Vec::new();
    for c in p.max_lod.saturating_sub(5).max(1)..p.max_lod {
        match cluster(p, c, HUGE_TRIANGLES, [51, 52]) {
            Ok(inputs) => out.push(case_of(p, inputs)?),
            Err(BuildError::IndexOverflow { .. }) => {}
            Err(e) => return Err(golden_err(e)),
        }
    }
    Ok(out)
}

/// Triangles of each soup of `huge_clusters`: their prims fit `2^12`
/// indices at D = 8 (1,500 give 5,315).
pub const HUGE_TRIANGLES: usize = 1000;

/// The widest index `huge_clusters` are made for.
pub const HUGE_MOST_INDEX_BITS: u8 = 12;

/// Per `c` in `lods`, a case of two soups of `triangles` triangles each
/// (drawn from `seeds`) in the LOD-`c` voxel at the scene's corner.
fn clusters(
    p: &Params,
    lods: std::ops::Range<u8>,
    triangles: usize,
    seeds: [u64; 2],
) -> Result<Vec<RealCase>> {
    lods.map(|c| case_of(p, cluster(p, c, triangles, seeds).map_err(golden_err)?))
        .collect()
}

/// The two inputs of one case of [`clusters`]: soups of `triangles`
/// triangles (drawn from `seeds`) in the LOD-`c` voxel at the scene's
/// corner, untranslated.
fn cluster(
    p: &Params,
    c: u8,
    triangles: usize,
    seeds: [u64; 2],
) -> std::result::Result<Vec<(Hierarchy, Translation)>, BuildError> {
    let grid = corner_grid(p, c);
    [(1u8, seeds[0]), (2, seeds[1])]
        .into_iter()
        .map(|(id, seed)| {
            let h = build(&random_soup(triangles, 0.3, seed), &grid, p, id)?;
            let t = Translation::zero(h.top_lod);
            Ok((h, t))
        })
        .collect()
}

/// A case of `inputs`, each written into the table with its translation,
/// merged in the order given.
fn case_of(p: &Params, inputs: Vec<(Hierarchy, Translation)>) -> Result<RealCase> {
    let mut store = HierarchyStore::new();
    let mut table = TranslationTable::new(p.hier_capacity() as usize, p).map_err(golden_err)?;
    let ids = inputs.iter().map(|(h, _)| h.id).collect();
    for (h, tr) in inputs {
        table.write(h.id as u32, tr).map_err(golden_err)?;
        store.insert(h).map_err(golden_err)?;
    }
    Ok((store, table, ids))
}

/// `a` alone at its own top LOD `t`, and per `L` in `t - 4..t` (`L >= 1`)
/// `a` and `b` one voxel apart at LOD `t` across the boundary of two
/// LOD-`(L + 1)` voxels, so that their common ancestor, the merged top,
/// is at LOD `L`.
fn tops_across_voxels(p: &Params, a: Hierarchy, b: Hierarchy) -> Result<Vec<RealCase>> {
    let t = a.top_lod;
    let Some(root) = a.roots().first().map(|n| n.voxel) else {
        return Ok(Vec::new());
    };
    let at = |x: i64| Translation {
        lod: t,
        t: [
            x - root.x as i64,
            (1 << (t - 1)) - root.y as i64,
            (1 << (t - 1)) - root.z as i64,
        ],
    };
    let case = |inputs| case_of(p, inputs);
    if t < 2 {
        return Ok(Vec::new());
    }
    let half = 1i64 << (t - 1);
    let mut out = vec![case(vec![(a.clone(), at(half))])?];
    for l in (t.saturating_sub(4).max(1)..t).rev() {
        // The last voxel of a LOD-(l + 1) voxel and the first of the next.
        let x = half + (1i64 << (t - l - 1)) - 1;
        out.push(case(vec![(a.clone(), at(x)), (b.clone(), at(x + 1))])?);
    }
    Ok(out)
}

/// An input filling the scene (its LOD-0 root gives way to several roots
/// at LOD 1, 4.7) and a small translated one.
fn several_roots(p: &Params) -> Result<RealCase> {
    let big = try_scene_soup(p, 1, 60, 0.3, 77).map_err(golden_err)?;
    let small = try_soup(p, 2, 20, 0.2, 78).map_err(golden_err)?;
    several_roots_case(p, big, small, vec![1, 2]).map_err(golden_err)
}

/// A triangle of edge 0.3 near the low corner of each octant of the unit
/// cube and a small one inside it: built fitted to the cube, each LOD-1
/// voxel holds a leaf (the large triangle) and an inner node (the small
/// one's), and the top rule (4.7) puts the top at LOD 1 with all 16 as
/// roots. Beside a small soup, as [`several_roots`].
fn sixteen_roots(p: &Params) -> Result<RealCase> {
    let mut m = Mesh::default();
    for o in 0..8u32 {
        let bit = |b: u32| ((o >> b) & 1) as f32 * 0.5;
        let c = Vec3::new(bit(0), bit(1), bit(2)) + Vec3::splat(0.05);
        push_triangle(
            &mut m,
            c,
            c + Vec3::new(0.3, 0.0, 0.0),
            c + Vec3::new(0.0, 0.3, 0.3),
        );
        let s = c + Vec3::splat(0.2);
        push_triangle(
            &mut m,
            s,
            s + Vec3::new(0.01, 0.0, 0.0),
            s + Vec3::new(0.0, 0.01, 0.0),
        );
    }
    let (lo, hi) = m.bounds();
    let big = build(&m, &GridMap::fit(lo, hi, p), p, 1).map_err(golden_err)?;
    let small = try_soup(p, 2, 20, 0.2, 78).map_err(golden_err)?;
    several_roots_case(p, big, small, vec![1, 2]).map_err(golden_err)
}

/// [`sixteen_roots`] with the 16 roots stored in reverse: Morton order
/// descending, each voxel's leaf before its inner node. A builder never
/// stores them so (4.8), and a translation keeps roots in order (they lie
/// at LOD 1, and every one moves by the same `t`); a store written by other
/// software may, and the fetcher's root sorter (paragraph 107) orders them
/// again, so the merge is [`sixteen_roots`]'s. Every root that arrives
/// moves every one the sorter holds.
fn sixteen_roots_reversed(p: &Params) -> Result<RealCase> {
    let (store, _, ids) = sixteen_roots(p)?;
    let missing = |id: u8| golden_err(format!("the 16-root case has no input {id}"));
    let mut big = store.get(1).ok_or_else(|| missing(1))?.clone();
    let small = store.get(2).ok_or_else(|| missing(2))?.clone();
    big.nodes[..big.root_count as usize].reverse();
    several_roots_case(p, big, small, ids).map_err(golden_err)
}

/// A tiny triangle alone (its top at its own deep LOD `t`, as in
/// [`deep_tops`]) beside a ladder of triangles whose edges halve from 0.5
/// of the scene, one per LOD: the range starts at `t`, so the merging
/// level is `t` and the ladder's leaves above it, one LOD each, fill the
/// leaf FIFOs of every LOD from 1 to `t - 1` (no leaf lies at LOD 0, 4.2).
fn leaf_ladder(p: &Params) -> Result<RealCase> {
    let tiny = try_soup(p, 1, 1, 0.001, 21).map_err(golden_err)?;
    let mut m = Mesh::default();
    let (mut edge, mut x) = (0.5f32, 0.0f32);
    for _ in 0..p.max_lod {
        let c = Vec3::new(x, 0.0, 0.0);
        push_triangle(
            &mut m,
            c,
            c + Vec3::new(edge, 0.0, 0.0),
            c + Vec3::new(0.0, edge, edge * 0.5),
        );
        x += edge * 0.5 + 0.001;
        edge *= 0.5;
    }
    let (lo, hi) = m.bounds();
    let ladder = build(&m, &GridMap::fit(lo, hi, p), p, 2).map_err(golden_err)?;
    let mut store = HierarchyStore::new();
    let mut table = TranslationTable::new(p.hier_capacity() as usize, p).map_err(golden_err)?;
    table
        .write(1, place(&tiny, [0.5, 0.5, 0.5]))
        .map_err(golden_err)?;
    table
        .write(2, Translation::zero(ladder.top_lod))
        .map_err(golden_err)?;
    store.insert(tiny).map_err(golden_err)?;
    store.insert(ladder).map_err(golden_err)?;
    Ok((store, table, vec![1, 2]))
}

/// The largest `leaf_bits` [`leaf_flood`] floods: `2^8 + 2` triangles a
/// lattice.
pub const FLOOD_MOST_LEAF_BITS: u32 = 8;

/// The lattices of [`leaf_flood`], each half the scale of the one before:
/// leaves at as many consecutive LODs (at D = 8 and `leaf_bits` 4 or 6, LODs
/// 3 to 7: every LOD whose voxels outnumber a FIFO, above the tiny soup's).
pub const FLOOD_LATTICES: usize = 5;

/// A flood of leaves: [`FLOOD_LATTICES`] lattices of `2^leaf_bits + 2`
/// triangles each, the triangles of a lattice of one size and each a leaf of
/// its own voxel, every lattice at half the scale of the one before, so at
/// the next LOD; merged with a tiny deep soup, so the merging level lies
/// below them and the leaf FIFO of each lattice's LOD receives two leaves
/// more than it holds (`leaf_overflow`; the FIFO keeps the first
/// `2^leaf_bits`). None when `leaf_bits` is above [`FLOOD_MOST_LEAF_BITS`].
pub fn leaf_flood(p: &Params, leaf_bits: u32) -> Result<Option<RealCase>> {
    if leaf_bits > FLOOD_MOST_LEAF_BITS {
        return Ok(None);
    }
    let n = (1usize << leaf_bits) + 2;
    let side = (1..).find(|s| s * s * s >= n).unwrap_or(n);
    let mut m = Mesh::default();
    // The first lattice (step 2) at the origin, `2 side` a side; the others
    // on it (`y` from `2 side`), side by side along `x` (less than `2 side`
    // together): all within `3 side`.
    let mut origin = Vec3::ZERO;
    for j in 0..FLOOD_LATTICES {
        let step = 2.0f32.powi(1 - j as i32);
        for i in 0..n {
            let (x, y, z) = (i % side, i / side % side, i / (side * side));
            // 0.6 of a lattice step and 0.2 from its corner: no two
            // triangles share a voxel of the LOD they sit at.
            let c =
                origin + Vec3::new(x as f32, y as f32, z as f32) * step + Vec3::splat(0.2 * step);
            push_triangle(
                &mut m,
                c,
                c + Vec3::new(0.6 * step, 0.0, 0.0),
                c + Vec3::new(0.0, 0.6 * step, 0.3 * step),
            );
        }
        origin = match j {
            0 => Vec3::new(0.0, 2.0 * side as f32, 0.0),
            _ => origin + Vec3::new(side as f32 * step, 0.0, 0.0),
        };
    }
    // Origin 0 and a power-of-two unit: every lattice step is a voxel edge
    // and every lattice origin a multiple of it.
    let map = GridMap::fit(Vec3::ZERO, Vec3::splat(3.0 * side as f32), p);
    let lattices = build(&m, &map, p, 1).map_err(golden_err)?;
    let tiny = try_soup(p, 2, 1, 0.001, 21).map_err(golden_err)?;
    let top = lattices.top_lod;
    let placed = place(&tiny, [0.5, 0.5, 0.5]);
    case_of(p, vec![(lattices, Translation::zero(top)), (tiny, placed)]).map(Some)
}

/// The LOD both inputs of [`flood_of_two`] flood: the first of more voxels
/// (64) than the leaf FIFOs of the long runs' small configuration hold
/// (`2^6`) whose leaves one input alone cannot overflow.
pub const FLOOD_OF_TWO_LOD: u8 = 2;

/// Leaves each input of [`flood_of_two`] brings to LOD
/// [`FLOOD_OF_TWO_LOD`]: three layers of its 4 x 4 voxels.
pub const FLOOD_OF_TWO_LEAVES: usize = 48;

/// A flood of one LOD's leaf FIFO by two inputs, where [`leaf_flood`]'s one
/// input cannot: at LOD [`FLOOD_OF_TWO_LOD`] (64 voxels), one input brings
/// at most 64 leaves, so a FIFO of `2^6` overflows only from both. Each
/// input is a lattice of [`FLOOD_OF_TWO_LEAVES`] triangles, each a leaf of
/// its own LOD-2 voxel (the first input's in the voxel layers `z` 0 to 2,
/// the second's `z` 1 to 3), and a tiny triangle at the same place in
/// both, so the two inputs share one voxel at every LOD from 3 down to the
/// tiny triangle's, the merging level lies there, and the 96 leaves above
/// it enter LOD 2's FIFO.
/// Both are built on one grid (the unit cube), untranslated.
pub fn flood_of_two(p: &Params) -> Result<RealCase> {
    let edge = 0.5f32.powi(FLOOD_OF_TWO_LOD as i32);
    let input = |id: u8, z0: usize| -> Result<(Hierarchy, Translation)> {
        let mut m = Mesh::default();
        for i in 0..FLOOD_OF_TWO_LEAVES {
            let (x, y, z) = (i % 4, i / 4 % 4, z0 + i / 16);
            // As the leaf flood's: 0.6 of a voxel, 0.2 from its corner.
            let c = Vec3::new(x as f32, y as f32, z as f32) * edge + Vec3::splat(0.2 * edge);
            push_triangle(
                &mut m,
                c,
                c + Vec3::new(0.6 * edge, 0.0, 0.0),
                c + Vec3::new(0.0, 0.6 * edge, 0.3 * edge),
            );
        }
        // Near the high corner of a voxel, away from its lattice triangle.
        let t = Vec3::splat(0.95 * edge);
        push_triangle(
            &mut m,
            t,
            t + Vec3::new(0.001, 0.0, 0.0),
            t + Vec3::new(0.0, 0.001, 0.0),
        );
        let h = build(&m, &GridMap::fit(Vec3::ZERO, Vec3::ONE, p), p, id).map_err(golden_err)?;
        let top = h.top_lod;
        Ok((h, Translation::zero(top)))
    };
    case_of(p, vec![input(1, 0)?, input(2, 1)?])
}

/// Both floods for leaf FIFOs of `2^leaf_bits`, in the order the hard
/// merges send them: [`leaf_flood`] (when `leaf_bits` allows it), then
/// [`flood_of_two`].
pub fn leaf_floods(p: &Params, leaf_bits: u32) -> Result<Vec<RealCase>> {
    let mut floods: Vec<RealCase> = leaf_flood(p, leaf_bits)?.into_iter().collect();
    floods.push(flood_of_two(p)?);
    Ok(floods)
}

/// Triangle counts of [`depth_first_store`]'s dense input, largest first:
/// the first whose records `I` can number is taken (1,200 gives about
/// 2,600 records, which at `I = 12` reach index bit 11).
const DEPTH_FIRST_TRIANGLES: [usize; 5] = [1200, 300, 60, 12, 1];

/// A dense input stored depth first ([`stored_depth_first`]) beside a small
/// soup over it. Its triangles fill the LOD-`(D - 4)` corner voxel, so the
/// fetcher's walk above the merging level stays four levels from the
/// leaves and narrow, while the store holds every record below: the
/// indices the fetcher reads (the top's `first`, the reused nodes'
/// references) come near `2^I`, where a builder's store (level by level,
/// 4.8) keeps them small for any input whose walk fits the frontier.
fn depth_first_store(p: &Params) -> Result<RealCase> {
    let (_, _, dense) = dense_corner(p)?;
    let small = try_soup(p, 2, 20, 0.2, 78).map_err(golden_err)?;
    let (tr_dense, tr_small) = (Translation::zero(dense.top_lod), place(&small, [0.1; 3]));
    case_of(
        p,
        vec![(stored_depth_first(&dense), tr_dense), (small, tr_small)],
    )
}

/// [`depth_first_store`]'s dense input as the builder stores it, with its
/// mesh and grid: the largest soup of [`DEPTH_FIRST_TRIANGLES`] that fits.
fn dense_corner(p: &Params) -> Result<(Mesh, GridMap, Hierarchy)> {
    let grid = corner_grid(p, p.max_lod.saturating_sub(4));
    DEPTH_FIRST_TRIANGLES
        .into_iter()
        .find_map(|n| {
            let mesh = random_soup(n, 0.05, 7);
            let h = build(&mesh, &grid, p, 1).ok()?;
            Some((mesh, grid, h))
        })
        .ok_or_else(|| golden_err("no dense soup of the depth-first case builds"))
}

/// `h` as a writer that stores depth first would: the roots keep `0..`
/// `root_count`, every other record is numbered in pre-order, and each
/// inner node's references follow those of its whole subtree (the top's
/// come last). The same nodes and the same children, in another order:
/// SPEC 3 fixes no order beyond the roots at the front.
fn stored_depth_first(h: &Hierarchy) -> Hierarchy {
    let roots: Vec<u32> = (0..h.root_count).collect();
    relaid_depth_first(h, &roots)
}

/// The hierarchy below `roots` (stored records of `h`, all of one LOD, in
/// the order given), stored depth first as in [`stored_depth_first`]:
/// `roots` become the roots, in that order, and what they do not reach is
/// dropped. The prims stay as they are.
fn relaid_depth_first(h: &Hierarchy, roots: &[u32]) -> Hierarchy {
    let mut order = DepthFirst {
        h,
        number: vec![u32::MAX; h.nodes.len()],
        next: roots.len() as u32,
        first: h.nodes.iter().map(|n| n.first).collect(),
        refs: Vec::with_capacity(h.refs.len()),
    };
    for (i, root) in roots.iter().enumerate() {
        order.number[*root as usize] = i as u32;
    }
    for root in roots {
        order.visit(*root);
    }
    let mut nodes = vec![h.nodes[0]; order.next as usize];
    for (old, rec) in h.nodes.iter().enumerate() {
        if let Some(at) = nodes.get_mut(order.number[old] as usize) {
            *at = NodeRecord {
                first: order.first[old],
                ..*rec
            };
        }
    }
    let top_lod = roots
        .first()
        .map_or(h.top_lod, |r| h.nodes[*r as usize].voxel.lod);
    Hierarchy {
        nodes,
        refs: order.refs,
        root_count: roots.len() as u32,
        top_lod,
        ..h.clone()
    }
}

/// The LODs below `h`'s top at which it can be cut into 2 to `most_roots`
/// roots (no leaf above the cut, which would be lost), with their node
/// counts.
fn cut_lods(h: &Hierarchy, most_roots: usize) -> Vec<(u8, usize)> {
    let at = |l: u8| h.nodes.iter().filter(move |n| n.voxel.lod == l);
    (h.top_lod + 1..=h.params.max_lod)
        .take_while(|l| !at(l - 1).any(|n| n.leaf))
        .map(|l| (l, at(l).count()))
        .filter(|(_, n)| (2..=most_roots).contains(n))
        .collect()
}

/// `h` cut at `lod`: its nodes there become the roots, stored in a random
/// order (a store written by other software: SPEC 3 asks only that every
/// root lie at `top_lod`), the rest depth first.
fn cut_at(rng: &mut SplitMix64, h: &Hierarchy, lod: u8) -> Hierarchy {
    let mut roots: Vec<u32> = (0..h.nodes.len() as u32)
        .filter(|n| h.nodes[*n as usize].voxel.lod == lod)
        .collect();
    // Fisher-Yates from the run's seed.
    for i in (1..roots.len()).rev() {
        roots.swap(i, rng.below(i as u64 + 1) as usize);
    }
    relaid_depth_first(h, &roots)
}

/// `h` cut at a random LOD of `cut_lods` (`Merges::Hard`'s random merges,
/// a third of their soups), its roots in a random order. So the root sorter
/// takes roots of every LOD with random keys, records and arrival order,
/// where a builder's several roots lie at LOD 1 in Morton order (4.7).
/// `None` when no LOD qualifies.
pub fn random_cut(rng: &mut SplitMix64, h: &Hierarchy, most_roots: usize) -> Option<Hierarchy> {
    let lods = cut_lods(h, most_roots);
    if lods.is_empty() {
        return None;
    }
    let (lod, _) = lods[rng.below(lods.len() as u64) as usize];
    Some(cut_at(rng, h, lod))
}

/// Merges of `root_cuts`.
pub const ROOT_CUTS: u64 = 4;

/// [`ROOT_CUTS`] merges of two soups of 60 triangles, each cut at the LOD
/// of the most roots the root sorter holds (`most_roots`), stored in a
/// random order and placed at random: every entry of the sorter takes
/// roots whose keys, boxes, `first` and `count` differ from merge to
/// merge, arriving out of order, where the named several-root cases repeat
/// one store each. A soup with no such LOD stays as built.
fn root_cuts(p: &Params, most_roots: usize) -> Result<Vec<RealCase>> {
    (0..ROOT_CUTS)
        .map(|j| {
            let mut rng = SplitMix64(0x5eed_c075 + j);
            let inputs = (1..=2u8)
                .map(|id| {
                    let size = 0.1 + 0.1 * (j + id as u64) as f32;
                    let h = try_soup(p, id, 60, size, rng.next_u64()).map_err(golden_err)?;
                    let fullest = cut_lods(&h, most_roots).into_iter().max_by_key(|c| c.1);
                    let h = match fullest {
                        Some((lod, _)) => cut_at(&mut rng, &h, lod),
                        None => h,
                    };
                    let frac = [0, 1, 2].map(|_| rng.below(101) as f64 / 100.0);
                    let t = place(&h, frac);
                    Ok((h, t))
                })
                .collect::<Result<Vec<_>>>()?;
            case_of(p, inputs)
        })
        .collect()
}

/// [`sixteen_deep_roots`]'s triangles in the unit cube, which
/// `corner_grid(p, 3)` maps onto the LOD-3 corner voxel, whose LOD-5
/// voxels are quarters of it: one tiny triangle in each of sixteen of
/// them, edges from 0.004 to 0.02.
fn deep_roots_mesh() -> Mesh {
    let mut m = Mesh::default();
    for i in 0..16u32 {
        let v = [i % 4, (i / 4) % 4, (i * 3 + i / 4) % 4];
        let c = Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32) * 0.25
            + Vec3::splat(0.03 + 0.01 * i as f32);
        let e = 0.004 * (1 + i % 5) as f32;
        push_triangle(
            &mut m,
            c,
            c + Vec3::new(e, 0.0, 0.0),
            c + Vec3::new(0.0, e, e),
        );
    }
    m
}

/// The grid map that puts the unit cube onto the scene's LOD-`lod` corner
/// voxel.
fn corner_grid(p: &Params, lod: u8) -> GridMap {
    GridMap {
        origin: DVec3::ZERO,
        unit: 1.0 / (p.scene_edge() >> lod) as f64,
    }
}

/// Sixteen roots at LOD 5 (at `D >= 6`), stored against Morton order, and
/// placed near the scene's far corner: a hierarchy of sixteen tiny
/// triangles, one in each of sixteen LOD-5 voxels, cut below its LOD-4
/// nodes (which hold no leaf), so that its roots are those voxels'
/// nodes, and stored from the last root to the first (a store written by
/// other software: SPEC 3 asks only that every root lie at `top_lod`).
/// The root sorter then holds sixteen roots whose coordinates, boxes,
/// `first` and `count` all differ, where the builder's several roots lie
/// at LOD 1 (4.7) and the 16-root case's differ in one coordinate bit.
/// `None` below `D = 6`.
fn sixteen_deep_roots(p: &Params) -> Result<Option<RealCase>> {
    const LOD: u8 = 5;
    if p.max_lod <= LOD {
        return Ok(None);
    }
    let built = build(&deep_roots_mesh(), &corner_grid(p, 3), p, 1).map_err(golden_err)?;
    let mut roots: Vec<u32> = (0..built.nodes.len() as u32)
        .filter(|n| built.nodes[*n as usize].voxel.lod == LOD)
        .collect();
    if roots.len() != 16 || built.nodes.iter().any(|n| n.leaf && n.voxel.lod < LOD) {
        return Err(golden_err(format!(
            "the deep roots' mesh has {} nodes at LOD {LOD} (expected 16, no leaf above)",
            roots.len()
        )));
    }
    roots.reverse();
    let deep = relaid_depth_first(&built, &roots);
    let small = try_soup(p, 2, 20, 0.2, 78).map_err(golden_err)?;
    let (tr_deep, tr_small) = (
        place(&deep, [0.9, 0.8, 0.95]),
        place(&small, [0.7, 0.6, 0.8]),
    );
    case_of(p, vec![(deep, tr_deep), (small, tr_small)]).map(Some)
}

/// [`stored_depth_first`]'s walk: new numbers on the way down, reference
/// blocks on the way up.
struct DepthFirst<'a> {
    h: &'a Hierarchy,
    /// Per stored record, its new index.
    number: Vec<u32>,
    next: u32,
    /// Per stored record, its new `first` (a leaf's, into `prims`, stays).
    first: Vec<u32>,
    refs: Vec<Reference>,
}

impl DepthFirst<'_> {
    fn visit(&mut self, at: u32) {
        let h = self.h;
        let node = &h.nodes[at as usize];
        let children = h.children_of(node);
        for c in children.iter().filter(|c| c.hier == h.id) {
            self.number[c.node as usize] = self.next;
            self.next += 1;
            self.visit(c.node);
        }
        if node.leaf {
            return;
        }
        self.first[at as usize] = self.refs.len() as u32;
        for c in children {
            let node = if c.hier == h.id {
                self.number[c.node as usize]
            } else {
                c.node
            };
            self.refs.push(Reference { hier: c.hier, node });
        }
    }
}

/// The merge a merger makes of `ids` when the translation entry of the
/// input of rank `rank` is invalid (`ENTRY`) and the others' entries are
/// `table`'s: as [`hard_merges`]' error merges (the header names `ENTRY`
/// and the rank; the rest is the merge of the other inputs over the range
/// of all of them). What the hierarchy unit does with a merge command that
/// names an input no determine command wrote. `None` when such a merge is
/// not one golden models bit for bit (see `cfg_error_merge`).
pub fn entry_error_merge(
    d: &MergeDesign,
    sizes: MergerSizes,
    store: &HierarchyStore,
    table: &TranslationTable,
    ids: &[u8],
    rank: usize,
) -> Result<Option<MergerTransaction>> {
    cfg_error_merge(d, sizes, store, table, ids, (fetch_err::ENTRY, rank))
}

/// A merge whose input of rank `rank` has a `cfg` that makes its fetcher
/// refuse it with `code` (one of [`CFG_ERRORS`]): an invalid translation entry, a
/// `root_count` of 0, or one more root than the sorter holds. Its fetcher
/// answers every command with an error beat (8.13, no store read), which
/// the glue passes on as that input's `End`, so the rest is the merge of
/// the other inputs over the same `(lo, hi)` with the rank left empty (a
/// rank orders only ties between inputs, and the others keep their order);
/// the header names the error and the input (docs/hardware.md, the merger's
/// fetcher errors). `None` when the case has one input or more than `k`,
/// when the other inputs' leaves overflow the leaf FIFOs, or when the
/// input cannot claim that many roots.
fn cfg_error_merge(
    d: &MergeDesign,
    sizes: MergerSizes,
    store: &HierarchyStore,
    table: &TranslationTable,
    ids: &[u8],
    (code, rank): (u64, usize),
) -> Result<Option<MergerTransaction>> {
    let p = &d.params;
    let n = ids.len();
    if n < 2 || n > d.inputs || rank >= n {
        return Ok(None);
    }
    let hs: Vec<&Hierarchy> = ids.iter().filter_map(|i| store.get(*i)).collect();
    if hs.len() != n {
        return Ok(None);
    }
    let range = candidate_range(&hs);
    let out_id = out_id(p);
    let others: Vec<u8> = (0..n).filter(|&i| i != rank).map(|i| ids[i]).collect();
    let Ok(mut tx) = merger_transaction_in_range(
        store,
        table,
        &others,
        d.mode,
        out_id,
        d.inputs,
        sizes,
        Some(range),
    ) else {
        return Ok(None);
    };
    // The error's merge overflows nothing, so that its header differs from
    // the other inputs' merge only in the fetcher's error.
    if tx.header.leaf_overflow {
        return Ok(None);
    }
    // The `cfg` software sends for the input; the store keeps its records.
    let mut broken = hs[rank].clone();
    let t = table.get(ids[rank] as u32).ok().flatten();
    let t = match code {
        fetch_err::ENTRY => None,
        fetch_err::ROOT_COUNT => {
            broken.root_count = 0;
            t
        }
        _ => {
            let roots = sizes.fetch.roots + 1;
            if roots > broken.nodes.len() || roots as u64 >= p.index_capacity() {
                return Ok(None);
            }
            broken.root_count = roots as u32;
            t
        }
    };
    tx.cfg
        .inputs
        .insert(rank, FetchCfg::of(&broken, t.as_ref()));
    // Per-node mode: the fetcher takes the module's whole `report` (that
    // of the other inputs' merge: an empty input changes no decision).
    let (reports, passes) = match &tx.module {
        ModulePass::PerNode(pn) => (pn.reports.clone(), Some(pn.passes)),
        ModulePass::Level(_) => (Vec::new(), None),
    };
    let entry = crate::translate::table::pack_entry(t.as_ref(), p);
    let f = fetch_transaction_with_reports(&broken, entry, &tx.cmds, &reports, sizes.fetch)
        .map_err(golden_err)?;
    check_cfg_errors(&f, &tx, passes, code)?;
    tx.fetch.insert(rank, f);
    tx.header.fetch_err = code;
    tx.header.fetch_rank = rank as u16;
    Ok(Some(tx))
}

/// That `f`, the fetch of an input whose `cfg` its fetcher refuses with
/// `code`, reads nothing and answers every command with a `code` error
/// beat, then one `End` per later level (per-node: per later pass).
fn check_cfg_errors(
    f: &FetchTransaction,
    tx: &MergerTransaction,
    passes: Option<u32>,
    code: u64,
) -> Result<()> {
    let errors = f
        .out
        .iter()
        .filter(|o| matches!(o, FetchOut::Error { code: c, .. } if *c == code))
        .count();
    let levels: usize = tx.cmds.iter().map(|c| c.levels()).sum();
    let beats = passes.map_or(levels, |n| n.max(1) as usize);
    let read = f.node_reqs.len() + f.ref_reqs.len() + f.probe_reqs.len();
    if read != 0 || errors != tx.cmds.len() || f.out.len() != beats {
        return Err(golden_err(format!(
            "the fetch of an input refused with code {code}: {read} store reads (expected 0), {errors} error beats of that code (expected {}), {} beats (expected {beats})",
            tx.cmds.len(),
            f.out.len()
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::merge::merge_level::{BaseKind, BaseNode};
    use crate::merge::record_writer::writer_err;
    use crate::merge::MergeMode;

    /// The merge of `case` (two inputs) with leaf FIFOs of `2^leaf_bits`
    /// in `mode`, and a label naming them.
    fn merge_of(
        case: &RealCase,
        p: &Params,
        leaf_bits: u32,
        mode: MergeMode,
    ) -> (String, MergerTransaction) {
        let sizes = MergerSizes {
            leaf_bits,
            ..MergerSizes::new(p)
        };
        let (store, table, ids) = case;
        let tx = merger_transaction(store, table, ids, mode, 7, 2, sizes).unwrap();
        (format!("D = {} L = {leaf_bits} {mode}", p.max_lod), tx)
    }

    /// The flood sends the leaf FIFOs of five consecutive LODs, from LOD 3
    /// down, two leaves more than each holds, in a level mode and in per-node
    /// mode, at the default and at the long runs' small configuration: the
    /// header flags it, the base keeps the first `2^leaf_bits` of each LOD
    /// (then the module's nodes, all deeper), the merge is exact, and the
    /// writer writes it without error.
    #[test]
    fn the_leaf_flood_overflows_five_fifos_by_two_leaves() {
        let small = Params::new(8, 0, 12, 3).unwrap();
        for p in [Params::default(), small] {
            for leaf_bits in [4, 6] {
                let case = leaf_flood(&p, leaf_bits).unwrap().unwrap();
                let held = 1usize << leaf_bits;
                for mode in BOTH_MODES {
                    let (at, tx) = merge_of(&case, &p, leaf_bits, mode);
                    let mut per_lod = std::collections::BTreeMap::<u8, Vec<&BaseNode>>::new();
                    for l in &tx.leaves {
                        per_lod.entry(l.record.voxel.lod).or_default().push(l);
                    }
                    let lods: Vec<u8> = per_lod.keys().copied().collect();
                    let first = lods[0];
                    assert!(first >= 3, "{at}: LOD {first} has at most 64 voxels");
                    let want: Vec<u8> = (first..).take(FLOOD_LATTICES).collect();
                    assert_eq!(lods, want, "{at}");
                    let counts: Vec<usize> = per_lod.values().map(|l| l.len()).collect();
                    assert!(
                        counts.iter().all(|&c| c == held + 2),
                        "{at}: {lods:?} {counts:?}"
                    );
                    assert!(tx.header.leaf_overflow, "{at}");
                    assert!(tx.exact, "{at}");
                    let kept: Vec<&BaseNode> = per_lod
                        .values()
                        .flat_map(|l| l[..held].iter().copied())
                        .collect();
                    let n = kept.len();
                    assert!(tx.base[..n].iter().eq(kept), "{at}");
                    let last = lods[lods.len() - 1];
                    assert!(
                        tx.base[n..].iter().all(|b| b.record.voxel.lod > last),
                        "{at}"
                    );
                    assert_eq!(tx.header.writer.err, 0, "{at}");
                }
            }
            assert!(leaf_flood(&p, FLOOD_MOST_LEAF_BITS + 1).unwrap().is_none());
        }
    }

    /// Both inputs of the flood of two bring their 48 leaves to LOD 2,
    /// above the merging level: 96 leaves in 64 voxels, which overflow the
    /// FIFOs of `2^4` and `2^6` and not of `2^7`; the base keeps the first
    /// `2^leaf_bits` in the leaf merge's order, from both inputs, at the
    /// default and the small configuration, in the level modes of the
    /// regression (per-node mode merges them in the module: its leaf FIFOs
    /// take only leaves above `lo`, where at most one of two inputs has
    /// nodes).
    #[test]
    fn the_flood_of_two_overflows_lod_2_from_both_inputs() {
        let small = Params::new(8, 0, 12, 3).unwrap();
        for p in [Params::default(), small] {
            let case = flood_of_two(&p).unwrap();
            for leaf_bits in [4, 6, 7] {
                let held = 1usize << leaf_bits;
                let modes = [
                    MergeMode::Overlap { num: 1, den: 2 },
                    MergeMode::Proportion { num: 1, den: 1 },
                ];
                for mode in modes {
                    let (at, tx) = merge_of(&case, &p, leaf_bits, mode);
                    let at2: Vec<&BaseNode> = tx
                        .leaves
                        .iter()
                        .filter(|l| l.record.voxel.lod == FLOOD_OF_TWO_LOD)
                        .collect();
                    assert_eq!(at2.len(), 2 * FLOOD_OF_TWO_LEAVES, "{at}");
                    assert!(
                        tx.leaves
                            .iter()
                            .all(|l| l.record.voxel.lod >= FLOOD_OF_TWO_LOD),
                        "{at}"
                    );
                    let inputs: std::collections::BTreeSet<u8> = at2
                        .iter()
                        .filter_map(|l| match l.kind {
                            BaseKind::Reused { at } => Some(at.hier),
                            BaseKind::Created { .. } => None,
                        })
                        .collect();
                    assert_eq!(inputs, [1, 2].into(), "{at}: reused leaves of both inputs");
                    let overflows = at2.len() > held;
                    assert_eq!(tx.header.leaf_overflow, overflows, "{at}");
                    assert!(tx.exact, "{at}");
                    let kept = &at2[..at2.len().min(held)];
                    assert!(
                        tx.base[..kept.len()].iter().eq(kept.iter().copied()),
                        "{at}"
                    );
                    assert_eq!(tx.header.writer.err, 0, "{at}");
                }
            }
        }
    }

    /// The level-mode and per-node merges every store-order case runs.
    const BOTH_MODES: [MergeMode; 2] = [
        MergeMode::Overlap { num: 1, den: 2 },
        MergeMode::PerNode { num: 1, den: 2 },
    ];

    /// The deep-top merges' tops are where [`deep_tops`] puts them: the
    /// pairs' one LOD apart from the triangle's own LOD down (at D = 8 its
    /// LOD-8 leaf root's merged top is one LOD above it), the one alone
    /// no higher, at the default and at the long runs' small configuration.
    #[test]
    fn deep_tops_put_the_top_at_the_deepest_lods() {
        let small = Params::new(8, 0, 12, 3).unwrap();
        for p in [Params::default(), small] {
            let d = MergeDesign {
                params: p,
                inputs: 2,
                ..MergeDesign::default()
            };
            let sizes = MergerSizes::new(&p);
            let cases = deep_tops(&p).unwrap();
            let t = cases[0].0.get(1).unwrap().top_lod as i64;
            assert_eq!(cases.len(), 5, "D = {}", p.max_lod);
            let tops: Vec<i64> = cases
                .iter()
                .map(|(store, table, ids)| {
                    let tx = merger_transaction(store, table, ids, d.mode, 7, 2, sizes).unwrap();
                    tx.header.writer.top as i64
                })
                .collect();
            let first = tops[1];
            assert!(
                first >= t - 1 && tops[0] >= first,
                "D = {}: {tops:?}",
                p.max_lod
            );
            for (n, top) in tops[1..].iter().enumerate() {
                assert_eq!(*top, first - n as i64, "D = {}: {tops:?}", p.max_lod);
            }
        }
    }

    /// The deep clusters' merges have their top at the clusters' LOD and
    /// write several created records, within the coverage configuration's
    /// writer (`2^5` entries a buffer), at the default and at D = 8.
    #[test]
    fn deep_clusters_write_records_at_the_deep_lods() {
        let small = Params::new(8, 0, 12, 3).unwrap();
        for p in [Params::default(), small] {
            let mut sizes = MergerSizes::new(&p);
            sizes.capacity_bits = 5;
            let cases = deep_clusters(&p).unwrap();
            assert_eq!(cases.len(), 3, "D = {}", p.max_lod);
            for (c, (store, table, ids)) in (p.max_lod - 4..).zip(&cases) {
                let mode = MergeMode::Overlap { num: 1, den: 2 };
                let tx = merger_transaction(store, table, ids, mode, 7, 2, sizes).unwrap();
                let w = &tx.header.writer;
                let at = format!("D = {} c = {c}: {w:?}", p.max_lod);
                assert_eq!((w.top, w.err), (c, 0), "{at}");
                assert!(w.nodes >= 4, "{at}");
            }
        }
    }

    /// The huge clusters exist at I = 12 only; every input's prims pass
    /// `2^10`, some input's `2^11` (its leaves' `first` set the top bit),
    /// some input's nodes pass `2^10`, and every merge is exact.
    #[test]
    fn huge_clusters_reach_the_upper_index_bits_at_i12_only() {
        assert!(huge_clusters(&Params::default()).unwrap().is_empty());
        let p = Params::new(8, 0, 12, 3).unwrap();
        let cases = huge_clusters(&p).unwrap();
        assert_eq!(cases.len(), 5);
        let sizes = MergerSizes::new(&p);
        let (mut most_nodes, mut most_prims) = (0, 0);
        for (store, table, ids) in &cases {
            for i in ids {
                let h = store.get(*i).unwrap();
                assert!(h.prims.len() > 1 << 10, "{} prims", h.prims.len());
                most_nodes = most_nodes.max(h.nodes.len());
                most_prims = most_prims.max(h.prims.len());
            }
            let mode = MergeMode::Overlap { num: 1, den: 2 };
            let tx = merger_transaction(store, table, ids, mode, 7, 2, sizes).unwrap();
            assert!(tx.exact);
        }
        assert!(most_nodes > 1 << 10, "{most_nodes} nodes");
        assert!(most_prims > 1 << 11, "{most_prims} prims");
    }

    /// The capacity clusters' inputs hold hundreds of nodes (indices past
    /// `2^8`). At the coverage configuration (D = 8, a writer of `2^5`
    /// entries a buffer) the writer refuses the four of `c` 3 to 6 with
    /// `CAPACITY`, each a merge golden models exactly; at the default's
    /// writer (`2^8`) every one is written, its top at its cluster's LOD.
    #[test]
    fn capacity_clusters_fill_levels_past_the_small_writer() {
        let small = Params::new(8, 0, 12, 3).unwrap();
        let mode = MergeMode::Overlap { num: 1, den: 2 };
        for (p, cap, refused) in [(small, 5, 4), (Params::default(), 8, 0)] {
            let mut sizes = MergerSizes::new(&p);
            sizes.capacity_bits = cap;
            let cases = capacity_clusters(&p).unwrap();
            assert_eq!(cases.len(), 5, "D = {}", p.max_lod);
            let mut n_refused = 0;
            for (c, (store, table, ids)) in (p.max_lod - 5..).zip(&cases) {
                let tx = merger_transaction(store, table, ids, mode, 7, 2, sizes).unwrap();
                let w = &tx.header.writer;
                let at = format!("D = {} c = {c}: {w:?}", p.max_lod);
                assert!(tx.exact, "{at}");
                if w.err == writer_err::CAPACITY {
                    n_refused += 1;
                    assert_eq!((w.nodes, w.refs), (0, 0), "{at}");
                } else {
                    assert_eq!((w.err, w.top), (0, c), "{at}");
                }
            }
            assert_eq!(n_refused, refused, "D = {}", p.max_lod);
            let biggest = cases[0].0.get(1).map_or(0, |h| h.nodes.len());
            assert!(biggest > 256, "{biggest} nodes");
        }
    }

    /// The 16-root input has 16 roots, at the default and at the long runs'
    /// small configuration, and the ladder's merge puts leaves in the FIFO
    /// of every LOD from 1 to the merging level (at D = 8: the top, 8).
    #[test]
    fn sixteen_roots_and_the_leaf_ladder_reach_what_they_name() {
        let small = Params::new(8, 0, 12, 3).unwrap();
        for p in [Params::default(), small] {
            let (store, ..) = sixteen_roots(&p).unwrap();
            assert_eq!(store.get(1).unwrap().root_count, 16, "D = {}", p.max_lod);
            let mut sizes = MergerSizes::new(&p);
            sizes.leaf_bits = 6;
            let (store, table, ids) = leaf_ladder(&p).unwrap();
            let mode = MergeMode::Overlap { num: 1, den: 2 };
            let tx = merger_transaction(&store, &table, &ids, mode, 7, 2, sizes).unwrap();
            let m = tx.chosen.unwrap();
            let mut lods: Vec<u8> = tx.leaves.iter().map(|l| l.record.voxel.lod).collect();
            lods.dedup();
            assert_eq!(lods, (1..m).collect::<Vec<_>>(), "D = {}", p.max_lod);
            assert!(!tx.header.leaf_overflow);
        }
        let (store, table, ids) = leaf_ladder(&small).unwrap();
        let mode = MergeMode::Overlap { num: 1, den: 2 };
        let sizes = MergerSizes::new(&small);
        let tx = merger_transaction(&store, &table, &ids, mode, 7, 2, sizes).unwrap();
        assert_eq!(tx.chosen, Some(small.max_lod));
    }

    /// Roots stored in reverse are read in stored order and merge into
    /// the hierarchy of the roots stored in order, in every mode: the same
    /// module input, records and header, and references to the same
    /// nodes where they are stored.
    #[test]
    fn reversed_roots_merge_as_the_ordered_ones() {
        use crate::store::Reference;
        let small = Params::new(8, 0, 12, 3).unwrap();
        for p in [Params::default(), small] {
            for mode in BOTH_MODES {
                let mut sizes = MergerSizes::new(&p);
                sizes.leaf_bits = 6;
                let merge = |(store, table, ids): RealCase| {
                    merger_transaction(&store, &table, &ids, mode, 7, 2, sizes).unwrap()
                };
                let ordered = merge(sixteen_roots(&p).unwrap());
                let reversed = merge(sixteen_roots_reversed(&p).unwrap());
                let at = format!("D = {}, {mode}", p.max_lod);
                let roots_read = |t: &MergerTransaction| t.fetch[0].node_resps[..16].to_vec();
                let mut read = roots_read(&ordered);
                read.reverse();
                assert_eq!(roots_read(&reversed), read, "{at}: stored order");
                assert_eq!(reversed.fetch[0].out, ordered.fetch[0].out, "{at}: sorted");
                assert_eq!(reversed.writer.nodes, ordered.writer.nodes, "{at}");
                // A reused root is named where it is stored: root `n` of
                // input 1 is stored at `15 - n` in the reversed store.
                let stored: Vec<_> = reversed
                    .writer
                    .refs
                    .iter()
                    .map(|r| match (r.hier, r.node) {
                        (1, n) if n < 16 => Reference {
                            hier: 1,
                            node: 15 - n,
                        },
                        _ => *r,
                    })
                    .collect();
                assert_eq!(stored, ordered.writer.refs, "{at}");
                assert_eq!(reversed.header, ordered.header, "{at}");
                assert!(!ordered.writer.nodes.is_empty(), "{at}");
            }
        }
    }

    /// Every code of [`CFG_ERRORS`] has its merge on the last input, and an
    /// invalid entry one on the first, in the level modes and per node: the
    /// header names the code and the rank, that input's fetcher reads
    /// nothing, and the merge is that of the other inputs (their fetches
    /// and the writer's streams as without the broken one).
    #[test]
    fn every_cfg_error_has_its_merge() {
        for mode in BOTH_MODES {
            let d = MergeDesign {
                mode,
                ..MergeDesign::default()
            };
            let sizes = MergerSizes::new(&d.params);
            let h = hard_merges(&d, sizes).unwrap();
            let mut met = Vec::new();
            for tx in h.merges.iter().filter(|t| t.header.fetch_err != 0) {
                let (code, rank) = (tx.header.fetch_err, tx.header.fetch_rank as usize);
                let last = tx.fetch.len() - 1;
                met.push((code, if rank == last { "last" } else { "first" }));
                assert!(rank == 0 || rank == last, "{mode} {code} {rank}");
                let f = &tx.fetch[rank];
                assert!(
                    f.node_reqs.is_empty() && f.ref_reqs.is_empty(),
                    "{mode} {code}"
                );
                assert!(f
                    .leaves
                    .iter()
                    .all(|l| matches!(l, crate::merge::fetcher::LeafOut::End)));
                assert!(tx
                    .fetch
                    .iter()
                    .enumerate()
                    .all(|(i, f)| i == rank || !f.node_reqs.is_empty()));
                assert!(!tx.header.leaf_overflow, "{mode} {code}");
                assert_eq!(tx.cfg.inputs.len(), tx.fetch.len(), "{mode} {code}");
            }
            met.sort();
            let mut want: Vec<(u64, &str)> = CFG_ERRORS.iter().map(|&c| (c, "last")).collect();
            want.push((fetch_err::ENTRY, "first"));
            want.sort();
            assert_eq!(met, want, "{mode}");
        }
    }

    /// The depth-first store is a store the checker accepts (an
    /// independent walk over the triangles), and at the coverage
    /// configuration (`I = 12`) it puts the top's `first` and references
    /// to reused nodes at index bit 11, which the builder's order does not.
    #[test]
    fn a_depth_first_store_is_valid_and_reaches_the_top_index_bit() {
        let p = Params::new(8, 0, 12, 3).unwrap();
        let (mesh, grid, built) = dense_corner(&p).unwrap();
        let tris: Vec<_> = (0..mesh.triangles.len())
            .map(|i| grid.triangle(&mesh, i, &p).unwrap())
            .collect();
        let stored = stored_depth_first(&built);
        crate::check::check_built(&stored, &tris).unwrap();
        let high = 1 << (p.index_bits - 1);
        let top = |h: &Hierarchy| h.roots().iter().map(|n| n.first).max().unwrap();
        let deepest_ref = |h: &Hierarchy| {
            h.children_of(&h.nodes[0])
                .iter()
                .map(|r| r.node)
                .max()
                .unwrap()
        };
        assert!(top(&stored) >= high && deepest_ref(&stored) >= high);
        assert!(top(&built) < high && deepest_ref(&built) < high);
    }

    /// An input put under a LOD-0 root is a valid store (the checker
    /// against its triangles), and each merge of two such inputs writes
    /// its top at LOD 0 in both modes, at the coverage configuration (Q = 0,
    /// where no built input has a LOD-0 root; its writer of `2^5` entries a
    /// buffer) and at the default.
    #[test]
    fn lod0_roots_are_valid_and_put_the_merged_top_at_lod_0() {
        let small = Params::new(8, 0, 12, 3).unwrap();
        let mesh = random_soup(40, 0.3, 91);
        let (lo, hi) = mesh.bounds();
        let grid = GridMap::fit(lo, hi, &small);
        let built = build(&mesh, &grid, &small, 1).unwrap();
        assert_eq!(built.top_lod, 1);
        let wrapped = under_lod0_root(built.clone());
        let tris = grid.mesh_to_grid(&mesh, &small).unwrap();
        crate::check::check_built(&wrapped, &tris).unwrap();
        assert_eq!(
            (wrapped.top_lod, wrapped.root_count, wrapped.nodes[0].count),
            (0, 1, built.root_count)
        );
        for p in [small, Params::default()] {
            for (store, table, ids) in lod0_tops(&p).unwrap() {
                for mode in BOTH_MODES {
                    let mut sizes = MergerSizes::new(&p);
                    sizes.capacity_bits = 5;
                    sizes.leaf_bits = 6;
                    let tx = merger_transaction(&store, &table, &ids, mode, 7, 2, sizes).unwrap();
                    let w = &tx.header.writer;
                    let at = format!("D = {} {mode:?}: {w:?}", p.max_lod);
                    assert_eq!((w.top, w.err), (0, 0), "{at}");
                    assert!(w.nodes >= 1, "{at}");
                }
            }
        }
    }

    /// Merged from the depth-first store, the merge writes what it writes
    /// from the builder's store, references to reused nodes renumbered:
    /// the order of a store changes where records are, not the merge.
    #[test]
    fn a_depth_first_store_merges_as_the_builders_store() {
        for p in [Params::default(), Params::new(8, 0, 12, 3).unwrap()] {
            let (_, _, built) = dense_corner(&p).unwrap();
            let (stored, table, ids) = depth_first_store(&p).unwrap();
            let mut ordered = stored.clone();
            ordered.replace(built.clone()).unwrap();
            let renumber = |r: &Reference| match r.hier {
                1 => {
                    let rec = built.nodes[r.node as usize];
                    let at = stored.get(1).unwrap().nodes.iter().position(|n| {
                        (n.voxel, n.leaf, n.lo, n.hi) == (rec.voxel, rec.leaf, rec.lo, rec.hi)
                    });
                    Reference {
                        hier: 1,
                        node: at.unwrap() as u32,
                    }
                }
                _ => *r,
            };
            for mode in BOTH_MODES {
                let sizes = MergerSizes::new(&p);
                let a = merger_transaction(&stored, &table, &ids, mode, 7, 2, sizes).unwrap();
                let b = merger_transaction(&ordered, &table, &ids, mode, 7, 2, sizes).unwrap();
                let at = format!("D = {} {mode}", p.max_lod);
                assert_eq!(a.header, b.header, "{at}");
                assert_eq!(a.header.fetch_err, 0, "{at}");
                assert_eq!(a.writer.nodes, b.writer.nodes, "{at}");
                let renumbered: Vec<Reference> = b.writer.refs.iter().map(renumber).collect();
                assert_eq!(a.writer.refs, renumbered, "{at}");
                assert!(a.writer.refs.iter().any(|r| r.hier == 1), "{at}");
            }
        }
    }

    /// The root cuts fill most of the sorter with roots out of Morton
    /// order, deeper than LOD 1, and merge as the same cuts stored in
    /// Morton order (the sorter's order is the merge's), at the default and
    /// at D = 8.
    #[test]
    fn root_cuts_fill_the_sorter_out_of_order_and_merge_as_the_ordered_ones() {
        let morton = |n: &NodeRecord| crate::grid::morton3(n.voxel.x, n.voxel.y, n.voxel.z);
        for p in [Params::default(), Params::new(8, 0, 12, 3).unwrap()] {
            let cases = root_cuts(&p, 16).unwrap();
            assert_eq!(cases.len() as u64, ROOT_CUTS);
            let mut most = 0;
            for (n, (store, table, ids)) in cases.iter().enumerate() {
                let at = format!("D = {} cut {n}", p.max_lod);
                let mut ordered = store.clone();
                for id in ids {
                    let h = store.get(*id).unwrap();
                    assert!(h.root_count <= 16, "{at}");
                    assert!(h.top_lod > 1 || h.root_count == 1, "{at}");
                    most = most.max(h.root_count);
                    let mut roots: Vec<u32> = (0..h.root_count).collect();
                    roots.sort_by_key(|r| morton(&h.nodes[*r as usize]));
                    ordered.replace(relaid_depth_first(h, &roots)).unwrap();
                }
                let unordered = ids.iter().any(|id| {
                    let h = store.get(*id).unwrap();
                    h.roots().windows(2).any(|w| morton(&w[0]) > morton(&w[1]))
                });
                assert!(unordered, "{at}: every input's roots in Morton order");
                for mode in BOTH_MODES {
                    let sizes = MergerSizes::new(&p);
                    let a = merger_transaction(store, table, ids, mode, 7, 2, sizes).unwrap();
                    let b = merger_transaction(&ordered, table, ids, mode, 7, 2, sizes).unwrap();
                    assert_eq!(a.header.fetch_err, 0, "{at} {mode}");
                    assert_eq!(a.header, b.header, "{at} {mode}");
                    assert_eq!(a.writer.nodes, b.writer.nodes, "{at} {mode}");
                }
            }
            assert!(most >= 12, "D = {}: at most {most} roots", p.max_lod);
        }
    }

    /// The deep roots are sixteen roots at LOD 5 that the checker accepts
    /// (an independent walk over the triangles), stored against Morton
    /// order; merged, they give what the same cut stored in Morton order
    /// gives (the root sorter's order is the merge's), at the default and
    /// at D = 8.
    #[test]
    fn sixteen_deep_roots_merge_as_the_ordered_ones() {
        let shallow = Params::new(5, 2, 12, 3).unwrap();
        assert!(sixteen_deep_roots(&shallow).unwrap().is_none());
        for p in [Params::default(), Params::new(8, 0, 12, 3).unwrap()] {
            let (store, table, ids) = sixteen_deep_roots(&p).unwrap().unwrap();
            let deep = store.get(1).unwrap();
            assert_eq!((deep.root_count, deep.top_lod), (16, 5));
            let grid = corner_grid(&p, 3);
            let mesh = deep_roots_mesh();
            let tris: Vec<_> = (0..mesh.triangles.len())
                .map(|i| grid.triangle(&mesh, i, &p).unwrap())
                .collect();
            crate::check::check_built(deep, &tris).unwrap();
            let morton = |n: &NodeRecord| crate::grid::morton3(n.voxel.x, n.voxel.y, n.voxel.z);
            assert!(deep
                .roots()
                .windows(2)
                .all(|w| morton(&w[0]) > morton(&w[1])));
            let roots: Vec<u32> = (0..16).rev().collect();
            let mut ordered = store.clone();
            ordered.replace(relaid_depth_first(deep, &roots)).unwrap();
            for mode in BOTH_MODES {
                let sizes = MergerSizes::new(&p);
                let a = merger_transaction(&store, &table, &ids, mode, 7, 2, sizes).unwrap();
                let b = merger_transaction(&ordered, &table, &ids, mode, 7, 2, sizes).unwrap();
                let at = format!("D = {} {mode}", p.max_lod);
                assert_eq!((a.header.writer.err, a.header.fetch_err), (0, 0), "{at}");
                assert_eq!(a.header, b.header, "{at}");
                assert_eq!(a.writer.nodes, b.writer.nodes, "{at}");
            }
        }
    }
}
