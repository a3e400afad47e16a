//! A frozen copy of the builder as it was before the speed work (commit
//! bd58d2c): LOD, leaf placement with the Vec-based Sutherland–Hodgman clip
//! and the overlap test, radix sort, upper levels and store layout. The
//! identity tests and the build bench compare the optimized builder with it
//! bit for bit. Do not "improve" this file: its value is that it is old.
#![allow(dead_code, clippy::all)]

use glam::DVec3;
use golden::build::{check_grid_triangle, BuildError, GridMap};
use golden::mesh::Mesh;
use golden::store::Hierarchy;
use golden::Params;

/// `geom::ROUNDING_MARGIN_REL`, `magnitude`, `triangle_bounds` as they were.
pub mod geom {
    use glam::DVec3;
    pub const ROUNDING_MARGIN_REL: f64 = 1.0 / (1u64 << 40) as f64;
    pub fn magnitude(tri: &[DVec3; 3], lo: DVec3, hi: DVec3) -> f64 {
        let m = tri[0]
            .abs()
            .max(tri[1].abs())
            .max(tri[2].abs())
            .max(lo.abs())
            .max(hi.abs());
        m.max_element()
    }
    pub fn triangle_bounds(tri: &[DVec3; 3]) -> (DVec3, DVec3) {
        (
            tri[0].min(tri[1]).min(tri[2]),
            tri[0].max(tri[1]).max(tri[2]),
        )
    }
    pub mod clip {

        use glam::DVec3;

        use super::{
            magnitude, overlap::triangle_overlaps_box, triangle_bounds, ROUNDING_MARGIN_REL,
        };

        /// An AABB `(lo, hi)` inside `[lo, hi]` that contains every point of the
        /// closed triangle inside the closed box; `None` only when the two are
        /// certainly disjoint. Degenerate triangles (segments, points) are handled.
        pub fn clip_triangle_to_box(
            tri: &[DVec3; 3],
            lo: DVec3,
            hi: DVec3,
        ) -> Option<(DVec3, DVec3)> {
            let (tlo, thi) = triangle_bounds(tri);
            // Comparisons are exact, so disjoint AABBs are certainly disjoint.
            if tlo.cmpgt(hi).any() || thi.cmplt(lo).any() {
                return None;
            }
            let bounded_lo = tlo.max(lo);
            let bounded_hi = thi.min(hi);
            let fallback = || {
                if triangle_overlaps_box(tri, lo, hi) {
                    Some((bounded_lo, bounded_hi))
                } else {
                    None
                }
            };

            let m = ROUNDING_MARGIN_REL * magnitude(tri, lo, hi);
            let grown_lo = lo - DVec3::splat(m);
            let grown_hi = hi + DVec3::splat(m);
            let mut poly: Vec<DVec3> = tri.to_vec();
            for axis in 0..3 {
                poly = clip_against_plane(&poly, axis, grown_lo[axis], KeepSide::Above);
                poly = clip_against_plane(&poly, axis, grown_hi[axis], KeepSide::Below);
                if poly.is_empty() {
                    return fallback();
                }
            }
            let (plo, phi) = polygon_bounds(&poly);
            let out_lo = (plo - DVec3::splat(m)).max(bounded_lo);
            let out_hi = (phi + DVec3::splat(m)).min(bounded_hi);
            if out_lo.cmpgt(out_hi).any() {
                return fallback();
            }
            Some((out_lo, out_hi))
        }

        /// Which side of an axis-aligned plane survives a clip.
        #[derive(Clone, Copy)]
        enum KeepSide {
            /// Keep `p[axis] >= plane`.
            Above,
            /// Keep `p[axis] <= plane`.
            Below,
        }

        /// One Sutherland–Hodgman step: the part of the closed polygon on the kept
        /// side of the plane `p[axis] = plane`. A polygon of one or two vertices (a
        /// degenerate triangle after deduplication is not needed: repeated vertices
        /// are simply repeated) is clipped like any other.
        fn clip_against_plane(
            poly: &[DVec3],
            axis: usize,
            plane: f64,
            keep: KeepSide,
        ) -> Vec<DVec3> {
            let dist = |p: DVec3| match keep {
                KeepSide::Above => p[axis] - plane,
                KeepSide::Below => plane - p[axis],
            };
            let mut out = Vec::with_capacity(poly.len() + 2);
            for i in 0..poly.len() {
                let a = poly[i];
                let b = poly[(i + 1) % poly.len()];
                let (da, db) = (dist(a), dist(b));
                if da >= 0.0 {
                    out.push(a);
                }
                if (da >= 0.0) != (db >= 0.0) {
                    // The crossing point; t is in [0, 1] since da and db differ in sign.
                    let t = da / (da - db);
                    let mut p = a + (b - a) * t;
                    // Put the crossing exactly on the plane on its own axis.
                    p[axis] = plane;
                    out.push(p);
                }
            }
            out
        }

        fn polygon_bounds(poly: &[DVec3]) -> (DVec3, DVec3) {
            let mut lo = DVec3::splat(f64::INFINITY);
            let mut hi = DVec3::splat(f64::NEG_INFINITY);
            for &p in poly {
                lo = lo.min(p);
                hi = hi.max(p);
            }
            (lo, hi)
        }
    }
    pub mod overlap {

        use glam::DVec3;

        use super::{magnitude, ROUNDING_MARGIN_REL};

        /// True unless the closed triangle and the closed box `[lo, hi]` are
        /// certainly disjoint. Never false when they touch, even at one point; may be
        /// true when they miss by less than `2^-40` of the coordinates' magnitude.
        pub fn triangle_overlaps_box(tri: &[DVec3; 3], lo: DVec3, hi: DVec3) -> bool {
            let scale = magnitude(tri, lo, hi);
            let center = (lo + hi) * 0.5;
            let half = (hi - lo) * 0.5;
            let v = [tri[0] - center, tri[1] - center, tri[2] - center];
            let edges = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];

            let box_axes = [DVec3::X, DVec3::Y, DVec3::Z];
            for axis in box_axes {
                if separates(axis, &v, half, scale) {
                    return false;
                }
            }
            let normal = edges[0].cross(edges[1]);
            if separates(normal, &v, half, scale) {
                return false;
            }
            for e in edges {
                for b in box_axes {
                    if separates(e.cross(b), &v, half, scale) {
                        return false;
                    }
                }
            }
            true
        }

        /// True when `axis` certainly separates the triangle `v` (relative to the box
        /// center) from the box of half-extents `half`.
        fn separates(axis: DVec3, v: &[DVec3; 3], half: DVec3, scale: f64) -> bool {
            let p = [axis.dot(v[0]), axis.dot(v[1]), axis.dot(v[2])];
            let pmin = p[0].min(p[1]).min(p[2]);
            let pmax = p[0].max(p[1]).max(p[2]);
            let radius = half.dot(axis.abs());
            let margin = ROUNDING_MARGIN_REL * axis.abs().element_sum() * scale;
            pmin > radius + margin || pmax < -radius - margin
        }
    }
}
pub mod lod {

    use glam::DVec3;

    /// Most extra levels a sliver triangle goes below its base LOD: bounds the
    /// voxels one triangle can land in by about `(2^3 + 1)^3`.
    pub const SLIVER_LEVEL_CAP: u32 = 3;

    /// Smallest `k >= 0` with `2^k >= x`, for finite `x > 0` (0 for `x <= 1`).
    /// Exact: read from the binary64 exponent and mantissa, no logarithm.
    pub fn ceil_log2(x: f64) -> u32 {
        if x <= 1.0 {
            return 0;
        }
        let bits = x.to_bits();
        let exp = ((bits >> 52) & 0x7ff) as i64 - 1023; // x >= 1 is normal
        let mantissa = bits & ((1u64 << 52) - 1);
        (exp + (mantissa != 0) as i64) as u32
    }

    /// The base LOD: `D - ceil_log2(extent)`, at least 0, where `extent` is the
    /// AABB's largest side in grid units (a point or a side <= 1 gives `D`).
    pub fn base_lod(extent: f64, max_lod: u8) -> u8 {
        let k = ceil_log2(extent);
        (max_lod as u32).saturating_sub(k) as u8
    }

    /// Sliver levels: the largest `k <= SLIVER_LEVEL_CAP` with `r >= 2^(k+1)`,
    /// where `r = L / h = L^2 / (2 A)` is the longest edge over the height on it
    /// (an equilateral triangle has `r = 1.15`, a right isoceles one `r = 2`: both
    /// 0 levels; `r = 4` is the first sliver). Computed without division as
    /// `L2^2 >= 4^(k+1) * N2`, with `L2` the longest
    /// squared edge length and `N2 = |e0 x e1|^2 = (2 A)^2`, in binary64 in that
    /// operation order. A zero-area triangle with an edge (a segment) gets the
    /// cap; a point gets 0.
    pub fn sliver_levels(tri: &[DVec3; 3]) -> u32 {
        let e0 = tri[1] - tri[0];
        let e1 = tri[2] - tri[1];
        let e2 = tri[0] - tri[2];
        let l2 = e0
            .length_squared()
            .max(e1.length_squared())
            .max(e2.length_squared());
        if l2 == 0.0 {
            return 0;
        }
        let n2 = e0.cross(e1).length_squared();
        let lhs = l2 * l2;
        let mut k = SLIVER_LEVEL_CAP;
        while k > 0 {
            if lhs >= (1u64 << (2 * k + 2)) as f64 * n2 {
                return k;
            }
            k -= 1;
        }
        0
    }

    /// The primitive's LOD: `base_lod + sliver_levels` in `1..=D`. The one
    /// change since the freeze is SPEC 4.2's rule that no primitive sits at
    /// LOD 0 (`golden::build::lod::MIN_PRIMITIVE_LOD`): a rule, not speed.
    pub fn primitive_lod(tri: &[DVec3; 3], lo: DVec3, hi: DVec3, max_lod: u8) -> u8 {
        let extent = (hi - lo).max_element();
        let base = base_lod(extent, max_lod) as u32;
        (base + sliver_levels(tri)).clamp(1, max_lod as u32) as u8
    }
}
pub mod quantize {

    /// Quantizes the grid-unit interval `[a, b]` (inside the closed voxel
    /// `[v0, v0 + edge]`) into cells of `edge / 2^Q`:
    /// `lo = floor((a - v0) 2^Q / edge)`, `hi = ceil((b - v0) 2^Q / edge) - 1`,
    /// then `lo` clamped to `[0, 2^Q - 1]` and `hi` to `[lo, 2^Q - 1]`.
    ///
    /// Exact in binary64: `v0` and `edge` are powers-of-two multiples below
    /// `2^31`, `a - v0` is exact by Sterbenz's lemma when `v0 > 0` (because
    /// `v0 <= a <= v0 + edge <= 2 v0`) and trivially when `v0 = 0`, and the scale
    /// `2^Q / edge` is a power of two. An `a` or `b` slightly outside the voxel
    /// only meets the clamps.
    ///
    /// Floor and ceiling are taken through the float-to-integer conversion
    /// (truncation, saturating at 0 for negative values, which is the clamp) to
    /// stay off the C library's `floor` on baseline x86-64.
    pub fn quantize_interval(a: f64, b: f64, v0: f64, scale: f64, cells: u32) -> (u16, u16) {
        let top = cells as u64 - 1;
        let lo = floor_nonneg((a - v0) * scale).min(top);
        let hi = ceil_nonneg((b - v0) * scale)
            .saturating_sub(1)
            .clamp(lo, top);
        (lo as u16, hi as u16)
    }

    /// `floor(t)` for `t >= 0`, and 0 for `t < 0` (finite `t`).
    #[inline(always)]
    pub fn floor_nonneg(t: f64) -> u64 {
        t as u64
    }

    /// `ceil(t)` for `t >= 0`, and 0 for `t < 0` (finite `t`).
    #[inline(always)]
    pub fn ceil_nonneg(t: f64) -> u64 {
        let f = t as u64;
        f + ((f as f64) < t) as u64
    }

    /// The cells of the parent voxel (one LOD up) covering a child's cells
    /// `lo..=hi` on one axis, where `odd` is the child's coordinate bit on that
    /// axis (which half of the parent it is in). In child cells relative to the
    /// parent's minimum corner the child box is `[A, B) = [odd 2^Q + lo,
    /// odd 2^Q + hi + 1)`; parent cells are twice as wide, so outward rounding
    /// gives `floor(A / 2)` and `ceil(B / 2) - 1`. Always inside `[0, 2^Q - 1]`.
    pub fn child_cells_in_parent(lo: u16, hi: u16, odd: bool, quant_bits: u8) -> (u16, u16) {
        let base = (odd as u32) << quant_bits;
        let a = base + lo as u32;
        let b = base + hi as u32 + 1;
        ((a >> 1) as u16, (b.div_ceil(2) - 1) as u16)
    }
}
pub mod radix {

    /// Bits per radix digit: 2^11 counters (8 KiB) per pass stay in L1.
    const DIGIT_BITS: u32 = 11;
    const BUCKETS: usize = 1 << DIGIT_BITS;

    /// Stable LSD radix sort of `items` by the low `key_bits` bits of `key`.
    /// `scratch` is reused storage (its contents are discarded). Histograms of
    /// all passes are taken in one read; a pass whose digit is the same for every
    /// item is skipped, since it would not move anything.
    pub fn radix_sort<T: Copy>(
        items: &mut Vec<T>,
        scratch: &mut Vec<T>,
        key_bits: u32,
        key: impl Fn(&T) -> u128,
    ) {
        let n = items.len();
        if n < 2 || key_bits == 0 {
            return;
        }
        let passes = key_bits.div_ceil(DIGIT_BITS) as usize;
        let mut hist = vec![[0u32; BUCKETS]; passes];
        for it in items.iter() {
            let k = key(it);
            for (p, h) in hist.iter_mut().enumerate() {
                h[digit(k, p)] += 1;
            }
        }
        scratch.clear();
        scratch.reserve(n);
        // Safety-free: fill scratch with copies so it has length n; every slot is
        // overwritten by the scatter below.
        scratch.extend_from_slice(items);
        for (p, h) in hist.iter().enumerate() {
            if h.iter().any(|&c| c as usize == n) {
                continue;
            }
            let mut offsets = [0u32; BUCKETS];
            let mut sum = 0u32;
            for (o, &c) in offsets.iter_mut().zip(h.iter()) {
                *o = sum;
                sum += c;
            }
            for it in items.iter() {
                let d = digit(key(it), p);
                scratch[offsets[d] as usize] = *it;
                offsets[d] += 1;
            }
            std::mem::swap(items, scratch);
        }
    }

    #[inline(always)]
    fn digit(k: u128, pass: usize) -> usize {
        ((k >> (pass as u32 * DIGIT_BITS)) as usize) & (BUCKETS - 1)
    }

    /// Spreads the low 21 bits of `v` so that bit `i` lands at bit `3i`.
    #[inline(always)]
    fn spread21(v: u64) -> u64 {
        let mut x = v & 0x1f_ffff;
        x = (x | x << 32) & 0x001f_0000_0000_ffff;
        x = (x | x << 16) & 0x001f_0000_ff00_00ff;
        x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
        x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
        x = (x | x << 2) & 0x1249_2492_4924_9249;
        x
    }

    /// The same code as [`golden::grid::morton3`], computed with masks instead of
    /// a bit loop (the builder computes one per primitive and voxel).
    #[inline(always)]
    pub fn morton3_fast(x: u32, y: u32, z: u32) -> u128 {
        let s = |v: u32| spread21(v as u64) as u128 | (spread21((v >> 21) as u64) as u128) << 63;
        s(x) | s(y) << 1 | s(z) << 2
    }
}
pub mod leaves {

    use glam::DVec3;

    use super::geom::{clip::clip_triangle_to_box, overlap::triangle_overlaps_box};
    use super::lod::primitive_lod;
    use super::quantize::{floor_nonneg, quantize_interval};
    use super::radix::morton3_fast;
    use golden::params::Params;

    /// A primitive in one leaf voxel, with its box there in that voxel's cells.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub struct LeafEntry {
        /// `(lod << 3D) | morton(x, y, z)`: sorting by it sorts by LOD, then Morton.
        pub key: u128,
        /// Triangle index.
        pub prim: u32,
        pub lo: [u16; 3],
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
    /// [`triangle_overlaps_box`] and [`clip_triangle_to_box`] both find contact,
    /// and its box is the clipped AABB. Either box is quantized outward.
    pub fn place_triangle(tri: &[DVec3; 3], prim: u32, p: &Params, out: &mut Vec<LeafEntry>) {
        let tlo = tri[0].min(tri[1]).min(tri[2]);
        let thi = tri[0].max(tri[1]).max(tri[2]);
        let lod = primitive_lod(tri, tlo, thi, p.max_lod);
        let edge = p.voxel_edge(lod) as f64;
        let last = (1u64 << lod) - 1;
        let cells = p.quant_cells();
        let scale = cells as f64 / edge;
        let voxel_of = |v: f64| floor_nonneg(v / edge).min(last) as u32;
        let i0 = glam::UVec3::new(voxel_of(tlo.x), voxel_of(tlo.y), voxel_of(tlo.z));
        let i1 = glam::UVec3::new(voxel_of(thi.x), voxel_of(thi.y), voxel_of(thi.z));

        let entry = |x: u32, y: u32, z: u32, blo: DVec3, bhi: DVec3| {
            let v0 = DVec3::new(x as f64, y as f64, z as f64) * edge;
            let mut lo = [0u16; 3];
            let mut hi = [0u16; 3];
            for a in 0..3 {
                (lo[a], hi[a]) = quantize_interval(blo[a], bhi[a], v0[a], scale, cells);
            }
            LeafEntry {
                key: leaf_key(lod, x, y, z, p.max_lod),
                prim,
                lo,
                hi,
            }
        };

        if i0 == i1 {
            out.push(entry(i0.x, i0.y, i0.z, tlo, thi));
            return;
        }
        for z in i0.z..=i1.z {
            for y in i0.y..=i1.y {
                for x in i0.x..=i1.x {
                    let vlo = DVec3::new(x as f64, y as f64, z as f64) * edge;
                    let vhi = vlo + DVec3::splat(edge);
                    // A vertex in the closed voxel is contact, where the
                    // conservative overlap test is true: skip computing it.
                    let holds_vertex = tri.iter().any(|v| v.cmpge(vlo).all() && v.cmple(vhi).all());
                    if !holds_vertex && !triangle_overlaps_box(tri, vlo, vhi) {
                        continue;
                    }
                    if let Some((blo, bhi)) = clip_triangle_to_box(tri, vlo, vhi) {
                        out.push(entry(x, y, z, blo, bhi));
                    }
                }
            }
        }
    }
}
pub mod upper {

    use super::leaves::LeafEntry;
    use super::quantize::child_cells_in_parent;
    use golden::build::BuildError;
    use golden::grid::VoxelAddr;
    use golden::params::Params;
    use golden::store::{Hierarchy, NodeRecord, Reference};

    /// A node while its level is being built. A *base* node is given by the
    /// caller (the builder: every leaf; the merger: the nodes of S610-S614) and
    /// its `first`/`count` mean what the caller says (the builder: the sorted
    /// entries = `prims`); a grouped node (`base = false`, made by
    /// [`group_by_parent`]) has `first`/`count` indexing the level below.
    #[derive(Clone, Copy, Debug)]
    pub struct LevelNode {
        pub morton: u128,
        pub x: u32,
        pub y: u32,
        pub z: u32,
        pub leaf: bool,
        pub base: bool,
        pub lo: [u16; 3],
        pub hi: [u16; 3],
        pub first: u32,
        pub count: u32,
    }

    /// Inverse of the 21-bit spread: gathers bits `3i` into bit `i`.
    fn compact21(v: u64) -> u32 {
        let mut x = v & 0x1249_2492_4924_9249;
        x = (x ^ (x >> 2)) & 0x10c3_0c30_c30c_30c3;
        x = (x ^ (x >> 4)) & 0x100f_00f0_0f00_f00f;
        x = (x ^ (x >> 8)) & 0x001f_0000_ff00_00ff;
        x = (x ^ (x >> 16)) & 0x001f_0000_0000_ffff;
        x = (x ^ (x >> 32)) & 0x1f_ffff;
        x as u32
    }

    /// The coordinate at bit offset `axis` of a Morton code.
    fn morton_coord(m: u128, axis: u32) -> u32 {
        let m = m >> axis;
        compact21(m as u64 & ((1u64 << 63) - 1)) | compact21((m >> 63) as u64) << 21
    }

    /// Groups the sorted entries into one leaf per (LOD, voxel); returns the
    /// leaves of each LOD (index = LOD), each list in Morton order.
    fn leaves_by_lod(entries: &[LeafEntry], p: &Params) -> Vec<Vec<LevelNode>> {
        let shift = 3 * p.max_lod as u32;
        let mut out = vec![Vec::new(); p.max_lod as usize + 1];
        let mut i = 0;
        while i < entries.len() {
            let key = entries[i].key;
            let mut lo = entries[i].lo;
            let mut hi = entries[i].hi;
            let mut j = i + 1;
            while j < entries.len() && entries[j].key == key {
                for a in 0..3 {
                    lo[a] = lo[a].min(entries[j].lo[a]);
                    hi[a] = hi[a].max(entries[j].hi[a]);
                }
                j += 1;
            }
            let morton = key & ((1u128 << shift) - 1);
            out[(key >> shift) as usize].push(LevelNode {
                morton,
                x: morton_coord(morton, 0),
                y: morton_coord(morton, 1),
                z: morton_coord(morton, 2),
                leaf: true,
                base: true,
                lo,
                hi,
                first: i as u32,
                count: (j - i) as u32,
            });
            i = j;
        }
        out
    }

    /// One inner node per parent voxel of `level` (sorted by Morton, so the
    /// children of a parent are a contiguous run); the parent's box is the union
    /// of its children's boxes rounded outward into its own cells.
    #[allow(clippy::needless_range_loop)] // per-axis loops over parallel arrays
    pub fn group_by_parent(level: &[LevelNode], quant_bits: u8) -> Vec<LevelNode> {
        let mut out = Vec::with_capacity(level.len() / 2 + 1);
        let mut i = 0;
        while i < level.len() {
            let pm = level[i].morton >> 3;
            let mut node = LevelNode {
                morton: pm,
                x: level[i].x >> 1,
                y: level[i].y >> 1,
                z: level[i].z >> 1,
                leaf: false,
                base: false,
                lo: [u16::MAX; 3],
                hi: [0; 3],
                first: i as u32,
                count: 0,
            };
            let mut j = i;
            while j < level.len() && level[j].morton >> 3 == pm {
                let c = &level[j];
                let odd = [c.x & 1 == 1, c.y & 1 == 1, c.z & 1 == 1];
                for a in 0..3 {
                    let (l, h) = child_cells_in_parent(c.lo[a], c.hi[a], odd[a], quant_bits);
                    node.lo[a] = node.lo[a].min(l);
                    node.hi[a] = node.hi[a].max(h);
                }
                j += 1;
            }
            node.count = (j - i) as u32;
            out.push(node);
            i = j;
        }
        out
    }

    /// Merges the inner nodes and the leaves of one LOD, both in Morton order;
    /// at the same voxel the inner node comes first.
    fn merge_level(inner: Vec<LevelNode>, leaves: Vec<LevelNode>) -> Vec<LevelNode> {
        if leaves.is_empty() {
            return inner;
        }
        let mut out = Vec::with_capacity(inner.len() + leaves.len());
        let (mut a, mut b) = (inner.into_iter().peekable(), leaves.into_iter().peekable());
        loop {
            let take_inner = match (a.peek(), b.peek()) {
                (Some(i), Some(l)) => i.morton <= l.morton,
                (Some(_), None) => true,
                (None, Some(_)) => false,
                (None, None) => break,
            };
            out.push(if take_inner { a.next() } else { b.next() }.expect("peeked"));
        }
        out
    }

    /// The top rule's exception: a single inner LOD-0 node whose box covers more
    /// than half the scene, `(hx-lx+1)(hy-ly+1)(hz-lz+1) * 2 > 2^(3Q)`, exactly.
    pub fn covers_most_of_scene(n: &LevelNode, quant_bits: u8) -> bool {
        let cells: u64 = (0..3).map(|a| (n.hi[a] - n.lo[a]) as u64 + 1).product();
        cells * 2 > 1u64 << (3 * quant_bits as u32)
    }

    fn check_index(what: &'static str, value: u64, p: &Params) -> Result<(), BuildError> {
        if value >= p.index_capacity() {
            return Err(BuildError::IndexOverflow {
                what,
                value,
                index_bits: p.index_bits,
            });
        }
        Ok(())
    }

    /// The levels of a hierarchy over `base` (index = LOD, each list in Morton
    /// order): from the deepest base level up, each level is the grouping of the
    /// one below merged with that LOD's base nodes, until the top rule stops it
    /// (SPEC.md section 4). Returns the levels (`levels[d]` for `d <= deepest`,
    /// empty above the top) and the top LOD; `None` when `base` is empty. Shared
    /// by the builder (S408) and the merger (S616).
    pub fn build_levels(
        mut base: Vec<Vec<LevelNode>>,
        p: &Params,
    ) -> Option<(Vec<Vec<LevelNode>>, usize)> {
        let deepest = base.iter().rposition(|l| !l.is_empty())?;
        let shallowest_base = base.iter().position(|l| !l.is_empty())?;

        // levels[d]: the nodes of LOD d, in store order.
        let mut levels: Vec<Vec<LevelNode>> = vec![Vec::new(); deepest + 1];
        let mut d = deepest;
        levels[d] = std::mem::take(&mut base[d]);
        while !(d == 0 || (levels[d].len() == 1 && d <= shallowest_base)) {
            let parents = group_by_parent(&levels[d], p.quant_bits);
            levels[d - 1] = merge_level(parents, std::mem::take(&mut base[d - 1]));
            d -= 1;
        }
        let mut top = d;
        // Only a grouped root can give way to its children: they are level 1.
        if top == 0
            && levels[0].len() == 1
            && !levels[0][0].base
            && covers_most_of_scene(&levels[0][0], p.quant_bits)
        {
            top = 1;
        }
        Some((levels, top))
    }

    /// Builds the hierarchy from entries sorted by key (then primitive index).
    pub fn assemble(entries: &[LeafEntry], p: &Params, id: u8) -> Result<Hierarchy, BuildError> {
        let (levels, top) =
            build_levels(leaves_by_lod(entries, p), p).ok_or(BuildError::EmptyMesh)?;
        let deepest = levels.len() - 1;

        let mut offset = vec![0u64; deepest + 2];
        for lod in top..=deepest {
            offset[lod + 1] = offset[lod] + levels[lod].len() as u64;
        }
        let total_nodes = offset[deepest + 1];
        check_index("node count - 1", total_nodes.saturating_sub(1), p)?;
        check_index(
            "prims length - 1",
            (entries.len() as u64).saturating_sub(1),
            p,
        )?;

        let mut nodes = Vec::with_capacity(total_nodes as usize);
        let mut refs = Vec::with_capacity(total_nodes as usize);
        for lod in top..=deepest {
            for n in &levels[lod] {
                check_index("count", n.count as u64, p)?;
                let first = if n.leaf {
                    n.first
                } else {
                    let first = refs.len() as u32;
                    for c in 0..n.count as u64 {
                        let child = offset[lod + 1] + n.first as u64 + c;
                        refs.push(Reference {
                            hier: id,
                            node: child as u32,
                        });
                    }
                    first
                };
                nodes.push(NodeRecord {
                    leaf: n.leaf,
                    voxel: VoxelAddr::new(lod as u8, n.x, n.y, n.z),
                    lo: n.lo,
                    hi: n.hi,
                    first,
                    count: n.count,
                });
            }
        }
        check_index("refs length - 1", (refs.len() as u64).saturating_sub(1), p)?;
        Ok(Hierarchy {
            id,
            params: *p,
            nodes,
            refs,
            prims: entries.iter().map(|e| e.prim).collect(),
            root_count: levels[top].len() as u32,
            top_lod: top as u8,
        })
    }
}

/// The reference `build`.
pub fn build(
    mesh: &Mesh,
    grid: &GridMap,
    params: &Params,
    id: u8,
) -> Result<Hierarchy, BuildError> {
    let tris = grid.mesh_to_grid(mesh, params)?;
    build_grid_triangles(&tris, params, id)
}

/// The reference `build_grid_triangles` (errors are not its point: inputs
/// are checked like the real builder's).
pub fn build_grid_triangles(
    tris: &[[DVec3; 3]],
    params: &Params,
    id: u8,
) -> Result<Hierarchy, BuildError> {
    params.validate()?;
    if tris.is_empty() {
        return Err(BuildError::EmptyMesh);
    }
    let mut entries = Vec::with_capacity(tris.len() * 4);
    for (i, tri) in tris.iter().enumerate() {
        check_grid_triangle(tri, i, params)?;
        leaves::place_triangle(tri, i as u32, params, &mut entries);
    }
    let mut scratch = Vec::new();
    radix::radix_sort(
        &mut entries,
        &mut scratch,
        leaves::leaf_key_bits(params),
        |e| e.key,
    );
    upper::assemble(&entries, params, id)
}

/// The reference leaf phase alone, for the bench.
pub fn place_all(tris: &[[DVec3; 3]], params: &Params, out: &mut Vec<leaves::LeafEntry>) {
    out.clear();
    for (i, tri) in tris.iter().enumerate() {
        leaves::place_triangle(tri, i as u32, params, out);
    }
}
