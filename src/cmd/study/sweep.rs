//! The Q x D sweep of one case (SPEC 13.2, 13.4): build, looseness, false
//! box hits, node and primitive tests per ray, sizes, software times.

use std::time::Instant;

use glam::DVec3;
use golden::build::{build, GridMap};
use golden::geom::ray::Ray;
use golden::layout::{NodeLayout, RefLayout};
use golden::merge::MergeMode;
use golden::oracle::reference::{RefHit, ReferenceTracer};
use golden::store::Hierarchy;
use golden::study::looseness::{exact_boxes, looseness, nesting, Looseness, Nesting};
use golden::study::walk::{stored_boxes, walk_ray, WalkCounts};
use golden::trace::{closest_hit, random_rays, Instance, TraceScene, TraceStats};
use golden::Params;
use serde::Serialize;

use super::inputs::Case;
use super::merge::merge_pair;
use super::rtl::RtlFigures;
use super::synth::SynthFigures;

/// A case's rays and the reference's closest hits, shared by every configuration.
pub struct Prepared {
    pub rays: Vec<Ray>,
    pub reference: Vec<Option<RefHit>>,
}

impl Prepared {
    pub fn new(case: &Case, n: usize, seed: u64) -> Prepared {
        let (lo, hi) = case.mesh.bounds();
        let rays = random_rays(lo, hi, n, seed);
        let tris = (0..case.mesh.triangles.len())
            .map(|i| case.mesh.triangle_f64(i))
            .collect();
        let tracer = ReferenceTracer::new(tris);
        let reference = rays
            .iter()
            .map(|r| {
                tracer.closest(
                    r.origin.as_dvec3(),
                    r.dir.as_dvec3(),
                    r.tmin as f64,
                    r.tmax as f64,
                )
            })
            .collect();
        Prepared { rays, reference }
    }
}

/// One row of the study: a case at one configuration.
#[derive(Serialize, Clone, Debug)]
pub struct Row {
    pub case: String,
    pub max_lod: u8,
    pub quant_bits: u8,
    pub default_config: bool,
    pub triangles: u64,
    pub nodes: u64,
    pub leaves: u64,
    pub record_bits: u32,
    /// The same record with six binary32 bounds in place of the 6Q bits.
    pub record_bits_f32_boxes: u32,
    pub ref_bits: u32,
    pub bytes: u64,
    pub bytes_per_triangle: f64,
    pub looseness: Looseness,
    /// Against the row of the next smaller Q of the sweep at the same D.
    pub nesting: Option<Nesting>,
    pub node_tests_per_ray: f64,
    pub prim_tests_per_ray: f64,
    pub false_hits_per_ray: f64,
    /// Box tests of the study walk with stored boxes over those with exact boxes, minus 1.
    pub extra_box_tests_vs_exact: f64,
    pub build_ms: f64,
    pub trace_us_per_ray: f64,
    pub merge_ms: f64,
    pub merging_level: Option<u8>,
    pub rtl: Option<RtlFigures>,
    pub synth: Option<SynthFigures>,
    /// RTL cycles per merge / Fmax, when both are measured.
    pub ns_per_merge: Option<f64>,
}

/// Median of the times of `repeats` runs of `f` (seconds), and its last result.
pub fn median_time<T>(repeats: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut times = Vec::with_capacity(repeats.max(1));
    let mut last = None;
    for _ in 0..repeats.max(1) {
        let start = Instant::now();
        last = Some(f());
        times.push(start.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    let n = times.len();
    let median = if n % 2 == 1 {
        times[n / 2]
    } else {
        (times[n / 2 - 1] + times[n / 2]) / 2.0
    };
    (median, last.expect("at least one run"))
}

/// Measures `case` at `params`; `coarser`: the case's hierarchy at the same
/// D and a smaller Q, to check nesting against. Returns the hierarchy too.
pub fn measure(
    case: &Case,
    prep: &Prepared,
    params: Params,
    repeats: usize,
    mode: MergeMode,
    coarser: Option<&Hierarchy>,
) -> Result<(Row, Hierarchy), String> {
    let (lo, hi) = case.mesh.bounds();
    let grid = GridMap::fit(lo, hi, &params);
    let (build_s, h) = median_time(repeats, || build(&case.mesh, &grid, &params, 0));
    let h = h.map_err(|e| format!("{}: build at {}: {e}", case.source, params.tag()))?;
    let tris = grid
        .mesh_to_grid(&case.mesh, &params)
        .map_err(|e| format!("{}: {e}", case.source))?;
    let exact = exact_boxes(&h, &tris);
    let loose = looseness(&h, &exact);

    let scene = TraceScene::new(grid, &[Instance::new(&h, &case.mesh)])
        .map_err(|e| format!("{}: {e}", case.source))?;
    let mut stats = TraceStats::default();
    for r in &prep.rays {
        closest_hit(r, &scene, &mut stats);
    }
    let (trace_s, _) = median_time(repeats, || {
        let mut s = TraceStats::default();
        prep.rays
            .iter()
            .filter(|r| closest_hit(r, &scene, &mut s).is_some())
            .count()
    });
    let stored = stored_boxes(&h);
    let mut walk = WalkCounts::default();
    for (r, hit) in prep.rays.iter().zip(&prep.reference) {
        let (org, dir) = grid_ray(&grid, r);
        let t_end = hit.map_or(r.tmax as f64, |h| h.t);
        walk.add(&walk_ray(&h, &stored, &exact, org, dir, t_end));
    }
    let (merge_s, level) = merge_pair(&case.mesh, params, mode, repeats)
        .map_err(|e| format!("{}: merge at {}: {e}", case.source, params.tag()))?;

    let node_bits = NodeLayout::new(&params).width();
    let ref_bits = RefLayout::new(&params).width();
    let bits = h.nodes.len() as u64 * node_bits as u64
        + h.refs.len() as u64 * ref_bits as u64
        + h.prims.len() as u64 * params.index_bits as u64;
    let bytes = bits.div_ceil(8);
    let n = prep.rays.len().max(1) as f64;
    let triangles = case.mesh.triangles.len() as u64;
    let row = Row {
        case: case.name.clone(),
        max_lod: params.max_lod,
        quant_bits: params.quant_bits,
        default_config: params == Params::default(),
        triangles,
        nodes: h.nodes.len() as u64,
        leaves: h.nodes.iter().filter(|n| n.leaf).count() as u64,
        record_bits: node_bits,
        record_bits_f32_boxes: node_bits - 6 * params.quant_bits as u32 + 6 * 32,
        ref_bits,
        bytes,
        bytes_per_triangle: bytes as f64 / triangles.max(1) as f64,
        looseness: loose,
        nesting: coarser.map(|c| nesting(&h, c)),
        node_tests_per_ray: stats.node_tests as f64 / n,
        prim_tests_per_ray: stats.prim_tests as f64 / n,
        false_hits_per_ray: walk.false_hits as f64 / n,
        extra_box_tests_vs_exact: walk.tests as f64 / walk.exact_tests.max(1) as f64 - 1.0,
        build_ms: build_s * 1e3,
        trace_us_per_ray: trace_s * 1e6 / n,
        merge_ms: merge_s * 1e3,
        merging_level: level,
        rtl: None,
        synth: None,
        ns_per_merge: None,
    };
    Ok((row, h))
}

/// A world ray in grid units (the map is affine, so `t` is the same).
pub fn grid_ray(grid: &GridMap, r: &Ray) -> (DVec3, DVec3) {
    (
        (r.origin.as_dvec3() - grid.origin) / grid.unit,
        r.dir.as_dvec3() / grid.unit,
    )
}
