//! What the study measures: the shared meshes and a generated scene by
//! default, or the user's meshes (OBJ, PLY) and scene files (JSON, every
//! object baked at its first frame's offset into one mesh).

use std::path::{Path, PathBuf};

use glam::Vec3;
use golden::mesh::Mesh;
use golden::scene::Scene;

use crate::cmd::common::load_mesh;

/// One input: a name and a mesh in its own frame.
pub struct Case {
    pub name: String,
    pub source: String,
    pub mesh: Mesh,
}

/// The cases for `inputs`, or the defaults when empty (a missing shared
/// mesh is left out with a warning on stderr, naming its path).
pub fn cases(inputs: &[PathBuf], seed: u64, quiet: bool) -> Result<Vec<Case>, String> {
    if !inputs.is_empty() {
        return inputs.iter().map(|p| load(p)).collect();
    }
    let mut out = Vec::new();
    for name in ["bunny.obj", "teapot.obj"] {
        let path = golden::scenes::shared_mesh_path(name);
        if path.exists() {
            out.push(load(&path)?);
        } else if !quiet {
            eprintln!(
                "warning: {}: not found; the study goes on without it",
                path.display()
            );
        }
    }
    out.push(generated(seed));
    Ok(out)
}

fn load(path: &Path) -> Result<Case, String> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    let name = path
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("input")
        .to_string();
    let mesh = if ext.eq_ignore_ascii_case("json") {
        bake_scene(path)?
    } else {
        load_mesh(path)?
    };
    Ok(Case {
        name,
        source: path.display().to_string(),
        mesh,
    })
}

/// A scene file's objects at their first frame's offsets, as one mesh.
fn bake_scene(path: &Path) -> Result<Mesh, String> {
    let scene = Scene::load(path).map_err(|e| e.to_string())?;
    let mut out = Mesh::default();
    for o in &scene.objects {
        let off = o.offsets.first().copied().unwrap_or_default();
        let mut placed = (*o.mesh).clone();
        for v in &mut placed.vertices {
            *v = (v.as_dvec3() + off).as_vec3();
        }
        golden::scenes::append(&mut out, &placed);
    }
    if out.triangles.is_empty() {
        return Err(format!(
            "{}: objects: expected at least one triangle",
            path.display()
        ));
    }
    Ok(out)
}

/// The generated scene: a terrain with a sphere and a torus standing on it.
pub fn generated(seed: u64) -> Case {
    let mut mesh = golden::scenes::terrain(48, seed);
    let (lo, hi) = mesh.bounds();
    let c = (lo + hi) * 0.5;
    let r = (hi - lo).max_element() * 0.12;
    golden::scenes::append(
        &mut mesh,
        &golden::scenes::sphere(c + Vec3::new(0.0, r, 0.0), r, 16, 24),
    );
    golden::scenes::append(
        &mut mesh,
        &golden::scenes::torus(c + Vec3::new(2.5 * r, r, 0.0), r, r * 0.3, 24, 12),
    );
    Case {
        name: "generated".into(),
        source: format!("golden::scenes::terrain(48, {seed}) + sphere + torus"),
        mesh,
    }
}
