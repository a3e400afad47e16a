//! S616 in hardware, every level at once (`rtl_gen::merge::upper_builder_unit`,
//! SPEC.md section 8.11) against `golden::merge::upper_builder::unit::builder_transaction`
//! (expected outputs from the golden `build_levels`, grouping and lift rule),
//! bit for bit on every `level{d}` stream and on `done`, with independent
//! random stalls (0.05..=0.5) on every `base{d}` and out stream
//! (`cosim::tb::run_multi_stream_bench`), on the IR simulator, Verilator and
//! Icarus. Stimulus: random bases (`random_base`: every top rule, empty
//! bases, leaves above the merging level, small-I overflows) and the bases of
//! real merges (golden-built soups, translated, walked and merged by S614 at
//! every candidate level: `fixed_level_base`). Throughput with no
//! back-pressure printed; lint and synthesis. The bench (streams, stimulus,
//! run) is `cosim::units::upper_builder`; this file holds the
//! configurations, seeds and what each run must reach.
mod merge_common;

use cosim::tb::MultiReport;
use cosim::units::multi_stream::MultiSim;
use cosim::units::upper_builder::{self, random_merges, real_merges, BuilderStreams};
use golden::merge::upper_builder::unit::{builder_transaction, random_base, BuilderTransaction};
use golden::params::Params;
use golden::seed::seeded;
use golden::translate::stimulus::SplitMix64;
use merge_common::*;

fn configs() -> Vec<(&'static str, Params)> {
    vec![
        ("default", Params::default()),
        ("d31", Params::new(31, 16, 32, 8).unwrap()),
        ("q0", Params::new(8, 0, 12, 3).unwrap()),
        // 2^I = 8: positions, counts and `first` overflow.
        ("i3", Params::new(5, 2, 3, 2).unwrap()),
    ]
}

/// The streams of `txs`.
fn streams(p: &Params, txs: &[BuilderTransaction]) -> BuilderStreams {
    upper_builder::streams(p, txs).expect("the beats pack")
}

/// One run of `s` on `engine`, every stream stalling with probability
/// `stall`; printed, a panic naming the run when it fails.
fn bench(
    engine: &mut dyn cosim::Engine,
    s: &BuilderStreams,
    seed: u64,
    stall: f64,
    what: &str,
) -> MultiReport {
    let sim = MultiSim::Stepped(engine);
    let r = upper_builder::run(sim, s, &stalled(seed, stall)).expect("the bench runs");
    check_passed(&r, stall, what);
    r
}

/// Random merges on every engine (`runs`: engine, merges), then the real
/// merges on the IR simulator and Verilator (Icarus on the first few).
fn check(name: &str, runs: &[(&str, usize)], most: u64) {
    let all = configs();
    let i = all.iter().position(|c| c.0 == name).unwrap();
    let p = all[i].1;
    let seed = seeded(0xb11d + i as u64);
    let dir = tempfile::tempdir().unwrap();
    let m = upper_builder::upper_builder_module(&p);
    let design = design_of(&m, dir.path());
    // Soups need more than 2^I triangle indices at small I: random bases only.
    let real = if p.index_bits >= 8 {
        real_merges(&p).expect("the real merges build")
    } else {
        Vec::new()
    };
    for &(kind, merges) in runs {
        let stall = stall_of(seed ^ kind.len() as u64).max(0.05);
        let mut e = engine(kind, &m, &design);
        let txs = random_merges(&p, seed, merges, most);
        let s = streams(&p, &txs);
        let seen = &s.seen;
        eprintln!("upper_builder {name}/{kind} random: {seen:?}");
        assert!(
            seen.no_top > 0 && seen.several_roots > 0 && seen.top_above_base > 0,
            "{seen:?}"
        );
        if merges >= 150 {
            assert!(seen.lifted > 0 && seen.root_cut > 0, "{seen:?}");
        }
        if p.index_bits <= 3 {
            assert!(seen.overflow > 0, "{seen:?}");
        }
        let what = format!("merge_builder {name} {kind} random");
        let r = bench(e.as_mut(), &s, seed, stall, &what);
        println!(
            "upper_builder {name} {kind}: {merges} random merges, {} base beats, {} level beats, {} cycles, stall {stall:.2}, {:.1?}",
            seen.base_beats, seen.level_beats, r.cycles, r.wall
        );
        if real.is_empty() {
            continue;
        }
        let count = if kind == "iverilog" { 3 } else { real.len() };
        let s = streams(&p, &real[..count.min(real.len())]);
        let seen = &s.seen;
        let mut e = engine(kind, &m, &design);
        let what = format!("merge_builder {name} {kind} real");
        let r = bench(e.as_mut(), &s, seed + 1, stall, &what);
        println!(
            "upper_builder {name} {kind}: {} real merges, {} base beats, {} level beats, {} cycles",
            seen.merges, seen.base_beats, seen.level_beats, r.cycles
        );
    }
}

/// Beats per cycle with no back-pressure on large bases (Verilator cycle
/// counts): level beats out over all streams, base beats in, and the
/// deepest level's stream alone (a level streams at one beat per clock).
fn throughput(name: &str) -> (f64, f64) {
    let p = configs().into_iter().find(|c| c.0 == name).unwrap().1;
    let dir = tempfile::tempdir().unwrap();
    let m = upper_builder::upper_builder_module(&p);
    let design = design_of(&m, dir.path());
    // One merging level per merge, 2000 nodes there, no leaves above.
    let mut rng = SplitMix64(seeded(0x7b));
    let mut txs: Vec<BuilderTransaction> = Vec::new();
    while txs.len() < 8 {
        let mut base = random_base(&mut rng, &p, 2000);
        let deepest = base.iter().map(|b| b.record.voxel.lod).max().unwrap_or(0);
        base.retain(|b| b.record.voxel.lod == deepest);
        if base.len() >= 1000 {
            txs.push(builder_transaction(&base, &p));
        }
    }
    let s = streams(&p, &txs);
    let seen = &s.seen;
    let mut e = engine("verilator", &m, &design);
    let what = format!("merge_builder {name} throughput");
    let r = bench(e.as_mut(), &s, 1, 0.0, &what);
    let cycles = r.cycles as f64;
    let base_in: u64 = r.sent.iter().map(|s| s.1).sum();
    let deepest = txs
        .iter()
        .map(|t| t.base.iter().rposition(|b| b.len() > 1).unwrap())
        .collect::<Vec<_>>();
    let deepest_beats: u64 = txs
        .iter()
        .zip(&deepest)
        .map(|(t, &d)| t.base[d].len() as u64)
        .sum();
    let deepest_rate = deepest_beats as f64 / cycles;
    println!(
        "upper_builder {name} throughput: {} merges, {base_in} base beats in ({:.4}/cycle), {} level beats out ({:.4}/cycle), merging-level stream {deepest_beats} beats: {deepest_rate:.4} beats/cycle, {} cycles",
        seen.merges,
        base_in as f64 / cycles,
        seen.level_beats,
        seen.level_beats as f64 / cycles,
        r.cycles
    );
    (deepest_rate, seen.level_beats as f64 / cycles)
}

#[test]
fn upper_builder_default_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check(
        "default",
        &[("ir", 150), ("verilator", 1500), ("iverilog", 25)],
        40,
    );
}

#[test]
fn upper_builder_d31_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check(
        "d31",
        &[("ir", 60), ("verilator", 600), ("iverilog", 10)],
        40,
    );
}

#[test]
fn upper_builder_q0_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check(
        "q0",
        &[("ir", 150), ("verilator", 1500), ("iverilog", 25)],
        40,
    );
}

#[test]
fn upper_builder_small_index_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check(
        "i3",
        &[("ir", 150), ("verilator", 1500), ("iverilog", 25)],
        12,
    );
}

#[test]
fn upper_builder_streams_one_beat_per_clock() {
    if !tools_present(&["verilator"]) {
        return;
    }
    for name in ["default", "q0"] {
        let (deepest, _) = throughput(name);
        assert!(deepest >= 0.95, "{name}: {deepest:.4} beats per cycle");
    }
}

/// Every configuration lints clean; the small ones (D = 8, D = 5) also go
/// through Yosys `synth` with no latch. The stages are the same logic at
/// every D; the default and D = 31 synthesize the same way but take 45 s
/// and 140 s, too long for every run.
#[test]
fn upper_builder_verilog_lints_and_synthesizes() {
    if !tools_present(&["verilator", "yosys"]) {
        return;
    }
    for (name, p) in configs() {
        let t = std::time::Instant::now();
        let dir = tempfile::tempdir().unwrap();
        let m = upper_builder::upper_builder_module(&p);
        let warnings = m.validate_design().expect("valid");
        assert!(warnings.is_empty(), "{name}: {warnings:?}");
        let design = design_of(&m, dir.path());
        if p.max_lod <= 8 {
            lint_and_synth(&design);
        } else {
            lint_only(&design);
        }
        println!(
            "upper_builder {name}: lint (and synthesis) in {:.1?}",
            t.elapsed()
        );
    }
}
