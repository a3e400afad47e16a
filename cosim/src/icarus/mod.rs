//! The Icarus Verilog engine: generated testbench, pipe protocol, X/Z checks.

pub mod engine;
pub mod testbench;

pub use engine::IcarusEngine;
