//! The interface every simulator presents to the testbench.
//!
//! Cycle model, identical for all engines: inputs poked between edges are
//! sampled at the next rising clock edge; `eval` settles combinational logic
//! (outputs are only refreshed by `eval` or `step`); `step` is one full clock
//! period (clock low, settle, clock high, settle) and advances `cycle` by one.

use crate::design::{Design, PortId};
use crate::error::{CosimError, Result};
use golden::bits::Bits;
use std::path::Path;

/// A simulator instance of one design, stepped cycle by cycle.
pub trait Engine {
    /// Short engine name for reports: "verilator", "iverilog", ...
    fn name(&self) -> &'static str;

    /// The design this engine simulates.
    fn design(&self) -> &Design;

    /// Drive input `port` with `value` (exactly the port's width).
    fn poke(&mut self, port: PortId, value: &Bits) -> Result<()>;

    /// The value of `port` as of the last `eval` or `step` (inputs: last poke).
    fn peek(&self, port: PortId) -> Result<Bits>;

    /// Settle combinational logic after pokes, without a clock edge.
    fn eval(&mut self) -> Result<()>;

    /// One rising clock edge, then settle; `cycle` advances by one.
    fn step(&mut self) -> Result<()>;

    /// Rising edges taken since the engine was created.
    fn cycle(&self) -> u64;

    /// Start writing a VCD of every signal to `path` (may be called once per run
    /// for Icarus; Verilator needs a trace build).
    fn trace_start(&mut self, path: &Path) -> Result<()>;

    /// Stop tracing and flush the VCD file.
    fn trace_stop(&mut self) -> Result<()>;

    /// Called once reset has been released; 4-state engines start checking
    /// outputs for X/Z from here on.
    fn reset_released(&mut self) {}

    /// Id of the port called `name`.
    fn port_id(&self, name: &str) -> Result<PortId> {
        self.design().port_id(name)
    }

    /// Poke a value given as u64, sized to the port (error if it does not fit).
    fn poke_u64(&mut self, port: PortId, value: u64) -> Result<()> {
        let width = self.design().port(port)?.width;
        let v = Bits::from_u64(value, width).map_err(|_| CosimError::Width {
            port: self
                .design()
                .port(port)
                .map(|p| p.name.clone())
                .unwrap_or_default(),
            width,
            value_bits: 64 - value.leading_zeros(),
        })?;
        self.poke(port, &v)
    }

    /// Peek a port of at most 64 significant bits.
    fn peek_u64(&self, port: PortId) -> Result<u64> {
        let v = self.peek(port)?;
        v.to_u64().ok_or_else(|| CosimError::Width {
            port: self
                .design()
                .port(port)
                .map(|p| p.name.clone())
                .unwrap_or_default(),
            width: 64,
            value_bits: v.width(),
        })
    }

    /// Peek a 1-bit port as a bool.
    fn peek_bool(&self, port: PortId) -> Result<bool> {
        Ok(self.peek(port)?.bit(0))
    }

    /// Hold the design's reset for `cycles` rising edges, release it and settle.
    /// Designs without a reset just settle.
    fn reset(&mut self, cycles: u32) -> Result<()> {
        let Some(reset) = self.design().reset.clone() else {
            self.reset_released();
            return self.eval();
        };
        let id = self.port_id(&reset.port)?;
        let active = u64::from(!reset.active_low);
        self.poke_u64(id, active)?;
        for _ in 0..cycles {
            self.step()?;
        }
        self.poke_u64(id, 1 - active)?;
        self.reset_released();
        self.eval()
    }
}
