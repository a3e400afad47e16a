//! `--unit merger`: seeded random merges through the hierarchy merger top,
//! its run as the long-run ledger regenerates it, and its ledger entry.

use std::path::{Path, PathBuf};

use cosim::tb::{Stalls, StreamStalls};
use cosim::units::merger;
use golden::merge::merge_module::MergeDesign;

use super::command_line::run_args;
use super::report::{
    chunked_failure, finish_report, Counts, MergerReport, MismatchReport, Report, StoreReport,
};
use super::{bar, bench_config, count, module_engine, Args, Unit, DEFAULT_COUNT};

/// The hierarchy merger of `design` with the flags `--capacity-bits`
/// and `--leaf-bits`, validated.
pub fn merger_config(
    design: &MergeDesign,
    capacity_bits: Option<u32>,
    leaf_bits: Option<u32>,
) -> Result<rtl_gen::merge::MergerConfig, String> {
    let mut c = rtl_gen::merge::MergerConfig::new(*design);
    if let Some(bits) = capacity_bits {
        c.sizes.capacity_bits = bits;
    }
    if let Some(bits) = leaf_bits {
        c.sizes.leaf_bits = bits;
    }
    c.validate()
        .map_err(|e| format!("hierarchy merger configuration: {e}"))?;
    Ok(c)
}

/// The hierarchy merger `a` asks for, validated.
fn merger_config_of(
    a: &Args,
    design: &MergeDesign,
) -> Result<rtl_gen::merge::MergerConfig, String> {
    let mut c = merger_config(design, a.capacity_bits, a.leaf_bits)?;
    if let Some(port) = a.store_port {
        c.sizes.store_port = port;
        c.validate()
            .map_err(|e| format!("hierarchy merger configuration: {e}"))?;
    }
    Ok(c)
}

/// The merges `--merges` asks for (random when not given).
pub(super) fn merges_of(a: &Args) -> merger::Merges {
    a.merges.unwrap_or(super::MergesChoice::Random).merges()
}

/// A `--unit merger` or `--unit hierarchy` run as the ledger (SPEC 10.2)
/// needs to regenerate it.
pub struct LedgerRun {
    /// `merger` or `hierarchy`.
    pub unit: &'static str,
    /// The top module, as the generator names the configuration.
    pub top: String,
    pub engine: &'static str,
    pub seed: u64,
    pub count: usize,
    pub stall: Stalls,
    pub stream_stalls: StreamStalls,
    design: LedgerDesign,
}

enum LedgerDesign {
    Merger {
        config: rtl_gen::merge::MergerConfig,
        merges: merger::Merges,
    },
    Hierarchy {
        config: rtl_gen::merge::HierarchyUnitConfig,
        merges: merger::Merges,
    },
}

impl LedgerRun {
    /// The netlist digest of the configuration as generated today.
    pub fn netlist_digest(&self) -> Result<String, String> {
        match &self.design {
            LedgerDesign::Merger { config, .. } => merger::netlist_digest(config),
            LedgerDesign::Hierarchy { config, .. } => {
                cosim::units::hierarchy_unit::netlist_digest(config)
            }
        }
        .map_err(|e| e.to_string())
    }

    /// The stimulus digest of the run as golden draws it today.
    pub fn stimulus_digest(&self) -> Result<String, String> {
        match &self.design {
            LedgerDesign::Merger { config, merges } => {
                let stalls = (self.stall, &self.stream_stalls);
                merger::stimulus_digest(config, self.seed, self.count, stalls, *merges)
            }
            LedgerDesign::Hierarchy { config, merges } => {
                let cases = cosim::units::hierarchy_unit::Cases {
                    count: self.count,
                    merges: *merges,
                    flip: None,
                };
                let stalls = (self.stall, &self.stream_stalls);
                cosim::units::hierarchy_unit::stimulus_digest(config, self.seed, cases, stalls)
            }
        }
        .map_err(|e| e.to_string())
    }
}

/// What the `hiermerge cosim` arguments `args` (without the program and
/// subcommand names) run, when they are a `--unit merger` or `--unit
/// hierarchy` run.
pub fn ledger_run(args: &[String]) -> Result<LedgerRun, String> {
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
    let design = &a.design.merge_design()?;
    let (unit, top, design) = match a.unit {
        Unit::Merger => {
            let config = merger_config_of(&a, design)?;
            let top = rtl_gen::merge::hierarchy_merger_name(&config);
            let merges = merges_of(&a);
            ("merger", top, LedgerDesign::Merger { config, merges })
        }
        Unit::Hierarchy => {
            let config = super::hierarchy::config_of(&a, design)?;
            let top = rtl_gen::merge::hierarchy_unit_name(&config);
            let merges = merges_of(&a);
            ("hierarchy", top, LedgerDesign::Hierarchy { config, merges })
        }
        _ => {
            return Err(format!(
                "`{}`: expected --unit merger or --unit hierarchy",
                args.join(" ")
            ))
        }
    };
    Ok(LedgerRun {
        unit,
        top,
        engine: a.engine.name(),
        seed: a.seed,
        count: count(&a)?,
        stall: super::stalls(&a)?,
        stream_stalls: super::stream_stalls(&a)?,
        design,
    })
}

/// `--unit merger`: seeded random merges through the hierarchy merger,
/// every stream with its own stall pattern, 10,000 merges at a time.
pub(super) fn run(
    a: &Args,
    design: &MergeDesign,
    flip: Option<usize>,
    dir: &Path,
) -> Result<Report, String> {
    let engine = module_engine(a.engine)?;
    let c = merger_config_of(a, design)?;
    if let Some(path) = &a.vectors {
        return replay(a, &c, flip, path, engine, dir);
    }
    let count = count(a)?;
    let config = merger::RunConfig {
        bench: bench_config(a, merger::STAGE)?,
        count,
        merges: merges_of(a),
        flip_expected: flip,
        store_latency: a.store_latency.unwrap_or(1),
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
    let first = chunked_failure(stage, a.seed, t).or_else(|| store_failure(a, &o));
    if t.passed() {
        super::bins::merger(c.design.inputs, s);
    }
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
        leaf_overflows: s.leaf_overflows as u64,
        materialized: s.materialized as u64,
        several_roots: s.several_roots as u64,
        multi_pass: s.multi_pass as u64,
        descents: s.descents,
        done_pulses: t.done_pulses,
        golden_seconds: t.golden_wall.as_secs_f64(),
        top: rtl_gen::merge::hierarchy_merger_name(&c),
        netlist_sha256: o.netlist_sha256.clone(),
        stimulus_sha256: o.stimulus_sha256.clone(),
        store: o.store.as_ref().map(|st| store_report(&c, a, &o, st)),
    });
    Ok(report)
}

/// The shared store port's figures: reads against the port's one read per
/// clock (SPEC 8.15). A record costs `reads / records` reads, so the port
/// allows `records / reads` records per cycle, and the run's share of that
/// is `reads / cycles`, whichever records are counted.
fn store_report(
    c: &rtl_gen::merge::MergerConfig,
    a: &Args,
    o: &merger::Outcome,
    st: &merger::StoreOutcome,
) -> StoreReport {
    let (t, s) = (&o.totals, &o.stats);
    let cycles = t.cycles.max(1) as f64;
    let reads = st.stats.reads.max(1) as f64;
    StoreReport {
        port: match c.sizes.store_port {
            golden::merge::merger::store_port::StorePort::Shared { tag_bits } => {
                format!("shared:{tag_bits}")
            }
            golden::merge::merger::store_port::StorePort::PerUnit => "per-unit".into(),
        },
        latency: a.store_latency.unwrap_or(1),
        reads: st.stats.reads,
        expected_reads: st.expected_reads,
        reads_per_cycle: st.stats.reads as f64 / cycles,
        records_per_cycle: s.module_in as f64 / cycles,
        records_allowed_per_cycle: s.module_in as f64 / reads,
        nodes_per_cycle: s.records as f64 / cycles,
        nodes_allowed_per_cycle: s.records as f64 / reads,
        of_port: st.stats.reads as f64 / cycles,
        read_window_cycles: st.stats.window_cycles(),
        reads_per_window_cycle: st.stats.reads as f64 / st.stats.window_cycles().max(1) as f64,
    }
}

/// The report of a shared-port run whose reads broke the store's rules
/// (a read outside the merge's store, or another number of reads than
/// golden's units make), when nothing else failed first.
fn store_failure(a: &Args, o: &merger::Outcome) -> Option<MismatchReport> {
    let what = o.store.as_ref()?.failure.clone()?;
    Some(MismatchReport {
        transaction: o.totals.cfg_accepted.saturating_sub(1),
        stream: Some("store_req".into()),
        beat: None,
        kind: merger::STAGE.into(),
        cycle: o.totals.cycles,
        seed: a.seed,
        what,
        fields: Vec::new(),
    })
}

/// `--unit merger --vectors FILE` (`hiermerge vectors --unit merger`):
/// the file's merges through the merger `c` as one chunk, its header's
/// parameters checked against `c`'s. The flip hook flips merge `n`'s
/// expected `header` beat, as in a generated run. The file holds beats,
/// not golden's transactions, so neither the merger's outcome counts
/// (`merger` in the report) nor its functional bins come from a replay:
/// `records` counts the beats the store answered with, `nodes` the node
/// records the file expects.
fn replay(
    a: &Args,
    c: &rtl_gen::merge::MergerConfig,
    flip: Option<usize>,
    path: &Path,
    engine: merger::MergerEngine,
    dir: &Path,
) -> Result<Report, String> {
    let e = |e: cosim::CosimError| e.to_string();
    let mut streams = merger::streams_from_vectors(c, path).map_err(e)?;
    if let Some(n) = flip.filter(|&n| n < streams.merges()) {
        merger::flip_header(&mut streams, n).map_err(e)?;
    }
    let bench = bench_config(a, merger::STAGE)?;
    if !a.json {
        eprintln!(
            "replaying {} merges of {} on {}",
            streams.merges(),
            path.display(),
            a.engine.name()
        );
    }
    let t = merger::run_streams(c, &streams, engine, &bench, dir).map_err(e)?;
    let written = streams
        .outputs
        .iter()
        .find(|s| s.name == "nodes")
        .map_or(0, |s| s.beats.len() as u64);
    let counts = Counts {
        transactions: t.merges as u64,
        records: t.data_beats_in,
        nodes: written,
        mismatches: t.mismatches,
        cycles: t.cycles,
        wall_seconds: t.wall.as_secs_f64(),
    };
    let first = chunked_failure(merger::STAGE, a.seed, &t);
    finish_report(a, merger::STAGE, flip, counts, first, t.vcd.as_ref())
}

/// Writes `report` (a `--unit merger` or `--unit hierarchy` run) into the
/// ledger folder `dir`.
pub(super) fn record(a: &Args, report: &Report, dir: &Path) -> Result<PathBuf, String> {
    let (unit, top, netlist, stimulus) = match (&report.merger, &report.hierarchy) {
        (Some(m), _) => ("merger", &m.top, &m.netlist_sha256, &m.stimulus_sha256),
        (None, Some(h)) => ("hierarchy", &h.top, &h.netlist_sha256, &h.stimulus_sha256),
        (None, None) => return Err("--ledger: the run has no merger or hierarchy report".into()),
    };
    let args = run_args(a)?;
    let entry = cosim::ledger::Entry {
        format: cosim::ledger::FORMAT.into(),
        unit: unit.into(),
        top: top.clone(),
        engine: a.engine.name().into(),
        args,
        seed: a.seed,
        // As asked: a failing run stops early, and says so by not passing.
        count: a.count.unwrap_or(DEFAULT_COUNT),
        passed: report.passed,
        mismatches: report.counts.mismatches,
        cycles: report.counts.cycles,
        wall_seconds: report.counts.wall_seconds,
        netlist_sha256: netlist.clone(),
        stimulus_sha256: stimulus.clone(),
        hiermerge_version: env!("CARGO_PKG_VERSION").into(),
    };
    entry.write_into(dir).map_err(|e| format!("--ledger: {e}"))
}
