//! S402-S404: each primitive's LOD, the voxels at that LOD it really
//! intersects, and its box in each of them (SPEC.md sections 4.2-4.4).
//!
//! The output is one [`LeafEntry`] per (primitive, voxel): the hot path of
//! the build. It allocates nothing per triangle; entries go into one vector.

use glam::DVec3;

use super::lod::primitive_lod;
use super::quantize::{floor_nonneg, quantize_interval};
use super::radix::{morton3_fast, SortKey};
use crate::geom::clip::{clip_candidate, ClipScratch, PreparedTriangle};
use crate::geom::overlap::overlaps_candidate;
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
    // The input is checked finite: see `PreparedTriangle::new_finite`.
    let prepared = PreparedTriangle::new_finite(tri);
    let (tlo, thi) = (prepared.lo, prepared.hi);
    let lod = primitive_lod(tri, tlo, thi, p.max_lod);
    let edge = p.voxel_edge(lod) as f64;
    let last = (1u64 << lod) - 1;
    let cells = p.quant_cells();
    let scale = cells as f64 / edge;
    let voxel_of = |v: f64| floor_nonneg(v / edge).min(last) as u32;
    let i0 = glam::UVec3::new(voxel_of(tlo.x), voxel_of(tlo.y), voxel_of(tlo.z));
    let i1 = glam::UVec3::new(voxel_of(thi.x), voxel_of(thi.y), voxel_of(thi.z));

    // `v0` is the voxel's minimum corner, `(x, y, z) * edge`.
    let entry = |x: u32, y: u32, z: u32, v0: DVec3, blo: DVec3, bhi: DVec3| {
        let (lx, hx) = quantize_interval(blo.x, bhi.x, v0.x, scale, cells);
        let (ly, hy) = quantize_interval(blo.y, bhi.y, v0.y, scale, cells);
        let (lz, hz) = quantize_interval(blo.z, bhi.z, v0.z, scale, cells);
        LeafEntry {
            key: K::from_u128(leaf_key(lod, x, y, z, p.max_lod)),
            prim,
            lo: [lx, ly, lz],
            hi: [hx, hy, hz],
        }
    };
    let corner = |x: u32, y: u32, z: u32| DVec3::new(x as f64, y as f64, z as f64) * edge;

    if i0 == i1 {
        out.push(entry(i0.x, i0.y, i0.z, corner(i0.x, i0.y, i0.z), tlo, thi));
        return;
    }
    // Exclusive ranges: an inclusive one carries an exhaustion flag through
    // every step. The ends are voxel indices below `2^31`, so `+ 1` fits.
    for z in i0.z..i1.z + 1 {
        for y in i0.y..i1.y + 1 {
            for x in i0.x..i1.x + 1 {
                let vlo = corner(x, y, z);
                let vhi = vlo + DVec3::splat(edge);
                // A vertex in the closed voxel is contact, where the
                // conservative overlap test is true: skip computing it.
                let holds_vertex = tri.iter().any(|v| v.cmpge(vlo).all() && v.cmple(vhi).all());
                if !holds_vertex && !overlaps_candidate(&prepared, vlo, vhi) {
                    continue;
                }
                // A candidate's box meets the triangle's AABB, and both are
                // finite and below 2^32: what `clip_candidate` asks.
                if let Some((blo, bhi)) = clip_candidate(&prepared, vlo, vhi, scratch) {
                    out.push(entry(x, y, z, vlo, blo, bhi));
                }
            }
        }
    }
}
