//! One module per subcommand.

pub mod build;
pub mod common;
pub mod cosim;
pub mod coverage;
pub mod export_tb;
pub mod formal;
pub mod gen;
pub mod ledger;
pub mod merge;
pub mod merge_args;
pub mod run;
pub mod study;
pub mod synth;
pub mod trace;
pub mod vectors;
pub mod verilog_stats;
