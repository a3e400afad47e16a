//! Small designs used by the snapshot and tool tests (besides the examples).
#![allow(dead_code)]

use rtl_gen::{Bits, Module, Stream};

/// Every operator once, on 5-bit operands, combinational.
pub fn kitchen_sink() -> Module {
    let m = Module::new("kitchen_sink");
    let a = m.input("a", 5);
    let b = m.input("b", 5);
    let s = m.input("s", 3);
    let sel = m.input("sel", 1);
    let sum = a.add(b, 6).name("sum");
    let diff = a.as_signed().sub(b.as_signed(), 6).name("diff");
    m.output("sum", sum);
    m.output("diff", diff);
    m.output("bitwise", (a & b) | (!a ^ b));
    m.output(
        "shifts",
        m.concat(&[a << 2, a >> s, a.as_signed() >> s, a.as_signed() >> 1]),
    );
    m.output(
        "cmp",
        m.concat(&[
            a.eq(b),
            a.ne(b),
            a.lt(b),
            a.as_signed().le(b.as_signed()),
            a.gt(3),
            a.as_signed().ge(b),
        ]),
    );
    m.output("mux", sel.mux(a, b.slice(4, 0)));
    m.output("select", s.slice(1, 0).select(&[a, b, !b, a ^ b]));
    m.output(
        "red",
        m.concat(&[a.reduce_and(), a.reduce_or(), b.reduce_xor()]),
    );
    m.output("ext", m.concat(&[a.zext(7), b.sext(7)]));
    m
}

/// A RAM with two write ports, a synchronous and an asynchronous read port,
/// and a reset register beside it.
pub fn ram() -> Module {
    let m = Module::new("ram_sync");
    let mem = m.memory("mem", 12, 16);
    mem.write(m.input("wa", 4), m.input("wd", 12), m.input("we", 1));
    m.output("q", mem.read_sync(m.input("ra", 4), m.input("re", 1)));
    let wb = m.input("wb", 4);
    mem.write(wb, m.input("wd_b", 12), wb.ne(0));
    m.output("peek0", mem.read(0));
    let seen = m.reg_reset("writes", 8, Bits::from_u128(0x80, 8).expect("fits"));
    seen.next(seen.add(1, 8));
    m.output("writes", seen);
    m
}

/// A top with two instances of one child and a fixed-priority merge of two streams.
pub fn hierarchy() -> Module {
    let inc = Module::new("incrementer");
    let x = inc.input("x", 8);
    inc.output("y", x.add(1, 8));
    let top = Module::new("hier_top");
    let a = Stream::input(&top, "a", 8);
    let b = Stream::input(&top, "b", 8);
    let u0 = top.instance("u0", &inc);
    u0.connect("x", a.data);
    let u1 = top.instance("u1", &inc);
    u1.connect("x", b.data);
    let a2 = Stream {
        data: u0.output("y"),
        ..a
    };
    let b2 = Stream {
        data: u1.output("y"),
        ..b
    };
    Stream::merge_priority(&top, "arb", &[a2, b2])
        .pipeline_reg("out_q")
        .output("out");
    top
}

/// A 300-bit register pipeline with a wide constant.
pub fn wide() -> Module {
    let m = Module::new("wide300");
    let a = m.input("a", 300);
    let k = m.lit_bits(Bits::from_i128(-12345, 300).expect("fits"));
    let r = m.reg("acc", 300);
    r.next(r.add(a ^ k, 300));
    m.output("acc", r);
    m
}
