//! The expanding variant (FIG. 11, 12a/12b, paragraphs 78-79): a translation
//! finer than a node's voxel. A node at LOD `d < L` moved by `t 2^(D-L)`
//! grid units no longer sits in one LOD-`d` voxel: its box straddles up to
//! two voxels per axis, so it becomes up to 8 nodes, one per covered voxel,
//! each with the part of the box inside that voxel re-quantized outward.
//! This is the growth the voxel-aligned translation exists to avoid (80);
//! the golden model implements it to measure that cost.
//!
//! Boxes are handled in fine units (SPEC section 3: grid units times `2^Q`):
//! a LOD-`d` voxel is `V = 2^(D-d+Q)` fine units, a cell `2^(D-d)`. The box
//! of cells `lo..=hi` of voxel `x` is the closed interval
//! `[x V + lo 2^(D-d), x V + (hi+1) 2^(D-d)]`; it covers the voxels
//! `floor(a / V) ..= floor((b - 1) / V)` (a box ending exactly on a voxel
//! boundary does not reach into the next voxel, so an unmoved box covers
//! only its own voxel).

use std::collections::{BTreeMap, HashSet};

use super::apply::{check_node, translate_node};
use super::error::{Axis, TranslateError};
use super::translation::Translation;
use crate::grid::VoxelAddr;
use crate::params::Params;

/// A node's voxel and its quantized box: cells `lo[a] ..= hi[a]` per axis,
/// each below `2^Q` (the node record's `lo_*`, `hi_*` fields).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct NodeBox {
    /// The node's voxel.
    pub addr: VoxelAddr,
    /// Lowest cell per axis (x, y, z) inside the voxel.
    pub lo: [u32; 3],
    /// Highest cell per axis, inclusive; `lo <= hi < 2^Q`.
    pub hi: [u32; 3],
}

impl NodeBox {
    /// The node whose box is its whole voxel (cells `0 ..= 2^Q - 1`).
    pub fn full_voxel(addr: VoxelAddr, p: &Params) -> NodeBox {
        let top = p.quant_cells() - 1;
        NodeBox {
            addr,
            lo: [0; 3],
            hi: [top; 3],
        }
    }

    /// Checks the address and `lo <= hi < 2^Q` on every axis.
    pub fn validate(&self, p: &Params) -> Result<(), TranslateError> {
        check_node(&self.addr, p)?;
        for axis in Axis::ALL {
            let (lo, hi) = (self.lo[axis.index()], self.hi[axis.index()]);
            if lo > hi || hi >= p.quant_cells() {
                return Err(TranslateError::InvalidBox {
                    axis,
                    lo,
                    hi,
                    quant_bits: p.quant_bits,
                });
            }
        }
        Ok(())
    }

    /// The box on `axis` as a closed fine-unit interval `[a, b]`; errors
    /// when the node is not valid for `p` ([`NodeBox::validate`]).
    pub fn fine_interval(&self, axis: Axis, p: &Params) -> Result<(i128, i128), TranslateError> {
        self.validate(p)?;
        Ok(self.fine_interval_unchecked(axis, p))
    }

    /// [`NodeBox::fine_interval`] for a node already validated.
    fn fine_interval_unchecked(&self, axis: Axis, p: &Params) -> (i128, i128) {
        let a = axis.index();
        let c = [self.addr.x, self.addr.y, self.addr.z][a] as i128;
        let cell = cell_shift(self.addr.lod, p);
        let v0 = c << (cell + p.quant_bits as u32);
        (
            v0 + ((self.lo[a] as i128) << cell),
            v0 + ((self.hi[a] as i128 + 1) << cell),
        )
    }
}

/// `log2` of a LOD-`d` cell in fine units: `D - d`.
fn cell_shift(d: u8, p: &Params) -> u32 {
    (p.max_lod - d) as u32
}

/// `log2` of a LOD-`d` voxel in fine units: `D - d + Q`.
fn voxel_shift(d: u8, p: &Params) -> u32 {
    cell_shift(d, p) + p.quant_bits as u32
}

/// The move of `t` on `axis` in fine units: `t << (D - L + Q)`; errors
/// when the translation is not valid for `p`.
pub fn fine_offset(t: &Translation, axis: Axis, p: &Params) -> Result<i128, TranslateError> {
    t.validate(p)?;
    Ok((t.t[axis.index()] as i128) << voxel_shift(t.lod, p))
}

/// The LOD-`d` voxel indices `first ..= last` covered by the fine interval
/// `[a, b]` (`a < b`): `floor(a / V)` to `floor((b - 1) / V)`.
pub(crate) fn covering_span(a: i128, b: i128, d: u8, p: &Params) -> (i128, i128) {
    let s = voxel_shift(d, p);
    (a >> s, (b - 1) >> s)
}

/// Quantizes the part of `[a, b]` inside voxel `v` at LOD `d` outward
/// (SPEC section 3): clip to `[v V, (v+1) V]`, then
/// `lo = floor((a' - v0) / cell)`, `hi = ceil((b' - v0) / cell) - 1`.
/// `v` must be in [`covering_span`], so the clipped part has positive width
/// and `lo <= hi < 2^Q` hold without clamping.
pub(crate) fn quantize_outward(a: i128, b: i128, v: i128, d: u8, p: &Params) -> (u32, u32) {
    let (cs, vs) = (cell_shift(d, p), voxel_shift(d, p));
    let v0 = v << vs;
    let a1 = a.max(v0) - v0;
    let b1 = b.min(v0 + (1i128 << vs)) - v0;
    let lo = a1 >> cs;
    let hi = ((b1 + (1i128 << cs) - 1) >> cs) - 1;
    debug_assert!(0 <= lo && lo <= hi && hi < 1i128 << p.quant_bits);
    (lo as u32, hi as u32)
}

/// Moves a node by a translation of any granularity.
///
/// `d >= L`: the aligned move ([`translate_node`]), one node, cells
/// unchanged. `d < L`: the box moved by `t 2^(D-L)` grid units must stay in
/// the scene `[0, 2^(D+Q)]` fine units (else
/// [`TranslateError::BoxOutsideScene`]); the result is one node per covered
/// LOD-`d` voxel, each with its clipped part quantized outward, listed with
/// x varying fastest, then y, then z (ascending).
pub fn expand_node(
    node: &NodeBox,
    t: &Translation,
    p: &Params,
) -> Result<Vec<NodeBox>, TranslateError> {
    node.validate(p)?;
    t.validate(p)?;
    let d = node.addr.lod;
    if d >= t.lod {
        let addr = translate_node(node.addr, t, p)?;
        return Ok(vec![NodeBox { addr, ..*node }]);
    }
    let limit = 1i128 << (p.max_lod as u32 + p.quant_bits as u32);
    let mut moved = [(0i128, 0i128); 3];
    let mut spans = [(0i128, 0i128); 3];
    for axis in Axis::ALL {
        let (a, b) = node.fine_interval_unchecked(axis, p);
        let o = fine_offset(t, axis, p)?;
        let (a, b) = (a + o, b + o);
        if a < 0 || b > limit {
            return Err(TranslateError::BoxOutsideScene {
                axis,
                lo: a,
                hi: b,
                limit,
            });
        }
        moved[axis.index()] = (a, b);
        spans[axis.index()] = covering_span(a, b, d, p);
    }
    let mut out = Vec::with_capacity(8);
    for vz in spans[2].0..=spans[2].1 {
        for vy in spans[1].0..=spans[1].1 {
            for vx in spans[0].0..=spans[0].1 {
                let v = [vx, vy, vz];
                let mut lo = [0u32; 3];
                let mut hi = [0u32; 3];
                for a in 0..3 {
                    (lo[a], hi[a]) = quantize_outward(moved[a].0, moved[a].1, v[a], d, p);
                }
                // Inside the scene: 0 <= v < 2^d, so the narrowing is exact.
                let addr = VoxelAddr::new(d, vx as u32, vy as u32, vz as u32);
                out.push(NodeBox { addr, lo, hi });
            }
        }
    }
    Ok(out)
}

/// [`expand_node`] for a node whose box is its whole voxel; returns the
/// covered voxels (up to 8) in the same order.
pub fn expand_voxel(
    addr: VoxelAddr,
    t: &Translation,
    p: &Params,
) -> Result<Vec<VoxelAddr>, TranslateError> {
    Ok(expand_node(&NodeBox::full_voxel(addr, p), t, p)?
        .into_iter()
        .map(|n| n.addr)
        .collect())
}

/// The cost of the expanding variant at one LOD.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LodExpansion {
    /// The LOD `d` these counts are for.
    pub lod: u8,
    /// Nodes given at this LOD.
    pub before: u64,
    /// Nodes after expansion, every copy a node of its own (FIG. 12b).
    pub after: u64,
    /// Distinct voxels those copies occupy (the count if copies sharing a
    /// voxel were combined into one node).
    pub distinct_voxels: u64,
}

/// The cost of the expanding variant over a set of nodes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ExpansionCost {
    /// One entry per LOD present, shallowest first.
    pub per_lod: Vec<LodExpansion>,
    /// Nodes given, over all LODs.
    pub before: u64,
    /// Nodes after expansion, over all LODs.
    pub after: u64,
    /// Nodes the expansion adds: `after - before`.
    pub added: u64,
}

/// Expands every node (a hierarchy's node list, any order) and counts what
/// the expansion adds, per LOD and in total.
pub fn expansion_cost(
    nodes: &[NodeBox],
    t: &Translation,
    p: &Params,
) -> Result<ExpansionCost, TranslateError> {
    let mut per: BTreeMap<u8, (u64, u64, HashSet<VoxelAddr>)> = BTreeMap::new();
    for n in nodes {
        let copies = expand_node(n, t, p)?;
        let e = per.entry(n.addr.lod).or_default();
        e.0 += 1;
        e.1 += copies.len() as u64;
        e.2.extend(copies.iter().map(|c| c.addr));
    }
    let per_lod: Vec<LodExpansion> = per
        .into_iter()
        .map(|(lod, (before, after, set))| LodExpansion {
            lod,
            before,
            after,
            distinct_voxels: set.len() as u64,
        })
        .collect();
    let before = per_lod.iter().map(|l| l.before).sum();
    let after = per_lod.iter().map(|l| l.after).sum();
    Ok(ExpansionCost {
        per_lod,
        before,
        after,
        added: after - before,
    })
}

/// [`expansion_cost`] for nodes whose boxes are their whole voxels.
pub fn expansion_cost_voxels(
    addrs: &[VoxelAddr],
    t: &Translation,
    p: &Params,
) -> Result<ExpansionCost, TranslateError> {
    let nodes: Vec<NodeBox> = addrs.iter().map(|a| NodeBox::full_voxel(*a, p)).collect();
    expansion_cost(&nodes, t, p)
}
