//! The fetcher's building blocks: prioritized register updates, the node
//! check and move (section 7.6) and the beats it packs.

use golden::merge::fetcher::{fetch_err, FetchLayout};
use golden::merge::merge_level::unit::BeatLayout;
use golden::params::Params;

use crate::{Module, Signal};

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
        let m = self.reg.module();
        self.reg.next(m.first_of(&self.arms, self.reg));
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
    let lod = rec.view(nl.lod());
    let coords = rec.coords(nl);
    let mut bad = coords
        .iter()
        .map(|c| c.srl(lod).ne(0))
        .reduce(|a, b| a | b)
        .expect("three axes");
    if (1u64 << lb) - 1 > dmax as u64 {
        bad = bad | lod.gt(m.lit(dmax as u128, lb));
    }
    for a in 0..3 {
        if let (Some(lo), Some(hi)) = (rec.view_opt(nl.lo(a)), rec.view_opt(nl.hi(a))) {
            bad = bad | lo.gt(hi);
        }
    }
    bad = bad | rec.view(nl.count()).eq(0);
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
    let code = m.first_of(
        &[
            (lod.ne(want), code(fetch_err::LOD)),
            (bad, code(fetch_err::RECORD)),
            (above, code(fetch_err::ABOVE)),
            (outside[0], code(fetch_err::OUTSIDE_X)),
            (outside[1], code(fetch_err::OUTSIDE_Y)),
            (outside[2], code(fetch_err::OUTSIDE_Z)),
        ],
        code(fetch_err::NONE),
    );
    let moved = rec.with_fields(&[
        (*nl.x(), moved[0]),
        (*nl.y(), moved[1]),
        (*nl.z(), moved[2]),
    ]);
    Checked { code, moved }
}

/// The check of a reference `(r_hier, r_node)` read from the store
/// (`fetch_err` order): another hierarchy than `hier`, a node not below
/// `nodes`, else 0.
pub(super) fn reference_code<'m>(
    m: &'m Module,
    r_node: Signal<'m>,
    r_hier: Signal<'m>,
    hier: Signal<'m>,
    nodes: Signal<'m>,
) -> Signal<'m> {
    let code = |c: u64| m.lit(c as u128, fetch_err::BITS);
    m.first_of(
        &[
            (r_hier.ne(hier), code(fetch_err::REF_HIER)),
            (r_node.ge(nodes), code(fetch_err::REF_NODE)),
        ],
        code(0),
    )
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
    m.lit(0, l.out.width()).with_fields(&f)
}
