//! Per-node merging without one level (paragraph 55): the roots of the
//! merged sub-hierarchies are chosen node by node, from the overlap of the
//! nodes themselves, irrespective of level.
//!
//! The rule, starting from the voxel groups at `lo` (the deepest top LOD):
//! at a voxel `v` (LOD `l`) holding `k` inner nodes (a well-formed input has
//! at most one per voxel, so `k` inputs meet there),
//! - `k >= 2`: take their children (LOD `l + 1`, translated) grouped by
//!   voxel; `S` = child voxels held by two or more inputs, `U` = child voxels
//!   held by any. If `S * den > num * U` (the same strict exact threshold as
//!   the overlap mode, per node) descend: every child voxel group is decided
//!   by this rule in turn. Otherwise merge here: one created node at `v`
//!   referencing all their children (as S614 does).
//! - `k == 1`: the inner node is reused as it is; `k == 0`: nothing.
//!
//! Leaves at `v` are always reused as they are.
//! Descending stops at the first voxel whose children overlap too little,
//! so each path ends in a created or reused node; the result is a base at
//! several LODs, on which S616 builds the upper levels.

pub mod unit;

use crate::merge::error::MergeError;
use crate::merge::fetcher::walk::{children, place_node, PlacedNode};
use crate::merge::merge_level::{
    created_node, sort_stream, voxel_groups, BaseNode, MergeLevelCounts,
};
use crate::params::Params;
use crate::store::Hierarchy;
use crate::translate::Translation;

/// What per-node merging did beyond S614's counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct PerNodeCounts {
    /// Voxels where the rule went one level deeper.
    pub descents: u64,
    /// Deepest LOD of a created node.
    pub deepest_created: u8,
}

/// One contested voxel: what [`PerNode::contest`] found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Contest {
    /// The translated children of the contested inner nodes, in stream
    /// order (8.4 key): the next LOD's voxel groups when descending.
    pub children: Vec<PlacedNode>,
    /// `S`: child voxels holding children of two or more inputs.
    pub shared: u64,
    /// `U`: child voxels.
    pub union: u64,
    /// `S * den > num * U`.
    pub descend: bool,
}

/// The decider's context.
pub struct PerNode<'a> {
    /// The input hierarchies, in rank order.
    pub inputs: &'a [&'a Hierarchy],
    /// Each input's translation, by rank.
    pub translations: &'a [Translation],
    /// The inputs' parameters (all equal).
    pub params: Params,
    /// Numerator of the descent threshold `S * den > num * U`.
    pub num: u32,
    /// Denominator of the descent threshold.
    pub den: u32,
}

impl PerNode<'_> {
    /// The translated children of the inner nodes of `inner`, in stream order.
    fn children_stream(&self, inner: &[&PlacedNode]) -> Result<Vec<PlacedNode>, MergeError> {
        let mut out = Vec::new();
        for n in inner {
            let h = self.inputs[n.rank as usize];
            for c in children(h, n.at.node, &h.nodes[n.at.node as usize])? {
                out.push(place_node(
                    h,
                    n.rank,
                    &self.translations[n.rank as usize],
                    c.node,
                )?);
            }
        }
        sort_stream(&mut out);
        Ok(out)
    }

    /// `(S, U)` of a sorted child stream.
    fn child_overlap(stream: &[PlacedNode]) -> (u64, u64) {
        let mut shared = 0;
        let groups = voxel_groups(stream);
        for g in &groups {
            let s = &stream[g.clone()];
            shared += s.iter().any(|n| n.rank != s[0].rank) as u64;
        }
        (shared, groups.len() as u64)
    }

    /// The rule at one voxel whose inner nodes `inner` (two or more) are
    /// contested: their translated children in stream order, `S`, `U` and
    /// whether to descend (`S * den > num * U`, strict, exact).
    pub fn contest(&self, inner: &[&PlacedNode]) -> Result<Contest, MergeError> {
        let children = self.children_stream(inner)?;
        let (shared, union) = Self::child_overlap(&children);
        let descend = shared as u128 * self.den as u128 > self.num as u128 * union as u128;
        Ok(Contest {
            children,
            shared,
            union,
            descend,
        })
    }

    /// Decides the voxel group `group` (one voxel, stream order), appending
    /// base nodes to `out`.
    pub fn decide(
        &self,
        group: &[PlacedNode],
        out: &mut Vec<BaseNode>,
        counts: &mut MergeLevelCounts,
        pn: &mut PerNodeCounts,
    ) -> Result<(), MergeError> {
        let inner: Vec<&PlacedNode> = group.iter().filter(|n| !n.record.leaf).collect();
        if inner.len() >= 2 {
            let c = self.contest(&inner)?;
            if c.descend {
                pn.descents += 1;
                for g in voxel_groups(&c.children) {
                    self.decide(&c.children[g], out, counts, pn)?;
                }
            } else {
                out.push(created_node(&inner, self.inputs, &self.params)?);
                counts.created += 1;
                pn.deepest_created = pn.deepest_created.max(inner[0].record.voxel.lod);
            }
        } else {
            for n in &inner {
                out.push(BaseNode::reused(n));
                counts.reused_inner += 1;
            }
        }
        for leaf in group.iter().filter(|n| n.record.leaf) {
            out.push(BaseNode::reused(leaf));
            counts.reused_leaves += 1;
        }
        Ok(())
    }

    /// Per-node merging of the nodes at the first level (all inputs, any order).
    pub fn merge_from(
        &self,
        mut first_level: Vec<PlacedNode>,
        counts: &mut MergeLevelCounts,
        pn: &mut PerNodeCounts,
    ) -> Result<Vec<BaseNode>, MergeError> {
        sort_stream(&mut first_level);
        let mut out = Vec::new();
        for g in voxel_groups(&first_level) {
            self.decide(&first_level[g], &mut out, counts, pn)?;
        }
        Ok(out)
    }
}
