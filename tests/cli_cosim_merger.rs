//! `hiermerge cosim --unit merger`: the hierarchy merger (S610-S618 as one
//! top, SPEC 8.15) through the CLI against golden `merger_transaction`s, on
//! Verilator (50 merges) and Icarus (the multi-stream batch, 5 merges): 0
//! mismatches, one `done` pulse per merge, the JSON report's fields, the
//! same stimulus on both engines; flags that do not apply are refused.
//! Under CI=true a missing Verilator or Icarus fails.

mod common;

use std::process::Output;

use serde_json::Value;

use common::{assert_passed, hiermerge, json_of, tool_present};

fn merger_run(engine: &str, seed: &str, count: &str) -> Output {
    hiermerge(
        &[
            "cosim", "--unit", "merger", "--engine", engine, "--seed", seed, "--count", count,
            "--stall", "0.2", "--json",
        ],
        &[],
    )
}

/// A passing run: exit 0, every merge, no mismatch, one `done` pulse per
/// merge, one chunk, and counts that hang together.
fn assert_passes(o: &Output, engine: &str, merges: u64) -> Value {
    let r = assert_passed(o, merges);
    assert_eq!(r["unit"], "merger", "{r}");
    assert_eq!(r["stage"], "hierarchy_merger", "{r}");
    assert_eq!(r["engine"], engine, "{r}");
    assert!(r["reproduce"].is_null(), "{r}");
    let m = &r["merger"];
    assert_eq!(m["chunks"], 1, "{r}");
    assert_eq!(m["done_pulses"], merges, "{r}");
    let cycles = r["cycles"].as_u64().unwrap();
    let (records, nodes) = (r["records"].as_u64().unwrap(), r["nodes"].as_u64().unwrap());
    // Every merge sends a cfg beat and gets a header and a report beat back;
    // a merge that is not refused writes at least one node.
    let (beats_in, beats_out) = (
        m["beats_in"].as_u64().unwrap(),
        m["beats_out"].as_u64().unwrap(),
    );
    assert!(beats_in > merges && beats_out >= 2 * merges, "{r}");
    let refused = m["refused"].as_u64().unwrap();
    assert!(nodes >= merges - refused && records > 0, "{r}");
    assert!(cycles > merges, "{r}");
    let per_cycle = r["records_per_cycle"].as_f64().unwrap();
    assert!(
        (per_cycle - records as f64 / cycles as f64).abs() < 1e-9,
        "{r}"
    );
    r
}

#[test]
fn merger_cli_runs_on_verilator_and_icarus() {
    if !tool_present("verilator") || !tool_present("iverilog") {
        return;
    }
    let v = assert_passes(&merger_run("verilator", "2", "50"), "verilator", 50);
    let small = assert_passes(&merger_run("verilator", "3", "5"), "verilator", 5);
    let i = assert_passes(&merger_run("iverilog", "3", "5"), "iverilog", 5);
    // The seed fixes the merges: both engines see the same stimulus and
    // must give the same beats back.
    for f in ["records", "nodes"] {
        assert_eq!(small[f], i[f], "{f}: {small} vs {i}");
    }
    for f in ["refused", "refs_written", "beats_in", "beats_out"] {
        assert_eq!(small["merger"][f], i["merger"][f], "{f}: {small} vs {i}");
    }
    println!(
        "cli merger: verilator 50 merges {} cycles {:.2} s; icarus 5 merges {} cycles {:.2} s",
        v["cycles"], v["wall_seconds"], i["cycles"], i["wall_seconds"]
    );
}

/// `hiermerge <args>` (a space-separated line) with `env` fails, its
/// error saying `what`.
fn assert_refused(args: &str, env: &[(&str, &str)], what: &str) {
    let args: Vec<&str> = args.split(' ').collect();
    let o = hiermerge(&args, env);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains(what), "{args:?}: {e}");
}

#[test]
fn merger_flags_are_checked() {
    assert_refused(
        "cosim --unit merge-module --leaf-bits 5 --json",
        &[],
        "--unit merger and --unit hierarchy only",
    );
    // The Verilog patch hook needs a Verilog engine and a unit that takes it.
    let patch = [
        ("HIERMERGE_COSIM_PATCH_FROM", "assign"),
        ("HIERMERGE_COSIM_PATCH_TO", "assign"),
    ];
    let ir_merger = "cosim --unit merger --engine ir --count 1";
    assert_refused(ir_merger, &patch, "IR engine");
    assert_refused(
        "cosim --unit translate --engine ir --count 1",
        &patch,
        "HIERMERGE_COSIM_PATCH_FROM applies to",
    );
    // A stall the drivers refuse is refused before anything is built.
    assert_refused(
        "cosim --unit merger --engine ir --count 1 --stall 0.95",
        &[],
        "expected 0 <= P <= 0.9",
    );
    // Inputs take ids 1..=k and the merge 2^H - 1: four inputs need H = 3.
    assert_refused(
        &format!("{ir_merger} --hier-bits 2 --inputs 4"),
        &[],
        "at most 2 inputs fit H = 2",
    );
    // A writer of 2^40 entries per buffer does not fit the index width.
    assert_refused(
        &format!("{ir_merger} --capacity-bits 40"),
        &[],
        "hierarchy merger configuration",
    );
    // Soups that I = 8 cannot number are refused, naming the flag, for
    // the random and the hard merges alike (this panicked once).
    for merges in ["random", "hard"] {
        assert_refused(
            &format!("cosim --unit merger --engine ir --count 20 --index-bits 8 --capacity-bits 7 --merges {merges}"),
            &[],
            "does not fit in I = 8 index bits",
        );
    }
}

/// `cosim --unit merger --vectors FILE` replays a file of `vectors --unit
/// merger` bit for bit; a merger of other sizes refuses it naming the
/// parameter; the flip hook's bit is caught at its merge, `out_id` named.
#[test]
fn merger_vectors_replay_through_the_cli() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("merger.jsonl");
    let file = path.to_str().unwrap();
    let design = "--inputs 2 --max-lod 8 --quant-bits 0 --index-bits 12 --hier-bits 3";
    let sizes = "--capacity-bits 7 --leaf-bits 6";
    let run = |line: String, env: &[(&str, &str)]| {
        let args: Vec<&str> = line.split(' ').collect();
        hiermerge(&args, env)
    };
    let o = run(
        format!("vectors --unit merger {design} {sizes} --seed 5 --count 4 --out {file}"),
        &[],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let replay = format!("cosim --unit merger --engine ir --vectors {file} --json {design}");
    let r = assert_passed(&run(format!("{replay} {sizes}"), &[]), 4);
    assert_eq!(r["vectors"], file, "{r}");
    assert_eq!(r["stage"], "hierarchy_merger", "{r}");
    assert!(r["cycles"].as_u64().unwrap() > 4, "{r}");

    assert_refused(
        &format!("{replay} --capacity-bits 7"),
        &[],
        "`leaf_bits` is 6 in the file",
    );

    let o = run(
        format!("{replay} {sizes}"),
        &[("HIERMERGE_COSIM_FLIP_EXPECTED", "2")],
    );
    assert!(!o.status.success(), "a flipped bit must fail the replay");
    let m = &json_of(&o)["first_mismatch"];
    assert_eq!(
        (m["transaction"].as_u64(), m["stream"].as_str()),
        (Some(2), Some("header")),
        "{m}"
    );
    let differing: Vec<&str> = m["fields"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["differs"] == true)
        .map(|f| f["name"].as_str().unwrap())
        .collect();
    assert_eq!(differing, ["out_id"], "{m}");
}

/// `--store-port shared`: the run passes on the IR engine with the port's
/// figures in the JSON (as many reads as golden's units make, reads per
/// cycle the share of the port, the records the port allows); the port's
/// flags are refused where they do not apply.
#[test]
fn merger_shared_store_port_through_the_cli() {
    let line = "cosim --unit merger --engine ir --count 3 --stalls none --store-port shared:2 \
                --store-latency 2 --max-lod 8 --quant-bits 0 --index-bits 12 --hier-bits 3 \
                --inputs 3 --json";
    let o = hiermerge(&line.split_whitespace().collect::<Vec<_>>(), &[]);
    let r = assert_passed(&o, 3);
    let st = &r["merger"]["store"];
    assert_eq!(st["port"], "shared:2", "{r}");
    assert!(
        r["merger"]["top"].as_str().unwrap().ends_with("_sp2"),
        "{r}"
    );
    let (reads, cycles) = (st["reads"].as_u64().unwrap(), r["cycles"].as_u64().unwrap());
    assert!(reads > 0 && st["expected_reads"] == reads, "{r}");
    let of_port = st["of_port"].as_f64().unwrap();
    assert!((of_port - reads as f64 / cycles as f64).abs() < 1e-9, "{r}");
    assert!(of_port > 0.0 && of_port <= 1.0, "{r}");
    let allowed = st["records_allowed_per_cycle"].as_f64().unwrap();
    let records = r["records"].as_u64().unwrap() as f64;
    assert!((allowed - records / reads as f64).abs() < 1e-9, "{r}");
    let ir_merger = "cosim --unit merger --engine ir --count 1";
    assert_refused(
        &format!("{ir_merger} --store-latency 3"),
        &[],
        "--store-latency applies to --store-port shared only",
    );
    assert_refused(
        &format!("{ir_merger} --store-port shared:9"),
        &[],
        "expected per-unit, shared or shared:T",
    );
    assert_refused(
        "cosim --unit merge-module --engine ir --count 1 --store-port shared",
        &[],
        "--unit merger only",
    );
}

/// `cosim --unit hierarchy`: the hierarchy unit (docs/hardware.md 8.16)
/// through the CLI, its determine commands counted as records in, 0
/// mismatches on Verilator; the flip hook's bit is caught at its merge's
/// `header`, with a command that reproduces it; `vectors` points to
/// `export-tb`, and a shared store port is refused.
#[test]
fn hierarchy_unit_through_the_cli() {
    if !tool_present("verilator") {
        return;
    }
    let run = |env: &[(&str, &str)]| {
        hiermerge(
            &[
                "cosim",
                "--unit",
                "hierarchy",
                // The small configuration (k = 2): the unit's glue and CLI
                // are the same at every size; three engines run the others.
                "--max-lod",
                "8",
                "--quant-bits",
                "0",
                "--index-bits",
                "12",
                "--hier-bits",
                "3",
                "--inputs",
                "2",
                "--seed",
                "4",
                "--count",
                "12",
                "--json",
            ],
            env,
        )
    };
    let r = assert_passed(&run(&[]), 12);
    assert_eq!(r["unit"], "hierarchy", "{r}");
    assert_eq!(r["stage"], "hierarchy_unit", "{r}");
    // One determine command per input of each merge, 1..=k inputs.
    let dets = r["records"].as_u64().unwrap();
    assert!((12..=24).contains(&dets), "{r}");
    assert!(r["nodes"].as_u64().unwrap() > 0, "{r}");
    let o = run(&[("HIERMERGE_COSIM_FLIP_EXPECTED", "5")]);
    assert!(!o.status.success());
    let r = json_of(&o);
    let m = &r["first_mismatch"];
    assert_eq!(m["transaction"], 5, "{r}");
    assert_eq!(m["stream"], "header", "{r}");
    assert!(
        r["reproduce"]
            .as_str()
            .unwrap()
            .contains("--unit hierarchy"),
        "{r}"
    );
    assert_refused(
        "vectors --unit hierarchy --count 2 --out x",
        &[],
        "export-tb --unit hierarchy",
    );
    assert_refused(
        "cosim --unit hierarchy --count 1 --store-port shared",
        &[],
        "--unit merger only",
    );
}
