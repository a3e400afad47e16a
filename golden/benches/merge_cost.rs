//! Does merging pay? `cargo bench -p golden --bench merge_cost`.
//!
//! Per scene and merging mode: node tests per ray through the merged
//! hierarchy, the separate hierarchies and a full rebuild of the placed
//! triangles, on the same rays (issue 19, item 4). Scenes: the shipped
//! scenes' objects at frame 0 (`scenes/default.json`, `scenes/bunny_teapot.json`),
//! bunny beside teapot, a generated building alone (a single-input merge)
//! and with the bunny and teapot inside it.
//! `m/s` and `m/r` are merged over separate and over rebuild; `records`
//! and `lone` count the merged hierarchy's records and those with a single
//! child (a chain link: a box test that cannot cull more than its child's).
//! `MERGE_COST_RAYS=N` sets the rays per scene (default 20000).

use std::path::Path;

use glam::{DVec3, Vec3};
use golden::build::{build, GridMap};
use golden::geom::Ray;
use golden::merge::MergeMode;
use golden::mesh::Mesh;
use golden::scene::Scene;
use golden::scenes::{architecture, shared_mesh_path};
use golden::trace::{closest_hit, random_rays, Instance, TraceScene, TraceStats};
use golden::world::World;
use golden::Params;

#[path = "support/fitted.rs"]
mod fitted;
use fitted::fitted;

fn per_ray(scene: &TraceScene, rays: &[Ray]) -> f64 {
    let mut s = TraceStats::default();
    for r in rays {
        closest_hit(r, scene, &mut s);
    }
    s.node_tests as f64 / rays.len() as f64
}

struct Part {
    name: String,
    mesh: Mesh,
    offset: DVec3,
}

fn scene_parts(file: &str) -> (Params, GridMap, Vec<Part>, Vec<Vec<u8>>) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenes")
        .join(file);
    let s = Scene::load(&path).expect("a shipped scene");
    let parts = s
        .objects
        .iter()
        .map(|o| Part {
            name: o.name.clone(),
            mesh: (*o.mesh).clone(),
            offset: o.offsets[0],
        })
        .collect();
    (s.params, s.grid, parts, s.groups)
}

fn generated() -> Vec<(String, Params, GridMap, Vec<Part>)> {
    let p = Params::new(16, 8, 24, 4).expect("params");
    let grid = GridMap {
        origin: DVec3::ZERO,
        unit: 1.0 / 2048.0,
    };
    let bunny = Mesh::load(&shared_mesh_path("bunny.obj")).expect("bunny.obj");
    let teapot = Mesh::load(&shared_mesh_path("teapot.obj")).expect("teapot.obj");
    let part = |name: &str, mesh: Mesh, offset: DVec3| Part {
        name: name.into(),
        mesh,
        offset,
    };
    let house = || architecture(3, 4);
    let b = || fitted(&bunny, 1.5, Vec3::ZERO);
    let t = || fitted(&teapot, 1.5, Vec3::ZERO);
    vec![
        (
            "bunny beside teapot".into(),
            p,
            grid,
            vec![
                part("bunny", b(), DVec3::new(4.1, 4.2, 4.3)),
                part("teapot", t(), DVec3::new(6.37, 4.2, 4.3)),
            ],
        ),
        (
            "building alone".into(),
            p,
            grid,
            vec![part("building", house(), DVec3::new(0.5, 0.5, 0.5))],
        ),
        (
            "building, bunny and teapot".into(),
            p,
            grid,
            vec![
                part("building", house(), DVec3::new(0.5, 0.5, 0.5)),
                part("bunny", b(), DVec3::new(2.6, 0.7, 6.6)),
                part("teapot", t(), DVec3::new(10.6, 3.7, 10.6)),
            ],
        ),
    ]
}

fn main() {
    let rays_n: usize = std::env::var("MERGE_COST_RAYS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20_000);
    let mut scenes = Vec::new();
    // Per scene, its merge groups when it names several (paragraph 67).
    let mut grouped = std::collections::BTreeMap::new();
    for file in ["default.json", "bunny_teapot.json", "groups.json"] {
        let (p, g, parts, groups) = scene_parts(file);
        let name = format!("scenes/{file}");
        if groups.len() > 1 {
            grouped.insert(name.clone(), groups);
        }
        scenes.push((name, p, g, parts));
    }
    scenes.extend(generated());
    let modes = [
        MergeMode::default(),
        MergeMode::Proportion { num: 1, den: 2 },
        MergeMode::PerNode { num: 1, den: 2 },
    ];
    println!(
        "{:<28} {:<16} {:>8} {:>8} {:>8} {:>6} {:>6} | {:>7} {:>5}",
        "scene", "mode", "merged", "separate", "rebuild", "m/s", "m/r", "records", "lone"
    );
    println!("{:<45} node tests per ray, the same rays", "");
    for (name, p, grid, parts) in &scenes {
        let mut w = World::new(*p, *grid).expect("world");
        let ids: Vec<u8> = (0..parts.len() as u8).collect();
        for (&id, part) in ids.iter().zip(parts) {
            w.add(id, part.mesh.clone(), part.offset)
                .unwrap_or_else(|e| panic!("{name}: {}: {e}", part.name));
        }
        let si = w.separate_instances(&ids).expect("instances");
        let ss = w.trace_scene(&si, &ids).expect("separate scene");
        let (lo, hi) = ss.bounds();
        let rays = random_rays(lo, hi, rays_n, 7);
        let separate = per_ray(&ss, &rays);
        let placed = w.placed_mesh(&ids).expect("placed");
        let full = build(&placed, grid, p, 0).expect("full rebuild");
        let rebuild = per_ray(
            &TraceScene::new(*grid, &[Instance::new(&full, &placed)]).expect("rebuild scene"),
            &rays,
        );
        let out = (p.hier_capacity() - 1) as u8;
        for mode in modes {
            w.merge(&ids, mode, out).expect("merge");
            let mi = w.merged_instances(out, &ids).expect("instances");
            let merged = per_ray(&w.trace_scene(&mi, &[out]).expect("merged scene"), &rays);
            let h = w.store.get(out).expect("merged");
            let lone = h.nodes.iter().filter(|n| !n.leaf && n.count == 1).count();
            println!(
                "{:<28} {:<16} {:>8.2} {:>8.2} {:>8.2} {:>6.3} {:>6.3} | {:>7} {:>5}",
                name,
                mode.to_string(),
                merged,
                separate,
                rebuild,
                merged / separate,
                merged / rebuild,
                h.nodes.len(),
                lone
            );
        }
        if let Some(groups) = grouped.get(name) {
            // The scene's own groups, each merged in the default mode, traced together.
            let outs: Vec<u8> = (0..groups.len()).map(|g| out - g as u8).collect();
            for (g, members) in groups.iter().enumerate() {
                w.merge(members, MergeMode::default(), outs[g])
                    .expect("group merge");
            }
            let gi = w.group_instances(&outs, &ids).expect("instances");
            let merged = per_ray(&w.trace_scene(&gi, &outs).expect("groups scene"), &rays);
            let records: usize = outs
                .iter()
                .map(|&o| w.store.get(o).expect("merged").nodes.len())
                .sum();
            println!(
                "{:<28} {:<16} {:>8.2} {:>8.2} {:>8.2} {:>6.3} {:>6.3} | {:>7} {:>5}",
                name,
                format!("{} groups", groups.len()),
                merged,
                separate,
                rebuild,
                merged / separate,
                merged / rebuild,
                records,
                "-"
            );
        }
    }
}
