//! Stream driver: feeds queued transactions into a valid/ready input with
//! seeded gaps of a stall pattern ([`Stalls`]).
//!
//! Protocol kept: once `valid` is raised its payload is held until the design
//! accepts it (`valid && ready` at a rising edge); gaps are only inserted
//! between transactions. While `valid` is low the payload carries random
//! garbage so a design that samples data without `valid` is caught.

use super::prng::Prng;
use super::stalls::{StallGen, Stalls};
use super::stream::{StreamPorts, Transaction};
use crate::design::PortId;
use crate::engine::Engine;
use crate::error::{CosimError, Result};
use golden::bits::Bits;
use std::collections::VecDeque;

/// Drives one input stream of a design.
pub struct StreamDriver {
    ports: StreamPorts,
    queue: VecDeque<Transaction>,
    rng: Prng,
    stalls: StallGen,
    presenting: bool,
    sent: u64,
    /// Cycles the design held `ready` low on a presented beat (its input
    /// buffer full), and the functional-coverage bin they count in.
    full: (u64, Option<String>),
}

impl StreamDriver {
    /// A driver that leaves `valid` low when `stalls` says so, one decision
    /// each cycle it could present a new transaction.
    pub fn new(ports: StreamPorts, seed: u64, stalls: Stalls) -> Result<StreamDriver> {
        check_stalls(&stalls)?;
        Ok(StreamDriver {
            ports,
            queue: VecDeque::new(),
            rng: Prng::derived(seed, 1),
            stalls: StallGen::new(stalls),
            presenting: false,
            sent: 0,
            full: (0, None),
        })
    }

    /// Queue a transaction.
    pub fn push(&mut self, txn: Transaction) {
        self.queue.push_back(txn);
    }

    /// Transactions accepted by the design so far.
    pub fn sent(&self) -> u64 {
        self.sent
    }

    /// Transactions still queued (including one being presented).
    pub fn pending(&self) -> usize {
        self.queue.len()
    }

    /// Drive `valid` and the payload for this cycle (call before `eval`).
    pub fn drive<E: Engine + ?Sized>(&mut self, engine: &mut E) -> Result<()> {
        if self.full.1.is_none() {
            self.full.1 = Some(stream_bin(&*engine, self.ports.valid, "full")?);
        }
        if !self.presenting && !self.queue.is_empty() && self.stalls.go(&mut self.rng) {
            self.presenting = true;
        }
        engine.poke(self.ports.valid, &bool_bits(self.presenting))?;
        for (k, &port) in self.ports.payload.iter().enumerate() {
            let value = match (self.presenting, self.queue.front()) {
                (true, Some(txn)) => txn.get(k).cloned().ok_or_else(|| CosimError::Design {
                    what: format!(
                        "transaction has {} fields, stream has {} payload ports",
                        txn.len(),
                        self.ports.payload.len()
                    ),
                })?,
                _ => self.rng.bits(engine.design().port(port)?.width),
            };
            engine.poke(port, &value)?;
        }
        Ok(())
    }

    /// After `eval`: if the design accepts this cycle, the transaction leaves
    /// the queue and is returned.
    pub fn observe<E: Engine + ?Sized>(&mut self, engine: &E) -> Result<Option<Transaction>> {
        if self.presenting {
            if engine.peek_bool(self.ports.ready)? {
                self.presenting = false;
                self.sent += 1;
                return Ok(self.queue.pop_front());
            }
            self.full.0 += 1;
        }
        Ok(None)
    }
}

impl Drop for StreamDriver {
    fn drop(&mut self) {
        // Counted when seen; required only where a runner declares it.
        if let (Some(bin), n @ 1..) = (&self.full.1, self.full.0) {
            crate::fcov::hit(bin, n);
        }
    }
}

/// The functional-coverage bin `<top>.<stream>.<what>` of the stream whose
/// valid port is `valid` (`in0_valid`: stream `in0`).
pub(crate) fn stream_bin<E: Engine + ?Sized>(
    engine: &E,
    valid: PortId,
    what: &str,
) -> Result<String> {
    let d = engine.design();
    let name = &d.port(valid)?.name;
    let stream = name.strip_suffix("_valid").unwrap_or(name);
    Ok(format!("{}.{stream}.{what}", d.top))
}

pub(crate) fn bool_bits(b: bool) -> Bits {
    if b {
        Bits::ones(1)
    } else {
        Bits::zero(1)
    }
}

pub(crate) fn check_stalls(stalls: &Stalls) -> Result<()> {
    stalls.check().map_err(|what| CosimError::Design { what })
}
