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
//! back-pressure printed; lint and synthesis.
mod merge_common;

use cosim::tb::StreamBeats;
use golden::build::{build, GridMap};
use golden::merge::level_choice::candidate_range;
use golden::merge::merge_level::BaseNode;
use golden::merge::upper_builder::unit::{
    builder_transaction, fixed_level_base, random_base, BuilderLayout, BuilderTransaction, LevelOut,
};
use golden::params::Params;
use golden::scenes::random_soup;
use golden::seed::seeded;
use golden::store::Hierarchy;
use golden::translate::stimulus::SplitMix64;
use golden::translate::Translation;
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

/// What the stimulus exercised.
#[derive(Default, Debug)]
struct Seen {
    merges: usize,
    no_top: usize,
    top_above_base: usize,
    several_roots: usize,
    lifted: usize,
    root_cut: usize,
    overflow: usize,
    base_beats: usize,
    level_beats: usize,
}

/// The streams of a list of merges.
fn streams(p: &Params, txs: &[BuilderTransaction]) -> (Vec<StreamBeats>, Vec<StreamBeats>, Seen) {
    let l = BuilderLayout::new(p);
    let d = p.max_lod as usize;
    let mut bases = vec![Vec::new(); d + 1];
    let mut levels = vec![Vec::new(); d + 1];
    let mut done = Vec::new();
    let mut seen = Seen::default();
    for tx in txs {
        seen.merges += 1;
        seen.no_top += tx.done.err as usize;
        seen.lifted += (tx.lifted > 0) as usize;
        seen.root_cut += tx.root_cut as usize;
        let top = tx.done.top as usize;
        let n_top = tx.levels[top].len() - 1;
        seen.several_roots += (!tx.done.err && n_top > 1) as usize;
        let deepest_base = tx.base.iter().rposition(|b| b.len() > 1).unwrap_or(0);
        seen.top_above_base += (top + 1 < deepest_base) as usize;
        seen.overflow += tx.levels.iter().flatten().any(|b| {
            matches!(
                b,
                LevelOut::Node { err: true, .. } | LevelOut::End { err: true, .. }
            )
        }) as usize;
        for (s, beats) in bases.iter_mut().zip(&tx.base) {
            seen.base_beats += beats.len();
            s.extend(beats.iter().map(|b| vec![b.pack(&l.base).unwrap()]));
        }
        for (s, beats) in levels.iter_mut().zip(&tx.levels) {
            seen.level_beats += beats.len();
            s.extend(beats.iter().map(|b| vec![b.pack(&l).unwrap()]));
        }
        done.push(vec![tx.done.pack(&l).unwrap()]);
    }
    let ins = bases
        .into_iter()
        .enumerate()
        .map(|(i, beats)| StreamBeats {
            name: format!("base{i}"),
            beats,
        })
        .collect();
    let mut outs: Vec<StreamBeats> = levels
        .into_iter()
        .enumerate()
        .map(|(i, beats)| StreamBeats {
            name: format!("level{i}"),
            beats,
        })
        .collect();
    outs.push(StreamBeats {
        name: "done".into(),
        beats: done,
    });
    (ins, outs, seen)
}

/// `merges` random merges of up to `most` base nodes.
fn random_merges(p: &Params, seed: u64, merges: usize, most: u64) -> Vec<BuilderTransaction> {
    let mut rng = SplitMix64(seed);
    (0..merges)
        .map(|_| {
            let n = match rng.below(4) {
                0 => rng.below(3),
                _ => rng.below(most + 1),
            };
            builder_transaction(&random_base(&mut rng, p, n as usize), p)
        })
        .collect()
}

/// A soup hierarchy `id` of `n` triangles in the scene's `2^-3` corner.
fn soup(p: &Params, id: u8, n: usize, size: f32, seed: u64) -> Hierarchy {
    let mesh = random_soup(n, size, seed);
    let (lo, hi) = mesh.bounds();
    let fitted = GridMap::fit(lo, hi, p);
    let grid = GridMap {
        origin: fitted.origin * 0.0,
        unit: 1.0 / (p.scene_edge() >> 3) as f64,
    };
    build(&mesh, &grid, p, id).expect("the soup builds")
}

/// A translation at `h`'s top LOD by `frac` of the room left in the scene.
fn place(h: &Hierarchy, frac: [f64; 3]) -> Translation {
    let l = h.top_lod;
    let max = [0, 1, 2].map(|a| {
        h.roots()
            .iter()
            .map(|n| [n.voxel.x, n.voxel.y, n.voxel.z][a] as i64)
            .max()
            .unwrap()
    });
    let room = [0, 1, 2].map(|a| (1i64 << l) - 1 - max[a]);
    Translation {
        lod: l,
        t: [0, 1, 2].map(|a| (room[a] as f64 * frac[a]) as i64),
    }
}

/// Real merges: overlapping soups, disjoint soups, single-triangle inputs
/// with a big one; every candidate level of each.
fn real_merges(p: &Params) -> Vec<BuilderTransaction> {
    let same = [0.4, 0.5, 0.6];
    let hs: Vec<Hierarchy> = (1..=3).map(|i| soup(p, i, 60, 0.2, i as u64)).collect();
    let mut cases: Vec<Vec<(Hierarchy, Translation)>> = Vec::new();
    cases.push(hs.iter().map(|h| (h.clone(), place(h, same))).collect());
    cases.push(
        hs.iter()
            .enumerate()
            .map(|(i, h)| {
                (
                    h.clone(),
                    place(h, [0.1 + 0.3 * i as f64, 0.9 - 0.3 * i as f64, 0.3]),
                )
            })
            .collect(),
    );
    let mut single: Vec<(Hierarchy, Translation)> = (1..=2)
        .map(|i| {
            let h = soup(p, i, 1, 0.001, 10 + i as u64);
            let t = place(&h, if i < 2 { same } else { [0.9, 0.1, 0.2] });
            (h, t)
        })
        .collect();
    let big = soup(p, 3, 80, 0.3, 99);
    single.push((big.clone(), place(&big, same)));
    cases.push(single);
    let mut out = Vec::new();
    for c in &cases {
        let refs: Vec<&Hierarchy> = c.iter().map(|(h, _)| h).collect();
        let inputs: Vec<(&Hierarchy, Translation)> = c.iter().map(|(h, t)| (h, *t)).collect();
        let (lo, hi) = candidate_range(&refs);
        for m in lo..=hi {
            let base: Vec<BaseNode> = fixed_level_base(&inputs, m, p).expect("the merge walks");
            out.push(builder_transaction(&base, p));
        }
    }
    out
}

/// Random merges on every engine (`runs`: engine, merges), then the real
/// merges on the IR simulator and Verilator (Icarus on the first few).
fn check(name: &str, runs: &[(&str, usize)], most: u64) {
    let all = configs();
    let i = all.iter().position(|c| c.0 == name).unwrap();
    let p = all[i].1;
    let seed = seeded(0xb11d + i as u64);
    let dir = tempfile::tempdir().unwrap();
    let m = rtl_gen::merge::upper_builder_unit(&p);
    let design = design_of(&m, dir.path());
    // Soups need more than 2^I triangle indices at small I: random bases only.
    let real = if p.index_bits >= 8 {
        real_merges(&p)
    } else {
        Vec::new()
    };
    for &(kind, merges) in runs {
        let stall = stall_of(seed ^ kind.len() as u64).max(0.05);
        let mut e = engine(kind, &m, &design);
        let txs = random_merges(&p, seed, merges, most);
        let (ins, outs, seen) = streams(&p, &txs);
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
        let r = multi_bench(e.as_mut(), &ins, &outs, seed, stall, &what);
        println!(
            "upper_builder {name} {kind}: {merges} random merges, {} base beats, {} level beats, {} cycles, stall {stall:.2}, {:.1?}",
            seen.base_beats, seen.level_beats, r.cycles, r.wall
        );
        if real.is_empty() {
            continue;
        }
        let count = if kind == "iverilog" { 3 } else { real.len() };
        let (ins, outs, seen) = streams(&p, &real[..count.min(real.len())]);
        let mut e = engine(kind, &m, &design);
        let what = format!("merge_builder {name} {kind} real");
        let r = multi_bench(e.as_mut(), &ins, &outs, seed + 1, stall, &what);
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
    let m = rtl_gen::merge::upper_builder_unit(&p);
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
    let (ins, outs, seen) = streams(&p, &txs);
    let mut e = engine("verilator", &m, &design);
    let r = multi_bench(
        e.as_mut(),
        &ins,
        &outs,
        1,
        0.0,
        &format!("merge_builder {name} throughput"),
    );
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
        let m = rtl_gen::merge::upper_builder_unit(&p);
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
