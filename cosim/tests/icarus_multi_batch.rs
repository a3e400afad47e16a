//! The Icarus multi-stream batch (`cosim::icarus::IcarusMultiBatch`)
//! against `tb::run_multi_stream_bench` on Verilator, on the merging module
//! (`cosim::units::merge_module` streams): same pass/fail, same cycles and
//! per-stream counts for the same seed and stalls (the batch replays the
//! pipe bench's stall draws), a planted wrong expected beat caught on the
//! same stream and beat, a missing beat caught by the same watchdog. Prints
//! cycles per second of the batch, the Icarus pipe engine and Verilator.

use cosim::icarus::{IcarusEngine, IcarusMultiBatch};
use cosim::tb::{run_multi_stream_bench, BenchConfig, MultiReport};
use cosim::tools::{ci_mode, tool_available, INSTALL_HINT};
use cosim::units::merge_module::{generate_streams, input_names, MergeStreams, OUTPUT_NAMES};
use cosim::verilator::{VerilatorEngine, VerilatorOptions};
use cosim::{BitVec, Design};
use golden::merge::MergeMode;
use golden::params::Params;
use golden::vectors::merge::MergeDesign;

fn tools_present() -> bool {
    let missing: Vec<&str> = ["verilator", "iverilog"]
        .into_iter()
        .filter(|t| !tool_available(t))
        .collect();
    if missing.is_empty() {
        return true;
    }
    if ci_mode() {
        panic!("CI=true and {missing:?} missing: {INSTALL_HINT}");
    }
    eprintln!("SKIPPING: {missing:?} not installed; {INSTALL_HINT}");
    false
}

struct Unit {
    design: Design,
    batch: IcarusMultiBatch,
    _dir: tempfile::TempDir,
}

fn unit(d: &MergeDesign) -> Unit {
    let dir = tempfile::tempdir().unwrap();
    let m = rtl_gen::merge::merge_module_unit(d);
    let design = cosim::from_rtl::design_from_module(&m, dir.path()).unwrap();
    let names = input_names(d);
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let batch = IcarusMultiBatch::new(&design, &names, &OUTPUT_NAMES).unwrap();
    Unit {
        design,
        batch,
        _dir: dir,
    }
}

fn config(seed: u64, stall: f64) -> BenchConfig {
    BenchConfig {
        seed,
        in_stall: stall,
        out_stall: stall,
        stop_on_mismatch: false,
        ..BenchConfig::default()
    }
}

fn verilator(u: &Unit, s: &MergeStreams, c: &BenchConfig) -> MultiReport {
    let mut e = VerilatorEngine::new(&u.design, &VerilatorOptions::default()).unwrap();
    run_multi_stream_bench(&mut e, &s.inputs, &s.outputs, c).unwrap()
}

fn batch(u: &Unit, s: &MergeStreams, c: &BenchConfig) -> MultiReport {
    u.batch.run(&s.inputs, &s.outputs, c).unwrap().report
}

/// Everything the two runs count is equal.
fn assert_same(pipe: &MultiReport, batch: &MultiReport) {
    let what = format!("pipe:\n{pipe}batch:\n{batch}");
    assert_eq!(pipe.passed(), batch.passed(), "{what}");
    assert_eq!(pipe.cycles, batch.cycles, "{what}");
    assert_eq!(pipe.sent, batch.sent, "{what}");
    assert_eq!(pipe.received, batch.received, "{what}");
    assert_eq!(pipe.matched, batch.matched, "{what}");
    assert_eq!(pipe.mismatches, batch.mismatches, "{what}");
    assert_eq!(pipe.missing, batch.missing, "{what}");
    assert_eq!(pipe.hang.is_some(), batch.hang.is_some(), "{what}");
    match (&pipe.first_mismatch, &batch.first_mismatch) {
        (Some((ps, pm)), Some((bs, bm))) => {
            assert_eq!(ps, bs, "{what}");
            assert_eq!(pm.output_index, bm.output_index, "{what}");
            assert_eq!(pm.cycle, bm.cycle, "{what}");
            assert_eq!(pm.expected, bm.expected, "{what}");
            assert_eq!(pm.got, bm.got, "{what}");
        }
        (None, None) => {}
        _ => panic!("one run has a mismatch, the other not: {what}"),
    }
}

fn configs() -> Vec<(&'static str, MergeDesign)> {
    let d = MergeDesign::default();
    vec![
        ("default", d),
        (
            "q0_fixed",
            MergeDesign {
                params: Params::new(8, 0, 12, 3).unwrap(),
                inputs: 2,
                mode: MergeMode::Fixed(3),
                ..d
            },
        ),
    ]
}

#[test]
fn batch_equals_the_pipe_bench_cycle_for_cycle() {
    if !tools_present() {
        return;
    }
    for (name, d) in configs() {
        let u = unit(&d);
        let s = generate_streams(&d, 0xba7c, 150, 12, None).unwrap();
        for (seed, stall) in [(1, 0.0), (2, 0.3), (3, 0.8)] {
            let c = config(seed, stall);
            let (p, b) = (verilator(&u, &s, &c), batch(&u, &s, &c));
            eprintln!("{name} stall {stall}: pipe {p}batch {b}");
            assert!(p.passed(), "{p}");
            assert!(p.sent.iter().all(|x| x.1 > 0), "{p}");
            assert_same(&p, &b);
        }
    }
}

#[test]
fn a_planted_wrong_beat_is_caught_on_its_stream() {
    if !tools_present() {
        return;
    }
    let d = MergeDesign::default();
    let u = unit(&d);
    let mut s = generate_streams(&d, 0xbad, 60, 12, None).unwrap();
    let out = &mut s.outputs[1];
    assert_eq!(out.name, "out");
    let n = out.beats.len() / 2;
    let mut w = out.beats[n][0].words().to_vec();
    w[0] ^= 1 << 3;
    out.beats[n][0] = BitVec::from_words(out.beats[n][0].width(), &w).unwrap();
    let c = config(5, 0.25);
    let (p, b) = (verilator(&u, &s, &c), batch(&u, &s, &c));
    assert!(!b.passed());
    assert_eq!(b.mismatches, 1, "{b}");
    let (stream, m) = b.first_mismatch.as_ref().unwrap();
    assert_eq!(stream, "out");
    assert_eq!(m.output_index, n as u64);
    assert_same(&p, &b);
}

#[test]
fn a_beat_that_never_comes_fires_the_same_watchdog() {
    if !tools_present() {
        return;
    }
    let d = MergeDesign::default();
    let u = unit(&d);
    let mut s = generate_streams(&d, 0x1055, 20, 12, None).unwrap();
    let extra = s.outputs[0].beats[0].clone();
    s.outputs[0].beats.push(extra);
    let c = BenchConfig {
        watchdog_cycles: 200,
        ..config(9, 0.2)
    };
    let (p, b) = (verilator(&u, &s, &c), batch(&u, &s, &c));
    let hang = b.hang.as_ref().expect("the watchdog fires");
    assert_eq!(hang.cycle, p.hang.as_ref().unwrap().cycle);
    assert!(
        hang.ports.iter().any(|(n, _)| n == "report_valid"),
        "{hang}"
    );
    assert_eq!(b.missing[0], ("report".to_string(), 1));
    assert_same(&p, &b);
}

#[test]
fn streams_other_than_the_built_ones_are_refused() {
    if !tools_present() {
        return;
    }
    let d = MergeDesign::default();
    let u = unit(&d);
    let s = generate_streams(&d, 1, 2, 12, None).unwrap();
    let err = u
        .batch
        .run(&s.inputs[1..], &s.outputs, &config(1, 0.0))
        .unwrap_err()
        .to_string();
    assert!(err.contains("cfg") && err.contains("built for"), "{err}");
    assert!(IcarusMultiBatch::new(&u.design, &["nope"], &[]).is_err());
}

/// Cycles per second of the batch, the Icarus pipe engine and Verilator on
/// the same merges (printed, never asserted).
#[test]
fn batch_speed_against_the_pipe_engines() {
    if !tools_present() {
        return;
    }
    let d = MergeDesign::default();
    let u = unit(&d);
    let s = generate_streams(&d, 0x5eed, 300, 12, None).unwrap();
    let c = config(4, 0.3);
    let b = u.batch.run(&s.inputs, &s.outputs, &c).unwrap();
    let mut e = IcarusEngine::new(&u.design).unwrap();
    let p = run_multi_stream_bench(&mut e, &s.inputs, &s.outputs, &c).unwrap();
    let v = verilator(&u, &s, &c);
    assert_same(&p, &b.report);
    assert_same(&v, &b.report);
    let rate = |r: &MultiReport| r.cycles as f64 / r.wall.as_secs_f64();
    println!(
        "merge_module default, {} cycles: iverilog-batch {:.0} cycles/s (vvp alone {:.0}), iverilog pipe {:.0} cycles/s, verilator pipe {:.0} cycles/s",
        b.report.cycles,
        b.cycles_per_second(),
        b.report.cycles as f64 / b.sim_wall.as_secs_f64(),
        rate(&p),
        rate(&v)
    );
}
