//! `hiermerge merge MESH...`: build one hierarchy per mesh, place each by its
//! translation, merge them, check the result, and compare tracing through the
//! merged hierarchy with the separate ones and with a full rebuild.

use std::path::PathBuf;
use std::time::Instant;

use glam::DVec3;
use golden::build::build;
use golden::merge::MergeMode;
use golden::oracle::{Oracle, OracleSummary};
use golden::trace::{
    brute_force_closest, closest_hit, edge_rays, random_rays, Instance, TraceScene, TraceStats,
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
    /// A subset of the meshes (0-based indices in command-line order, `0,1`) merged into its
    /// own hierarchy (paragraph 67); the merged hierarchies are traced together. Repeat it;
    /// every mesh in exactly one group. Without it, one group of all meshes.
    #[arg(long = "group", value_parser = parse_group)]
    groups: Vec<Vec<u8>>,
    /// Rays traced through the merged, separate and rebuilt hierarchies.
    #[arg(long, default_value_t = 10_000, value_parser = super::common::unsigned::<usize>)]
    rays: usize,
    #[arg(long, default_value_t = 1, value_parser = super::common::unsigned::<u64>)]
    seed: u64,
    /// Check every closest hit through the merged hierarchy: against brute force over the same
    /// triangles (bit for bit), and against the independent binary64 oracle over the triangles
    /// at their requested positions (SPEC 6.10); half as many rays again aim at edges and vertices.
    #[arg(long)]
    verify: bool,
    #[command(flatten)]
    grid: GridOpts,
    /// Print one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

fn parse_group(s: &str) -> Result<Vec<u8>, String> {
    s.split(',')
        .map(|p| {
            p.trim().parse::<u8>().map_err(|e| {
                format!("`{s}`: `{p}`: {e}; expected mesh indices 0, 1, ... separated by commas")
            })
        })
        .collect()
}

#[derive(Serialize)]
struct Report {
    params: golden::Params,
    mode: MergeMode,
    inputs: Vec<InputReport>,
    /// One merged hierarchy per group (one group of every input without `--group`).
    groups: Vec<GroupReport>,
    /// The first group's merging level.
    merging_level: Option<u8>,
    /// Records of the merged hierarchies per LOD, (lod, count), top first, summed over groups.
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
    /// With --verify: the merged hierarchy's hits judged by the binary64 oracle.
    #[serde(skip_serializing_if = "Option::is_none")]
    oracle: Option<OracleSummary>,
}

#[derive(Serialize)]
struct InputReport {
    file: String,
    id: u8,
    triangles: u64,
    /// Translation (L, t) determined from the placement.
    lod: u8,
    t: [i64; 3],
    /// What the voxel grid could not express, requested minus the translation, world units:
    /// carried by the input's local geometry (SPEC 7.10).
    residual: [f64; 3],
    #[serde(flatten)]
    shape: Shape,
}

#[derive(Serialize)]
struct GroupReport {
    /// The merged hierarchy's id.
    id: u8,
    /// Its inputs' ids (= mesh indices).
    inputs: Vec<u8>,
    merging_level: Option<u8>,
    nodes_created: u64,
    nodes_reused: u64,
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
    let groups = groups_of(&a.groups, a.meshes.len())?;
    if (a.meshes.len() + groups.len()) as u64 > params.hier_capacity() {
        return Err(format!(
            "{} meshes and {} merged hierarchies need more than --hier-bits {}",
            a.meshes.len(),
            groups.len(),
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
    // Merged ids from the top: 2^H - 1, 2^H - 2, ...
    let outs: Vec<u8> = (0..groups.len())
        .map(|g| (params.hier_capacity() - 1 - g as u64) as u8)
        .collect();
    let start = Instant::now();
    let mut merges = Vec::new();
    for (g, &out) in groups.iter().zip(&outs) {
        let r = world
            .merge(g, a.mode, out)
            .map_err(|e| format!("group {g:?}: {e}"))?;
        merges.push(r);
    }
    let merge_seconds = start.elapsed().as_secs_f64();
    let mut check = golden::check::CheckReport::default();
    for (g, &out) in groups.iter().zip(&outs) {
        let c = world.check(out).map_err(|e| format!("group {g:?}: {e}"))?;
        check.nodes += c.nodes;
        check.leaves += c.leaves;
        check.prims_reached += c.prims_reached;
    }
    let mut nodes_per_level: std::collections::BTreeMap<u8, u64> = Default::default();
    for r in &merges {
        for &(l, c) in &r.stats.nodes_per_level {
            *nodes_per_level.entry(l).or_default() += c;
        }
    }
    let group_reports: Vec<GroupReport> = groups
        .iter()
        .zip(&outs)
        .zip(&merges)
        .map(|((g, &id), r)| GroupReport {
            id,
            inputs: g.clone(),
            merging_level: r.level,
            nodes_created: r.stats.created(),
            nodes_reused: r.stats.reused(),
        })
        .collect();

    // The full rebuild: every placed triangle in one hierarchy.
    let placed = world.placed_mesh(&ids).map_err(|e| e.to_string())?;
    let start = Instant::now();
    let rebuilt = build(&placed, &grid, &params, 0).map_err(|e| format!("full rebuild: {e}"))?;
    let rebuild_seconds = start.elapsed().as_secs_f64();

    let mi = world
        .group_instances(&outs, &ids)
        .map_err(|e| e.to_string())?;
    let si = world.separate_instances(&ids).map_err(|e| e.to_string())?;
    let ms = world.trace_scene(&mi, &outs).map_err(|e| e.to_string())?;
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
    for ray in &rays {
        let hit = closest_hit(ray, &ms, &mut m_stats);
        closest_hit(ray, &ss, &mut s_stats);
        closest_hit(ray, &rs, &mut r_stats);
        hits += hit.is_some() as u64;
    }
    let (mismatches, oracle) = if a.verify {
        let (m, o) = verify(&world, &ids, &ms, &ss, &rays, a.seed)?;
        (m, Some(o))
    } else {
        (0, None)
    };
    let n = rays.len().max(1) as f64;
    let report = Report {
        params,
        mode: a.mode,
        inputs,
        merging_level: group_reports[0].merging_level,
        nodes_per_level: nodes_per_level.into_iter().rev().collect(),
        nodes_created: group_reports.iter().map(|g| g.nodes_created).sum(),
        nodes_reused: group_reports.iter().map(|g| g.nodes_reused).sum(),
        groups: group_reports,
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
        oracle,
    };
    emit(a.json, &report, |r| {
        for i in &r.inputs {
            println!(
                "input {} {}: {} triangles, {} nodes, top LOD {}, translation L={} t={:?}",
                i.id, i.file, i.triangles, i.shape.nodes, i.shape.top_lod, i.lod, i.t
            );
        }
        for g in &r.groups {
            println!(
                "mode {:?}: group {:?} merged into hierarchy {}: merging level {:?}",
                r.mode, g.inputs, g.id, g.merging_level
            );
        }
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
        if let Some(o) = &r.oracle {
            println!("{o}");
        }
    })?;
    if mismatches > 0 {
        return Err(format!("{mismatches} rays disagree with brute force"));
    }
    if let Some(o) = &report.oracle {
        if o.faults() > 0 {
            return Err(format!(
                "{} rays disagree with the binary64 oracle; first: {}",
                o.faults(),
                o.first_fault.as_deref().unwrap_or("-")
            ));
        }
    }
    Ok(())
}

/// `--verify`: the merged hierarchy's hit for every ray (the random ones and
/// as many again at edges and vertices) against brute force over the same
/// triangles, and against the oracle (SPEC 6.10).
fn verify(
    world: &World,
    ids: &[u8],
    merged: &TraceScene,
    separate: &TraceScene,
    random: &[golden::geom::Ray],
    seed: u64,
) -> Result<(u64, OracleSummary), String> {
    let parts = world.oracle_parts(ids).map_err(|e| e.to_string())?;
    let oracle = Oracle::new(&parts).map_err(|e| e.to_string())?;
    let mut rays = random.to_vec();
    rays.extend(edge_rays(separate, random.len(), seed ^ 0xED6E));
    let mut mismatches = 0;
    let mut summary = OracleSummary::default();
    for ray in &rays {
        let hit = closest_hit(ray, merged, &mut TraceStats::default());
        let brute = brute_force_closest(ray, separate, &mut TraceStats::default());
        let same = match (&hit, &brute) {
            (None, None) => true,
            (Some(x), Some(y)) => x.identical(y),
            _ => false,
        };
        mismatches += !same as u64;
        oracle.count(&mut summary, ray, hit.as_ref());
    }
    Ok((mismatches, summary))
}

/// The groups of `--group` (indices checked, every mesh in exactly one), or
/// one group of all `n` meshes.
fn groups_of(given: &[Vec<u8>], n: usize) -> Result<Vec<Vec<u8>>, String> {
    if given.is_empty() {
        return Ok(vec![(0..n as u8).collect()]);
    }
    let mut owner = vec![None; n];
    for (k, g) in given.iter().enumerate() {
        for &i in g {
            let slot = owner.get_mut(i as usize).ok_or_else(|| {
                format!("--group {g:?}: mesh {i} does not exist; expected an index below {n}")
            })?;
            if let Some(j) = slot.replace(k) {
                return Err(format!(
                    "--group: mesh {i} is in group {j} and group {k}; each mesh belongs to one group"
                ));
            }
        }
    }
    if let Some(i) = owner.iter().position(Option::is_none) {
        return Err(format!(
            "--group: mesh {i} is in no group; list every mesh in one group"
        ));
    }
    Ok(given.to_vec())
}
