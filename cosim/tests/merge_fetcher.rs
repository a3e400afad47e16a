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
mod merge_common;

use cosim::tb::StreamBeats;
use cosim::volume::volume;
use cosim::Bits;
use golden::build::{build, GridMap};
use golden::merge::fetcher::{
    fetch_err, fetch_transaction, fetch_transaction_with_reports, FetchCmd, FetchLayout, FetchOut,
    FetchSizes, FetchTransaction,
};
use golden::merge::per_node::unit::{random_per_node_case, PerNodeReport};
use golden::params::Params;
use golden::scenes::random_soup;
use golden::seed::seeded;
use golden::store::{Hierarchy, Reference};
use golden::translate::stimulus::SplitMix64;
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

/// A soup hierarchy `id` of `n` triangles in the scene's `2^-3` corner.
fn soup(p: &Params, id: u8, n: usize, size: f32, seed: u64) -> Option<Hierarchy> {
    let mesh = random_soup(n, size, seed);
    let (lo, hi) = mesh.bounds();
    let grid = GridMap {
        origin: GridMap::fit(lo, hi, p).origin * 0.0,
        unit: 1.0 / (p.scene_edge() >> 3) as f64,
    };
    let h = build(&mesh, &grid, p, id).ok()?;
    let cap = p.index_capacity() as usize;
    (h.nodes.len() < cap && h.refs.len() < cap).then_some(h)
}

/// A random translation of `h`: mostly at or above its top, inside the
/// scene; sometimes past the edge or below the top (errors).
fn random_translation(rng: &mut SplitMix64, h: &Hierarchy) -> Translation {
    let top = h.top_lod;
    let p = &h.params;
    let lod = if rng.below(20) == 0 && top < p.max_lod {
        top + 1
    } else {
        rng.below(top as u64 + 1) as u8
    };
    let t = [0, 1, 2].map(|a| {
        let shift = top - lod;
        let (mut lo, mut hi) = (i64::MAX, i64::MIN);
        for n in h.roots() {
            let c = [n.voxel.x, n.voxel.y, n.voxel.z][a] as i64 >> shift;
            lo = lo.min(c);
            hi = hi.max(c);
        }
        let room_hi = (1i64 << lod) - 1 - hi;
        if rng.below(25) == 0 {
            room_hi + 1
        } else if room_hi + lo <= 0 {
            0
        } else {
            rng.range_i64(-lo, room_hi)
        }
    });
    Translation { lod, t }
}

/// `h` with one random defect (or none), and the sizes' limits in play.
fn corrupt(rng: &mut SplitMix64, h: &Hierarchy) -> Hierarchy {
    let mut h = h.clone();
    let p = h.params;
    let n = h.nodes.len();
    let pick = rng.below(n as u64) as usize;
    match rng.below(16) {
        0 => h.nodes[pick].voxel.lod = (h.nodes[pick].voxel.lod + 1).min(p.max_lod),
        1 => {
            let lod = h.nodes[pick].voxel.lod;
            if lod < p.max_lod {
                h.nodes[pick].voxel.x = 1 << lod;
            }
        }
        2 if p.quant_bits > 0 => {
            h.nodes[pick].lo[1] = 1;
            h.nodes[pick].hi[1] = 0;
        }
        3 => h.nodes[pick].count = 0,
        4 if !h.nodes[pick].leaf => h.nodes[pick].count = h.refs.len() as u32,
        5 if !h.refs.is_empty() => {
            let j = rng.below(h.refs.len() as u64) as usize;
            h.refs[j].hier = ((h.id as u64 + 1) % p.hier_capacity()) as u8;
        }
        6 if !h.refs.is_empty() => {
            let j = rng.below(h.refs.len() as u64) as usize;
            h.refs[j].node = n as u32 + rng.below(3) as u32;
        }
        7 if h.refs.len() >= 2 => {
            let j = rng.below(h.refs.len() as u64 - 1) as usize;
            h.refs.swap(j, j + 1);
        }
        8 => h.root_count = if rng.below(2) == 0 { 0 } else { n as u32 + 1 },
        // Every node a root: LOD errors, or more roots than the sorter holds.
        9 => h.root_count = n as u32,
        _ => {}
    }
    h
}

/// What the stimulus reached.
#[derive(Default, Debug)]
struct Seen {
    inputs: usize,
    cmds: usize,
    codes: [usize; 15],
    /// Commands sending several levels, and those with an error.
    multi: usize,
    multi_errors: usize,
    out_beats: usize,
    leaf_beats: usize,
    node_reads: usize,
    ref_reads: usize,
    probe_reads: usize,
}

/// Random fetches: soups of 1 to `most` triangles, random translations,
/// corrupted half the time, each with 1 to 4 commands at random levels.
fn random_fetches(
    p: &Params,
    sizes: FetchSizes,
    seed: u64,
    cmds: usize,
    most: usize,
) -> Vec<FetchTransaction> {
    let mut rng = SplitMix64(seed);
    let mut out = Vec::new();
    let mut pool: Vec<Hierarchy> = Vec::new();
    let mut sent = 0;
    while sent < cmds {
        if pool.len() < 24 || rng.below(8) == 0 {
            let n = 1 + rng.below(most as u64) as usize;
            let size = [0.01, 0.05, 0.2][rng.below(3) as usize];
            let id = rng.below(p.hier_capacity()) as u8;
            if let Some(h) = soup(p, id, n, size, rng.next_u64()) {
                if pool.len() >= 24 {
                    let at = rng.below(pool.len() as u64) as usize;
                    pool[at] = h;
                } else {
                    pool.push(h);
                }
            }
            continue;
        }
        let h = &pool[rng.below(pool.len() as u64) as usize];
        let t = random_translation(&mut rng, h);
        let h = if rng.below(2) == 0 {
            corrupt(&mut rng, h)
        } else {
            h.clone()
        };
        let entry = if rng.below(40) == 0 {
            0
        } else {
            pack_entry(Some(&t), p)
        };
        let deepest = h.nodes.iter().map(|n| n.voxel.lod).max().unwrap_or(0);
        let k = 1 + rng.below(4) as usize;
        let list: Vec<FetchCmd> = (0..k)
            .map(|i| {
                let lod = (h.top_lod as u64 + rng.below((deepest - h.top_lod) as u64 + 3))
                    .saturating_sub(1)
                    .min(p.max_lod as u64) as u8;
                // A third of the commands send several levels from one walk
                // (from above the top at times), a few have `from` past `lod`.
                let from = match rng.below(12) {
                    0..=3 => rng.below(lod as u64 + 1) as u8,
                    4 => (lod as u64 + 1 + rng.below(3)).min((1 << p.lod_bits()) - 1) as u8,
                    _ => lod,
                };
                FetchCmd {
                    from,
                    ..FetchCmd::level(lod, rng.below(2) == 0, rng.below(3) != 0, i + 1 == k)
                }
            })
            .collect();
        sent += k;
        out.push(fetch_transaction(&h, entry, &list, sizes).expect("representable"));
    }
    out
}

fn bits(b: Bits) -> Vec<Bits> {
    vec![b]
}

/// Index `v` as an `I`-bit beat.
fn index_beat(v: u32, width: u32) -> Vec<Bits> {
    let mut b = golden::bits::Bits::zero(width);
    b.set(
        &golden::layout::Field {
            name: "index",
            offset: 0,
            width,
        },
        v as u64,
    )
    .unwrap();
    bits(b)
}

/// The streams of a list of fetches.
fn streams(p: &Params, txs: &[FetchTransaction]) -> (Vec<StreamBeats>, Vec<StreamBeats>, Seen) {
    streams_of(&FetchLayout::new(p), txs)
}

/// The streams of a list of fetches for a fetcher of layout `l` (with the
/// per-node command's `probe_resp`, `report` and `probe_req` when it has
/// them).
fn streams_of(
    l: &FetchLayout,
    txs: &[FetchTransaction],
) -> (Vec<StreamBeats>, Vec<StreamBeats>, Seen) {
    let mut s: [Vec<Vec<Bits>>; 10] = Default::default();
    let mut probe_resp = Vec::new();
    let mut report = Vec::new();
    let mut probe_req = Vec::new();
    let mut seen = Seen::default();
    for tx in txs {
        seen.inputs += 1;
        seen.cmds += tx.cmds.len();
        seen.multi += tx.cmds.iter().filter(|c| c.levels() > 1).count();
        if tx.cmds.iter().any(|c| c.levels() > 1)
            && tx.out.iter().any(|o| matches!(o, FetchOut::Error { .. }))
        {
            seen.multi_errors += 1;
        }
        s[0].push(bits(tx.cfg.pack(l).unwrap()));
        s[1].extend(tx.cmds.iter().map(|c| bits(c.pack(l).unwrap())));
        s[2].extend(tx.node_resps.iter().map(|r| bits(r.pack(&l.node).unwrap())));
        s[3].extend(
            tx.ref_resps
                .iter()
                .map(|r: &Reference| bits(r.pack(&l.reference).unwrap())),
        );
        s[4].extend(
            tx.cref_resps
                .iter()
                .map(|r: &Reference| bits(r.pack(&l.reference).unwrap())),
        );
        s[5].extend(tx.node_reqs.iter().map(|&i| index_beat(i, l.index_width)));
        s[6].extend(tx.ref_reqs.iter().map(|&i| index_beat(i, l.index_width)));
        s[7].extend(tx.cref_reqs.iter().map(|&i| index_beat(i, l.index_width)));
        s[8].extend(tx.out.iter().map(|o| bits(o.pack(l).unwrap())));
        s[9].extend(tx.leaves.iter().map(|o| bits(o.pack(l).unwrap())));
        if let Some(f) = &l.pn {
            probe_resp.extend(
                tx.probe_resps
                    .iter()
                    .map(|r| bits(r.pack(&l.node).unwrap())),
            );
            report.extend(tx.reports.iter().map(|r| bits(f.pack_report(r).unwrap())));
            probe_req.extend(tx.probe_reqs.iter().map(|&i| index_beat(i, l.index_width)));
        }
        seen.probe_reads += tx.probe_reqs.len();
        for o in &tx.out {
            if let FetchOut::Error { code, .. } = o {
                seen.codes[*code as usize] += 1;
            }
        }
        seen.out_beats += tx.out.len();
        seen.leaf_beats += tx.leaves.len();
        seen.node_reads += tx.node_reqs.len();
        seen.ref_reads += tx.ref_reqs.len() + tx.cref_reqs.len();
    }
    let names = [
        "cfg",
        "cmd",
        "node_resp",
        "ref_resp",
        "cref_resp",
        "node_req",
        "ref_req",
        "cref_req",
        "out",
        "leaves",
    ];
    let mut all: Vec<StreamBeats> = names
        .iter()
        .zip(s)
        .map(|(n, beats)| StreamBeats {
            name: n.to_string(),
            beats,
        })
        .collect();
    let mut outs = all.split_off(5);
    if l.pn.is_some() {
        for (name, beats) in [("probe_resp", probe_resp), ("report", report)] {
            all.push(StreamBeats {
                name: name.into(),
                beats,
            });
        }
        outs.push(StreamBeats {
            name: "probe_req".into(),
            beats: probe_req,
        });
    }
    (all, outs, seen)
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
    let m = rtl_gen::merge::fetcher_unit(&p, &sizes);
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
            let txs = random_fetches(&p, sizes, seed, n, most);
            let (ins, outs, seen) = streams(&p, &txs);
            let what = format!("merge_fetcher {name} {kind} chunk {chunk}");
            let r = match e.as_mut() {
                Some(e) => multi_bench(e.as_mut(), &ins, &outs, seed, stall, &what),
                None => multi_batch_bench(&design, &ins, &outs, seed, stall, &what),
            };
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
        let m = rtl_gen::merge::fetcher_unit(&p, &sizes);
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
            let (ins, outs, seen) = streams(&p, &txs);
            let mut e = engine("verilator", &m, &design);
            let r = multi_bench(
                e.as_mut(),
                &ins,
                &outs,
                1,
                0.0,
                &format!("fetcher {name} rate ({what})"),
            );
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
        let m = rtl_gen::merge::fetcher_unit(&p, &sizes);
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
        let (ins, outs, seen) = streams(&p, &[tx]);
        let mut e = engine("verilator", &m, &design);
        let r = multi_bench(
            e.as_mut(),
            &ins,
            &outs,
            1,
            0.0,
            &format!("fetcher {name} steady state"),
        );
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
        let m = rtl_gen::merge::fetcher_unit(&p, &sizes);
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
    let (ins, outs, _) = streams(&p, std::slice::from_ref(&tx));
    let dir = tempfile::tempdir().unwrap();
    let m = rtl_gen::merge::fetcher_unit(&p, &sizes);
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

/// What the per-node stimulus reached.
#[derive(Default, Debug)]
struct PnSeen {
    fetches: usize,
    passes: usize,
    multi_pass: usize,
    descents: usize,
    probes: usize,
    level_cmds: usize,
    errors: usize,
    corrupted: usize,
}

/// Random per-node fetches: the inputs of random per-node merges
/// (`random_per_node_case`, 2-`k` inputs, trees 4 LODs deep, ratio 1/2 or
/// 0/1), each input's fetcher given the module's `report` stream with one
/// decision in 8 flipped (so descents are random, at the contested voxels),
/// one input in 4 corrupted (errors: then only the passes' `End`s follow
/// it), half the inputs first given a level command.
fn random_per_node_fetches(
    p: &Params,
    sizes: FetchSizes,
    seed: u64,
    merges: usize,
) -> (Vec<FetchTransaction>, PnSeen) {
    let mut rng = SplitMix64(seed);
    let mut out = Vec::new();
    let mut seen = PnSeen::default();
    let k = 2 + (seed % 3) as usize;
    while seen.fetches < merges {
        let c = random_per_node_case(&mut rng, p, k, 4);
        let (num, den) = if rng.below(2) == 0 { (1, 2) } else { (0, 1) };
        let Ok(tx) = c.transaction(p, num, den) else {
            continue;
        };
        if tx.passes == 0 {
            continue;
        }
        seen.fetches += 1;
        for (h, t) in c.hierarchies.iter().zip(&c.translations) {
            // One descent in 4 refused; a pass left with none ends the
            // merge (the module's `more`: some voxel descended, `l < D`).
            let mut reports = Vec::new();
            let mut descended = false;
            for r in &tx.reports {
                match *r {
                    PerNodeReport::Decision {
                        voxel,
                        shared,
                        union,
                        descend,
                    } => {
                        let descend = descend && rng.below(4) != 0;
                        descended |= descend;
                        reports.push(PerNodeReport::Decision {
                            voxel,
                            shared,
                            union,
                            descend,
                        });
                    }
                    PerNodeReport::PassEnd { lod, more } => {
                        let more = more && descended;
                        reports.push(PerNodeReport::PassEnd { lod, more });
                        if !more {
                            break;
                        }
                        descended = false;
                    }
                    other => reports.push(other),
                }
            }
            let h = if rng.below(4) == 0 {
                seen.corrupted += 1;
                corrupt(&mut rng, h)
            } else {
                h.clone()
            };
            let entry = if rng.below(40) == 0 {
                0
            } else {
                pack_entry(Some(t), p)
            };
            let mut cmds = Vec::new();
            if rng.below(2) == 0 {
                seen.level_cmds += 1;
                let lod = c.lo.saturating_sub(rng.below(2) as u8);
                cmds.push(FetchCmd::level(
                    lod,
                    rng.below(2) == 0,
                    rng.below(2) == 0,
                    false,
                ));
            }
            cmds.push(FetchCmd::per_node(c.lo, rng.below(4) != 0, true));
            let f = fetch_transaction_with_reports(&h, entry, &cmds, &reports, sizes)
                .expect("representable, every pass closed");
            let passes = f
                .reports
                .iter()
                .filter(|r| !matches!(r, PerNodeReport::Decision { .. }))
                .count();
            seen.passes += passes;
            seen.multi_pass += (passes > 1) as usize;
            seen.descents += f
                .reports
                .iter()
                .filter(|r| matches!(r, PerNodeReport::Decision { descend: true, .. }))
                .count();
            seen.probes += f.probe_reqs.len();
            seen.errors += f.out.iter().any(|o| matches!(o, FetchOut::Error { .. })) as usize;
            out.push(f);
        }
    }
    (out, seen)
}

/// Per-node fetches on each engine of `runs` (engine, merges), in chunks.
fn check_per_node(name: &str, runs: &[(&str, usize)]) {
    let all = configs();
    let i = all.iter().position(|c| c.0 == name).unwrap();
    let (_, p, sizes) = all[i];
    let dir = tempfile::tempdir().unwrap();
    let m = rtl_gen::merge::fetcher_per_node_unit(&p, &sizes);
    let design = design_of(&m, dir.path());
    let l = FetchLayout::per_node(&p);
    for &(kind, merges) in runs {
        let (mut total, mut chunk) = (0, 0u64);
        let (mut beats, mut cycles, mut wall) = (0usize, 0u64, 0.0f64);
        let mut all_seen = PnSeen::default();
        let mut e = (kind != "iverilog").then(|| engine(kind, &m, &design));
        while total < merges {
            let n = 2_000.min(merges - total);
            let seed = seeded(0x9e7c + 0x100 * i as u64 + chunk);
            let stall = stall_of(seed ^ kind.len() as u64).max(0.05);
            let (txs, seen) = random_per_node_fetches(&p, sizes, seed, n);
            let (ins, outs, s) = streams_of(&l, &txs);
            let what = format!("merge_fetcher per-node {name} {kind} chunk {chunk}");
            let r = match e.as_mut() {
                Some(e) => multi_bench(e.as_mut(), &ins, &outs, seed, stall, &what),
                None => multi_batch_bench(&design, &ins, &outs, seed, stall, &what),
            };
            total += seen.fetches;
            beats += s.out_beats + s.leaf_beats + s.node_reads + s.ref_reads + s.probe_reads;
            cycles += r.cycles;
            wall += r.wall.as_secs_f64();
            chunk += 1;
            all_seen.fetches += seen.fetches;
            all_seen.passes += seen.passes;
            all_seen.multi_pass += seen.multi_pass;
            all_seen.descents += seen.descents;
            all_seen.probes += seen.probes;
            all_seen.level_cmds += seen.level_cmds;
            all_seen.errors += seen.errors;
            all_seen.corrupted += seen.corrupted;
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
        let m = rtl_gen::merge::fetcher_per_node_unit(&p, &sizes);
        let warnings = m.validate_design().expect("valid");
        assert!(warnings.is_empty(), "{name}: {warnings:?}");
        let design = design_of(&m, dir.path());
        if name == "small" {
            lint_and_synth(&design);
        } else {
            lint_only(&design);
        }
        let plain = rtl_gen::merge::fetcher_unit(&p, &sizes);
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
        let mut reports = Vec::new();
        for l in h.top_lod..=deepest {
            let w = golden::merge::fetcher::walk::walk_input(&h, 0, &t, l).unwrap();
            let (_, mut at) = golden::merge::fetcher::walk::collect(std::slice::from_ref(&w), l);
            golden::merge::merge_level::sort_stream(&mut at);
            for n in at.iter().filter(|n| !n.record.leaf) {
                reports.push(PerNodeReport::Decision {
                    voxel: n.record.voxel,
                    shared: 1,
                    union: 1,
                    descend: true,
                });
            }
            reports.push(PerNodeReport::PassEnd {
                lod: l,
                more: l < deepest,
            });
        }
        let cmd = FetchCmd::per_node(h.top_lod, true, true);
        let entry = pack_entry(Some(&t), &p);
        let tx = fetch_transaction_with_reports(&h, entry, &[cmd], &reports, sizes).unwrap();
        if !tx.out.iter().all(|o| !matches!(o, FetchOut::Error { .. })) {
            println!("fetcher per-node {name} steady state: an error (capacity), not measured");
            continue;
        }
        let l = FetchLayout::per_node(&p);
        let (ins, outs, seen) = streams_of(&l, std::slice::from_ref(&tx));
        let dir = tempfile::tempdir().unwrap();
        let m = rtl_gen::merge::fetcher_per_node_unit(&p, &sizes);
        let design = design_of(&m, dir.path());
        let mut e = engine("verilator", &m, &design);
        let r = multi_bench(
            e.as_mut(),
            &ins,
            &outs,
            1,
            0.0,
            &format!("fetcher per-node {name} steady state"),
        );
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
