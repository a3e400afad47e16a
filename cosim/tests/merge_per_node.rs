//! Per-node merging built into the merging module (`per-node:N/D`,
//! `rtl_gen::merge::per_node_module_unit`, SPEC.md section 8.14) against the
//! golden `golden::merge::per_node::unit` transactions, bit for bit on
//! `report` and `out`, with independent random stalls on `cfg`, every input,
//! `report` and `out`, on the IR simulator, Verilator and Icarus (pipe and
//! multi-stream batch). One transaction = one merge (cfg, every pass).
//! Configurations: the default (1/2, k = 4), D = 31 (k = 5), Q = 0 (k = 2),
//! and the edge ratios 0/1 and 1/1; random octree merges
//! (`random_per_node_case`) and golden-built soups. Also: throughput with no
//! back-pressure, only per-node configurations hold the per-node modules,
//! lint and synthesis.
mod merge_common;

use cosim::tb::StreamBeats;
use cosim::volume::volume;
use golden::build::{build, GridMap};
use golden::merge::merge_level::unit::BeatLayout;
use golden::merge::merge_module::MergeDesign;
use golden::merge::merge_module::TopLayout;
use golden::merge::per_node::unit::{
    random_per_node_case, PerNodeCase, PerNodeLayout, PerNodeReport, PerNodeTransaction,
};
use golden::merge::MergeMode;
use golden::params::Params;
use golden::scenes::random_soup;
use golden::seed::seeded;
use golden::store::Hierarchy;
use golden::translate::stimulus::SplitMix64;
use golden::translate::Translation;
use merge_common::*;

fn per_node(params: Params, inputs: usize, num: u32, den: u32) -> MergeDesign {
    MergeDesign {
        params,
        inputs,
        mode: MergeMode::PerNode { num, den },
        ..MergeDesign::default()
    }
}

/// Configurations, each with the depth of its random trees below `lo`.
fn configs() -> Vec<(&'static str, MergeDesign, u8)> {
    vec![
        ("default", per_node(Params::default(), 4, 1, 2), 4),
        (
            "d31",
            per_node(Params::new(31, 16, 32, 8).unwrap(), 5, 1, 2),
            4,
        ),
        (
            "q0",
            per_node(Params::new(8, 0, 12, 3).unwrap(), 2, 1, 2),
            4,
        ),
        ("num0", per_node(Params::default(), 3, 0, 1), 3),
        ("num_den", per_node(Params::default(), 3, 3, 3), 3),
    ]
}

/// What the stimulus exercised, read off the golden transactions.
#[derive(Default, Debug)]
struct Seen {
    merges: usize,
    refused: usize,
    passes: u64,
    multi_pass: usize,
    decisions: usize,
    descended: usize,
    in_beats: usize,
    out_beats: usize,
}

fn ratio(d: &MergeDesign) -> (u32, u32) {
    match d.mode {
        MergeMode::PerNode { num, den } => (num, den),
        other => panic!("not per-node: {other}"),
    }
}

/// The streams of `txs` through the unit: `cfg`, `in*`; `report`, `out`.
fn streams_of(
    d: &MergeDesign,
    txs: &[PerNodeTransaction],
    seen: &mut Seen,
) -> (Vec<StreamBeats>, Vec<StreamBeats>) {
    let p = &d.params;
    let (tl, pl, ol) = (
        TopLayout::new(p),
        PerNodeLayout::new(p),
        BeatLayout::output(p),
    );
    let beats = |name: String, v: Vec<golden::bits::Bits>| StreamBeats {
        name,
        beats: v.iter().map(|b| vec![b.clone()]).collect(),
    };
    let mut cfg = Vec::new();
    let mut ins = vec![Vec::new(); d.inputs];
    let mut report = Vec::new();
    let mut out = Vec::new();
    for tx in txs {
        seen.merges += 1;
        seen.refused += (tx.passes == 0) as usize;
        seen.passes += tx.passes as u64;
        seen.multi_pass += (tx.passes > 1) as usize;
        cfg.push(tl.pack_cfg(tx.lo, tx.hi).unwrap());
        for (s, beats) in ins.iter_mut().zip(&tx.inputs) {
            seen.in_beats += beats.len();
            s.extend(beats.iter().map(|b| b.pack(&pl).unwrap()));
        }
        for r in &tx.reports {
            if let PerNodeReport::Decision { descend, .. } = r {
                seen.decisions += 1;
                seen.descended += *descend as usize;
            }
            report.push(r.pack(&pl).unwrap());
        }
        seen.out_beats += tx.out.len();
        out.extend(tx.out.iter().map(|b| b.pack(&ol).unwrap()));
    }
    let mut i = vec![beats("cfg".into(), cfg)];
    for (r, s) in ins.into_iter().enumerate() {
        i.push(beats(format!("in{r}"), s));
    }
    let o = vec![beats("report".into(), report), beats("out".into(), out)];
    (i, o)
}

/// `merges` random merges for `d` (seeded), as streams.
fn random_streams(
    d: &MergeDesign,
    seed: u64,
    merges: usize,
    depth: u8,
) -> (Vec<StreamBeats>, Vec<StreamBeats>, Seen) {
    let (num, den) = ratio(d);
    let mut rng = SplitMix64(seed);
    let txs: Vec<PerNodeTransaction> = (0..merges)
        .map(|_| {
            random_per_node_case(&mut rng, &d.params, d.inputs, depth)
                .transaction(&d.params, num, den)
                .expect("golden per-node merge")
        })
        .collect();
    let mut seen = Seen::default();
    let (i, o) = streams_of(d, &txs, &mut seen);
    (i, o, seen)
}

/// Merges per bench run: long runs go in chunks of fresh stimulus.
const CHUNK: usize = 5_000;

fn check(name: &str, d: &MergeDesign, depth: u8, runs: &[(&str, usize)], seed: u64) {
    let seed = seeded(seed);
    d.validate().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let m = rtl_gen::merge::merge_module_unit(d);
    let design = design_of(&m, dir.path());
    let (num, den) = ratio(d);
    for &(kind, total) in runs {
        let stall = stall_of(seed ^ kind.len() as u64).max(0.05);
        let what = format!("merge_per_node {name} {kind}");
        let t0 = std::time::Instant::now();
        let mut e = (kind != "iverilog-batch").then(|| engine(kind, &m, &design));
        let (mut done, mut cycles, mut out_beats, mut in_beats, mut chunk) = (0, 0, 0, 0, 0u64);
        while done < total {
            let merges = CHUNK.min(total - done);
            let (ins, outs, seen) = random_streams(d, seed + chunk, merges, depth);
            eprintln!("{what}: {seen:?}");
            assert_eq!(seen.merges, merges);
            if merges >= 200 {
                assert!(seen.refused > 0 && seen.refused * 10 < merges, "{seen:?}");
                if num == den {
                    assert_eq!(seen.descended, 0, "{seen:?}");
                } else {
                    assert!(
                        seen.multi_pass * 10 > merges && seen.descended * 10 > seen.decisions,
                        "{seen:?}"
                    );
                }
                if num != 0 {
                    assert!(seen.descended < seen.decisions, "{seen:?}");
                }
            }
            let (r, before) = match e.as_mut() {
                Some(e) => {
                    let before = e.cycle();
                    (
                        multi_bench_done_per_merge(
                            e.as_mut(),
                            &ins,
                            &outs,
                            seed + chunk,
                            stall,
                            &what,
                        ),
                        before,
                    )
                }
                None => (
                    multi_batch_bench(&design, &ins, &outs, seed + chunk, stall, &what),
                    0,
                ),
            };
            done += merges;
            cycles += r.cycles - before;
            out_beats += r.received[1].1;
            in_beats += seen.in_beats;
            chunk += 1;
        }
        println!(
            "merge_per_node {name} {kind}: {total} merges, {in_beats} input beats, {out_beats} out beats, {cycles} cycles, stall {stall:.2}, {:.1} s wall",
            t0.elapsed().as_secs_f64()
        );
    }
}

/// Merges per engine: the IR simulator, Verilator, Icarus over pipes (a
/// few) and Icarus in batch mode.
fn runs(ir: usize, verilator: usize, batch: usize) -> Vec<(&'static str, usize)> {
    vec![
        ("ir", ir),
        ("verilator", volume(verilator)),
        ("iverilog", ir / 10),
        ("iverilog-batch", batch),
    ]
}

fn check_config(i: usize, ir: usize, verilator: usize, batch: usize) {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    let (name, d, depth) = &configs()[i];
    check(
        name,
        d,
        *depth,
        &runs(ir, verilator, batch),
        0x9e0 + i as u64,
    );
}

#[test]
fn per_node_default_matches_golden() {
    check_config(0, 100, 10_000, 200);
}

#[test]
fn per_node_d31_matches_golden() {
    check_config(1, 40, 2_000, 40);
}

#[test]
fn per_node_q0_matches_golden() {
    check_config(2, 100, 5_000, 100);
}

#[test]
fn per_node_edge_ratios_match_golden() {
    check_config(3, 100, 3_000, 100);
    check_config(4, 100, 3_000, 100);
}

/// A golden-built soup hierarchy `id` filling `2^-shrink` of the scene.
fn soup(p: &Params, id: u8, n: usize, size: f32, seed: u64, shrink: u32) -> Hierarchy {
    let mesh = random_soup(n, size, seed);
    let (lo, hi) = mesh.bounds();
    // The origin at the scene's corner (a zero vector of GridMap's type).
    let grid = GridMap {
        origin: GridMap::fit(lo, hi, p).origin * 0.0,
        unit: 1.0 / (p.scene_edge() >> shrink) as f64,
    };
    build(&mesh, &grid, p, id).expect("the soup builds")
}

/// Real merges: golden-built soups, overlapping (all at the origin) and
/// partly apart (moved by one top voxel), 2-4 inputs, ratios 1/2, 0/1, 1/1
/// and 1/4, on every engine;
/// the transaction's descents equal golden `merge`'s (golden tests that
/// the passes' base is golden per-node's).
#[test]
fn per_node_real_merges_match_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    let p = Params::new(10, 3, 16, 3).unwrap();
    let mut rng = SplitMix64(seeded(77));
    let mut cases = Vec::new();
    for c in 0..12u64 {
        let k = 2 + (c % 3) as usize;
        let hs: Vec<Hierarchy> = (0..k)
            .map(|i| {
                let n = 5 + rng.below(80) as usize;
                let size = 0.05 + rng.below(30) as f32 / 100.0;
                soup(&p, i as u8 + 1, n, size, c * 16 + i as u64, 2)
            })
            .collect();
        let translations: Vec<Translation> = hs
            .iter()
            .enumerate()
            .map(|(i, h)| Translation {
                lod: h.top_lod,
                t: [if c % 4 == 3 { (i % 2) as i64 } else { 0 }, 0, 0],
            })
            .collect();
        let refs: Vec<&Hierarchy> = hs.iter().collect();
        let (lo, hi) = golden::merge::level_choice::candidate_range(&refs);
        cases.push(PerNodeCase {
            hierarchies: hs,
            translations,
            lo,
            hi,
        });
    }
    // One design per (k, ratio): every k at 1/2, the other ratios at k = 3.
    let designs = [
        (2, 1, 2),
        (3, 1, 2),
        (4, 1, 2),
        (3, 0, 1),
        (3, 1, 1),
        (3, 1, 4),
    ];
    for (k, num, den) in designs {
        let d = per_node(p, k, num, den);
        let txs: Vec<PerNodeTransaction> = cases
            .iter()
            .filter(|c| c.hierarchies.len() == k)
            .map(|c| c.transaction(&p, num, den).expect("golden per-node"))
            .collect();
        let mut seen = Seen::default();
        let (ins, outs) = streams_of(&d, &txs, &mut seen);
        eprintln!("real k = {k} {num}/{den}: {seen:?}");
        let m = rtl_gen::merge::merge_module_unit(&d);
        let dir = tempfile::tempdir().unwrap();
        let design = design_of(&m, dir.path());
        for kind in ["ir", "verilator", "iverilog"] {
            let mut e = engine(kind, &m, &design);
            multi_bench_done_per_merge(
                e.as_mut(),
                &ins,
                &outs,
                3,
                0.3,
                &format!("real k = {k} {num}/{den} {kind}"),
            );
        }
    }
}

/// Input beats (all streams) per cycle with no back-pressure on merges of
/// large trees, from Verilator's simulated cycles.
#[test]
fn per_node_streams_one_beat_per_clock() {
    if !tools_present(&["verilator"]) {
        return;
    }
    for (name, d, _) in configs() {
        let dir = tempfile::tempdir().unwrap();
        let m = rtl_gen::merge::merge_module_unit(&d);
        let design = design_of(&m, dir.path());
        let (ins, outs, seen) = random_streams(&d, 0x71, 60, 6);
        let mut e = engine("verilator", &m, &design);
        let r = multi_bench_done_per_merge(
            e.as_mut(),
            &ins,
            &outs,
            1,
            0.0,
            &format!("{name} throughput"),
        );
        let beats: u64 = r.sent.iter().filter(|s| s.0 != "cfg").map(|s| s.1).sum();
        let rate = beats as f64 / r.cycles as f64;
        println!(
            "merge_per_node {name} throughput: {} merges, {} passes, {beats} input beats ({} streams) in {} cycles: {rate:.4} beats/cycle merged",
            seen.merges, seen.passes, d.inputs, r.cycles
        );
        assert!(rate >= 0.95, "{name}: {rate:.4} merged beats per cycle");
    }
}

/// Per-node logic only where asked: the per-node modules are instantiated
/// by per-node configurations and by no other mode's merging module.
#[test]
fn per_node_logic_only_in_per_node_configurations() {
    let p = Params::default();
    for mode in [
        MergeMode::Overlap { num: 1, den: 2 },
        MergeMode::Fixed(3),
        MergeMode::BelowTop(1),
        MergeMode::Proportion { num: 1, den: 2 },
        MergeMode::PerNode { num: 1, den: 2 },
    ] {
        let d = MergeDesign {
            mode,
            ..MergeDesign::default()
        };
        let dir = tempfile::tempdir().unwrap();
        let files = rtl_gen::merge::emit_merge(&d, dir.path()).unwrap();
        let names: Vec<String> = files
            .iter()
            .map(|f| f.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        let text: String = files
            .iter()
            .map(|f| std::fs::read_to_string(f).unwrap())
            .collect();
        let is_pn = matches!(mode, MergeMode::PerNode { .. });
        let network = rtl_gen::merge::per_node_network_name(&p, d.inputs);
        let decider = rtl_gen::merge::per_node_decider_name(&p, d.inputs, 1, 2);
        for module in [&network, &decider] {
            assert_eq!(
                names.contains(&format!("{module}.v")),
                is_pn,
                "{mode}: {names:?}"
            );
            assert_eq!(text.contains(module.as_str()), is_pn, "{mode}");
        }
        assert_eq!(text.contains("per_node"), is_pn, "{mode}");
        // The per-node module has no overlap counter, no level choice.
        if is_pn {
            assert!(!text.contains("overlap_counter"), "{names:?}");
        }
    }
}

#[test]
fn per_node_verilog_lints_and_synthesizes() {
    if !tools_present(&["verilator", "yosys"]) {
        return;
    }
    for (_, d, _) in configs() {
        let dir = tempfile::tempdir().unwrap();
        let m = rtl_gen::merge::merge_module_unit(&d);
        lint_and_synth(&design_of(&m, dir.path()));
    }
}
