//! Shadow rays for the trace benches.

use glam::Vec3;
use golden::geom::Ray;
use golden::trace::{TraceContext, TraceScene, TraceStats};

/// Shadow rays from the hit points of `rays` (moved back off the surface)
/// to a light above the scene: `tmax = 1` ends them at the light.
pub fn shadow_rays(scene: &TraceScene, rays: &[Ray]) -> Vec<Ray> {
    let (lo, hi) = scene.bounds();
    let size = (hi - lo).length();
    let light = (lo + hi) * 0.5 + Vec3::new(0.3, 1.5, 0.2) * size;
    let mut ctx = TraceContext::new();
    rays.iter()
        .filter_map(|r| {
            let h = ctx.closest_hit(r, scene, &mut TraceStats::default())?;
            let p = r.at(h.t) - r.dir.normalize() * (size * 1e-4);
            let s = Ray::new(p, light - p, 0.0, 1.0);
            s.is_valid().then_some(s)
        })
        .collect()
}
