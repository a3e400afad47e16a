//! Node tests per ray through the merged hierarchy against the separate
//! hierarchies and a full rebuild of the placed scene, on a subsample of the
//! primary rays (every [`SUBSAMPLE`]-th pixel on both axes) to keep it cheap.
//! The merged and separate hierarchies must give identical closest hits;
//! with `--verify` the merged hits are also judged by the binary64 oracle
//! over the triangles at their requested positions (SPEC 6.10).

use golden::build::build;
use golden::oracle::{Oracle, OracleSummary};
use golden::scene::Scene;
use golden::trace::{closest_hit, Instance, TraceScene, TraceStats};
use golden::world::World;
use indicatif::ProgressBar;

use super::render::clipped;

/// One pixel in `SUBSAMPLE` on each axis.
pub const SUBSAMPLE: u32 = 4;

/// Node tests per primary ray of the subsample, three ways.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Comparison {
    pub rays: u64,
    pub merged: f64,
    pub separate: f64,
    pub full_rebuild: f64,
    /// Rays whose closest hit differs between merged and separate.
    pub hit_mismatches: u64,
    pub full_rebuild_nodes: u64,
    pub seconds: f64,
    /// With `--verify`: the merged hits judged by the oracle.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub oracle: Option<OracleSummary>,
}

impl Comparison {
    /// Rays that fail: merged and separate differ, or the oracle finds a fault.
    pub fn faults(&self) -> u64 {
        self.hit_mismatches + self.oracle.as_ref().map_or(0, OracleSummary::faults)
    }
}

/// Traces the subsample through `merged`, the separate hierarchies of
/// `ids` and a fresh build of their placed triangles.
pub fn compare(
    scene: &Scene,
    world: &World,
    ids: &[u8],
    merged: &TraceScene,
    verify: bool,
    bar: &ProgressBar,
) -> Result<Comparison, String> {
    let start = std::time::Instant::now();
    let oracle = if verify {
        let parts = world.oracle_parts(ids).map_err(|e| e.to_string())?;
        Some(Oracle::new(&parts).map_err(|e| e.to_string())?)
    } else {
        None
    };
    let mut summary = OracleSummary::default();
    let separate_instances = world.separate_instances(ids).map_err(|e| e.to_string())?;
    let separate = world
        .trace_scene(&separate_instances, ids)
        .map_err(|e| e.to_string())?;
    let placed = world.placed_mesh(ids).map_err(|e| e.to_string())?;
    let rebuilt = build(&placed, &world.grid, &world.params, 0).map_err(|e| e.to_string())?;
    let full_instances = [Instance::new(&rebuilt, &placed)];
    let full = TraceScene::new(world.grid, &full_instances).map_err(|e| e.to_string())?;
    let (w, h) = (scene.width, scene.height);
    let mut c = Comparison {
        full_rebuild_nodes: rebuilt.nodes.len() as u64,
        ..Comparison::default()
    };
    let (mut m, mut s, mut f) = (
        TraceStats::default(),
        TraceStats::default(),
        TraceStats::default(),
    );
    bar.set_length(h.div_ceil(SUBSAMPLE) as u64);
    for py in (0..h).step_by(SUBSAMPLE as usize) {
        for px in (0..w).step_by(SUBSAMPLE as usize) {
            let ray = clipped(scene.camera.primary_ray(px, py, w, h), scene);
            let a = closest_hit(&ray, merged, &mut m);
            let b = closest_hit(&ray, &separate, &mut s);
            closest_hit(&ray, &full, &mut f);
            let same = match (a, b) {
                (None, None) => true,
                (Some(a), Some(b)) => a.identical(&b),
                _ => false,
            };
            c.hit_mismatches += !same as u64;
            if let Some(o) = &oracle {
                o.count(&mut summary, &ray, a.as_ref());
            }
            c.rays += 1;
        }
        bar.inc(1);
    }
    let per = |s: TraceStats| s.node_tests as f64 / c.rays.max(1) as f64;
    c.merged = per(m);
    c.separate = per(s);
    c.full_rebuild = per(f);
    c.seconds = start.elapsed().as_secs_f64();
    c.oracle = oracle.map(|_| summary);
    Ok(c)
}
