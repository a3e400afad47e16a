//! `hiermerge vectors`: write a unit's test vectors (JSON Lines: a header
//! with every parameter and the seed, then one record per transaction with
//! inputs and expected outputs as the RTL ports see them; SPEC section 9).

use std::path::PathBuf;

use golden::translate::TranslateUnitConfig;
use golden::vectors::merge::{write_merge_vectors, MergeDesign};
use golden::vectors::translate::{write_translate_vectors, TranslateDesign};
use serde::Serialize;

use super::common::GridOpts;
use super::gen::Unit;
use crate::report::{emit, CmdResult};

#[derive(clap::Args)]
pub struct Args {
    #[arg(long, value_enum)]
    unit: Unit,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Number of transactions (records after the header).
    #[arg(long, default_value_t = 10_000)]
    count: u64,
    /// The file to write (atomically: a temporary file, then a rename).
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    grid: GridOpts,
    /// Translation unit: entries of the translation table (default: one per hierarchy id).
    #[arg(long = "table-depth")]
    table_depth: Option<u32>,
    /// Translation unit: binary64 placements as well as binary32.
    #[arg(long)]
    binary64: bool,
    /// Merging module: number of merged inputs.
    #[arg(long, default_value_t = MergeDesign::default().inputs)]
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
    unit: Unit,
    out: String,
    seed: u64,
    count: u64,
    bytes: u64,
}

pub fn main(a: Args) -> CmdResult {
    let params = a.grid.params()?;
    match a.unit {
        Unit::Translate => {
            let design = TranslateDesign {
                unit: TranslateUnitConfig {
                    params,
                    table_depth: a.table_depth.unwrap_or(params.hier_capacity() as u32),
                },
                binary64: a.binary64,
            };
            design
                .validate()
                .map_err(|e| format!("translation unit configuration: {e}"))?;
            let count = usize::try_from(a.count)
                .map_err(|_| format!("--count {} is too large", a.count))?;
            write_translate_vectors(&a.out, &design, a.seed, count).map_err(|e| e.to_string())?;
        }
        Unit::Merge => {
            let (num, den) = super::merge::parse_ratio(&a.threshold)?;
            if num > den {
                return Err(format!("--threshold {}: expected N <= D", a.threshold));
            }
            let design = MergeDesign {
                params,
                inputs: a.inputs,
                num,
                den,
                ..MergeDesign::default()
            };
            write_merge_vectors(&a.out, &design, a.seed, a.count).map_err(|e| e.to_string())?;
        }
    }
    let bytes = std::fs::metadata(&a.out).map(|m| m.len()).unwrap_or(0);
    let report = Report {
        unit: a.unit,
        out: a.out.display().to_string(),
        seed: a.seed,
        count: a.count,
        bytes,
    };
    emit(a.json, &report, |r| {
        println!(
            "wrote {} transactions ({} bytes) to {}",
            r.count, r.bytes, r.out
        )
    })
}
