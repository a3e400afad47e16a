//! Triangle meshes and their import from Wavefront OBJ and PLY.
//!
//! A [`Mesh`] is what the builder and traversal consume: f32 world positions
//! and triangles as vertex-index triples. Import never panics: every malformed
//! input gives a [`MeshError`] naming the file, the line (OBJ, ascii PLY) or
//! element (binary PLY), the field, and what was expected.

// Errors are the cold path and carry the file, line, field and expectation
// as text; their size is the price of a useful message.
#![allow(clippy::result_large_err)]

pub mod error;
pub mod obj;
pub mod ply;

pub use error::{MeshError, MeshLocation};
pub use obj::parse_obj;
pub use ply::{parse_ply, write_ply, PlyFormat};

use glam::{DVec3, Vec3};
use std::path::Path;

/// An indexed triangle mesh in world units (f32, as a renderer holds it).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions, world units (finite when imported).
    pub vertices: Vec<Vec3>,
    /// Triangles as index triples into `vertices`; an imported polygon is a fan.
    pub triangles: Vec<[u32; 3]>,
}

impl Mesh {
    /// Reads a mesh, choosing the parser by extension: `.obj` or `.ply`
    /// (case-insensitive).
    pub fn load(path: &Path) -> Result<Mesh, MeshError> {
        let name = path.display().to_string();
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        let parse: fn(&[u8], &str) -> Result<Mesh, MeshError> = match ext.as_deref() {
            Some("obj") => parse_obj,
            Some("ply") => parse_ply,
            other => {
                return Err(MeshError::new(
                    &name,
                    MeshLocation::File,
                    "file extension",
                    "`.obj` or `.ply`",
                    format!("{:?}", other.unwrap_or("")),
                ))
            }
        };
        let bytes = crate::input::read_bytes(path, crate::input::MAX_MESH_BYTES)
            .map_err(|e| MeshError::new(&name, MeshLocation::File, "file", e.expected, e.found))?;
        parse(&bytes, &name)
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// True when the mesh has no triangles.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// The smallest box holding every vertex, as `(min, max)`. For a mesh
    /// without vertices it is the empty box `(+inf, -inf)`.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.vertices.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), &v| (lo.min(v), hi.max(v)),
        )
    }

    /// The three vertex positions of triangle `i`. Panics if `i` or one of
    /// its indices is out of range (meshes from the parsers and generators
    /// are always in range; see [`Mesh::validate`]).
    pub fn triangle(&self, i: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[i];
        [
            self.vertices[a as usize],
            self.vertices[b as usize],
            self.vertices[c as usize],
        ]
    }

    /// Triangle `i` widened exactly to binary64.
    pub fn triangle_f64(&self, i: usize) -> [DVec3; 3] {
        self.triangle(i).map(|v| v.as_dvec3())
    }

    /// Checks that every index is in range and every vertex finite, naming
    /// the first offender; `name` is used as the file name in the error.
    pub fn validate(&self, name: &str) -> Result<(), MeshError> {
        for (i, v) in self.vertices.iter().enumerate() {
            if !v.is_finite() {
                return Err(MeshError::new(
                    name,
                    MeshLocation::Element {
                        element: "vertex".into(),
                        index: i as u64,
                    },
                    "position",
                    "finite coordinates",
                    format!("{v}"),
                ));
            }
        }
        let n = self.vertices.len() as u64;
        for (i, t) in self.triangles.iter().enumerate() {
            if let Some(&bad) = t.iter().find(|&&k| k as u64 >= n) {
                return Err(MeshError::new(
                    name,
                    MeshLocation::Element {
                        element: "triangle".into(),
                        index: i as u64,
                    },
                    "vertex index",
                    format!("an index below the vertex count {n}"),
                    bad.to_string(),
                ));
            }
        }
        Ok(())
    }
}
