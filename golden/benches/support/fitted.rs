//! Meshes scaled and placed for the benches.

use glam::Vec3;
use golden::mesh::Mesh;

/// `mesh` scaled uniformly so its largest side is `size`, its lower corner at `at`.
pub fn fitted(mesh: &Mesh, size: f32, at: Vec3) -> Mesh {
    let (lo, hi) = mesh.bounds();
    let s = size / (hi - lo).max_element();
    Mesh {
        vertices: mesh.vertices.iter().map(|&v| (v - lo) * s + at).collect(),
        triangles: mesh.triangles.clone(),
    }
}
