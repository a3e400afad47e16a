//! `hiermerge gen`: emit the Verilog of a unit's configuration, or of every
//! default configuration (what `verilog/` holds).

use std::path::{Path, PathBuf};

use golden::translate::TranslateUnitConfig;
use golden::vectors::translate::TranslateDesign;
use rtl_gen::merge::{emit_merge, MergeConfig};
use serde::Serialize;

use super::common::GridOpts;
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
    grid: GridOpts,
    /// Translation unit: entries of the translation table (default: one per hierarchy id).
    #[arg(long = "table-depth")]
    table_depth: Option<u32>,
    /// Translation unit: accept binary64 placements as well as binary32.
    #[arg(long)]
    binary64: bool,
    /// Merging module: number of merged inputs.
    #[arg(long, default_value_t = MergeConfig::default().inputs)]
    inputs: usize,
    /// Merging module: overlap threshold N/D.
    #[arg(long, default_value = "1/2")]
    threshold: String,
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
    Ok(files)
}

pub fn main(a: Args) -> CmdResult {
    std::fs::create_dir_all(&a.out).map_err(|e| format!("{}: {e}", a.out.display()))?;
    let files = if a.defaults {
        emit_defaults(&a.out)?
    } else {
        let params = a.grid.params()?;
        match a.unit {
            Some(Unit::Translate) => {
                let design = TranslateDesign {
                    unit: TranslateUnitConfig {
                        params,
                        table_depth: a.table_depth.unwrap_or(params.hier_capacity() as u32),
                    },
                    binary64: a.binary64,
                };
                rtl_gen::translate::emit(&design, &a.out)?
            }
            Some(Unit::Merge) => {
                let (num, den) = super::merge::parse_ratio(&a.threshold)?;
                if num > den {
                    return Err(format!("--threshold {}: expected N <= D", a.threshold));
                }
                if a.inputs < 2 || a.inputs as u64 > params.hier_capacity() {
                    return Err(format!(
                        "--inputs {}: expected 2..={} (2^hier_bits)",
                        a.inputs,
                        params.hier_capacity()
                    ));
                }
                let c = MergeConfig {
                    params,
                    inputs: a.inputs,
                    num,
                    den,
                    ..MergeConfig::default()
                };
                emit_merge(&c, &a.out).map_err(|e| e.to_string())?
            }
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
