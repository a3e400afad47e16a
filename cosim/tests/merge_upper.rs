//! S616 one level up (`rtl_gen::merge::upper_level_unit`) against the
//! golden `build::upper::group_by_parent` through
//! `golden::merge::upper_builder::level_unit::upper_transaction`, bit for bit, random
//! back-pressure (0.05..=0.5), in-order scoreboard; one transaction = one
//! parent group (its children in, its record out). The default, D = 31,
//! Q = 0 and I = 3 run 100,000 groups each on Verilator and on Icarus
//! Verilog (batch mode, 4-state), Q = 1 20,000; the IR simulator 100,000
//! default, 5,000 other. Throughput with no back-pressure printed (>= 0.95 beats per
//! cycle); lint and synthesis of every configuration. The vectors are
//! `cosim::units::upper_builder::level`'s.
mod merge_common;

use cosim::units::upper_builder::level::{upper_level_module, vectors, LevelVectors};
use cosim::volume::volume;
use golden::params::Params;
use golden::seed::seeded;
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

/// Every engine on `groups` random transactions with random back-pressure
/// (stall 0.05..=0.5; Verilator on `volume(groups)`, the IR simulator and Icarus on `ir_groups`), then without
/// back-pressure on the first 100k beats (at least 0.95 beats per cycle).
/// Icarus runs in batch mode (`IcarusBatch`, 4-state).
fn check(name: &str, groups: usize, ir_groups: usize) {
    let all = configs();
    let i = all.iter().position(|c| c.0 == name).unwrap();
    let p = all[i].1;
    let seed = seeded(0x5616 + i as u64);
    let dir = tempfile::tempdir().unwrap();
    let m = upper_level_module(&p);
    let design = design_of(&m, dir.path());
    let batch = icarus_batch(&design);
    // Verilator at volume; the IR simulator and Icarus (4-state) at depth.
    let groups = volume(groups);
    let levels = |groups| vectors(&p, seed, groups).expect("the beats pack");
    let full = levels(groups);
    let ir = (ir_groups != groups).then(|| levels(ir_groups));
    for kind in ["ir", "verilator", "iverilog"] {
        let LevelVectors {
            vectors: vs,
            groups: n,
            errs,
            ends,
            groups_at_end,
        } = match (&ir, kind) {
            (Some(v), "ir" | "iverilog") => v,
            _ => &full,
        };
        eprintln!(
            "upper {name}/{kind}: {n} groups, {} beats, {errs} with err",
            vs.len()
        );
        if p.index_bits <= 3 {
            assert!(*errs > 0, "index overflow reached");
        }
        let sim = |kind: &str| match kind {
            "iverilog" => Sim::Batch(&batch),
            k => Sim::Stepped(engine(k, &m, &design)),
        };
        let stall = stall_of(seed ^ kind.len() as u64).max(0.05);
        let what = format!("merge_upper {name} {kind}");
        run_sim(sim(kind), vs, *n, seed, stall, &what);
        let cut = level_prefix(ends, 100_000);
        let part_groups = groups_at_end[ends.iter().position(|&e| e == cut).unwrap()];
        let r = run_sim(sim(kind), &vs[..cut], part_groups, seed + 1, 0.0, &what);
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
fn upper_level_default_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check("default", 100_000, 10_000);
}

#[test]
fn upper_level_d31_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check("d31", 100_000, 5_000);
}

#[test]
fn upper_level_q0_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check("q0", 100_000, 5_000);
}

#[test]
fn upper_level_q1_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check("q1", 20_000, 5_000);
}

#[test]
fn upper_level_i3_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check("i3", 100_000, 5_000);
}

#[test]
fn upper_level_verilog_lints_and_synthesizes() {
    if !tools_present(&["verilator", "yosys"]) {
        return;
    }
    for (_, p) in configs() {
        let dir = tempfile::tempdir().unwrap();
        let m = upper_level_module(&p);
        let warnings = m.validate_design().expect("valid");
        assert!(warnings.is_empty(), "{warnings:?}");
        lint_and_synth(&design_of(&m, dir.path()));
    }
}
