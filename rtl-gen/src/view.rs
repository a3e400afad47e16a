//! Field views: reading and rewriting a packed word's fields through the
//! golden layout's [`Field`]s (Amaranth's `data.View`), the one place the
//! generators turn a field description into slices, so no offset is
//! restated. A view is named `<word>_<field>` in the Verilog.

use golden::layout::{Field, Layout, NodeLayout};

use crate::{Module, Signal};

impl<'m> Signal<'m> {
    /// Field `f` of this packed word, named `<word>_<field>`. Only box
    /// bounds are ever zero-width (`Q = 0`); reading one here is a generator
    /// bug, reported naming the field. Read those with [`Signal::view_opt`].
    #[track_caller]
    pub fn view(self, f: &Field) -> Signal<'m> {
        assert!(
            f.width > 0,
            "field `{}` has no bits: read it with `view_opt`",
            f.name
        );
        self.field_view(f.end() - 1, f.offset, f.name)
    }

    /// Field `f` of this word as [`Signal::view`]; `None` for a zero-width
    /// field (the box bounds when `Q = 0`).
    #[track_caller]
    pub fn view_opt(self, f: &Field) -> Option<Signal<'m>> {
        // Not in a closure: the caller's line is the view's source comment.
        if f.width > 0 {
            Some(self.field_view(f.end() - 1, f.offset, f.name))
        } else {
            None
        }
    }

    /// Field `name` of this word of `layout` (as [`Signal::view`]); an
    /// unknown name is a generator bug, reported naming layout and field.
    #[track_caller]
    pub fn view_named(self, layout: &Layout, name: &str) -> Signal<'m> {
        let f = match layout.get(name) {
            Ok(f) => f,
            Err(e) => panic!("{e}"),
        };
        self.view(f)
    }

    /// The contiguous bits from field `first` to field `last` inclusive
    /// (`lod` through `z` of a node record: a voxel address).
    #[track_caller]
    pub fn view_span(self, first: &Field, last: &Field) -> Signal<'m> {
        self.slice(last.end() - 1, first.offset)
    }

    /// The voxel coordinates of this node record: its `x`, `y`, `z` fields.
    #[track_caller]
    pub fn coords(self, nl: &NodeLayout) -> [Signal<'m>; 3] {
        [0, 1, 2].map(|a| self.view(nl.coord(a)))
    }

    /// This word with the fields of `replace` set to the given signals
    /// (each as wide as its field; zero-width fields are skipped), every
    /// other bit kept. On a literal 0, the word of those fields alone.
    #[track_caller]
    pub fn with_fields(self, replace: &[(Field, Signal<'m>)]) -> Signal<'m> {
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
                low_first.push(self.slice(lo - 1, at));
            }
            low_first.extend(s);
            at = hi;
        }
        if at < self.width() {
            low_first.push(self.slice(self.width() - 1, at));
        }
        low_first.reverse();
        self.m.concat(&low_first)
    }
}

impl Module {
    /// The word of `layout` holding `values`, one per field in bit order,
    /// each exactly as wide as its field: the concatenation that the views
    /// of [`Signal::view_named`] take apart, so packing and unpacking an
    /// internal word (a FIFO's entry) cannot drift apart.
    #[track_caller]
    pub fn pack<'m>(&'m self, layout: &Layout, values: &[Signal<'m>]) -> Signal<'m> {
        assert_eq!(
            values.len(),
            layout.fields().len(),
            "layout `{}`: one value per field",
            layout.name()
        );
        for (f, v) in layout.fields().zip(values) {
            assert_eq!(
                v.width(),
                f.width,
                "layout `{}`: a {}-bit value for field `{}`",
                layout.name(),
                v.width(),
                f.name
            );
        }
        let msb_first: Vec<Signal<'m>> = values.iter().rev().copied().collect();
        self.concat(&msb_first)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Sim;

    #[test]
    fn a_word_packs_from_bit_0_and_unpacks_what_it_packed() {
        let w = Layout::packed("word", &[("first", 5), ("flag", 1), ("count", 6)]);
        assert_eq!(w.width(), 12);
        let m = Module::new("word");
        let (a, f, c) = (m.input("a", 5), m.input("f", 1), m.input("c", 6));
        let packed = m.pack(&w, &[a, f, c]);
        m.output("word_out", packed);
        m.output("a_out", packed.view_named(&w, "first"));
        m.output("f_out", packed.view_named(&w, "flag"));
        m.output("c_out", packed.view_named(&w, "count"));
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

    #[test]
    #[should_panic(expected = "layout `word`: a 4-bit value for field `first`")]
    fn a_value_of_the_wrong_width_is_refused() {
        let w = Layout::packed("word", &[("first", 5), ("flag", 1)]);
        let m = Module::new("word");
        m.pack(&w, &[m.input("a", 4), m.input("f", 1)]);
    }

    #[test]
    #[should_panic(expected = "layout `word` has no field `last`")]
    fn an_unknown_field_is_named_with_its_layout() {
        let w = Layout::packed("word", &[("first", 5)]);
        let m = Module::new("word");
        m.input("a", 5).view_named(&w, "last");
    }
}
