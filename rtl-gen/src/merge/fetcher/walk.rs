//! The walk's first stages: the walk state, the roots read into the
//! sorter, the frontier of ranges, the range stage (one `ref` read a clock)
//! and the reference stage (each answer checked, its `node` read issued).

use golden::layout::Layout;
use golden::merge::fetcher::fetch_err;
use golden::merge::merge_level::unit::{level_kind, BeatLayout};
use golden::params::bits_to_hold;

use super::command::{Command, FirstErr};
use super::parts::{check_and_move, reference, reference_code, Checked};
use super::root_sorter::root_sorter_unit;
use super::{nk, Ctx, Ports, IN_FLIGHT};
use crate::{Instance, Signal, Stream};

/// The walk's registers, reset by each command's START.
pub(super) struct WalkState<'m> {
    /// The level the visit stage is at.
    pub(super) level: Signal<'m>,
    pub(super) at_top: Signal<'m>,
    pub(super) done: Signal<'m>,
    /// The last node's Morton key on this level (for the order check).
    pub(super) prev_valid: Signal<'m>,
    pub(super) prev_key: Signal<'m>,
    /// Ranges pushed on this level (pass).
    pub(super) pushed: Signal<'m>,
    pub(super) visit_errored: Signal<'m>,
    pub(super) out_errored: Signal<'m>,
    /// Bits of a Morton key with its leaf bit.
    pub(super) key_bits: u32,
    /// The frontier's capacity in ranges, and the bits that count it.
    pub(super) fcap: u64,
    pub(super) cb: u32,
}

pub(super) fn walk_state<'m>(cx: &Ctx<'_, 'm>) -> WalkState<'m> {
    let m = cx.m;
    let key_bits = 3 * cx.p.coord_bits() + 1;
    let fcap = cx.sizes.frontier as u64;
    let cb = bits_to_hold(fcap);
    WalkState {
        level: m.reg("level", cx.lb),
        at_top: m.reg("at_top", 1),
        done: m.reg("walk_done", 1),
        prev_valid: m.reg("prev_valid", 1),
        prev_key: m.reg("prev_key", key_bits),
        pushed: m.reg("pushed", cb),
        visit_errored: m.reg("visit_errored", 1),
        out_errored: m.reg("out_errored", 1),
        key_bits,
        fcap,
        cb,
    }
}

/// The roots stage and the node answers' check: what the visit stage
/// takes from them.
pub(super) struct Roots<'m> {
    pub(super) sorter: Instance<'m>,
    pub(super) s_in_ready: Signal<'m>,
    pub(super) s_out_valid: Signal<'m>,
    pub(super) s_rec: Signal<'m>,
    pub(super) s_ref: Signal<'m>,
    pub(super) s_end: Signal<'m>,
    pub(super) s_err: Signal<'m>,
    /// Roots whose `node` read is issued.
    pub(super) issued: Signal<'m>,
    pub(super) req_valid: Signal<'m>,
    pub(super) outstanding: Signal<'m>,
    /// Every `node` answer checked and moved (a root's at the top LOD, a
    /// walked node's at the visit stage's level).
    pub(super) got: Checked<'m>,
    pub(super) got_code: Signal<'m>,
}

/// ROOTS: read `0..root_count`, one a clock, into the sorter.
pub(super) fn roots_stage<'m>(
    cx: &Ctx<'_, 'm>,
    c: &mut Command<'m>,
    e: &mut FirstErr<'m>,
    w: &WalkState<'m>,
    io: &Ports<'m>,
) -> Roots<'m> {
    let (m, p, l, ib) = (cx.m, cx.p, cx.l, cx.ib);
    let nl = &l.node;
    let bl = BeatLayout::input(p);
    let sorted = BeatLayout::output(p);
    let (start, roots_ph, roots) = (c.start, c.roots_ph, c.roots);
    let zero_i = cx.lit(0, ib);
    let sorter = m.instance("u_root_sorter", &root_sorter_unit(p, cx.sizes.roots.max(1)));
    let s_in_ready = sorter.output("in_ready");
    let s_out_valid = sorter.output("out_valid");
    let s_out_data = sorter.output("out_data");
    let s_rec = s_out_data.view(&sorted.rec).name("sorted_rec");
    let s_ref = s_out_data.view(&sorted.refer);
    let s_end = s_out_data
        .view(&sorted.kind)
        .eq(level_kind::END)
        .name("sorted_end");
    let s_err = s_out_data.view(&sorted.err.expect("output beats have err"));
    let issued = m.reg("roots_issued", ib);
    let taken = m.reg("roots_taken", ib);
    issued.next(start.mux(
        zero_i,
        (roots_ph & io.node_req.fire()).mux(issued.add(1, ib), issued),
    ));
    let root_req_v = (roots_ph & issued.ne(roots)).name("root_req_valid");
    let root_out = (roots_ph & issued.ne(taken)).name("root_outstanding");
    let all_taken = (roots_ph & taken.eq(roots)).name("roots_all_taken");

    let node_resp = io.node_resp;
    let got = check_and_move(m, p, l, node_resp.data, roots_ph.mux(c.top, w.level), &c.mv);
    let got_code = got.code.name("node_code");
    let root_take = (root_out & node_resp.valid & s_in_ready).name("root_take");
    taken.next(start.mux(zero_i, root_take.mux(taken.add(1, ib), taken)));
    let root_fail = (root_take & got_code.ne(0)).name("root_fail");
    e.n_valid.when(root_fail, cx.lit(1, 1));
    e.n_code.when(root_fail & !e.valid, got_code);
    e.n_node.when(root_fail & !e.valid, taken);
    let root_beat = m.lit(0, bl.width()).with_fields(&[
        (bl.rec, got.moved),
        (bl.refer, reference(m, c.hier, taken)),
        (
            bl.kind,
            node_resp.data.view(nl.leaf()).mux(
                cx.lit(level_kind::LEAF, bl.kind.width),
                cx.lit(level_kind::INNER, bl.kind.width),
            ),
        ),
    ]);
    let end_beat = m
        .lit(0, bl.width())
        .with_fields(&[(bl.kind, cx.lit(level_kind::END, bl.kind.width))]);
    sorter.connect(
        "in_valid",
        root_out & node_resp.valid & got_code.eq(0) | all_taken,
    );
    sorter.connect("in_data", all_taken.mux(end_beat, root_beat));
    let ready = c.roots_ready(cx);
    c.n_phase.when(all_taken & s_in_ready, ready);
    Roots {
        sorter,
        s_in_ready,
        s_out_valid,
        s_rec,
        s_ref,
        s_end,
        s_err,
        issued,
        req_valid: root_req_v,
        outstanding: root_out,
        got,
        got_code,
    }
}

/// The frontier: ranges (first, count, parent) and level markers.
pub(super) struct Frontier<'m> {
    pub(super) word: Layout,
    /// Its input, driven by the visit stage (and the per-node join).
    pub(super) push: Stream<'m>,
    pub(super) head: Stream<'m>,
}

pub(super) fn frontier<'m>(cx: &Ctx<'_, 'm>, w: &WalkState<'m>) -> Frontier<'m> {
    let ib = cx.ib;
    let f_words = (2 * w.fcap + 1).max(2).next_power_of_two() as u32;
    // A range of `count` references from `first`, read by inner node
    // `parent`, or (`marker`) a level's end.
    let word = Layout::packed(
        "frontier entry",
        &[("first", ib), ("count", ib), ("parent", ib), ("marker", 1)],
    );
    let push = Stream::wires(cx.m, "frontier_in", word.width());
    let head = push.fifo("frontier", f_words);
    Frontier { word, push, head }
}

/// The range stage: one `ref` read a clock over the frontier's head range;
/// returns the stream of its reads' contexts (the parent, or a level's end
/// marker) in issue order.
pub(super) fn range_stage<'m>(
    cx: &Ctx<'_, 'm>,
    c: &Command<'m>,
    f: &Frontier<'m>,
    io: &Ports<'m>,
) -> Stream<'m> {
    let (m, ib) = (cx.m, cx.ib);
    let _scope = m.scope("range");
    let (walk, start, front) = (c.walk, c.start, f.head);
    let fo_marker = front.data.view_named(&f.word, "marker");
    let fo_first = front.data.view_named(&f.word, "first");
    let fo_count = front.data.view_named(&f.word, "count");
    let fo_parent = front.data.view_named(&f.word, "parent");
    let cur_valid = m.reg("valid", 1);
    let cur_idx = m.reg("idx", ib);
    let cur_end = m.reg("end", ib + 1);
    let cur_parent = m.reg("parent", ib);
    let ctx1_in = Stream::wires(m, "ref_ctx_in", ib + 1);
    let ctx1 = ctx1_in.fifo("ref_ctx", IN_FLIGHT);
    io.ref_req.valid.drive(walk & cur_valid & ctx1_in.ready);
    io.ref_req.data.drive(cur_idx);
    let issue = io.ref_req.fire().name("issue");
    let idx_next = cur_idx.add(1, ib);
    let cur_last = idx_next.zext(ib + 1).eq(cur_end);
    let load = (walk & front.valid & !fo_marker & (!cur_valid | issue & cur_last)).name("load");
    let pop_marker =
        (walk & front.valid & fo_marker & !cur_valid & ctx1_in.ready).name("marker_pop");
    front.ready.drive(load | pop_marker);
    cur_valid.next(start.mux(
        cx.lit(0, 1),
        load.mux(
            cx.lit(1, 1),
            (issue & cur_last).mux(cx.lit(0, 1), cur_valid),
        ),
    ));
    cur_idx.next(load.mux(fo_first, issue.mux(idx_next, cur_idx)));
    cur_end.next_when(
        load,
        fo_first.zext(ib + 1).add(fo_count.zext(ib + 1), ib + 1),
    );
    cur_parent.next_when(load, fo_parent);
    ctx1_in.valid.drive(issue | pop_marker);
    ctx1_in
        .data
        .drive(m.concat(&[pop_marker, pop_marker.mux(cx.lit(0, ib), cur_parent)]));
    ctx1
}

/// The reference stage: checks each `ref` answer and issues its `node`
/// read (the roots stage's reads go first); returns the stream of the
/// visit stage's words (`nk` kind, error code, reference) and its width.
pub(super) fn reference_stage<'m>(
    cx: &Ctx<'_, 'm>,
    c: &Command<'m>,
    r: &Roots<'m>,
    ctx1: Stream<'m>,
    io: &Ports<'m>,
) -> (Stream<'m>, u32) {
    let (m, ib) = (cx.m, cx.ib);
    let _scope = m.scope("ref_stage");
    let rl = &cx.l.reference;
    let (walk, hier, ref_resp, node_req) = (c.walk, c.hier, io.ref_resp, io.node_req);
    let lit = |v: u64, w: u32| cx.lit(v, w);
    let code4 = |v: u64| cx.code4(v);
    let c1_end = ctx1.data.bit(ib);
    let c1_parent = ctx1.data.slice(ib - 1, 0);
    let ctx2_w = nk::BITS + fetch_err::BITS + rl.width();
    let ctx2_in = Stream::wires(m, "node_ctx_in", ctx2_w);
    let ctx2 = ctx2_in.fifo("node_ctx", IN_FLIGHT);
    let r_node = ref_resp.data.view(rl.node()).name("resp_node");
    let r_hier = ref_resp.data.view(rl.hier()).name("resp_hier");
    let ref_code = reference_code(m, r_node, r_hier, hier, c.nodes).name("code");
    let rr_wait = (walk & ctx1.valid & !c1_end & ctx2_in.ready & node_req.ready).name("wait");
    ref_resp.ready.drive(rr_wait);
    let rr_take = (rr_wait & ref_resp.valid).name("take");
    let rr_end = (walk & ctx1.valid & c1_end & ctx2_in.ready).name("end");
    ctx1.ready.drive(rr_take | rr_end);
    let walk_node_req =
        (walk & ctx1.valid & !c1_end & ctx2_in.ready & ref_resp.valid & ref_code.eq(0))
            .name("node_req");
    node_req.valid.drive(r.req_valid | walk_node_req);
    node_req.data.drive(c.roots_ph.mux(r.issued, r_node));
    ctx2_in.valid.drive(rr_take | rr_end);
    ctx2_in.data.drive(rr_end.mux(
        m.concat(&[lit(nk::END, nk::BITS), code4(0), m.lit(0, rl.width())]),
        ref_code.eq(0).mux(
            m.concat(&[lit(nk::NODE, nk::BITS), code4(0), ref_resp.data]),
            m.concat(&[
                lit(nk::ERR, nk::BITS),
                ref_code,
                reference(m, hier, c1_parent),
            ]),
        ),
    ));
    (ctx2, ctx2_w)
}
