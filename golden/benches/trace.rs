//! Traversal throughput: `cargo bench -p golden --bench trace`.
//!
//! Per scene and (D, Q), in one run on the same rays: the frozen traversal
//! before the reusable context (`tests/support/reference_trace.rs`, which
//! allocates per ray) against [`TraceContext::closest_hit`] on seeded random
//! rays, and, on shadow rays from each hit point to a light above the
//! scene, the reference's closest-hit search (what shadow rays ran before)
//! against [`TraceContext::occluded`]. Each is run three times, alternately;
//! rays per CPU second (this thread's CPU time) and node and triangle tests
//! per ray are printed with the ratio to the reference. Before timing, every
//! ray's answer and test counts are compared with the reference: the closest
//! hit bit for bit, `occluded` against the closest hit's existence.
//!
//! The big scene is a noisy terrain of just over a million triangles.
//! `TRACE_BENCH=bunny` runs only the scenes whose name contains "bunny".

#[path = "support/cpu_time.rs"]
mod cpu_time;
#[path = "../tests/support/reference_trace.rs"]
mod reference_trace;
#[path = "support/shadow.rs"]
mod shadow;

use std::hint::black_box;
use std::time::Instant;

use cpu_time::thread_cpu_time;
use golden::build::{build, GridMap};
use golden::geom::Ray;
use golden::mesh::Mesh;
use golden::scenes::{self, shared_mesh_path};
use golden::trace::{random_rays, Instance, TraceContext, TraceScene, TraceStats};
use golden::Params;
use reference_trace::RefScene;
use shadow::shadow_rays;

/// Rounds of each measurement, alternating between the ways.
const ROUNDS: u32 = 3;

/// CPU seconds (wall where there is no thread clock) of `f`.
fn timed(f: impl FnOnce()) -> f64 {
    let (c0, w0) = (thread_cpu_time(), Instant::now());
    f();
    match (c0, thread_cpu_time()) {
        (Some(a), Some(b)) => (b - a).as_secs_f64(),
        _ => w0.elapsed().as_secs_f64(),
    }
}

/// Rays per second, tests per ray of one way of tracing.
#[derive(Default)]
struct Way {
    seconds: f64,
    rays: u64,
    stats: TraceStats,
    answers: u64,
}

impl Way {
    fn rays_per_second(&self) -> f64 {
        self.rays as f64 / self.seconds.max(1e-12)
    }
    fn per_ray(&self, n: u64) -> f64 {
        n as f64 / self.rays.max(1) as f64 / ROUNDS as f64
    }
    fn line(&self, label: &str) -> String {
        format!(
            "{label} {:>8.0} rays/s, {:>5.1} node {:>5.1} tri tests/ray",
            self.rays_per_second(),
            self.per_ray(self.stats.node_tests),
            self.per_ray(self.stats.prim_tests),
        )
    }
}

/// Every ray's answers agree with the reference (not timed).
fn check_agreement(name: &str, scene: &TraceScene, old: &RefScene, rays: &[Ray], shadows: &[Ray]) {
    let mut ctx = TraceContext::new();
    for r in rays.iter().chain(shadows) {
        let (mut a, mut b, mut o) = Default::default();
        let got = ctx.closest_hit(r, scene, &mut a);
        let want = reference_trace::closest_hit(r, old, &mut b);
        let same = match (got, want) {
            (Some(x), Some(y)) => x.identical(&y),
            (None, None) => true,
            _ => false,
        };
        assert!(
            same && a == b,
            "{name}: {r:?}: {got:?} {a:?} vs reference {want:?} {b:?}"
        );
        let blocked = ctx.occluded(r, scene, &mut o);
        assert_eq!(blocked, got.is_some(), "{name}: {r:?}: occluded");
    }
}

fn run(name: &str, mesh: &Mesh, configs: &[(u8, u8)], rays: usize) {
    if let Ok(filter) = std::env::var("TRACE_BENCH") {
        if !name.contains(&filter) {
            return;
        }
    }
    for &(d, q) in configs {
        let p = Params::new(d, q, 24, 4).expect("bench params");
        let (lo, hi) = mesh.bounds();
        let grid = GridMap::fit(lo, hi, &p);
        let t = Instant::now();
        let h = build(mesh, &grid, &p, 1).expect("bench scene builds");
        let build_s = t.elapsed().as_secs_f64();
        let inst = [Instance::new(&h, mesh)];
        let scene = TraceScene::new(grid, &inst).expect("scene");
        let old = RefScene::new(grid, &inst);
        let (blo, bhi) = scene.bounds();
        let primary = random_rays(blo, bhi, rays, 1);
        let shadows = shadow_rays(&scene, &primary);
        check_agreement(name, &scene, &old, &primary, &shadows);
        let (mut ref_p, mut ctx_p, mut ref_s, mut occ_s) = Default::default();
        let mut ctx = TraceContext::new();
        for _ in 0..ROUNDS {
            trace_ref(&mut ref_p, &primary, &old);
            trace_ctx(&mut ctx_p, &primary, &scene, &mut ctx, false);
            trace_ref(&mut ref_s, &shadows, &old);
            trace_ctx(&mut occ_s, &shadows, &scene, &mut ctx, true);
        }
        assert_eq!(ref_p.answers, ctx_p.answers, "{name}: hits");
        assert_eq!(ref_s.answers, occ_s.answers, "{name}: shadowed");
        println!(
            "{name:<14} D={d:<2} Q={q:<2} tris {:>8} build {:>7.1} ms | {} rays: {} | {} ({:.2}x, identical) | {} shadow rays: {} | {} ({:.2}x, {:.1}% shadowed)",
            mesh.triangles.len(),
            build_s * 1e3,
            primary.len(),
            ref_p.line("reference"),
            ctx_p.line("context"),
            ctx_p.rays_per_second() / ref_p.rays_per_second(),
            shadows.len(),
            ref_s.line("reference closest"),
            occ_s.line("occluded"),
            occ_s.rays_per_second() / ref_s.rays_per_second(),
            100.0 * occ_s.answers as f64 / (occ_s.rays.max(1) as f64),
        );
    }
}

fn trace_ref(w: &mut Way, rays: &[Ray], old: &RefScene) {
    let mut answers = 0;
    w.seconds += timed(|| {
        for r in rays {
            answers +=
                reference_trace::closest_hit(black_box(r), old, &mut w.stats).is_some() as u64;
        }
    });
    w.rays += rays.len() as u64;
    w.answers = answers;
}

fn trace_ctx(w: &mut Way, rays: &[Ray], scene: &TraceScene, ctx: &mut TraceContext, any: bool) {
    let mut answers = 0;
    w.seconds += timed(|| {
        for r in rays {
            answers += if any {
                ctx.occluded(black_box(r), scene, &mut w.stats)
            } else {
                ctx.closest_hit(black_box(r), scene, &mut w.stats).is_some()
            } as u64;
        }
    });
    w.rays += rays.len() as u64;
    w.answers = answers;
}

fn main() {
    let configs = [(8, 0), (12, 4), (16, 0), (16, 8)];
    for name in ["bunny.obj", "teapot.obj"] {
        match Mesh::load(&shared_mesh_path(name)) {
            Ok(m) => run(name, &m, &configs, 100_000),
            Err(e) => println!("{name}: skipped: {e}"),
        }
    }
    run(
        "slivers+axis",
        &scenes::hard_cases(3000, 7),
        &configs,
        100_000,
    );
    run(
        "terrain 1M",
        &scenes::terrain(708, 1),
        &[(16, 0), (16, 8)],
        100_000,
    );
}
