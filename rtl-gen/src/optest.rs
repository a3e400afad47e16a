//! Operator test modules: one small module per operator, width and
//! signedness, for checking the IR simulator, Verilator and Icarus Verilog
//! against each other bit for bit.
//!
//! Every module has inputs `a` (and `b`, `c`, `s` or `sel` when the operator
//! needs them) and output `y` (and `y2` for [`OpKind::Slice`]); a
//! registered variant puts a register between the operator and `y`.

use crate::{Module, Signal};

/// The widths the operator suite runs at.
pub const WIDTHS: [u32; 13] = [1, 7, 8, 31, 32, 33, 63, 64, 65, 127, 128, 129, 300];

/// One operator under test.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum OpKind {
    /// `y = a + b` in `w + 1` bits.
    Add,
    /// `y = a + b` in `w` bits (wrapping).
    AddWrap,
    /// `y = a + c` in `w + 2` bits where `c` has `w/2 + 1` bits (extension).
    AddExt,
    /// `y = a - b` in `w + 1` bits.
    Sub,
    /// `y = a - b` in `w` bits (wrapping).
    SubWrap,
    /// `y = a & b`.
    And,
    /// `y = a | b`.
    Or,
    /// `y = a ^ b`.
    Xor,
    /// `y = ~a`.
    Not,
    /// `y = a << (w / 3)`.
    ShlConst,
    /// `y = a >> (w / 3)`, arithmetic when signed.
    ShrConst,
    /// `y = a << s`, `s` wide enough to shift by more than the width.
    ShlVar,
    /// `y = a >> s`, arithmetic when signed.
    ShrVar,
    /// `y = a == b`.
    Eq,
    /// `y = a != b`.
    Ne,
    /// `y = a < b`.
    Lt,
    /// `y = a <= b`.
    Le,
    /// `y = a > b`.
    Gt,
    /// `y = a >= b`.
    Ge,
    /// `y = a < b` with `a` signed and `b` unsigned, whatever the suite's signedness.
    LtMixed,
    /// `y = sel ? a : b`.
    Mux,
    /// `y = {a, b}`.
    Concat,
    /// `y = a[w-1:w/2]`, `y2 = a[w/2-1:0]` (for `w = 1`, `y = a`).
    Slice,
    /// `y = &a`.
    ReduceAnd,
    /// `y = |a`.
    ReduceOr,
    /// `y = ^a`.
    ReduceXor,
    /// `y = a` extended to `2w` bits (sign-extended when signed).
    Ext,
}

impl OpKind {
    /// Every operator.
    pub const ALL: [OpKind; 27] = [
        OpKind::Add,
        OpKind::AddWrap,
        OpKind::AddExt,
        OpKind::Sub,
        OpKind::SubWrap,
        OpKind::And,
        OpKind::Or,
        OpKind::Xor,
        OpKind::Not,
        OpKind::ShlConst,
        OpKind::ShrConst,
        OpKind::ShlVar,
        OpKind::ShrVar,
        OpKind::Eq,
        OpKind::Ne,
        OpKind::Lt,
        OpKind::Le,
        OpKind::Gt,
        OpKind::Ge,
        OpKind::LtMixed,
        OpKind::Mux,
        OpKind::Concat,
        OpKind::Slice,
        OpKind::ReduceAnd,
        OpKind::ReduceOr,
        OpKind::ReduceXor,
        OpKind::Ext,
    ];

    /// Lower-case name used in module names.
    pub fn name(self) -> &'static str {
        match self {
            OpKind::Add => "add",
            OpKind::AddWrap => "addwrap",
            OpKind::AddExt => "addext",
            OpKind::Sub => "sub",
            OpKind::SubWrap => "subwrap",
            OpKind::And => "and",
            OpKind::Or => "or",
            OpKind::Xor => "xor",
            OpKind::Not => "not",
            OpKind::ShlConst => "shlk",
            OpKind::ShrConst => "shrk",
            OpKind::ShlVar => "shlv",
            OpKind::ShrVar => "shrv",
            OpKind::Eq => "eq",
            OpKind::Ne => "ne",
            OpKind::Lt => "lt",
            OpKind::Le => "le",
            OpKind::Gt => "gt",
            OpKind::Ge => "ge",
            OpKind::LtMixed => "ltmixed",
            OpKind::Mux => "mux",
            OpKind::Concat => "concat",
            OpKind::Slice => "slice",
            OpKind::ReduceAnd => "rand",
            OpKind::ReduceOr => "ror",
            OpKind::ReduceXor => "rxor",
            OpKind::Ext => "ext",
        }
    }

    /// Width of the shift-amount input `s` for a `width`-bit operand: enough
    /// bits to shift by up to twice the width, so over-shifts are exercised.
    pub fn shift_amount_width(width: u32) -> u32 {
        32 - (2 * width).leading_zeros()
    }

    /// Width of the `c` input of [`OpKind::AddExt`].
    pub fn narrow_width(width: u32) -> u32 {
        width / 2 + 1
    }

    /// The constant shift of [`OpKind::ShlConst`] / [`OpKind::ShrConst`].
    pub fn const_shift(width: u32) -> u32 {
        width / 3
    }
}

/// Module name of an operator test module, e.g. `op_add_w33_s_reg`.
pub fn op_module_name(op: OpKind, width: u32, signed: bool, registered: bool) -> String {
    format!(
        "op_{}_w{width}_{}{}",
        op.name(),
        if signed { "s" } else { "u" },
        if registered { "_reg" } else { "" }
    )
}

/// A module computing `op` on `width`-bit operands, read as signed when
/// `signed`; `registered` adds a reset-to-zero register before each output.
///
/// ```
/// use rtl_gen::optest::{op_test_module, OpKind};
/// use rtl_gen::Sim;
/// let m = op_test_module(OpKind::Add, 8, false, false);
/// let mut sim = Sim::new(&m).unwrap();
/// sim.poke("a", 200u64).unwrap();
/// sim.poke("b", 100u64).unwrap();
/// assert_eq!(sim.peek("y").unwrap().to_u64(), Some(300));
/// ```
pub fn op_test_module(op: OpKind, width: u32, signed: bool, registered: bool) -> Module {
    let m = Module::new(&op_module_name(op, width, signed, registered));
    build(&m, op, width, signed, registered);
    m
}

fn build<'m>(m: &'m Module, op: OpKind, w: u32, signed: bool, registered: bool) {
    let sg = |x: Signal<'m>| if signed { x.as_signed() } else { x };
    let a = || sg(m.input("a", w));
    let ab = || (sg(m.input("a", w)), sg(m.input("b", w)));
    let out = |name: &str, y: Signal<'m>| {
        if registered {
            let r = m.reg(&format!("{name}_q"), y.width());
            r.next(y);
            m.output(name, r);
        } else {
            m.output(name, y);
        }
    };
    match op {
        OpKind::Add => {
            let (a, b) = ab();
            out("y", a.add(b, w + 1));
        }
        OpKind::AddWrap => {
            let (a, b) = ab();
            out("y", a.add(b, w));
        }
        OpKind::AddExt => {
            let a = a();
            let c = sg(m.input("c", OpKind::narrow_width(w)));
            out("y", a.add(c, w + 2));
        }
        OpKind::Sub => {
            let (a, b) = ab();
            out("y", a.sub(b, w + 1));
        }
        OpKind::SubWrap => {
            let (a, b) = ab();
            out("y", a.sub(b, w));
        }
        OpKind::And => {
            let (a, b) = ab();
            out("y", a & b);
        }
        OpKind::Or => {
            let (a, b) = ab();
            out("y", a | b);
        }
        OpKind::Xor => {
            let (a, b) = ab();
            out("y", a ^ b);
        }
        OpKind::Not => out("y", !a()),
        OpKind::ShlConst => out("y", a() << OpKind::const_shift(w)),
        OpKind::ShrConst => out("y", a() >> OpKind::const_shift(w)),
        OpKind::ShlVar => {
            let a = a();
            out("y", a << m.input("s", OpKind::shift_amount_width(w)));
        }
        OpKind::ShrVar => {
            let a = a();
            out("y", a >> m.input("s", OpKind::shift_amount_width(w)));
        }
        OpKind::Eq => {
            let (a, b) = ab();
            out("y", a.eq(b));
        }
        OpKind::Ne => {
            let (a, b) = ab();
            out("y", a.ne(b));
        }
        OpKind::Lt => {
            let (a, b) = ab();
            out("y", a.lt(b));
        }
        OpKind::Le => {
            let (a, b) = ab();
            out("y", a.le(b));
        }
        OpKind::Gt => {
            let (a, b) = ab();
            out("y", a.gt(b));
        }
        OpKind::Ge => {
            let (a, b) = ab();
            out("y", a.ge(b));
        }
        OpKind::LtMixed => {
            let (a, b) = (m.input("a", w).as_signed(), m.input("b", w));
            out("y", a.lt(b));
        }
        OpKind::Mux => {
            let (a, b) = ab();
            let sel = m.input("sel", 1);
            out("y", sel.mux(a, b));
        }
        OpKind::Concat => {
            let (a, b) = ab();
            out("y", a.concat(b));
        }
        OpKind::Slice => {
            let a = a();
            if w == 1 {
                out("y", a);
            } else {
                out("y", a.slice(w - 1, w / 2));
                out("y2", a.slice(w / 2 - 1, 0));
            }
        }
        OpKind::ReduceAnd => out("y", a().reduce_and()),
        OpKind::ReduceOr => out("y", a().reduce_or()),
        OpKind::ReduceXor => out("y", a().reduce_xor()),
        OpKind::Ext => out("y", a().ext(2 * w)),
    }
}

/// One top module `op_suite_w<width>_<s|u>[_reg]` instantiating the test
/// module of every operator, with ports `<op>_<port>`; lint and synthesize
/// it to check every operator module at once.
pub fn op_suite(width: u32, signed: bool, registered: bool) -> Module {
    let children: Vec<Module> = OpKind::ALL
        .iter()
        .map(|&op| op_test_module(op, width, signed, registered))
        .collect();
    let top = Module::new(&format!(
        "op_suite_w{width}_{}{}",
        if signed { "s" } else { "u" },
        if registered { "_reg" } else { "" }
    ));
    for (op, child) in OpKind::ALL.iter().zip(&children) {
        let u = top.instance(&format!("u_{}", op.name()), child);
        for p in child.ports() {
            if p.name == crate::CLOCK || p.name == crate::RESET {
                continue;
            }
            let name = format!("{}_{}", op.name(), p.name);
            match p.direction {
                crate::Direction::Input => u.connect(&p.name, top.input(&name, p.width)),
                crate::Direction::Output => {
                    top.output(&name, u.output(&p.name));
                }
            }
        }
    }
    top
}
