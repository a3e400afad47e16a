//! Outward quantization of boxes into a voxel's `2^Q` cells (SPEC.md section 3).
//!
//! Both functions round the minimum down and the maximum up, so the quantized
//! box always contains what it quantizes: the property that keeps every ray
//! test conservative.

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
///
/// The clamps are taken in `i64` on the truncated values: `lo` is
/// `trunc(ta)` clamped to `[0, top]` (for `ta < 0` the truncation is
/// `<= 0`); `hi` is `max(c - 1, lo)` then `min(top)` with `c = ceil(tb)`
/// (for `tb < 0`, `c <= 0` and `hi` is `lo`, as the clamp of
/// `ceil_nonneg(tb) - 1` saturating at 0 gives; for `tb >= 0`,
/// `max(max(c - 1, 0), lo) = max(c - 1, lo)` since `lo >= 0`).
pub fn quantize_interval(a: f64, b: f64, v0: f64, scale: f64, cells: u32) -> (u16, u16) {
    let top = cells as i64 - 1;
    let lo = ((a - v0) * scale) as i64;
    let lo = lo.max(0).min(top);
    let tb = (b - v0) * scale;
    let f = tb as i64;
    let c = f + ((f as f64) < tb) as i64;
    let hi = (c - 1).max(lo).min(top);
    (lo as u16, hi as u16)
}

/// [`quantize_interval`] of an interval the caller guarantees inside the
/// closed voxel, `v0 <= a <= b <= v0 + edge` with `scale = 2^Q / edge`:
/// the builder's case (a clipped box lies in its voxel, and a triangle's
/// box in the voxel that holds it). The same result, with fewer
/// instructions: `ta = (a - v0) scale` and `tb` are then finite and in
/// `[0, 2^Q]` (`a - v0` is exact, see [`quantize_interval`], and so is the
/// product by a power of two), so the conversions need not saturate (Rust's
/// `as` spends five instructions a conversion on NaN and range checks) and
/// `lo = trunc(ta) >= 0` needs no `max(0)`.
#[inline(always)]
pub fn quantize_in_voxel(a: f64, b: f64, v0: f64, scale: f64, cells: u32) -> (u16, u16) {
    let top = cells as i64 - 1;
    let ta = (a - v0) * scale;
    let tb = (b - v0) * scale;
    debug_assert!((0.0..=cells as f64).contains(&ta) && (0.0..=cells as f64).contains(&tb));
    debug_assert!(ta <= tb);
    // SAFETY: `ta` and `tb` are finite and in `[0, 2^Q]` with `Q <= 16`
    // (above), so their truncations fit `i64`.
    let (fa, fb) = unsafe { (ta.to_int_unchecked::<i64>(), tb.to_int_unchecked::<i64>()) };
    let lo = fa.min(top);
    let c = fb + ((fb as f64) < tb) as i64;
    let hi = (c - 1).max(lo).min(top);
    debug_assert_eq!(
        (lo as u16, hi as u16),
        quantize_interval(a, b, v0, scale, cells)
    );
    (lo as u16, hi as u16)
}

/// `(floor(t), ceil(t))` for a finite `t` in `[0, 2^62]` (a grid coordinate
/// over a voxel edge: at most `2^31`): the same values as [`floor_nonneg`]
/// and [`ceil_nonneg`], without the saturating conversion's checks, which
/// such a `t` never needs.
#[inline(always)]
pub fn floor_ceil_in_scene(t: f64) -> (i64, i64) {
    debug_assert!((0.0..=(1u64 << 62) as f64).contains(&t));
    // SAFETY: `t` is finite and in `[0, 2^62]` (above), so its truncation,
    // its floor, fits `i64`.
    let f = unsafe { t.to_int_unchecked::<i64>() };
    (f, f + ((f as f64) < t) as i64)
}

/// `floor(t)` for `0 <= t < 2^63`, and 0 for `t < 0` (finite `t`).
///
/// Through `i64`, not `u64`: baseline x86-64 converts between binary64 and
/// signed 64-bit integers in one instruction, while the unsigned
/// conversions take a branch and several more. Below `2^63` the two agree,
/// and a negative `t` truncates to a value `<= 0`, which the `max` makes 0.
#[inline(always)]
pub fn floor_nonneg(t: f64) -> u64 {
    (t as i64).max(0) as u64
}

/// `ceil(t)` for `0 <= t < 2^63`, and 0 for `t < 0` (finite `t`).
#[inline(always)]
pub fn ceil_nonneg(t: f64) -> u64 {
    let f = (t as i64).max(0);
    (f + ((f as f64) < t) as i64) as u64
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interval_rounds_outward_and_clamps() {
        // Voxel [8, 16), Q = 2: cells of 2 grid units.
        let s = 4.0 / 8.0;
        assert_eq!(quantize_interval(8.0, 16.0, 8.0, s, 4), (0, 3));
        assert_eq!(quantize_interval(9.0, 9.5, 8.0, s, 4), (0, 0));
        assert_eq!(
            quantize_interval(10.0, 12.0, 8.0, s, 4),
            (1, 1),
            "max on a cell edge"
        );
        assert_eq!(quantize_interval(10.0, 12.1, 8.0, s, 4), (1, 2));
        assert_eq!(
            quantize_interval(12.0, 12.0, 8.0, s, 4),
            (2, 2),
            "a point on an edge"
        );
        assert_eq!(
            quantize_interval(16.0, 16.0, 8.0, s, 4),
            (3, 3),
            "the far face"
        );
        // Q = 0: always the whole voxel.
        assert_eq!(quantize_interval(9.0, 9.5, 8.0, 1.0 / 8.0, 1), (0, 0));
    }

    #[test]
    fn integer_floor_and_ceil() {
        for t in [
            0.0,
            0.25,
            1.0,
            1.5,
            2.0,
            1e15 + 0.5,
            4503599627370495.5,
            9007199254740992.0,
            4611686018427387904.0,
        ] {
            assert_eq!(floor_nonneg(t), t.floor() as u64, "{t}");
            let (f, c) = floor_ceil_in_scene(t);
            assert_eq!(
                (f as u64, c as u64),
                (floor_nonneg(t), ceil_nonneg(t)),
                "{t}"
            );
            assert_eq!(ceil_nonneg(t), t.ceil() as u64, "{t}");
        }
        for t in [-0.5, -1.0, -1.5, -1e18] {
            assert_eq!((floor_nonneg(t), ceil_nonneg(t)), (0, 0), "{t}");
        }
    }

    #[test]
    fn parent_cells_contain_child_cells() {
        for q in 0..=4u8 {
            let n = 1u32 << q;
            for odd in [false, true] {
                for lo in 0..n {
                    for hi in lo..n {
                        let (pl, ph) = child_cells_in_parent(lo as u16, hi as u16, odd, q);
                        let base = (odd as u32) * n;
                        // In child-cell units the parent box [2 pl, 2 ph + 2) holds [base+lo, base+hi+1).
                        assert!(2 * pl as u32 <= base + lo);
                        assert!(2 * ph as u32 + 2 > base + hi);
                        assert!(pl <= ph && (ph as u32) < n);
                        // Tight: one cell less on either side would not contain it.
                        assert!(2 * (pl as u32 + 1) > base + lo);
                        assert!(2 * (ph as u32) < base + hi + 1);
                    }
                }
            }
        }
    }
}
