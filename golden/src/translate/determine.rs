//! Determine (FIG. 15 S1502): from a requested placement, the voxel-aligned
//! translation at the granularity of LOD `L` and the residual.
//!
//! Convention (SPEC section 7.1): a hierarchy is built in local grid
//! coordinates; placement `p` (per axis, grid units) puts local grid point 0
//! at scene grid point `p`. With `k = D - L` (the LOD-`L` voxel edge is
//! `2^k`), the translation is `t = round_half_even(p / 2^k)` and the
//! residual `r = p - t 2^k`, so `p = t 2^k + r` exactly and
//! `|r| <= 2^(k-1)`. Everything is computed from the encoding's fields with
//! integer shifts, adds and compares.

use serde::{Deserialize, Serialize};

use super::error::{Axis, TranslateError};
use super::extents::{check_scene_extents, VoxelRange};
use super::float::{bit_length, pack_exact, unpack, Decoded, FloatFormat, Format};
use super::translation::{trans_bits, trans_max, Translation};
use crate::params::Params;

/// A requested placement: three IEEE-754 encodings of one format, in grid
/// units. binary32 encodings sit in the low 32 bits of each `u64`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Placement {
    /// Format of all three encodings.
    pub format: Format,
    /// Encodings x, y, z; binary32 in bits 31..0 with the bits above zero.
    pub bits: [u64; 3],
}

impl Placement {
    /// A binary32 placement from its encodings.
    pub fn from_bits32(bits: [u32; 3]) -> Placement {
        Placement {
            format: Format::Binary32,
            bits: bits.map(u64::from),
        }
    }

    /// A binary64 placement from its encodings.
    pub fn from_bits64(bits: [u64; 3]) -> Placement {
        Placement {
            format: Format::Binary64,
            bits,
        }
    }

    /// A binary32 placement (the encodings of the given values).
    pub fn binary32(v: [f32; 3]) -> Placement {
        Placement::from_bits32(v.map(f32::to_bits))
    }

    /// A binary64 placement (the encodings of the given values).
    pub fn binary64(v: [f64; 3]) -> Placement {
        Placement::from_bits64(v.map(f64::to_bits))
    }

    /// The value on `axis` as an `f64` (exact for both formats); for display
    /// and for software that wants numbers, never used by the unit itself.
    pub fn value_f64(&self, axis: Axis) -> f64 {
        let b = self.bits[axis.index()];
        match self.format {
            Format::Binary32 => f32::from_bits(b as u32) as f64,
            Format::Binary64 => f64::from_bits(b),
        }
    }
}

/// What determine produces: the translation and the exact residual.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Determined {
    /// The voxel-aligned translation `(L, t)` (SPEC 7.1).
    pub translation: Translation,
    /// `p - t 2^(D-L)` per axis, in the placement's format, exact; zero is +0.
    pub residual: Placement,
}

/// Why one axis of a placement cannot be rounded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AxisFault {
    /// A NaN, of any payload or sign.
    NotANumber,
    /// An infinity.
    Infinite {
        /// True for `-inf`.
        negative: bool,
    },
    /// `|round(p / 2^k)|` exceeds the largest field magnitude.
    TooLarge,
}

/// One axis rounded: the signed translation and the residual's encoding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AxisRounding {
    /// Signed translation in voxels of edge `2^k`; `|t| < 2^max_bits`.
    pub t: i64,
    /// Encoding of the residual `p - t 2^k` in the placement's format; +0 when it is zero.
    pub residual_bits: u64,
}

/// A right shift that keeps what the rounding needs: the kept bits, the
/// round (first dropped) bit, and the sticky OR of the bits below it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shifted {
    /// `sig >> n`.
    pub kept: u64,
    /// Bit `n - 1` of `sig`, the first bit dropped.
    pub round: bool,
    /// True when any bit below the round bit is set.
    pub sticky: bool,
}

/// Shifts `sig` (below `2^precision`) right by `n` (0 keeps all), keeping round and
/// sticky bits. Shifts beyond `precision + 1` saturate to `precision + 1`:
/// they leave `kept = 0, round = 0, sticky = (sig != 0)` either way, so the
/// shifter is `precision + 2` bits wide.
pub fn shift_right_round_sticky(sig: u64, n: u32, precision: u32) -> Shifted {
    if n == 0 {
        return Shifted {
            kept: sig,
            round: false,
            sticky: false,
        };
    }
    let n = n.min(precision + 1).min(64);
    Shifted {
        kept: ((sig as u128) >> n) as u64,
        round: ((sig as u128) >> (n - 1)) & 1 == 1,
        sticky: (sig as u128) & ((1u128 << (n - 1)) - 1) != 0,
    }
}

/// Round half to even on a shifted magnitude: add one when the dropped part
/// is above one half, or exactly one half and the kept value is odd.
pub fn round_half_even_increment(s: &Shifted) -> bool {
    s.round && (s.sticky || s.kept & 1 == 1)
}

/// The residual of a right-shift rounding in units of the input's lsb:
/// the dropped low `n` bits, minus `2^n` when the kept part was rounded up.
/// Its magnitude is at most `2^(n-1)`. `n` saturates as in
/// [`shift_right_round_sticky`] (then nothing is rounded up and the residual
/// is all of `sig`).
pub fn residual_units(sig: u64, n: u32, precision: u32, increment: bool) -> i128 {
    let n = n.min(precision + 1).min(64);
    let low = ((sig as u128) & ((1u128 << n) - 1)) as i128;
    if increment {
        low - (1i128 << n)
    } else {
        low
    }
}

/// Rounds one axis: `t = round_half_even(p / 2^k)` and `r = p - t 2^k`.
///
/// `p = (-1)^s m 2^e` (from [`unpack`]). With `shift = e - k`:
/// - `m = 0`: `t = 0`, `r = +0`;
/// - `shift >= 0`: `t = m << shift` exactly, `r = +0`; too large when
///   `bit_length(m) + shift > max_bits`;
/// - `shift < 0`: `n = -shift`, `t = (m >> n) + round_half_even_increment`,
///   `r = residual_units * 2^e` with the sign of `p` (flipped when negative
///   units), encoded in the same format.
///
/// `max_bits` is the most bits `|t|` may have (`D`: `|t| <= 2^D - 1`).
pub fn round_axis(
    fmt: FloatFormat,
    bits: u64,
    k: u32,
    max_bits: u32,
) -> Result<AxisRounding, AxisFault> {
    let u = match unpack(fmt, bits) {
        Decoded::NaN => return Err(AxisFault::NotANumber),
        Decoded::Infinite { negative } => return Err(AxisFault::Infinite { negative }),
        Decoded::Finite(u) => u,
    };
    let positive_zero = 0u64;
    if u.significand == 0 {
        return Ok(AxisRounding {
            t: 0,
            residual_bits: positive_zero,
        });
    }
    let shift = u.lsb_exponent - k as i32;
    let (magnitude, residual_bits) = if shift >= 0 {
        // p is a multiple of 2^k: t is exact, nothing is left over.
        if bit_length(u.significand) as i64 + shift as i64 > max_bits as i64 {
            return Err(AxisFault::TooLarge);
        }
        (u.significand << shift, positive_zero)
    } else {
        let n = (-shift) as u32;
        let s = shift_right_round_sticky(u.significand, n, fmt.precision());
        let inc = round_half_even_increment(&s);
        let magnitude = s.kept + inc as u64;
        if bit_length(magnitude) > max_bits {
            return Err(AxisFault::TooLarge);
        }
        let r = residual_units(u.significand, n, fmt.precision(), inc);
        (
            magnitude,
            encode_residual(fmt, u.negative, r, u.lsb_exponent),
        )
    };
    let t = if u.negative {
        -(magnitude as i64)
    } else {
        magnitude as i64
    };
    Ok(AxisRounding { t, residual_bits })
}

/// Encodes `(-1)^negative * units * 2^lsb_exponent`; zero as +0.
///
/// Always exact (SPEC 7.2): either `t = 0` and the residual is `p` itself,
/// or `|p| > 2^(k-1)`, so `p`'s lsb exponent is at least `k - precision`,
/// and `|units| <= 2^(n-1)` with `n = k - e` means `|units| <= 2^(precision-1)`:
/// the residual has at most `precision` significant bits on `p`'s own lsb
/// grid, which is on or above the format's smallest lsb.
fn encode_residual(fmt: FloatFormat, negative: bool, units: i128, lsb_exponent: i32) -> u64 {
    if units == 0 {
        return 0;
    }
    let sign = negative != (units < 0);
    pack_exact(fmt, sign, units.unsigned_abs() as u64, lsb_exponent)
        .expect("the residual is exactly representable (SPEC 7.2)")
}

/// Rounds a placement to LOD-`lod` voxels without the extents rule: checks
/// `lod <= D`, then each axis x, y, z in order (encoding width, NaN,
/// infinity, field range); the first failure is the error.
pub fn round_placement(
    placement: &Placement,
    lod: u8,
    p: &Params,
) -> Result<Determined, TranslateError> {
    if lod > p.max_lod {
        return Err(TranslateError::LodAboveMax {
            lod,
            max_lod: p.max_lod,
        });
    }
    let fmt = placement.format.layout();
    let k = (p.max_lod - lod) as u32;
    let max_bits = bit_length(trans_max(p) as u64);
    let mut t = [0i64; 3];
    let mut residual = [0u64; 3];
    for axis in Axis::ALL {
        let bits = placement.bits[axis.index()];
        if !fmt.fits(bits) {
            return Err(TranslateError::PlacementTooWide { axis, bits });
        }
        let a = round_axis(fmt, bits, k, max_bits).map_err(|f| match f {
            AxisFault::NotANumber => TranslateError::NotANumber { axis, bits },
            AxisFault::Infinite { negative } => TranslateError::Infinite { axis, negative },
            AxisFault::TooLarge => TranslateError::TranslationTooLarge {
                axis,
                bits,
                field_bits: trans_bits(p),
            },
        })?;
        t[axis.index()] = a.t;
        residual[axis.index()] = a.residual_bits;
    }
    Ok(Determined {
        translation: Translation { lod, t },
        residual: Placement {
            format: placement.format,
            bits: residual,
        },
    })
}

/// Determine: the translation at LOD `lod` nearest (ties to even) to the
/// placement, and the residual, subject to the scene-extents rule.
///
/// `extents` is the hierarchy's occupied voxel range at LOD `lod` (see
/// [`VoxelRange::of_nodes`]). Checks, in order: `lod <= D`; `extents.lod ==
/// lod`; the extents are a valid range; [`round_placement`]; the extents
/// rule ([`check_scene_extents`]). The first failure is the error.
pub fn determine(
    placement: &Placement,
    lod: u8,
    extents: &VoxelRange,
    p: &Params,
) -> Result<Determined, TranslateError> {
    if lod > p.max_lod {
        return Err(TranslateError::LodAboveMax {
            lod,
            max_lod: p.max_lod,
        });
    }
    if extents.lod != lod {
        return Err(TranslateError::ExtentsLodMismatch {
            extents_lod: extents.lod,
            lod,
        });
    }
    extents.validate(p)?;
    let d = round_placement(placement, lod, p)?;
    check_scene_extents(extents, &d.translation, p)?;
    Ok(d)
}

#[cfg(test)]
mod tests {
    use super::super::float::{BINARY32, BINARY64};
    use super::*;

    fn r32(v: f32, k: u32) -> (i64, f32) {
        let a = round_axis(BINARY32, v.to_bits() as u64, k, 31).unwrap();
        (a.t, f32::from_bits(a.residual_bits as u32))
    }

    #[test]
    fn ties_go_to_even() {
        assert_eq!(r32(2.5, 0), (2, 0.5));
        assert_eq!(r32(3.5, 0), (4, -0.5));
        assert_eq!(r32(-2.5, 0), (-2, -0.5));
        assert_eq!(r32(-3.5, 0), (-4, 0.5));
        assert_eq!(r32(0.5, 0), (0, 0.5));
        assert_eq!(r32(1.5, 0), (2, -0.5));
        // 12 / 8 = 1.5 -> 2, residual 12 - 16 = -4.
        assert_eq!(r32(12.0, 3), (2, -4.0));
        assert_eq!(r32(20.0, 3), (2, 4.0));
    }

    #[test]
    fn zero_residual_is_positive_zero() {
        let a = round_axis(BINARY64, (-0.0f64).to_bits(), 4, 31).unwrap();
        assert_eq!((a.t, a.residual_bits), (0, 0));
        let a = round_axis(BINARY64, (-64.0f64).to_bits(), 4, 31).unwrap();
        assert_eq!((a.t, a.residual_bits), (-4, 0));
    }

    #[test]
    fn saturated_shift_keeps_everything_as_residual() {
        let tiny = f64::from_bits(1); // the smallest subnormal
        let a = round_axis(BINARY64, tiny.to_bits(), 31, 31).unwrap();
        assert_eq!((a.t, a.residual_bits), (0, 1));
    }

    #[test]
    fn too_large_and_specials() {
        assert_eq!(
            round_axis(BINARY32, (2147483648.0f32).to_bits() as u64, 0, 31),
            Err(AxisFault::TooLarge)
        );
        assert_eq!(
            round_axis(BINARY64, f64::MAX.to_bits(), 0, 31),
            Err(AxisFault::TooLarge)
        );
        assert_eq!(
            round_axis(BINARY64, f64::NAN.to_bits(), 0, 31),
            Err(AxisFault::NotANumber)
        );
        assert_eq!(
            round_axis(BINARY64, f64::NEG_INFINITY.to_bits(), 0, 31),
            Err(AxisFault::Infinite { negative: true })
        );
    }
}
