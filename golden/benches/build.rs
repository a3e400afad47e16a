//! Build throughput: `cargo bench -p golden --bench build`.
//!
//! Prints, per scene, triangles per second of the whole build (best of a few
//! runs), the node/prim counts, and the share of the leaf phase (LOD, voxel
//! overlap, clip, quantize) and of the radix sort, measured on their own.

use std::hint::black_box;
use std::time::{Duration, Instant};

use glam::DVec3;
use golden::build::{build, leaves, radix, GridMap};
use golden::mesh::Mesh;
use golden::scenes;
use golden::Params;

/// CPU time (user + system) of this thread so far, from
/// `/proc/thread-self/stat` in clock ticks of 1/100 s (Linux's USER_HZ); None
/// elsewhere. The machine may be shared, so throughput is reported per CPU
/// second as well as per wall second.
fn thread_cpu_time() -> Option<Duration> {
    let stat = std::fs::read_to_string("/proc/thread-self/stat").ok()?;
    // Fields after the command name, which is in parentheses and may hold spaces.
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    // utime and stime are fields 14 and 15 of the whole line, 12 and 13 here (0-based 11, 12).
    let ticks: u64 = f.get(11)?.parse::<u64>().ok()? + f.get(12)?.parse::<u64>().ok()?;
    Some(Duration::from_millis(ticks * 10))
}

/// Runs `f` `runs` times; returns the best wall time and the mean CPU time.
fn measure(runs: usize, mut f: impl FnMut()) -> (Duration, Option<Duration>) {
    let cpu0 = thread_cpu_time();
    let best = best_of(runs, &mut f);
    let cpu = match (cpu0, thread_cpu_time()) {
        (Some(a), Some(b)) => Some((b - a) / runs as u32),
        _ => None,
    };
    (best, cpu)
}

fn best_of(runs: usize, mut f: impl FnMut()) -> Duration {
    (0..runs)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed()
        })
        .min()
        .expect("at least one run")
}

fn bench(name: &str, mesh: &Mesh, grid: &GridMap, p: &Params, runs: usize) {
    // `BUILD_BENCH=soup cargo bench ...` runs only the scenes whose name contains "soup".
    if let Ok(filter) = std::env::var("BUILD_BENCH") {
        if !name.contains(&filter) {
            return;
        }
    }
    let n = mesh.triangles.len();
    let h = build(mesh, grid, p, 0).expect("bench scene builds");
    let (total, cpu) = measure(runs, || {
        black_box(build(mesh, grid, p, 0).unwrap());
    });
    // The leaf phase alone (grid mapping included), then the sort alone.
    let tris = grid.mesh_to_grid(mesh, p).unwrap();
    let mut entries = Vec::with_capacity(n * 4);
    let place = best_of(runs, || {
        entries.clear();
        for (i, t) in tris.iter().enumerate() {
            leaves::place_triangle(t, i as u32, p, &mut entries);
        }
        black_box(&entries);
    });
    let unsorted = entries.clone();
    let mut scratch = Vec::new();
    let sort = best_of(runs, || {
        entries.clone_from(&unsorted);
        radix::radix_sort(&mut entries, &mut scratch, leaves::leaf_key_bits(p), |e| {
            e.key
        });
    });
    let secs = total.as_secs_f64();
    let cpu_secs = cpu.map_or(f64::NAN, |c| c.as_secs_f64());
    println!(
        "{name:<26} D={:<2} Q={:<2} tris {n:>8} | wall {:>8.2} ms {:>5.2} M tris/s | cpu {:>8.2} ms {:>5.2} M tris/s | leaf phase {:>7.2} ms, sort {:>6.2} ms (wall) | entries {:>8} nodes {:>8} refs {:>8} top_lod {} roots {}",
        p.max_lod,
        p.quant_bits,
        secs * 1e3,
        n as f64 / secs / 1e6,
        cpu_secs * 1e3,
        n as f64 / cpu_secs / 1e6,
        place.as_secs_f64() * 1e3,
        sort.as_secs_f64() * 1e3,
        h.prims.len(),
        h.nodes.len(),
        h.refs.len(),
        h.top_lod,
        h.root_count,
    );
}

fn unit_cube_grid(p: &Params) -> GridMap {
    GridMap {
        origin: DVec3::ZERO,
        unit: 1.0 / p.scene_edge() as f64,
    }
}

fn main() {
    let p = Params::new(16, 8, 24, 4).unwrap();
    let bunny = Mesh::load(&scenes::shared_mesh_path("bunny.obj")).expect("bunny.obj");
    let (lo, hi) = bunny.bounds();
    for d in [8u8, 12, 16] {
        let pd = Params::new(d, 8, 24, 4).unwrap();
        bench("bunny", &bunny, &GridMap::fit(lo, hi, &pd), &pd, 100);
    }
    let teapot = Mesh::load(&scenes::shared_mesh_path("teapot.obj")).expect("teapot.obj");
    let (lo, hi) = teapot.bounds();
    bench("teapot", &teapot, &GridMap::fit(lo, hi, &p), &p, 200);

    // 1M small triangles: edges up to 1/1000 of the scene (about 65 grid units at D = 16).
    let soup = scenes::random_soup(1_000_000, 0.001, 1);
    bench("soup 1M size 1e-3", &soup, &unit_cube_grid(&p), &p, 3);
    let soup = scenes::random_soup(1_000_000, 0.0001, 2);
    bench("soup 1M size 1e-4", &soup, &unit_cube_grid(&p), &p, 3);
    let terrain = scenes::terrain(708, 3);
    bench(
        "terrain 1M (shared edges)",
        &terrain,
        &unit_cube_grid(&p),
        &p,
        3,
    );
    let slivers = scenes::slivers(100_000, 4);
    bench("slivers 100k", &slivers, &unit_cube_grid(&p), &p, 3);
}
