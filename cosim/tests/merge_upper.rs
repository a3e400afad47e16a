//! S616 one level up (`rtl_gen::merge::upper_level_unit`) against the
//! golden `build::upper::group_by_parent` through
//! `golden::merge::unit::upper_transaction`, bit for bit, on the IR
//! simulator, Verilator and Icarus, random back-pressure (0..=0.5), in-order
//! scoreboard; one transaction = one parent group (its children in, its
//! record out). Throughput with no back-pressure printed (>= 0.95 beats per
//! cycle); lint and synthesis of every configuration.
mod merge_common;

use cosim::tb::Vector;
use golden::merge::unit::{random_upper_level, upper_transaction, UpperBeat, UpperLayout};
use golden::params::Params;
use golden::translate::stimulus::SplitMix64;
use merge_common::*;

fn configs() -> Vec<(&'static str, Params)> {
    vec![
        ("default", Params::default()),
        ("d31", Params::new(31, 16, 32, 8).unwrap()),
        ("q0", Params::new(8, 0, 12, 3).unwrap()),
        ("q1", Params::new(3, 1, 5, 2).unwrap()),
        ("i3", Params::new(5, 2, 3, 2).unwrap()),
    ]
}

/// Levels until `groups` parent groups (transactions); a level's outputs
/// are expected with its first beat. Also counts the groups with `err`.
fn vectors(p: &Params, seed: u64, groups: usize) -> (Vec<Vector>, usize, usize, Vec<usize>) {
    let l = UpperLayout::new(p);
    let mut rng = SplitMix64(seed);
    let mut out = Vec::new();
    let (mut n, mut errs) = (0, 0);
    let mut ends = Vec::new();
    while n < groups {
        let size = 1 + rng.below(40) as usize;
        let level = random_upper_level(&mut rng, p, size);
        let (ins, outs) = upper_transaction(&level, p);
        n += outs.len() - 1;
        errs += outs
            .iter()
            .filter(|b| matches!(b, UpperBeat::Node { err: true, .. }))
            .count();
        let expected: Vec<_> = outs
            .iter()
            .map(|b| vec![bitvec(&b.pack(&l, true).unwrap())])
            .collect();
        for (j, b) in ins.iter().enumerate() {
            out.push(Vector {
                input: vec![bitvec(&b.pack(&l, false).unwrap())],
                outputs: if j == 0 { expected.clone() } else { Vec::new() },
            });
        }
        ends.push(out.len());
    }
    (out, n, errs, ends)
}

fn check(name: &str, p: &Params, runs: &[(&str, usize)], seed: u64) {
    let dir = tempfile::tempdir().unwrap();
    let m = rtl_gen::merge::upper_level_unit(p);
    let design = design_of(&m, dir.path());
    for &(kind, groups) in runs {
        let (vs, n, errs, ends) = vectors(p, seed, groups);
        eprintln!(
            "upper {name}/{kind}: {n} groups, {} beats, {errs} with err",
            vs.len()
        );
        if p.index_bits <= 3 {
            assert!(errs > 0, "index overflow reached");
        }
        let stall = stall_of(seed ^ kind.len() as u64).max(0.05);
        let mut e = engine(kind, &m, &design);
        run(
            e.as_mut(),
            &vs,
            seed,
            stall,
            &format!("merge_upper {name} {kind}"),
        );
        let part = &vs[..level_prefix(&ends, 100_000)];
        let mut e = engine(kind, &m, &design);
        let r = run(
            e.as_mut(),
            part,
            seed + 1,
            0.0,
            &format!("merge_upper {name} {kind}"),
        );
        println!(
            "upper_level {name} {kind}: {} input beats in {} cycles: {:.4} beats/cycle",
            r.inputs_sent,
            r.cycles,
            r.inputs_per_cycle()
        );
        assert!(
            r.inputs_per_cycle() >= 0.95,
            "{name} {kind}: {}",
            r.inputs_per_cycle()
        );
    }
}

#[test]
fn upper_level_default_matches_golden_on_100k_groups() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check(
        "default",
        &Params::default(),
        &[("ir", 100_000), ("verilator", 100_000), ("iverilog", 2_000)],
        0x5616,
    );
}

#[test]
fn upper_level_other_configs_match_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    for (i, (name, p)) in configs().into_iter().skip(1).enumerate() {
        check(
            name,
            &p,
            &[("ir", 5_000), ("verilator", 20_000), ("iverilog", 300)],
            0x5617 + i as u64,
        );
    }
}

#[test]
fn upper_level_verilog_lints_and_synthesizes() {
    if !tools_present(&["verilator", "yosys"]) {
        return;
    }
    for (_, p) in configs() {
        let dir = tempfile::tempdir().unwrap();
        let m = rtl_gen::merge::upper_level_unit(&p);
        let warnings = m.validate_design().expect("valid");
        assert!(warnings.is_empty(), "{warnings:?}");
        lint_and_synth(&design_of(&m, dir.path()));
    }
}
