//! The Icarus Verilog engine: generated testbench, pipe protocol, X/Z checks;
//! and the batch mode, a whole stream bench inside one `vvp` run.

pub mod batch;
pub mod batch_runner;
pub mod batch_tb_frame;
pub mod batch_testbench;
#[cfg(test)]
mod batch_tests;
pub mod engine;
pub mod multi_batch;
pub mod multi_batch_testbench;
pub mod testbench;

pub use batch::{BatchReport, BatchSpec, IcarusBatch, LaneVector, WatchLog};
pub use engine::IcarusEngine;
pub use multi_batch::{IcarusMultiBatch, MultiBatchReport};
