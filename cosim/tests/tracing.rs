//! VCD tracing: a trace window records exactly the cycles asked for, on both
//! engines, and a Verilator model built without `--trace` refuses to trace
//! instead of silently writing nothing.
mod common;

use cosim::tb::TraceWindow;
use cosim::verilator::{VerilatorEngine, VerilatorOptions};
use cosim::{CosimError, Engine};
use std::collections::BTreeSet;

/// Every value a VCD records for variables named `name` (any scope).
fn vcd_values(vcd: &str, name: &str) -> BTreeSet<u64> {
    let ids: BTreeSet<String> = vcd
        .lines()
        .filter_map(|l| {
            let t: Vec<&str> = l.split_whitespace().collect();
            (t.len() >= 5 && t[0] == "$var" && t[4] == name).then(|| t[3].to_string())
        })
        .collect();
    vcd.lines()
        .filter_map(|l| {
            let (value, id) = l.strip_prefix('b')?.split_once(' ')?;
            ids.contains(id.trim())
                .then(|| u64::from_str_radix(value, 2).ok())?
        })
        .collect()
}

#[test]
fn a_trace_window_records_only_its_cycles_on_every_engine() {
    if !common::all_tools_present() {
        return;
    }
    let design = common::counter();
    let dir = tempfile::tempdir().unwrap();
    for kind in common::ENGINES {
        let mut e = common::make_engine(kind, &design, true).unwrap();
        e.reset(2).unwrap();
        e.poke_u64(e.port_id("en").unwrap(), 1).unwrap();
        let path = dir.path().join(format!("{kind}.vcd"));
        // count == cycle - 2 after the two reset edges; trace cycles 60..=70,
        // so counts 58..=68 and nothing far from them.
        let mut window = TraceWindow::around(65, 5, path.clone());
        while e.cycle() < 100 {
            window.update(e.as_mut()).unwrap();
            e.eval().unwrap();
            e.step().unwrap();
        }
        window.finish(e.as_mut()).unwrap();
        drop(e);
        let values = vcd_values(&std::fs::read_to_string(&path).unwrap(), "count");
        for inside in 58..=68 {
            assert!(
                values.contains(&inside),
                "{kind}: count {inside} missing from {values:?}"
            );
        }
        assert!(
            values.iter().all(|&v| (57..=70).contains(&v)),
            "{kind}: values outside the window: {values:?}"
        );
    }
}

#[test]
fn tracing_a_model_built_without_trace_is_an_error() {
    if !common::tools_present(&["verilator", "g++"]) {
        return;
    }
    let mut e = VerilatorEngine::new(&common::counter(), &VerilatorOptions::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    match e.trace_start(&dir.path().join("x.vcd")) {
        Err(CosimError::Unsupported { what }) => assert!(what.contains("trace: true"), "{what}"),
        other => panic!("expected Unsupported, got {other:?}"),
    }
}
