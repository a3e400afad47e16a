//! The proofs the project runs (`hiermerge formal`, SPEC 11.1): the stream
//! primitives of [`crate::Stream`] and the library FIFO, each in a small
//! module of its own, and the generated units small enough to prove in
//! seconds, at their default configuration ([`NAMES`]); and the larger
//! units ([`LARGE`]): the merging modules, the per-node network and the
//! upper builder at a small D, whose two-copy checks take about a minute,
//! and the fetchers, the record writer, the merger tops and the store front
//! end, at their default sizes (handshake) and at small configurations
//! (every check, BMC).
//!
//! Depths: at least a flow's capacity plus three, so that the base case
//! (BMC from reset) reaches a full buffer and one beat more: a fault is then
//! a counterexample from reset, not only a failed induction step.

use golden::merge::level_choice::unit::OverlapLayout;
use golden::merge::merge_level::unit::{base_kind, level_kind, BeatLayout};
use golden::merge::merge_module::MergeDesign;
use golden::merge::per_node::unit::PerNodeLayout;
use golden::merge::MergeMode;
use golden::translate::model::TranslateDesign;

use super::{Check, Flow, Mode, Proof, Status};
use crate::{Module, Stream};

use Check::{Determined, Flow as FlowCheck, Handshake};
use Mode::{Bmc, Induction};

/// `<s>_valid && <s>_ready`.
fn fire(s: &str) -> String {
    format!("{s}_valid && {s}_ready")
}

/// `[hi:lo]` of a field at `offset`, `width` bits.
fn bits(offset: u32, width: u32) -> String {
    format!("[{}:{}]", offset + width - 1, offset)
}

/// [`Stream::pipeline_reg`] alone: `in` -> `out`, `width` bits.
pub fn pipeline_reg(width: u32) -> Proof {
    let m = Module::new(&format!("pipeline_reg_w{width}"));
    Stream::input(&m, "in", width)
        .pipeline_reg("pipe")
        .output("out");
    Proof::new(m, &["in"], &["out"], 6)
        .flow(Flow::Fifo {
            input: "in".into(),
            output: "out".into(),
            capacity: 1,
            occupancy: Some("dut.pipe_valid".into()),
            slots: vec!["dut.pipe_data".into()],
        })
        .check(Handshake, Induction)
        .check(FlowCheck, Induction)
        .check(Determined, Induction)
}

/// [`Stream::skid_buffer`] ([`crate::examples::skid_buffer`]).
pub fn skid_buffer(width: u32) -> Proof {
    Proof::new(crate::examples::skid_buffer(width), &["in"], &["out"], 8)
        .flow(Flow::Fifo {
            input: "in".into(),
            output: "out".into(),
            capacity: 2,
            occupancy: Some("dut.skid_valid + dut.skid_spare_valid".into()),
            slots: vec!["dut.skid_data".into(), "dut.skid_spare_data".into()],
        })
        .invariant(
            "spare_only_behind_out",
            "!dut.skid_spare_valid || dut.skid_valid",
        )
        .check(Handshake, Induction)
        .check(FlowCheck, Induction)
        .check(Determined, Induction)
}

/// The library FIFO ([`Stream::fifo`], [`crate::examples::fifo`]) of
/// `2^addr_bits` words: its words are a memory, which the harness cannot
/// name, so the flow and determinism are proven by BMC, to a depth in which
/// its addresses wrap (`2^(addr_bits + 1)` beats in) and it fills and
/// drains. The handshake's induction needs the count to match the
/// addresses, or a push could overwrite the word at the head.
pub fn fifo(width: u32, addr_bits: u32) -> Proof {
    let depth = 1u32 << addr_bits;
    let cb = golden::params::bits_to_hold(depth as u64);
    memory_fifo(
        crate::examples::fifo(width, addr_bits),
        depth,
        "dut.mem_count",
    )
    .invariant(
        "count_within_depth",
        &format!("dut.mem_count <= {cb}'d{depth}"),
    )
    .invariant(
        "count_is_tail_minus_head",
        &format!(
            "dut.mem_tail - dut.mem_head == dut.mem_count[{}:0]",
            addr_bits - 1
        ),
    )
    .check(Handshake, Induction)
    .check(FlowCheck, Bmc)
    .check(Determined, Bmc)
}

/// The library's drop FIFO ([`crate::DropFifo`],
/// [`crate::examples::drop_fifo`]) of `2^cb` words, to the same depth as
/// [`fifo`]. Its producer is never held, so the flow (no beat lost,
/// duplicated or reordered) holds under the promise its callers keep or
/// flag (no push while full), and the handshake with `clear` low; the
/// occupancy stays within the depth, and nothing is X after reset, with
/// `clear` free.
pub fn drop_fifo(width: u32, cb: u32) -> Proof {
    let depth = 1u32 << cb;
    let occ = "(dut.q_wr - dut.q_rd)";
    memory_fifo(crate::examples::drop_fifo(width, cb), depth, occ)
        .assume(
            "no_push_while_full",
            "!(in_valid && dut.q_full)",
            &[FlowCheck],
        )
        .assume("no_clear", "!clear", &[Handshake, FlowCheck])
        .invariant("within_depth", &format!("{occ} <= {}'d{depth}", cb + 1))
        .check(Handshake, Induction)
        .check(FlowCheck, Bmc)
        .check(Determined, Bmc)
}

/// A FIFO of `depth` words on a memory between streams `in` and `out`,
/// `occupancy` its words held: the flow of both library FIFOs, to a depth
/// in which the addresses wrap and it fills and drains.
fn memory_fifo(m: Module, depth: u32, occupancy: &str) -> Proof {
    Proof::new(m, &["in"], &["out"], 2 * depth + 2).flow(Flow::Fifo {
        input: "in".into(),
        output: "out".into(),
        capacity: depth,
        occupancy: Some(occupancy.into()),
        slots: vec![],
    })
}

/// [`Stream::merge_priority`] of `n` streams of `width` bits.
pub fn merge_priority(width: u32, n: usize) -> Proof {
    let m = Module::new(&format!("merge_priority_w{width}_n{n}"));
    let names: Vec<String> = (0..n).map(|i| format!("in{i}")).collect();
    let ins: Vec<Stream> = names.iter().map(|s| Stream::input(&m, s, width)).collect();
    Stream::merge_priority(&m, "arb", &ins).output("out");
    let refs: Vec<&str> = names.iter().map(String::as_str).collect();
    let valids: Vec<String> = names.iter().rev().map(|s| format!("{s}_valid")).collect();
    Proof::new(m, &refs, &["out"], 6)
        .flow(Flow::Priority {
            inputs: names.clone(),
            output: "out".into(),
        })
        .invariant(
            "held_one_hot",
            &format!("(dut.arb_held & (dut.arb_held - {n}'d1)) == {n}'d0"),
        )
        .invariant("stalled_as_seen", "dut.arb_stalled == f0_stalled")
        .invariant(
            "held_input_valid",
            &format!(
                "!dut.arb_stalled || (dut.arb_held & {{{}}}) != {n}'d0",
                valids.join(", ")
            ),
        )
        .check(Handshake, Induction)
        .check(FlowCheck, Induction)
        .check(Determined, Induction)
}

/// S608's overlap counter at the default merging module (k = 4, 1/2): one
/// result beat per level's `End`.
pub fn overlap_counter() -> Proof {
    let c = MergeDesign::default();
    let (num, den) = c.threshold().unwrap_or((1, 2));
    let m = crate::merge::overlap_counter_unit(&c.params, c.inputs, num, den);
    let l = OverlapLayout::new(&c.params, c.inputs);
    Proof::new(m, &["in"], &["out"], 4)
        .flow(Flow::Counted {
            name: "level_result".into(),
            input: format!("{} && in_data[{}]", fire("in"), l.end.offset),
            output: fire("out"),
            capacity: 1,
            occupancy: Some("dut.out_valid_q".into()),
        })
        .check(Handshake, Induction)
        .check(FlowCheck, Induction)
        .check(Determined, Induction)
}

/// S614 (merge level) at the default parameters: every level's `End`
/// leaves once, in order.
pub fn merge_level() -> Proof {
    let p = MergeDesign::default().params;
    let (li, lo) = (BeatLayout::input(&p), BeatLayout::output(&p));
    Proof::new(crate::merge::merge_level_unit(&p), &["in"], &["out"], 6)
        .flow(Flow::Counted {
            name: "level_end".into(),
            input: format!(
                "{} && in_data{} == 2'd{}",
                fire("in"),
                bits(li.kind.offset, 2),
                level_kind::END
            ),
            output: format!(
                "{} && out_data{} == 2'd{}",
                fire("out"),
                bits(lo.kind.offset, 2),
                base_kind::END
            ),
            // The holding register and the skid buffer's two (a bound one
            // lower fails).
            capacity: 3,
            occupancy: None,
        })
        .check(Handshake, Induction)
        .check_to(FlowCheck, Bmc, 12)
        .check(Determined, Induction)
}

/// S616 one level up at the default parameters.
pub fn upper_level() -> Proof {
    let p = MergeDesign::default().params;
    Proof::new(crate::merge::upper_level_unit(&p), &["in"], &["out"], 6)
        .check(Handshake, Induction)
        .check(Determined, Induction)
}

/// The merge network (k = 4, ranks tagged) at the default parameters.
pub fn morton_merge() -> Proof {
    let c = MergeDesign::default();
    let ins: Vec<String> = (0..c.inputs).map(|i| format!("in{i}")).collect();
    let refs: Vec<&str> = ins.iter().map(String::as_str).collect();
    Proof::new(
        crate::merge::morton_merge_unit(&c.params, c.inputs, true),
        &refs,
        &["out"],
        4,
    )
    .check(Handshake, Induction)
    .check(Determined, Induction)
}

/// The per-node decider at the default per-node configuration (k = 4, 1/2).
pub fn per_node_decider() -> Proof {
    let c = MergeDesign::default();
    let m = crate::merge::per_node_decider_unit(&c.params, c.inputs, 1, 2);
    Proof::new(m, &["in"], &["out", "report"], 4)
        .check(Handshake, Induction)
        .check(Determined, Induction)
}

/// The translation unit at its default design: each path answers every
/// transaction once; `idle` and `done` as SPEC 7.9's table says.
pub fn translate_unit() -> Proof {
    let m = crate::translate::translate_unit(&TranslateDesign::default());
    let mut p = Proof::new(m, &["det_in", "apply_in"], &["det_out", "apply_out"], 4);
    // The most inside each path holds (a bound one lower fails).
    for (path, capacity) in [("det", 6), ("apply", 5)] {
        p = p.flow(Flow::Counted {
            name: format!("{path}_answered"),
            input: fire(&format!("{path}_in")),
            output: fire(&format!("{path}_out")),
            capacity,
            occupancy: None,
        });
    }
    p.status = Some(Status {
        idle: Some("idle".into()),
        done: Some("done".into()),
        busy: vec![0, 1],
        ..Status::default()
    });
    // The two-copy check holds the table memory twice: BMC to 4 only.
    p.check(Handshake, Induction)
        .check_to(FlowCheck, Bmc, 12)
        .check(Determined, Bmc)
        .check_to(Check::Status, Bmc, 12)
}

/// `<s>` leaving with an `End` of S614's output layout for `p` (a merge
/// pass's last beat).
fn end_leaves(s: &str, p: &golden::params::Params) -> String {
    let ol = BeatLayout::output(p);
    format!(
        "{} && {s}_data{} == 2'd{}",
        fire(s),
        bits(ol.kind.offset, 2),
        base_kind::END
    )
}

/// The merging module of `c` (k = `c.inputs` streams `in*`, `cfg`,
/// `report`, `out`): a merge is a transaction from its `cfg` beat to its end
/// (`end`, SystemVerilog over ports and nets), one at a time; `idle` and
/// `done` as SPEC 8.10 says, `cfg` taken only while idle.
fn merge_module(c: &MergeDesign, end: &str, depth: u32) -> Proof {
    let m = crate::merge::merge_module_unit(c);
    let ins: Vec<String> = std::iter::once("cfg".to_string())
        .chain((0..c.inputs).map(|i| format!("in{i}")))
        .collect();
    let refs: Vec<&str> = ins.iter().map(String::as_str).collect();
    let mut p = Proof::new(m, &refs, &["report", "out"], depth).flow(Flow::Counted {
        name: "merge_answered".into(),
        input: fire("cfg"),
        output: end.into(),
        capacity: 1,
        occupancy: Some("!dut.is_idle".into()),
    });
    p.status = Some(Status {
        idle: Some("idle".into()),
        done: Some("done".into()),
        busy: vec![0],
        only_when_idle: vec!["cfg".into()],
        ..Status::default()
    });
    p
}

/// The default merging module (overlap 1/2, k = 4): a merge ends when its
/// merge pass's `End` leaves `out`, or when its refusal (`report` beat with
/// `err`) enters `report`'s skid buffer (the cycle `done` answers, SPEC
/// 8.10; under a stall it leaves `report` later).
pub fn merge_module_overlap() -> Proof {
    let c = MergeDesign::default();
    let end = format!(
        "({}) || (dut.choice_reported && dut.choice_err != 2'd0)",
        end_leaves("out", &c.params)
    );
    merge_module(&c, &end, 4)
        .check(Handshake, Induction)
        .check_to(FlowCheck, Bmc, 20)
        .check(Determined, Induction)
        .check_to(Check::Status, Bmc, 20)
}

/// The default per-node merging module (per-node 1/2, k = 4): a merge ends
/// when its last pass's `End` leaves `out` (`merge_done`: every pass ends
/// with an `End`, only the last ends the merge) or its refusal enters
/// `report`'s skid buffer.
pub fn merge_module_per_node() -> Proof {
    let c = MergeDesign {
        mode: MergeMode::PerNode { num: 1, den: 2 },
        ..MergeDesign::default()
    };
    merge_module(&c, "dut.merge_done || dut.refusal_sent", 4)
        .check(Handshake, Induction)
        .check_to(FlowCheck, Bmc, 20)
        .check(Determined, Induction)
        .check_to(Check::Status, Bmc, 20)
}

/// The per-node merge network (k = 4) at the default parameters: every
/// `End` taken on `in0` is answered by one `End` leaving `out` (the network
/// sends one `End` when every head holds one), in order.
pub fn per_node_network() -> Proof {
    let c = MergeDesign::default();
    let pl = PerNodeLayout::new(&c.params);
    // `out` is `{rank, beat}`: the beat's fields where an input has them.
    let end_of = |s: &str| {
        format!(
            "{} && !{s}_data[{}] && {s}_data{} == 2'd{}",
            fire(s),
            pl.probe.offset,
            bits(pl.beat.kind.offset, 2),
            level_kind::END
        )
    };
    let ins: Vec<String> = (0..c.inputs).map(|i| format!("in{i}")).collect();
    let refs: Vec<&str> = ins.iter().map(String::as_str).collect();
    Proof::new(
        crate::merge::per_node_network_unit(&c.params, c.inputs),
        &refs,
        &["out"],
        4,
    )
    .flow(Flow::Counted {
        name: "pass_end".into(),
        input: end_of("in0"),
        output: end_of("out"),
        capacity: 4,
        occupancy: None,
    })
    .check(Handshake, Induction)
    .check_to(FlowCheck, Bmc, 10)
    .check(Determined, Induction)
}

/// The upper builder at `max_lod` = `d` (other parameters the defaults):
/// a chain of `d` groupings, streams `base0..=base{d}` in, `level0..=level{d}`
/// and `done` out.
pub fn upper_builder(d: u8) -> Proof {
    let p = golden::params::Params {
        max_lod: d,
        ..MergeDesign::default().params
    };
    let ins: Vec<String> = (0..=d).map(|l| format!("base{l}")).collect();
    let outs: Vec<String> = (0..=d)
        .map(|l| format!("level{l}"))
        .chain(std::iter::once("done".to_string()))
        .collect();
    let ins: Vec<&str> = ins.iter().map(String::as_str).collect();
    let outs: Vec<&str> = outs.iter().map(String::as_str).collect();
    Proof::new(crate::merge::upper_builder_unit(&p), &ins, &outs, 4)
        .check(Handshake, Induction)
        .check(Determined, Induction)
}

/// The upper builder at the default D = 16: handshake only. Its two-copy
/// check's induction step at D = 16 did not converge in 25 minutes (the
/// base case, BMC 4, passes in about a minute); [`upper_builder`] at D = 2
/// proves it for every kind of stage.
pub fn upper_builder_default() -> Proof {
    let d = MergeDesign::default().params.max_lod;
    let mut p = upper_builder(d);
    p.checks.retain(|(c, _, _)| matches!(c, Handshake));
    p
}

/// The fetcher (S610 + S612, overlap configurations) at its default sizes
/// (16 roots, a frontier of 256 ranges): every output stream leaves
/// through a skid buffer; handshake only (its frontier FIFO and root sorter
/// are memories, held twice by the two-copy check).
pub fn fetcher() -> Proof {
    let c = MergeDesign::default();
    let sizes = golden::merge::fetcher::FetchSizes::default();
    Proof::new(
        crate::merge::fetcher_unit(&c.params, &sizes),
        &["cfg", "cmd", "node_resp", "ref_resp", "cref_resp"],
        &["node_req", "ref_req", "cref_req", "out", "leaves"],
        4,
    )
    .check(Handshake, Induction)
}

/// The fetcher with the per-node command (per-node configurations) at its
/// default sizes: the fetcher's streams and `report` in, `probe_resp` in,
/// `probe_req` out; handshake only, as [`fetcher`].
pub fn fetcher_per_node() -> Proof {
    let c = MergeDesign::default();
    let sizes = golden::merge::fetcher::FetchSizes::default();
    Proof::new(
        crate::merge::fetcher_per_node_unit(&c.params, &sizes),
        &[
            "cfg",
            "cmd",
            "node_resp",
            "ref_resp",
            "cref_resp",
            "report",
            "probe_resp",
        ],
        &[
            "node_req",
            "ref_req",
            "cref_req",
            "out",
            "leaves",
            "probe_req",
        ],
        4,
    )
    .check(Handshake, Induction)
}

/// The record writer at the default merger's sizes (D = 16, its level
/// buffers memories): every output stream leaves through a skid buffer;
/// handshake only.
pub fn record_writer() -> Proof {
    let c = MergeDesign::default();
    let p = c.params;
    let bits = crate::merge::MergerConfig::new(c).sizes.capacity_bits;
    let m = crate::merge::record_writer_unit(&p, bits)
        .expect("the default merger's writer capacity is valid");
    let ins: Vec<String> = ["cfg", "done", "crefs", "ref_resp"]
        .iter()
        .map(|s| s.to_string())
        .chain((0..=p.max_lod).map(|d| format!("level{d}")))
        .collect();
    let ins: Vec<&str> = ins.iter().map(String::as_str).collect();
    Proof::new(m, &ins, &["header", "nodes", "refs", "ref_req"], 4).check(Handshake, Induction)
}

/// The streams of `m`'s ports (`<s>_valid`, `_ready`, `_data`): inputs,
/// outputs, in port order.
fn streams(m: &Module) -> (Vec<String>, Vec<String>) {
    let ports = m.ports();
    let has = |n: &str| ports.iter().any(|p| p.name == n);
    let (mut ins, mut outs) = (Vec::new(), Vec::new());
    for p in &ports {
        let Some(s) = p.name.strip_suffix("_valid") else {
            continue;
        };
        if has(&format!("{s}_ready")) && has(&format!("{s}_data")) {
            match p.direction {
                crate::Direction::Input => ins.push(s.to_string()),
                crate::Direction::Output => outs.push(s.to_string()),
            }
        }
    }
    (ins, outs)
}

/// The hierarchy merger top at the default configuration (overlap 1/2,
/// k = 4): handshake only, on every stream of its ports. Inductive because
/// every output stream leaves a child's skid buffer, and the flags the top
/// adds to the writer's `header` hold while that beat waits (8.15).
pub fn hierarchy_merger() -> Proof {
    merger_handshake(MergeDesign::default())
}

/// The hierarchy merger top in per-node mode (1/2, k = 4): handshake only,
/// as [`hierarchy_merger`].
pub fn hierarchy_merger_per_node() -> Proof {
    merger_handshake(MergeDesign {
        mode: MergeMode::PerNode { num: 1, den: 2 },
        ..MergeDesign::default()
    })
}

fn merger_handshake(design: MergeDesign) -> Proof {
    let c = crate::merge::MergerConfig::new(design);
    let m = crate::merge::hierarchy_merger_unit(&c).expect("the merger configuration is valid");
    let (ins, outs) = streams(&m);
    let ins: Vec<&str> = ins.iter().map(String::as_str).collect();
    let outs: Vec<&str> = outs.iter().map(String::as_str).collect();
    Proof::new(m, &ins, &outs, 4).check(Handshake, Induction)
}

/// The merger's shared store front end (SPEC 8.15, "The shared store
/// port") at a small grid (D = 4, Q = 0, I = 8, H = 2) with three
/// requesters (a node reader, two reference readers) and a tag FIFO of 2,
/// by BMC to 14 clocks (every buffer fills, drains and wraps): handshake on
/// every stream; each requester's reads answered once each on its
/// `r{j}_resp`, at most 2 (`2^T`, its credit) outstanding, and each read
/// taken on `store_req` answered by one `store_resp` beat, at most 2;
/// determined (BMC 10); `idle` exactly while no requester has a read outstanding,
/// `store_resp` ready whenever a read is in flight. Assumed: the store
/// answers only reads it has taken. Which requester gets which word is the
/// bench's to check (`cosim/tests/merge_store_port.rs`).
pub fn store_port() -> Proof {
    use golden::merge::merger::store_port::StoreArray::{Node, Reference};
    let c = crate::merge::StorePortConfig {
        params: golden::params::Params::new(4, 0, 8, 2).expect("valid parameters"),
        arrays: vec![Node, Reference, Reference],
        tag_bits: 1,
    };
    let n = c.arrays.len();
    let m = crate::merge::store_port_unit(&c).expect("a valid store port");
    let (ins, outs) = streams(&m);
    let ins: Vec<&str> = ins.iter().map(String::as_str).collect();
    let outs: Vec<&str> = outs.iter().map(String::as_str).collect();
    // BMC from reset: its answer buffers and tag FIFO are memories, whose
    // words an induction invariant cannot name, so induction meets states
    // no run reaches (a buffer fuller than its requester's credit).
    let mut p = Proof::new(m, &ins, &outs, 14);
    for j in 0..n {
        p = p.flow(Flow::Counted {
            name: format!("r{j}_answered"),
            input: fire(&format!("r{j}_req")),
            output: fire(&format!("r{j}_resp")),
            capacity: 1 << c.tag_bits,
            occupancy: None,
        });
    }
    p = p.flow(Flow::Counted {
        name: "store_answered".into(),
        input: fire("store_req"),
        output: fire("store_resp"),
        capacity: 1 << c.tag_bits,
        occupancy: None,
    });
    let mut p = p.assume(
        "store_answers_reads_taken",
        &format!("!store_resp_valid || f{n}_occ != 0"),
        &[],
    );
    p.status = Some(Status {
        idle: Some("idle".into()),
        busy: (0..n).collect(),
        rules: vec![(
            "store_resp_taken_in_flight".into(),
            format!("f{n}_occ == 0 || store_resp_ready"),
        )],
        ..Status::default()
    });
    // The two-copy check holds the buffers twice: 14 took 5 minutes.
    p.check(Handshake, Bmc)
        .check(FlowCheck, Bmc)
        .check_to(Determined, Bmc, 10)
        .check(Check::Status, Bmc)
}

/// The grid of the small configurations below: D = 4, Q = 0, I = 8,
/// H = 2 (the smallest the merger's tests build).
fn small_params() -> golden::params::Params {
    golden::params::Params::new(4, 0, 8, 2).expect("valid parameters")
}

/// The fetchers' small sizes: 2 roots, a frontier of 2 ranges (a FIFO of 8
/// words).
const SMALL_FETCH: golden::merge::fetcher::FetchSizes = golden::merge::fetcher::FetchSizes {
    roots: 2,
    frontier: 2,
};

/// The `kind` field of the small fetchers' `out` beat (the tests' broken
/// fetcher clears it).
pub fn small_fetch_out_kind() -> golden::layout::Field {
    golden::merge::fetcher::FetchLayout::new(&small_params())
        .beat
        .kind
}

/// `<s>_data` bits of `f`.
fn data(s: &str, f: &golden::layout::Field) -> String {
    format!("{s}_data{}", bits(f.offset, f.width))
}

/// The `End`-kind beats a `cmd` beat asks of a fetcher: a level command,
/// `lod - min(from, lod) + 1` (8.13: every command sends exactly that many).
fn levels_asked(l: &golden::merge::fetcher::FetchLayout) -> String {
    let (lod, from) = (data("cmd", &l.lod), data("cmd", &l.from));
    format!("({lod} - ({from} < {lod} ? {from} : {lod}) + 1'b1)")
}

/// The fetcher of `l` (a `Module` built with `l`'s layout) with the flows,
/// status and checks both fetchers share: a command is a transaction from
/// its `cmd` beat to the cycle its phase is DONE (the out stage handed its
/// last `End` to `out`'s skid buffer); each command's `End`-kind beats
/// (`ends`, a count per cycle) leave `out`, none invented; `idle` exactly
/// while no command is in progress, `cfg` and `cmd` taken only then, and
/// by then every `End` owed is at least in `out`'s skid buffer. At most
/// `capacity` `End`s owed: a command's levels (a `lod` field's worth) and
/// two of the one before in that skid buffer. With `ahead` (the level
/// fetcher's PREFETCH), no command is in progress either while the fetcher
/// reads the next command's roots before its `cmd` beat, and `cmd` is
/// taken then too.
fn fetcher_small_proof(
    m: Module,
    l: &golden::merge::fetcher::FetchLayout,
    ends: String,
    capacity: u32,
    rules: Vec<(String, String)>,
    ahead: bool,
) -> Proof {
    let end_leaves = format!(
        "{} && {} == 2'd{}",
        fire("out"),
        data("out", &l.beat.kind),
        level_kind::END
    );
    let (ins, outs) = streams(&m);
    let ins: Vec<&str> = ins.iter().map(String::as_str).collect();
    let outs: Vec<&str> = outs.iter().map(String::as_str).collect();
    let mut p = Proof::new(m, &ins, &outs, 4)
        .flow(Flow::Counted {
            name: "command_done".into(),
            input: fire("cmd"),
            // DONE is the fetcher's phase code 4 (its `localparam DONE`),
            // which the harness cannot name.
            output: "dut.phase == 3'd4".into(),
            capacity: 1,
            occupancy: None,
        })
        .flow(Flow::Counted {
            name: "command_ends".into(),
            input: ends,
            output: end_leaves,
            capacity,
            occupancy: None,
        });
    let mut rules = rules;
    rules.push((
        "idle_ends_handed_over".into(),
        "!idle || f1_occ <= dut.out_q_valid + dut.out_q_spare_valid".into(),
    ));
    // The phases of PREFETCH before its command is taken (the fetcher's
    // `localparam`s START, ROOTS, ARMED), which the harness cannot name.
    let prefetching = || {
        let ph = crate::merge::fetcher_prefetch_phases();
        let is: Vec<String> = ph.iter().map(|c| format!("dut.phase == 3'd{c}")).collect();
        format!("({}) && !dut.cmd_have", is.join(" || "))
    };
    p.status = Some(Status {
        idle: Some("idle".into()),
        busy: vec![0],
        only_when_idle: match ahead {
            true => vec!["cfg".into()],
            false => vec!["cfg".into(), "cmd".into()],
        },
        ahead: ahead.then(|| (prefetching(), vec!["cmd".into()])),
        rules,
        ..Status::default()
    });
    p.check(Handshake, Induction)
        .check_to(FlowCheck, Bmc, 16)
        .check_to(Determined, Bmc, 12)
        .check_to(Check::Status, Bmc, 16)
}

/// The fetcher at a small configuration (D = 4, Q = 0, I = 8, H = 2, 2
/// roots, a frontier of 2): its memories (the frontier FIFO, the root
/// sorter) make induction meet unreachable states, so every check but the
/// handshake is BMC from reset: flow and status to 16 clocks (a `cfg`, a
/// command with a header error or one root, its `End`s: the shortest ends
/// at step 13), determined to 12 (16 took 5 minutes).
pub fn fetcher_small() -> Proof {
    let p = small_params();
    let l = golden::merge::fetcher::FetchLayout::new(&p);
    let ends = format!("{} ? {} : 1'b0", fire("cmd"), levels_asked(&l));
    fetcher_small_proof(
        crate::merge::fetcher_unit(&p, &SMALL_FETCH),
        &l,
        ends,
        (1 << p.lod_bits()) + 2,
        vec![],
        true,
    )
}

/// The fetcher with the per-node command at the small configuration of
/// [`fetcher_small`]: a per-node command owes one `End` per pass, the
/// first and one per `report` beat with `pass_end` and `more` (8.13), a
/// level command as in the level modes; `report` is taken only during a
/// command. BMC as [`fetcher_small`].
pub fn fetcher_per_node_small() -> Proof {
    let p = small_params();
    let l = golden::merge::fetcher::FetchLayout::per_node(&p);
    let pn = l.pn.as_ref().expect("per-node fields");
    let ends = format!(
        "({} ? ({} ? 1'b1 : {}) : 1'b0) + ({} && {} && {})",
        fire("cmd"),
        data("cmd", &pn.per_node),
        levels_asked(&l),
        fire("report"),
        data("report", &pn.report_pass_end),
        data("report", &pn.report_more),
    );
    fetcher_small_proof(
        crate::merge::fetcher_per_node_unit(&p, &SMALL_FETCH),
        &l,
        ends,
        (1 << p.lod_bits()) + 2,
        vec![(
            "report_only_in_command".into(),
            "!report_ready || !idle".into(),
        )],
        false,
    )
}

/// The record writer at a small configuration (D = 4, Q = 0, I = 8, H = 2,
/// buffers of 2^2 words): each `cfg` answered by one `header` (the next
/// merge's `cfg` may be taken while the header waits in its skid buffer:
/// at most 3 outstanding); its status outputs as 8.12 says: the level,
/// `done` and `crefs` streams are taken only while `filling`, and neither
/// sequencer drains then; determined under the upper builder's contract
/// ([`builder_contract`]), which the writer does not check: a merge that
/// breaks it makes the drain read buffer words no beat wrote since reset.
/// BMC (its buffers are memories): flow and status to 16, determined to
/// [`WRITER_SMALL_DETERMINED`].
pub fn record_writer_small() -> Proof {
    let p = small_params();
    let m = crate::merge::record_writer_unit(&p, 2).expect("a valid writer capacity");
    let ins: Vec<String> = ["cfg", "done", "crefs", "ref_resp"]
        .iter()
        .map(|s| s.to_string())
        .chain((0..=p.max_lod).map(|d| format!("level{d}")))
        .collect();
    let mut rules: Vec<(String, String)> = ins[1..3]
        .iter()
        .chain(&ins[4..])
        .map(|s| {
            (
                format!("{s}_only_filling"),
                format!("!{s}_ready || filling"),
            )
        })
        .collect();
    rules.push((
        "drain_not_filling".into(),
        "!(filling && (drain_records || drain_refs))".into(),
    ));
    let ins: Vec<&str> = ins.iter().map(String::as_str).collect();
    let mut pr =
        Proof::new(m, &ins, &["header", "nodes", "refs", "ref_req"], 4).flow(Flow::Counted {
            name: "header_per_cfg".into(),
            input: fire("cfg"),
            output: fire("header"),
            capacity: 3,
            occupancy: None,
        });
    pr.status = Some(Status {
        rules,
        ..Status::default()
    });
    builder_contract(pr, &p, 2)
        .check(Handshake, Induction)
        .check_to(FlowCheck, Bmc, 16)
        .check_to(Determined, Bmc, WRITER_SMALL_DETERMINED)
        .check_to(Check::Status, Bmc, 16)
}

/// The BMC depth of the small record writer's two-copy check: a merge of
/// one node per level is whole at step 3 and drains from step 4, so 8
/// holds its first records and references; step 8 alone took two minutes.
pub const WRITER_SMALL_DETERMINED: u32 = 8;

/// The upper builder's contract with the record writer `pr` (built for `p`
/// with `2^capacity_bits` words per buffer; SPEC 8.11, 8.12), as
/// environment promises of its `determined` check only (its other checks
/// hold for any beats). Trackers count, per level, the nodes, records
/// (grouped and created nodes) and the grouped and created nodes' `count`s
/// since its last `End`, and hold them from that `End` on; and the `crefs`
/// references before their `End`. Promised: each level beat's `index` and
/// `records` are the nodes and records before it (an `End`'s, its level's);
/// and once the writer has a whole merge (`fill_done`) whose `done` has no
/// error, that its top level sent a node (the builder's top holds the
/// roots), that each level's grouped nodes have as many references as the
/// level below has nodes, and that the created nodes' references of the
/// merge's levels are the `crefs` references. Which level is the top, the
/// writer's `top` register says (`done`'s field).
pub fn builder_contract(mut pr: Proof, p: &golden::params::Params, capacity_bits: u32) -> Proof {
    use golden::merge::upper_builder::unit::level_out_kind as kind;
    let wl = golden::merge::record_writer::WriterLayout::new(p, capacity_bits)
        .expect("a valid writer capacity");
    let bl = &wl.builder;
    let i = p.index_bits as u32;
    let sum_w = i + capacity_bits + 1;
    let lb = p.lod_bits();
    let count = bl.node.count();
    let zext = |e: &str, w: u32| format!("{{{}'d0, {e}}}", sum_w - w);
    let promise = |pr: Proof, label: String, expr: String| pr.assume(&label, &expr, &[Determined]);
    for d in 0..=p.max_lod {
        let s = format!("level{d}");
        let f = |field: &golden::layout::Field| data(&s, field);
        let fired = format!("({})", fire(&s));
        let k = f(&bl.kind);
        let end = format!("({k} == 2'd{})", kind::END);
        let cnt = zext(
            &data(
                &s,
                &golden::layout::Field::new("count", bl.rec.offset + count.offset, count.width),
            ),
            count.width,
        );
        let t = |n: &str| format!("t_l{d}_{n}");
        let step =
            |n: &str, add: String| format!("{fired} ? ({end} ? 0 : {} + {add}) : {}", t(n), t(n));
        let of_kind = |code: u64| format!("({k} == 2'd{code} ? {cnt} : {sum_w}'d0)");
        pr = pr
            .tracker(&format!("l{d}_nodes"), i, &step("nodes", format!("{i}'d1")))
            .tracker(
                &format!("l{d}_records"),
                i,
                &step("records", format!("({k} != 2'd{})", kind::REUSED)),
            )
            .tracker(
                &format!("l{d}_grouped"),
                sum_w,
                &step("grouped", of_kind(kind::GROUPED)),
            )
            .tracker(
                &format!("l{d}_created"),
                sum_w,
                &step("created", of_kind(kind::CREATED)),
            );
        for (n, w) in [("nodes", i), ("grouped", sum_w), ("created", sum_w)] {
            let ended = format!("ended_{n}");
            pr = pr.tracker(
                &format!("l{d}_{ended}"),
                w,
                &format!("{fired} && {end} ? {} : {}", t(n), t(&ended)),
            );
        }
        pr = promise(
            pr,
            format!("l{d}_index_counts_nodes"),
            format!("!{s}_valid || {} == {}", f(&bl.index), t("nodes")),
        );
        pr = promise(
            pr,
            format!("l{d}_records_count_records"),
            format!("!{s}_valid || {} == {}", f(&bl.records), t("records")),
        );
    }
    let crefs_end = data("crefs", &wl.cref_end);
    pr = pr
        .tracker(
            "crefs",
            sum_w,
            &format!(
                "({}) ? ({crefs_end} ? 0 : t_crefs + 1'b1) : t_crefs",
                fire("crefs")
            ),
        )
        .tracker(
            "ended_crefs",
            sum_w,
            &format!(
                "({}) && {crefs_end} ? t_crefs : t_ended_crefs",
                fire("crefs")
            ),
        );
    let whole = "!(dut.fill_done && !dut.done_err) || ";
    let lod = |d: u8| format!("{lb}'d{d}");
    let top_nodes: String = (0..=p.max_lod)
        .map(|d| format!("dut.top == {} ? t_l{d}_ended_nodes : ", lod(d)))
        .collect();
    pr = promise(
        pr,
        "top_has_nodes".into(),
        format!("{whole}({top_nodes}{i}'d0) != {i}'d0"),
    );
    for d in 0..p.max_lod {
        pr = promise(
            pr,
            format!("l{d}_grouped_counts_l{}_nodes", d + 1),
            format!(
                "{whole}dut.top > {} || t_l{d}_ended_grouped == {}",
                lod(d),
                zext(&format!("t_l{}_ended_nodes", d + 1), i)
            ),
        );
    }
    let created: Vec<String> = (0..=p.max_lod)
        .map(|d| format!("(dut.top > {} ? {sum_w}'d0 : t_l{d}_ended_created)", lod(d)))
        .collect();
    promise(
        pr,
        "crefs_are_created_counts".into(),
        format!("{whole}t_ended_crefs == {}", created.join(" + ")),
    )
}

/// The small merger configurations: [`small_params`], k = 2, 2 roots, a
/// frontier of 2, writer buffers of 2^2, leaf FIFOs of 2, in `mode`, with
/// `store_port`.
fn small_merger(
    mode: MergeMode,
    store_port: golden::merge::merger::store_port::StorePort,
) -> crate::merge::MergerConfig {
    crate::merge::MergerConfig {
        design: MergeDesign {
            params: small_params(),
            inputs: 2,
            mode,
            roots: SMALL_FETCH.roots,
        },
        sizes: golden::merge::merger::MergerSizes {
            fetch: SMALL_FETCH,
            capacity_bits: 2,
            leaf_bits: 1,
            store_port,
        },
    }
}

/// The merger top of `c` with its merges as transactions: each `cfg`
/// answered by one `header` (`overlap`: two merges may be taken, 8.15 step
/// 8; else one, and `cfg` only while idle); `idle` exactly while no merge
/// is in progress; `done` high exactly one clock after a `header` beat
/// left, low the first clock after reset (with one merge at a time, that
/// is `idle` rising).
fn merger_small_proof(c: &crate::merge::MergerConfig, overlap: bool) -> Proof {
    let m = crate::merge::hierarchy_merger_unit(c).expect("the merger configuration is valid");
    let (ins, outs) = streams(&m);
    let ins: Vec<&str> = ins.iter().map(String::as_str).collect();
    let outs: Vec<&str> = outs.iter().map(String::as_str).collect();
    let mut p = Proof::new(m, &ins, &outs, 4).flow(Flow::Counted {
        name: "header_per_cfg".into(),
        input: fire("cfg"),
        output: fire("header"),
        capacity: if overlap { 2 } else { 1 },
        occupancy: None,
    });
    p.status = Some(Status {
        idle: Some("idle".into()),
        done: (!overlap).then(|| "done".to_string()),
        busy: vec![0],
        only_when_idle: if overlap { vec![] } else { vec!["cfg".into()] },
        ahead: None,
        rules: vec![(
            "done_after_header".into(),
            "done == $past(header_valid && header_ready)".into(),
        )],
    });
    if overlap {
        // (`Status::done` says it where `done` is `idle` rising.)
        if let Some(s) = p.status.as_mut() {
            s.rules
                .push(("done_low_after_reset".into(), "f_prev || !done".into()));
        }
    }
    p.check(Handshake, Induction)
        .check_to(FlowCheck, Bmc, MERGER_SMALL_DEPTH)
        .check_to(Determined, Bmc, MERGER_SMALL_DETERMINED)
        .check_to(Check::Status, Bmc, MERGER_SMALL_DEPTH)
}

/// The BMC depth of the small merger tops' flow and status: their shortest
/// merge sends its `header` at step 17 (a refusal, the leaves and the
/// writer's `NO_TOP` header), so 24 holds one whole merge and the next
/// `cfg`.
pub const MERGER_SMALL_DEPTH: u32 = 24;

/// The BMC depth of the small merger tops' two-copy check: 12 (the count
/// pass's first reads); each step past it costs about twice the one before
/// (step 15 of BMC 20 took 3 minutes, which did not finish in 5).
pub const MERGER_SMALL_DETERMINED: u32 = 12;

/// The merger top (overlap 1/2) at the small configuration (D = 4, Q = 0,
/// I = 8, H = 2, k = 2, small buffers; SPEC 11.1): BMC from reset (its units' buffers are memories), flow
/// and status to [`MERGER_SMALL_DEPTH`], determined to
/// [`MERGER_SMALL_DETERMINED`].
pub fn hierarchy_merger_small() -> Proof {
    let c = small_merger(MergeMode::Overlap { num: 1, den: 2 }, Default::default());
    merger_small_proof(&c, true)
}

/// The per-node merger top (1/2) at the small configuration: as
/// [`hierarchy_merger_small`], one merge at a time.
pub fn hierarchy_merger_per_node_small() -> Proof {
    let c = small_merger(MergeMode::PerNode { num: 1, den: 2 }, Default::default());
    merger_small_proof(&c, false)
}

/// The merger top (overlap 1/2) at the small configuration with its units
/// behind one shared store port (`_sp1`: a tag FIFO of 2): as
/// [`hierarchy_merger_small`], and each read taken on `store_req` answered
/// by one `store_resp` beat, at most 2 (`2^T`) taken and unanswered;
/// `store_resp` is ready whenever a read is in flight, and `store_idle`
/// only with none. Assumed: the store answers only reads it has taken.
/// Status is BMC 16 (below).
pub fn hierarchy_merger_store_port() -> Proof {
    let c = small_merger(
        MergeMode::Overlap { num: 1, den: 2 },
        golden::merge::merger::store_port::StorePort::Shared { tag_bits: 1 },
    );
    let p = merger_small_proof(&c, true).flow(Flow::Counted {
        name: "store_answered".into(),
        input: fire("store_req"),
        output: fire("store_resp"),
        capacity: 2,
        occupancy: None,
    });
    // `store_resp_ready` is high from a read's grant, before the store has
    // taken it from `store_req`'s skid buffer: a store answering a read it
    // never took would be taken as that read's answer.
    let mut p = p.assume(
        "store_answers_reads_taken",
        "!store_resp_valid || f1_occ != 0",
        &[],
    );
    if let Some(s) = p.status.as_mut() {
        s.rules.push((
            "store_resp_taken_in_flight".into(),
            "f1_occ == 0 || store_resp_ready".into(),
        ));
        s.rules.push((
            "store_idle_none_in_flight".into(),
            "!store_idle || f1_occ == 0".into(),
        ));
    }
    // With every unit's reads on one port the status check grows fastest:
    // BMC 20 took 260 s and 24 did not end in 10 minutes; 16 holds the
    // count pass's reads, not yet a header.
    for c in p.checks.iter_mut().filter(|c| c.0 == Check::Status) {
        c.2 = 16;
    }
    p
}

/// The hierarchy unit (docs/hardware.md 8.16) around the small merger top
/// of [`hierarchy_merger_small`], its translation unit binary32 with a
/// table of 4: each merge command answered by one `header` (two taken at
/// most, as the merger's `cfg`), each determine command by one `det_out`
/// beat (six inside at most, as the translation unit's); `idle` exactly
/// when neither is outstanding; `done` one clock after a `header` left; and
/// the order that places a merge by the table: a merge command is taken
/// only when every determine command before it has left `det_out`. BMC from
/// reset, as the merger top.
pub fn hierarchy_unit_small() -> Proof {
    let merger = small_merger(MergeMode::Overlap { num: 1, den: 2 }, Default::default());
    let mut c = crate::merge::HierarchyUnitConfig::new(merger);
    c.table.binary64 = false;
    let m = crate::merge::hierarchy_unit(&c).expect("the hierarchy unit configuration is valid");
    let merge = format!("cmd_data[{}]", c.cmd_layout().kind.offset);
    let (ins, outs) = streams(&m);
    let ins: Vec<&str> = ins.iter().map(String::as_str).collect();
    let outs: Vec<&str> = outs.iter().map(String::as_str).collect();
    let cmd = fire("cmd");
    let mut p = Proof::new(m, &ins, &outs, 4)
        .flow(Flow::Counted {
            name: "header_per_merge".into(),
            input: format!("{cmd} && {merge}"),
            output: fire("header"),
            capacity: 2,
            occupancy: None,
        })
        .flow(Flow::Counted {
            name: "det_out_per_determine".into(),
            input: format!("{cmd} && !{merge}"),
            output: fire("det_out"),
            capacity: 6,
            occupancy: None,
        });
    p.status = Some(Status {
        idle: Some("idle".into()),
        done: None,
        busy: vec![0, 1],
        only_when_idle: vec![],
        ahead: None,
        rules: vec![
            (
                "merge_after_its_determines".into(),
                format!("!({cmd} && {merge}) || f1_occ == 0"),
            ),
            (
                "done_after_header".into(),
                "done == $past(header_valid && header_ready)".into(),
            ),
            ("done_low_after_reset".into(), "f_prev || !done".into()),
        ],
    });
    p.check(Handshake, Induction)
        .check_to(FlowCheck, Bmc, MERGER_SMALL_DEPTH)
        .check_to(Determined, Bmc, MERGER_SMALL_DETERMINED)
        .check_to(Check::Status, Bmc, MERGER_SMALL_DEPTH)
}

/// The units `hiermerge formal` proves by default (and with `--all`), in
/// report order: each check takes seconds.
pub const NAMES: [&str; 11] = [
    "pipeline_reg",
    "skid_buffer",
    "fifo",
    "drop_fifo",
    "merge_priority",
    "overlap_counter",
    "merge_level",
    "upper_level",
    "morton_merge",
    "per_node_decider",
    "translate",
];

/// The larger units (`hiermerge formal --large`, or by name with `--unit`):
/// their two-copy `determined` proofs take about a minute each, so CI runs
/// only their handshake checks.
pub const LARGE: [&str; 18] = [
    "per_node_network",
    "merge_module_overlap",
    "merge_module_per_node",
    "upper_builder",
    "upper_builder_default",
    "fetcher",
    "fetcher_per_node",
    "record_writer",
    "hierarchy_merger",
    "hierarchy_merger_per_node",
    "store_port",
    "fetcher_small",
    "fetcher_per_node_small",
    "record_writer_small",
    "hierarchy_merger_small",
    "hierarchy_merger_per_node_small",
    "hierarchy_merger_store_port",
    "hierarchy_unit_small",
];

/// The max_lod of the `upper_builder` proof: two groupings in a chain and
/// the top rule above them (the builder has one stage per level).
pub const UPPER_BUILDER_D: u8 = 2;

/// The proof named `name` (one of [`NAMES`] or [`LARGE`]).
pub fn by_name(name: &str) -> Option<Proof> {
    Some(match name {
        "pipeline_reg" => pipeline_reg(8),
        "skid_buffer" => skid_buffer(8),
        "fifo" => fifo(8, 2),
        "drop_fifo" => drop_fifo(8, 2),
        "merge_priority" => merge_priority(8, 3),
        "overlap_counter" => overlap_counter(),
        "merge_level" => merge_level(),
        "upper_level" => upper_level(),
        "morton_merge" => morton_merge(),
        "per_node_decider" => per_node_decider(),
        "translate" => translate_unit(),
        "per_node_network" => per_node_network(),
        "merge_module_overlap" => merge_module_overlap(),
        "merge_module_per_node" => merge_module_per_node(),
        "upper_builder" => upper_builder(UPPER_BUILDER_D),
        "upper_builder_default" => upper_builder_default(),
        "fetcher" => fetcher(),
        "fetcher_per_node" => fetcher_per_node(),
        "record_writer" => record_writer(),
        "hierarchy_merger" => hierarchy_merger(),
        "hierarchy_merger_per_node" => hierarchy_merger_per_node(),
        "store_port" => store_port(),
        "fetcher_small" => fetcher_small(),
        "fetcher_per_node_small" => fetcher_per_node_small(),
        "record_writer_small" => record_writer_small(),
        "hierarchy_merger_small" => hierarchy_merger_small(),
        "hierarchy_merger_per_node_small" => hierarchy_merger_per_node_small(),
        "hierarchy_merger_store_port" => hierarchy_merger_store_port(),
        "hierarchy_unit_small" => hierarchy_unit_small(),
        _ => return None,
    })
}
