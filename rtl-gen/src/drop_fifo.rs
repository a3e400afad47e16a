//! [`DropFifo`]: the library FIFO for producers that cannot be held.
//!
//! [`crate::Stream::fifo`] back-pressures its producer. Some producers must
//! not stop: the merger top's leaves above the merging level, and the nodes
//! per-node mode hands to the builder, arrive while the module keeps `out`
//! moving, and the shared store port's answers arrive a fixed latency after
//! their reads whatever the requester does. For them the FIFO takes every
//! beat it has room for, drops a push while full and lets the caller flag it
//! (of the data alone if no pop precedes the last push; SPEC 8.15 step 4),
//! and empties at once on `clear` (the end of a merge). Its state is two
//! pointers of `cb + 1` bits, whose top bits tell full from empty, so that
//! `full` and `empty` are single compares and no count is kept.

use crate::{Memory, Module, Signal};

/// A FIFO of `2^cb` words on a memory, whose pushes while full are dropped
/// (the caller flags them). Registers `{name}_wr` and `{name}_rd`; wires
/// `{name}_empty`, `{name}_full` and `{name}_put` (a push kept).
///
/// ```
/// use rtl_gen::{DropFifo, Module, Sim};
/// let m = Module::new("m");
/// let push = m.input("push", 1);
/// let pop = m.input("pop", 1);
/// let word = m.input("word", 8);
/// let q = DropFifo::new(&m, "q_mem", "q", 8, 1);
/// q.write(word, push);
/// q.advance(push, pop, m.lit(0, 1));
/// m.output("head", q.head());
/// m.output("full", q.full());
/// let mut sim = Sim::new(&m).unwrap();
/// sim.reset();
/// for w in [1u64, 2, 3] {
///     sim.poke("push", 1u64).unwrap();
///     sim.poke("word", w).unwrap();
///     sim.step();
/// }
/// // Two words held; the third push found the FIFO full and was dropped.
/// assert_eq!(sim.peek("full").unwrap().to_u64(), Some(1));
/// assert_eq!(sim.peek("head").unwrap().to_u64(), Some(1));
/// ```
pub struct DropFifo<'m> {
    m: &'m Module,
    mem: Memory<'m>,
    wr: Signal<'m>,
    rd: Signal<'m>,
    cb: u32,
    empty: Signal<'m>,
    full: Signal<'m>,
}

impl<'m> DropFifo<'m> {
    /// A FIFO of `2^cb` words of `width` bits in memory `mem_name`, its
    /// registers and wires named after `name`.
    pub fn new(m: &'m Module, mem_name: &str, name: &str, width: u32, cb: u32) -> Self {
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

    /// No word held.
    pub fn empty(&self) -> Signal<'m> {
        self.empty
    }

    /// `2^cb` words held: a push now is dropped.
    pub fn full(&self) -> Signal<'m> {
        self.full
    }

    /// Writes `data` when `push` and not full.
    pub fn write(&self, data: Signal<'m>, push: Signal<'m>) {
        let cb = self.cb;
        self.mem.write(
            self.wr.slice(cb - 1, 0),
            data,
            (push & !self.full).named_after(self.wr, "put"),
        );
    }

    /// The oldest word (meaningful when not empty).
    pub fn head(&self) -> Signal<'m> {
        self.mem.read(self.rd.slice(self.cb - 1, 0))
    }

    /// Moves the pointers: a kept push, a pop (only while not empty);
    /// `clear` empties it.
    pub fn advance(&self, push: Signal<'m>, pop: Signal<'m>, clear: Signal<'m>) {
        let (wr, rd, w) = (self.wr, self.rd, self.cb + 1);
        let zero = self.m.lit(0, w);
        wr.next(clear.mux(zero, (push & !self.full).mux(wr.add(1, w), wr)));
        rd.next(clear.mux(zero, pop.mux(rd.add(1, w), rd)));
    }
}
