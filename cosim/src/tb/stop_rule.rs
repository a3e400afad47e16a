//! When a stepped bench stops: the watchdog while work is outstanding, then
//! a drain once every beat is sent and received, so a late extra beat is
//! still seen; the same rule for the single-stream and the multi-stream
//! benches (and the one the Icarus batch testbenches implement in Verilog).

use super::bench::{BenchConfig, PROGRESS_EVERY};
use super::watchdog::{Hang, Watchdog};
use crate::engine::Engine;

/// The stop rule's state over a run.
#[derive(Debug)]
pub struct StopRule {
    watchdog: Watchdog,
    drain_cycles: u64,
    drain_left: Option<u64>,
    next_progress: u64,
    hang: Option<Hang>,
}

impl StopRule {
    /// The rule of `config`, the run (out of reset) starting at `cycle`.
    pub fn new(config: &BenchConfig, cycle: u64) -> StopRule {
        let mut watchdog = Watchdog::new(config.watchdog_cycles);
        watchdog.progress(cycle);
        StopRule {
            watchdog,
            drain_cycles: config.drain_cycles,
            drain_left: None,
            next_progress: 0,
            hang: None,
        }
    }

    /// A handshake moved at `cycle`.
    pub fn progress(&mut self, cycle: u64) {
        self.watchdog.progress(cycle);
    }

    /// After a cycle's checks, whether the run stops here: `finished` when
    /// everything is sent and every expected beat received, `mismatch_stop`
    /// when a mismatch ends the run. Once finished, the drain of
    /// `drain_cycles` starts, watched by a watchdog one cycle longer, so the
    /// drain ends the run, not a hang. A hang stops it too ([`Self::hang`]).
    pub fn stops_after<E: Engine + ?Sized>(
        &mut self,
        engine: &E,
        finished: bool,
        mismatch_stop: bool,
    ) -> bool {
        if finished && self.drain_left.is_none() {
            self.drain_left = Some(self.drain_cycles);
            self.watchdog = Watchdog::new(self.drain_cycles + 1);
            self.watchdog.progress(engine.cycle());
        }
        if mismatch_stop || self.drain_left == Some(0) {
            return true;
        }
        self.drain_left = self.drain_left.map(|d| d - 1);
        self.hang = self.watchdog.check(engine);
        self.hang.is_some()
    }

    /// The watchdog's finding, when it stopped the run.
    pub fn hang(&self) -> Option<&Hang> {
        self.hang.as_ref()
    }

    /// [`Self::hang`], taken at the end of the run.
    pub fn into_hang(self) -> Option<Hang> {
        self.hang
    }

    /// Whether a progress callback is due at `cycle` (every
    /// [`PROGRESS_EVERY`] cycles, and at the first).
    pub fn progress_due(&mut self, cycle: u64) -> bool {
        let due = cycle >= self.next_progress;
        if due {
            self.next_progress = cycle + PROGRESS_EVERY;
        }
        due
    }
}
