//! Merge against a full rebuild, in the same run:
//! `cargo bench -p golden --bench merge`.
//!
//! Scene: a static terrain of just over a million triangles (built once, its
//! hierarchy reused) and a small dynamic bunny placed on it by a
//! translation. Per merging mode it prints the merge time (best of several
//! runs), the time of a full rebuild of all triangles (terrain + placed
//! bunny) and their ratio, and node tests per ray through the merged
//! hierarchy, the rebuilt one and the two separate hierarchies.
//! `MERGE_BENCH_RAYS=N` sets the number of rays (default 20000).

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use golden::build::{build, GridMap};
use golden::merge::instances::{input_instances, merged_instances};
use golden::merge::{merge, MergeMode};
use golden::mesh::Mesh;
use golden::scenes::{self, shared_mesh_path};
use golden::store::HierarchyStore;
use golden::trace::{closest_hit, random_rays, Instance, TraceScene, TraceStats};
use golden::translate::{Axis, Translation, TranslationTable};
use golden::Params;

fn best_of<T>(runs: usize, mut f: impl FnMut() -> T) -> (Duration, T) {
    let mut best = Duration::MAX;
    let mut out = None;
    for _ in 0..runs {
        let t = Instant::now();
        let r = f();
        best = best.min(t.elapsed());
        out = Some(r);
    }
    (best, out.expect("at least one run"))
}

fn node_tests(scene: &TraceScene, rays: &[golden::geom::Ray]) -> f64 {
    let mut s = TraceStats::default();
    for r in rays {
        closest_hit(r, scene, &mut s);
    }
    s.node_tests as f64 / rays.len() as f64
}

fn main() {
    let p = Params::new(16, 8, 24, 4).expect("params");
    let terrain = scenes::terrain(708, 1);
    let grid = GridMap::fit(glam::Vec3::ZERO, glam::Vec3::ONE, &p);
    let bunny_src = Mesh::load(&shared_mesh_path("bunny.obj")).expect("bunny.obj");
    // The bunny, 0.04 world units tall, built in its local frame near the origin.
    let (blo, bhi) = bunny_src.bounds();
    let s = 0.04 / (bhi - blo).max_element();
    let bunny = Mesh {
        vertices: bunny_src
            .vertices
            .iter()
            .map(|&v| (v - blo) * s + glam::Vec3::splat(0.002))
            .collect(),
        triangles: bunny_src.triangles.clone(),
    };
    println!(
        "scene: terrain {} triangles (static), bunny {} triangles (dynamic), D={} Q={}",
        terrain.triangles.len(),
        bunny.triangles.len(),
        p.max_lod,
        p.quant_bits
    );

    let t0 = Instant::now();
    let static_h = build(&terrain, &grid, &p, 1).expect("terrain builds");
    let static_time = t0.elapsed();
    let (dyn_time, dyn_h) = best_of(5, || build(&bunny, &grid, &p, 2).expect("bunny builds"));
    // Place the bunny on the terrain's middle at its top LOD.
    let l = dyn_h.top_lod;
    let e = p.voxel_edge(l) as f64 * grid.unit;
    let t = [0.5f64, 0.55, 0.5].map(|w| (w / e).round() as i64);
    let tr = Translation { lod: l, t };
    let mut table = TranslationTable::new(p.hier_capacity() as usize, &p).expect("table");
    table
        .write(1, Translation::zero(static_h.top_lod))
        .expect("table write");
    table.write(2, tr).expect("table write");
    println!(
        "static build {:.1} ms ({} nodes, top LOD {}), dynamic build {:.3} ms ({} nodes, top LOD {l}), translation {tr:?}",
        static_time.as_secs_f64() * 1e3,
        static_h.nodes.len(),
        static_h.top_lod,
        dyn_time.as_secs_f64() * 1e3,
        dyn_h.nodes.len()
    );
    let mut store = HierarchyStore::new();
    store.insert(static_h).expect("insert");
    store.insert(dyn_h).expect("insert");

    // The full rebuild: every triangle, the bunny at its placed position.
    let shift =
        glam::DVec3::from_array(Axis::ALL.map(|a| tr.grid_offset(a, &p) as f64 * grid.unit));
    let mut all = terrain.clone();
    let base = all.vertices.len() as u32;
    all.vertices.extend(
        bunny
            .vertices
            .iter()
            .map(|v| (v.as_dvec3() + shift).as_vec3()),
    );
    all.triangles
        .extend(bunny.triangles.iter().map(|t| t.map(|i| i + base)));
    let (rebuild_time, rebuilt) = best_of(2, || build(&all, &grid, &p, 4).expect("rebuild"));

    let n_rays: usize = std::env::var("MERGE_BENCH_RAYS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(20_000);
    let meshes: BTreeMap<u8, &Mesh> = [(1u8, &terrain), (2u8, &bunny)].into_iter().collect();
    let separate = input_instances(&store, &table, &meshes).expect("instances");
    let sep_scene = TraceScene::new(grid, &separate).expect("scene");
    // Half the rays at the bunny, half at the whole scene.
    let bunny_scene = TraceScene::new(grid, &separate[1..]).expect("scene");
    let (lo, hi) = bunny_scene.bounds();
    let mut rays = random_rays(lo, hi, n_rays / 2, 11);
    let (lo, hi) = sep_scene.bounds();
    rays.extend(random_rays(lo, hi, n_rays - n_rays / 2, 12));
    let rebuilt_scene = TraceScene::new(grid, &[Instance::new(&rebuilt, &all)]).expect("scene");
    let rebuild_tests = node_tests(&rebuilt_scene, &rays);
    let separate_tests = node_tests(&sep_scene, &rays);
    println!(
        "full rebuild of {} triangles: {:.1} ms, {} nodes; node tests/ray: rebuild {rebuild_tests:.2}, separate {separate_tests:.2} ({} rays)",
        all.triangles.len(),
        rebuild_time.as_secs_f64() * 1e3,
        rebuilt.nodes.len(),
        rays.len()
    );
    println!("| mode | level | merge ms | rebuild / merge | created | reused | walked | node tests/ray merged | vs rebuild |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for mode in [
        MergeMode::default(),
        MergeMode::BelowTop(0),
        MergeMode::BelowTop(2),
        MergeMode::Proportion { num: 1, den: 2 },
        MergeMode::PerNode { num: 1, den: 2 },
        MergeMode::PerNode { num: 0, den: 1 },
    ] {
        let (merge_time, r) = best_of(10, || {
            merge(&store, &[1, 2], &table, mode, 3).expect("merge")
        });
        let mut st = store.clone();
        st.insert(r.merged.clone()).expect("insert merged");
        let mi =
            merged_instances(st.get(3).expect("merged"), &st, &table, &meshes).expect("instances");
        let ms = TraceScene::with_roots(grid, &mi, &[3]).expect("scene");
        let merged_tests = node_tests(&ms, &rays);
        println!(
            "| {mode:?} | {:?} | {:.3} | {:.0}x | {} | {} | {} | {merged_tests:.2} | {:+.1}% |",
            r.level,
            merge_time.as_secs_f64() * 1e3,
            rebuild_time.as_secs_f64() / merge_time.as_secs_f64(),
            r.stats.created(),
            r.stats.reused(),
            r.stats.nodes_walked,
            (merged_tests / rebuild_tests - 1.0) * 100.0
        );
    }
}
