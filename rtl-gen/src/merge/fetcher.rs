//! The fetcher (S610 + S612 in hardware, SPEC.md section 8.13): walks one
//! input hierarchy in the store, translating every node it reads, and sends
//! the merging module's per-input stream (`golden::merge::top::input_stream`
//! order) and the leaves above the walked level.
//!
//! A sequential walker, one store read at a time: the roots are read in
//! stored order, checked, moved and handed to a root sorter instance (the
//! only level a translation can put out of Morton order); the sorted roots
//! start a breadth-first walk whose frontier is a FIFO of the inner nodes'
//! `(first, count, parent)` ranges. Each deeper node costs a reference
//! read and a node read. Every check of `golden::merge::fetch_unit`'s
//! `fetch_err` ends the walk with an error beat naming the record; the
//! sorter is closed and drained and the FIFO emptied so the next command
//! starts clean.

use golden::merge::fetch_unit::{fetch_err, FetchLayout, FetchSizes};
use golden::merge::unit::{level_kind, BeatLayout};
use golden::params::{bits_to_hold, Params};

use super::fields::{field, with_fields};
use super::network::morton_code;
use super::sorter::root_sorter_unit;
use crate::{Module, Signal, Stream};

/// Module name of the fetcher.
pub fn fetcher_name(p: &Params, sizes: &FetchSizes) -> String {
    format!(
        "fetcher_d{}_q{}_i{}_h{}_r{}_f{}",
        p.max_lod, p.quant_bits, p.index_bits, p.hier_bits, sizes.roots, sizes.frontier
    )
}

/// The walker's states (one action each).
mod st {
    pub const IDLE: u64 = 0;
    pub const START: u64 = 1;
    pub const ROOT_REQ: u64 = 2;
    pub const ROOT_RESP: u64 = 3;
    pub const ROOT_END: u64 = 4;
    pub const TOP_NEXT: u64 = 5;
    pub const RANGE_NEXT: u64 = 6;
    pub const REF_REQ: u64 = 7;
    pub const REF_RESP: u64 = 8;
    pub const NODE_REQ: u64 = 9;
    pub const NODE_RESP: u64 = 10;
    pub const VISIT: u64 = 11;
    pub const LEAF_OUT: u64 = 12;
    pub const EMIT: u64 = 13;
    pub const PREF_REQ: u64 = 14;
    pub const PREF_RESP: u64 = 15;
    pub const LEVEL_END: u64 = 17;
    pub const FINISH: u64 = 18;
    pub const LEAF_END: u64 = 19;
    pub const DONE: u64 = 20;
    pub const ERR: u64 = 21;
    pub const ERR_EMIT: u64 = 22;
    pub const BITS: u32 = 5;
}

/// Prioritized register updates: the first arm whose condition holds sets
/// the next value; none holding keeps the register.
struct Next<'m> {
    reg: Signal<'m>,
    arms: Vec<(Signal<'m>, Signal<'m>)>,
}

impl<'m> Next<'m> {
    fn new(reg: Signal<'m>) -> Next<'m> {
        Next {
            reg,
            arms: Vec::new(),
        }
    }

    fn when(&mut self, cond: Signal<'m>, value: Signal<'m>) {
        self.arms.push((cond, value));
    }

    fn apply(self) {
        let mut v = self.reg;
        for (c, val) in self.arms.into_iter().rev() {
            v = c.mux(val, v);
        }
        self.reg.next(v);
    }
}

/// What reading a node record finds: the first failing check's code (0
/// none) in `golden::merge::fetch_unit`'s order, LOD, record, translation
/// level, then the moved coordinate on x, y, z; and the moved record.
struct Checked<'m> {
    code: Signal<'m>,
    moved: Signal<'m>,
}

/// The translation the `cfg` beat carried.
struct Move<'m> {
    lod: Signal<'m>,
    t: [Signal<'m>; 3],
}

/// Checks record `rec` (expected at LOD `want`) and moves it by `mv`
/// (section 7.6: `x' = x + (t << (d - L))` in `2D + 2`-bit two's complement,
/// outside when negative or `x' >> d != 0`).
fn check_and_move<'m>(
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
    let coords = [0, 1, 2].map(|a| field(rec, nl.coord(a)).expect("coordinate"));
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
fn reference<'m>(m: &'m Module, hier: Signal<'m>, node: Signal<'m>) -> Signal<'m> {
    m.concat(&[hier, node])
}

/// An S614 input beat with `err`, as the `out` stream carries it.
fn out_beat<'m>(
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

/// The fetcher for `p` with a root sorter of `sizes.roots` entries and a
/// frontier FIFO of `sizes.frontier` ranges. Streams (beats of
/// `golden::merge::fetch_unit::FetchLayout`): `cfg`, `cmd`, `node_resp`,
/// `ref_resp` in; `node_req`, `ref_req`, `out`, `leaves` out. `idle` is high
/// while no command is in progress.
pub fn fetcher_unit(p: &Params, sizes: &FetchSizes) -> Module {
    let m = Module::new(&fetcher_name(p, sizes));
    let l = FetchLayout::new(p);
    let nl = &l.node;
    let rl = &l.reference;
    let bl = BeatLayout::input(p);
    let sorted = BeatLayout::output(p);
    let (ib, lb) = (p.index_bits as u32, p.lod_bits());
    let lit = |v: u64, w: u32| m.lit(v as u128, w);

    let state = m.reg("state", st::BITS);
    let is = |s: u64| state.eq(lit(s, st::BITS));
    let goto = |s: u64| lit(s, st::BITS);
    let mut next_state = Next::new(state);

    // ---- cfg and cmd
    let cfg = Stream::input(&m, "cfg", l.cfg_width);
    let cmd = Stream::input(&m, "cmd", l.cmd_width);
    let cfg_have = m.reg("cfg_have", 1);
    let idle = is(st::IDLE).name("is_idle");
    cfg.ready.drive(idle & !cfg_have);
    cmd.ready.drive(idle & cfg_have);
    let cfg_fire = cfg.fire().name("cfg_fire");
    let cmd_fire = cmd.fire().name("cmd_fire");
    let cfg_data = cfg.data;
    let keep = |name: &str, f: &golden::layout::Field| {
        let r = m.reg(name, f.width);
        r.next_when(cfg_fire, field(cfg_data, f).expect("a cfg field"));
        r
    };
    let hier = keep("cfg_hier", &l.hier);
    let roots = keep("cfg_roots", &l.roots);
    let top = keep("cfg_top", &l.top);
    let nodes = keep("cfg_nodes", &l.nodes);
    let refs = keep("cfg_refs", &l.refs);
    let entry_valid = keep("cfg_entry_valid", &l.entry_valid);
    let mv = Move {
        lod: keep("cfg_entry_lod", &l.entry_lod),
        t: [0, 1, 2].map(|a| keep(&format!("cfg_entry_t{a}"), &l.entry_t[a])),
    };
    let dmax = p.max_lod as u64;
    let mut entry_ok = entry_valid;
    if (1u64 << lb) - 1 > dmax {
        entry_ok = entry_ok & mv.lod.le(lit(dmax, lb));
    }
    for t in &mv.t {
        // The code -2^D is never produced and is refused when read (7.3).
        entry_ok = entry_ok & t.ne(m.lit(1u128 << dmax, t.width()));
    }
    let entry_ok = entry_ok.name("entry_ok");

    let c_lod = m.reg("cmd_lod", lb);
    let c_refs = m.reg("cmd_send_refs", 1);
    let c_leaves = m.reg("cmd_send_leaves", 1);
    let c_last = m.reg("cmd_last", 1);
    c_lod.next_when(cmd_fire, field(cmd.data, &l.lod).expect("lod"));
    c_refs.next_when(cmd_fire, field(cmd.data, &l.send_refs).expect("send_refs"));
    c_leaves.next_when(
        cmd_fire,
        field(cmd.data, &l.send_leaves).expect("send_leaves"),
    );
    c_last.next_when(cmd_fire, field(cmd.data, &l.last).expect("last"));

    // ---- walk registers
    let idx = m.reg("idx", ib);
    let rng_end = m.reg("range_end", ib + 1);
    let parent = m.reg("parent", ib);
    let d = m.reg("level", lb);
    let from_sorter = m.reg("from_sorter", 1);
    let node = m.reg("node", nl.width());
    // Where the node is stored, (hier, node): the sorter's `ref` for a root,
    // the checked reference for a deeper node.
    let node_ref = m.reg("node_ref", rl.width());
    let node_idx = field(node_ref, rl.node()).expect("node").name("node_idx");
    let key_bits = 3 * p.coord_bits() + 1;
    let prev_valid = m.reg("prev_valid", 1);
    let prev_key = m.reg("prev_key", key_bits);
    let pend_valid = m.reg("pend_valid", 1);
    let pend_first = m.reg("pend_first", ib);
    let pend_end = m.reg("pend_end", ib + 1);
    let pend_voxel = m.reg("pend_voxel", 3 * p.coord_bits());
    let pend_node = m.reg("pend_node", ib);
    let drain_ret = m.reg("drain_ret", st::BITS);
    let err_code = m.reg("err_code", fetch_err::BITS);
    let err_node = m.reg("err_node", ib);
    let sorter_used = m.reg("sorter_used", 1);
    let sorter_closed = m.reg("sorter_closed", 1);
    let fcap = sizes.frontier as u64;
    let cb = bits_to_hold(fcap);
    let this_level = m.reg("this_level", cb);
    let next_level = m.reg("next_level", cb);

    let mut n_idx = Next::new(idx);
    let mut n_rng_end = Next::new(rng_end);
    let mut n_parent = Next::new(parent);
    let mut n_d = Next::new(d);
    let mut n_from_sorter = Next::new(from_sorter);
    let mut n_node = Next::new(node);
    let mut n_node_ref = Next::new(node_ref);
    let mut n_prev_valid = Next::new(prev_valid);
    let mut n_prev_key = Next::new(prev_key);
    let mut n_pend_valid = Next::new(pend_valid);
    let mut n_pend_first = Next::new(pend_first);
    let mut n_drain_ret = Next::new(drain_ret);
    let mut n_err_code = Next::new(err_code);
    let mut n_err_node = Next::new(err_node);
    let mut n_sorter_used = Next::new(sorter_used);
    let mut n_sorter_closed = Next::new(sorter_closed);
    let mut n_this_level = Next::new(this_level);
    let mut n_next_level = Next::new(next_level);
    let mut n_cfg_have = Next::new(cfg_have);

    // An error: remember the code and the record, go to ERR.
    let mut failures: Vec<(Signal, Signal, Signal)> = Vec::new();

    // ---- frontier FIFO of (first, count, parent)
    let words = (fcap.max(2)).next_power_of_two() as u32;
    let aw = words.trailing_zeros();
    let fifo = m.memory("frontier", 3 * ib, words);
    let head = m.reg("fifo_head", aw);
    let tail = m.reg("fifo_tail", aw);
    let fcount = m.reg("fifo_count", cb);
    let fifo_full = fcount.ge(lit(fcap, cb)).name("fifo_full");
    let popped = fifo.read(head).name("fifo_head_word");
    let pop_first = popped.slice(ib - 1, 0);
    let pop_count = popped.slice(2 * ib - 1, ib);
    let pop_parent = popped.slice(3 * ib - 1, 2 * ib);

    // ---- output streams (registered through skid buffers)
    let node_req = Stream::wires(&m, "node_req_core", ib);
    let ref_req = Stream::wires(&m, "ref_req_core", ib);
    let out = Stream::wires(&m, "out_core", l.out_width);
    let leaves = Stream::wires(&m, "leaves_core", l.leaves_width);
    let node_resp = Stream::input(&m, "node_resp", nl.width());
    let ref_resp = Stream::input(&m, "ref_resp", rl.width());

    // ---- the root sorter
    let sorter = m.instance("u_root_sorter", &root_sorter_unit(p, sizes.roots.max(1)));
    let s_in_ready = sorter.output("in_ready");
    let s_out_valid = sorter.output("out_valid");
    let s_out_data = sorter.output("out_data");
    let s_rec = field(s_out_data, &sorted.rec)
        .expect("rec")
        .name("sorted_rec");
    let s_ref = field(s_out_data, &sorted.refer).expect("ref");
    let s_err = field(s_out_data, &sorted.err.expect("output beats have err")).expect("err");
    let s_end = field(s_out_data, &sorted.kind)
        .expect("kind")
        .eq(level_kind::END)
        .name("sorted_end");

    // ---- START: header checks
    let start = is(st::START);
    let roots_bad = (roots.eq(0) | roots.gt(nodes)).name("roots_bad");
    let roots_over = if (sizes.roots as u64) >> ib != 0 {
        lit(0, 1)
    } else {
        roots.gt(lit(sizes.roots as u64, ib))
    }
    .name("roots_over");
    let zero_i = lit(0, ib);
    failures.push((start & !entry_ok, lit(fetch_err::ENTRY, 4), zero_i));
    failures.push((
        start & entry_ok & roots_bad,
        lit(fetch_err::ROOT_COUNT, 4),
        zero_i,
    ));
    failures.push((
        start & entry_ok & !roots_bad & roots_over,
        lit(fetch_err::ROOT_CAPACITY, 4),
        zero_i,
    ));
    let start_ok = (start & entry_ok & !roots_bad & !roots_over).name("start_ok");
    next_state.when(cmd_fire, goto(st::START));
    n_idx.when(start_ok, zero_i);
    n_sorter_used.when(start_ok, lit(1, 1));
    n_sorter_closed.when(start_ok, lit(0, 1));
    next_state.when(start_ok, goto(st::ROOT_REQ));

    // ---- roots: read, check, into the sorter
    let root_req = is(st::ROOT_REQ);
    let root_resp = is(st::ROOT_RESP);
    let root_end = is(st::ROOT_END);
    next_state.when(root_req & node_req.ready, goto(st::ROOT_RESP));
    let got_root = check_and_move(&m, p, &l, node_resp.data, top, &mv);
    let root_code = got_root.code.name("root_code");
    let root_take = (root_resp & node_resp.valid & s_in_ready).name("root_take");
    failures.push((root_take & root_code.ne(0), root_code, idx));
    let root_ok = (root_take & root_code.eq(0)).name("root_ok");
    let idx_next = idx.add(1, ib);
    let last_root = idx_next.eq(roots);
    n_idx.when(root_ok, idx_next);
    next_state.when(
        root_ok,
        last_root.mux(goto(st::ROOT_END), goto(st::ROOT_REQ)),
    );
    let root_beat = with_fields(
        &m,
        m.lit(0, bl.width),
        &[
            (bl.rec, got_root.moved),
            (bl.refer, reference(&m, hier, idx)),
            (
                bl.kind,
                field(node_resp.data, nl.leaf())
                    .expect("leaf")
                    .mux(lit(level_kind::LEAF, 2), lit(level_kind::INNER, 2)),
            ),
        ],
    );
    let end_beat = with_fields(
        &m,
        m.lit(0, bl.width),
        &[(bl.kind, lit(level_kind::END, 2))],
    );
    let err_st = is(st::ERR);
    let err_close = (err_st & sorter_used & !sorter_closed).name("err_close");
    let s_in_valid = (root_resp & node_resp.valid & root_code.eq(0)) | root_end | err_close;
    sorter.connect("in_valid", s_in_valid);
    sorter.connect("in_data", root_resp.mux(root_beat, end_beat));
    node_resp
        .ready
        .drive(root_resp & s_in_ready | is(st::NODE_RESP));
    let end_in = (root_end & s_in_ready).name("sorter_end_in");
    n_sorter_closed.when(end_in | err_close & s_in_ready, lit(1, 1));
    n_d.when(end_in, top);
    n_prev_valid.when(end_in, lit(0, 1));
    n_pend_valid.when(end_in, lit(0, 1));
    n_from_sorter.when(end_in, lit(1, 1));
    n_next_level.when(end_in, lit(0, cb));
    next_state.when(end_in, goto(st::TOP_NEXT));

    // ---- top level: the sorted roots
    let top_next = is(st::TOP_NEXT);
    let err_drain = (err_st & sorter_used & sorter_closed).name("err_drain");
    sorter.connect("out_ready", top_next | err_drain);
    let s_take = (top_next & s_out_valid).name("sorted_take");
    n_sorter_used.when((s_take | err_drain & s_out_valid) & s_end, lit(0, 1));
    next_state.when(s_take & s_end, goto(st::LEVEL_END));
    n_node.when(s_take & !s_end, s_rec);
    n_node_ref.when(s_take & !s_end, s_ref);
    // The sorter drops roots beyond its capacity and says so at `End`; the
    // START check keeps that from happening, and this keeps it from passing
    // silently if it ever did.
    failures.push((
        s_take & s_end & s_err,
        lit(fetch_err::ROOT_CAPACITY, 4),
        zero_i,
    ));
    next_state.when(s_take & !s_end, goto(st::VISIT));

    // ---- deeper levels: ranges from the frontier
    let range_next = is(st::RANGE_NEXT);
    let level_done = this_level.eq(0);
    next_state.when(range_next & level_done, goto(st::LEVEL_END));
    let pop = (range_next & !level_done).name("fifo_pop");
    n_idx.when(pop, pop_first);
    n_rng_end.when(
        pop,
        pop_first.zext(ib + 1).add(pop_count.zext(ib + 1), ib + 1),
    );
    n_parent.when(pop, pop_parent);
    n_this_level.when(pop, this_level.sub(1, cb));
    next_state.when(pop, goto(st::REF_REQ));

    let ref_req_st = is(st::REF_REQ);
    next_state.when(ref_req_st & ref_req.ready, goto(st::REF_RESP));
    let ref_resp_st = is(st::REF_RESP);
    let r_node = field(ref_resp.data, rl.node())
        .expect("node")
        .name("resp_ref_node");
    let r_hier = field(ref_resp.data, rl.hier())
        .expect("hier")
        .name("resp_ref_hier");
    let ref_code = r_hier.ne(hier).mux(
        lit(fetch_err::REF_HIER, 4),
        r_node.ge(nodes).mux(lit(fetch_err::REF_NODE, 4), lit(0, 4)),
    );
    let ref_code = ref_code.name("ref_code");
    let child_ref = (ref_resp_st & ref_resp.valid).name("child_ref_take");
    failures.push((child_ref & ref_code.ne(0), ref_code, parent));
    let child_ok = child_ref & ref_code.eq(0);
    n_node_ref.when(child_ok, ref_resp.data);
    n_idx.when(child_ok, idx_next);
    next_state.when(child_ok, goto(st::NODE_REQ));

    let node_req_st = is(st::NODE_REQ);
    next_state.when(node_req_st & node_req.ready, goto(st::NODE_RESP));
    let node_resp_st = is(st::NODE_RESP);
    let got = check_and_move(&m, p, &l, node_resp.data, d, &mv);
    let node_code = got.code.name("node_code");
    let node_take = (node_resp_st & node_resp.valid).name("node_take");
    failures.push((node_take & node_code.ne(0), node_code, node_idx));
    n_node.when(node_take & node_code.eq(0), got.moved);
    next_state.when(node_take & node_code.eq(0), goto(st::VISIT));

    node_req.valid.drive(root_req | node_req_st);
    node_req.data.drive(root_req.mux(idx, node_idx));

    // After a node, the level's next one: the sorter's next root, the
    // range's next child, or the next range (no state of its own).
    let after_node = from_sorter
        .mux(
            goto(st::TOP_NEXT),
            idx.zext(ib + 1)
                .ne(rng_end)
                .mux(goto(st::REF_REQ), goto(st::RANGE_NEXT)),
        )
        .name("after_node");

    // ---- VISIT: order, range and frontier checks, then where the node goes
    let visit = is(st::VISIT);
    let leaf = field(node, nl.leaf()).expect("leaf").name("node_leaf");
    let inner = !leaf;
    let voxel = m
        .concat(&[
            field(node, nl.z()).expect("z"),
            field(node, nl.y()).expect("y"),
            field(node, nl.x()).expect("x"),
        ])
        .name("node_voxel");
    let key = m
        .concat(&[
            morton_code(
                &m,
                [0, 1, 2].map(|a| field(node, nl.coord(a)).expect("coord")),
            ),
            leaf,
        ])
        .name("node_key");
    let n_first = field(node, nl.first()).expect("first");
    let n_count = field(node, nl.count()).expect("count");
    let n_end = n_first
        .zext(ib + 1)
        .add(n_count.zext(ib + 1), ib + 1)
        .name("node_range_end");
    let above_level = d.lt(c_lod).name("above_level");
    let at_level = d.eq(c_lod).name("at_level");
    let order_bad = (prev_valid & key.le(prev_key)).name("order_bad");
    let range_bad =
        (inner & (above_level | at_level & c_refs) & n_end.gt(refs.zext(ib + 1))).name("range_bad");
    let front_bad = (inner & above_level & fifo_full).name("frontier_bad");
    let visit_code = order_bad.mux(
        lit(fetch_err::ORDER, 4),
        range_bad.mux(
            lit(fetch_err::RANGE, 4),
            front_bad.mux(lit(fetch_err::FRONTIER, 4), lit(0, 4)),
        ),
    );
    failures.push((visit & visit_code.ne(0), visit_code, node_idx));
    let visit_ok = (visit & visit_code.eq(0)).name("visit_ok");
    n_prev_valid.when(visit_ok, lit(1, 1));
    n_prev_key.when(visit_ok, key);
    let push = (visit_ok & above_level & inner).name("fifo_push");
    n_next_level.when(push, next_level.add(1, cb));
    next_state.when(visit_ok & above_level & leaf & c_leaves, goto(st::LEAF_OUT));
    next_state.when(visit_ok & at_level, goto(st::EMIT));
    next_state.when(visit_ok, after_node);
    fifo.write(tail, m.concat(&[node_idx, n_count, n_first]), push);

    let leaf_out = is(st::LEAF_OUT);
    next_state.when(leaf_out & leaves.ready, after_node);

    // ---- EMIT: a node at the level; a held inner node's references go
    // after its voxel's leaf, or before any other node.
    let emit = is(st::EMIT);
    let same_leaf = (pend_valid & leaf & voxel.eq(pend_voxel)).name("leaf_of_held");
    let refs_first = (emit & pend_valid & !same_leaf).name("refs_first");
    n_drain_ret.when(refs_first, goto(st::EMIT));
    next_state.when(refs_first, goto(st::PREF_REQ));
    let emit_node = (emit & !(pend_valid & !same_leaf)).name("emit_node");
    let emitted = (emit_node & out.ready).name("emitted");
    n_drain_ret.when(emitted & same_leaf, after_node);
    next_state.when(emitted & same_leaf, goto(st::PREF_REQ));
    let hold = (emitted & inner & c_refs).name("hold_refs");
    n_pend_valid.when(hold, lit(1, 1));
    n_pend_first.when(hold, n_first);
    pend_end.next_when(hold, n_end);
    pend_voxel.next_when(hold, voxel);
    pend_node.next_when(hold, node_idx);
    next_state.when(emitted, after_node);

    // ---- the held node's references
    let pref_req = is(st::PREF_REQ);
    let level_end = is(st::LEVEL_END);
    next_state.when(pref_req & ref_req.ready, goto(st::PREF_RESP));
    ref_req.valid.drive(ref_req_st | pref_req);
    ref_req.data.drive(ref_req_st.mux(idx, pend_first));
    let pref_resp = is(st::PREF_RESP);
    let pref_take = (pref_resp & ref_resp.valid & out.ready).name("pref_take");
    failures.push((pref_take & ref_code.ne(0), ref_code, pend_node));
    let pref_ok = (pref_take & ref_code.eq(0)).name("pref_ok");
    let pf_next = pend_first.add(1, ib);
    let pref_last = pf_next.zext(ib + 1).eq(pend_end);
    n_pend_first.when(pref_ok, pf_next);
    n_pend_valid.when(pref_ok & pref_last, lit(0, 1));
    next_state.when(pref_ok & pref_last, drain_ret);
    next_state.when(pref_ok, goto(st::PREF_REQ));
    ref_resp.ready.drive(ref_resp_st | pref_resp & out.ready);

    // ---- LEVEL_END: held references, then the next level or the end
    let le_refs = (level_end & pend_valid).name("level_end_refs");
    n_drain_ret.when(le_refs, goto(st::LEVEL_END));
    next_state.when(le_refs, goto(st::PREF_REQ));
    let walk_over = (d.ge(c_lod) | next_level.eq(0)).name("walk_over");
    next_state.when(level_end & walk_over, goto(st::FINISH));
    let deeper = (level_end & !pend_valid & !walk_over).name("deeper");
    n_d.when(deeper, d.add(1, lb));
    n_this_level.when(deeper, next_level);
    n_next_level.when(deeper, lit(0, cb));
    n_prev_valid.when(deeper, lit(0, 1));
    n_from_sorter.when(deeper, lit(0, 1));
    next_state.when(deeper, goto(st::RANGE_NEXT));

    // ---- FINISH / LEAF_END / DONE
    let finish = is(st::FINISH);
    let err_emit = is(st::ERR_EMIT);
    let closing = ((finish | err_emit) & out.ready).name("closing");
    next_state.when(closing & c_leaves, goto(st::LEAF_END));
    next_state.when(closing, goto(st::DONE));
    let leaf_end = is(st::LEAF_END);
    next_state.when(leaf_end & leaves.ready, goto(st::DONE));
    let done = is(st::DONE);
    n_cfg_have.when(cfg_fire, lit(1, 1));
    n_cfg_have.when(done & c_last, lit(0, 1));
    next_state.when(done, goto(st::IDLE));

    // ---- ERR: close and drain the sorter, empty the frontier, then report
    let failed = failures
        .iter()
        .map(|f| f.0)
        .reduce(|a, b| a | b)
        .expect("checks")
        .name("failed");
    let mut code_sel = lit(0, 4);
    let mut node_sel = zero_i;
    for (c, code, at) in failures.iter().rev() {
        code_sel = c.mux(*code, code_sel);
        node_sel = c.mux(*at, node_sel);
    }
    n_err_code.when(failed, code_sel);
    n_err_node.when(failed, node_sel);
    n_pend_valid.when(failed, lit(0, 1));
    let clean = (err_st & !sorter_used).name("err_clean");
    next_state.when(clean, goto(st::ERR_EMIT));
    // A failure wins over every other transition of the same clock.
    let mut arms = vec![(failed, goto(st::ERR))];
    arms.append(&mut next_state.arms);
    next_state.arms = arms;

    let front_reset = failed;
    let popped_now = pop;
    head.next(front_reset.mux(lit(0, aw), popped_now.mux(head.add(1, aw), head)));
    tail.next(front_reset.mux(lit(0, aw), push.mux(tail.add(1, aw), tail)));
    fcount.next(front_reset.mux(
        lit(0, cb),
        push.mux(
            popped_now.mux(fcount, fcount.add(1, cb)),
            popped_now.mux(fcount.sub(1, cb), fcount),
        ),
    ));

    // ---- out and leaves beats
    let node_beat = out_beat(
        &m,
        &l,
        Some(node),
        Some(node_ref),
        leaf.mux(lit(level_kind::LEAF, 2), lit(level_kind::INNER, 2)),
        None,
    );
    let child_beat = out_beat(
        &m,
        &l,
        None,
        Some(ref_resp.data),
        lit(level_kind::CHILD_REF, 2),
        None,
    );
    let end_out = out_beat(&m, &l, None, None, lit(level_kind::END, 2), None);
    let err_out = out_beat(
        &m,
        &l,
        None,
        Some(reference(&m, hier, err_node)),
        lit(level_kind::END, 2),
        Some(err_code),
    );
    out.valid
        .drive(emit_node | pref_resp & ref_resp.valid & ref_code.eq(0) | finish | err_emit);
    out.data.drive(emit.mux(
        node_beat,
        pref_resp.mux(child_beat, finish.mux(end_out, err_out)),
    ));
    let leaf_beat = with_fields(
        &m,
        m.lit(0, l.leaves_width),
        &[
            (l.leaf_rec, node),
            (l.leaf_ref, node_ref),
            (l.leaf_lod, field(node, nl.lod()).expect("lod")),
        ],
    );
    let leaf_end_beat = with_fields(&m, m.lit(0, l.leaves_width), &[(l.leaf_end, lit(1, 1))]);
    leaves.valid.drive(leaf_out | leaf_end);
    leaves.data.drive(leaf_out.mux(leaf_beat, leaf_end_beat));

    node_req.skid_buffer("node_req_q").output("node_req");
    ref_req.skid_buffer("ref_req_q").output("ref_req");
    out.skid_buffer("out_q").output("out");
    leaves.skid_buffer("leaves_q").output("leaves");
    m.output("idle", idle);

    for n in [
        next_state,
        n_idx,
        n_rng_end,
        n_parent,
        n_d,
        n_from_sorter,
        n_node,
        n_node_ref,
        n_prev_valid,
        n_prev_key,
        n_pend_valid,
        n_pend_first,
        n_drain_ret,
        n_err_code,
        n_err_node,
        n_sorter_used,
        n_sorter_closed,
        n_this_level,
        n_next_level,
        n_cfg_have,
    ] {
        n.apply();
    }
    m
}
