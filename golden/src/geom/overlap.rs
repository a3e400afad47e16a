//! Conservative triangle/box overlap: the separating-axis test of
//! Akenine-Möller ("Fast 3D Triangle-Box Overlap Testing", 2001).
//!
//! Two convex sets are disjoint exactly when some axis separates their
//! projections; for a triangle and a box it suffices to try the three box
//! normals, the triangle normal and the nine cross products of a triangle
//! edge with a box axis. The same thirteen axes are complete for degenerate
//! triangles: a segment has no face, and its direction is among the edges; a
//! point needs only the box normals (the other axes vanish and never separate).
//!
//! Conservative by construction: an axis is declared separating only when the
//! gap between the projections exceeds `ROUNDING_MARGIN_REL * |axis|_1 * M`,
//! where `M` is the largest input coordinate magnitude (see [`super`]). The
//! computed axis itself may be rounded: that is harmless, since projections of
//! intersecting sets overlap on *every* axis, and only the projections'
//! rounding must be covered by the margin. Non-finite input never separates
//! (every comparison with NaN is false), so it reports an overlap.

use glam::DVec3;

use super::clip::PreparedTriangle;
use super::ROUNDING_MARGIN_REL;

/// True unless the closed triangle and the closed box `[lo, hi]` are
/// certainly disjoint. Never false when they touch, even at one point; may be
/// true when they miss by less than `2^-40` of the coordinates' magnitude.
pub fn triangle_overlaps_box(tri: &[DVec3; 3], lo: DVec3, hi: DVec3) -> bool {
    triangle_overlaps_box_prepared(&PreparedTriangle::new(tri), lo, hi)
}

/// [`triangle_overlaps_box`] of a prepared triangle: the same answer.
pub fn triangle_overlaps_box_prepared(pt: &PreparedTriangle, lo: DVec3, hi: DVec3) -> bool {
    let tri = &pt.tri;
    if pt.is_finite() && lo.is_finite() && hi.is_finite() {
        let scale = pt.magnitude_finite(lo, hi);
        if scale < FAST_PATH_LIMIT {
            return overlaps_finite::<true>(tri, lo, hi, scale);
        }
    }
    overlaps_any(tri, lo, hi, pt.magnitude(lo, hi))
}

/// [`triangle_overlaps_box_prepared`] for a box the builder tries: the
/// caller guarantees that the triangle and the box are finite, of magnitude
/// below `2^32`, and that their AABBs meet (the box is a candidate voxel).
/// The box-axis tests are left out, since they cannot separate then: the
/// box's center and half extents are exact (corners are integers below
/// `2^32`), and some vertex `w` has `w[a] <= hi[a]`, i.e. exactly
/// `w[a] - center[a] <= half[a]`; rounding is monotone and `half[a]` is
/// representable, so the computed projection is `<= half[a]` too, never
/// beyond `half[a] + margin`; the same below. The same answer. `scale` is
/// the magnitude of the triangle and the box (`geom::magnitude`), which the
/// caller computes once for this and the clip.
#[inline]
pub fn overlaps_candidate(pt: &PreparedTriangle, lo: DVec3, hi: DVec3, scale: f64) -> bool {
    debug_assert!(pt.is_finite() && lo.is_finite() && hi.is_finite());
    debug_assert!(!(pt.lo.cmpgt(hi).any() || pt.hi.cmplt(lo).any()));
    debug_assert_eq!(scale.to_bits(), pt.magnitude_finite(lo, hi).to_bits());
    debug_assert!(scale < (1u64 << 32) as f64);
    let answer = overlaps_finite::<false>(&pt.tri, lo, hi, scale);
    debug_assert_eq!(answer, triangle_overlaps_box_prepared(pt, lo, hi));
    answer
}

/// What [`overlaps_candidate`] computes of a triangle that is the same in
/// every candidate voxel of one LOD, computed once: the edges, the normal,
/// and each axis's radius and margin per unit of magnitude.
///
/// The test subtracts the voxel's center `c` from each vertex `t` and takes
/// the edges between those. When every such difference is exact, an edge
/// `(t1 - c) - (t0 - c)` is `t1 - t0` rounded once, whatever the voxel: the
/// same bits as `t1 - t0`, so the edges, the normal `e0 x e1` and everything
/// made of them and the half extent (one per LOD) are the test's own values.
/// [`Self::new`] checks exactness for the candidates `i0..=i1` per axis (at
/// most 32): a center is an odd multiple of `edge / 2`, so with every vertex
/// coordinate a multiple of `g = edge 2^-48` both are multiples of `g`, and
/// they are less than `32 edge = 2^53 g` apart (the vertex lies in the
/// candidates' span): the difference is an integer below `2^53` times `g`,
/// representable, hence exact. Otherwise `exact` is false and the caller
/// runs [`overlaps_candidate`].
pub struct OverlapPrep {
    /// The differences are exact for every candidate: the fields below hold.
    pub exact: bool,
    edges: [DVec3; 3],
    normal: DVec3,
    normal_radius: f64,
    /// `ROUNDING_MARGIN_REL * |normal|_1`: times the magnitude, the margin.
    normal_margin: f64,
    /// Per edge, the radius of the axes `e x X`, `e x Y`, `e x Z`.
    radius: [[f64; 3]; 3],
    /// Per edge and axis, the margin per unit of magnitude.
    margin: [[f64; 3]; 3],
}

impl OverlapPrep {
    /// The triangle's values for the candidates `i0..=i1` (per axis) of edge
    /// `edge`, a power of two.
    pub fn new(tri: &[DVec3; 3], edge: f64, i0: glam::UVec3, i1: glam::UVec3) -> OverlapPrep {
        let inv_g = (1u64 << 48) as f64 / edge;
        let multiple_of_g = |t: f64| {
            let x = t * inv_g;
            // At or above 2^52 every binary64 is an integer; below, `x` is
            // a non-negative finite value that fits `i64`.
            // SAFETY: `x` is finite (a checked coordinate times a power of
            // two below 2^48) and, in this branch, in `[0, 2^52)`.
            x >= (1u64 << 52) as f64 || unsafe { x.to_int_unchecked::<i64>() } as f64 == x
        };
        let exact = (i1 - i0).max_element() < 32
            && tri.iter().all(|v| {
                debug_assert!(v.cmpge(DVec3::ZERO).all());
                multiple_of_g(v.x) && multiple_of_g(v.y) && multiple_of_g(v.z)
            });
        let edges = [tri[1] - tri[0], tri[2] - tri[1], tri[0] - tri[2]];
        let half = DVec3::splat(edge * 0.5);
        let normal = edges[0].cross(edges[1]);
        let rel = ROUNDING_MARGIN_REL;
        let axis = |a: f64, b: f64, ha: f64, hb: f64| {
            (ha * a.abs() + hb * b.abs(), rel * (a.abs() + b.abs()))
        };
        let mut radius = [[0.0; 3]; 3];
        let mut margin = [[0.0; 3]; 3];
        for (k, e) in edges.iter().enumerate() {
            // The radius and margin expressions of `overlaps_finite`.
            [
                (radius[k][0], margin[k][0]),
                (radius[k][1], margin[k][1]),
                (radius[k][2], margin[k][2]),
            ] = [
                axis(e.z, e.y, half.y, half.z),
                axis(e.z, e.x, half.x, half.z),
                axis(e.y, e.x, half.x, half.y),
            ];
        }
        OverlapPrep {
            exact,
            edges,
            normal,
            normal_radius: half.dot(normal.abs()),
            normal_margin: rel * normal.abs().element_sum(),
            radius,
            margin,
        }
    }
}

/// [`overlaps_candidate`] with the triangle's part precomputed: the same
/// operations on the same values (see [`OverlapPrep`]; a margin is its
/// coefficient times `scale`, as `ROUNDING_MARGIN_REL * |axis|_1 * scale`
/// is evaluated left to right), so the same answer. The caller guarantees
/// `prep.exact`, that `prep` is of `pt`'s triangle at the box's LOD and
/// that the box is one of its candidates, besides what
/// [`overlaps_candidate`] asks.
#[inline(always)]
pub fn overlaps_candidate_prepared(
    prep: &OverlapPrep,
    pt: &PreparedTriangle,
    lo: DVec3,
    hi: DVec3,
    scale: f64,
) -> bool {
    debug_assert!(prep.exact);
    let tri = &pt.tri;
    let center = (lo + hi) * 0.5;
    let v = [tri[0] - center, tri[1] - center, tri[2] - center];
    let answer = 'test: {
        let n = prep.normal;
        let p = [n.dot(v[0]), n.dot(v[1]), n.dot(v[2])];
        if gap_exceeds_finite(p, prep.normal_radius, prep.normal_margin * scale) {
            break 'test false;
        }
        for ((e, r), m) in prep.edges.iter().zip(&prep.radius).zip(&prep.margin) {
            let p = v.map(|w| e.z * w.y + (-e.y) * w.z);
            if gap_exceeds_finite(p, r[0], m[0] * scale) {
                break 'test false;
            }
            let p = v.map(|w| (-e.z) * w.x + e.x * w.z);
            if gap_exceeds_finite(p, r[1], m[1] * scale) {
                break 'test false;
            }
            let p = v.map(|w| e.y * w.x + (-e.x) * w.y);
            if gap_exceeds_finite(p, r[2], m[2] * scale) {
                break 'test false;
            }
        }
        true
    };
    debug_assert_eq!(answer, overlaps_candidate(pt, lo, hi, scale));
    answer
}

/// Below this magnitude no product or sum of the test overflows, but for
/// the normal's (see [`NORMAL_FINITE_LIMIT`]).
const FAST_PATH_LIMIT: f64 = 1e150;

/// Below this magnitude `s` the normal's projections are finite too: with
/// `|v| <= 2s` per component, edges are at most `4s`, the normal's
/// components at most `2 (4s)^2 = 32 s^2`, a projection at most
/// `3 * 32 s^2 * 2s = 192 s^3 < 2e302`, and the radius and margin smaller.
const NORMAL_FINITE_LIMIT: f64 = 1e100;

/// The test as written: thirteen axes, each through [`separates`].
fn overlaps_any(tri: &[DVec3; 3], lo: DVec3, hi: DVec3, scale: f64) -> bool {
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

/// [`overlaps_any`] for finite input of moderate magnitude, with the zero
/// components of the box axes and of the edge-by-axis crosses left out.
///
/// The same booleans, not just close ones: with finite operands a product
/// by 0 is a zero and adding a zero to `a` gives `a` exactly (or a zero when
/// `a` is one), so every projection, radius and margin below equals the
/// general one's up to the sign of a zero, which no comparison sees. E.g.
/// `e x X = (e.y 0 - 0 e.z, e.z 1 - 0 e.x, e.x 0 - 1 e.y) = (0, e.z, -e.y)`,
/// and its projection `(0 v.x + e.z v.y) + (-e.y) v.z` is
/// `e.z v.y - e.y v.z` rounded the same way.
///
/// `BOX_AXES = false` leaves the box-axis tests out (see
/// [`overlaps_candidate`] for when they cannot separate).
fn overlaps_finite<const BOX_AXES: bool>(
    tri: &[DVec3; 3],
    lo: DVec3,
    hi: DVec3,
    scale: f64,
) -> bool {
    let center = (lo + hi) * 0.5;
    let half = (hi - lo) * 0.5;
    let v = [tri[0] - center, tri[1] - center, tri[2] - center];
    let edges = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];

    // Box axes: projections are the coordinates, radius the half extent,
    // |axis|_1 = 1.
    let box_margin = ROUNDING_MARGIN_REL * 1.0 * scale;
    for a in 0..3 {
        let p = [v[0][a], v[1][a], v[2][a]];
        if BOX_AXES && gap_exceeds_finite(p, half[a], box_margin) {
            return false;
        }
    }
    // The normal's projections are of degree 3 and may overflow (to NaN
    // through inf - inf) below FAST_PATH_LIMIT: the general test there;
    // below NORMAL_FINITE_LIMIT they are finite, so the projections are
    // compared without min/max (`separates` with `gap_exceeds_finite`).
    let normal = edges[0].cross(edges[1]);
    let (p, radius, margin) = projection(normal, &v, half, scale);
    let separated = if scale < NORMAL_FINITE_LIMIT {
        gap_exceeds_finite(p, radius, margin)
    } else {
        gap_exceeds(p, radius, margin)
    };
    if separated {
        return false;
    }
    let margin = |a: f64, b: f64| ROUNDING_MARGIN_REL * (a.abs() + b.abs()) * scale;
    for e in edges {
        // e x X = (0, e.z, -e.y)
        let p = v.map(|w| e.z * w.y + (-e.y) * w.z);
        let r = half.y * e.z.abs() + half.z * e.y.abs();
        if gap_exceeds_finite(p, r, margin(e.z, e.y)) {
            return false;
        }
        // e x Y = (-e.z, 0, e.x)
        let p = v.map(|w| (-e.z) * w.x + e.x * w.z);
        let r = half.x * e.z.abs() + half.z * e.x.abs();
        if gap_exceeds_finite(p, r, margin(e.z, e.x)) {
            return false;
        }
        // e x Z = (e.y, -e.x, 0)
        let p = v.map(|w| e.y * w.x + (-e.x) * w.y);
        let r = half.x * e.y.abs() + half.y * e.x.abs();
        if gap_exceeds_finite(p, r, margin(e.y, e.x)) {
            return false;
        }
    }
    true
}

/// True when `axis` certainly separates the triangle `v` (relative to the box
/// center) from the box of half-extents `half`.
fn separates(axis: DVec3, v: &[DVec3; 3], half: DVec3, scale: f64) -> bool {
    let (p, radius, margin) = projection(axis, v, half, scale);
    gap_exceeds(p, radius, margin)
}

/// The triangle's projections on `axis`, the box's radius on it and the
/// margin of the test.
#[inline(always)]
fn projection(axis: DVec3, v: &[DVec3; 3], half: DVec3, scale: f64) -> ([f64; 3], f64, f64) {
    let p = [axis.dot(v[0]), axis.dot(v[1]), axis.dot(v[2])];
    let radius = half.dot(axis.abs());
    let margin = ROUNDING_MARGIN_REL * axis.abs().element_sum() * scale;
    (p, radius, margin)
}

/// True when the projections `p` lie beyond `radius + margin` on one side.
#[inline(always)]
fn gap_exceeds(p: [f64; 3], radius: f64, margin: f64) -> bool {
    let pmin = p[0].min(p[1]).min(p[2]);
    let pmax = p[0].max(p[1]).max(p[2]);
    pmin > radius + margin || pmax < -radius - margin
}

/// [`gap_exceeds`] for projections, radius and margin that are not NaN
/// (the box axes and edge crosses of [`overlaps_finite`], of degree at most
/// 2 below `FAST_PATH_LIMIT`, so finite): "the smallest projection is beyond
/// the bound" is "every projection is beyond it", so no `min`/`max` is taken.
/// `f64::min` and `max` cost about eight instructions each on baseline
/// x86-64 (they must pass NaN through), and this test runs for every
/// candidate voxel. The same answer: for values that are not NaN,
/// `min(a, b) > t` exactly when `a > t` and `b > t` (a signed zero compares
/// equal to the other zero either way).
#[inline(always)]
fn gap_exceeds_finite(p: [f64; 3], radius: f64, margin: f64) -> bool {
    let above = radius + margin;
    let below = -radius - margin;
    (p[0] > above && p[1] > above && p[2] > above) || (p[0] < below && p[1] < below && p[2] < below)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use proptest::prelude::*;

    fn d(x: f64, y: f64, z: f64) -> DVec3 {
        DVec3::new(x, y, z)
    }

    #[test]
    fn touching_at_a_corner_overlaps() {
        let tri = [d(1.0, 1.0, 1.0), d(2.0, 1.0, 1.0), d(1.0, 2.0, 1.0)];
        assert!(triangle_overlaps_box(&tri, DVec3::ZERO, DVec3::ONE));
    }

    #[test]
    fn off_axis_triangle_near_corner_is_separated_by_an_edge_axis() {
        // The triangle's AABB overlaps the box but the triangle passes the
        // corner (1,1,*) diagonally, missing it: only an edge-cross axis separates.
        let tri = [d(2.5, 0.0, -1.0), d(0.0, 2.5, -1.0), d(0.0, 2.5, 2.0)];
        assert!(!triangle_overlaps_box(&tri, DVec3::ZERO, DVec3::ONE));
        let touching = [d(2.0, 0.0, -1.0), d(0.0, 2.0, -1.0), d(0.0, 2.0, 2.0)];
        assert!(triangle_overlaps_box(&touching, DVec3::ZERO, DVec3::ONE));
    }

    #[test]
    fn plane_passing_beside_box_is_separated_by_normal() {
        let tri = [d(3.1, 0.0, 0.0), d(0.0, 3.1, 0.0), d(0.0, 0.0, 3.1)];
        assert!(!triangle_overlaps_box(&tri, DVec3::ZERO, DVec3::ONE));
        let through = [d(2.9, 0.0, 0.0), d(0.0, 2.9, 0.0), d(0.0, 0.0, 2.9)];
        assert!(triangle_overlaps_box(&through, DVec3::ZERO, DVec3::ONE));
    }

    #[test]
    fn degenerate_segment_and_point() {
        let seg = [d(-1.0, 0.5, 0.5), d(2.0, 0.5, 0.5), d(0.5, 0.5, 0.5)];
        assert!(triangle_overlaps_box(&seg, DVec3::ZERO, DVec3::ONE));
        // A diagonal segment passing the box's corner edge outside.
        let miss = [d(2.2, 0.0, 0.5), d(0.0, 2.2, 0.5), d(1.1, 1.1, 0.5)];
        assert!(!triangle_overlaps_box(&miss, DVec3::ZERO, DVec3::ONE));
        let p_in = [d(0.3, 0.3, 0.3); 3];
        let p_out = [d(0.3, 1.3, 0.3); 3];
        assert!(triangle_overlaps_box(&p_in, DVec3::ZERO, DVec3::ONE));
        assert!(!triangle_overlaps_box(&p_out, DVec3::ZERO, DVec3::ONE));
    }

    #[test]
    fn flat_box_and_nan() {
        // A zero-thickness box (a face) crossed by the triangle.
        let tri = [d(0.0, 0.0, -1.0), d(1.0, 0.0, 1.0), d(0.0, 1.0, 1.0)];
        assert!(triangle_overlaps_box(
            &tri,
            d(0.0, 0.0, 0.0),
            d(1.0, 1.0, 0.0)
        ));
        let nan = [d(f64::NAN, 0.0, 0.0), d(1.0, 0.0, 0.0), d(0.0, 1.0, 0.0)];
        assert!(triangle_overlaps_box(&nan, DVec3::ZERO, DVec3::ONE));
    }

    /// Points on the triangle at a dense barycentric lattice (vertices and
    /// edges included). Rounding may push a computed point off the exact
    /// triangle; clamping it to the triangle's AABB keeps it within rounding
    /// of the triangle and never outside the exact triangle's bounds.
    pub(crate) fn sample_triangle(tri: &[DVec3; 3], n: u32) -> Vec<DVec3> {
        let (tlo, thi) = crate::geom::triangle_bounds(tri);
        let mut out = Vec::new();
        for i in 0..=n {
            for j in 0..=(n - i) {
                let a = i as f64 / n as f64;
                let b = j as f64 / n as f64;
                let c = 1.0 - a - b;
                out.push((tri[0] * c + tri[1] * a + tri[2] * b).clamp(tlo, thi));
            }
        }
        out
    }

    pub(crate) fn inside(p: DVec3, lo: DVec3, hi: DVec3) -> bool {
        p.cmpge(lo).all() && p.cmple(hi).all()
    }

    /// Coordinates on a coarse lattice so that touching and exactly-on-plane
    /// cases are frequent, mixed with arbitrary values.
    pub(crate) fn coord() -> impl Strategy<Value = f64> {
        prop_oneof![(-8i32..=8).prop_map(|k| k as f64 * 0.25), -2.0f64..2.0,]
    }

    pub(crate) fn point() -> impl Strategy<Value = DVec3> {
        (coord(), coord(), coord()).prop_map(|(x, y, z)| DVec3::new(x, y, z))
    }

    pub(crate) fn tri_and_box() -> impl Strategy<Value = ([DVec3; 3], DVec3, DVec3)> {
        (point(), point(), point(), point(), point()).prop_map(|(a, b, c, p, q)| {
            // Sometimes collapse a vertex to make segments and points.
            ([a, b, c], p.min(q), p.max(q))
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(3000))]
        #[test]
        fn never_misses_a_sampled_contact((tri, lo, hi) in tri_and_box(), collapse in 0u8..4) {
            let mut tri = tri;
            if collapse == 1 { tri[2] = tri[1]; }
            if collapse == 2 { tri[1] = tri[0]; tri[2] = tri[0]; }
            let touches = sample_triangle(&tri, 24).into_iter().any(|p| inside(p, lo, hi));
            if touches {
                prop_assert!(triangle_overlaps_box(&tri, lo, hi));
            }
        }

        /// Tightness: a triangle beyond a random plane that clears the box by
        /// a visible gap is never reported as overlapping (the margin is
        /// 2^-40 relative; the gap here is 1e-3).
        #[test]
        fn never_overlaps_beyond_a_separating_plane(
            (_, lo, hi) in tri_and_box(),
            n in point(),
            raw in prop::array::uniform3(point()),
        ) {
            prop_assume!(n.length() > 0.1);
            let n = n.normalize();
            let corners = (0..8).map(|i| DVec3::new(
                if i & 1 != 0 { hi.x } else { lo.x },
                if i & 2 != 0 { hi.y } else { lo.y },
                if i & 4 != 0 { hi.z } else { lo.z },
            ));
            let support = corners.map(|c| n.dot(c)).fold(f64::NEG_INFINITY, f64::max);
            // Push each vertex along n until it is 1e-3 beyond the plane.
            let tri = raw.map(|v| {
                let gap = support + 1e-3 - n.dot(v);
                if gap > 0.0 { v + n * (gap * 1.001) } else { v }
            });
            prop_assert!(!triangle_overlaps_box(&tri, lo, hi), "{tri:?} {lo} {hi} n={n}");
        }

        #[test]
        fn never_overlaps_when_bounds_are_disjoint((tri, lo, hi) in tri_and_box()) {
            let (tlo, thi) = crate::geom::triangle_bounds(&tri);
            let far = (tlo.cmpgt(hi + DVec3::splat(1e-6))).any() || (thi.cmplt(lo - DVec3::splat(1e-6))).any();
            if far {
                prop_assert!(!triangle_overlaps_box(&tri, lo, hi));
            }
        }
    }
}
