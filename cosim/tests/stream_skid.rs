//! The skid buffer through the full stream testbench on both engines, with
//! random valid gaps and ready back-pressure, checked against its Rust model
//! (payload + 1 mod 2^16, in order, one output per input).
mod common;

use cosim::tb::{
    run_stream_bench, run_stream_bench_with_progress, BenchConfig, Prng, StreamNames, Vector,
};
use cosim::Bits;
use golden::seed::seeded;

/// Random payloads and what the skid stage must emit for each.
pub fn vectors(seed: u64, count: usize) -> Vec<Vector> {
    let mut rng = Prng::new(seed);
    (0..count)
        .map(|_| {
            let x = rng.below(1 << common::SKID_WIDTH);
            let y = (x + 1) & 0xffff;
            Vector {
                input: vec![Bits::from_u64(x, common::SKID_WIDTH).unwrap()],
                outputs: vec![vec![Bits::from_u64(y, common::SKID_WIDTH).unwrap()]],
            }
        })
        .collect()
}

#[test]
fn skid_passes_under_random_back_pressure_on_every_engine() {
    if !common::all_tools_present() {
        return;
    }
    let design = common::skid();
    for kind in common::ENGINES {
        for (seed, stall) in [(1u64, 0.0), (2, 0.3), (3, 0.6), (4, 0.9)] {
            let seed = seeded(seed);
            let count = if kind == "verilator" { 3000 } else { 400 };
            let vs = vectors(seed, count);
            let config = BenchConfig {
                seed,
                in_stall: cosim::tb::Stalls::Coin(stall),
                out_stall: cosim::tb::Stalls::Coin(stall),
                ..BenchConfig::default()
            };
            let mut e = common::make_engine(kind, &design, false).unwrap();
            let report = run_stream_bench(
                e.as_mut(),
                &StreamNames::single("data"),
                &vs,
                None,
                &config,
                None,
            )
            .unwrap();
            eprint!("{report}");
            assert!(report.passed(), "{kind} stall {stall}:\n{report}");
            assert_eq!(report.inputs_sent, count as u64);
            assert_eq!(report.matched, count as u64);
            assert_eq!(report.accounting.delivered_outputs, count as u64);
            if stall == 0.0 {
                // A skid buffer must sustain one transfer per cycle.
                assert!(
                    report.inputs_per_cycle() > 0.95,
                    "{kind}: {}",
                    report.inputs_per_cycle()
                );
            }
        }
    }
}

#[test]
fn a_dropped_expectation_shows_up_as_a_duplicate_and_a_missing_one_as_lost() {
    if !common::all_tools_present() {
        return;
    }
    let design = common::skid();
    let mut vs = vectors(9, 50);
    // Claim input 10 produces no output: the design's output for it is then extra.
    vs[10].outputs.clear();
    let mut e = common::make_engine("verilator", &design, false).unwrap();
    let config = BenchConfig {
        stop_on_mismatch: false,
        watchdog_cycles: 50,
        ..BenchConfig::default()
    };
    let r = run_stream_bench(
        e.as_mut(),
        &StreamNames::single("data"),
        &vs,
        None,
        &config,
        None,
    )
    .unwrap();
    assert!(!r.passed());
    assert_eq!(r.accounting.duplicated_outputs, 1, "{r}");
    // Claim input 20 produces two outputs: one of them never comes.
    let mut vs = vectors(9, 50);
    let extra = vs[20].outputs[0].clone();
    vs[20].outputs.push(extra);
    let mut e = common::make_engine("verilator", &design, false).unwrap();
    let r = run_stream_bench(
        e.as_mut(),
        &StreamNames::single("data"),
        &vs,
        None,
        &config,
        None,
    )
    .unwrap();
    assert!(!r.passed());
    assert!(r.hang.is_some(), "the missing output stalls the run: {r}");
    assert_eq!(r.accounting.inputs_with_lost_outputs, 1, "{r}");
}

#[test]
fn progress_is_reported_and_the_json_report_counts_everything() {
    if !common::all_tools_present() {
        return;
    }
    let design = common::skid();
    let vs = vectors(11, 10_000);
    let mut e = common::make_engine("verilator", &design, false).unwrap();
    let mut calls = Vec::new();
    let config = BenchConfig {
        in_stall: cosim::tb::Stalls::Coin(0.2),
        out_stall: cosim::tb::Stalls::Coin(0.2),
        ..BenchConfig::default()
    };
    let r = run_stream_bench_with_progress(
        e.as_mut(),
        &StreamNames::single("data"),
        &vs,
        None,
        &config,
        None,
        &mut |p| calls.push(p),
    )
    .unwrap();
    assert!(r.passed(), "{r}");
    assert!(
        calls.len() as u64 >= r.cycles / 4096 - 1,
        "{} calls for {} cycles",
        calls.len(),
        r.cycles
    );
    assert!(calls.windows(2).all(|w| w[0].outputs <= w[1].outputs));
    assert!(calls.iter().all(|p| p.expected_outputs == 10_000));
    let json = r.to_json();
    assert_eq!(json["transactions_in"], 10_000);
    assert_eq!(json["transactions_out"], 10_000);
    assert_eq!(json["mismatches"], 0);
    assert_eq!(json["cycles"], r.cycles);
    assert_eq!(json["accounting"]["balanced"], true);
}
