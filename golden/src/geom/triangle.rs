//! Watertight ray/triangle intersection: Woop, Benthin and Wald,
//! "Watertight Ray/Triangle Intersection", JCGT 2(1), 2013.
//!
//! The ray is turned into a shear transform that maps it to the +z axis
//! through the origin; the triangle's vertices are translated and sheared the
//! same way, and the three 2D edge functions `U, V, W` decide the hit. If one
//! of them is exactly zero in f32 it is recomputed in binary64 (and rounded
//! back), as the paper does, so that a ray through an edge or vertex shared by
//! two triangles hits at least one of them: no cracks. Both orientations are
//! accepted (no back-face culling).

use glam::{Vec3, Vec3A, Vec3Swizzles};

use super::ray::Ray;

/// A hit on one triangle: `t` along the ray, and barycentric weights such
/// that the hit point is `u v0 + v v1 + w v2` (with `u + v + w = 1` up to
/// rounding).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    /// Ray parameter of the hit, within the ray's `[tmin, tmax]`.
    pub t: f32,
    /// Weight of `v0`.
    pub u: f32,
    /// Weight of `v1`.
    pub v: f32,
    /// Weight of `v2`.
    pub w: f32,
}

/// Per-ray constants of the watertight test (paper, section 3).
#[derive(Clone, Copy, Debug)]
pub struct ShearedRay {
    origin: Vec3,
    // Axes index arrays, not `Vec3`s: indexing a `Vec3` by a runtime value
    // is a three-way branch per access.
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f32,
    sy: f32,
    sz: f32,
    tmin: f32,
    tmax: f32,
}

impl ShearedRay {
    /// `kz` is the axis of the largest `|dir|` component (ties: x before y
    /// before z); `kx, ky` follow cyclically and are swapped when
    /// `dir[kz] < 0` to keep the winding.
    pub fn new(ray: &Ray) -> ShearedRay {
        let a = ray.dir.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if ray.dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        ShearedRay {
            origin: ray.origin,
            kx,
            ky,
            kz,
            sx: ray.dir[kx] / ray.dir[kz],
            sy: ray.dir[ky] / ray.dir[kz],
            sz: 1.0 / ray.dir[kz],
            tmin: ray.tmin,
            tmax: ray.tmax,
        }
    }

    /// The same ray with a new `[tmin, tmax]`.
    pub fn with_range(&self, tmin: f32, tmax: f32) -> ShearedRay {
        ShearedRay {
            tmin,
            tmax,
            ..*self
        }
    }
}

/// The watertight test. A hit needs: `U, V, W` all `>= 0` or all `<= 0`,
/// `det = U + V + W != 0`, `T` of the sign of `det`, and
/// `t = T * (1 / det)` in `[tmin, tmax]` (inclusive). Returns `None` otherwise,
/// also for non-finite input (every comparison with NaN fails).
pub fn intersect_triangle(ray: &ShearedRay, tri: &[Vec3; 3]) -> Option<TriangleHit> {
    intersect_triangle_in(ray, tri, ray.tmin, ray.tmax)
}

/// [`intersect_triangle`] over `[tmin, tmax]` instead of the ray's own
/// range: traversal narrows the range after every hit.
#[inline]
pub fn intersect_triangle_in(
    ray: &ShearedRay,
    tri: &[Vec3; 3],
    tmin: f32,
    tmax: f32,
) -> Option<TriangleHit> {
    // One instance per axis order, with the axes as constants: no index
    // is checked or looked up per triangle, and the match goes the same
    // way for every triangle of a ray, so it is predicted.
    match (ray.kx, ray.ky, ray.kz) {
        (1, 2, 0) => intersect_axes::<1, 2, 0>(ray, tri, tmin, tmax),
        (2, 1, 0) => intersect_axes::<2, 1, 0>(ray, tri, tmin, tmax),
        (2, 0, 1) => intersect_axes::<2, 0, 1>(ray, tri, tmin, tmax),
        (0, 2, 1) => intersect_axes::<0, 2, 1>(ray, tri, tmin, tmax),
        (0, 1, 2) => intersect_axes::<0, 1, 2>(ray, tri, tmin, tmax),
        _ => intersect_axes::<1, 0, 2>(ray, tri, tmin, tmax),
    }
}

/// A triangle's vertices by coordinate, for [`intersect_each`]: `by_axis[a]`
/// holds coordinate `a` of vertices 0, 1, 2 (and a fourth lane that no
/// answer depends on), so the test works on the three vertices at once.
#[derive(Clone, Copy, Debug)]
pub struct TriangleLanes {
    by_axis: [Vec3A; 3],
}

impl TriangleLanes {
    /// The triangle `tri` by coordinate.
    pub fn new(tri: &[Vec3; 3]) -> TriangleLanes {
        TriangleLanes {
            by_axis: [0, 1, 2].map(|a| Vec3A::new(tri[0][a], tri[1][a], tri[2][a])),
        }
    }
}

/// The watertight test on the triangles `tris[prims[0]]`, `tris[prims[1]]`,
/// ... in order, each as [`intersect_triangle_in`] over `[tmin, tmax]`
/// with the same answer bit for bit, for a leaf of a hierarchy.
/// `on_hit(prim, hit)` is told of every hit and gives the `tmax` the
/// following triangles are tested with, or `None` to stop there. Returns
/// how many triangles were tested. The ray's axis order is looked at once
/// for all of them, not once per triangle.
pub fn intersect_each(
    ray: &ShearedRay,
    prims: &[u32],
    tris: &[TriangleLanes],
    tmin: f32,
    tmax: f32,
    on_hit: impl FnMut(u32, &TriangleHit) -> Option<f32>,
) -> usize {
    match (ray.kx, ray.ky, ray.kz) {
        (1, 2, 0) => each_axes::<1, 2, 0>(ray, prims, tris, tmin, tmax, on_hit),
        (2, 1, 0) => each_axes::<2, 1, 0>(ray, prims, tris, tmin, tmax, on_hit),
        (2, 0, 1) => each_axes::<2, 0, 1>(ray, prims, tris, tmin, tmax, on_hit),
        (0, 2, 1) => each_axes::<0, 2, 1>(ray, prims, tris, tmin, tmax, on_hit),
        (0, 1, 2) => each_axes::<0, 1, 2>(ray, prims, tris, tmin, tmax, on_hit),
        _ => each_axes::<1, 0, 2>(ray, prims, tris, tmin, tmax, on_hit),
    }
}

/// [`intersect_each`] with the ray's axis order as constants.
#[inline(always)]
fn each_axes<const KX: usize, const KY: usize, const KZ: usize>(
    ray: &ShearedRay,
    prims: &[u32],
    tris: &[TriangleLanes],
    tmin: f32,
    mut tmax: f32,
    mut on_hit: impl FnMut(u32, &TriangleHit) -> Option<f32>,
) -> usize {
    let lanes = LaneRay {
        origin: [KX, KY, KZ].map(|k| Vec3A::splat(ray.origin[k])),
        sx: Vec3A::splat(ray.sx),
        sy: Vec3A::splat(ray.sy),
    };
    for (tested, &prim) in prims.iter().enumerate() {
        let tri = &tris[prim as usize];
        if let Some(hit) = intersect_lanes::<KX, KY, KZ>(ray, &lanes, tri, tmin, tmax) {
            match on_hit(prim, &hit) {
                Some(t) => tmax = t,
                None => return tested + 1,
            }
        }
    }
    prims.len()
}

/// The ray's origin (in `kx, ky, kz` order) and shear, each in every lane.
struct LaneRay {
    origin: [Vec3A; 3],
    sx: Vec3A,
    sy: Vec3A,
}

/// [`intersect_axes`] on the three vertices at once: lane `i` of each
/// vector is vertex `i`'s value of the scalar test, by the same IEEE
/// operations in the same order, so the same answer bit for bit.
#[inline(always)]
fn intersect_lanes<const KX: usize, const KY: usize, const KZ: usize>(
    ray: &ShearedRay,
    lanes: &LaneRay,
    tri: &TriangleLanes,
    tmin: f32,
    tmax: f32,
) -> Option<TriangleHit> {
    // Vertices relative to the ray origin, then sheared: (ax, bx, cx), (ay, by, cy).
    let z = tri.by_axis[KZ] - lanes.origin[2];
    let x = (tri.by_axis[KX] - lanes.origin[0]) - lanes.sx * z;
    let y = (tri.by_axis[KY] - lanes.origin[1]) - lanes.sy * z;
    // u = cx by - cy bx, v = ax cy - ay cx, w = bx ay - by ax.
    let mut uvw = x.zxy() * y.yzx() - y.zxy() * x.yzx();
    if uvw.cmpeq(Vec3A::ZERO).any() {
        let ([ax, bx, cx], [ay, by, cy]) = (x.to_array(), y.to_array());
        uvw = Vec3A::new(
            edge_f64(cx, by, cy, bx),
            edge_f64(ax, cy, ay, cx),
            edge_f64(bx, ay, by, ax),
        );
    }
    if uvw.cmplt(Vec3A::ZERO).any() & uvw.cmpgt(Vec3A::ZERO).any() {
        return None;
    }
    let [u, v, w] = uvw.to_array();
    let [za, zb, zc] = z.to_array();
    from_edges(ray.sz, [u, v, w], [za, zb, zc], tmin, tmax)
}

/// The watertight test with the ray's `kx, ky, kz` (SPEC 6.2) as `KX, KY, KZ`.
#[inline(always)]
fn intersect_axes<const KX: usize, const KY: usize, const KZ: usize>(
    ray: &ShearedRay,
    tri: &[Vec3; 3],
    tmin: f32,
    tmax: f32,
) -> Option<TriangleHit> {
    let (kx, ky, kz) = (KX, KY, KZ);
    // Vertices relative to the ray origin.
    let a = (tri[0] - ray.origin).to_array();
    let b = (tri[1] - ray.origin).to_array();
    let c = (tri[2] - ray.origin).to_array();
    // Shear and scale to the ray's space (z is scaled later, only on a hit).
    let ax = a[kx] - ray.sx * a[kz];
    let ay = a[ky] - ray.sy * a[kz];
    let bx = b[kx] - ray.sx * b[kz];
    let by = b[ky] - ray.sy * b[kz];
    let cx = c[kx] - ray.sx * c[kz];
    let cy = c[ky] - ray.sy * c[kz];
    // Scaled barycentric coordinates (edge functions).
    let mut u = cx * by - cy * bx;
    let mut v = ax * cy - ay * cx;
    let mut w = bx * ay - by * ax;
    // The conditions below use `|` and `&`, not `||` and `&&`: the same
    // truth values, one branch instead of one per operand, each as hard to
    // predict as whether the ray hits the triangle.
    if (u == 0.0) | (v == 0.0) | (w == 0.0) {
        u = edge_f64(cx, by, cy, bx);
        v = edge_f64(ax, cy, ay, cx);
        w = edge_f64(bx, ay, by, ax);
    }
    if ((u < 0.0) | (v < 0.0) | (w < 0.0)) & ((u > 0.0) | (v > 0.0) | (w > 0.0)) {
        return None;
    }
    from_edges(ray.sz, [u, v, w], [a[kz], b[kz], c[kz]], tmin, tmax)
}

/// The rest of the watertight test from the edge functions `u, v, w` of
/// one sign (or zero) and the vertices' `kz` coordinates relative to the
/// ray origin, `sz` the ray's scale along `kz`.
#[inline(always)]
fn from_edges(
    sz: f32,
    [u, v, w]: [f32; 3],
    [za, zb, zc]: [f32; 3],
    tmin: f32,
    tmax: f32,
) -> Option<TriangleHit> {
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    let az = sz * za;
    let bz = sz * zb;
    let cz = sz * zc;
    let t_scaled = u * az + v * bz + w * cz;
    // T must have det's sign: the hit is in front of the origin.
    if ((t_scaled < 0.0) & (det > 0.0)) | ((t_scaled > 0.0) & (det < 0.0)) {
        return None;
    }
    let rcp_det = 1.0 / det;
    let t = t_scaled * rcp_det;
    if !(t >= tmin && t <= tmax) {
        return None;
    }
    Some(TriangleHit {
        t,
        u: u * rcp_det,
        v: v * rcp_det,
        w: w * rcp_det,
    })
}

/// `p q - r s` computed in binary64 from f32 operands (products exact) and
/// rounded once to f32: the paper's fallback for an edge exactly on the ray.
fn edge_f64(p: f32, q: f32, r: f32, s: f32) -> f32 {
    (p as f64 * q as f64 - r as f64 * s as f64) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenes::SplitMix64;

    fn hit(ray: &Ray, tri: &[Vec3; 3]) -> Option<TriangleHit> {
        intersect_triangle(&ShearedRay::new(ray), tri)
    }

    #[test]
    fn hits_with_barycentrics_and_t() {
        let tri = [
            Vec3::new(0.0, 0.0, 5.0),
            Vec3::new(4.0, 0.0, 5.0),
            Vec3::new(0.0, 4.0, 5.0),
        ];
        let r = Ray::unbounded(Vec3::new(1.0, 1.0, 0.0), Vec3::Z);
        let h = hit(&r, &tri).unwrap();
        assert_eq!(h.t, 5.0);
        assert_eq!((h.u, h.v, h.w), (0.5, 0.25, 0.25));
        // Both orientations.
        let flipped = [tri[0], tri[2], tri[1]];
        assert_eq!(hit(&r, &flipped).unwrap().t, 5.0);
        // Behind, out of range, beside.
        assert!(hit(&Ray::unbounded(Vec3::new(1.0, 1.0, 6.0), Vec3::Z), &tri).is_none());
        assert!(hit(&Ray::new(r.origin, r.dir, 0.0, 4.999), &tri).is_none());
        assert!(hit(&Ray::new(r.origin, r.dir, 5.0, 5.0), &tri).is_some());
        assert!(hit(&Ray::unbounded(Vec3::new(3.0, 3.0, 0.0), Vec3::Z), &tri).is_none());
        // Negative direction (kx/ky swap) and a direction along y (kz = 1).
        let r = Ray::unbounded(Vec3::new(1.0, 1.0, 10.0), -Vec3::Z * 2.0);
        assert_eq!(hit(&r, &tri).unwrap().t, 2.5);
        let side = [
            Vec3::new(0.0, 3.0, 0.0),
            Vec3::new(2.0, 3.0, 0.0),
            Vec3::new(0.0, 3.0, 2.0),
        ];
        let r = Ray::unbounded(Vec3::new(0.5, -1.0, 0.5), Vec3::new(0.0, 1.0, 0.0));
        assert_eq!(hit(&r, &side).unwrap().t, 4.0);
    }

    #[test]
    fn degenerate_and_nan_miss() {
        let seg = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
        assert!(hit(&Ray::unbounded(Vec3::new(0.5, 0.0, -1.0), Vec3::Z), &seg).is_none());
        let nan = [
            Vec3::new(f32::NAN, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
        ];
        assert!(hit(&Ray::unbounded(Vec3::new(0.2, 0.2, 0.0), Vec3::Z), &nan).is_none());
        // A ray in the triangle's plane.
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        assert!(hit(&Ray::unbounded(Vec3::new(-1.0, 0.2, 0.0), Vec3::X), &tri).is_none());
    }

    /// The leaf loop on vertex lanes makes the tests the one-by-one test
    /// makes, bit for bit, in every axis order, narrowing `tmax` and
    /// stopping as told: on random rays, and on rays through vertices and
    /// edge midpoints of triangles on a coarse grid (edge functions exactly
    /// zero: the binary64 fallback), some with zero direction components.
    #[test]
    fn each_is_one_by_one() {
        let mut rng = SplitMix64::new(9);
        let on_grid = |p: Vec3| (p * 4.0).round() / 4.0;
        let tris: Vec<[Vec3; 3]> = (0..40)
            .map(|_| [(); 3].map(|_| on_grid(rng.point_in(Vec3::splat(-2.0), Vec3::splat(2.0)))))
            .collect();
        let lanes: Vec<TriangleLanes> = tris.iter().map(TriangleLanes::new).collect();
        let prims: Vec<u32> = (0..60).map(|_| rng.below(40) as u32).collect();
        let bits = |h: &TriangleHit| [h.t, h.u, h.v, h.w].map(f32::to_bits);
        let (mut hits, mut on_edges) = (0, 0);
        for k in 0..6000 {
            let tri = tris[rng.below(40) as usize];
            let target = match k % 4 {
                0 => rng.point_in(Vec3::splat(-2.0), Vec3::splat(2.0)),
                1 => tri[k % 3],
                _ => (tri[k % 3] + tri[(k + 1) % 3]) * 0.5,
            };
            let mut origin = on_grid(rng.unit_vector() * 6.0);
            if k % 5 == 0 {
                origin[k % 3] = target[k % 3];
            }
            let ray = Ray::unbounded(origin, target - origin);
            if !ray.is_valid() {
                continue;
            }
            let s = ShearedRay::new(&ray);
            let stop_after = k % 3;
            let (mut want, mut tmax, mut tested) = (Vec::new(), ray.tmax, 0);
            for &p in &prims {
                tested += 1;
                if let Some(h) = intersect_triangle_in(&s, &tris[p as usize], ray.tmin, tmax) {
                    want.push((p, bits(&h)));
                    tmax = tmax.min(h.t);
                    if want.len() == stop_after {
                        break;
                    }
                }
            }
            let mut got = Vec::new();
            let mut best = ray.tmax;
            let n = intersect_each(&s, &prims, &lanes, ray.tmin, ray.tmax, |p, h| {
                got.push((p, bits(h)));
                best = best.min(h.t);
                (got.len() != stop_after).then_some(best)
            });
            assert_eq!((n, &got), (tested, &want), "{ray:?}");
            hits += got.len();
            on_edges += (k % 4 != 0 && !got.is_empty()) as usize;
        }
        assert!(hits > 1000 && on_edges > 1000, "{hits} {on_edges}");
    }

    /// Watertightness: rays through the shared edge and shared vertex of a
    /// fan of triangles around a point always hit at least one of them.
    #[test]
    fn shared_edges_and_vertices_leave_no_crack() {
        let mut rng = SplitMix64::new(3);
        for _ in 0..3000 {
            let center = rng.point_in(Vec3::splat(-1.0), Vec3::splat(1.0));
            // Angular gaps below 180 degrees, so the fan seen from above is a disc.
            let n = 4 + rng.below(6) as usize;
            let rim: Vec<Vec3> = (0..n)
                .map(|k| {
                    let a = std::f32::consts::TAU * (k as f32 + rng.range_f32(0.3, 0.7)) / n as f32;
                    center + Vec3::new(a.cos(), a.sin(), rng.range_f32(-0.05, 0.05))
                })
                .collect();
            let fan: Vec<[Vec3; 3]> = (0..n).map(|k| [center, rim[k], rim[(k + 1) % n]]).collect();
            // Seen from within ~20 degrees of +z, no triangle of the fan is seen
            // edge-on or from behind: no silhouette, where a miss is legitimate.
            let origin = center + rng.unit_vector() * 2.0 + Vec3::Z * 6.0;
            // Through the shared vertex, and through points on shared edges.
            let mut targets = vec![center];
            for r in &rim {
                let s = rng.range_f32(0.0, 0.9);
                targets.push(center + (*r - center) * s);
            }
            for target in targets {
                let r = Ray::unbounded(origin, target - origin);
                assert!(
                    fan.iter().any(|t| hit(&r, t).is_some()),
                    "crack at {target}"
                );
            }
        }
    }
}
