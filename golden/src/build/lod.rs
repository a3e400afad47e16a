//! S402: the LOD of a primitive (SPEC.md section 4.2).
//!
//! A triangle's **base LOD** is the deepest level whose voxel edge is at least
//! the largest extent of its grid-space AABB, so the triangle's box is about
//! one voxel. A long thin triangle goes deeper by its **sliver levels**, so
//! that several smaller voxels cover it instead of one mostly empty one.

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

/// Shallowest LOD a primitive is placed at. A leaf at LOD 0 would be a
/// root that no merged hierarchy can hold (its primitives index its own
/// input's triangles, SPEC 8.6), so a floor as large as the scene could
/// never be merged; at LOD 1 it lands in the (at most 8) voxels it touches.
pub const MIN_PRIMITIVE_LOD: u32 = 1;

/// The primitive's LOD: `base_lod + sliver_levels`, clamped to
/// `MIN_PRIMITIVE_LOD..=D`.
pub fn primitive_lod(tri: &[DVec3; 3], lo: DVec3, hi: DVec3, max_lod: u8) -> u8 {
    let extent = (hi - lo).max_element();
    let base = base_lod(extent, max_lod) as u32;
    (base + sliver_levels(tri)).clamp(MIN_PRIMITIVE_LOD, max_lod as u32) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ceil_log2_is_exact_at_powers_of_two() {
        assert_eq!(ceil_log2(0.0), 0);
        assert_eq!(ceil_log2(0.25), 0);
        assert_eq!(ceil_log2(1.0), 0);
        assert_eq!(ceil_log2(1.0 + f64::EPSILON), 1);
        assert_eq!(ceil_log2(2.0), 1);
        assert_eq!(ceil_log2(3.0), 2);
        assert_eq!(ceil_log2(4.0), 2);
        assert_eq!(ceil_log2(4.000001), 3);
        assert_eq!(ceil_log2((1u64 << 31) as f64), 31);
    }

    #[test]
    fn base_lod_fits_the_extent_in_one_voxel_edge() {
        for d in 1..=31u8 {
            for ext in [0.0, 0.5, 1.0, 1.5, 2.0, 7.0, 8.0, 1000.0] {
                let l = base_lod(ext, d);
                let edge = (1u64 << (d - l)) as f64;
                if l > 0 && ext <= (1u64 << d) as f64 {
                    assert!(edge >= ext, "d={d} ext={ext}: edge {edge}");
                }
                if l < d {
                    assert!(edge / 2.0 < ext, "d={d} ext={ext}: could go deeper");
                }
            }
        }
    }

    #[test]
    fn slivers_go_deeper_and_are_capped() {
        let eq = [
            DVec3::ZERO,
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(1.0, 3f64.sqrt(), 0.0),
        ];
        assert_eq!(sliver_levels(&eq), 0);
        // Right isoceles with legs 1: L = sqrt 2, h = sqrt 2 / 2, r = 2.
        let right = [DVec3::ZERO, DVec3::X, DVec3::Y];
        assert_eq!(sliver_levels(&right), 0);
        // Length 4, height 1: r = 4 exactly: 1 level.
        let four = [
            DVec3::ZERO,
            DVec3::new(4.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
        ];
        assert_eq!(sliver_levels(&four), 1);
        // Length 100, height 1: r = 100 >= 16: capped at 3.
        let thin = [
            DVec3::ZERO,
            DVec3::new(100.0, 0.0, 0.0),
            DVec3::new(50.0, 1.0, 0.0),
        ];
        assert_eq!(sliver_levels(&thin), SLIVER_LEVEL_CAP);
        // Length 10, height 2: r = 5: 4 <= 5 < 8: 1 level.
        let mid = [
            DVec3::ZERO,
            DVec3::new(10.0, 0.0, 0.0),
            DVec3::new(3.0, 2.0, 0.0),
        ];
        assert_eq!(sliver_levels(&mid), 1);
        // Length 10, height 1: r = 10: 8 <= 10 < 16: 2 levels.
        let ten = [
            DVec3::ZERO,
            DVec3::new(10.0, 0.0, 0.0),
            DVec3::new(3.0, 1.0, 0.0),
        ];
        assert_eq!(sliver_levels(&ten), 2);
        let segment = [DVec3::ZERO, DVec3::ONE, DVec3::splat(2.0)];
        assert_eq!(sliver_levels(&segment), SLIVER_LEVEL_CAP);
        assert_eq!(sliver_levels(&[DVec3::ONE; 3]), 0);
    }

    #[test]
    fn primitive_lod_is_clamped_to_d() {
        let tiny = [
            DVec3::ZERO,
            DVec3::new(0.01, 0.0, 0.0),
            DVec3::new(0.0, 0.0001, 0.0),
        ];
        assert_eq!(
            primitive_lod(&tiny, DVec3::ZERO, DVec3::new(0.01, 0.0001, 0.0), 8),
            8
        );
    }

    #[test]
    fn a_triangle_spanning_the_scene_sits_at_lod_1() {
        // An equilateral-ish triangle across the whole cube of D = 4: its
        // base LOD is 0, and nothing may be placed there.
        let big = [
            DVec3::ZERO,
            DVec3::new(16.0, 0.0, 0.0),
            DVec3::new(8.0, 0.0, 14.0),
        ];
        let (lo, hi) = (DVec3::ZERO, DVec3::new(16.0, 0.0, 14.0));
        assert_eq!(base_lod(16.0, 4), 0);
        assert_eq!(primitive_lod(&big, lo, hi, 4), 1);
        assert_eq!(primitive_lod(&big, lo, hi, 1), 1);
    }
}
