//! S618 in hardware, the record writer (`rtl_gen::merge::record_writer_unit`,
//! SPEC.md section 8.12) against `golden::merge::record_writer::writer_transaction`
//! (expected records and references: the merged hierarchy
//! `merge::upper_builder::build_upper` lays out, tested equal to `merge()`'s in
//! golden), bit for bit on every out stream (`ref_req`, `nodes`, `refs`,
//! `header`), with independent random stalls on every stream
//! (`cosim::tb::run_multi_stream_bench`; the store's responses are an
//! ordinary input stream), on the IR simulator, Verilator and Icarus (pipe
//! and multi-stream batch). Stimulus: random cases (`stimulus::random_case`: every top
//! rule, materialized roots, capacity and index overflows at small I) and
//! real merges (golden-built soups at every fixed level and in per-node
//! mode, created nodes at several LODs). Throughput with no back-pressure;
//! lint and synthesis. The bench (streams, stimulus, run) is
//! `cosim::units::record_writer`; this file holds the configurations, seeds
//! and what each run must reach.
mod merge_common;

use cosim::tb::{MultiReport, PulseCounts};
use cosim::units::multi_stream::MultiSim;
use cosim::units::record_writer::{
    self, random_merges, real_merges, record_writer_module, Seen, WriterStreams,
};
use cosim::volume::volume;
use golden::merge::record_writer::{writer_err, WriterTransaction};
use golden::params::Params;
use golden::seed::seeded;
use merge_common::*;

/// Name, parameters, capacity bits (2^C entries per level buffer).
fn configs() -> Vec<(&'static str, Params, u32)> {
    vec![
        ("default", Params::default(), 8),
        ("d31", Params::new(31, 16, 32, 8).unwrap(), 8),
        ("q0", Params::new(8, 0, 12, 3).unwrap(), 8),
        // 2^I = 8 and 4 entries per level: capacity and index overflows.
        ("small", Params::new(5, 2, 3, 2).unwrap(), 2),
    ]
}

/// The streams of `txs` for a writer of `2^cap` entries per level buffer.
fn streams(p: &Params, cap: u32, txs: &[WriterTransaction]) -> WriterStreams {
    record_writer::streams(p, cap, txs).expect("the beats pack")
}

/// One run of `s` on `sim`, every stream stalling with probability
/// `stall`, counting the phase outputs on a stepped engine; printed, a
/// panic naming the run when it fails.
fn bench(
    sim: MultiSim,
    s: &WriterStreams,
    seed: u64,
    stall: f64,
    what: &str,
) -> (MultiReport, PulseCounts) {
    let r = record_writer::run(sim, s, &stalled(seed, stall)).expect("the bench runs");
    check_passed(&r.0, stall, what);
    r
}

/// Merges per bench run; longer runs go in chunks of fresh stimulus on the
/// same simulator.
const CHUNK: usize = 10_000;

/// Random merges on every engine (`runs`: engine, merges), then the real
/// merges on each (Icarus pipe: the first few).
fn check(name: &str, runs: &[(&str, usize)], most: u64) {
    let all = configs();
    let k = all.iter().position(|c| c.0 == name).unwrap();
    let (_, p, cap) = all[k];
    let seed = seeded(0x5618 + k as u64);
    let dir = tempfile::tempdir().unwrap();
    let m = record_writer_module(&p, cap).expect("a valid capacity");
    let design = design_of(&m, dir.path());
    // Soups need more than 2^I triangle indices at small I: random only.
    let real = if p.index_bits >= 8 {
        real_merges(&p, cap).expect("the real merges build")
    } else {
        Vec::new()
    };
    for &(kind, total) in runs {
        let t = std::time::Instant::now();
        let stall = stall_of(seed ^ kind.len() as u64).max(0.05);
        let what = format!("merge_writer {name} {kind}");
        let mut e = (kind != "iverilog-batch").then(|| engine(kind, &m, &design));
        let (mut done, mut cycles, mut chunk) = (0, 0, 0u64);
        let mut all_seen = Seen::default();
        while done < total {
            let merges = CHUNK.min(total - done);
            let txs = random_merges(&p, cap, seed + chunk, merges, most).expect("a case lays out");
            let s = streams(&p, cap, &txs);
            // A stepped engine's cycle count runs on over the chunks.
            let before = e.as_ref().map_or(0, |e| e.cycle());
            let sim = sim_of(&mut e, &design);
            cycles += bench(sim, &s, seed + chunk, stall, &what).0.cycles - before;
            done += merges;
            chunk += 1;
            all_seen.add(&s.seen);
        }
        eprintln!("merge_writer {name}/{kind} random: {all_seen:?}");
        if total >= 100 {
            assert!(
                all_seen.codes[0] > 0
                    && all_seen.codes[writer_err::NO_TOP as usize] > 0
                    && all_seen.materialized > 0
                    && all_seen.several_roots > 0
                    && all_seen.created_lods > 0,
                "{all_seen:?}"
            );
            if p.index_bits <= 3 {
                assert!(
                    all_seen.codes[writer_err::CAPACITY as usize] > 0
                        && all_seen.codes[writer_err::INDEX_OVERFLOW as usize] > 0,
                    "{all_seen:?}"
                );
            }
        }
        println!(
            "merge_writer {name} {kind}: {total} random merges, {} level beats, {} records, {} refs, {cycles} cycles, stall {stall:.2}, {:.1?}",
            all_seen.level_beats, all_seen.records, all_seen.refs, t.elapsed()
        );
        if real.is_empty() {
            continue;
        }
        let count = if kind == "iverilog" { 3 } else { real.len() };
        let s = streams(&p, cap, &real[..count.min(real.len())]);
        let seen = &s.seen;
        let created_lods = seen.created_lods;
        assert_eq!(seen.codes[0], seen.merges, "real merges fit: {seen:?}");
        let what = format!("merge_writer {name} {kind} real");
        let mut e = (kind != "iverilog-batch").then(|| engine(kind, &m, &design));
        let sim = sim_of(&mut e, &design);
        let cycles = bench(sim, &s, seed + 1, stall, &what).0.cycles;
        println!(
            "merge_writer {name} {kind}: {} real merges ({created_lods} with created nodes at several LODs, {} materialized), {} level beats, {} records, {} refs, {cycles} cycles",
            seen.merges, seen.materialized, seen.level_beats, seen.records, seen.refs
        );
    }
}

/// Runs per engine: the IR simulator, Verilator, Icarus over pipes (slow:
/// a few merges) and Icarus in batch mode. The Verilator counts are what
/// fits about 60-90 s of wall per configuration on 2 shared cores.
fn runs(ir: usize, verilator: usize, pipe: usize, batch: usize) -> Vec<(&'static str, usize)> {
    vec![
        ("ir", ir),
        ("verilator", volume(verilator)),
        ("iverilog", pipe),
        ("iverilog-batch", batch),
    ]
}

#[test]
fn record_writer_default_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check("default", &runs(300, 10_000, 20, 500), 40);
}

#[test]
fn record_writer_d31_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check("d31", &runs(150, 5_000, 10, 200), 40);
}

#[test]
fn record_writer_q0_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check("q0", &runs(300, 40_000, 30, 1_000), 40);
}

#[test]
fn record_writer_small_capacity_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check("small", &runs(300, 100_000, 30, 1_000), 12);
}

/// With no back-pressure (Verilator cycle counts, status outputs counted
/// per cycle): the fill takes the longest in stream at one beat per clock,
/// and each drain sequencer writes one word per clock while it has words.
#[test]
fn record_writer_one_word_per_clock() {
    if !tools_present(&["verilator"]) {
        return;
    }
    for name in ["default", "q0"] {
        let (_, p, cap) = configs().into_iter().find(|c| c.0 == name).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let m = record_writer_module(&p, cap).unwrap();
        let design = design_of(&m, dir.path());
        // Large merges: real ones, then random cases of up to 2^C / 2 nodes.
        let mut txs = real_merges(&p, cap).expect("the real merges build");
        txs.extend(
            random_merges(&p, cap, 0x7b, 400, 1 << (cap - 1))
                .expect("a case lays out")
                .into_iter()
                .filter(|t| t.header.err == writer_err::NONE),
        );
        let s = streams(&p, cap, &txs);
        let seen = &s.seen;
        let mut e = engine("verilator", &m, &design);
        let what = format!("merge_writer {name} throughput");
        let (r, counts) = bench(MultiSim::Stepped(e.as_mut()), &s, 1, 0.0, &what);
        let count = |n: &str| counts.iter().find(|c| c.0 == n).unwrap().1 as f64;
        let fill = seen.longest_in as f64 / count("filling");
        let records = seen.records as f64 / count("drain_records");
        let refs = seen.refs as f64 / count("drain_refs");
        println!(
            "merge_writer {name} throughput: {} merges, {} cycles; fill: longest in stream {} beats in {} filling cycles ({fill:.4}/cycle); drain: {} records in {} cycles ({records:.4}/cycle), {} refs in {} cycles ({refs:.4}/cycle)",
            seen.merges,
            r.cycles,
            seen.longest_in,
            count("filling"),
            seen.records,
            count("drain_records"),
            seen.refs,
            count("drain_refs"),
        );
        assert!(fill >= 0.95 && records >= 0.95 && refs >= 0.95, "{name}");
    }
}

/// Every configuration lints clean; the small one (D = 5, C = 2) goes
/// through Yosys' plain `synth; check -assert` with no latch (its 4-word
/// buffers are flip-flops). The default configuration's synthesis, with
/// the buffers mapped onto RAM macros, is in tests/verilog_fresh.rs
/// (SPEC.md 11, "Mapping the RAMs").
#[test]
fn record_writer_verilog_lints_and_synthesizes() {
    if !tools_present(&["verilator", "yosys"]) {
        return;
    }
    for (name, p, cap) in configs() {
        let t = std::time::Instant::now();
        let dir = tempfile::tempdir().unwrap();
        let m = record_writer_module(&p, cap).unwrap();
        let warnings = m.validate_design().expect("valid");
        assert!(warnings.is_empty(), "{name}: {warnings:?}");
        let design = design_of(&m, dir.path());
        lint_only(&design);
        if p.max_lod <= 5 {
            lint_and_synth(&design);
        }
        println!(
            "record_writer {name}: lint (and synthesis at D = 5, C = 2) in {:.1?}",
            t.elapsed()
        );
    }
}

#[test]
fn capacity_outside_one_to_i_is_an_error() {
    let p = Params::default();
    assert!(rtl_gen::merge::record_writer_unit(&p, 0).is_err());
    assert!(rtl_gen::merge::record_writer_unit(&p, p.index_bits as u32).is_err());
}
