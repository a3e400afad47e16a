//! What the `hiermerge cosim` CLI tests share: running the binary, reading
//! its JSON report, the tool check (a missing simulator fails under
//! CI=true), the emitted Verilog the patch hook edits, and the checks of a
//! deliberately broken run.

// Each test binary includes this module and uses a part of it.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

use serde_json::Value;

/// The test hook's variables (`src/cmd/cosim/mod.rs`).
pub const FLIP: &str = "HIERMERGE_COSIM_FLIP_EXPECTED";
pub const PATCH_FROM: &str = "HIERMERGE_COSIM_PATCH_FROM";
pub const PATCH_TO: &str = "HIERMERGE_COSIM_PATCH_TO";

/// `hiermerge <args>` with `env` set and no test hook inherited.
pub fn hiermerge(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_hiermerge"));
    c.args(args)
        .env_remove(FLIP)
        .env_remove(PATCH_FROM)
        .env_remove(PATCH_TO);
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().expect("hiermerge runs")
}

/// The JSON report of a run that must have succeeded (its stderr shown
/// when it did not).
pub fn succeeded(o: &Output) -> Value {
    assert!(
        o.status.success(),
        "stderr:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    json_of(o)
}

/// The one JSON object a `--json` run prints on stdout.
pub fn json_of(o: &Output) -> Value {
    let text = String::from_utf8_lossy(&o.stdout);
    serde_json::from_str(text.trim()).unwrap_or_else(|e| {
        panic!(
            "stdout is not one JSON object ({e}):\n{text}\nstderr:\n{}",
            String::from_utf8_lossy(&o.stderr)
        )
    })
}

/// True when `tool` is installed; under CI=true a missing tool fails the
/// test, elsewhere it is skipped saying how to install it.
pub fn tool_present(tool: &str) -> bool {
    if cosim::tools::tool_available(tool) {
        return true;
    }
    if cosim::tools::ci_mode() {
        panic!("CI=true and {tool} missing: {}", cosim::tools::INSTALL_HINT);
    }
    eprintln!("SKIPPING: {tool} missing; {}", cosim::tools::INSTALL_HINT);
    false
}

/// The emitted Verilog of `module`'s line `assign <port> = <rhs>;` and its
/// `<rhs>`, as the patch hook will find them.
pub fn emitted_assign(module: &rtl_gen::Module, port: &str) -> (String, String) {
    let head = format!("assign {port} = ");
    let line = emitted_line(module, &head);
    let rhs = line[head.len()..].trim_end_matches(';').to_string();
    (line, rhs)
}

/// The first line of `module`'s emitted Verilog (instances included) that
/// starts with `head`, trimmed.
pub fn emitted_line(module: &rtl_gen::Module, head: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let design = cosim::from_rtl::design_from_module(module, dir.path()).unwrap();
    let text: String = design
        .verilog_files
        .iter()
        .map(|f| std::fs::read_to_string(f).unwrap())
        .collect();
    text.lines()
        .map(str::trim)
        .find(|l| l.starts_with(head))
        .unwrap_or_else(|| panic!("`{}` has no `{head}...`", design.top))
        .to_string()
}

/// The width of `module`'s port `name`.
pub fn port_width(module: &rtl_gen::Module, name: &str) -> u32 {
    module
        .ports()
        .into_iter()
        .find(|p| p.name == name)
        .map(|p| p.width)
        .unwrap_or_else(|| panic!("no port `{name}`"))
}

/// A passing run's report: exit 0, `passed`, no mismatch, no
/// first-mismatch report, `transactions` transactions.
pub fn assert_passed(o: &Output, transactions: u64) -> Value {
    assert!(
        o.status.success(),
        "stderr:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let r = json_of(o);
    assert_eq!(r["passed"], true, "{r}");
    assert_eq!(r["mismatches"], 0, "{r}");
    assert_eq!(r["transactions"], transactions, "{r}");
    assert!(r["first_mismatch"].is_null(), "{r}");
    r
}

/// The names of a mismatch report's decoded fields, in order.
pub fn field_names(m: &Value) -> Vec<&str> {
    m["fields"]
        .as_array()
        .unwrap_or_else(|| panic!("no fields: {m}"))
        .iter()
        .map(|f| f["name"].as_str().unwrap())
        .collect()
}

/// A failed run: exit non-zero, `passed: false`, a reproduce command that
/// names `hook` (a test hook variable).
pub fn assert_fails(o: &Output, r: &Value, hook: &str) {
    assert!(!o.status.success(), "a broken run must fail: {r}");
    assert_eq!(r["passed"], false, "{r}");
    let reproduce = r["reproduce"].as_str().unwrap();
    assert!(reproduce.contains(hook), "{r}");
}

/// The first mismatch's decoded fields: exactly one differs, and it is
/// `field`; more than one field decoded.
pub fn assert_one_field_differs(m: &Value, field: &str) {
    let fields = m["fields"].as_array().unwrap();
    assert!(fields.len() > 1, "decoded field by field: {m}");
    let differing: Vec<&Value> = fields.iter().filter(|f| f["differs"] == true).collect();
    assert_eq!(differing.len(), 1, "one bit, one field: {m}");
    assert_eq!(differing[0]["name"], field, "{m}");
    assert_ne!(differing[0]["expected"], differing[0]["got"], "{m}");
}

/// The report's VCD exists under `vcd_dir` and holds value changes.
pub fn assert_vcd(r: &Value, vcd_dir: &Path) {
    let path = r["vcd"].as_str().unwrap_or_else(|| panic!("no VCD: {r}"));
    assert!(Path::new(path).starts_with(vcd_dir), "{path}");
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    assert!(text.contains("$enddefinitions"), "{path}: no VCD header");
    let stamps = text.lines().filter(|l| l.starts_with('#')).count();
    assert!(stamps > 2, "{path}: {stamps} time stamps");
}
