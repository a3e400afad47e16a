//! The root sorter (`rtl_gen::merge::root_sorter_unit`) against the golden
//! `sort_stream` through `golden::merge::fetcher::root_sorter::root_sort_transaction`, bit
//! for bit, in-order scoreboard; one transaction = one input's roots
//! (translated so that Morton order breaks; sometimes more than the
//! capacity, which must raise `err`). Every configuration passes 100,000
//! sets in Verilator at full volume (SPEC 10.3; random back-pressure in
//! 0.05..=0.5 on both streams), 10,000 in Icarus (batch mode, the whole
//! bench in one `vvp` run; 0.05), and
//! fewer on the IR simulator and the Icarus pipe engine (random); with no
//! back-pressure the input rate (a cycle count of the RTL, deterministic:
//! the same in every simulator) must be at least 0.95 beats per cycle.
//! Lint and synthesis of every configuration. The vectors are
//! `cosim::units::fetcher::root_sorter`'s.
mod merge_common;

use cosim::tb::{BenchReport, Vector};
use cosim::units::fetcher::root_sorter::{root_sorter_module, vectors, SortVectors};
use cosim::volume::volume;
use golden::params::Params;
use golden::seed::seeded;
use merge_common::*;

/// Sets per configuration in Verilator at full volume (issue 5: 100,000
/// random transactions; SPEC 10.3).
const SETS: usize = 100_000;

/// Sets per configuration in Icarus batch mode: the 4-state engine at depth.
const ICARUS_SETS: usize = 10_000;

/// The least input rate with no back-pressure (issue 5), in beats per cycle.
const MIN_RATE: f64 = 0.95;

/// Reset, pipeline and drain cycles of a run (measured: 22 to 36).
const FIXED_CYCLES: u64 = 64;

/// Beats of the no-back-pressure rate run (whole sets, at most this many).
const RATE_BEATS: usize = 100_000;

/// Name, parameters, capacity and stimulus seed of each configuration.
fn configs() -> Vec<(&'static str, Params, usize, u64)> {
    vec![
        ("default", Params::default(), 16, 0x5107),
        ("d31", Params::new(31, 16, 32, 8).unwrap(), 16, 0x5108),
        ("q0", Params::new(8, 0, 12, 3).unwrap(), 8, 0x5109),
        ("n2", Params::new(4, 2, 6, 2).unwrap(), 2, 0x510a),
    ]
}

/// The Icarus batch mode: the whole bench inside one `vvp` run.
const ICARUS_BATCH: &str = "iverilog-batch";

/// One bench run of `vectors` (`sets` transactions) on engine `kind` (`ir`,
/// `verilator`, `iverilog` (the pipe engine) or [`ICARUS_BATCH`]); panics
/// with the report when an output mismatches, is lost or duplicated, or the
/// design hangs.
fn bench(
    kind: &str,
    (m, design): (&rtl_gen::Module, &cosim::Design),
    vectors: &[Vector],
    sets: usize,
    seed: u64,
    stall: f64,
    what: &str,
) -> BenchReport {
    if kind == ICARUS_BATCH {
        let batch = icarus_batch(design);
        run_sim(Sim::Batch(&batch), vectors, sets, seed, stall, what)
    } else {
        let e = engine(kind, m, design);
        run_sim(Sim::Stepped(e), vectors, sets, seed, stall, what)
    }
}

/// `sets` random sets through `engine` with back-pressure `stall` on both
/// streams, bit for bit against golden.
fn matches_golden(
    name: &str,
    p: &Params,
    n: usize,
    seed: u64,
    engine_kind: &str,
    sets: usize,
    stall: f64,
) {
    let dir = tempfile::tempdir().unwrap();
    let m = root_sorter_module(p, n);
    let design = design_of(&m, dir.path());
    let SortVectors {
        vectors: vs,
        unsorted,
        overflow,
        ..
    } = vectors(p, n, seed, sets).expect("the beats pack");
    eprintln!(
        "sorter {name}/{engine_kind}: {sets} sets, {} beats, {unsorted} out of order, {overflow} overflowed",
        vs.len()
    );
    assert!(unsorted > sets / 10 && overflow > 0);
    let what = format!("merge_sorter {name} {engine_kind}");
    bench(engine_kind, (&m, &design), &vs, sets, seed, stall, &what);
}

/// The input rate with no back-pressure on about [`RATE_BEATS`] beats of
/// whole sets, checked against golden too; at least [`MIN_RATE`].
fn rate_without_back_pressure(name: &str, p: &Params, n: usize, seed: u64, engine_kind: &str) {
    let dir = tempfile::tempdir().unwrap();
    let m = root_sorter_module(p, n);
    let design = design_of(&m, dir.path());
    // A set is at least two beats: enough sets for RATE_BEATS beats.
    let SortVectors {
        vectors: vs, ends, ..
    } = vectors(p, n, seed, RATE_BEATS / 2).expect("the beats pack");
    let part = &vs[..level_prefix(&ends, RATE_BEATS)];
    let what = format!("merge_sorter {name} {engine_kind}");
    let sets = ends.iter().filter(|&&e| e <= part.len()).count();
    let r = bench(engine_kind, (&m, &design), part, sets, seed + 1, 0.0, &what);
    let rate = r.inputs_per_cycle();
    println!(
        "root_sorter {name} {engine_kind}: {} input beats in {} cycles: {rate:.4} beats/cycle",
        r.inputs_sent, r.cycles
    );
    assert!(
        rate >= MIN_RATE,
        "root sorter {name}: {rate:.4} input beats per cycle with no back-pressure, below {MIN_RATE}"
    );
    // Stronger, SPEC 8.9: the input never waits, so the cycles beyond one
    // per beat are only reset, pipeline and drain, whatever the run length.
    assert!(
        r.cycles <= r.inputs_sent + FIXED_CYCLES,
        "root sorter {name}: {} cycles for {} beats: the input waited",
        r.cycles,
        r.inputs_sent
    );
}

/// Back-pressure of the Icarus batch runs: the least of the range
/// (Icarus simulates this unit at ~5-15 k cycles/s, D = 31 the slowest;
/// heavier back-pressure doubles the cycles). Verilator, the IR simulator
/// and the Icarus pipe engine run the random stall in `0.05..=0.5`.
const ICARUS_STALL: f64 = 0.05;

/// Sets of the Icarus pipe-engine runs (one `vvp` round trip per clock).
const PIPE_SETS: usize = 1_000;

/// Verilator on [`volume`]`(`[`SETS`]`)` sets with random back-pressure and the rate with
/// none, then `ir_sets` sets on the IR simulator.
fn verilator_and_ir(config: usize, ir_sets: usize) {
    let (name, p, n, seed) = configs()[config];
    let seed = seeded(seed);
    let stall = stall_of(seed).max(0.05);
    matches_golden(name, &p, n, seed, "verilator", volume(SETS), stall);
    rate_without_back_pressure(name, &p, n, seed + 1, "verilator");
    matches_golden(name, &p, n, seed + 2, "ir", ir_sets, stall);
}

/// Icarus batch mode on [`ICARUS_SETS`] sets, then the pipe engine on
/// [`PIPE_SETS`] with random back-pressure.
fn icarus(config: usize) {
    let (name, p, n, seed) = configs()[config];
    let seed = seeded(seed);
    matches_golden(
        name,
        &p,
        n,
        seed + 3,
        ICARUS_BATCH,
        ICARUS_SETS,
        ICARUS_STALL,
    );
    let stall = stall_of(seed + 4).max(0.05);
    matches_golden(name, &p, n, seed + 4, "iverilog", PIPE_SETS, stall);
}

// The Icarus runs are split in two tests of about equal time so that both
// cores work (tests start in name order, two at a time): a D = 31 cycle
// costs Icarus about 1.7 default cycles.

#[test]
fn root_sorter_icarus_d31_q0() {
    if tools_present(&["iverilog"]) {
        icarus(1);
        icarus(2);
    }
}

#[test]
fn root_sorter_icarus_default_n2() {
    if tools_present(&["iverilog"]) {
        icarus(0);
        icarus(3);
    }
}

#[test]
fn root_sorter_verilator_rate_and_ir() {
    if tools_present(&["verilator"]) {
        for config in 0..configs().len() {
            verilator_and_ir(config, if config == 0 { 4_000 } else { 1_000 });
        }
    }
}

#[test]
fn root_sorter_verilog_lints_and_synthesizes() {
    if !tools_present(&["verilator", "yosys"]) {
        return;
    }
    for (_, p, n, _) in configs() {
        let dir = tempfile::tempdir().unwrap();
        let m = root_sorter_module(&p, n);
        let warnings = m.validate_design().expect("valid");
        assert!(warnings.is_empty(), "{warnings:?}");
        lint_and_synth(&design_of(&m, dir.path()));
    }
}
