//! S614 (unit 506, `rtl_gen::merge::merge_level_unit`) against the golden
//! `merge_level` through `golden::merge::merge_level::unit::level_transaction`, bit for
//! bit, with random back-pressure (stall 0.05..=0.5 on both streams) and an
//! in-order scoreboard; a transaction is one voxel group (its beats in, its
//! base nodes and references out). Each of the four configurations runs
//! 100,000 transactions on Verilator and on Icarus Verilog (batch mode,
//! 4-state) and on rtl-gen's IR simulator (100,000 default, 10,000 other).
//! Also: throughput with no back-pressure (printed; at least 0.95 input
//! beats per cycle), the batch mode against the Icarus pipe engine cycle for
//! cycle, lint and synthesis.
mod merge_common;

use cosim::tb::Vector;
use cosim::volume::volume;
use golden::merge::merge_level::unit::{random_level_case, BeatLayout, LevelTransaction};
use golden::params::Params;
use golden::seed::seeded;
use golden::translate::stimulus::SplitMix64;
use merge_common::*;

/// Default, D = 31 (widest record), Q = 0 (no box fields), small I (count overflow).
fn configs() -> Vec<(&'static str, Params)> {
    vec![
        ("default", Params::default()),
        ("d31", Params::new(31, 16, 32, 8).unwrap()),
        ("q0", Params::new(8, 0, 12, 3).unwrap()),
        ("i3", Params::new(5, 2, 3, 2).unwrap()),
    ]
}

/// Where each level ends: (beats so far, transactions so far).
type Ends = (Vec<usize>, Vec<usize>);

/// Random levels until at least `groups` voxel groups (transactions);
/// every group's outputs are expected with its first beat.
fn vectors(p: &Params, seed: u64, groups: usize) -> (Vec<Vector>, usize, LevelStats, Ends) {
    let (li, lo) = (BeatLayout::input(p), BeatLayout::output(p));
    let mut rng = SplitMix64(seed);
    let mut out = Vec::new();
    let mut stats = LevelStats::default();
    let mut ends = (Vec::new(), Vec::new());
    let mut n = 0;
    while n < groups {
        let k = 1 + rng.below(p.hier_capacity().min(5)) as usize;
        let voxels = 1 + rng.below(40) as usize;
        let case = random_level_case(&mut rng, p, k, voxels);
        let tx = case.transaction(p).expect("a well-formed case");
        stats.add(&tx);
        for g in &tx.groups {
            for (j, b) in tx.inputs[g.inputs.clone()].iter().enumerate() {
                let outputs = if j == 0 {
                    tx.outputs[g.outputs.clone()]
                        .iter()
                        .map(|o| vec![o.pack(&lo).unwrap()])
                        .collect()
                } else {
                    Vec::new()
                };
                out.push(Vector {
                    input: vec![b.pack(&li).unwrap()],
                    outputs,
                });
            }
        }
        n += tx.groups.len();
        ends.0.push(out.len());
        ends.1.push(n);
    }
    (out, n, stats, ends)
}

/// What the stimulus reached, so a test can insist on the hard cases.
#[derive(Default, Debug)]
struct LevelStats {
    created: usize,
    overflow: usize,
    reused: usize,
    refs: usize,
}

impl LevelStats {
    fn add(&mut self, tx: &LevelTransaction) {
        use golden::merge::merge_level::unit::BaseBeat::*;
        for o in &tx.outputs {
            match o {
                Created { count_overflow, .. } => {
                    self.created += 1;
                    self.overflow += *count_overflow as usize;
                }
                Reused { .. } => self.reused += 1,
                Ref(_) => self.refs += 1,
                End => {}
            }
        }
    }
}

/// Every engine on `groups` random transactions with random back-pressure
/// (stall 0.05..=0.5 on both streams; Verilator on `volume(groups)`, the IR simulator and Icarus on `ir_groups`),
/// then without back-pressure on the first 100k beats (at least 0.95 input
/// beats per cycle). Icarus runs in batch mode (`IcarusBatch`, 4-state).
fn check_config(name: &str, p: &Params, groups: usize, ir_groups: usize, seed: u64) {
    let seed = seeded(seed);
    let dir = tempfile::tempdir().unwrap();
    let m = rtl_gen::merge::merge_level_unit(p);
    let design = design_of(&m, dir.path());
    let batch = icarus_batch(&design);
    // Verilator at volume; the IR simulator and Icarus (4-state) at depth.
    let groups = volume(groups);
    let all = vectors(p, seed, groups);
    let ir = (ir_groups != groups).then(|| vectors(p, seed, ir_groups));
    for kind in ["ir", "verilator", "iverilog"] {
        let (vs, n, stats, ends) = match (&ir, kind) {
            (Some(v), "ir" | "iverilog") => v,
            _ => &all,
        };
        eprintln!(
            "{name}/{kind}: {n} transactions, {} beats, {stats:?}",
            vs.len()
        );
        assert!(stats.created > 0 && stats.reused > 0 && stats.refs > 0);
        if p.index_bits <= 3 {
            assert!(stats.overflow > 0, "count overflow reached");
        }
        let sim = |kind: &str| match kind {
            "iverilog" => Sim::Batch(&batch),
            k => Sim::Stepped(engine(k, &m, &design)),
        };
        let stall = stall_of(seed ^ kind.len() as u64).max(0.05);
        let what = format!("merge_level {name} {kind}");
        let r = run_sim(sim(kind), vs, *n, seed, stall, &what);
        assert_eq!(r.inputs_sent, vs.len() as u64);
        // No back-pressure: one input beat per clock in steady state (on
        // the first 100k beats, enough for a steady state).
        let cut = level_prefix(&ends.0, 100_000);
        let part_groups = ends.1[ends.0.iter().position(|&e| e == cut).unwrap()];
        let r = run_sim(sim(kind), &vs[..cut], part_groups, seed + 1, 0.0, &what);
        // Cycles include reset (2) and the drain after the last output (16).
        let rate = r.inputs_per_cycle();
        println!(
            "merge_level {name} {kind}: {} input beats in {} cycles: {rate:.4} beats/cycle ({part_groups} transactions)",
            r.inputs_sent, r.cycles
        );
        assert!(rate >= 0.95, "{name} {kind}: {rate}");
    }
}

/// A configuration of `configs()` by name.
fn config(name: &str) -> (Params, u64) {
    let all = configs();
    let i = all.iter().position(|c| c.0 == name).unwrap();
    (all[i].1, 0x5614 + i as u64)
}

#[test]
fn merge_level_default_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    let (p, seed) = config("default");
    check_config("default", &p, 100_000, 10_000, seed);
}

#[test]
fn merge_level_d31_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    let (p, seed) = config("d31");
    check_config("d31", &p, 100_000, 10_000, seed);
}

#[test]
fn merge_level_q0_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    let (p, seed) = config("q0");
    check_config("q0", &p, 100_000, 10_000, seed);
}

#[test]
fn merge_level_i3_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    let (p, seed) = config("i3");
    check_config("i3", &p, 100_000, 10_000, seed);
}

/// The Icarus batch mode agrees with the pipe engine on this unit: the
/// same transfers and books, and without back-pressure the same cycle
/// count (the stall patterns of the two benches differ, their law does
/// not). Both speeds are printed (cycles per second of wall time, files
/// and comparison included).
#[test]
fn merge_level_icarus_batch_agrees_with_the_pipe_engine() {
    if !tools_present(&["iverilog"]) {
        return;
    }
    let p = Params::default();
    let dir = tempfile::tempdir().unwrap();
    let m = rtl_gen::merge::merge_level_unit(&p);
    let design = design_of(&m, dir.path());
    let batch = icarus_batch(&design);
    let (vs, n, _, _) = vectors(&p, 0x5ee, 1_500);
    for stall in [0.0, 0.3] {
        let what = "merge_level icarus pipe vs batch";
        let pipe = engine("iverilog", &m, &design);
        let pipe = run_sim(Sim::Stepped(pipe), &vs, n, 7, stall, what);
        let b = run_sim(Sim::Batch(&batch), &vs, n, 7, stall, what);
        assert_eq!(
            (b.inputs_sent, b.outputs_received, b.matched),
            (pipe.inputs_sent, pipe.outputs_received, pipe.matched)
        );
        assert_eq!(b.accounting, pipe.accounting);
        if stall == 0.0 {
            assert_eq!(b.cycles, pipe.cycles);
        }
        let speed = |r: &cosim::tb::BenchReport| r.cycles as f64 / r.wall.as_secs_f64();
        println!(
            "merge_level default, stall {stall}: Icarus pipe engine {:.0} cycles/s, batch mode {:.0} cycles/s (x{:.1})",
            speed(&pipe),
            speed(&b),
            speed(&b) / speed(&pipe)
        );
    }
}

#[test]
fn merge_level_verilog_lints_and_synthesizes() {
    if !tools_present(&["verilator", "yosys"]) {
        return;
    }
    for (_, p) in configs() {
        let dir = tempfile::tempdir().unwrap();
        let m = rtl_gen::merge::merge_level_unit(&p);
        let warnings = m.validate_design().expect("valid");
        assert!(warnings.is_empty(), "{warnings:?}");
        lint_and_synth(&design_of(&m, dir.path()));
    }
}

/// The bench notices a wrong bit: a flipped bit of one expected created
/// node's box (or count) is a mismatch, so passing runs mean agreement.
#[test]
fn merge_level_bench_catches_a_flipped_bit() {
    let p = Params::default();
    let (mut vs, _, _, _) = vectors(&p, 0xbad, 300);
    let l = BeatLayout::output(&p);
    let flip = l.rec.offset + l.node.count().offset;
    let target = vs
        .iter()
        .position(|v| {
            v.outputs
                .first()
                .is_some_and(|o| o[0].extract(l.kind.offset, 2).unwrap().to_u64() == Some(0))
        })
        .expect("a created node");
    vs[target].outputs[0][0].flip_bit(flip).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let m = rtl_gen::merge::merge_level_unit(&p);
    let design = design_of(&m, dir.path());
    let mut e = engine("ir", &m, &design);
    let config = cosim::tb::BenchConfig {
        stop_on_mismatch: false,
        ..cosim::tb::BenchConfig::default()
    };
    let r = cosim::tb::run_stream_bench(
        e.as_mut(),
        &cosim::tb::StreamNames::single("data"),
        &vs,
        None,
        &config,
        None,
    )
    .unwrap();
    assert!(!r.passed());
    assert_eq!(r.mismatches, 1, "{r}");
}

/// `emit_merge` writes one Verilog file per module of a configuration, named
/// after it, each of which lints clean as the top.
#[test]
fn emit_merge_writes_every_stage() {
    if !tools_present(&["verilator"]) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let c = rtl_gen::merge::MergeConfig::default();
    let files = rtl_gen::merge::emit_merge(&c, dir.path()).unwrap();
    let names: Vec<String> = files
        .iter()
        .map(|f| f.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    // The top modules and their instances (the merging module's), each once, sorted.
    let mut want: Vec<String> = rtl_gen::merge::merge_units(&c)
        .unwrap()
        .iter()
        .map(|m| m.name())
        .collect();
    want.push(rtl_gen::merge::merge_level_name(&c.params));
    want.push(rtl_gen::merge::overlap_counter_name(
        &c.params, c.inputs, 1, 2,
    ));
    want.push(rtl_gen::merge::morton_merge_name(&c.params, c.inputs, true));
    // The record writer's level modules: level 0's without by-slot buffers.
    let capacity = rtl_gen::merge::MergerConfig::new(c).sizes.capacity_bits;
    for by_slot in [true, false] {
        want.push(rtl_gen::merge::record_writer_level_name(
            &c.params, capacity, by_slot,
        ));
    }
    // The hierarchy unit's translation unit, with a lookup port per input.
    let unit = rtl_gen::merge::HierarchyUnitConfig::new(rtl_gen::merge::MergerConfig::new(c));
    want.push(rtl_gen::translate::lookup_unit_name(&unit.table, c.inputs));
    want.sort();
    // The fetcher's root sorter is the standalone one (same capacity).
    assert_eq!(names, want);
    assert_eq!(names.len(), 14);
    // Each module as the top, with every emitted file so that a module
    // that instantiates others (the merging module) finds them.
    for name in &names {
        let out = std::process::Command::new("verilator")
            .args(["--lint-only", "-Wall", "--top-module", name])
            .args(&files)
            .output()
            .unwrap();
        assert!(
            out.status.success() && out.stderr.is_empty(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}
