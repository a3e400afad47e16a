//! Traversal throughput: `cargo bench -p golden --bench trace`.
//!
//! Per scene and (D, Q): build time, rays per second of closest-hit
//! traversal, node (box) and triangle tests per ray. The big scene is a
//! noisy terrain of just over a million triangles. `TRACE_BENCH=bunny`
//! runs only the scenes whose name contains "bunny".

use std::time::Instant;

use golden::build::{build, GridMap};
use golden::mesh::Mesh;
use golden::scenes::{self, shared_mesh_path};
use golden::trace::{bench_trace, Instance, TraceScene};
use golden::Params;

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
        let scene = TraceScene::new(grid, &[Instance::new(&h, mesh)]).expect("scene");
        let b = bench_trace(&scene, rays, 1);
        println!(
            "{name:<16} D={d:<2} Q={q:<2} tris {:>8}  build {:>8.1} ms  trace {:>7} rays {:>7.3} s  {:>8.0} rays/s  hits {:>5.1}%  node tests/ray {:>6.1}  tri tests/ray {:>6.1}",
            mesh.triangles.len(),
            build_s * 1e3,
            b.rays,
            b.seconds,
            b.rays_per_second,
            100.0 * b.hits as f64 / b.rays as f64,
            b.node_tests_per_ray,
            b.prim_tests_per_ray,
        );
    }
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
