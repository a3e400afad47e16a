//! [`Memory`]: register files (asynchronous read) and RAMs (synchronous read).

use crate::diagnostic::{DiagKind, Loc};
use crate::graph::{Op, WritePort};
use crate::{IntoSignal, Module, Signal};
use std::panic::Location;

/// A memory made by [`Module::memory`]. Write ports act on the rising clock
/// edge (`if (en) mem[addr] <= data`, later ports win on the same address);
/// reads are asynchronous ([`Memory::read`], a register file) or registered
/// ([`Memory::read_sync`], a RAM, returning the word before any write of the
/// same edge). Addresses are exactly `log2(depth)` bits. Contents are
/// undefined until written (the simulator starts from zero).
///
/// ```
/// use rtl_gen::Module;
/// let m = Module::new("ram");
/// let mem = m.memory("mem", 16, 64);
/// mem.write(m.input("wa", 6), m.input("wd", 16), m.input("we", 1));
/// let q = mem.read_sync(m.input("ra", 6), m.input("re", 1));
/// m.output("q", q);
/// assert!(m.validate().is_ok());
/// ```
#[derive(Clone, Copy)]
pub struct Memory<'m> {
    pub(crate) m: &'m Module,
    pub(crate) idx: usize,
}

impl<'m> Memory<'m> {
    /// Word width in bits.
    pub fn width(&self) -> u32 {
        self.m.graph().mems[self.idx].width
    }

    /// Address width in bits (`log2(depth)`).
    pub fn addr_width(&self) -> u32 {
        self.m.graph().mems[self.idx].addr_width
    }

    fn name(&self) -> String {
        self.m.graph().mems[self.idx].name.clone()
    }

    fn check_addr(&self, addr: Signal<'m>, loc: Loc) -> bool {
        if addr.width() != self.addr_width() || addr.is_signed() {
            let msg = format!(
                "address must be an unsigned {}-bit signal, is {} bits{}",
                self.addr_width(),
                addr.width(),
                if addr.is_signed() { " signed" } else { "" }
            );
            let name = self.name();
            self.m
                .graph_mut()
                .error(DiagKind::Width, Some(name), loc, msg);
            return false;
        }
        true
    }

    fn addr(&self, addr: impl IntoSignal<'m>, loc: Loc) -> Signal<'m> {
        let like = self.m.lit(0, self.addr_width());
        addr.into_signal_like(like, loc)
    }

    /// Adds a write port: on the clock edge, when `en` (one bit), `data` is
    /// stored at `addr`.
    #[track_caller]
    pub fn write(&self, addr: impl IntoSignal<'m>, data: Signal<'m>, en: impl IntoSignal<'m>) {
        let loc = Location::caller();
        let a = self.addr(addr, loc);
        let e = en.into_signal_like(self.m.lit(0, 1), loc);
        if !self.m.owns(data, loc) || !self.check_addr(a, loc) {
            return;
        }
        if data.width() != self.width() || e.width() != 1 {
            let msg = format!(
                "write data must be {} bits (is {}) and enable 1 bit (is {})",
                self.width(),
                data.width(),
                e.width()
            );
            let name = self.name();
            self.m
                .graph_mut()
                .error(DiagKind::Width, Some(name), loc, msg);
            return;
        }
        self.m.clock(loc);
        self.m.graph_mut().mems[self.idx].writes.push(WritePort {
            addr: a.id,
            data: data.id,
            en: e.id,
        });
    }

    /// Asynchronous read: the word at `addr`, this cycle.
    #[track_caller]
    pub fn read(&self, addr: impl IntoSignal<'m>) -> Signal<'m> {
        let loc = Location::caller();
        let a = self.addr(addr, loc);
        if !self.check_addr(a, loc) {
            return self.m.fail(
                DiagKind::Width,
                None,
                loc,
                "bad memory address".into(),
                self.width(),
            );
        }
        let id = self.m.add_node(
            Op::MemRead {
                mem: self.idx,
                addr: a.id,
            },
            self.width(),
            &self.name(),
            "rd",
            loc,
        );
        self.m.sig(id, false)
    }

    /// Synchronous read: a register loaded with the word at `addr` on the
    /// clock edge when `en` is high (the old word if the same edge writes it).
    #[track_caller]
    pub fn read_sync(&self, addr: impl IntoSignal<'m>, en: impl IntoSignal<'m>) -> Signal<'m> {
        let loc = Location::caller();
        let a = self.addr(addr, loc);
        let e = en.into_signal_like(self.m.lit(0, 1), loc);
        if !self.check_addr(a, loc) || e.width() != 1 {
            return self.m.fail(
                DiagKind::Width,
                None,
                loc,
                "bad memory address or enable".into(),
                self.width(),
            );
        }
        self.m.clock(loc);
        let op = Op::MemReadSync {
            mem: self.idx,
            addr: a.id,
            en: e.id,
        };
        let id = self
            .m
            .add_node(op, self.width(), &self.name(), "rdata", loc);
        self.m.sig(id, false)
    }
}
