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
//! lint and synthesis.
mod merge_common;

use cosim::tb::{MultiReport, StreamBeats};
use cosim::volume::volume;
use golden::merge::level_choice::candidate_range;
use golden::merge::merge_level::BaseNode;
use golden::merge::record_writer::{
    pack_cfg, writer_err, writer_transaction, WriterLayout, WriterTransaction,
};
use golden::merge::stimulus::{per_node_base, random_case, real_cases};
use golden::merge::upper_builder::unit::fixed_level_base;
use golden::params::Params;
use golden::seed::seeded;
use golden::store::Hierarchy;
use golden::translate::stimulus::SplitMix64;
use golden::translate::Translation;
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

/// What the stimulus exercised.
#[derive(Default, Debug)]
struct Seen {
    merges: usize,
    codes: [usize; 5],
    materialized: usize,
    several_roots: usize,
    /// Merges with created nodes at two or more LODs.
    created_lods: usize,
    level_beats: u64,
    records: u64,
    refs: u64,
    /// Per merge, the longest in stream (a level or `crefs`).
    longest_in: u64,
}

fn one(b: &cosim::Bits) -> Vec<cosim::Bits> {
    vec![b.clone()]
}

/// The streams of a list of merges.
fn streams(
    p: &Params,
    cap: u32,
    txs: &[WriterTransaction],
) -> (Vec<StreamBeats>, Vec<StreamBeats>, Seen) {
    let wl = WriterLayout::new(p, cap).unwrap();
    let bl = &wl.builder;
    let d = p.max_lod as usize;
    let named = |name: &str| StreamBeats {
        name: name.into(),
        beats: Vec::new(),
    };
    let mut cfg = named("cfg");
    let mut levels: Vec<StreamBeats> = (0..=d).map(|i| named(&format!("level{i}"))).collect();
    let mut done = named("done");
    let mut crefs = named("crefs");
    let mut ref_resp = named("ref_resp");
    let mut ref_req = named("ref_req");
    let mut nodes = named("nodes");
    let mut refs = named("refs");
    let mut header = named("header");
    let mut seen = Seen::default();
    for tx in txs {
        seen.merges += 1;
        seen.codes[tx.header.err as usize] += 1;
        seen.materialized += !tx.ref_reqs.is_empty() as usize;
        seen.several_roots += (tx.header.roots > 1) as usize;
        let created_at = tx.builder.levels.iter().filter(|l| {
            l.iter().any(|b| {
                matches!(b, golden::merge::upper_builder::unit::LevelOut::Node { kind, .. }
                    if *kind == golden::merge::upper_builder::unit::level_out_kind::CREATED)
            })
        });
        seen.created_lods += (created_at.count() > 1) as usize;
        seen.records += tx.nodes.len() as u64;
        seen.refs += tx.refs.len() as u64;
        let mut longest = tx.crefs.len();
        cfg.beats.push(one(&pack_cfg(tx.out_id, &wl).unwrap()));
        for (s, beats) in levels.iter_mut().zip(&tx.builder.levels) {
            seen.level_beats += beats.len() as u64;
            longest = longest.max(beats.len());
            s.beats
                .extend(beats.iter().map(|b| one(&b.pack(bl).unwrap())));
        }
        seen.longest_in += longest as u64;
        done.beats.push(one(&tx.builder.done.pack(bl).unwrap()));
        crefs
            .beats
            .extend(tx.crefs.iter().map(|c| one(&c.pack(&wl).unwrap())));
        let r = |x: &golden::store::Reference| one(&x.pack(&wl.reference).unwrap());
        let n = |x: &golden::store::NodeRecord| one(&x.pack(&wl.node).unwrap());
        ref_req.beats.extend(tx.ref_reqs.iter().map(r));
        ref_resp.beats.extend(tx.ref_resps.iter().map(r));
        nodes.beats.extend(tx.nodes.iter().map(n));
        refs.beats.extend(tx.refs.iter().map(r));
        header.beats.push(one(&tx.header.pack(&wl).unwrap()));
    }
    let mut ins = vec![cfg];
    ins.extend(levels);
    ins.extend([done, crefs, ref_resp]);
    (ins, vec![ref_req, nodes, refs, header], seen)
}

/// `merges` random cases of up to `most` base nodes.
fn random_merges(
    p: &Params,
    cap: u32,
    seed: u64,
    merges: usize,
    most: u64,
) -> Vec<WriterTransaction> {
    let mut rng = SplitMix64(seed);
    (0..merges)
        .map(|_| {
            let n = match rng.below(4) {
                0 => rng.below(3),
                _ => rng.below(most + 1),
            };
            let (base, inputs) = random_case(&mut rng, p, n as usize, 0);
            let hs: Vec<&Hierarchy> = inputs.iter().collect();
            writer_transaction(&base, &hs, p, cap, 0).expect("a random case lays out")
        })
        .collect()
}

/// Real merges: overlapping, disjoint, single-triangle soups and one input
/// alone (a materialized root), at every fixed level and in per-node mode.
fn real_merges(p: &Params, cap: u32) -> Vec<WriterTransaction> {
    let mut out = Vec::new();
    for (store, table, ids) in real_cases(p).expect("the real cases build") {
        let hs: Vec<&Hierarchy> = ids.iter().map(|i| store.get(*i).unwrap()).collect();
        let inputs: Vec<(&Hierarchy, Translation)> = hs
            .iter()
            .map(|h| (*h, table.read(h.id as u32).unwrap()))
            .collect();
        let (lo, hi) = candidate_range(&hs);
        let mut bases: Vec<Vec<BaseNode>> = (lo..=hi)
            .map(|m| fixed_level_base(&inputs, m, p).expect("the merge walks"))
            .collect();
        for (num, den) in [(0, 1), (1, 4), (1, 2)] {
            bases.push(per_node_base(&inputs, num, den, p).expect("per-node merge"));
        }
        for base in bases {
            let out_id = (p.hier_capacity() - 1) as u8;
            out.push(writer_transaction(&base, &hs, p, cap, out_id).unwrap());
        }
    }
    out
}

/// A writer run counting the cycles each phase output is high.
fn writer_bench(
    engine: &mut dyn cosim::Engine,
    ins: &[StreamBeats],
    outs: &[StreamBeats],
    seed: u64,
    stall: f64,
    what: &str,
) -> (MultiReport, Vec<(String, u64)>) {
    let pulses = ["filling", "drain_records", "drain_refs"];
    multi_bench_watching(engine, ins, outs, seed, stall, what, &pulses)
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
    let m = rtl_gen::merge::record_writer_unit(&p, cap).expect("a valid capacity");
    let design = design_of(&m, dir.path());
    // Soups need more than 2^I triangle indices at small I: random only.
    let real = if p.index_bits >= 8 {
        real_merges(&p, cap)
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
            let txs = random_merges(&p, cap, seed + chunk, merges, most);
            let (ins, outs, seen) = streams(&p, cap, &txs);
            let r = match e.as_mut() {
                Some(e) => {
                    let before = e.cycle();
                    writer_bench(e.as_mut(), &ins, &outs, seed + chunk, stall, &what)
                        .0
                        .cycles
                        - before
                }
                None => multi_batch_bench(&design, &ins, &outs, seed + chunk, stall, &what).cycles,
            };
            cycles += r;
            done += merges;
            chunk += 1;
            all_seen.merges += seen.merges;
            for c in 0..5 {
                all_seen.codes[c] += seen.codes[c];
            }
            all_seen.materialized += seen.materialized;
            all_seen.several_roots += seen.several_roots;
            all_seen.created_lods += seen.created_lods;
            all_seen.level_beats += seen.level_beats;
            all_seen.records += seen.records;
            all_seen.refs += seen.refs;
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
        let (ins, outs, seen) = streams(&p, cap, &real[..count.min(real.len())]);
        let created_lods = seen.created_lods;
        assert_eq!(seen.codes[0], seen.merges, "real merges fit: {seen:?}");
        let what = format!("merge_writer {name} {kind} real");
        let cycles = match kind {
            "iverilog-batch" => {
                multi_batch_bench(&design, &ins, &outs, seed + 1, stall, &what).cycles
            }
            _ => {
                let mut e = engine(kind, &m, &design);
                writer_bench(e.as_mut(), &ins, &outs, seed + 1, stall, &what)
                    .0
                    .cycles
            }
        };
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
        let m = rtl_gen::merge::record_writer_unit(&p, cap).unwrap();
        let design = design_of(&m, dir.path());
        // Large merges: real ones, then random cases of up to 2^C / 2 nodes.
        let mut txs = real_merges(&p, cap);
        txs.extend(
            random_merges(&p, cap, 0x7b, 400, 1 << (cap - 1))
                .into_iter()
                .filter(|t| t.header.err == writer_err::NONE),
        );
        let (ins, outs, seen) = streams(&p, cap, &txs);
        let mut e = engine("verilator", &m, &design);
        let (r, counts) = writer_bench(
            e.as_mut(),
            &ins,
            &outs,
            1,
            0.0,
            &format!("merge_writer {name} throughput"),
        );
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
        let m = rtl_gen::merge::record_writer_unit(&p, cap).unwrap();
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
