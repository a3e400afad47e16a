//! Conservative clipping of a triangle to a box: the box of the part of the
//! triangle inside it, as the builder's leaf box (Sutherland–Hodgman).
//!
//! The polygon is clipped against the six planes of the box grown by the
//! margin `m = ROUNDING_MARGIN_REL * M` (see [`super`]), its vertices' AABB is
//! grown by `m` again and intersected with the box itself. Growing the
//! clipping box first keeps a triangle that only touches the box (at a corner,
//! an edge, or lying in a face) from being clipped away by rounding: the grown
//! box holds a neighbourhood of width `m` around every contact, much wider
//! than any rounding error. If clipping nevertheless leaves nothing while the
//! overlap test cannot rule out contact, the answer falls back to the
//! intersection of the triangle's AABB with the box, which is always
//! conservative.

use glam::DVec3;

use super::lanes::{Lanes, Plain, P4};
use super::overlap::triangle_overlaps_box_prepared;
use super::{magnitude, triangle_bounds, ROUNDING_MARGIN_REL};

/// What the kernels need of a triangle whatever the box: its vertices, AABB,
/// per-axis largest magnitude and finiteness, computed once for the many
/// voxels the builder tests it against. Every value is the one the kernels
/// computed per box before, by the same operations in the same order.
#[derive(Clone, Copy, Debug)]
pub struct PreparedTriangle {
    /// The vertices.
    pub tri: [DVec3; 3],
    /// The vertices' AABB.
    pub lo: DVec3,
    /// The vertices' AABB.
    pub hi: DVec3,
    /// `|v0|.max(|v1|).max(|v2|)`: the triangle's part of the magnitude.
    abs_max: DVec3,
    /// Every coordinate finite.
    finite: bool,
    /// The vertices in lanes, as the clip's polygon starts.
    lanes: [P4; 3],
}

impl PreparedTriangle {
    /// Prepares `tri`.
    #[inline]
    pub fn new(tri: &[DVec3; 3]) -> PreparedTriangle {
        let (lo, hi) = triangle_bounds(tri);
        PreparedTriangle {
            tri: *tri,
            lo,
            hi,
            abs_max: tri[0].abs().max(tri[1].abs()).max(tri[2].abs()),
            finite: tri.iter().all(|v| v.is_finite()),
            lanes: tri.map(P4::new),
        }
    }

    /// [`Self::new`] of a finite triangle (the builder's, checked), with
    /// `min_not_nan` and `max_not_nan` for the NaN-passing `min`/`max`:
    /// the same bits (the same operands folded in the same order, and the
    /// same operand kept on a tie), and its AABB `(lo, hi)` for the caller.
    #[inline(always)]
    pub fn new_finite(tri: &[DVec3; 3]) -> PreparedTriangle {
        debug_assert!(tri.iter().all(|v| v.is_finite()));
        let lo = min3(min3(tri[0], tri[1]), tri[2]);
        let hi = max3(max3(tri[0], tri[1]), tri[2]);
        let abs_max = max3(max3(tri[0].abs(), tri[1].abs()), tri[2].abs());
        debug_assert!({
            let bits = |v: DVec3| v.to_array().map(f64::to_bits);
            let p = PreparedTriangle::new(tri);
            [p.lo, p.hi, p.abs_max].map(bits) == [lo, hi, abs_max].map(bits)
        });
        PreparedTriangle {
            tri: *tri,
            lo,
            hi,
            abs_max,
            finite: true,
            lanes: tri.map(P4::new),
        }
    }

    /// `geom::magnitude(tri, lo, hi)`, continuing its fold from the
    /// triangle's part (`max` of non-negative values: the same result).
    #[inline(always)]
    pub(crate) fn magnitude(&self, lo: DVec3, hi: DVec3) -> f64 {
        let m = self.abs_max.max(lo.abs()).max(hi.abs()).max_element();
        debug_assert_eq!(m.to_bits(), magnitude(&self.tri, lo, hi).to_bits());
        m
    }

    /// [`Self::magnitude`] of a finite triangle and box, with
    /// [`max_not_nan`]: the same bits, since every operand is an absolute
    /// value (never NaN here, never `-0.0`), so equal operands are equal
    /// bits and the order of the fold does not matter.
    #[inline(always)]
    pub(crate) fn magnitude_finite(&self, lo: DVec3, hi: DVec3) -> f64 {
        let v = max3(max3(self.abs_max, lo.abs()), hi.abs());
        let m = max_not_nan(max_not_nan(v.x, v.y), v.z);
        debug_assert_eq!(m.to_bits(), magnitude(&self.tri, lo, hi).to_bits());
        m
    }

    /// The largest absolute coordinate of the triangle: with a box of
    /// non-negative corners `[lo, hi]`, `geom::magnitude` is the `max` of it
    /// and `hi`'s coordinates (a `max` of non-negative values is the largest
    /// one, whatever the order, and `|lo| <= |hi|`).
    #[inline(always)]
    pub fn abs_max_element(&self) -> f64 {
        max_not_nan(max_not_nan(self.abs_max.x, self.abs_max.y), self.abs_max.z)
    }

    /// Every coordinate of the triangle is finite.
    #[inline(always)]
    pub(crate) fn is_finite(&self) -> bool {
        self.finite
    }
}

/// An AABB `(lo, hi)` inside `[lo, hi]` that contains every point of the
/// closed triangle inside the closed box; `None` only when the two are
/// certainly disjoint. Degenerate triangles (segments, points) are handled.
pub fn clip_triangle_to_box(tri: &[DVec3; 3], lo: DVec3, hi: DVec3) -> Option<(DVec3, DVec3)> {
    clip_triangle_to_box_with(tri, lo, hi, &mut ClipScratch::new())
}

/// Reusable polygon buffers for [`clip_triangle_to_box_with`], so that a
/// caller clipping many times (the builder) sets them up once.
pub struct ClipScratch {
    polys: [Polygon; 2],
}

impl ClipScratch {
    /// Fresh buffers.
    pub fn new() -> ClipScratch {
        ClipScratch {
            polys: [Polygon::empty(), Polygon::empty()],
        }
    }
}

impl Default for ClipScratch {
    fn default() -> Self {
        ClipScratch::new()
    }
}

/// [`clip_triangle_to_box`] with caller-provided buffers; the same result,
/// bit for bit.
///
/// A clip step whose plane has every vertex on its kept side returns its
/// input unchanged (no vertex dropped, no crossing), so it is skipped: with
/// finite coordinates `p - plane >= 0` exactly when `p >= plane`, so the
/// test "the polygon's minimum is at or above the plane" decides it without
/// looking at the vertices again. With a non-finite coordinate nothing is
/// skipped, as the plain algorithm would do.
pub fn clip_triangle_to_box_with(
    tri: &[DVec3; 3],
    lo: DVec3,
    hi: DVec3,
    scratch: &mut ClipScratch,
) -> Option<(DVec3, DVec3)> {
    clip_prepared(&PreparedTriangle::new(tri), lo, hi, scratch)
}

/// [`clip_triangle_to_box`] of a prepared triangle, with reused buffers; the
/// same result, bit for bit.
pub fn clip_prepared(
    pt: &PreparedTriangle,
    lo: DVec3,
    hi: DVec3,
    scratch: &mut ClipScratch,
) -> Option<(DVec3, DVec3)> {
    let (tlo, thi) = (pt.lo, pt.hi);
    // Comparisons are exact, so disjoint AABBs are certainly disjoint.
    if tlo.cmpgt(hi).any() || thi.cmplt(lo).any() {
        return None;
    }
    if pt.is_finite() && lo.is_finite() && hi.is_finite() {
        let scale = pt.magnitude_finite(lo, hi);
        if scale < FINITE_CLIP_LIMIT {
            return clip_finite::<Plain>(pt, lo, hi, scale, scratch)
                .map(|(l, h)| (l.xyz(), h.xyz()));
        }
    }
    clip_general(pt, lo, hi, scratch)
}

/// [`clip_prepared`] for a box the builder tries: the caller guarantees
/// that the triangle and the box are finite, of magnitude below `2^32`, and
/// that their AABBs meet (the box is a candidate voxel, from the triangle's
/// AABB), and passes their magnitude `scale` (`geom::magnitude`, which it
/// computes once for this and [`crate::geom::overlap::overlaps_candidate`]).
/// [`clip_prepared`] would then skip none of its checks' other branches, so
/// this is `clip_finite` without them: the same bits. `L` is how the
/// points are computed on (see [`Lanes`]): the same bits either way. The
/// box comes in lanes, for the caller's quantization in lanes.
#[inline(always)]
pub(crate) fn clip_candidate<L: Lanes>(
    pt: &PreparedTriangle,
    lo: DVec3,
    hi: DVec3,
    scale: f64,
    scratch: &mut ClipScratch,
) -> Option<(P4, P4)> {
    debug_assert!(pt.is_finite() && lo.is_finite() && hi.is_finite());
    debug_assert!(!(pt.lo.cmpgt(hi).any() || pt.hi.cmplt(lo).any()));
    debug_assert_eq!(scale.to_bits(), pt.magnitude_finite(lo, hi).to_bits());
    debug_assert!(scale < FINITE_CLIP_LIMIT);
    clip_finite::<L>(pt, lo, hi, scale, scratch)
}

/// Below this magnitude no value of [`clip_finite`] overflows: distances
/// to a plane and their differences stay below `4 * 2^500`, and `t` is in
/// `[0, 1]`.
const FINITE_CLIP_LIMIT: f64 = 1e150;

/// `f64::min` for operands that are not NaN, as one `minsd`: the same
/// value, and on equal operands (`0.0` and `-0.0`) the same one, `a`, as
/// `f64::min` returns here (checked bit for bit against the frozen
/// reference clip by `tests/build_identity.rs`). `f64::min` costs about eight
/// instructions on baseline x86-64 to pass NaN through, and the clip folds
/// every vertex of every step through six of them.
#[inline(always)]
pub(crate) fn min_not_nan(a: f64, b: f64) -> f64 {
    if b < a {
        b
    } else {
        a
    }
}

/// `f64::max` for operands that are not NaN: see [`min_not_nan`].
#[inline(always)]
pub(crate) fn max_not_nan(a: f64, b: f64) -> f64 {
    if b > a {
        b
    } else {
        a
    }
}

/// `f` per component.
#[inline(always)]
fn per_component(a: DVec3, b: DVec3, f: impl Fn(f64, f64) -> f64) -> DVec3 {
    DVec3::new(f(a.x, b.x), f(a.y, b.y), f(a.z, b.z))
}

/// [`min_not_nan`] per component.
#[inline(always)]
fn min3(a: DVec3, b: DVec3) -> DVec3 {
    per_component(a, b, min_not_nan)
}

/// [`max_not_nan`] per component.
#[inline(always)]
fn max3(a: DVec3, b: DVec3) -> DVec3 {
    per_component(a, b, max_not_nan)
}

/// [`clip_prepared`] when the triangle and the box are finite and their
/// magnitude `scale` is below [`FINITE_CLIP_LIMIT`] (the builder's only
/// case): every value is finite, so `min`/`max` become [`min_not_nan`] and
/// [`max_not_nan`], a step whose plane has every vertex on its kept side is
/// skipped (it would return its input: see [`clip_triangle_to_box_with`]),
/// and the polygon's bounds are folded while its vertices are written, in
/// the order [`Polygon::bounds`] folds them. Each step is one instance of
/// [`clip_step`] per axis and side, so the axis is a constant. The same
/// operations on the same values in the same order as [`clip_general`]: the
/// same bits.
#[inline(always)]
fn clip_finite<L: Lanes>(
    pt: &PreparedTriangle,
    lo: DVec3,
    hi: DVec3,
    scale: f64,
    scratch: &mut ClipScratch,
) -> Option<(P4, P4)> {
    let fallback = |bounded_lo, bounded_hi| {
        clip_fallback(pt, lo, hi, bounded_lo, bounded_hi).map(|(l, h)| (P4::new(l), P4::new(h)))
    };
    let bounded_lo = max3(pt.lo, lo);
    let bounded_hi = min3(pt.hi, hi);
    let m = ROUNDING_MARGIN_REL * scale;
    let grown_lo = lo - DVec3::splat(m);
    let grown_hi = hi + DVec3::splat(m);
    let [a, b] = &mut scratch.polys;
    let (mut cur, mut next) = (a, b);
    cur.set_lanes(&pt.lanes);
    let (mut plo, mut phi) = (P4::new(pt.lo), P4::new(pt.hi));
    macro_rules! step {
        ($axis:literal, $above:literal, $plane:expr) => {
            match clip_step::<L, $axis, $above>(cur, next, $plane) {
                Some((l, h)) => {
                    (plo, phi) = (L::store(l), L::store(h));
                    std::mem::swap(&mut cur, &mut next);
                }
                None => return fallback(bounded_lo, bounded_hi),
            }
        };
    }
    if plo.0[0] < grown_lo.x {
        step!(0, true, grown_lo.x);
    }
    if phi.0[0] > grown_hi.x {
        step!(0, false, grown_hi.x);
    }
    if plo.0[1] < grown_lo.y {
        step!(1, true, grown_lo.y);
    }
    if phi.0[1] > grown_hi.y {
        step!(1, false, grown_hi.y);
    }
    if plo.0[2] < grown_lo.z {
        step!(2, true, grown_lo.z);
    }
    if phi.0[2] > grown_hi.z {
        step!(2, false, grown_hi.z);
    }
    let m4 = L::splat(m);
    let out_lo = L::max(L::sub(L::load(&plo), m4), L::load(&P4::new(bounded_lo)));
    let out_hi = L::min(L::add(L::load(&phi), m4), L::load(&P4::new(bounded_hi)));
    let (out_lo, out_hi) = (L::store(out_lo), L::store(out_hi));
    if (0..3).any(|a| out_lo.0[a] > out_hi.0[a]) {
        return fallback(bounded_lo, bounded_hi);
    }
    Some((out_lo, out_hi))
}

/// What the clip answers when clipping left nothing: the box of the
/// triangle's AABB in the box, unless the overlap test rules contact out.
#[cold]
fn clip_fallback(
    pt: &PreparedTriangle,
    lo: DVec3,
    hi: DVec3,
    bounded_lo: DVec3,
    bounded_hi: DVec3,
) -> Option<(DVec3, DVec3)> {
    if triangle_overlaps_box_prepared(pt, lo, hi) {
        Some((bounded_lo, bounded_hi))
    } else {
        None
    }
}

/// One step of [`clip_finite`]: [`clip_against_plane`] of the finite
/// polygon `poly` at `p[AXIS] = plane`, keeping `p[AXIS] >= plane` when
/// `ABOVE`, else `<=`, into `out`; returns the new polygon's bounds, or
/// `None` when nothing is left. The crossing point is computed as there
/// (`a + (b - a) * t`, per component, in lanes), its own axis then set to
/// the plane; the bounds are [`min3`] and [`max3`] in lanes.
#[inline(always)]
fn clip_step<L: Lanes, const AXIS: usize, const ABOVE: bool>(
    poly: &mut Polygon,
    out: &mut Polygon,
    plane: f64,
) -> Option<(L::V, L::V)> {
    let dist = |p: &P4| {
        if ABOVE {
            p.0[AXIS] - plane
        } else {
            plane - p.0[AXIS]
        }
    };
    let mut lo = L::splat(f64::INFINITY);
    let mut hi = L::splat(f64::NEG_INFINITY);
    let mut len = 0;
    // `for_each_edge`'s loop, written out: as a closure the body was not
    // inlined into the builder's AVX copy. A distance is read from memory,
    // a point kept in lanes.
    let n = poly.len;
    poly.v[n] = poly.v[0];
    let (mut a, mut da) = (L::load(&poly.v[0]), dist(&poly.v[0]));
    for b in &poly.v[1..n + 1] {
        let db = dist(b);
        let b = L::load(b);
        if da >= 0.0 {
            out.v[len] = L::store(a);
            len += 1;
            lo = L::min(lo, a);
            hi = L::max(hi, a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            let t = da / (da - db);
            let p = L::add(a, L::mul(L::sub(b, a), L::splat(t)));
            let p = L::with_lane::<AXIS>(p, plane);
            out.v[len] = L::store(p);
            len += 1;
            lo = L::min(lo, p);
            hi = L::max(hi, p);
        }
        (a, da) = (b, db);
    }
    out.len = len;
    (len > 0).then_some((lo, hi))
}

/// [`clip_prepared`] for any input (non-finite or huge coordinates): the
/// plain algorithm, skipping a step only where that is exact.
fn clip_general(
    pt: &PreparedTriangle,
    lo: DVec3,
    hi: DVec3,
    scratch: &mut ClipScratch,
) -> Option<(DVec3, DVec3)> {
    let tri = &pt.tri;
    let (tlo, thi) = (pt.lo, pt.hi);
    let bounded_lo = tlo.max(lo);
    let bounded_hi = thi.min(hi);
    let fallback = || clip_fallback(pt, lo, hi, bounded_lo, bounded_hi);

    let m = ROUNDING_MARGIN_REL * pt.magnitude(lo, hi);
    let grown_lo = lo - DVec3::splat(m);
    let grown_hi = hi + DVec3::splat(m);
    let may_skip = pt.is_finite() && grown_lo.is_finite() && grown_hi.is_finite();
    let [a, b] = &mut scratch.polys;
    let (mut cur, mut next) = (a, b);
    cur.set_lanes(&tri.map(P4::new));
    let (mut plo, mut phi) = cur.bounds();
    for axis in 0..3 {
        if !(may_skip && plo[axis] >= grown_lo[axis]) {
            clip_against_plane(cur, next, axis, grown_lo[axis], KeepSide::Above);
            std::mem::swap(&mut cur, &mut next);
            if cur.len == 0 {
                return fallback();
            }
            (plo, phi) = cur.bounds();
        }
        if !(may_skip && phi[axis] <= grown_hi[axis]) {
            clip_against_plane(cur, next, axis, grown_hi[axis], KeepSide::Below);
            std::mem::swap(&mut cur, &mut next);
            if cur.len == 0 {
                return fallback();
            }
            (plo, phi) = cur.bounds();
        }
    }
    let out_lo = (plo - DVec3::splat(m)).max(bounded_lo);
    let out_hi = (phi + DVec3::splat(m)).min(bounded_hi);
    if out_lo.cmpgt(out_hi).any() {
        return fallback();
    }
    Some((out_lo, out_hi))
}

/// Most vertices a clipped polygon can have. One Sutherland–Hodgman step
/// outputs the kept vertices plus one per sign change; with `k` kept runs
/// there are `2k` changes and at least `k` dropped vertices, so `n` vertices
/// become at most `n + n/2` (a convex polygon gains at most one, but rounding
/// is not promised to keep it convex). From 3: 4, 6, 9, 13, 19, 28.
const MAX_POLYGON: usize = 28;

/// A polygon in a fixed buffer: clipping allocates nothing. One slot past
/// the last vertex is kept for [`for_each_edge`]'s copy of vertex 0.
struct Polygon {
    v: [P4; MAX_POLYGON + 1],
    len: usize,
}

impl Polygon {
    #[inline(always)]
    fn empty() -> Polygon {
        Polygon {
            v: [P4::splat(0.0); MAX_POLYGON + 1],
            len: 0,
        }
    }

    #[inline(always)]
    fn set_lanes(&mut self, tri: &[P4; 3]) {
        self.v[..3].copy_from_slice(tri);
        self.len = 3;
    }

    #[inline(always)]
    fn push(&mut self, p: DVec3) {
        self.v[self.len] = P4::new(p);
        self.len += 1;
    }

    /// The vertices' AABB, folded in vertex order (as the plain algorithm
    /// does once at the end).
    #[inline(always)]
    fn bounds(&self) -> (DVec3, DVec3) {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for p in &self.v[..self.len] {
            lo = lo.min(p.xyz());
            hi = hi.max(p.xyz());
        }
        (lo, hi)
    }
}

/// Which side of an axis-aligned plane survives a clip.
#[derive(Clone, Copy)]
enum KeepSide {
    /// Keep `p[axis] >= plane`.
    Above,
    /// Keep `p[axis] <= plane`.
    Below,
}

/// One Sutherland–Hodgman step: the part of the closed polygon `poly` on the
/// kept side of the plane `p[axis] = plane`, written to `out`. A polygon of
/// one or two vertices (repeated vertices are simply repeated) is clipped
/// like any other.
#[inline(always)]
fn clip_against_plane(
    poly: &mut Polygon,
    out: &mut Polygon,
    axis: usize,
    plane: f64,
    keep: KeepSide,
) {
    let dist = |p: &P4| match keep {
        KeepSide::Above => p.0[axis] - plane,
        KeepSide::Below => plane - p.0[axis],
    };
    out.len = 0;
    if poly.len == 0 {
        return;
    }
    for_each_edge(poly, dist, |a, da, b, db| {
        let (a, b) = (a.xyz(), b.xyz());
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
    });
}

/// Calls `f(a, da, b, db)` for each edge `(a, b)` of the closed polygon
/// `poly` (at least one vertex), from vertex 0 in order, the last edge back
/// to vertex 0; `da`, `db` are the vertices' `dist`, each computed once and
/// carried to the next edge (vertex 0's twice: the same value). Vertex 0 is
/// copied past the last so that every edge reads its end the same way,
/// without a branch for the last one.
#[inline(always)]
fn for_each_edge(
    poly: &mut Polygon,
    dist: impl Fn(&P4) -> f64,
    mut f: impl FnMut(P4, f64, P4, f64),
) {
    let n = poly.len;
    poly.v[n] = poly.v[0];
    let (mut a, mut da) = (poly.v[0], dist(&poly.v[0]));
    for b in &poly.v[1..n + 1] {
        let db = dist(b);
        f(a, da, *b, db);
        (a, da) = (*b, db);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::overlap::tests::{inside, sample_triangle, tri_and_box};
    use proptest::prelude::*;

    fn d(x: f64, y: f64, z: f64) -> DVec3 {
        DVec3::new(x, y, z)
    }

    #[test]
    fn clip_of_a_big_triangle_is_tight() {
        // The plane z = 0.5 crosses the unit box fully: the clip is that slab.
        let tri = [
            d(-10.0, -10.0, 0.5),
            d(30.0, -10.0, 0.5),
            d(-10.0, 30.0, 0.5),
        ];
        let (lo, hi) = clip_triangle_to_box(&tri, DVec3::ZERO, DVec3::ONE).unwrap();
        assert_eq!(lo.x, 0.0);
        assert_eq!(hi.x, 1.0);
        assert!((lo.z - 0.5).abs() < 1e-9 && (hi.z - 0.5).abs() < 1e-9);
        assert!(lo.z <= 0.5 && hi.z >= 0.5);
    }

    #[test]
    fn clip_of_a_diagonal_sliver_is_smaller_than_its_aabb() {
        // A thin triangle along the diagonal x = y, crossing the box [0,1]^2 x [0,1].
        let tri = [d(-1.0, -1.0, 0.5), d(3.0, 3.0, 0.5), d(3.0, 3.01, 0.5)];
        let (lo, hi) = clip_triangle_to_box(&tri, d(0.0, 0.0, 0.0), d(1.0, 1.0, 1.0)).unwrap();
        assert!(lo.x <= 0.0 + 1e-12 && hi.x >= 1.0 - 1e-12);
        // In the box [2, 3] x [0, 1] it misses entirely.
        assert_eq!(
            clip_triangle_to_box(&tri, d(2.0, 0.0, 0.0), d(3.0, 1.0, 1.0)),
            None
        );
        // In [0.5,1] x [0,0.25] it misses though the AABBs overlap.
        assert_eq!(
            clip_triangle_to_box(&tri, d(0.5, 0.0, 0.0), d(1.0, 0.25, 1.0)),
            None
        );
    }

    #[test]
    fn touching_corner_and_degenerates() {
        let tri = [d(1.0, 1.0, 1.0), d(2.0, 1.0, 1.0), d(1.0, 2.0, 1.0)];
        let (lo, hi) = clip_triangle_to_box(&tri, DVec3::ZERO, DVec3::ONE).unwrap();
        assert!(inside(DVec3::ONE, lo, hi));
        let point = [d(0.25, 0.5, 0.75); 3];
        let (lo, hi) = clip_triangle_to_box(&point, DVec3::ZERO, DVec3::ONE).unwrap();
        assert!(inside(point[0], lo, hi));
        assert!((hi - lo).max_element() < 1e-9);
        let seg = [d(-1.0, 0.5, 0.5), d(2.0, 0.5, 0.5), d(2.0, 0.5, 0.5)];
        let (lo, hi) = clip_triangle_to_box(&seg, DVec3::ZERO, DVec3::ONE).unwrap();
        assert_eq!((lo.x, hi.x), (0.0, 1.0));
        assert!((hi.y - lo.y) < 1e-9);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(3000))]
        #[test]
        fn clip_box_holds_every_sampled_point_inside((tri, lo, hi) in tri_and_box(), collapse in 0u8..4) {
            let mut tri = tri;
            if collapse == 1 { tri[2] = tri[1]; }
            if collapse == 2 { tri[1] = tri[0]; tri[2] = tri[0]; }
            let clip = clip_triangle_to_box(&tri, lo, hi);
            if let Some((clo, chi)) = clip {
                prop_assert!(clo.cmpge(lo).all() && chi.cmple(hi).all() && clo.cmple(chi).all());
                // Tight where it can be checked: never beyond the triangle's
                // AABB, and equal to it when the triangle is inside the box.
                let (tlo, thi) = crate::geom::triangle_bounds(&tri);
                prop_assert!(clo.cmpge(tlo).all() && chi.cmple(thi).all());
                if inside(tlo, lo, hi) && inside(thi, lo, hi) {
                    prop_assert_eq!((clo, chi), (tlo, thi));
                }
            }
            for p in sample_triangle(&tri, 24) {
                if inside(p, lo, hi) {
                    let (clo, chi) = clip.expect("a point of the triangle is in the box");
                    prop_assert!(inside(p, clo, chi), "{p} not in {clo}..{chi}");
                }
            }
        }
    }
}
