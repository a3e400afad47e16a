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

use glam::Vec3;

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

/// The watertight test on the triangles `tris[prims[0]]`, `tris[prims[1]]`,
/// ... in order, each as [`intersect_triangle_in`] over `[tmin, tmax]`,
/// for a leaf of a hierarchy. `on_hit(prim, hit)` is told of every hit and
/// gives the `tmax` the following triangles are tested with, or `None` to
/// stop there. Returns how many triangles were tested. The ray's axis
/// order is looked at once for all of them, not once per triangle.
pub fn intersect_each(
    ray: &ShearedRay,
    prims: &[u32],
    tris: &[[Vec3; 3]],
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
    tris: &[[Vec3; 3]],
    tmin: f32,
    mut tmax: f32,
    mut on_hit: impl FnMut(u32, &TriangleHit) -> Option<f32>,
) -> usize {
    for (tested, &prim) in prims.iter().enumerate() {
        if let Some(hit) = intersect_axes::<KX, KY, KZ>(ray, &tris[prim as usize], tmin, tmax) {
            match on_hit(prim, &hit) {
                Some(t) => tmax = t,
                None => return tested + 1,
            }
        }
    }
    prims.len()
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
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    let az = ray.sz * a[kz];
    let bz = ray.sz * b[kz];
    let cz = ray.sz * c[kz];
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

    /// The leaf loop makes the tests the one-by-one test makes, in every
    /// axis order, narrowing `tmax` and stopping as told.
    #[test]
    fn each_is_one_by_one() {
        let mut rng = SplitMix64::new(9);
        let box_lo = Vec3::splat(-1.0);
        let tris: Vec<[Vec3; 3]> = (0..40)
            .map(|_| [(); 3].map(|_| rng.point_in(box_lo, Vec3::ONE)))
            .collect();
        let prims: Vec<u32> = (0..60).map(|_| rng.below(40) as u32).collect();
        let mut hits = 0;
        for k in 0..3000 {
            let origin = rng.unit_vector() * 4.0;
            let ray = Ray::unbounded(origin, rng.point_in(box_lo, Vec3::ONE) - origin);
            let s = ShearedRay::new(&ray);
            let stop_after = k % 3;
            let (mut want, mut tmax, mut tested) = (Vec::new(), ray.tmax, 0);
            for &p in &prims {
                tested += 1;
                if let Some(h) = intersect_triangle_in(&s, &tris[p as usize], ray.tmin, tmax) {
                    want.push((p, h));
                    tmax = tmax.min(h.t);
                    if want.len() == stop_after {
                        break;
                    }
                }
            }
            let mut got = Vec::new();
            let n = intersect_each(&s, &prims, &tris, ray.tmin, ray.tmax, |p, h| {
                got.push((p, *h));
                (got.len() != stop_after)
                    .then(|| got.iter().map(|g| g.1.t).fold(f32::INFINITY, f32::min))
            });
            assert_eq!((n, &got), (tested, &want), "{ray:?}");
            hits += got.len();
        }
        assert!(hits > 1000, "{hits}");
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
