//! `hiermerge build MESH...`: build one hierarchy per mesh and report its shape and speed.

use std::path::PathBuf;

use serde::Serialize;

use super::common::{build_fitted, load_mesh, GridOpts, Shape};
use crate::report::{emit, per_second, CmdResult};

#[derive(clap::Args)]
pub struct Args {
    /// Mesh files (OBJ or PLY).
    #[arg(required = true)]
    meshes: Vec<PathBuf>,
    #[command(flatten)]
    grid: GridOpts,
    /// Save each checked hierarchy to a file (SPEC section 16), written
    /// atomically: one `--save` per mesh, in the order of the meshes.
    #[arg(long, value_name = "FILE")]
    save: Vec<PathBuf>,
    /// Print one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct Report {
    params: golden::Params,
    hierarchies: Vec<MeshReport>,
}

#[derive(Serialize)]
struct MeshReport {
    file: String,
    triangles: u64,
    #[serde(flatten)]
    shape: Shape,
    build_seconds: f64,
    triangles_per_second: f64,
    /// The checker proved the hierarchy valid (SPEC section 5).
    checked: bool,
    /// The saved hierarchy's file (`--save`).
    #[serde(skip_serializing_if = "Option::is_none")]
    saved: Option<String>,
}

pub fn main(a: Args) -> CmdResult {
    let params = a.grid.params()?;
    if !a.save.is_empty() && a.save.len() != a.meshes.len() {
        return Err(format!(
            "--save: expected one file per mesh ({} meshes), found {} files",
            a.meshes.len(),
            a.save.len()
        ));
    }
    let mut hierarchies = Vec::new();
    for (i, path) in a.meshes.iter().enumerate() {
        let mesh = load_mesh(path)?;
        let id = u8::try_from(i)
            .ok()
            .filter(|&id| (id as u64) < params.hier_capacity())
            .ok_or_else(|| {
                format!(
                    "too many meshes: at most {} with --hier-bits {}",
                    params.hier_capacity(),
                    params.hier_bits
                )
            })?;
        let b = build_fitted(path.clone(), mesh, &params, id)?;
        let tris = b
            .grid
            .mesh_to_grid(&b.mesh, &params)
            .map_err(|e| e.to_string())?;
        golden::check::check_built(&b.hierarchy, &tris).map_err(|e| {
            format!(
                "{}: the built hierarchy fails the checker: {e}",
                path.display()
            )
        })?;
        let saved = match a.save.get(i) {
            Some(file) => {
                golden::saved::save(file, &b.hierarchy, &b.grid, &b.mesh)?;
                Some(file.display().to_string())
            }
            None => None,
        };
        let n = b.mesh.triangles.len() as u64;
        hierarchies.push(MeshReport {
            file: path.display().to_string(),
            triangles: n,
            shape: Shape::of(&b.hierarchy),
            build_seconds: b.seconds,
            triangles_per_second: per_second(n as f64, b.seconds),
            checked: true,
            saved,
        });
    }
    let report = Report {
        params,
        hierarchies,
    };
    emit(a.json, &report, |r| {
        let p = &r.params;
        println!(
            "params: D={} Q={} I={} H={}",
            p.max_lod, p.quant_bits, p.index_bits, p.hier_bits
        );
        for h in &r.hierarchies {
            println!(
                "{}: {} triangles -> {} nodes ({} inner, {} leaves), top LOD {} ({} roots), depth {}, built in {:.3} ms ({:.2} M triangles/s), checker: ok",
                h.file, h.triangles, h.shape.nodes, h.shape.inner, h.shape.leaves, h.shape.top_lod, h.shape.roots, h.shape.depth,
                h.build_seconds * 1e3, h.triangles_per_second / 1e6
            );
            let per_lod: Vec<String> = h
                .shape
                .nodes_per_lod
                .iter()
                .enumerate()
                .filter(|(_, &c)| c > 0)
                .map(|(l, c)| format!("{l}:{c}"))
                .collect();
            println!("  nodes per LOD: {}", per_lod.join(" "));
            if let Some(f) = &h.saved {
                println!("  saved to {f}");
            }
        }
    })
}
