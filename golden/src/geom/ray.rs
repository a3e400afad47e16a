//! Rays in world space, f32 as a renderer holds them.

use glam::Vec3;

/// A ray `origin + t dir` for `t` in `[tmin, tmax]` (both ends included).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start point, world units; must be finite.
    pub origin: Vec3,
    /// Need not be normalized; must not be zero.
    pub dir: Vec3,
    /// Nearest parameter accepted, `>= 0`.
    pub tmin: f32,
    /// Farthest parameter accepted, `>= tmin`; may be `+inf`.
    pub tmax: f32,
}

impl Ray {
    /// A ray over `[tmin, tmax]`; [`Ray::is_valid`] says whether the kernels accept it.
    pub fn new(origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Ray {
        Ray {
            origin,
            dir,
            tmin,
            tmax,
        }
    }

    /// A ray over `[0, +inf]`.
    pub fn unbounded(origin: Vec3, dir: Vec3) -> Ray {
        Ray::new(origin, dir, 0.0, f32::INFINITY)
    }

    /// The point at parameter `t` (rounded in f32).
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }

    /// True when the kernels give meaningful answers: finite origin,
    /// finite non-zero direction, `0 <= tmin <= tmax` (tmax may be +inf).
    pub fn is_valid(&self) -> bool {
        self.origin.is_finite()
            && self.dir.is_finite()
            && self.dir != Vec3::ZERO
            && self.tmin >= 0.0
            && self.tmin <= self.tmax
    }

    /// The same ray with a new far end.
    pub fn with_tmax(&self, tmax: f32) -> Ray {
        Ray { tmax, ..*self }
    }
}
