//! Arbitrary-width two-state bit vectors, the values carried by ports.
//!
//! Stored as 64-bit words, least significant word first, with every bit at or
//! above `width` kept zero (so equality and hashing are plain word compares).

use crate::error::{CosimError, Result};
use std::fmt;

/// A bit vector of a fixed width; bits above the width are always zero.
#[derive(Clone, PartialEq, Eq, Hash, Default)]
pub struct BitVec {
    width: usize,
    words: Vec<u64>,
}

fn words_for(width: usize) -> usize {
    width.div_ceil(64)
}

/// Number of bits needed to hold `v` (0 for 0).
fn significant_bits_u128(v: u128) -> usize {
    128 - v.leading_zeros() as usize
}

impl BitVec {
    /// All zeros, `width` bits.
    pub fn zeros(width: usize) -> BitVec {
        BitVec {
            width,
            words: vec![0; words_for(width)],
        }
    }

    /// All ones, `width` bits.
    pub fn ones(width: usize) -> BitVec {
        let mut v = BitVec {
            width,
            words: vec![u64::MAX; words_for(width)],
        };
        v.clear_above_width();
        v
    }

    /// `value` as a `width`-bit vector; an error if it does not fit.
    pub fn from_u64(width: usize, value: u64) -> Result<BitVec> {
        BitVec::from_u128(width, value as u128)
    }

    /// `value` as a `width`-bit vector; an error if it does not fit.
    pub fn from_u128(width: usize, value: u128) -> Result<BitVec> {
        let needed = significant_bits_u128(value);
        if needed > width {
            return Err(CosimError::Parse {
                text: format!("{value:#x}"),
                what: format!("needs {needed} bits, more than the width {width}"),
            });
        }
        let mut v = BitVec::zeros(width);
        for (i, w) in v.words.iter_mut().enumerate().take(2) {
            *w = (value >> (64 * i)) as u64;
        }
        Ok(v)
    }

    /// From LSB-first words; an error if any bit at or above `width` is set
    /// or there are more words than the width needs.
    pub fn from_words(width: usize, words: &[u64]) -> Result<BitVec> {
        let mut v = BitVec::zeros(width);
        for (i, &w) in words.iter().enumerate() {
            if i >= v.words.len() {
                if w != 0 {
                    return Err(CosimError::Parse {
                        text: format!("word {i} = {w:#x}"),
                        what: format!("bits above the width {width} are set"),
                    });
                }
                continue;
            }
            v.words[i] = w;
        }
        let before = v.words.clone();
        v.clear_above_width();
        if before != v.words {
            return Err(CosimError::Parse {
                text: format!("{words:x?}"),
                what: format!("bits above the width {width} are set"),
            });
        }
        Ok(v)
    }

    /// A record packed by one of golden's layouts.
    pub fn from_layout(b: &golden::bits::Bits) -> Result<BitVec> {
        BitVec::from_words(b.width() as usize, b.words())
    }

    /// From hexadecimal text (optional `0x`, `_` separators allowed); an error
    /// on a non-hex digit or a value that does not fit `width`.
    pub fn from_hex(width: usize, text: &str) -> Result<BitVec> {
        let digits = text.trim();
        let digits = digits
            .strip_prefix("0x")
            .or_else(|| digits.strip_prefix("0X"))
            .unwrap_or(digits);
        let mut v = BitVec::zeros(width);
        let mut bit = 0usize;
        if digits.is_empty() {
            return Err(CosimError::Parse {
                text: text.to_string(),
                what: "no hex digits".to_string(),
            });
        }
        for c in digits.chars().rev() {
            if c == '_' {
                continue;
            }
            let nibble = c.to_digit(16).ok_or_else(|| CosimError::Parse {
                text: text.to_string(),
                what: format!("`{c}` is not a hex digit"),
            })? as u64;
            for k in 0..4 {
                if nibble >> k & 1 == 1 {
                    if bit + k >= width {
                        return Err(CosimError::Parse {
                            text: text.to_string(),
                            what: format!("value does not fit in {width} bits"),
                        });
                    }
                    v.words[(bit + k) / 64] |= 1 << ((bit + k) % 64);
                }
            }
            bit += 4;
        }
        Ok(v)
    }

    /// The width in bits.
    pub fn width(&self) -> usize {
        self.width
    }

    /// The LSB-first words (bits above the width are zero).
    pub fn words(&self) -> &[u64] {
        &self.words
    }

    /// Bit `i`; false past the width.
    pub fn bit(&self, i: usize) -> bool {
        i < self.width && self.words[i / 64] >> (i % 64) & 1 == 1
    }

    /// Set bit `i` to `value`; an error past the width.
    pub fn set_bit(&mut self, i: usize, value: bool) -> Result<()> {
        if i >= self.width {
            return Err(CosimError::Parse {
                text: format!("bit {i}"),
                what: format!("past the width {}", self.width),
            });
        }
        let mask = 1u64 << (i % 64);
        if value {
            self.words[i / 64] |= mask;
        } else {
            self.words[i / 64] &= !mask;
        }
        Ok(())
    }

    /// Invert bit `i`; an error past the width.
    pub fn flip_bit(&mut self, i: usize) -> Result<()> {
        let b = self.bit(i);
        self.set_bit(i, !b)
    }

    /// True when every bit is zero.
    pub fn is_zero(&self) -> bool {
        self.words.iter().all(|&w| w == 0)
    }

    /// The value as a u64 when it fits (width <= 64 or high bits zero).
    pub fn to_u64(&self) -> Option<u64> {
        if self.words.iter().skip(1).any(|&w| w != 0) {
            return None;
        }
        Some(self.words.first().copied().unwrap_or(0))
    }

    /// The value as a u128 when it fits.
    pub fn to_u128(&self) -> Option<u128> {
        if self.words.iter().skip(2).any(|&w| w != 0) {
            return None;
        }
        let lo = self.words.first().copied().unwrap_or(0) as u128;
        let hi = self.words.get(1).copied().unwrap_or(0) as u128;
        Some(lo | hi << 64)
    }

    /// Bits `[lo, lo + len)` as a new vector of width `len`; an error past the width.
    pub fn field(&self, lo: usize, len: usize) -> Result<BitVec> {
        if lo + len > self.width {
            return Err(CosimError::Parse {
                text: format!("field [{lo}, {})", lo + len),
                what: format!("past the width {}", self.width),
            });
        }
        let mut out = BitVec::zeros(len);
        for i in 0..len {
            if self.bit(lo + i) {
                out.words[i / 64] |= 1 << (i % 64);
            }
        }
        Ok(out)
    }

    /// Write `value` into bits `[lo, lo + value.width())`; an error past the width.
    pub fn set_field(&mut self, lo: usize, value: &BitVec) -> Result<()> {
        if lo + value.width > self.width {
            return Err(CosimError::Parse {
                text: format!("field [{lo}, {})", lo + value.width),
                what: format!("past the width {}", self.width),
            });
        }
        for i in 0..value.width {
            self.set_bit(lo + i, value.bit(i))?;
        }
        Ok(())
    }

    /// The value in hex, exactly `ceil(width / 4)` digits, no prefix.
    pub fn to_hex(&self) -> String {
        let digits = self.width.div_ceil(4).max(1);
        let mut s = String::with_capacity(digits);
        for d in (0..digits).rev() {
            let bit = d * 4;
            let word = self.words.get(bit / 64).copied().unwrap_or(0);
            let nibble = (word >> (bit % 64)) & 0xf;
            s.push(char::from_digit(nibble as u32, 16).unwrap_or('?'));
        }
        s
    }

    fn clear_above_width(&mut self) {
        let rem = self.width % 64;
        if rem != 0 {
            if let Some(last) = self.words.last_mut() {
                *last &= (1u64 << rem) - 1;
            }
        }
    }
}

impl fmt::Display for BitVec {
    /// `<width>'h<hex>`, the Verilog literal form.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}'h{}", self.width, self.to_hex())
    }
}

impl fmt::Debug for BitVec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

impl fmt::LowerHex for BitVec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.to_hex())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_round_trip_300_bits() {
        let text = "abc_0123456789abcdef_fedcba9876543210_0f0f0f0f0f0f0f0f_1234567890abcdef";
        let v = BitVec::from_hex(300, text).unwrap();
        let back = BitVec::from_hex(300, &v.to_hex()).unwrap();
        assert_eq!(v, back);
        assert_eq!(v.words()[0], 0x1234567890abcdef);
        assert_eq!(v.words()[4], 0xabc);
        assert_eq!(v.to_hex().len(), 75);
    }

    #[test]
    fn overflow_is_an_error_not_a_wrap() {
        assert!(BitVec::from_u64(8, 256).is_err());
        assert!(BitVec::from_u64(8, 255).is_ok());
        assert!(BitVec::from_hex(5, "20").is_err());
        assert!(BitVec::from_hex(5, "1f").is_ok());
        assert!(BitVec::from_words(65, &[0, 2]).is_err());
        assert!(BitVec::from_hex(8, "g1").is_err());
    }

    #[test]
    fn fields_and_bits() {
        let mut v = BitVec::zeros(130);
        v.set_field(60, &BitVec::from_u64(10, 0x3ff).unwrap())
            .unwrap();
        assert_eq!(v.field(60, 10).unwrap().to_u64(), Some(0x3ff));
        assert!(v.bit(63) && v.bit(64) && !v.bit(70));
        v.flip_bit(129).unwrap();
        assert!(v.bit(129));
        assert!(v.set_bit(130, true).is_err());
        assert_eq!(BitVec::ones(70).to_hex(), "3fffffffffffffffff");
        assert_eq!(format!("{}", BitVec::from_u64(4, 9).unwrap()), "4'h9");
    }
}
