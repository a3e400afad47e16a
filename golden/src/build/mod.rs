//! The bottom-up hierarchy builder, S402-S408 (SPEC.md section 4).
//!
//! 1. [`GridMap`] maps each triangle to grid units; bad input is an error
//!    naming the triangle ([`BuildError`]).
//! 2. [`leaves`]: each triangle's LOD ([`lod`]), the voxels at that LOD it
//!    really intersects, its clipped box in each, quantized outward
//!    ([`quantize`]): one entry per (triangle, voxel).
//! 3. [`radix`]: one LSD radix sort of the entries by (LOD, Morton).
//! 4. `upper`: one leaf per (LOD, voxel), then level by level one inner
//!    node per parent voxel, up to the top rule; laid out in store order.
//!    The parallel build makes the levels from LOD 2 down one subtree at
//!    a time (`subtrees`).

mod context;
pub mod leaves;
pub mod lod;
pub mod quantize;
pub mod radix;
mod subtrees;
pub(crate) mod upper;

use std::fmt;

use glam::{DVec3, Vec3};

use crate::mesh::Mesh;
use crate::params::{ParamError, Params};
use crate::store::Hierarchy;
pub use context::BuildContext;
use leaves::{LeafEntry, LeafKey};

/// How world coordinates map to grid units: `g = (p - origin) / unit`,
/// computed in binary64 from the f32 position widened exactly.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridMap {
    /// The world point at grid coordinate (0, 0, 0).
    pub origin: DVec3,
    /// World units per grid unit; finite and > 0.
    pub unit: f64,
}

impl GridMap {
    /// A map fitting the box `[lo, hi]` (world units) into the scene cube of
    /// `p`: origin at `lo`, unit the smallest power of two at or above the
    /// largest side over `2^D`. The side is taken in binary64 (exact or
    /// rounded like every vertex's offset, so no vertex maps past `2^D`), and
    /// the power of two is found by exact doubling and halving, no logarithm.
    /// A non-finite box gives a non-finite origin, which [`build`] refuses.
    pub fn fit(lo: Vec3, hi: Vec3, p: &Params) -> GridMap {
        let side = (hi.as_dvec3() - lo.as_dvec3()).max_element();
        let wanted = side / p.scene_edge() as f64;
        GridMap {
            origin: lo.as_dvec3(),
            unit: power_of_two_at_least(wanted),
        }
    }

    /// A point in grid units.
    pub fn to_grid(&self, p: Vec3) -> DVec3 {
        (p.as_dvec3() - self.origin) / self.unit
    }

    fn validate(&self) -> Result<(), BuildError> {
        if !self.origin.is_finite() {
            return Err(BuildError::BadGridMap {
                field: "origin",
                expected: "finite coordinates",
            });
        }
        if !(self.unit.is_finite() && self.unit > 0.0) {
            return Err(BuildError::BadGridMap {
                field: "unit",
                expected: "finite and > 0",
            });
        }
        Ok(())
    }

    /// Triangle `i` of `mesh` in grid units, checked: indices in range,
    /// coordinates finite and inside the closed scene cube `[0, 2^D]^3`.
    pub fn triangle(&self, mesh: &Mesh, i: usize, p: &Params) -> Result<[DVec3; 3], BuildError> {
        let t = mesh.triangles[i];
        let mut out = [DVec3::ZERO; 3];
        for corner in 0..3 {
            let v = t[corner] as usize;
            let world = *mesh.vertices.get(v).ok_or(BuildError::BadVertexIndex {
                triangle: i,
                corner,
                vertex: t[corner],
                vertices: mesh.vertices.len(),
            })?;
            out[corner] = self.to_grid(world);
        }
        check_grid_triangle(&out, i, p)?;
        Ok(out)
    }

    /// Every triangle of `mesh` in grid units (what [`crate::check`] takes).
    pub fn mesh_to_grid(&self, mesh: &Mesh, p: &Params) -> Result<Vec<[DVec3; 3]>, BuildError> {
        self.validate()?;
        (0..mesh.triangles.len())
            .map(|i| self.triangle(mesh, i, p))
            .collect()
    }
}

/// The smallest power of two `>= x` (1 for a non-finite or non-positive `x`,
/// at least the smallest normal binary64).
fn power_of_two_at_least(x: f64) -> f64 {
    if !(x.is_finite() && x > 0.0) {
        return 1.0;
    }
    let mut u = 1.0f64;
    while u < x {
        u *= 2.0;
    }
    while u * 0.5 >= x && u * 0.5 >= f64::MIN_POSITIVE {
        u *= 0.5;
    }
    u
}

/// Checks one grid-space triangle: finite and inside `[0, 2^D]^3`.
pub fn check_grid_triangle(t: &[DVec3; 3], index: usize, p: &Params) -> Result<(), BuildError> {
    let edge = p.scene_edge() as f64;
    // Every coordinate in `[0, edge]` (a NaN or an infinity fails one of
    // the comparisons): the common case, decided without the loop below,
    // which finds the first bad coordinate otherwise.
    let inside = |v: &DVec3| v.cmpge(DVec3::ZERO).all() && v.cmple(DVec3::splat(edge)).all();
    if inside(&t[0]) && inside(&t[1]) && inside(&t[2]) {
        return Ok(());
    }
    for (corner, v) in t.iter().enumerate() {
        for axis in 0..3 {
            let g = v[axis];
            if !g.is_finite() {
                return Err(BuildError::NonFinite {
                    triangle: index,
                    corner,
                    axis,
                });
            }
            if !(0.0..=edge).contains(&g) {
                return Err(BuildError::OutsideScene {
                    triangle: index,
                    corner,
                    axis,
                    value: g,
                    scene_edge: p.scene_edge(),
                });
            }
        }
    }
    Ok(())
}

/// Why a build failed. Every variant names the offending element.
#[derive(Clone, Debug, PartialEq)]
pub enum BuildError {
    /// The parameters are out of range (SPEC 1).
    Params(ParamError),
    /// The grid map's `origin` is not finite, or its `unit` not finite and > 0 (SPEC 4.1).
    BadGridMap {
        /// The field at fault: `"origin"` or `"unit"`.
        field: &'static str,
        /// What the field must be.
        expected: &'static str,
    },
    /// The hierarchy id is `>= 2^H`.
    HierIdOutOfRange {
        /// The id asked for.
        id: u8,
        /// `H`: ids run `0..2^H`.
        hier_bits: u8,
    },
    /// The mesh has no triangles.
    EmptyMesh,
    /// A triangle's vertex index is not below the mesh's vertex count.
    BadVertexIndex {
        /// Index of the triangle in the mesh.
        triangle: usize,
        /// The triangle's corner, 0..=2.
        corner: usize,
        /// The vertex index that corner holds.
        vertex: u32,
        /// The mesh's vertex count.
        vertices: usize,
    },
    /// A corner's grid coordinate is NaN or infinite.
    NonFinite {
        /// Index of the triangle in the mesh.
        triangle: usize,
        /// The triangle's corner, 0..=2.
        corner: usize,
        /// The axis: 0 = x, 1 = y, 2 = z.
        axis: usize,
    },
    /// A corner's grid coordinate is outside the closed scene cube `[0, 2^D]`.
    OutsideScene {
        /// Index of the triangle in the mesh.
        triangle: usize,
        /// The triangle's corner, 0..=2.
        corner: usize,
        /// The axis: 0 = x, 1 = y, 2 = z.
        axis: usize,
        /// The coordinate, in grid units.
        value: f64,
        /// `2^D`, the cube's edge in grid units.
        scene_edge: u64,
    },
    /// An index, length or count does not fit the `I`-bit fields.
    IndexOverflow {
        /// What overflowed, e.g. `"triangle index"`, `"node count - 1"` or `"count"`.
        what: &'static str,
        /// Its value, at or above `2^I`.
        value: u64,
        /// `I`, the width of index, length and count fields (SPEC 1).
        index_bits: u8,
    },
}

const AXES: [&str; 3] = ["x", "y", "z"];

impl fmt::Display for BuildError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BuildError::Params(e) => write!(f, "{e}"),
            BuildError::BadGridMap { field, expected } => {
                write!(f, "grid map field `{field}`: expected {expected}")
            }
            BuildError::HierIdOutOfRange { id, hier_bits } => {
                write!(f, "hierarchy id {id} does not fit in H = {hier_bits} bits")
            }
            BuildError::EmptyMesh => write!(f, "the mesh has no triangles: nothing to build"),
            BuildError::BadVertexIndex {
                triangle,
                corner,
                vertex,
                vertices,
            } => write!(
                f,
                "triangle {triangle} corner {corner}: vertex index {vertex} out of range (mesh has {vertices} vertices)"
            ),
            BuildError::NonFinite {
                triangle,
                corner,
                axis,
            } => write!(
                f,
                "triangle {triangle} corner {corner}: {} grid coordinate is not finite",
                AXES[*axis]
            ),
            BuildError::OutsideScene {
                triangle,
                corner,
                axis,
                value,
                scene_edge,
            } => write!(
                f,
                "triangle {triangle} corner {corner}: {} grid coordinate {value} is outside the scene [0, {scene_edge}]",
                AXES[*axis]
            ),
            BuildError::IndexOverflow {
                what,
                value,
                index_bits,
            } => write!(
                f,
                "{what} = {value} does not fit in I = {index_bits} index bits"
            ),
        }
    }
}

impl std::error::Error for BuildError {}

impl From<ParamError> for BuildError {
    fn from(e: ParamError) -> Self {
        BuildError::Params(e)
    }
}

/// Builds hierarchy `id` over `mesh`, placed in the grid by `grid`
/// (SPEC.md section 4). Deterministic: the same input gives the same store.
pub fn build(
    mesh: &Mesh,
    grid: &GridMap,
    params: &Params,
    id: u8,
) -> Result<Hierarchy, BuildError> {
    grid.validate()?;
    build_with(mesh.triangles.len(), params, id, |i| {
        grid.triangle(mesh, i, params)
    })
}

/// Builds hierarchy `id` over triangles already in grid units.
pub fn build_grid_triangles(
    tris: &[[DVec3; 3]],
    params: &Params,
    id: u8,
) -> Result<Hierarchy, BuildError> {
    build_with(tris.len(), params, id, |i| {
        check_grid_triangle(&tris[i], i, params)?;
        Ok(tris[i])
    })
}

/// [`build`] on the threads of the current rayon pool: the same
/// hierarchy, bit for bit, or the same error. Triangles are placed in
/// chunks, each chunk on one thread, and the chunks' entries are kept in
/// triangle order, so the sort sees exactly the sequence [`build`] makes;
/// the levels are then built one subtree at a time (`subtrees`).
pub fn build_parallel(
    mesh: &Mesh,
    grid: &GridMap,
    params: &Params,
    id: u8,
) -> Result<Hierarchy, BuildError> {
    let input = MeshInput::checked(mesh, grid, params, id)?;
    let (n, triangle) = (mesh.triangles.len(), |i| input.triangle(i));
    if leaves::leaf_key_bits(params) <= 64 {
        build_parallel_keyed::<u64>(n, params, id, &triangle)
    } else {
        build_parallel_keyed::<u128>(n, params, id, &triangle)
    }
}

/// A triangle in grid units, by index, as the parallel builds read it.
type TriangleOf<'a> = &'a (dyn Fn(usize) -> Result<[DVec3; 3], BuildError> + Sync);

/// A mesh a build has checked (its grid map, then [`check_build`]).
struct MeshInput<'a> {
    mesh: &'a Mesh,
    grid: &'a GridMap,
    params: &'a Params,
}

impl<'a> MeshInput<'a> {
    fn checked(
        mesh: &'a Mesh,
        grid: &'a GridMap,
        params: &'a Params,
        id: u8,
    ) -> Result<MeshInput<'a>, BuildError> {
        grid.validate()?;
        check_build(mesh.triangles.len(), params, id)?;
        Ok(MeshInput { mesh, grid, params })
    }

    /// Triangle `i` in grid units.
    fn triangle(&self, i: usize) -> Result<[DVec3; 3], BuildError> {
        self.grid.triangle(self.mesh, i, self.params)
    }
}

/// [`build_parallel`] with keys held in `K`.
fn build_parallel_keyed<K: LeafKey>(
    n: usize,
    params: &Params,
    id: u8,
    triangle: TriangleOf<'_>,
) -> Result<Hierarchy, BuildError> {
    let mut parts = Vec::new();
    place_parallel_into::<K>(n, params, triangle, &mut parts, true)?;
    let entries = radix::radix_sort_parts(parts, leaves::leaf_key_bits(params), |e| e.key);
    subtrees::assemble_parallel(&entries, params, id)
}

/// Most triangles per chunk of the parallel placement: large enough that a
/// chunk's setup and its vector are negligible. A small mesh is cut into
/// smaller chunks, eight per thread, so that the threads finish together.
const PLACE_CHUNK: usize = 1 << 13;

/// Fewest triangles per chunk (below it a chunk's setup is no longer small).
const PLACE_CHUNK_MIN: usize = 256;

/// The entries of triangles `0..n` in triangle order, as the entries of
/// consecutive chunks placed on the current rayon pool into `parts` (one
/// vector a chunk, emptied first, and any more left empty; the sort reads
/// them where they are); the error of the lowest failing triangle.
/// `shrink`: give each chunk's spare room back (a one-shot build; a kept
/// context keeps it).
fn place_parallel_into<K: LeafKey>(
    n: usize,
    params: &Params,
    triangle: TriangleOf<'_>,
    parts: &mut Vec<Vec<LeafEntry<K>>>,
    shrink: bool,
) -> Result<(), BuildError> {
    use rayon::prelude::*;
    let chunk = n
        .div_ceil(8 * rayon::current_num_threads())
        .clamp(PLACE_CHUNK_MIN, PLACE_CHUNK);
    let chunks = n.div_ceil(chunk);
    if parts.len() < chunks {
        parts.resize_with(chunks, Vec::new);
    }
    // A kept context's vectors past this mesh's chunks stay, empty.
    parts[chunks..].iter_mut().for_each(Vec::clear);
    parts[..chunks]
        .par_iter_mut()
        .enumerate()
        .map(|(c, part)| {
            let range = c * chunk..((c + 1) * chunk).min(n);
            part.clear();
            part.reserve(range.len() * 4);
            place_range_into(range, params, triangle, part)?;
            if shrink {
                part.shrink_to_fit();
            }
            Ok(())
        })
        // In chunk order, so that the first error is the lowest chunk's
        // (rayon's own collect into a `Result` gives any chunk's).
        .collect::<Vec<_>>()
        .into_iter()
        .collect()
}

/// Room kept free before placing a triangle: its entries are at most its
/// candidate voxels, about `2^SLIVER_LEVEL_CAP + 1 = 9` per axis (see
/// `leaves::VertexVoxels`); more would only make the vector grow by itself.
const MOST_ENTRIES_PER_TRIANGLE: usize = 9 * 9 * 9;

/// The entries of triangles `range`, in order, in a vector of their own
/// (no spare room: it would stay allocated through the sort and the levels;
/// shrinking a block moves nothing).
fn place_range<K: LeafKey>(
    range: std::ops::Range<usize>,
    params: &Params,
    triangle: &dyn Fn(usize) -> Result<[DVec3; 3], BuildError>,
) -> Result<Vec<LeafEntry<K>>, BuildError> {
    let mut entries = Vec::with_capacity(range.len() * 4);
    place_range_into(range, params, triangle, &mut entries)?;
    entries.shrink_to_fit();
    Ok(entries)
}

/// The entries of triangles `range`, in order, appended to `entries`.
///
/// On a CPU with AVX the placement is compiled a second time with it
/// ([`place_range_avx`]): four binary64 lanes per instruction where the
/// kernels work on lanes. Both copies make the same IEEE operations on the
/// same values (Rust never fuses a multiply and an add by itself, and AVX
/// rounds every lane as the scalar instruction does), so the same entries.
fn place_range_into<K: LeafKey>(
    range: std::ops::Range<usize>,
    params: &Params,
    triangle: &dyn Fn(usize) -> Result<[DVec3; 3], BuildError>,
    entries: &mut Vec<LeafEntry<K>>,
) -> Result<(), BuildError> {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU has AVX, checked just above.
        return unsafe { place_range_avx(range, params, triangle, entries) };
    }
    place_range_in::<K, crate::geom::lanes::Plain>(range, params, triangle, entries)
}

/// [`place_range_in`] compiled with AVX, its kernels computing in AVX
/// registers; the caller checks the CPU has it.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
fn place_range_avx<K: LeafKey>(
    range: std::ops::Range<usize>,
    params: &Params,
    triangle: &dyn Fn(usize) -> Result<[DVec3; 3], BuildError>,
    entries: &mut Vec<LeafEntry<K>>,
) -> Result<(), BuildError> {
    place_range_in::<K, crate::geom::lanes::Avx>(range, params, triangle, entries)
}

/// [`place_range_into`]'s work, inlined into each of its two copies with
/// the kernels it calls.
#[inline(always)]
fn place_range_in<K: LeafKey, L: crate::geom::lanes::Lanes>(
    range: std::ops::Range<usize>,
    params: &Params,
    triangle: &dyn Fn(usize) -> Result<[DVec3; 3], BuildError>,
    entries: &mut Vec<LeafEntry<K>>,
) -> Result<(), BuildError> {
    let mut clip_scratch = crate::geom::clip::ClipScratch::new();
    for i in range.clone() {
        // Past the room there is, it grows by one entry a triangle at a
        // time, not by doubling: a scene of 4.5 entries a triangle would
        // otherwise hold room for 8 at the peak.
        if entries.capacity() - entries.len() < MOST_ENTRIES_PER_TRIANGLE {
            entries.reserve_exact(range.len().max(MOST_ENTRIES_PER_TRIANGLE));
        }
        let tri = triangle(i)?;
        leaves::place_triangle_in::<K, L>(&tri, i as u32, params, entries, &mut clip_scratch);
    }
    Ok(())
}

/// The checks every build makes before placing a triangle.
fn check_build(n: usize, params: &Params, id: u8) -> Result<(), BuildError> {
    params.validate()?;
    if id as u64 >= params.hier_capacity() {
        return Err(BuildError::HierIdOutOfRange {
            id,
            hier_bits: params.hier_bits,
        });
    }
    if n == 0 {
        return Err(BuildError::EmptyMesh);
    }
    if n as u64 > params.index_capacity() {
        return Err(BuildError::IndexOverflow {
            what: "triangle index",
            value: n as u64 - 1,
            index_bits: params.index_bits,
        });
    }
    Ok(())
}

fn build_with(
    n: usize,
    params: &Params,
    id: u8,
    triangle: impl Fn(usize) -> Result<[DVec3; 3], BuildError>,
) -> Result<Hierarchy, BuildError> {
    check_build(n, params, id)?;
    if leaves::leaf_key_bits(params) <= 64 {
        build_keyed::<u64>(n, params, id, &triangle)
    } else {
        build_keyed::<u128>(n, params, id, &triangle)
    }
}

/// The one-thread build with keys held in `K`.
fn build_keyed<K: LeafKey>(
    n: usize,
    params: &Params,
    id: u8,
    triangle: &dyn Fn(usize) -> Result<[DVec3; 3], BuildError>,
) -> Result<Hierarchy, BuildError> {
    let mut entries = place_range::<K>(0..n, params, triangle)?;
    // The sort's second buffer is gone before the levels are made.
    radix::radix_sort(
        &mut entries,
        &mut Vec::new(),
        leaves::leaf_key_bits(params),
        |e| e.key,
    );
    upper::assemble(&entries, params, id)
}
