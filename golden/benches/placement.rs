//! Cost against distance from the origin: `cargo bench -p golden --bench placement`.
//!
//! The same relative configuration (bunny and teapot, 4 units each, a
//! fraction of a voxel off the grid, rays from the same relative points) is
//! placed at 0, 1e3, 1e6 and 1e9 world units from the origin, on +x and -x
//! (and the diagonal), and traced through the merged hierarchy, the separate
//! hierarchies and a full rebuild of the placed triangles (binary32 world
//! coordinates, which lose the geometry far out: shown, not a target). Node
//! and triangle tests per ray are counts, not timings. `--verify`-style
//! oracle faults are counted too; they must be 0 for merged and separate.
//!
//! The grid: D = 31, one grid unit = one world unit, from -2^30 to 2^30.

use glam::{DVec3, Vec3};
use golden::build::{build, GridMap};
use golden::geom::Ray;
use golden::merge::MergeMode;
use golden::mesh::Mesh;
use golden::oracle::{Oracle, OracleSummary};
use golden::scenes::shared_mesh_path;
use golden::trace::{closest_hit, Hit, Instance, TraceScene, TraceStats};
use golden::world::World;
use golden::Params;

#[path = "support/fitted.rs"]
mod fitted;
use fitted::fitted;

struct Row {
    node: f64,
    prim: f64,
    faults: u64,
}

/// `remap` turns a hit of `scene` into the hierarchy and triangle the oracle knows.
fn measure(scene: &TraceScene, rays: &[Ray], oracle: &Oracle, remap: &dyn Fn(Hit) -> Hit) -> Row {
    let mut st = TraceStats::default();
    let hits: Vec<Option<Hit>> = rays
        .iter()
        .map(|r| closest_hit(r, scene, &mut st).map(remap))
        .collect();
    let s: OracleSummary = oracle.judge_all(rays, hits.iter().map(|h| h.as_ref()));
    let n = rays.len() as f64;
    Row {
        node: st.node_tests as f64 / n,
        prim: st.prim_tests as f64 / n,
        faults: s.faults(),
    }
}

fn main() {
    let p = Params::new(31, 8, 24, 4).expect("params");
    let grid = GridMap {
        origin: DVec3::splat(-((1u64 << 30) as f64)),
        unit: 1.0,
    };
    let bunny = Mesh::load(&shared_mesh_path("bunny.obj")).expect("bunny");
    let teapot = Mesh::load(&shared_mesh_path("teapot.obj")).expect("teapot");
    let a = fitted(&bunny, 4.0, Vec3::splat(2.0));
    let b = fitted(&teapot, 4.0, Vec3::new(7.0, 2.0, 3.0));
    let fraction = DVec3::new(0.37, -0.21, 0.113);
    println!(
        "{:>10} {:>6} | {:>8} {:>8} {:>6} | {:>8} {:>8} {:>6} | {:>8} {:>8} {:>6}",
        "distance",
        "axis",
        "merged",
        "tri",
        "fault",
        "separate",
        "tri",
        "fault",
        "rebuild",
        "tri",
        "fault"
    );
    println!(
        "{:>17} | node tests and triangle tests per ray; oracle faults",
        ""
    );
    for (axis, u) in [
        ("+x", DVec3::X),
        ("-x", -DVec3::X),
        ("diag", DVec3::new(1.0, 0.618, 0.382).normalize()),
    ] {
        for d in [0.0, 1e3, 1e6, 1e9] {
            // A multiple of 64 plus the same fraction: the same relative
            // configuration, the same residual, at every distance.
            let base = (u * d / 64.0).round() * 64.0;
            let at = base + fraction;
            let mut w = World::new(p, grid).expect("world");
            w.add(1, a.clone(), at).expect("bunny placed");
            w.add(2, b.clone(), at).expect("teapot placed");
            w.merge(&[1, 2], MergeMode::default(), 9).expect("merge");
            let r = w.lattice_rays(&[1, 2], base, 20_000, 7, false).unwrap();
            let oracle = Oracle::new(&w.oracle_parts(&[1, 2]).unwrap()).unwrap();
            let mi = w.merged_instances(9, &[1, 2]).unwrap();
            let si = w.separate_instances(&[1, 2]).unwrap();
            let same = |h: Hit| h;
            let merged = measure(&w.trace_scene(&mi, &[9]).unwrap(), &r, &oracle, &same);
            let separate = measure(&w.trace_scene(&si, &[1, 2]).unwrap(), &r, &oracle, &same);
            let placed = w.placed_mesh(&[1, 2]).unwrap();
            // The rebuild's triangle k: the bunny's, then the teapot's.
            let split = a.triangles.len() as u32;
            let remap = |h: Hit| match h.prim.checked_sub(split) {
                Some(prim) => Hit { hier: 2, prim, ..h },
                None => Hit { hier: 1, ..h },
            };
            let rebuild = build(&placed, &grid, &p, 0).map(|h| {
                let s = TraceScene::new(grid, &[Instance::new(&h, &placed)]).unwrap();
                measure(&s, &r, &oracle, &remap)
            });
            let cell = |x: &Row| format!("{:>8.1} {:>8.1} {:>6}", x.node, x.prim, x.faults);
            println!(
                "{d:>10.0e} {axis:>6} | {} | {} | {}",
                cell(&merged),
                cell(&separate),
                rebuild.as_ref().map_or_else(|e| format!("{e}"), cell)
            );
        }
    }
}
