//! The fetcher (S610 + S612 in hardware, SPEC.md section 8.13): walks one
//! input hierarchy in the store, translating every node it reads, and sends
//! the merging module's per-input stream (`golden::merge::top::input_stream`
//! order) and the leaves above the walked level.
//!
//! A read pipeline, one node per clock: the roots are read in stored
//! order, checked, moved and handed to a root sorter instance (the only
//! level a translation can put out of Morton order); the sorted roots start
//! a breadth-first walk whose frontier is a FIFO of the inner nodes'
//! `(first, count, parent)` ranges and one end-of-level marker. Stages,
//! each with a small FIFO of the reads in flight beside it: the range stage
//! issues one `ref` read a clock; the reference stage checks each answer
//! and issues its `node` read; the visit stage checks and moves the node,
//! pushes ranges, sends leaves, and passes the level's nodes to the out
//! stage, which issues the held inner nodes' `cref` reads and sends `out`.
//! Reads are issued from validated data only and all of them are made even
//! after an error (`out` stops after its error beat), so every request
//! stream is fixed by the data, never by timing.

use golden::merge::fetch_unit::{fetch_err, FetchLayout, FetchSizes};
use golden::merge::unit::{level_kind, BeatLayout};
use golden::params::{bits_to_hold, Params};

use super::fields::{coords, field, with_fields, Word};
use super::network::morton_code;
use super::sorter::root_sorter_unit;
use crate::{Module, Signal, Stream};

/// Module name of the fetcher.
pub fn fetcher_name(p: &Params, sizes: &FetchSizes) -> String {
    format!("fetcher_{}_r{}_f{}", p.tag(), sizes.roots, sizes.frontier)
}

/// Module name of the fetcher built with the per-node command.
pub fn fetcher_per_node_name(p: &Params, sizes: &FetchSizes) -> String {
    format!("{}_pn", fetcher_name(p, sizes))
}

/// The command's phases.
mod ph {
    pub const IDLE: u64 = 0;
    pub const START: u64 = 1;
    pub const ROOTS: u64 = 2;
    pub const WALK: u64 = 3;
    pub const DONE: u64 = 4;
    pub const BITS: u32 = 3;
    /// Every phase by name (the Verilog's `localparam`s).
    pub const STATES: &[(&str, u64)] = &[
        ("IDLE", IDLE),
        ("START", START),
        ("ROOTS", ROOTS),
        ("WALK", WALK),
        ("DONE", DONE),
    ];
}

/// Kinds of the reference stage's in-flight words (`node_ctx`).
mod nk {
    /// Width of the encoding (internal to the fetcher, no golden format).
    pub const BITS: u32 = 2;
    pub const NODE: u64 = 0;
    pub const ERR: u64 = 1;
    pub const END: u64 = 2;
}

/// Kinds of the out stage's words (`out_items` from the visit stage; the
/// ordered `out_tokens`).
mod ok {
    /// Width of both encodings (internal to the fetcher, no golden format).
    pub const BITS: u32 = 2;
    pub const NODE: u64 = 0;
    pub const ERR: u64 = 1;
    /// The last level's `End`: the command is over once it has left.
    pub const FINAL: u64 = 2;
    /// Another sent level's `End`.
    pub const LEVEL_END: u64 = 3;
    pub const TOK_BEAT: u64 = 0;
    pub const TOK_ERR: u64 = 1;
    pub const TOK_CREF: u64 = 2;
    pub const TOK_FINAL: u64 = 3;
}

/// A FIFO of `depth` (a power of two) words, in-order: `input.ready` is
/// driven here (space left), the returned stream's `ready` by its consumer.
/// A word pushed is readable from the next clock; push and pop may share a
/// clock, so a depth of 2 runs one word a clock.
fn fifo<'m>(m: &'m Module, name: &str, input: Stream<'m>, depth: u32) -> Stream<'m> {
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
/// frontier FIFO of `2 * sizes.frontier + 1` words, rounded up to a power of
/// two (a level's ranges popped while the next's are pushed, a marker).
/// Streams (beats of `golden::merge::fetch_unit::FetchLayout`): `cfg`,
/// `cmd`, `node_resp`, `ref_resp`, `cref_resp` in; `node_req`, `ref_req`,
/// `cref_req`, `out`, `leaves` out. `idle` is high while no command is in
/// progress.
pub fn fetcher_unit(p: &Params, sizes: &FetchSizes) -> Module {
    fetcher_unit_with(p, sizes, false)
}

/// [`fetcher_unit`] with the per-node command (SPEC 8.13): `cmd`'s
/// `per_node` bit, `out`'s `probe` bit, the `report` input (the glue's
/// narrow beat of the per-node module's `report`) and the `probe` read
/// port (`probe_req` out, `probe_resp` in: a node index, a record), all
/// from `golden::merge::fetch_unit::FetchLayout::per_node`. Level commands
/// run as in [`fetcher_unit`] (one more out stage: the probes' answers).
pub fn fetcher_per_node_unit(p: &Params, sizes: &FetchSizes) -> Module {
    fetcher_unit_with(p, sizes, true)
}

/// The fetcher, with the per-node command when `pn`; without it every
/// signal, register and port is the level modes' fetcher's, built in the
/// same order (the same Verilog).
fn fetcher_unit_with(p: &Params, sizes: &FetchSizes, pn: bool) -> Module {
    let name = match pn {
        true => fetcher_per_node_name(p, sizes),
        false => fetcher_name(p, sizes),
    };
    let m = Module::new(&name);
    let l = FetchLayout::build(p, pn);
    let nl = &l.node;
    let rl = &l.reference;
    let bl = BeatLayout::input(p);
    let sorted = BeatLayout::output(p);
    let (ib, lb) = (p.index_bits as u32, p.lod_bits());
    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let code4 = |c: u64| lit(c, fetch_err::BITS);
    // Words in flight per read port: enough for a memory answering a few
    // clocks after the request at one read a clock.
    const IN_FLIGHT: u32 = 8;

    let phase = m.reg("phase", ph::BITS);
    let phases = m.states(ph::BITS, ph::STATES);
    let is = |s: u64| phases.is(phase, s);
    let goto = |s: u64| phases.code(s);
    let mut n_phase = Next::new(phase);

    // ---- cfg and cmd
    let cfg = Stream::input(&m, "cfg", l.cfg_width);
    let cmd = Stream::input(&m, "cmd", l.cmd_width);
    let cfg_have = m.reg("cfg_have", 1);
    let idle = is(ph::IDLE).name("is_idle");
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
    // The first level sent: `min(from, lod)` (`from >= lod`: one level).
    let c_first = m.reg("cmd_first", lb);
    let cmd_from = field(cmd.data, &l.from).expect("from");
    let cmd_lod = field(cmd.data, &l.lod).expect("lod");
    let first = cmd_from.gt(cmd_lod).mux(cmd_lod, cmd_from);
    // The per-node command's passes start at `lod` (`from` not read).
    let c_pn = l.pn.as_ref().map(|f| {
        let r = m.reg("cmd_per_node", 1);
        r.next_when(cmd_fire, field(cmd.data, &f.per_node).expect("per_node"));
        r
    });
    let first = match &l.pn {
        Some(f) => field(cmd.data, &f.per_node)
            .expect("per_node")
            .mux(cmd_lod, first),
        None => first,
    };
    c_first.next_when(cmd_fire, first);
    n_phase.when(cmd_fire, goto(ph::START));

    let walk = is(ph::WALK).name("walking");
    let start = is(ph::START);
    let roots_ph = is(ph::ROOTS);

    // ---- ports
    let node_req = Stream::wires(&m, "node_req_core", ib);
    let ref_req = Stream::wires(&m, "ref_req_core", ib);
    let cref_req = Stream::wires(&m, "cref_req_core", ib);
    let out = Stream::wires(&m, "out_core", l.out_width);
    let leaves = Stream::wires(&m, "leaves_core", l.leaves_width);
    let node_resp = Stream::input(&m, "node_resp", nl.width());
    let ref_resp = Stream::input(&m, "ref_resp", rl.width());
    let cref_resp = Stream::input(&m, "cref_resp", rl.width());

    // ---- START: header checks. A failure is reported as the command's
    // first error, before a walk with no roots.
    let roots_bad = (roots.eq(0) | roots.gt(nodes)).name("roots_bad");
    let roots_over = if (sizes.roots as u64) >> ib != 0 {
        lit(0, 1)
    } else {
        roots.gt(lit(sizes.roots as u64, ib))
    }
    .name("roots_over");
    let hdr_code = (!entry_ok)
        .mux(
            code4(fetch_err::ENTRY),
            roots_bad.mux(
                code4(fetch_err::ROOT_COUNT),
                roots_over.mux(code4(fetch_err::ROOT_CAPACITY), code4(0)),
            ),
        )
        .name("header_code");
    let hdr_bad = hdr_code.ne(0);
    n_phase.when(start, hdr_bad.mux(goto(ph::WALK), goto(ph::ROOTS)));
    let zero_i = lit(0, ib);
    // The first error before the walk (header or root), reported by the
    // visit stage ahead of the top level.
    let rerr_valid = m.reg("first_err_valid", 1);
    let rerr_code = m.reg("first_err_code", fetch_err::BITS);
    let rerr_node = m.reg("first_err_node", ib);
    let hdr_err = m.reg("header_err", 1);
    let mut n_rerr_valid = Next::new(rerr_valid);
    let mut n_rerr_code = Next::new(rerr_code);
    let mut n_rerr_node = Next::new(rerr_node);
    n_rerr_valid.when(start, hdr_bad);
    n_rerr_code.when(start, hdr_code);
    n_rerr_node.when(start, zero_i);
    hdr_err.next_when(start, hdr_bad);

    // ---- ROOTS: read 0..root_count, one a clock, into the sorter
    let sorter = m.instance("u_root_sorter", &root_sorter_unit(p, sizes.roots.max(1)));
    let s_in_ready = sorter.output("in_ready");
    let s_out_valid = sorter.output("out_valid");
    let s_out_data = sorter.output("out_data");
    let s_rec = field(s_out_data, &sorted.rec)
        .expect("rec")
        .name("sorted_rec");
    let s_ref = field(s_out_data, &sorted.refer).expect("ref");
    let s_end = field(s_out_data, &sorted.kind)
        .expect("kind")
        .eq(level_kind::END)
        .name("sorted_end");
    let s_err = field(s_out_data, &sorted.err.expect("output beats have err")).expect("err");
    let issued = m.reg("roots_issued", ib);
    let taken = m.reg("roots_taken", ib);
    issued.next(start.mux(
        zero_i,
        (roots_ph & node_req.fire()).mux(issued.add(1, ib), issued),
    ));
    let root_req_v = (roots_ph & issued.ne(roots)).name("root_req_valid");
    let root_out = (roots_ph & issued.ne(taken)).name("root_outstanding");
    let all_taken = (roots_ph & taken.eq(roots)).name("roots_all_taken");

    // ---- walk state, reset by each command's START
    let v_d = m.reg("level", lb);
    let v_top = m.reg("at_top", 1);
    let v_done = m.reg("walk_done", 1);
    let prev_valid = m.reg("prev_valid", 1);
    let key_bits = 3 * p.coord_bits() + 1;
    let prev_key = m.reg("prev_key", key_bits);
    let fcap = sizes.frontier as u64;
    let cb = bits_to_hold(fcap);
    let pushed = m.reg("pushed", cb);
    let v_errored = m.reg("visit_errored", 1);
    let o_errored = m.reg("out_errored", 1);

    let got = check_and_move(&m, p, &l, node_resp.data, roots_ph.mux(top, v_d), &mv);
    let got_code = got.code.name("node_code");
    let root_take = (root_out & node_resp.valid & s_in_ready).name("root_take");
    taken.next(start.mux(zero_i, root_take.mux(taken.add(1, ib), taken)));
    let root_fail = (root_take & got_code.ne(0)).name("root_fail");
    n_rerr_valid.when(root_fail, lit(1, 1));
    n_rerr_code.when(root_fail & !rerr_valid, got_code);
    n_rerr_node.when(root_fail & !rerr_valid, taken);
    let root_beat = with_fields(
        &m,
        m.lit(0, bl.width),
        &[
            (bl.rec, got.moved),
            (bl.refer, reference(&m, hier, taken)),
            (
                bl.kind,
                field(node_resp.data, nl.leaf()).expect("leaf").mux(
                    lit(level_kind::LEAF, bl.kind.width),
                    lit(level_kind::INNER, bl.kind.width),
                ),
            ),
        ],
    );
    let end_beat = with_fields(
        &m,
        m.lit(0, bl.width),
        &[(bl.kind, lit(level_kind::END, bl.kind.width))],
    );
    sorter.connect(
        "in_valid",
        root_out & node_resp.valid & got_code.eq(0) | all_taken,
    );
    sorter.connect("in_data", all_taken.mux(end_beat, root_beat));
    n_phase.when(all_taken & s_in_ready, goto(ph::WALK));

    // ---- the frontier: ranges (first, count, parent) and level markers
    let f_words = (2 * fcap + 1).max(2).next_power_of_two() as u32;
    // A range of `count` references from `first`, read by inner node
    // `parent`, or (`marker`) a level's end.
    let front_word = Word::new(&[("first", ib), ("count", ib), ("parent", ib), ("marker", 1)]);
    let front_in = Stream::wires(&m, "frontier_in", front_word.width());
    let front = fifo(&m, "frontier", front_in, f_words);
    let fo_marker = front_word.get(front.data, "marker");
    let fo_first = front_word.get(front.data, "first");
    let fo_count = front_word.get(front.data, "count");
    let fo_parent = front_word.get(front.data, "parent");

    // ---- range stage: one `ref` read a clock
    let cur_valid = m.reg("range_valid", 1);
    let cur_idx = m.reg("range_idx", ib);
    let cur_end = m.reg("range_end", ib + 1);
    let cur_parent = m.reg("range_parent", ib);
    let ctx1_in = Stream::wires(&m, "ref_ctx_in", ib + 1);
    let ctx1 = fifo(&m, "ref_ctx", ctx1_in, IN_FLIGHT);
    ref_req.valid.drive(walk & cur_valid & ctx1_in.ready);
    ref_req.data.drive(cur_idx);
    let issue = ref_req.fire().name("ref_issue");
    let idx_next = cur_idx.add(1, ib);
    let cur_last = idx_next.zext(ib + 1).eq(cur_end);
    let load =
        (walk & front.valid & !fo_marker & (!cur_valid | issue & cur_last)).name("range_load");
    let pop_marker =
        (walk & front.valid & fo_marker & !cur_valid & ctx1_in.ready).name("marker_pop");
    front.ready.drive(load | pop_marker);
    cur_valid.next(start.mux(
        lit(0, 1),
        load.mux(lit(1, 1), (issue & cur_last).mux(lit(0, 1), cur_valid)),
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
        .drive(m.concat(&[pop_marker, pop_marker.mux(zero_i, cur_parent)]));

    // ---- reference stage: check each answer, issue its `node` read
    let c1_end = ctx1.data.bit(ib);
    let c1_parent = ctx1.data.slice(ib - 1, 0);
    let ctx2_w = nk::BITS + fetch_err::BITS + rl.width();
    let ctx2_in = Stream::wires(&m, "node_ctx_in", ctx2_w);
    let ctx2 = fifo(&m, "node_ctx", ctx2_in, IN_FLIGHT);
    let r_node = field(ref_resp.data, rl.node())
        .expect("node")
        .name("resp_ref_node");
    let r_hier = field(ref_resp.data, rl.hier())
        .expect("hier")
        .name("resp_ref_hier");
    let ref_code = r_hier
        .ne(hier)
        .mux(
            code4(fetch_err::REF_HIER),
            r_node.ge(nodes).mux(code4(fetch_err::REF_NODE), code4(0)),
        )
        .name("ref_code");
    let rr_wait = (walk & ctx1.valid & !c1_end & ctx2_in.ready & node_req.ready).name("ref_wait");
    ref_resp.ready.drive(rr_wait);
    let rr_take = (rr_wait & ref_resp.valid).name("ref_take");
    let rr_end = (walk & ctx1.valid & c1_end & ctx2_in.ready).name("ref_stage_end");
    ctx1.ready.drive(rr_take | rr_end);
    let walk_node_req =
        (walk & ctx1.valid & !c1_end & ctx2_in.ready & ref_resp.valid & ref_code.eq(0))
            .name("walk_node_req");
    node_req.valid.drive(root_req_v | walk_node_req);
    node_req.data.drive(roots_ph.mux(issued, r_node));
    ctx2_in.valid.drive(rr_take | rr_end);
    ctx2_in.data.drive(rr_end.mux(
        m.concat(&[lit(nk::END, nk::BITS), code4(0), m.lit(0, rl.width())]),
        ref_code.eq(0).mux(
            m.concat(&[lit(nk::NODE, nk::BITS), code4(0), ref_resp.data]),
            m.concat(&[
                lit(nk::ERR, nk::BITS),
                ref_code,
                reference(&m, hier, c1_parent),
            ]),
        ),
    ));

    // ---- visit stage: the item at its head (top level: the header or
    // first root error, then the sorter; deeper: the reference stage's
    // word with its node's answer)
    let c2_ref = ctx2.data.slice(rl.width() - 1, 0);
    let c2_code = ctx2
        .data
        .slice(rl.width() + fetch_err::BITS - 1, rl.width());
    let c2_kind = ctx2.data.slice(ctx2_w - 1, ctx2_w - nk::BITS);
    let c2_node = c2_kind.eq(lit(nk::NODE, nk::BITS));
    let oin_w = ok::BITS + fetch_err::BITS + rl.width() + nl.width();
    let oin = Stream::wires(&m, "out_items_in", oin_w);
    let items = fifo(&m, "out_items", oin, 4);
    let live = (walk & !v_done).name("visit_live");
    // Ranges are followed above `lod`; levels `first..=lod` are sent, the
    // leaves above `first` go to `leaves`.
    let above = v_d.lt(c_lod).name("above_level");
    let above_first = v_d.lt(c_first).name("above_first");
    // Per-node: every level from the first pass on is a pass (`pn_pass`).
    let sending = match c_pn {
        Some(c) => !above_first & (v_d.le(c_lod) | c),
        None => !above_first & v_d.le(c_lod),
    }
    .name("sending_level");
    let pn_pass = c_pn.map(|c| (c & !above).name("pn_pass"));
    // The visit stage has sent a pass's `End` and waits for the join to
    // take the pass's `pass_end` (the next pass's nodes wait behind it).
    let pn_visited = c_pn.map(|_| m.reg("pn_visited", 1));
    // The pass's inner nodes (Morton code, range, node) for the join.
    // Per-node: an inner node of this pass, at Morton `key` (without the
    // walk's leading bit), with its child range; joined with the module's
    // decisions in key order.
    let pass_word = Word::new(&[
        ("key", key_bits - 1),
        ("first", ib),
        ("count", ib),
        ("node", ib),
    ]);
    let pass_in = c_pn.map(|_| Stream::wires(&m, "pass_in", pass_word.width()));
    // The `leaves` end beat leaves as soon as the visit stage is at the
    // first sent level (every node above it visited), before any item of
    // a sent level may wait on `out`: the merger's leaf merge then never
    // waits on a fetcher whose level beats wait on the merging module
    // (SPEC 8.15, the deadlock argument). A sent level's item waits for
    // it; above the first level only leaves need `leaves`.
    let lend_sent = m.reg("leaves_end_sent", 1);
    let lend_due = (live & c_leaves & !lend_sent & !above_first).name("leaves_end_due");
    let downstream =
        (oin.ready & front_in.ready & above_first.mux(leaves.ready, !c_leaves | lend_sent))
            .name("visit_room");
    // The sent levels' `End`s: `end_next` is the level owed next. The
    // levels above the top but the last hold no node: their `End`s go
    // first, before any item (`pre_ends`); a level's `End` goes with its
    // end marker while the walk goes on; at the walk's end every level
    // still owed gets its `End`, `lod`'s last (`FINAL`: the command is
    // over once it has left).
    let end_next = m.reg("end_next", lb);
    let fin_sent = m.reg("final_sent", 1);
    let pre_ends = (live & end_next.lt(top) & end_next.lt(c_lod)).name("pre_ends");
    let drain = (walk & v_done & !fin_sent).name("ends_drain");
    let end_emit = (pre_ends | drain).name("end_emit");
    let end_final = (drain & end_next.eq(c_lod)).name("end_final");
    let end_fire = (end_emit & oin.ready).name("end_fire");
    let top_err = v_top & rerr_valid;
    let top_hdr_end = v_top & !rerr_valid & hdr_err;
    let top_sorted = v_top & !rerr_valid & !hdr_err;
    let deep = !v_top;
    // The sorter drops roots beyond its capacity and says so at `End`; the
    // START check keeps that from happening, and this keeps it from passing
    // silently if it ever did (an error item before the `End`).
    let cap_told = m.reg("capacity_told", 1);
    let top_cap = (top_sorted & s_out_valid & s_end & s_err & !cap_told).name("sorter_dropped");
    let in_avail = (live
        & (top_err
            | top_hdr_end
            | top_sorted & s_out_valid
            | deep & ctx2.valid & (!c2_node | node_resp.valid)))
        .name("visit_avail");
    let visit_room = match (pn_visited, pass_in) {
        (Some(w), Some(e)) => downstream & !pre_ends & !w & e.ready,
        _ => downstream & !pre_ends,
    }
    .name("visit_free");
    let go = (in_avail & visit_room).name("visit_go");
    sorter.connect("out_ready", live & top_sorted & !top_cap & visit_room);
    cap_told.next(start.mux(lit(0, 1), (go & top_cap).mux(lit(1, 1), cap_told)));
    ctx2.ready
        .drive(live & deep & (!c2_node | node_resp.valid) & visit_room);
    node_resp
        .ready
        .drive(root_out & s_in_ready | live & deep & ctx2.valid & c2_node & visit_room);
    n_rerr_valid.when(go & top_err, lit(0, 1));
    let deep_fail = c2_node.mux(got_code.ne(0), c2_kind.eq(lit(nk::ERR, nk::BITS)));
    let in_err = (top_err | top_cap | deep & deep_fail).name("item_err");
    let in_end =
        (top_hdr_end | top_sorted & s_end & !top_cap | deep & c2_kind.eq(lit(nk::END, nk::BITS)))
            .name("item_end");
    let in_node = (!in_err & !in_end).name("item_node");
    let in_err_code = top_err.mux(
        rerr_code,
        top_cap.mux(
            code4(fetch_err::ROOT_CAPACITY),
            c2_node.mux(got_code, c2_code),
        ),
    );
    let c2_ref_node = field(c2_ref, rl.node()).expect("node");
    let in_err_node = top_err.mux(rerr_node, top_cap.mux(zero_i, c2_ref_node));
    let rec = v_top.mux(s_rec, got.moved).name("item_rec");
    let rec_ref = v_top.mux(s_ref, c2_ref).name("item_ref");
    let rec_idx = field(rec_ref, rl.node()).expect("node");

    let leaf = field(rec, nl.leaf()).expect("leaf").name("item_leaf");
    let inner = !leaf;
    let key = m
        .concat(&[morton_code(&m, coords(rec, nl)), leaf])
        .name("item_key");
    let n_first = field(rec, nl.first()).expect("first");
    let n_count = field(rec, nl.count()).expect("count");
    let n_end = n_first
        .zext(ib + 1)
        .add(n_count.zext(ib + 1), ib + 1)
        .name("item_range_end");
    let at_level = v_d.eq(c_lod).name("at_level");
    let order_bad = (prev_valid & key.le(prev_key)).name("order_bad");
    // A pass's inner nodes use their ranges (probes, references) and are
    // kept for the join, `frontier` of them at most per pass.
    let (uses_range, counted) = match pn_pass {
        Some(q) => (above | at_level & c_refs | q, above | q),
        None => (above | at_level & c_refs, above),
    };
    let range_bad = (inner & uses_range & n_end.gt(refs.zext(ib + 1))).name("range_bad");
    let front_bad = (inner & counted & pushed.ge(lit(fcap, cb))).name("frontier_bad");
    let visit_code = in_err.mux(
        in_err_code,
        in_end.mux(
            code4(0),
            order_bad.mux(
                code4(fetch_err::ORDER),
                range_bad.mux(
                    code4(fetch_err::RANGE),
                    front_bad.mux(code4(fetch_err::FRONTIER), code4(0)),
                ),
            ),
        ),
    );
    let visit_code = visit_code.name("visit_code");
    let err_node = in_err.mux(in_err_node, rec_idx);
    let fails = (go & visit_code.ne(0)).name("visit_fails");
    let passes = (go & in_node & visit_code.eq(0)).name("visit_passes");
    let push = (passes & above & inner).name("frontier_push");
    let leaf_out = (passes & above_first & leaf & c_leaves & !v_errored).name("leaf_out");
    let to_out = (passes & sending).name("to_out");
    let more = (above & pushed.ne(0)).name("next_level");
    let level_end = (go & in_end).name("level_end");
    // Per-node: a level end with nothing pushed (a pass's end, or the walk
    // run out above the first pass) is a pass's `End`; the command ends
    // with the join, not with the walk.
    let (walk_over, pn_end, ran_out) = match c_pn {
        Some(c) => {
            let ran_out = (level_end & !more).name("walk_ran_out");
            let pn_end = (ran_out & c).name("pn_pass_end");
            ((ran_out & !c).name("walk_over"), Some(pn_end), ran_out)
        }
        None => {
            let w = (level_end & !more).name("walk_over");
            (w, None, w)
        }
    };
    let marker = (level_end & more).name("marker_push");
    let pass_fifo = pn_pass.zip(pass_in).map(|(q, pass_in)| {
        let e_push = (passes & q & inner).name("pass_push");
        pass_in.valid.drive(e_push);
        let morton_part = key.slice(key_bits - 1, 1);
        pass_in
            .data
            .drive(pass_word.pack(&m, &[morton_part, n_first, n_count, rec_idx]));
        let depth = (fcap.max(2)).next_power_of_two() as u32;
        (e_push, fifo(&m, "pass", pass_in, depth))
    });
    let step_level = match pn_end {
        Some(e) => marker | e,
        None => marker,
    };
    let level_end_push = (marker & end_next.eq(v_d)).name("level_end_push");
    end_next.next(start.mux(
        c_first,
        (end_fire & !end_final | level_end_push).mux(end_next.add(1, lb), end_next),
    ));
    fin_sent.next(start.mux(lit(0, 1), (end_fire & end_final).mux(lit(1, 1), fin_sent)));

    prev_valid.next(start.mux(
        lit(0, 1),
        step_level.mux(lit(0, 1), (go & in_node).mux(lit(1, 1), prev_valid)),
    ));
    prev_key.next_when(go & in_node, key);
    let counted_push = match &pass_fifo {
        Some((e_push, _)) => push | *e_push,
        None => push,
    };
    pushed.next(start.mux(
        lit(0, cb),
        step_level.mux(lit(0, cb), counted_push.mux(pushed.add(1, cb), pushed)),
    ));
    v_d.next(start.mux(top, step_level.mux(v_d.add(1, lb), v_d)));
    v_top.next(start.mux(lit(1, 1), level_end.mux(lit(0, 1), v_top)));
    v_done.next(start.mux(lit(0, 1), walk_over.mux(lit(1, 1), v_done)));
    v_errored.next(start.mux(lit(0, 1), fails.mux(lit(1, 1), v_errored)));

    // ---- the join (per-node): the pass's inner nodes against the
    // module's decisions; a descending one's range goes on the frontier
    // for the next pass, whose end marker goes on at `pass_end` with
    // `more`. It pushes only while the visit stage is at a pass (which
    // pushes nothing there), so the two never push in one clock.
    let mut pn_end_left = None;
    let mut pn_join_take = None;
    match (&pass_fifo, &l.pn) {
        (Some((_, entries)), Some(f)) => {
            let report = Stream::input(&m, "report", f.report_width);
            let visited = pn_visited.expect("per-node");
            let end_left = m.reg("pn_end_left", 1);
            pn_end_left = Some(end_left);
            let r = |f: &golden::layout::Field| field(report.data, f).expect("report field");
            let r_key =
                morton_code(&m, [0, 1, 2].map(|a| r(&f.report_coord[a]))).name("report_key");
            let r_pe = r(&f.report_pass_end);
            let r_more = r(&f.report_more);
            // A voxel at D has no child voxels: never followed.
            let r_desc = r(&f.report_descend) & r(&f.report_lod).lt(lit(dmax, lb));
            let e_key = pass_word.get(entries.data, "key");
            let e_first = pass_word.get(entries.data, "first");
            let e_count = pass_word.get(entries.data, "count");
            let e_node = pass_word.get(entries.data, "node");
            let jv = (walk & c_pn.expect("per-node") & report.valid).name("join_valid");
            let dec = (jv & !r_pe).name("join_decision");
            let e_lt = (entries.valid & e_key.lt(r_key)).name("join_entry_before");
            let e_eq = (entries.valid & e_key.eq(r_key)).name("join_entry_at");
            let skip = (dec & e_lt | jv & r_pe & entries.valid).name("join_entry_stays");
            let matched = (dec & e_eq & (!r_desc | front_in.ready)).name("join_match");
            let j_push = (matched & r_desc).name("join_descend");
            let passed = (dec & (!entries.valid & visited | entries.valid & !e_lt & !e_eq))
                .name("join_other_voxel");
            let pe_take =
                (jv & r_pe & !entries.valid & visited & end_left & (!r_more | front_in.ready))
                    .name("join_pass_end");
            let j_marker = (pe_take & r_more).name("join_marker");
            entries.ready.drive(skip | matched);
            report.ready.drive(matched | passed | pe_take);
            front_in.valid.drive(push | marker | j_push | j_marker);
            front_in.data.drive((j_push | j_marker).mux(
                front_word.pack(&m, &[e_first, e_count, e_node, j_marker]),
                front_word.pack(&m, &[n_first, n_count, rec_idx, marker]),
            ));
            let pn_end = pn_end.expect("per-node");
            visited.next(start.mux(
                lit(0, 1),
                pn_end.mux(lit(1, 1), pe_take.mux(lit(0, 1), visited)),
            ));
            pn_join_take = Some(pe_take);
            n_phase.when(pe_take & !r_more, goto(ph::DONE));
        }
        _ => {
            front_in.valid.drive(push | marker);
            front_in
                .data
                .drive(front_word.pack(&m, &[n_first, n_count, rec_idx, marker]));
        }
    }
    let leaf_beat = with_fields(
        &m,
        m.lit(0, l.leaves_width),
        &[
            (l.leaf_rec, rec),
            (l.leaf_ref, rec_ref),
            (l.leaf_lod, field(rec, nl.lod()).expect("lod")),
        ],
    );
    let leaf_end_beat = with_fields(&m, m.lit(0, l.leaves_width), &[(l.leaf_end, lit(1, 1))]);
    // The end beat: the walk over above the first level, or it reached.
    // (Per-node: the walk may run out above the first pass once per pass.)
    let lend_out = match c_pn {
        Some(_) => ran_out & !lend_sent,
        None => walk_over,
    };
    let lend_fire =
        (lend_out & above_first & c_leaves | lend_due & leaves.ready).name("leaves_end_fire");
    lend_sent.next(start.mux(lit(0, 1), lend_fire.mux(lit(1, 1), lend_sent)));
    leaves
        .valid
        .drive(leaf_out | lend_out & above_first & c_leaves | lend_due);
    leaves.data.drive(leaf_out.mux(leaf_beat, leaf_end_beat));
    // Only the first error goes on: `out` drops what follows it, and so at
    // most one item enters `out_items` above the level (it never fills
    // there, so the walk above the level never waits on `out`).
    match pn_end {
        Some(e) => oin
            .valid
            .drive(to_out | fails & !v_errored | level_end_push | end_emit | e),
        None => oin
            .valid
            .drive(to_out | fails & !v_errored | level_end_push | end_emit),
    }
    oin.data.drive(
        m.concat(&[
            fails.mux(
                lit(ok::ERR, ok::BITS),
                end_final.mux(
                    lit(ok::FINAL, ok::BITS),
                    match pn_end {
                        Some(e) => level_end_push | end_emit | e,
                        None => level_end_push | end_emit,
                    }
                    .mux(lit(ok::LEVEL_END, ok::BITS), lit(ok::NODE, ok::BITS)),
                ),
            ),
            visit_code,
            fails.mux(reference(&m, hier, err_node), rec_ref),
            rec,
        ]),
    );

    // ---- out ordering stage: a voxel's inner node, its leaf, then the
    // inner node's child references (`cref` reads, one a clock)
    let o_rec = items.data.slice(nl.width() - 1, 0);
    let o_ref = items.data.slice(nl.width() + rl.width() - 1, nl.width());
    let o_code = items.data.slice(
        nl.width() + rl.width() + fetch_err::BITS - 1,
        nl.width() + rl.width(),
    );
    let o_kind = items.data.slice(oin_w - 1, oin_w - ok::BITS);
    let o_is_node = o_kind.eq(lit(ok::NODE, ok::BITS));
    let o_leaf = field(o_rec, nl.leaf()).expect("leaf");
    let o_voxel = m.concat(&[
        field(o_rec, nl.z()).expect("z"),
        field(o_rec, nl.y()).expect("y"),
        field(o_rec, nl.x()).expect("x"),
    ]);
    let o_first = field(o_rec, nl.first()).expect("first");
    let o_end = o_first.zext(ib + 1).add(
        field(o_rec, nl.count()).expect("count").zext(ib + 1),
        ib + 1,
    );
    let pend_valid = m.reg("pend_valid", 1);
    let pend_first = m.reg("pend_first", ib);
    let pend_end = m.reg("pend_end", ib + 1);
    let pend_voxel = m.reg("pend_voxel", 3 * p.coord_bits());
    let pend_node = m.reg("pend_node", ib);
    let cr_active = m.reg("cref_active", 1);
    let cr_idx = m.reg("cref_idx", ib);
    let cr_end = m.reg("cref_end", ib + 1);
    let cr_parent = m.reg("cref_parent", ib);
    let tok_w = ok::BITS + l.out_width;
    let tok_in = Stream::wires(&m, "out_tokens_in", tok_w);
    let toks = fifo(&m, "out_tokens", tok_in, 4);
    let can = (walk & tok_in.ready & cref_req.ready).name("order_room");
    let same_leaf = (pend_valid & o_is_node & o_leaf & o_voxel.eq(pend_voxel)).name("leaf_of_held");
    let a_cref = (can & cr_active).name("cref_next");
    let b_leaf = (can & !cr_active & items.valid & same_leaf).name("held_leaf");
    let c_flush =
        (can & !cr_active & items.valid & pend_valid & !same_leaf).name("held_refs_first");
    // Per-node: a pass's inner node first sends its probes, one `cref`
    // read a clock (a probe token beside each), then goes out as the
    // others (`probes_sent`).
    struct ProbeRun<'m> {
        active: Signal<'m>,
        sent: Signal<'m>,
        idx: Signal<'m>,
        end: Signal<'m>,
        parent: Signal<'m>,
        lod: Signal<'m>,
        begin_ok: Signal<'m>,
        begin: Signal<'m>,
        next: Signal<'m>,
    }
    let o_pn_inner = c_pn.map(|c| (o_is_node & !o_leaf & c).name("item_pass_inner"));
    let probe_run = o_pn_inner.map(|pi| {
        let active = m.reg("probe_active", 1);
        let sent = m.reg("probes_sent", 1);
        let begin_ok =
            (!cr_active & !active & items.valid & !pend_valid & pi & !sent).name("probe_first_ok");
        ProbeRun {
            active,
            sent,
            idx: m.reg("probe_idx", ib),
            end: m.reg("probe_end", ib + 1),
            parent: m.reg("probe_parent", ib),
            lod: m.reg("probe_lod", lb),
            begin_ok,
            begin: (can & begin_ok).name("probe_first"),
            next: (can & active).name("probe_next"),
        }
    });
    let d_item = match (&probe_run, o_pn_inner) {
        (Some(pr), Some(pi)) => {
            can & !cr_active & items.valid & !pend_valid & !pr.active & (!pi | pr.sent)
        }
        _ => can & !cr_active & items.valid & !pend_valid,
    }
    .name("item_out");
    items.ready.drive(b_leaf | d_item);
    match &probe_run {
        Some(pr) => {
            cref_req.valid.drive(
                walk & tok_in.ready
                    & (cr_active
                        | !cr_active & items.valid & pend_valid & !same_leaf
                        | pr.active
                        | pr.begin_ok),
            );
            cref_req.data.drive(pr.active.mux(
                pr.idx,
                pr.begin_ok.mux(o_first, cr_active.mux(cr_idx, pend_first)),
            ));
            let o_count = field(o_rec, nl.count()).expect("count");
            let idx_next = pr.idx.add(1, ib);
            let last = idx_next.zext(ib + 1).eq(pr.end);
            pr.active.next(start.mux(
                lit(0, 1),
                pr.next.mux(!last, pr.begin.mux(o_count.ne(1), pr.active)),
            ));
            pr.sent.next(
                start.mux(
                    lit(0, 1),
                    (pr.next & last | pr.begin & o_count.eq(1))
                        .mux(lit(1, 1), d_item.mux(lit(0, 1), pr.sent)),
                ),
            );
            pr.idx.next(
                pr.begin
                    .mux(o_first.add(1, ib), pr.next.mux(idx_next, pr.idx)),
            );
            pr.end.next_when(pr.begin, o_end);
            pr.parent
                .next_when(pr.begin, field(o_ref, rl.node()).expect("node"));
            pr.lod
                .next_when(pr.begin, field(o_rec, nl.lod()).expect("lod"));
        }
        None => {
            cref_req.valid.drive(
                walk & tok_in.ready
                    & (cr_active | !cr_active & items.valid & pend_valid & !same_leaf),
            );
            cref_req.data.drive(cr_active.mux(cr_idx, pend_first));
        }
    }
    let cr_next = cr_idx.add(1, ib);
    let pf_next = pend_first.add(1, ib);
    cr_active.next(start.mux(
        lit(0, 1),
        a_cref.mux(
            cr_next.zext(ib + 1).ne(cr_end),
            b_leaf.mux(
                lit(1, 1),
                c_flush.mux(pf_next.zext(ib + 1).ne(pend_end), cr_active),
            ),
        ),
    ));
    cr_idx.next(a_cref.mux(
        cr_next,
        b_leaf.mux(pend_first, c_flush.mux(pf_next, cr_idx)),
    ));
    cr_end.next_when(b_leaf | c_flush, pend_end);
    cr_parent.next_when(b_leaf | c_flush, pend_node);
    let hold = match c_pn {
        Some(c) => d_item & o_is_node & !o_leaf & (c_refs | c),
        None => d_item & o_is_node & !o_leaf & c_refs,
    }
    .name("hold_refs");
    pend_valid.next(start.mux(
        lit(0, 1),
        (b_leaf | c_flush).mux(lit(0, 1), hold.mux(lit(1, 1), pend_valid)),
    ));
    pend_first.next_when(hold, o_first);
    pend_end.next_when(hold, o_end);
    pend_voxel.next_when(hold, o_voxel);
    pend_node.next_when(hold, field(o_ref, rl.node()).expect("node"));
    let node_beat = out_beat(
        &m,
        &l,
        Some(o_rec),
        Some(o_ref),
        o_leaf.mux(
            lit(level_kind::LEAF, bl.kind.width),
            lit(level_kind::INNER, bl.kind.width),
        ),
        None,
    );
    let err_beat = out_beat(
        &m,
        &l,
        None,
        Some(o_ref),
        lit(level_kind::END, bl.kind.width),
        Some(o_code),
    );
    let end_out = out_beat(
        &m,
        &l,
        None,
        None,
        lit(level_kind::END, bl.kind.width),
        None,
    );
    let cref_tok = m.concat(&[
        lit(ok::TOK_CREF, ok::BITS),
        m.lit(0, l.out_width - ib),
        cr_active.mux(cr_parent, pend_node),
    ]);
    let item_tok = o_kind.eq(lit(ok::NODE, ok::BITS)).mux(
        m.concat(&[lit(ok::TOK_BEAT, ok::BITS), node_beat]),
        o_kind.eq(lit(ok::ERR, ok::BITS)).mux(
            m.concat(&[lit(ok::TOK_ERR, ok::BITS), err_beat]),
            o_kind.eq(lit(ok::FINAL, ok::BITS)).mux(
                m.concat(&[lit(ok::TOK_FINAL, ok::BITS), end_out]),
                m.concat(&[lit(ok::TOK_BEAT, ok::BITS), end_out]),
            ),
        ),
    );
    match &probe_run {
        Some(pr) => {
            // A probe token: a `cref` token with bit I set and the parent's
            // LOD above it.
            let probe_tok = m.concat(&[
                lit(ok::TOK_CREF, ok::BITS),
                m.lit(0, l.out_width - ib - 1 - lb),
                pr.begin.mux(field(o_rec, nl.lod()).expect("lod"), pr.lod),
                lit(1, 1),
                pr.begin
                    .mux(field(o_ref, rl.node()).expect("node"), pr.parent),
            ]);
            tok_in
                .valid
                .drive(a_cref | b_leaf | c_flush | d_item | pr.begin | pr.next);
            tok_in.data.drive(
                (pr.begin | pr.next).mux(probe_tok, (a_cref | c_flush).mux(cref_tok, item_tok)),
            );
        }
        None => {
            tok_in.valid.drive(a_cref | b_leaf | c_flush | d_item);
            tok_in
                .data
                .drive((a_cref | c_flush).mux(cref_tok, item_tok));
        }
    }

    let pn_ports = match &l.pn {
        None => {
            // ---- out stage: beats in order, the child references checked as
            // their answers come; after the error beat only the later levels'
            // `End`s, the first of them dropped (the error stands for it)
            let t_kind = toks.data.slice(tok_w - 1, tok_w - ok::BITS);
            let t_beat = toks.data.slice(l.out_width - 1, 0);
            let t_parent = toks.data.slice(ib - 1, 0);
            let t_cref = t_kind.eq(lit(ok::TOK_CREF, ok::BITS)).name("token_cref");
            let cr_node = field(cref_resp.data, rl.node()).expect("node");
            let cr_hier = field(cref_resp.data, rl.hier()).expect("hier");
            let cref_code = cr_hier
                .ne(hier)
                .mux(
                    code4(fetch_err::REF_HIER),
                    cr_node.ge(nodes).mux(code4(fetch_err::REF_NODE), code4(0)),
                )
                .name("cref_code");
            let answered = (!t_cref | cref_resp.valid).name("token_answered");
            let o_skip = m.reg("out_skip_end", 1);
            let t_end = (t_kind.eq(lit(ok::TOK_FINAL, ok::BITS))
                | t_kind.eq(lit(ok::TOK_BEAT, ok::BITS))
                    & field(t_beat, &bl.kind).expect("kind").eq(level_kind::END))
            .name("token_end");
            let t_send = (!o_errored | t_end & !o_skip).name("token_sent");
            let t_fire = (walk & toks.valid & answered & (!t_send | out.ready)).name("token_fire");
            toks.ready.drive(t_fire);
            cref_resp
                .ready
                .drive(walk & toks.valid & t_cref & (!t_send | out.ready));
            let child_beat = out_beat(
                &m,
                &l,
                None,
                Some(cref_resp.data),
                lit(level_kind::CHILD_REF, bl.kind.width),
                None,
            );
            let cref_err_beat = out_beat(
                &m,
                &l,
                None,
                Some(reference(&m, hier, t_parent)),
                lit(level_kind::END, bl.kind.width),
                Some(cref_code),
            );
            out.valid.drive(walk & toks.valid & answered & t_send);
            out.data
                .drive(t_cref.mux(cref_code.eq(0).mux(child_beat, cref_err_beat), t_beat));
            let errs = t_kind.eq(lit(ok::TOK_ERR, ok::BITS)) | t_cref & cref_code.ne(0);
            let first_err = (t_fire & errs & !o_errored).name("out_first_error");
            o_errored.next(start.mux(lit(0, 1), first_err.mux(lit(1, 1), o_errored)));
            o_skip.next(start.mux(
                lit(0, 1),
                first_err.mux(
                    lit(1, 1),
                    (t_fire & t_end & o_errored).mux(lit(0, 1), o_skip),
                ),
            ));
            n_phase.when(
                t_fire & t_kind.eq(lit(ok::TOK_FINAL, ok::BITS)),
                goto(ph::DONE),
            );

            None
        }
        Some(f) => Some(per_node_out_stages(
            &m,
            p,
            &l,
            f,
            OutStageIo {
                walk,
                start,
                hier,
                nodes,
                mv: &mv,
                toks,
                tok_w,
                cref_resp,
                out,
                o_errored,
            },
            &mut n_phase,
        )),
    };
    if let (Some(ps), Some(end_left), Some(take)) = (&pn_ports, pn_end_left, pn_join_take) {
        end_left.next(start.mux(
            lit(0, 1),
            take.mux(lit(0, 1), ps.end_fire.mux(lit(1, 1), end_left)),
        ));
    }

    // ---- DONE
    let done = is(ph::DONE);
    cfg_have.next(cfg_fire.mux(lit(1, 1), (done & c_last).mux(lit(0, 1), cfg_have)));
    n_phase.when(done, goto(ph::IDLE));

    node_req.skid_buffer("node_req_q").output("node_req");
    ref_req.skid_buffer("ref_req_q").output("ref_req");
    cref_req.skid_buffer("cref_req_q").output("cref_req");
    out.skid_buffer("out_q").output("out");
    leaves.skid_buffer("leaves_q").output("leaves");
    if let Some(ps) = pn_ports {
        ps.probe_req.skid_buffer("probe_req_q").output("probe_req");
    }
    m.output("idle", idle);

    for n in [n_phase, n_rerr_valid, n_rerr_code, n_rerr_node] {
        n.apply();
    }
    m
}

/// The signals the per-node out stages take from the fetcher.
struct OutStageIo<'a, 'm> {
    walk: Signal<'m>,
    start: Signal<'m>,
    hier: Signal<'m>,
    nodes: Signal<'m>,
    mv: &'a Move<'m>,
    toks: Stream<'m>,
    tok_w: u32,
    cref_resp: Stream<'m>,
    out: Stream<'m>,
    o_errored: Signal<'m>,
}

/// What the per-node out stages give back: the `probe` request stream
/// (its skid buffer and port are added with the others) and the clock in
/// which an `End` token leaves (the join's "the pass's `End` has left").
struct PerNodePorts<'m> {
    probe_req: Stream<'m>,
    end_fire: Signal<'m>,
}

/// The out stages of a fetcher built with the per-node command: the
/// **answer stage** takes each token with its `cref` answer, turning a
/// child-reference token into its beat (or the error naming the parent)
/// and a probe token into a `probe` read (its child's index and expected
/// LOD beside it in `out_probes`, 8 words), and the **send stage** sends
/// each beat in order, a probe's beat made from its `probe` answer (checked
/// at the parent's LOD + 1 and moved; an error names the child), with
/// [`fetcher_unit`]'s first-error rule.
fn per_node_out_stages<'m>(
    m: &'m Module,
    p: &Params,
    l: &FetchLayout,
    f: &golden::merge::fetch_unit::PerNodeFetchLayout,
    io: OutStageIo<'_, 'm>,
    n_phase: &mut Next<'m>,
) -> PerNodePorts<'m> {
    const IN_FLIGHT: u32 = 8;
    let (nl, rl, bl) = (&l.node, &l.reference, &l.beat);
    let (ib, lb) = (p.index_bits as u32, p.lod_bits());
    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let code4 = |c: u64| lit(c, fetch_err::BITS);
    let kind = |k: u64| lit(k, ok::BITS);
    let OutStageIo {
        walk,
        start,
        hier,
        nodes,
        mv,
        toks,
        tok_w,
        cref_resp,
        out,
        o_errored,
    } = io;
    // ---- answer stage
    let t_kind = toks.data.slice(tok_w - 1, tok_w - ok::BITS);
    let t_parent = toks.data.slice(ib - 1, 0);
    let t_cref = t_kind.eq(kind(ok::TOK_CREF)).name("token_cref");
    let t_probe = (t_cref & toks.data.bit(ib)).name("token_probe");
    let t_plod = toks.data.slice(ib + lb, ib + 1);
    let cr_node = field(cref_resp.data, rl.node()).expect("node");
    let cr_hier = field(cref_resp.data, rl.hier()).expect("hier");
    let cref_code = cr_hier
        .ne(hier)
        .mux(
            code4(fetch_err::REF_HIER),
            cr_node.ge(nodes).mux(code4(fetch_err::REF_NODE), code4(0)),
        )
        .name("cref_code");
    let cref_ok = cref_code.eq(0);
    let probe_req = Stream::wires(m, "probe_req_core", ib);
    let probe_resp = Stream::input(m, "probe_resp", nl.width());
    let tok2_in = Stream::wires(m, "out_probes_in", tok_w);
    let toks2 = fifo(m, "out_probes", tok2_in, IN_FLIGHT);
    let answered = (!t_cref | cref_resp.valid).name("token_answered");
    let room = (tok2_in.ready & (!t_probe | probe_req.ready)).name("answer_room");
    let a_fire = (walk & toks.valid & answered & room).name("token_fire");
    toks.ready.drive(a_fire);
    cref_resp.ready.drive(walk & toks.valid & t_cref & room);
    probe_req
        .valid
        .drive(walk & toks.valid & t_probe & cref_resp.valid & cref_ok & tok2_in.ready);
    probe_req.data.drive(cr_node);
    // The probe's LOD is its parent's + 1, carry kept (a child of a node at
    // the deepest LOD is never at a valid one).
    let want = t_plod.zext(lb + 1).add(1, lb + 1);
    let wait_tok = m.concat(&[
        kind(ok::TOK_CREF),
        m.lit(0, l.out_width - ib - lb - 1),
        want,
        cr_node,
    ]);
    let child_beat = out_beat(
        m,
        l,
        None,
        Some(cref_resp.data),
        lit(level_kind::CHILD_REF, bl.kind.width),
        None,
    );
    let cref_err_beat = out_beat(
        m,
        l,
        None,
        Some(reference(m, hier, t_parent)),
        lit(level_kind::END, bl.kind.width),
        Some(cref_code),
    );
    tok2_in.valid.drive(a_fire);
    tok2_in.data.drive(t_cref.mux(
        cref_ok.mux(
            t_probe.mux(wait_tok, m.concat(&[kind(ok::TOK_BEAT), child_beat])),
            m.concat(&[kind(ok::TOK_ERR), cref_err_beat]),
        ),
        toks.data,
    ));

    // ---- send stage: after the error beat only the later passes' `End`s,
    // the first of them dropped (the error stands for it)
    let k2 = toks2.data.slice(tok_w - 1, tok_w - ok::BITS);
    let b2 = toks2.data.slice(l.out_width - 1, 0);
    let t_wait = k2.eq(kind(ok::TOK_CREF)).name("token_probe_wait");
    let p_idx = toks2.data.slice(ib - 1, 0);
    let p_want = toks2.data.slice(ib + lb, ib);
    let got = check_and_move(m, p, l, probe_resp.data, p_want.slice(lb - 1, 0), mv);
    let p_code = p_want
        .bit(lb)
        .mux(code4(fetch_err::LOD), got.code)
        .name("probe_code");
    let p_ref = reference(m, hier, p_idx);
    let probe_beat = with_fields(
        m,
        m.lit(0, l.out_width),
        &[
            (bl.kind, lit(level_kind::INNER, bl.kind.width)),
            (bl.rec, got.moved),
            (bl.refer, p_ref),
            (f.probe, lit(1, 1)),
        ],
    );
    let probe_err = out_beat(
        m,
        l,
        None,
        Some(p_ref),
        lit(level_kind::END, bl.kind.width),
        Some(p_code),
    );
    let answered2 = (!t_wait | probe_resp.valid).name("probe_answered");
    let o_skip = m.reg("out_skip_end", 1);
    let t_end = (k2.eq(kind(ok::TOK_FINAL))
        | k2.eq(kind(ok::TOK_BEAT)) & field(b2, &bl.kind).expect("kind").eq(level_kind::END))
    .name("token_end");
    let t_send = (!o_errored | t_end & !o_skip).name("token_sent");
    let t_fire = (walk & toks2.valid & answered2 & (!t_send | out.ready)).name("send_fire");
    toks2.ready.drive(t_fire);
    probe_resp
        .ready
        .drive(walk & toks2.valid & t_wait & (!t_send | out.ready));
    out.valid.drive(walk & toks2.valid & answered2 & t_send);
    out.data
        .drive(t_wait.mux(p_code.eq(0).mux(probe_beat, probe_err), b2));
    let errs = k2.eq(kind(ok::TOK_ERR)) | t_wait & p_code.ne(0);
    let first_err = (t_fire & errs & !o_errored).name("out_first_error");
    o_errored.next(start.mux(lit(0, 1), first_err.mux(lit(1, 1), o_errored)));
    o_skip.next(start.mux(
        lit(0, 1),
        first_err.mux(
            lit(1, 1),
            (t_fire & t_end & o_errored).mux(lit(0, 1), o_skip),
        ),
    ));
    n_phase.when(t_fire & k2.eq(kind(ok::TOK_FINAL)), goto_done(m));
    PerNodePorts {
        probe_req,
        end_fire: (t_fire & t_end).name("pass_end_left"),
    }
}

/// The `DONE` phase's code.
fn goto_done(m: &Module) -> Signal<'_> {
    m.states(ph::BITS, ph::STATES).code(ph::DONE)
}
