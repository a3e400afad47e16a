//! Places two objects by voxel-aligned translations and merges their
//! hierarchies into one, which traces like the two side by side.
//!
//! `cargo run -p golden --example place_and_merge`

use std::error::Error;
use std::fmt::Write as _;

use glam::{DVec3, Vec3};
use golden::build::GridMap;
use golden::merge::MergeMode;
use golden::scenes::{sphere, torus};
use golden::trace::{random_rays, TraceContext, TraceStats};
use golden::world::World;
use golden::Params;

/// The example's work; returns what it prints.
pub fn run() -> Result<String, Box<dyn Error>> {
    let params = Params::new(12, 6, 24, 4)?;
    // One grid for the scene and every object's local frame: 2^12 grid
    // units of 1/256 world unit, a cube of 16 world units.
    let grid = GridMap {
        origin: DVec3::ZERO,
        unit: 1.0 / 256.0,
    };
    let mut world = World::new(params, grid)?;
    // Each object is built once in its local frame, then placed.
    world.add(1, sphere(Vec3::splat(1.0), 0.5, 16, 32), DVec3::ZERO)?;
    world.add(
        2,
        torus(Vec3::splat(1.0), 0.6, 0.15, 32, 16),
        DVec3::new(0.75, 0.5, 0.0),
    )?;
    // Moving an object by whole voxels of its translation's LOD only
    // changes its translation; its hierarchy is reused.
    let lod = world
        .object(2)
        .ok_or("object 2")?
        .determined
        .translation
        .lod;
    let voxel = params.voxel_edge(lod) as f64 * grid.unit;
    let away = world.place(2, DVec3::new(0.75 + voxel, 0.5, 0.0))?;
    let back = world.place(2, DVec3::new(0.75, 0.5, 0.0))?;

    // Merge both into hierarchy 9; the inputs stay in the store.
    let merged = world.merge(&[1, 2], MergeMode::default(), 9)?;
    world.check(9)?;

    let m_inst = world.merged_instances(9, &[1, 2])?;
    let merged_scene = world.trace_scene(&m_inst, &[9])?;
    let s_inst = world.separate_instances(&[1, 2])?;
    let separate_scene = world.trace_scene(&s_inst, &[1, 2])?;

    let (lo, hi) = separate_scene.bounds();
    let rays = random_rays(lo, hi, 5000, 3);
    let mut ctx = TraceContext::new();
    let (mut m, mut s) = (TraceStats::default(), TraceStats::default());
    let mut hits = 0;
    for ray in &rays {
        let a = ctx.closest_hit(ray, &merged_scene, &mut m);
        let b = ctx.closest_hit(ray, &separate_scene, &mut s);
        let same = match (a, b) {
            (Some(a), Some(b)) => a.identical(&b),
            (None, None) => true,
            _ => false,
        };
        if !same {
            return Err(format!("{ray:?}: merged {a:?}, separate {b:?}").into());
        }
        hits += a.is_some() as u32;
    }
    let per = |t: u64| t as f64 / rays.len() as f64;
    let mut out = String::new();
    writeln!(
        out,
        "moving object 2 by one voxel of LOD {lod} ({voxel} world units) and back: {away:?}, {back:?}"
    )?;
    writeln!(
        out,
        "merged at level {:?}: {} nodes created, {} input nodes reused",
        merged.level,
        merged.stats.created(),
        merged.stats.reused()
    )?;
    writeln!(
        out,
        "{} rays, {hits} hits, the same hit merged and separate",
        rays.len()
    )?;
    writeln!(
        out,
        "node tests per ray: merged {:.2}, separate {:.2}",
        per(m.node_tests),
        per(s.node_tests)
    )?;
    Ok(out)
}

fn main() -> Result<(), Box<dyn Error>> {
    print!("{}", run()?);
    Ok(())
}
