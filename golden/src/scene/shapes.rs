//! Meshes of the shapes a scene file names: procedural ones from
//! [`crate::scenes`], files through [`Mesh::load`], each checked first.

use std::path::Path;

use glam::Vec3;

use super::file::ShapeSpec;
use super::SceneError;
use crate::mesh::Mesh;
use crate::scenes::{box_mesh, sphere, terrain, torus};

/// Largest tessellation count accepted per parameter (stacks, slices, cells).
const MAX_TESSELLATION: u32 = 2048;

/// Most triangles a procedural shape may have (SPEC.md section 15): it is
/// refused before it is generated, not after seconds and gigabytes.
pub const MAX_SHAPE_TRIANGLES: u64 = 1 << 21;

/// The mesh of `shape`; `path` is the shape's JSON path for errors.
pub fn shape_mesh(
    shape: &ShapeSpec,
    file: &str,
    path: &str,
    base: &Path,
) -> Result<Mesh, SceneError> {
    let err = |field: &str, expected: &str, found: String| {
        SceneError::new(file, format!("{path}.{field}"), expected, found)
    };
    let finite3 = |field: &str, v: [f32; 3]| {
        if v.iter().all(|c| c.is_finite()) {
            Ok(Vec3::from_array(v))
        } else {
            Err(err(field, "three finite numbers", format!("{v:?}")))
        }
    };
    let positive = |field: &str, v: f32| {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(err(field, "a finite number > 0", v.to_string()))
        }
    };
    let count = |field: &str, v: u32, min: u32| {
        if (min..=MAX_TESSELLATION).contains(&v) {
            Ok(v)
        } else {
            Err(err(
                field,
                &format!("an integer in {min}..={MAX_TESSELLATION}"),
                v.to_string(),
            ))
        }
    };
    let budget = |field: &str, triangles: u64| {
        if triangles <= MAX_SHAPE_TRIANGLES {
            Ok(())
        } else {
            Err(err(
                field,
                &format!("a shape of at most {MAX_SHAPE_TRIANGLES} triangles (SPEC.md section 15)"),
                format!("{triangles} triangles"),
            ))
        }
    };
    match *shape {
        ShapeSpec::Sphere { stacks, slices, .. } => {
            budget("sphere", 2 * stacks as u64 * slices as u64)?
        }
        ShapeSpec::Torus { rings, sides, .. } => budget("torus", 2 * rings as u64 * sides as u64)?,
        ShapeSpec::Terrain { cells, .. } => budget("terrain", 2 * cells as u64 * cells as u64)?,
        _ => {}
    }
    Ok(match shape {
        ShapeSpec::Mesh {
            file: mesh_file,
            center,
            size,
        } => {
            let center = finite3("mesh.center", *center)?;
            let size = positive("mesh.size", *size)?;
            let full = base.join(mesh_file);
            let mesh = Mesh::load(&full)
                .map_err(|e| err("mesh.file", "a readable OBJ or PLY mesh", e.to_string()))?;
            if mesh.is_empty() {
                return Err(err(
                    "mesh.file",
                    "a mesh with at least one triangle",
                    format!("{}: no triangles", full.display()),
                ));
            }
            fit(&mesh, center, size)
        }
        ShapeSpec::Sphere {
            center,
            radius,
            stacks,
            slices,
        } => sphere(
            finite3("sphere.center", *center)?,
            positive("sphere.radius", *radius)?,
            count("sphere.stacks", *stacks, 2)?,
            count("sphere.slices", *slices, 3)?,
        ),
        ShapeSpec::Torus {
            center,
            major,
            minor,
            rings,
            sides,
        } => {
            let minor = positive("torus.minor", *minor)?;
            let major = positive("torus.major", *major)?;
            if minor >= major {
                return Err(err(
                    "torus.minor",
                    &format!("less than major ({major})"),
                    minor.to_string(),
                ));
            }
            torus(
                finite3("torus.center", *center)?,
                major,
                minor,
                count("torus.rings", *rings, 3)?,
                count("torus.sides", *sides, 3)?,
            )
        }
        ShapeSpec::Box { lo, hi } => {
            let (lo, hi) = (finite3("box.lo", *lo)?, finite3("box.hi", *hi)?);
            if !lo.cmplt(hi).all() {
                return Err(err(
                    "box.hi",
                    &format!("above lo {:?} on every axis", lo.to_array()),
                    format!("{:?}", hi.to_array()),
                ));
            }
            box_mesh(lo, hi)
        }
        ShapeSpec::Terrain {
            cells,
            seed,
            size,
            height,
        } => {
            let size = positive("terrain.size", *size)?;
            let height = positive("terrain.height", height.unwrap_or(size))?;
            let mut m = terrain(count("terrain.cells", *cells, 1)?, *seed);
            for v in &mut m.vertices {
                *v *= Vec3::new(size, height, size);
            }
            m
        }
    })
}

/// `mesh` scaled uniformly so its largest side is `size`, centred at `center`.
fn fit(mesh: &Mesh, center: Vec3, size: f32) -> Mesh {
    let (lo, hi) = mesh.bounds();
    let side = (hi - lo).max_element();
    let scale = if side > 0.0 { size / side } else { 1.0 };
    let mid = (lo + hi) * 0.5;
    Mesh {
        vertices: mesh
            .vertices
            .iter()
            .map(|&v| (v - mid) * scale + center)
            .collect(),
        triangles: mesh.triangles.clone(),
    }
}
