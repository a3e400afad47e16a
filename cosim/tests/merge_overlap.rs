//! S608's overlap counter (unit 508, `rtl_gen::merge::overlap_counter_unit`)
//! against the golden `overlap_counts` + `above_threshold` through
//! `golden::merge::level_choice::unit::overlap_transaction`, bit for bit, random
//! back-pressure (0.05..=0.5), in-order scoreboard; one transaction = one
//! level (its beats, then `End`; one result beat). The default, D = 31,
//! Q = 0 and I = 4 run 100,000 levels each on Verilator and on Icarus
//! Verilog (batch mode, 4-state), k = 1 20,000; the IR simulator 100,000
//! default, 5,000 other. Throughput with no back-pressure printed (>= 0.95 beats per
//! cycle); lint and synthesis of every configuration.
mod merge_common;

use cosim::tb::Vector;
use cosim::volume::volume;
use golden::merge::level_choice::unit::{overlap_transaction, random_overlap_case, OverlapLayout};
use golden::params::Params;
use golden::seed::seeded;
use golden::translate::stimulus::SplitMix64;
use merge_common::*;

/// (name, params, inputs k, num, den): default; D = 31 with k = 2^H-ish and
/// 0/1; Q = 0 with 3/4; I = 4 so counts overflow.
fn configs() -> Vec<(&'static str, Params, usize, u32, u32)> {
    vec![
        ("default", Params::default(), 4, 1, 2),
        ("d31", Params::new(31, 16, 32, 8).unwrap(), 8, 0, 1),
        ("q0", Params::new(8, 0, 12, 3).unwrap(), 3, 3, 4),
        ("i4", Params::new(6, 2, 4, 2).unwrap(), 4, 2, 3),
        ("k1", Params::new(10, 4, 10, 1).unwrap(), 1, 1, 1),
    ]
}

/// Levels until `levels` transactions; a level's result is expected with its
/// `End` beat. Returns the vectors and how many results were `above`/overflowed.
fn vectors(
    p: &Params,
    k: usize,
    num: u32,
    den: u32,
    seed: u64,
    levels: usize,
) -> (Vec<Vector>, [usize; 3], Vec<usize>) {
    let l = OverlapLayout::new(p, k);
    let mut rng = SplitMix64(seed);
    let mut out = Vec::new();
    let mut seen = [0; 3];
    let mut ends = Vec::new();
    for _ in 0..levels {
        let size = if p.index_bits <= 4 && rng.below(4) == 0 {
            24
        } else {
            1 + rng.below(6) as usize
        };
        let voxels = random_overlap_case(&mut rng, p, k, size);
        let (beats, r) = overlap_transaction(&voxels, p, num, den);
        seen[0] += r.above as usize;
        seen[1] += (!r.above && !r.overflow) as usize;
        seen[2] += r.overflow as usize;
        let n = beats.len();
        for (j, b) in beats.iter().enumerate() {
            out.push(Vector {
                input: vec![b.pack(&l).unwrap()],
                outputs: if j + 1 == n {
                    vec![vec![r.pack(&l).unwrap()]]
                } else {
                    Vec::new()
                },
            });
        }
        ends.push(out.len());
    }
    (out, seen, ends)
}

/// Every engine on `levels` random transactions with random back-pressure
/// (stall 0.05..=0.5; Verilator on `volume(levels)`, the IR simulator and Icarus on `ir_levels`), then without
/// back-pressure on the first 100k beats (at least 0.95 beats per cycle).
/// Icarus runs in batch mode (`IcarusBatch`, 4-state).
fn check(name: &str, levels: usize, ir_levels: usize) {
    let all = configs();
    let i = all.iter().position(|c| c.0 == name).unwrap();
    let (_, p, k, num, den) = all[i];
    let seed = seeded(0x5608 + i as u64);
    let dir = tempfile::tempdir().unwrap();
    let m = rtl_gen::merge::overlap_counter_unit(&p, k, num, den);
    let design = design_of(&m, dir.path());
    let batch = icarus_batch(&design);
    // Verilator at volume; the IR simulator and Icarus (4-state) at depth.
    let levels = volume(levels);
    let full = vectors(&p, k, num, den, seed, levels);
    let ir = (ir_levels != levels).then(|| vectors(&p, k, num, den, seed, ir_levels));
    for kind in ["ir", "verilator", "iverilog"] {
        let ((vs, seen, ends), n) = match (&ir, kind) {
            (Some(v), "ir" | "iverilog") => (v, ir_levels),
            _ => (&full, levels),
        };
        eprintln!(
            "overlap {name}/{kind}: {n} levels, {} beats, above/not/overflow {seen:?}",
            vs.len()
        );
        assert!(seen[1] > 0, "some level below the threshold");
        if num < den && k > 1 {
            assert!(seen[0] > 0, "some level above the threshold");
        }
        if p.index_bits <= 4 {
            assert!(seen[2] > 0, "count overflow reached");
        }
        let sim = |kind: &str| match kind {
            "iverilog" => Sim::Batch(&batch),
            k => Sim::Stepped(engine(k, &m, &design)),
        };
        let stall = stall_of(seed ^ kind.len() as u64).max(0.05);
        let what = format!("merge_overlap {name} {kind}");
        let r = run_sim(sim(kind), vs, n, seed, stall, &what);
        assert_eq!(r.inputs_sent, vs.len() as u64);
        let cut = level_prefix(ends, 100_000);
        let part_levels = ends.iter().position(|&e| e == cut).unwrap() + 1;
        let r = run_sim(sim(kind), &vs[..cut], part_levels, seed + 1, 0.0, &what);
        println!(
            "overlap_counter {name} {kind}: {} input beats in {} cycles: {:.4} beats/cycle",
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
fn overlap_counter_default_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check("default", 100_000, 10_000);
}

#[test]
fn overlap_counter_d31_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check("d31", 100_000, 5_000);
}

#[test]
fn overlap_counter_q0_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check("q0", 100_000, 5_000);
}

#[test]
fn overlap_counter_i4_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check("i4", 100_000, 5_000);
}

#[test]
fn overlap_counter_k1_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check("k1", 20_000, 5_000);
}

#[test]
fn overlap_counter_verilog_lints_and_synthesizes() {
    if !tools_present(&["verilator", "yosys"]) {
        return;
    }
    for (_, p, k, num, den) in configs() {
        let dir = tempfile::tempdir().unwrap();
        let m = rtl_gen::merge::overlap_counter_unit(&p, k, num, den);
        let warnings = m.validate_design().expect("valid");
        assert!(warnings.is_empty(), "{warnings:?}");
        lint_and_synth(&design_of(&m, dir.path()));
    }
}
