//! S616 and S618's layout: the levels above the base, built bottom-up with
//! the builder's own grouping and top rule (`build::upper::build_levels`), then
//! laid out as records of the merged hierarchy.
//!
//! Records: every grouped node (made here), every created node (S614), and
//! every reused inner node that ends up at the top (materialized: a root
//! must be a record of the merged hierarchy; it is copied with its
//! translated voxel and its references, which name its input). A reused
//! leaf cannot be a root (its primitives index its input's triangles), so
//! while the top level holds one the top moves one level up by one more
//! grouping; at LOD 0 that is [`MergeError::InputLeafAtTop`].
//!
//! Store order as the builder's: the roots first, then level by level down,
//! each level in Morton order. A reference to a base node that is not a
//! record is the input node itself, `(input id, node index)`.

pub mod level_unit;
pub mod unit;

use crate::build::upper::{build_levels, group_by_parent, LevelNode};
use crate::grid::VoxelAddr;
use crate::merge::error::MergeError;
use crate::merge::merge_level::{BaseKind, BaseNode};
use crate::params::Params;
use crate::store::{Hierarchy, NodeRecord, Reference};

/// What S616 did.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct UpperCounts {
    /// Records made by grouping (S616).
    pub grouped: u64,
    /// Reused input inner nodes copied to be roots.
    pub materialized: u64,
    /// Extra groupings because a reused leaf was at the top.
    pub lifted: u64,
    /// Records of the merged hierarchy per LOD, `(lod, count)`, top first.
    pub nodes_per_level: Vec<(u8, u64)>,
}

fn level_node(b: &BaseNode, k: usize) -> LevelNode {
    let v = b.record.voxel;
    LevelNode {
        morton: crate::merge::fetcher::walk::morton(&v),
        x: v.x,
        y: v.y,
        z: v.z,
        leaf: b.record.leaf,
        base: true,
        lo: b.record.lo,
        hi: b.record.hi,
        first: k as u32,
        count: 1,
    }
}

fn check_index(what: &'static str, value: u64, p: &Params) -> Result<(), MergeError> {
    if value >= p.index_capacity() {
        return Err(MergeError::IndexOverflow {
            what,
            value,
            index_bits: p.index_bits,
        });
    }
    Ok(())
}

/// The base nodes as the builder's level lists: by LOD, Morton order
/// (stable: the base's own order within a voxel); a node's `first` is its
/// index in `base`.
pub(crate) fn base_by_lod(base: &[BaseNode], p: &Params) -> Vec<Vec<LevelNode>> {
    let mut out = vec![Vec::new(); p.max_lod as usize + 1];
    for (k, b) in base.iter().enumerate() {
        out[b.record.voxel.lod as usize].push(level_node(b, k));
    }
    for l in &mut out {
        l.sort_by_key(|n| n.morton);
    }
    out
}

fn reused_leaf<'a>(n: &LevelNode, base: &'a [BaseNode]) -> Option<&'a Reference> {
    match (&base[n.first as usize].kind, n.base && n.leaf) {
        (BaseKind::Reused { at }, true) => Some(at),
        _ => None,
    }
}

/// S616's levels over `base` (8.6): the builder's level loop and top rule,
/// then the lift rule.
#[derive(Clone, Debug)]
pub(crate) struct UpperLevels {
    /// The level lists by LOD (a base node's `first` is its index in `base`).
    pub levels: Vec<Vec<LevelNode>>,
    /// The top LOD after the lifts.
    pub top: usize,
    /// The top LOD the builder's top rule chose, before any lift.
    pub built_top: usize,
    /// Extra groupings because a reused leaf was at the top.
    pub lifted: u64,
    /// The reused input leaf still at the top at LOD 0, if any
    /// ([`MergeError::InputLeafAtTop`]).
    pub leaf_at_top: Option<Reference>,
}

/// The levels and the top over `base`; `None` when `base` is empty.
pub(crate) fn upper_levels(base: &[BaseNode], p: &Params) -> Option<UpperLevels> {
    let (mut levels, built_top) = build_levels(base_by_lod(base, p), p)?;
    let (mut top, mut lifted) = (built_top, 0);
    while let Some(at) = levels[top].iter().find_map(|n| reused_leaf(n, base)) {
        if top == 0 {
            return Some(UpperLevels {
                levels,
                top,
                built_top,
                lifted,
                leaf_at_top: Some(*at),
            });
        }
        levels[top - 1] = group_by_parent(&levels[top], p.quant_bits);
        top -= 1;
        lifted += 1;
    }
    Some(UpperLevels {
        levels,
        top,
        built_top,
        lifted,
        leaf_at_top: None,
    })
}

/// Builds the merged hierarchy `out_id` over `base` (non-empty).
pub fn build_upper(
    base: &[BaseNode],
    inputs: &[&Hierarchy],
    p: &Params,
    out_id: u8,
) -> Result<(Hierarchy, UpperCounts), MergeError> {
    let u = upper_levels(base, p).ok_or(MergeError::NoInputs)?;
    if let Some(at) = u.leaf_at_top {
        return Err(MergeError::InputLeafAtTop {
            input: at.hier,
            node: at.node,
        });
    }
    let (levels, top) = (u.levels, u.top);
    let mut counts = UpperCounts {
        lifted: u.lifted,
        ..UpperCounts::default()
    };
    let deepest = levels.len() - 1;

    // Record index of every node that is a record, level by level.
    let is_record = |lod: usize, n: &LevelNode| {
        !n.base || lod == top || matches!(base[n.first as usize].kind, BaseKind::Created { .. })
    };
    let mut index: Vec<Vec<Option<u32>>> = vec![Vec::new(); deepest + 1];
    let mut next = 0u64;
    for lod in top..=deepest {
        index[lod] = levels[lod]
            .iter()
            .map(|n| {
                is_record(lod, n).then(|| {
                    next += 1;
                    (next - 1) as u32
                })
            })
            .collect();
    }
    check_index("node count - 1", next.saturating_sub(1), p)?;

    let by_rank = |hier: u8| inputs.iter().find(|h| h.id == hier).copied();
    let reference = |lod: usize, i: usize| -> Reference {
        match index[lod][i] {
            Some(node) => Reference { hier: out_id, node },
            None => match &base[levels[lod][i].first as usize].kind {
                BaseKind::Reused { at } => *at,
                BaseKind::Created { .. } => unreachable!("created nodes are records"),
            },
        }
    };
    let mut nodes = Vec::with_capacity(next as usize);
    let mut refs: Vec<Reference> = Vec::new();
    for lod in top..=deepest {
        let mut made = 0u64;
        for (i, n) in levels[lod].iter().enumerate() {
            if index[lod][i].is_none() {
                continue;
            }
            let first = refs.len() as u64;
            if !n.base {
                for c in n.first as usize..(n.first + n.count) as usize {
                    refs.push(reference(lod + 1, c));
                }
                counts.grouped += 1;
            } else {
                match &base[n.first as usize].kind {
                    BaseKind::Created { refs: r } => refs.extend_from_slice(r),
                    BaseKind::Reused { at } => {
                        let h = by_rank(at.hier).ok_or(MergeError::UnknownInput(at.hier))?;
                        let rec = &h.nodes[at.node as usize];
                        refs.extend_from_slice(crate::merge::fetcher::walk::children(
                            h, at.node, rec,
                        )?);
                        counts.materialized += 1;
                    }
                }
            }
            let count = refs.len() as u64 - first;
            check_index("count", count, p)?;
            check_index("refs length - 1", (refs.len() as u64).saturating_sub(1), p)?;
            nodes.push(NodeRecord {
                leaf: false,
                voxel: VoxelAddr::new(lod as u8, n.x, n.y, n.z),
                lo: n.lo,
                hi: n.hi,
                first: first as u32,
                count: count as u32,
            });
            made += 1;
        }
        if made > 0 {
            counts.nodes_per_level.push((lod as u8, made));
        }
    }
    let root_count = index[top].len() as u32;
    Ok((
        Hierarchy {
            id: out_id,
            params: *p,
            nodes,
            refs,
            prims: Vec::new(),
            root_count,
            top_lod: top as u8,
        },
        counts,
    ))
}
