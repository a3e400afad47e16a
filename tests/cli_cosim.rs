//! `hiermerge cosim`: passing runs on the IR simulator and Verilator report
//! zero mismatches and their cycles; a vectors file for other parameters is
//! refused naming them; a run broken through the test hook
//! (`HIERMERGE_COSIM_FLIP_EXPECTED`) exits non-zero with the decoded fields,
//! the reproduce command and a VCD. `--unit merge-module` runs the merging module
//! (Verilator, and Icarus through the multi-stream batch, cycle for cycle
//! the same run); `--stage merge-level` its S614 stage. Under CI=true a
//! missing Verilator or Icarus fails.

mod common;

use std::process::Output;

use golden::params::Params;
use golden::translate::model::TranslateDesign;
use golden::translate::TranslateUnitConfig;
use golden::vectors::translate::write_translate_vectors;
use serde_json::Value;

use common::{assert_passed, hiermerge, json_of, tool_present};

fn verilator_present() -> bool {
    tool_present("verilator")
}

/// A passing run: exit 0, every transaction, no mismatch, cycles at least
/// one per input record (the units take at most one record per clock).
fn assert_passes(o: &Output, transactions: u64) -> Value {
    let r = assert_passed(o, transactions);
    let cycles = r["cycles"].as_u64().unwrap();
    assert!(cycles >= r["records"].as_u64().unwrap(), "{r}");
    assert!(r["wall_seconds"].as_f64().unwrap() > 0.0, "{r}");
    r
}

#[test]
fn translate_on_the_ir_simulator_passes() {
    let o = hiermerge(
        &[
            "cosim",
            "--unit",
            "translate",
            "--engine",
            "ir",
            "--seed",
            "1",
            "--count",
            "2000",
            "--json",
        ],
        &[],
    );
    let r = assert_passes(&o, 2000);
    assert_eq!(r["records"], 2000);
}

#[test]
fn translate_on_verilator_with_back_pressure_passes() {
    if !verilator_present() {
        return;
    }
    let o = hiermerge(
        &[
            "cosim",
            "--unit",
            "translate",
            "--engine",
            "verilator",
            "--seed",
            "1",
            "--count",
            "2000",
            "--stall",
            "0.5",
            "--json",
        ],
        &[],
    );
    let r = assert_passes(&o, 2000);
    // Half the cycles stall on each side: well under one record per clock.
    assert!(r["records_per_cycle"].as_f64().unwrap() < 0.75, "{r}");
}

#[test]
fn merge_level_on_verilator_with_back_pressure_passes() {
    if !verilator_present() {
        return;
    }
    let o = hiermerge(
        &[
            "cosim",
            "--unit",
            "merge-module",
            "--stage",
            "merge-level",
            "--seed",
            "1",
            "--count",
            "2000",
            "--stall",
            "0.5",
            "--json",
        ],
        &[],
    );
    let r = assert_passes(&o, 2000);
    assert_eq!(r["stage"], "merge_level");
    assert_eq!(r["engine"], "verilator");
    assert!(r["nodes"].as_u64().unwrap() > 0, "{r}");
}

#[test]
fn vectors_for_other_parameters_are_refused_naming_them() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.jsonl");
    let params = Params::new(12, 8, 24, 4).unwrap();
    let other = TranslateDesign {
        unit: TranslateUnitConfig {
            params,
            table_depth: params.hier_capacity() as u32,
        },
        binary64: false,
    };
    write_translate_vectors(&path, &other, 3, 50).unwrap();
    let o = hiermerge(
        &[
            "cosim",
            "--unit",
            "translate",
            "--engine",
            "ir",
            "--vectors",
            path.to_str().unwrap(),
        ],
        &[],
    );
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("max_lod"), "{err}");
    assert!(err.contains("other parameters"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    // The same file is accepted with the file's parameters.
    let o = hiermerge(
        &[
            "cosim",
            "--unit",
            "translate",
            "--engine",
            "ir",
            "--max-lod",
            "12",
            "--vectors",
            path.to_str().unwrap(),
            "--json",
        ],
        &[],
    );
    assert_passes(&o, 50);
}

/// A broken run: non-zero exit, the first differing transaction decoded by
/// field name, its cycle and seed, the one command that reproduces it (which
/// does), and a VCD of the cycles around it.
fn check_broken(unit: &[&str], flip: &str, count: &str) {
    let dir = tempfile::tempdir().unwrap();
    let vcd_dir = dir.path().join("vcd");
    let mut args = vec!["cosim", "--unit"];
    args.extend(unit);
    args.extend([
        "--engine",
        "ir",
        "--seed",
        "7",
        "--count",
        count,
        "--stall",
        "0.25",
        "--vcd-dir",
        vcd_dir.to_str().unwrap(),
        "--json",
    ]);
    let env = [("HIERMERGE_COSIM_FLIP_EXPECTED", flip)];
    let o = hiermerge(&args, &env);
    assert!(!o.status.success(), "a flipped bit must fail the run");
    let r = json_of(&o);
    assert_eq!(r["passed"], false);
    assert!(r["mismatches"].as_u64().unwrap() >= 1);
    let m = &r["first_mismatch"];
    assert_eq!(
        m["transaction"].as_u64().unwrap(),
        flip.parse::<u64>().unwrap(),
        "{m}"
    );
    assert_eq!(m["seed"], 7);
    assert!(m["cycle"].as_u64().unwrap() > 0);
    let fields = m["fields"].as_array().unwrap();
    assert!(fields.len() > 1, "{m}");
    let differing: Vec<&Value> = fields.iter().filter(|f| f["differs"] == true).collect();
    assert_eq!(differing.len(), 1, "one flipped bit, one field: {m}");
    assert_ne!(differing[0]["expected"], differing[0]["got"]);
    assert!(!differing[0]["name"].as_str().unwrap().is_empty());
    let rep = r["reproduce"].as_str().unwrap();
    for part in [
        format!("HIERMERGE_COSIM_FLIP_EXPECTED={flip} "),
        format!("hiermerge cosim --unit {} --engine ir", unit.join(" ")),
        "--seed 7".into(),
        format!("--count {count}"),
        "--stall 0.25".into(),
    ] {
        assert!(rep.contains(&part), "{part} in {rep}");
    }
    let vcd = std::path::PathBuf::from(r["vcd"].as_str().unwrap());
    assert!(vcd.starts_with(&vcd_dir), "{}", vcd.display());
    let text = std::fs::read_to_string(&vcd).unwrap();
    assert!(text.contains("$enddefinitions"), "a VCD: {}", vcd.display());
    assert!(text.contains('#'), "with time steps");
    // Written atomically (SPEC 15.3): the VCD and nothing else, no temporary.
    let files: Vec<_> = std::fs::read_dir(&vcd_dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(
        files,
        std::slice::from_ref(&vcd),
        "only the VCD in {}",
        vcd_dir.display()
    );
    // The reproduce command, run as printed, fails the same way.
    let words: Vec<&str> = rep.split_whitespace().collect();
    assert_eq!(words[1], "hiermerge");
    let mut again: Vec<&str> = words[2..].to_vec();
    again.extend(["--vcd-dir", vcd_dir.to_str().unwrap(), "--json"]);
    let o2 = hiermerge(&again, &env);
    assert!(!o2.status.success());
    assert_eq!(json_of(&o2)["first_mismatch"], r["first_mismatch"]);
    // Without the hook the same run passes: the failure was the flipped bit.
    assert!(hiermerge(&args, &[]).status.success());
}

#[test]
fn a_broken_translate_run_is_caught_and_reported() {
    check_broken(&["translate"], "37", "300");
}

#[test]
fn a_broken_merge_level_run_is_caught_and_reported() {
    check_broken(&["merge-module", "--stage", "merge-level"], "4", "20");
}

fn merge_module_args<'a>(engine: &'a str, seed: &'a str, count: &'a str) -> Vec<&'a str> {
    vec![
        "cosim",
        "--unit",
        "merge-module",
        "--engine",
        engine,
        "--seed",
        seed,
        "--count",
        count,
        "--stall",
        "0.3",
        "--json",
    ]
}

#[test]
fn merge_module_on_the_ir_simulator_passes() {
    let r = assert_passes(&hiermerge(&merge_module_args("ir", "2", "40"), &[]), 40);
    assert_eq!(r["stage"], "merge_module");
    assert_eq!(r["engine"], "ir");
    assert!(r["nodes"].as_u64().unwrap() > 40, "{r}");
    assert!(r["cycles_per_second"].as_f64().unwrap() > 0.0, "{r}");
}

/// The merging module on Verilator and on Icarus (the multi-stream batch):
/// both pass, and since the batch replays the pipe bench's stall draws, the
/// two runs take the same cycles and move the same beats.
#[test]
fn merge_module_on_verilator_and_iverilog_passes_cycle_for_cycle() {
    if !verilator_present() || !tool_present("iverilog") {
        return;
    }
    let v = assert_passes(
        &hiermerge(&merge_module_args("verilator", "3", "150"), &[]),
        150,
    );
    let i = assert_passes(
        &hiermerge(&merge_module_args("iverilog", "3", "150"), &[]),
        150,
    );
    for r in [&v, &i] {
        assert_eq!(r["stage"], "merge_module", "{r}");
        assert!(r["nodes"].as_u64().unwrap() > 150, "{r}");
        // At most one merged beat per clock, well below it at stall 0.3.
        let rate = r["records_per_cycle"].as_f64().unwrap();
        assert!(rate > 0.3 && rate < 1.0, "{r}");
    }
    assert_eq!(v["engine"], "verilator");
    assert_eq!(i["engine"], "iverilog");
    for key in ["cycles", "records", "nodes", "transactions"] {
        assert_eq!(v[key], i[key], "{key}: {v} / {i}");
    }
    // Another seed is another run.
    let other = assert_passes(
        &hiermerge(&merge_module_args("iverilog", "4", "150"), &[]),
        150,
    );
    assert_ne!(other["records"], i["records"]);
}

/// A merging-module run broken through the hook fails on both engines at
/// merge `flip`'s first `report` beat, with its fields decoded (one differs:
/// `lod`), the stream and beat named, and a reproduce command that fails
/// the same way; without the hook the same run passes.
fn check_broken_module(engine: &str) {
    let flip = "6";
    let args = merge_module_args(engine, "11", "25");
    let env = [("HIERMERGE_COSIM_FLIP_EXPECTED", flip)];
    let o = hiermerge(&args, &env);
    assert!(!o.status.success(), "a flipped bit must fail the run");
    let r = json_of(&o);
    assert_eq!(r["passed"], false);
    assert_eq!(r["mismatches"], 1, "{r}");
    let m = &r["first_mismatch"];
    assert_eq!(m["transaction"], 6, "{m}");
    assert_eq!(m["stream"], "report", "{m}");
    assert!(m["beat"].as_u64().unwrap() >= 6, "{m}");
    assert_eq!(m["kind"], "merge_module");
    assert_eq!(m["seed"], 11);
    let fields = m["fields"].as_array().unwrap();
    let names: Vec<&str> = fields.iter().map(|f| f["name"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        ["lod", "shared", "union", "above", "overflow", "chosen", "err"],
        "{m}"
    );
    let differing: Vec<&Value> = fields.iter().filter(|f| f["differs"] == true).collect();
    assert_eq!(differing.len(), 1, "one flipped bit, one field: {m}");
    assert_eq!(differing[0]["name"], "lod");
    let rep = r["reproduce"].as_str().unwrap();
    for part in [
        format!("HIERMERGE_COSIM_FLIP_EXPECTED={flip} "),
        format!("hiermerge cosim --unit merge-module --engine {engine} --seed 11 --count 25"),
        "--stall 0.3".into(),
        "--inputs 4 --mode overlap:1/2".into(),
    ] {
        assert!(rep.contains(&part), "{part} in {rep}");
    }
    assert!(!rep.contains("--stage"), "{rep}");
    let words: Vec<&str> = rep.split_whitespace().collect();
    let mut again: Vec<&str> = words[2..].to_vec();
    again.push("--json");
    let o2 = hiermerge(&again, &env);
    assert!(!o2.status.success());
    assert_eq!(json_of(&o2)["first_mismatch"], r["first_mismatch"]);
    assert_passes(&hiermerge(&args, &[]), 25);
}

#[test]
fn a_broken_merge_module_run_is_caught_on_verilator() {
    if verilator_present() {
        check_broken_module("verilator");
    }
}

#[test]
fn a_broken_merge_module_run_is_caught_on_iverilog() {
    if tool_present("iverilog") {
        check_broken_module("iverilog");
    }
}

#[test]
fn stage_flags_that_do_not_fit_are_refused() {
    let o = hiermerge(
        &[
            "cosim",
            "--unit",
            "translate",
            "--stage",
            "merge-level",
            "--count",
            "5",
        ],
        &[],
    );
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("--stage applies to --unit merge-module"),
        "{err}"
    );
    let o = hiermerge(
        &[
            "cosim",
            "--unit",
            "merge-module",
            "--stage",
            "module",
            "--vectors",
            "x.jsonl",
        ],
        &[],
    );
    // The module replays whole-merge files, so the flags fit; the missing
    // file is named.
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("x.jsonl") && err.contains("cannot read"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
}

/// A flag that configures or drives other units is refused before
/// anything is built, naming the flag and the units it applies to (never
/// silently ignored); so are the flags of generated merges with a
/// `--vectors` replay.
#[test]
fn flags_of_other_units_are_refused_naming_them() {
    let merging = "applies to --unit merge-module and --unit merger and --unit hierarchy only";
    for (unit, flag, want) in [
        ("translate", "--mode fixed:3", merging),
        ("translate", "--inputs 3", merging),
        (
            "merge-module",
            "--table-depth 4",
            "--table-depth applies to --unit translate and --unit hierarchy only",
        ),
        (
            "hierarchy",
            "--binary64",
            "--binary64 applies to --unit translate only",
        ),
        (
            "merge-module",
            "--merges hard",
            "--merges applies to --unit merger and --unit hierarchy only",
        ),
        (
            "translate",
            "--ledger x",
            "--ledger applies to --unit merger and --unit hierarchy only",
        ),
        (
            "translate",
            "--capacity-bits 5",
            "--capacity-bits applies to --unit merger and --unit hierarchy only",
        ),
    ] {
        let line = format!("cosim --unit {unit} --engine ir --count 1 {flag}");
        let args: Vec<&str> = line.split(' ').collect();
        let o = hiermerge(&args, &[]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{line}: accepted");
        let named = flag.split(' ').next().unwrap();
        assert!(err.contains(named) && err.contains(want), "{line}: {err}");
        assert!(
            err.contains(&format!("not to --unit {unit}")),
            "{line}: {err}"
        );
    }
    // The same flags with their units pass the check (and fail later, on
    // the missing file, or run).
    let o = hiermerge(
        &[
            "cosim", "--unit", "merger", "--engine", "ir", "--mode", "fixed:3",
        ]
        .iter()
        .chain(&["--vectors", "none.jsonl"])
        .copied()
        .collect::<Vec<_>>(),
        &[],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("none.jsonl") && !err.contains("applies to"),
        "{err}"
    );
    for flag in ["--merges", "--ledger"] {
        let value = if flag == "--merges" { "hard" } else { "x" };
        let args = [
            "cosim",
            "--unit",
            "merger",
            "--engine",
            "ir",
            "--vectors",
            "v.jsonl",
            flag,
            value,
        ];
        let o = hiermerge(&args, &[]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains(&format!("{flag} applies to generated merges")),
            "{flag}: {err}"
        );
    }
}
