//! `hiermerge cosim`: run a generated unit's Verilog (or its IR) against the
//! golden model, transaction by transaction, with random back-pressure; print
//! what it measured, or the first mismatch decoded field by field with the
//! one command that reproduces it and a VCD of the cycles around it (SPEC 10.1).
//!
//! Test hook: the environment variable `HIERMERGE_COSIM_FLIP_EXPECTED=<n>`
//! flips the lowest bit of transaction `n`'s expected output (translate: the
//! n-th transaction; merge: the first `report` beat of the n-th merge;
//! `--stage merge-level`: the first output beat of the n-th level; merger:
//! the `header` beat of the n-th merge), so a test can check that a broken
//! run is caught and reported. With `--unit merge` (the module) and `--unit
//! merger`, `HIERMERGE_COSIM_PATCH_FROM=<text>` and
//! `HIERMERGE_COSIM_PATCH_TO=<text>` replace the one occurrence of the first
//! in the emitted Verilog by the second before Verilator or Icarus reads it:
//! a deliberately broken unit.

use std::path::{Path, PathBuf};

use cosim::from_rtl::design_from_module;
use cosim::ir_engine::IrEngine;
use cosim::units::merge_module::{self, ModuleEngine, ModuleMismatch};
use cosim::units::merger;
use cosim::units::translate::{self, Failure, RunConfig};
use cosim::units::{check_stall, merge};
use cosim::{open_engine, Design, Engine, EngineKind};
use golden::vectors::merge::MergeDesign;
use golden::vectors::translate::{generate, read_translate_vectors, TranslateDesign};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

use super::common::UnitOpts;
use crate::report::{emit, CmdResult};

/// The environment variable of the test hook (see the module docs).
pub const FLIP_EXPECTED_VAR: &str = "HIERMERGE_COSIM_FLIP_EXPECTED";

/// The environment variables of the Verilog patch hook (see the module docs).
pub const PATCH_FROM_VAR: &str = "HIERMERGE_COSIM_PATCH_FROM";
pub const PATCH_TO_VAR: &str = "HIERMERGE_COSIM_PATCH_TO";

/// Cycles either side of a mismatch written to its VCD.
const VCD_RADIUS: u64 = 20;

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum EngineChoice {
    /// Verilator (2-state, compiled).
    Verilator,
    /// Icarus Verilog (4-state, X/Z checked; --unit merge: the whole bench
    /// inside one vvp run, the multi-stream batch).
    Iverilog,
    /// rtl-gen's IR simulator (the model the Verilog was emitted from).
    Ir,
}

impl EngineChoice {
    fn name(self) -> &'static str {
        match self {
            EngineChoice::Verilator => "verilator",
            EngineChoice::Iverilog => "iverilog",
            EngineChoice::Ir => "ir",
        }
    }
}

/// The unit `hiermerge cosim` runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Unit {
    /// The translation unit.
    Translate,
    /// The merging module (or, with `--stage merge-level`, its S614 stage).
    Merge,
    /// The hierarchy merger, S610-S618 as one top (SPEC 8.15).
    Merger,
}

/// Which part of the merging module `--unit merge` runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum MergeStage {
    /// The whole merging module (`merge_module_unit`): a transaction is one
    /// merge, seeded random stimulus on every stream.
    Module,
    /// Only its S614 merge-level stage (`merge_level_unit`): a transaction
    /// is one level; what `--vectors` files hold.
    MergeLevel,
}

/// --unit translate: the whole translation unit (determine and apply
/// streams). --unit merge: the merging module as one unit (streams cfg,
/// in0.., report, out; a transaction is one merge; Icarus runs the
/// multi-stream batch, the whole bench inside one vvp run); with
/// `--stage merge-level` its S614 stage alone (unit 506; a transaction is
/// one level). --unit merger: the hierarchy merger (S610-S618; a
/// transaction is one merge, store responses precomputed from golden;
/// run in chunks of 10,000 merges).
#[derive(clap::Args)]
pub struct Args {
    /// translate: the translation unit; merge: the merging module; merger:
    /// the hierarchy merger.
    #[arg(long, value_enum)]
    unit: Unit,
    /// --unit merge only: `module` (default) or `merge-level`, the S614
    /// stage alone (the default with --vectors, whose files hold its records).
    #[arg(long, value_enum)]
    stage: Option<MergeStage>,
    #[arg(long, value_enum, default_value = "verilator")]
    engine: EngineChoice,
    /// Run the transactions of this vectors file (`hiermerge vectors`;
    /// its header's parameters must equal the design's). Merge: its
    /// merge_level records (implies --stage merge-level).
    #[arg(long, conflicts_with = "count")]
    vectors: Option<PathBuf>,
    /// Seed of the generated transactions and of the stall patterns.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Transactions to generate (translate: determine/apply records;
    /// merge: merges; --stage merge-level: levels).
    #[arg(long)]
    count: Option<u64>,
    /// Probability that the driver holds valid low and the monitor ready low
    /// (0 <= P < 1; merge: on every stream, each with its own pattern).
    #[arg(long, default_value_t = 0.3)]
    stall: f64,
    /// Directory of the VCD written on a mismatch.
    #[arg(long = "vcd-dir", default_value = "out/cosim")]
    vcd_dir: PathBuf,
    #[command(flatten)]
    design: UnitOpts,
    /// --unit merger only: log2 of the writer's entries per buffer
    /// (default: the merger's default, min(10, index bits - 1)).
    #[arg(long = "capacity-bits")]
    capacity_bits: Option<u32>,
    /// --unit merger only: log2 of each leaf FIFO's entries (default 4).
    #[arg(long = "leaf-bits")]
    leaf_bits: Option<u32>,
    /// --unit merger only: also record the run, passed or failed, as an
    /// entry of the long-run ledger in this folder (SPEC 10.2; `hiermerge
    /// ledger` checks the entries against today's code).
    #[arg(long)]
    ledger: Option<PathBuf>,
    /// Print one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

const DEFAULT_COUNT: u64 = 10_000;

#[derive(Serialize, Clone, Debug)]
struct FieldReport {
    name: String,
    expected: String,
    got: String,
    differs: bool,
}

#[derive(Serialize, Clone, Debug)]
struct MismatchReport {
    transaction: u64,
    /// Merging module: the output stream (`report`, `out`) and the beat's
    /// index on it.
    stream: Option<String>,
    beat: Option<u64>,
    kind: String,
    cycle: u64,
    seed: u64,
    what: String,
    fields: Vec<FieldReport>,
}

#[derive(Serialize)]
struct Report {
    unit: Unit,
    stage: &'static str,
    engine: &'static str,
    seed: u64,
    stall: f64,
    vectors: Option<String>,
    passed: bool,
    #[serde(flatten)]
    counts: Counts,
    records_per_cycle: f64,
    nodes_per_cycle: f64,
    /// Simulation speed of the engine under the testbench: cycles / wall_seconds.
    cycles_per_second: f64,
    first_mismatch: Option<MismatchReport>,
    vcd: Option<String>,
    reproduce: Option<String>,
    /// --unit merger: what the merges exercised.
    #[serde(skip_serializing_if = "Option::is_none")]
    merger: Option<MergerReport>,
}

/// What `--unit merger`'s merges exercised.
#[derive(Serialize)]
struct MergerReport {
    /// Chunks of at most 10,000 merges, each run from reset.
    chunks: u64,
    refused: u64,
    fetch_errors: u64,
    /// References written (`refs` beats).
    refs_written: u64,
    /// Beats accepted on every input stream and out on every output stream.
    beats_in: u64,
    beats_out: u64,
    leaves_above: u64,
    materialized: u64,
    several_roots: u64,
    /// Per-node merges of more than one pass, and voxels that descended.
    multi_pass: u64,
    descents: u64,
    /// One `done` pulse per merge expected.
    done_pulses: u64,
    /// Wall time of generating the golden stimulus (not in wall_seconds).
    golden_seconds: f64,
    /// The simulated top module: the configuration, as the generator names it.
    top: String,
    /// Digests of the simulated netlist and of the stimulus (SPEC 10.2).
    netlist_sha256: String,
    stimulus_sha256: String,
}

fn flip_expected() -> Result<Option<usize>, String> {
    match std::env::var(FLIP_EXPECTED_VAR) {
        Ok(v) => v
            .trim()
            .parse()
            .map(Some)
            .map_err(|_| format!("{FLIP_EXPECTED_VAR}={v}: expected a transaction index")),
        Err(_) => Ok(None),
    }
}

/// The Verilog patch of the test hook, when both variables are set.
fn verilog_patch() -> Result<Option<merge_module::VerilogPatch>, String> {
    match (std::env::var(PATCH_FROM_VAR), std::env::var(PATCH_TO_VAR)) {
        (Ok(from), Ok(to)) if !from.is_empty() => Ok(Some(merge_module::VerilogPatch { from, to })),
        (Err(_), Err(_)) => Ok(None),
        _ => Err(format!(
            "{PATCH_FROM_VAR} (not empty) and {PATCH_TO_VAR} go together"
        )),
    }
}

/// The one command line that runs this again, the same way: the test hooks'
/// variables, then `hiermerge cosim` and [`run_args`], quoted for a shell.
fn reproduce(a: &Args, flip: Option<usize>) -> Result<String, String> {
    let mut s = String::new();
    if let Some(n) = flip {
        s += &format!("{FLIP_EXPECTED_VAR}={n} ");
    }
    if let Some(p) = verilog_patch()? {
        s += &format!(
            "{PATCH_FROM_VAR}={} {PATCH_TO_VAR}={} ",
            shell_quoted(&p.from),
            shell_quoted(&p.to)
        );
    }
    s += "hiermerge cosim";
    for arg in run_args(a)? {
        s += " ";
        s += &shell_quoted(&arg);
    }
    Ok(s)
}

/// `text` as one shell word: as it is when it holds only characters no shell
/// treats specially, else in single quotes.
fn shell_quoted(text: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || "-_.,:/=+@%".contains(c);
    if !text.is_empty() && text.chars().all(plain) {
        text.to_string()
    } else {
        format!("'{}'", text.replace('\'', "'\\''"))
    }
}

/// The arguments of `hiermerge cosim` that run this again, every value
/// spelled out (defaults too) and the mode in its canonical form, so that a
/// ledger entry's `args` name the run whatever the defaults become.
fn run_args(a: &Args) -> Result<Vec<String>, String> {
    let mut v: Vec<String> = Vec::new();
    let mut push = |flag: &str, value: String| v.extend([flag.to_string(), value]);
    let unit = match a.unit {
        Unit::Translate => "translate",
        Unit::Merge => "merge",
        Unit::Merger => "merger",
    };
    push("--unit", unit.into());
    if a.unit == Unit::Merge && merge_stage(a)? == MergeStage::MergeLevel {
        push("--stage", "merge-level".into());
    }
    push("--engine", a.engine.name().into());
    match &a.vectors {
        Some(p) => {
            push("--vectors", p.display().to_string());
            push("--seed", a.seed.to_string());
        }
        None => {
            push("--seed", a.seed.to_string());
            push("--count", a.count.unwrap_or(DEFAULT_COUNT).to_string());
        }
    }
    push("--stall", a.stall.to_string());
    let g = &a.design.grid;
    push("--max-lod", g.max_lod.to_string());
    push("--quant-bits", g.quant_bits.to_string());
    push("--index-bits", g.index_bits.to_string());
    push("--hier-bits", g.hier_bits.to_string());
    match a.unit {
        Unit::Translate => {
            if let Some(t) = a.design.table_depth {
                push("--table-depth", t.to_string());
            }
            if a.design.binary64 {
                v.push("--binary64".into());
            }
        }
        Unit::Merge | Unit::Merger => {
            let mode = super::merge::parse_mode(&a.design.mode)?;
            push("--inputs", a.design.inputs.to_string());
            push("--mode", mode.to_string());
            if a.unit == Unit::Merger {
                if let Some(c) = a.capacity_bits {
                    push("--capacity-bits", c.to_string());
                }
                if let Some(l) = a.leaf_bits {
                    push("--leaf-bits", l.to_string());
                }
            }
        }
    }
    Ok(v)
}

/// Writes `report` (a `--unit merger` run) into the ledger folder `dir`.
fn record(a: &Args, report: &Report, dir: &Path) -> Result<PathBuf, String> {
    let m = report
        .merger
        .as_ref()
        .ok_or("--ledger: the run has no merger report")?;
    let args = run_args(a)?;
    let entry = cosim::ledger::Entry {
        format: cosim::ledger::FORMAT.into(),
        unit: "merger".into(),
        top: m.top.clone(),
        engine: a.engine.name().into(),
        args,
        seed: a.seed,
        // As asked: a failing run stops early, and says so by not passing.
        count: a.count.unwrap_or(DEFAULT_COUNT),
        passed: report.passed,
        mismatches: report.counts.mismatches,
        cycles: report.counts.cycles,
        wall_seconds: report.counts.wall_seconds,
        netlist_sha256: m.netlist_sha256.clone(),
        stimulus_sha256: m.stimulus_sha256.clone(),
        hiermerge_version: env!("CARGO_PKG_VERSION").into(),
    };
    entry.write_into(dir).map_err(|e| format!("--ledger: {e}"))
}

/// The merging module's stage to run: `--stage`, else merge-level with
/// `--vectors` (its files hold merge_level records), else the module.
fn merge_stage(a: &Args) -> Result<MergeStage, String> {
    match (a.stage, &a.vectors) {
        (Some(MergeStage::Module), Some(_)) => Err(
            "--stage module takes no --vectors (vectors files hold merge_level records): \
             use --stage merge-level, or --seed/--count for the module"
                .into(),
        ),
        (Some(s), _) => Ok(s),
        (None, Some(_)) => Ok(MergeStage::MergeLevel),
        (None, None) => Ok(MergeStage::Module),
    }
}

/// An engine factory for `module` / `design` (`true`: able to trace).
fn factory<'a>(
    choice: EngineChoice,
    module: &'a rtl_gen::Module,
    design: &'a Design,
) -> Result<impl FnMut(bool) -> cosim::Result<Box<dyn Engine>> + 'a, String> {
    let kind = match choice {
        EngineChoice::Verilator => Some(EngineKind::Verilator),
        EngineChoice::Iverilog => Some(EngineKind::Icarus),
        EngineChoice::Ir => None,
    };
    if let Some(k) = kind {
        k.check_tools().map_err(|e| e.to_string())?;
    }
    Ok(move |trace: bool| -> cosim::Result<Box<dyn Engine>> {
        match kind {
            Some(k) => open_engine(k, design, trace),
            None => Ok(Box::new(IrEngine::new(module, design)?)),
        }
    })
}

fn bar(len: u64, json: bool) -> ProgressBar {
    if json {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} {msg} [{elapsed_precise} / ~{eta}]")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    pb
}

fn vcd_path(a: &Args, unit: &str) -> PathBuf {
    a.vcd_dir
        .join(format!("{unit}-{}-seed{}.vcd", a.engine.name(), a.seed))
}

pub fn main(a: Args) -> CmdResult {
    check_stall(a.stall).map_err(|e| format!("--stall: {e}"))?;
    if a.count == Some(0) {
        return Err("--count 0: expected at least one transaction".into());
    }
    let flip = flip_expected()?;
    if a.stage.is_some() && a.unit != Unit::Merge {
        return Err("--stage applies to --unit merge only".into());
    }
    if (a.capacity_bits.is_some() || a.leaf_bits.is_some()) && a.unit != Unit::Merger {
        return Err("--capacity-bits and --leaf-bits apply to --unit merger only".into());
    }
    let patchable = match a.unit {
        Unit::Translate => false,
        Unit::Merge => merge_stage(&a)? == MergeStage::Module,
        Unit::Merger => true,
    };
    if verilog_patch()?.is_some() && !patchable {
        return Err(format!(
            "{PATCH_FROM_VAR} applies to --unit merge (the module) and --unit merger only"
        ));
    }
    if a.ledger.is_some() {
        if a.unit != Unit::Merger {
            return Err("--ledger applies to --unit merger only".into());
        }
        if flip.is_some() || verilog_patch()?.is_some() {
            return Err(format!(
                "--ledger records real runs only: unset {FLIP_EXPECTED_VAR}, {PATCH_FROM_VAR} and {PATCH_TO_VAR}"
            ));
        }
    }
    let dir = tempfile::tempdir().map_err(|e| format!("temporary directory: {e}"))?;
    let report = match a.unit {
        Unit::Translate => run_translate(&a, &a.design.translate_design()?, flip, dir.path())?,
        Unit::Merge => match merge_stage(&a)? {
            MergeStage::Module => {
                run_merge_module(&a, &a.design.merge_design()?, flip, dir.path())?
            }
            MergeStage::MergeLevel => run_merge(&a, &a.design.merge_design()?, flip, dir.path())?,
        },
        Unit::Merger => run_merger(&a, &a.design.merge_design()?, flip, dir.path())?,
    };
    if let Some(dir) = &a.ledger {
        let path = record(&a, &report, dir)?;
        if !a.json {
            eprintln!("recorded in the ledger: {}", path.display());
        }
    }
    let passed = report.passed;
    let summary = report.first_mismatch.as_ref().map(|m| {
        format!(
            "transaction {} at cycle {}: {}",
            m.transaction, m.cycle, m.what
        )
    });
    emit(a.json, &report, print_text)?;
    if passed {
        Ok(())
    } else {
        Err(format!(
            "co-simulation failed: {}; reproduce: {}",
            summary.unwrap_or_else(|| "see the report".into()),
            report.reproduce.clone().unwrap_or_default()
        ))
    }
}

fn run_translate(
    a: &Args,
    design: &TranslateDesign,
    flip: Option<usize>,
    dir: &Path,
) -> Result<Report, String> {
    let txns = match &a.vectors {
        Some(p) => {
            read_translate_vectors(p, design)
                .map_err(|e| e.to_string())?
                .1
        }
        None => {
            let count = usize::try_from(a.count.unwrap_or(DEFAULT_COUNT))
                .map_err(|_| "--count is too large".to_string())?;
            generate(design, a.seed, count).map_err(|e| e.to_string())?
        }
    };
    let module = rtl_gen::translate::translate_unit(design);
    let cdesign = design_from_module(&module, dir).map_err(|e| e.to_string())?;
    let mut make = factory(a.engine, &module, &cdesign)?;
    let config = RunConfig {
        seed: a.seed,
        stall: a.stall,
        flip_expected: flip,
    };
    let pb = bar(txns.len() as u64, a.json);
    let result = translate::run_with_vcd_on_mismatch(
        &mut make,
        design,
        &txns,
        &config,
        Some(vcd_path(a, "translate")),
        VCD_RADIUS,
        &mut |done, cycle| {
            pb.set_position(done);
            pb.set_message(format!("cycle {cycle}"));
        },
    );
    pb.finish_and_clear();
    let n = txns.len() as u64;
    let (counts, first, vcd) = match result {
        Ok(o) => {
            let counts = Counts {
                transactions: n,
                records: n,
                nodes: n,
                mismatches: 0,
                cycles: o.cycles,
                wall_seconds: o.wall.as_secs_f64(),
            };
            (counts, None, None)
        }
        Err(Failure::Engine(e)) => return Err(e.to_string()),
        Err(Failure::Mismatch(m)) => {
            let counts = Counts {
                transactions: n,
                records: n,
                nodes: n,
                mismatches: 1,
                cycles: m.cycle,
                wall_seconds: 0.0,
            };
            let first = MismatchReport {
                transaction: m.transaction as u64,
                stream: None,
                beat: None,
                kind: m.kind.to_string(),
                cycle: m.cycle,
                seed: m.seed,
                what: m.what.clone(),
                fields: m
                    .fields
                    .iter()
                    .map(|f| FieldReport {
                        name: f.name.clone(),
                        expected: format!("{:#x}", f.expected),
                        got: format!("{:#x}", f.got),
                        differs: f.differs(),
                    })
                    .collect(),
            };
            (counts, Some(first), m.vcd.clone())
        }
    };
    finish_report(a, "translate_unit", flip, counts, first, vcd.as_ref())
}

fn run_merge(
    a: &Args,
    design: &MergeDesign,
    flip: Option<usize>,
    dir: &Path,
) -> Result<Report, String> {
    let levels = match &a.vectors {
        Some(p) => merge::read_levels(p, design)?,
        None => {
            let count = usize::try_from(a.count.unwrap_or(DEFAULT_COUNT))
                .map_err(|_| "--count is too large".to_string())?;
            merge::generate_levels(design, a.seed, count).map_err(|e| e.to_string())?
        }
    };
    let vectors = merge::bench_vectors(&levels, flip).map_err(|e| e.to_string())?;
    let module = merge::merge_level_module(&design.params);
    let cdesign = design_from_module(&module, dir).map_err(|e| e.to_string())?;
    let mut make = factory(a.engine, &module, &cdesign)?;
    let expected_outputs: u64 = levels.iter().map(|l| l.outputs.len() as u64).sum();
    let config = merge::RunConfig {
        seed: a.seed,
        stall: a.stall,
        reproduce: Some(reproduce(a, flip)?),
    };
    let pb = bar(expected_outputs, a.json);
    let report = merge::run_with_vcd_on_mismatch(
        &mut make,
        &design.params,
        &vectors,
        &config,
        Some(vcd_path(a, "merge")),
        VCD_RADIUS,
        &mut |outputs, cycle| {
            pb.set_position(outputs);
            pb.set_message(format!("cycle {cycle}"));
        },
    )
    .map_err(|e| e.to_string())?;
    pb.finish_and_clear();
    // The level (transaction) of an input beat.
    let level_of = |beat: u64| -> u64 {
        let mut end = 0u64;
        for (n, l) in levels.iter().enumerate() {
            end += l.inputs.len() as u64;
            if beat < end {
                return n as u64;
            }
        }
        levels.len() as u64
    };
    let passed = report.passed();
    let mut first = report.first_mismatch.as_ref().map(|m| MismatchReport {
        transaction: level_of(m.input_id),
        stream: None,
        beat: None,
        kind: merge::STAGE.to_string(),
        cycle: m.cycle,
        seed: a.seed,
        what: format!("output beat {} differs", m.output_index),
        fields: m
            .fields
            .iter()
            .map(|f| FieldReport {
                name: f.name.clone(),
                expected: f.expected.clone(),
                got: f.got.clone(),
                differs: f.differs(),
            })
            .collect(),
    });
    if first.is_none() && !passed {
        first = Some(MismatchReport {
            transaction: level_of(report.inputs_sent),
            stream: None,
            beat: None,
            kind: merge::STAGE.to_string(),
            cycle: report.hang.as_ref().map_or(report.cycles, |h| h.cycle),
            seed: a.seed,
            what: match &report.hang {
                Some(h) => format!("no handshake for {} cycles", h.idle_cycles),
                None => format!("outputs lost or duplicated: {}", report.accounting),
            },
            fields: Vec::new(),
        });
    }
    let counts = Counts {
        transactions: levels.len() as u64,
        records: report.inputs_sent,
        nodes: report.outputs_received,
        mismatches: report.mismatches,
        cycles: report.cycles,
        wall_seconds: report.wall.as_secs_f64(),
    };
    finish_report(a, merge::STAGE, flip, counts, first, report.vcd.as_ref())
}

/// The multi-stream engine `choice` names, its tools checked.
fn module_engine(choice: EngineChoice) -> Result<ModuleEngine, String> {
    let (engine, kind) = match choice {
        EngineChoice::Ir => return Ok(ModuleEngine::Ir),
        EngineChoice::Verilator => (ModuleEngine::Verilator, EngineKind::Verilator),
        EngineChoice::Iverilog => (ModuleEngine::Iverilog, EngineKind::Icarus),
    };
    kind.check_tools().map_err(|e| e.to_string())?;
    Ok(engine)
}

/// How a multi-stream unit's run is driven: the flags' seed and stall, its
/// VCD under `--vcd-dir`, the Verilog patch hook.
fn bench_config(a: &Args, stage: &str) -> Result<merge_module::RunConfig, String> {
    Ok(merge_module::RunConfig {
        seed: a.seed,
        stall: a.stall,
        vcd_path: Some(vcd_path(a, stage)),
        vcd_radius: VCD_RADIUS,
        verilog_patch: verilog_patch()?,
    })
}

/// The report of a multi-stream unit's first mismatched beat: its merge,
/// stream and beat, each field of the stream's layout expected against got.
/// `beat_is` says where the beat index counts from (`""`, ` of its chunk`).
fn stream_mismatch(kind: &str, m: &ModuleMismatch, seed: u64, beat_is: &str) -> MismatchReport {
    MismatchReport {
        transaction: m.merge as u64,
        stream: Some(m.stream.clone()),
        beat: Some(m.beat),
        kind: kind.to_string(),
        cycle: m.cycle,
        seed,
        what: format!(
            "`{}` beat {}{beat_is} (merge {}) differs",
            m.stream, m.beat, m.merge
        ),
        fields: m
            .fields
            .iter()
            .map(|(name, expected, got)| FieldReport {
                name: name.clone(),
                expected: expected.clone(),
                got: got.clone(),
                differs: expected != got,
            })
            .collect(),
    }
}

/// What a run counted (the report's counts, [`finish_report`]).
#[derive(Serialize)]
struct Counts {
    transactions: u64,
    /// Input records (translate: transactions; merge: beats on in0..;
    /// merge-level: input beats; merger: beats into its merging module).
    records: u64,
    /// Output records (translate: transactions; merge: report and out
    /// beats; merge-level: base-node/reference beats; merger: node
    /// records written).
    nodes: u64,
    mismatches: u64,
    cycles: u64,
    /// Of the bench: the Verilator build and the Icarus compile excluded.
    wall_seconds: f64,
}

/// The report of a finished run: its counts, the rates derived from them,
/// and on a failure the reproduce command.
fn finish_report(
    a: &Args,
    stage: &'static str,
    flip: Option<usize>,
    counts: Counts,
    first_mismatch: Option<MismatchReport>,
    vcd: Option<&PathBuf>,
) -> Result<Report, String> {
    let passed = first_mismatch.is_none();
    let per_cycle = |n: u64| n as f64 / counts.cycles.max(1) as f64;
    Ok(Report {
        unit: a.unit,
        stage,
        engine: a.engine.name(),
        seed: a.seed,
        stall: a.stall,
        vectors: a.vectors.as_ref().map(|p| p.display().to_string()),
        passed,
        records_per_cycle: per_cycle(counts.records),
        nodes_per_cycle: per_cycle(counts.nodes),
        cycles_per_second: crate::report::per_second(counts.cycles as f64, counts.wall_seconds),
        counts,
        first_mismatch,
        vcd: vcd.map(|p| p.display().to_string()),
        reproduce: if passed {
            None
        } else {
            Some(reproduce(a, flip)?)
        },
        merger: None,
    })
}

/// `--unit merge`: seeded merges through the merging module, every stream
/// with its own stall pattern, 10,000 merges at a time.
fn run_merge_module(
    a: &Args,
    design: &MergeDesign,
    flip: Option<usize>,
    dir: &Path,
) -> Result<Report, String> {
    let count = usize::try_from(a.count.unwrap_or(DEFAULT_COUNT))
        .map_err(|_| "--count is too large".to_string())?;
    let engine = module_engine(a.engine)?;
    let run = merge_module::LongRun {
        count,
        seed: a.seed,
        most_voxels: merge_module::DEFAULT_MOST_VOXELS,
        flip_expected: flip,
        chunk: cosim::units::chunked::CHUNK,
        bench: bench_config(a, merge_module::STAGE)?,
    };
    if !a.json {
        eprintln!(
            "running {count} merges on {} in chunks of {}",
            a.engine.name(),
            cosim::units::chunked::CHUNK
        );
    }
    let pb = bar(count as u64, a.json);
    let o = merge_module::run_chunked(design, engine, &run, dir, &mut |merges, cycle| {
        pb.set_position(merges);
        pb.set_message(format!("cycle {cycle}"));
    });
    pb.finish_and_clear();
    let o = o.map_err(|e| e.to_string())?;
    let stage = merge_module::STAGE;
    let end = RunEnd {
        failed: !o.passed(),
        started: o.cfg_accepted,
        cycles: o.cycles,
        hang: o.hang.as_ref(),
        missing: &o.missing,
        status: o.status_failure(),
    };
    let first = multi_stream_failure(
        stage,
        a.seed,
        o.first_mismatch.as_ref(),
        " of its chunk",
        end,
    );
    let counts = Counts {
        transactions: o.merges as u64,
        records: o.data_beats_in,
        nodes: o.beats_out,
        mismatches: o.mismatches,
        cycles: o.cycles,
        wall_seconds: o.wall.as_secs_f64(),
    };
    finish_report(a, stage, flip, counts, first, o.vcd.as_ref())
}

/// The hierarchy merger `a` asks for, validated.
fn merger_config(a: &Args, design: &MergeDesign) -> Result<rtl_gen::merge::MergerConfig, String> {
    let mut c = rtl_gen::merge::MergerConfig::new(*design);
    if let Some(bits) = a.capacity_bits {
        c.sizes.capacity_bits = bits;
    }
    if let Some(bits) = a.leaf_bits {
        c.sizes.leaf_bits = bits;
    }
    c.validate()
        .map_err(|e| format!("hierarchy merger configuration: {e}"))?;
    Ok(c)
}

/// A `--unit merger` run as the ledger (SPEC 10.2) needs to regenerate it.
pub struct MergerRun {
    pub config: rtl_gen::merge::MergerConfig,
    pub engine: &'static str,
    pub seed: u64,
    pub count: usize,
    pub stall: f64,
}

/// What the `hiermerge cosim` arguments `args` (without the program and
/// subcommand names) run, when they are a `--unit merger` run.
pub fn merger_run(args: &[String]) -> Result<MergerRun, String> {
    #[derive(clap::Parser)]
    #[command(name = "hiermerge cosim", no_binary_name = true)]
    struct Line {
        #[command(flatten)]
        args: Args,
    }
    let a = <Line as clap::Parser>::try_parse_from(args)
        .map_err(|e| {
            // clap's first line names the argument and what was wrong.
            let text = e.to_string();
            let what = text.lines().next().unwrap_or_default();
            format!(
                "`{}`: {}",
                args.join(" "),
                what.trim_start_matches("error: ")
            )
        })?
        .args;
    if a.unit != Unit::Merger {
        return Err(format!("`{}`: expected --unit merger", args.join(" ")));
    }
    check_stall(a.stall).map_err(|e| format!("--stall: {e}"))?;
    Ok(MergerRun {
        config: merger_config(&a, &a.design.merge_design()?)?,
        engine: a.engine.name(),
        seed: a.seed,
        count: usize::try_from(a.count.unwrap_or(DEFAULT_COUNT))
            .map_err(|_| "--count is too large".to_string())?,
        stall: a.stall,
    })
}

/// `--unit merger`: seeded random merges through the hierarchy merger,
/// every stream with its own stall pattern, 10,000 merges at a time.
fn run_merger(
    a: &Args,
    design: &MergeDesign,
    flip: Option<usize>,
    dir: &Path,
) -> Result<Report, String> {
    let count = usize::try_from(a.count.unwrap_or(DEFAULT_COUNT))
        .map_err(|_| "--count is too large".to_string())?;
    if a.vectors.is_some() {
        return Err("--unit merger takes no --vectors: use --seed/--count".into());
    }
    let engine = module_engine(a.engine)?;
    let c = merger_config(a, design)?;
    let config = merger::RunConfig {
        bench: bench_config(a, merger::STAGE)?,
        count,
        flip_expected: flip,
    };
    if !a.json {
        eprintln!(
            "running {count} merges on {} in chunks of {}",
            a.engine.name(),
            merger::CHUNK
        );
    }
    let pb = bar(count as u64, a.json);
    let o = merger::run(&c, engine, &config, dir, &mut |merges, cycle| {
        pb.set_position(merges);
        pb.set_message(format!("cycle {cycle}"));
    });
    pb.finish_and_clear();
    let o = o.map_err(|e| e.to_string())?;
    let (t, s) = (&o.totals, &o.stats);
    let stage = merger::STAGE;
    let end = RunEnd {
        failed: !o.passed(),
        started: t.cfg_accepted,
        cycles: t.cycles,
        hang: t.hang.as_ref(),
        missing: &t.missing,
        status: t.status_failure(),
    };
    let mismatch = t.first_mismatch.as_ref();
    let first = multi_stream_failure(stage, a.seed, mismatch, " of its chunk", end);
    let counts = Counts {
        transactions: t.merges as u64,
        records: s.module_in,
        nodes: s.records,
        mismatches: t.mismatches,
        cycles: t.cycles,
        wall_seconds: t.wall.as_secs_f64(),
    };
    let mut report = finish_report(a, stage, flip, counts, first, t.vcd.as_ref())?;
    report.merger = Some(MergerReport {
        chunks: t.chunks as u64,
        refused: s.refused as u64,
        fetch_errors: s.fetch_errors as u64,
        refs_written: s.refs,
        beats_in: t.cfg_accepted + t.data_beats_in,
        beats_out: t.beats_out,
        leaves_above: s.leaves_above as u64,
        materialized: s.materialized as u64,
        several_roots: s.several_roots as u64,
        multi_pass: s.multi_pass as u64,
        descents: s.descents,
        done_pulses: t.done_pulses,
        golden_seconds: t.golden_wall.as_secs_f64(),
        top: rtl_gen::merge::hierarchy_merger_name(&c),
        netlist_sha256: o.netlist_sha256.clone(),
        stimulus_sha256: o.stimulus_sha256.clone(),
    });
    Ok(report)
}

fn print_text(r: &Report) {
    println!(
        "{} ({}) on {}: {} transactions, {} records in, {} out, {} cycles ({:.3} records/cycle, {:.3} nodes/cycle), {} mismatches, {:.2} s",
        r.unit_name(),
        r.stage,
        r.engine,
        r.counts.transactions,
        r.counts.records,
        r.counts.nodes,
        r.counts.cycles,
        r.records_per_cycle,
        r.nodes_per_cycle,
        r.counts.mismatches,
        r.counts.wall_seconds
    );
    if let Some(m) = &r.first_mismatch {
        println!(
            "MISMATCH: transaction {} ({}), cycle {}, seed {}: {}",
            m.transaction, m.kind, m.cycle, m.seed, m.what
        );
        for f in &m.fields {
            println!(
                "  {}{}: expected {} got {}",
                if f.differs { "*" } else { " " },
                f.name,
                f.expected,
                f.got
            );
        }
    }
    if let Some(v) = &r.vcd {
        println!("VCD: {v}");
    }
    if let Some(c) = &r.reproduce {
        println!("reproduce: {c}");
    }
}

impl Report {
    fn unit_name(&self) -> &'static str {
        match self.unit {
            Unit::Translate => "translate",
            Unit::Merge => "merge",
            Unit::Merger => "merger",
        }
    }
}

/// How a multi-stream run ended, for its failure report.
struct RunEnd<'a> {
    /// Anything wrong: a mismatch, a hang, missing beats, a status rule.
    failed: bool,
    /// Transactions started (`cfg` beats accepted).
    started: u64,
    cycles: u64,
    hang: Option<&'a cosim::tb::Hang>,
    missing: &'a [(String, usize)],
    /// What the status outputs (`done`, `idle`) got wrong.
    status: Option<String>,
}

/// The first failure of a multi-stream run (merging module, hierarchy
/// merger): its first mismatched beat ([`stream_mismatch`]), else, when it
/// failed, [`no_mismatch_failure`]; None when it passed.
fn multi_stream_failure(
    kind: &str,
    seed: u64,
    mismatch: Option<&ModuleMismatch>,
    beat_is: &str,
    end: RunEnd,
) -> Option<MismatchReport> {
    match mismatch {
        Some(m) => Some(stream_mismatch(kind, m, seed, beat_is)),
        None if end.failed => Some(no_mismatch_failure(kind, seed, end)),
        None => None,
    }
}

/// The report of a multi-stream run that failed without a mismatched beat:
/// a hang, expected beats that never came, or a status output (`done`,
/// `idle`) that broke its rule; its transaction is the last one started.
fn no_mismatch_failure(kind: &str, seed: u64, end: RunEnd) -> MismatchReport {
    let missing: Vec<String> = end
        .missing
        .iter()
        .filter(|m| m.1 > 0)
        .map(|(s, n)| format!("{n} `{s}` beats"))
        .collect();
    MismatchReport {
        transaction: end.started.saturating_sub(1),
        stream: None,
        beat: None,
        kind: kind.to_string(),
        cycle: end.hang.map_or(end.cycles, |h| h.cycle),
        seed,
        what: match (end.hang, missing.is_empty()) {
            (Some(h), _) => format!(
                "no handshake for {} cycles; missing {}",
                h.idle_cycles,
                missing.join(", ")
            ),
            (None, false) => format!("missing {}", missing.join(", ")),
            (None, true) => end.status.unwrap_or_default(),
        },
        fields: Vec::new(),
    }
}
