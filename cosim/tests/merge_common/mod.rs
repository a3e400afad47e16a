//! Shared pieces of the merging-module RTL tests (`merge_*.rs`): engine
//! selection (`cosim::ir_engine::IrEngine`, Verilator, Icarus) for a design
//! from `cosim::from_rtl`, tool checks, lint/synthesis, and the bench loop.
#![allow(dead_code)]

use std::path::Path;

use cosim::ir_engine::IrEngine;
use cosim::tb::{run_stream_bench, BenchConfig, BenchReport, StreamNames, Vector};
use cosim::tools::{ci_mode, tool_available, INSTALL_HINT};
use cosim::units::{run_vectors, StreamSim};
use cosim::{Design, Engine, PortDir};
use rtl_gen::Module;

mod multi;
#[allow(unused_imports)] // not every test uses the multi-stream runs
pub use multi::*;

/// True when Verilator, Icarus and Yosys can run. Under CI=true a missing
/// tool panics (a failure, never a skip); locally it prints how to install.
pub fn tools_present(tools: &[&str]) -> bool {
    let missing: Vec<&str> = tools
        .iter()
        .copied()
        .filter(|t| !tool_available(t))
        .collect();
    if missing.is_empty() {
        return true;
    }
    if ci_mode() {
        panic!("CI=true and {missing:?} missing: {INSTALL_HINT}");
    }
    eprintln!("SKIPPING: {missing:?} not installed; {INSTALL_HINT} (or apt-get install yosys)");
    false
}

/// The cosim description of `m`, its Verilog written into `dir`.
pub fn design_of(m: &Module, dir: &Path) -> Design {
    cosim::from_rtl::design_from_module(m, dir).expect("the design validates and is written")
}

/// An engine of kind `ir`, `verilator` or `iverilog` for `m` / `design`.
pub fn engine(kind: &str, m: &Module, design: &Design) -> Box<dyn Engine> {
    match kind {
        "ir" => Box::new(IrEngine::new(m, design).expect("the design validates")),
        "verilator" => Box::new(
            cosim::verilator::VerilatorEngine::new(
                design,
                &cosim::verilator::VerilatorOptions::default(),
            )
            .expect("verilator build"),
        ),
        "iverilog" => Box::new(cosim::icarus::IcarusEngine::new(design).expect("iverilog build")),
        other => panic!("unknown engine {other}"),
    }
}

/// One bench run, printed; panics with the report when it fails.
pub fn run(
    engine: &mut dyn Engine,
    vectors: &[Vector],
    seed: u64,
    stall: f64,
    what: &str,
) -> BenchReport {
    let config = BenchConfig {
        seed,
        in_stall: cosim::tb::Stalls::Coin(stall),
        out_stall: cosim::tb::Stalls::Coin(stall),
        reproduce: Some(format!("cargo test -p cosim --test {what}")),
        ..BenchConfig::default()
    };
    let report = run_stream_bench(
        engine,
        &StreamNames::single("data"),
        vectors,
        None,
        &config,
        None,
    )
    .expect("the bench runs");
    eprint!("{what}: stall {stall:.2}: {report}");
    assert!(report.passed(), "{what} stall {stall}:\n{report}");
    report
}

/// `verilator --lint-only -Wall` with zero warnings on the Verilog of `design`.
pub fn lint_only(design: &Design) {
    let files = verilog_files(design);
    let out = std::process::Command::new("verilator")
        .args(["--lint-only", "-Wall", "--top-module", &design.top])
        .args(&files)
        .output()
        .expect("verilator runs");
    let text =
        String::from_utf8_lossy(&out.stderr).to_string() + &String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && text.trim().is_empty(),
        "verilator lint of {}:\n{text}",
        design.top
    );
}

fn verilog_files(design: &Design) -> Vec<String> {
    design
        .verilog_files
        .iter()
        .map(|f| f.display().to_string())
        .collect()
}

/// [`lint_only`], then Yosys `synth` to its coarse netlist (`-run
/// begin:fine`: elaboration, processes, memories; where a latch would be
/// inferred) with `check -assert` and no latch, on the Verilog files of
/// `design`. The fine step (gate mapping, ABC) is `hiermerge synth`'s.
pub fn lint_and_synth(design: &Design) {
    lint_only(design);
    let files = verilog_files(design);
    let script = format!(
        "read_verilog {}; synth -top {} -run begin:fine; check -assert; select -assert-none t:$dlatch t:$adlatch t:$dlatchsr t:$_DLATCH_* t:$sr t:$_SR_*",
        files.join(" "),
        design.top
    );
    let out = std::process::Command::new("yosys")
        .args(["-q", "-p", &script])
        .output()
        .expect("yosys runs");
    assert!(
        out.status.success(),
        "yosys synth of {}:\n{}{}",
        design.top,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A uniform stall probability in `0..=0.5` from `seed`.
pub fn stall_of(seed: u64) -> f64 {
    (golden::translate::stimulus::SplitMix64(seed).next_u64() % 51) as f64 / 100.0
}

pub fn is_output(d: &Design, name: &str) -> bool {
    d.ports
        .iter()
        .any(|p| p.name == name && p.dir == PortDir::Output)
}

/// The length of the longest prefix of a vector list that ends at one of
/// `ends` (indices just past a level's `End` beat) and is at most `max`
/// long (at least the first level): a run must not stop inside a level,
/// whose last outputs wait for its `End`.
pub fn level_prefix(ends: &[usize], max: usize) -> usize {
    ends.iter()
        .copied()
        .filter(|&e| e <= max)
        .max()
        .unwrap_or_else(|| ends.first().copied().unwrap_or(0))
}

/// The Icarus batch simulator (`cosim::icarus::IcarusBatch`, 4-state, the
/// whole bench inside one `vvp` run) of `design` for the `in` -> `out`
/// stream; built once, used for every Icarus run of a configuration.
pub fn icarus_batch(design: &Design) -> cosim::icarus::IcarusBatch {
    cosim::icarus::IcarusBatch::new(
        design,
        &cosim::icarus::BatchSpec::single(&StreamNames::single("data")),
    )
    .expect("iverilog batch build")
}

/// Where a bench run goes: an engine stepped from Rust, or the Icarus batch mode.
pub enum Sim<'a> {
    /// rtl-gen's IR simulator, Verilator or the Icarus pipe engine.
    Stepped(Box<dyn Engine>),
    /// The Icarus batch simulator.
    Batch(&'a cosim::icarus::IcarusBatch),
}

/// One bench run of `transactions` transactions on `sim`, with the line
/// `what: engine, transactions, beats, cycles, wall seconds, cycles/s`
/// printed; panics with the report when it fails.
pub fn run_sim(
    sim: Sim,
    vectors: &[Vector],
    transactions: usize,
    seed: u64,
    stall: f64,
    what: &str,
) -> BenchReport {
    let config = BenchConfig {
        seed,
        in_stall: cosim::tb::Stalls::Coin(stall),
        out_stall: cosim::tb::Stalls::Coin(stall),
        reproduce: Some(format!("cargo test -p cosim --release --test {what}")),
        ..BenchConfig::default()
    };
    let report = match sim {
        Sim::Stepped(mut e) => run_vectors(StreamSim::Stepped(e.as_mut()), vectors, &config),
        Sim::Batch(b) => run_vectors(StreamSim::Batch(b), vectors, &config),
    }
    .unwrap_or_else(|e| panic!("{what}: {e}"));
    println!(
        "{what}: {} stall {stall:.2}: {transactions} transactions, {} beats, {} cycles, {:.2} s wall, {:.0} cycles/s",
        report.engine,
        report.inputs_sent,
        report.cycles,
        report.wall.as_secs_f64(),
        report.cycles as f64 / report.wall.as_secs_f64().max(1e-9)
    );
    assert!(report.passed(), "{what} stall {stall}:\n{report}");
    report
}
