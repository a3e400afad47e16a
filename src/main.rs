//! The hiermerge command-line program.
//!
//! Every subcommand builds one report (a `serde::Serialize` value); `--json`
//! prints it as one JSON object on stdout, otherwise it is printed for people.
//! Errors go to stderr with a non-zero exit status, never a panic.

mod cmd;
mod progress;
mod report;
mod signals;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "hiermerge",
    version,
    about = "Hierarchy merging and voxel-granular translation for ray-tracing acceleration hierarchies (US 12,386,806)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Build one hierarchy per mesh and report nodes per LOD, leaves, depth and build speed.
    Build(cmd::build::Args),
    /// Trace random rays through a mesh's hierarchy; --verify compares with brute force.
    Trace(cmd::trace::Args),
    /// Build a hierarchy per mesh, place each by its translation, merge, check and compare tracing.
    Merge(cmd::merge::Args),
    /// Emit the Verilog of a unit's configuration, or of every default configuration.
    Gen(cmd::gen::Args),
    /// Write a unit's test vectors (JSON Lines) for the RTL.
    Vectors(cmd::vectors::Args),
    /// Write a portable self-checking testbench of a unit: Verilog-2005,
    /// $readmemh vectors from golden, a run script for Icarus and Verilator.
    ExportTb(cmd::export_tb::Args),
    /// The main job: build, (merge,) and trace a scene; with no argument, the embedded default scene.
    Run(cmd::run::Args),
    /// Co-simulate a unit (translate; merge-module: the merging module, --stage merge-level its S614 stage; merger: the hierarchy merger top) against golden, cycle by cycle.
    Cosim(cmd::cosim::Args),
    /// The coverage regression: every unit on Verilator with line/branch and toggle coverage; code coverage per unit and functional-coverage bins; fails on an unhit bin or a point below the aims without a waiver.
    Coverage(cmd::coverage::Args),
    /// Show what accuracy costs in time: sweep Q, D, translation level, number format and merging mode; table, JSON, CSV, plots, study.md.
    Study(cmd::study::Args),
    /// Check the long-run ledger (cosim --ledger) against today's code and sum what it proves.
    Ledger(cmd::ledger::Args),
    /// Area and timing of a unit's modules: generic gates, ECP5 and iCE40 place and route, the critical path by generator line.
    Synth(cmd::synth::Args),
    /// How the emitted Verilog reads: per file and in total its size, declarations, the share of auto-named ones and (--yosys) Yosys cell counts, beside --before DIR.
    VerilogStats(cmd::verilog_stats::Args),
    /// Formal proofs (SymbiYosys) of the stream primitives and the small units: handshakes, beat flow, determined outputs, idle/done.
    Formal(cmd::formal::Args),
}

fn main() {
    // Printing into a closed pipe (`hiermerge ... | head`) ends the program
    // quietly, as for any Unix tool, instead of a panic on a failed write.
    // SAFETY: restoring a signal's default disposition before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    // A value may be negative (`--seed -1` is then refused as no u64, by
    // its flag, not taken for an unknown flag `-1`).
    let mut command = Cli::command().mut_subcommands(|s| s.allow_negative_numbers(true));
    let cli = Cli::from_arg_matches(&command.clone().get_matches())
        .unwrap_or_else(|e| e.format(&mut command).exit());
    signals::install();
    let result = match cli.command {
        Command::Build(a) => cmd::build::main(a),
        Command::Trace(a) => cmd::trace::main(a),
        Command::Merge(a) => cmd::merge::main(a),
        Command::Gen(a) => cmd::gen::main(a),
        Command::Run(a) => cmd::run::main(a),
        Command::Vectors(a) => cmd::vectors::main(a),
        Command::ExportTb(a) => cmd::export_tb::main(a),
        Command::Cosim(a) => cmd::cosim::main(a),
        Command::Coverage(a) => cmd::coverage::main(a),
        Command::Ledger(a) => cmd::ledger::main(a),
        Command::Study(a) => cmd::study::main(a),
        Command::Synth(a) => cmd::synth::main(a),
        Command::Formal(a) => cmd::formal::main(a),
        Command::VerilogStats(a) => cmd::verilog_stats::main(a),
    };
    if let Err(e) = result {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
