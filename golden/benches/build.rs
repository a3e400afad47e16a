//! Build throughput: `cargo bench -p golden --bench build`.
//!
//! Per scene: the optimized builder and the frozen reference builder
//! (`tests/support/reference_builder.rs`, the builder before the speed
//! work) are run alternately on the same input, their outputs are compared
//! bit for bit, and each one's CPU time per build and triangles per CPU
//! second are printed with the speed-up. CPU time (this thread's, from
//! `clock_gettime`) is the number to read: the machine may be shared, so wall
//! time is printed too but is noisy.
//!
//! `BUILD_BENCH=<substring>` runs only the scenes whose name contains it;
//! `BUILD_BENCH_NEW_ONLY=1` skips the reference (for profiling the new path).

#[path = "support/cpu_time.rs"]
mod cpu_time;
#[path = "../tests/support/reference_builder.rs"]
mod reference_builder;

use std::hint::black_box;
use std::time::{Duration, Instant};

use cpu_time::thread_cpu_time;

use glam::DVec3;
use golden::build::{build, GridMap};
use golden::mesh::Mesh;
use golden::scenes;
use golden::store::Hierarchy;
use golden::Params;

/// Accumulated CPU and best wall time of one builder over several runs.
#[derive(Default)]
struct Timing {
    cpu: Duration,
    runs: u32,
    best_wall: Option<Duration>,
}

impl Timing {
    fn run(&mut self, f: impl FnOnce() -> Hierarchy) -> Hierarchy {
        let cpu0 = thread_cpu_time().unwrap_or_default();
        let t = Instant::now();
        let h = black_box(f());
        let wall = t.elapsed();
        self.cpu += thread_cpu_time().unwrap_or_default().saturating_sub(cpu0);
        self.runs += 1;
        self.best_wall = Some(self.best_wall.map_or(wall, |b| b.min(wall)));
        h
    }

    /// Mean CPU seconds per run (NaN without /proc).
    fn cpu_secs(&self) -> f64 {
        if self.cpu.is_zero() {
            return f64::NAN;
        }
        self.cpu.as_secs_f64() / self.runs as f64
    }

    fn wall_secs(&self) -> f64 {
        self.best_wall.map_or(f64::NAN, |w| w.as_secs_f64())
    }
}

fn selected(name: &str) -> bool {
    std::env::var("BUILD_BENCH").map_or(true, |f| name.contains(&f))
}

fn bench(name: &str, mesh: &Mesh, grid: &GridMap, p: &Params, runs: usize) {
    let n = mesh.triangles.len() as f64;
    let new_only = std::env::var("BUILD_BENCH_NEW_ONLY").is_ok_and(|v| v == "1");
    let (mut new, mut old) = (Timing::default(), Timing::default());
    let mut last = None;
    for _ in 0..runs {
        let h = new.run(|| build(mesh, grid, p, 0).expect("bench scene builds"));
        if !new_only {
            let r =
                old.run(|| reference_builder::build(mesh, grid, p, 0).expect("reference builds"));
            assert!(
                h == r,
                "{name}: the builder's output differs from the reference"
            );
        }
        last = Some(h);
    }
    let h = last.expect("at least one run");
    let rate = |s: f64| n / s / 1e6;
    let mut line = format!(
        "{name:<26} D={:<2} Q={:<2} tris {:>8} | new cpu {:>8.2} ms {:>6.2} M tris/s (wall best {:>8.2} ms)",
        p.max_lod,
        p.quant_bits,
        n,
        new.cpu_secs() * 1e3,
        rate(new.cpu_secs()),
        new.wall_secs() * 1e3,
    );
    if !new_only {
        line += &format!(
            " | reference cpu {:>8.2} ms {:>6.2} M tris/s (wall best {:>8.2} ms) | speed-up cpu {:>5.2}x wall {:>5.2}x, identical",
            old.cpu_secs() * 1e3,
            rate(old.cpu_secs()),
            old.wall_secs() * 1e3,
            old.cpu_secs() / new.cpu_secs(),
            old.wall_secs() / new.wall_secs(),
        );
    }
    line += &format!(
        " | entries {} nodes {} top_lod {} roots {}",
        h.prims.len(),
        h.nodes.len(),
        h.top_lod,
        h.root_count
    );
    println!("{line}");
}

fn unit_cube_grid(p: &Params) -> GridMap {
    GridMap {
        origin: DVec3::ZERO,
        unit: 1.0 / p.scene_edge() as f64,
    }
}

fn main() {
    let p = Params::new(16, 8, 24, 4).unwrap();
    if selected("bunny") {
        let bunny = Mesh::load(&scenes::shared_mesh_path("bunny.obj")).expect("bunny.obj");
        let (lo, hi) = bunny.bounds();
        for d in [8u8, 12, 16] {
            let pd = Params::new(d, 8, 24, 4).unwrap();
            bench("bunny", &bunny, &GridMap::fit(lo, hi, &pd), &pd, 100);
        }
    }
    if selected("teapot") {
        let teapot = Mesh::load(&scenes::shared_mesh_path("teapot.obj")).expect("teapot.obj");
        let (lo, hi) = teapot.bounds();
        bench("teapot", &teapot, &GridMap::fit(lo, hi, &p), &p, 100);
    }
    // 1M small triangles: edges up to 1/1000 of the scene (about 65 grid units at D = 16).
    if selected("soup 1M size 1e-3") {
        let soup = scenes::random_soup(1_000_000, 0.001, 1);
        bench("soup 1M size 1e-3", &soup, &unit_cube_grid(&p), &p, 3);
    }
    if selected("soup 1M size 1e-4") {
        let soup = scenes::random_soup(1_000_000, 0.0001, 2);
        bench("soup 1M size 1e-4", &soup, &unit_cube_grid(&p), &p, 3);
    }
    if selected("terrain 1M (shared edges)") {
        let terrain = scenes::terrain(708, 3);
        bench(
            "terrain 1M (shared edges)",
            &terrain,
            &unit_cube_grid(&p),
            &p,
            3,
        );
    }
    if selected("architecture") {
        let house = scenes::architecture(6, 12);
        let (lo, hi) = house.bounds();
        bench("architecture", &house, &GridMap::fit(lo, hi, &p), &p, 3);
    }
    if selected("slivers 100k") {
        let slivers = scenes::slivers(100_000, 4);
        bench("slivers 100k", &slivers, &unit_cube_grid(&p), &p, 3);
    }
}
