//! S614, the merging level (unit 506): the beats of its input and output
//! streams, its transaction from golden's [`merge_level`], and its seeded
//! stimulus ([`LevelCase`]).

use std::collections::BTreeSet;
use std::ops::Range;

use crate::bits::Bits;
use crate::grid::VoxelAddr;
use crate::layout::{Field, Layout, LayoutError, NodeLayout, RefLayout};
use crate::merge::error::MergeError;
use crate::merge::fetcher::walk::PlacedNode;
use crate::merge::merge_level::{merge_level, BaseKind, BaseNode, MergeLevelCounts};
use crate::merge::stimulus::{random_box, random_coord, random_index};
use crate::params::Params;
use crate::store::{Hierarchy, NodeRecord, Reference};
use crate::translate::stimulus::SplitMix64;

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
/// A [`Layout`] (through `Deref`) with an accessor per field.
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
    beat: Layout,
}

impl std::ops::Deref for BeatLayout {
    type Target = Layout;
    fn deref(&self) -> &Layout {
        &self.beat
    }
}

impl BeatLayout {
    fn new(p: &Params, with_err: bool) -> BeatLayout {
        let node = NodeLayout::new(p);
        let reference = RefLayout::new(p);
        let mut beat = Layout::new(if with_err {
            "S614 output beat"
        } else {
            "S614 input beat"
        });
        let rec = beat.push("rec", node.width());
        let refer = beat.push("ref", reference.width());
        let kind = beat.push("kind", 2);
        let err = with_err.then(|| beat.push("err", 1));
        BeatLayout {
            node,
            reference,
            rec,
            refer,
            kind,
            err,
            beat,
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
        let mut b = Bits::zero(self.width());
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
    /// A placed node's beat: [`LevelBeat::Leaf`] or [`LevelBeat::Inner`]
    /// by its record's leaf flag.
    pub fn of_node(n: &PlacedNode) -> LevelBeat {
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
    }

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
            beats.push(LevelBeat::of_node(n));
        }
        for n in group.iter().filter(|n| !n.record.leaf) {
            let h = inputs[n.rank as usize];
            let refs =
                crate::merge::fetcher::walk::children(h, n.at.node, &h.nodes[n.at.node as usize])?;
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
    let mut counts = MergeLevelCounts::default();
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
            let mut c = MergeLevelCounts::default();
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
                assert_eq!(b.pack(&l_in).unwrap().width(), l_in.width());
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
}
