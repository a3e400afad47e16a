//! Stream monitor: applies seeded back-pressure of a stall pattern
//! ([`Stalls`]) on a valid/ready output and collects the transactions that
//! leave the design.

use super::driver::{bool_bits, check_stalls};
use super::prng::Prng;
use super::stalls::{StallGen, Stalls};
use super::stream::{StreamPorts, Transaction};
use crate::engine::Engine;
use crate::error::Result;

/// Watches one output stream of a design.
pub struct StreamMonitor {
    ports: StreamPorts,
    rng: Prng,
    stalls: StallGen,
    ready: bool,
    received: u64,
}

impl StreamMonitor {
    /// A monitor that holds `ready` low when `stalls` says so, one decision
    /// each cycle.
    pub fn new(ports: StreamPorts, seed: u64, stalls: Stalls) -> Result<StreamMonitor> {
        check_stalls(&stalls)?;
        Ok(StreamMonitor {
            ports,
            rng: Prng::derived(seed, 2),
            stalls: StallGen::new(stalls),
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
        self.ready = self.stalls.go(&mut self.rng);
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
