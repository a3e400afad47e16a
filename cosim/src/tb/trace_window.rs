//! Tracing only a window of cycles, so a VCD of a long run stays small.
//!
//! The simulator writes into a temporary file beside the destination
//! (`golden::output::AtomicFile`), renamed over it when the window is
//! finished: an interrupted or failed run leaves no half-written VCD, and
//! SIGINT/SIGTERM remove the temporary (SPEC 15.3).

use crate::engine::Engine;
use crate::error::{CosimError, Result};
use golden::output::AtomicFile;
use std::path::PathBuf;

/// Trace cycles `from..=to` into `path`.
pub struct TraceWindow {
    /// First cycle traced.
    pub from: u64,
    /// Last cycle traced.
    pub to: u64,
    /// VCD file written.
    pub path: PathBuf,
    out: Option<AtomicFile>,
    done: bool,
}

impl std::fmt::Debug for TraceWindow {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TraceWindow")
            .field("from", &self.from)
            .field("to", &self.to)
            .field("path", &self.path)
            .field("active", &self.out.is_some())
            .finish()
    }
}

fn output_error(path: &std::path::Path, what: String) -> CosimError {
    CosimError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(what),
    }
}

impl TraceWindow {
    /// The window of `radius` cycles either side of `center`.
    pub fn around(center: u64, radius: u64, path: PathBuf) -> TraceWindow {
        TraceWindow {
            from: center.saturating_sub(radius),
            to: center.saturating_add(radius),
            path,
            out: None,
            done: false,
        }
    }

    /// Call once per cycle before driving inputs: starts or stops the trace.
    pub fn update<E: Engine + ?Sized>(&mut self, engine: &mut E) -> Result<()> {
        let c = engine.cycle();
        if self.out.is_none() && !self.done && c >= self.from && c <= self.to {
            if let Some(dir) = self.path.parent() {
                std::fs::create_dir_all(dir).map_err(crate::error::io_err(dir))?;
            }
            let out = AtomicFile::create(&self.path).map_err(|e| output_error(&self.path, e))?;
            engine.trace_start(out.path())?;
            self.out = Some(out);
        } else if self.out.is_some() && c > self.to {
            self.finish(engine)?;
        }
        Ok(())
    }

    /// Stop tracing (end of run) and put the file in place; harmless when
    /// not tracing.
    pub fn finish<E: Engine + ?Sized>(&mut self, engine: &mut E) -> Result<()> {
        if let Some(out) = self.out.take() {
            engine.trace_stop()?;
            self.done = true;
            out.commit().map_err(|e| output_error(&self.path, e))?;
        }
        Ok(())
    }
}
