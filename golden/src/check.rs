//! The hierarchy checker (SPEC.md section 5): proves, node by node, the
//! properties every ray test relies on, and names the first node that breaks one.
//!
//! It walks from the roots through the references, which may lead into other
//! hierarchies (a merged hierarchy references its inputs), so it reads nodes
//! through a [`CheckView`]: the store, the triangles each hierarchy's
//! primitive indices point at, and a placement hook for translated inputs.

use std::collections::BTreeMap;
use std::fmt;

use glam::DVec3;

use crate::geom::clip_triangle_to_box;
use crate::geom::triangle_overlaps_box;
use crate::grid::VoxelAddr;
use crate::params::Params;
use crate::store::{
    node_box_fine, node_box_grid, voxel_box_fine, Hierarchy, HierarchyStore, NodeRecord,
    RecordError, Reference,
};

/// What the checker reads besides the hierarchy under check.
pub trait CheckView {
    /// Hierarchy `id`, when the checked one references it (the checked
    /// hierarchy itself is always found, whatever this returns).
    fn hierarchy(&self, id: u8) -> Option<&Hierarchy>;

    /// The triangles (grid units, where they sit in the checked hierarchy's
    /// scene) that hierarchy `id`'s primitive indices point at.
    fn triangles(&self, id: u8) -> Option<&[[DVec3; 3]]>;

    /// Where node record `node` of hierarchy `id` sits in the checked
    /// hierarchy's grid. The identity unless overridden: the extension point
    /// for translated inputs (a translation moves `voxel` and nothing else;
    /// its triangles must then be given translated by [`CheckView::triangles`]).
    fn place(&self, id: u8, node: &NodeRecord) -> Result<NodeRecord, String> {
        let _ = id;
        Ok(*node)
    }

    /// True (the default): re-derive the builder's coverage rule (SPEC 5,
    /// check 9) and require every voxel it names to hold the primitive. Turn
    /// off for inputs whose triangles are not bit-exact images of the ones
    /// they were built from.
    fn exact_coverage(&self) -> bool {
        true
    }

    /// False (the default): hierarchy `id`'s leaves are checked placed,
    /// against [`CheckView::triangles`] in the checked hierarchy's grid.
    /// True: they are checked as stored, in the hierarchy's own (local)
    /// frame, and `triangles(id)` must then be local: far from the origin a
    /// moved binary64 vertex loses the precision the leaf boxes were built
    /// with (paragraph 71); a voxel-aligned move does not change a box
    /// relative to its voxel, so the local check is the placed one, exactly.
    fn leaves_in_local_frame(&self, id: u8) -> bool {
        let _ = id;
        false
    }
}

/// The view for a built hierarchy alone: its triangles, nothing else.
pub struct Standalone<'a> {
    /// The hierarchy's triangles in grid units, indexed by primitive index.
    pub triangles: &'a [[DVec3; 3]],
}

impl CheckView for Standalone<'_> {
    fn hierarchy(&self, _id: u8) -> Option<&Hierarchy> {
        None
    }
    fn triangles(&self, _id: u8) -> Option<&[[DVec3; 3]]> {
        Some(self.triangles)
    }
}

/// The view for a hierarchy whose references lead into a store, with each
/// hierarchy's triangles by id; untranslated.
pub struct StoreView<'a> {
    /// The hierarchies the references may lead into.
    pub store: &'a HierarchyStore,
    /// Each hierarchy's triangles in grid units, by hierarchy id; a hierarchy
    /// missing here fails `MissingTriangles` at its first leaf.
    pub triangles: BTreeMap<u8, &'a [[DVec3; 3]]>,
}

impl CheckView for StoreView<'_> {
    fn hierarchy(&self, id: u8) -> Option<&Hierarchy> {
        self.store.get(id)
    }
    fn triangles(&self, id: u8) -> Option<&[[DVec3; 3]]> {
        self.triangles.get(&id).copied()
    }
}

/// What a passing check saw.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CheckReport {
    /// Nodes visited (each exactly once).
    pub nodes: usize,
    /// Inner nodes visited.
    pub inner: usize,
    /// Leaves visited.
    pub leaves: usize,
    /// Primitive slots of all visited leaves.
    pub leaf_prims: usize,
    /// Distinct (hierarchy, primitive) pairs reached.
    pub prims_reached: usize,
    /// Voxels the coverage check (SPEC 5, check 9) examined.
    pub coverage_voxels: usize,
    /// The hierarchies the walk entered, ascending.
    pub hierarchies: Vec<u8>,
    /// Deepest LOD visited.
    pub deepest_lod: u8,
}

/// The first violated property: where, and what.
#[derive(Clone, Debug, PartialEq)]
pub struct CheckError {
    /// The hierarchy holding the node (or primitive) at fault.
    pub hier: u8,
    /// The node at fault, when the fault is a node's.
    pub node: Option<u32>,
    /// The property that failed, with the values that broke it.
    pub kind: CheckErrorKind,
}

/// The property that failed.
#[derive(Clone, Debug, PartialEq)]
pub enum CheckErrorKind {
    /// Check 1: the header's `root_count` is 0. Names no node.
    NoRoots,
    /// Check 1: `root_count` is above the number of node records. Names no node.
    RootCountExceedsNodes {
        /// The header's root count.
        root_count: u32,
        /// Length of the hierarchy's `nodes`.
        nodes: usize,
    },
    /// Check 1: a root's placed LOD is not the header's `top_lod`.
    RootLod {
        /// The root's placed LOD.
        lod: u8,
        /// The header's `top_lod`.
        top_lod: u8,
    },
    /// Check 3: the placed record fails [`NodeRecord::validate`] (SPEC 3); the
    /// error names the field.
    BadRecord(RecordError),
    /// [`CheckView::place`] refused the node; holds its message.
    PlaceFailed(String),
    /// Check 5: a reference names a hierarchy the view does not give. Names the
    /// referring node.
    UnknownHierarchy {
        /// The reference, as stored in `refs`.
        target: Reference,
        /// The referring node (the one the error names).
        parent: Reference,
    },
    /// A hierarchy the walk reaches has parameters other than the checked
    /// hierarchy's. Names that hierarchy and no node.
    ParamsMismatch {
        /// The checked hierarchy's parameters.
        expected: Params,
        /// The reached hierarchy's parameters.
        found: Params,
    },
    /// Check 4: a child's placed LOD is not its parent's plus one. Names the child.
    ChildLod {
        /// The parent node.
        parent: Reference,
        /// The parent's placed LOD.
        parent_lod: u8,
        /// The child's placed LOD.
        child_lod: u8,
    },
    /// Check 4: a child's placed voxel is not a child of its parent's voxel.
    /// Names the child.
    ChildOutsideParentVoxel {
        /// The parent node.
        parent: Reference,
    },
    /// Check 4: a child's box is not inside its parent's box, compared exactly
    /// in fine units (SPEC 3). Names the child.
    ChildBoxOutsideParent {
        /// The parent node.
        parent: Reference,
        /// The first axis where it sticks out: 0 = x, 1 = y, 2 = z.
        axis: usize,
        /// The child's box on that axis, `(min, max)` in fine units.
        child: (u64, u64),
        /// The parent's box on that axis, `(min, max)` in fine units.
        parent_box: (u64, u64),
    },
    /// Check 5: an inner node's `first + count` is above the length of its
    /// hierarchy's `refs`.
    RefRangeOutOfBounds {
        /// The node's `first`.
        first: u32,
        /// The node's `count`.
        count: u32,
        /// Length of the hierarchy's `refs`.
        refs: usize,
    },
    /// Check 5: a reference names a node index past its target hierarchy's
    /// `nodes`. Names the referring node.
    DanglingReference {
        /// Index of the reference in the referring hierarchy's `refs`.
        ref_index: u64,
        /// The reference, as stored.
        target: Reference,
    },
    /// Check 2: a node is reached a second time, by two references or as a root
    /// and a reference. Names that node.
    DoubleReference {
        /// The second referrer; the node itself when the second visit is as a root.
        parent: Reference,
    },
    /// Check 6: a leaf's `first + count` is above the length of its hierarchy's
    /// `prims`.
    PrimRangeOutOfBounds {
        /// The leaf's `first`.
        first: u32,
        /// The leaf's `count`.
        count: u32,
        /// Length of the hierarchy's `prims`.
        prims: usize,
    },
    /// Check 6: the view gives no triangles for the leaf's hierarchy.
    MissingTriangles,
    /// Check 6: a leaf's primitive index is not below its hierarchy's triangle count.
    PrimIndexOutOfBounds {
        /// Index of the entry in `prims`.
        slot: u64,
        /// The primitive index stored there.
        prim: u32,
        /// Number of triangles the view gives for the hierarchy.
        triangles: usize,
    },
    /// Check 7: the part of a triangle inside the leaf's voxel is not inside the
    /// leaf's box, compared in binary64 grid units.
    PrimOutsideLeafBox {
        /// The triangle's primitive index.
        prim: u32,
        /// The first axis where it sticks out: 0 = x, 1 = y, 2 = z.
        axis: usize,
        /// The clipped triangle's `(min, max)` on that axis, in grid units.
        clipped: (f64, f64),
        /// The leaf box's `(min, max)` on that axis, in grid units.
        leaf_box: (f64, f64),
    },
    /// Check 7: `clip_triangle_to_box` finds that a leaf's triangle certainly
    /// misses the leaf's voxel.
    PrimMissesLeafVoxel {
        /// The triangle's primitive index.
        prim: u32,
    },
    /// Check 9 (with [`CheckView::exact_coverage`]): leaves holding one
    /// primitive are at two LODs. Names no node.
    PrimLeavesAtMixedLods {
        /// The triangle's primitive index.
        prim: u32,
        /// The lowest LOD holding it, then the next one up.
        lods: (u8, u8),
    },
    /// Check 9 (with [`CheckView::exact_coverage`]): a voxel at the primitive's
    /// leaf LOD that both kernels say it meets holds it in no reached leaf.
    /// Names no node.
    PrimNotCovered {
        /// The triangle's primitive index.
        prim: u32,
        /// The voxel that should hold it.
        voxel: VoxelAddr,
    },
    /// Check 9 (with [`CheckView::exact_coverage`]): the primitive's AABB meets
    /// more than [`MAX_COVERAGE_CANDIDATES`] voxels at its leaf LOD. Names no node.
    PrimSpansTooManyVoxels {
        /// The triangle's primitive index.
        prim: u32,
        /// The LOD of the leaves holding it.
        lod: u8,
        /// How many LOD-`lod` voxels its AABB meets.
        voxels: u128,
    },
    /// Check 8: a node of the checked hierarchy is not reached from its roots.
    /// Names the first such node.
    UnreachableNode,
    /// Check 8: a triangle of a hierarchy the walk entered is in no reached
    /// leaf. Names no node.
    UnreachablePrim {
        /// The lowest such primitive index.
        prim: u32,
    },
}

const AXES: [&str; 3] = ["x", "y", "z"];

/// Most LOD-`l` voxels a primitive's AABB may meet in the coverage check.
/// The LOD rule (SPEC 4.2) keeps the AABB within 2 voxels per axis at the base
/// LOD and adds at most 3 sliver levels: at most `17^3 = 4913` candidates. A
/// primitive held far deeper than its size allows fails instead of making the
/// check loop over a huge range.
pub const MAX_COVERAGE_CANDIDATES: u128 = 1 << 15;

impl fmt::Display for CheckErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use CheckErrorKind::*;
        let r = |r: &Reference| format!("({}, {})", r.hier, r.node);
        match self {
            NoRoots => write!(f, "root_count is 0"),
            RootCountExceedsNodes { root_count, nodes } => {
                write!(f, "root_count {root_count} exceeds the {nodes} nodes")
            }
            RootLod { lod, top_lod } => write!(f, "root at LOD {lod}, header top_lod is {top_lod}"),
            BadRecord(e) => write!(f, "bad record: {e}"),
            PlaceFailed(e) => write!(f, "placement failed: {e}"),
            UnknownHierarchy { target, parent } => {
                write!(f, "node {} references {}: no such hierarchy", r(parent), r(target))
            }
            ParamsMismatch { expected, found } => {
                write!(f, "parameters {found:?} differ from the checked hierarchy's {expected:?}")
            }
            ChildLod { parent, parent_lod, child_lod } => write!(
                f,
                "child at LOD {child_lod} of parent {} at LOD {parent_lod}: expected LOD {}",
                r(parent),
                *parent_lod as u16 + 1
            ),
            ChildOutsideParentVoxel { parent } => {
                write!(f, "voxel is not a child of parent {}'s voxel", r(parent))
            }
            ChildBoxOutsideParent { parent, axis, child, parent_box } => write!(
                f,
                "box on {} is [{}, {}] (fine units), outside parent {}'s [{}, {}]",
                AXES[*axis],
                child.0,
                child.1,
                r(parent),
                parent_box.0,
                parent_box.1
            ),
            RefRangeOutOfBounds { first, count, refs } => {
                write!(f, "refs range first {first} count {count} exceeds the {refs} refs")
            }
            DanglingReference { ref_index, target } => {
                write!(f, "refs[{ref_index}] = {} names no node", r(target))
            }
            DoubleReference { parent } => {
                write!(f, "referenced a second time, by {}", r(parent))
            }
            PrimRangeOutOfBounds { first, count, prims } => {
                write!(f, "prims range first {first} count {count} exceeds the {prims} prims")
            }
            MissingTriangles => write!(f, "no triangles given for this hierarchy"),
            PrimIndexOutOfBounds { slot, prim, triangles } => {
                write!(f, "prims[{slot}] = {prim} but there are {triangles} triangles")
            }
            PrimOutsideLeafBox { prim, axis, clipped, leaf_box } => write!(
                f,
                "triangle {prim} inside the voxel spans [{}, {}] on {}, outside the leaf box [{}, {}]",
                clipped.0, clipped.1, AXES[*axis], leaf_box.0, leaf_box.1
            ),
            PrimMissesLeafVoxel { prim } => {
                write!(f, "triangle {prim} certainly misses the leaf's voxel")
            }
            PrimLeavesAtMixedLods { prim, lods } => write!(
                f,
                "triangle {prim} is in leaves at LOD {} and at LOD {}",
                lods.0, lods.1
            ),
            PrimSpansTooManyVoxels { prim, lod, voxels } => write!(
                f,
                "triangle {prim} held at LOD {lod} meets {voxels} voxels there by its AABB, \
                 more than the {MAX_COVERAGE_CANDIDATES} any LOD of section 4.2 allows"
            ),
            PrimNotCovered { prim, voxel } => write!(
                f,
                "triangle {prim} meets voxel {voxel:?} but no reachable leaf there holds it"
            ),
            UnreachableNode => write!(f, "not reachable from the roots"),
            UnreachablePrim { prim } => write!(f, "triangle {prim} is in no reachable leaf"),
        }
    }
}

impl fmt::Display for CheckError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.node {
            Some(n) => write!(f, "hierarchy {} node {}: {}", self.hier, n, self.kind),
            None => write!(f, "hierarchy {}: {}", self.hier, self.kind),
        }
    }
}

impl std::error::Error for CheckError {}

fn fail<T>(hier: u8, node: Option<u32>, kind: CheckErrorKind) -> Result<T, CheckError> {
    Err(CheckError { hier, node, kind })
}

/// Checks a built hierarchy over its own triangles (grid units).
pub fn check_built(h: &Hierarchy, triangles: &[[DVec3; 3]]) -> Result<CheckReport, CheckError> {
    check(h, &Standalone { triangles })
}

/// The walk's state: what has been seen so far.
struct Walk<'a, V: CheckView + ?Sized> {
    root: &'a Hierarchy,
    view: &'a V,
    visited: BTreeMap<u8, Vec<bool>>,
    reached: BTreeMap<u8, Vec<bool>>,
    /// (hierarchy, primitive, placed leaf voxel) of every leaf slot visited.
    holders: Vec<(u8, u32, VoxelAddr)>,
    report: CheckReport,
}

impl<'a, V: CheckView + ?Sized> Walk<'a, V> {
    fn hierarchy(&self, id: u8) -> Option<&'a Hierarchy> {
        if id == self.root.id {
            Some(self.root)
        } else {
            self.view.hierarchy(id)
        }
    }

    /// Marks `r` visited; an error if it was already.
    fn visit(
        &mut self,
        r: Reference,
        h: &Hierarchy,
        parent: Option<Reference>,
    ) -> Result<(), CheckError> {
        let seen = self
            .visited
            .entry(r.hier)
            .or_insert_with(|| vec![false; h.nodes.len()]);
        if seen[r.node as usize] {
            let kind = CheckErrorKind::DoubleReference {
                parent: parent.unwrap_or(r),
            };
            return fail(r.hier, Some(r.node), kind);
        }
        seen[r.node as usize] = true;
        Ok(())
    }

    /// The placed record of `r` (which exists), validated.
    fn placed(&self, r: Reference, h: &Hierarchy) -> Result<NodeRecord, CheckError> {
        let stored = &h.nodes[r.node as usize];
        let n = self
            .view
            .place(r.hier, stored)
            .or_else(|e| fail(r.hier, Some(r.node), CheckErrorKind::PlaceFailed(e)))?;
        n.validate(&self.root.params)
            .or_else(|e| fail(r.hier, Some(r.node), CheckErrorKind::BadRecord(e)))?;
        Ok(n)
    }

    /// Child `c` of parent `p`: one LOD below, inside its voxel and its box.
    fn check_child(
        &self,
        c: Reference,
        cn: &NodeRecord,
        p: Reference,
        pn: &NodeRecord,
    ) -> Result<(), CheckError> {
        let params = &self.root.params;
        if cn.voxel.lod != pn.voxel.lod + 1 {
            let kind = CheckErrorKind::ChildLod {
                parent: p,
                parent_lod: pn.voxel.lod,
                child_lod: cn.voxel.lod,
            };
            return fail(c.hier, Some(c.node), kind);
        }
        if cn.voxel.parent() != Some(pn.voxel) {
            return fail(
                c.hier,
                Some(c.node),
                CheckErrorKind::ChildOutsideParentVoxel { parent: p },
            );
        }
        let (clo, chi) = node_box_fine(cn, params);
        let (plo, phi) = node_box_fine(pn, params);
        for axis in 0..3 {
            if clo[axis] < plo[axis] || chi[axis] > phi[axis] {
                let kind = CheckErrorKind::ChildBoxOutsideParent {
                    parent: p,
                    axis,
                    child: (clo[axis], chi[axis]),
                    parent_box: (plo[axis], phi[axis]),
                };
                return fail(c.hier, Some(c.node), kind);
            }
        }
        Ok(())
    }

    /// A leaf's primitives: in range, and each one's part inside the leaf's
    /// voxel inside the leaf's box.
    fn check_leaf(
        &mut self,
        r: Reference,
        n: &NodeRecord,
        h: &Hierarchy,
    ) -> Result<(), CheckError> {
        let params = &self.root.params;
        let range = n.range();
        if range.end > h.prims.len() as u64 {
            let kind = CheckErrorKind::PrimRangeOutOfBounds {
                first: n.first,
                count: n.count,
                prims: h.prims.len(),
            };
            return fail(r.hier, Some(r.node), kind);
        }
        let Some(tris) = self.view.triangles(r.hier) else {
            return fail(r.hier, Some(r.node), CheckErrorKind::MissingTriangles);
        };
        let (vlo, vhi) = voxel_box_fine(&n.voxel, params);
        let to_grid = 1.0 / params.quant_cells() as f64;
        let vlo = DVec3::from_array(vlo.map(|v| v as f64 * to_grid));
        let vhi = DVec3::from_array(vhi.map(|v| v as f64 * to_grid));
        let (blo, bhi) = node_box_grid(n, params);
        let reached = self
            .reached
            .entry(r.hier)
            .or_insert_with(|| vec![false; tris.len()]);
        for slot in range {
            let prim = h.prims[slot as usize];
            let Some(tri) = tris.get(prim as usize) else {
                let kind = CheckErrorKind::PrimIndexOutOfBounds {
                    slot,
                    prim,
                    triangles: tris.len(),
                };
                return fail(r.hier, Some(r.node), kind);
            };
            reached[prim as usize] = true;
            self.holders.push((r.hier, prim, n.voxel));
            self.report.leaf_prims += 1;
            let Some((clo, chi)) = clip_triangle_to_box(tri, vlo, vhi) else {
                return fail(
                    r.hier,
                    Some(r.node),
                    CheckErrorKind::PrimMissesLeafVoxel { prim },
                );
            };
            for axis in 0..3 {
                if clo[axis] < blo[axis] || chi[axis] > bhi[axis] {
                    let kind = CheckErrorKind::PrimOutsideLeafBox {
                        prim,
                        axis,
                        clipped: (clo[axis], chi[axis]),
                        leaf_box: (blo[axis], bhi[axis]),
                    };
                    return fail(r.hier, Some(r.node), kind);
                }
            }
        }
        Ok(())
    }

    /// Resolves reference `refs[i]` of inner node `r`.
    fn resolve(
        &self,
        r: Reference,
        i: u64,
        target: Reference,
    ) -> Result<&'a Hierarchy, CheckError> {
        let Some(th) = self.hierarchy(target.hier) else {
            return fail(
                r.hier,
                Some(r.node),
                CheckErrorKind::UnknownHierarchy { target, parent: r },
            );
        };
        if th.params != self.root.params {
            let kind = CheckErrorKind::ParamsMismatch {
                expected: self.root.params,
                found: th.params,
            };
            return fail(target.hier, None, kind);
        }
        if target.node as usize >= th.nodes.len() {
            return fail(
                r.hier,
                Some(r.node),
                CheckErrorKind::DanglingReference {
                    ref_index: i,
                    target,
                },
            );
        }
        Ok(th)
    }

    fn run(mut self) -> Result<CheckReport, CheckError> {
        let h = self.root;
        let id = h.id;
        if h.root_count == 0 {
            return fail(id, None, CheckErrorKind::NoRoots);
        }
        if h.root_count as usize > h.nodes.len() {
            let kind = CheckErrorKind::RootCountExceedsNodes {
                root_count: h.root_count,
                nodes: h.nodes.len(),
            };
            return fail(id, None, kind);
        }
        // Depth-first; each stack entry is a node and the parent that referenced it.
        let mut stack: Vec<(Reference, Option<(Reference, NodeRecord)>)> = (0..h.root_count)
            .rev()
            .map(|node| (Reference { hier: id, node }, None))
            .collect();
        while let Some((r, parent)) = stack.pop() {
            let rh = self.hierarchy(r.hier).expect("resolved before pushing");
            self.visit(r, rh, parent.map(|p| p.0))?;
            let n = self.placed(r, rh)?;
            match parent {
                None if n.voxel.lod != h.top_lod => {
                    let kind = CheckErrorKind::RootLod {
                        lod: n.voxel.lod,
                        top_lod: h.top_lod,
                    };
                    return fail(r.hier, Some(r.node), kind);
                }
                None => {}
                Some((p, pn)) => self.check_child(r, &n, p, &pn)?,
            }
            self.report.nodes += 1;
            self.report.deepest_lod = self.report.deepest_lod.max(n.voxel.lod);
            if n.leaf {
                self.report.leaves += 1;
                let stored = rh.nodes[r.node as usize];
                let frame = if self.view.leaves_in_local_frame(r.hier) {
                    stored
                } else {
                    n
                };
                self.check_leaf(r, &frame, rh)?;
                continue;
            }
            self.report.inner += 1;
            let range = n.range();
            if range.end > rh.refs.len() as u64 {
                let kind = CheckErrorKind::RefRangeOutOfBounds {
                    first: n.first,
                    count: n.count,
                    refs: rh.refs.len(),
                };
                return fail(r.hier, Some(r.node), kind);
            }
            for i in range.rev() {
                let target = rh.refs[i as usize];
                self.resolve(r, i, target)?;
                stack.push((target, Some((r, n))));
            }
        }
        self.finish()
    }

    /// Every node of the checked hierarchy and every triangle of every
    /// entered hierarchy was reached.
    fn finish(mut self) -> Result<CheckReport, CheckError> {
        let own = &self.visited[&self.root.id];
        if let Some(node) = own.iter().position(|&v| !v) {
            return fail(
                self.root.id,
                Some(node as u32),
                CheckErrorKind::UnreachableNode,
            );
        }
        for (&hier, _) in self.visited.iter() {
            let Some(tris) = self.view.triangles(hier) else {
                continue; // no leaf of it was visited, or check_leaf had failed
            };
            let reached = self.reached.get(&hier);
            for prim in 0..tris.len() {
                if !reached.is_some_and(|r| r[prim]) {
                    return fail(
                        hier,
                        None,
                        CheckErrorKind::UnreachablePrim { prim: prim as u32 },
                    );
                }
            }
        }
        if self.view.exact_coverage() {
            self.check_coverage()?;
        }
        self.report.prims_reached = self
            .reached
            .values()
            .map(|r| r.iter().filter(|&&b| b).count())
            .sum();
        self.report.hierarchies = self.visited.keys().copied().collect();
        Ok(self.report)
    }
}

impl<V: CheckView + ?Sized> Walk<'_, V> {
    /// SPEC 5, check 9: all leaves holding a primitive are at one LOD `l`,
    /// and every LOD-`l` voxel meeting the triangle's AABB (per axis
    /// `floor(min / e) ..= min(floor(max / e), 2^l - 1)`) in which both
    /// kernels find contact holds it.
    fn check_coverage(&mut self) -> Result<(), CheckError> {
        let params = self.root.params;
        let mut holders = std::mem::take(&mut self.holders);
        holders.sort_unstable();
        holders.dedup();
        let mut i = 0;
        while i < holders.len() {
            let (hier, prim, first) = holders[i];
            let mut j = i;
            while j < holders.len() && holders[j].0 == hier && holders[j].1 == prim {
                if holders[j].2.lod != first.lod {
                    let lods = (first.lod, holders[j].2.lod);
                    return fail(
                        hier,
                        None,
                        CheckErrorKind::PrimLeavesAtMixedLods { prim, lods },
                    );
                }
                j += 1;
            }
            let held = &holders[i..j];
            let tri = self.view.triangles(hier).expect("checked in check_leaf")[prim as usize];
            let lod = first.lod;
            let e = params.voxel_edge(lod) as f64;
            let last = ((1u64 << lod) - 1) as f64;
            let tlo = tri[0].min(tri[1]).min(tri[2]);
            let thi = tri[0].max(tri[1]).max(tri[2]);
            let a = (tlo / e)
                .floor()
                .clamp(DVec3::ZERO, DVec3::splat(last))
                .as_uvec3();
            let b = (thi / e)
                .floor()
                .clamp(DVec3::ZERO, DVec3::splat(last))
                .as_uvec3();
            // b >= a unless the triangle is NaN (then the walk found no box to check).
            let span = |lo: u32, hi: u32| (hi as u128 + 1).saturating_sub(lo as u128);
            let candidates = span(a.x, b.x) * span(a.y, b.y) * span(a.z, b.z);
            if candidates > MAX_COVERAGE_CANDIDATES {
                let kind = CheckErrorKind::PrimSpansTooManyVoxels {
                    prim,
                    lod,
                    voxels: candidates,
                };
                return fail(hier, None, kind);
            }
            for z in a.z..=b.z {
                for y in a.y..=b.y {
                    for x in a.x..=b.x {
                        let voxel = VoxelAddr::new(lod, x, y, z);
                        self.report.coverage_voxels += 1;
                        let vlo = DVec3::new(x as f64, y as f64, z as f64) * e;
                        let vhi = vlo + DVec3::splat(e);
                        let meets = triangle_overlaps_box(&tri, vlo, vhi)
                            && clip_triangle_to_box(&tri, vlo, vhi).is_some();
                        if meets && held.binary_search(&(hier, prim, voxel)).is_err() {
                            return fail(
                                hier,
                                None,
                                CheckErrorKind::PrimNotCovered { prim, voxel },
                            );
                        }
                    }
                }
            }
            i = j;
        }
        Ok(())
    }
}

/// Checks `h` (SPEC.md section 5), reading referenced hierarchies, triangles
/// and placements through `view`. Returns what it saw, or the first failure.
pub fn check<V: CheckView + ?Sized>(h: &Hierarchy, view: &V) -> Result<CheckReport, CheckError> {
    Walk {
        root: h,
        view,
        visited: BTreeMap::new(),
        reached: BTreeMap::new(),
        holders: Vec::new(),
        report: CheckReport::default(),
    }
    .run()
}
