//! [`Bundle`]: named signals carried through one pipeline register as one
//! bus, so that a stage boundary is a single [`Stream::pipeline_reg`] or
//! [`Stream::skid_buffer`] whatever the stage carries.

use golden::layout::Layout;

use crate::{Signal, Stream};

/// Named signals, packed into a bus in insertion order from bit 0 upward,
/// as [`Bundle::layout`] describes it.
#[derive(Clone, Default)]
pub(crate) struct Bundle<'m> {
    parts: Vec<(String, Signal<'m>)>,
}

impl<'m> Bundle<'m> {
    pub(crate) fn new() -> Bundle<'m> {
        Bundle { parts: Vec::new() }
    }

    /// Adds `sig` under `name` (names are unique within a bundle).
    pub(crate) fn put(&mut self, name: &str, sig: Signal<'m>) {
        debug_assert!(self.parts.iter().all(|(n, _)| n != name), "{name} twice");
        self.parts.push((name.to_string(), sig));
    }

    /// The signal called `name`. A missing name is a generator bug.
    pub(crate) fn get(&self, name: &str) -> Signal<'m> {
        self.parts
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, s)| *s)
            .unwrap_or_else(|| panic!("bundle has no signal `{name}`"))
    }

    /// The names, in insertion order.
    pub(crate) fn names(&self) -> Vec<String> {
        self.parts.iter().map(|(n, _)| n.clone()).collect()
    }

    /// Total width of the parts.
    pub(crate) fn width(&self) -> u32 {
        self.parts.iter().map(|(_, s)| s.width()).sum()
    }

    /// The bus's layout, called `name`: each part's name and width, the
    /// first part in the low bits. [`Bundle::unpack`] slices by it and a
    /// testbench decodes the bus with it.
    pub(crate) fn layout(&self, name: &str) -> Layout {
        let mut l = Layout::new(name);
        for (n, s) in &self.parts {
            l.push(n, s.width());
        }
        l
    }

    /// The bus: the first part in the low bits.
    fn pack(&self) -> Signal<'m> {
        let sigs: Vec<Signal<'m>> = self.parts.iter().rev().map(|(_, s)| *s).collect();
        let m = sigs[0].module();
        if sigs.len() == 1 {
            sigs[0].as_unsigned()
        } else {
            m.concat(&sigs)
        }
    }

    /// The same names and widths sliced out of `bus`; signedness restored.
    fn unpack(&self, bus: Signal<'m>) -> Bundle<'m> {
        let layout = self.layout("bundle");
        let mut out = Bundle::new();
        for (f, (_, s)) in layout.fields().zip(&self.parts) {
            let mut part = if f.width == bus.width() {
                bus
            } else {
                bus.view(f)
            };
            if s.is_signed() {
                part = part.as_signed();
            }
            out.put(f.name, part);
        }
        out
    }

    /// `self` as the payload of a stream with the given handshake, passed
    /// through a pipeline register named `name`; returns the registered
    /// stream and its bundle.
    pub(crate) fn pipeline_reg(
        &self,
        valid: Signal<'m>,
        ready: Signal<'m>,
        name: &str,
    ) -> (Stream<'m>, Bundle<'m>) {
        let s = Stream {
            valid,
            ready,
            data: self.pack(),
        }
        .pipeline_reg(name);
        let b = self.unpack(s.data);
        (s, b)
    }

    /// As [`Bundle::pipeline_reg`] with a skid buffer (registered `ready`).
    pub(crate) fn skid_buffer(
        &self,
        valid: Signal<'m>,
        ready: Signal<'m>,
        name: &str,
    ) -> (Stream<'m>, Bundle<'m>) {
        let s = Stream {
            valid,
            ready,
            data: self.pack(),
        }
        .skid_buffer(name);
        let b = self.unpack(s.data);
        (s, b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Module, Sim};

    #[test]
    fn a_bundles_bus_decodes_by_its_layout() {
        let m = Module::new("bundle");
        let mut b = Bundle::new();
        b.put("a", m.input("a", 3));
        b.put("b", m.input("b", 5).as_signed());
        b.put("c", m.input("c", 1));
        let l = b.layout("s1");
        assert_eq!(l.width(), b.width());
        let offsets: Vec<(&str, u32)> = l.fields().map(|f| (f.name, f.offset)).collect();
        assert_eq!(offsets, [("a", 0), ("b", 3), ("c", 8)]);
        let bus = b.pack();
        m.output("bus", bus);
        let back = b.unpack(bus);
        assert!(back.get("b").is_signed());
        m.output("b_back", back.get("b").as_unsigned());
        let mut sim = Sim::new(&m).unwrap();
        for (n, v) in [("a", 5u64), ("b", 0b10110), ("c", 1)] {
            sim.poke(n, v).unwrap();
        }
        let got = l.unpack(&sim.peek("bus").unwrap()).unwrap();
        assert_eq!(got, [("a", 5), ("b", 0b10110), ("c", 1)]);
        assert_eq!(sim.peek("b_back").unwrap().to_u64(), Some(0b10110));
    }
}
