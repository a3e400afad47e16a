//! `hiermerge trace MESH`: random rays through a mesh's hierarchy; `--verify`
//! compares every closest hit with brute force over all triangles, bit for
//! bit, and judges it by the independent binary64 oracle (SPEC 6.10).

use std::path::PathBuf;

use golden::oracle::{Oracle, OracleSummary, Part};
use golden::trace::{
    bench_trace, verify_ray_list, verify_ray_set, Instance, TraceContext, TraceScene, TraceStats,
};
use serde::Serialize;

use super::common::{build_fitted, load_mesh, Built, GridOpts};
use crate::report::{emit, CmdResult};

#[derive(clap::Args)]
pub struct Args {
    /// Mesh file (OBJ or PLY).
    mesh: PathBuf,
    /// Number of random rays.
    #[arg(long, default_value_t = 100_000, value_parser = super::common::unsigned::<usize>)]
    rays: usize,
    /// Seed of the ray generator.
    #[arg(long, default_value_t = 1, value_parser = super::common::unsigned::<u64>)]
    seed: u64,
    /// Also trace every ray by brute force and count the rays whose closest
    /// hit differs in any bit, and judge every hit by the binary64 oracle
    /// (SPEC 6.10); half the rays aim at edges and vertices.
    #[arg(long)]
    verify: bool,
    /// Trace the hierarchy saved in FILE (`hiermerge build --save`, SPEC
    /// section 16) instead of building one: its parameters and grid map come
    /// from the file, which must have been saved over MESH; it is checked
    /// (SPEC section 5) before any ray.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["max_lod", "quant_bits", "index_bits", "hier_bits"])]
    load: Option<PathBuf>,
    #[command(flatten)]
    grid: GridOpts,
    /// Print one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct Report {
    file: String,
    triangles: u64,
    params: golden::Params,
    rays: u64,
    seed: u64,
    hits: u64,
    node_tests_per_ray: f64,
    prim_tests_per_ray: f64,
    rays_per_second: f64,
    /// Present with --load: the saved hierarchy's file.
    #[serde(skip_serializing_if = "Option::is_none")]
    loaded: Option<String>,
    /// Present with --verify: rays whose hit differs from brute force.
    #[serde(skip_serializing_if = "Option::is_none")]
    mismatches: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    first_mismatch: Option<String>,
    /// Present with --verify: the hits judged by the binary64 oracle.
    #[serde(skip_serializing_if = "Option::is_none")]
    oracle: Option<OracleSummary>,
}

pub fn main(a: Args) -> CmdResult {
    golden::trace::check_ray_count(a.rays)?;
    let mesh = load_mesh(&a.mesh)?;
    let b = match &a.load {
        Some(file) => {
            let s = golden::saved::load(file, &mesh).map_err(|e| e.to_string())?;
            Built {
                mesh,
                grid: s.grid,
                hierarchy: s.hierarchy,
                seconds: 0.0,
            }
        }
        None => build_fitted(a.mesh.clone(), mesh, &a.grid.params()?, 0)?,
    };
    let params = b.hierarchy.params;
    let scene = TraceScene::new(b.grid, &[Instance::new(&b.hierarchy, &b.mesh)])
        .map_err(|e| e.to_string())?;
    let (lo, hi) = scene.bounds();
    golden::trace::check_ray_bounds(lo, hi).map_err(|e| format!("{}: {e}", a.mesh.display()))?;
    let speed = bench_trace(&scene, a.rays, a.seed);
    let mut report = Report {
        file: a.mesh.display().to_string(),
        triangles: b.mesh.triangles.len() as u64,
        params,
        rays: speed.rays,
        seed: a.seed,
        hits: speed.hits,
        node_tests_per_ray: speed.node_tests_per_ray,
        prim_tests_per_ray: speed.prim_tests_per_ray,
        rays_per_second: speed.rays_per_second,
        loaded: a.load.as_ref().map(|f| f.display().to_string()),
        mismatches: None,
        first_mismatch: None,
        oracle: None,
    };
    if a.verify {
        let rays = verify_ray_set(&scene, a.rays, a.seed);
        let v = verify_ray_list(&scene, &rays);
        let part = Part {
            hier: 0,
            source: &b.mesh,
            offset: glam::DVec3::ZERO,
            traced: &b.mesh,
            shift: glam::DVec3::ZERO,
        };
        let oracle = Oracle::new(&[part]).map_err(|e| e.to_string())?;
        let mut summary = OracleSummary::default();
        let mut ctx = TraceContext::new();
        for ray in &rays {
            let hit = ctx.closest_hit(ray, &scene, &mut TraceStats::default());
            oracle.count(&mut summary, ray, hit.as_ref());
        }
        report.oracle = Some(summary);
        report.rays = v.rays;
        report.hits = v.hits;
        report.node_tests_per_ray = v.node_tests_per_ray;
        report.prim_tests_per_ray = v.prim_tests_per_ray;
        report.mismatches = Some(v.mismatches);
        report.first_mismatch = v.first_mismatch;
    }
    emit(a.json, &report, |r| {
        if let Some(f) = &r.loaded {
            println!("hierarchy loaded from {f} (checked)");
        }
        println!(
            "{}: {} triangles, {} rays (seed {}), {} hits, {:.1} node tests/ray, {:.1} triangle tests/ray, {:.0} rays/s",
            r.file, r.triangles, r.rays, r.seed, r.hits, r.node_tests_per_ray, r.prim_tests_per_ray, r.rays_per_second
        );
        if let Some(m) = r.mismatches {
            println!("verify: {m} mismatches against brute force");
            if let Some(f) = &r.first_mismatch {
                println!("first mismatch: {f}");
            }
        }
        if let Some(o) = &r.oracle {
            println!("{o}");
        }
    })?;
    if let Some(m) = report.mismatches.filter(|&m| m > 0) {
        return Err(format!("{m} rays disagree with brute force"));
    }
    match &report.oracle {
        Some(o) if o.faults() > 0 => Err(format!(
            "{} rays disagree with the binary64 oracle; first: {}",
            o.faults(),
            o.first_fault.as_deref().unwrap_or("-")
        )),
        _ => Ok(()),
    }
}
