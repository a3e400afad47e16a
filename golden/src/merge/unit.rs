//! The merging module's stages as the RTL sees them (SPEC.md section 8,
//! "Merging module RTL"): the beat formats of each stage's ready/valid
//! streams, packed with [`crate::layout`], and each stage's transaction,
//! whose expected outputs come from the golden stage functions
//! ([`super::level_merge::merge_level`], [`super::level::overlap_counts`],
//! [`super::level::above_threshold`]), never from a second model.
//!
//! Two stages:
//! - **S614, merge level** (unit 506): in, the merging-level nodes of all
//!   inputs in *delivery order* ([`level_stream`]): per voxel, Morton order,
//!   the inner nodes (input order), then the leaves (input order), then the
//!   child references of those inner nodes (same order), then one `End`
//!   beat after the last voxel. Out, the base nodes in golden order (per
//!   voxel: the created or reused inner node, then the leaves), each created
//!   node's references right after that voxel's leaves, then `End`.
//! - **S608, overlap counter** (unit 508): in, one level's `(voxel, rank)`
//!   beats in `(Morton, rank)` order then `End`; out, one beat: `shared`,
//!   `union`, whether `shared * den > num * union`, and a count overflow flag.
//!
//! Also the seeded stimulus of both (hard cases on purpose: shared voxels,
//! lone inner nodes, inner + leaf at one voxel, two inner nodes of one input,
//! `count` overflow at small `I`, voxels at the grid's edges).

use std::collections::BTreeSet;
use std::ops::Range;

use super::error::MergeError;
use super::level::{above_threshold, overlap_counts, LevelOverlap};
use super::level_merge::{merge_level, BaseKind, BaseNode, LevelMergeCounts};
use super::walk::PlacedNode;
use crate::grid::VoxelAddr;
use crate::layout::{Bits, Field, LayoutError, NodeLayout, RefLayout};
use crate::params::{bits_to_hold, Params};
use crate::store::{Hierarchy, NodeRecord, Reference};
use crate::translate::stimulus::SplitMix64;

// ---------------------------------------------------------------------------
// S614 beats

/// Kind codes of an S614 input beat (the `kind` field).
pub mod level_kind {
    /// A translated inner node at the merging level.
    pub const INNER: u64 = 0;
    /// A translated leaf at the merging level.
    pub const LEAF: u64 = 1;
    /// A child reference of an inner node of the current voxel.
    pub const CHILD_REF: u64 = 2;
    /// End of the level.
    pub const END: u64 = 3;
}

/// Kind codes of an S614 output beat.
pub mod base_kind {
    /// A created node (record only; its references follow the voxel's leaves).
    pub const CREATED: u64 = 0;
    /// An input node referenced where it is stored (`ref` = where).
    pub const REUSED: u64 = 1;
    /// A reference of the last created node.
    pub const REF: u64 = 2;
    /// End of the level.
    pub const END: u64 = 3;
}

/// One beat into the S614 unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LevelBeat {
    /// A merging-level inner node, translated, and where it is stored.
    Inner {
        /// The stored record with its voxel translated.
        record: NodeRecord,
        /// Where the node is stored: `(input id, node index)`.
        at: Reference,
    },
    /// A merging-level leaf, translated, and where it is stored.
    Leaf {
        /// The stored record with its voxel translated.
        record: NodeRecord,
        /// Where the node is stored: `(input id, node index)`.
        at: Reference,
    },
    /// A child reference (as stored in its input's `refs`).
    ChildRef(Reference),
    /// End of the level.
    End,
}

/// One beat out of the S614 unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BaseBeat {
    /// A created node: `first` 0, `count` the number of its references
    /// modulo `2^I`; `count_overflow` when that number is `>= 2^I`.
    Created {
        /// The created inner record: the voxel, the per-axis min/max of the merged
        /// nodes' cells, `first` 0, `count` modulo `2^I`.
        record: NodeRecord,
        /// The number of references is `2^I` or more (the `err` bit).
        count_overflow: bool,
    },
    /// A reused input node (translated record) and where it is stored.
    Reused {
        /// The input node's record as it came in (voxel translated).
        record: NodeRecord,
        /// Where the node is stored: `(input id, node index)`.
        at: Reference,
    },
    /// A reference of the preceding created node.
    Ref(Reference),
    /// End of the level.
    End,
}

/// Bit layout of an S614 beat, from bit 0: `rec` (a node record, section 3),
/// `ref` (a reference), `kind` (2 bits), and on output beats `err` (1 bit).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BeatLayout {
    /// Layout of the node record in `rec`.
    pub node: NodeLayout,
    /// Layout of the reference in `ref`.
    pub reference: RefLayout,
    /// `rec` (W bits, from bit 0): the node record; 0 on reference and `End` beats.
    pub rec: Field,
    /// `ref` (I + H bits): where a node is stored, or a child reference; 0 on a
    /// created node and on `End`.
    pub refer: Field,
    /// `kind` (2 bits): a [`level_kind`] code in, a [`base_kind`] code out.
    pub kind: Field,
    /// Output beats only: the count-overflow flag.
    pub err: Option<Field>,
    /// Width of the beat in bits.
    pub width: u32,
}

impl BeatLayout {
    fn new(p: &Params, with_err: bool) -> BeatLayout {
        let node = NodeLayout::new(p);
        let reference = RefLayout::new(p);
        let rec = Field {
            name: "rec",
            offset: 0,
            width: node.width(),
        };
        let refer = Field {
            name: "ref",
            offset: rec.end(),
            width: reference.width(),
        };
        let kind = Field {
            name: "kind",
            offset: refer.end(),
            width: 2,
        };
        let err = with_err.then_some(Field {
            name: "err",
            offset: kind.end(),
            width: 1,
        });
        let width = err.map_or(kind.end(), |e| e.end());
        BeatLayout {
            node,
            reference,
            rec,
            refer,
            kind,
            err,
            width,
        }
    }

    /// The input beat layout (`rec`, `ref`, `kind`).
    pub fn input(p: &Params) -> BeatLayout {
        BeatLayout::new(p, false)
    }

    /// The output beat layout (`rec`, `ref`, `kind`, `err`).
    pub fn output(p: &Params) -> BeatLayout {
        BeatLayout::new(p, true)
    }

    fn put(
        &self,
        rec: Option<&NodeRecord>,
        r: Option<&Reference>,
        kind: u64,
    ) -> Result<Bits, LayoutError> {
        let mut b = Bits::zero(self.width);
        if let Some(n) = rec {
            b.put(self.rec.offset, &n.pack(&self.node)?)?;
        }
        if let Some(r) = r {
            b.put(self.refer.offset, &r.pack(&self.reference)?)?;
        }
        b.set(&self.kind, kind)?;
        Ok(b)
    }
}

impl LevelBeat {
    /// The packed beat ([`BeatLayout::input`]).
    pub fn pack(&self, l: &BeatLayout) -> Result<Bits, LayoutError> {
        match self {
            LevelBeat::Inner { record, at } => l.put(Some(record), Some(at), level_kind::INNER),
            LevelBeat::Leaf { record, at } => l.put(Some(record), Some(at), level_kind::LEAF),
            LevelBeat::ChildRef(r) => l.put(None, Some(r), level_kind::CHILD_REF),
            LevelBeat::End => l.put(None, None, level_kind::END),
        }
    }
}

impl BaseBeat {
    /// The packed beat ([`BeatLayout::output`]).
    pub fn pack(&self, l: &BeatLayout) -> Result<Bits, LayoutError> {
        match self {
            BaseBeat::Created {
                record,
                count_overflow,
            } => {
                let mut b = l.put(Some(record), None, base_kind::CREATED)?;
                if let Some(e) = &l.err {
                    b.set(e, *count_overflow as u64)?;
                }
                Ok(b)
            }
            BaseBeat::Reused { record, at } => l.put(Some(record), Some(at), base_kind::REUSED),
            BaseBeat::Ref(r) => l.put(None, Some(r), base_kind::REF),
            BaseBeat::End => l.put(None, None, base_kind::END),
        }
    }
}

/// One S614 transaction per voxel: its input beats and the output beats
/// they produce (the final `End` is a group of its own).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LevelGroup {
    /// This group's beats in [`LevelTransaction::inputs`].
    pub inputs: Range<usize>,
    /// The beats they produce in [`LevelTransaction::outputs`].
    pub outputs: Range<usize>,
}

/// A whole level through S614: input beats, expected output beats, and the
/// per-voxel grouping of both.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LevelTransaction {
    /// The input beats in delivery order ([`level_stream`]), `End` last.
    pub inputs: Vec<LevelBeat>,
    /// The expected output beats: per voxel the created or reused inner node,
    /// the leaves, a created node's references; `End` last.
    pub outputs: Vec<BaseBeat>,
    /// One group per voxel in stream order, then one for the final `End`.
    pub groups: Vec<LevelGroup>,
}

/// One voxel's input beats, with the range of sorted placed nodes they came from.
pub type VoxelBeats = (Range<usize>, Vec<LevelBeat>);

/// The delivery order of S614's input: sorted by (Morton, leaf, input rank)
/// (stable), per voxel the inner nodes, the leaves, then the inner nodes'
/// child references in the same order; `End` last. Grouping is per voxel.
pub fn level_stream(
    at_level: &[PlacedNode],
    inputs: &[&Hierarchy],
) -> Result<Vec<VoxelBeats>, MergeError> {
    let mut sorted = at_level.to_vec();
    sorted.sort_by_key(|n| (n.record.voxel.morton(), n.record.leaf, n.rank));
    let mut out = Vec::new();
    let mut i = 0;
    while i < sorted.len() {
        let v = sorted[i].record.voxel;
        let j = i + sorted[i..]
            .iter()
            .take_while(|n| n.record.voxel == v)
            .count();
        let group = &sorted[i..j];
        let mut beats = Vec::new();
        for n in group {
            beats.push(if n.record.leaf {
                LevelBeat::Leaf {
                    record: n.record,
                    at: n.at,
                }
            } else {
                LevelBeat::Inner {
                    record: n.record,
                    at: n.at,
                }
            });
        }
        for n in group.iter().filter(|n| !n.record.leaf) {
            let h = inputs[n.rank as usize];
            let refs = super::walk::children(h, n.at.node, &h.nodes[n.at.node as usize])?;
            beats.extend(refs.iter().map(|r| LevelBeat::ChildRef(*r)));
        }
        out.push((i..j, beats));
        i = j;
    }
    Ok(out)
}

/// S614 as a stream transaction: the input beats in delivery order and the
/// expected output beats, computed by the golden [`merge_level`].
pub fn level_transaction(
    at_level: &[PlacedNode],
    inputs: &[&Hierarchy],
    p: &Params,
) -> Result<LevelTransaction, MergeError> {
    let mut counts = LevelMergeCounts::default();
    let base = merge_level(at_level.to_vec(), inputs, p, &mut counts)?;
    let groups_in = level_stream(at_level, inputs)?;
    let mut tx = LevelTransaction {
        inputs: Vec::new(),
        outputs: Vec::new(),
        groups: Vec::new(),
    };
    let mut b = 0;
    for (_, beats) in groups_in {
        let v = match beats[0] {
            LevelBeat::Inner { record, .. } | LevelBeat::Leaf { record, .. } => record.voxel,
            _ => unreachable!("a voxel group starts with a node"),
        };
        let in_start = tx.inputs.len();
        let out_start = tx.outputs.len();
        tx.inputs.extend(beats);
        let mut refs_after = Vec::new();
        while b < base.len() && base[b].record.voxel == v {
            tx.outputs.push(base_beat(&base[b], p, &mut refs_after));
            b += 1;
        }
        tx.outputs.extend(refs_after);
        tx.groups.push(LevelGroup {
            inputs: in_start..tx.inputs.len(),
            outputs: out_start..tx.outputs.len(),
        });
    }
    debug_assert_eq!(b, base.len(), "every base node belongs to a voxel group");
    let (i, o) = (tx.inputs.len(), tx.outputs.len());
    tx.inputs.push(LevelBeat::End);
    tx.outputs.push(BaseBeat::End);
    tx.groups.push(LevelGroup {
        inputs: i..i + 1,
        outputs: o..o + 1,
    });
    Ok(tx)
}

/// The output beat of one golden base node; a created node's references go
/// to `refs_after` (they follow the voxel's leaves).
fn base_beat(n: &BaseNode, p: &Params, refs_after: &mut Vec<BaseBeat>) -> BaseBeat {
    match &n.kind {
        BaseKind::Reused { at } => BaseBeat::Reused {
            record: n.record,
            at: *at,
        },
        BaseKind::Created { refs } => {
            refs_after.extend(refs.iter().map(|r| BaseBeat::Ref(*r)));
            let total = refs.len() as u64;
            BaseBeat::Created {
                record: NodeRecord {
                    first: 0,
                    count: (total % p.index_capacity()) as u32,
                    ..n.record
                },
                count_overflow: total >= p.index_capacity(),
            }
        }
    }
}

// ---------------------------------------------------------------------------
// S608 overlap counter beats

/// Bit layout of an overlap-counter input beat, from bit 0: `x`, `y`, `z`
/// (D bits each), `rank` (`bits_to_hold(k - 1)`), `end` (1); and of its
/// output beat: `shared`, `union` (I bits each), `above` (1), `overflow` (1).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OverlapLayout {
    /// In beat: `x`, `y`, `z` of the translated voxel (D bits each), from bit 0.
    pub coord: [Field; 3],
    /// In beat: the rank of the input holding the voxel ([`rank_bits`]`(k)` bits).
    pub rank: Field,
    /// In beat: 1 on the `End` beat closing the level.
    pub end: Field,
    /// Width of an input beat in bits.
    pub in_width: u32,
    /// Out beat: `shared` (I bits, from bit 0), voxels held by two or more inputs.
    pub shared: Field,
    /// Out beat: `union` (I bits), voxels held by any input.
    pub union: Field,
    /// Out beat: `above` (1 bit), `shared * den > num * union`.
    pub above: Field,
    /// Out beat: `overflow` (1 bit), `union` reached `2^I`; the other fields are then 0.
    pub overflow: Field,
    /// Width of the output beat in bits.
    pub out_width: u32,
}

impl OverlapLayout {
    /// The layouts for `p` and `k` inputs (`k >= 1`).
    pub fn new(p: &Params, k: usize) -> OverlapLayout {
        let d = p.coord_bits();
        let i = p.index_bits as u32;
        let coord = [
            Field::new("x", 0, d),
            Field::new("y", d, d),
            Field::new("z", 2 * d, d),
        ];
        let rank = Field::new("rank", 3 * d, rank_bits(k));
        let end = Field::new("end", rank.end(), 1);
        let shared = Field::new("shared", 0, i);
        let union = Field::new("union", i, i);
        let above = Field::new("above", 2 * i, 1);
        let overflow = Field::new("overflow", 2 * i + 1, 1);
        OverlapLayout {
            coord,
            rank,
            end,
            in_width: end.end(),
            shared,
            union,
            above,
            overflow,
            out_width: overflow.end(),
        }
    }
}

/// Bits of an input rank for `k` inputs.
pub fn rank_bits(k: usize) -> u32 {
    bits_to_hold(k.saturating_sub(1) as u64)
}

/// One beat into the overlap counter: a voxel of the level and the rank of
/// the input occupying it, or the end of the level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OverlapBeat {
    /// A voxel of the level held by input `rank`.
    Voxel {
        /// The translated voxel.
        voxel: VoxelAddr,
        /// The input's rank, `0..k`.
        rank: u16,
    },
    /// The end of the level (`end` = 1).
    End,
}

/// The overlap counter's single output beat of a level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OverlapResult {
    /// `shared`, `union` and `above` are 0 when `overflow` (a count reached `2^I`).
    pub shared: u64,
    /// Voxels held by at least one input (`union(l)`).
    pub union: u64,
    /// `shared * den > num * union` (strict, exact).
    pub above: bool,
    /// `union` reached `2^I`, the width of the count fields.
    pub overflow: bool,
}

impl OverlapBeat {
    /// The packed beat.
    pub fn pack(&self, l: &OverlapLayout) -> Result<Bits, LayoutError> {
        let mut b = Bits::zero(l.in_width);
        match self {
            OverlapBeat::Voxel { voxel, rank } => {
                for (f, c) in l.coord.iter().zip([voxel.x, voxel.y, voxel.z]) {
                    b.set(f, c as u64)?;
                }
                b.set(&l.rank, *rank as u64)?;
            }
            OverlapBeat::End => b.set(&l.end, 1)?,
        }
        Ok(b)
    }
}

impl OverlapResult {
    /// The packed beat.
    pub fn pack(&self, l: &OverlapLayout) -> Result<Bits, LayoutError> {
        let mut b = Bits::zero(l.out_width);
        b.set(&l.shared, self.shared)?;
        b.set(&l.union, self.union)?;
        b.set(&l.above, self.above as u64)?;
        b.set(&l.overflow, self.overflow as u64)?;
        Ok(b)
    }
}

/// S608 for one level as a stream transaction: `voxels[r]` is the
/// (unsorted) voxel list of input rank `r`; the beats are their union in
/// (Morton, rank) order then `End`; the result comes from the golden
/// [`overlap_counts`] and [`above_threshold`].
pub fn overlap_transaction(
    voxels: &[Vec<VoxelAddr>],
    p: &Params,
    num: u32,
    den: u32,
) -> (Vec<OverlapBeat>, OverlapResult) {
    let mut beats: Vec<(u128, u16, VoxelAddr)> = voxels
        .iter()
        .enumerate()
        .flat_map(|(r, vs)| vs.iter().map(move |v| (v.morton(), r as u16, *v)))
        .collect();
    beats.sort_by_key(|b| (b.0, b.1));
    let streams = voxels
        .iter()
        .map(|vs| {
            let mut m: Vec<u128> = vs.iter().map(|v| v.morton()).collect();
            m.sort_unstable();
            m.into_iter()
        })
        .collect();
    let (shared, union) = overlap_counts(streams);
    let o = LevelOverlap {
        lod: 0,
        shared,
        union,
    };
    let overflow = union >= p.index_capacity();
    let result = if overflow {
        OverlapResult {
            shared: 0,
            union: 0,
            above: false,
            overflow,
        }
    } else {
        OverlapResult {
            shared,
            union,
            above: above_threshold(&o, num, den),
            overflow,
        }
    };
    let mut out: Vec<OverlapBeat> = beats
        .into_iter()
        .map(|(_, rank, voxel)| OverlapBeat::Voxel { voxel, rank })
        .collect();
    out.push(OverlapBeat::End);
    (out, result)
}

// ---------------------------------------------------------------------------
// Stimulus

/// A synthetic merging level: `k` input hierarchies (ids distinct, rank =
/// position) holding the level's nodes and their children, and the level's
/// placed nodes, ready for [`level_transaction`].
#[derive(Clone, Debug)]
pub struct LevelCase {
    /// The `k` synthetic inputs in rank order (distinct random ids): the level's
    /// nodes, padded with copies so that every child reference names a node.
    pub hierarchies: Vec<Hierarchy>,
    /// The level's placed nodes of all inputs, shuffled (not in delivery order).
    pub at_level: Vec<PlacedNode>,
}

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

/// Children per inner node: mostly 1..=8, sometimes up to 16, never more
/// than a `count` field holds.
fn random_child_count(rng: &mut SplitMix64, p: &Params) -> u32 {
    let most = (p.index_capacity() - 1).min(16);
    let n = if rng.below(4) == 0 { 16 } else { 8 };
    (1 + rng.below(n)).min(most) as u32
}

/// A random merging level with about `voxels` distinct voxels shared among
/// `k` inputs (`1 <= k <= 2^H`). The LOD is random (both ends included);
/// each input holds, per voxel, nothing, an inner node, a leaf or both, and
/// rarely two inner nodes.
pub fn random_level_case(rng: &mut SplitMix64, p: &Params, k: usize, voxels: usize) -> LevelCase {
    let lod = match rng.below(5) {
        0 => 0,
        1 => p.max_lod,
        _ => rng.below(p.max_lod as u64 + 1) as u8,
    };
    random_level_case_at(rng, p, k, voxels, lod)
}

/// [`random_level_case`] at a given LOD (`lod <= D`).
pub fn random_level_case_at(
    rng: &mut SplitMix64,
    p: &Params,
    k: usize,
    voxels: usize,
    lod: u8,
) -> LevelCase {
    let possible = 1u64.checked_shl(3 * lod as u32).unwrap_or(u64::MAX);
    let want = (voxels as u64).min(possible) as usize;
    let mut set = BTreeSet::new();
    while set.len() < want {
        set.insert((
            random_coord(rng, lod),
            random_coord(rng, lod),
            random_coord(rng, lod),
        ));
    }
    let mut ids: Vec<u8> = (0..p.hier_capacity()).map(|v| v as u8).collect();
    for i in 0..ids.len() {
        let j = i + rng.below((ids.len() - i) as u64) as usize;
        ids.swap(i, j);
    }
    let mut hierarchies: Vec<Hierarchy> = ids[..k]
        .iter()
        .map(|&id| Hierarchy {
            id,
            params: *p,
            nodes: Vec::new(),
            refs: Vec::new(),
            prims: Vec::new(),
            root_count: 1,
            top_lod: lod,
        })
        .collect();
    let mut at_level = Vec::new();
    let density = 1 + rng.below(4);
    // Node indices must fit I bits: each input holds at most `limit` nodes.
    let limit = p.index_capacity().min(64) as usize;
    // Each input's `refs`: `limit` children, ranges of inner nodes may overlap.
    for h in &mut hierarchies {
        h.refs = (0..limit)
            .map(|_| Reference {
                hier: h.id,
                node: rng.below(limit as u64) as u32,
            })
            .collect();
    }
    for &(x, y, z) in &set {
        let voxel = VoxelAddr::new(lod, x, y, z);
        for (rank, h) in hierarchies.iter_mut().enumerate() {
            if rng.below(4) >= density {
                continue;
            }
            let what = rng.below(16);
            let inner = match what {
                0..=5 => 1,
                6 => 2,
                7..=10 => 0,
                _ => 1,
            };
            let leaf = matches!(what, 7..=12) && h.nodes.len() + inner < limit;
            let inner = inner.min(limit - h.nodes.len().min(limit));
            for _ in 0..inner {
                let (lo, hi) = random_box(rng, p);
                let count = random_child_count(rng, p);
                let first = rng.below((h.refs.len() - count as usize) as u64 + 1) as u32;
                let record = NodeRecord {
                    leaf: false,
                    voxel,
                    lo,
                    hi,
                    first,
                    count,
                };
                let at = Reference {
                    hier: h.id,
                    node: h.nodes.len() as u32,
                };
                h.nodes.push(record);
                at_level.push(PlacedNode {
                    rank: rank as u16,
                    at,
                    record,
                });
            }
            if leaf {
                let (lo, hi) = random_box(rng, p);
                let record = NodeRecord {
                    leaf: true,
                    voxel,
                    lo,
                    hi,
                    first: random_index(rng, p, 0),
                    count: random_index(rng, p, 1),
                };
                let at = Reference {
                    hier: h.id,
                    node: h.nodes.len() as u32,
                };
                h.nodes.push(record);
                at_level.push(PlacedNode {
                    rank: rank as u16,
                    at,
                    record,
                });
            }
        }
    }
    // Children must name existing nodes of their input: pad with copies.
    for h in &mut hierarchies {
        let filler = h.nodes.first().copied().unwrap_or(NodeRecord {
            leaf: true,
            voxel: VoxelAddr::ROOT,
            lo: [0; 3],
            hi: [0; 3],
            first: 0,
            count: 1,
        });
        while h.nodes.len() < limit {
            h.nodes.push(filler);
        }
    }
    // Walk order differs from delivery order: shuffle to prove the sort matters.
    for i in 0..at_level.len() {
        let j = i + rng.below((at_level.len() - i) as u64) as usize;
        at_level.swap(i, j);
    }
    LevelCase {
        hierarchies,
        at_level,
    }
}

impl LevelCase {
    /// [`level_transaction`] of this case.
    pub fn transaction(&self, p: &Params) -> Result<LevelTransaction, MergeError> {
        let hs: Vec<&Hierarchy> = self.hierarchies.iter().collect();
        level_transaction(&self.at_level, &hs, p)
    }
}

/// A random level for the overlap counter: `k` inputs, about `voxels`
/// voxels each drawn from a shared pool (so overlap ranges from none to
/// full), repeats allowed within an input (an inner node and a leaf).
pub fn random_overlap_case(
    rng: &mut SplitMix64,
    p: &Params,
    k: usize,
    voxels: usize,
) -> Vec<Vec<VoxelAddr>> {
    let lod = match rng.below(5) {
        0 => 0,
        1 => p.max_lod,
        _ => rng.below(p.max_lod as u64 + 1) as u8,
    };
    let pool_size = 1 + rng.below(voxels as u64 + 1) as usize;
    let pool: Vec<VoxelAddr> = (0..pool_size)
        .map(|_| {
            VoxelAddr::new(
                lod,
                random_coord(rng, lod),
                random_coord(rng, lod),
                random_coord(rng, lod),
            )
        })
        .collect();
    (0..k)
        .map(|_| {
            let n = rng.below(voxels as u64 + 1) as usize;
            (0..n)
                .map(|_| pool[rng.below(pool.len() as u64) as usize])
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beats_round_the_golden_merge() {
        let p = Params::new(5, 2, 3, 2).unwrap();
        let mut rng = SplitMix64(7);
        let mut created = 0;
        let mut overflow = 0;
        for _ in 0..200 {
            let case = random_level_case(&mut rng, &p, 3, 6);
            let tx = case.transaction(&p).unwrap();
            // Every golden base node appears once, in golden order.
            let hs: Vec<&Hierarchy> = case.hierarchies.iter().collect();
            let mut c = LevelMergeCounts::default();
            let base = merge_level(case.at_level.clone(), &hs, &p, &mut c).unwrap();
            let nodes: Vec<_> = tx
                .outputs
                .iter()
                .filter(|b| matches!(b, BaseBeat::Created { .. } | BaseBeat::Reused { .. }))
                .collect();
            assert_eq!(nodes.len(), base.len());
            created += c.created;
            overflow += tx
                .outputs
                .iter()
                .filter(|b| {
                    matches!(
                        b,
                        BaseBeat::Created {
                            count_overflow: true,
                            ..
                        }
                    )
                })
                .count();
            let l_in = BeatLayout::input(&p);
            let l_out = BeatLayout::output(&p);
            for b in &tx.inputs {
                assert_eq!(b.pack(&l_in).unwrap().width(), l_in.width);
            }
            for b in &tx.outputs {
                b.pack(&l_out).unwrap();
            }
        }
        assert!(
            created > 50 && overflow > 5,
            "created {created} overflow {overflow}"
        );
    }

    #[test]
    fn overlap_transaction_counts_distinct_inputs() {
        let p = Params::new(4, 0, 8, 2).unwrap();
        let v = |x| VoxelAddr::new(2, x, 0, 0);
        let (beats, r) = overlap_transaction(&[vec![v(1), v(3), v(3)], vec![v(3), v(2)]], &p, 1, 2);
        assert_eq!(beats.len(), 6);
        assert_eq!((r.shared, r.union, r.above), (1, 3, false));
        let (_, r) = overlap_transaction(&[vec![v(1), v(3)], vec![v(3), v(1)]], &p, 1, 2);
        assert_eq!((r.shared, r.union, r.above), (2, 2, true));
    }
}

// ---------------------------------------------------------------------------
// S616 one level up: grouping by parent voxel

/// Bit layout of the upper-level unit's beats. Input, from bit 0: `child`
/// (the bits of a node record S616 reads: `lod` through `hi_z`, i.e. record
/// bits `[1, first.offset)`, in the record's order), `end` (1). Output:
/// `rec` (a node record), `end` (1), `err` (1: the group's `first` or
/// `count` reached `2^I`, both then modulo `2^I`, or a child had `lo > hi`
/// on some axis).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UpperLayout {
    /// Layout of the node record (`rec`, and the part `child` carries).
    pub node: NodeLayout,
    /// In beat: `child` (from bit 0), record bits `[1, first.offset)`: `lod` through `hi_z`.
    pub child: Field,
    /// In beat: `end` (1 bit), set on the `End` beat closing the level.
    pub in_end: Field,
    /// Out beat: `rec` (W bits, from bit 0), the parent's inner record.
    pub rec: Field,
    /// Out beat: `end` (1 bit), set on the `End` beat.
    pub end: Field,
    /// Out beat: `err` (1 bit), the group's `first` or `count` reached `2^I`, or
    /// a child had `lo > hi`.
    pub err: Field,
    /// Width of an input beat in bits.
    pub in_width: u32,
    /// Width of an output beat in bits.
    pub out_width: u32,
}

impl UpperLayout {
    /// The layouts for `p`.
    pub fn new(p: &Params) -> UpperLayout {
        let node = NodeLayout::new(p);
        let child = Field::new("child", 0, node.first().offset - 1);
        let in_end = Field::new("end", child.end(), 1);
        let rec = Field::new("rec", 0, node.width());
        let end = Field::new("end", rec.end(), 1);
        let err = Field::new("err", end.end(), 1);
        UpperLayout {
            child,
            in_end,
            rec,
            end,
            err,
            in_width: in_end.end(),
            out_width: err.end(),
            node,
        }
    }

    /// Field `f` of a node record as it sits in an input beat's `child`
    /// (one bit lower: the `leaf` bit is not carried).
    pub fn in_child(&self, f: &Field) -> Field {
        Field {
            offset: f.offset - 1,
            ..*f
        }
    }
}

/// One beat of the upper-level unit: a node record, or the end of a level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UpperBeat {
    /// A node: a child on the input, its parent on the output.
    Node {
        /// The record; an input beat carries only `lod` through `hi_z`.
        record: NodeRecord,
        /// Output only: the `err` flag ([`UpperLayout::err`]); ignored on input.
        err: bool,
    },
    /// The end of the level.
    End,
}

impl UpperBeat {
    /// Packed as an input beat (`child` bits of the record; `err` ignored)
    /// or an output beat.
    pub fn pack(&self, l: &UpperLayout, output: bool) -> Result<Bits, LayoutError> {
        let mut b = Bits::zero(if output { l.out_width } else { l.in_width });
        match self {
            UpperBeat::Node { record, err } => {
                let r = record.pack(&l.node)?;
                if output {
                    b.put(l.rec.offset, &r)?;
                    b.set(&l.err, *err as u64)?;
                } else {
                    for i in 0..l.child.width {
                        if r.bit(i + 1) {
                            b.set(&Field::new("bit", i, 1), 1)?;
                        }
                    }
                }
            }
            UpperBeat::End => b.set(if output { &l.end } else { &l.in_end }, 1)?,
        }
        Ok(b)
    }
}

/// S616's grouping of one level as a stream transaction: `level` (records
/// of one LOD `d >= 1`, in Morton order as the level lists of S616 hold
/// them) in, one inner record per parent voxel out, computed by the golden
/// `build::upper::group_by_parent`: box = union of the children's
/// cells re-quantized into the parent, `first` = index of its first child
/// in the level, `count` = its children. Both streams end with `End`.
pub fn upper_transaction(level: &[NodeRecord], p: &Params) -> (Vec<UpperBeat>, Vec<UpperBeat>) {
    use crate::build::upper::{group_by_parent, LevelNode};
    let nodes: Vec<LevelNode> = level
        .iter()
        .map(|n| LevelNode {
            morton: n.voxel.morton(),
            x: n.voxel.x,
            y: n.voxel.y,
            z: n.voxel.z,
            leaf: n.leaf,
            base: true,
            lo: n.lo,
            hi: n.hi,
            first: n.first,
            count: n.count,
        })
        .collect();
    let cap = p.index_capacity();
    let parent_lod = level.first().map_or(0, |n| n.voxel.lod.saturating_sub(1));
    let bad_box = |n: &NodeRecord| (0..3).any(|a| n.lo[a] > n.hi[a]);
    let mut outputs: Vec<UpperBeat> = group_by_parent(&nodes, p.quant_bits)
        .iter()
        .map(|g| UpperBeat::Node {
            record: NodeRecord {
                leaf: false,
                voxel: VoxelAddr::new(parent_lod, g.x, g.y, g.z),
                lo: g.lo,
                hi: g.hi,
                first: (g.first as u64 % cap) as u32,
                count: (g.count as u64 % cap) as u32,
            },
            err: g.first as u64 >= cap
                || g.count as u64 >= cap
                || level[g.first as usize..(g.first + g.count) as usize]
                    .iter()
                    .any(bad_box),
        })
        .collect();
    outputs.push(UpperBeat::End);
    let mut inputs: Vec<UpperBeat> = level
        .iter()
        .map(|n| UpperBeat::Node {
            record: *n,
            err: false,
        })
        .collect();
    inputs.push(UpperBeat::End);
    (inputs, outputs)
}

/// A random level of about `n` nodes at one LOD `d >= 1` in Morton order:
/// clustered so that parents have 1 to 8 children, sometimes an inner node
/// and a leaf at one voxel, boxes and `first`/`count` random.
pub fn random_upper_level(rng: &mut SplitMix64, p: &Params, n: usize) -> Vec<NodeRecord> {
    let lod = match rng.below(4) {
        0 => 1,
        1 => p.max_lod,
        _ => 1 + rng.below(p.max_lod as u64) as u8,
    };
    let mut set = BTreeSet::new();
    let mut out = Vec::new();
    while set.len() < n {
        // A parent voxel and some of its children.
        let (px, py, pz) = (
            random_coord(rng, lod - 1),
            random_coord(rng, lod - 1),
            random_coord(rng, lod - 1),
        );
        let children = 1 + rng.below(8);
        for _ in 0..children {
            let o = rng.below(8) as u32;
            set.insert(VoxelAddr::new(
                lod,
                px * 2 + (o & 1),
                py * 2 + (o >> 1 & 1),
                pz * 2 + (o >> 2),
            ));
        }
        if rng.below(64) == 0 {
            break;
        }
    }
    let mut voxels: Vec<VoxelAddr> = set.into_iter().collect();
    voxels.sort_by_key(|v| v.morton());
    for v in voxels {
        let both = rng.below(6) == 0;
        for leaf in [false, true] {
            if !both && (rng.below(2) == 0) != leaf {
                continue;
            }
            let (mut lo, mut hi) = random_box(rng, p);
            if p.quant_bits > 0 && rng.below(200) == 0 {
                // A corrupt box (lo > hi) on purpose: the unit flags it.
                let a = rng.below(3) as usize;
                (lo[a], hi[a]) = (hi[a].max(1), lo[a].min(hi[a].max(1) - 1));
            }
            out.push(NodeRecord {
                leaf,
                voxel: v,
                lo,
                hi,
                first: random_index(rng, p, 0),
                count: random_index(rng, p, 1),
            });
        }
    }
    out
}

// ---------------------------------------------------------------------------
// Root sorter: restoring Morton order after a translation

/// Why sorting the roots is enough: a translation at level `L` moves a node
/// at LOD `d >= L` by `t << (d - L)`, so a child moves by exactly twice its
/// parent's move and keeps its octant. Below the top, a breadth-first walk
/// that visits the roots in translated Morton order therefore meets every
/// level in translated Morton order (a voxel's descendants are contiguous
/// in Morton order at every LOD). Only the roots (`root_count`, at most 16
/// for a builder-made input: 8 octants of the root voxel, an inner node and
/// a leaf each) can come out of order; the root sorter orders them by
/// (translated Morton code, inner before leaf), stably, as golden's
/// [`super::level_merge::sort_stream`] orders one input.
///
/// The transaction: the roots of one input as [`LevelBeat::Inner`] /
/// [`LevelBeat::Leaf`] beats in stored order, then `End`; out, the first
/// `capacity` of them sorted, then `End` with `err` set when there were more
/// than `capacity` (those are dropped, never silently: the flag says so).
pub fn root_sort_transaction(
    roots: &[PlacedNode],
    capacity: usize,
) -> (Vec<LevelBeat>, Vec<(LevelBeat, bool)>) {
    let beat = |n: &PlacedNode| {
        if n.record.leaf {
            LevelBeat::Leaf {
                record: n.record,
                at: n.at,
            }
        } else {
            LevelBeat::Inner {
                record: n.record,
                at: n.at,
            }
        }
    };
    let mut inputs: Vec<LevelBeat> = roots.iter().map(beat).collect();
    inputs.push(LevelBeat::End);
    let mut kept: Vec<PlacedNode> = roots.iter().take(capacity).copied().collect();
    super::level_merge::sort_stream(&mut kept);
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
