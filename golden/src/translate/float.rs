//! IEEE-754 binary interchange formats, taken apart and put together with
//! integer operations only (no float arithmetic), in the style of Berkeley
//! SoftFloat. The translation unit reads placements and writes residuals in
//! these encodings; the RTL mirrors every function here.

use serde::{Deserialize, Serialize};

/// An IEEE-754 binary format, described by its field widths.
///
/// An encoding is `sign | exponent field (exp_bits) | fraction (frac_bits)`
/// from the top bit down, as in IEEE 754-2019 section 3.4.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct FloatFormat {
    /// Width of the exponent field.
    pub exp_bits: u32,
    /// Width of the fraction field (the significand without its hidden bit).
    pub frac_bits: u32,
}

/// binary32 (`f32`): 8 exponent bits, 23 fraction bits.
pub const BINARY32: FloatFormat = FloatFormat {
    exp_bits: 8,
    frac_bits: 23,
};
/// binary64 (`f64`): 11 exponent bits, 52 fraction bits.
pub const BINARY64: FloatFormat = FloatFormat {
    exp_bits: 11,
    frac_bits: 52,
};

/// Which of the two placement formats a value is in; the `format` flag of
/// the unit's ports (0: binary32, 1: binary64).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// IEEE-754 binary32; format flag 0.
    Binary32,
    /// IEEE-754 binary64; format flag 1.
    Binary64,
}

impl Format {
    /// The field widths of this format.
    pub fn layout(self) -> FloatFormat {
        match self {
            Format::Binary32 => BINARY32,
            Format::Binary64 => BINARY64,
        }
    }

    /// The port encoding of the format flag.
    pub fn flag(self) -> u8 {
        match self {
            Format::Binary32 => 0,
            Format::Binary64 => 1,
        }
    }
}

impl FloatFormat {
    /// Width of an encoding: `1 + exp_bits + frac_bits`.
    pub fn total_bits(&self) -> u32 {
        1 + self.exp_bits + self.frac_bits
    }

    /// Exponent bias: `2^(exp_bits-1) - 1`.
    pub fn bias(&self) -> i32 {
        (1i32 << (self.exp_bits - 1)) - 1
    }

    /// The all-ones exponent field that marks infinities and NaNs.
    pub fn exp_field_max(&self) -> u64 {
        (1u64 << self.exp_bits) - 1
    }

    /// Significand width including the hidden bit: `frac_bits + 1`.
    pub fn precision(&self) -> u32 {
        self.frac_bits + 1
    }

    /// Exponent of the least significant bit of a subnormal (and of the
    /// smallest normal binade): `1 - bias - frac_bits`.
    pub fn min_lsb_exponent(&self) -> i32 {
        1 - self.bias() - self.frac_bits as i32
    }

    fn frac_mask(&self) -> u64 {
        (1u64 << self.frac_bits) - 1
    }

    /// True when `bits` has nothing set above the encoding's width.
    pub fn fits(&self, bits: u64) -> bool {
        self.total_bits() == 64 || bits >> self.total_bits() == 0
    }
}

/// A finite value taken apart: `(-1)^negative * significand * 2^lsb_exponent`.
///
/// `significand` is the integer significand with the hidden bit made
/// explicit for normals (so it is below `2^precision`); zero has
/// significand 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Unpacked {
    /// The sign bit; true also for `-0`.
    pub negative: bool,
    /// Integer significand, below `2^precision`; 0 for either zero.
    pub significand: u64,
    /// Exponent of the significand's least significant bit.
    pub lsb_exponent: i32,
}

/// The classes of an encoding the translation unit tells apart.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Decoded {
    /// A zero, subnormal or normal number.
    Finite(Unpacked),
    /// Exponent field all ones, fraction 0: an infinity.
    Infinite {
        /// True for `-inf`.
        negative: bool,
    },
    /// Exponent field all ones, fraction not 0: a NaN of any payload or sign.
    NaN,
}

/// Takes an encoding apart into sign, integer significand and the exponent
/// of its least significant bit. `bits` must fit the format (see
/// [`FloatFormat::fits`]); bits above the width are ignored here.
pub fn unpack(fmt: FloatFormat, bits: u64) -> Decoded {
    let negative = (bits >> (fmt.exp_bits + fmt.frac_bits)) & 1 == 1;
    let exp_field = (bits >> fmt.frac_bits) & fmt.exp_field_max();
    let fraction = bits & fmt.frac_mask();
    if exp_field == fmt.exp_field_max() {
        return if fraction == 0 {
            Decoded::Infinite { negative }
        } else {
            Decoded::NaN
        };
    }
    // A subnormal (field 0) has no hidden bit and the exponent of field 1.
    let (significand, exp_field_eff) = if exp_field == 0 {
        (fraction, 1)
    } else {
        (fraction | (1u64 << fmt.frac_bits), exp_field as i32)
    };
    Decoded::Finite(Unpacked {
        negative,
        significand,
        lsb_exponent: exp_field_eff - fmt.bias() - fmt.frac_bits as i32,
    })
}

/// Bits needed to write `v` (0 for 0): the position of its leading one plus one.
pub fn bit_length(v: u64) -> u32 {
    64 - v.leading_zeros()
}

/// Encodes `(-1)^negative * magnitude * 2^lsb_exponent` exactly.
///
/// Returns `None` when the value is not representable without rounding
/// (more significant bits than the precision, below the subnormal grid, or
/// above the largest finite). Zero encodes with the given sign.
pub fn pack_exact(
    fmt: FloatFormat,
    negative: bool,
    magnitude: u64,
    lsb_exponent: i32,
) -> Option<u64> {
    let sign = (negative as u64) << (fmt.exp_bits + fmt.frac_bits);
    if magnitude == 0 {
        return Some(sign);
    }
    // Strip trailing zeros so the exponent is as large as it can be; this is
    // only a normal form, the value is unchanged.
    let tz = magnitude.trailing_zeros();
    let (mag, lsb) = (magnitude >> tz, lsb_exponent + tz as i32);
    if bit_length(mag) > fmt.precision() || lsb < fmt.min_lsb_exponent() {
        return None;
    }
    // Unbiased exponent of the leading one, and its biased field.
    let lead = lsb + bit_length(mag) as i32 - 1;
    let exp_field = lead + fmt.bias();
    if exp_field >= fmt.exp_field_max() as i32 {
        return None;
    }
    if exp_field >= 1 {
        // Normal: put the leading one at the hidden-bit position and drop it.
        let aligned = mag << (fmt.frac_bits + 1 - bit_length(mag));
        Some(sign | ((exp_field as u64) << fmt.frac_bits) | (aligned & fmt.frac_mask()))
    } else {
        // Subnormal: the fraction counts units of 2^min_lsb_exponent.
        let fraction = mag << (lsb - fmt.min_lsb_exponent());
        Some(sign | fraction)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unpack_matches_the_standard_library_on_edges() {
        for v in [1.0f64, -2.5, f64::MIN_POSITIVE, 5e-324, f64::MAX, 0.1, -0.0] {
            match unpack(BINARY64, v.to_bits()) {
                Decoded::Finite(u) => {
                    let back = u.significand as f64 * (u.lsb_exponent as f64).exp2();
                    assert_eq!(back.abs(), v.abs(), "{v}");
                    assert_eq!(u.negative, v.is_sign_negative());
                }
                other => panic!("{v} decoded as {other:?}"),
            }
        }
        assert_eq!(unpack(BINARY32, f32::NAN.to_bits() as u64), Decoded::NaN);
        assert_eq!(
            unpack(BINARY32, f32::NEG_INFINITY.to_bits() as u64),
            Decoded::Infinite { negative: true }
        );
    }

    #[test]
    fn pack_round_trips_every_unpacked_finite() {
        for v in [
            1.0f32,
            -3.75,
            f32::MIN_POSITIVE,
            1e-45,
            -1.5e-40,
            f32::MAX,
            0.0,
        ] {
            let Decoded::Finite(u) = unpack(BINARY32, v.to_bits() as u64) else {
                panic!("not finite")
            };
            assert_eq!(
                pack_exact(BINARY32, u.negative, u.significand, u.lsb_exponent),
                Some(v.to_bits() as u64)
            );
        }
    }

    #[test]
    fn pack_refuses_what_needs_rounding() {
        assert_eq!(pack_exact(BINARY32, false, (1 << 24) + 1, 0), None);
        assert_eq!(pack_exact(BINARY32, false, 1, -150), None);
        assert_eq!(pack_exact(BINARY32, false, 1, 128), None);
        assert_eq!(pack_exact(BINARY32, false, 3, -150), None);
        assert_eq!(pack_exact(BINARY32, false, 2, -150), Some(1));
    }
}
