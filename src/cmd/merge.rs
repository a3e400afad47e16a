//! `hiermerge merge MESH...`: build one hierarchy per mesh, place each by its
//! translation, merge them, check the result, and compare tracing through the
//! merged hierarchy with the separate ones and with a full rebuild.

use std::path::PathBuf;
use std::time::Instant;

use glam::DVec3;
use golden::build::build;
use golden::merge::MergeMode;
use golden::trace::{
    brute_force_closest, closest_hit, random_rays, Instance, TraceScene, TraceStats,
};
use golden::world::World;
use serde::Serialize;

use super::common::{load_mesh, placement_grid, GridOpts, Shape};
pub use super::merge_args::{parse_mode, parse_vec3};
use crate::report::{emit, CmdResult};

#[derive(clap::Args)]
pub struct Args {
    /// Mesh files (OBJ or PLY), each in its own local frame.
    #[arg(required = true)]
    meshes: Vec<PathBuf>,
    /// Placement of each mesh in turn, world units `x,y,z` (one per mesh; missing ones are 0,0,0).
    #[arg(long = "translate", value_parser = parse_vec3, allow_hyphen_values = true)]
    translate: Vec<DVec3>,
    /// Merging level mode: overlap[:N/D] (default overlap:1/2), fixed:L, below-top:K, proportion:N/D, per-node[:N/D].
    #[arg(long, default_value = "overlap:1/2", value_parser = parse_mode)]
    mode: MergeMode,
    /// Rays traced through the merged, separate and rebuilt hierarchies.
    #[arg(long, default_value_t = 10_000)]
    rays: usize,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Compare every closest hit through the merged hierarchy with brute force over all placed triangles.
    #[arg(long)]
    verify: bool,
    #[command(flatten)]
    grid: GridOpts,
    /// Print one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct Report {
    params: golden::Params,
    mode: MergeMode,
    inputs: Vec<InputReport>,
    merging_level: Option<u8>,
    /// Records of the merged hierarchy per LOD, (lod, count), top first.
    nodes_per_level: Vec<(u8, u64)>,
    nodes_created: u64,
    nodes_reused: u64,
    merge_seconds: f64,
    rebuild_seconds: f64,
    checker: String,
    rays: u64,
    hits: u64,
    node_tests_per_ray: PerRay,
    #[serde(skip_serializing_if = "Option::is_none")]
    mismatches: Option<u64>,
}

#[derive(Serialize)]
struct InputReport {
    file: String,
    id: u8,
    triangles: u64,
    /// Translation (L, t) determined from the placement.
    lod: u8,
    t: [i64; 3],
    /// What the voxel grid could not express: requested minus applied, world units.
    residual: [f64; 3],
    #[serde(flatten)]
    shape: Shape,
}

#[derive(Serialize)]
struct PerRay {
    merged: f64,
    separate: f64,
    rebuild: f64,
}

pub fn main(a: Args) -> CmdResult {
    let params = a.grid.params()?;
    if a.translate.len() > a.meshes.len() {
        return Err(format!(
            "{} --translate values for {} meshes",
            a.translate.len(),
            a.meshes.len()
        ));
    }
    if a.meshes.len() as u64 + 1 > params.hier_capacity() {
        return Err(format!(
            "{} meshes and the merged hierarchy need more than --hier-bits {}",
            a.meshes.len(),
            params.hier_bits
        ));
    }
    golden::trace::check_ray_count(a.rays)?;
    let meshes = a
        .meshes
        .iter()
        .map(|p| load_mesh(p))
        .collect::<Result<Vec<_>, _>>()?;
    let offsets: Vec<DVec3> = (0..meshes.len())
        .map(|i| a.translate.get(i).copied().unwrap_or(DVec3::ZERO))
        .collect();

    let grid = placement_grid(&meshes, &offsets, &params)?;
    let mut world = World::new(params, grid).map_err(|e| e.to_string())?;
    let mut inputs = Vec::new();
    for (i, ((mesh, off), path)) in meshes.into_iter().zip(&offsets).zip(&a.meshes).enumerate() {
        let id = i as u8;
        let o = world
            .add(id, mesh, *off)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        let t = o.determined.translation;
        let triangles = o.mesh.triangles.len() as u64;
        let residual =
            golden::translate::Axis::ALL.map(|ax| o.determined.residual.value_f64(ax) * grid.unit);
        inputs.push(InputReport {
            file: path.display().to_string(),
            id,
            triangles,
            lod: t.lod,
            t: t.t,
            residual,
            shape: Shape::of(world.store.get(id).expect("just added")),
        });
    }
    let ids: Vec<u8> = (0..inputs.len() as u8).collect();
    let out = (params.hier_capacity() - 1) as u8;
    let start = Instant::now();
    let merged = world.merge(&ids, a.mode, out).map_err(|e| e.to_string())?;
    let merge_seconds = start.elapsed().as_secs_f64();
    let check = world.check(out).map_err(|e| e.to_string())?;

    // The full rebuild: every placed triangle in one hierarchy.
    let placed = world.placed_mesh(&ids).map_err(|e| e.to_string())?;
    let start = Instant::now();
    let rebuilt = build(&placed, &grid, &params, 0).map_err(|e| format!("full rebuild: {e}"))?;
    let rebuild_seconds = start.elapsed().as_secs_f64();

    let mi = world
        .merged_instances(out, &ids)
        .map_err(|e| e.to_string())?;
    let si = world.separate_instances(&ids).map_err(|e| e.to_string())?;
    let ms = world.trace_scene(&mi, &[out]).map_err(|e| e.to_string())?;
    let ss = world.trace_scene(&si, &ids).map_err(|e| e.to_string())?;
    let rs =
        TraceScene::new(grid, &[Instance::new(&rebuilt, &placed)]).map_err(|e| e.to_string())?;
    let (blo, bhi) = ss.bounds();
    golden::trace::check_ray_bounds(blo, bhi)?;
    let rays = random_rays(blo, bhi, a.rays, a.seed);
    let (mut m_stats, mut s_stats, mut r_stats) = (
        TraceStats::default(),
        TraceStats::default(),
        TraceStats::default(),
    );
    let mut hits = 0u64;
    let mut mismatches = 0u64;
    for ray in &rays {
        let hit = closest_hit(ray, &ms, &mut m_stats);
        closest_hit(ray, &ss, &mut s_stats);
        closest_hit(ray, &rs, &mut r_stats);
        hits += hit.is_some() as u64;
        if a.verify {
            let brute = brute_force_closest(ray, &ss, &mut TraceStats::default());
            let same = match (&hit, &brute) {
                (None, None) => true,
                (Some(x), Some(y)) => x.identical(y),
                _ => false,
            };
            mismatches += !same as u64;
        }
    }
    let n = rays.len().max(1) as f64;
    let report = Report {
        params,
        mode: a.mode,
        inputs,
        merging_level: merged.level,
        nodes_per_level: merged.stats.nodes_per_level.clone(),
        nodes_created: merged.stats.created(),
        nodes_reused: merged.stats.reused(),
        merge_seconds,
        rebuild_seconds,
        checker: format!(
            "ok: {} nodes, {} leaves, {} primitives reached",
            check.nodes, check.leaves, check.prims_reached
        ),
        rays: rays.len() as u64,
        hits,
        node_tests_per_ray: PerRay {
            merged: m_stats.node_tests as f64 / n,
            separate: s_stats.node_tests as f64 / n,
            rebuild: r_stats.node_tests as f64 / n,
        },
        mismatches: a.verify.then_some(mismatches),
    };
    emit(a.json, &report, |r| {
        for i in &r.inputs {
            println!(
                "input {} {}: {} triangles, {} nodes, top LOD {}, translation L={} t={:?}",
                i.id, i.file, i.triangles, i.shape.nodes, i.shape.top_lod, i.lod, i.t
            );
        }
        println!("mode {:?}: merging level {:?}", r.mode, r.merging_level);
        let per: Vec<String> = r
            .nodes_per_level
            .iter()
            .map(|(l, c)| format!("{l}:{c}"))
            .collect();
        println!("merged nodes per level: {}", per.join(" "));
        println!(
            "nodes created {}, input nodes reused {}",
            r.nodes_created, r.nodes_reused
        );
        println!(
            "merge {:.3} ms vs full rebuild {:.3} ms",
            r.merge_seconds * 1e3,
            r.rebuild_seconds * 1e3
        );
        println!("checker: {}", r.checker);
        println!(
            "{} rays, {} hits; node tests per ray: merged {:.1}, separate {:.1}, full rebuild {:.1}",
            r.rays, r.hits, r.node_tests_per_ray.merged, r.node_tests_per_ray.separate, r.node_tests_per_ray.rebuild
        );
        if let Some(m) = r.mismatches {
            println!("verify: {m} mismatches against brute force");
        }
    })?;
    if mismatches > 0 {
        return Err(format!("{mismatches} rays disagree with brute force"));
    }
    Ok(())
}
