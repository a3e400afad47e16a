//! The Icarus multi-stream batch (`cosim::icarus::IcarusMultiBatch`)
//! against `tb::run_multi_stream_bench` on Verilator, on the merging module
//! (`cosim::units::merge_module` streams): same pass/fail, same cycles and
//! per-stream counts for the same seed and stalls (the batch replays the
//! pipe bench's stall draws), a planted wrong expected beat caught on the
//! same stream and beat, a missing beat caught by the same watchdog, an X
//! on an output an error naming the port and cycle on both Icarus. Prints
//! cycles per second of the batch, the Icarus pipe engine and Verilator.

use cosim::icarus::{IcarusEngine, IcarusMultiBatch};
use cosim::tb::StreamBeats;
use cosim::tb::{run_multi_stream_bench, BenchConfig, MultiReport};
use cosim::tools::{ci_mode, tool_available, INSTALL_HINT};
use cosim::units::merge_module::{generate_streams, input_names, UnitStreams, OUTPUT_NAMES};
use cosim::verilator::{VerilatorEngine, VerilatorOptions};
use cosim::{Bits, CosimError, Design, PortSpec};
use golden::merge::merge_module::MergeDesign;
use golden::merge::MergeMode;
use golden::params::Params;
use golden::seed::seeded;

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
        in_stall: cosim::tb::Stalls::Coin(stall),
        out_stall: cosim::tb::Stalls::Coin(stall),
        stop_on_mismatch: false,
        ..BenchConfig::default()
    }
}

fn verilator(u: &Unit, s: &UnitStreams, c: &BenchConfig) -> MultiReport {
    let mut e = VerilatorEngine::new(&u.design, &VerilatorOptions::default()).unwrap();
    run_multi_stream_bench(&mut e, &s.inputs, &s.outputs, c).unwrap()
}

fn batch(u: &Unit, s: &UnitStreams, c: &BenchConfig) -> MultiReport {
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
            let seed = seeded(seed);
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
    out.beats[n][0] = Bits::from_words(&w, out.beats[n][0].width()).unwrap();
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

/// A one-register pass-through whose data turns X while it holds a 5.
const X_ON_FIVE: &str = "module x_on_five(input clk, input rst,
    input a_valid, output a_ready, input [7:0] a_data,
    output b_valid, input b_ready, output [7:0] b_data);
    reg full;
    reg [7:0] d;
    assign a_ready = !full || b_ready;
    assign b_valid = full;
    assign b_data = d == 8'd5 ? 8'bx : d;
    always @(posedge clk)
        if (rst) begin full <= 1'b0; d <= 8'd0; end
        else if (a_ready) begin full <= a_valid; if (a_valid) d <= a_data; end
endmodule
";

fn beats(values: &[u64]) -> Vec<cosim::tb::Transaction> {
    values
        .iter()
        .map(|&v| vec![Bits::from_u64(v, 8).unwrap()])
        .collect()
}

#[test]
fn an_x_on_an_output_is_an_error_naming_port_and_cycle() {
    if !tools_present() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("x_on_five.v");
    std::fs::write(&file, X_ON_FIVE).unwrap();
    let design = Design::new(
        "x_on_five",
        vec![file],
        vec![
            PortSpec::input("clk", 1),
            PortSpec::input("rst", 1),
            PortSpec::input("a_valid", 1),
            PortSpec::output("a_ready", 1),
            PortSpec::input("a_data", 8),
            PortSpec::output("b_valid", 1),
            PortSpec::input("b_ready", 1),
            PortSpec::output("b_data", 8),
        ],
        Some("clk"),
        Some("rst"),
    )
    .unwrap();
    let batch = IcarusMultiBatch::new(&design, &["a"], &["b"]).unwrap();
    let stream = |name: &str, v: &[u64]| StreamBeats {
        name: name.into(),
        beats: beats(v),
    };
    let c = config(3, 0.4);
    // Clean beats pass and match the Icarus pipe engine.
    let (ins, outs) = ([stream("a", &[1, 2, 3, 4])], [stream("b", &[1, 2, 3, 4])]);
    let b = batch.run(&ins, &outs, &c).unwrap().report;
    let mut e = IcarusEngine::new(&design).unwrap();
    let p = run_multi_stream_bench(&mut e, &ins, &outs, &c).unwrap();
    assert!(b.passed(), "{b}");
    assert_same(&p, &b);
    // A 5 makes b_data X: both Icarus benches fail on it, same port and cycle.
    let (ins, outs) = ([stream("a", &[1, 2, 5, 4])], [stream("b", &[1, 2, 5, 4])]);
    let cycle_of = |r: cosim::Result<MultiReport>| match r {
        Err(CosimError::UnknownOutput { port, cycle, .. }) => {
            assert_eq!(port, "b_data");
            cycle
        }
        other => panic!("expected UnknownOutput on b_data, got {other:?}"),
    };
    let batch_cycle = cycle_of(batch.run(&ins, &outs, &c).map(|r| r.report));
    let mut e = IcarusEngine::new(&design).unwrap();
    let pipe_cycle = cycle_of(run_multi_stream_bench(&mut e, &ins, &outs, &c));
    assert_eq!(batch_cycle, pipe_cycle);
    assert!(batch_cycle > 2, "after reset: {batch_cycle}");
}
