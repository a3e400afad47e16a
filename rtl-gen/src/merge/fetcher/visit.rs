//! The visit stage: the item at its head (top level: the header or first
//! root error, then the sorter; deeper: the reference stage's word with its
//! node's answer) is checked, its ranges pushed on the frontier, its leaves
//! sent on `leaves`, and the level's nodes passed to the out stage; and,
//! per-node, the join of a pass's inner nodes with the module's decisions.

use golden::layout::Layout;
use golden::merge::fetcher::fetch_err;

use super::super::network::morton_code;
use super::command::{goto, Command, FirstErr};
use super::parts::reference;
use super::walk::{Frontier, Roots, WalkState};
use super::{nk, ok, ph, Ctx, Ports};
use crate::{Signal, Stream};

/// The item at the visit stage's head and what the stage decides of it.
pub(super) struct Head<'m> {
    /// The out stage's items (`ok` kind, code, reference, record) and width.
    pub(super) oin: Stream<'m>,
    pub(super) items: Stream<'m>,
    pub(super) oin_w: u32,
    /// Ranges are followed above `lod`.
    pub(super) above: Signal<'m>,
    /// Levels `first..=lod` are sent; the leaves above `first` go to `leaves`.
    pub(super) above_first: Signal<'m>,
    pub(super) sending: Signal<'m>,
    pub(super) pn_pass: Option<Signal<'m>>,
    pub(super) pn_visited: Option<Signal<'m>>,
    pub(super) pass_word: Layout,
    pub(super) pass_in: Option<Stream<'m>>,
    pub(super) lend_sent: Signal<'m>,
    pub(super) lend_due: Signal<'m>,
    pub(super) end_next: Signal<'m>,
    pub(super) fin_sent: Signal<'m>,
    pub(super) end_emit: Signal<'m>,
    pub(super) end_final: Signal<'m>,
    pub(super) end_fire: Signal<'m>,
    pub(super) go: Signal<'m>,
    pub(super) in_err: Signal<'m>,
    pub(super) in_end: Signal<'m>,
    pub(super) in_node: Signal<'m>,
    pub(super) in_err_code: Signal<'m>,
    pub(super) in_err_node: Signal<'m>,
    pub(super) rec: Signal<'m>,
    pub(super) rec_ref: Signal<'m>,
    pub(super) rec_idx: Signal<'m>,
}

/// The visit stage's head: which item is there, whether it may go, and the
/// handshakes with the sorter, the reference stage and `node_resp`.
#[allow(clippy::too_many_arguments)]
pub(super) fn visit_head<'m>(
    cx: &Ctx<'_, 'm>,
    c: &Command<'m>,
    e: &mut FirstErr<'m>,
    w: &WalkState<'m>,
    r: &Roots<'m>,
    (ctx2, ctx2_w): (Stream<'m>, u32),
    f: &Frontier<'m>,
    io: &Ports<'m>,
) -> Head<'m> {
    let (m, l, ib, lb) = (cx.m, cx.l, cx.ib, cx.lb);
    let _scope = m.scope("visit");
    let (nl, rl) = (&l.node, &l.reference);
    let lit = |v: u64, w: u32| cx.lit(v, w);
    let code4 = |v: u64| cx.code4(v);
    let (walk, start, v_d, v_top) = (c.walk, c.start, w.level, w.at_top);
    let c2_ref = ctx2.data.slice(rl.width() - 1, 0);
    let c2_code = ctx2
        .data
        .slice(rl.width() + fetch_err::BITS - 1, rl.width());
    let c2_kind = ctx2.data.slice(ctx2_w - 1, ctx2_w - nk::BITS);
    let c2_node = c2_kind.eq(lit(nk::NODE, nk::BITS));
    let oin_w = ok::BITS + fetch_err::BITS + rl.width() + nl.width();
    let oin = Stream::wires(m, "out_items_in", oin_w);
    let items = oin.fifo("out_items", 4);
    let live = (walk & !w.done).name("live");
    let above = v_d.lt(c.lod).name("above_level");
    let above_first = v_d.lt(c.first).name("above_first");
    // Per-node: every level from the first pass on is a pass (`pn_pass`).
    let sending = match c.per_node {
        Some(pn) => !above_first & (v_d.le(c.lod) | pn),
        None => !above_first & v_d.le(c.lod),
    }
    .name("sending_level");
    let pn_pass = c.per_node.map(|pn| (pn & !above).name("pn_pass"));
    // The visit stage has sent a pass's `End` and waits for the join to
    // take the pass's `pass_end` (the next pass's nodes wait behind it).
    let pn_visited = c.per_node.map(|_| m.reg("pn_visited", 1));
    // Per-node: an inner node of this pass, at Morton `key` (without the
    // walk's leading bit), with its child range; joined with the module's
    // decisions in key order.
    let pass_word = Layout::packed(
        "pass entry",
        &[
            ("key", w.key_bits - 1),
            ("first", ib),
            ("count", ib),
            ("node", ib),
        ],
    );
    let pass_in = c
        .per_node
        .map(|_| Stream::wires(m, "pass_in", pass_word.width()));
    // The `leaves` end beat leaves as soon as the visit stage is at the
    // first sent level (every node above it visited), before any item of
    // a sent level may wait on `out`: the merger's leaf merge then never
    // waits on a fetcher whose level beats wait on the merging module
    // (SPEC 8.15, the deadlock argument). A sent level's item waits for
    // it; above the first level only leaves need `leaves`.
    let lend_sent = m.reg("leaves_end_sent", 1);
    let lend_due = (live & c.send_leaves & !lend_sent & !above_first).name("leaves_end_due");
    let downstream =
        (oin.ready & f.push.ready & above_first.mux(io.leaves.ready, !c.send_leaves | lend_sent))
            .name("room");
    // The sent levels' `End`s: `end_next` is the level owed next. The
    // levels above the top but the last hold no node: their `End`s go
    // first, before any item (`pre_ends`); a level's `End` goes with its
    // end marker while the walk goes on; at the walk's end every level
    // still owed gets its `End`, `lod`'s last (`FINAL`: the command is
    // over once it has left).
    let end_next = m.reg("end_next", lb);
    let fin_sent = m.reg("final_sent", 1);
    let pre_ends = (live & end_next.lt(c.top) & end_next.lt(c.lod)).name("pre_ends");
    let drain = (walk & w.done & !fin_sent).name("ends_drain");
    let end_emit = (pre_ends | drain).name("end_emit");
    let end_final = (drain & end_next.eq(c.lod)).name("end_final");
    let end_fire = (end_emit & oin.ready).name("end_fire");
    let top_err = v_top & e.valid;
    let top_hdr_end = v_top & !e.valid & e.header;
    let top_sorted = v_top & !e.valid & !e.header;
    let deep = !v_top;
    // The sorter drops roots beyond its capacity and says so at `End`; the
    // START check keeps that from happening, and this keeps it from passing
    // silently if it ever did (an error item before the `End`).
    let cap_told = m.reg("capacity_told", 1);
    let top_cap =
        (top_sorted & r.s_out_valid & r.s_end & r.s_err & !cap_told).name("sorter_dropped");
    let node_resp = io.node_resp;
    let in_avail = (live
        & (top_err
            | top_hdr_end
            | top_sorted & r.s_out_valid
            | deep & ctx2.valid & (!c2_node | node_resp.valid)))
        .name("avail");
    let visit_room = match (pn_visited, pass_in) {
        (Some(v), Some(p)) => downstream & !pre_ends & !v & p.ready,
        _ => downstream & !pre_ends,
    }
    .name("free");
    let go = (in_avail & visit_room).name("go");
    r.sorter
        .connect("out_ready", live & top_sorted & !top_cap & visit_room);
    cap_told.next(start.mux(lit(0, 1), (go & top_cap).mux(lit(1, 1), cap_told)));
    ctx2.ready
        .drive(live & deep & (!c2_node | node_resp.valid) & visit_room);
    node_resp
        .ready
        .drive(r.outstanding & r.s_in_ready | live & deep & ctx2.valid & c2_node & visit_room);
    e.n_valid.when(go & top_err, lit(0, 1));
    let deep_fail = c2_node.mux(r.got_code.ne(0), c2_kind.eq(lit(nk::ERR, nk::BITS)));
    let in_err = (top_err | top_cap | deep & deep_fail).name("item_err");
    let in_end =
        (top_hdr_end | top_sorted & r.s_end & !top_cap | deep & c2_kind.eq(lit(nk::END, nk::BITS)))
            .name("item_end");
    let in_node = (!in_err & !in_end).name("item_node");
    let in_err_code = m.first_of(
        &[
            (top_err, e.code),
            (top_cap, code4(fetch_err::ROOT_CAPACITY)),
            (c2_node, r.got_code),
        ],
        c2_code,
    );
    let c2_ref_node = c2_ref.view(rl.node());
    let in_err_node = top_err.mux(e.node, top_cap.mux(lit(0, ib), c2_ref_node));
    let rec = v_top.mux(r.s_rec, r.got.moved).name("item_rec");
    let rec_ref = v_top.mux(r.s_ref, c2_ref).name("item_ref");
    let rec_idx = rec_ref.view(rl.node());
    Head {
        oin,
        items,
        oin_w,
        above,
        above_first,
        sending,
        pn_pass,
        pn_visited,
        pass_word,
        pass_in,
        lend_sent,
        lend_due,
        end_next,
        fin_sent,
        end_emit,
        end_final,
        end_fire,
        go,
        in_err,
        in_end,
        in_node,
        in_err_code,
        in_err_node,
        rec,
        rec_ref,
        rec_idx,
    }
}

/// What the visit stage's checks decide of the item that goes.
pub(super) struct Visited<'m> {
    pub(super) n_first: Signal<'m>,
    pub(super) n_count: Signal<'m>,
    pub(super) visit_code: Signal<'m>,
    pub(super) err_node: Signal<'m>,
    pub(super) fails: Signal<'m>,
    /// A range pushed on the frontier, and a level's end marker.
    pub(super) push: Signal<'m>,
    pub(super) marker: Signal<'m>,
    pub(super) leaf_out: Signal<'m>,
    pub(super) to_out: Signal<'m>,
    pub(super) level_end_push: Signal<'m>,
    pub(super) walk_over: Signal<'m>,
    pub(super) ran_out: Signal<'m>,
    /// Per-node: a pass's `End`.
    pub(super) pn_end: Option<Signal<'m>>,
    /// Per-node: the pass's inner nodes kept for the join.
    pub(super) pass_fifo: Option<Stream<'m>>,
    /// The pass's highest visited Morton code so far, and whether it has
    /// one: every inner node the pass still pushes lies above it.
    pub(super) past: (Signal<'m>, Signal<'m>),
}

/// The visit stage's checks (order, range, frontier capacity) and the walk
/// state's next values.
pub(super) fn visit_checks<'m>(
    cx: &Ctx<'_, 'm>,
    c: &Command<'m>,
    w: &WalkState<'m>,
    h: &Head<'m>,
) -> Visited<'m> {
    let (m, l, ib, lb) = (cx.m, cx.l, cx.ib, cx.lb);
    let _scope = m.scope("visit");
    let nl = &l.node;
    let lit = |v: u64, w: u32| cx.lit(v, w);
    let code4 = |v: u64| cx.code4(v);
    let (start, v_d, go, rec) = (c.start, w.level, h.go, h.rec);
    let (fcap, cb, key_bits) = (w.fcap, w.cb, w.key_bits);
    let leaf = rec.view(nl.leaf()).name("item_leaf");
    let inner = !leaf;
    let key = m
        .concat(&[morton_code(m, rec.coords(nl)), leaf])
        .name("item_key");
    let n_first = rec.view(nl.first());
    let n_count = rec.view(nl.count());
    let n_end = n_first
        .zext(ib + 1)
        .add(n_count.zext(ib + 1), ib + 1)
        .name("item_range_end");
    let at_level = v_d.eq(c.lod).name("at_level");
    let order_bad = (w.prev_valid & key.le(w.prev_key)).name("order_bad");
    // A pass's inner nodes use their ranges (probes, references) and are
    // kept for the join, `frontier` of them at most per pass.
    let above = h.above;
    let (uses_range, counted) = match h.pn_pass {
        Some(q) => (above | at_level & c.send_refs | q, above | q),
        None => (above | at_level & c.send_refs, above),
    };
    let range_bad = (inner & uses_range & n_end.gt(c.refs.zext(ib + 1))).name("range_bad");
    let front_bad = (inner & counted & w.pushed.ge(lit(fcap, cb))).name("frontier_bad");
    let visit_code = m
        .first_of(
            &[
                (h.in_err, h.in_err_code),
                (h.in_end, code4(0)),
                (order_bad, code4(fetch_err::ORDER)),
                (range_bad, code4(fetch_err::RANGE)),
                (front_bad, code4(fetch_err::FRONTIER)),
            ],
            code4(0),
        )
        .name("code");
    let err_node = h.in_err.mux(h.in_err_node, h.rec_idx);
    let fails = (go & visit_code.ne(0)).name("fails");
    let passes = (go & h.in_node & visit_code.eq(0)).name("passes");
    let push = (passes & above & inner).name("frontier_push");
    let leaf_out =
        (passes & h.above_first & leaf & c.send_leaves & !w.visit_errored).name("leaf_out");
    let to_out = (passes & h.sending).name("to_out");
    let more = (above & w.pushed.ne(0)).name("next_level");
    let level_end = (go & h.in_end).name("level_end");
    // Per-node: a level end with nothing pushed (a pass's end, or the walk
    // run out above the first pass) is a pass's `End`; the command ends
    // with the join, not with the walk.
    let (walk_over, pn_end, ran_out) = match c.per_node {
        Some(pn) => {
            let ran_out = (level_end & !more).name("walk_ran_out");
            let pn_end = (ran_out & pn).name("pn_pass_end");
            ((ran_out & !pn).name("walk_over"), Some(pn_end), ran_out)
        }
        None => {
            let w = (level_end & !more).name("walk_over");
            (w, None, w)
        }
    };
    let marker = (level_end & more).name("marker_push");
    let pass_fifo = h.pn_pass.zip(h.pass_in).map(|(q, pass_in)| {
        let e_push = (passes & q & inner).name("pass_push");
        pass_in.valid.drive(e_push);
        let morton_part = key.slice(key_bits - 1, 1);
        pass_in
            .data
            .drive(m.pack(&h.pass_word, &[morton_part, n_first, n_count, h.rec_idx]));
        let depth = (fcap.max(2)).next_power_of_two() as u32;
        (e_push, pass_in.fifo("pass", depth))
    });
    let step_level = match pn_end {
        Some(e) => marker | e,
        None => marker,
    };
    let level_end_push = (marker & h.end_next.eq(v_d)).name("level_end_push");
    // With PREFETCH a command's START comes before it is taken, so the
    // first level owed is loaded as it is taken.
    let (load, first) = match super::command::prefetches(cx) {
        true => (c.cmd_fire, c.first_in),
        false => (start, c.first),
    };
    h.end_next.next(load.mux(
        first,
        (h.end_fire & !h.end_final | level_end_push).mux(h.end_next.add(1, lb), h.end_next),
    ));
    h.fin_sent.next(start.mux(
        lit(0, 1),
        (h.end_fire & h.end_final).mux(lit(1, 1), h.fin_sent),
    ));

    w.prev_valid.next(start.mux(
        lit(0, 1),
        step_level.mux(lit(0, 1), (go & h.in_node).mux(lit(1, 1), w.prev_valid)),
    ));
    // A pass keeps its highest key (golden `visit_per_node`), so its
    // entries rise strictly; the level walk's predecessor is the last node.
    let prev_load = match h.pn_pass {
        Some(q) => go & h.in_node & !(q & order_bad),
        None => go & h.in_node,
    };
    w.prev_key.next_when(prev_load, key);
    let counted_push = match &pass_fifo {
        Some((e_push, _)) => push | *e_push,
        None => push,
    };
    w.pushed.next(start.mux(
        lit(0, cb),
        step_level.mux(lit(0, cb), counted_push.mux(w.pushed.add(1, cb), w.pushed)),
    ));
    v_d.next(start.mux(c.top, step_level.mux(v_d.add(1, lb), v_d)));
    w.at_top
        .next(start.mux(lit(1, 1), level_end.mux(lit(0, 1), w.at_top)));
    w.done
        .next(start.mux(lit(0, 1), walk_over.mux(lit(1, 1), w.done)));
    w.visit_errored
        .next(start.mux(lit(0, 1), fails.mux(lit(1, 1), w.visit_errored)));
    Visited {
        n_first,
        n_count,
        visit_code,
        err_node,
        fails,
        push,
        marker,
        leaf_out,
        to_out,
        level_end_push,
        walk_over,
        ran_out,
        pn_end,
        pass_fifo: pass_fifo.map(|(_, entries)| entries),
        // Above the first pass the walk's levels are no pass's.
        past: (
            h.pn_pass.map_or(lit(0, 1), |q| w.prev_valid & q),
            w.prev_key.slice(key_bits - 1, 1),
        ),
    }
}

/// The per-node join's registers the out stage completes: whether the
/// pass's `End` has left (`end_left`), and the clock the join takes the
/// pass's end (`take`).
pub(super) struct Join<'m> {
    pub(super) end_left: Signal<'m>,
    pub(super) take: Signal<'m>,
}

/// What goes on the frontier: the visit stage's ranges and markers, and
/// per-node the join: the pass's inner nodes against the module's
/// decisions; a descending one's range goes on the frontier for the next
/// pass, whose end marker goes on at `pass_end` with `more`. It pushes only
/// while the visit stage is at a pass (which pushes nothing there), so the
/// two never push in one clock.
pub(super) fn frontier_push<'m>(
    cx: &Ctx<'_, 'm>,
    c: &mut Command<'m>,
    f: &Frontier<'m>,
    h: &Head<'m>,
    v: &Visited<'m>,
) -> Option<Join<'m>> {
    let (m, l, lb) = (cx.m, cx.l, cx.lb);
    let _scope = m.scope("join");
    let lit = |x: u64, w: u32| cx.lit(x, w);
    let front_in = f.push;
    let (entries, pf) = match (v.pass_fifo, &l.pn) {
        (Some(entries), Some(pf)) => (entries, pf),
        _ => {
            front_in.valid.drive(v.push | v.marker);
            front_in
                .data
                .drive(m.pack(&f.word, &[v.n_first, v.n_count, h.rec_idx, v.marker]));
            return None;
        }
    };
    let dmax = cx.p.max_lod as u64;
    let report = Stream::input(m, "report", pf.report.width());
    let visited = h.pn_visited.expect("per-node");
    let end_left = m.reg("end_left", 1);
    let r = |f: &golden::layout::Field| report.data.view(f);
    let r_key = morton_code(m, [0, 1, 2].map(|a| r(&pf.report_coord[a]))).name("report_key");
    let r_pe = r(&pf.report_pass_end);
    let r_more = r(&pf.report_more);
    // A voxel at D has no child voxels: never followed.
    let r_desc = r(&pf.report_descend) & r(&pf.report_lod).lt(lit(dmax, lb));
    let e_key = entries.data.view_named(&h.pass_word, "key");
    let e_first = entries.data.view_named(&h.pass_word, "first");
    let e_count = entries.data.view_named(&h.pass_word, "count");
    let e_node = entries.data.view_named(&h.pass_word, "node");
    let jv = (c.walk & c.per_node.expect("per-node") & report.valid).name("valid");
    let dec = (jv & !r_pe).name("decision");
    let e_lt = (entries.valid & e_key.lt(r_key)).name("entry_before");
    let e_eq = (entries.valid & e_key.eq(r_key)).name("entry_at");
    let skip = (dec & e_lt | jv & r_pe & entries.valid).name("entry_stays");
    let matched = (dec & e_eq & (!r_desc | front_in.ready)).name("match");
    let j_push = (matched & r_desc).name("descend");
    // With the FIFO empty, a decision at or below a voxel the visit has
    // passed is another input's: every entry still to come lies above it.
    // Waiting for the visit there could deadlock: the visit waits for
    // `out`, which the module takes only while its `report` drains (8.14).
    let (past_valid, past_key) = v.past;
    let behind = (past_valid & r_key.le(past_key)).name("visit_past");
    let passed = (dec & (!entries.valid & (visited | behind) | entries.valid & !e_lt & !e_eq))
        .name("other_voxel");
    let pe_take = (jv & r_pe & !entries.valid & visited & end_left & (!r_more | front_in.ready))
        .name("pass_end");
    let j_marker = (pe_take & r_more).name("marker");
    entries.ready.drive(skip | matched);
    report.ready.drive(matched | passed | pe_take);
    front_in.valid.drive(v.push | v.marker | j_push | j_marker);
    front_in.data.drive((j_push | j_marker).mux(
        m.pack(&f.word, &[e_first, e_count, e_node, j_marker]),
        m.pack(&f.word, &[v.n_first, v.n_count, h.rec_idx, v.marker]),
    ));
    let pn_end = v.pn_end.expect("per-node");
    visited.next(c.start.mux(
        lit(0, 1),
        pn_end.mux(lit(1, 1), pe_take.mux(lit(0, 1), visited)),
    ));
    c.n_phase.when(pe_take & !r_more, goto(cx, ph::DONE));
    Some(Join {
        end_left,
        take: pe_take,
    })
}

/// The visit stage's outputs: `leaves` (the leaves above the first sent
/// level and its end beat) and the out stage's items.
pub(super) fn visit_out<'m>(
    cx: &Ctx<'_, 'm>,
    c: &Command<'m>,
    w: &WalkState<'m>,
    h: &Head<'m>,
    v: &Visited<'m>,
    io: &Ports<'m>,
) {
    let (m, l) = (cx.m, cx.l);
    let _scope = m.scope("visit");
    let lit = |x: u64, w: u32| cx.lit(x, w);
    let (rec, rec_ref, above_first) = (h.rec, h.rec_ref, h.above_first);
    let leaf_beat = m.lit(0, l.leaves.width()).with_fields(&[
        (l.leaf_rec, rec),
        (l.leaf_ref, rec_ref),
        (l.leaf_lod, rec.view(l.node.lod())),
    ]);
    let leaf_end_beat = m
        .lit(0, l.leaves.width())
        .with_fields(&[(l.leaf_end, lit(1, 1))]);
    // The end beat: the walk over above the first level, or it reached.
    // (Per-node: the walk may run out above the first pass once per pass.)
    let lend_out = match c.per_node {
        Some(_) => v.ran_out & !h.lend_sent,
        None => v.walk_over,
    };
    let lend_fire = (lend_out & above_first & c.send_leaves | h.lend_due & io.leaves.ready)
        .name("leaves_end_fire");
    h.lend_sent.next(
        c.start
            .mux(lit(0, 1), lend_fire.mux(lit(1, 1), h.lend_sent)),
    );
    io.leaves
        .valid
        .drive(v.leaf_out | lend_out & above_first & c.send_leaves | h.lend_due);
    io.leaves
        .data
        .drive(v.leaf_out.mux(leaf_beat, leaf_end_beat));
    // Only the first error goes on: `out` drops what follows it, and so at
    // most one item enters `out_items` above the level (it never fills
    // there, so the walk above the level never waits on `out`).
    let first_err = v.fails & !w.visit_errored;
    let (valid, ends) = match v.pn_end {
        Some(e) => (
            v.to_out | first_err | v.level_end_push | h.end_emit | e,
            v.level_end_push | h.end_emit | e,
        ),
        None => (
            v.to_out | first_err | v.level_end_push | h.end_emit,
            v.level_end_push | h.end_emit,
        ),
    };
    h.oin.valid.drive(valid);
    h.oin.data.drive(m.concat(&[
        m.first_of(
            &[
                (v.fails, lit(ok::ERR, ok::BITS)),
                (h.end_final, lit(ok::FINAL, ok::BITS)),
                (ends, lit(ok::LEVEL_END, ok::BITS)),
            ],
            lit(ok::NODE, ok::BITS),
        ),
        v.visit_code,
        v.fails.mux(reference(m, c.hier, v.err_node), rec_ref),
        rec,
    ]));
}
