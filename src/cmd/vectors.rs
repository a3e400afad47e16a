//! `hiermerge vectors`: write a unit's test vectors (JSON Lines: a header
//! with every parameter and the seed, then one record per transaction with
//! inputs and expected outputs as the RTL ports see them; SPEC section 9).

use std::path::PathBuf;

use golden::vectors::merge::write_merge_vectors;
use golden::vectors::translate::write_translate_vectors;
use serde::Serialize;

use super::common::UnitOpts;
use super::gen::Unit;
use crate::report::{emit, CmdResult};

#[derive(clap::Args)]
pub struct Args {
    #[arg(long, value_enum)]
    unit: Unit,
    #[arg(long, default_value_t = 1, value_parser = super::common::unsigned::<u64>)]
    seed: u64,
    /// Number of transactions (records after the header).
    #[arg(long, default_value_t = 10_000, value_parser = super::common::unsigned::<u64>)]
    count: u64,
    /// The file to write (atomically: a temporary file, then a rename).
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
    unit: Unit,
    out: String,
    seed: u64,
    count: u64,
    bytes: u64,
}

pub fn main(a: Args) -> CmdResult {
    let unit = match a.unit {
        Unit::Translate => golden::vectors::UnitKind::Translate,
        Unit::Merge => golden::vectors::UnitKind::Merge,
    };
    golden::vectors::check_count("--count", a.count, unit.max_count())?;
    match a.unit {
        Unit::Translate => {
            let design = a.design.translate_design()?;
            let count = usize::try_from(a.count)
                .map_err(|_| format!("--count {} is too large", a.count))?;
            write_translate_vectors(&a.out, &design, a.seed, count).map_err(|e| e.to_string())?;
        }
        Unit::Merge => {
            let design = a.design.merge_design()?;
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
