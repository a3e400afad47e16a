//! The merging module as one unit (FIG. 5's module with its merging level
//! determining unit 508 and merging determination unit 506; SPEC.md
//! section 8.10): `cfg`, `k` input streams, `report` and `out`, around three
//! instances: the k-way Morton merge ([`super::morton_merge_unit`]), the
//! overlap counter ([`super::overlap_counter_unit`], overlap mode only) and
//! S614 ([`super::merge_level_unit`]).
//!
//! One merge: a `cfg` beat `(lo, hi)`; in overlap mode the count pass (each
//! candidate level `lo..=hi` on every input, each level one `report` beat);
//! the choice (one `report` beat with `chosen`); unless refused, the merge
//! pass (the chosen level on every input, S614's beats on `out`, `End`
//! last). The mode is built in: a configuration holds only its own choice
//! logic, and no overlap counter unless it counts.

use golden::merge::level_choice::choose_level;
use golden::merge::level_choice::unit::{rank_bits, OverlapLayout};
use golden::merge::merge_level::unit::{base_kind, level_kind, BeatLayout};
use golden::merge::merge_module::{choice_err, TopLayout};
use golden::merge::MergeMode;
use golden::params::Params;

use super::{merge_level_unit, morton_merge_unit, overlap_counter_unit, MergeConfig};
use crate::{Module, Signal, Stream};

/// FSM states of the unit.
mod state {
    pub const IDLE: u64 = 0;
    pub const COUNT: u64 = 1;
    pub const CHOOSE: u64 = 2;
    pub const MERGE: u64 = 3;
    /// Every state by name (the Verilog's `localparam`s).
    pub const STATES: &[(&str, u64)] = &[
        ("IDLE", IDLE),
        ("COUNT", COUNT),
        ("CHOOSE", CHOOSE),
        ("MERGE", MERGE),
    ];
}

/// The mode's part of a module name: `ov1_2`, `fix5`, `bt2`, `pr1_2`.
fn mode_tag(mode: &MergeMode) -> String {
    match *mode {
        MergeMode::Overlap { num, den } => format!("ov{num}_{den}"),
        MergeMode::Fixed(l) => format!("fix{l}"),
        MergeMode::BelowTop(k) => format!("bt{k}"),
        MergeMode::Proportion { num, den } => format!("pr{num}_{den}"),
        MergeMode::PerNode { num, den } => format!("pn{num}_{den}"),
    }
}

/// Module name of the merging module for `c`.
pub fn merge_module_name(c: &MergeConfig) -> String {
    format!(
        "merge_module_{}_k{}_{}",
        c.params.tag(),
        c.inputs,
        mode_tag(&c.mode)
    )
}

/// The choice of a level mode other than overlap from `(lo, hi)` (a valid
/// range): `(lod, refused)`, exactly golden `choose_level`.
fn choose_from_range<'m>(
    m: &'m Module,
    p: &Params,
    mode: &MergeMode,
    lo: Signal<'m>,
    hi: Signal<'m>,
) -> (Signal<'m>, Signal<'m>) {
    let lb = lo.width();
    match *mode {
        MergeMode::Fixed(l) => {
            let level = m.lit(l as u128, lb);
            (level, level.lt(lo) | level.gt(hi))
        }
        MergeMode::BelowTop(k) => {
            // lo + k in 9 bits: k is a u8.
            let w = lb.max(8) + 1;
            let deep = lo.zext(w).add(m.lit(k as u128, w), w).name("below_top");
            (deep.slice(lb - 1, 0), deep.gt(hi.zext(w)))
        }
        MergeMode::Proportion { .. } => {
            // The depth below `lo` for every depth `hi - lo` the range can
            // have, from golden's own `choose_level` over `[0, j]`: a
            // constant table indexed by hi - lo.
            let depth = hi.sub(lo, lb).name("range_depth");
            let table: Vec<Signal> = (0..1u64 << lb)
                .map(|j| {
                    let v = u8::try_from(j)
                        .ok()
                        .filter(|&j| j <= p.max_lod)
                        .and_then(|j| choose_level(mode, 0, j, &[]).ok().flatten())
                        .unwrap_or(0);
                    m.lit(v as u128, lb)
                })
                .collect();
            let below = depth.select(&table).name("proportion_depth");
            (lo.add(below, lb), m.lit(0, 1))
        }
        MergeMode::Overlap { .. } | MergeMode::PerNode { .. } => {
            unreachable!("the overlap choice is the count pass's; per-node has its own module")
        }
    }
}

/// The merging module for `c` (validated with `MergeConfig::validate`). A
/// `per-node:N/D` configuration is [`super::per_node_module_unit`]'s: per-node
/// logic only there.
pub fn merge_module_unit(c: &MergeConfig) -> Module {
    if let MergeMode::PerNode { num, den } = c.mode {
        return super::per_node_module_unit(c, num, den);
    }
    let p = &c.params;
    let k = c.inputs;
    let m = Module::new(&merge_module_name(c));
    let tl = TopLayout::new(p);
    let bl = BeatLayout::input(p);
    let lb = p.lod_bits();
    let rb = rank_bits(k);
    let lit = |v: u64, w: u32| m.lit(v as u128, w);

    let st = m.reg("state", 2);
    let states = m.states(2, state::STATES);
    let in_state = |s: u64| states.is(st, s);
    let idle = in_state(state::IDLE).name("is_idle");
    let choosing = in_state(state::CHOOSE).name("is_choose");
    let merging = in_state(state::MERGE).name("is_merge");

    // The k input streams into the merge network.
    let counts = c.threshold().is_some();
    let net = m.instance("u_network", &morton_merge_unit(p, k, counts));
    for i in 0..k {
        let s = Stream::input(&m, &format!("in{i}"), bl.width());
        net.connect(&format!("in{i}_valid"), s.valid);
        net.connect(&format!("in{i}_data"), s.data);
        s.ready.drive(net.output(&format!("in{i}_ready")));
    }
    let net_valid = net.output("out_valid");
    let net_data = net.output("out_data");
    let net_beat = net_data.slice(bl.width() - 1, 0).name("net_beat");

    // cfg: accepted when idle.
    let cfg = Stream::input(&m, "cfg", tl.cfg.width());
    cfg.ready.drive(idle);
    let cfg_fire = cfg.fire().name("cfg_fire");
    let cfg_lo = cfg.data.view(&tl.lo).name("cfg_lo");
    let cfg_hi = cfg.data.view(&tl.hi).name("cfg_hi");
    // `hi > D` only when the field can hold it (D = 31 fills 5 bits).
    let beyond = if (1u64 << lb) - 1 > p.max_lod as u64 {
        cfg_hi.gt(lit(p.max_lod as u64, lb))
    } else {
        lit(0, 1)
    };
    let bad_range = (cfg_lo.gt(cfg_hi) | beyond).name("bad_range");

    // The choice, written when known, reported in CHOOSE.
    let choice_lod = m.reg("choice_lod", lb);
    let choice_err_r = m.reg("choice_err", 2);
    let report_in_ready = m.wire("report_in_ready", 1);
    let ml = m.instance("u_merge_level", &merge_level_unit(p));

    let (report_valid, report_data, count_done) = if let Some((num, den)) = c.threshold() {
        let ol = OverlapLayout::new(p, k);
        let counting = in_state(state::COUNT).name("is_count");
        // The deepest candidate: the count pass ends there.
        let hi = m.reg("hi", lb);
        hi.next_when(cfg_fire, cfg_hi);
        let net_rank = net_data
            .slice(bl.width() + rb - 1, bl.width())
            .name("net_rank");
        let net_kind = net_beat.view(&bl.kind).name("net_kind");
        let net_end = net_kind.eq(level_kind::END).name("net_end");
        let net_ref = net_kind.eq(level_kind::CHILD_REF).name("net_ref");
        let counter = m.instance("u_overlap", &overlap_counter_unit(p, k, num, den));
        // Levels still to send and to report, LOD of each.
        let sending = m.reg("sending", 1);
        let send_lod = m.reg("send_lod", lb);
        let res_lod = m.reg("result_lod", lb);
        let best = m.reg("best_lod", lb);
        let overflowed = m.reg("count_overflowed", 1);

        let rec = net_beat.view(&bl.rec);
        let xyz: Vec<Signal> = (0..3).map(|a| rec.view(bl.node.coord(a))).collect();
        let d = p.coord_bits();
        let count_beat = m
            .concat(&[net_end, net_rank, xyz[2], xyz[1], xyz[0]])
            .name("count_beat");
        debug_assert_eq!(count_beat.width(), ol.input.width());
        debug_assert_eq!(xyz[0].width(), d);
        let to_counter = (counting & sending & net_valid & !net_ref).name("to_counter_valid");
        counter.connect("in_valid", to_counter);
        counter.connect("in_data", count_beat);
        let counter_ready = counter.output("in_ready");
        // A child reference in the count pass is taken and dropped.
        let count_take = (counting & sending & (net_ref | counter_ready)).name("count_take");
        let sent_end = (to_counter & counter_ready & net_end).name("count_level_sent");
        sending.next(cfg_fire.mux(
            !bad_range,
            (sent_end & send_lod.eq(hi)).mux(lit(0, 1), sending),
        ));
        send_lod.next(cfg_fire.mux(cfg_lo, sent_end.mux(send_lod.add(1, lb), send_lod)));

        let res_valid = counter.output("out_valid");
        let res = counter.output("out_data");
        let above = res.view(&ol.above);
        let ovf = res.view(&ol.overflow);
        let shown = (counting & res_valid).name("result_valid");
        counter.connect("out_ready", counting & report_in_ready);
        let took = (shown & report_in_ready).name("result_taken");
        let last = (took & res_lod.eq(hi)).name("count_done");
        res_lod.next(cfg_fire.mux(cfg_lo, took.mux(res_lod.add(1, lb), res_lod)));
        let best_next = (above & !ovf).mux(res_lod, best);
        best.next(cfg_fire.mux(cfg_lo, took.mux(best_next, best)));
        let ovf_next = overflowed | ovf;
        overflowed.next(cfg_fire.mux(lit(0, 1), took.mux(ovf_next, overflowed)));
        choice_lod.next(cfg_fire.mux(
            lit(0, lb),
            last.mux(ovf_next.mux(lit(0, lb), best_next), choice_lod),
        ));
        choice_err_r.next(cfg_fire.mux(
            bad_range.mux(lit(choice_err::BAD_RANGE, 2), lit(choice_err::NONE, 2)),
            last.mux(
                ovf_next.mux(lit(choice_err::COUNT_OVERFLOW, 2), lit(choice_err::NONE, 2)),
                choice_err_r,
            ),
        ));
        // A counted level: lod, the counter's shared/union/above/overflow.
        let counted = m.concat(&[lit(0, 3), res.slice(ol.output.width() - 1, 0), res_lod]);
        let chosen = m.concat(&[
            choice_err_r,
            lit(1, 1),
            lit(0, ol.output.width()),
            choice_lod,
        ]);
        let data = counting.mux(counted, chosen);
        (shown | choosing, data, Some((count_take, last)))
    } else {
        let (lod, refused) = choose_from_range(&m, p, &c.mode, cfg_lo, cfg_hi);
        let err = bad_range.mux(
            lit(choice_err::BAD_RANGE, 2),
            refused.mux(lit(choice_err::NOT_CANDIDATE, 2), lit(choice_err::NONE, 2)),
        );
        let ok = err.eq(lit(choice_err::NONE, 2));
        choice_lod.next_when(cfg_fire, ok.mux(lod, lit(0, lb)));
        choice_err_r.next_when(cfg_fire, err);
        let i = p.index_bits as u32;
        let chosen = m.concat(&[choice_err_r, lit(1, 1), lit(0, 2 * i + 2), choice_lod]);
        (choosing, chosen, None)
    };
    debug_assert_eq!(report_data.width(), tl.report.width());
    let report = Stream {
        valid: report_valid.name("report_in_valid"),
        ready: report_in_ready,
        data: report_data.name("report_in_data"),
    };
    let choice_fire = (choosing & report_in_ready).name("choice_reported");
    report.skid_buffer("report_skid").output("report");

    // The merge pass: the network into S614, S614 out.
    // The merge pass is one level: after its End, the next merge's beats
    // wait in the network until the unit is idle again.
    let feeding = m.reg("merge_feeding", 1);
    let to_ml = (merging & feeding & net_valid).name("to_merge_level_valid");
    ml.connect("in_valid", to_ml);
    ml.connect("in_data", net_beat);
    let ml_ready = ml.output("in_ready");
    let out_valid = ml.output("out_valid");
    let out_data = ml.output("out_data");
    let ol_ = BeatLayout::output(p);
    let out_ready = m.input("out_ready", 1);
    ml.connect("out_ready", out_ready);
    m.output("out_valid", out_valid);
    m.output("out_data", out_data);
    let out_kind = out_data.view(&ol_.kind);
    let merge_done = (out_valid & out_ready & out_kind.eq(base_kind::END)).name("merge_done");

    let (count_take, count_done) = match count_done {
        Some((take, done)) => (take, done),
        None => (lit(0, 1), lit(0, 1)),
    };
    net.connect("out_ready", merging.mux(feeding & ml_ready, count_take));
    let net_kind = net_beat.view(&bl.kind);
    let level_in = (to_ml & ml_ready & net_kind.eq(level_kind::END)).name("merge_level_sent");
    feeding.next(choice_fire.mux(lit(1, 1), level_in.mux(lit(0, 1), feeding)));

    // IDLE -(cfg)-> COUNT (overlap, good range) or CHOOSE; COUNT -(last
    // result)-> CHOOSE; CHOOSE -(reported)-> MERGE, or IDLE when refused;
    // MERGE -(End out)-> IDLE.
    let after_cfg = if counts {
        bad_range.mux(states.code(state::CHOOSE), states.code(state::COUNT))
    } else {
        states.code(state::CHOOSE)
    };
    let after_choice = choice_err_r
        .eq(lit(choice_err::NONE, 2))
        .mux(states.code(state::MERGE), states.code(state::IDLE));
    let next = cfg_fire.mux(
        after_cfg,
        count_done.mux(
            states.code(state::CHOOSE),
            choice_fire.mux(after_choice, merge_done.mux(states.code(state::IDLE), st)),
        ),
    );
    st.next(next);
    m.output("idle", idle);
    // One clock high after a merge ends: its End left on `out`, or its
    // refusal left on `report`.
    let done = m.reg("done_pulse", 1);
    done.next(merge_done | (choice_fire & !choice_err_r.eq(lit(choice_err::NONE, 2))));
    m.output("done", done);
    m
}
