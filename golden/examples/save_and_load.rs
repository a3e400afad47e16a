//! Saves a built hierarchy to a file and loads it back, bit for bit, so a
//! later run need not build it again.
//!
//! `cargo run -p golden --example save_and_load [FILE]` (default: a file in
//! a temporary folder, removed at the end).

use std::error::Error;
use std::fmt::Write as _;
use std::time::Instant;

use glam::Vec3;
use golden::build::{build, GridMap};
use golden::saved;
use golden::scenes::torus;
use golden::Params;

/// The example's work, saving to `file`; returns what it prints.
pub fn run(file: &std::path::Path) -> Result<String, Box<dyn Error>> {
    let mesh = torus(Vec3::ZERO, 1.0, 0.3, 128, 64);
    let params = Params::default();
    let (lo, hi) = mesh.bounds();
    let grid = GridMap::fit(lo, hi, &params);
    let t = Instant::now();
    let built = build(&mesh, &grid, &params, 0)?;
    let build_ms = t.elapsed().as_secs_f64() * 1e3;

    // Written atomically: a temporary file renamed over `file` when complete.
    saved::save(file, &built, &grid, &mesh)?;
    let bytes = std::fs::metadata(file)?.len();
    // Read with a size bound, every field checked, then the checker run.
    let t = Instant::now();
    let loaded = saved::load(file, &mesh)?;
    let load_ms = t.elapsed().as_secs_f64() * 1e3;
    // A caller states what it builds with; a file saved otherwise is refused.
    loaded.require(&file.display().to_string(), &params, &grid, 0)?;
    if loaded.hierarchy != built {
        return Err("the loaded hierarchy differs from the built one".into());
    }
    let mut out = String::new();
    writeln!(out, "{} triangles, {} nodes", mesh.len(), built.nodes.len())?;
    writeln!(out, "saved {bytes} bytes to {}", file.display())?;
    writeln!(out, "loaded: identical to the built hierarchy")?;
    writeln!(
        out,
        "build {build_ms:.1} ms, load and check {load_ms:.1} ms"
    )?;
    Ok(out)
}

fn main() -> Result<(), Box<dyn Error>> {
    let dir = tempfile::tempdir()?;
    let file = match std::env::args().nth(1) {
        Some(f) => f.into(),
        None => dir.path().join("torus.hmh"),
    };
    print!("{}", run(&file)?);
    Ok(())
}
