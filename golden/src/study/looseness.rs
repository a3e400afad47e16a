//! Box looseness (SPEC 13.2): each stored box's surface area over that of
//! the exact tight box of the same content, per LOD.
//!
//! The exact box of a leaf is the union, over its primitives, of the
//! bounding box of the triangle clipped to the node's voxel (a
//! Sutherland–Hodgman clip in binary64 written here, not golden's
//! conservative builder kernel); an inner node's is the union of its
//! children's. Stored boxes come from `store::node_box_grid`.

use glam::DVec3;
use serde::Serialize;

use super::Box64;
use crate::store::{node_box_fine, node_box_grid, voxel_box_fine, Hierarchy};

/// The exact tight box of every node of `h` (index = node index), grid
/// units, over the triangles `tris` (grid units, as built); `None` where the
/// content is empty after clipping or a reference leaves `h`.
pub fn exact_boxes(h: &Hierarchy, tris: &[[DVec3; 3]]) -> Vec<Option<Box64>> {
    let p = &h.params;
    let mut order: Vec<usize> = (0..h.nodes.len()).collect();
    // Deepest first, so children are done before their parents.
    order.sort_by_key(|&i| std::cmp::Reverse(h.nodes[i].voxel.lod));
    let mut out: Vec<Option<Box64>> = vec![None; h.nodes.len()];
    for i in order {
        let n = &h.nodes[i];
        let (vlo, vhi) = voxel_box_fine(&n.voxel, p);
        let scale = (1u64 << p.quant_bits) as f64;
        let voxel = Box64 {
            lo: DVec3::from_array(vlo.map(|v| v as f64 / scale)),
            hi: DVec3::from_array(vhi.map(|v| v as f64 / scale)),
        };
        let mut acc: Option<Box64> = None;
        let mut add = |b: Option<Box64>| {
            if let Some(b) = b {
                acc = Some(acc.map_or(b, |a| a.union(&b)));
            }
        };
        if n.leaf {
            for &prim in h.prims_of(n) {
                add(tris.get(prim as usize).and_then(|t| clip_box(t, &voxel)));
            }
        } else {
            for r in h.children_of(n) {
                if r.hier == h.id {
                    add(out.get(r.node as usize).copied().flatten());
                }
            }
        }
        out[i] = acc;
    }
    out
}

/// The bounding box of triangle `t` clipped to the closed box `b`, or
/// `None` when they do not meet.
pub fn clip_box(t: &[DVec3; 3], b: &Box64) -> Option<Box64> {
    let mut poly: Vec<DVec3> = t.to_vec();
    for axis in 0..3 {
        poly = clip_plane(&poly, axis, b.lo[axis], true);
        poly = clip_plane(&poly, axis, b.hi[axis], false);
        if poly.is_empty() {
            return None;
        }
    }
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for v in &poly {
        lo = lo.min(*v);
        hi = hi.max(*v);
    }
    // The crossing points are computed in binary64; keep them in the box.
    Some(Box64 {
        lo: lo.max(b.lo),
        hi: hi.min(b.hi),
    })
}

/// Keeps the part of `poly` on the inner side of the plane `x[axis] = c`
/// (`keep_above`: `x >= c`, else `x <= c`); crossing points are put on the plane.
fn clip_plane(poly: &[DVec3], axis: usize, c: f64, keep_above: bool) -> Vec<DVec3> {
    let inside = |v: &DVec3| {
        if keep_above {
            v[axis] >= c
        } else {
            v[axis] <= c
        }
    };
    let mut out = Vec::with_capacity(poly.len() + 1);
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        let (ia, ib) = (inside(&a), inside(&b));
        if ia {
            out.push(a);
        }
        if ia != ib {
            let s = (c - a[axis]) / (b[axis] - a[axis]);
            let mut x = a + (b - a) * s;
            x[axis] = c;
            out.push(x);
        }
    }
    out
}

/// Looseness of one LOD's boxes (or of all of them: `lod` = `None`).
#[derive(Clone, Debug, Default, Serialize)]
pub struct LodLooseness {
    /// The LOD, or `None` for every node.
    pub lod: Option<u8>,
    /// Nodes with a measurable ratio (the exact box has a positive area).
    pub nodes: u64,
    /// Nodes left out: empty exact content or an exact box of zero area.
    pub degenerate: u64,
    /// Mean of stored area / exact area.
    pub mean: f64,
    /// 99th percentile (nearest rank) of the ratio.
    pub p99: f64,
    /// Largest ratio.
    pub max: f64,
}

/// The looseness of `h`'s boxes, overall first, then per LOD (top first),
/// and the number of nodes whose stored box equals its voxel.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Looseness {
    /// Every node.
    pub all: LodLooseness,
    /// Per LOD, top first.
    pub per_lod: Vec<LodLooseness>,
    /// Nodes of `h`.
    pub nodes: u64,
    /// Nodes whose stored box is their whole voxel (all of them at Q = 0).
    pub boxes_equal_voxel: u64,
    /// Sum over nodes of stored box area (grid units squared), to compare
    /// configurations of the same tree.
    pub stored_area_sum: f64,
}

/// Measures `h`'s looseness against `exact` (from [`exact_boxes`]).
pub fn looseness(h: &Hierarchy, exact: &[Option<Box64>]) -> Looseness {
    let p = &h.params;
    let mut by_lod: std::collections::BTreeMap<u8, (Vec<f64>, u64)> = Default::default();
    let mut all: (Vec<f64>, u64) = (Vec::new(), 0);
    let mut equal = 0u64;
    let mut area_sum = 0.0;
    for (i, n) in h.nodes.iter().enumerate() {
        let (lo, hi) = node_box_grid(n, p);
        let stored = Box64 {
            lo: DVec3::from_array(lo),
            hi: DVec3::from_array(hi),
        };
        area_sum += stored.surface_area();
        equal += (node_box_fine(n, p) == voxel_box_fine(&n.voxel, p)) as u64;
        let e = by_lod.entry(n.voxel.lod).or_default();
        match exact.get(i).copied().flatten().map(|b| b.surface_area()) {
            Some(a) if a > 0.0 => {
                let r = stored.surface_area() / a;
                e.0.push(r);
                all.0.push(r);
            }
            _ => {
                e.1 += 1;
                all.1 += 1;
            }
        }
    }
    Looseness {
        all: summarize(None, all.0, all.1),
        per_lod: by_lod
            .into_iter()
            .map(|(l, (v, d))| summarize(Some(l), v, d))
            .collect(),
        nodes: h.nodes.len() as u64,
        boxes_equal_voxel: equal,
        stored_area_sum: area_sum,
    }
}

fn summarize(lod: Option<u8>, mut v: Vec<f64>, degenerate: u64) -> LodLooseness {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    LodLooseness {
        lod,
        nodes: n as u64,
        degenerate,
        mean: if n == 0 {
            0.0
        } else {
            v.iter().sum::<f64>() / n as f64
        },
        p99: percentile(&v, 0.99),
        max: v.last().copied().unwrap_or(0.0),
    }
}

/// Nearest-rank percentile of sorted `v` (0 when empty).
pub fn percentile(v: &[f64], q: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let rank = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
    v[rank - 1]
}

/// How the boxes of a hierarchy built with more quantization bits nest in
/// those of the same content built with fewer (SPEC 13.2).
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq, Eq)]
pub struct Nesting {
    /// Q of the coarser hierarchy.
    pub lower_q: u8,
    /// Nodes of the finer hierarchy whose voxel (and kind) the coarser also has.
    pub matched: u64,
    /// Of those, boxes not inside the coarser hierarchy's box of the same voxel.
    pub violations: u64,
}

/// Compares every node of `finer` with the node of the same voxel and kind
/// (leaf or inner) in `coarser` (both over the same triangles and grid):
/// more Q never loosens a box.
pub fn nesting(finer: &Hierarchy, coarser: &Hierarchy) -> Nesting {
    use std::collections::BTreeMap;
    let key = |n: &crate::store::NodeRecord| (n.voxel.lod, n.voxel.x, n.voxel.y, n.voxel.z, n.leaf);
    let boxes = |h: &Hierarchy| {
        let mut m: BTreeMap<_, Box64> = BTreeMap::new();
        for n in &h.nodes {
            let (lo, hi) = node_box_grid(n, &h.params);
            let b = Box64 {
                lo: DVec3::from_array(lo),
                hi: DVec3::from_array(hi),
            };
            m.entry(key(n))
                .and_modify(|a| *a = a.union(&b))
                .or_insert(b);
        }
        m
    };
    let (fine, coarse) = (boxes(finer), boxes(coarser));
    let mut out = Nesting {
        lower_q: coarser.params.quant_bits,
        ..Default::default()
    };
    for (k, f) in &fine {
        if let Some(c) = coarse.get(k) {
            out.matched += 1;
            let inside = f.lo.cmpge(c.lo).all() && f.hi.cmple(c.hi).all();
            out.violations += !inside as u64;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::build::{build, GridMap};
    use crate::scenes::random_soup;
    use crate::Params;

    #[test]
    fn clip_keeps_the_part_inside() {
        let t = [
            DVec3::ZERO,
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(0.0, 2.0, 0.0),
        ];
        let b = Box64 {
            lo: DVec3::splat(-1.0),
            hi: DVec3::splat(1.0),
        };
        let c = clip_box(&t, &b).expect("they meet");
        assert_eq!(c.lo, DVec3::ZERO);
        assert_eq!(c.hi, DVec3::new(1.0, 1.0, 0.0));
        let far = Box64 {
            lo: DVec3::splat(3.0),
            hi: DVec3::splat(4.0),
        };
        assert_eq!(clip_box(&t, &far), None);
    }

    /// Stored boxes contain the exact ones; Q = 0 boxes are voxels; more Q nests.
    #[test]
    fn stored_boxes_bound_the_exact_ones_and_nest() {
        let mesh = random_soup(200, 0.1, 11);
        let (lo, hi) = mesh.bounds();
        let mut prev: Option<Hierarchy> = None;
        for q in [0, 2, 8] {
            let p = Params::new(12, q, 24, 4).unwrap();
            let grid = GridMap::fit(lo, hi, &p);
            let h = build(&mesh, &grid, &p, 0).unwrap();
            let tris = grid.mesh_to_grid(&mesh, &p).unwrap();
            let exact = exact_boxes(&h, &tris);
            for (n, e) in h.nodes.iter().zip(&exact) {
                let (slo, shi) = node_box_grid(n, &p);
                let e = e.expect("every node has content");
                assert!(
                    e.lo.cmpge(DVec3::from_array(slo)).all()
                        && e.hi.cmple(DVec3::from_array(shi)).all()
                );
            }
            let l = looseness(&h, &exact);
            if q == 0 {
                assert_eq!(l.boxes_equal_voxel, l.nodes);
            }
            if let Some(c) = &prev {
                let n = nesting(&h, c);
                assert_eq!(n.violations, 0);
                assert!(n.matched + 2 >= h.nodes.len() as u64);
            }
            prev = Some(h);
        }
    }
}
