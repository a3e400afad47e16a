//! The bit layout of a node record and of a child reference (SPEC.md section 3),
//! defined once, as data.
//!
//! A layout is a list of [`Field`]s, each a named bit range, packed from bit 0
//! upward in a fixed order. The golden model packs records with it, the RTL
//! generators slice ports with it and the test vectors print it: no other
//! module restates an offset or a width.
//!
//! [`Bits`] is a packed record of any width (stored as 64-bit words, least
//! significant first). Writing a value that does not fit its field is an
//! error, never a silent truncation.

use std::fmt;

use crate::params::Params;

/// One named bit range of a packed record.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Field {
    /// The field's name as written in SPEC.md (`leaf`, `lod`, `x`, `lo_x`, ...).
    pub name: &'static str,
    /// Bit position of the field's least significant bit in the record.
    pub offset: u32,
    /// Number of bits; may be 0 (e.g. box bounds when `Q = 0`), then only 0 fits.
    pub width: u32,
}

impl Field {
    /// Field `name`, `width` bits from bit `offset` up.
    pub const fn new(name: &'static str, offset: u32, width: u32) -> Field {
        Field {
            name,
            offset,
            width,
        }
    }

    /// Largest value the field holds: `2^width - 1` (0 for a zero-width field).
    pub fn max_value(&self) -> u64 {
        if self.width >= 64 {
            u64::MAX
        } else {
            (1u64 << self.width) - 1
        }
    }

    /// True when `value` fits in the field's width.
    pub fn fits(&self, value: u64) -> bool {
        value <= self.max_value()
    }

    /// One past the field's most significant bit.
    pub fn end(&self) -> u32 {
        self.offset + self.width
    }
}

/// A value that does not fit, or a record of the wrong width.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LayoutError {
    /// `value` needs more than the `width` bits of field `field`.
    DoesNotFit {
        /// Name of the field written.
        field: &'static str,
        /// The value refused.
        value: u64,
        /// The field's width in bits.
        width: u32,
    },
    /// A field reaches past the end of the record it is read from or written to.
    OutOfRecord {
        /// Name of the field.
        field: &'static str,
        /// One past the field's most significant bit.
        end: u32,
        /// The record's width in bits.
        record_width: u32,
    },
    /// A record of `found` bits was given where the layout has `expected` bits.
    WrongWidth {
        /// What was read: `"node record"`, `"reference"`, or the `Bits::from_words` call.
        what: &'static str,
        /// Width the layout expects, in bits.
        expected: u32,
        /// Width given, in bits (64 per word for `Bits::from_words`).
        found: u32,
    },
}

impl fmt::Display for LayoutError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LayoutError::DoesNotFit {
                field,
                value,
                width,
            } => write!(
                f,
                "field `{field}`: value {value} does not fit in {width} bits (max {})",
                Field {
                    name: field,
                    offset: 0,
                    width: *width
                }
                .max_value()
            ),
            LayoutError::OutOfRecord {
                field,
                end,
                record_width,
            } => write!(
                f,
                "field `{field}` ends at bit {end}, past the {record_width}-bit record"
            ),
            LayoutError::WrongWidth {
                what,
                expected,
                found,
            } => write!(
                f,
                "{what}: expected a {expected}-bit record, found {found} bits"
            ),
        }
    }
}

impl std::error::Error for LayoutError {}

/// A packed record: `width` bits in 64-bit words, least significant word first.
/// Bits at and above `width` are always zero.
#[derive(Clone, PartialEq, Eq, Hash)]
pub struct Bits {
    width: u32,
    words: Vec<u64>,
}

impl Bits {
    /// An all-zero record of `width` bits.
    pub fn zero(width: u32) -> Bits {
        Bits {
            width,
            words: vec![0; width.div_ceil(64) as usize],
        }
    }

    /// A record from words (LSB first); bits at or above `width` must be zero.
    pub fn from_words(width: u32, words: &[u64]) -> Result<Bits, LayoutError> {
        let mut b = Bits::zero(width);
        if words.len() > b.words.len() && words[b.words.len()..].iter().any(|&w| w != 0) {
            return Err(LayoutError::WrongWidth {
                what: "Bits::from_words",
                expected: width,
                found: words.len() as u32 * 64,
            });
        }
        for (dst, src) in b.words.iter_mut().zip(words) {
            *dst = *src;
        }
        if b.has_bits_above_width() {
            return Err(LayoutError::WrongWidth {
                what: "Bits::from_words (set bits above the width)",
                expected: width,
                found: b.words.len() as u32 * 64,
            });
        }
        Ok(b)
    }

    fn has_bits_above_width(&self) -> bool {
        let rem = self.width % 64;
        match self.words.last() {
            Some(&last) if rem != 0 => last >> rem != 0,
            _ => false,
        }
    }

    /// The record's width in bits.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// The words, least significant first.
    pub fn words(&self) -> &[u64] {
        &self.words
    }

    /// Reads `width <= 64` bits at `offset` (caller guarantees the range is inside).
    fn read_raw(&self, offset: u32, width: u32) -> u64 {
        if width == 0 {
            return 0;
        }
        let w = (offset / 64) as usize;
        let s = offset % 64;
        let mut v = self.words[w] >> s;
        if s != 0 && s + width > 64 {
            v |= self.words[w + 1] << (64 - s);
        }
        v & Field {
            name: "",
            offset: 0,
            width,
        }
        .max_value()
    }

    /// Writes the low `width <= 64` bits of `value` at `offset` (range inside, value fits).
    fn write_raw(&mut self, offset: u32, width: u32, value: u64) {
        if width == 0 {
            return;
        }
        let mask = Field {
            name: "",
            offset: 0,
            width,
        }
        .max_value();
        let w = (offset / 64) as usize;
        let s = offset % 64;
        self.words[w] = (self.words[w] & !(mask << s)) | (value << s);
        if s != 0 && s + width > 64 {
            let hi_mask = mask >> (64 - s);
            self.words[w + 1] = (self.words[w + 1] & !hi_mask) | (value >> (64 - s));
        }
    }

    fn check_inside(&self, f: &Field) -> Result<(), LayoutError> {
        if f.end() > self.width || f.width > 64 {
            return Err(LayoutError::OutOfRecord {
                field: f.name,
                end: f.end(),
                record_width: self.width,
            });
        }
        Ok(())
    }

    /// The value of field `f`.
    pub fn get(&self, f: &Field) -> Result<u64, LayoutError> {
        self.check_inside(f)?;
        Ok(self.read_raw(f.offset, f.width))
    }

    /// Sets field `f` to `value`; an error when it does not fit the field's width.
    pub fn set(&mut self, f: &Field, value: u64) -> Result<(), LayoutError> {
        self.check_inside(f)?;
        if !f.fits(value) {
            return Err(LayoutError::DoesNotFit {
                field: f.name,
                value,
                width: f.width,
            });
        }
        self.write_raw(f.offset, f.width, value);
        Ok(())
    }

    /// Writes all of `src` into these bits from bit `offset` up, 64 bits at a
    /// time: how a record is packed into a wider beat. An error when it
    /// would reach past the width.
    pub fn put(&mut self, offset: u32, src: &Bits) -> Result<(), LayoutError> {
        let end = offset.saturating_add(src.width);
        if end > self.width {
            return Err(LayoutError::OutOfRecord {
                field: "bits",
                end,
                record_width: self.width,
            });
        }
        let mut done = 0;
        while done < src.width {
            let n = (src.width - done).min(64);
            self.write_raw(offset + done, n, src.read_raw(done, n));
            done += n;
        }
        Ok(())
    }

    /// Bit `i` (false past the width).
    pub fn bit(&self, i: u32) -> bool {
        i < self.width && (self.words[(i / 64) as usize] >> (i % 64)) & 1 == 1
    }

    /// Hexadecimal, most significant digit first, `ceil(width / 4)` digits
    /// (at least one): the form `$readmemh` and the test vectors use.
    pub fn to_hex(&self) -> String {
        let digits = self.width.div_ceil(4).max(1);
        let mut s = String::with_capacity(digits as usize);
        for d in (0..digits).rev() {
            let lo = d * 4;
            let n = (self.width.saturating_sub(lo)).min(4);
            let v = if n == 0 { 0 } else { self.read_raw(lo, n) };
            s.push(char::from_digit(v as u32, 16).expect("nibble"));
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

impl fmt::Debug for Bits {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Bits({}'h{})", self.width, self.to_hex())
    }
}

/// Index of each node-record field in [`NodeLayout::fields`] (bit order).
const LEAF: usize = 0;
const LOD: usize = 1;
const COORD: usize = 2; // x, y, z
const LO: usize = 5; // lo_x, lo_y, lo_z
const HI: usize = 8; // hi_x, hi_y, hi_z
const FIRST: usize = 11;
const COUNT: usize = 12;
const NODE_FIELDS: usize = 13;

/// The node-record layout of SPEC.md section 3 for one parameter set:
/// `leaf, lod, x, y, z, lo_x, lo_y, lo_z, hi_x, hi_y, hi_z, first, count`,
/// packed from bit 0 upward.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NodeLayout {
    fields: [Field; NODE_FIELDS],
    width: u32,
}

/// Lays out `(name, width)` pairs consecutively from bit 0.
fn pack_consecutively<const N: usize>(spec: [(&'static str, u32); N]) -> ([Field; N], u32) {
    let mut offset = 0;
    let fields = spec.map(|(name, width)| {
        let f = Field {
            name,
            offset,
            width,
        };
        offset += width;
        f
    });
    (fields, offset)
}

impl NodeLayout {
    /// The layout for `p` (widths from [`Params`]: lod_bits, D, Q, I).
    pub fn new(p: &Params) -> NodeLayout {
        let lod = p.lod_bits();
        let d = p.coord_bits();
        let q = p.quant_bits as u32;
        let i = p.index_bits as u32;
        let (fields, width) = pack_consecutively([
            ("leaf", 1),
            ("lod", lod),
            ("x", d),
            ("y", d),
            ("z", d),
            ("lo_x", q),
            ("lo_y", q),
            ("lo_z", q),
            ("hi_x", q),
            ("hi_y", q),
            ("hi_z", q),
            ("first", i),
            ("count", i),
        ]);
        NodeLayout { fields, width }
    }

    /// Record width `W = 1 + lod_bits + 3D + 6Q + 2I`.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// The fields in bit order (lowest offset first).
    pub fn fields(&self) -> impl Iterator<Item = &Field> + '_ {
        self.fields.iter()
    }

    /// The field called `name`, if any.
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.fields.iter().find(|f| f.name == name)
    }

    /// The `leaf` flag (1 bit): 1 for a leaf, 0 for an inner node.
    pub fn leaf(&self) -> &Field {
        &self.fields[LEAF]
    }
    /// The node's LOD `d` (`lod_bits` wide).
    pub fn lod(&self) -> &Field {
        &self.fields[LOD]
    }
    /// Voxel x coordinate (D bits).
    pub fn x(&self) -> &Field {
        &self.fields[COORD]
    }
    /// Voxel y coordinate (D bits).
    pub fn y(&self) -> &Field {
        &self.fields[COORD + 1]
    }
    /// Voxel z coordinate (D bits).
    pub fn z(&self) -> &Field {
        &self.fields[COORD + 2]
    }
    /// Voxel coordinate of `axis` (0 = x, 1 = y, 2 = z). Panics on axis > 2.
    pub fn coord(&self, axis: usize) -> &Field {
        assert!(axis < 3, "axis {axis} is not 0, 1 or 2");
        &self.fields[COORD + axis]
    }
    /// Box minimum cell on `axis`. Panics on axis > 2.
    pub fn lo(&self, axis: usize) -> &Field {
        assert!(axis < 3, "axis {axis} is not 0, 1 or 2");
        &self.fields[LO + axis]
    }
    /// Box maximum cell (inclusive) on `axis`. Panics on axis > 2.
    pub fn hi(&self, axis: usize) -> &Field {
        assert!(axis < 3, "axis {axis} is not 0, 1 or 2");
        &self.fields[HI + axis]
    }
    /// First index into `refs` (inner node) or `prims` (leaf); I bits.
    pub fn first(&self) -> &Field {
        &self.fields[FIRST]
    }
    /// Number of children or primitives, at least 1; I bits.
    pub fn count(&self) -> &Field {
        &self.fields[COUNT]
    }

    /// A zero record of this layout's width.
    pub fn zero(&self) -> Bits {
        Bits::zero(self.width)
    }
}

/// The child-reference layout: `node` in bits `[0, I)`, `hier` in `[I, I + H)`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RefLayout {
    fields: [Field; 2],
    width: u32,
}

impl RefLayout {
    /// The layout for `p` (widths I and H).
    pub fn new(p: &Params) -> RefLayout {
        let (fields, width) =
            pack_consecutively([("node", p.index_bits as u32), ("hier", p.hier_bits as u32)]);
        RefLayout { fields, width }
    }

    /// `I + H`.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// The fields in bit order.
    pub fn fields(&self) -> impl Iterator<Item = &Field> + '_ {
        self.fields.iter()
    }

    /// The field called `name`, if any.
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.fields.iter().find(|f| f.name == name)
    }

    /// Node index into the named hierarchy's `nodes`, bits `[0, I)`.
    pub fn node(&self) -> &Field {
        &self.fields[0]
    }
    /// Hierarchy id, bits `[I, I + H)`.
    pub fn hier(&self) -> &Field {
        &self.fields[1]
    }

    /// A zero record of this layout's width.
    pub fn zero(&self) -> Bits {
        Bits::zero(self.width)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn widest_record_is_259_bits_and_fields_tile_it() {
        let p = Params::new(31, 16, 32, 8).unwrap();
        let l = NodeLayout::new(&p);
        assert_eq!(l.width(), 1 + 5 + 3 * 31 + 6 * 16 + 2 * 32);
        assert_eq!(l.width(), 259);
        let mut next = 0;
        for f in l.fields() {
            assert_eq!(f.offset, next, "field {} not adjacent", f.name);
            next = f.end();
        }
        assert_eq!(next, l.width());
        assert_eq!(l.count().end(), 259);
        assert_eq!(l.lo(1).name, "lo_y");
        assert_eq!(l.hi(2).name, "hi_z");
        assert_eq!(l.field("first"), Some(l.first()));
        let r = RefLayout::new(&p);
        assert_eq!((r.node().offset, r.node().width), (0, 32));
        assert_eq!((r.hier().offset, r.hier().width), (32, 8));
        assert_eq!(r.width(), 40);
    }

    #[test]
    fn narrowest_record() {
        let p = Params::new(1, 0, 1, 1).unwrap();
        let l = NodeLayout::new(&p);
        assert_eq!(l.width(), 1 + 1 + 3 + 2);
        assert_eq!(l.lo(0).width, 0);
        let mut b = l.zero();
        b.set(l.lo(0), 0).unwrap();
        assert!(matches!(
            b.set(l.hi(0), 1),
            Err(LayoutError::DoesNotFit { field: "hi_x", .. })
        ));
    }

    #[test]
    fn fields_straddling_words_round_trip() {
        let mut b = Bits::zero(200);
        let f = Field {
            name: "f",
            offset: 60,
            width: 40,
        };
        b.set(&f, 0xAB_CDEF_0123).unwrap();
        assert_eq!(b.get(&f).unwrap(), 0xAB_CDEF_0123);
        let g = Field {
            name: "g",
            offset: 100,
            width: 64,
        };
        b.set(&g, u64::MAX).unwrap();
        assert_eq!(b.get(&g).unwrap(), u64::MAX);
        assert_eq!(b.get(&f).unwrap(), 0xAB_CDEF_0123, "neighbour untouched");
        b.set(&g, 5).unwrap();
        assert_eq!(b.get(&g).unwrap(), 5);
        assert!(!b.bit(199));
    }

    #[test]
    fn overflow_and_out_of_record_are_errors() {
        let mut b = Bits::zero(10);
        let f = Field {
            name: "f",
            offset: 2,
            width: 3,
        };
        let e = b.set(&f, 8).unwrap_err();
        assert_eq!(
            e,
            LayoutError::DoesNotFit {
                field: "f",
                value: 8,
                width: 3
            }
        );
        assert!(e.to_string().contains("does not fit in 3 bits"));
        let g = Field {
            name: "g",
            offset: 8,
            width: 3,
        };
        assert!(matches!(b.set(&g, 1), Err(LayoutError::OutOfRecord { .. })));
        assert!(matches!(b.get(&g), Err(LayoutError::OutOfRecord { .. })));
    }

    #[test]
    fn hex_and_binary_show_msb_first() {
        let mut b = Bits::zero(6);
        b.set(
            &Field {
                name: "a",
                offset: 0,
                width: 6,
            },
            0b10_1101,
        )
        .unwrap();
        assert_eq!(b.to_binary(), "101101");
        assert_eq!(b.to_hex(), "2d");
        assert_eq!(Bits::from_words(6, &[0x2d]).unwrap(), b);
        assert!(Bits::from_words(6, &[0x40]).is_err());
        assert!(Bits::from_words(6, &[0, 1]).is_err());
    }

    #[test]
    fn put_writes_every_bit_of_a_record_at_any_offset() {
        // A 140-bit pattern (three words, the last partial) at offsets that
        // start inside, at and across word boundaries.
        let mut src = Bits::zero(140);
        for i in (0..140).filter(|i| (i * 7) % 3 == 0 || i % 64 == 63) {
            src.set(&Field::new("bit", i, 1), 1).unwrap();
        }
        for offset in [0, 1, 63, 64, 65, 100, 127] {
            let mut dst = Bits::zero(300);
            // Bits around the target stay as they are; bits inside are replaced.
            dst.set(
                &Field::new("below", 0, offset.min(64)),
                Field::new("", 0, offset.min(64)).max_value(),
            )
            .unwrap();
            dst.set(&Field::new("inside", offset, 64), u64::MAX)
                .unwrap();
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
        assert!(matches!(
            dst.put(11, &src),
            Err(LayoutError::OutOfRecord {
                end: 151,
                record_width: 150,
                ..
            })
        ));
        assert_eq!(dst, Bits::zero(150), "nothing written on an error");
    }
}
