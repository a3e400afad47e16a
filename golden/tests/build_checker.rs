//! The checker rejects corrupted hierarchies with the right error, follows
//! references into other hierarchies, and honours the placement hook.

use golden::seed::seeded;
use std::collections::BTreeMap;

use glam::DVec3;
use golden::build::build_grid_triangles;
use golden::check::{check, check_built, CheckErrorKind, CheckView, StoreView};
use golden::store::{node_box_fine, Hierarchy, HierarchyStore, NodeRecord, Reference};
use golden::{Params, VoxelAddr};

fn params() -> Params {
    Params::new(10, 4, 24, 4).unwrap()
}

/// A few hundred small triangles spread over the scene, in grid units.
fn triangles(seed: u64, n: usize, spread: f64) -> Vec<[DVec3; 3]> {
    let mut rng = golden::scenes::SplitMix64::new(seeded(seed));
    (0..n)
        .map(|_| {
            let c = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * spread
                + DVec3::splat(5.0);
            let d = |r: &mut golden::scenes::SplitMix64| {
                DVec3::new(r.next_f64(), r.next_f64(), r.next_f64()) * 6.0
            };
            [c, c + d(&mut rng), c + d(&mut rng)]
        })
        .collect()
}

fn built() -> (Hierarchy, Vec<[DVec3; 3]>) {
    let tris = triangles(11, 300, 1000.0);
    let h = build_grid_triangles(&tris, &params(), 1).unwrap();
    check_built(&h, &tris).expect("the uncorrupted build passes");
    (h, tris)
}

/// An inner node that is not a root, with at least two children.
fn inner_with_two_children(h: &Hierarchy) -> usize {
    (h.root_count as usize..h.nodes.len())
        .find(|&i| !h.nodes[i].leaf && h.nodes[i].count >= 2)
        .expect("an inner node with two children")
}

#[test]
fn child_box_outside_parent() {
    let (mut h, tris) = built();
    let p = inner_with_two_children(&h);
    let first_child = h.refs[h.nodes[p].first as usize].node as usize;
    let (clo, chi) = node_box_fine(&h.nodes[first_child], &h.params);
    // Shrink the parent to one cell on an axis, the one farthest from the child.
    let (plo, _) = node_box_fine(&h.nodes[p], &h.params);
    let cell = h.params.voxel_edge(h.nodes[p].voxel.lod);
    let vmin = plo[0] - h.nodes[p].lo[0] as u64 * cell;
    let far_cell = if clo[0] - vmin >= 8 * cell { 0 } else { 15 };
    h.nodes[p].lo[0] = far_cell;
    h.nodes[p].hi[0] = far_cell;
    let e = check_built(&h, &tris).unwrap_err();
    match e.kind {
        CheckErrorKind::ChildBoxOutsideParent {
            parent, axis: 0, ..
        } => {
            assert_eq!(
                parent,
                Reference {
                    hier: 1,
                    node: p as u32
                }
            );
            assert_eq!(e.node, Some(first_child as u32), "{e}");
        }
        other => panic!("expected ChildBoxOutsideParent, got {other:?} ({chi:?})"),
    }
    assert!(e.to_string().contains(&format!("node {first_child}")));
}

#[test]
fn dangling_reference() {
    let (mut h, tris) = built();
    let p = inner_with_two_children(&h);
    let k = h.nodes[p].first as usize + 1;
    h.refs[k].node = h.nodes.len() as u32;
    let e = check_built(&h, &tris).unwrap_err();
    assert_eq!(e.node, Some(p as u32));
    assert!(
        matches!(e.kind, CheckErrorKind::DanglingReference { ref_index, .. } if ref_index == k as u64),
        "{e}"
    );
}

#[test]
fn reference_to_a_missing_hierarchy() {
    let (mut h, tris) = built();
    let p = inner_with_two_children(&h);
    h.refs[h.nodes[p].first as usize].hier = 9;
    let e = check_built(&h, &tris).unwrap_err();
    assert!(
        matches!(e.kind, CheckErrorKind::UnknownHierarchy { .. }),
        "{e}"
    );
}

#[test]
fn double_reference() {
    let (mut h, tris) = built();
    let p = inner_with_two_children(&h);
    let k = h.nodes[p].first as usize;
    let twice = h.refs[k + 1];
    h.refs[k] = twice;
    let e = check_built(&h, &tris).unwrap_err();
    assert_eq!(e.node, Some(twice.node), "{e}");
    assert_eq!(
        e.kind,
        CheckErrorKind::DoubleReference {
            parent: Reference {
                hier: 1,
                node: p as u32
            }
        }
    );
}

#[test]
fn unreachable_primitive_and_node() {
    let (mut h, mut tris) = built();
    // A triangle the hierarchy does not hold.
    tris.push([
        DVec3::splat(500.0),
        DVec3::splat(501.0),
        DVec3::new(500.0, 501.0, 500.0),
    ]);
    let e = check_built(&h, &tris).unwrap_err();
    assert_eq!(e.kind, CheckErrorKind::UnreachablePrim { prim: 300 });
    tris.pop();
    // A node nobody references.
    let extra = h.nodes[h.nodes.len() - 1];
    h.nodes.push(extra);
    let e = check_built(&h, &tris).unwrap_err();
    assert_eq!(
        (e.node, e.kind),
        (
            Some(h.nodes.len() as u32 - 1),
            CheckErrorKind::UnreachableNode
        )
    );
}

/// Replaces, in a leaf holding two or more primitives, the one slot of a
/// triangle chosen by `pick` (given how many leaves hold it) with another
/// primitive of the same leaf; returns the triangle lost from that leaf.
fn drop_from_leaf(h: &mut Hierarchy, pick: impl Fn(usize) -> bool) -> u32 {
    let mut holders: BTreeMap<u32, usize> = BTreeMap::new();
    for &t in &h.prims {
        *holders.entry(t).or_default() += 1;
    }
    let (first, count) = h
        .nodes
        .iter()
        .filter(|n| n.leaf && n.count >= 2)
        .find(|n| h.prims_of(n).iter().any(|t| pick(holders[t])))
        .map(|n| (n.first as usize, n.count as usize))
        .expect("a shared leaf with a suitable triangle");
    let range = first..first + count;
    let s = range.clone().find(|&s| pick(holders[&h.prims[s]])).unwrap();
    let lost = h.prims[s];
    let other = range.clone().find(|&o| h.prims[o] != lost).unwrap();
    h.prims[s] = h.prims[other];
    lost
}

fn dense() -> (Hierarchy, Vec<[DVec3; 3]>) {
    let tris = triangles(12, 400, 60.0);
    let h = build_grid_triangles(&tris, &params(), 1).unwrap();
    check_built(&h, &tris).expect("the uncorrupted build passes");
    (h, tris)
}

#[test]
fn primitive_dropped_from_its_only_leaf() {
    let (mut h, tris) = dense();
    let lost = drop_from_leaf(&mut h, |holders| holders == 1);
    let e = check_built(&h, &tris).unwrap_err();
    assert_eq!(e.kind, CheckErrorKind::UnreachablePrim { prim: lost });
}

#[test]
fn primitive_dropped_from_one_of_its_leaves() {
    let (mut h, tris) = dense();
    let lost = drop_from_leaf(&mut h, |holders| holders >= 2);
    let e = check_built(&h, &tris).unwrap_err();
    assert!(
        matches!(e.kind, CheckErrorKind::PrimNotCovered { prim, .. } if prim == lost),
        "{e}"
    );
}

#[test]
fn primitive_in_a_leaf_it_misses() {
    let (mut h, tris) = built();
    let i = h.nodes.iter().position(|n| n.leaf).unwrap();
    let slot = h.nodes[i].first as usize;
    let here = h.nodes[i].voxel;
    // A primitive held only by leaves in other voxels far away.
    let far = (0..h.nodes.len())
        .filter(|&j| h.nodes[j].leaf)
        .find(|&j| {
            let v = h.nodes[j].voxel;
            v.lod == here.lod && v.x.abs_diff(here.x) > 2
        })
        .unwrap();
    h.prims[slot] = h.prims[h.nodes[far].first as usize];
    let e = check_built(&h, &tris).unwrap_err();
    assert_eq!(e.node, Some(i as u32));
    assert!(
        matches!(
            e.kind,
            CheckErrorKind::PrimMissesLeafVoxel { .. } | CheckErrorKind::PrimOutsideLeafBox { .. }
        ),
        "{e}"
    );
}

#[test]
fn leaf_box_too_small() {
    let (mut h, tris) = built();
    let i = h
        .nodes
        .iter()
        .position(|n| n.leaf && n.hi[1] > n.lo[1])
        .expect("a leaf wider than one cell on y");
    h.nodes[i].hi[1] = h.nodes[i].lo[1];
    let e = check_built(&h, &tris).unwrap_err();
    assert_eq!(e.node, Some(i as u32));
    assert!(
        matches!(e.kind, CheckErrorKind::PrimOutsideLeafBox { axis: 1, .. }),
        "{e}"
    );
}

#[test]
fn wrong_lod_voxel_and_header() {
    let (h, tris) = built();
    let p = inner_with_two_children(&h);
    let c = h.refs[h.nodes[p].first as usize].node as usize;
    let child = h.nodes[c];

    let mut bad = h.clone();
    bad.nodes[c].voxel = child.voxel.parent().unwrap(); // same place, one LOD up
    let e = check_built(&bad, &tris).unwrap_err();
    assert_eq!(e.node, Some(c as u32));
    assert!(matches!(e.kind, CheckErrorKind::ChildLod { .. }), "{e}");

    let mut bad = h.clone();
    let v = child.voxel;
    bad.nodes[c].voxel = VoxelAddr::new(v.lod, v.x ^ 2, v.y, v.z);
    let e = check_built(&bad, &tris).unwrap_err();
    assert_eq!(e.node, Some(c as u32));
    assert!(
        matches!(e.kind, CheckErrorKind::ChildOutsideParentVoxel { .. }),
        "{e}"
    );

    let mut bad = h.clone();
    bad.nodes[c].lo[2] = 3;
    bad.nodes[c].hi[2] = 2;
    let e = check_built(&bad, &tris).unwrap_err();
    assert!(
        matches!(e.kind, CheckErrorKind::BadRecord(ref r) if r.field == "lo_z"),
        "{e}"
    );

    let mut bad = h.clone();
    bad.top_lod += 1;
    assert!(matches!(
        check_built(&bad, &tris).unwrap_err().kind,
        CheckErrorKind::RootLod { .. }
    ));
    let mut bad = h.clone();
    bad.root_count = 0;
    assert_eq!(
        check_built(&bad, &tris).unwrap_err().kind,
        CheckErrorKind::NoRoots
    );
    let mut bad = h.clone();
    let leaf = bad.nodes.iter().position(|n| n.leaf).unwrap();
    bad.nodes[leaf].count = bad.prims.len() as u32 - bad.nodes[leaf].first + 1;
    assert!(matches!(
        check_built(&bad, &tris).unwrap_err().kind,
        CheckErrorKind::PrimRangeOutOfBounds { .. }
    ));
}

/// A hand-made "merged" hierarchy whose single node references the roots of
/// two stored hierarchies: the checker walks into both.
#[test]
fn references_into_other_hierarchies() {
    let p = params();
    // Two clusters in the same LOD-3 voxel (edge 128), separate LOD-4 voxels.
    let a = triangles(1, 40, 50.0);
    let b: Vec<_> = triangles(2, 40, 50.0)
        .into_iter()
        .map(|t| t.map(|v| v + DVec3::new(64.0, 0.0, 0.0)))
        .collect();
    let ha = build_grid_triangles(&a, &p, 1).unwrap();
    let hb = build_grid_triangles(&b, &p, 2).unwrap();
    assert!(
        ha.top_lod >= 4 && hb.top_lod == ha.top_lod,
        "{} {}",
        ha.top_lod,
        hb.top_lod
    );
    let lod = ha.top_lod - 1;
    let v = ha.nodes[0].voxel.ancestor(lod);
    assert_eq!(hb.nodes[0].voxel.ancestor(lod), v);
    let mut refs = Vec::new();
    for h in [&ha, &hb] {
        for node in 0..h.root_count {
            refs.push(Reference { hier: h.id, node });
        }
    }
    let merged = Hierarchy {
        id: 5,
        params: p,
        nodes: vec![NodeRecord {
            leaf: false,
            voxel: v,
            lo: [0; 3],
            hi: [15; 3],
            first: 0,
            count: refs.len() as u32,
        }],
        refs,
        prims: vec![],
        root_count: 1,
        top_lod: lod,
    };
    let mut store = HierarchyStore::new();
    store.insert(ha.clone()).unwrap();
    store.insert(hb).unwrap();
    let view = StoreView {
        store: &store,
        triangles: BTreeMap::from([(1, a.as_slice()), (2, b.as_slice())]),
    };
    let r = check(&merged, &view).unwrap();
    assert_eq!(r.hierarchies, vec![1, 2, 5]);
    assert_eq!(r.prims_reached, 80);

    // Without hierarchy 2 in the store the reference dangles into nothing.
    let mut only_a = HierarchyStore::new();
    only_a.insert(ha).unwrap();
    let view = StoreView {
        store: &only_a,
        triangles: BTreeMap::from([(1, a.as_slice())]),
    };
    let e = check(&merged, &view).unwrap_err();
    assert!(
        matches!(e.kind, CheckErrorKind::UnknownHierarchy { .. }),
        "{e}"
    );
}

/// A view that places hierarchy 1 one LOD-`l` voxel further along x.
struct Shifted<'a> {
    l: u8,
    triangles: &'a [[DVec3; 3]],
}

impl CheckView for Shifted<'_> {
    fn hierarchy(&self, _id: u8) -> Option<&Hierarchy> {
        None
    }
    fn triangles(&self, _id: u8) -> Option<&[[DVec3; 3]]> {
        Some(self.triangles)
    }
    fn place(&self, _id: u8, n: &NodeRecord) -> Result<NodeRecord, String> {
        let d = n.voxel.lod;
        if d < self.l {
            return Err(format!(
                "node at LOD {d} above the translation level {}",
                self.l
            ));
        }
        let mut out = *n;
        out.voxel.x += 1 << (d - self.l);
        Ok(out)
    }
}

#[test]
fn placement_hook_moves_nodes() {
    let p = params();
    let tris = triangles(3, 60, 40.0);
    let h = build_grid_triangles(&tris, &p, 1).unwrap();
    let l = h.top_lod;
    assert!(l >= 2);
    let edge = p.voxel_edge(l) as f64;
    let moved: Vec<_> = tris
        .iter()
        .map(|t| t.map(|v| v + DVec3::new(edge, 0.0, 0.0)))
        .collect();
    check(
        &h,
        &Shifted {
            l,
            triangles: &moved,
        },
    )
    .expect("moved nodes over moved triangles");
    let e = check(
        &h,
        &Shifted {
            l,
            triangles: &tris,
        },
    )
    .unwrap_err();
    assert!(
        matches!(
            e.kind,
            CheckErrorKind::PrimMissesLeafVoxel { .. } | CheckErrorKind::PrimOutsideLeafBox { .. }
        ),
        "{e}"
    );
    let e = check(
        &h,
        &Shifted {
            l: l + 1,
            triangles: &moved,
        },
    )
    .unwrap_err();
    assert!(matches!(e.kind, CheckErrorKind::PlaceFailed(_)), "{e}");
}
