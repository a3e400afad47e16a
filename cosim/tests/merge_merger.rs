//! The hierarchy merger, S610-S618 as one top module
//! (`rtl_gen::merge::hierarchy_merger_unit`, SPEC.md section 8.15), against
//! `golden::merge::merger::merger_transaction` (the chain of the units'
//! golden transactions, tested equal to `merge()` in golden), bit for bit on
//! every out stream: `report`, every fetcher's `node_req` / `ref_req`, the
//! writer's `ref_req`, `nodes`, `refs`, `header`. The store's responses are
//! precomputed from golden and presented as ordinary input streams (each
//! unit raises `resp_ready` only while a request is outstanding). Random
//! stalls on every stream (`cosim::tb::run_multi_stream_bench`); Verilator,
//! Icarus (multi-stream batch) and the IR simulator; throughput with no
//! back-pressure; lint and synthesis.
mod merge_common;

use cosim::tb::{run_multi_stream_bench_watching, BenchConfig, MultiReport, StreamBeats};
use cosim::units::merger::{merger_streams, random_merge, MergeStats};
use golden::merge::fetcher::{FetchCmd, FetchOut, FetchTransaction};
use golden::merge::merge_level::unit::LevelBeat;
use golden::merge::merge_module::MergeDesign;
use golden::merge::merger::{
    cmd_per_level, feeds_module, merger_transaction, MergerSizes, MergerTransaction,
};
use golden::merge::stimulus::{place, soup};
use golden::merge::MergeMode;
use golden::params::Params;
use golden::seed::seeded;
use golden::store::HierarchyStore;
use golden::translate::stimulus::SplitMix64;
use golden::translate::TranslationTable;
use golden::vectors::hard_merges::hard_merges;
use merge_common::*;
use rtl_gen::merge::MergerConfig;

/// Name and configuration: the default (D = 16, k = 4, overlap 1/2), a
/// small one (D = 8, Q = 0, k = 3, proportion:1/1: the deepest candidate)
/// D = 31 (Q = 16, I = 32, H = 8, k = 5, overlap 1/3) and `fixed:4` with
/// k = 2 at D = 8, Q = 0 (refuses a merge whose candidates do not hold 4),
/// and per-node 1/2 at the default (k = 4; its FIFOs hold every LOD's
/// pass nodes, so 256 each).
fn configs() -> Vec<(&'static str, MergerConfig)> {
    let sizes = |p: &Params, cap: u32| MergerSizes {
        capacity_bits: cap,
        leaf_bits: 6,
        ..MergerSizes::new(p)
    };
    let default = MergeDesign::default();
    let q0 = MergeDesign {
        params: Params::new(8, 0, 12, 3).unwrap(),
        inputs: 3,
        mode: MergeMode::Proportion { num: 1, den: 1 },
        roots: 16,
    };
    let d31 = MergeDesign {
        params: Params::new(31, 16, 32, 8).unwrap(),
        inputs: 5,
        mode: MergeMode::Overlap { num: 1, den: 3 },
        roots: 16,
    };
    vec![
        (
            "default",
            MergerConfig {
                sizes: sizes(&default.params, 8),
                design: default,
            },
        ),
        (
            "q0",
            MergerConfig {
                sizes: sizes(&q0.params, 7),
                design: q0,
            },
        ),
        (
            "d31",
            MergerConfig {
                sizes: sizes(&d31.params, 7),
                design: d31,
            },
        ),
        (
            "fixed",
            MergerConfig {
                sizes: sizes(&q0.params, 7),
                design: MergeDesign {
                    inputs: 2,
                    mode: MergeMode::Fixed(4),
                    ..q0
                },
            },
        ),
        (
            "pernode",
            MergerConfig {
                sizes: MergerSizes {
                    leaf_bits: 8,
                    ..sizes(&default.params, 8)
                },
                design: MergeDesign {
                    mode: MergeMode::PerNode { num: 1, den: 2 },
                    ..default
                },
            },
        ),
    ]
}

/// The merger's streams of `txs` (the CLI's stimulus packing), unwrapped:
/// (inputs, outputs, what they exercise).
fn streams(
    c: &MergerConfig,
    txs: &[MergerTransaction],
) -> (Vec<StreamBeats>, Vec<StreamBeats>, MergeStats) {
    let s = merger_streams(c, txs).expect("the golden merges pack");
    (s.streams.inputs, s.streams.outputs, s.stats)
}

/// The hard merges (`golden::vectors::hard_merges`: real merges, an input
/// of several roots, a fetcher error, refused ranges, the leaf flood)
/// through the configuration's mode; at this file's sizes golden models
/// every one of them (none left out as inexact).
fn real_merges(c: &MergerConfig) -> (Vec<MergerTransaction>, usize) {
    let h = hard_merges(&c.design, c.sizes).expect("the hard merges");
    assert_eq!(h.overflowing, 0, "no hard merge left out as inexact");
    (h.merges, h.several_root_inputs)
}

fn bench(
    engine: &mut dyn cosim::Engine,
    ins: &[StreamBeats],
    outs: &[StreamBeats],
    seed: u64,
    stall: f64,
    what: &str,
) -> MultiReport {
    let config = BenchConfig {
        seed,
        in_stall: cosim::tb::Stalls::Coin(stall),
        out_stall: cosim::tb::Stalls::Coin(stall),
        watchdog_cycles: cosim::units::chunked::WATCHDOG_CYCLES,
        ..BenchConfig::default()
    };
    let (r, counts) = run_multi_stream_bench_watching(engine, ins, outs, &config, &["done"])
        .expect("the bench runs");
    eprint!("{what}: stall {stall:.2}: {r}");
    assert!(r.passed(), "{what} stall {stall}:\n{r}");
    let headers = outs
        .iter()
        .find(|s| s.name == "header")
        .unwrap()
        .beats
        .len() as u64;
    assert_eq!(counts[0].1, headers, "{what}: one done pulse per merge");
    r
}

fn batch_bench(
    design: &cosim::Design,
    ins: &[StreamBeats],
    outs: &[StreamBeats],
    seed: u64,
    stall: f64,
    what: &str,
) -> MultiReport {
    let names = |s: &[StreamBeats]| s.iter().map(|b| b.name.clone()).collect::<Vec<_>>();
    let (i, o) = (names(ins), names(outs));
    let i: Vec<&str> = i.iter().map(String::as_str).collect();
    let o: Vec<&str> = o.iter().map(String::as_str).collect();
    let batch = cosim::icarus::IcarusMultiBatch::new(design, &i, &o).expect("iverilog build");
    let config = BenchConfig {
        seed,
        in_stall: cosim::tb::Stalls::Coin(stall),
        out_stall: cosim::tb::Stalls::Coin(stall),
        watchdog_cycles: cosim::units::chunked::WATCHDOG_CYCLES,
        ..BenchConfig::default()
    };
    let r = batch
        .run(ins, outs, &config)
        .expect("the batch runs")
        .report;
    eprint!("{what}: stall {stall:.2}: {r}");
    assert!(r.passed(), "{what} stall {stall}:\n{r}");
    r
}

/// Real merges, then `random` random merges, on every engine in `runs`;
/// `leaves`: the merges reach leaves above the merging level (not at a
/// shallow fixed level).
fn check(name: &str, runs: &[(&str, usize)], leaves: bool) {
    let all = configs();
    let at = all.iter().position(|c| c.0 == name).unwrap();
    let c = &all[at].1;
    let seed = seeded(0x5615 + at as u64);
    let dir = tempfile::tempdir().unwrap();
    let m = rtl_gen::merge::hierarchy_merger_unit(c).expect("a valid merger");
    let design = design_of(&m, dir.path());
    let (real, several_root_inputs) = real_merges(c);
    assert!(several_root_inputs > 0);
    for &(kind, random) in runs {
        let t = std::time::Instant::now();
        let stall = stall_of(seed ^ kind.len() as u64).max(0.05);
        let mut rng = SplitMix64(seed);
        let mut txs = real.clone();
        txs.extend((0..random).map(|_| random_merge(&mut rng, c).expect("a random merge")));
        let (ins, outs, seen) = streams(c, &txs);
        let what = format!("merge_merger {name} {kind}");
        let r = match kind {
            "iverilog-batch" => batch_bench(&design, &ins, &outs, seed, stall, &what),
            _ => {
                let mut e = engine(kind, &m, &design);
                bench(e.as_mut(), &ins, &outs, seed, stall, &what)
            }
        };
        println!(
            "merge_merger {name} {kind}: {} merges ({} real, {random} random, {} refused), {} module-in beats, {} records, {} refs, {} cycles, stall {stall:.2}, {:.1?} wall; {seen:?}",
            seen.merges,
            real.len(),
            seen.refused,
            seen.module_in,
            seen.records,
            seen.refs,
            r.cycles,
            t.elapsed()
        );
        // Refusals and a fetcher error in every run; on the long run, leaves above the level
        // and roots that are input nodes or several (per-node: multi-pass merges with
        // descents).
        assert!(seen.refused > 0 && seen.fetch_errors > 0, "{seen:?}");
        if matches!(c.design.mode, MergeMode::PerNode { .. }) {
            assert!(seen.multi_pass > 0 && seen.descents > 0, "{seen:?}");
        }
        if kind == "verilator" {
            assert!(
                (seen.leaves_above > 0 || !leaves) && seen.materialized + seen.several_roots > 0,
                "{seen:?}"
            );
        }
    }
}

#[test]
fn hierarchy_merger_default_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check(
        "default",
        &[("verilator", 2000), ("iverilog-batch", 4), ("ir", 2)],
        true,
    );
}

#[test]
fn hierarchy_merger_d31_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check("d31", &[("verilator", 1000), ("iverilog-batch", 1)], true);
}

#[test]
fn hierarchy_merger_fixed_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check(
        "fixed",
        &[("verilator", 1000), ("iverilog-batch", 4), ("ir", 2)],
        false,
    );
}

/// Per-node 1/2 at the default (k = 4): every fetcher runs the per-node
/// command, the module's `report` forks to the top and the fetchers, the
/// passes' nodes come out of the per-LOD FIFOs.
#[test]
fn hierarchy_merger_per_node_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check(
        "pernode",
        &[("verilator", 1000), ("iverilog-batch", 2), ("ir", 1)],
        true,
    );
}

#[test]
fn hierarchy_merger_q0_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check(
        "q0",
        &[("verilator", 1000), ("iverilog-batch", 4), ("ir", 2)],
        true,
    );
}

/// The `out` beats of `f` the glue passes to the merging module (those of
/// the count and merge passes; the closing command's are dropped).
fn fed_beats(f: &FetchTransaction, cmds: &[FetchCmd]) -> u64 {
    if cmds.first().is_some_and(|c| c.per_node) {
        // Every pass of the per-node command goes to the module.
        return f.out.len() as u64;
    }
    let per_level = cmd_per_level(cmds);
    let mut level = 0;
    let mut fed = 0;
    for o in &f.out {
        if per_level.get(level).is_some_and(feeds_module) {
            fed += 1;
        }
        let closes = match o {
            FetchOut::Beat(b) => *b == LevelBeat::End,
            FetchOut::Error { .. } => true,
            FetchOut::Probe { .. } => false,
        };
        level += closes as usize;
    }
    fed
}

/// Merged nodes (records written) per cycle with no back-pressure, on
/// Verilator, over the real merges and random ones; what the fetchers read
/// and send per merge. No back-pressure anywhere also runs the merge pass's
/// one walk (leaves and level `m` together) where nothing hides a wait.
#[test]
fn hierarchy_merger_throughput() {
    if !tools_present(&["verilator"]) {
        return;
    }
    for (name, c) in configs()
        .into_iter()
        .filter(|c| c.0 == "default" || c.0 == "q0" || c.0 == "pernode")
    {
        let dir = tempfile::tempdir().unwrap();
        let m = rtl_gen::merge::hierarchy_merger_unit(&c).expect("a valid merger");
        let design = design_of(&m, dir.path());
        let mut rng = SplitMix64(seeded(77));
        let mut txs: Vec<MergerTransaction> = real_merges(&c).0;
        txs.extend((0..20).map(|_| random_merge(&mut rng, &c).expect("a random merge")));
        let (ins, outs, seen) = streams(&c, &txs);
        let mut e = engine("verilator", &m, &design);
        let r = bench(e.as_mut(), &ins, &outs, 5, 0.0, "merge_merger throughput");
        let reads: u64 = txs
            .iter()
            .map(|t| {
                t.fetch
                    .iter()
                    .map(|f| {
                        f.node_reqs.len()
                            + f.ref_reqs.len()
                            + f.cref_reqs.len()
                            + f.probe_reqs.len()
                    })
                    .sum::<usize>() as u64
            })
            .sum();
        let fed: u64 = txs
            .iter()
            .map(|t| t.fetch.iter().map(|f| fed_beats(f, &t.cmds)).sum::<u64>())
            .sum();
        let cmds: usize = txs.iter().map(|t| t.cmds.len() * t.fetch.len()).sum();
        let merges = seen.merges as f64;
        let cycles = r.cycles as f64;
        println!(
            "merge_merger {name} throughput: {} merges, {cmds} fetcher commands, {} records + {} refs written, {} fetcher out beats ({fed} into the module), {reads} store reads by the fetchers, {} cycles: {:.4} records/cycle, {:.4} module-in beats/cycle ({:.4} counting every fetcher out beat), {:.1} store reads and {:.1} cycles per merge",
            seen.merges,
            seen.records,
            seen.refs,
            seen.module_in,
            r.cycles,
            seen.records as f64 / cycles,
            fed as f64 / cycles,
            seen.module_in as f64 / cycles,
            reads as f64 / merges,
            cycles / merges,
        );
    }
}

/// Both configurations lint clean (`verilator --lint-only -Wall`) with no
/// warning from the generator; the small one also goes through Yosys
/// `synth; check -assert` with no latch (at small capacities).
#[test]
fn hierarchy_merger_verilog_lints_and_synthesizes() {
    if !tools_present(&["verilator", "yosys"]) {
        return;
    }
    for (name, c) in configs() {
        let dir = tempfile::tempdir().unwrap();
        let m = rtl_gen::merge::hierarchy_merger_unit(&c).expect("a valid merger");
        let warnings = m.validate_design().expect("valid");
        assert!(warnings.is_empty(), "{name}: {warnings:?}");
        let design = design_of(&m, dir.path());
        if name == "q0" {
            let small = MergerConfig {
                sizes: MergerSizes {
                    capacity_bits: 2,
                    leaf_bits: 1,
                    fetch: golden::merge::fetcher::FetchSizes {
                        roots: 4,
                        frontier: 4,
                    },
                    store_port: Default::default(),
                },
                design: MergeDesign {
                    roots: 4,
                    ..c.design
                },
            };
            let sm = rtl_gen::merge::hierarchy_merger_unit(&small).expect("a valid merger");
            let sdir = tempfile::tempdir().unwrap();
            let t = std::time::Instant::now();
            lint_and_synth(&design_of(&sm, sdir.path()));
            println!(
                "merge_merger {name} small: lint + yosys synth in {:.1?}",
                t.elapsed()
            );
        }
        let t = std::time::Instant::now();
        lint_only(&design);
        println!("merge_merger {name}: lint in {:.1?}", t.elapsed());
    }
}

/// Per-node logic only in the per-node merger: its fetchers' probe ports
/// come out of the top, a level mode's top has none; the per-node merger
/// at small sizes (D = 4, Q = 0, I = 8, H = 2, k = 2) lints clean and goes through Yosys
/// `synth; check -assert` with no latch.
#[test]
fn hierarchy_merger_per_node_ports_lint_and_synth() {
    let has_probe = |c: &MergerConfig| {
        let m = rtl_gen::merge::hierarchy_merger_unit(c).expect("a valid merger");
        m.ports().iter().any(|q| q.name.contains("probe"))
    };
    for (name, c) in configs() {
        let pn = matches!(c.design.mode, MergeMode::PerNode { .. });
        assert_eq!(has_probe(&c), pn, "{name}");
    }
    if !tools_present(&["verilator", "yosys"]) {
        return;
    }
    let small = MergerConfig {
        sizes: MergerSizes {
            capacity_bits: 2,
            leaf_bits: 1,
            fetch: golden::merge::fetcher::FetchSizes {
                roots: 4,
                frontier: 4,
            },
            store_port: Default::default(),
        },
        design: MergeDesign {
            params: Params::new(4, 0, 8, 2).unwrap(),
            inputs: 2,
            mode: MergeMode::PerNode { num: 1, den: 2 },
            roots: 4,
        },
    };
    let sm = rtl_gen::merge::hierarchy_merger_unit(&small).expect("a valid merger");
    let warnings = sm.validate_design().expect("valid");
    assert!(warnings.is_empty(), "{warnings:?}");
    let sdir = tempfile::tempdir().unwrap();
    let t = std::time::Instant::now();
    lint_and_synth(&design_of(&sm, sdir.path()));
    println!(
        "merge_merger per-node small: lint + yosys synth in {:.1?}",
        t.elapsed()
    );
}

fn lint_only(design: &cosim::Design) {
    let files: Vec<String> = design
        .verilog_files
        .iter()
        .map(|f| f.display().to_string())
        .collect();
    let out = std::process::Command::new("verilator")
        .args(["--lint-only", "-Wall", "--top-module", &design.top])
        .args(&files)
        .output()
        .expect("verilator runs");
    let text =
        String::from_utf8_lossy(&out.stderr).to_string() + &String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && text.trim().is_empty(),
        "verilator lint of {}:\n{text}",
        design.top
    );
}

/// Steady state with no back-pressure (SPEC 8.15, Throughput): one merge
/// of k overlapping soups at a time, of growing size, on a fresh engine.
/// While a stream moves beats it moves one a clock: the writer's `nodes` and
/// `refs` from their first beat to their last, and the fetchers' store
/// reads together, which share the merging module's one merged input (each
/// fetcher gets about 1/k of the clocks). What the whole merge loses is
/// between its phases (count pass, the choice and the walk to `m`, merge
/// pass, write), which run one after the other; the printout gives the
/// cycles of each.
#[test]
fn hierarchy_merger_steady_state() {
    if !tools_present(&["verilator"]) {
        return;
    }
    let mut c = MergerConfig::new(MergeDesign::default());
    // Leaf FIFOs for the leaves above the merging level of large inputs.
    c.sizes.leaf_bits = 9;
    let p = c.design.params;
    let k = c.design.inputs;
    let dir = tempfile::tempdir().unwrap();
    let m = rtl_gen::merge::hierarchy_merger_unit(&c).expect("a valid merger");
    let design = design_of(&m, dir.path());
    for tris in [80usize, 320] {
        let mut store = HierarchyStore::new();
        let mut table = TranslationTable::new(p.hier_capacity() as usize, &p).unwrap();
        let ids: Vec<u8> = (1..=k as u8).collect();
        for &id in &ids {
            let h = soup(&p, id, tris, 0.3, 1000 + id as u64);
            table.write(id as u32, place(&h, [0.5, 0.5, 0.5])).unwrap();
            store.insert(h).unwrap();
        }
        let tx = merger_transaction(&store, &table, &ids, c.design.mode, 9, k, c.sizes)
            .expect("the merge");
        let h = &tx.header;
        assert!(!h.leaf_overflow && h.writer.err == 0, "{tris}: {h:?}");
        let (ins, outs, seen) = streams(&c, std::slice::from_ref(&tx));
        let mut e = engine("verilator", &m, &design);
        let r = bench(e.as_mut(), &ins, &outs, 3, 0.0, "merge_merger steady state");
        let w = |name: &str| {
            r.active(name)
                .unwrap_or_else(|| panic!("`{name}` moved nothing"))
        };
        // The store reads of every fetcher together, first to last.
        let reads: Vec<_> = (0..k).map(|i| w(&format!("f{i}_node_req"))).collect();
        let (first, last) = (
            reads.iter().map(|a| a.first).min().unwrap(),
            reads.iter().map(|a| a.last).max().unwrap(),
        );
        let read_beats: u64 = reads.iter().map(|a| a.beats).sum();
        let read_rate = read_beats as f64 / (last - first + 1) as f64;
        let (nodes, refs) = (w("nodes"), w("refs"));
        println!(
            "steady state, {k} soups of {tris} triangles: {} cycles; {} beats into the module; store node reads {read_beats} in cycles {first}..{last} ({read_rate:.3} a clock, per fetcher {}); written: {} records in {}..{} ({:.3}), {} refs in {}..{} ({:.3})",
            r.cycles,
            seen.module_in,
            reads
                .iter()
                .map(|a| format!("{:.3}", a.beats as f64 / (last - first + 1) as f64))
                .collect::<Vec<_>>()
                .join(" "),
            nodes.beats,
            nodes.first,
            nodes.last,
            nodes.rate(),
            refs.beats,
            refs.first,
            refs.last,
            refs.rate(),
        );
        assert!(
            nodes.rate() >= 0.95 && refs.rate() >= 0.95,
            "{tris}: the writer bubbles"
        );
        // Two walks (count pass, merge pass) with the choice between them:
        // a fixed gap, small against the reads of the larger merge.
        if tris == 320 {
            assert!(
                read_rate >= 0.9,
                "the fetchers' reads bubble: {read_rate:.3}"
            );
        }
    }
}

/// The hierarchy unit (docs/hardware.md 8.16): determine commands write
/// the translation unit's table, the merge command after them runs the
/// merger top on that table with `(lo, hi)` from the headers; every beat
/// (`det_out` and the merger's) against golden, random stalls, on the three
/// engines, at the default, at D = 31 (binary64 placements of up to 31
/// bits), at Q = 0 with k = 3 and at D = 8 `fixed:4` with k = 2 (per-node
/// runs in the long-run ledger): volume on Verilator (2,000 merges each),
/// depth on Icarus (the 4-state engine) and the IR simulator, whose
/// 100,000 and 2,000 merges per configuration are the long-run ledger's.
#[test]
fn hierarchy_unit_matches_golden_on_three_engines() {
    use cosim::units::hierarchy_unit::{run, Cases};
    use cosim::units::multi_stream::{ModuleEngine, RunConfig};
    use rtl_gen::merge::HierarchyUnitConfig;
    let bench = RunConfig {
        seed: seeded(8016),
        stall: cosim::tb::Stalls::Coin(0.3),
        ..RunConfig::default()
    };
    for (name, merger) in configs().into_iter().filter(|c| c.0 != "pernode") {
        let c = HierarchyUnitConfig::new(merger);
        for (engine, count) in [
            (ModuleEngine::Ir, 3),
            (ModuleEngine::Verilator, 2000),
            (ModuleEngine::Iverilog, 6),
        ] {
            let dir = tempfile::tempdir().unwrap();
            let o = run(
                &c,
                engine,
                &bench,
                Cases::random(count),
                dir.path(),
                &mut |_, _| {},
            )
            .unwrap();
            let (t, stats) = (o.totals, o.stats);
            assert_eq!(stats.merges.merges, count, "every case is counted");
            assert_eq!(
                stats.determines as usize,
                stats
                    .merges
                    .by_inputs
                    .iter()
                    .map(|(n, m)| n * m)
                    .sum::<usize>(),
                "one determine command per input"
            );
            assert!(
                t.passed(),
                "{name} on {engine:?}: {} mismatches, first {:?}, missing {:?}, hang {:?}, {:?}",
                t.mismatches,
                t.first_mismatch,
                t.missing,
                t.hang,
                t.status_failure()
            );
            assert_eq!(t.merges, count);
            let det_out = t
                .received
                .iter()
                .find(|r| r.0 == "det_out")
                .map_or(0, |r| r.1);
            assert!(det_out as usize >= count, "{name}: {det_out} det_out beats");
        }
        // Golden's named hard cases (deep tops, several and sixteen roots,
        // the leaf ladder, the real merges), written by determine commands.
        let dir = tempfile::tempdir().unwrap();
        let hard = Cases {
            count: 20,
            merges: golden::vectors::streams::Merges::Hard,
            flip: None,
        };
        let engine = ModuleEngine::Verilator;
        let o = run(&c, engine, &bench, hard, dir.path(), &mut |_, _| {}).unwrap();
        assert!(o.stats.named > 0, "{name}: no named hard case");
        assert!(
            o.totals.passed(),
            "{name}, hard merges: {} mismatches, first {:?}",
            o.totals.mismatches,
            o.totals.first_mismatch
        );
    }
}

/// A hierarchy unit whose range ignores the headers' `deep` (`hi = lo`)
/// fails against golden: the headers' range is what the merges use.
#[test]
fn hierarchy_unit_with_a_wrong_range_fails() {
    use cosim::units::hierarchy_unit::{run, Cases};
    use cosim::units::multi_stream::{ModuleEngine, RunConfig, VerilogPatch};
    use rtl_gen::merge::HierarchyUnitConfig;
    // The Q = 0 configuration (k = 3), on Icarus: a patched netlist is a
    // build of its own, which Icarus makes in a second and Verilator in
    // half a minute.
    let c = HierarchyUnitConfig::new(configs().remove(1).1);
    let bench = RunConfig {
        seed: seeded(8017),
        verilog_patch: Some(VerilogPatch {
            from: "assign range_hi = (deep_upto2 > range_lo) ? deep_upto2 : range_lo;".into(),
            to: "assign range_hi = range_lo;".into(),
        }),
        ..RunConfig::default()
    };
    let dir = tempfile::tempdir().unwrap();
    let t = run(
        &c,
        ModuleEngine::Iverilog,
        &bench,
        Cases::random(30),
        dir.path(),
        &mut |_, _| {},
    )
    .unwrap()
    .totals;
    assert!(!t.passed(), "the broken range passed");
    let m = t.first_mismatch.expect("a mismatch");
    assert_eq!(m.stream, "report", "{m:?}");
}

/// The hierarchy unit behind one shared store port: the store model
/// attributes each read to its merge by the `slot`, though determine
/// commands come between the merge commands on `cmd`; every beat against
/// golden and each merge's reads as many as golden's units make.
#[test]
fn hierarchy_unit_behind_a_shared_store_port_matches_golden() {
    use cosim::units::hierarchy_unit::{random_case, HierarchySim};
    use cosim::units::multi_stream::{ModuleEngine, RunConfig};
    use golden::translate::model::TranslateModel;
    use rtl_gen::merge::HierarchyUnitConfig;
    let mut merger = configs().remove(0).1;
    merger.sizes.store_port = golden::merge::merger::store_port::StorePort::SHARED;
    let c = HierarchyUnitConfig::new(merger);
    let mut model = TranslateModel::new(c.table).unwrap();
    let mut rng = SplitMix64(seeded(8018));
    let cases: Vec<_> = (0..12)
        .map(|_| {
            random_case(
                &mut rng,
                &c,
                &mut model,
                golden::vectors::streams::Merges::Random,
            )
            .unwrap()
        })
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let sim = HierarchySim::new(&c, ModuleEngine::Verilator, dir.path(), None).unwrap();
    let bench = RunConfig {
        seed: seeded(8019),
        stall: cosim::tb::Stalls::Coin(0.3),
        ..RunConfig::default()
    };
    let o = sim.run(&cases, &bench, None, None).unwrap();
    let t = &o.totals;
    assert!(
        t.passed(),
        "{} mismatches, first {:?}, hang {:?}, {:?}",
        t.mismatches,
        t.first_mismatch,
        t.hang,
        t.status_failure()
    );
    let store = o.store.expect("a shared port's store outcome");
    assert_eq!(store.failure, None);
    assert!(store.stats.reads > 0 && store.stats.reads == store.expected_reads);
}
