//! The repository's long-run ledger (`longruns/`, SPEC 10.2) is evidence
//! about this code: every entry is well formed, passed, agrees with its own
//! command line and is one of the plan's runs (`longruns/plan.txt`, which
//! parses). Entries whose design or stimulus changed since their run are
//! reported, with the configurations that then lack evidence: a change of
//! behaviour asks for new runs, it does not fail CI. A refactor that keeps
//! behaviour keeps every entry current (the netlist digest is structural).

mod common;

use common::{hiermerge, json_of};

#[test]
fn the_ledger_in_the_repository_is_current() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/longruns");
    let plan = concat!(env!("CARGO_MANIFEST_DIR"), "/longruns/plan.txt");
    let o = hiermerge(
        &[
            "ledger",
            "--dir",
            dir,
            "--stimulus",
            "first",
            "--plan",
            plan,
            "--json",
        ],
        &[],
    );
    let r = json_of(&o);
    assert!(o.status.success(), "{:#}", r["problems"]);
    let entries = r["entries"].as_array().unwrap();
    assert!(!entries.is_empty(), "no entry in {dir}");
    // One stimulus check per configuration.
    let tops: std::collections::BTreeSet<&str> =
        entries.iter().map(|e| e["top"].as_str().unwrap()).collect();
    let stimulus_checked = entries
        .iter()
        .filter(|e| !e["stimulus_current"].is_null())
        .count();
    assert_eq!(stimulus_checked, tops.len(), "{r}");
    // Every entry is one of the plan's lines: a plan line whose entry is
    // current is done, and a stale entry's line is not.
    let planned = r["plan"].as_array().unwrap();
    let key = |v: &serde_json::Value| {
        (
            v["top"].as_str().unwrap().to_string(),
            v["engine"].as_str().unwrap().to_string(),
            v["seed"].as_u64().unwrap(),
            v["count"].as_u64().unwrap(),
        )
    };
    let lines: std::collections::BTreeSet<_> = planned.iter().map(key).collect();
    for e in entries {
        assert!(lines.contains(&key(e)), "an entry outside the plan: {e}");
    }
    let done = planned.iter().filter(|l| l["done"] == true).count();
    let current = entries
        .iter()
        .filter(|e| e["netlist_current"] == true && e["stimulus_current"] != false)
        .count();
    assert_eq!(done, current, "{r}");
    println!("plan: {done} of {} runs done", planned.len());
    for s in r["stale"].as_array().unwrap() {
        println!("stale: {}", s.as_str().unwrap());
    }
    for t in r["lacking"].as_array().unwrap() {
        println!(
            "lacking evidence: {} {}: {} merges",
            t["top"], t["engine"], t["merges"]
        );
    }
    for t in r["totals"].as_array().unwrap() {
        println!(
            "{} {}: {} merges in {} runs, {} cycles",
            t["top"], t["engine"], t["merges"], t["runs"], t["cycles"]
        );
    }
}
