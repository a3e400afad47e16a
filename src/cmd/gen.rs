//! `hiermerge gen`: emit the Verilog of a unit's configuration, or of every
//! default configuration (what `verilog/` holds).

use std::path::{Path, PathBuf};

use rtl_gen::merge::{emit_merge, MergeConfig};
use serde::Serialize;

use super::common::UnitOpts;
use crate::report::{emit, CmdResult};

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Unit {
    Translate,
    Merge,
}

#[derive(clap::Args)]
pub struct Args {
    /// The unit to generate; omit with --defaults.
    #[arg(long, value_enum, required_unless_present = "defaults")]
    unit: Option<Unit>,
    /// Emit the default configuration of every unit (the contents of verilog/).
    #[arg(long, conflicts_with = "unit")]
    defaults: bool,
    /// Output folder (created if needed).
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    design: UnitOpts,
    /// Print one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct Report {
    out: String,
    files: Vec<String>,
}

/// Writes the default configuration of every unit into `dir`.
pub fn emit_defaults(dir: &Path) -> Result<Vec<PathBuf>, String> {
    let mut files = rtl_gen::translate::emit_default(dir)?;
    files.extend(emit_merge(&MergeConfig::default(), dir).map_err(|e| e.to_string())?);
    // Per-node merging is its own merging module (SPEC 8.14): the default
    // design with the default per-node ratio.
    let per_node = MergeConfig {
        mode: golden::merge::MergeMode::PerNode { num: 1, den: 2 },
        ..MergeConfig::default()
    };
    files.extend(emit_merge(&per_node, dir).map_err(|e| e.to_string())?);
    files.sort();
    files.dedup();
    Ok(files)
}

/// Writes the configuration of `unit` that `design` asks for into `dir`.
pub fn emit_unit(unit: Unit, design: &UnitOpts, dir: &Path) -> Result<Vec<PathBuf>, String> {
    match unit {
        Unit::Translate => rtl_gen::translate::emit(&design.translate_design()?, dir),
        Unit::Merge => emit_merge(&design.merge_design()?, dir).map_err(|e| e.to_string()),
    }
}

pub fn main(a: Args) -> CmdResult {
    golden::output::check_destination(&a.out, true)?;
    std::fs::create_dir_all(&a.out).map_err(|e| format!("{}: {e}", a.out.display()))?;
    let files = if a.defaults {
        emit_defaults(&a.out)?
    } else {
        match a.unit {
            Some(unit) => emit_unit(unit, &a.design, &a.out)?,
            None => return Err("expected --unit translate|merge, or --defaults".into()),
        }
    };
    let report = Report {
        out: a.out.display().to_string(),
        files: files.iter().map(|f| f.display().to_string()).collect(),
    };
    emit(a.json, &report, |r| {
        for f in &r.files {
            println!("wrote {f}");
        }
    })
}
