//! The merging module as one unit (`rtl_gen::merge::merge_module_unit`)
//! against the golden `golden::merge::merge_module` transactions, bit for bit on every
//! stream (`report`, `out`), on the IR simulator, Verilator and Icarus, with
//! random stalls on every input and output stream independently; one
//! transaction = one merge (cfg, count pass in overlap mode, choice, merge
//! pass). Configurations: the default (overlap 1/2, k = 4), D = 31 (k = 5),
//! Q = 0 with a fixed level, a small-I proportion mode (count overflows),
//! below-top. Throughput with no back-pressure is printed and asserted from
//! simulated cycle counts (deterministic); lint and synthesis of each.
mod merge_common;

use cosim::tb::StreamBeats;
use cosim::volume::volume;
use golden::merge::merge_module::MergeDesign;
use golden::merge::merge_module::TopLayout;
use golden::merge::MergeMode;
use golden::params::Params;
use golden::seed::seeded;
use merge_common::*;

/// Configurations, each with the most voxels of a random level.
fn configs() -> Vec<(&'static str, MergeDesign, usize)> {
    let d = MergeDesign::default();
    vec![
        ("default", d, 12),
        (
            "d31",
            MergeDesign {
                params: Params::new(31, 16, 32, 8).unwrap(),
                inputs: 5,
                ..d
            },
            12,
        ),
        (
            "q0_fixed",
            MergeDesign {
                params: Params::new(8, 0, 12, 3).unwrap(),
                inputs: 2,
                mode: MergeMode::Fixed(3),
                ..d
            },
            12,
        ),
        (
            "i6_proportion",
            MergeDesign {
                params: Params::new(4, 2, 6, 2).unwrap(),
                inputs: 3,
                mode: MergeMode::Proportion { num: 1, den: 3 },
                ..d
            },
            12,
        ),
        (
            // 2^I = 16: a level's union overflows the counter.
            "i4_overlap",
            MergeDesign {
                params: Params::new(4, 2, 4, 2).unwrap(),
                inputs: 3,
                mode: MergeMode::Overlap { num: 1, den: 3 },
                ..d
            },
            30,
        ),
        (
            "below_top",
            MergeDesign {
                mode: MergeMode::BelowTop(2),
                ..d
            },
            12,
        ),
    ]
}

/// Counts of what the stimulus exercised.
#[derive(Default, Debug)]
struct Seen {
    merges: usize,
    refused: usize,
    counted_levels: usize,
    above: usize,
    overflow: usize,
}

/// `merges` random merges for `d` as streams in and out of the unit
/// (`cosim::units::merge_module::generate_streams`, what `hiermerge cosim`
/// runs), and what they exercise, read off the expected `report` beats.
fn streams(
    d: &MergeDesign,
    seed: u64,
    merges: usize,
    most_voxels: usize,
) -> (Vec<StreamBeats>, Vec<StreamBeats>, Seen) {
    let s = cosim::units::merge_module::generate_streams(d, seed, merges, most_voxels, None)
        .expect("golden merges");
    let tl = TopLayout::new(&d.params);
    let mut seen = Seen {
        merges: s.merges(),
        ..Seen::default()
    };
    for beat in &s.outputs[0].beats {
        let b = &beat[0];
        let get = |f| b.get(f).expect("a report field");
        if get(&tl.chosen) == 1 {
            seen.refused += (get(&tl.err) != 0) as usize;
        } else {
            seen.counted_levels += 1;
            seen.above += get(&tl.above) as usize;
            seen.overflow += get(&tl.overflow) as usize;
        }
    }
    (s.inputs, s.outputs, seen)
}

/// Merges per bench run: longer runs go in chunks of fresh stimulus (the
/// seed plus the chunk's number) on the same simulator, so the stimulus held
/// in memory stays small (100,000 merges at once take several GB).
const CHUNK: usize = 10_000;

fn check(name: &str, d: &MergeDesign, most_voxels: usize, runs: &[(&str, usize)], seed: u64) {
    let seed = seeded(seed);
    d.validate().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let m = rtl_gen::merge::merge_module_unit(d);
    let design = design_of(&m, dir.path());
    for &(kind, total) in runs {
        let stall = stall_of(seed ^ kind.len() as u64).max(0.05);
        let what = format!("merge_module {name} {kind}");
        let mut e = (kind != "iverilog-batch").then(|| engine(kind, &m, &design));
        let (mut done, mut cycles, mut out_beats, mut chunk) = (0, 0, 0, 0u64);
        while done < total {
            let merges = CHUNK.min(total - done);
            let (ins, outs, seen) = streams(d, seed + chunk, merges, most_voxels);
            eprintln!("merge_module {name}/{kind}: {seen:?}");
            assert_eq!(seen.merges, merges);
            // Both refusals and merges are exercised (in runs long enough
            // to meet a bad range, 1 in 32).
            assert!(
                (seen.refused > 0 || merges < 100) && seen.refused * 10 < merges * 6,
                "{seen:?}"
            );
            if d.threshold().is_some() {
                assert!(
                    seen.above > 0 && seen.above < seen.counted_levels,
                    "{seen:?}"
                );
            }
            if d.params.index_bits <= 4 && d.threshold().is_some() {
                assert!(seen.overflow > 0, "{seen:?}");
            }
            // An engine's cycle count runs on across chunks; a batch starts at 0.
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
            chunk += 1;
        }
        println!(
            "merge_module {name} {kind}: {total} merges, {out_beats} out beats, {cycles} cycles, stall {stall:.2}"
        );
    }
}

/// Input beats (all streams) per cycle with no back-pressure, on merges of
/// large levels, from simulated cycles.
fn throughput(name: &str, d: &MergeDesign) -> f64 {
    let dir = tempfile::tempdir().unwrap();
    let m = rtl_gen::merge::merge_module_unit(d);
    let design = design_of(&m, dir.path());
    let (ins, outs, _) = streams(d, 0x70, 40, 400);
    let mut e = engine("verilator", &m, &design);
    let r = multi_bench_done_per_merge(
        e.as_mut(),
        &ins,
        &outs,
        1,
        0.0,
        &format!("merge_module {name} throughput"),
    );
    let beats: u64 = r.sent.iter().filter(|s| s.0 != "cfg").map(|s| s.1).sum();
    let rate = beats as f64 / r.cycles as f64;
    println!(
        "merge_module {name} throughput: {beats} input beats ({} streams) in {} cycles: {rate:.4} beats/cycle merged",
        d.inputs, r.cycles
    );
    rate
}

/// Runs per engine: the IR simulator, Verilator, Icarus over pipes (slow:
/// a few merges) and Icarus in batch mode.
fn runs(verilator: usize, batch: usize) -> Vec<(&'static str, usize)> {
    vec![
        ("ir", 200),
        ("verilator", volume(verilator)),
        ("iverilog", 20),
        ("iverilog-batch", batch),
    ]
}

fn check_config(i: usize, verilator: usize, batch: usize) {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    let (name, d, most) = &configs()[i];
    check(name, d, *most, &runs(verilator, batch), 0x70d + i as u64);
}

#[test]
fn merge_module_default_matches_golden() {
    check_config(0, 100_000, 2_000);
}

#[test]
fn merge_module_d31_matches_golden() {
    check_config(1, 100_000, 500);
}

#[test]
fn merge_module_q0_fixed_matches_golden() {
    check_config(2, 100_000, 500);
}

#[test]
fn merge_module_i6_proportion_matches_golden() {
    check_config(3, 100_000, 500);
}

#[test]
fn merge_module_i4_overlap_and_below_top_match_golden() {
    check_config(4, 20_000, 500);
    check_config(5, 20_000, 500);
}

#[test]
fn merge_module_streams_one_beat_per_clock() {
    if !tools_present(&["verilator"]) {
        return;
    }
    for (name, d, _) in configs() {
        let rate = throughput(name, &d);
        assert!(rate >= 0.95, "{name}: {rate:.4} merged beats per cycle");
    }
}

#[test]
fn merge_module_verilog_lints_and_synthesizes() {
    if !tools_present(&["verilator", "yosys"]) {
        return;
    }
    for (_, d, _) in configs() {
        let dir = tempfile::tempdir().unwrap();
        let m = rtl_gen::merge::merge_module_unit(&d);
        lint_and_synth(&design_of(&m, dir.path()));
    }
}
