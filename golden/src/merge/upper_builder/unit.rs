//! S616 in hardware, every level above the base at once (SPEC.md section
//! 8.11, `rtl_gen::merge::upper_builder_unit`): the beat formats of the
//! upper builder's streams and its transaction, whose expected outputs come
//! from the golden level loop (`build::upper::build_levels`), its grouping
//! (`group_by_parent`) and 8.6's lift rule as `merge::upper_builder::build_upper`
//! applies it, never from a second model.
//!
//! Streams of one merge:
//! - in `base{d}` (`d = 0..=D`): the base nodes at LOD `d` (S614's nodes at
//!   the merging level, the reused leaves above it) in the order S616's level
//!   lists hold them (Morton, stable), then `End`; S614's input layout
//!   ([`BeatLayout::input`]) with S614's output kind codes
//!   ([`base_kind`](crate::merge::merge_level::unit::base_kind):
//!   created, reused, end; no reference beats).
//! - out `level{d}`: level `d`'s nodes in level order, then `End` with the
//!   level's node and record counts, for every `d` from `D` up to the top;
//!   nothing for the levels above the top.
//! - out `done`: one beat, the top LOD and an error flag.

use crate::bits::Bits;
use crate::build::upper::LevelNode;
use crate::grid::VoxelAddr;
use crate::layout::{Field, Layout, LayoutError, NodeLayout, RefLayout};
use crate::merge::error::MergeError;
use crate::merge::fetcher::walk::{collect, walk_input, WalkedInput};
use crate::merge::merge_level::unit::{BaseBeat, BeatLayout};
use crate::merge::merge_level::{merge_level, BaseKind, BaseNode, MergeLevelCounts};
use crate::merge::upper_builder::{base_by_lod, upper_levels};
use crate::params::Params;
use crate::store::{Hierarchy, NodeRecord, Reference};
use crate::translate::stimulus::SplitMix64;
use crate::translate::Translation;

/// The `ref` of a beat that is not a reused node.
const NO_REF: Reference = Reference { hier: 0, node: 0 };

/// Kind codes of a `level{d}` out beat (its `kind` field).
pub mod level_out_kind {
    /// An inner node made by grouping (S616): a record.
    pub const GROUPED: u64 = 0;
    /// A node created by S614: a record.
    pub const CREATED: u64 = 1;
    /// A reused input node (inner or leaf: the record's `leaf` bit).
    pub const REUSED: u64 = 2;
    /// End of the level: `index` = its nodes, `records` = its records.
    pub const END: u64 = 3;
}

/// Bit layouts of the upper builder's beats.
///
/// `level{d}` out beat, from bit 0: `rec` (a node record), `ref` (a
/// reference: where a reused node is stored, else 0), `kind` (2,
/// [`level_out_kind`]), `index` (I: a node's position in its level; an
/// `End`'s node count), `records` (I: the records (grouped or created
/// nodes) before a node in its level; an `End`'s record count), `err` (1:
/// a grouped node whose `first` or `count` reached `2^I` or one of whose
/// children had `lo > hi`, or a position / count that reached `2^I`; all
/// values modulo `2^I`).
///
/// `done` out beat, from bit 0: `top` (lod bits), `err` (1: no top: the
/// base was empty, or a reused leaf is at the LOD-0 top, 8.6's
/// `InputLeafAtTop`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BuilderLayout {
    /// Layout of the node record in `rec`.
    pub node: NodeLayout,
    /// Layout of the reference in `ref`.
    pub reference: RefLayout,
    /// The `base{d}` in beat.
    pub base: BeatLayout,
    /// The `level{d}` out beat: `rec`, `ref`, `kind`, `index`, `records`, `err`.
    pub level: Layout,
    /// `level{d}`: `rec` (W bits, from bit 0), the node's record; 0 on `End`.
    pub rec: Field,
    /// `level{d}`: `ref` (I + H bits), where a reused node is stored; else 0.
    pub refer: Field,
    /// `level{d}`: `kind` (2 bits), a [`level_out_kind`] code.
    pub kind: Field,
    /// `level{d}`: `index` (I bits), the node's position in its level; on `End`
    /// the level's node count.
    pub index: Field,
    /// `level{d}`: `records` (I bits), the records before the node in its level;
    /// on `End` the level's record count.
    pub records: Field,
    /// `level{d}`: `err` (1 bit), an overflow or a child box with `lo > hi`.
    pub err: Field,
    /// The `done` out beat: `top`, `err`.
    pub done: Layout,
    /// `done`: `top` (`lod_bits`, from bit 0), the LOD of the merged roots.
    pub top: Field,
    /// `done`: `err` (1 bit), no top.
    pub done_err: Field,
}

impl BuilderLayout {
    /// The layouts for `p`.
    pub fn new(p: &Params) -> BuilderLayout {
        let node = NodeLayout::new(p);
        let reference = RefLayout::new(p);
        let i = p.index_bits as u32;
        let mut level = Layout::new("upper builder level");
        let rec = level.push("rec", node.width());
        let refer = level.push("ref", reference.width());
        let kind = level.push("kind", 2);
        let index = level.push("index", i);
        let records = level.push("records", i);
        let err = level.push("err", 1);
        let mut done = Layout::new("upper builder done");
        let top = done.push("top", p.lod_bits());
        let done_err = done.push("err", 1);
        BuilderLayout {
            base: BeatLayout::input(p),
            level,
            rec,
            refer,
            kind,
            index,
            records,
            err,
            done,
            top,
            done_err,
            node,
            reference,
        }
    }
}

/// One beat out on a `level{d}` stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LevelOut {
    /// A node of the level: `kind` one of GROUPED, CREATED, REUSED; `at`
    /// where a reused node is stored (zero otherwise); `index` its position
    /// in the level and `records` the records before it, both modulo `2^I`.
    Node {
        /// A [`level_out_kind`] code: `GROUPED`, `CREATED` or `REUSED`.
        kind: u64,
        /// The record: a grouped node's parent voxel, box and `first`/`count` in
        /// the level below (modulo `2^I`); a created or reused node's as it came.
        record: NodeRecord,
        /// Where a reused node is stored; `(0, 0)` otherwise.
        at: Reference,
        /// The node's position in its level, modulo `2^I`.
        index: u32,
        /// The records (grouped and created nodes) before it in its level, modulo `2^I`.
        records: u32,
        /// A grouped node's `first` or `count` reached `2^I`, a child of it had
        /// `lo > hi`, or the position reached `2^I`.
        err: bool,
    },
    /// End of the level: its nodes and records, modulo `2^I`; `err` when
    /// the node count reached `2^I`.
    End {
        /// The level's node count, modulo `2^I` (the `index` field).
        nodes: u32,
        /// The level's record count, modulo `2^I` (the `records` field).
        records: u32,
        /// The node count reached `2^I`.
        err: bool,
    },
}

/// The `done` beat of a merge.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Done {
    /// The top LOD: the LOD of the merged hierarchy's roots (0 with `err`).
    pub top: u8,
    /// No top: the base was empty, or a reused leaf is at the LOD-0 top.
    pub err: bool,
}

impl LevelOut {
    /// The packed beat ([`BuilderLayout`]'s level layout).
    pub fn pack(&self, l: &BuilderLayout) -> Result<Bits, LayoutError> {
        let mut b = l.level.zero();
        match self {
            LevelOut::Node {
                kind,
                record,
                at,
                index,
                records,
                err,
            } => {
                b.put(l.rec.offset, &record.pack(&l.node)?)?;
                b.put(l.refer.offset, &at.pack(&l.reference)?)?;
                b.set(&l.kind, *kind)?;
                b.set(&l.index, *index as u64)?;
                b.set(&l.records, *records as u64)?;
                b.set(&l.err, *err as u64)?;
            }
            LevelOut::End {
                nodes,
                records,
                err,
            } => {
                b.set(&l.kind, level_out_kind::END)?;
                b.set(&l.index, *nodes as u64)?;
                b.set(&l.records, *records as u64)?;
                b.set(&l.err, *err as u64)?;
            }
        }
        Ok(b)
    }
}

impl Done {
    /// The packed beat ([`BuilderLayout`]'s done layout).
    pub fn pack(&self, l: &BuilderLayout) -> Result<Bits, LayoutError> {
        let mut b = l.done.zero();
        b.set(&l.top, self.top as u64)?;
        b.set(&l.done_err, self.err as u64)?;
        Ok(b)
    }
}

/// One merge through the upper builder: the `base{d}` in beats and the
/// expected `level{d}` and `done` out beats (index = LOD, `0..=D`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BuilderTransaction {
    /// `base[d]`: the `base{d}` in beats, LOD `d`'s base nodes in level order, then `End`.
    pub base: Vec<Vec<BaseBeat>>,
    /// `levels[d]`: the expected `level{d}` beats; empty above the top.
    pub levels: Vec<Vec<LevelOut>>,
    /// The expected `done` beat.
    pub done: Done,
    /// Which rules decided the top (to check that stimulus reaches them):
    /// lifts of a reused leaf (8.6), and the half-scene cut of 4.7.
    pub lifted: usize,
    /// The half-scene cut dropped a lone grouped LOD-0 node (the top is then 1).
    pub root_cut: bool,
}

/// The transaction of one merge over `base` (any base: empty, several
/// LODs, any kinds).
pub fn builder_transaction(base: &[BaseNode], p: &Params) -> BuilderTransaction {
    let dmax = p.max_lod as usize;
    let cap = p.index_capacity();
    let by_lod = base_by_lod(base, p);
    let base_beats: Vec<Vec<BaseBeat>> = by_lod
        .iter()
        .map(|l| {
            let mut v: Vec<BaseBeat> = l
                .iter()
                .map(|n| {
                    let b = &base[n.first as usize];
                    match &b.kind {
                        BaseKind::Created { .. } => BaseBeat::Created {
                            record: b.record,
                            count_overflow: false,
                        },
                        BaseKind::Reused { at } => BaseBeat::Reused {
                            record: b.record,
                            at: *at,
                        },
                    }
                })
                .collect();
            v.push(BaseBeat::End);
            v
        })
        .collect();
    // The levels and the top of 8.6 exactly as `merge::upper_builder::build_upper`
    // makes them; `build_levels` reaches LOD 0 only when no level below is
    // the top, so a built top of 1 with a LOD-0 level is the half-scene cut.
    let ((levels, top, lifted, root_cut), err) = match upper_levels(base, p) {
        None => ((vec![Vec::new(); dmax + 1], 0, 0, false), true),
        Some(u) => {
            let cut = u.built_top == 1 && u.lifted == 0 && !u.levels[0].is_empty();
            let err = u.leaf_at_top.is_some();
            ((u.levels, u.top, u.lifted as usize, cut && !err), err)
        }
    };
    let bad_box = |n: &LevelNode| (0..3).any(|a| n.lo[a] > n.hi[a]);
    let mut out = vec![Vec::new(); dmax + 1];
    for (d, beats) in out.iter_mut().enumerate().skip(top) {
        let empty = Vec::new();
        let level = levels.get(d).unwrap_or(&empty);
        let below = levels.get(d + 1).unwrap_or(&empty);
        let mut records = 0u64;
        for (i, n) in level.iter().enumerate() {
            let (kind, record, at, rec_err) = if n.base {
                let b = &base[n.first as usize];
                match &b.kind {
                    BaseKind::Created { .. } => (level_out_kind::CREATED, b.record, NO_REF, false),
                    BaseKind::Reused { at } => (level_out_kind::REUSED, b.record, *at, false),
                }
            } else {
                let children = &below[n.first as usize..(n.first + n.count) as usize];
                let record = NodeRecord {
                    leaf: false,
                    voxel: VoxelAddr::new(d as u8, n.x, n.y, n.z),
                    lo: n.lo,
                    hi: n.hi,
                    first: (n.first as u64 % cap) as u32,
                    count: (n.count as u64 % cap) as u32,
                };
                let e =
                    n.first as u64 >= cap || n.count as u64 >= cap || children.iter().any(bad_box);
                (level_out_kind::GROUPED, record, NO_REF, e)
            };
            beats.push(LevelOut::Node {
                kind,
                record,
                at,
                index: (i as u64 % cap) as u32,
                records: (records % cap) as u32,
                err: rec_err || i as u64 >= cap,
            });
            records += (kind != level_out_kind::REUSED) as u64;
        }
        beats.push(LevelOut::End {
            nodes: (level.len() as u64 % cap) as u32,
            records: (records % cap) as u32,
            err: level.len() as u64 >= cap,
        });
    }
    BuilderTransaction {
        base: base_beats,
        levels: out,
        done: Done {
            top: top as u8,
            err,
        },
        lifted,
        root_cut,
    }
}

/// S610-S614 for a fixed merging level `m`, as `merge::merge` runs them:
/// the reused leaves above `m`, then S614's nodes at `m` (the base S616
/// builds on).
pub fn fixed_level_base(
    inputs: &[(&Hierarchy, Translation)],
    m: u8,
    p: &Params,
) -> Result<Vec<BaseNode>, MergeError> {
    let walked: Vec<WalkedInput> = inputs
        .iter()
        .enumerate()
        .map(|(r, (h, t))| walk_input(h, r as u16, t, m))
        .collect::<Result<_, _>>()?;
    let (above, at) = collect(&walked, m);
    let hs: Vec<&Hierarchy> = inputs.iter().map(|(h, _)| *h).collect();
    let mut base: Vec<BaseNode> = above.iter().map(BaseNode::reused).collect();
    base.extend(merge_level(at, &hs, p, &mut MergeLevelCounts::default())?);
    Ok(base)
}

fn random_box(rng: &mut SplitMix64, p: &Params) -> ([u16; 3], [u16; 3]) {
    let cells = 1u64 << p.quant_bits;
    let mut lo = [0u16; 3];
    let mut hi = [0u16; 3];
    for a in 0..3 {
        let (x, y) = (rng.below(cells) as u16, rng.below(cells) as u16);
        lo[a] = x.min(y);
        hi[a] = x.max(y);
    }
    (lo, hi)
}

fn random_base_node(rng: &mut SplitMix64, p: &Params, v: VoxelAddr, leaf: bool) -> BaseNode {
    let (mut lo, mut hi) = random_box(rng, p);
    if rng.below(8) == 0 {
        // A box over most of its voxel (the half-scene rule at the top).
        lo = [0; 3];
        hi = [((1u32 << p.quant_bits) - 1) as u16; 3];
    }
    let cap = p.index_capacity();
    let record = NodeRecord {
        leaf,
        voxel: v,
        lo,
        hi,
        first: rng.below(cap) as u32,
        count: 1 + rng.below(cap - 1) as u32,
    };
    let at = Reference {
        hier: rng.below(p.hier_capacity()) as u8,
        node: rng.below(cap) as u32,
    };
    let kind = if !leaf && rng.below(2) == 0 {
        BaseKind::Created {
            refs: vec![at; 1 + rng.below(3) as usize],
        }
    } else {
        BaseKind::Reused { at }
    };
    BaseNode { record, kind }
}

/// A random base as S610-S614 make one for a merging level `m`: about `n`
/// nodes at `m` clustered under a few voxels of a shallower LOD (an inner
/// node and/or a leaf per voxel, created or reused), and a few reused leaves
/// above `m`, at voxels that may coincide with the others' ancestors. Small
/// `n` on purpose often: single-node bases reach every top rule (a
/// single node at the top, the lift of a reused leaf, the half-scene rule,
/// a reused leaf at the LOD-0 top), and `n = 0` an empty base.
pub fn random_base(rng: &mut SplitMix64, p: &Params, n: usize) -> Vec<BaseNode> {
    let dmax = p.max_lod as u64;
    let m = match rng.below(4) {
        0 => rng.below(3.min(dmax + 1)) as u8,
        1 => p.max_lod,
        _ => rng.below(dmax + 1) as u8,
    };
    let mut voxels = std::collections::BTreeSet::new();
    // Clusters: a corner at LOD `m - up` and nodes below it.
    let up = rng.below(m as u64 + 1).min(4) as u8;
    let mut tries = 0;
    while voxels.len() < n && tries < 4 * n + 8 {
        tries += 1;
        let c = [0; 3].map(|_| rng.below(1u64 << (m - up)) as u32);
        for _ in 0..1 + rng.below(6) {
            let v = c.map(|x| (x << up) | rng.below(1u64 << up) as u32);
            voxels.insert((m, v));
        }
    }
    let mut base = Vec::new();
    for (lod, v) in voxels.into_iter().take(n) {
        let v = VoxelAddr::new(lod, v[0], v[1], v[2]);
        match rng.below(4) {
            0 => {
                base.push(random_base_node(rng, p, v, false));
                base.push(random_base_node(rng, p, v, true));
            }
            1 => base.push(random_base_node(rng, p, v, true)),
            _ => base.push(random_base_node(rng, p, v, false)),
        }
    }
    // Leaves above m (reused), sometimes.
    if m > 0 && rng.below(3) == 0 {
        for _ in 0..1 + rng.below(4) {
            let lod = rng.below(m as u64) as u8;
            let v = [0; 3].map(|_| rng.below(1u64 << lod) as u32);
            let mut node = random_base_node(rng, p, VoxelAddr::new(lod, v[0], v[1], v[2]), true);
            if let BaseKind::Created { refs } = &node.kind {
                node.kind = BaseKind::Reused { at: refs[0] };
            }
            base.push(node);
        }
    }
    base
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::build::build;
    use crate::build::GridMap;
    use crate::merge::level_choice::candidate_range;
    use crate::merge::{merge, MergeMode};
    use crate::scenes::random_soup;
    use crate::store::HierarchyStore;
    use crate::translate::TranslationTable;

    /// Records per LOD as a writer lays them out (8.11): the top level's
    /// every node, each deeper level's `End.records`, top first.
    fn records_per_level(tx: &BuilderTransaction) -> Vec<(u8, u64)> {
        let top = tx.done.top as usize;
        let mut out = Vec::new();
        for (d, beats) in tx.levels.iter().enumerate().skip(top) {
            let Some(LevelOut::End { nodes, records, .. }) = beats.last() else {
                panic!("level {d} ends with End");
            };
            let r = if d == top { *nodes } else { *records };
            if r > 0 {
                out.push((d as u8, r as u64));
            }
        }
        out
    }

    fn soup(p: &Params, id: u8, n: usize, seed: u64) -> Hierarchy {
        let mesh = random_soup(n, 0.25, seed);
        let (lo, hi) = mesh.bounds();
        let fitted = GridMap::fit(lo, hi, p);
        let grid = GridMap {
            origin: fitted.origin * 0.0,
            unit: 1.0 / (p.scene_edge() >> 3) as f64,
        };
        build(&mesh, &grid, p, id).expect("the soup builds")
    }

    /// The transaction's top and records per level equal `merge`'s merged
    /// hierarchy at every fixed level of real merges.
    #[test]
    fn transaction_matches_merge_on_real_inputs() {
        let p = Params::default();
        let mut store = HierarchyStore::new();
        let mut table = TranslationTable::new(p.hier_capacity() as usize, &p).unwrap();
        let mut hs = Vec::new();
        for (i, n) in [(1u8, 60usize), (2, 1), (3, 40)] {
            let h = soup(&p, i, n, 100 + i as u64);
            let t = Translation {
                lod: h.top_lod,
                t: [0, 0, 0],
            };
            table.write(i as u32, t).unwrap();
            hs.push((h.clone(), t));
            store.insert(h).unwrap();
        }
        let refs: Vec<&Hierarchy> = hs.iter().map(|(h, _)| h).collect();
        let (lo, hi) = candidate_range(&refs);
        let inputs: Vec<(&Hierarchy, Translation)> = hs.iter().map(|(h, t)| (h, *t)).collect();
        for m in lo..=hi {
            let base = fixed_level_base(&inputs, m, &p).unwrap();
            let tx = builder_transaction(&base, &p);
            let r = merge(&store, &[1, 2, 3], &table, MergeMode::Fixed(m), 9).unwrap();
            assert!(!tx.done.err);
            assert_eq!(tx.done.top, r.merged.top_lod, "m = {m}");
            assert_eq!(records_per_level(&tx), r.stats.nodes_per_level, "m = {m}");
        }
    }

    /// Random bases reach every top rule, and the transaction agrees with
    /// `build_upper` wherever it succeeds without materializing.
    #[test]
    fn random_bases_reach_every_top_rule() {
        let p = Params::new(6, 2, 10, 3).unwrap();
        let mut rng = SplitMix64(0xb1d);
        let (mut empty, mut leaf_at_top, mut half, mut lifted, mut several) = (0, 0, 0, 0, 0);
        for _ in 0..3000 {
            let n = match rng.below(3) {
                0 => rng.below(3) as usize,
                _ => rng.below(30) as usize,
            };
            let base = random_base(&mut rng, &p, n);
            let tx = builder_transaction(&base, &p);
            let r = crate::merge::upper_builder::build_upper(&base, &[], &p, 1);
            match (&r, tx.done.err) {
                (Err(MergeError::NoInputs), true) => empty += 1,
                (Err(MergeError::InputLeafAtTop { .. }), true) => leaf_at_top += 1,
                (Ok((h, c)), false) => {
                    assert_eq!(h.top_lod, tx.done.top);
                    assert_eq!(records_per_level(&tx), c.nodes_per_level);
                    assert_eq!(c.lifted as usize, tx.lifted);
                    lifted += (c.lifted > 0) as usize;
                    several += (h.root_count > 1) as usize;
                    half += tx.root_cut as usize;
                }
                // A reused inner node at the top needs its input.
                (Err(MergeError::UnknownInput(_)), false) => {}
                (r, e) => panic!("build_upper {r:?}, transaction err {e}"),
            }
        }
        assert!(
            empty > 0 && leaf_at_top > 0 && half > 0 && lifted > 0 && several > 0,
            "{empty} {leaf_at_top} {half} {lifted} {several}"
        );
    }
}
