//! Code coverage of the Verilated units (issue 23 item 1, SPEC 10.5).
//!
//! While a process collects ([`collect_into`]), every Verilator engine that
//! [`crate::open_engine`] opens is built with Verilator's line and toggle
//! coverage (its own cache entry) and, when dropped, writes its counts as a
//! raw `coverage.dat` under `<dir>/raw/<top>/`, next to a copy of the
//! Verilog it ran (`<dir>/sources/<top>/`). [`report`] merges the raw files
//! of each unit with `verilator_coverage --write`, annotates the sources,
//! and summarizes the points, each uncovered one named by its emitted net
//! or line and the generator line the emitted Verilog's comments give
//! (the same index `hiermerge synth` uses for its critical path).

pub mod by_design;
pub mod constants;
mod dat;
mod summary;
mod waivers;

pub use dat::{read_points, Kind, Point};
pub use summary::{report, Aims, CoverageReport, UncoveredPoint, UnitSummary};
pub use waivers::{Waiver, Waivers};

use crate::design::Design;
use crate::error::{io_err, CosimError, Result};
use crate::verilator::VerilatorOptions;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// What Verilator is given for a coverage build: line coverage (which in
/// Verilator includes every `if`/`else` arm, the `v_branch` points) and
/// toggle coverage.
pub const VERILATOR_FLAGS: [&str; 2] = ["--coverage-line", "--coverage-toggle"];

/// The C++ optimization of a coverage build: its runs are short, so the
/// compile time `-O1` would add (about half of the build) is not won back.
pub const CXX_OPT: &str = "-O0";

/// `options` as a coverage build while the process collects, else as given.
pub fn options(options: VerilatorOptions) -> VerilatorOptions {
    match collecting() {
        true => VerilatorOptions {
            coverage: true,
            cxx_opt: CXX_OPT.to_string(),
            ..options
        },
        false => options,
    }
}

struct Sink {
    dir: PathBuf,
    written: u64,
    errors: Vec<String>,
}

static SINK: Mutex<Option<Sink>> = Mutex::new(None);

fn sink() -> std::sync::MutexGuard<'static, Option<Sink>> {
    SINK.lock().unwrap_or_else(|p| p.into_inner())
}

/// From now on, Verilator engines opened by this process are coverage
/// builds whose counts go to `dir` (created if missing).
pub fn collect_into(dir: &Path) -> Result<()> {
    for sub in ["raw", "sources"] {
        let d = dir.join(sub);
        std::fs::create_dir_all(&d).map_err(io_err(&d))?;
    }
    *sink() = Some(Sink {
        dir: dir.to_path_buf(),
        written: 0,
        errors: Vec::new(),
    });
    Ok(())
}

/// True while [`collect_into`] is in force.
pub fn collecting() -> bool {
    sink().is_some()
}

/// Stops collecting; the number of raw files written, or the first error
/// an engine met writing one (engines write when dropped, so they cannot
/// return it themselves).
pub fn stop_collecting() -> Result<u64> {
    let s = sink().take();
    match s {
        None => Ok(0),
        Some(s) => match s.errors.into_iter().next() {
            Some(what) => Err(CosimError::Protocol { what }),
            None => Ok(s.written),
        },
    }
}

/// Where a new engine of `design` writes its counts, after copying the
/// design's Verilog next to them; `None` when not collecting.
pub(crate) fn raw_path_for(design: &Design) -> Result<Option<PathBuf>> {
    let mut guard = sink();
    let Some(s) = guard.as_mut() else {
        return Ok(None);
    };
    let raw = s.dir.join("raw").join(&design.top);
    std::fs::create_dir_all(&raw).map_err(io_err(&raw))?;
    let sources = s.dir.join("sources").join(&design.top);
    std::fs::create_dir_all(&sources).map_err(io_err(&sources))?;
    for f in &design.verilog_files {
        if let Some(name) = f.file_name() {
            let to = sources.join(name);
            std::fs::copy(f, &to).map_err(io_err(&to))?;
        }
    }
    s.written += 1;
    Ok(Some(raw.join(format!(
        "{}-{}.dat",
        std::process::id(),
        s.written
    ))))
}

/// An engine could not write its counts: kept for [`stop_collecting`].
pub(crate) fn record_error(what: String) {
    if let Some(s) = sink().as_mut() {
        s.errors.push(what);
    }
}
