//! An independent binary64 reference tracer (SPEC 6.10, 13.3): Möller–Trumbore
//! (1997) in binary64 over a simple median-split BVH of its own, closest
//! hit by `(t, triangle index)`. It shares no code with golden's traversal
//! or kernels: what it answers is what the triangles at their requested
//! positions show a ray, up to binary64 rounding.

use glam::DVec3;

/// A closest hit of the reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefHit {
    /// Ray parameter (world units when `dir` has length 1).
    pub t: f64,
    /// Triangle index.
    pub prim: u32,
    /// Smallest barycentric coordinate: near 0, the ray grazes an edge.
    pub min_bary: f64,
}

#[derive(Clone, Debug)]
struct Node {
    lo: DVec3,
    hi: DVec3,
    /// Leaf: `[first, first + count)` of `order`; inner: children `left`, `left + 1`.
    first: u32,
    count: u32,
    left: u32,
}

/// Triangles in binary64 and a BVH over them.
#[derive(Clone, Debug)]
pub struct ReferenceTracer {
    tris: Vec<[DVec3; 3]>,
    order: Vec<u32>,
    nodes: Vec<Node>,
}

const LEAF: usize = 4;

impl ReferenceTracer {
    /// A tracer over `tris` (triangle `i` keeps index `i`).
    pub fn new(tris: Vec<[DVec3; 3]>) -> ReferenceTracer {
        let mut r = ReferenceTracer {
            order: (0..tris.len() as u32).collect(),
            tris,
            nodes: Vec::new(),
        };
        if !r.tris.is_empty() {
            r.nodes.push(Node {
                lo: DVec3::ZERO,
                hi: DVec3::ZERO,
                first: 0,
                count: 0,
                left: 0,
            });
            r.split(0, 0, r.tris.len());
        }
        r
    }

    /// The triangles.
    pub fn triangles(&self) -> &[[DVec3; 3]] {
        &self.tris
    }

    fn bounds(&self, a: usize, b: usize) -> (DVec3, DVec3) {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for &i in &self.order[a..b] {
            for v in &self.tris[i as usize] {
                lo = lo.min(*v);
                hi = hi.max(*v);
            }
        }
        // Room for the rounding of the slab test: never lose a hit.
        let pad = (lo.abs().max(hi.abs()).max_element() + (hi - lo).max_element()) * 1e-12;
        (lo - pad, hi + pad)
    }

    fn split(&mut self, node: usize, a: usize, b: usize) {
        let (lo, hi) = self.bounds(a, b);
        self.nodes[node].lo = lo;
        self.nodes[node].hi = hi;
        if b - a <= LEAF {
            self.nodes[node].first = a as u32;
            self.nodes[node].count = (b - a) as u32;
            return;
        }
        let w = hi - lo;
        let axis = if w.x >= w.y && w.x >= w.z {
            0
        } else if w.y >= w.z {
            1
        } else {
            2
        };
        let tris = &self.tris;
        let key = |i: &u32| {
            let t = &tris[*i as usize];
            t[0][axis] + t[1][axis] + t[2][axis]
        };
        let mid = (a + b) / 2;
        self.order[a..b].select_nth_unstable_by(mid - a, |x, y| key(x).total_cmp(&key(y)));
        let left = self.nodes.len();
        self.nodes[node].left = left as u32;
        for _ in 0..2 {
            self.nodes.push(Node {
                lo: DVec3::ZERO,
                hi: DVec3::ZERO,
                first: 0,
                count: 0,
                left: 0,
            });
        }
        self.split(left, a, mid);
        self.split(left + 1, mid, b);
    }

    /// The closest hit of `org + t dir`, `t` in `[tmin, tmax]`: smallest
    /// `t`, ties to the smaller triangle index.
    pub fn closest(&self, org: DVec3, dir: DVec3, tmin: f64, tmax: f64) -> Option<RefHit> {
        let mut best: Option<RefHit> = None;
        if self.nodes.is_empty() {
            return None;
        }
        let mut stack = vec![0usize];
        while let Some(n) = stack.pop() {
            let node = &self.nodes[n];
            let far = best.map_or(tmax, |b| b.t);
            if !slab(node.lo, node.hi, org, dir, tmin, far) {
                continue;
            }
            if node.count > 0 || node.left == 0 {
                let (a, c) = (node.first as usize, (node.first + node.count) as usize);
                for &i in &self.order[a..c] {
                    if let Some((t, mb)) = moller_trumbore(&self.tris[i as usize], org, dir, 0.0) {
                        let better = match best {
                            None => true,
                            Some(b) => (t, i) < (b.t, b.prim),
                        };
                        if t >= tmin && t <= tmax && better {
                            best = Some(RefHit {
                                t,
                                prim: i,
                                min_bary: mb,
                            });
                        }
                    }
                }
            } else {
                stack.push(node.left as usize);
                stack.push(node.left as usize + 1);
            }
        }
        best
    }

    /// Does the ray meet triangle `prim` grown by `eps` in barycentric
    /// coordinates? Its `t` if so.
    pub fn hits_prim(&self, prim: u32, org: DVec3, dir: DVec3, eps: f64) -> Option<f64> {
        let t = self.tris.get(prim as usize)?;
        moller_trumbore(t, org, dir, eps).map(|(t, _)| t)
    }
}

fn slab(lo: DVec3, hi: DVec3, org: DVec3, dir: DVec3, t0: f64, t1: f64) -> bool {
    let (mut near, mut far) = (t0, t1);
    for a in 0..3 {
        if dir[a] == 0.0 {
            if org[a] < lo[a] || org[a] > hi[a] {
                return false;
            }
            continue;
        }
        let inv = 1.0 / dir[a];
        let (ta, tb) = ((lo[a] - org[a]) * inv, (hi[a] - org[a]) * inv);
        near = near.max(ta.min(tb));
        far = far.min(ta.max(tb));
    }
    near <= far
}

/// Möller–Trumbore, both windings, in binary64; barycentrics may go below 0
/// by `eps`. Returns `(t, smallest barycentric)`.
fn moller_trumbore(tri: &[DVec3; 3], org: DVec3, dir: DVec3, eps: f64) -> Option<(f64, f64)> {
    let e1 = tri[1] - tri[0];
    let e2 = tri[2] - tri[0];
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let s = org - tri[0];
    let u = s.dot(p) * inv;
    if u < -eps || u > 1.0 + eps {
        return None;
    }
    let q = s.cross(e1);
    let v = dir.dot(q) * inv;
    if v < -eps || u + v > 1.0 + eps {
        return None;
    }
    let t = e2.dot(q) * inv;
    t.is_finite().then_some((t, u.min(v).min(1.0 - u - v)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenes::{random_soup, SplitMix64};

    /// The BVH finds what testing every triangle finds.
    #[test]
    fn bvh_closest_equals_every_triangle() {
        let mesh = random_soup(300, 0.2, 7);
        let tris: Vec<[DVec3; 3]> = (0..mesh.triangles.len())
            .map(|i| mesh.triangle_f64(i))
            .collect();
        let r = ReferenceTracer::new(tris.clone());
        let mut rng = SplitMix64::new(3);
        let mut hits = 0;
        for _ in 0..500 {
            let org = (rng.unit_vector() * 2.0).as_dvec3() + DVec3::splat(0.5);
            let dir =
                (rng.point_in(glam::Vec3::ZERO, glam::Vec3::ONE).as_dvec3() - org).normalize();
            let mut best: Option<(f64, u32)> = None;
            for (i, t) in tris.iter().enumerate() {
                if let Some((t, _)) = moller_trumbore(t, org, dir, 0.0) {
                    let better = match best {
                        None => true,
                        Some(b) => (t, i as u32) < b,
                    };
                    if t >= 0.0 && better {
                        best = Some((t, i as u32));
                    }
                }
            }
            let got = r
                .closest(org, dir, 0.0, f64::INFINITY)
                .map(|h| (h.t, h.prim));
            assert_eq!(got, best);
            hits += got.is_some() as u32;
        }
        assert!(hits > 100, "the rays meet the soup: {hits}");
    }
}
