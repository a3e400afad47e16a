//! The repository's long-run ledger (`longruns/`, SPEC 10.2) is evidence
//! about this code: every entry passed, its netlist regenerated today has
//! its digest, and the first entry of each configuration regenerates its
//! stimulus. A generator or golden change that makes an entry stale fails
//! here, naming the entry, until it is rerun or removed. The plan
//! (`longruns/plan.txt`) parses, and every entry is one of its runs.

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
    // Every entry was checked against a regenerated netlist, and one per
    // configuration against its regenerated stimulus.
    assert!(entries.iter().all(|e| e["netlist_current"] == true), "{r}");
    let tops: std::collections::BTreeSet<&str> =
        entries.iter().map(|e| e["top"].as_str().unwrap()).collect();
    let stimulus_checked = entries
        .iter()
        .filter(|e| e["stimulus_current"] == true)
        .count();
    assert_eq!(stimulus_checked, tops.len(), "{r}");
    // The plan parses, and every entry is one of its lines.
    let planned = r["plan"].as_array().unwrap();
    let done = planned.iter().filter(|l| l["done"] == true).count();
    assert_eq!(done, entries.len(), "an entry outside the plan: {r}");
    println!("plan: {done} of {} runs done", planned.len());
    for t in r["totals"].as_array().unwrap() {
        println!(
            "{} {}: {} merges in {} runs, {} cycles",
            t["top"], t["engine"], t["merges"], t["runs"], t["cycles"]
        );
    }
}
