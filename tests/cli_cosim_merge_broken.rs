//! `hiermerge cosim --unit merge` against a deliberately broken merging
//! module: the emitted Verilog patched through the test hook
//! (`HIERMERGE_COSIM_PATCH_FROM` / `_TO`) before Verilator or Icarus reads
//! it. A flipped bit of the `report` stream is caught with the mismatch
//! decoded field by field and a VCD around it that exists, on both engines
//! at the same cycle; a `done` that never pulses, an `idle` that stays low
//! and a `cfg` that is never accepted (a hang, with its VCD) are caught
//! too. Under CI=true a missing Verilator or Icarus fails.

use std::path::Path;
use std::process::{Command, Output};

use golden::vectors::merge::MergeDesign;
use serde_json::Value;

const FROM: &str = "HIERMERGE_COSIM_PATCH_FROM";
const TO: &str = "HIERMERGE_COSIM_PATCH_TO";

fn tool_present(tool: &str) -> bool {
    if cosim::tools::tool_available(tool) {
        return true;
    }
    if cosim::tools::ci_mode() {
        panic!("CI=true and {tool} missing: {}", cosim::tools::INSTALL_HINT);
    }
    eprintln!("SKIPPING: {tool} missing; {}", cosim::tools::INSTALL_HINT);
    false
}

/// `hiermerge cosim --unit merge --json` (default design, `count` merges,
/// seed 7, stall 0.3) on `engine` with the emitted text `from` replaced by
/// `to`, VCDs into `vcd_dir`.
fn hiermerge_patched(engine: &str, count: &str, from: &str, to: &str, vcd_dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_hiermerge"))
        .args([
            "cosim", "--unit", "merge", "--engine", engine, "--count", count,
        ])
        .args(["--seed", "7", "--stall", "0.3", "--json", "--vcd-dir"])
        .arg(vcd_dir)
        .env_remove("HIERMERGE_COSIM_FLIP_EXPECTED")
        .env(FROM, from)
        .env(TO, to)
        .output()
        .expect("hiermerge runs")
}

/// [`hiermerge_patched`] with 40 merges, and its JSON report.
fn run_patched(engine: &str, from: &str, to: &str, vcd_dir: &Path) -> (Output, Value) {
    let o = hiermerge_patched(engine, "40", from, to, vcd_dir);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    let r = serde_json::from_str(text.trim()).unwrap_or_else(|e| {
        panic!(
            "stdout is not one JSON object ({e}):\n{text}\nstderr:\n{}",
            String::from_utf8_lossy(&o.stderr)
        )
    });
    eprintln!("{engine} `{from}` -> `{to}`: {r}");
    (o, r)
}

/// The emitted default merging module's line `assign <port> = <rhs>;`.
fn emitted_assign(port: &str) -> (String, String) {
    let dir = tempfile::tempdir().unwrap();
    let m = rtl_gen::merge::merge_module_unit(&MergeDesign::default());
    let design = cosim::from_rtl::design_from_module(&m, dir.path()).unwrap();
    let text: String = design
        .verilog_files
        .iter()
        .map(|f| std::fs::read_to_string(f).unwrap())
        .collect();
    let head = format!("assign {port} = ");
    let line = text
        .lines()
        .map(str::trim)
        .find(|l| l.starts_with(&head))
        .unwrap_or_else(|| panic!("the emitted merging module has no `{head}...`"));
    let rhs = line[head.len()..].trim_end_matches(';').to_string();
    (line.to_string(), rhs)
}

/// A failed run: exit non-zero, `passed: false`, a reproduce command that
/// names the patch.
fn assert_fails(o: &Output, r: &Value) {
    assert!(
        !o.status.success(),
        "a broken module must fail the run: {r}"
    );
    assert_eq!(r["passed"], false, "{r}");
    let reproduce = r["reproduce"].as_str().unwrap();
    assert!(reproduce.contains(FROM) && reproduce.contains(TO), "{r}");
}

/// The report's VCD exists under `vcd_dir` and holds value changes.
fn assert_vcd(r: &Value, vcd_dir: &Path) {
    let path = r["vcd"].as_str().unwrap_or_else(|| panic!("no VCD: {r}"));
    assert!(Path::new(path).starts_with(vcd_dir), "{path}");
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    assert!(text.contains("$enddefinitions"), "{path}: no VCD header");
    let stamps = text.lines().filter(|l| l.starts_with('#')).count();
    assert!(stamps > 2, "{path}: {stamps} time stamps");
}

#[test]
fn a_flipped_report_bit_is_caught_decoded_with_a_vcd_on_both_engines() {
    if !tool_present("verilator") || !tool_present("iverilog") {
        return;
    }
    let (line, rhs) = emitted_assign("report_data");
    let width = cosim::units::merge_module::merge_module(&MergeDesign::default())
        .ports()
        .into_iter()
        .find(|p| p.name == "report_data")
        .map(|p| p.width)
        .expect("a report_data port");
    // Bit 0 of every `report` beat flipped.
    let broken = format!("assign report_data = {rhs} ^ {width}'d1;");
    let mut cycles = Vec::new();
    for engine in ["verilator", "iverilog"] {
        let vcd_dir = tempfile::tempdir().unwrap();
        let (o, r) = run_patched(engine, &line, &broken, vcd_dir.path());
        assert_fails(&o, &r);
        let m = &r["first_mismatch"];
        assert_eq!(m["stream"], "report", "{m}");
        assert_eq!(m["transaction"], 0, "the first report beat is wrong: {m}");
        assert_eq!(m["beat"], 0, "{m}");
        // Every `report` beat differs (at least one per merge), the `out`
        // beats do not.
        let (mismatches, nodes) = (
            r["mismatches"].as_u64().unwrap(),
            r["nodes"].as_u64().unwrap(),
        );
        assert!(mismatches >= 40 && mismatches < nodes, "{r}");
        let fields = m["fields"].as_array().unwrap();
        assert!(fields.len() > 1, "decoded field by field: {m}");
        let differing: Vec<&Value> = fields.iter().filter(|f| f["differs"] == true).collect();
        assert_eq!(differing.len(), 1, "one bit, one field: {m}");
        assert_ne!(differing[0]["expected"], differing[0]["got"], "{m}");
        assert_vcd(&r, vcd_dir.path());
        cycles.push(m["cycle"].clone());
    }
    assert_eq!(cycles[0], cycles[1], "same stall draws, same failing cycle");
}

#[test]
fn a_done_that_never_pulses_and_an_idle_that_stays_low_are_caught() {
    if !tool_present("verilator") || !tool_present("iverilog") {
        return;
    }
    let (done_line, _) = emitted_assign("done");
    let (idle_line, _) = emitted_assign("idle");
    let cases = [
        (
            "iverilog",
            &done_line,
            "assign done = 1'b0;",
            "`done` pulsed 0 times for 40 merges",
        ),
        (
            "verilator",
            &done_line,
            "assign done = 1'b0;",
            "`done` pulsed 0 times for 40 merges",
        ),
        (
            "iverilog",
            &idle_line,
            "assign idle = 1'b0;",
            "`idle` low at the end",
        ),
        (
            "verilator",
            &idle_line,
            "assign idle = 1'b0;",
            "`idle` low at the end",
        ),
    ];
    for (engine, from, to, what) in cases {
        let vcd_dir = tempfile::tempdir().unwrap();
        let (o, r) = run_patched(engine, from, to, vcd_dir.path());
        assert_fails(&o, &r);
        // The data streams are still right: only the status is wrong.
        assert_eq!(r["mismatches"], 0, "{r}");
        let m = &r["first_mismatch"];
        assert!(m["what"].as_str().unwrap().contains(what), "{engine}: {m}");
    }
}

#[test]
fn a_cfg_never_accepted_hangs_with_a_vcd_on_both_engines() {
    if !tool_present("verilator") || !tool_present("iverilog") {
        return;
    }
    let (line, _) = emitted_assign("cfg_ready");
    for engine in ["verilator", "iverilog"] {
        let vcd_dir = tempfile::tempdir().unwrap();
        let (o, r) = run_patched(engine, &line, "assign cfg_ready = 1'b0;", vcd_dir.path());
        assert_fails(&o, &r);
        assert_eq!(r["nodes"], 0, "nothing comes out without a cfg: {r}");
        let what = r["first_mismatch"]["what"].as_str().unwrap();
        assert!(what.contains("no handshake for"), "{r}");
        assert_vcd(&r, vcd_dir.path());
    }
}

#[test]
fn a_patch_that_does_not_match_once_is_refused() {
    if !tool_present("verilator") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let o = hiermerge_patched(
        "verilator",
        "2",
        "no such text in any emitted module",
        "x",
        dir.path(),
    );
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("occurs 0 times"), "{err}");
}
