//! A point in four binary64 lanes, for the builder's kernels: one vector
//! instruction per operation on the three coordinates where the CPU has
//! four-lane vectors (the builder's AVX copy, `build::place_range`), two
//! where it has two.
//!
//! Every operation is the scalar one per lane (no fused multiply-add, the
//! same operand order), so each lane's bits are those of the scalar code on
//! that coordinate. The fourth lane is padding, never read.

use glam::DVec3;

use super::clip::{max_not_nan, min_not_nan};
use crate::build::quantize::quantize_in_voxel;

/// `(x, y, z, pad)`, aligned so that a point is one vector load or store.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub(crate) struct P4(pub [f64; 4]);

impl P4 {
    /// `v` with a zero pad.
    #[inline(always)]
    pub fn new(v: DVec3) -> P4 {
        P4([v.x, v.y, v.z, 0.0])
    }

    /// The same value in every lane.
    #[inline(always)]
    pub fn splat(s: f64) -> P4 {
        P4([s; 4])
    }

    /// The three coordinates.
    #[inline(always)]
    pub fn xyz(self) -> DVec3 {
        DVec3::new(self.0[0], self.0[1], self.0[2])
    }

    /// `f(self[i], o[i])` per lane.
    #[inline(always)]
    fn zip(self, o: P4, f: impl Fn(f64, f64) -> f64) -> P4 {
        let (a, b) = (self.0, o.0);
        P4([f(a[0], b[0]), f(a[1], b[1]), f(a[2], b[2]), f(a[3], b[3])])
    }
}

/// How a kernel computes on points: in plain arrays ([`Plain`]), or in AVX
/// vectors ([`Avx`], only inside a function compiled with AVX, whose CPU
/// the caller checked). The same IEEE operation per lane either way.
pub(crate) trait Lanes {
    /// A point in registers.
    type V: Copy;
    /// `p`'s lanes.
    fn load(p: &P4) -> Self::V;
    /// The lanes as a point.
    fn store(v: Self::V) -> P4;
    /// `s` in every lane.
    fn splat(s: f64) -> Self::V;
    /// `a + b` per lane.
    fn add(a: Self::V, b: Self::V) -> Self::V;
    /// `a - b` per lane.
    fn sub(a: Self::V, b: Self::V) -> Self::V;
    /// `a * b` per lane.
    fn mul(a: Self::V, b: Self::V) -> Self::V;
    /// [`min_not_nan`]`(a, b)` per lane.
    fn min(a: Self::V, b: Self::V) -> Self::V;
    /// [`max_not_nan`]`(a, b)` per lane.
    fn max(a: Self::V, b: Self::V) -> Self::V;
    /// `v` with lane `LANE` (0 to 2) replaced by `s`.
    fn with_lane<const LANE: usize>(v: Self::V, s: f64) -> Self::V;
    /// `quantize_in_voxel` of the box `[lo, hi]` in the voxel of minimum
    /// corner `v0`, per axis: its `(lo, hi)` cells.
    fn quantize(lo: &P4, hi: &P4, v0: &P4, scale: f64, cells: u32) -> ([u16; 3], [u16; 3]);
}

/// [`Lanes`] in plain arrays: what the compiler makes of them.
pub(crate) struct Plain;

impl Lanes for Plain {
    type V = P4;
    #[inline(always)]
    fn load(p: &P4) -> P4 {
        *p
    }
    #[inline(always)]
    fn store(v: P4) -> P4 {
        v
    }
    #[inline(always)]
    fn splat(s: f64) -> P4 {
        P4::splat(s)
    }
    #[inline(always)]
    fn add(a: P4, b: P4) -> P4 {
        a.zip(b, |a, b| a + b)
    }
    #[inline(always)]
    fn sub(a: P4, b: P4) -> P4 {
        a.zip(b, |a, b| a - b)
    }
    #[inline(always)]
    fn mul(a: P4, b: P4) -> P4 {
        a.zip(b, |a, b| a * b)
    }
    #[inline(always)]
    fn min(a: P4, b: P4) -> P4 {
        a.zip(b, min_not_nan)
    }
    #[inline(always)]
    fn max(a: P4, b: P4) -> P4 {
        a.zip(b, max_not_nan)
    }
    #[inline(always)]
    fn with_lane<const LANE: usize>(mut v: P4, s: f64) -> P4 {
        v.0[LANE] = s;
        v
    }
    #[inline(always)]
    fn quantize(lo: &P4, hi: &P4, v0: &P4, scale: f64, cells: u32) -> ([u16; 3], [u16; 3]) {
        let q = |a: usize| quantize_in_voxel(lo.0[a], hi.0[a], v0.0[a], scale, cells);
        let [(lx, hx), (ly, hy), (lz, hz)] = [q(0), q(1), q(2)];
        ([lx, ly, lz], [hx, hy, hz])
    }
}

/// [`Lanes`] in AVX registers, for the builder's AVX copy only: its
/// functions are inlined into a function compiled with AVX (see
/// `build::place_range`), which runs only on a CPU that has it.
#[cfg(target_arch = "x86_64")]
pub(crate) struct Avx;

#[cfg(target_arch = "x86_64")]
mod avx {
    use super::{Avx, Lanes, Plain, P4};
    use std::arch::x86_64::*;

    // SAFETY (every `unsafe` below): `Avx` is used only inside functions
    // compiled with AVX that run after the CPU was checked to have it
    // (`build::place_range`), and `P4` is 32-byte aligned for the loads
    // and stores.
    impl Lanes for Avx {
        type V = __m256d;
        #[inline(always)]
        fn load(p: &P4) -> __m256d {
            unsafe { _mm256_load_pd(p.0.as_ptr()) }
        }
        #[inline(always)]
        fn store(v: __m256d) -> P4 {
            let mut p = P4::splat(0.0);
            unsafe { _mm256_store_pd(p.0.as_mut_ptr(), v) };
            p
        }
        #[inline(always)]
        fn splat(s: f64) -> __m256d {
            unsafe { _mm256_set1_pd(s) }
        }
        #[inline(always)]
        fn add(a: __m256d, b: __m256d) -> __m256d {
            unsafe { _mm256_add_pd(a, b) }
        }
        #[inline(always)]
        fn sub(a: __m256d, b: __m256d) -> __m256d {
            unsafe { _mm256_sub_pd(a, b) }
        }
        #[inline(always)]
        fn mul(a: __m256d, b: __m256d) -> __m256d {
            unsafe { _mm256_mul_pd(a, b) }
        }
        /// `vminpd b, a` is `b < a ? b : a` per lane: `min_not_nan(a, b)`,
        /// the same operand on a tie.
        #[inline(always)]
        fn min(a: __m256d, b: __m256d) -> __m256d {
            unsafe { _mm256_min_pd(b, a) }
        }
        /// `vmaxpd b, a` is `b > a ? b : a` per lane: `max_not_nan(a, b)`.
        #[inline(always)]
        fn max(a: __m256d, b: __m256d) -> __m256d {
            unsafe { _mm256_max_pd(b, a) }
        }
        #[inline(always)]
        fn with_lane<const LANE: usize>(v: __m256d, s: f64) -> __m256d {
            let s = Self::splat(s);
            unsafe {
                match LANE {
                    0 => _mm256_blend_pd::<1>(v, s),
                    1 => _mm256_blend_pd::<2>(v, s),
                    _ => _mm256_blend_pd::<4>(v, s),
                }
            }
        }
        /// `quantize_in_voxel`'s integers as binary64 integers, all exact
        /// (below `2^17`): `ta = (a - v0) scale` and `tb` are the same
        /// products, in `[0, 2^Q]`; its `lo = min(trunc(ta), top)`; its
        /// `c = trunc(tb) + (trunc(tb) < tb)` is `ceil(tb)` for `tb >= 0`;
        /// its `hi = min(max(c - 1, lo), top)`. `min`/`max` of integers
        /// (never NaN, equal only when the same integer) are those of `i64`.
        #[inline(always)]
        fn quantize(lo: &P4, hi: &P4, v0: &P4, scale: f64, cells: u32) -> ([u16; 3], [u16; 3]) {
            let (v0, scale4) = (Self::load(v0), Self::splat(scale));
            let ta = Self::mul(Self::sub(Self::load(lo), v0), scale4);
            let tb = Self::mul(Self::sub(Self::load(hi), v0), scale4);
            let top = Self::splat((cells - 1) as f64);
            let mut cells16 = [0u16; 8];
            unsafe {
                let ql = Self::min(
                    _mm256_round_pd::<{ _MM_FROUND_TO_ZERO | _MM_FROUND_NO_EXC }>(ta),
                    top,
                );
                let c = _mm256_round_pd::<{ _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC }>(tb);
                let qh = Self::min(Self::max(Self::sub(c, Self::splat(1.0)), ql), top);
                // Integers in `[0, 2^16 - 1]`: exact as `i32`, then as `u16`.
                let packed = _mm_packus_epi32(_mm256_cvttpd_epi32(ql), _mm256_cvttpd_epi32(qh));
                _mm_storeu_si128(cells16.as_mut_ptr().cast(), packed);
            }
            let [lx, ly, lz, _, hx, hy, hz, _] = cells16;
            let out = ([lx, ly, lz], [hx, hy, hz]);
            debug_assert_eq!(out, Plain::quantize(lo, hi, &Self::store(v0), scale, cells));
            out
        }
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;

    /// `Avx`'s min and max of `(a, b)`, compiled with AVX.
    #[target_feature(enable = "avx")]
    fn avx_min_max(a: &P4, b: &P4) -> [P4; 2] {
        let (va, vb) = (Avx::load(a), Avx::load(b));
        [Avx::store(Avx::min(va, vb)), Avx::store(Avx::max(va, vb))]
    }

    fn bits(p: P4) -> [u64; 4] {
        p.0.map(f64::to_bits)
    }

    /// The lanes pick the operand the scalar `min_not_nan`/`max_not_nan`
    /// pick, zero signs included (the tie the instruction's operand order
    /// decides), and quantize as the scalar code does. Only where the CPU
    /// has AVX, the only place the AVX lanes run.
    #[test]
    fn avx_lanes_match_the_plain_ones() {
        if !std::arch::is_x86_feature_detected!("avx") {
            return;
        }
        let values = [0.0, -0.0, 1.0, 0.5, 2.0, -1.0];
        for &x in &values {
            for &y in &values {
                let (a, b) = (P4([x, y, x, y]), P4([y, x, x, y]));
                // SAFETY: the CPU has AVX (checked above).
                let [min, max] = unsafe { avx_min_max(&a, &b) };
                assert_eq!(bits(min), bits(Plain::min(a, b)), "min {a:?} {b:?}");
                assert_eq!(bits(max), bits(Plain::max(a, b)), "max {a:?} {b:?}");
            }
        }
        // Boxes in the voxel [8, 16]^3 at 256 cells: every cell boundary,
        // and values between them.
        let scale = 256.0 / 8.0;
        for i in 0..=512 {
            let t = 8.0 + i as f64 / 64.0;
            let lo = P4([8.0, t.min(12.0), t, 0.0]);
            let hi = P4([t, 16.0, t.max(12.0), 0.0]);
            let v0 = P4::splat(8.0);
            let want = Plain::quantize(&lo, &hi, &v0, scale, 256);
            // SAFETY: the CPU has AVX (checked above).
            let got = unsafe { avx_quantize(&lo, &hi, &v0, scale) };
            assert_eq!(got, want, "{lo:?} {hi:?}");
        }
    }

    #[target_feature(enable = "avx")]
    fn avx_quantize(lo: &P4, hi: &P4, v0: &P4, scale: f64) -> ([u16; 3], [u16; 3]) {
        Avx::quantize(lo, hi, v0, scale, 256)
    }
}
