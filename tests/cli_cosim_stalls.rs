//! Stall patterns beyond a coin per cycle (issue 23 item 3, SPEC 10):
//! `hiermerge cosim --stalls none|coin|bursty[:S,G]|periodic[:K/N]` on the
//! translation unit and the merging module, on all three engines. Each
//! engine takes its stall decisions from `tb::StallGen`, so one seed and
//! pattern give the same cycles and transfers on IR, Verilator and Icarus;
//! the pattern is in the report and in the command that reproduces a
//! mismatch. The shapes themselves (run lengths, k of every n) are tested
//! on the masks in `cosim/src/tb/stalls.rs`.

mod common;

use common::{hiermerge, json_of, succeeded, tool_present};
use serde_json::Value;

const ENGINES: [&str; 3] = ["ir", "verilator", "iverilog"];

/// One passing `--json` run of `args` with `--stalls stalls` (and what
/// else `stalls` holds: `none --stall-stream out=...`).
fn passes(args: &str, engine: &str, stalls: &str) -> Value {
    let mut a: Vec<&str> = args.split_whitespace().collect();
    a.extend(["--engine", engine, "--stalls"]);
    a.extend(stalls.split_whitespace());
    a.push("--json");
    let r = succeeded(&hiermerge(&a, &[]));
    assert_eq!(r["passed"], true, "{r}");
    assert_eq!(r["mismatches"], 0, "{r}");
    r
}

/// Per pattern: every engine passes with the same cycles and beats, and
/// the report names the pattern. Returns records per cycle per pattern.
fn same_on_every_engine(args: &str, patterns: &[(&str, &str)]) -> Vec<f64> {
    let engines: Vec<&str> = ENGINES
        .iter()
        .copied()
        .filter(|e| match *e {
            "ir" => true,
            "verilator" => tool_present("verilator"),
            _ => tool_present("iverilog"),
        })
        .collect();
    let mut rates = Vec::new();
    for (asked, canonical) in patterns {
        let runs: Vec<Value> = engines.iter().map(|e| passes(args, e, asked)).collect();
        for r in &runs {
            assert_eq!(r["stalls"], *canonical, "{r}");
            for key in ["cycles", "records", "nodes", "transactions"] {
                assert_eq!(r[key], runs[0][key], "{asked} {key}: {r} / {}", runs[0]);
            }
        }
        rates.push(runs[0]["records_per_cycle"].as_f64().unwrap());
    }
    rates
}

const PATTERNS: [(&str, &str); 5] = [
    ("none", "none"),
    ("coin:0.2", "coin:0.2"),
    ("periodic", "periodic:1/3"),
    ("bursty", "bursty:16,16"),
    ("bursty:60,3", "bursty:60,3"),
];

/// The throughput follows each pattern's share of stalls on every side:
/// none, a 0.2 coin, 1 of 3, runs of stalls as long as the go runs (half),
/// then long stall runs with short go runs (about 0.94).
fn slower_in_pattern_order(rates: &[f64]) {
    for w in rates.windows(2) {
        assert!(w[0] > w[1], "{rates:?}");
    }
}

#[test]
fn translate_runs_each_pattern_alike_on_three_engines() {
    let rates = same_on_every_engine("cosim --unit translate --seed 5 --count 200", &PATTERNS);
    slower_in_pattern_order(&rates);
}

#[test]
fn merge_module_runs_each_pattern_alike_on_three_engines() {
    let rates = same_on_every_engine("cosim --unit merge-module --seed 3 --count 30", &PATTERNS);
    slower_in_pattern_order(&rates);
}

/// A mismatch under a pattern is reproduced by the printed command, which
/// names the pattern; `--stall` with another pattern is refused.
#[test]
fn a_mismatch_under_a_pattern_reproduces_with_it() {
    let dir = tempfile::tempdir().unwrap();
    let vcd = dir.path().to_str().unwrap();
    let mut args: Vec<&str> =
        "cosim --unit translate --engine ir --count 200 --stalls periodic:2/7 --json"
            .split_whitespace()
            .collect();
    args.extend(["--vcd-dir", vcd]);
    let env = [("HIERMERGE_COSIM_FLIP_EXPECTED", "50")];
    let o = hiermerge(&args, &env);
    assert!(!o.status.success());
    let r = json_of(&o);
    assert_eq!(r["stalls"], "periodic:2/7");
    assert_eq!(r["stall"], Value::Null);
    let rep = r["reproduce"].as_str().unwrap();
    assert!(rep.contains("--stalls periodic:2/7"), "{rep}");
    assert!(!rep.contains("--stall "), "{rep}");
    let words: Vec<&str> = rep.split_whitespace().collect();
    let mut again: Vec<&str> = words[2..].to_vec();
    again.extend(["--vcd-dir", vcd, "--json"]);
    let o2 = hiermerge(&again, &env);
    assert_eq!(json_of(&o2)["first_mismatch"], r["first_mismatch"]);
    let o3 = hiermerge(
        &[
            "cosim",
            "--unit",
            "translate",
            "--engine",
            "ir",
            "--stalls",
            "bursty",
            "--stall",
            "0.2",
        ],
        &[],
    );
    let err = String::from_utf8_lossy(&o3.stderr);
    assert!(
        err.contains("--stall 0.2 is the probability of --stalls coin"),
        "{err}"
    );
}

/// A stream's own pattern (`--stall-stream`) holds that stream alone: the
/// merging module with its `out` stream in long stall runs and no other
/// stall runs alike on three engines, slower than with no stall at all,
/// and the report, the reproduce command and the refusals name it.
#[test]
fn a_streams_own_pattern_holds_that_stream_alone_on_three_engines() {
    let args = "cosim --unit merge-module --seed 3 --count 30";
    let held = "none --stall-stream out=bursty:60,3";
    let rates = same_on_every_engine(args, &[("none", "none"), (held, "none")]);
    slower_in_pattern_order(&rates);
    let r = passes(args, "ir", held);
    assert_eq!(
        r["stream_stalls"],
        serde_json::json!(["out=bursty:60,3"]),
        "{r}"
    );

    let dir = tempfile::tempdir().unwrap();
    let vcd = dir.path().to_str().unwrap();
    let mut a: Vec<&str> = args.split_whitespace().collect();
    a.extend(["--engine", "ir", "--stalls"]);
    a.extend(held.split_whitespace());
    a.extend(["--json", "--vcd-dir", vcd]);
    let env = [("HIERMERGE_COSIM_FLIP_EXPECTED", "7")];
    let o = hiermerge(&a, &env);
    assert!(!o.status.success());
    let r = json_of(&o);
    let rep = r["reproduce"].as_str().unwrap();
    assert!(rep.contains("--stall-stream out=bursty:60,3"), "{rep}");
    let words: Vec<&str> = rep.split_whitespace().collect();
    let mut again: Vec<&str> = words[2..].to_vec();
    again.extend(["--vcd-dir", vcd, "--json"]);
    assert_eq!(
        json_of(&hiermerge(&again, &env))["first_mismatch"],
        r["first_mismatch"]
    );

    for (line, want) in [
        (
            "cosim --unit merge-module --engine ir --count 1 --stall-stream outt=none",
            "stream `outt`, which the design does not have; its streams: in0, in1, in2, in3, cfg, report, out",
        ),
        (
            "cosim --unit merge-module --engine ir --count 1 --stall-stream out=coin",
            "--stall-stream `out=coin`: a coin here takes its probability: coin:P",
        ),
        (
            "cosim --unit translate --engine ir --count 1 --stall-stream out=none",
            "--unit translate has one input and one output stream",
        ),
    ] {
        let o = hiermerge(&line.split_whitespace().collect::<Vec<_>>(), &[]);
        assert!(!o.status.success(), "{line}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(want), "{line}: {err}");
    }
}

/// The per-node merger top with its `report` held in long stall runs and
/// nothing else stalled: its header waits until the merge's report has
/// reached the fetchers. Before it did, the header could leave first, the
/// merge's end cut a fetcher off from its last decisions, and the next
/// `cfg` waited for that fetcher forever (a hang at merge 18 of these 30).
#[test]
fn the_per_node_merger_drains_its_report_before_its_header() {
    let r = passes(
        "cosim --unit merger --mode per-node:1/2 --max-lod 8 --quant-bits 0 --index-bits 12 \
         --hier-bits 3 --inputs 2 --leaf-bits 6 --capacity-bits 5 --merges hard --count 30 --seed 3",
        "ir",
        "none --stall-stream report=bursty:100,2",
    );
    assert_eq!(r["transactions"], 30, "{r}");
}
