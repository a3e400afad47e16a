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
}

/// [`Lanes`] in AVX registers, for the builder's AVX copy only: its
/// functions are inlined into a function compiled with AVX (see
/// `build::place_range`), which runs only on a CPU that has it.
#[cfg(target_arch = "x86_64")]
pub(crate) struct Avx;

#[cfg(target_arch = "x86_64")]
mod avx {
    use super::{Avx, Lanes, P4};
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
    }
}
