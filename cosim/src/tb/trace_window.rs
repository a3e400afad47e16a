//! Tracing only a window of cycles, so a VCD of a long run stays small.

use crate::engine::Engine;
use crate::error::Result;
use std::path::PathBuf;

/// Trace cycles `from..=to` into `path`.
#[derive(Clone, Debug)]
pub struct TraceWindow {
    /// First cycle traced.
    pub from: u64,
    /// Last cycle traced.
    pub to: u64,
    /// VCD file written.
    pub path: PathBuf,
    active: bool,
    done: bool,
}

impl TraceWindow {
    /// The window of `radius` cycles either side of `center`.
    pub fn around(center: u64, radius: u64, path: PathBuf) -> TraceWindow {
        TraceWindow {
            from: center.saturating_sub(radius),
            to: center.saturating_add(radius),
            path,
            active: false,
            done: false,
        }
    }

    /// Call once per cycle before driving inputs: starts or stops the trace.
    pub fn update<E: Engine + ?Sized>(&mut self, engine: &mut E) -> Result<()> {
        let c = engine.cycle();
        if !self.active && !self.done && c >= self.from && c <= self.to {
            if let Some(dir) = self.path.parent() {
                std::fs::create_dir_all(dir).map_err(crate::error::io_err(dir))?;
            }
            engine.trace_start(&self.path)?;
            self.active = true;
        } else if self.active && c > self.to {
            self.finish(engine)?;
        }
        Ok(())
    }

    /// Stop tracing (end of run); harmless when not tracing.
    pub fn finish<E: Engine + ?Sized>(&mut self, engine: &mut E) -> Result<()> {
        if self.active {
            engine.trace_stop()?;
            self.active = false;
            self.done = true;
        }
        Ok(())
    }
}
