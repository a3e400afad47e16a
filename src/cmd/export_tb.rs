//! `hiermerge export-tb`: a unit's portable self-checking testbench
//! (SPEC 9.1): the unit's Verilog, a plain Verilog-2005 testbench, the
//! stimulus, stall masks and golden's expected outputs as `$readmemh`
//! files, and `run.sh` for Icarus and Verilator, none of which needs this
//! workspace to run.

use std::path::{Path, PathBuf};

use cosim::export_tb::{self, ExportSpec, RTL_DIR};
use cosim::units::{hierarchy_unit, merge_level, merge_module, merger, translate};
use serde::Serialize;

use super::common::UnitOpts;
use super::cosim::{
    merger_config, no_stream_stalls, parse_stalls, parse_stream_stalls, MergeStage, Unit,
};
use crate::report::{emit, CmdResult};

#[derive(clap::Args)]
pub struct Args {
    /// translate: the translation unit; merge-module: the merging module (or,
    /// with --stage merge-level, its S614 stage); merger: the hierarchy
    /// merger top.
    #[arg(long, value_enum)]
    unit: Unit,
    /// --unit merge-module only: `module` (default) or `merge-level`.
    #[arg(long, value_enum)]
    stage: Option<MergeStage>,
    /// Seed of the stimulus and of the stall masks.
    #[arg(long, default_value_t = 1, value_parser = super::common::unsigned::<u64>)]
    seed: u64,
    /// Transactions (translate: determine/apply records; merge, merger:
    /// merges; --stage merge-level: levels).
    #[arg(long, default_value_t = 100, value_parser = super::common::unsigned::<u64>)]
    count: u64,
    /// With `--stalls coin`: the probability of a stall per decision (default 0.3).
    #[arg(long)]
    stall: Option<f64>,
    /// The stall pattern of every driver and monitor, as `hiermerge cosim
    /// --stalls`: `coin`, `bursty[:S,G]`, `periodic[:K/N]`, `none`.
    #[arg(long, default_value = "coin")]
    stalls: String,
    /// One stream's own pattern, as `hiermerge cosim --stall-stream`
    /// (`STREAM=PATTERN`, repeatable; merge-module, merger, hierarchy).
    #[arg(long = "stall-stream", value_name = "STREAM=PATTERN")]
    stall_stream: Vec<String>,
    /// Output folder (created; files in it are replaced).
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
    /// --unit merger only: `per-unit` (the default: every store answer a
    /// precomputed stream), or `shared` / `shared:T`: one store read port,
    /// answered by a store model in the testbench from a `$readmemh` store
    /// image after --store-latency clocks.
    #[arg(long = "store-port", value_parser = super::cosim::parse_store_port)]
    store_port: Option<golden::merge::merger::store_port::StorePort>,
    /// --store-port shared only: clocks from a read taken to its answer,
    /// at the earliest (default 1).
    #[arg(long = "store-latency")]
    store_latency: Option<u64>,
    /// Print one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct Report {
    out: String,
    top: String,
    transactions: u64,
    beats_in: u64,
    beats_out: u64,
    mask_cycles: u64,
    files: usize,
}

/// Refuses `--store-port` but with `--unit merger`, and `--store-latency`
/// but with a shared port.
fn check_store_flags(a: &Args) -> Result<(), String> {
    use golden::merge::merger::store_port::StorePort;
    let shared = matches!(a.store_port, Some(StorePort::Shared { .. }));
    if a.store_port.is_some() && a.unit != Unit::Merger {
        return Err("--store-port applies to --unit merger only".into());
    }
    match a.store_latency {
        Some(_) if !shared => {
            Err("--store-latency applies to --unit merger --store-port shared only".into())
        }
        Some(0) => Err("--store-latency 0: expected 1 or more clocks".into()),
        _ => Ok(()),
    }
}

/// The merger `a` asks for: its sizes and store port.
fn merger_of(a: &Args) -> Result<rtl_gen::merge::MergerConfig, String> {
    let mut c = merger_config(&a.design.merge_design()?, a.capacity_bits, a.leaf_bits)?;
    if let Some(port) = a.store_port {
        c.sizes.store_port = port;
    }
    c.validate().map_err(|e| e.to_string())?;
    Ok(c)
}

/// The hierarchy unit `a` asks for (per-unit store ports).
fn hierarchy_of(a: &Args) -> Result<rtl_gen::merge::HierarchyUnitConfig, String> {
    super::cosim::hierarchy::hierarchy_config(merger_of(a)?, a.design.table_depth)
}

/// The arguments that wrote the testbench, as a shell line.
fn command_line() -> String {
    let args: Vec<String> = std::env::args().skip(1).collect();
    format!("hiermerge {}", args.join(" "))
}

/// The streams' own patterns `--stall-stream` asks for, checked; refused
/// where `hiermerge cosim` refuses them (one input and one output stream).
fn stream_stalls(a: &Args) -> Result<cosim::tb::StreamStalls, String> {
    match (a.unit, a.stage) {
        (Unit::Translate, _) => no_stream_stalls(&a.stall_stream, "--unit translate")?,
        (Unit::MergeModule, Some(MergeStage::MergeLevel)) => {
            no_stream_stalls(&a.stall_stream, "--stage merge-level")?
        }
        _ => {}
    }
    parse_stream_stalls(&a.stall_stream)
}

fn spec(a: &Args, count: usize, rtl: &Path) -> Result<ExportSpec, String> {
    let mut spec = unit_spec(a, count, rtl)?;
    spec.stream_stalls = stream_stalls(a)?;
    Ok(spec)
}

fn unit_spec(a: &Args, count: usize, rtl: &Path) -> Result<ExportSpec, String> {
    let stalls = parse_stalls(&a.stalls, a.stall)?;
    let e = |e: cosim::CosimError| e.to_string();
    match (a.unit, a.stage.unwrap_or(MergeStage::Module)) {
        (Unit::Translate, _) => {
            let d = a.design.translate_design()?;
            let txns = golden::vectors::translate::generate(&d, a.seed, count)
                .map_err(|e| e.to_string())?;
            translate::export_spec(&d, &txns, a.seed, stalls, rtl).map_err(e)
        }
        (Unit::MergeModule, MergeStage::Module) => {
            let d = a.design.merge_design()?;
            merge_module::export_spec(&d, a.seed, count, stalls, rtl).map_err(e)
        }
        (Unit::MergeModule, MergeStage::MergeLevel) => {
            let d = a.design.merge_design()?;
            merge_level::export_spec(&d, a.seed, count, stalls, rtl).map_err(e)
        }
        (Unit::Hierarchy, _) => {
            let c = hierarchy_of(a)?;
            hierarchy_unit::export_spec(
                &c,
                a.seed,
                (count, golden::vectors::streams::Merges::Random),
                stalls,
                rtl,
            )
            .map_err(e)
        }
        (Unit::Merger, _) => {
            let c = merger_of(a)?;
            let latency = a.store_latency.unwrap_or(1);
            merger::export_spec(&c, a.seed, count, stalls, latency, rtl).map_err(e)
        }
    }
}

pub fn main(a: Args) -> CmdResult {
    parse_stalls(&a.stalls, a.stall)?;
    stream_stalls(&a)?;
    let (stage, capacity, leaf) = (a.stage, a.capacity_bits, a.leaf_bits);
    super::cosim::refuse_unit_flags(a.unit, &a.design, stage, [capacity, leaf], &[])?;
    if a.count == 0 {
        return Err("--count 0: expected at least one transaction".into());
    }
    let limit = match a.unit {
        Unit::Translate => golden::vectors::MAX_COUNT,
        Unit::Merger | Unit::MergeModule | Unit::Hierarchy => golden::vectors::MAX_MERGE_COUNT,
    };
    golden::vectors::check_count("--count", a.count, limit)?;
    check_store_flags(&a)?;
    let count = usize::try_from(a.count).map_err(|_| "--count is too large".to_string())?;
    // Refuse a bad configuration before anything is written.
    match a.unit {
        Unit::Translate => a.design.translate_design().map(|_| ())?,
        Unit::MergeModule => a.design.merge_design().map(|_| ())?,
        Unit::Merger => merger_of(&a).map(|_| ())?,
        Unit::Hierarchy => hierarchy_of(&a).map(|_| ())?,
    }
    golden::output::check_destination(&a.out, true)?;
    let rtl = a.out.join(RTL_DIR);
    std::fs::create_dir_all(&rtl).map_err(|e| format!("{}: {e}", rtl.display()))?;
    let mut spec = spec(&a, count, &rtl)?;
    spec.command = command_line();
    let written =
        export_tb::write(&spec, &a.out).map_err(|e| format!("{}: {e}", a.out.display()))?;
    let report = Report {
        out: a.out.display().to_string(),
        top: spec.design.top.clone(),
        transactions: spec.transactions,
        beats_in: written.beats_in,
        beats_out: written.beats_out,
        mask_cycles: written.mask_cycles,
        files: written.files.len() + spec.design.verilog_files.len(),
    };
    emit(a.json, &report, |r| {
        println!(
            "wrote the testbench of {} to {}: {} transactions, {} beats in, {} beats out, {} files; run: {}/run.sh icarus|verilator",
            r.top, r.out, r.transactions, r.beats_in, r.beats_out, r.files, r.out
        )
    })
}
