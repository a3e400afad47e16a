//! Shared helpers for rtl-gen's tests: external tools, random numbers.
#![allow(dead_code)]

use rtl_gen::{Bits, Module};
use std::path::{Path, PathBuf};
use std::process::Command;

/// True when `tool` runs. When it is missing: a failure under `CI=true`,
/// otherwise a printed install hint and `false` (the caller skips).
pub fn require_tool(tool: &str) -> bool {
    let ok = Command::new(tool)
        .arg(if tool == "verilator" {
            "--version"
        } else {
            "-V"
        })
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if ok {
        return true;
    }
    if std::env::var("CI").map(|v| v == "true").unwrap_or(false) {
        panic!("{tool} is required under CI=true but was not found on PATH");
    }
    eprintln!(
        "SKIPPED: {tool} not found; install it with `apt-get install verilator iverilog yosys`"
    );
    false
}

/// `verilator --lint-only -Wall` on the files with `top` as top module;
/// any warning or error is a failure.
pub fn verilator_lint(files: &[PathBuf], top: &str) -> Result<(), String> {
    let out = Command::new("verilator")
        .args(["--lint-only", "-Wall", "--top-module", top])
        .args(files)
        .output()
        .map_err(|e| format!("running verilator: {e}"))?;
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    if !out.status.success() || text.contains("%Warning") || text.contains("%Error") {
        return Err(format!("verilator lint of {top} failed:\n{text}"));
    }
    Ok(())
}

/// `yosys`: read, `synth -top`, `check -assert`, `stat`; fails on any
/// problem and on any latch cell in the result.
pub fn yosys_synth(files: &[PathBuf], top: &str) -> Result<(), String> {
    let reads: Vec<String> = files
        .iter()
        .map(|f| format!("read_verilog {};", f.display()))
        .collect();
    let script = format!("{} synth -top {top}; check -assert; stat", reads.join(" "));
    let out = Command::new("yosys")
        .args(["-p", &script])
        .output()
        .map_err(|e| format!("running yosys: {e}"))?;
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    if !out.status.success() {
        let tail: Vec<&str> = text.lines().rev().take(30).collect();
        return Err(format!(
            "yosys failed on {top}:\n{}",
            tail.into_iter().rev().collect::<Vec<_>>().join("\n")
        ));
    }
    for latch in ["$dlatch", "$_DLATCH", "Latch inferred"] {
        if text.contains(latch) {
            return Err(format!("yosys found a latch ({latch}) in {top}"));
        }
    }
    Ok(())
}

/// Writes the design into `dir` and returns its files and top name.
pub fn write(m: &Module, dir: &Path) -> (Vec<PathBuf>, String) {
    let files =
        rtl_gen::write_design(m, dir).unwrap_or_else(|e| panic!("write_design({}): {e}", m.name()));
    (files, m.name())
}

/// Lints (and, when `synth`, synthesizes) a design; skips when tools are missing outside CI.
pub fn check_tools(m: &Module, synth: bool) {
    // The validator's unused-logic warnings mirror Verilator's UNUSED lint:
    // a design without warnings must lint clean, and the test designs have none.
    let warnings = m.validate_design().unwrap_or_else(|e| panic!("{e}"));
    assert!(
        warnings.is_empty(),
        "{}: {}",
        m.name(),
        rtl_gen::Diagnostics(warnings.clone())
    );
    let dir = tempfile::tempdir().expect("temp dir");
    let (files, top) = write(m, dir.path());
    if require_tool("verilator") {
        verilator_lint(&files, &top).unwrap_or_else(|e| panic!("{e}"));
    }
    if synth && require_tool("yosys") {
        yosys_synth(&files, &top).unwrap_or_else(|e| panic!("{e}"));
    }
}

/// SplitMix64: small, deterministic, good enough for test stimulus.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    pub fn bit(&mut self) -> bool {
        self.next_u64() & 1 == 1
    }

    /// True with probability `num/den`.
    pub fn chance(&mut self, num: u64, den: u64) -> bool {
        self.next_u64() % den < num
    }

    pub fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n.max(1)
    }

    /// Uniformly random bits of `width`.
    pub fn bits(&mut self, width: u32) -> Vec<bool> {
        (0..width).map(|_| self.bit()).collect()
    }
}

/// Edge-case operands of `width` bits, LSB first: zero, one, all ones,
/// most negative, most positive, alternating.
pub fn edge_values(width: u32) -> Vec<Vec<bool>> {
    let w = width as usize;
    let mut v = vec![vec![false; w], vec![true; w]];
    let mut one = vec![false; w];
    one[0] = true;
    v.push(one);
    let mut min = vec![false; w];
    min[w - 1] = true;
    v.push(min);
    let mut max = vec![true; w];
    max[w - 1] = false;
    v.push(max);
    v.push((0..w).map(|i| i % 2 == 0).collect());
    v
}

pub fn to_bits(v: &[bool]) -> Bits {
    Bits::from_bools(v)
}

pub fn from_bits(b: &Bits) -> Vec<bool> {
    (0..b.width()).map(|i| b.bit(i)).collect()
}
