//! Conservative ray/box slab test (Kay–Kajiya slabs, made robust as in
//! Ize, "Robust BVH Ray Traversal", JCGT 2(2), 2013).
//!
//! Per axis the ray enters and leaves the slab `[lo, hi]` at
//! `(lo - o) / d` and `(hi - o) / d`, computed as `(lo - o) * (1/d)`. Each of
//! these is within `gamma(3) = 3 u / (1 - 3 u)` (`u = 2^-24`) of the exact
//! value relative; scaling the far end by `1 + 2 gamma(3)` makes the
//! computed interval contain the exact one whenever that is non-empty.
//! A zero direction component (infinite reciprocal) is decided exactly: the
//! ray is inside that slab for every `t` or for none. A bound equal to the
//! origin's coordinate is crossed at `t = 0` exactly (so a subnormal
//! component, whose reciprocal overflows, never gives `0 * inf`).

use glam::Vec3;

use super::ray::Ray;

/// `gamma(3)` for f32 as in Pharr, Jakob, Humphreys (PBRT 3e, 3.9.1).
const fn gamma_f32(n: u32) -> f32 {
    let u = f32::EPSILON * 0.5;
    (n as f32 * u) / (1.0 - n as f32 * u)
}

/// The factor applied to the far end: `1 + 2 gamma(3)`.
pub const FAR_SCALE: f32 = 1.0 + 2.0 * gamma_f32(3);

/// Per-ray constants of the slab test, as arrays: indexing a `Vec3` by a
/// loop variable is a three-way branch per access.
#[derive(Clone, Copy, Debug)]
pub struct SlabRay {
    origin: [f32; 3],
    inv_dir: [f32; 3],
    zero: [bool; 3],
}

impl SlabRay {
    /// Precomputes the reciprocal direction and which components are exactly zero (SPEC 6.3).
    pub fn new(ray: &Ray) -> SlabRay {
        SlabRay {
            origin: ray.origin.to_array(),
            inv_dir: ray.dir.recip().to_array(),
            zero: [ray.dir.x == 0.0, ray.dir.y == 0.0, ray.dir.z == 0.0],
        }
    }
}

/// The parameter interval `[entry, exit]` over which the ray may be inside
/// the closed box `[lo, hi]`, clipped to `[tmin, tmax]`; `None` when it
/// certainly misses the box within that range. Conservative: never `None`
/// when the exact ray meets the box for some `t` in `[tmin, tmax]`.
pub fn ray_box(ray: &SlabRay, lo: Vec3, hi: Vec3, tmin: f32, tmax: f32) -> Option<(f32, f32)> {
    let (lo, hi) = (lo.to_array(), hi.to_array());
    let mut near = tmin;
    let mut far = f32::INFINITY;
    // Straight-line code: every way out is folded into `miss` and taken at
    // the end, and the choices are selects, because a branch on data that
    // changes from ray to ray (the direction's signs) is mispredicted often.
    // Going on past a miss changes nothing but the values it discards.
    let mut miss = false;
    for axis in 0..3 {
        let o = ray.origin[axis];
        let inv = ray.inv_dir[axis];
        // A bound through the origin is crossed at t = 0 exactly; writing it
        // out avoids 0 * inf = NaN when a tiny (subnormal) direction
        // component has an infinite reciprocal.
        let t0 = if lo[axis] == o {
            0.0
        } else {
            (lo[axis] - o) * inv
        };
        let t1 = if hi[axis] == o {
            0.0
        } else {
            (hi[axis] - o) * inv
        };
        let ordered = t0 <= t1;
        let mut t_enter = if ordered { t0 } else { t1 };
        let mut t_leave = if ordered { t1 } else { t0 };
        if ray.zero[axis] {
            // Inside the slab for every t or for none: max(near, -inf) and
            // min(far, inf) leave near and far as they are, bit for bit.
            miss |= o < lo[axis] || o > hi[axis];
            t_enter = f32::NEG_INFINITY;
            t_leave = f32::INFINITY;
        } else {
            // Only non-finite input gets here with a NaN: refuse it as a
            // miss rather than let max/min silently drop it.
            miss |= t_enter.is_nan() || t_leave.is_nan();
        }
        near = near.max(t_enter);
        far = far.min(t_leave);
    }
    if miss {
        return None;
    }
    let far = (far * FAR_SCALE).min(tmax);
    (near <= far).then_some((near, far))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenes::SplitMix64;

    fn test(r: &Ray, lo: Vec3, hi: Vec3) -> Option<(f32, f32)> {
        ray_box(&SlabRay::new(r), lo, hi, r.tmin, r.tmax)
    }

    #[test]
    fn basic_entry_exit_and_zero_components() {
        let r = Ray::unbounded(Vec3::new(-1.0, 0.5, 0.5), Vec3::X);
        let (t0, t1) = test(&r, Vec3::ZERO, Vec3::ONE).unwrap();
        assert_eq!(t0, 1.0);
        assert!((2.0..2.0001).contains(&t1));
        // Along the face plane y = 1 (zero y, z components): inside, closed box.
        let r = Ray::unbounded(Vec3::new(-1.0, 1.0, 0.5), Vec3::X);
        assert!(test(&r, Vec3::ZERO, Vec3::ONE).is_some());
        let r = Ray::unbounded(Vec3::new(-1.0, 1.0001, 0.5), Vec3::X);
        assert!(test(&r, Vec3::ZERO, Vec3::ONE).is_none());
        // Negative zero direction component.
        let r = Ray::unbounded(Vec3::new(0.5, -1.0, 0.5), Vec3::new(-0.0, 1.0, 0.0));
        assert!(test(&r, Vec3::ZERO, Vec3::ONE).is_some());
        // Behind the origin, and beyond tmax.
        let r = Ray::unbounded(Vec3::new(2.0, 0.5, 0.5), Vec3::X);
        assert!(test(&r, Vec3::ZERO, Vec3::ONE).is_none());
        let r = Ray::new(Vec3::new(-1.0, 0.5, 0.5), Vec3::X, 0.0, 0.5);
        assert!(test(&r, Vec3::ZERO, Vec3::ONE).is_none());
        // A subnormal direction component (infinite reciprocal) with the
        // origin on a face plane: inside that slab from t = 0 on.
        let r = Ray::unbounded(
            Vec3::new(-1.0, 0.0, 0.5),
            Vec3::new(1.0, f32::from_bits(1), 0.0),
        );
        assert!(test(&r, Vec3::ZERO, Vec3::ONE).is_some());
        let r = Ray::unbounded(
            Vec3::new(-1.0, 1.0, 0.5),
            Vec3::new(1.0, -f32::from_bits(1), 0.0),
        );
        assert!(test(&r, Vec3::ZERO, Vec3::ONE).is_some());
        // A flat box (zero thickness) hit head-on.
        let r = Ray::unbounded(Vec3::new(0.5, 0.5, -3.0), Vec3::Z);
        assert_eq!(
            test(&r, Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 1.0, 1.0)).map(|h| h.0),
            Some(4.0)
        );
    }

    /// Points strictly inside a box, reached along random rays, are always
    /// within the returned interval (checked at the points' own t, computed
    /// in f64 exactly enough).
    #[test]
    fn never_misses_a_point_inside() {
        let mut rng = SplitMix64::new(11);
        for _ in 0..20000 {
            let lo = rng.point_in(Vec3::splat(-100.0), Vec3::splat(100.0));
            let size = rng.range_f32(1e-3, 50.0);
            let hi = lo + rng.point_in(Vec3::ZERO, Vec3::splat(size));
            let origin = rng.point_in(Vec3::splat(-300.0), Vec3::splat(300.0));
            // Aim at a corner or a point on the surface: the hardest targets.
            let mut target = rng.point_in(lo, hi);
            let axis = rng.below(3) as usize;
            target[axis] = if rng.below(2) == 0 {
                lo[axis]
            } else {
                hi[axis]
            };
            let mut dir = target - origin;
            if rng.below(4) == 0 {
                dir[(axis + 1) % 3] = 0.0;
                let mut o = origin;
                o[(axis + 1) % 3] = target[(axis + 1) % 3];
                let r = Ray::unbounded(o, target - o);
                assert!(test(&r, lo, hi).is_some());
                continue;
            }
            let r = Ray::unbounded(origin, dir);
            assert!(test(&r, lo, hi).is_some(), "{r:?} {lo} {hi}");
            // The exact parameter of the target is 1.
            let (t0, t1) = test(&r, lo, hi).unwrap();
            assert!(t0 <= 1.0 + 1e-5 && t1 >= 1.0 - 1e-5, "{t0} {t1}");
        }
    }
}
