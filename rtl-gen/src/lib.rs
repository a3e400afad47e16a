//! rtl-gen: a Rust embedded DSL for synthesizable RTL.
//!
//! Build a [`Module`] with ports, wires, registers, memories and instances;
//! combine [`Signal`]s with explicitly sized operators; check it with
//! [`Module::validate`]; emit Verilog-2005 with [`emit_verilog`] /
//! [`write_design`]; simulate it cycle by cycle with [`Sim`].
//!
//! ```
//! use rtl_gen::{emit_verilog, Module, Sim};
//! let m = Module::new("acc");
//! let x = m.input("x", 8);
//! let en = m.input("en", 1);
//! let acc = m.reg("acc", 12);
//! acc.next_when(en, acc.add(x, 12));
//! m.output("sum", acc);
//! let verilog = emit_verilog(&m).unwrap();
//! assert!(verilog.contains("module acc ("));
//! let mut sim = Sim::new(&m).unwrap();
//! sim.poke("x", 5u64).unwrap();
//! sim.poke("en", 1u64).unwrap();
//! sim.step_n(3);
//! assert_eq!(sim.peek("sum").unwrap().to_u64(), Some(15));
//! ```
//!
//! See the crate's README.md for the semantics and the emitted-Verilog conventions.

#![warn(missing_docs)]

mod diagnostic;
mod drop_fifo;
pub mod examples;
mod first_of;
pub mod formal;
mod graph;
pub mod identity;
mod instance;
mod memory;
pub mod merge;
mod module;
mod names;
pub mod optest;
mod scope;
mod signal;
pub mod sim;
mod states;
pub mod stream;
pub mod translate;
mod validate;
pub mod verilog;
mod view;

/// The DSL's value type (constants, reset values, the simulator's values) is
/// golden's bit vector, so a packed record crosses crates without a copy.
pub use golden::bits::{Bits, BitsError};

/// The widest signal the DSL accepts (16 Mi bits): wider is a width error,
/// so a typo cannot allocate gigabytes.
pub const MAX_WIDTH: u32 = 1 << 24;
pub use diagnostic::{DiagKind, Diagnostic, Diagnostics, Loc, Severity};
pub use drop_fifo::DropFifo;
pub use graph::{CmpOp, Direction, CLOCK, RESET};
pub use instance::Instance;
pub use memory::Memory;
pub use module::{Module, PortInfo};
pub use names::{is_auto_name, AUTO_NAME_WORDS};
pub use scope::Scope;
pub use signal::{IntoSignal, ShiftAmount, ShiftBy, Signal};
pub use sim::{Sim, SimError};
pub use states::States;
pub use stream::{SkidBuffer, Stream};
pub use verilog::{emit_design, emit_verilog, write_design, DesignError};

/// The README's code examples, compiled and run as doctests.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;
