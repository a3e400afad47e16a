//! Stream monitor: applies seeded random back-pressure on a valid/ready
//! output and collects the transactions that leave the design.

use super::driver::{bool_bits, check_stall};
use super::prng::Prng;
use super::stream::{StreamPorts, Transaction};
use crate::engine::Engine;
use crate::error::Result;

/// Watches one output stream of a design.
pub struct StreamMonitor {
    ports: StreamPorts,
    rng: Prng,
    stall: f64,
    ready: bool,
    received: u64,
}

impl StreamMonitor {
    /// A monitor that holds `ready` low with probability `stall` (0..=0.9) each cycle.
    pub fn new(ports: StreamPorts, seed: u64, stall: f64) -> Result<StreamMonitor> {
        check_stall(stall)?;
        Ok(StreamMonitor {
            ports,
            rng: Prng::derived(seed, 2),
            stall,
            ready: false,
            received: 0,
        })
    }

    /// Transactions collected so far.
    pub fn received(&self) -> u64 {
        self.received
    }

    /// Drive `ready` for this cycle (call before `eval`).
    pub fn drive<E: Engine + ?Sized>(&mut self, engine: &mut E) -> Result<()> {
        self.ready = !self.rng.chance(self.stall);
        engine.poke(self.ports.ready, &bool_bits(self.ready))
    }

    /// After `eval`: the transaction leaving the design this cycle, if any.
    pub fn observe<E: Engine + ?Sized>(&mut self, engine: &E) -> Result<Option<Transaction>> {
        if !(self.ready && engine.peek_bool(self.ports.valid)?) {
            return Ok(None);
        }
        self.received += 1;
        let txn = self
            .ports
            .payload
            .iter()
            .map(|&p| engine.peek(p))
            .collect::<Result<Transaction>>()?;
        Ok(Some(txn))
    }

    /// Names of the payload ports (for decoding).
    pub fn payload_names(&self) -> &[String] {
        &self.ports.payload_names
    }
}
