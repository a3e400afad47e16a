//! The root sorter (`rtl_gen::merge::root_sorter_unit`) against the golden
//! `sort_stream` through `golden::merge::unit::root_sort_transaction`, bit
//! for bit, on the IR simulator, Verilator and Icarus, in-order scoreboard;
//! one transaction = one input's roots (translated so that Morton order
//! breaks; sometimes more than the capacity, which must raise `err`). Every
//! configuration passes 100,000 sets with back-pressure in Verilator (random
//! in 0.05..=0.5) and in Icarus (0.05); with no back-pressure the input rate (a cycle count of the
//! RTL, deterministic) must be at least 0.95 beats per cycle. Lint and
//! synthesis of every configuration.
mod merge_common;

use cosim::tb::Vector;
use cosim::BitVec;
use golden::merge::unit::{random_roots, root_sort_transaction, BeatLayout, LevelBeat};
use golden::params::Params;
use golden::translate::stimulus::SplitMix64;
use merge_common::*;

/// Sets per configuration in Verilator and in Icarus (issue 5: 100,000
/// random transactions each).
const SETS: usize = 100_000;

/// The least input rate with no back-pressure (issue 5), in beats per cycle.
const MIN_RATE: f64 = 0.95;

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

/// Root sets until `sets` transactions; returns the vectors, the level
/// ends, how many sets were out of Morton order and how many overflowed.
fn vectors(
    p: &Params,
    n: usize,
    seed: u64,
    sets: usize,
) -> (Vec<Vector>, Vec<usize>, usize, usize) {
    let (li, lo) = (BeatLayout::input(p), BeatLayout::output(p));
    let err_bit = lo.err.expect("output beats have err").offset as usize;
    let mut rng = SplitMix64(seed);
    let (mut out, mut ends, mut unsorted, mut overflow) = (Vec::new(), Vec::new(), 0, 0);
    for _ in 0..sets {
        let roots = random_roots(&mut rng, p, n);
        let keys: Vec<_> = roots
            .iter()
            .map(|r| (r.record.voxel.morton(), r.record.leaf))
            .collect();
        unsorted += keys.windows(2).any(|w| w[0] > w[1]) as usize;
        let (ins, outs) = root_sort_transaction(&roots, n);
        overflow += outs.last().is_some_and(|o| o.1) as usize;
        let expected: Vec<_> = outs
            .iter()
            .map(|(b, err): &(LevelBeat, bool)| {
                let bits = b.pack(&li).unwrap();
                let mut v = BitVec::from_words(lo.width as usize, bits.words()).unwrap();
                v.set_bit(err_bit, *err).unwrap();
                vec![v]
            })
            .collect();
        for (j, b) in ins.iter().enumerate() {
            out.push(Vector {
                input: vec![bitvec(&b.pack(&li).unwrap())],
                outputs: if j == 0 { expected.clone() } else { Vec::new() },
            });
        }
        ends.push(out.len());
    }
    (out, ends, unsorted, overflow)
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
    let m = rtl_gen::merge::root_sorter_unit(p, n);
    let design = design_of(&m, dir.path());
    let (vs, _, unsorted, overflow) = vectors(p, n, seed, sets);
    eprintln!(
        "sorter {name}/{engine_kind}: {sets} sets, {} beats, {unsorted} out of order, {overflow} overflowed",
        vs.len()
    );
    assert!(unsorted > sets / 10 && overflow > 0);
    let mut e = engine(engine_kind, &m, &design);
    let what = format!("merge_sorter {name} {engine_kind}");
    let r = run(e.as_mut(), &vs, seed, stall, &what);
    eprintln!(
        "{what}: {} cycles in {:.1} s",
        r.cycles,
        r.wall.as_secs_f64()
    );
}

/// The input rate with no back-pressure on about [`RATE_BEATS`] beats of
/// whole sets, checked against golden too; at least [`MIN_RATE`].
fn rate_without_back_pressure(name: &str, p: &Params, n: usize, seed: u64, engine_kind: &str) {
    let dir = tempfile::tempdir().unwrap();
    let m = rtl_gen::merge::root_sorter_unit(p, n);
    let design = design_of(&m, dir.path());
    // A set is at least two beats: enough sets for RATE_BEATS beats.
    let (vs, ends, _, _) = vectors(p, n, seed, RATE_BEATS / 2);
    let part = &vs[..level_prefix(&ends, RATE_BEATS)];
    let mut e = engine(engine_kind, &m, &design);
    let r = run(
        e.as_mut(),
        part,
        seed + 1,
        0.0,
        &format!("merge_sorter {name} {engine_kind}"),
    );
    let rate = r.inputs_per_cycle();
    println!(
        "root_sorter {name} {engine_kind}: {} input beats in {} cycles: {rate:.4} beats/cycle",
        r.inputs_sent, r.cycles
    );
    assert!(
        rate >= MIN_RATE,
        "root sorter {name}: {rate:.4} input beats per cycle with no back-pressure, below {MIN_RATE}"
    );
}

/// Back-pressure of the Icarus runs: the least of the Verilator range, so
/// that 100,000 sets per configuration stay within the CI budget (the pipe
/// engine simulates ~10-20 k cycles/s; Verilator covers up to 0.5).
const ICARUS_STALL: f64 = 0.05;

/// IR (a smaller count: it is the slowest), then Verilator on [`SETS`] sets
/// with back-pressure in `0.05..=0.5`, then the rate with none.
fn ir_and_verilator(config: usize, ir_sets: usize) {
    let (name, p, n, seed) = configs()[config];
    let stall = stall_of(seed).max(0.05);
    matches_golden(name, &p, n, seed, "ir", ir_sets, stall);
    matches_golden(name, &p, n, seed + 1, "verilator", SETS, stall);
    rate_without_back_pressure(name, &p, n, seed + 2, "verilator");
}

/// Icarus on [`SETS`] sets of each of `config_indices`.
fn icarus(config_indices: &[usize]) {
    for &i in config_indices {
        let (name, p, n, seed) = configs()[i];
        matches_golden(name, &p, n, seed + 3, "iverilog", SETS, ICARUS_STALL);
    }
}

// The Icarus runs are split in two tests of about equal wall time so that
// both cores work (tests run in name order, two at a time): D = 31's wide
// ports make its cycles about twice as slow as the default's.

#[test]
fn root_sorter_icarus_d31_100k_sets() {
    if tools_present(&["iverilog"]) {
        icarus(&[1]);
    }
}

#[test]
fn root_sorter_icarus_default_q0_n2_100k_sets() {
    if tools_present(&["iverilog"]) {
        icarus(&[0, 2, 3]);
    }
}

#[test]
fn root_sorter_verilator_default_100k_sets_and_rate() {
    if tools_present(&["verilator"]) {
        ir_and_verilator(0, 4_000);
    }
}

#[test]
fn root_sorter_verilator_other_configs_100k_sets_and_rate() {
    if tools_present(&["verilator"]) {
        for config in 1..configs().len() {
            ir_and_verilator(config, 1_000);
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
        let m = rtl_gen::merge::root_sorter_unit(&p, n);
        let warnings = m.validate_design().expect("valid");
        assert!(warnings.is_empty(), "{warnings:?}");
        lint_and_synth(&design_of(&m, dir.path()));
    }
}
