//! Tests of the Icarus batch mode against the pipe engine on the fixtures
//! of `tests/fixtures/` (skid buffer, broken skid, stuck stage) and an
//! inline stage that outputs X: the same results as `tb::run_stream_bench`
//! on `IcarusEngine` (the same cycles without back-pressure), mismatches
//! decoded, hangs and X/Z reported, VCD written around a failure, two lanes
//! with a wait, stall masks of the asked density.

use super::batch::{BatchSpec, StallMasks, BATCH_ENGINE_NAME};
use super::batch::{IcarusBatch, LaneVector};
use super::IcarusEngine;
use crate::design::{Design, PortSpec};
use crate::error::CosimError;
use crate::tb::{run_stream_bench, BenchConfig, Prng, StreamNames, Vector};
use crate::tools::{ci_mode, tool_available, INSTALL_HINT};
use crate::Bits;
use std::path::PathBuf;

fn icarus_present() -> bool {
    if tool_available("iverilog") && tool_available("vvp") {
        return true;
    }
    if ci_mode() {
        panic!("CI=true and iverilog/vvp missing: {INSTALL_HINT}");
    }
    eprintln!("SKIPPING: iverilog not installed; {INSTALL_HINT}");
    false
}

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests")
        .join("fixtures")
        .join(name)
}

fn stage(top: &str, file: PathBuf, width: u32) -> Design {
    Design::new(
        top,
        vec![file],
        vec![
            PortSpec::input("clk", 1),
            PortSpec::input("rst", 1),
            PortSpec::input("in_valid", 1),
            PortSpec::output("in_ready", 1),
            PortSpec::input("in_data", width),
            PortSpec::output("out_valid", 1),
            PortSpec::input("out_ready", 1),
            PortSpec::output("out_data", width),
        ],
        Some("clk"),
        Some("rst"),
    )
    .unwrap()
}

/// The skid stage's Rust model: payload + 1 mod 2^16.
fn skid_vectors(seed: u64, count: usize) -> Vec<Vector> {
    let mut rng = Prng::new(seed);
    (0..count)
        .map(|_| {
            let x = rng.below(1 << 16);
            Vector {
                input: vec![Bits::from_u64(x, 16).unwrap()],
                outputs: vec![vec![Bits::from_u64((x + 1) & 0xffff, 16).unwrap()]],
            }
        })
        .collect()
}

fn config(seed: u64, stall: f64) -> BenchConfig {
    BenchConfig {
        seed,
        in_stall: crate::tb::Stalls::Coin(stall),
        out_stall: crate::tb::Stalls::Coin(stall),
        ..BenchConfig::default()
    }
}

#[test]
fn stall_masks_go_with_probability_one_minus_stall_per_stream() {
    let ones = |stall: f64, seed: u64| {
        let mut m = StallMasks::new(&config(seed, stall), 2);
        let blocks: Vec<Vec<u64>> = (0..500).map(|_| m.next_block()).collect();
        assert!(blocks.iter().all(|b| b.len() == 4));
        let per_stream: Vec<f64> = (0..4)
            .map(|s| blocks.iter().map(|b| b[s].count_ones()).sum::<u32>() as f64 / (500.0 * 64.0))
            .collect();
        (per_stream, blocks)
    };
    let (none, _) = ones(0.0, 1);
    assert!(none.iter().all(|&f| f == 1.0));
    let (some, a) = ones(0.3, 1);
    assert!(some.iter().all(|&f| (f - 0.7).abs() < 0.02), "{some:?}");
    let (_, b) = ones(0.3, 1);
    assert_eq!(a, b, "a seed gives one pattern");
    let (_, c) = ones(0.3, 2);
    assert_ne!(a, c);
    assert_ne!(a[0][0], a[0][1], "the driver and the monitor draw apart");
}

#[test]
fn a_batch_run_agrees_with_the_pipe_run() {
    if !icarus_present() {
        return;
    }
    let design = stage("skid", fixture("skid.v"), 16);
    let batch =
        IcarusBatch::new(&design, &BatchSpec::single(&StreamNames::single("data"))).unwrap();
    for (seed, stall, count) in [(3u64, 0.0, 300), (4, 0.3, 400), (5, 0.9, 150)] {
        let vs = skid_vectors(seed, count);
        let c = config(seed, stall);
        let mut pipe = IcarusEngine::new(&design).unwrap();
        let p =
            run_stream_bench(&mut pipe, &StreamNames::single("data"), &vs, None, &c, None).unwrap();
        let b = batch.run_stream(&vs, None, &c).unwrap();
        eprint!("{p}{b}");
        assert!(p.passed() && b.passed(), "{p}\n{b}");
        assert_eq!(b.engine, BATCH_ENGINE_NAME);
        assert_eq!(
            (b.inputs_sent, b.outputs_received, b.matched),
            (p.inputs_sent, p.outputs_received, p.matched)
        );
        assert_eq!(b.accounting, p.accounting);
        assert_eq!(b.matched, count as u64);
        if stall == 0.0 {
            // No randomness left: the same cycle sequence as the pipe bench.
            assert_eq!(b.cycles, p.cycles);
        } else {
            // Same stall law: cycle counts within 15 % of each other.
            let ratio = b.cycles as f64 / p.cycles as f64;
            assert!(
                (0.85..1.15).contains(&ratio),
                "{} vs {}",
                b.cycles,
                p.cycles
            );
        }
    }
}

#[test]
fn a_wrong_expected_bit_is_the_same_decoded_mismatch_as_in_a_pipe_run() {
    if !icarus_present() {
        return;
    }
    let design = stage("skid", fixture("skid.v"), 16);
    let mut vs = skid_vectors(11, 200);
    vs[77].outputs[0][0].flip_bit(3).unwrap();
    let c = config(11, 0.4);
    let mut pipe = IcarusEngine::new(&design).unwrap();
    let p = run_stream_bench(&mut pipe, &StreamNames::single("data"), &vs, None, &c, None).unwrap();
    let batch =
        IcarusBatch::new(&design, &BatchSpec::single(&StreamNames::single("data"))).unwrap();
    let b = batch.run_stream(&vs, None, &c).unwrap();
    eprint!("{b}");
    assert!(!b.passed());
    assert_eq!(b.mismatches, 1, "the run goes on after the mismatch");
    assert_eq!(b.matched, 199);
    let (pm, bm) = (p.first_mismatch.unwrap(), b.first_mismatch.unwrap());
    assert_eq!((bm.output_index, bm.input_id), (pm.output_index, 77));
    assert_eq!(bm.fields, pm.fields);
    assert!(bm.fields[0].differs());
}

#[test]
fn a_broken_design_fails_with_a_vcd_around_the_mismatch() {
    if !icarus_present() {
        return;
    }
    let design = stage("skid", fixture("skid_broken.v"), 16);
    let batch =
        IcarusBatch::new(&design, &BatchSpec::single(&StreamNames::single("data"))).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let vcd = dir.path().join("fail.vcd");
    let c = BenchConfig {
        vcd_path: Some(vcd.clone()),
        ..config(2, 0.3)
    };
    let vs = skid_vectors(2, 2000);
    let lanes: Vec<LaneVector> = vs.iter().map(|v| LaneVector::new(0, v.clone())).collect();
    let r = batch.run(&lanes, &mut |_| None, &c).unwrap();
    eprint!("{}", r.bench);
    assert!(!r.bench.passed());
    let m = r.bench.first_mismatch.as_ref().unwrap();
    assert_eq!(r.bench.vcd.as_deref(), Some(vcd.as_path()));
    let text = std::fs::read_to_string(&vcd).unwrap();
    assert!(text.contains("$enddefinitions"), "a VCD");
    // The window starts at most vcd_radius cycles (2 time units each) before the failure.
    let first_time: u64 = text
        .lines()
        .find_map(|l| l.strip_prefix('#'))
        .and_then(|t| t.parse().ok())
        .unwrap();
    assert!(
        first_time / 2 + c.vcd_radius + 2 >= m.cycle,
        "{first_time} {}",
        m.cycle
    );
}

#[test]
fn a_stuck_stage_is_a_hang_with_every_port() {
    if !icarus_present() {
        return;
    }
    let design = stage("stuck", fixture("stuck.v"), 8);
    let batch =
        IcarusBatch::new(&design, &BatchSpec::single(&StreamNames::single("data"))).unwrap();
    let vs = vec![Vector {
        input: vec![Bits::from_u64(5, 8).unwrap()],
        outputs: vec![vec![Bits::from_u64(5, 8).unwrap()]],
    }];
    let c = BenchConfig {
        watchdog_cycles: 50,
        ..config(1, 0.0)
    };
    let r = batch.run_stream(&vs, None, &c).unwrap();
    let h = r.hang.as_ref().expect("a hang");
    assert_eq!(h.idle_cycles, 51);
    assert_eq!(h.ports.len(), design.ports.len());
    assert!(h.ports.iter().any(|(n, v)| n == "in_ready" && v == "1'h0"));
    assert_eq!(r.inputs_sent, 0);
    assert!(!r.passed());
}

#[test]
fn an_x_on_an_output_after_reset_is_an_error_naming_the_port() {
    if !icarus_present() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("xstage.v");
    // Registered pass-through whose data turns X for the payload 0x5a.
    std::fs::write(
        &file,
        "module xstage (input wire clk, input wire rst, input wire in_valid, output wire in_ready,
    input wire [7:0] in_data, output reg out_valid, input wire out_ready, output wire [7:0] out_data);
    reg [7:0] r;
    assign in_ready = !out_valid || out_ready;
    assign out_data = (r == 8'h5a) ? 8'bx : r;
    always @(posedge clk) begin
        if (rst) begin out_valid <= 1'b0; r <= 8'd0; end
        else if (in_ready) begin out_valid <= in_valid; if (in_valid) r <= in_data; end
    end
endmodule
",
    )
    .unwrap();
    let design = stage("xstage", file, 8);
    let batch =
        IcarusBatch::new(&design, &BatchSpec::single(&StreamNames::single("data"))).unwrap();
    let vs: Vec<Vector> = [1u64, 2, 0x5a, 4]
        .iter()
        .map(|&x| Vector {
            input: vec![Bits::from_u64(x, 8).unwrap()],
            outputs: vec![vec![Bits::from_u64(x, 8).unwrap()]],
        })
        .collect();
    match batch.run_stream(&vs, None, &config(1, 0.0)) {
        Err(CosimError::UnknownOutput { port, value, .. }) => {
            assert_eq!(port, "out_data");
            assert_eq!(value.to_lowercase(), "xx");
        }
        other => panic!("expected UnknownOutput, got {other:?}"),
    }
    // Without the X payload the same stage passes.
    let ok: Vec<Vector> = vs
        .iter()
        .filter(|v| v.input[0].to_u64() != Some(0x5a))
        .cloned()
        .collect();
    assert!(batch
        .run_stream(&ok, None, &config(1, 0.2))
        .unwrap()
        .passed());
}

/// Two skid stages side by side as two lanes; a beat that waits for the
/// earlier outputs is only offered once they have all arrived, so the
/// other lane is empty when it goes in.
#[test]
fn two_lanes_keep_their_order_and_a_wait_holds_the_beat_back() {
    if !icarus_present() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("two.v");
    std::fs::write(
        &file,
        "module two (input wire clk, input wire rst,
    input wire a_in_valid, output wire a_in_ready, input wire [15:0] a_in_data,
    output wire a_out_valid, input wire a_out_ready, output wire [15:0] a_out_data,
    input wire b_in_valid, output wire b_in_ready, input wire [15:0] b_in_data,
    output wire b_out_valid, input wire b_out_ready, output wire [15:0] b_out_data,
    output wire both_busy);
    skid a (.clk(clk), .rst(rst), .in_valid(a_in_valid), .in_ready(a_in_ready), .in_data(a_in_data),
        .out_valid(a_out_valid), .out_ready(a_out_ready), .out_data(a_out_data));
    skid b (.clk(clk), .rst(rst), .in_valid(b_in_valid), .in_ready(b_in_ready), .in_data(b_in_data),
        .out_valid(b_out_valid), .out_ready(b_out_ready), .out_data(b_out_data));
    assign both_busy = a_out_valid && b_out_valid;
endmodule
",
    )
    .unwrap();
    let mut ports = vec![PortSpec::input("clk", 1), PortSpec::input("rst", 1)];
    for s in ["a", "b"] {
        ports.extend([
            PortSpec::input(&format!("{s}_in_valid"), 1),
            PortSpec::output(&format!("{s}_in_ready"), 1),
            PortSpec::input(&format!("{s}_in_data"), 16),
            PortSpec::output(&format!("{s}_out_valid"), 1),
            PortSpec::input(&format!("{s}_out_ready"), 1),
            PortSpec::output(&format!("{s}_out_data"), 16),
        ]);
    }
    ports.push(PortSpec::output("both_busy", 1));
    let design = Design::new(
        "two",
        vec![file, fixture("skid.v")],
        ports,
        Some("clk"),
        Some("rst"),
    )
    .unwrap();
    let lane = |s: &str| StreamNames {
        in_valid: format!("{s}_in_valid"),
        in_ready: format!("{s}_in_ready"),
        in_payload: vec![format!("{s}_in_data")],
        out_valid: format!("{s}_out_valid"),
        out_ready: format!("{s}_out_ready"),
        out_payload: vec![format!("{s}_out_data")],
    };
    let spec = BatchSpec {
        lanes: vec![lane("a"), lane("b")],
        watch: vec!["both_busy".into()],
        constants: Vec::new(),
    };
    let batch = IcarusBatch::new(&design, &spec).unwrap();
    // Runs of 1..=20 beats alternating between the lanes; each run waits.
    let mut rng = Prng::new(9);
    let mut vs = Vec::new();
    for run in 0..60 {
        let len = 1 + rng.below(20) as usize;
        for (k, v) in skid_vectors(run, len).into_iter().enumerate() {
            vs.push(LaneVector {
                lane: (run % 2) as usize,
                wait_for_earlier_outputs: k == 0,
                vector: v,
            });
        }
    }
    let r = batch.run(&vs, &mut |_| None, &config(6, 0.4)).unwrap();
    eprint!("{}", r.bench);
    assert!(r.bench.passed(), "{}", r.bench);
    assert_eq!(r.bench.matched, vs.len() as u64);
    // Never both lanes holding an output: the waits kept the runs apart.
    assert_eq!(r.watch.ports, vec!["both_busy".to_string()]);
    assert!(!r.watch.changes.is_empty());
    let mut busy_cycles = 0;
    r.watch
        .for_each_cycle(r.bench.cycles, |_, v| busy_cycles += v[0].bit(0) as u32);
    assert_eq!(busy_cycles, 0);
    // Without the waits the lanes overlap and both hold outputs at times.
    let free: Vec<LaneVector> = vs
        .iter()
        .cloned()
        .map(|mut v| {
            v.wait_for_earlier_outputs = false;
            v
        })
        .collect();
    let r = batch.run(&free, &mut |_| None, &config(6, 0.4)).unwrap();
    assert!(r.bench.passed(), "{}", r.bench);
    let mut busy_cycles = 0;
    r.watch
        .for_each_cycle(r.bench.cycles, |_, v| busy_cycles += v[0].bit(0) as u32);
    assert!(busy_cycles > 0);
}

/// Beats spread over three stimulus chunk files arrive whole and in order.
#[test]
fn beats_across_stimulus_chunks_arrive_in_order() {
    if !icarus_present() {
        return;
    }
    let design = stage("skid", fixture("skid.v"), 16);
    let batch =
        IcarusBatch::new(&design, &BatchSpec::single(&StreamNames::single("data"))).unwrap();
    let count = 2 * super::batch_testbench::STIM_CHUNK + 5;
    let vs = skid_vectors(21, count);
    let r = batch.run_stream(&vs, None, &config(21, 0.1)).unwrap();
    assert!(r.passed(), "{r}");
    assert_eq!((r.inputs_sent, r.matched), (count as u64, count as u64));
}
