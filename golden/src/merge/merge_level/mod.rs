//! S614 (paragraph 59): the merged nodes at the merging level.
//!
//! Over the Morton-sorted union of all inputs' translated merging-level
//! nodes, grouped by voxel `v`:
//! - inner nodes of two or more inputs at `v`: one **created** node at `v`
//!   referencing the children (one LOD below) of every one of them, in input
//!   order, as `(input id, node index)`; its box is the union of their boxes
//!   re-quantized outward into `v` ([`requantize_outward`]);
//! - an inner node alone at `v` (no other input's inner node there): **reused**,
//!   referenced directly: a created node would have the same box and children;
//! - every leaf at `v`: reused as it is (a leaf has no children to merge;
//!   its primitives index its input's triangles).

pub mod unit;

use crate::grid::VoxelAddr;
use crate::merge::error::MergeError;
use crate::merge::fetcher::walk::{children, PlacedNode};
use crate::params::Params;
use crate::store::{node_box_fine, voxel_box_fine, Hierarchy, NodeRecord, Reference};

/// What a node of the merged hierarchy's base stands for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BaseKind {
    /// A new record of the merged hierarchy with these references.
    Created {
        /// The children of the merged inner nodes in input rank order, each
        /// `(input id, node index)` as stored in its input.
        refs: Vec<Reference>,
    },
    /// An input node referenced where it is stored.
    Reused {
        /// Where the node is stored: `(input id, node index)`.
        at: Reference,
    },
}

/// A node the upper levels (S616) are built on: a record in the scene
/// (translated voxel, box cells, leaf flag; `first`/`count` are the stored
/// ones for a reused node; a created one has `first` 0 and `count` its
/// number of references, which S614 and the writer use) and its kind.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BaseNode {
    /// The record with its voxel in the scene; a reused node's box, `first`
    /// and `count` are the stored ones.
    pub record: NodeRecord,
    /// A new record with its references, or an input node and where it is stored.
    pub kind: BaseKind,
}

impl BaseNode {
    /// A reused input node.
    pub fn reused(n: &PlacedNode) -> BaseNode {
        BaseNode {
            record: n.record,
            kind: BaseKind::Reused { at: n.at },
        }
    }
}

/// What S614 did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct MergeLevelCounts {
    /// Created nodes: voxels where two or more inner nodes were merged into
    /// one new record.
    pub created: u64,
    /// Inner nodes alone at their voxel, referenced where they are stored.
    pub reused_inner: u64,
    /// Leaves at the merging level(s), referenced where they are stored.
    pub reused_leaves: u64,
}

/// The cells of voxel `v` covering the fine-unit box `[lo, hi]`, rounded
/// outward: per axis `floor((a - v0) / e)` and `ceil((b - v0) / e) - 1`
/// (at least the former), `e = 2^(D-d)` fine units per cell. `None` when
/// the box is not inside the voxel.
pub fn requantize_outward(
    lo: [u64; 3],
    hi: [u64; 3],
    v: &VoxelAddr,
    p: &Params,
) -> Option<([u16; 3], [u16; 3])> {
    let (vlo, vhi) = voxel_box_fine(v, p);
    let e = p.voxel_edge(v.lod);
    let mut clo = [0u16; 3];
    let mut chi = [0u16; 3];
    for a in 0..3 {
        if lo[a] < vlo[a] || hi[a] > vhi[a] || lo[a] > hi[a] {
            return None;
        }
        let l = (lo[a] - vlo[a]) / e;
        let h = (hi[a] - vlo[a]).div_ceil(e).saturating_sub(1).max(l);
        clo[a] = l as u16;
        chi[a] = h as u16;
    }
    Some((clo, chi))
}

/// The union of the boxes of `nodes` (all at voxel `v`), re-quantized
/// outward into `v`.
pub fn union_box(nodes: &[&PlacedNode], v: &VoxelAddr, p: &Params) -> Option<([u16; 3], [u16; 3])> {
    let mut lo = [u64::MAX; 3];
    let mut hi = [0u64; 3];
    for n in nodes {
        let (a, b) = node_box_fine(&n.record, p);
        for k in 0..3 {
            lo[k] = lo[k].min(a[k]);
            hi[k] = hi[k].max(b[k]);
        }
    }
    requantize_outward(lo, hi, v, p)
}

/// One created node at `v` merging the inner nodes `inner` (two or more):
/// their children's references in input order, the union of their boxes.
pub fn created_node(
    inner: &[&PlacedNode],
    inputs: &[&Hierarchy],
    p: &Params,
) -> Result<BaseNode, MergeError> {
    let v = inner[0].record.voxel;
    let mut refs = Vec::new();
    for n in inner {
        let h = inputs[n.rank as usize];
        refs.extend_from_slice(children(h, n.at.node, &h.nodes[n.at.node as usize])?);
    }
    let (lo, hi) = union_box(inner, &v, p).ok_or_else(|| MergeError::BadInput {
        input: inner[0].at.hier,
        node: Some(inner[0].at.node),
        field: "voxel",
        expected: "nodes of one voxel".into(),
        found: format!("{v:?}"),
    })?;
    Ok(BaseNode {
        record: NodeRecord {
            leaf: false,
            voxel: v,
            lo,
            hi,
            first: 0,
            count: refs.len() as u32,
        },
        kind: BaseKind::Created { refs },
    })
}

/// Sorts `nodes` into the stream order (Morton, input rank, inner first).
pub fn sort_stream(nodes: &mut [PlacedNode]) {
    nodes.sort_by_key(|n| n.key());
}

/// The runs of equal voxels of a sorted stream, as index ranges.
pub fn voxel_groups(nodes: &[PlacedNode]) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < nodes.len() {
        let v = nodes[i].record.voxel;
        let mut j = i + 1;
        while j < nodes.len() && nodes[j].record.voxel == v {
            j += 1;
        }
        out.push(i..j);
        i = j;
    }
    out
}

/// S614 over the merging-level nodes of all inputs: the base nodes at the
/// merging level, in stream order.
pub fn merge_level(
    mut at_level: Vec<PlacedNode>,
    inputs: &[&Hierarchy],
    p: &Params,
    counts: &mut MergeLevelCounts,
) -> Result<Vec<BaseNode>, MergeError> {
    sort_stream(&mut at_level);
    let mut out = Vec::new();
    for g in voxel_groups(&at_level) {
        let group = &at_level[g];
        let inner: Vec<&PlacedNode> = group.iter().filter(|n| !n.record.leaf).collect();
        if inner.len() >= 2 {
            out.push(created_node(&inner, inputs, p)?);
            counts.created += 1;
        } else if let Some(n) = inner.first() {
            out.push(BaseNode::reused(n));
            counts.reused_inner += 1;
        }
        for leaf in group.iter().filter(|n| n.record.leaf) {
            out.push(BaseNode::reused(leaf));
            counts.reused_leaves += 1;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requantize_is_outward_and_exact() {
        let p = Params::new(4, 2, 8, 2).unwrap();
        // LOD 2 voxel x = 1: grid [4, 8) = fine [16, 32), cells of 4 fine units.
        let v = VoxelAddr::new(2, 1, 0, 0);
        let r = requantize_outward([17, 0, 0], [24, 16, 1], &v, &p).unwrap();
        assert_eq!(r, ([0, 0, 0], [1, 3, 0]));
        let r = requantize_outward([20, 4, 0], [25, 8, 16], &v, &p).unwrap();
        assert_eq!(r, ([1, 1, 0], [2, 1, 3]));
        assert_eq!(requantize_outward([15, 0, 0], [20, 1, 1], &v, &p), None);
        assert_eq!(requantize_outward([16, 0, 0], [33, 1, 1], &v, &p), None);
    }
}
