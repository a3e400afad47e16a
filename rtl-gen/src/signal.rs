//! [`Signal`]: a cheap handle to a node of a module, and every operator.

use crate::diagnostic::{DiagKind, Loc};
use crate::graph::{Amount, BinOp, CmpOp, NodeId, Op, RedOp, ShiftKind};
use crate::{Bits, Module};
use std::panic::Location;

/// A value in a module: a port, wire, register, constant or the result of an
/// operator. It is a `Copy` handle into its module's arena; the `signed` flag
/// says how operators read its bits (two's complement or unsigned) and costs
/// no hardware.
///
/// ```
/// use rtl_gen::Module;
/// let m = Module::new("m");
/// let a = m.input("a", 8);
/// let b = m.input("b", 8);
/// let x = (a ^ b) & 0x0f;          // bitwise ops need equal widths; integers adopt them
/// let s = a.add(b, 9);              // explicit result width, no overflow
/// let lt = a.as_signed().lt(b.as_signed());
/// m.output("y", lt.mux(x, s.slice(7, 0)));
/// m.output("carry", s.bit(8));
/// assert!(m.validate().is_ok());
/// ```
#[derive(Clone, Copy)]
pub struct Signal<'m> {
    pub(crate) m: &'m Module,
    pub(crate) id: NodeId,
    pub(crate) signed: bool,
}

impl std::fmt::Debug for Signal<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let g = self.m.graph();
        write!(
            f,
            "Signal({}, {} bits{})",
            g.describe(self.id),
            g.node(self.id).width,
            if self.signed { ", signed" } else { "" }
        )
    }
}

/// Something usable as an operand next to a signal: another [`Signal`], or an
/// integer or [`Bits`] constant, which takes the other operand's width and
/// signedness (an error if it does not fit).
pub trait IntoSignal<'m> {
    /// Converts `self` into a signal of `like`'s module, shaped like `like` when a constant.
    fn into_signal_like(self, like: Signal<'m>, loc: Loc) -> Signal<'m>;
}

impl<'m> IntoSignal<'m> for Signal<'m> {
    fn into_signal_like(self, like: Signal<'m>, loc: Loc) -> Signal<'m> {
        if like.m.owns(self, loc) {
            self
        } else {
            like.m.poison(self.width(), loc)
        }
    }
}

fn int_like<'m>(value: i128, like: Signal<'m>, loc: Loc) -> Signal<'m> {
    let w = like.width();
    let bits = if like.signed {
        Bits::from_i128(value, w)
    } else if value < 0 {
        return like.m.fail(
            DiagKind::Width,
            None,
            loc,
            format!("negative constant {value} next to an unsigned signal; make the signal signed with .as_signed()"),
            w,
        );
    } else {
        Bits::from_u128(value as u128, w)
    };
    match bits {
        Ok(b) => like.m.constant(b, like.signed, loc),
        Err(e) => like.m.fail(
            DiagKind::Width,
            None,
            loc,
            format!(
                "{e} ({} operand)",
                if like.signed { "signed" } else { "unsigned" }
            ),
            w,
        ),
    }
}

macro_rules! int_operand {
    ($($t:ty),*) => {$(
        impl<'m> IntoSignal<'m> for $t {
            fn into_signal_like(self, like: Signal<'m>, loc: Loc) -> Signal<'m> {
                int_like(self as i128, like, loc)
            }
        }
    )*};
}
int_operand!(i32, i64, u8, u16, u32, u64);

impl<'m> IntoSignal<'m> for u128 {
    fn into_signal_like(self, like: Signal<'m>, loc: Loc) -> Signal<'m> {
        match i128::try_from(self) {
            Ok(v) => int_like(v, like, loc),
            Err(_) => match Bits::from_u128(self, like.width()) {
                Ok(b) if !like.signed => like.m.constant(b, false, loc),
                _ => like.m.fail(
                    DiagKind::Width,
                    None,
                    loc,
                    format!("constant {self} does not fit"),
                    like.width(),
                ),
            },
        }
    }
}

impl<'m> IntoSignal<'m> for bool {
    fn into_signal_like(self, like: Signal<'m>, loc: Loc) -> Signal<'m> {
        int_like(self as i128, like, loc)
    }
}

impl<'m> IntoSignal<'m> for Bits {
    fn into_signal_like(self, like: Signal<'m>, loc: Loc) -> Signal<'m> {
        if self.width() != like.width() {
            return like.m.fail(
                DiagKind::Width,
                None,
                loc,
                format!(
                    "constant is {} bits, the other operand {}",
                    self.width(),
                    like.width()
                ),
                like.width(),
            );
        }
        like.m.constant(self, like.signed, loc)
    }
}

/// A shift amount: a constant `u32` or an unsigned signal.
pub trait ShiftAmount<'m> {
    /// The amount as a constant or a signal.
    fn shift_by(self) -> ShiftBy<'m>;
}

/// What a shift is by.
#[derive(Clone, Copy, Debug)]
pub enum ShiftBy<'m> {
    /// A constant number of bits.
    Const(u32),
    /// An unsigned signal, any width.
    Signal(Signal<'m>),
}

impl<'m> ShiftAmount<'m> for u32 {
    fn shift_by(self) -> ShiftBy<'m> {
        ShiftBy::Const(self)
    }
}

impl<'m> ShiftAmount<'m> for Signal<'m> {
    fn shift_by(self) -> ShiftBy<'m> {
        ShiftBy::Signal(self)
    }
}

fn shift_amount<'m>(by: ShiftBy<'m>, m: &'m Module, loc: Loc) -> Option<Amount> {
    match by {
        ShiftBy::Const(k) => Some(Amount::Const(k)),
        ShiftBy::Signal(s) => {
            if !m.owns(s, loc) {
                return None;
            }
            if s.signed {
                let what = m.graph().describe(s.id);
                m.graph_mut().error(
                    DiagKind::Misuse,
                    Some(what),
                    loc,
                    "shift amount must be unsigned (use .as_unsigned())".into(),
                );
                return None;
            }
            Some(Amount::Signal(s.id))
        }
    }
}

impl<'m> Signal<'m> {
    /// Width in bits.
    pub fn width(&self) -> u32 {
        self.m.graph().node(self.id).width
    }

    /// True when operators read this handle as two's complement.
    pub fn is_signed(&self) -> bool {
        self.signed
    }

    /// The same bits, read as two's complement (no hardware).
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let a = m.input("a", 8).as_signed();
    /// assert!(a.is_signed() && !a.as_unsigned().is_signed());
    /// m.output("neg", a.lt(0));
    /// # assert!(m.validate().is_ok());
    /// ```
    pub fn as_signed(self) -> Signal<'m> {
        Signal {
            signed: true,
            ..self
        }
    }

    /// The same bits, read as unsigned (no hardware).
    pub fn as_unsigned(self) -> Signal<'m> {
        Signal {
            signed: false,
            ..self
        }
    }

    /// The module this signal belongs to.
    pub fn module(&self) -> &'m Module {
        self.m
    }

    /// Gives the signal a name in the emitted Verilog and diagnostics
    /// (made unique if needed); ports keep their port name.
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let a = m.input("a", 8);
    /// let sum = a.add(1, 8).name("sum");
    /// m.output("y", sum);
    /// assert!(rtl_gen::emit_verilog(&m).unwrap().contains("wire [7:0] sum;"));
    /// ```
    #[track_caller]
    pub fn name(self, name: &str) -> Signal<'m> {
        self.name_unscoped(&self.m.scoped(name), Location::caller())
    }

    /// [`Signal::name`] with `name` as it is, whatever scope is open.
    pub(crate) fn name_unscoped(self, name: &str, loc: Loc) -> Signal<'m> {
        let is_port = self.m.graph().node(self.id).port.is_some();
        if is_port {
            self.m.graph_mut().error(
                DiagKind::Name,
                Some(name.into()),
                loc,
                "a port cannot be renamed".into(),
            );
            return self;
        }
        let mut g = self.m.graph_mut();
        let n = &mut g.nodes[self.id as usize];
        n.name = Some(name.to_string());
        n.base = name.to_string();
        self
    }

    fn base(&self) -> String {
        self.m.graph().node(self.id).base.clone()
    }

    fn op(&self) -> Op {
        self.m.graph().node(self.id).op.clone()
    }

    fn derive(
        self,
        op: Op,
        width: u32,
        opname: &'static str,
        signed: bool,
        loc: Loc,
    ) -> Signal<'m> {
        // Name derived temporaries after the first operand that is not a constant.
        let g = self.m.graph();
        let base = match &op {
            Op::Bin(_, a, b) | Op::Cmp(_, _, a, b) => {
                let pick = |x: NodeId| match g.node(x).op {
                    Op::Const(_) => None,
                    Op::Ext(inner, _) => Some(g.node(inner).base.clone()),
                    _ => Some(g.node(x).base.clone()),
                };
                pick(*a)
                    .or_else(|| pick(*b))
                    .unwrap_or_else(|| g.node(self.id).base.clone())
            }
            _ => g.node(self.id).base.clone(),
        };
        drop(g);
        let id = self.m.add_node(op, width, &base, opname, loc);
        Signal {
            m: self.m,
            id,
            signed,
        }
    }

    fn fail(self, kind: DiagKind, loc: Loc, msg: String, width: u32) -> Signal<'m> {
        let what = self.m.graph().describe(self.id);
        self.m.fail(kind, Some(what), loc, msg, width)
    }

    /// Drives a wire or output port with `value` (same width); a wire takes exactly one driver.
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let w = m.wire("w", 4);
    /// w.drive(5);
    /// m.output("y", w);
    /// # assert!(m.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn drive(self, value: impl IntoSignal<'m>) {
        self.drive_at(value, Location::caller());
    }

    pub(crate) fn drive_at(self, value: impl IntoSignal<'m>, loc: Loc) {
        let v = value.into_signal_like(self, loc);
        let problem = match self.op() {
            Op::Wire { .. } => None,
            Op::Input => Some("an input is driven from outside the module"),
            Op::Reg { .. } => Some("a register takes its next value with .next(), not .drive()"),
            _ => {
                Some("only wires and output ports can be driven; this is the result of an operator")
            }
        };
        if let Some(why) = problem {
            self.fail(DiagKind::Misuse, loc, format!("cannot drive: {why}"), 1);
            return;
        }
        if v.width() != self.width() {
            self.fail(
                DiagKind::Width,
                loc,
                format!(
                    "driven with {} bits, declared {} bits",
                    v.width(),
                    self.width()
                ),
                1,
            );
            return;
        }
        if let Op::Wire { drivers } = &mut self.m.graph_mut().nodes[self.id as usize].op {
            drivers.push((v.id, loc));
        }
    }

    /// Sets a register's next value (same width), loaded at each rising clock
    /// edge unless reset is high. A register takes exactly one `next`.
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let en = m.input("en", 1);
    /// let r = m.reg("r", 4);
    /// r.next(en.mux(r.add(1, 4), r));
    /// # m.output("y", r);
    /// # assert!(m.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn next(self, value: impl IntoSignal<'m>) {
        self.next_at(value, Location::caller());
    }

    fn next_at(self, value: impl IntoSignal<'m>, loc: Loc) {
        let v = value.into_signal_like(self, loc);
        if !matches!(self.op(), Op::Reg { .. }) {
            self.fail(
                DiagKind::Misuse,
                loc,
                "only a register has a next value (use .drive() for wires)".into(),
                1,
            );
            return;
        }
        if v.width() != self.width() {
            self.fail(
                DiagKind::Width,
                loc,
                format!(
                    "next value is {} bits, the register {} bits",
                    v.width(),
                    self.width()
                ),
                1,
            );
            return;
        }
        let mut g = self.m.graph_mut();
        let reg_name = g.node(self.id).base.clone();
        // An unnamed operator result feeding a register is called `<reg>_next`.
        let vn = &mut g.nodes[v.id as usize];
        if vn.name.is_none()
            && vn.port.is_none()
            && !matches!(vn.op, Op::Const(_) | Op::Slice(..) | Op::Ext(..))
        {
            vn.base = reg_name;
            vn.opname = "next";
        }
        if let Op::Reg { next, .. } = &mut g.nodes[self.id as usize].op {
            next.push((v.id, loc));
        }
    }

    /// `next(cond ? value : self)`: load `value` only when `cond` is high.
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let (en, d) = (m.input("en", 1), m.input("d", 8));
    /// let q = m.reg("q", 8);
    /// q.next_when(en, d);
    /// # m.output("y", q);
    /// # assert!(m.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn next_when(self, cond: Signal<'m>, value: impl IntoSignal<'m>) {
        let loc = Location::caller();
        let v = value.into_signal_like(self, loc);
        let n = cond.mux_at(v, self, loc);
        self.next_at(n, loc);
    }

    /// Extension to `width` bits by this handle's signedness (sign or zero).
    #[track_caller]
    pub fn ext(self, width: u32) -> Signal<'m> {
        self.ext_at(width, self.signed, Location::caller())
    }

    /// Zero extension to `width` bits (result unsigned).
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// assert_eq!(m.input("a", 8).zext(12).width(), 12);
    /// ```
    #[track_caller]
    pub fn zext(self, width: u32) -> Signal<'m> {
        self.ext_at(width, false, Location::caller()).as_unsigned()
    }

    /// Sign extension to `width` bits (result signed).
    ///
    /// ```
    /// # use rtl_gen::{Module, Sim};
    /// let m = Module::new("m");
    /// m.output("y", m.input("a", 4).sext(8));
    /// let mut sim = Sim::new(&m).unwrap();
    /// sim.poke("a", 0b1010u64).unwrap();
    /// assert_eq!(sim.peek("y").unwrap().to_u64(), Some(0b1111_1010));
    /// ```
    #[track_caller]
    pub fn sext(self, width: u32) -> Signal<'m> {
        self.ext_at(width, true, Location::caller()).as_signed()
    }

    pub(crate) fn ext_at(self, width: u32, signed: bool, loc: Loc) -> Signal<'m> {
        let w = self.width();
        if width > crate::MAX_WIDTH {
            return self.fail(
                DiagKind::Width,
                loc,
                format!("cannot extend to {width} bits (above {})", crate::MAX_WIDTH),
                1,
            );
        }
        if width < w {
            return self.fail(
                DiagKind::Width,
                loc,
                format!("cannot extend {w} bits to {width}; use .slice() to narrow"),
                width.max(1),
            );
        }
        if width == w {
            return Signal { signed, ..self };
        }
        match self.op() {
            Op::Const(b) => {
                let e = b.extend(width, signed).unwrap_or_else(|| Bits::zero(width));
                self.m.constant(e, signed, loc)
            }
            // Extending an extension of the same kind extends the original.
            Op::Ext(inner, s) if s == signed => {
                Signal { id: inner, ..self }.ext_at(width, signed, loc)
            }
            _ => self.derive(
                Op::Ext(self.id, signed),
                width,
                if signed { "sext" } else { "zext" },
                signed,
                loc,
            ),
        }
    }

    /// Bits `hi` down to `lo` inclusive, as in Verilog `x[hi:lo]` (result unsigned).
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let a = m.input("a", 16);
    /// assert_eq!(a.slice(11, 4).width(), 8);
    /// ```
    #[track_caller]
    pub fn slice(self, hi: u32, lo: u32) -> Signal<'m> {
        self.slice_at(hi, lo, Location::caller())
    }

    /// This signal named `<source>_<role>`, after the signal it describes
    /// (what `.name()` does when the source's name is made elsewhere, as in
    /// a helper called for several sources).
    ///
    /// ```
    /// # use rtl_gen::{emit_verilog, Module};
    /// let m = Module::new("m");
    /// let lod = m.input("lod", 4);
    /// let deep = lod.gt(9).named_after(lod, "deep");
    /// m.output("y", deep & m.input("a", 1));
    /// m.output("z", deep);
    /// assert!(emit_verilog(&m).unwrap().contains("wire lod_deep;"));
    /// ```
    #[track_caller]
    pub fn named_after(self, source: Signal<'m>, role: &str) -> Signal<'m> {
        let name = format!("{}_{role}", source.base());
        self.name_unscoped(&name, Location::caller())
    }

    /// Bits `hi` down to `lo` as field `field` of this record: where
    /// anything reads them, the Verilog declares them once, as a wire named
    /// `<record>_<field>` (a layout's field read by name instead of as a
    /// raw part-select).
    ///
    /// ```
    /// # use rtl_gen::{emit_verilog, Module};
    /// let m = Module::new("m");
    /// let rec = m.input("rec", 8);
    /// m.output("y", rec.field_view(6, 4, "lod").add(1, 3));
    /// let v = emit_verilog(&m).unwrap();
    /// assert!(v.contains("assign rec_lod = rec[6:4];"), "{v}");
    /// ```
    #[track_caller]
    pub fn field_view(self, hi: u32, lo: u32, field: &str) -> Signal<'m> {
        let s = self.slice_at(hi, lo, Location::caller());
        let base = format!("{}_{field}", self.base());
        let mut g = self.m.graph_mut();
        let n = &mut g.nodes[s.id as usize];
        if s.id != self.id && n.name.is_none() && matches!(n.op, Op::Slice(..)) {
            n.base = base;
            n.opname = crate::graph::FIELD_VIEW;
        }
        drop(g);
        s
    }

    pub(crate) fn slice_at(self, hi: u32, lo: u32, loc: Loc) -> Signal<'m> {
        let w = self.width();
        if hi < lo || hi >= w {
            return self.fail(
                DiagKind::Misuse,
                loc,
                format!("slice [{hi}:{lo}] is out of range for a {w}-bit signal"),
                hi.saturating_sub(lo).saturating_add(1).min(1 << 20),
            );
        }
        let width = hi - lo + 1;
        if width == w {
            return self.as_unsigned();
        }
        match self.op() {
            Op::Const(b) => {
                let s = b.extract(lo, width).unwrap_or_else(|_| Bits::zero(width));
                self.m.constant(s, false, loc)
            }
            Op::Slice(inner, inner_lo) => {
                let id = self.m.add_node(
                    Op::Slice(inner, inner_lo + lo),
                    width,
                    &self.base(),
                    "slice",
                    loc,
                );
                Signal {
                    m: self.m,
                    id,
                    signed: false,
                }
            }
            _ => self.derive(Op::Slice(self.id, lo), width, "slice", false, loc),
        }
    }

    /// Bit `i` (one bit, unsigned).
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let a = m.input("a", 8);
    /// m.output("odd", a.bit(0));
    /// m.output("top", a.slice(7, 1).msb());
    /// # m.output("mid", a.slice(6, 1));
    /// # assert!(m.validate().unwrap().is_empty());
    /// ```
    #[track_caller]
    pub fn bit(self, i: u32) -> Signal<'m> {
        self.slice_at(i, i, Location::caller())
    }

    /// The most significant bit.
    #[track_caller]
    pub fn msb(self) -> Signal<'m> {
        let w = self.width();
        self.slice_at(w - 1, w - 1, Location::caller())
    }

    /// `{self, low}`: this signal in the high bits.
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let (hi, lo) = (m.input("hi", 3), m.input("lo", 5));
    /// assert_eq!(hi.concat(lo).width(), 8);
    /// ```
    #[track_caller]
    pub fn concat(self, low: Signal<'m>) -> Signal<'m> {
        let loc = Location::caller();
        if !self.m.owns(low, loc) {
            return self;
        }
        if self.width() as u64 + low.width() as u64 > crate::MAX_WIDTH as u64 {
            return self.fail(DiagKind::Width, loc, "concatenation too wide".into(), 1);
        }
        self.derive(
            Op::Concat(vec![self.id, low.id]),
            self.width() + low.width(),
            "cat",
            false,
            loc,
        )
    }

    /// `self + other` in exactly `width` bits (modulo `2^width`); each operand
    /// is first extended to `width` by its own signedness, and `width` must be
    /// at least both operand widths. Signed if either operand is.
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let a = m.input("a", 8);
    /// let b = m.input("b", 4);
    /// assert_eq!(a.add(b, 9).width(), 9);  // full sum with carry
    /// assert_eq!(a.add(1, 8).width(), 8);  // wrapping counter step
    /// ```
    #[track_caller]
    pub fn add(self, other: impl IntoSignal<'m>, width: u32) -> Signal<'m> {
        self.arith(BinOp::Add, other, width, Location::caller())
    }

    /// `self - other` in exactly `width` bits (modulo `2^width`), operands
    /// extended as for [`Signal::add`].
    ///
    /// ```
    /// # use rtl_gen::{Module, Sim};
    /// let m = Module::new("m");
    /// let (a, b) = (m.input("a", 8).as_signed(), m.input("b", 8).as_signed());
    /// m.output("d", a.sub(b, 9)); // never overflows
    /// let mut sim = Sim::new(&m).unwrap();
    /// sim.poke("a", -128i64).unwrap();
    /// sim.poke("b", 127i64).unwrap();
    /// assert_eq!(sim.peek("d").unwrap().to_i128(), Some(-255));
    /// ```
    #[track_caller]
    pub fn sub(self, other: impl IntoSignal<'m>, width: u32) -> Signal<'m> {
        self.arith(BinOp::Sub, other, width, Location::caller())
    }

    fn arith(self, op: BinOp, other: impl IntoSignal<'m>, width: u32, loc: Loc) -> Signal<'m> {
        let b = other.into_signal_like(self, loc);
        let (wa, wb) = (self.width(), b.width());
        if width > crate::MAX_WIDTH {
            return self.fail(
                DiagKind::Width,
                loc,
                format!("result width {width} is above {}", crate::MAX_WIDTH),
                1,
            );
        }
        if width == 0 || width < wa.max(wb) {
            return self.fail(
                DiagKind::Width,
                loc,
                format!("result width {width} is narrower than the operands ({wa} and {wb} bits); slice the operands first"),
                width.max(1),
            );
        }
        let x = self.ext_at(width, self.signed, loc);
        let y = b.ext_at(width, b.signed, loc);
        let name = if op == BinOp::Add { "add" } else { "sub" };
        self.derive(
            Op::Bin(op, x.id, y.id),
            width,
            name,
            self.signed || b.signed,
            loc,
        )
    }

    fn bitwise(self, op: BinOp, other: impl IntoSignal<'m>, loc: Loc) -> Signal<'m> {
        let b = other.into_signal_like(self, loc);
        if b.width() != self.width() {
            return self.fail(
                DiagKind::Width,
                loc,
                format!(
                    "bitwise operands differ in width: {} and {} bits; extend or slice one",
                    self.width(),
                    b.width()
                ),
                self.width(),
            );
        }
        let name = match op {
            BinOp::And => "and",
            BinOp::Or => "or",
            _ => "xor",
        };
        self.derive(
            Op::Bin(op, self.id, b.id),
            self.width(),
            name,
            self.signed && b.signed,
            loc,
        )
    }

    /// Bitwise and (same as `&`).
    #[track_caller]
    pub fn and(self, other: impl IntoSignal<'m>) -> Signal<'m> {
        self.bitwise(BinOp::And, other, Location::caller())
    }

    /// Bitwise or (same as `|`).
    #[track_caller]
    pub fn or(self, other: impl IntoSignal<'m>) -> Signal<'m> {
        self.bitwise(BinOp::Or, other, Location::caller())
    }

    /// Bitwise exclusive or (same as `^`).
    #[track_caller]
    pub fn xor(self, other: impl IntoSignal<'m>) -> Signal<'m> {
        self.bitwise(BinOp::Xor, other, Location::caller())
    }

    fn shift(self, kind: ShiftKind, amount: impl ShiftAmount<'m>, loc: Loc) -> Signal<'m> {
        let Some(a) = shift_amount(amount.shift_by(), self.m, loc) else {
            return self.m.poison(self.width(), loc);
        };
        if a == Amount::Const(0) {
            return self;
        }
        let name = match kind {
            ShiftKind::Left => "shl",
            ShiftKind::RightLogical => "shr",
            ShiftKind::RightArith => "sra",
        };
        self.derive(
            Op::Shift(kind, self.id, a),
            self.width(),
            name,
            self.signed,
            loc,
        )
    }

    /// Logical shift right regardless of signedness. Shifts are written
    /// with the operators: `a << k` and `a >> k` (arithmetic when `a` is
    /// signed, logical otherwise), by a constant `u32` or an unsigned signal;
    /// the result keeps `a`'s width, and shifting by the width or more gives
    /// zero (or all sign bits).
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let a = m.input("a", 8);
    /// let s = m.input("s", 3);
    /// m.output("shl", (a << s) ^ (a << 1));
    /// m.output("sra", a.as_signed() >> 2);   // arithmetic
    /// m.output("srl", a.as_signed().srl(2)); // logical
    /// # assert!(m.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn srl(self, amount: impl ShiftAmount<'m>) -> Signal<'m> {
        self.shift(ShiftKind::RightLogical, amount, Location::caller())
    }

    /// Arithmetic shift right regardless of signedness (result signed).
    #[track_caller]
    pub fn sra(self, amount: impl ShiftAmount<'m>) -> Signal<'m> {
        self.shift(ShiftKind::RightArith, amount, Location::caller())
            .as_signed()
    }

    fn compare(self, op: CmpOp, other: impl IntoSignal<'m>, loc: Loc) -> Signal<'m> {
        let b = other.into_signal_like(self, loc);
        let (wa, wb) = (self.width(), b.width());
        // Compare the mathematical values: mixed signedness needs one more bit
        // so the unsigned operand stays non-negative.
        let (width, signed) = match (self.signed, b.signed) {
            (false, false) => (wa.max(wb), false),
            (true, true) => (wa.max(wb), true),
            _ => (wa.max(wb) + 1, true),
        };
        let x = self.ext_at(width, self.signed, loc);
        let y = b.ext_at(width, b.signed, loc);
        let name = match op {
            CmpOp::Eq => "eq",
            CmpOp::Ne => "ne",
            CmpOp::Lt => "lt",
            CmpOp::Le => "le",
            CmpOp::Gt => "gt",
            CmpOp::Ge => "ge",
        };
        self.derive(Op::Cmp(op, signed, x.id, y.id), 1, name, false, loc)
    }

    /// `self == other` (one bit). Operands of different widths or signedness
    /// are compared as the numbers they represent.
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let a = m.input("a", 8);
    /// m.output("is_five", a.eq(5));
    /// # assert!(m.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn eq(self, other: impl IntoSignal<'m>) -> Signal<'m> {
        self.compare(CmpOp::Eq, other, Location::caller())
    }

    /// `self != other` (one bit).
    #[track_caller]
    pub fn ne(self, other: impl IntoSignal<'m>) -> Signal<'m> {
        self.compare(CmpOp::Ne, other, Location::caller())
    }

    /// `self < other` (one bit), signed when both handles are signed.
    ///
    /// ```
    /// # use rtl_gen::{Module, Sim};
    /// let m = Module::new("m");
    /// let (a, b) = (m.input("a", 8), m.input("b", 8));
    /// m.output("u", a.lt(b));                         // unsigned
    /// m.output("s", a.as_signed().lt(b.as_signed())); // signed
    /// m.output("x", a.as_signed().lt(b));             // mixed: exact
    /// let mut sim = Sim::new(&m).unwrap();
    /// sim.poke("a", 0xffu64).unwrap(); // 255 or -1
    /// sim.poke("b", 1u64).unwrap();
    /// assert_eq!(sim.peek("u").unwrap().to_u64(), Some(0));
    /// assert_eq!(sim.peek("s").unwrap().to_u64(), Some(1));
    /// assert_eq!(sim.peek("x").unwrap().to_u64(), Some(1));
    /// ```
    #[track_caller]
    pub fn lt(self, other: impl IntoSignal<'m>) -> Signal<'m> {
        self.compare(CmpOp::Lt, other, Location::caller())
    }

    /// `self <= other` (one bit).
    #[track_caller]
    pub fn le(self, other: impl IntoSignal<'m>) -> Signal<'m> {
        self.compare(CmpOp::Le, other, Location::caller())
    }

    /// `self > other` (one bit).
    #[track_caller]
    pub fn gt(self, other: impl IntoSignal<'m>) -> Signal<'m> {
        self.compare(CmpOp::Gt, other, Location::caller())
    }

    /// `self >= other` (one bit).
    #[track_caller]
    pub fn ge(self, other: impl IntoSignal<'m>) -> Signal<'m> {
        self.compare(CmpOp::Ge, other, Location::caller())
    }

    /// `self ? then_ : else_` where `self` is one bit and both arms have the same width.
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let (s, a) = (m.input("s", 1), m.input("a", 8));
    /// m.output("y", s.mux(a, 0));
    /// # assert!(m.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn mux(self, then_: Signal<'m>, else_: impl IntoSignal<'m>) -> Signal<'m> {
        self.mux_at(then_, else_, Location::caller())
    }

    pub(crate) fn mux_at(
        self,
        then_: Signal<'m>,
        else_: impl IntoSignal<'m>,
        loc: Loc,
    ) -> Signal<'m> {
        if !self.m.owns(then_, loc) {
            return then_;
        }
        let e = else_.into_signal_like(then_, loc);
        if self.width() != 1 {
            return self.fail(
                DiagKind::Width,
                loc,
                format!("mux select must be 1 bit, is {}", self.width()),
                then_.width(),
            );
        }
        if e.width() != then_.width() {
            return self.fail(
                DiagKind::Width,
                loc,
                format!(
                    "mux arms differ in width: {} and {} bits",
                    then_.width(),
                    e.width()
                ),
                then_.width(),
            );
        }
        let op = Op::Mux {
            sel: self.id,
            then_: then_.id,
            else_: e.id,
        };
        self.derive(op, then_.width(), "mux", then_.signed && e.signed, loc)
    }

    /// `options[self]`: a multi-way mux indexed by this unsigned signal.
    /// There must be exactly `2^width` options, all of one width (so every
    /// index selects something); built as a tree of 2-way muxes.
    ///
    /// ```
    /// # use rtl_gen::{Module, Sim};
    /// let m = Module::new("m");
    /// let idx = m.input("idx", 2);
    /// let opts = [m.lit(10, 8), m.lit(20, 8), m.lit(30, 8), m.input("d", 8)];
    /// m.output("y", idx.select(&opts));
    /// let mut sim = Sim::new(&m).unwrap();
    /// sim.poke("idx", 2u64).unwrap();
    /// assert_eq!(sim.peek("y").unwrap().to_u64(), Some(30));
    /// ```
    #[track_caller]
    pub fn select(self, options: &[Signal<'m>]) -> Signal<'m> {
        let loc = Location::caller();
        let w = self.width();
        let width = options.first().map(|o| o.width()).unwrap_or(1);
        if w >= 32 || options.len() != 1usize << w {
            return self.fail(
                DiagKind::Width,
                loc,
                format!(
                    "a {w}-bit index needs {} options, got {}",
                    1u64 << w.min(63),
                    options.len()
                ),
                width,
            );
        }
        if let Some(o) = options.iter().find(|o| o.width() != width) {
            return self.fail(
                DiagKind::Width,
                loc,
                format!(
                    "select options differ in width: {width} and {} bits",
                    o.width()
                ),
                width,
            );
        }
        if options.iter().any(|o| !self.m.owns(*o, loc)) {
            return self.m.poison(width, loc);
        }
        self.select_tree(options, w, loc)
    }

    /// Bit `bits - 1` of the index picks the half; recurse on the low bits.
    fn select_tree(self, options: &[Signal<'m>], bits: u32, loc: Loc) -> Signal<'m> {
        if bits == 0 {
            return options[0];
        }
        let half = options.len() / 2;
        let low = self.select_tree(&options[..half], bits - 1, loc);
        let high = self.select_tree(&options[half..], bits - 1, loc);
        self.slice_at(bits - 1, bits - 1, loc)
            .mux_at(high, low, loc)
    }

    fn reduce(self, op: RedOp, name: &'static str, loc: Loc) -> Signal<'m> {
        self.derive(Op::Reduce(op, self.id), 1, name, false, loc)
    }

    /// One bit: all bits are one (`&x`).
    #[track_caller]
    pub fn reduce_and(self) -> Signal<'m> {
        self.reduce(RedOp::And, "all", Location::caller())
    }

    /// One bit: some bit is one (`|x`).
    ///
    /// ```
    /// # use rtl_gen::Module;
    /// let m = Module::new("m");
    /// let a = m.input("a", 8);
    /// m.output("any", a.reduce_or());
    /// m.output("parity", a.reduce_xor());
    /// m.output("all", a.reduce_and());
    /// # assert!(m.validate().is_ok());
    /// ```
    #[track_caller]
    pub fn reduce_or(self) -> Signal<'m> {
        self.reduce(RedOp::Or, "any", Location::caller())
    }

    /// One bit: odd number of ones (`^x`).
    #[track_caller]
    pub fn reduce_xor(self) -> Signal<'m> {
        self.reduce(RedOp::Xor, "parity", Location::caller())
    }
}

macro_rules! bit_operator {
    ($tr:ident, $f:ident, $op:expr) => {
        impl<'m, T: IntoSignal<'m>> std::ops::$tr<T> for Signal<'m> {
            type Output = Signal<'m>;
            #[track_caller]
            fn $f(self, rhs: T) -> Signal<'m> {
                self.bitwise($op, rhs, Location::caller())
            }
        }
    };
}
bit_operator!(BitAnd, bitand, BinOp::And);
bit_operator!(BitOr, bitor, BinOp::Or);
bit_operator!(BitXor, bitxor, BinOp::Xor);

impl<'m> std::ops::Not for Signal<'m> {
    type Output = Signal<'m>;
    #[track_caller]
    fn not(self) -> Signal<'m> {
        self.derive(
            Op::Not(self.id),
            self.width(),
            "not",
            self.signed,
            Location::caller(),
        )
    }
}

impl<'m, A: ShiftAmount<'m>> std::ops::Shl<A> for Signal<'m> {
    type Output = Signal<'m>;
    #[track_caller]
    fn shl(self, amount: A) -> Signal<'m> {
        self.shift(ShiftKind::Left, amount, Location::caller())
    }
}

impl<'m, A: ShiftAmount<'m>> std::ops::Shr<A> for Signal<'m> {
    type Output = Signal<'m>;
    #[track_caller]
    fn shr(self, amount: A) -> Signal<'m> {
        let kind = if self.signed {
            ShiftKind::RightArith
        } else {
            ShiftKind::RightLogical
        };
        self.shift(kind, amount, Location::caller())
    }
}
