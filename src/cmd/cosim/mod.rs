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
//! run is caught and reported. With `--unit merge-module` (the module) and `--unit
//! merger`, `HIERMERGE_COSIM_PATCH_FROM=<text>` and
//! `HIERMERGE_COSIM_PATCH_TO=<text>` replace the one occurrence of the first
//! in the emitted Verilog by the second before Verilator or Icarus reads it:
//! a deliberately broken unit.
//!
//! One file per part: the arguments and the hooks here, the runs per unit
//! (`translate`, `merge`, `merger`), the report (`report`) and the command
//! line that reproduces a run (`command_line`).

mod bins;
mod command_line;
pub(crate) mod hierarchy;
mod merge;
mod merger;
mod report;
mod translate;

use std::path::{Path, PathBuf};

use cosim::ir_engine::IrEngine;
use cosim::tb::{Stalls, StreamStalls};
use cosim::units::merge_module::{self, ModuleEngine};
use cosim::waves::WaveFormat;
use cosim::{open_engine, open_tracing_engine, Design, Engine, EngineKind};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

use super::common::UnitOpts;
use crate::report::{emit, CmdResult};
use report::print_text;

pub use merger::{ledger_run, merger_config};

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
    /// Icarus Verilog (4-state, X/Z checked; --unit merge-module: the whole bench
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

/// The merges `--unit merger --merges` asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum MergesChoice {
    /// Random merges of small soups (the long runs').
    Random,
    /// The hard merges, then random merges over every scale.
    Hard,
}

impl MergesChoice {
    fn merges(self) -> cosim::units::merger::Merges {
        match self {
            MergesChoice::Random => cosim::units::merger::Merges::Random,
            MergesChoice::Hard => cosim::units::merger::Merges::Hard,
        }
    }
}

/// The waveform format `--waves` asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum WavesChoice {
    /// Value change dump (text).
    Vcd,
    /// Fast Signal Trace (GTKWave's compressed format).
    Fst,
}

/// `FROM:TO`, two cycles, `FROM <= TO`.
fn parse_window(s: &str) -> Result<(u64, u64), String> {
    let (a, b) = s
        .split_once(':')
        .ok_or_else(|| format!("`{s}`: expected FROM:TO (two cycles)"))?;
    let cycle =
        |x: &str| super::common::unsigned::<u64>(x).map_err(|e| format!("`{s}`: `{x}`: {e}"));
    let (from, to) = (cycle(a)?, cycle(b)?);
    if from > to {
        return Err(format!("`{s}`: the first cycle is after the last"));
    }
    Ok((from, to))
}

/// Refuses a waveform request the engine and unit cannot meet, before
/// anything is built.
fn check_waves(a: &Args) -> Result<(), String> {
    if a.waves == WavesChoice::Vcd {
        return Ok(());
    }
    let batch = matches!(a.unit, Unit::Merger | Unit::Hierarchy)
        || (a.unit == Unit::MergeModule && merge_stage(a)? == MergeStage::Module);
    match a.engine {
        EngineChoice::Ir => Err("--waves fst: the IR simulator writes VCD only".into()),
        EngineChoice::Iverilog if !batch => Err(
            "--waves fst: Icarus writes FST in its batch runs (--unit merge-module, --unit merger), \
             whose vvp ends with the run; here it runs through a pipe: use VCD, or Verilator"
                .into(),
        ),
        EngineChoice::Iverilog if a.wave_scope.is_some() => Err(
            "--waves fst --wave-scope: the Icarus batch's FST holds every signal; an FST of \
             one scope comes from Verilator (or give VCD with the scope)"
                .into(),
        ),
        _ => Ok(()),
    }
}

/// The unit `hiermerge cosim` runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Unit {
    /// The translation unit.
    Translate,
    /// The merging module (or, with `--stage merge-level`, its S614 stage).
    MergeModule,
    /// The hierarchy merger, S610-S618 as one top (SPEC 8.15).
    Merger,
    /// The hierarchy unit: the translation unit and the merger top behind
    /// one command stream (docs/hardware.md 8.16).
    Hierarchy,
}

impl Unit {
    /// The unit as `--unit` spells it.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Unit::Translate => "translate",
            Unit::MergeModule => "merge-module",
            Unit::Merger => "merger",
            Unit::Hierarchy => "hierarchy",
        }
    }
}

/// Which part of the merging module `--unit merge-module` runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum MergeStage {
    /// The whole merging module (`merge_module_unit`): a transaction is one
    /// merge, seeded random stimulus on every stream.
    Module,
    /// Only its S614 merge-level stage (`merge_level_unit`): a transaction
    /// is one level; what `vectors --stage merge-level` files hold.
    MergeLevel,
}

/// --unit translate: the whole translation unit (determine and apply
/// streams). --unit merge-module: the merging module as one unit (streams cfg,
/// in0.., report, out; a transaction is one merge; Icarus runs the
/// multi-stream batch, the whole bench inside one vvp run); with
/// `--stage merge-level` its S614 stage alone (unit 506; a transaction is
/// one level). --unit merger: the hierarchy merger (S610-S618; a
/// transaction is one merge, store responses precomputed from golden;
/// run in chunks of 10,000 merges). --unit hierarchy: the hierarchy unit
/// (the translation unit and the merger top behind one command stream; a
/// transaction is one merge, its translations written by determine
/// commands before it).
#[derive(clap::Args, Clone)]
pub struct Args {
    /// translate: the translation unit; merge-module: the merging module; merger:
    /// the hierarchy merger; hierarchy: the hierarchy unit (translation
    /// unit and merger top).
    #[arg(long, value_enum)]
    unit: Unit,
    /// --unit merge-module only: `module` (default) or `merge-level`, the S614
    /// stage alone (the default with a --vectors file of stage records).
    #[arg(long, value_enum)]
    stage: Option<MergeStage>,
    #[arg(long, value_enum, default_value = "verilator")]
    engine: EngineChoice,
    /// Run the transactions of this vectors file (`hiermerge vectors`;
    /// its header's parameters must equal the design's). Merge: a file of
    /// whole merges runs the module; one of stage records runs its
    /// merge_level records (--stage merge-level). Merger: a file of its
    /// merges (`vectors --unit merger`).
    #[arg(long, conflicts_with = "count")]
    vectors: Option<PathBuf>,
    /// Seed of the generated transactions and of the stall patterns.
    #[arg(long, default_value_t = 1, value_parser = super::common::unsigned::<u64>)]
    seed: u64,
    /// Transactions to generate (translate: determine/apply records;
    /// merge: merges; --stage merge-level: levels).
    #[arg(long, value_parser = super::common::unsigned::<u64>)]
    count: Option<u64>,
    /// With `--stalls coin`: the probability that the driver holds valid
    /// low and the monitor ready low, per decision (0 <= P <= 0.9; default
    /// 0.3).
    #[arg(long)]
    stall: Option<f64>,
    /// The stall pattern of every driver (valid) and monitor (ready), each
    /// stream with its own seed: `coin` (a draw per decision, probability
    /// --stall), `bursty[:S,G]` (alternating runs of 1..=S stalls and 1..=G
    /// go, lengths drawn from the seed; default 16,16), `periodic[:K/N]` (K
    /// stalls of every N decisions at a seeded phase; default 1/3), `none`.
    #[arg(long, default_value = "coin")]
    stalls: String,
    /// One stream's own pattern, `STREAM=PATTERN` (`header=bursty:200,2`;
    /// a coin as `coin:P`), in place of `--stalls` on that stream alone;
    /// repeat for more streams. The multi-stream units (merge-module,
    /// merger, hierarchy) only: e.g. a unit's outputs held while its inputs
    /// flow.
    #[arg(long = "stall-stream", value_name = "STREAM=PATTERN")]
    stall_stream: Vec<String>,
    /// Directory of the waveform written on a mismatch (or asked by
    /// --wave-window).
    #[arg(long = "vcd-dir", default_value = "out/cosim")]
    vcd_dir: PathBuf,
    /// Waveform format: `vcd` (every engine) or `fst` (Verilator; Icarus
    /// with --unit merge-module and merger, whose batch vvp ends with the run).
    #[arg(long, value_enum, default_value = "vcd")]
    waves: WavesChoice,
    /// Trace only this instance of the design and everything below it
    /// (instance names from the top down, `u_a.u_b`).
    #[arg(long = "wave-scope")]
    wave_scope: Option<String>,
    /// Trace cycles FROM:TO whatever the outcome (merge, merger: of the
    /// first chunk of 10,000 merges), instead of 20 cycles either side of
    /// the first mismatch.
    #[arg(long = "wave-window", value_parser = parse_window)]
    wave_window: Option<(u64, u64)>,
    #[command(flatten)]
    design: UnitOpts,
    /// --unit merger only: log2 of the writer's entries per buffer
    /// (default: the merger's default, min(10, index bits - 1)).
    #[arg(long = "capacity-bits")]
    capacity_bits: Option<u32>,
    /// --unit merger only: log2 of each leaf FIFO's entries (default 4).
    #[arg(long = "leaf-bits")]
    leaf_bits: Option<u32>,
    /// --unit merger only: which merges. `random`: 1..=k small random soups
    /// (the long runs'); `hard`: the named hard merges first (real meshes,
    /// several roots, a fetcher error, refused ranges), then random merges
    /// whose soups span every scale (the coverage regression's). Default
    /// `random`.
    #[arg(long, value_enum)]
    merges: Option<MergesChoice>,
    /// --unit merger only: how the fetchers and the writer reach the store.
    /// `per-unit` (the default): each with its own read streams, their
    /// responses precomputed by golden; `shared` or `shared:T`: one read
    /// port (`store_req` / `store_resp`) behind the store front end, its tag
    /// FIFO of 2^T reads in flight (default T = 3), answered by a store
    /// model after --store-latency clocks.
    #[arg(long = "store-port", value_parser = parse_store_port)]
    store_port: Option<golden::merge::merger::store_port::StorePort>,
    /// --unit merger --store-port shared only: clocks from a read taken to
    /// its answer, at the earliest (default 1).
    #[arg(long = "store-latency")]
    store_latency: Option<u64>,
    /// --unit merger only: also record the run, passed or failed, as an
    /// entry of the long-run ledger in this folder (SPEC 10.2; `hiermerge
    /// ledger` checks the entries against today's code).
    #[arg(long)]
    ledger: Option<PathBuf>,
    /// Build Verilator with line/branch and toggle coverage and write the
    /// code coverage of this run (raw `coverage.dat`, summary, annotated
    /// source, uncovered points by generator line) and its functional
    /// coverage bins into DIR (SPEC 10.5; `hiermerge coverage` runs the
    /// whole regression).
    #[arg(long, value_name = "DIR", num_args = 0..=1, default_missing_value = "out/coverage")]
    pub(crate) coverage: Option<PathBuf>,
    /// Print one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

const DEFAULT_COUNT: u64 = 10_000;

/// `--store-port`: `per-unit`, `shared` or `shared:T` (T in 1..=8).
pub(crate) fn parse_store_port(
    text: &str,
) -> Result<golden::merge::merger::store_port::StorePort, String> {
    use golden::merge::merger::store_port::StorePort;
    match text {
        "per-unit" => return Ok(StorePort::PerUnit),
        "shared" => return Ok(StorePort::SHARED),
        _ => {}
    }
    let tag_bits = text
        .strip_prefix("shared:")
        .and_then(|t| t.parse::<u32>().ok())
        .filter(|t| (1..=8).contains(t))
        .ok_or_else(|| {
            format!("`{text}`: expected per-unit, shared or shared:T with T in 1..=8 (a tag FIFO of 2^T reads)")
        })?;
    Ok(StorePort::Shared { tag_bits })
}

/// `--stall` when not given.
const DEFAULT_STALL: f64 = 0.3;

/// The stall pattern `--stalls` and `--stall` ask for, checked.
fn stalls(a: &Args) -> Result<Stalls, String> {
    parse_stalls(&a.stalls, a.stall)
}

/// The stall pattern of the flags `--stalls` (`stalls`) and `--stall`
/// (`stall`), checked (also `hiermerge export-tb`'s).
pub fn parse_stalls(stalls: &str, stall: Option<f64>) -> Result<Stalls, String> {
    let coin = stall.unwrap_or(DEFAULT_STALL);
    let s = Stalls::parse(stalls, coin).map_err(|e| match stall {
        Some(_) if stalls == "coin" => format!("--stall: {e}"),
        _ => format!("--stalls: {e}"),
    })?;
    if stall.is_some() && stalls != "coin" {
        return Err(format!(
            "--stall {coin} is the probability of --stalls coin; --stalls {stalls} takes its parameters after a colon"
        ));
    }
    Ok(s)
}

/// The streams' own patterns `--stall-stream` asks for, checked.
fn stream_stalls(a: &Args) -> Result<StreamStalls, String> {
    parse_stream_stalls(&a.stall_stream)
}

/// The `--stall-stream` items `items`, checked (also `hiermerge export-tb`'s).
pub fn parse_stream_stalls(items: &[String]) -> Result<StreamStalls, String> {
    StreamStalls::parse(items.iter().map(String::as_str)).map_err(|e| format!("--stall-stream {e}"))
}

/// Refuses `--stall-stream` items for a unit whose bench has one input and
/// one output stream (`unit`), which `--stalls` already names (also
/// `hiermerge export-tb`'s).
pub fn no_stream_stalls(items: &[String], unit: &str) -> Result<(), String> {
    if items.is_empty() {
        return Ok(());
    }
    Err(format!(
        "--stall-stream: {unit} has one input and one output stream; --stalls sets their pattern"
    ))
}

/// `--count`, or the default, as a number of transactions.
fn count(a: &Args) -> Result<usize, String> {
    let n = a.count.unwrap_or(DEFAULT_COUNT);
    golden::vectors::check_count("--count", n, golden::vectors::MAX_COUNT)?;
    usize::try_from(n).map_err(|_| "--count is too large".to_string())
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

/// The merging module's stage to run: `--stage`, else that of the
/// `--vectors` file (whole merges: the module; stage records:
/// merge-level), else the module.
fn merge_stage(a: &Args) -> Result<MergeStage, String> {
    match (a.stage, &a.vectors) {
        (Some(s), _) => Ok(s),
        (None, Some(p)) if vectors_unit(p).as_deref() == Some("merge_module") => {
            Ok(MergeStage::Module)
        }
        (None, Some(_)) => Ok(MergeStage::MergeLevel),
        (None, None) => Ok(MergeStage::Module),
    }
}

/// The header `unit` of the vectors file `path`, if its first line says
/// one (the reader checks the whole header, and names what is wrong).
fn vectors_unit(path: &Path) -> Option<String> {
    let mut lines = golden::input::open_lines(path, golden::vectors::MAX_FILE_BYTES).ok()?;
    let (_, first) = lines.next_line()?.ok()?;
    let v: serde_json::Value = serde_json::from_str(&first).ok()?;
    v.get("unit")?.as_str().map(String::from)
}

/// An engine factory for `module` / `design` (`true`: able to trace).
fn factory<'a>(
    a: &Args,
    module: &'a rtl_gen::Module,
    design: &'a Design,
) -> Result<impl FnMut(bool) -> cosim::Result<Box<dyn Engine>> + 'a, String> {
    let format = match a.waves {
        WavesChoice::Vcd => WaveFormat::Vcd,
        WavesChoice::Fst => WaveFormat::Fst,
    };
    let scope = a.wave_scope.clone();
    let kind = match a.engine {
        EngineChoice::Verilator => Some(EngineKind::Verilator),
        EngineChoice::Iverilog => Some(EngineKind::Icarus),
        EngineChoice::Ir => None,
    };
    if let Some(k) = kind {
        k.check_tools().map_err(|e| e.to_string())?;
    }
    Ok(move |trace: bool| -> cosim::Result<Box<dyn Engine>> {
        match kind {
            Some(k) if trace => open_tracing_engine(k, design, format, scope.as_deref()),
            Some(k) => open_engine(k, design, false),
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
    let ext = match a.waves {
        WavesChoice::Vcd => "vcd",
        WavesChoice::Fst => "fst",
    };
    a.vcd_dir
        .join(format!("{unit}-{}-seed{}.{ext}", a.engine.name(), a.seed))
}

pub fn main(a: Args) -> CmdResult {
    let Some(dir) = a.coverage.clone() else {
        return run(a);
    };
    if a.engine != EngineChoice::Verilator {
        return Err("--coverage: code coverage comes from Verilator (--engine verilator)".into());
    }
    crate::cmd::coverage::collected(&dir, crate::cmd::coverage::WAIVERS.as_ref(), false, || {
        run(a)
    })
}

const MERGER: &[&str] = &["merger"];
/// Units with a merger top inside.
const WITH_MERGER: &[&str] = &["merger", "hierarchy"];

/// Refuses a flag that `cosim`, `vectors` and `export-tb` share and
/// `unit` does not take, naming it and the units it applies to: the unit
/// parameters of `design`, `--stage`, `--capacity-bits` and `--leaf-bits`
/// (`sizes`), then the command's own `more`.
pub(crate) fn refuse_unit_flags(
    unit: Unit,
    design: &UnitOpts,
    stage: Option<MergeStage>,
    sizes: [Option<u32>; 2],
    more: &[super::common::UnitFlag],
) -> Result<(), String> {
    let mut flags = vec![("--stage", stage.is_some(), &["merge-module"][..])];
    flags.extend(design.unit_flags());
    flags.extend([
        ("--capacity-bits", sizes[0].is_some(), WITH_MERGER),
        ("--leaf-bits", sizes[1].is_some(), WITH_MERGER),
    ]);
    flags.extend_from_slice(more);
    super::common::refuse_flags_of_other_units(unit.name(), &flags)
}

/// Refuses a flag of another unit (naming it and the units it applies
/// to), and a flag of generated merges with a `--vectors` replay.
fn check_flags(a: &Args) -> Result<(), String> {
    let merges = ("--merges", a.merges.is_some(), WITH_MERGER);
    let ledger = ("--ledger", a.ledger.is_some(), WITH_MERGER);
    let sizes = [a.capacity_bits, a.leaf_bits];
    let port = ("--store-port", a.store_port.is_some(), MERGER);
    let latency = ("--store-latency", a.store_latency.is_some(), MERGER);
    refuse_unit_flags(
        a.unit,
        &a.design,
        a.stage,
        sizes,
        &[merges, ledger, port, latency],
    )?;
    let shared = matches!(
        a.store_port,
        Some(golden::merge::merger::store_port::StorePort::Shared { .. })
    );
    if a.store_latency.is_some() && !shared {
        return Err("--store-latency applies to --store-port shared only".into());
    }
    if a.vectors.is_some() {
        // A ledger entry is regenerated from its seed and count (SPEC 10.2).
        for (flag, given) in [
            ("--merges", a.merges.is_some()),
            ("--ledger", a.ledger.is_some()),
        ] {
            if given {
                return Err(format!(
                    "{flag} applies to generated merges (--seed/--count), not to a --vectors replay, whose merges are the file's"
                ));
            }
        }
    }
    Ok(())
}

/// One run: its report printed, an error when it failed.
pub(crate) fn run(a: Args) -> CmdResult {
    stalls(&a)?;
    check_waves(&a)?;
    if a.count == Some(0) {
        return Err("--count 0: expected at least one transaction".into());
    }
    let flip = flip_expected()?;
    check_flags(&a)?;
    let patchable = match a.unit {
        Unit::Translate => false,
        Unit::MergeModule => merge_stage(&a)? == MergeStage::Module,
        Unit::Merger | Unit::Hierarchy => true,
    };
    if verilog_patch()?.is_some() && !patchable {
        return Err(format!(
            "{PATCH_FROM_VAR} applies to --unit merge-module (the module), merger and hierarchy only"
        ));
    }
    if a.ledger.is_some() && (flip.is_some() || verilog_patch()?.is_some()) {
        return Err(format!(
            "--ledger records real runs only: unset {FLIP_EXPECTED_VAR}, {PATCH_FROM_VAR} and {PATCH_TO_VAR}"
        ));
    }
    let dir = tempfile::tempdir().map_err(|e| format!("temporary directory: {e}"))?;
    let report = match a.unit {
        Unit::Translate => translate::run(&a, &a.design.translate_design()?, flip, dir.path())?,
        Unit::MergeModule => match merge_stage(&a)? {
            MergeStage::Module => {
                merge::run_module(&a, &a.design.merge_design()?, flip, dir.path())?
            }
            MergeStage::MergeLevel => {
                merge::run_level(&a, &a.design.merge_design()?, flip, dir.path())?
            }
        },
        Unit::Merger => merger::run(&a, &a.design.merge_design()?, flip, dir.path())?,
        Unit::Hierarchy => hierarchy::run(&a, &a.design.merge_design()?, flip, dir.path())?,
    };
    if let Some(dir) = &a.ledger {
        let path = merger::record(&a, &report, dir)?;
        if !a.json {
            eprintln!("recorded in the ledger: {}", path.display());
        }
    }
    let passed = report.passed;
    if passed {
        bins::stalls(&stalls(&a)?);
    }
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
        stall: stalls(a)?,
        stream_stalls: stream_stalls(a)?,
        vcd_path: Some(vcd_path(a, stage)),
        vcd_radius: VCD_RADIUS,
        wave_scope: a.wave_scope.clone(),
        wave_window: a.wave_window,
        verilog_patch: verilog_patch()?,
    })
}
