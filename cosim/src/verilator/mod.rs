//! The Verilator engine: build, cache, shim, load, step.

pub mod build;
pub mod engine;
pub mod header;
pub mod shim;

pub use build::{build_model, VerilatorOptions};
pub use engine::{BuildInfo, VerilatorEngine};
