//! `hiermerge cosim --unit merge-module` against a deliberately broken merging
//! module: the emitted Verilog patched through the test hook
//! (`HIERMERGE_COSIM_PATCH_FROM` / `_TO`) before Verilator or Icarus reads
//! it. A flipped bit of the `report` stream is caught with the mismatch
//! decoded field by field and a VCD around it that exists, on both engines
//! at the same cycle; a `done` that never pulses, an `idle` that stays low
//! and a `cfg` that is never accepted (a hang, with its VCD) are caught
//! too. Under CI=true a missing Verilator or Icarus fails.

mod common;

use std::path::Path;
use std::process::Output;

use golden::merge::merge_module::MergeDesign;
use serde_json::Value;

use common::{
    assert_fails, assert_one_field_differs, assert_vcd, hiermerge, json_of, port_width,
    tool_present, PATCH_FROM, PATCH_TO,
};

/// `hiermerge cosim --unit merge-module --json` (default design, `count` merges,
/// seed 7, stall 0.3) on `engine` with the emitted text `from` replaced by
/// `to`, VCDs into `vcd_dir`.
fn hiermerge_patched(engine: &str, count: &str, from: &str, to: &str, vcd_dir: &Path) -> Output {
    let vcd = vcd_dir.to_str().unwrap();
    hiermerge(
        &[
            "cosim",
            "--unit",
            "merge-module",
            "--engine",
            engine,
            "--count",
            count,
            "--seed",
            "7",
            "--stall",
            "0.3",
            "--json",
            "--vcd-dir",
            vcd,
        ],
        &[(PATCH_FROM, from), (PATCH_TO, to)],
    )
}

/// [`hiermerge_patched`] with 40 merges, and its JSON report.
fn run_patched(engine: &str, from: &str, to: &str, vcd_dir: &Path) -> (Output, Value) {
    let o = hiermerge_patched(engine, "40", from, to, vcd_dir);
    let r = json_of(&o);
    eprintln!("{engine} `{from}` -> `{to}`: {r}");
    (o, r)
}

/// The emitted default merging module's line `assign <port> = <rhs>;`.
fn emitted_assign(port: &str) -> (String, String) {
    common::emitted_assign(&module(), port)
}

fn module() -> rtl_gen::Module {
    cosim::units::merge_module::merge_module(&MergeDesign::default())
}

#[test]
fn a_flipped_report_bit_is_caught_decoded_with_a_vcd_on_both_engines() {
    if !tool_present("verilator") || !tool_present("iverilog") {
        return;
    }
    let (line, rhs) = emitted_assign("report_data");
    let width = port_width(&module(), "report_data");
    // Bit 0 of every `report` beat flipped.
    let broken = format!("assign report_data = {rhs} ^ {width}'d1;");
    let mut cycles = Vec::new();
    for engine in ["verilator", "iverilog"] {
        let vcd_dir = tempfile::tempdir().unwrap();
        let (o, r) = run_patched(engine, &line, &broken, vcd_dir.path());
        assert_fails(&o, &r, PATCH_FROM);
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
        assert_one_field_differs(m, "lod");
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
        assert_fails(&o, &r, PATCH_FROM);
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
        assert_fails(&o, &r, PATCH_FROM);
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
