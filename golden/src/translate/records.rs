//! The translation unit applied to hierarchy-store records
//! ([`crate::store`]): the aligned move of a record, a hierarchy's extents,
//! and the cost of the expanding variant over a whole stored hierarchy.

use super::apply::translate_node;
use super::error::TranslateError;
use super::expand::{expansion_cost, ExpansionCost, NodeBox};
use super::extents::VoxelRange;
use super::translation::Translation;
use crate::params::Params;
use crate::store::{Hierarchy, NodeRecord};

impl From<&NodeRecord> for NodeBox {
    fn from(n: &NodeRecord) -> NodeBox {
        NodeBox {
            addr: n.voxel,
            lo: n.lo.map(u32::from),
            hi: n.hi.map(u32::from),
        }
    }
}

/// The aligned move of a record (SPEC 7.6): the voxel moves, the box cells,
/// the leaf flag and the child/primitive range stay as they are.
pub fn translate_record(
    n: &NodeRecord,
    t: &Translation,
    p: &Params,
) -> Result<NodeRecord, TranslateError> {
    Ok(NodeRecord {
        voxel: translate_node(n.voxel, t, p)?,
        ..*n
    })
}

/// The extents at LOD `lod` of a stored hierarchy: the voxel range of its
/// roots ([`VoxelRange::of_nodes`]).
pub fn hierarchy_extents(h: &Hierarchy, lod: u8) -> Result<VoxelRange, TranslateError> {
    let roots: Vec<_> = h.roots().iter().map(|n| n.voxel).collect();
    VoxelRange::of_nodes(&roots, lod, &h.params)
}

/// The cost of moving every node of `h` by `t` with the expanding variant
/// (SPEC 7.7): nodes at `d >= L` move aligned, nodes above split.
pub fn hierarchy_expansion_cost(
    h: &Hierarchy,
    t: &Translation,
) -> Result<ExpansionCost, TranslateError> {
    let nodes: Vec<NodeBox> = h.nodes.iter().map(NodeBox::from).collect();
    expansion_cost(&nodes, t, &h.params)
}
