//! The fetcher's building blocks: its FIFO, prioritized register
//! updates, the node check and move (section 7.6) and the beats it packs.

use golden::merge::fetcher::{fetch_err, FetchLayout};
use golden::merge::merge_level::unit::BeatLayout;
use golden::params::{bits_to_hold, Params};

use super::super::fields::{coords, field, with_fields};
use crate::{Module, Signal, Stream};

/// A FIFO of `depth` (a power of two) words, in-order: `input.ready` is
/// driven here (space left), the returned stream's `ready` by its consumer.
/// A word pushed is readable from the next clock; push and pop may share a
/// clock, so a depth of 2 runs one word a clock.
pub(super) fn fifo<'m>(m: &'m Module, name: &str, input: Stream<'m>, depth: u32) -> Stream<'m> {
    let aw = depth.trailing_zeros();
    let cb = bits_to_hold(depth as u64);
    let mem = m.memory(name, input.data.width(), depth);
    let head = m.reg(&format!("{name}_head"), aw.max(1));
    let tail = m.reg(&format!("{name}_tail"), aw.max(1));
    let count = m.reg(&format!("{name}_count"), cb);
    let out = Stream::wires(m, &format!("{name}_out"), input.data.width());
    input.ready.drive(count.ne(m.lit(depth as u128, cb)));
    let nonempty = count.ne(0);
    out.valid.drive(nonempty);
    // Zero when empty: an unwritten word is X in 4-state simulators.
    out.data.drive(nonempty.mux(
        mem.read(head.slice(aw.max(1) - 1, 0)),
        m.lit(0, input.data.width()),
    ));
    let push = input.fire();
    let pop = out.fire();
    mem.write(tail, input.data, push);
    let step = |r: Signal<'m>| {
        if aw == 0 {
            r
        } else {
            r.add(1, aw)
        }
    };
    head.next(pop.mux(step(head), head));
    tail.next(push.mux(step(tail), tail));
    count.next(push.mux(
        pop.mux(count, count.add(1, cb)),
        pop.mux(count.sub(1, cb), count),
    ));
    out
}

/// Prioritized register updates: the first arm whose condition holds sets
/// the next value; none holding keeps the register.
pub(super) struct Next<'m> {
    reg: Signal<'m>,
    arms: Vec<(Signal<'m>, Signal<'m>)>,
}

impl<'m> Next<'m> {
    pub(super) fn new(reg: Signal<'m>) -> Next<'m> {
        Next {
            reg,
            arms: Vec::new(),
        }
    }

    pub(super) fn when(&mut self, cond: Signal<'m>, value: Signal<'m>) {
        self.arms.push((cond, value));
    }

    pub(super) fn apply(self) {
        let mut v = self.reg;
        for (c, val) in self.arms.into_iter().rev() {
            v = c.mux(val, v);
        }
        self.reg.next(v);
    }
}

/// What reading a node record finds: the first failing check's code (0
/// none) in `golden::merge::fetcher`'s order, LOD, record, translation
/// level, then the moved coordinate on x, y, z; and the moved record.
pub(super) struct Checked<'m> {
    pub(super) code: Signal<'m>,
    pub(super) moved: Signal<'m>,
}

/// The translation the `cfg` beat carried.
pub(super) struct Move<'m> {
    pub(super) lod: Signal<'m>,
    pub(super) t: [Signal<'m>; 3],
}

/// Checks record `rec` (expected at LOD `want`) and moves it by `mv`
/// (section 7.6: `x' = x + (t << (d - L))` in `2D + 2`-bit two's complement,
/// outside when negative or `x' >> d != 0`).
pub(super) fn check_and_move<'m>(
    m: &'m Module,
    p: &Params,
    l: &FetchLayout,
    rec: Signal<'m>,
    want: Signal<'m>,
    mv: &Move<'m>,
) -> Checked<'m> {
    let nl = &l.node;
    let lb = p.lod_bits();
    let dmax = p.max_lod as u32;
    let lod = field(rec, nl.lod()).expect("lod");
    let coords = coords(rec, nl);
    let mut bad = coords
        .iter()
        .map(|c| c.srl(lod).ne(0))
        .reduce(|a, b| a | b)
        .expect("three axes");
    if (1u64 << lb) - 1 > dmax as u64 {
        bad = bad | lod.gt(m.lit(dmax as u128, lb));
    }
    for a in 0..3 {
        if let (Some(lo), Some(hi)) = (field(rec, nl.lo(a)), field(rec, nl.hi(a))) {
            bad = bad | lo.gt(hi);
        }
    }
    bad = bad | field(rec, nl.count()).expect("count").eq(0);
    let above = lod.lt(mv.lod);
    let shift = lod.sub(mv.lod, lb);
    let sum_bits = 2 * dmax + 2;
    let mut outside = Vec::new();
    let mut moved = Vec::new();
    for (c, t) in coords.iter().zip(&mv.t) {
        let offset = t.as_signed().sext(sum_bits) << shift;
        let sum = c.zext(sum_bits).add(offset.as_unsigned(), sum_bits);
        outside.push(sum.msb() | sum.srl(lod).ne(0));
        moved.push(sum.slice(dmax - 1, 0));
    }
    let code = |c: u64| m.lit(c as u128, fetch_err::BITS);
    let code = lod.ne(want).mux(
        code(fetch_err::LOD),
        bad.mux(
            code(fetch_err::RECORD),
            above.mux(
                code(fetch_err::ABOVE),
                outside[0].mux(
                    code(fetch_err::OUTSIDE_X),
                    outside[1].mux(
                        code(fetch_err::OUTSIDE_Y),
                        outside[2].mux(code(fetch_err::OUTSIDE_Z), code(fetch_err::NONE)),
                    ),
                ),
            ),
        ),
    );
    let moved = with_fields(
        m,
        rec,
        &[
            (*nl.x(), moved[0]),
            (*nl.y(), moved[1]),
            (*nl.z(), moved[2]),
        ],
    );
    Checked { code, moved }
}

/// A reference `(hier, node)` as the reference layout packs it (node low).
pub(super) fn reference<'m>(m: &'m Module, hier: Signal<'m>, node: Signal<'m>) -> Signal<'m> {
    m.concat(&[hier, node])
}

/// An S614 input beat with `err`, as the `out` stream carries it.
pub(super) fn out_beat<'m>(
    m: &'m Module,
    l: &FetchLayout,
    rec: Option<Signal<'m>>,
    reference: Option<Signal<'m>>,
    kind: Signal<'m>,
    err: Option<Signal<'m>>,
) -> Signal<'m> {
    let b: &BeatLayout = &l.beat;
    let mut f = vec![(b.kind, kind)];
    if let Some(r) = rec {
        f.push((b.rec, r));
    }
    if let Some(r) = reference {
        f.push((b.refer, r));
    }
    if let Some(e) = err {
        f.push((l.err, e));
    }
    with_fields(m, m.lit(0, l.out_width), &f)
}
