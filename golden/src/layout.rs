//! The bit layout of a node record and of a child reference (SPEC.md section 3),
//! defined once, as data.
//!
//! A [`Layout`] is a list of [`Field`]s, each a named bit range, in bit
//! order. The golden model packs and unpacks words with it, the RTL
//! generators slice ports and pipeline buses with it, the testbenches decode
//! beats with it and the test vectors print it: no other module restates an
//! offset or a width. [`NodeLayout`] and [`RefLayout`] are layouts with an
//! accessor per field.
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
    /// Layout `layout` has no field called `field`.
    NoField {
        /// The layout's name.
        layout: String,
        /// The name looked up.
        field: String,
    },
    /// [`Layout::pack`] was given field `field` `given` times (0 or more
    /// than once) instead of exactly once.
    Unpacked {
        /// The layout's name.
        layout: String,
        /// The field.
        field: &'static str,
        /// How often a value was given for it (0, or 2 for "more than once").
        given: u8,
    },
    /// A word of `found` bits was given where layout `layout` has `expected`.
    WrongWidthOf {
        /// The layout's name.
        layout: String,
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
            LayoutError::NoField { layout, field } => {
                write!(f, "layout `{layout}` has no field `{field}`")
            }
            LayoutError::Unpacked {
                layout,
                field,
                given,
            } => write!(
                f,
                "layout `{layout}`: field `{field}` {}",
                if *given == 0 {
                    "given no value"
                } else {
                    "given more than one value"
                }
            ),
            LayoutError::WrongWidthOf {
                layout,
                expected,
                found,
            } => write!(
                f,
                "layout `{layout}`: expected a {expected}-bit word, found {found} bits"
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

/// Field names are `&'static str` so that a [`Field`] stays `Copy`; layouts
/// built at run time (port payloads named per axis, pipeline bundles) get
/// their names from here. Each distinct name is stored once for the life of
/// the process, and the set of names a design uses is small and fixed.
pub fn intern(name: &str) -> &'static str {
    use std::collections::HashSet;
    use std::sync::{Mutex, OnceLock};
    static NAMES: OnceLock<Mutex<HashSet<&'static str>>> = OnceLock::new();
    let mut names = NAMES
        .get_or_init(|| Mutex::new(HashSet::new()))
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    if let Some(n) = names.get(name) {
        return n;
    }
    let n: &'static str = Box::leak(name.to_owned().into_boxed_str());
    names.insert(n);
    n
}

/// A packed word of named fields: the one description that golden packs and
/// unpacks with, the RTL generators slice signals by and the testbenches
/// decode beats with.
///
/// Fields are kept in bit order (lowest offset first). Most layouts tile
/// their width from bit 0 ([`Layout::packed`], [`Layout::push`]); a few
/// leave gaps or start a field at a fixed bit ([`Layout::from_fields`]).
/// Fields never overlap and never reach past [`Layout::width`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Layout {
    name: String,
    fields: Vec<Field>,
    width: u32,
}

impl Layout {
    /// An empty layout called `name` (the name errors report: `"node
    /// record"`, `"det_in_data"`, ...).
    pub fn new(name: impl Into<String>) -> Layout {
        Layout {
            name: name.into(),
            fields: Vec::new(),
            width: 0,
        }
    }

    /// `(name, width)` pairs laid out consecutively from bit 0.
    pub fn packed(name: impl Into<String>, parts: &[(&str, u32)]) -> Layout {
        let mut l = Layout::new(name);
        for &(n, w) in parts {
            l.push(n, w);
        }
        l
    }

    /// `fields` at their own offsets inside a `width`-bit word. Panics when
    /// two fields overlap, a field reaches past `width` or a name repeats:
    /// layouts are built from parameters by code, so that is a bug there.
    #[track_caller]
    pub fn from_fields(name: impl Into<String>, fields: &[Field], width: u32) -> Layout {
        let mut l = Layout::new(name);
        let mut sorted = fields.to_vec();
        sorted.sort_by_key(|f| (f.offset, f.width));
        for f in sorted {
            l.insert(f);
        }
        assert!(
            l.width <= width,
            "layout `{}`: fields end at bit {}, past its {width} bits",
            l.name,
            l.width
        );
        l.width = width;
        l
    }

    /// Appends field `name`, `width` bits wide, above every field so far;
    /// returns it.
    #[track_caller]
    pub fn push(&mut self, name: &str, width: u32) -> Field {
        let f = Field::new(intern(name), self.width, width);
        self.insert(f);
        f
    }

    /// Field `name`, `width` bits from bit `offset` up, above every field
    /// so far: the bits between are a gap that packs as 0. For a field
    /// placed above the wider of two alternatives (a command's `kind`
    /// above either payload).
    #[track_caller]
    pub fn push_at(&mut self, name: &str, offset: u32, width: u32) -> Field {
        let f = Field::new(intern(name), offset, width);
        self.insert(f);
        f
    }

    /// Appends `inner`'s fields above every field so far, each named
    /// `prefix.name`, keeping `inner`'s gaps: a struct inside a struct.
    /// Returns the whole group as one field called `prefix` (not itself
    /// a field of this layout), for code that moves the group at once.
    #[track_caller]
    pub fn nest(&mut self, prefix: &str, inner: &Layout) -> Field {
        let at = self.width;
        for f in &inner.fields {
            self.insert(Field::new(
                intern(&format!("{prefix}.{}", f.name)),
                at + f.offset,
                f.width,
            ));
        }
        self.width = at + inner.width;
        Field::new(intern(prefix), at, inner.width)
    }

    /// This layout called `name`, with every field for which `inner` gives
    /// a layout replaced by that layout's fields, named `field.name`: the
    /// view a testbench decodes a beat with, where the generator slices the
    /// field whole. `inner`'s layout must be exactly as wide as the field.
    #[track_caller]
    pub fn flattened<'a>(
        &self,
        name: impl Into<String>,
        inner: impl Fn(&Field) -> Option<&'a Layout>,
    ) -> Layout {
        let mut l = Layout::new(name);
        for f in &self.fields {
            let Some(group) = inner(f) else {
                l.insert(*f);
                continue;
            };
            assert_eq!(
                group.width, f.width,
                "layout `{}`: field `{}` flattened as `{}`, {} bits for {}",
                self.name, f.name, group.name, group.width, f.width
            );
            l.width = f.offset;
            l.nest(f.name, group);
        }
        l.width = self.width;
        l
    }

    /// This layout under another name (a stream named after its port
    /// carrying beats of this layout).
    pub fn renamed(&self, name: impl Into<String>) -> Layout {
        Layout {
            name: name.into(),
            ..self.clone()
        }
    }

    #[track_caller]
    fn insert(&mut self, f: Field) {
        assert!(
            f.offset >= self.width,
            "layout `{}`: field `{}` at bit {} overlaps the fields below bit {}",
            self.name,
            f.name,
            f.offset,
            self.width
        );
        assert!(
            self.field(f.name).is_none(),
            "layout `{}`: field `{}` twice",
            self.name,
            f.name
        );
        self.width = f.end();
        self.fields.push(f);
    }

    /// The layout's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Width of a packed word in bits.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// The fields in bit order (lowest offset first).
    pub fn fields(&self) -> std::slice::Iter<'_, Field> {
        self.fields.iter()
    }

    /// The field called `name`, if any.
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.fields.iter().find(|f| f.name == name)
    }

    /// The field called `name`; an error naming the layout and the field
    /// when there is none.
    pub fn get(&self, name: &str) -> Result<&Field, LayoutError> {
        self.field(name).ok_or_else(|| LayoutError::NoField {
            layout: self.name.clone(),
            field: name.to_string(),
        })
    }

    /// The `i`-th field in bit order. Panics past the last field.
    pub fn at(&self, i: usize) -> &Field {
        &self.fields[i]
    }

    /// A zero word of this layout's width.
    pub fn zero(&self) -> Bits {
        Bits::zero(self.width)
    }

    /// The word holding `values`: every field given exactly once, by name,
    /// each value fitting its field. Bits outside every field are 0.
    pub fn pack<S: AsRef<str>>(&self, values: &[(S, u64)]) -> Result<Bits, LayoutError> {
        let mut b = self.zero();
        for (name, _) in values {
            self.get(name.as_ref())?;
        }
        for f in &self.fields {
            let mut given = values.iter().filter(|(n, _)| n.as_ref() == f.name);
            match (given.next(), given.next()) {
                (Some(&(_, v)), None) => b.set(f, v)?,
                (found, _) => {
                    return Err(LayoutError::Unpacked {
                        layout: self.name.clone(),
                        field: f.name,
                        given: if found.is_some() { 2 } else { 0 },
                    })
                }
            }
        }
        Ok(b)
    }

    /// Every field's value in `word`, in bit order. `word` must be exactly
    /// as wide as the layout, and every field at most 64 bits wide.
    pub fn unpack(&self, word: &Bits) -> Result<Vec<(&'static str, u64)>, LayoutError> {
        if word.width() != self.width {
            return Err(LayoutError::WrongWidthOf {
                layout: self.name.clone(),
                expected: self.width,
                found: word.width(),
            });
        }
        self.fields
            .iter()
            .map(|f| Ok((f.name, word.get(f)?)))
            .collect()
    }
}

/// Index of each node-record field in bit order.
const LEAF: usize = 0;
const LOD: usize = 1;
const COORD: usize = 2; // x, y, z
const LO: usize = 5; // lo_x, lo_y, lo_z
const HI: usize = 8; // hi_x, hi_y, hi_z
const FIRST: usize = 11;
const COUNT: usize = 12;

/// The node-record layout of SPEC.md section 3 for one parameter set:
/// `leaf, lod, x, y, z, lo_x, lo_y, lo_z, hi_x, hi_y, hi_z, first, count`,
/// packed from bit 0 upward. A [`Layout`] (through `Deref`) with an
/// accessor per field.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NodeLayout(Layout);

impl std::ops::Deref for NodeLayout {
    type Target = Layout;
    fn deref(&self) -> &Layout {
        &self.0
    }
}

impl NodeLayout {
    /// The layout for `p` (widths from [`Params`]: lod_bits, D, Q, I); its
    /// width is `W = 1 + lod_bits + 3D + 6Q + 2I`.
    pub fn new(p: &Params) -> NodeLayout {
        let lod = p.lod_bits();
        let d = p.coord_bits();
        let q = p.quant_bits as u32;
        let i = p.index_bits as u32;
        NodeLayout(Layout::packed(
            "node record",
            &[
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
            ],
        ))
    }

    /// The plain [`Layout`].
    pub fn layout(&self) -> &Layout {
        &self.0
    }

    /// The `leaf` flag (1 bit): 1 for a leaf, 0 for an inner node.
    pub fn leaf(&self) -> &Field {
        self.at(LEAF)
    }
    /// The node's LOD `d` (`lod_bits` wide).
    pub fn lod(&self) -> &Field {
        self.at(LOD)
    }
    /// Voxel x coordinate (D bits).
    pub fn x(&self) -> &Field {
        self.at(COORD)
    }
    /// Voxel y coordinate (D bits).
    pub fn y(&self) -> &Field {
        self.at(COORD + 1)
    }
    /// Voxel z coordinate (D bits).
    pub fn z(&self) -> &Field {
        self.at(COORD + 2)
    }
    /// Voxel coordinate of `axis` (0 = x, 1 = y, 2 = z). Panics on axis > 2.
    pub fn coord(&self, axis: usize) -> &Field {
        assert!(axis < 3, "axis {axis} is not 0, 1 or 2");
        self.at(COORD + axis)
    }
    /// Box minimum cell on `axis`. Panics on axis > 2.
    pub fn lo(&self, axis: usize) -> &Field {
        assert!(axis < 3, "axis {axis} is not 0, 1 or 2");
        self.at(LO + axis)
    }
    /// Box maximum cell (inclusive) on `axis`. Panics on axis > 2.
    pub fn hi(&self, axis: usize) -> &Field {
        assert!(axis < 3, "axis {axis} is not 0, 1 or 2");
        self.at(HI + axis)
    }
    /// First index into `refs` (inner node) or `prims` (leaf); I bits.
    pub fn first(&self) -> &Field {
        self.at(FIRST)
    }
    /// Number of children or primitives, at least 1; I bits.
    pub fn count(&self) -> &Field {
        self.at(COUNT)
    }
}

/// The child-reference layout: `node` in bits `[0, I)`, `hier` in `[I, I + H)`.
/// A [`Layout`] (through `Deref`) with an accessor per field.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RefLayout(Layout);

impl std::ops::Deref for RefLayout {
    type Target = Layout;
    fn deref(&self) -> &Layout {
        &self.0
    }
}

impl RefLayout {
    /// The layout for `p` (widths I and H; `I + H` in all).
    pub fn new(p: &Params) -> RefLayout {
        RefLayout(Layout::packed(
            "reference",
            &[("node", p.index_bits as u32), ("hier", p.hier_bits as u32)],
        ))
    }

    /// The plain [`Layout`].
    pub fn layout(&self) -> &Layout {
        &self.0
    }

    /// Node index into the named hierarchy's `nodes`, bits `[0, I)`.
    pub fn node(&self) -> &Field {
        self.at(0)
    }
    /// Hierarchy id, bits `[I, I + H)`.
    pub fn hier(&self) -> &Field {
        self.at(1)
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
    fn a_layout_packs_by_name_and_unpacks_what_it_packed() {
        let l = Layout::packed("beat", &[("a", 5), ("none", 0), ("b", 1), ("c", 64)]);
        assert_eq!(l.width(), 70);
        assert_eq!(
            (l.get("b").unwrap().offset, l.get("c").unwrap().offset),
            (5, 6)
        );
        let values = [("c", u64::MAX - 1), ("a", 0b10110), ("b", 1), ("none", 0)];
        let w = l.pack(&values).unwrap();
        assert_eq!(w.get(l.get("a").unwrap()).unwrap(), 0b10110);
        assert!(w.bit(5));
        assert_eq!(
            l.unpack(&w).unwrap(),
            vec![("a", 0b10110), ("none", 0), ("b", 1), ("c", u64::MAX - 1)]
        );
    }

    #[test]
    fn a_layout_refuses_what_it_cannot_pack_exactly() {
        let l = Layout::packed("beat", &[("a", 3), ("b", 1)]);
        let e = l.get("c").unwrap_err();
        assert!(
            e.to_string().contains("layout `beat` has no field `c`"),
            "{e}"
        );
        assert!(matches!(
            l.pack(&[("a", 8), ("b", 0)]),
            Err(LayoutError::DoesNotFit { field: "a", .. })
        ));
        assert!(matches!(
            l.pack(&[("a", 1)]),
            Err(LayoutError::Unpacked {
                field: "b",
                given: 0,
                ..
            })
        ));
        assert!(matches!(
            l.pack(&[("a", 1), ("b", 0), ("b", 1)]),
            Err(LayoutError::Unpacked {
                field: "b",
                given: 2,
                ..
            })
        ));
        assert!(matches!(
            l.pack(&[("a", 1), ("b", 0), ("z", 1)]),
            Err(LayoutError::NoField { .. })
        ));
        let e = l.unpack(&Bits::zero(5)).unwrap_err();
        assert!(
            e.to_string().contains("expected a 4-bit word, found 5"),
            "{e}"
        );
    }

    #[test]
    fn fixed_offsets_keep_their_gaps_and_overlaps_are_refused() {
        let l = Layout::from_fields(
            "cmd",
            &[Field::new("kind", 9, 1), Field::new("count", 0, 2)],
            12,
        );
        assert_eq!(l.width(), 12);
        assert_eq!(
            l.fields().map(|f| f.name).collect::<Vec<_>>(),
            ["count", "kind"]
        );
        let w = l.pack(&[("kind", 1), ("count", 3)]).unwrap();
        assert_eq!(w.to_u64(), Some((1 << 9) | 3));
        let overlap = std::panic::catch_unwind(|| {
            Layout::from_fields("bad", &[Field::new("a", 0, 4), Field::new("b", 3, 1)], 8)
        });
        assert!(overlap.is_err());
        let past =
            std::panic::catch_unwind(|| Layout::from_fields("bad", &[Field::new("a", 0, 4)], 3));
        assert!(past.is_err());
    }

    #[test]
    fn nested_and_flattened_layouts_name_fields_by_path() {
        let mut inner = Layout::new("input");
        inner.push("a", 3);
        inner.push_at("b", 5, 2);
        assert_eq!(inner.width(), 7);
        let mut outer = Layout::new("cmd");
        let g0 = outer.nest("in0", &inner);
        let g1 = outer.nest("in1", &inner);
        let kind = outer.push_at("kind", 20, 1);
        assert_eq!((g0.offset, g0.width, g1.offset, g1.name), (0, 7, 7, "in1"));
        assert_eq!(outer.get("in1.b").unwrap().offset, 12);
        assert_eq!((kind.offset, outer.width()), (20, 21));
        let w = outer
            .pack(&[
                ("in0.a", 5),
                ("in0.b", 1),
                ("in1.a", 2),
                ("in1.b", 3),
                ("kind", 1),
            ])
            .unwrap();
        assert_eq!(w.to_u64(), Some(5 | 1 << 5 | 2 << 7 | 3 << 12 | 1 << 20));

        let coarse = Layout::packed("cfg", &[("in0", 7), ("count", 2), ("in1", 7)]);
        let flat = coarse.flattened("cfg stream", |f| f.name.starts_with("in").then_some(&inner));
        let names: Vec<_> = flat.fields().map(|f| (f.name, f.offset)).collect();
        assert_eq!(
            names,
            [
                ("in0.a", 0),
                ("in0.b", 5),
                ("count", 7),
                ("in1.a", 9),
                ("in1.b", 14)
            ]
        );
        assert_eq!((flat.name(), flat.width()), ("cfg stream", 16));
        let narrow = std::panic::catch_unwind(|| coarse.flattened("bad", |_| Some(&inner)));
        assert!(
            narrow.is_err(),
            "a 7-bit layout flattened into `count`'s 2 bits"
        );
        let gap = std::panic::catch_unwind(|| {
            let mut l = Layout::packed("l", &[("a", 4)]);
            l.push_at("b", 2, 1)
        });
        assert!(gap.is_err(), "a field placed below the top is an overlap");
    }

    #[test]
    fn interned_names_are_shared() {
        let a = intern(&format!("{}_{}", "placement", "x"));
        assert_eq!(a, "placement_x");
        assert!(std::ptr::eq(a, intern("placement_x")));
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
