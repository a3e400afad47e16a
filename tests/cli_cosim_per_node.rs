//! `hiermerge cosim --unit merge-module --mode per-node:N/D`: the per-node merging
//! module (SPEC 8.14) through the CLI against golden `per_node_transaction`s
//! (`random_per_node_case`), on the IR simulator, Verilator (a few hundred
//! merges) and Icarus (the multi-stream batch, a few merges), 0 mismatches,
//! the JSON report checked; a run broken through the test hook is caught
//! with the per-node `report` fields decoded, a VCD and a reproduce command.
//! Under CI=true a missing Verilator or Icarus fails.

mod common;

use std::process::Output;

use serde_json::Value;

use common::{assert_passed, field_names, hiermerge, json_of, tool_present};

fn per_node_args<'a>(engine: &'a str, seed: &'a str, count: &'a str) -> Vec<&'a str> {
    vec![
        "cosim",
        "--unit",
        "merge-module",
        "--mode",
        "per-node:1/2",
        "--engine",
        engine,
        "--seed",
        seed,
        "--count",
        count,
        "--stall",
        "0.2",
        "--json",
    ]
}

/// A passing per-node run: exit 0, every merge, no mismatch, the merging
/// module's stage, more beats out than merges (each merge ends its passes
/// with a `report` beat), at most one input beat per clock.
fn assert_passes(o: &Output, engine: &str, merges: u64) -> Value {
    let r = assert_passed(o, merges);
    assert_eq!(r["unit"], "merge-module", "{r}");
    assert_eq!(r["stage"], "merge_module", "{r}");
    assert_eq!(r["engine"], engine, "{r}");
    assert!(r["nodes"].as_u64().unwrap() > merges, "{r}");
    let records = r["records"].as_u64().unwrap();
    assert!(records > merges, "{r}");
    assert!(r["cycles"].as_u64().unwrap() >= records, "{r}");
    let rate = r["records_per_cycle"].as_f64().unwrap();
    assert!(rate > 0.0 && rate <= 1.0, "{r}");
    r
}

#[test]
fn per_node_merges_on_the_ir_simulator_pass() {
    assert_passes(&hiermerge(&per_node_args("ir", "5", "30"), &[]), "ir", 30);
}

/// A few hundred per-node merges on Verilator and a few on Icarus; the
/// batch replays the pipe bench's stall draws, so the same stimulus takes
/// the same cycles on both.
#[test]
fn per_node_merges_on_verilator_and_iverilog_pass() {
    if !tool_present("verilator") || !tool_present("iverilog") {
        return;
    }
    let v = assert_passes(
        &hiermerge(&per_node_args("verilator", "7", "300"), &[]),
        "verilator",
        300,
    );
    let i = assert_passes(
        &hiermerge(&per_node_args("iverilog", "8", "12"), &[]),
        "iverilog",
        12,
    );
    let v_small = assert_passes(
        &hiermerge(&per_node_args("verilator", "8", "12"), &[]),
        "verilator",
        12,
    );
    for key in ["cycles", "records", "nodes"] {
        assert_eq!(v_small[key], i[key], "{key}: {v_small} / {i}");
    }
    assert_ne!(v["records"], v_small["records"]);
}

/// The hook flips bit 0 of merge 3's first `report` beat: the run fails
/// there with the per-node report's fields decoded (only `x`, bit 0,
/// differs), a VCD around the failure, and a reproduce command naming the
/// per-node mode that fails the same way.
#[test]
fn a_broken_per_node_run_is_caught_with_per_node_fields() {
    if !tool_present("verilator") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let mut args = per_node_args("verilator", "9", "10");
    let out = dir.path().to_str().unwrap();
    args.extend(["--vcd-dir", out]);
    let env = [("HIERMERGE_COSIM_FLIP_EXPECTED", "3")];
    let o = hiermerge(&args, &env);
    assert!(!o.status.success(), "a flipped bit must fail the run");
    let r = json_of(&o);
    assert_eq!(r["passed"], false, "{r}");
    assert_eq!(r["mismatches"], 1, "{r}");
    let m = &r["first_mismatch"];
    assert_eq!(m["transaction"], 3, "{m}");
    assert_eq!(m["stream"], "report", "{m}");
    let names = field_names(m);
    assert_eq!(
        names,
        ["x", "y", "z", "lod", "shared", "union", "descend", "pass_end", "more", "err"],
        "{m}"
    );
    let differing: Vec<&Value> = m["fields"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["differs"] == true)
        .collect();
    assert_eq!(differing.len(), 1, "{m}");
    assert_eq!(differing[0]["name"], "x", "{m}");
    let vcd = r["vcd"].as_str().expect("a VCD of the failure");
    assert!(std::path::Path::new(vcd).exists(), "{vcd}");
    let rep = r["reproduce"].as_str().unwrap();
    assert!(rep.contains("--mode per-node:1/2"), "{rep}");
    assert!(rep.contains("HIERMERGE_COSIM_FLIP_EXPECTED=3"), "{rep}");
    args.truncate(args.len() - 2);
    assert_passes(&hiermerge(&args, &[]), "verilator", 10);
}
