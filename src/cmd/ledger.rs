//! `hiermerge ledger`: checks the long-run ledger (SPEC 10.2) against
//! today's code and adds up what it still proves. Each entry's command
//! line is parsed again; its configuration's netlist is regenerated and
//! digested, and (`--stimulus`) its stimulus too. An entry whose digests
//! differ is stale: the design it ran no longer computes what today's does
//! (a rename or a refactor keeps it current: the netlist digest is of the
//! design's structural identity). What is left is summed per configuration
//! and engine, each seed counted once, and the configurations short of
//! `--need` are named. Stale entries are reported, not errors, unless
//! `--strict`; failed and inconsistent entries are always errors.

use std::collections::{BTreeMap, HashMap};
use std::path::PathBuf;

use cosim::ledger::{read_ledger, Entry};
use indicatif::ProgressBar;
use serde::Serialize;

use super::cosim::ledger_run;
use crate::report::{emit, CmdResult};

/// Which entries get their stimulus regenerated (golden, no simulation;
/// about 4-10 s per 10,000 merges).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum StimulusCheck {
    /// None: netlists only.
    None,
    /// The first entry of each configuration.
    First,
    /// Every entry.
    All,
}

#[derive(clap::Args)]
pub struct Args {
    /// The ledger folder.
    #[arg(long, default_value = "longruns")]
    dir: PathBuf,
    /// Whose stimulus to regenerate and compare.
    #[arg(long, value_enum, default_value = "first")]
    stimulus: StimulusCheck,
    /// Merges per configuration and engine the summary asks for, where
    /// no --plan says: with a plan, a configuration and engine needs the
    /// merges its plan lines sum to (Verilator the volume, Icarus the depth).
    #[arg(long, default_value_t = 100_000)]
    need: u64,
    /// A plan: one `hiermerge cosim` argument line per run wanted (`#`
    /// starts a comment); the report then lists the lines no current,
    /// passing entry covers.
    #[arg(long)]
    plan: Option<PathBuf>,
    /// With --plan: print only the lines still to run, one per line (with
    /// --json: `{"missing": [...]}`), and exit 0 whatever the entries'
    /// problems (for scripts/longruns).
    #[arg(long, requires = "plan")]
    missing: bool,
    /// Print only the paths of the stale entries (their netlist, or with
    /// --stimulus their stimulus, changed since the run), one per line
    /// (with --json: `{"stale": [...]}`), and exit 0 whatever the entries'
    /// problems: what scripts/longruns removes before it reruns them.
    #[arg(long, conflicts_with = "missing")]
    stale_paths: bool,
    /// Exit non-zero when an entry is stale, too (by default a stale entry
    /// is reported and its configuration listed as lacking evidence).
    #[arg(long)]
    strict: bool,
    /// Print one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

/// One line of a plan and whether a current, passing entry covers it.
#[derive(Serialize)]
struct PlanLine {
    line: usize,
    args: String,
    top: String,
    engine: String,
    seed: u64,
    count: u64,
    done: bool,
}

/// One entry's verdict.
#[derive(Serialize)]
struct Checked {
    path: String,
    top: String,
    engine: String,
    seed: u64,
    count: u64,
    passed: bool,
    /// The netlist regenerated today has the entry's digest.
    netlist_current: bool,
    /// Some(whether the stimulus regenerated today has the entry's digest).
    stimulus_current: Option<bool>,
    /// The netlist regenerated today has another digest than the entry's.
    netlist_changed: bool,
}

impl Checked {
    /// Its netlist or its stimulus changed since the run.
    fn is_stale(&self) -> bool {
        self.netlist_changed || self.stimulus_current == Some(false)
    }
}

/// What the current, passing entries of one configuration and engine add up to.
#[derive(Serialize, Default, Clone)]
struct Total {
    top: String,
    engine: String,
    runs: u64,
    /// Distinct merges: per seed the longest run.
    merges: u64,
    cycles: u64,
    wall_seconds: f64,
    /// The merges asked for: the plan's lines' sum, else `--need`.
    need: u64,
    /// `merges >= need`.
    met: bool,
}

#[derive(Serialize)]
struct Report {
    dir: String,
    need: u64,
    entries: Vec<Checked>,
    totals: Vec<Total>,
    /// Failed or inconsistent entries, one line each: errors.
    problems: Vec<String>,
    /// Entries whose netlist or stimulus changed since the run, one line
    /// each: no longer evidence about this code.
    stale: Vec<String>,
    /// The configurations and engines (of the entries and the plan) whose
    /// current, passing merges fall short of `need`.
    lacking: Vec<Total>,
    /// With --plan: its lines, each done or not.
    #[serde(skip_serializing_if = "Option::is_none")]
    plan: Option<Vec<PlanLine>>,
}

/// Reads the plan `path`: each line's run, and whether one of `good`
/// (current, passing entries: (top, engine, seed, count)) covers it. An
/// unparsable line is an error naming the file and line.
fn read_plan(
    path: &std::path::Path,
    good: &std::collections::HashSet<(String, String, u64, u64)>,
) -> Result<Vec<PlanLine>, String> {
    let text =
        golden::input::read_text(path, golden::input::MAX_JSON_BYTES).map_err(|e| e.to_string())?;
    let mut out = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let at = |what: String| format!("{} line {}: {what}", path.display(), i + 1);
        let args: Vec<String> = line.split_whitespace().map(String::from).collect();
        let run = ledger_run(&args).map_err(at)?;
        let top = run.top.clone();
        let (engine, seed, count) = (run.engine.to_string(), run.seed, run.count as u64);
        let done = good.contains(&(top.clone(), engine.clone(), seed, count));
        out.push(PlanLine {
            line: i + 1,
            args: line.to_string(),
            top,
            engine,
            seed,
            count,
            done,
        });
    }
    Ok(out)
}

/// Checks one entry; problems found go to `problems`.
fn check(
    path: &str,
    e: &Entry,
    digest_stimulus: bool,
    netlists: &mut HashMap<String, Result<String, String>>,
    problems: &mut Vec<String>,
    stale: &mut Vec<String>,
) -> Checked {
    let mut out = Checked {
        path: path.to_string(),
        top: e.top.clone(),
        engine: e.engine.clone(),
        seed: e.seed,
        count: e.count,
        passed: e.passed,
        netlist_current: false,
        stimulus_current: None,
        netlist_changed: false,
    };
    if !e.passed {
        problems.push(format!(
            "{path}: the run failed ({} mismatches): fix the design, then remove the entry and rerun",
            e.mismatches
        ));
    }
    let run = match ledger_run(&e.args) {
        Ok(r) => r,
        Err(what) => {
            problems.push(format!("{path}: field args: {what}"));
            return out;
        }
    };
    let (count, seed) = (run.count as u64, run.seed);
    if (run.engine, seed, count) != (e.engine.as_str(), e.seed, e.count) {
        problems.push(format!(
            "{path}: fields engine/seed/count ({}, {}, {}) differ from args ({}, {seed}, {count})",
            e.engine, e.seed, e.count, run.engine
        ));
        return out;
    }
    if run.unit != e.unit {
        problems.push(format!(
            "{path}: field unit `{}`, but its args run `--unit {}`",
            e.unit, run.unit
        ));
        return out;
    }
    // `ledger_run` validated the configuration.
    let top = run.top.clone();
    if top != e.top {
        problems.push(format!(
            "{path}: field top `{}`, but its args generate `{top}`",
            e.top
        ));
        return out;
    }
    let digest = netlists.entry(top).or_insert_with(|| run.netlist_digest());
    match digest {
        Ok(d) if *d == e.netlist_sha256 => out.netlist_current = true,
        Ok(d) => {
            out.netlist_changed = true;
            stale.push(format!(
                "{path}: the netlist changed since the run (netlist_sha256 {}, today {}): remove the entry and rerun `hiermerge cosim {} --ledger DIR` (scripts/longruns does both)",
                short(&e.netlist_sha256),
                short(d),
                e.args.join(" ")
            ))
        }
        Err(what) => problems.push(format!("{path}: regenerating the netlist: {what}")),
    }
    if digest_stimulus {
        match run.stimulus_digest() {
            Ok(d) => {
                let current = d == e.stimulus_sha256;
                out.stimulus_current = Some(current);
                if !current {
                    stale.push(format!(
                        "{path}: the stimulus changed since the run (stimulus_sha256 {}, today {}): golden or the random merges changed; remove the entry and rerun it",
                        short(&e.stimulus_sha256),
                        short(&d)
                    ));
                }
            }
            Err(what) => problems.push(format!("{path}: regenerating the stimulus: {what}")),
        }
    }
    out
}

/// The first 12 characters of a digest (all of it when shorter).
fn short(digest: &str) -> &str {
    digest
        .char_indices()
        .nth(12)
        .map_or(digest, |(i, _)| &digest[..i])
}

/// Of one (top, engine): the runs, and per seed the longest run's (count,
/// cycles, wall seconds).
type Seeds = (u64, BTreeMap<u64, (u64, u64, f64)>);

/// The current, passing entries summed per (top, engine).
fn totals(entries: &[(Entry, &Checked)], need: &dyn Fn(&str, &str) -> u64) -> Vec<Total> {
    let mut by: BTreeMap<(String, String), Seeds> = BTreeMap::new();
    for (e, c) in entries {
        if !(c.passed && c.netlist_current && c.stimulus_current != Some(false)) {
            continue;
        }
        let slot = by.entry((e.top.clone(), e.engine.clone())).or_default();
        slot.0 += 1;
        let longest = slot.1.entry(e.seed).or_insert((0, 0, 0.0));
        if e.count > longest.0 {
            *longest = (e.count, e.cycles, e.wall_seconds);
        }
    }
    by.into_iter()
        .map(|((top, engine), (runs, seeds))| {
            let merges = seeds.values().map(|s| s.0).sum();
            let need = need(&top, &engine);
            Total {
                cycles: seeds.values().map(|s| s.1).sum(),
                wall_seconds: seeds.values().map(|s| s.2).sum(),
                met: merges >= need,
                top,
                engine,
                runs,
                merges,
                need,
            }
        })
        .collect()
}

pub fn main(a: Args) -> CmdResult {
    let read = read_ledger(&a.dir).map_err(|e| format!("ledger {}: {e}", a.dir.display()))?;
    let mut problems = Vec::new();
    let mut ledger = Vec::new();
    for (path, entry) in read {
        match entry {
            Ok(e) => ledger.push((path, e)),
            Err(what) => problems.push(what),
        }
    }
    let pb = if a.json {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(ledger.len() as u64)
    };
    let mut netlists = HashMap::new();
    let mut stale = Vec::new();
    let mut first_seen = std::collections::HashSet::new();
    let mut checked = Vec::new();
    for (path, e) in &ledger {
        let shown = path.display().to_string();
        pb.set_message(shown.clone());
        let first = first_seen.insert(e.top.clone());
        let digest_stimulus = match a.stimulus {
            StimulusCheck::None => false,
            StimulusCheck::First => first,
            StimulusCheck::All => true,
        };
        checked.push(check(
            &shown,
            e,
            digest_stimulus,
            &mut netlists,
            &mut problems,
            &mut stale,
        ));
        pb.inc(1);
    }
    pb.finish_and_clear();
    if a.stale_paths {
        #[derive(Serialize)]
        struct Stale<'a> {
            stale: Vec<&'a str>,
        }
        let stale = Stale {
            stale: checked
                .iter()
                .filter(|c| c.is_stale())
                .map(|c| c.path.as_str())
                .collect(),
        };
        return emit(a.json, &stale, |s| {
            s.stale.iter().for_each(|p| println!("{p}"))
        });
    }
    let pairs: Vec<(Entry, &Checked)> = ledger
        .iter()
        .map(|(_, e)| e.clone())
        .zip(checked.iter())
        .collect();
    let good = pairs
        .iter()
        .filter(|(_, c)| c.passed && c.netlist_current && c.stimulus_current != Some(false))
        .map(|(e, _)| (e.top.clone(), e.engine.clone(), e.seed, e.count))
        .collect();
    let plan = a.plan.as_deref().map(|p| read_plan(p, &good)).transpose()?;
    if a.missing {
        #[derive(Serialize)]
        struct Missing {
            missing: Vec<String>,
        }
        let missing = Missing {
            missing: plan
                .iter()
                .flatten()
                .filter(|l| !l.done)
                .map(|l| l.args.clone())
                .collect(),
        };
        return emit(a.json, &missing, |m| {
            m.missing.iter().for_each(|l| println!("{l}"))
        });
    }
    let need = |top: &str, engine: &str| -> u64 {
        let lines = plan
            .iter()
            .flatten()
            .filter(|l| l.top == top && l.engine == engine);
        let planned: u64 = lines.map(|l| l.count).sum();
        if planned > 0 {
            planned
        } else {
            a.need
        }
    };
    let totals = totals(&pairs, &need);
    let lacking = lacking(&ledger, plan.as_deref(), &totals, &need);
    let report = Report {
        dir: a.dir.display().to_string(),
        need: a.need,
        totals,
        entries: checked,
        problems,
        stale,
        lacking,
        plan,
    };
    emit(a.json, &report, print_text)?;
    let stale = if a.strict { report.stale.len() } else { 0 };
    match (report.problems.len(), stale) {
        (0, 0) => Ok(()),
        (0, n) => Err(format!(
            "{n} ledger entries are stale (--strict; listed above)"
        )),
        (n, _) => Err(format!(
            "{n} ledger entries failed or are inconsistent (listed above)"
        )),
    }
}

/// Every (top, engine) of the entries and the plan whose current, passing
/// merges fall short of `need`, with what it has.
fn lacking(
    ledger: &[(PathBuf, Entry)],
    plan: Option<&[PlanLine]>,
    totals: &[Total],
    need: &dyn Fn(&str, &str) -> u64,
) -> Vec<Total> {
    let mut wanted: std::collections::BTreeSet<(String, String)> = ledger
        .iter()
        .map(|(_, e)| (e.top.clone(), e.engine.clone()))
        .collect();
    wanted.extend(
        plan.into_iter()
            .flatten()
            .map(|l| (l.top.clone(), l.engine.clone())),
    );
    wanted
        .into_iter()
        .map(|(top, engine)| {
            totals
                .iter()
                .find(|t| t.top == top && t.engine == engine)
                .cloned()
                .unwrap_or(Total {
                    need: need(&top, &engine),
                    top,
                    engine,
                    ..Total::default()
                })
        })
        .filter(|t| t.merges < t.need)
        .collect()
}

/// Plan lines still to run that the text report shows.
const SHOWN: usize = 5;

fn print_text(r: &Report) {
    println!(
        "{} entries in {}; current and passing, per configuration and engine (each seed once):",
        r.entries.len(),
        r.dir
    );
    println!(
        "{:<58} {:<10} {:>5} {:>9} {:>12} {:>9} {:>9}",
        "top", "engine", "runs", "merges", "cycles", "wall s", "need"
    );
    for t in &r.totals {
        println!(
            "{:<58} {:<10} {:>5} {:>9} {:>12} {:>9.0} {:>9}  {}",
            t.top,
            t.engine,
            t.runs,
            t.merges,
            t.cycles,
            t.wall_seconds,
            t.need,
            if t.met { "met" } else { "not yet" }
        );
    }
    if let Some(plan) = &r.plan {
        let done = plan.iter().filter(|l| l.done).count();
        println!("plan: {done} of {} runs done", plan.len());
        let left: Vec<&PlanLine> = plan.iter().filter(|l| !l.done).collect();
        for l in left.iter().take(SHOWN) {
            println!("  to run (line {}): {}", l.line, l.args);
        }
        if left.len() > SHOWN {
            println!(
                "  ... and {} more (--missing lists them all)",
                left.len() - SHOWN
            );
        }
    }
    for t in &r.lacking {
        println!(
            "lacking evidence: {} on {}: {} current merges of {}",
            t.top, t.engine, t.merges, t.need
        );
    }
    for s in &r.stale {
        println!("stale: {s}");
    }
    for p in &r.problems {
        println!("problem: {p}");
    }
}
