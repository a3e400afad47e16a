//! `hiermerge formal`: the formal proofs of the stream primitives and the
//! small units (SPEC 11.1) with SymbiYosys, one `sby` run per check, each
//! reported PASS or FAIL with its mode, depth and time.

use std::path::PathBuf;
use std::time::Instant;

use cosim::formal::{formal_tools, prepare, run_check, CheckResult};
use cosim::units::merge_module::VerilogPatch;
use rtl_gen::formal::{units, Check};
use serde::Serialize;

use crate::report::{emit, CmdResult};

/// The test hook (SPEC 10.1, 11.1): the emitted Verilog of the one `--unit`
/// is patched, text `..._FROM` (exactly once) to `..._TO`, before sby reads it.
pub const PATCH_FROM_VAR: &str = "HIERMERGE_FORMAL_PATCH_FROM";
/// See [`PATCH_FROM_VAR`].
pub const PATCH_TO_VAR: &str = "HIERMERGE_FORMAL_PATCH_TO";

#[derive(clap::Args)]
pub struct Args {
    /// The units to prove (repeatable; default: every unit of the default
    /// set): pipeline_reg, skid_buffer, fifo, merge_priority,
    /// overlap_counter, merge_level, upper_level, morton_merge,
    /// per_node_decider, translate; or a larger unit: per_node_network,
    /// merge_module_overlap, merge_module_per_node, upper_builder,
    /// upper_builder_default, fetcher, fetcher_per_node, record_writer,
    /// hierarchy_merger, hierarchy_merger_per_node, store_port (the
    /// merger's shared store front end, handshake by BMC), and at a small
    /// configuration, every check: fetcher_small, fetcher_per_node_small,
    /// record_writer_small, hierarchy_merger_small,
    /// hierarchy_merger_per_node_small, hierarchy_merger_store_port (the
    /// merger top behind one shared store port), hierarchy_unit_small (the
    /// hierarchy unit around the small merger top).
    #[arg(long = "unit")]
    units: Vec<String>,
    /// Every unit of the default set (the default when neither --unit nor
    /// --large is given).
    #[arg(long, conflicts_with = "units")]
    all: bool,
    /// The larger units (the merging modules, the per-node network, the
    /// upper builder at D = 2, the handshakes of the upper builder at
    /// D = 16, the fetchers, the record writer and the merger tops, and
    /// those at a small configuration; about 15 minutes);
    /// with --all, after the default set.
    #[arg(long, conflicts_with = "units")]
    large: bool,
    /// Only these checks (repeatable): handshake, flow, determined, status.
    #[arg(long = "check")]
    checks: Vec<String>,
    /// BMC depth (and k of k-induction) for every check, instead of each
    /// check's own.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=200))]
    depth: Option<u32>,
    /// Where the designs, harnesses, .sby jobs and sby's folders go.
    #[arg(long, default_value = "out/formal")]
    out: PathBuf,
    /// Time limit of each check, seconds.
    #[arg(long, default_value_t = 600, value_parser = clap::value_parser!(u32).range(1..=86400))]
    timeout: u32,
    /// Print one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
pub struct Report {
    pub command: String,
    pub sby: String,
    pub yosys: String,
    pub boolector: String,
    pub results: Vec<CheckResult>,
    pub passed: usize,
    pub failed: usize,
    pub seconds: f64,
}

fn parse_checks(names: &[String]) -> Result<Vec<Check>, String> {
    names
        .iter()
        .map(|n| {
            Check::ALL
                .into_iter()
                .find(|c| c.name() == n)
                .ok_or_else(|| {
                    format!("--check {n}: expected one of handshake, flow, determined, status")
                })
        })
        .collect()
}

fn patch() -> Result<Option<VerilogPatch>, String> {
    match (std::env::var(PATCH_FROM_VAR), std::env::var(PATCH_TO_VAR)) {
        (Ok(from), Ok(to)) if !from.is_empty() => Ok(Some(VerilogPatch { from, to })),
        (Err(_), Err(_)) => Ok(None),
        _ => Err(format!(
            "{PATCH_FROM_VAR} (not empty) and {PATCH_TO_VAR} go together"
        )),
    }
}

pub fn main(a: Args) -> CmdResult {
    let start = Instant::now();
    let mut names: Vec<String> = a.units.clone();
    if a.units.is_empty() && (a.all || !a.large) {
        names.extend(units::NAMES.iter().map(|s| s.to_string()));
    }
    if a.large {
        names.extend(units::LARGE.iter().map(|s| s.to_string()));
    }
    let mut proofs = Vec::new();
    for n in &names {
        let p = units::by_name(n).ok_or_else(|| {
            format!(
                "--unit {n}: expected one of {}, {}",
                units::NAMES.join(", "),
                units::LARGE.join(", ")
            )
        })?;
        proofs.push((n.clone(), p));
    }
    let only = parse_checks(&a.checks)?;
    let patch = patch()?;
    if patch.is_some() && proofs.len() != 1 {
        return Err(format!("{PATCH_FROM_VAR} applies to one --unit only"));
    }
    let tools = formal_tools().map_err(|e| format!("formal: {e}"))?;
    let mut results = Vec::new();
    for (name, proof) in &proofs {
        let folder = prepare(proof, &a.out, a.depth, a.timeout, patch.as_ref())
            .map_err(|e| format!("formal --unit {name}: {e}"))?;
        for &(check, _, _) in &proof.checks {
            if !only.is_empty() && !only.contains(&check) {
                continue;
            }
            let r = run_check(&tools, name, proof, &folder, check, a.depth, a.timeout)
                .map_err(|e| format!("formal --unit {name} ({}): {e}", check.name()))?;
            if !a.json {
                eprintln!(
                    "formal: {name} {}: {} ({} {}, {:.1} s)",
                    r.check, r.status, r.mode, r.depth, r.seconds
                );
            }
            results.push(r);
        }
    }
    if results.is_empty() {
        return Err("formal: no check selected (see --check)".into());
    }
    let failed = results.iter().filter(|r| !r.passed()).count();
    let report = Report {
        command: std::env::args().skip(1).collect::<Vec<_>>().join(" "),
        sby: tools.sby.program.display().to_string(),
        yosys: tools.yosys.version.clone(),
        boolector: tools.boolector.clone(),
        passed: results.len() - failed,
        failed,
        results,
        seconds: start.elapsed().as_secs_f64(),
    };
    emit(a.json, &report, print)?;
    if failed > 0 {
        let names: Vec<String> = report
            .results
            .iter()
            .filter(|r| !r.passed())
            .map(|r| format!("{} {} ({})", r.unit, r.check, r.status))
            .collect();
        return Err(format!(
            "{failed} of {} checks not proven: {}",
            report.results.len(),
            names.join(", ")
        ));
    }
    Ok(())
}

fn print(r: &Report) {
    println!(
        "| unit | module | check | mode | depth | result | time |\n|---|---|---|---|---|---|---|"
    );
    for c in &r.results {
        let mut result = c.status.clone();
        if !c.failed.is_empty() {
            result += &format!(": {}", c.failed.join(", "));
        }
        if let Some(s) = c.step {
            result += &format!(" at step {s}");
        }
        println!(
            "| {} | {} | {} | {} | {} | {} | {:.1} s |",
            c.unit, c.module, c.check, c.mode, c.depth, result, c.seconds
        );
    }
    for c in r.results.iter().filter(|c| !c.passed()) {
        let trace = c
            .trace
            .as_ref()
            .map(|t| format!(", counterexample {}", t.display()))
            .unwrap_or_default();
        println!("{} {}: log {}{trace}", c.unit, c.check, c.log.display());
    }
    println!(
        "{} passed, {} failed in {:.1} s ({}; {}; boolector {})",
        r.passed, r.failed, r.seconds, r.sby, r.yosys, r.boolector
    );
}
