//! [`Bundle`]: named signals carried through one pipeline register as one
//! bus, so that a stage boundary is a single [`Stream::pipeline_reg`] or
//! [`Stream::skid_buffer`] whatever the stage carries.

use crate::{Signal, Stream};

/// Named signals, packed into a bus in insertion order from bit 0 upward.
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
        let mut at = 0;
        let mut out = Bundle::new();
        for (name, s) in &self.parts {
            let w = s.width();
            let mut part = if w == bus.width() {
                bus
            } else {
                bus.field_view(at + w - 1, at, name)
            };
            if s.is_signed() {
                part = part.as_signed();
            }
            out.put(name, part);
            at += w;
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
