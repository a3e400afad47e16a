//! Per-node merging (8.5, paragraph 55) built into the merging module
//! (SPEC.md section 8.14): the `per-node:N/D` configuration's merging
//! module, breadth first, one LOD pass at a time (golden
//! `merge::per_node::unit`).
//!
//! - [`per_node_network_unit`]: the k-way Morton merge of the pass streams,
//!   whose beats add `probe` (a child of the voxel's inner node) to S614's
//!   input beat; the key puts a voxel's probes first.
//! - [`per_node_decider_unit`]: counts `S` and `U` of each voxel from its
//!   probes (8-bit octant masks), reports every contested voxel's decision,
//!   drops a descending voxel's inner nodes and child references, and ends
//!   each pass with a report saying whether another follows.
//! - [`per_node_module_unit`]: `cfg`, `k` inputs, `report`, `out` around the
//!   network, the decider and S614 ([`super::merge_level_unit`]).
//!
//! Only this configuration instantiates these modules: the other modes'
//! merging modules hold no per-node logic.

use golden::merge::level_choice::unit::rank_bits;
use golden::merge::merge_level::unit::{base_kind, level_kind, BeatLayout};
use golden::merge::merge_module::{choice_err, TopLayout};
use golden::merge::per_node::unit::{PerNodeLayout, CHILD_COUNT_BITS};
use golden::params::Params;

use super::level_choice::times_constant;
use super::merge_module::merge_module_name;
use super::network::{morton_code, take_minimum_head, winner_rank, KeyOrder, MergeHead};
use super::{merge_level_unit, MergeConfig};
use crate::{Module, Signal, Stream};

/// Module name of the per-node merge network for `p` and `k` inputs.
pub fn per_node_network_name(p: &Params, k: usize) -> String {
    format!("per_node_network_{}_k{k}", p.tag())
}

/// Module name of the per-node decider for `p`, `k` inputs, `num / den`.
pub fn per_node_decider_name(p: &Params, k: usize, num: u32, den: u32) -> String {
    format!("per_node_decider_{}_k{k}_t{num}_{den}", p.tag())
}

/// The merge network of the per-node passes: streams `in0`..`in{k-1}` of
/// [`PerNodeLayout::input`] beats, stream `out` of `{rank, beat}`.
///
/// Each head's key is `{end, Morton code, phase}` with phase probe 0, inner
/// 1, leaf 2, child reference 3, and the lower rank wins a tie. A probe's
/// voxel is its parent's (its coordinates shifted right by one: a child
/// lies in its parent's voxel), a child reference's the last node taken
/// from its stream; so a voxel's probes (rank by rank), inner nodes, leaves
/// and references leave in that order. Like [`super::morton_merge_unit`], a
/// beat leaves only when every head is present, one per clock, its key made
/// as it enters its head; each pair's order is a register (hardware.md 14.7).
pub fn per_node_network_unit(p: &Params, k: usize) -> Module {
    let m = Module::new(&per_node_network_name(p, k));
    let pl = PerNodeLayout::new(p);
    let bl = &pl.beat;

    let out_ready = m.wire("net_out_ready", 1);
    let mut heads = Vec::with_capacity(k);
    let mut all_valid = m.lit(1, 1);
    let mut all_end = m.lit(1, 1);
    for i in 0..k {
        let head = MergeHead::new(
            &m,
            i,
            pl.input.width(),
            |d, parent| {
                let probe = d.view(&pl.probe).name(&format!("in{i}_probe"));
                let kind = beat_kind(d, bl).name(&format!("in{i}_kind"));
                let is_end = !probe & kind.eq(level_kind::END);
                let is_ref = !probe & kind.eq(level_kind::CHILD_REF);
                let xyz = beat_xyz(d, bl);
                let key_xyz =
                    [0, 1, 2].map(|a| probe.mux(xyz[a].srl(1), is_ref.mux(parent[a], xyz[a])));
                let phase = probe.mux(m.lit(0, 2), kind.add(1, 2));
                m.concat(&[is_end, morton_code(&m, key_xyz), phase])
            },
            |d| !d.view(&pl.probe) & !beat_kind(d, bl).bit(1),
            |d| beat_xyz(d, bl),
        );
        let is_end = head
            .key()
            .bit(head.key_bits - 1)
            .name(&format!("in{i}_is_end"));
        all_valid = all_valid & head.stream.valid;
        all_end = all_end & is_end;
        heads.push(head);
    }
    let all_valid = all_valid.name("all_heads");
    let (wins, beat) = take_minimum_head(
        &m,
        &heads,
        all_valid,
        all_end,
        out_ready,
        KeyOrder::Registered,
    );
    Stream {
        valid: all_valid,
        ready: out_ready,
        data: m.concat(&[winner_rank(&m, &wins), beat]).name("net_beat"),
    }
    .skid_buffer("out_skid")
    .output("out");
    m
}

/// The kind of the beat in a head's `{probe, beat}`.
fn beat_kind<'m>(d: Signal<'m>, bl: &BeatLayout) -> Signal<'m> {
    d.slice(bl.width() - 1, 0).view(&bl.kind)
}

/// The voxel of the record in a head's `{probe, beat}`.
fn beat_xyz<'m>(d: Signal<'m>, bl: &BeatLayout) -> [Signal<'m>; 3] {
    let beat = d.slice(bl.width() - 1, 0);
    beat.view(&bl.rec).coords(&bl.node)
}

/// The number of set bits of an 8-bit mask, [`CHILD_COUNT_BITS`] wide.
fn popcount8<'m>(m: &'m Module, mask: Signal<'m>) -> Signal<'m> {
    let w = CHILD_COUNT_BITS;
    (0..8).fold(m.lit(0, w), |acc, b| acc.add(mask.bit(b).zext(w), w))
}

/// The one-hot 8-bit mask of the octant `{z, y, x}` (bit 0 of each
/// coordinate: where a child lies in its parent's voxel).
fn octant_mask<'m>(m: &'m Module, xyz: &[Signal<'m>; 3]) -> Signal<'m> {
    let oct = m.concat(&[xyz[2].bit(0), xyz[1].bit(0), xyz[0].bit(0)]);
    let high_first: Vec<Signal> = (0..8u64).rev().map(|j| oct.eq(j)).collect();
    m.concat(&high_first)
}

/// The per-node decider for `p`, `k` inputs and `num / den`: stream `in` of
/// the network's `{rank, beat}`, stream `out` of S614 input beats, stream
/// `report` of [`PerNodeLayout`] report beats; inputs `start`, `start_lod`
/// (a merge begins: its first pass is `start_lod`); outputs `pass_taken`
/// (an `End` was taken) and `last_taken` (it ends the merge's last pass).
///
/// A run of probe beats is one voxel's (they lead its beats). Over the run
/// it keeps the octants of earlier ranks (`any`), of the current rank
/// (`cur`), the octants met again under another rank (`multi`) and whether a
/// second rank came (`many`: two or more inner nodes, as every inner node
/// has a child). The beat after the run decides: `S` = `|multi|`, `U` =
/// `|any | cur|`, descend = `many` and `S * den > num * U`; a contested
/// voxel's decision leaves on `report` with that beat. While descending, the
/// voxel's inner nodes and child references are taken and dropped (its
/// leaves go on: they stay at the voxel). `End` passes with a `report` beat:
/// `more` = some voxel of the pass descended and the pass is above `D`.
pub fn per_node_decider_unit(p: &Params, k: usize, num: u32, den: u32) -> Module {
    let m = Module::new(&per_node_decider_name(p, k, num, den));
    let pl = PerNodeLayout::new(p);
    let bl = &pl.beat;
    let rb = rank_bits(k);
    let lb = p.lod_bits();
    let lit = |v: u64, w: u32| m.lit(v as u128, w);

    let start = m.input("start", 1);
    let start_lod = m.input("start_lod", lb);
    let input = Stream::input(&m, "in", pl.input.width() + rb);
    let beat = input.data.slice(bl.width() - 1, 0).name("in_beat");
    let probe = input.data.view(&pl.probe).name("in_probe");
    let rank = input
        .data
        .slice(pl.input.width() + rb - 1, pl.input.width())
        .name("in_rank");
    let kind = beat.view(&bl.kind).name("in_kind");
    let is_end = (!probe & kind.eq(level_kind::END)).name("in_is_end");
    let is_inner = !probe & kind.eq(level_kind::INNER);
    let is_ref = !probe & kind.eq(level_kind::CHILD_REF);
    let xyz = beat.view(&bl.rec).coords(&bl.node);

    let run = m.reg("probe_run", 1);
    let g_any = m.reg("g_any", 8);
    let g_cur = m.reg("g_cur", 8);
    let g_multi = m.reg("g_multi", 8);
    let g_rank = m.reg("g_rank", rb);
    let g_many = m.reg("g_many", 1);
    let g_voxel: [Signal; 3] =
        [0, 1, 2].map(|a| m.reg(&format!("g_{}", ["x", "y", "z"][a]), xyz[a].width()));
    let dropping = m.reg("dropping", 1);
    let descended = m.reg("pass_descended", 1);
    let lod = m.reg("pass_lod", lb);

    // The decision of the voxel whose probes just ended.
    let shared = popcount8(&m, g_multi).name("voxel_shared");
    let union = popcount8(&m, g_any | g_cur).name("voxel_union");
    let pw = CHILD_COUNT_BITS + 33;
    let above = times_constant(&m, shared, den, pw)
        .gt(times_constant(&m, union, num, pw))
        .name("voxel_above");
    let descend = (g_many & above).name("voxel_descends");
    let after_run = (run & !probe).name("after_probes");
    let decision = (after_run & g_many).name("decision");
    let drop_now = after_run.mux(descend, dropping);
    let dropped = (drop_now & (is_inner | is_ref)).name("dropped");
    let to_out = (!probe & !dropped).name("to_out");
    let more =
        ((descended | (after_run & descend)) & lod.ne(lit(p.max_lod as u64, lb))).name("more");
    let needs_report = (decision | is_end).name("needs_report");

    let out_ready = m.wire("out_in_ready", 1);
    let report_ready = m.wire("report_in_ready", 1);
    let out_ok = !to_out | out_ready;
    let report_ok = !needs_report | report_ready;
    let fire = (input.valid & out_ok & report_ok).name("fire");
    input.ready.drive(out_ok & report_ok);

    Stream {
        valid: (input.valid & to_out & report_ok).name("out_in_valid"),
        ready: out_ready,
        data: beat,
    }
    .skid_buffer("out_skid")
    .output("out");

    let report_data = lit(0, pl.report.width()).with_fields(&[
        (pl.coord[0], g_voxel[0]),
        (pl.coord[1], g_voxel[1]),
        (pl.coord[2], g_voxel[2]),
        (pl.lod, lod),
        (pl.shared, is_end.mux(lit(0, CHILD_COUNT_BITS), shared)),
        (pl.union, is_end.mux(lit(0, CHILD_COUNT_BITS), union)),
        (pl.descend, !is_end & descend),
        (pl.pass_end, is_end),
        (pl.more, is_end & more),
    ]);
    // A pass-end beat carries no voxel.
    let voxel_bits = pl.coord[2].end();
    let report_data = is_end
        .mux(
            m.concat(&[
                report_data.slice(pl.report.width() - 1, voxel_bits),
                lit(0, voxel_bits),
            ]),
            report_data,
        )
        .name("report_beat");
    Stream {
        valid: (input.valid & needs_report & out_ok).name("report_in_valid"),
        ready: report_ready,
        data: report_data,
    }
    .skid_buffer("report_skid")
    .output("report");

    // The probe run: a probe after a non-probe opens a voxel.
    let take_probe = (fire & probe).name("take_probe");
    let opens = !run;
    let new_rank = g_rank.ne(rank);
    let onehot = octant_mask(&m, &xyz).name("probe_octant");
    let before = new_rank.mux(g_any | g_cur, g_any);
    let zero8 = lit(0, 8);
    g_any.next_when(take_probe, opens.mux(zero8, before));
    g_cur.next_when(take_probe, (opens | new_rank).mux(onehot, g_cur | onehot));
    g_multi.next_when(take_probe, opens.mux(zero8, g_multi | (before & onehot)));
    g_rank.next_when(take_probe, rank);
    g_many.next_when(take_probe, !opens & (g_many | new_rank));
    for a in 0..3 {
        g_voxel[a].next_when(take_probe & opens, xyz[a].srl(1));
    }
    run.next_when(fire, probe);
    let lit1 = lit(1, 1);
    let lit0 = lit(0, 1);
    dropping.next(start.mux(
        lit0,
        fire.mux(is_end.mux(lit0, after_run.mux(descend, dropping)), dropping),
    ));
    descended.next(start.mux(
        lit0,
        fire.mux(
            is_end.mux(lit0, (after_run & descend).mux(lit1, descended)),
            descended,
        ),
    ));
    let pass_taken = (fire & is_end).name("pass_taken_now");
    lod.next(start.mux(start_lod, (pass_taken & more).mux(lod.add(1, lb), lod)));
    m.output("pass_taken", pass_taken);
    m.output("last_taken", (pass_taken & !more).name("last_taken_now"));
    m
}

/// FSM states of the per-node merging module.
mod state {
    pub const IDLE: u64 = 0;
    pub const RUN: u64 = 1;
    pub const REFUSE: u64 = 2;
    /// Every state by name (the Verilog's `localparam`s).
    pub const STATES: &[(&str, u64)] = &[("IDLE", IDLE), ("RUN", RUN), ("REFUSE", REFUSE)];
}

/// The merging module of a `per-node:num/den` configuration `c` (named
/// like every merging module, [`merge_module_name`]): streams `cfg` (8.10's
/// `(lo, hi)`), `in0`..`in{k-1}` ([`PerNodeLayout`] beats), `report`
/// ([`PerNodeLayout`]), `out` (S614's output beats, `End` per pass);
/// status `idle`, `done`.
///
/// A `cfg` with `lo > hi` or `hi > D` is refused with one `report` beat
/// (`err` 3). Otherwise the passes run from `lo` until one ends without a
/// descent; the merge is done when that pass's `End` leaves `out`.
pub fn per_node_module_unit(c: &MergeConfig, num: u32, den: u32) -> Module {
    let p = &c.params;
    let k = c.inputs;
    let m = Module::new(&merge_module_name(c));
    let tl = TopLayout::new(p);
    let pl = PerNodeLayout::new(p);
    let lb = p.lod_bits();
    let lit = |v: u64, w: u32| m.lit(v as u128, w);

    let st = m.reg("state", 2);
    let states = m.states(2, state::STATES);
    let in_state = |s: u64| states.is(st, s);
    let idle = in_state(state::IDLE).name("is_idle");
    let running = in_state(state::RUN).name("is_run");
    let refusing = in_state(state::REFUSE).name("is_refuse");

    let net = m.instance("u_network", &per_node_network_unit(p, k));
    for i in 0..k {
        let s = Stream::input(&m, &format!("in{i}"), pl.input.width());
        net.connect(&format!("in{i}_valid"), s.valid);
        net.connect(&format!("in{i}_data"), s.data);
        s.ready.drive(net.output(&format!("in{i}_ready")));
    }

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

    // The last pass's End has entered the decider: the network waits for
    // the next merge.
    let final_taken = m.reg("final_taken", 1);
    let dec = m.instance("u_decider", &per_node_decider_unit(p, k, num, den));
    dec.connect("start", cfg_fire & !bad_range);
    dec.connect("start_lod", cfg_lo);
    let feeding = (running & !final_taken).name("feeding");
    dec.connect("in_valid", feeding & net.output("out_valid"));
    dec.connect("in_data", net.output("out_data"));
    net.connect("out_ready", feeding & dec.output("in_ready"));

    let ml = m.instance("u_merge_level", &merge_level_unit(p));
    ml.connect("in_valid", dec.output("out_valid"));
    ml.connect("in_data", dec.output("out_data"));
    dec.connect("out_ready", ml.output("in_ready"));
    let out_ready = m.input("out_ready", 1);
    ml.connect("out_ready", out_ready);
    let out_valid = ml.output("out_valid");
    let out_data = ml.output("out_data");
    m.output("out_valid", out_valid);
    m.output("out_data", out_data);
    let ol = BeatLayout::output(p);
    let out_end =
        (out_valid & out_ready & out_data.view(&ol.kind).eq(base_kind::END)).name("out_end");

    // Passes whose End entered the decider and has not left `out`.
    let fw = lb + 1;
    let in_flight = m.reg("passes_in_flight", fw);
    let entered = dec.output("pass_taken");
    in_flight.next(
        in_flight
            .add(entered.zext(fw), fw)
            .sub(out_end.zext(fw), fw),
    );
    let merge_done = (out_end & final_taken & in_flight.eq(lit(1, fw))).name("merge_done");
    final_taken.next(cfg_fire.mux(
        lit(0, 1),
        dec.output("last_taken").mux(lit(1, 1), final_taken),
    ));

    // report: the decider's beats, or the refusal.
    let report_in_ready = m.wire("report_in_ready", 1);
    let dec_valid = dec.output("report_valid");
    let refusal = lit(0, pl.report.width()).with_fields(&[
        (pl.pass_end, lit(1, 1)),
        (pl.err, lit(choice_err::BAD_RANGE, 2)),
    ]);
    dec.connect("report_ready", report_in_ready);
    let refused = (refusing & !dec_valid & report_in_ready).name("refusal_sent");
    Stream {
        valid: (dec_valid | refusing).name("report_in_valid"),
        ready: report_in_ready,
        data: dec_valid
            .mux(dec.output("report_data"), refusal)
            .name("report_in_data"),
    }
    .skid_buffer("report_skid")
    .output("report");

    // IDLE -(cfg)-> RUN, or REFUSE on a bad range; REFUSE -(sent)-> IDLE;
    // RUN -(the last pass's End out)-> IDLE.
    let after_cfg = bad_range.mux(states.code(state::REFUSE), states.code(state::RUN));
    st.next(cfg_fire.mux(
        after_cfg,
        (refused | merge_done).mux(states.code(state::IDLE), st),
    ));
    m.output("idle", idle);
    let done = m.reg("done_pulse", 1);
    done.next(merge_done | refused);
    m.output("done", done);
    m
}
