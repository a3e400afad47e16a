//! Tracing only a window of cycles, so a waveform of a long run stays
//! small, and optionally only one scope of the design (VCD: filtered here,
//! `waves::filter_vcd_scope`, whatever the engine dumped; FST: by the engine,
//! Verilator's `dumpvars`). The format is the file name's (`waves::WaveFormat`).
//!
//! The simulator writes into a temporary file beside the destination
//! (`golden::output::AtomicFile`), renamed over it when the window is
//! finished: an interrupted or failed run leaves no half-written VCD, and
//! SIGINT/SIGTERM remove the temporary (SPEC 15.3).

use crate::engine::Engine;
use crate::error::{CosimError, Result};
use crate::waves::{filter_vcd_scope, read_fst_header, WaveFormat};
use golden::output::AtomicFile;
use std::path::PathBuf;

/// Trace cycles `from..=to` into `path`.
pub struct TraceWindow {
    /// First cycle traced.
    pub from: u64,
    /// Last cycle traced.
    pub to: u64,
    /// Waveform file written (`.fst`: FST, else VCD).
    pub path: PathBuf,
    /// Only this instance path (`u_a.u_b`) and below, when given.
    pub scope: Option<String>,
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
            scope: None,
            out: None,
            done: false,
        }
    }

    /// Cycles `from..=to`, asked for whatever the run's outcome.
    pub fn cycles(from: u64, to: u64, path: PathBuf) -> TraceWindow {
        TraceWindow {
            from,
            to,
            ..TraceWindow::around(0, 0, path)
        }
    }

    /// The window of `config`'s radius around the failure at `cycle`, of
    /// `config`'s scope.
    pub fn around_failure(config: &super::BenchConfig, cycle: u64, path: PathBuf) -> TraceWindow {
        TraceWindow::around(cycle, config.vcd_radius, path).with_scope(config.wave_scope.clone())
    }

    /// The window `config` asks of every run (`wave_window` into
    /// `vcd_path`), if any.
    pub fn asked(config: &super::BenchConfig) -> Option<TraceWindow> {
        let (from, to) = config.wave_window?;
        let path = config.vcd_path.clone()?;
        Some(TraceWindow::cycles(from, to, path).with_scope(config.wave_scope.clone()))
    }

    /// The same window, tracing only `scope` (None: everything).
    pub fn with_scope(mut self, scope: Option<String>) -> TraceWindow {
        self.scope = scope;
        self
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
            if let Some(scope) = &self.scope {
                narrow_to_scope(out.path(), scope).map_err(|e| output_error(&self.path, e))?;
            }
            out.commit().map_err(|e| output_error(&self.path, e))?;
        }
        Ok(())
    }
}

/// Applies the scope filter to the waveform the engine wrote at `path`: a
/// VCD is cut to the scope's signals; an FST (already cut by the engine)
/// must hold some.
pub(crate) fn narrow_to_scope(
    path: &std::path::Path,
    scope: &str,
) -> std::result::Result<(), String> {
    let at = |e: std::io::Error| format!("{}: {e}", path.display());
    match WaveFormat::of(path) {
        WaveFormat::Vcd => {
            let text = std::fs::read_to_string(path).map_err(at)?;
            std::fs::write(path, filter_vcd_scope(&text, scope)?).map_err(at)
        }
        WaveFormat::Fst => {
            let bytes = std::fs::read(path).map_err(at)?;
            let h = read_fst_header(&bytes)?;
            if h.vars == 0 {
                return Err(format!("no signal under scope `{scope}` in the waveform"));
            }
            Ok(())
        }
    }
}
