//! Watchdog: fails a design that makes no progress for too many cycles,
//! with every port's value dumped so the stuck handshake is visible.

use crate::engine::Engine;
use std::fmt;

/// A hung design: when, how long idle, and the state of every port.
#[derive(Clone, Debug)]
pub struct Hang {
    /// Cycle at which the watchdog fired.
    pub cycle: u64,
    /// Cycles since the last progress.
    pub idle_cycles: u64,
    /// (port name, value) for every port.
    pub ports: Vec<(String, String)>,
}

impl fmt::Display for Hang {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "watchdog: no progress for {} cycles, at cycle {}; port state:",
            self.idle_cycles, self.cycle
        )?;
        for (name, value) in &self.ports {
            writeln!(f, "  {name} = {value}")?;
        }
        Ok(())
    }
}

/// Counts cycles since the last handshake.
#[derive(Clone, Debug)]
pub struct Watchdog {
    limit: u64,
    last_progress: u64,
}

impl Watchdog {
    /// Fire after `limit` cycles without progress.
    pub fn new(limit: u64) -> Watchdog {
        Watchdog {
            limit,
            last_progress: 0,
        }
    }

    /// Note progress (any handshake) at `cycle`.
    pub fn progress(&mut self, cycle: u64) {
        self.last_progress = cycle;
    }

    /// `Some(Hang)` once the design has been idle for more than the limit.
    pub fn check<E: Engine + ?Sized>(&self, engine: &E) -> Option<Hang> {
        let idle = engine.cycle().saturating_sub(self.last_progress);
        if idle <= self.limit {
            return None;
        }
        Some(Hang {
            cycle: engine.cycle(),
            idle_cycles: idle,
            ports: dump_ports(engine),
        })
    }
}

/// Every port of `engine` as (name, value text).
pub fn dump_ports<E: Engine + ?Sized>(engine: &E) -> Vec<(String, String)> {
    engine
        .design()
        .ports
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let value = engine
                .peek(crate::design::PortId(i))
                .map(|v| v.to_string())
                .unwrap_or_else(|e| format!("<{e}>"));
            (p.name.clone(), value)
        })
        .collect()
}
