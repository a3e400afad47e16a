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

use glam::{BVec3A, Vec3, Vec3A};

use super::ray::Ray;

/// `gamma(3)` for f32 as in Pharr, Jakob, Humphreys (PBRT 3e, 3.9.1).
const fn gamma_f32(n: u32) -> f32 {
    let u = f32::EPSILON * 0.5;
    (n as f32 * u) / (1.0 - n as f32 * u)
}

/// The factor applied to the far end: `1 + 2 gamma(3)`.
pub const FAR_SCALE: f32 = 1.0 + 2.0 * gamma_f32(3);

/// Per-ray constants of the slab test, in vector registers: the three
/// axes are tested at once, lane by lane with the same IEEE operations.
#[derive(Clone, Copy, Debug)]
pub struct SlabRay {
    origin: Vec3A,
    inv_dir: Vec3A,
    zero: BVec3A,
    /// Every reciprocal is finite (no zero or subnormal component): the
    /// case [`ray_meets_box`] decides without the special cases.
    finite: bool,
}

impl SlabRay {
    /// Precomputes the reciprocal direction and which components are exactly zero (SPEC 6.3).
    pub fn new(ray: &Ray) -> SlabRay {
        SlabRay {
            origin: ray.origin.into(),
            inv_dir: ray.dir.recip().into(),
            zero: Vec3A::from(ray.dir).cmpeq(Vec3A::ZERO),
            finite: ray.dir.recip().is_finite(),
        }
    }
}

/// `max(a, b)` for non-NaN operands, `a` on a tie: one instruction where
/// `f32::max` adds a NaN fix-up (its NaN never gets here: a NaN makes the
/// test a miss). The tie matters only for the sign of a zero (SPEC 6.3
/// takes the maximum of values; an entry of -0 and one of +0 are the same
/// point and decide no hit or miss).
#[inline]
fn max_keep(a: f32, b: f32) -> f32 {
    if b > a {
        b
    } else {
        a
    }
}

/// `min(a, b)` for non-NaN operands, `a` on a tie; see [`max_keep`].
#[inline]
fn min_keep(a: f32, b: f32) -> f32 {
    if b < a {
        b
    } else {
        a
    }
}

/// The parameter interval `[entry, exit]` over which the ray may be inside
/// the closed box `[lo, hi]`, clipped to `[tmin, tmax]`; `None` when it
/// certainly misses the box within that range. Conservative: never `None`
/// when the exact ray meets the box for some `t` in `[tmin, tmax]`.
pub fn ray_box(ray: &SlabRay, lo: Vec3, hi: Vec3, tmin: f32, tmax: f32) -> Option<(f32, f32)> {
    ray_box_a(ray, lo.into(), hi.into(), tmin, tmax)
}

/// [`ray_box`] on a box already in vector registers. Straight-line code:
/// a branch on data that changes from ray to ray (the direction's signs)
/// is mispredicted often, so the choices are selects and every way out is
/// one test at the end.
#[inline]
pub fn ray_box_a(ray: &SlabRay, lo: Vec3A, hi: Vec3A, tmin: f32, tmax: f32) -> Option<(f32, f32)> {
    let o = ray.origin;
    // A bound through the origin is crossed at t = 0 exactly; writing it
    // out avoids 0 * inf = NaN when a tiny (subnormal) direction component
    // has an infinite reciprocal.
    let t0 = Vec3A::select(lo.cmpeq(o), Vec3A::ZERO, (lo - o) * ray.inv_dir);
    let t1 = Vec3A::select(hi.cmpeq(o), Vec3A::ZERO, (hi - o) * ray.inv_dir);
    let ordered = t0.cmple(t1);
    let enter = Vec3A::select(ordered, t0, t1);
    let leave = Vec3A::select(ordered, t1, t0);
    // A zero component: inside the slab for every t or for none (its t0,
    // t1 are discarded). Otherwise only non-finite input gets a NaN here:
    // refused as a miss rather than let max/min silently drop it.
    let outside = o.cmplt(lo) | o.cmpgt(hi);
    let nan = enter.is_nan_mask() | leave.is_nan_mask();
    if ((ray.zero & outside) | (!ray.zero & nan)).any() {
        return None;
    }
    // max_keep(near, -inf) is near and min_keep(far, inf) is far.
    let e = Vec3A::select(ray.zero, Vec3A::NEG_INFINITY, enter).to_array();
    let l = Vec3A::select(ray.zero, Vec3A::INFINITY, leave).to_array();
    let near = max_keep(max_keep(max_keep(tmin, e[0]), e[1]), e[2]);
    let far = min_keep(min_keep(l[0], l[1]), l[2]);
    let far = min_keep(far * FAR_SCALE, tmax);
    (near <= far).then_some((near, far))
}

/// `ray_box(ray, lo, hi, tmin, tmax).is_some()`, for a caller that needs
/// only the decision (a filter before an exact test). When every
/// reciprocal is finite no product is a NaN for finite input, a bound
/// through the origin gives `0 * inv`, a zero of either sign where
/// [`ray_box`] writes `+0`, and min and max of the two crossings are the
/// values its selects take: the same `near` and `far` up to the sign of a
/// zero, so the same `near <= far`. Other rays take [`ray_box_a`].
#[inline]
pub fn ray_meets_box(ray: &SlabRay, lo: Vec3A, hi: Vec3A, tmin: f32, tmax: f32) -> bool {
    if !ray.finite {
        return ray_box_a(ray, lo, hi, tmin, tmax).is_some();
    }
    let t0 = (lo - ray.origin) * ray.inv_dir;
    let t1 = (hi - ray.origin) * ray.inv_dir;
    let near = max_keep(t0.min(t1).max_element(), tmin);
    let far = min_keep(t0.max(t1).min_element() * FAR_SCALE, tmax);
    near <= far
}

/// The entry of [`ray_box_a`], for a caller that needs only the entry.
/// When every reciprocal is finite it takes the crossings as
/// [`ray_meets_box`] does: they differ from [`ray_box_a`]'s at most in the
/// sign of a zero, and the entry starts from `tmin` and takes a crossing
/// only when it is strictly larger, so a zero crossing never replaces a
/// zero entry: the same `near` bit for bit, and the same `near <= far`.
/// Other rays take [`ray_box_a`].
#[inline]
pub fn ray_box_entry(ray: &SlabRay, lo: Vec3A, hi: Vec3A, tmin: f32, tmax: f32) -> Option<f32> {
    if !ray.finite {
        return ray_box_a(ray, lo, hi, tmin, tmax).map(|(entry, _)| entry);
    }
    let t0 = (lo - ray.origin) * ray.inv_dir;
    let t1 = (hi - ray.origin) * ray.inv_dir;
    let e = t0.min(t1).to_array();
    let l = t0.max(t1).to_array();
    let near = max_keep(max_keep(max_keep(tmin, e[0]), e[1]), e[2]);
    let far = min_keep(min_keep(l[0], l[1]), l[2]);
    let far = min_keep(far * FAR_SCALE, tmax);
    (near <= far).then_some(near)
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

    /// The decision-only test agrees with the full one, and the entry-only
    /// test with its entry bit for bit, also on boxes with a bound through
    /// the origin and on axis-parallel rays.
    #[test]
    fn meets_box_is_the_full_decision() {
        let mut rng = SplitMix64::new(12);
        let mut hits = 0;
        for k in 0..50_000 {
            let lo = rng.point_in(Vec3::splat(-10.0), Vec3::splat(10.0));
            let hi = lo + rng.point_in(Vec3::ZERO, Vec3::splat(5.0));
            let mut origin = rng.point_in(Vec3::splat(-20.0), Vec3::splat(20.0));
            let mut dir = rng.point_in(lo, hi) - origin;
            let axis = k % 3;
            match k % 5 {
                0 => origin[axis] = lo[axis],
                1 => origin[axis] = hi[axis],
                2 => dir[axis] = 0.0,
                3 => dir[axis] = f32::from_bits(1),
                _ => {}
            }
            let tmax = if k % 4 == 0 {
                rng.range_f32(0.0, 2.0)
            } else {
                f32::INFINITY
            };
            // tmin = -0 as well: the entry's zero keeps the sign of tmin's.
            let tmin = if k % 7 == 0 { -0.0 } else { 0.0 };
            let r = Ray::new(origin, dir, tmin, tmax);
            if !r.is_valid() {
                continue;
            }
            let s = SlabRay::new(&r);
            let full = ray_box(&s, lo, hi, r.tmin, r.tmax);
            assert_eq!(
                ray_meets_box(&s, lo.into(), hi.into(), r.tmin, r.tmax),
                full.is_some(),
                "{r:?} {lo} {hi}"
            );
            assert_eq!(
                ray_box_entry(&s, lo.into(), hi.into(), r.tmin, r.tmax).map(f32::to_bits),
                full.map(|(entry, _)| entry.to_bits()),
                "{r:?} {lo} {hi}"
            );
            hits += full.is_some() as u32;
        }
        assert!(hits > 10_000, "{hits}");
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
