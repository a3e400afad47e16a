//! Waveforms (issue 23 item 5, SPEC 10.4): `hiermerge cosim --waves
//! vcd|fst --wave-scope PATH --wave-window FROM:TO`, from any run and from
//! the mismatch report. FST from Verilator (`--trace-fst`) and from the
//! Icarus batch (`vvp -fst`) is checked by its header block (type, length,
//! the endianness value e, times, scope and variable counts, the writer);
//! a scope keeps only that instance's signals on every engine.

mod common;

use std::path::{Path, PathBuf};

use common::{hiermerge, json_of, tool_present};
use cosim::waves::{read_fst_header, FstHeader};
use serde_json::Value;

/// A `--json` cosim run of the merging module (5 merges) with `extra`.
fn run(engine: &str, dir: &Path, extra: &str, env: &[(&str, &str)]) -> (bool, Value) {
    let mut a: Vec<&str> = "cosim --unit merge-module --count 5 --seed 2 --json"
        .split_whitespace()
        .collect();
    a.extend(["--engine", engine, "--vcd-dir", dir.to_str().unwrap()]);
    a.extend(extra.split_whitespace());
    let o = hiermerge(&a, env);
    (o.status.success(), json_of(&o))
}

fn fst_of(r: &Value) -> (PathBuf, FstHeader) {
    let p = PathBuf::from(
        r["vcd"]
            .as_str()
            .unwrap_or_else(|| panic!("no waveform: {r}")),
    );
    assert_eq!(p.extension().unwrap(), "fst", "{}", p.display());
    let h = read_fst_header(&std::fs::read(&p).unwrap()).unwrap_or_else(|e| panic!("{e}"));
    assert!(h.end_time > h.start_time, "{h:?}");
    assert!(h.value_blocks >= 1, "{h:?}");
    (p, h)
}

fn vcd_vars(r: &Value) -> Vec<String> {
    let p = r["vcd"]
        .as_str()
        .unwrap_or_else(|| panic!("no waveform: {r}"));
    let text = std::fs::read_to_string(p).unwrap();
    assert!(text.contains("$enddefinitions"), "{p}");
    text.lines()
        .filter(|l| l.starts_with("$var"))
        .map(|l| l.split_whitespace().nth(4).unwrap().to_string())
        .collect()
}

fn only_the_waveform_in(dir: &Path) {
    let names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .collect();
    assert!(
        names.iter().all(|n| !n.starts_with(".hiermerge")),
        "{names:?}"
    );
}

/// FST of a window of a passing run, of one scope of it, and around a
/// mismatch, from Verilator; FST from the Icarus batch. The scope's FST
/// declares as many variables as Icarus's VCD cut to the same scope.
#[test]
fn fst_from_verilator_and_the_icarus_batch() {
    if !tool_present("verilator") || !tool_present("iverilog") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (ok, r) = run("verilator", d, "--waves fst --wave-window 5:40", &[]);
    assert!(ok && r["passed"] == true, "{r}");
    let (_, whole) = fst_of(&r);
    assert!(whole.writer.contains("fst"), "{whole:?}");
    assert!(whole.vars > 300 && whole.scopes > 3, "{whole:?}");
    let (ok, r) = run(
        "verilator",
        d,
        "--waves fst --wave-window 5:40 --wave-scope u_overlap",
        &[],
    );
    assert!(ok, "{r}");
    let (_, scoped) = fst_of(&r);
    assert!(
        scoped.vars > 10 && scoped.vars < whole.vars / 4,
        "{scoped:?} / {whole:?}"
    );
    assert_eq!(
        (scoped.start_time, scoped.end_time),
        (whole.start_time, whole.end_time)
    );
    // Around a mismatch, from the failure report.
    let (ok, r) = run(
        "verilator",
        d,
        "--waves fst",
        &[("HIERMERGE_COSIM_FLIP_EXPECTED", "2")],
    );
    assert!(!ok && r["passed"] == false, "{r}");
    fst_of(&r);
    let (ok, r) = run("iverilog", d, "--waves fst --wave-window 5:40", &[]);
    assert!(ok, "{r}");
    let (_, icarus) = fst_of(&r);
    assert!(icarus.writer.contains("Icarus"), "{icarus:?}");
    assert!(icarus.vars > 300, "{icarus:?}");
    let (ok, r) = run(
        "iverilog",
        d,
        "--wave-window 5:40 --wave-scope u_overlap",
        &[],
    );
    assert!(ok, "{r}");
    assert_eq!(vcd_vars(&r).len() as u64, scoped.vars, "{r}");
    only_the_waveform_in(d);
}

/// A VCD window of a passing IR run holds the asked cycles; cut to a scope
/// it holds only that instance's nets (the IR names them `u_overlap_*`);
/// what no engine can write is refused before anything runs.
#[test]
fn vcd_windows_and_scopes_and_what_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let stamps = |r: &Value| {
        let text = std::fs::read_to_string(r["vcd"].as_str().unwrap()).unwrap();
        text.lines().filter(|l| l.starts_with('#')).count()
    };
    let (ok, short) = run("ir", d, "--wave-window 10:19", &[]);
    assert!(ok, "{short}");
    let short_stamps = stamps(&short);
    let (ok, long) = run("ir", d, "--wave-window 10:59", &[]);
    assert!(ok, "{long}");
    assert!(long["cycles"].as_u64().unwrap() > 60, "{long}");
    let long_stamps = stamps(&long);
    // Ten cycles against fifty: the same stamps a cycle.
    assert!(short_stamps >= 10, "{short_stamps}");
    let ratio = long_stamps as f64 / short_stamps as f64;
    assert!((ratio - 5.0).abs() < 0.5, "{short_stamps} {long_stamps}");
    let all = vcd_vars(&long);
    let (ok, r) = run("ir", d, "--wave-window 10:59 --wave-scope u_overlap", &[]);
    assert!(ok, "{r}");
    let vars = vcd_vars(&r);
    assert!(!vars.is_empty() && vars.len() * 4 < all.len(), "{vars:?}");
    assert!(vars.iter().all(|v| v.starts_with("u_overlap_")), "{vars:?}");
    only_the_waveform_in(d);
    for (engine, extra, want) in [
        ("ir", "--waves fst", "the IR simulator writes VCD only"),
        (
            "ir",
            "--wave-scope u_nowhere",
            "wave scope `u_nowhere`: no such instance path",
        ),
        (
            "ir",
            "--wave-window 9:3",
            "the first cycle is after the last",
        ),
    ] {
        let mut a: Vec<&str> = "cosim --unit merge-module --count 2"
            .split_whitespace()
            .collect();
        a.extend(["--engine", engine]);
        a.extend(extra.split_whitespace());
        let o = hiermerge(&a, &[]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{a:?}");
        assert!(err.contains(want), "{a:?}: {err}");
    }
    let o = hiermerge(
        &[
            "cosim",
            "--unit",
            "translate",
            "--engine",
            "iverilog",
            "--waves",
            "fst",
        ],
        &[],
    );
    assert!(String::from_utf8_lossy(&o.stderr).contains("Icarus writes FST in its batch runs"));
}
