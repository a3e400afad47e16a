//! Rays of the kinds a scene asks for, traced through one trace scene:
//! primary rays (clipped at the clip distance), shadow rays from each hit to
//! each point light, and mirror reflections up to the scene's depth. Every
//! ray's node tests are added to its pixel for the heat map.

use glam::Vec3;
use golden::geom::Ray;
use golden::scene::Scene;
use golden::trace::{Hit, TraceContext, TraceScene, TraceStats};
use indicatif::ProgressBar;

/// Fraction of the scene cube's edge by which secondary rays start off the
/// surface, so they do not hit the triangle they leave.
const SURFACE_OFFSET: f32 = 1e-4;
/// Light every lit surface gets regardless of the lights.
const AMBIENT: f32 = 0.18;

/// A traced frame.
#[derive(Clone, Debug, Default)]
pub struct Traced {
    pub rgb: Vec<u8>,
    /// Node tests per pixel, every kind of ray.
    pub node_tests: Vec<u64>,
    pub rays: RayCounts,
    pub stats: TraceStats,
    pub seconds: f64,
}

/// Rays traced, per kind.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct RayCounts {
    pub primary: u64,
    pub primary_hits: u64,
    pub shadow: u64,
    pub shadowed: u64,
    pub reflection: u64,
}

struct Tracer<'a> {
    scene: &'a Scene,
    trace: &'a TraceScene<'a>,
    eps: f32,
    rays: RayCounts,
    stats: TraceStats,
    /// Reused by every ray of the frame: tracing allocates nothing.
    ctx: TraceContext,
}

/// Traces one image of `scene` through `trace`.
pub fn trace_frame(scene: &Scene, trace: &TraceScene, bar: &ProgressBar) -> Traced {
    let start = std::time::Instant::now();
    let (w, h) = (scene.width, scene.height);
    let edge = scene.params.scene_edge() as f64 * scene.grid.unit;
    let mut t = Tracer {
        scene,
        trace,
        eps: (edge * SURFACE_OFFSET as f64) as f32,
        rays: RayCounts::default(),
        stats: TraceStats::default(),
        ctx: TraceContext::new(),
    };
    let mut rgb = Vec::with_capacity((w * h * 3) as usize);
    let mut node_tests = Vec::with_capacity((w * h) as usize);
    bar.set_length(h as u64);
    for py in 0..h {
        for px in 0..w {
            let before = t.stats.node_tests;
            let colour = if scene.effects.primary {
                let ray = clipped(scene.camera.primary_ray(px, py, w, h), scene);
                t.rays.primary += 1;
                t.radiance(&ray, 0, py as f32 / h as f32)
            } else {
                Vec3::ZERO
            };
            rgb.extend(
                colour
                    .to_array()
                    .map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8),
            );
            node_tests.push(t.stats.node_tests - before);
        }
        bar.inc(1);
    }
    Traced {
        rgb,
        node_tests,
        rays: t.rays,
        stats: t.stats,
        seconds: start.elapsed().as_secs_f64(),
    }
}

/// `ray` ending at the scene's clip distance (in world units along it).
pub fn clipped(ray: Ray, scene: &Scene) -> Ray {
    let len = ray.dir.length();
    ray.with_tmax(scene.effects.clip_distance / len)
}

fn sky(v: f32) -> Vec3 {
    Vec3::new(0.6, 0.75, 0.95) * (1.0 - 0.3 * v)
}

impl<'a> Tracer<'a> {
    fn hit(&mut self, ray: &Ray) -> Option<Hit> {
        let mut s = TraceStats::default();
        let h = self.ctx.closest_hit(ray, self.trace, &mut s);
        self.stats += s;
        h
    }

    /// Colour seen along `ray`; `depth` mirror bounces so far; `v` the
    /// pixel row as a fraction (for the sky gradient).
    fn radiance(&mut self, ray: &Ray, depth: u32, v: f32) -> Vec3 {
        let Some(hit) = self.hit(ray) else {
            return sky(v);
        };
        if depth == 0 {
            self.rays.primary_hits += 1;
        }
        let o = &self.scene.objects[hit.hier as usize];
        let [a, b, c] = o.mesh.triangle(hit.prim as usize);
        let mut n = (b - a).cross(c - a).normalize_or_zero();
        if n.dot(ray.dir) > 0.0 {
            n = -n;
        }
        let p = ray.at(hit.t) + n * self.eps;
        let mut light = AMBIENT;
        if self.scene.lights.is_empty() {
            light += (1.0 - AMBIENT) * n.dot(Vec3::new(-0.4, 1.0, -0.3).normalize()).max(0.0);
        }
        // The scene outlives the tracer: its lights need no copy while
        // `self.hit` borrows the tracer mutably.
        let scene: &'a Scene = self.scene;
        for l in &scene.lights {
            let to = l.position - p;
            let facing = n.dot(to.normalize_or_zero());
            if facing <= 0.0 {
                continue;
            }
            let lit = if self.scene.effects.shadow {
                self.rays.shadow += 1;
                let shadow = Ray::new(p, to, 0.0, 1.0);
                // Any hit before the light will do (SPEC 6.11).
                let blocked = self.ctx.occluded(&shadow, self.trace, &mut self.stats);
                self.rays.shadowed += blocked as u64;
                !blocked
            } else {
                true
            };
            if lit {
                light += (1.0 - AMBIENT) * l.intensity * facing;
            }
        }
        let local = o.color * light;
        if o.mirror > 0.0 && depth < self.scene.effects.reflection_depth {
            let d = ray.dir.normalize();
            let r = d - 2.0 * d.dot(n) * n;
            self.rays.reflection += 1;
            let bounce = clipped(Ray::new(p, r, 0.0, f32::INFINITY), self.scene);
            let seen = self.radiance(&bounce, depth + 1, v);
            local * (1.0 - o.mirror) + seen * o.mirror
        } else {
            local
        }
    }
}
