//! S608's overlap counter (unit 508, `rtl_gen::merge::overlap_counter_unit`)
//! against the golden `overlap_counts` + `above_threshold` through
//! `golden::merge::unit::overlap_transaction`, bit for bit, on the IR
//! simulator, Verilator and Icarus, random back-pressure (0..=0.5), in-order
//! scoreboard; one transaction = one level (its beats, then `End`; one
//! result beat). Throughput with no back-pressure printed (>= 0.95 beats per
//! cycle); lint and synthesis of every configuration.
mod merge_common;

use cosim::tb::Vector;
use golden::merge::unit::{overlap_transaction, random_overlap_case, OverlapLayout};
use golden::params::Params;
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
                input: vec![bitvec(&b.pack(&l).unwrap())],
                outputs: if j + 1 == n {
                    vec![vec![bitvec(&r.pack(&l).unwrap())]]
                } else {
                    Vec::new()
                },
            });
        }
        ends.push(out.len());
    }
    (out, seen, ends)
}

fn check(name: &str, p: &Params, k: usize, num: u32, den: u32, runs: &[(&str, usize)], seed: u64) {
    let dir = tempfile::tempdir().unwrap();
    let m = rtl_gen::merge::overlap_counter_unit(p, k, num, den);
    let design = design_of(&m, dir.path());
    for &(kind, levels) in runs {
        let (vs, seen, ends) = vectors(p, k, num, den, seed, levels);
        eprintln!(
            "overlap {name}/{kind}: {levels} levels, {} beats, above/not/overflow {seen:?}",
            vs.len()
        );
        assert!(seen[1] > 0, "some level below the threshold");
        if num < den && k > 1 {
            assert!(seen[0] > 0, "some level above the threshold");
        }
        if p.index_bits <= 4 {
            assert!(seen[2] > 0, "count overflow reached");
        }
        let stall = stall_of(seed ^ kind.len() as u64).max(0.05);
        let mut e = engine(kind, &m, &design);
        run(
            e.as_mut(),
            &vs,
            seed,
            stall,
            &format!("merge_overlap {name} {kind}"),
        );
        let part = &vs[..level_prefix(&ends, 100_000)];
        let mut e = engine(kind, &m, &design);
        let r = run(
            e.as_mut(),
            part,
            seed + 1,
            0.0,
            &format!("merge_overlap {name} {kind}"),
        );
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
fn overlap_counter_default_matches_golden_on_100k_levels() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    let (name, p, k, num, den) = configs()[0];
    check(
        name,
        &p,
        k,
        num,
        den,
        &[("ir", 100_000), ("verilator", 100_000), ("iverilog", 2_000)],
        0x5608,
    );
}

#[test]
fn overlap_counter_other_configs_match_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    for (i, (name, p, k, num, den)) in configs().into_iter().skip(1).enumerate() {
        check(
            name,
            &p,
            k,
            num,
            den,
            &[("ir", 5_000), ("verilator", 20_000), ("iverilog", 300)],
            0x5609 + i as u64,
        );
    }
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
