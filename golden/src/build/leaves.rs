//! S402-S404: each primitive's LOD, the voxels at that LOD it really
//! intersects, and its box in each of them (SPEC.md sections 4.2-4.4).
//!
//! The output is one [`LeafEntry`] per (primitive, voxel): the hot path of
//! the build. It allocates nothing per triangle; entries go into one vector.

use glam::DVec3;

use super::lod::primitive_lod;
use super::quantize::floor_ceil_in_scene;
use super::radix::{morton3_fast, SortKey};
use crate::geom::clip::{clip_candidate, max_not_nan, ClipScratch, PreparedTriangle};
use crate::geom::lanes::{Lanes, Plain, P4};
use crate::geom::overlap::{overlaps_candidate, overlaps_candidate_prepared, OverlapPrep};
use crate::params::Params;

/// The integer a [`LeafEntry`] holds its key in: `u128` holds every key
/// (`3D + 5` bits for `D <= 31`); the builder uses `u64` when the key fits
/// ([`leaf_key_bits`] `<= 64`, i.e. `D <= 19`), which halves the entries'
/// size (48 to 24 bytes) and with it the memory the sort moves. The key's
/// value is the same either way.
pub trait LeafKey: Copy + Eq + Send + Sync + std::fmt::Debug + SortKey + 'static {
    /// `k`, which the caller guarantees fits.
    fn from_u128(k: u128) -> Self;
    /// The key's value.
    fn to_u128(self) -> u128;
}

impl LeafKey for u128 {
    #[inline(always)]
    fn from_u128(k: u128) -> Self {
        k
    }
    #[inline(always)]
    fn to_u128(self) -> u128 {
        self
    }
}

impl LeafKey for u64 {
    #[inline(always)]
    fn from_u128(k: u128) -> Self {
        debug_assert!(k >> 64 == 0, "a leaf key of more than 64 bits in a u64");
        k as u64
    }
    #[inline(always)]
    fn to_u128(self) -> u128 {
        self as u128
    }
}

/// A primitive in one leaf voxel, with its box there in that voxel's cells.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LeafEntry<K: LeafKey = u128> {
    /// `(lod << 3D) | morton(x, y, z)`: sorting by it sorts by LOD, then Morton.
    pub key: K,
    /// Triangle index.
    pub prim: u32,
    /// Lowest cell per axis (x, y, z) of the primitive's box in this voxel, rounded outward (SPEC 3).
    pub lo: [u16; 3],
    /// Highest cell per axis, inclusive, rounded outward; `lo <= hi < 2^Q`.
    pub hi: [u16; 3],
}

/// The bits of a Morton code that hold the x coordinate (bit `i` of x at
/// bit `3i`, for the 42 bits `morton3_fast` places).
const MORTON_X: u128 = {
    let mut m = 0u128;
    let mut i = 0;
    while i < 42 {
        m |= 1 << (3 * i);
        i += 1;
    }
    m
};

/// The sort key of voxel `(lod, x, y, z)` under `D = max_lod`.
#[inline(always)]
pub fn leaf_key(lod: u8, x: u32, y: u32, z: u32, max_lod: u8) -> u128 {
    ((lod as u128) << (3 * max_lod as u32)) | morton3_fast(x, y, z)
}

/// Bits of a [`leaf_key`]: `3D + lod_bits`.
pub fn leaf_key_bits(p: &Params) -> u32 {
    3 * p.max_lod as u32 + p.lod_bits()
}

/// Appends the entries of triangle `prim` (grid units, already checked to be
/// finite and inside the closed scene cube) to `out`.
///
/// Candidate voxels are those at the primitive's LOD whose closed box meets
/// the triangle's AABB: per axis `floor(min / e) ..= min(floor(max / e),
/// 2^lod - 1)`. When there is one candidate, the triangle lies in it and its
/// box there is its AABB. Otherwise a candidate is kept when
/// [`triangle_overlaps_box`](crate::geom::overlap::triangle_overlaps_box) and [`clip_triangle_to_box`](crate::geom::clip::clip_triangle_to_box) both find contact,
/// and its box is the clipped AABB. Either box is quantized outward.
pub fn place_triangle(tri: &[DVec3; 3], prim: u32, p: &Params, out: &mut Vec<LeafEntry>) {
    place_triangle_with(tri, prim, p, out, &mut ClipScratch::new())
}

/// [`place_triangle`] with clip buffers reused across triangles, into
/// entries of either key type (`K = u64` only when [`leaf_key_bits`] `<= 64`).
pub fn place_triangle_with<K: LeafKey>(
    tri: &[DVec3; 3],
    prim: u32,
    p: &Params,
    out: &mut Vec<LeafEntry<K>>,
    scratch: &mut ClipScratch,
) {
    place_triangle_in::<K, Plain>(tri, prim, p, out, scratch)
}

/// [`place_triangle_with`] with the kernels computing in `L` (see
/// [`Lanes`]): the same entries whichever `L`. Inlined with its kernels
/// into the builder's AVX copy (see `build::place_range`).
#[inline(always)]
pub(crate) fn place_triangle_in<K: LeafKey, L: Lanes>(
    tri: &[DVec3; 3],
    prim: u32,
    p: &Params,
    out: &mut Vec<LeafEntry<K>>,
    scratch: &mut ClipScratch,
) {
    // The input is checked finite: see `PreparedTriangle::new_finite`.
    let prepared = PreparedTriangle::new_finite(tri);
    let (tlo, thi) = (prepared.lo, prepared.hi);
    let lod = primitive_lod(tri, tlo, thi, p.max_lod);
    let edge = p.voxel_edge(lod) as f64;
    let last = (1u64 << lod) - 1;
    let cells = p.quant_cells();
    let scale = cells as f64 / edge;
    // `v / edge` is `v` times the power of two `1 / edge`: exact either way
    // (an underflow rounds the same real quotient the same way), and a
    // product costs less than a division. A checked coordinate is in
    // `[0, 2^D]`, so the quotient is in `[0, 2^31]`.
    let inv_edge = 1.0 / edge;
    let voxel_of = |v: f64| (floor_ceil_in_scene(v * inv_edge).0 as u64).min(last) as u32;
    let i0 = glam::UVec3::new(voxel_of(tlo.x), voxel_of(tlo.y), voxel_of(tlo.z));
    let i1 = glam::UVec3::new(voxel_of(thi.x), voxel_of(thi.y), voxel_of(thi.z));
    let lod_key = (lod as u128) << (3 * p.max_lod as u32);

    // `v0` is the voxel's minimum corner, `(x, y, z) * edge`; `morton` the
    // voxel's Morton code. Both boxes lie in the closed voxel (the clip's
    // inside its box, the triangle's inside the one voxel that holds it),
    // as `quantize_in_voxel` asks.
    // The voxel's entry: a function, not a closure, so that it is inlined
    // (the closure was not) and the AVX copy's quantization is compiled
    // with AVX.
    #[inline(always)]
    fn entry<K: LeafKey, L: Lanes>(
        key: u128,
        prim: u32,
        (v0, blo, bhi): (DVec3, &P4, &P4),
        scale: f64,
        cells: u32,
    ) -> LeafEntry<K> {
        let (lo, hi) = L::quantize(blo, bhi, &P4::new(v0), scale, cells);
        LeafEntry {
            key: K::from_u128(key),
            prim,
            lo,
            hi,
        }
    }
    // Voxel corners are integers times a power of two, below 2^62: exact.
    let corner = |x: u32, y: u32, z: u32| DVec3::new(x as f64, y as f64, z as f64) * edge;

    if i0 == i1 {
        let v0 = corner(i0.x, i0.y, i0.z);
        let (blo, bhi) = (P4::new(tlo), P4::new(thi));
        let key = lod_key | morton3_fast(i0.x, i0.y, i0.z);
        out.push(entry::<K, L>(key, prim, (v0, &blo, &bhi), scale, cells));
        return;
    }
    let holds = VertexVoxels::new(tri, inv_edge, i0, i1);
    // The magnitude of the triangle and a candidate box (see
    // `PreparedTriangle::abs_max_element`), folded per loop level.
    let tri_scale = prepared.abs_max_element();
    // Made at the first candidate that needs the overlap test.
    let mut overlap_prep = None;
    // Exclusive ranges: an inclusive one carries an exhaustion flag through
    // every step. The ends are voxel indices below `2^31`, so `+ 1` fits.
    // Morton codes stepped per axis as `mx` below.
    let mut mz = morton3_fast(0, 0, i0.z);
    for z in i0.z..i1.z + 1 {
        let z0 = z as f64 * edge;
        let mz_here = mz;
        mz = ((mz | !(MORTON_X << 2)) + 1) & MORTON_X << 2;
        let scale_z = max_not_nan(tri_scale, z0 + edge);
        let mut my = morton3_fast(0, i0.y, 0);
        for y in i0.y..i1.y + 1 {
            let y0 = y as f64 * edge;
            let myz = my | mz_here;
            my = ((my | !(MORTON_X << 1)) + 1) & MORTON_X << 1;
            let scale_y = max_not_nan(scale_z, y0 + edge);
            let row = holds.row(y - i0.y, z - i0.z);
            // The voxel's Morton code, stepped along x: adding 1 to the x
            // bits with the other bits set carries through them exactly as
            // through x's own bits, so `mx` stays `morton3_fast(x, 0, 0)`.
            let mut mx = morton3_fast(i0.x, 0, 0);
            for x in i0.x..i1.x + 1 {
                let morton = myz | mx;
                debug_assert_eq!(morton, morton3_fast(x, y, z));
                mx = ((mx | !MORTON_X) + 1) & MORTON_X;
                let vlo = DVec3::new(x as f64 * edge, y0, z0);
                let vhi = vlo + DVec3::splat(edge);
                let box_scale = max_not_nan(scale_y, vhi.x);
                // A vertex in the closed voxel is contact, where the
                // conservative overlap test is true: skip computing it.
                let holds_vertex = row >> (x - i0.x) & 1 != 0;
                debug_assert_eq!(
                    holds_vertex,
                    tri.iter().any(|v| v.cmpge(vlo).all() && v.cmple(vhi).all())
                );
                if !holds_vertex {
                    let prep =
                        overlap_prep.get_or_insert_with(|| OverlapPrep::new(tri, edge, i0, i1));
                    let overlaps = if prep.exact {
                        overlaps_candidate_prepared(prep, &prepared, vlo, vhi, box_scale)
                    } else {
                        overlaps_candidate(&prepared, vlo, vhi, box_scale)
                    };
                    if !overlaps {
                        continue;
                    }
                }
                // A candidate's box meets the triangle's AABB, and both are
                // finite and below 2^32: what `clip_candidate` asks.
                if let Some((blo, bhi)) =
                    clip_candidate::<L>(&prepared, vlo, vhi, box_scale, scratch)
                {
                    let key = lod_key | morton;
                    out.push(entry::<K, L>(key, prim, (vlo, &blo, &bhi), scale, cells));
                }
            }
        }
    }
}

/// Which candidate voxels hold a vertex of the triangle, as bit masks: bit
/// `k` of `mask[v][a]` is set when vertex `v` lies in the closed slab of the
/// candidate `i0[a] + k` on axis `a`, so a voxel holds the vertex when its
/// three bits are set. Per axis, `t = v[a] / edge` is exact (a product by
/// the power of two `1 / edge`; an underflowed quotient is below any slab
/// but slab 0, whose test it passes either way), so `x edge <= v[a] <= (x + 1) edge` exactly
/// when `x <= t <= x + 1`, i.e. `ceil(t) - 1 <= x <= floor(t)`: the same
/// answer as comparing `v` with the voxel's corners: slab `f = floor(t)`,
/// and slab `f - 1` too when `t` is an integer. A candidate range is at
/// most 9 voxels per axis (a triangle's extent is about one voxel at its
/// base LOD, `2^SLIVER_LEVEL_CAP` at its LOD), far below the 63 a mask
/// holds here (checked).
struct VertexVoxels {
    mask: [[u64; 3]; 3],
}

impl VertexVoxels {
    #[inline(always)]
    fn new(tri: &[DVec3; 3], inv_edge: f64, i0: glam::UVec3, i1: glam::UVec3) -> VertexVoxels {
        assert!(
            (i1 - i0).max_element() < 63,
            "a candidate range of more than 63 voxels per axis"
        );
        let mut mask = [[0u64; 3]; 3];
        for (m, v) in mask.iter_mut().zip(tri) {
            for a in 0..3 {
                // A vertex lies in the candidates' AABB, so `f` is in
                // `i0[a] ..= i1[a] + 1` (`i1[a] + 1` for a vertex on the
                // scene's far face, in slab `f - 1` only): below 64 slabs
                // up, and the bit shifted out below slab 0 is dropped.
                let (f, c) = floor_ceil_in_scene(v[a] * inv_edge);
                let bit = 1u64 << (f - i0[a] as i64);
                m[a] = if c == f { bit | bit >> 1 } else { bit };
            }
        }
        VertexVoxels { mask }
    }

    /// The candidates `x` (bit `x - i0.x`) of row `(y, z)` (relative to `i0`)
    /// that hold a vertex.
    #[inline(always)]
    fn row(&self, y: u32, z: u32) -> u64 {
        let mut row = 0;
        for m in &self.mask {
            if m[1] >> y & m[2] >> z & 1 != 0 {
                row |= m[0];
            }
        }
        row
    }
}
