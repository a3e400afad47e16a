//! Reading and rewriting the fields of a packed record signal by the golden
//! layout's [`Field`]s: the one place the merge generators turn a field
//! description into slices, so no offset is restated.

use golden::layout::{Field, NodeLayout};

use crate::{Module, Signal};

/// The bits of field `f` of `record`; `None` for a zero-width field (the box
/// bounds when `Q = 0`).
#[track_caller]
pub fn field<'m>(record: Signal<'m>, f: &Field) -> Option<Signal<'m>> {
    // Not in a closure: the caller's line is the view's source comment.
    if f.width > 0 {
        Some(record.field_view(f.end() - 1, f.offset, f.name))
    } else {
        None
    }
}

/// The voxel coordinates of a node record: its `x`, `y`, `z` fields.
#[track_caller]
pub fn coords<'m>(record: Signal<'m>, nl: &NodeLayout) -> [Signal<'m>; 3] {
    [0, 1, 2].map(|a| field(record, nl.coord(a)).expect("coordinates are never zero-width"))
}

/// The contiguous bits from field `first` to field `last` inclusive (e.g.
/// `lod` through `z`: a voxel address).
#[track_caller]
pub fn span<'m>(record: Signal<'m>, first: &Field, last: &Field) -> Signal<'m> {
    record.slice(last.end() - 1, first.offset)
}

/// `record` with the fields of `replace` set to the given signals (each as
/// wide as its field; zero-width fields are skipped), every other bit kept.
#[track_caller]
pub fn with_fields<'m>(
    m: &'m Module,
    record: Signal<'m>,
    replace: &[(Field, Signal<'m>)],
) -> Signal<'m> {
    let mut parts: Vec<(u32, u32, Option<Signal<'m>>)> = replace
        .iter()
        .filter(|(f, _)| f.width > 0)
        .map(|(f, s)| (f.offset, f.end(), Some(*s)))
        .collect();
    parts.sort_by_key(|p| p.0);
    let mut low_first = Vec::new();
    let mut at = 0;
    for (lo, hi, s) in parts {
        if lo > at {
            low_first.push(record.slice(lo - 1, at));
        }
        low_first.extend(s);
        at = hi;
    }
    if at < record.width() {
        low_first.push(record.slice(record.width() - 1, at));
    }
    low_first.reverse();
    m.concat(&low_first)
}

/// An internal word of named fields packed from bit 0 upward, such as a
/// FIFO's entry: one definition for the concatenation that packs it and
/// the slices that unpack it, so the two cannot drift apart. Golden's
/// layouts describe what crosses a port; this describes what never does.
#[derive(Clone, Debug)]
pub struct Word {
    fields: Vec<Field>,
}

impl Word {
    /// Fields `(name, width)` from bit 0 upward; every width at least 1.
    pub fn new(parts: &[(&'static str, u32)]) -> Word {
        let mut offset = 0;
        let fields = parts
            .iter()
            .map(|&(name, width)| {
                assert!(width > 0, "word field `{name}` has no bits");
                let f = Field {
                    name,
                    offset,
                    width,
                };
                offset += width;
                f
            })
            .collect();
        Word { fields }
    }

    /// Bits in all.
    pub fn width(&self) -> u32 {
        self.fields.last().map_or(0, Field::end)
    }

    /// The field named `name`.
    #[track_caller]
    pub fn field(&self, name: &str) -> &Field {
        self.fields
            .iter()
            .find(|f| f.name == name)
            .unwrap_or_else(|| panic!("word has no field `{name}`"))
    }

    /// The word of `values`, one per field from bit 0 upward (each as wide
    /// as its field; the module's builder checks the widths).
    #[track_caller]
    pub fn pack<'m>(&self, m: &'m Module, values: &[Signal<'m>]) -> Signal<'m> {
        assert_eq!(values.len(), self.fields.len(), "one value per word field");
        let msb_first: Vec<Signal<'m>> = values.iter().rev().copied().collect();
        m.concat(&msb_first)
    }

    /// Field `name` of `word`.
    #[track_caller]
    pub fn get<'m>(&self, word: Signal<'m>, name: &str) -> Signal<'m> {
        let f = self.field(name);
        word.field_view(f.end() - 1, f.offset, name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Sim;

    #[test]
    fn a_word_packs_from_bit_0_and_unpacks_what_it_packed() {
        let w = Word::new(&[("first", 5), ("flag", 1), ("count", 6)]);
        assert_eq!(w.width(), 12);
        assert_eq!((w.field("flag").offset, w.field("count").offset), (5, 6));
        let m = Module::new("word");
        let (a, f, c) = (m.input("a", 5), m.input("f", 1), m.input("c", 6));
        let packed = w.pack(&m, &[a, f, c]);
        m.output("word_out", packed);
        m.output("a_out", w.get(packed, "first"));
        m.output("f_out", w.get(packed, "flag"));
        m.output("c_out", w.get(packed, "count"));
        let mut sim = Sim::new(&m).unwrap();
        sim.poke("a", 0b10110u64).unwrap();
        sim.poke("f", 1u64).unwrap();
        sim.poke("c", 0b100011u64).unwrap();
        let peek = |sim: &mut Sim, name| sim.peek(name).unwrap().to_u64().unwrap();
        assert_eq!(
            peek(&mut sim, "word_out"),
            (0b100011 << 6) | (1 << 5) | 0b10110
        );
        assert_eq!(peek(&mut sim, "a_out"), 0b10110);
        assert_eq!(peek(&mut sim, "f_out"), 1);
        assert_eq!(peek(&mut sim, "c_out"), 0b100011);
    }
}
