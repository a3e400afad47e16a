//! [`Bits`]: an arbitrary-width bit vector, the value type of constants,
//! reset values and the simulator.

use crate::words;
use std::fmt;

/// An unsigned bit vector of any width (stored little-endian in `u64` words).
///
/// Whether the bits mean a signed or unsigned number is decided by the signal
/// that carries them; `Bits` itself is just the pattern.
///
/// ```
/// use rtl_gen::Bits;
/// let x = Bits::from_u128(0xff, 8).unwrap();
/// assert_eq!(x.width(), 8);
/// assert_eq!(x.to_u128(), Some(0xff));
/// assert!(Bits::from_u128(256, 8).is_err()); // does not fit: an error, never a wrap
/// let minus_one = Bits::from_i128(-1, 300).unwrap();
/// assert_eq!(minus_one.to_i128(), Some(-1));
/// assert_eq!(format!("{}", Bits::from_u128(3, 12).unwrap()), "12'h003");
/// ```
#[derive(Clone, PartialEq, Eq, Hash)]
pub struct Bits {
    width: u32,
    words: Vec<u64>,
}

/// A value that does not fit in the requested width.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DoesNotFit {
    /// The value, in decimal.
    pub value: String,
    /// The width it was asked to fit.
    pub width: u32,
}

impl fmt::Display for DoesNotFit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "value {} does not fit in {} bits",
            self.value, self.width
        )
    }
}

impl std::error::Error for DoesNotFit {}

impl Bits {
    /// All-zero value of `width` bits.
    pub fn zero(width: u32) -> Bits {
        Bits {
            width,
            words: vec![0; words::words_for(width)],
        }
    }

    /// All-one value of `width` bits.
    pub fn ones(width: u32) -> Bits {
        let mut b = Bits {
            width,
            words: vec![u64::MAX; words::words_for(width)],
        };
        words::clamp(&mut b.words, width);
        b
    }

    /// The unsigned `value` in `width` bits; an error if it needs more bits.
    pub fn from_u128(value: u128, width: u32) -> Result<Bits, DoesNotFit> {
        if width < 128 && value >> width != 0 {
            return Err(DoesNotFit {
                value: value.to_string(),
                width,
            });
        }
        Ok(Bits::from_u128_truncating(value, width))
    }

    /// The low `width` bits of `value` (explicit truncation).
    pub fn from_u128_truncating(value: u128, width: u32) -> Bits {
        let mut b = Bits::zero(width);
        b.words[0] = value as u64;
        if b.words.len() > 1 {
            b.words[1] = (value >> 64) as u64;
        }
        words::clamp(&mut b.words, width);
        b
    }

    /// The signed `value` in two's complement in `width` bits; an error if it
    /// is outside `-2^(width-1) ..= 2^(width-1)-1`.
    pub fn from_i128(value: i128, width: u32) -> Result<Bits, DoesNotFit> {
        let fits = match width {
            0 => false,
            128.. => true,
            w => {
                let half = 1i128 << (w - 1);
                (-half..half).contains(&value)
            }
        };
        if !fits {
            return Err(DoesNotFit {
                value: value.to_string(),
                width,
            });
        }
        let mut b = Bits::zero(width);
        let fill = if value < 0 { u64::MAX } else { 0 };
        for (i, w) in b.words.iter_mut().enumerate() {
            *w = match i {
                0 => value as u64,
                1 => (value >> 64) as u64,
                _ => fill,
            };
        }
        words::clamp(&mut b.words, width);
        Ok(b)
    }

    /// Builds a value from little-endian words; bits beyond `width` must be zero.
    pub fn from_words(words_le: &[u64], width: u32) -> Result<Bits, DoesNotFit> {
        let mut b = Bits::zero(width);
        for (i, &w) in words_le.iter().enumerate() {
            if i < b.words.len() {
                b.words[i] = w;
            } else if w != 0 {
                return Err(DoesNotFit {
                    value: "(wide word list)".into(),
                    width,
                });
            }
        }
        let before = b.words.clone();
        words::clamp(&mut b.words, width);
        if before != b.words {
            return Err(DoesNotFit {
                value: format!("{:?}", words_le),
                width,
            });
        }
        Ok(b)
    }

    /// Builds a value from bits, index 0 = least significant.
    pub fn from_bools(bits: &[bool]) -> Bits {
        let mut b = Bits::zero(bits.len() as u32);
        for (i, &v) in bits.iter().enumerate() {
            words::set_bit(&mut b.words, i as u32, v);
        }
        b
    }

    /// Width in bits.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Little-endian words; bits at and above `width` are zero.
    pub fn words(&self) -> &[u64] {
        &self.words
    }

    /// Bit `i` (0 = least significant); false beyond the width.
    pub fn bit(&self, i: u32) -> bool {
        i < self.width && words::get_bit(&self.words, i)
    }

    /// The value as an unsigned integer when it fits in 128 bits.
    pub fn to_u128(&self) -> Option<u128> {
        if self.words.iter().skip(2).any(|&w| w != 0) {
            return None;
        }
        let lo = self.words[0] as u128;
        let hi = self.words.get(1).copied().unwrap_or(0) as u128;
        Some(lo | (hi << 64))
    }

    /// The value as an unsigned integer when it fits in 64 bits.
    pub fn to_u64(&self) -> Option<u64> {
        self.to_u128().and_then(|v| u64::try_from(v).ok())
    }

    /// The value read as two's complement, when it fits in an `i128`.
    pub fn to_i128(&self) -> Option<i128> {
        if self.width == 0 {
            return Some(0);
        }
        let neg = self.bit(self.width - 1);
        if self.width <= 128 {
            let u = self.to_u128()?;
            if !neg || self.width == 128 {
                return Some(u as i128);
            }
            return Some((u | (u128::MAX << self.width)) as i128);
        }
        // Wider: every bit from 127 upward must equal the sign.
        if (127..self.width).any(|i| self.bit(i) != neg) {
            return None;
        }
        let lo = self.words[0] as u128 | ((self.words[1] as u128) << 64);
        Some(lo as i128)
    }

    /// Bits `lo ..= hi`, or `None` when out of range.
    pub fn slice(&self, hi: u32, lo: u32) -> Option<Bits> {
        if hi < lo || hi >= self.width {
            return None;
        }
        let w = hi - lo + 1;
        let mut out = Bits::zero(w);
        words::extract(&mut out.words, &self.words, lo, w);
        Some(out)
    }

    /// Zero- or sign-extension to `width` (must be at least the current width).
    pub fn extend(&self, width: u32, signed: bool) -> Option<Bits> {
        if width < self.width || self.width == 0 {
            return None;
        }
        let mut out = Bits::zero(width);
        words::extend(&mut out.words, &self.words, self.width, width, signed);
        Some(out)
    }

    /// `{self, low}`: `self` in the high bits.
    pub fn concat(&self, low: &Bits) -> Bits {
        let mut out = Bits::zero(self.width + low.width);
        words::deposit(&mut out.words, &low.words, 0, low.width);
        words::deposit(&mut out.words, &self.words, low.width, self.width);
        out
    }

    /// Hexadecimal digits without prefix, most significant first, padded to the width.
    pub fn to_hex(&self) -> String {
        let digits = (self.width as usize).div_ceil(4).max(1);
        let mut s = String::with_capacity(digits);
        for d in (0..digits).rev() {
            let mut v = 0;
            for k in 0..4 {
                if self.bit(d as u32 * 4 + k) {
                    v |= 1 << k;
                }
            }
            s.push(char::from_digit(v, 16).unwrap_or('0'));
        }
        s
    }
}

impl fmt::Display for Bits {
    /// Verilog-style sized hexadecimal, e.g. `12'h003`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}'h{}", self.width, self.to_hex())
    }
}

impl fmt::Debug for Bits {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}
