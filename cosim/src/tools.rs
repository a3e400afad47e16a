//! Finding the external simulators and saying how to get them.

use crate::error::{CosimError, Result};
use std::process::Command;

/// True when running under CI (`CI=true`), where a missing simulator is a failure.
pub fn ci_mode() -> bool {
    std::env::var("CI")
        .map(|v| v == "true" || v == "1")
        .unwrap_or(false)
}

/// The hint printed when a tool is missing.
pub const INSTALL_HINT: &str =
    "install with `apt-get install verilator iverilog yosys g++ make` (or run scripts/setup)";

/// Run `tool args` and return stdout; a missing tool becomes `ToolMissing`.
pub fn tool_output(tool: &str, args: &[&str]) -> Result<String> {
    let out = Command::new(tool)
        .args(args)
        .output()
        .map_err(|e| CosimError::ToolMissing {
            tool: tool.to_string(),
            hint: format!("{e}; {INSTALL_HINT}"),
        })?;
    if !out.status.success() {
        return Err(CosimError::ToolFailed {
            tool: tool.to_string(),
            command: format!("{tool} {}", args.join(" ")),
            log: String::from_utf8_lossy(&out.stderr).into_owned(),
        });
    }
    Ok(String::from_utf8_lossy(&out.stdout).trim().to_string())
}

/// The first line of `verilator --version`, e.g. "Verilator 5.006 2023-01-22 rev (Debian 5.006-3)".
pub fn verilator_version() -> Result<String> {
    Ok(tool_output("verilator", &["--version"])?
        .lines()
        .next()
        .unwrap_or("")
        .to_string())
}

/// `$VERILATOR_ROOT` as Verilator itself reports it (env var wins).
pub fn verilator_root() -> Result<std::path::PathBuf> {
    if let Ok(root) = std::env::var("VERILATOR_ROOT") {
        if !root.is_empty() {
            return Ok(root.into());
        }
    }
    Ok(tool_output("verilator", &["--getenv", "VERILATOR_ROOT"])?.into())
}

/// Whether `tool` (`verilator`, `iverilog`, `vvp`, `yosys`) is an
/// executable file on `$PATH`. A look-up, not a start: `verilator` is a Perl
/// script taking ~90 ms per call, and every simulator test asks.
pub fn tool_available(tool: &str) -> bool {
    use std::os::unix::fs::PermissionsExt;
    which(tool)
        .and_then(|p| std::fs::metadata(p).ok())
        .is_some_and(|m| m.permissions().mode() & 0o111 != 0)
}

/// Where `tool` resolves on `$PATH`, canonicalized.
pub fn which(tool: &str) -> Option<std::path::PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|dir| dir.join(tool))
        .find(|p| p.is_file())
        .and_then(|p| std::fs::canonicalize(p).ok())
}

/// Facts about the Verilator installation that go into cache keys.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VerilatorFacts {
    /// `verilator --version`, first line.
    pub version: String,
    /// `$VERILATOR_ROOT`.
    pub root: std::path::PathBuf,
    /// `g++ --version`, first line.
    pub cxx_version: String,
}

static FACTS: std::sync::Mutex<Option<VerilatorFacts>> = std::sync::Mutex::new(None);

/// Verilator's version and root and the C++ compiler's version.
///
/// `verilator` is a Perl script taking ~90 ms per call, too slow for a cache
/// hit, so the answers are remembered per process and on disk in `facts_dir`
/// under a name derived from the executables' path, size and modification
/// time (a reinstalled tool gets a new name and is asked again).
pub fn verilator_facts(facts_dir: &std::path::Path) -> Result<VerilatorFacts> {
    if let Some(f) = FACTS.lock().ok().and_then(|g| g.clone()) {
        return Ok(f);
    }
    let identity = tool_identity(&["verilator", "g++"]).ok_or_else(|| CosimError::ToolMissing {
        tool: "verilator".to_string(),
        hint: format!("verilator or g++ not on PATH; {INSTALL_HINT}"),
    })?;
    let root_env = std::env::var("VERILATOR_ROOT").unwrap_or_default();
    let mut key = crate::cache::CacheKey::new();
    key.add("identity", identity.as_bytes())
        .add("root_env", root_env.as_bytes());
    let file = facts_dir.join(format!("verilator-{}.txt", &key.finish()[..24]));
    let facts = match read_facts(&file) {
        Some(f) => f,
        None => {
            let f = VerilatorFacts {
                version: verilator_version()?,
                root: verilator_root()?,
                cxx_version: tool_output("g++", &["--version"])?
                    .lines()
                    .next()
                    .unwrap_or("")
                    .to_string(),
            };
            write_facts(&file, &f);
            f
        }
    };
    if let Ok(mut g) = FACTS.lock() {
        *g = Some(facts.clone());
    }
    Ok(facts)
}

fn tool_identity(tools: &[&str]) -> Option<String> {
    let mut s = String::new();
    for t in tools {
        let p = which(t)?;
        let m = std::fs::metadata(&p).ok()?;
        let mtime = m
            .modified()
            .ok()
            .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
            .map(|d| d.as_nanos())
            .unwrap_or(0);
        s.push_str(&format!("{}:{}:{};", p.display(), m.len(), mtime));
    }
    Some(s)
}

fn read_facts(file: &std::path::Path) -> Option<VerilatorFacts> {
    let text = std::fs::read_to_string(file).ok()?;
    let mut lines = text.lines();
    let version = lines.next()?.to_string();
    let root = lines.next()?.into();
    let cxx_version = lines.next()?.to_string();
    (!version.is_empty()).then_some(VerilatorFacts {
        version,
        root,
        cxx_version,
    })
}

fn write_facts(file: &std::path::Path, f: &VerilatorFacts) {
    // Best effort: a failed write only costs the next process 200 ms.
    if let Some(dir) = file.parent() {
        let _ = std::fs::create_dir_all(dir);
        let tmp = dir.join(format!(".facts-{}", std::process::id()));
        let text = format!("{}\n{}\n{}\n", f.version, f.root.display(), f.cxx_version);
        if std::fs::write(&tmp, text).is_ok() {
            let _ = std::fs::rename(&tmp, file);
        }
    }
}
