//! Measurements of what accuracy costs (SPEC 13, `hiermerge study`), for
//! software that wants them too: how loose the stored boxes are against the
//! exact tight boxes of their content (`looseness`), how many box tests pass
//! only because a box is loose (`walk`), and an independent binary64
//! reference tracer (`reference`) that shares no code with golden's
//! traversal, ray/triangle or ray/box kernels, or its snapping and
//! quantization, so hit errors are measured against something golden did
//! not compute.

pub mod looseness;
pub mod walk;

use glam::DVec3;

/// An axis-aligned box `[lo, hi]` in binary64 (closed on both ends).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Box64 {
    /// Minimum corner.
    pub lo: DVec3,
    /// Maximum corner.
    pub hi: DVec3,
}

impl Box64 {
    /// The smallest box holding both.
    pub fn union(&self, o: &Box64) -> Box64 {
        Box64 {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }

    /// Surface area `2 (wx wy + wy wz + wz wx)`.
    pub fn surface_area(&self) -> f64 {
        let w = (self.hi - self.lo).max(DVec3::ZERO);
        2.0 * (w.x * w.y + w.y * w.z + w.z * w.x)
    }

    /// The ray `org + t dir` over `[t0, t1]` meets the closed box (a plain
    /// binary64 slab test, no slack; an axis with `dir == 0` is inside the
    /// slab iff `org` is).
    pub fn hit(&self, org: DVec3, dir: DVec3, t0: f64, t1: f64) -> bool {
        let (mut near, mut far) = (t0, t1);
        for a in 0..3 {
            if dir[a] == 0.0 {
                if org[a] < self.lo[a] || org[a] > self.hi[a] {
                    return false;
                }
                continue;
            }
            let inv = 1.0 / dir[a];
            let (ta, tb) = ((self.lo[a] - org[a]) * inv, (self.hi[a] - org[a]) * inv);
            near = near.max(ta.min(tb));
            far = far.min(ta.max(tb));
            if near > far {
                return false;
            }
        }
        true
    }
}
