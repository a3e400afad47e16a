//! Builds a hierarchy from a mesh, proves it valid with the checker, and
//! rebuilds it in a kept `BuildContext`, as a scene does every frame.
//!
//! `cargo run -p golden --example build_hierarchy [MESH.obj|MESH.ply]`: the
//! mesh file if given, else a generated terrain and sphere (so it runs
//! anywhere).

use std::error::Error;
use std::fmt::Write as _;

use glam::Vec3;
use golden::build::{build, BuildContext, GridMap};
use golden::check::check_built;
use golden::mesh::Mesh;
use golden::scenes::{append, sphere, terrain};
use golden::Params;

/// The example's work; returns what it prints.
pub fn run(mesh_file: Option<&str>) -> Result<String, Box<dyn Error>> {
    let mesh = match mesh_file {
        Some(f) => Mesh::load(std::path::Path::new(f))?,
        None => {
            let mut m = terrain(64, 7);
            append(&mut m, &sphere(Vec3::new(0.5, 0.8, 0.5), 0.15, 16, 32));
            m
        }
    };
    // D = 16 levels, Q = 8 bits per box bound, 24-bit indices, 4-bit ids.
    let params = Params::new(16, 8, 24, 4)?;
    // The grid map puts the mesh's bounds into the scene cube [0, 2^D]^3.
    let (lo, hi) = mesh.bounds();
    let grid = GridMap::fit(lo, hi, &params);
    let hierarchy = build(&mesh, &grid, &params, 0)?;
    // The checker re-derives what every ray test relies on (SPEC 5).
    let report = check_built(&hierarchy, &grid.mesh_to_grid(&mesh, &params)?)?;

    let mut out = String::new();
    writeln!(out, "{} triangles, parameters {}", mesh.len(), params.tag())?;
    writeln!(
        out,
        "{} nodes ({} leaves), {} roots at LOD {}, {} references, {} primitive slots",
        hierarchy.nodes.len(),
        report.leaves,
        hierarchy.root_count,
        hierarchy.top_lod,
        hierarchy.refs.len(),
        hierarchy.prims.len()
    )?;
    let bits = golden::layout::NodeLayout::new(&params).width();
    writeln!(out, "a node record is {bits} bits")?;
    writeln!(out, "checker: ok, deepest LOD {}", report.deepest_lod)?;

    // A hierarchy rebuilt every frame (a dynamic object): a kept context
    // reuses the build's buffers instead of asking the kernel for fresh
    // pages each time; on the threads of the rayon pool with
    // `build_parallel`. The same hierarchy, bit for bit.
    let mut ctx = BuildContext::new();
    for _frame in 0..3 {
        let again = ctx.build_parallel(&mesh, &grid, &params, 0)?;
        if again != hierarchy {
            return Err("a kept context built another hierarchy".into());
        }
    }
    writeln!(
        out,
        "rebuilt 3 times in a kept context ({} KiB of buffers): the same hierarchy",
        ctx.bytes() / 1024
    )?;
    Ok(out)
}

fn main() -> Result<(), Box<dyn Error>> {
    let arg = std::env::args().nth(1);
    print!("{}", run(arg.as_deref())?);
    Ok(())
}
