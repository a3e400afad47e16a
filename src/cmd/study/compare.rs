//! Ray-by-ray comparison of a tracer's closest hits with the reference's
//! (SPEC 13.3).

use glam::DVec3;
use golden::geom::ray::Ray;
use golden::oracle::reference::ReferenceTracer;
use serde::Serialize;

/// Barycentric margin within which a ray grazes an edge: there two tracers
/// may rightly disagree (the reference is not watertight, golden is).
pub const GRAZE: f64 = 1e-5;

/// What the comparison counted.
#[derive(Serialize, Clone, Copy, Debug, Default)]
pub struct HitCounts {
    pub rays: u64,
    pub reference_hits: u64,
    /// Both hit the same triangle.
    pub same: u64,
    /// Both hit, different triangles (not an edge tie).
    pub wrong_triangle: u64,
    /// The reference hits, the tracer does not.
    pub missed: u64,
    /// The tracer hits, the reference does not.
    pub extra: u64,
    /// Disagreements within [`GRAZE`] of an edge, not counted above.
    pub grazing: u64,
    /// |t - t_ref| over rays where both hit the same triangle, world units.
    pub t_error_mean: f64,
    pub t_error_max: f64,
}

impl HitCounts {
    /// Wrong, missed and extra hits per ray.
    pub fn error_rate(&self) -> f64 {
        (self.wrong_triangle + self.missed + self.extra) as f64 / self.rays.max(1) as f64
    }
}

/// Compares `hits` (t, triangle) of `rays` with the reference over the
/// case's own triangles, the case asked to be at `at` (world units).
pub fn compare(
    reference: &ReferenceTracer,
    at: DVec3,
    rays: &[Ray],
    hits: &[Option<(f64, u32)>],
) -> HitCounts {
    let mut c = HitCounts::default();
    let mut t_sum = 0.0;
    for (r, got) in rays.iter().zip(hits) {
        // The ray as given, in the case's frame: binary64, one rounding.
        let org = r.origin.as_dvec3() - at;
        let dir = r.dir.as_dvec3();
        let want = reference.closest(org, dir, 0.0, f64::INFINITY);
        c.rays += 1;
        c.reference_hits += want.is_some() as u64;
        let tie = |prim: u32, t: f64| {
            reference
                .hits_prim(prim, org, dir, GRAZE)
                .is_some_and(|tp| (tp - t).abs() <= GRAZE * (1.0 + t.abs()))
        };
        match (want, got) {
            (None, None) => {}
            (Some(w), None) => {
                if w.min_bary < GRAZE {
                    c.grazing += 1;
                } else {
                    c.missed += 1;
                }
            }
            (None, Some((t, prim))) => {
                if tie(*prim, *t) {
                    c.grazing += 1;
                } else {
                    c.extra += 1;
                }
            }
            (Some(w), Some((t, prim))) => {
                if w.prim == *prim {
                    c.same += 1;
                    let e = (t - w.t).abs() * dir.length();
                    t_sum += e;
                    c.t_error_max = c.t_error_max.max(e);
                } else if tie(*prim, w.t) {
                    c.grazing += 1;
                } else {
                    c.wrong_triangle += 1;
                }
            }
        }
    }
    c.t_error_mean = t_sum / c.same.max(1) as f64;
    c
}
