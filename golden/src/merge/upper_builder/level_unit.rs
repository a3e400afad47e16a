//! S616, one upper level in hardware: grouping a level's records by parent
//! voxel. Its beats, its transaction and its stimulus.

use std::collections::BTreeSet;

use crate::bits::Bits;
use crate::grid::VoxelAddr;
use crate::layout::{Field, Layout, LayoutError, NodeLayout};
use crate::merge::stimulus::{random_box, random_coord, random_index};
use crate::params::Params;
use crate::store::NodeRecord;
use crate::translate::stimulus::SplitMix64;

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
    /// The input beat: `child`, `end`.
    pub input: Layout,
    /// In beat: `child` (from bit 0), record bits `[1, first.offset)`: `lod` through `hi_z`.
    pub child: Field,
    /// In beat: `end` (1 bit), set on the `End` beat closing the level.
    pub in_end: Field,
    /// The output beat: `rec`, `end`, `err`.
    pub output: Layout,
    /// Out beat: `rec` (W bits, from bit 0), the parent's inner record.
    pub rec: Field,
    /// Out beat: `end` (1 bit), set on the `End` beat.
    pub end: Field,
    /// Out beat: `err` (1 bit), the group's `first` or `count` reached `2^I`, or
    /// a child had `lo > hi`.
    pub err: Field,
}

impl UpperLayout {
    /// The layouts for `p`.
    pub fn new(p: &Params) -> UpperLayout {
        let node = NodeLayout::new(p);
        let mut input = Layout::new("upper level input");
        let child = input.push("child", node.first().offset - 1);
        let in_end = input.push("end", 1);
        let mut output = Layout::new("upper level output");
        let rec = output.push("rec", node.width());
        let end = output.push("end", 1);
        let err = output.push("err", 1);
        UpperLayout {
            node,
            input,
            child,
            in_end,
            output,
            rec,
            end,
            err,
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
        let mut b = Bits::zero(if output {
            l.output.width()
        } else {
            l.input.width()
        });
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
