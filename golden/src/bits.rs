//! [`Bits`]: the one two-state bit vector of every crate: golden's packed
//! records, the DSL's constants and simulator values, and the co-simulation's
//! port values.
//!
//! Stored as 64-bit words, least significant word first, with every bit at or
//! above the width kept zero, so equality and hashing are plain word compares.
//! A value that does not fit its width is an error ([`BitsError`]), never a
//! silent truncation. Field access by a layout's [`crate::layout::Field`]
//! (`get`, `set`) lives beside the layouts in [`crate::layout`].

pub mod words;

use std::fmt;

/// An unsigned bit vector of any width.
///
/// Whether the bits mean a signed or unsigned number is decided by whoever
/// reads them; `Bits` itself is just the pattern.
///
/// ```
/// use golden::bits::Bits;
/// let x = Bits::from_u128(0xff, 8).unwrap();
/// assert_eq!(x.width(), 8);
/// assert_eq!(x.to_u128(), Some(0xff));
/// assert!(Bits::from_u128(256, 8).is_err()); // does not fit: an error, never a wrap
/// let minus_one = Bits::from_i128(-1, 300).unwrap();
/// assert_eq!(minus_one.to_i128(), Some(-1));
/// assert_eq!(format!("{}", Bits::from_u128(3, 12).unwrap()), "12'h003");
/// assert_eq!(Bits::from_hex("0x_2d", 6).unwrap().to_binary(), "101101");
/// ```
#[derive(Clone, PartialEq, Eq, Hash)]
pub struct Bits {
    width: u32,
    words: Vec<u64>,
}

/// Why a bit vector could not be built, read or written.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BitsError {
    /// `value` needs more than `width` bits.
    DoesNotFit {
        /// The value as given (decimal for integers, the text for hex, the
        /// words for a word list).
        value: String,
        /// The width it was asked to fit.
        width: u32,
    },
    /// Bits `[lo, end)` reach past the `width`-bit vector read or written.
    OutOfRange {
        /// First bit of the range.
        lo: u32,
        /// One past its last bit.
        end: u32,
        /// The vector's width.
        width: u32,
    },
    /// Hexadecimal text with no digits, or a character that is not one.
    NotHex {
        /// The text given.
        text: String,
        /// What is wrong with it.
        why: String,
    },
}

impl fmt::Display for BitsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BitsError::DoesNotFit { value, width } => {
                write!(f, "value {value} does not fit in {width} bits")
            }
            BitsError::OutOfRange { lo, end, width } => {
                write!(f, "bits [{lo}, {end}) reach past the {width}-bit vector")
            }
            BitsError::NotHex { text, why } => write!(f, "cannot parse `{text}` as hex: {why}"),
        }
    }
}

impl std::error::Error for BitsError {}

/// Mask of the low `width <= 64` bits.
fn low_mask(width: u32) -> u64 {
    if width >= 64 {
        u64::MAX
    } else {
        (1u64 << width) - 1
    }
}

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
    pub fn from_u64(value: u64, width: u32) -> Result<Bits, BitsError> {
        Bits::from_u128(value as u128, width)
    }

    /// The unsigned `value` in `width` bits; an error if it needs more bits.
    pub fn from_u128(value: u128, width: u32) -> Result<Bits, BitsError> {
        if width < 128 && value >> width != 0 {
            return Err(BitsError::DoesNotFit {
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
    pub fn from_i128(value: i128, width: u32) -> Result<Bits, BitsError> {
        let fits = match width {
            0 => false,
            128.. => true,
            w => {
                let half = 1i128 << (w - 1);
                (-half..half).contains(&value)
            }
        };
        if !fits {
            return Err(BitsError::DoesNotFit {
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

    /// A value from little-endian words; an error if a bit at or above
    /// `width` is set (extra all-zero words are accepted).
    pub fn from_words(words_le: &[u64], width: u32) -> Result<Bits, BitsError> {
        let mut b = Bits::zero(width);
        let n = b.words.len().min(words_le.len());
        b.words[..n].copy_from_slice(&words_le[..n]);
        words::clamp(&mut b.words, width);
        let extra_set = words_le[n..].iter().any(|&w| w != 0);
        if extra_set || b.words[..n] != words_le[..n] {
            return Err(BitsError::DoesNotFit {
                value: format!("{words_le:x?}"),
                width,
            });
        }
        Ok(b)
    }

    /// A value from bits, index 0 = least significant.
    pub fn from_bools(bits: &[bool]) -> Bits {
        let mut b = Bits::zero(bits.len() as u32);
        for (i, &v) in bits.iter().enumerate() {
            words::set_bit(&mut b.words, i as u32, v);
        }
        b
    }

    /// From hexadecimal text (optional `0x`, `_` separators allowed); an
    /// error on a non-hex digit or a value that does not fit `width`.
    pub fn from_hex(text: &str, width: u32) -> Result<Bits, BitsError> {
        let not_hex = |why: String| BitsError::NotHex {
            text: text.to_string(),
            why,
        };
        let digits = text.trim();
        let digits = digits
            .strip_prefix("0x")
            .or_else(|| digits.strip_prefix("0X"))
            .unwrap_or(digits);
        if digits.is_empty() {
            return Err(not_hex("no hex digits".to_string()));
        }
        let mut b = Bits::zero(width);
        let mut bit = 0u64;
        for c in digits.chars().rev() {
            if c == '_' {
                continue;
            }
            let nibble = c
                .to_digit(16)
                .ok_or_else(|| not_hex(format!("`{c}` is not a hex digit")))?;
            for k in 0..4 {
                if nibble >> k & 1 == 1 {
                    if bit + k >= width as u64 {
                        return Err(BitsError::DoesNotFit {
                            value: text.to_string(),
                            width,
                        });
                    }
                    words::set_bit(&mut b.words, (bit + k) as u32, true);
                }
            }
            bit += 4;
        }
        Ok(b)
    }

    /// Width in bits.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Little-endian words (at least one); bits at and above the width are zero.
    pub fn words(&self) -> &[u64] {
        &self.words
    }

    /// Bit `i` (0 = least significant); false beyond the width.
    pub fn bit(&self, i: u32) -> bool {
        i < self.width && words::get_bit(&self.words, i)
    }

    /// Sets bit `i` to `value`; an error past the width.
    pub fn set_bit(&mut self, i: u32, value: bool) -> Result<(), BitsError> {
        self.check_range(i, 1)?;
        words::set_bit(&mut self.words, i, value);
        Ok(())
    }

    /// Inverts bit `i`; an error past the width.
    pub fn flip_bit(&mut self, i: u32) -> Result<(), BitsError> {
        let b = self.bit(i);
        self.set_bit(i, !b)
    }

    /// True when every bit is zero.
    pub fn is_zero(&self) -> bool {
        self.words.iter().all(|&w| w == 0)
    }

    /// The value as an unsigned integer when it fits in 64 bits.
    pub fn to_u64(&self) -> Option<u64> {
        self.to_u128().and_then(|v| u64::try_from(v).ok())
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

    /// An error unless bits `[lo, lo + width)` are inside the vector.
    fn check_range(&self, lo: u32, width: u32) -> Result<(), BitsError> {
        let end = lo as u64 + width as u64;
        if end > self.width as u64 {
            return Err(BitsError::OutOfRange {
                lo,
                end: end.min(u32::MAX as u64) as u32,
                width: self.width,
            });
        }
        Ok(())
    }

    /// Bits `[lo, lo + width)` as a `width`-bit value; an error past the width.
    pub fn extract(&self, lo: u32, width: u32) -> Result<Bits, BitsError> {
        self.check_range(lo, width)?;
        let mut out = Bits::zero(width);
        words::extract(&mut out.words, &self.words, lo, width);
        Ok(out)
    }

    /// Writes all of `src` into these bits from bit `lo` up (how a record is
    /// packed into a wider beat); an error, with nothing written, when it
    /// would reach past the width.
    pub fn put(&mut self, lo: u32, src: &Bits) -> Result<(), BitsError> {
        self.check_range(lo, src.width)?;
        let mut done = 0;
        while done < src.width {
            let n = (src.width - done).min(64);
            self.write_raw(lo + done, n, src.read_raw(done, n));
            done += n;
        }
        Ok(())
    }

    /// Zero- or sign-extension to `width` (must be at least the current width,
    /// and the value at least one bit wide).
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

    /// Reads `width <= 64` bits at `offset`; the caller guarantees the range
    /// is inside.
    pub(crate) fn read_raw(&self, offset: u32, width: u32) -> u64 {
        if width == 0 {
            return 0;
        }
        let w = (offset / 64) as usize;
        let s = offset % 64;
        let mut v = self.words[w] >> s;
        if s != 0 && s + width > 64 {
            v |= self.words[w + 1] << (64 - s);
        }
        v & low_mask(width)
    }

    /// Writes the low `width <= 64` bits of `value` at `offset`; the caller
    /// guarantees the range is inside and the value fits.
    pub(crate) fn write_raw(&mut self, offset: u32, width: u32, value: u64) {
        if width == 0 {
            return;
        }
        let mask = low_mask(width);
        let w = (offset / 64) as usize;
        let s = offset % 64;
        self.words[w] = (self.words[w] & !(mask << s)) | (value << s);
        if s != 0 && s + width > 64 {
            let hi_mask = mask >> (64 - s);
            self.words[w + 1] = (self.words[w + 1] & !hi_mask) | (value >> (64 - s));
        }
    }

    /// Hexadecimal, most significant digit first, `ceil(width / 4)` digits
    /// (at least one), no prefix: the form `$readmemh` and the test vectors use.
    pub fn to_hex(&self) -> String {
        let digits = self.width.div_ceil(4).max(1);
        let mut s = String::with_capacity(digits as usize);
        for d in (0..digits).rev() {
            let lo = d * 4;
            let n = (self.width.saturating_sub(lo)).min(4);
            let v = self.read_raw(lo, n);
            s.push(char::from_digit(v as u32, 16).unwrap_or('0'));
        }
        s
    }

    /// Binary, most significant bit first, exactly `width` digits.
    pub fn to_binary(&self) -> String {
        (0..self.width)
            .rev()
            .map(|i| if self.bit(i) { '1' } else { '0' })
            .collect()
    }
}

impl Default for Bits {
    /// The zero-width value.
    fn default() -> Bits {
        Bits::zero(0)
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

impl fmt::LowerHex for Bits {
    /// The digits of [`Bits::to_hex`].
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
        let v = Bits::from_hex(text, 300).unwrap();
        let back = Bits::from_hex(&v.to_hex(), 300).unwrap();
        assert_eq!(v, back);
        assert_eq!(v.words()[0], 0x1234567890abcdef);
        assert_eq!(v.words()[4], 0xabc);
        assert_eq!(v.to_hex().len(), 75);
        assert_eq!(format!("{v:x}"), v.to_hex());
    }

    #[test]
    fn overflow_is_an_error_not_a_wrap() {
        assert!(Bits::from_u64(256, 8).is_err());
        assert!(Bits::from_u64(255, 8).is_ok());
        assert!(Bits::from_hex("20", 5).is_err());
        assert!(Bits::from_hex("1f", 5).is_ok());
        assert!(Bits::from_words(&[0, 2], 65).is_err());
        assert!(Bits::from_words(&[0x2d, 0], 6).is_ok());
        assert_eq!(
            Bits::from_words(&[0x40], 6).unwrap_err().to_string(),
            "value [40] does not fit in 6 bits"
        );
        assert!(Bits::from_words(&[0, 1], 6).is_err());
        assert!(matches!(
            Bits::from_hex("g1", 8),
            Err(BitsError::NotHex { .. })
        ));
        assert!(matches!(
            Bits::from_hex("0x", 8),
            Err(BitsError::NotHex { .. })
        ));
        let e = Bits::from_u128(8, 3).unwrap_err();
        assert_eq!(e.to_string(), "value 8 does not fit in 3 bits");
    }

    #[test]
    fn bits_ranges_and_flips() {
        let mut v = Bits::zero(130);
        v.put(60, &Bits::from_u64(0x3ff, 10).unwrap()).unwrap();
        assert_eq!(v.extract(60, 10).unwrap().to_u64(), Some(0x3ff));
        assert!(v.bit(63) && v.bit(64) && !v.bit(70));
        v.flip_bit(129).unwrap();
        assert!(v.bit(129));
        assert_eq!(
            v.set_bit(130, true),
            Err(BitsError::OutOfRange {
                lo: 130,
                end: 131,
                width: 130
            })
        );
        assert!(v.extract(125, 6).is_err());
        assert!(!v.is_zero() && Bits::zero(70).is_zero());
        assert_eq!(Bits::ones(70).to_hex(), "3fffffffffffffffff");
        assert_eq!(format!("{}", Bits::from_u64(9, 4).unwrap()), "4'h9");
        assert_eq!(Bits::zero(0), Bits::from_words(&[], 0).unwrap());
        assert_eq!(Bits::default().to_hex(), "0");
    }

    #[test]
    fn put_writes_every_bit_of_a_record_at_any_offset() {
        // A 140-bit pattern (three words, the last partial) at offsets that
        // start inside, at and across word boundaries.
        let bools: Vec<bool> = (0..140).map(|i| (i * 7) % 3 == 0 || i % 64 == 63).collect();
        let src = Bits::from_bools(&bools);
        for offset in [0, 1, 63, 64, 65, 100, 127] {
            let mut dst = Bits::zero(300);
            // Bits around the target stay as they are; bits inside are replaced.
            dst.put(0, &Bits::ones(offset.min(64))).unwrap();
            dst.put(offset, &Bits::ones(64)).unwrap();
            dst.put(offset, &src).unwrap();
            for i in 0..300 {
                let expected = if (offset..offset + 140).contains(&i) {
                    src.bit(i - offset)
                } else {
                    i < offset.min(64)
                };
                assert_eq!(dst.bit(i), expected, "offset {offset}, bit {i}");
            }
        }
        let mut dst = Bits::zero(150);
        assert_eq!(
            dst.put(11, &src),
            Err(BitsError::OutOfRange {
                lo: 11,
                end: 151,
                width: 150
            })
        );
        assert_eq!(dst, Bits::zero(150), "nothing written on an error");
    }
}
