//! `hiermerge vectors`: write a unit's test vectors (JSON Lines: a header
//! with every parameter and the seed, then one record per transaction with
//! inputs and expected outputs as the RTL ports see them; SPEC section 9).
//! `--unit merge-module` writes the whole merging module's merges (every stream,
//! field by field), or with `--stage merge-level` the stream-stage records
//! that `cosim --unit merge-module --stage merge-level --vectors` replays;
//! `--unit merger` the hierarchy merger top's merges.

use std::path::PathBuf;

use golden::vectors::merge::write_merge_vectors;
use golden::vectors::stream_file::{write_merger_vectors, write_module_vectors};
use golden::vectors::translate::write_translate_vectors;
use serde::Serialize;

use super::common::UnitOpts;
use super::cosim::{merger_config, MergeStage, Unit};
use crate::report::{emit, CmdResult};

#[derive(clap::Args)]
pub struct Args {
    /// translate: the translation unit; merge-module: the merging module (with
    /// --stage merge-level, its stream stages); merger: the hierarchy merger top.
    #[arg(long, value_enum)]
    unit: Unit,
    /// --unit merge-module only: `module` (default: one record per merge, every
    /// stream) or `merge-level` (one record per stream-stage transaction).
    #[arg(long, value_enum)]
    stage: Option<MergeStage>,
    #[arg(long, default_value_t = 1, value_parser = super::common::unsigned::<u64>)]
    seed: u64,
    /// Number of transactions (records after the header; merge, merger: merges).
    #[arg(long, default_value_t = 10_000, value_parser = super::common::unsigned::<u64>)]
    count: u64,
    /// The file to write (atomically: a temporary file, then a rename).
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    design: UnitOpts,
    /// --unit merger only: log2 of the writer's entries per buffer.
    #[arg(long = "capacity-bits")]
    capacity_bits: Option<u32>,
    /// --unit merger only: log2 of each leaf FIFO's entries.
    #[arg(long = "leaf-bits")]
    leaf_bits: Option<u32>,
    /// Print one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct Report {
    unit: Unit,
    /// The header's `unit`: what the records hold.
    records: &'static str,
    out: String,
    seed: u64,
    count: u64,
    bytes: u64,
}

/// What `vectors` says of `--unit hierarchy`.
const NO_HIERARCHY_FILES: &str = "--unit hierarchy: no vector file is written for it; `hiermerge export-tb --unit hierarchy` writes its stimulus and expected beats with a testbench, and `cosim --unit hierarchy` runs it (--unit merger and --unit translate write the merger top's and the translation unit's vectors)";

pub fn main(a: Args) -> CmdResult {
    let (stage, capacity, leaf) = (a.stage, a.capacity_bits, a.leaf_bits);
    super::cosim::refuse_unit_flags(a.unit, &a.design, stage, [capacity, leaf], &[])?;
    if a.count == 0 {
        return Err("--count 0: expected at least one transaction".into());
    }
    use golden::vectors::UnitKind;
    let kind = match (a.unit, a.stage.unwrap_or(MergeStage::Module)) {
        (Unit::Translate, _) => UnitKind::Translate,
        (Unit::MergeModule, MergeStage::Module) => UnitKind::MergeModule,
        (Unit::MergeModule, MergeStage::MergeLevel) => UnitKind::Merge,
        (Unit::Merger, _) => UnitKind::Merger,
        (Unit::Hierarchy, _) => return Err(NO_HIERARCHY_FILES.into()),
    };
    golden::vectors::check_count("--count", a.count, kind.max_count())?;
    let e = |e: golden::vectors::VectorError| e.to_string();
    match kind {
        UnitKind::Translate => {
            let design = a.design.translate_design()?;
            let count = usize::try_from(a.count)
                .map_err(|_| format!("--count {} is too large", a.count))?;
            write_translate_vectors(&a.out, &design, a.seed, count).map_err(e)?;
        }
        UnitKind::Merge => {
            let design = a.design.merge_design()?;
            write_merge_vectors(&a.out, &design, a.seed, a.count).map_err(e)?;
        }
        UnitKind::MergeModule => {
            let design = a.design.merge_design()?;
            write_module_vectors(&a.out, &design, a.seed, a.count).map_err(e)?;
        }
        UnitKind::Merger => {
            let c = merger_config(&a.design.merge_design()?, a.capacity_bits, a.leaf_bits)?;
            write_merger_vectors(&a.out, &c.design, c.sizes, a.seed, a.count).map_err(e)?;
        }
    }
    let bytes = std::fs::metadata(&a.out).map(|m| m.len()).unwrap_or(0);
    let report = Report {
        unit: a.unit,
        records: kind.name(),
        out: a.out.display().to_string(),
        seed: a.seed,
        count: a.count,
        bytes,
    };
    emit(a.json, &report, |r| {
        println!(
            "wrote {} transactions ({} records, {} bytes) to {}",
            r.count, r.records, r.bytes, r.out
        )
    })
}
