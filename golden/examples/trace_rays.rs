//! Traces rays through a hierarchy and reads the counts: closest hits with
//! a reusable context, and shadow rays with the any-hit `occluded` query.
//!
//! `cargo run -p golden --example trace_rays`

use std::error::Error;
use std::fmt::Write as _;

use glam::Vec3;
use golden::build::{build, GridMap};
use golden::geom::Ray;
use golden::scenes::terrain;
use golden::trace::{Instance, TraceContext, TraceScene, TraceStats};
use golden::Params;

/// The example's work; returns what it prints.
pub fn run() -> Result<String, Box<dyn Error>> {
    let mesh = terrain(128, 3);
    let params = Params::default();
    let (lo, hi) = mesh.bounds();
    let grid = GridMap::fit(lo, hi, &params);
    let hierarchy = build(&mesh, &grid, &params, 0)?;
    let scene = TraceScene::new(grid, &[Instance::new(&hierarchy, &mesh)])?;

    // One context for every ray: no allocation per ray once it has grown.
    let mut ctx = TraceContext::new();
    let (mut primary, mut shadow) = (TraceStats::default(), TraceStats::default());
    // Low over the terrain, so hills cast shadows.
    let light = Vec3::new(-0.5, 0.62, 0.5);
    let (n, mut hits, mut shadowed) = (64u32, 0, 0);
    for i in 0..n {
        for j in 0..n {
            // A grid of rays looking down onto the terrain.
            let target = Vec3::new(
                (i as f32 + 0.5) / n as f32,
                0.0,
                (j as f32 + 0.5) / n as f32,
            );
            let origin = Vec3::new(0.5, 2.0, -1.0);
            let ray = Ray::unbounded(origin, target - origin);
            let Some(hit) = ctx.closest_hit(&ray, &scene, &mut primary) else {
                continue;
            };
            hits += 1;
            // From just above the hit towards the light; t in [0, 1] ends at it.
            let p = ray.at(hit.t) + Vec3::Y * 1e-4;
            let to_light = Ray::new(p, light - p, 0.0, 1.0);
            shadowed += ctx.occluded(&to_light, &scene, &mut shadow) as u32;
        }
    }
    let rays = (n * n) as f64;
    let mut out = String::new();
    writeln!(
        out,
        "{} triangles, {} nodes",
        mesh.len(),
        hierarchy.nodes.len()
    )?;
    writeln!(
        out,
        "{} primary rays: {hits} hits, {:.2} node tests and {:.2} triangle tests per ray",
        n * n,
        primary.node_tests as f64 / rays,
        primary.prim_tests as f64 / rays
    )?;
    writeln!(
        out,
        "{hits} shadow rays: {shadowed} shadowed, {:.2} node tests per ray",
        shadow.node_tests as f64 / hits.max(1) as f64
    )?;
    Ok(out)
}

fn main() -> Result<(), Box<dyn Error>> {
    print!("{}", run()?);
    Ok(())
}
