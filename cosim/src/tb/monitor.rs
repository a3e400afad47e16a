//! Stream monitor: applies seeded back-pressure of a stall pattern
//! ([`Stalls`]) on a valid/ready output and collects the transactions that
//! leave the design.

use super::driver::{bool_bits, check_stalls, stream_bin};
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
    /// Cycles `ready` was high with nothing valid (the design's output
    /// empty), and the functional-coverage bin they count in.
    empty: (u64, Option<String>),
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
            empty: (0, None),
        })
    }

    /// Transactions collected so far.
    pub fn received(&self) -> u64 {
        self.received
    }

    /// Drive `ready` for this cycle (call before `eval`).
    pub fn drive<E: Engine + ?Sized>(&mut self, engine: &mut E) -> Result<()> {
        if self.empty.1.is_none() {
            self.empty.1 = Some(stream_bin(&*engine, self.ports.valid, "empty")?);
        }
        self.ready = self.stalls.go(&mut self.rng);
        engine.poke(self.ports.ready, &bool_bits(self.ready))
    }

    /// After `eval`: the transaction leaving the design this cycle, if any.
    pub fn observe<E: Engine + ?Sized>(&mut self, engine: &E) -> Result<Option<Transaction>> {
        if !self.ready {
            return Ok(None);
        }
        if !engine.peek_bool(self.ports.valid)? {
            self.empty.0 += 1;
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

impl Drop for StreamMonitor {
    fn drop(&mut self) {
        // Counted when seen; required only where a runner declares it.
        if let (Some(bin), n @ 1..) = (&self.empty.1, self.empty.0) {
            crate::fcov::hit(bin, n);
        }
    }
}
