//! The root sorter (`rtl_gen::merge::root_sorter_unit`) against the golden
//! `sort_stream` through `golden::merge::unit::root_sort_transaction`, bit
//! for bit, on the IR simulator, Verilator and Icarus, random back-pressure
//! (0..=0.5), in-order scoreboard; one transaction = one input's roots
//! (translated so that Morton order breaks; sometimes more than the
//! capacity, which must raise `err`). Throughput with no back-pressure is
//! printed; lint and synthesis of every configuration.
mod merge_common;

use cosim::tb::Vector;
use cosim::BitVec;
use golden::merge::unit::{random_roots, root_sort_transaction, BeatLayout, LevelBeat};
use golden::params::Params;
use golden::translate::stimulus::SplitMix64;
use merge_common::*;

fn configs() -> Vec<(&'static str, Params, usize)> {
    vec![
        ("default", Params::default(), 16),
        ("d31", Params::new(31, 16, 32, 8).unwrap(), 16),
        ("q0", Params::new(8, 0, 12, 3).unwrap(), 8),
        ("n2", Params::new(4, 2, 6, 2).unwrap(), 2),
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

fn check(name: &str, p: &Params, n: usize, runs: &[(&str, usize)], seed: u64) {
    let dir = tempfile::tempdir().unwrap();
    let m = rtl_gen::merge::root_sorter_unit(p, n);
    let design = design_of(&m, dir.path());
    for &(kind, sets) in runs {
        let (vs, ends, unsorted, overflow) = vectors(p, n, seed, sets);
        eprintln!("sorter {name}/{kind}: {sets} sets, {} beats, {unsorted} out of order, {overflow} overflowed", vs.len());
        assert!(unsorted > sets / 10 && overflow > 0);
        let stall = stall_of(seed ^ kind.len() as u64).max(0.05);
        let mut e = engine(kind, &m, &design);
        run(
            e.as_mut(),
            &vs,
            seed,
            stall,
            &format!("merge_sorter {name} {kind}"),
        );
        let part = &vs[..level_prefix(&ends, 100_000)];
        let mut e = engine(kind, &m, &design);
        let r = run(
            e.as_mut(),
            part,
            seed + 1,
            0.0,
            &format!("merge_sorter {name} {kind}"),
        );
        println!(
            "root_sorter {name} {kind}: {} input beats in {} cycles: {:.4} beats/cycle",
            r.inputs_sent,
            r.cycles,
            r.inputs_per_cycle()
        );
    }
}

#[test]
fn root_sorter_default_matches_golden_on_100k_sets() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    let (name, p, n) = configs()[0];
    check(
        name,
        &p,
        n,
        &[("ir", 4_000), ("verilator", 100_000), ("iverilog", 150)],
        0x5107,
    );
}

#[test]
fn root_sorter_other_configs_match_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    for (i, (name, p, n)) in configs().into_iter().skip(1).enumerate() {
        check(
            name,
            &p,
            n,
            &[("ir", 1_000), ("verilator", 10_000), ("iverilog", 100)],
            0x5108 + i as u64,
        );
    }
}

#[test]
fn root_sorter_verilog_lints_and_synthesizes() {
    if !tools_present(&["verilator", "yosys"]) {
        return;
    }
    for (_, p, n) in configs() {
        let dir = tempfile::tempdir().unwrap();
        let m = rtl_gen::merge::root_sorter_unit(&p, n);
        let warnings = m.validate_design().expect("valid");
        assert!(warnings.is_empty(), "{warnings:?}");
        lint_and_synth(&design_of(&m, dir.path()));
    }
}
