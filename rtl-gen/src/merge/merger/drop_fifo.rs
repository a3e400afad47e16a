//! The FIFOs of the leaves above the merging level and (per-node) of nodes.

use crate::{Module, Signal};

/// A FIFO of `2^cb` words on a memory, whose pushes while full are
/// dropped (the caller flags them): `{name}_wr` / `{name}_rd` pointers of
/// `cb + 1` bits (the top bit tells full from empty), cleared at the end of
/// a merge.
pub(super) struct DropFifo<'m> {
    pub(super) m: &'m Module,
    pub(super) mem: crate::Memory<'m>,
    pub(super) wr: Signal<'m>,
    pub(super) rd: Signal<'m>,
    pub(super) cb: u32,
    pub(super) empty: Signal<'m>,
    pub(super) full: Signal<'m>,
}

impl<'m> DropFifo<'m> {
    pub(super) fn new(m: &'m Module, mem_name: &str, name: &str, width: u32, cb: u32) -> Self {
        let mem = m.memory(mem_name, width, 1 << cb);
        let wr = m.reg(&format!("{name}_wr"), cb + 1);
        let rd = m.reg(&format!("{name}_rd"), cb + 1);
        let empty = wr.eq(rd).name(&format!("{name}_empty"));
        let full = (wr.slice(cb - 1, 0).eq(rd.slice(cb - 1, 0)) & !wr.bit(cb).eq(rd.bit(cb)))
            .name(&format!("{name}_full"));
        DropFifo {
            m,
            mem,
            wr,
            rd,
            cb,
            empty,
            full,
        }
    }

    /// Writes `data` when `push` and not full.
    pub(super) fn write(&self, data: Signal<'m>, push: Signal<'m>) {
        let cb = self.cb;
        self.mem.write(
            self.wr.slice(cb - 1, 0),
            data,
            (push & !self.full).named_after(self.wr, "put"),
        );
    }

    /// The oldest word (meaningful when not empty).
    pub(super) fn head(&self) -> Signal<'m> {
        self.mem.read(self.rd.slice(self.cb - 1, 0))
    }

    /// Moves the pointers: a kept push, a pop; `clear` empties it.
    pub(super) fn advance(&self, push: Signal<'m>, pop: Signal<'m>, clear: Signal<'m>) {
        let (wr, rd, w) = (self.wr, self.rd, self.cb + 1);
        let zero = self.m.lit(0, w);
        wr.next(clear.mux(zero, (push & !self.full).mux(wr.add(1, w), wr)));
        rd.next(clear.mux(zero, pop.mux(rd.add(1, w), rd)));
    }
}
