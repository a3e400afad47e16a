//! The fetcher (`rtl_gen::merge::fetcher_unit`, SPEC.md section 8.13)
//! against `golden::merge::fetcher::fetch_transaction`, bit for bit on
//! `out`, `leaves`, `node_req`, `ref_req` and `cref_req`; the store's answers
//! (`node_resp`, `ref_resp`, `cref_resp`) are precomputed from golden and presented as
//! ordinary input streams (the unit raises `*_resp_ready` only with a read
//! outstanding), with independent random stalls on every stream
//! (`cosim::tb::run_multi_stream_bench`), on the IR simulator, Verilator and
//! Icarus (`IcarusMultiBatch`). Stimulus: builder-made soups (`golden::build`
//! of `golden::scenes::random_soup`), translated, walked to every level with
//! random flags, and the same inputs corrupted so that every error code
//! occurs. Throughput with no back-pressure printed; lint and synthesis.
//! The bench (streams, stimulus, run) is `cosim::units::fetcher`; this file
//! holds the configurations, seeds and what each run must reach.
mod merge_common;

use cosim::tb::MultiReport;
use cosim::units::fetcher::stimulus::{
    descend_everywhere, random_fetches, random_per_node_fetches, soup, PerNodeSeen,
};
use cosim::units::fetcher::{self, FetchStreams};
use cosim::units::multi_stream::MultiSim;
use cosim::volume::volume;
use cosim::Bits;
use golden::merge::fetcher::{
    fetch_err, fetch_transaction, fetch_transaction_with_reports, FetchCmd, FetchLayout, FetchOut,
    FetchSizes, FetchTransaction,
};
use golden::params::Params;
use golden::seed::seeded;
use golden::translate::table::pack_entry;
use golden::translate::Translation;
use merge_common::*;

/// Name, parameters and sizes (root sorter, frontier FIFO) per configuration.
fn configs() -> Vec<(&'static str, Params, FetchSizes)> {
    vec![
        ("default", Params::default(), FetchSizes::default()),
        (
            "d31",
            Params::new(31, 16, 32, 8).unwrap(),
            FetchSizes {
                roots: 16,
                frontier: 64,
            },
        ),
        (
            "q0",
            Params::new(8, 0, 12, 3).unwrap(),
            FetchSizes {
                roots: 16,
                frontier: 32,
            },
        ),
        // Small sizes: the root capacity and the frontier overflow.
        (
            "small",
            Params::new(6, 2, 8, 2).unwrap(),
            FetchSizes {
                roots: 3,
                frontier: 4,
            },
        ),
    ]
}

/// The streams of `txs` for the level modes' fetcher.
fn streams(p: &Params, txs: &[FetchTransaction]) -> FetchStreams {
    fetcher::streams(&FetchLayout::new(p), txs).expect("the beats pack")
}

/// One run of `s` on `sim`, every stream stalling with probability
/// `stall`; printed, a panic naming the run when it fails.
fn bench(sim: MultiSim, s: &FetchStreams, seed: u64, stall: f64, what: &str) -> MultiReport {
    let r = fetcher::run(sim, s, &stalled(seed, stall)).expect("the bench runs");
    check_passed(&r, stall, what);
    r
}

/// Commands per bench run: longer runs go in chunks of fresh stimulus.
///
/// Verilator runs: 100,000 commands at the small configuration; 40,000
/// (default), 30,000 (D = 31), 60,000 (Q = 0): with the read pipeline the
/// benches take 21 s, 9 s, 11 s and 8 s of wall (5.3, 2.7, 8.9 and 12.3
/// million cycles), the stimulus about as long again.
const CHUNK: usize = 10_000;

/// Random fetches on each engine of `runs` (engine, commands), in chunks.
fn check(name: &str, runs: &[(&str, usize)], most: usize) {
    let all = configs();
    let i = all.iter().position(|c| c.0 == name).unwrap();
    let (_, p, sizes) = all[i];
    let dir = tempfile::tempdir().unwrap();
    let m = fetcher::fetcher_module(&p, &sizes);
    let design = design_of(&m, dir.path());
    for &(kind, cmds) in runs {
        let cmds = if kind == "verilator" {
            volume(cmds)
        } else {
            cmds
        };
        let mut codes = [0usize; 15];
        let (mut multi, mut multi_errors) = (0, 0);
        let (mut total, mut chunk) = (0, 0u64);
        let (mut beats, mut cycles, mut wall) = (0usize, 0u64, 0.0f64);
        let mut e = (kind != "iverilog").then(|| engine(kind, &m, &design));
        while total < cmds {
            let n = CHUNK.min(cmds - total);
            let seed = seeded(0xfe7c + 0x100 * i as u64 + chunk);
            let stall = stall_of(seed ^ kind.len() as u64).max(0.05);
            let txs = random_fetches(&p, sizes, seed, n, most).expect("representable");
            let s = streams(&p, &txs);
            let what = format!("merge_fetcher {name} {kind} chunk {chunk}");
            let sim = sim_of(&mut e, &design);
            let r = bench(sim, &s, seed, stall, &what);
            let seen = s.seen;
            for (c, k) in codes.iter_mut().zip(seen.codes) {
                *c += k;
            }
            total += seen.cmds;
            multi += seen.multi;
            multi_errors += seen.multi_errors;
            beats += seen.out_beats + seen.leaf_beats + seen.node_reads + seen.ref_reads;
            cycles += r.cycles;
            wall += r.wall.as_secs_f64();
            chunk += 1;
        }
        println!(
            "fetcher {name} {kind}: {total} commands ({multi} sending several levels, {multi_errors} inputs with such a command and an error), {beats} beats (out, leaves, requests), {cycles} cycles, {wall:.1} s wall; error codes {codes:?}"
        );
        assert!(multi > 0 && multi_errors > 0, "{name} {kind}");
        // The sizes' limits only in the small configuration.
        let needed: Vec<u64> = (fetch_err::ENTRY..=fetch_err::ORDER)
            .filter(|&c| {
                name == "small" || !matches!(c, fetch_err::ROOT_CAPACITY | fetch_err::FRONTIER)
            })
            .collect();
        if total >= 2_000 {
            for c in needed {
                assert!(
                    codes[c as usize] > 0,
                    "{name} {kind}: code {c} never reached: {codes:?}"
                );
            }
        }
    }
}

#[test]
fn fetcher_default_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check(
        "default",
        &[("ir", 500), ("verilator", 40_000), ("iverilog", 300)],
        12,
    );
}

#[test]
fn fetcher_d31_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check(
        "d31",
        &[("ir", 300), ("verilator", 30_000), ("iverilog", 200)],
        12,
    );
}

#[test]
fn fetcher_q0_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check(
        "q0",
        &[("ir", 500), ("verilator", 60_000), ("iverilog", 300)],
        12,
    );
}

#[test]
fn fetcher_small_sizes_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check(
        "small",
        &[("ir", 500), ("verilator", 100_000), ("iverilog", 300)],
        8,
    );
}

/// Out beats and node reads per cycle with no back-pressure and a memory
/// that answers every clock, on error-free walks of larger soups (Verilator
/// cycles): every level of each soup in turn, one command per level (each
/// re-walks from the roots), then every level from one command (one walk,
/// as the merger's count pass), then one command at each soup's deepest
/// level (the stream a merge pass reads).
#[test]
fn fetcher_throughput_without_back_pressure() {
    if !tools_present(&["verilator"]) {
        return;
    }
    for (name, p, sizes) in configs().into_iter().take(3) {
        let dir = tempfile::tempdir().unwrap();
        let m = fetcher::fetcher_module(&p, &sizes);
        let design = design_of(&m, dir.path());
        for what in ["every level", "every level, one walk", "deepest level"] {
            let mut txs = Vec::new();
            for s in 0..6u64 {
                let Some(h) = soup(&p, 1, 40 + 20 * s as usize, 0.2, 100 + s) else {
                    continue;
                };
                let t = Translation::zero(h.top_lod);
                let deepest = h.nodes.iter().map(|n| n.voxel.lod).max().unwrap();
                let cmds: Vec<FetchCmd> = match what {
                    "every level" => (h.top_lod..=deepest)
                        .map(|l| FetchCmd::level(l, true, true, l == deepest))
                        .collect(),
                    "deepest level" => vec![FetchCmd::level(deepest, true, true, true)],
                    _ => vec![FetchCmd {
                        from: h.top_lod,
                        ..FetchCmd::level(deepest, true, true, true)
                    }],
                };
                if let Ok(tx) = fetch_transaction(&h, pack_entry(Some(&t), &p), &cmds, sizes) {
                    if tx.out.iter().all(|o| matches!(o, FetchOut::Beat(_))) {
                        txs.push(tx);
                    }
                }
            }
            assert!(!txs.is_empty());
            let s = streams(&p, &txs);
            let mut e = engine("verilator", &m, &design);
            let run = format!("fetcher {name} rate ({what})");
            let r = bench(MultiSim::Stepped(e.as_mut()), &s, 1, 0.0, &run);
            let seen = s.seen;
            let c = r.cycles as f64;
            println!(
                "fetcher {name} throughput ({what}): {} commands, {} out beats in {} cycles: {:.4} out beats/cycle; {} node reads: {:.4} node reads/cycle; {} ref + cref reads; {:.3} reads/cycle in all",
                seen.cmds,
                seen.out_beats,
                r.cycles,
                seen.out_beats as f64 / c,
                seen.node_reads,
                seen.node_reads as f64 / c,
                seen.ref_reads,
                (seen.node_reads + seen.ref_reads) as f64 / c
            );
        }
    }
}

/// Steady state: one command at the deepest level of one large input
/// (1,500 triangles; 300 where I is small), where the per-command costs (roots, sorter, drain)
/// and the one-clock bubble per level are small against the level's reads.
/// The node port's stream is the unit's datapath: at least 0.95 node
/// records read per cycle (Verilator cycle counts, no back-pressure, a
/// memory that answers every clock).
#[test]
fn fetcher_steady_state_on_a_large_input() {
    if !tools_present(&["verilator"]) {
        return;
    }
    for (name, p, _) in configs().into_iter().take(3) {
        // A frontier wide enough for the large input's levels.
        let sizes = FetchSizes {
            roots: 16,
            frontier: 2048,
        };
        let dir = tempfile::tempdir().unwrap();
        let m = fetcher::fetcher_module(&p, &sizes);
        let design = design_of(&m, dir.path());
        // The largest of these soups that fits the configuration's I.
        let h = [1500, 300]
            .into_iter()
            .find_map(|n| soup(&p, 1, n, 0.05, 7))
            .expect("a 300-triangle soup fits every configuration's I");
        let deepest = h.nodes.iter().map(|n| n.voxel.lod).max().unwrap();
        let cmd = FetchCmd::level(deepest, true, true, true);
        let t = Translation::zero(h.top_lod);
        let tx = fetch_transaction(&h, pack_entry(Some(&t), &p), &[cmd], sizes)
            .expect("the walk of a builder-made input");
        if !tx.out.iter().all(|o| matches!(o, FetchOut::Beat(_))) {
            // The frontier of a level this wide is over the configuration's
            // capacity: an error walk is not a steady state.
            println!("fetcher {name} steady state: frontier over capacity, not measured");
            continue;
        }
        let s = streams(&p, &[tx]);
        let mut e = engine("verilator", &m, &design);
        let what = format!("fetcher {name} steady state");
        let r = bench(MultiSim::Stepped(e.as_mut()), &s, 1, 0.0, &what);
        let seen = s.seen;
        let rate = seen.node_reads as f64 / r.cycles as f64;
        println!(
            "fetcher {name} steady state ({} nodes, {} refs, deepest LOD {deepest}): {} node reads in {} cycles: {rate:.4} node reads/cycle; {} out beats",
            h.nodes.len(),
            h.refs.len(),
            seen.node_reads,
            r.cycles,
            seen.out_beats
        );
        assert!(
            rate >= 0.95,
            "fetcher {name}: {rate:.4} node reads per cycle"
        );
    }
}

/// Every configuration lints clean; Q = 0 and the small one also go
/// through Yosys `synth` with no latch (the same logic at every size; the
/// default and D = 31 pass too, in about 55 s and 50 s, mostly the frontier
/// FIFO's flops: too long for every run).
#[test]
fn fetcher_verilog_lints_and_synthesizes() {
    if !tools_present(&["verilator", "yosys"]) {
        return;
    }
    for (name, p, sizes) in configs() {
        let t = std::time::Instant::now();
        let dir = tempfile::tempdir().unwrap();
        let m = fetcher::fetcher_module(&p, &sizes);
        let warnings = m.validate_design().expect("valid");
        assert!(warnings.is_empty(), "{name}: {warnings:?}");
        let design = design_of(&m, dir.path());
        if p.max_lod <= 8 {
            lint_and_synth(&design);
        } else {
            lint_only(&design);
        }
        println!(
            "fetcher {name}: lint (and synthesis) in {:.1?}",
            t.elapsed()
        );
    }
}

/// The `leaves` end beat does not wait on `out` (SPEC 8.13 step 6, the
/// merger's deadlock argument in 8.15): with `out` never ready, a command
/// whose level holds more beats than the out pipeline (`visit_out_items`,
/// `order_tokens`, the skid buffer) still sends every leaf above the level and
/// its end beat, while its first level beat waits on `out`. Before session
/// 4 the end beat came after the walk and never left here. IR simulator,
/// memory answering every clock.
#[test]
fn leaves_end_does_not_wait_on_out() {
    let (_, p, sizes) = configs()[0];
    // The level with the most beats among those with leaves above it.
    let h = soup(&p, 1, 120, 0.2, 104).expect("a soup");
    let entry = pack_entry(Some(&Translation::zero(h.top_lod)), &p);
    let deepest = h.nodes.iter().map(|n| n.voxel.lod).max().unwrap();
    let tx = (h.top_lod + 1..=deepest)
        .map(|l| {
            let cmd = FetchCmd::level(l, true, true, true);
            fetch_transaction(&h, entry, &[cmd], sizes).unwrap()
        })
        .filter(|t| t.leaves.len() > 1)
        .max_by_key(|t| t.out.len())
        .expect("a level with leaves above it");
    assert!(tx.out.len() > 16, "{} beats at the level", tx.out.len());
    let FetchStreams {
        inputs: ins,
        outputs: outs,
        ..
    } = streams(&p, std::slice::from_ref(&tx));
    let dir = tempfile::tempdir().unwrap();
    let m = fetcher::fetcher_module(&p, &sizes);
    let design = design_of(&m, dir.path());
    let mut e = engine("ir", &m, &design);
    let port = |e: &dyn cosim::Engine, n: &str| e.port_id(n).unwrap();
    e.reset(2).unwrap();
    let mut next = vec![0usize; ins.len()];
    let mut leaves = Vec::new();
    let want_leaves = &outs.iter().find(|s| s.name == "leaves").unwrap().beats;
    for _ in 0..20_000 {
        for (s, at) in ins.iter().zip(&next) {
            let valid = *at < s.beats.len();
            let v = port(e.as_ref(), &format!("{}_valid", s.name));
            e.poke_u64(v, valid as u64).unwrap();
            if valid {
                let d = port(e.as_ref(), &format!("{}_data", s.name));
                e.poke(d, &s.beats[*at][0]).unwrap();
            }
        }
        for s in ["node_req", "ref_req", "cref_req", "leaves"] {
            let r = port(e.as_ref(), &format!("{s}_ready"));
            e.poke_u64(r, 1).unwrap();
        }
        let r = port(e.as_ref(), "out_ready");
        e.poke_u64(r, 0).unwrap();
        e.eval().unwrap();
        for (s, at) in ins.iter().zip(next.iter_mut()) {
            let fire = *at < s.beats.len()
                && e.peek_bool(port(e.as_ref(), &format!("{}_ready", s.name)))
                    .unwrap();
            *at += fire as usize;
        }
        if e.peek_bool(port(e.as_ref(), "leaves_valid")).unwrap() {
            leaves.push(e.peek(port(e.as_ref(), "leaves_data")).unwrap());
        }
        e.step().unwrap();
        // A while after the end beat, to see the level's beats wait.
        if leaves.len() == want_leaves.len() && e.cycle() > 500 {
            break;
        }
    }
    let want: Vec<Bits> = want_leaves.iter().map(|b| b[0].clone()).collect();
    assert_eq!(
        leaves, want,
        "every leaf and the end beat, `out` never ready"
    );
    e.eval().unwrap();
    assert!(
        e.peek_bool(port(e.as_ref(), "out_valid")).unwrap(),
        "the level's first beat waits on out"
    );
    println!(
        "fetcher leaves end with out blocked: {} leaves beats in {} cycles, {} level beats waiting",
        leaves.len(),
        e.cycle(),
        tx.out.len()
    );
}

// ---------------------------------------------------------------------------
// The per-node command (`rtl_gen::merge::fetcher_per_node_unit`)

/// Per-node fetches on each engine of `runs` (engine, merges), in chunks.
fn check_per_node(name: &str, runs: &[(&str, usize)]) {
    let all = configs();
    let i = all.iter().position(|c| c.0 == name).unwrap();
    let (_, p, sizes) = all[i];
    let dir = tempfile::tempdir().unwrap();
    let m = fetcher::fetcher_per_node_module(&p, &sizes);
    let design = design_of(&m, dir.path());
    let l = FetchLayout::per_node(&p);
    for &(kind, merges) in runs {
        let (mut total, mut chunk) = (0, 0u64);
        let (mut beats, mut cycles, mut wall) = (0usize, 0u64, 0.0f64);
        let mut all_seen = PerNodeSeen::default();
        let mut e = (kind != "iverilog").then(|| engine(kind, &m, &design));
        while total < merges {
            let n = 2_000.min(merges - total);
            let seed = seeded(0x9e7c + 0x100 * i as u64 + chunk);
            let stall = stall_of(seed ^ kind.len() as u64).max(0.05);
            let (txs, seen) =
                random_per_node_fetches(&p, sizes, seed, n).expect("representable, passes closed");
            let st = fetcher::streams(&l, &txs).expect("the beats pack");
            let what = format!("merge_fetcher per-node {name} {kind} chunk {chunk}");
            let sim = sim_of(&mut e, &design);
            let r = bench(sim, &st, seed, stall, &what);
            let s = st.seen;
            total += seen.fetches;
            beats += s.out_beats + s.leaf_beats + s.node_reads + s.ref_reads + s.probe_reads;
            cycles += r.cycles;
            wall += r.wall.as_secs_f64();
            chunk += 1;
            all_seen.add(&seen);
        }
        println!(
            "fetcher per-node {name} {kind}: {total} merges, {beats} beats (out, leaves, requests), {cycles} cycles, {wall:.1} s wall; {all_seen:?}"
        );
        assert!(
            all_seen.multi_pass > 0 && all_seen.descents > 0,
            "{name} {kind}: {all_seen:?}"
        );
        assert!(
            all_seen.errors > 0 && all_seen.level_cmds > 0,
            "{name} {kind}: {all_seen:?}"
        );
    }
}

#[test]
fn fetcher_per_node_default_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check_per_node(
        "default",
        &[("ir", 40), ("verilator", 1_000), ("iverilog", 20)],
    );
}

#[test]
fn fetcher_per_node_d31_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check_per_node("d31", &[("ir", 20), ("verilator", 300), ("iverilog", 10)]);
}

#[test]
fn fetcher_per_node_q0_matches_golden() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    check_per_node("q0", &[("ir", 40), ("verilator", 1_000), ("iverilog", 20)]);
}

/// The per-node fetcher lints clean at every configuration (Yosys at the
/// small one), and the level modes' fetcher has none of its logic.
#[test]
fn fetcher_per_node_lints_and_synthesizes() {
    if !tools_present(&["verilator", "yosys"]) {
        return;
    }
    for (name, p, sizes) in configs() {
        let dir = tempfile::tempdir().unwrap();
        let m = fetcher::fetcher_per_node_module(&p, &sizes);
        let warnings = m.validate_design().expect("valid");
        assert!(warnings.is_empty(), "{name}: {warnings:?}");
        let design = design_of(&m, dir.path());
        if name == "small" {
            lint_and_synth(&design);
        } else {
            lint_only(&design);
        }
        let plain = fetcher::fetcher_module(&p, &sizes);
        let plain = design_of(&plain, tempfile::tempdir().unwrap().path());
        for port in ["report", "probe_req", "probe_resp"] {
            assert!(
                design.ports.iter().any(|x| x.name.starts_with(port)),
                "{name} {port}"
            );
            assert!(
                !plain.ports.iter().any(|x| x.name.starts_with(port)),
                "{name} {port}"
            );
        }
    }
}

/// Per-node steady state: one per-node command on a large builder-made
/// input at its top, every inner voxel of every pass descending (a
/// `report` of one decision per inner node of the pass, always valid), no
/// back-pressure, a memory answering every clock (Verilator cycles). Every
/// node below the top is read once on `node` (as a pass's live node) and
/// once on `probe` (as its parent's probe).
#[test]
fn fetcher_per_node_steady_state() {
    if !tools_present(&["verilator"]) {
        return;
    }
    // (D = 31 walks the same soup as the default: the same cycles.)
    for (name, p, _) in configs()
        .into_iter()
        .filter(|c| c.0 != "d31" && c.0 != "small")
    {
        let sizes = FetchSizes {
            roots: 16,
            frontier: 2048,
        };
        let h = [1500, 300]
            .into_iter()
            .find_map(|n| soup(&p, 1, n, 0.05, 7))
            .expect("a 300-triangle soup fits every configuration's I");
        let t = Translation::zero(h.top_lod);
        let deepest = h.nodes.iter().map(|n| n.voxel.lod).max().unwrap();
        let reports = descend_everywhere(&h, &t).expect("the walk of a builder-made input");
        let cmd = FetchCmd::per_node(h.top_lod, true, true);
        let entry = pack_entry(Some(&t), &p);
        let tx = fetch_transaction_with_reports(&h, entry, &[cmd], &reports, sizes).unwrap();
        if !tx.out.iter().all(|o| !matches!(o, FetchOut::Error { .. })) {
            println!("fetcher per-node {name} steady state: an error (capacity), not measured");
            continue;
        }
        let l = FetchLayout::per_node(&p);
        let st = fetcher::streams(&l, std::slice::from_ref(&tx)).expect("the beats pack");
        let dir = tempfile::tempdir().unwrap();
        let m = fetcher::fetcher_per_node_module(&p, &sizes);
        let design = design_of(&m, dir.path());
        let mut e = engine("verilator", &m, &design);
        let what = format!("fetcher per-node {name} steady state");
        let r = bench(MultiSim::Stepped(e.as_mut()), &st, 1, 0.0, &what);
        let seen = st.seen;
        let c = r.cycles as f64;
        println!(
            "fetcher per-node {name} steady state ({} nodes, {} passes): {} node reads, {} probe reads, {} cref reads in {} cycles: {:.4} node + probe reads/cycle, {:.4} out beats/cycle ({} beats)",
            h.nodes.len(),
            deepest - h.top_lod + 1,
            seen.node_reads,
            seen.probe_reads,
            tx.cref_reqs.len(),
            r.cycles,
            (seen.node_reads + seen.probe_reads) as f64 / c,
            seen.out_beats as f64 / c,
            seen.out_beats
        );
    }
}
