//! The bit layout of a node record and of a child reference (SPEC.md section 3),
//! defined once, as data.
//!
//! A layout is a list of [`Field`]s, each a named bit range, packed from bit 0
//! upward in a fixed order. The golden model packs records with it, the RTL
//! generators slice ports with it and the test vectors print it: no other
//! module restates an offset or a width.
//!
//! A packed record is a [`Bits`]; this module adds its access by field
//! ([`Bits::get`], [`Bits::set`]). Writing a value that does not fit its field
//! is an error, never a silent truncation.

use std::fmt;

use crate::bits::{Bits, BitsError};
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
        /// What was read: `"node record"` or `"reference"`.
        what: &'static str,
        /// Width the layout expects, in bits.
        expected: u32,
        /// Width given, in bits.
        found: u32,
    },
    /// Building or packing the record's bits failed (a value wider than the
    /// record, a beat written past its end).
    Bits(BitsError),
}

impl From<BitsError> for LayoutError {
    fn from(e: BitsError) -> LayoutError {
        LayoutError::Bits(e)
    }
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
            LayoutError::Bits(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for LayoutError {}

impl Bits {
    fn check_inside(&self, f: &Field) -> Result<(), LayoutError> {
        if f.end() > self.width() || f.width > 64 {
            return Err(LayoutError::OutOfRecord {
                field: f.name,
                end: f.end(),
                record_width: self.width(),
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
        assert_eq!(Bits::from_words(&[0x2d], 6).unwrap(), b);
        assert!(Bits::from_words(&[0x40], 6).is_err());
        assert!(Bits::from_words(&[0, 1], 6).is_err());
    }
}
