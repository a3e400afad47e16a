//! Co-simulation harness (issue 6): engines that step a Verilog design cycle by
//! cycle from Rust behind one `Engine` trait (Verilator through a generated C
//! ABI shim and a content-addressed build cache; Icarus Verilog through a
//! piped testbench, 4-state, or a whole bench in one `vvp` run; rtl-gen's IR
//! simulator), reusable testbench pieces generic over it, the units' complete
//! benches (`units`) and the long-run ledger (`ledger`).
//! See `cosim/README.md`.

#![warn(missing_docs)]

pub mod cache;
pub mod coverage;
pub mod design;
pub mod engine;
pub mod engines;
pub mod error;
pub mod export_tb;
pub mod fcov;
pub mod formal;
pub mod from_rtl;
pub mod icarus;
pub mod ir_engine;
pub mod ledger;
pub mod synth;
pub mod tb;
pub mod tools;
pub mod units;
pub mod verilator;
pub mod volume;
pub mod waves;

pub use design::{Design, PortDir, PortId, PortSpec, Reset};
pub use engine::Engine;
pub use engines::{open_engine, open_tracing_engine, EngineKind};
pub use error::{CosimError, Result};
/// Port values are golden's bit vector, the same type the golden model packs
/// and the DSL simulates.
pub use golden::bits::{Bits, BitsError};
