//! [`BuildContext`]: the builder (one thread, or the parallel build) with
//! its working buffers kept from one build to the next.
//!
//! A scene rebuilds its dynamic hierarchies every frame. The entries, the
//! sort's second buffer and the parallel placement's chunks are most of a
//! build's memory (24 bytes an entry at D <= 19, four to five entries a
//! triangle), and fresh buffers are mapped and zeroed by the kernel page by
//! page as they are first written: on the versus bench's 1M-triangle
//! terrain, a fifth of the one-thread build. Kept, they are written over.

use super::leaves::{self, LeafEntry, LeafKey};
use super::radix::SortBuffers;
use super::{
    place_parallel_into, place_range_into, radix, subtrees, upper, BuildError, GridMap, MeshInput,
    TriangleOf,
};
use crate::mesh::Mesh;
use crate::params::Params;
use crate::store::Hierarchy;

/// The buffers of one key width.
#[derive(Default)]
struct Buffers<K: LeafKey> {
    entries: Vec<LeafEntry<K>>,
    scratch: Vec<LeafEntry<K>>,
    /// The parallel placement's chunks.
    parts: Vec<Vec<LeafEntry<K>>>,
}

impl<K: LeafKey> Buffers<K> {
    fn run(
        &mut self,
        n: usize,
        params: &Params,
        id: u8,
        triangle: TriangleOf<'_>,
        parallel: bool,
    ) -> Result<Hierarchy, BuildError> {
        match parallel {
            false => self.build(n, params, id, triangle),
            true => self.build_parallel(n, params, id, triangle),
        }
    }

    fn build(
        &mut self,
        n: usize,
        params: &Params,
        id: u8,
        triangle: TriangleOf<'_>,
    ) -> Result<Hierarchy, BuildError> {
        self.entries.clear();
        // The one-shot build's first guess, four entries a triangle; no
        // more once a build has made the room.
        self.entries.reserve(n.saturating_mul(4));
        place_range_into(0..n, params, triangle, &mut self.entries)?;
        let key_bits = leaves::leaf_key_bits(params);
        radix::radix_sort(&mut self.entries, &mut self.scratch, key_bits, |e| e.key);
        upper::assemble(&self.entries, params, id)
    }

    fn build_parallel(
        &mut self,
        n: usize,
        params: &Params,
        id: u8,
        triangle: TriangleOf<'_>,
    ) -> Result<Hierarchy, BuildError> {
        place_parallel_into(n, params, triangle, &mut self.parts, false)?;
        let bufs = SortBuffers {
            out: &mut self.entries,
            scratch: &mut self.scratch,
            keep_parts: true,
        };
        radix::radix_sort_parts_into(&mut self.parts, bufs, leaves::leaf_key_bits(params), |e| {
            e.key
        });
        subtrees::assemble_parallel(&self.entries, params, id)
    }

    fn bytes(&self) -> usize {
        let parts: usize = self.parts.iter().map(Vec::capacity).sum();
        (self.entries.capacity() + self.scratch.capacity() + parts)
            * std::mem::size_of::<LeafEntry<K>>()
    }
}

/// The builder, on one thread or on the rayon pool, with its buffers kept
/// across builds: the same hierarchy as [`super::build`], bit for bit, or
/// the same error.
///
/// ```
/// use golden::build::{BuildContext, GridMap};
/// use golden::mesh::Mesh;
/// use golden::Params;
/// use glam::Vec3;
///
/// let mesh = Mesh {
///     vertices: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
///     triangles: vec![[0, 1, 2]],
/// };
/// let p = Params::default();
/// let (lo, hi) = mesh.bounds();
/// let grid = GridMap::fit(lo, hi, &p);
/// let mut ctx = BuildContext::new();
/// for _frame in 0..3 {
///     let h = ctx.build(&mesh, &grid, &p, 0)?;
///     assert_eq!(h, golden::build::build(&mesh, &grid, &p, 0)?);
/// }
/// # Ok::<(), golden::build::BuildError>(())
/// ```
#[derive(Default)]
pub struct BuildContext {
    /// Keys of `3D + 5 <= 64` bits (`D <= 19`).
    narrow: Buffers<u64>,
    /// Wider keys.
    wide: Buffers<u128>,
}

impl BuildContext {
    /// A context with no buffers yet: the first build makes them.
    pub fn new() -> BuildContext {
        BuildContext::default()
    }

    /// [`super::build`] in this context's buffers.
    pub fn build(
        &mut self,
        mesh: &Mesh,
        grid: &GridMap,
        params: &Params,
        id: u8,
    ) -> Result<Hierarchy, BuildError> {
        self.run(mesh, grid, params, id, false)
    }

    /// [`super::build_parallel`] in this context's buffers: the same
    /// hierarchy as [`super::build`], bit for bit, or the same error.
    pub fn build_parallel(
        &mut self,
        mesh: &Mesh,
        grid: &GridMap,
        params: &Params,
        id: u8,
    ) -> Result<Hierarchy, BuildError> {
        self.run(mesh, grid, params, id, true)
    }

    fn run(
        &mut self,
        mesh: &Mesh,
        grid: &GridMap,
        params: &Params,
        id: u8,
        parallel: bool,
    ) -> Result<Hierarchy, BuildError> {
        let input = MeshInput::checked(mesh, grid, params, id)?;
        let (n, triangle) = (mesh.triangles.len(), |i| input.triangle(i));
        match leaves::leaf_key_bits(params) <= 64 {
            true => self.narrow.run(n, params, id, &triangle, parallel),
            false => self.wide.run(n, params, id, &triangle, parallel),
        }
    }

    /// The bytes its buffers hold.
    pub fn bytes(&self) -> usize {
        self.narrow.bytes() + self.wide.bytes()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::build::build;
    use crate::scenes;
    use glam::Vec3;

    /// The context's one-thread and 2-thread builds against the one-shot
    /// build.
    fn built(ctx: &mut BuildContext, mesh: &Mesh, p: &Params) {
        let (lo, hi) = mesh.bounds();
        let grid = GridMap::fit(lo, hi, p);
        let want = build(mesh, &grid, p, 1);
        assert_eq!(ctx.build(mesh, &grid, p, 1), want);
        let two = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .expect("a pool");
        assert_eq!(two.install(|| ctx.build_parallel(mesh, &grid, p, 1)), want);
    }

    /// One context through meshes large and small, both key widths, and a
    /// refused mesh between builds: each build is the one-shot build.
    #[test]
    fn a_kept_context_builds_what_build_builds() {
        let narrow = Params::default();
        let wide = Params {
            max_lod: 24,
            ..Params::default()
        };
        assert!(leaves::leaf_key_bits(&narrow) <= 64 && leaves::leaf_key_bits(&wide) > 64);
        let mut ctx = BuildContext::new();
        // Over 2^18 entries: the parallel sort and the levels built one
        // subtree at a time run (below, both run on one thread).
        let big = scenes::terrain(200, 3);
        let small = scenes::random_soup(50, 0.05, 7);
        built(&mut ctx, &big, &narrow);
        assert!(ctx.narrow.entries.len() > 1 << 18);
        let room = ctx.bytes();
        assert!(room > 0);
        built(&mut ctx, &small, &narrow);
        // The smaller build fits in the room the bigger one made.
        assert_eq!(ctx.bytes(), room);
        built(&mut ctx, &scenes::architecture(1, 2), &wide);
        built(&mut ctx, &small, &wide);

        // A vertex off the grid, after the first triangles have been
        // placed: the same error, and the context builds on after it.
        let mut bad = small.clone();
        bad.vertices.push(Vec3::splat(f32::NAN));
        let last = bad.vertices.len() as u32 - 1;
        bad.triangles[30][1] = last;
        built(&mut ctx, &bad, &narrow);
        let (lo, hi) = small.bounds();
        let grid = GridMap::fit(lo, hi, &narrow);
        assert!(matches!(
            ctx.build(&bad, &grid, &narrow, 1),
            Err(BuildError::NonFinite { triangle: 30, .. })
        ));
        built(&mut ctx, &big, &narrow);
    }
}
