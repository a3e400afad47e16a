//! `hiermerge synth`: area and timing of emitted modules (SPEC 14): generic
//! gates, ECP5 and iCE40 place and route, the critical path by generator
//! line, cached by netlist digest.

mod table;

use std::path::PathBuf;
use std::time::{Duration, Instant};

use cosim::synth::{sources::Netlist, Flow, ModuleReport, Target};
use serde::Serialize;

use super::common::UnitOpts;
use super::gen::{emit_defaults, emit_unit, Unit};
use crate::report::{emit, CmdResult};

/// The units `synth` knows, named as `gen` and `cosim` name them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SynthUnit {
    /// The translation unit.
    Translate,
    /// Every module `gen --unit merge` writes (merging module, its stages,
    /// upper builder, fetcher, record writer, hierarchy merger).
    Merge,
    /// The hierarchy merger top alone.
    Merger,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum TargetArg {
    Generic,
    Ecp5,
    Ice40,
    All,
}

#[derive(clap::Args)]
pub struct Args {
    /// The unit to synthesize; omit with --defaults.
    #[arg(long, value_enum, required_unless_present = "defaults")]
    unit: Option<SynthUnit>,
    /// Every default configuration (every module of verilog/).
    #[arg(long, conflicts_with = "unit")]
    defaults: bool,
    #[command(flatten)]
    design: UnitOpts,
    /// Only these modules (a name or the start of one; repeatable).
    #[arg(long = "module")]
    modules: Vec<String>,
    /// Which flows to run.
    #[arg(long, value_enum, default_value = "all")]
    target: TargetArg,
    /// Place and route with seeds 1..=N and report min/median/max Fmax.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..=100))]
    seeds: u64,
    /// Tool runs at a time (default: the machine's cores).
    #[arg(long)]
    jobs: Option<usize>,
    /// Time limit of each tool run, seconds.
    #[arg(long, default_value_t = 3600)]
    timeout: u64,
    /// The clock goal given to nextpnr, MHz.
    #[arg(long, default_value_t = 100.0)]
    freq: f64,
    /// Print one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

/// The whole report.
#[derive(Serialize)]
pub struct Report {
    pub command: String,
    pub tools: Tools,
    pub targets: Vec<Target>,
    pub seeds: u64,
    pub goal_mhz: f64,
    pub modules: Vec<ModuleReport>,
    /// Modules whose lowest ECP5 Fmax is below the goal.
    pub below_goal: Vec<String>,
    /// Modules that do not fit an LFE5U-85F (not placed).
    pub ecp5_unplaced: Vec<String>,
    pub computed: usize,
    pub seconds: f64,
}

#[derive(Serialize)]
pub struct Tools {
    pub yosys: String,
    pub nextpnr_ecp5: Option<String>,
    pub nextpnr_ice40: Option<String>,
}

fn targets(t: TargetArg) -> Vec<Target> {
    match t {
        TargetArg::Generic => vec![Target::Generic],
        TargetArg::Ecp5 => vec![Target::Ecp5],
        TargetArg::Ice40 => vec![Target::Ice40],
        TargetArg::All => vec![Target::Generic, Target::Ecp5, Target::Ice40],
    }
}

/// The emitted files of what `a` asks for, and the modules to synthesize.
fn configuration(a: &Args, dir: &std::path::Path) -> Result<(Netlist, Vec<String>), String> {
    let files: Vec<PathBuf> = match (a.defaults, a.unit) {
        (true, _) => emit_defaults(dir)?,
        (false, Some(SynthUnit::Translate)) => emit_unit(Unit::Translate, &a.design, dir)?,
        (false, Some(_)) => emit_unit(Unit::Merge, &a.design, dir)?,
        (false, None) => return Err("expected --unit translate|merge|merger, or --defaults".into()),
    };
    let netlist = Netlist::read(&files).map_err(|e| e.to_string())?;
    let mut tops: Vec<String> = netlist.modules.keys().cloned().collect();
    if a.unit == Some(SynthUnit::Merger) {
        tops.retain(|m| m.starts_with("hierarchy_merger_"));
    }
    if !a.modules.is_empty() {
        tops.retain(|m| a.modules.iter().any(|p| m.starts_with(p.as_str())));
        if tops.is_empty() {
            return Err(format!(
                "--module {}: no such module in this configuration (it has: {})",
                a.modules.join(", "),
                netlist
                    .modules
                    .keys()
                    .cloned()
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
    }
    Ok((netlist, tops))
}

pub fn main(a: Args) -> CmdResult {
    let start = Instant::now();
    if !(a.freq > 0.0 && a.freq.is_finite()) {
        return Err(format!(
            "--freq {}: expected a positive number of MHz",
            a.freq
        ));
    }
    let work = tempfile::tempdir().map_err(|e| format!("a temporary folder: {e}"))?;
    let (netlist, tops) = configuration(&a, work.path())?;
    let targets = targets(a.target);
    let root = cosim::cache::cache_root();
    let mut flow = Flow::new(&targets, root, Duration::from_secs(a.timeout), a.freq)
        .map_err(|e| format!("synth: {e}"))?;
    flow.progress = Box::new(|line| eprintln!("synth: {line}"));
    let jobs = a
        .jobs
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let modules = cosim::synth::run_all(&flow, &netlist, &tops, &targets, a.seeds, jobs)
        .map_err(|e| e.to_string())?;
    let below_goal = modules
        .iter()
        .filter(|m| m.ecp5.as_ref().is_some_and(|e| e.meets_goal == Some(false)))
        .map(|m| m.module.clone())
        .collect();
    let ecp5_unplaced = modules
        .iter()
        .filter(|m| m.ecp5.as_ref().is_some_and(|e| !e.fits))
        .map(|m| m.module.clone())
        .collect();
    let report = Report {
        command: std::env::args().skip(1).collect::<Vec<_>>().join(" "),
        tools: Tools {
            yosys: flow.yosys.version.clone(),
            nextpnr_ecp5: flow.ecp5.as_ref().map(|t| t.version.clone()),
            nextpnr_ice40: flow.ice40.as_ref().map(|t| t.version.clone()),
        },
        targets,
        seeds: a.seeds,
        goal_mhz: a.freq,
        computed: modules.iter().map(|m| m.computed.len()).sum(),
        below_goal,
        ecp5_unplaced,
        modules,
        seconds: start.elapsed().as_secs_f64(),
    };
    emit(a.json, &report, table::print)
}
