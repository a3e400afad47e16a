//! `hiermerge export-tb` (issue 23 item 6, SPEC 9.1): a unit's portable
//! self-checking testbench. Each exported folder is run the way an ASIC
//! team would run it: its own `run.sh`, a plain shell command with a PATH
//! of system folders only (no cargo, no workspace), on Icarus and on
//! Verilator. It must print PASS with the same cycle count on both; with
//! one expected bit flipped in its vector files it must fail, naming the
//! output, the beat, its transaction, and the field (from golden's layout).
//! Its testbench is lint-clean under `verilator --lint-only -Wall`.

mod common;

use std::path::Path;
use std::process::Command;

use common::{hiermerge, tool_present};
use golden::merge::merge_module::MergeDesign;
use golden::Params;

/// Small grid: quick Verilator builds.
const GRID: [&str; 8] = [
    "--max-lod",
    "8",
    "--quant-bits",
    "4",
    "--index-bits",
    "12",
    "--hier-bits",
    "3",
];

fn params() -> Params {
    Params::new(8, 4, 12, 3).unwrap()
}

/// `hiermerge export-tb <args> <GRID> --out <dir>`, which must succeed.
fn export(dir: &Path, args: &[&str]) {
    let mut a = vec!["export-tb"];
    a.extend(args);
    a.extend(GRID);
    a.extend(["--out", dir.to_str().unwrap()]);
    let o = hiermerge(&a, &[]);
    assert!(
        o.status.success(),
        "export-tb {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// `sh run.sh <sim>` in `dir` with only system folders on PATH: (passed, stdout).
fn run(dir: &Path, sim: &str) -> (bool, String) {
    let o = Command::new("sh")
        .arg("run.sh")
        .arg(sim)
        .current_dir(dir)
        .env_clear()
        .env("PATH", "/usr/local/bin:/usr/bin:/bin")
        .output()
        .expect("sh runs");
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    let err = String::from_utf8_lossy(&o.stderr);
    (o.status.success(), format!("{out}{err}"))
}

/// The PASS line's cycle count.
fn cycles(log: &str) -> u64 {
    let line = log
        .lines()
        .find(|l| l.starts_with("PASS"))
        .unwrap_or_else(|| panic!("no PASS line:\n{log}"));
    let before = line.split(" cycles").next().unwrap();
    before.rsplit(' ').next().unwrap().parse().unwrap()
}

/// The simulators present (under CI=true both must be).
fn simulators() -> Vec<&'static str> {
    let mut v = Vec::new();
    if tool_present("iverilog") {
        v.push("icarus");
    }
    if tool_present("verilator") {
        v.push("verilator");
    }
    v
}

/// Flips bit `bit` of line `line` of the hex file `path` (in place).
fn flip(path: &Path, line: usize, bit: u32) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let l = &mut lines[line];
    let at = l.len() - 1 - (bit / 4) as usize;
    let digit = u32::from_str_radix(&l[at..=at], 16).unwrap() ^ (1 << (bit % 4));
    l.replace_range(at..=at, &format!("{digit:x}"));
    std::fs::write(path, lines.join("\n") + "\n").unwrap();
}

fn hex_line(path: &Path, line: usize) -> u64 {
    let text = std::fs::read_to_string(path).unwrap();
    u64::from_str_radix(text.lines().nth(line).unwrap(), 16).unwrap()
}

/// The testbench in `dir` and its unit lint clean under Verilator.
fn lint_clean(dir: &Path) {
    let o = Command::new("sh")
        .args([
            "-c",
            "verilator --lint-only -Wall --timing --top-module tb tb.v rtl/*.v",
        ])
        .current_dir(dir)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && text.is_empty(), "lint:\n{text}");
}

/// Exports `args`, runs it on every simulator (same cycles, lint-clean),
/// then flips the lowest bit of `field` (at `offset`) in beat 1 of output
/// `stream` and checks every simulator reports that field.
fn passes_then_fails(args: &[&str], stream: &str, field: &str, offset: u32) {
    let dir = tempfile::tempdir().unwrap();
    export(dir.path(), args);
    let sims = simulators();
    let mut seen = Vec::new();
    for sim in &sims {
        let (ok, log) = run(dir.path(), sim);
        assert!(ok, "{args:?} on {sim}:\n{log}");
        seen.push(cycles(&log));
    }
    assert!(seen.windows(2).all(|w| w[0] == w[1]), "cycles {seen:?}");
    if sims.contains(&"verilator") {
        lint_clean(dir.path());
    }
    let vectors = dir.path().join("vectors");
    flip(&vectors.join(format!("{stream}.expected.hex")), 1, offset);
    let txn = hex_line(&vectors.join(format!("{stream}.transaction.hex")), 1);
    for sim in &sims {
        let (ok, log) = run(dir.path(), sim);
        assert!(!ok, "{sim} passed a flipped expectation:\n{log}");
        let head = format!("FAIL: output `{stream}` beat 1 (");
        let line = log.lines().find(|l| l.starts_with(&head));
        let line = line.unwrap_or_else(|| panic!("{sim}: no `{head}`:\n{log}"));
        assert!(line.contains(&format!(" {txn}) at cycle ")), "{line}");
        let starred: Vec<&str> = log
            .lines()
            .filter_map(|l| l.strip_prefix("  * "))
            .filter_map(|l| l.split_whitespace().next())
            .collect();
        assert_eq!(starred, [field, "beat"], "{sim}:\n{log}");
    }
}

#[test]
fn translation_unit_passes_on_both_simulators_and_names_a_flipped_field() {
    let d = golden::translate::model::TranslateDesign {
        unit: golden::translate::TranslateUnitConfig {
            params: params(),
            table_depth: params().hier_capacity() as u32,
        },
        binary64: false,
    };
    let layout = rtl_gen::translate::ports::det_out_layout(&d);
    let f = layout.field("read_valid").expect("a det_out field");
    let args = ["--unit", "translate", "--count", "200", "--seed", "4"];
    passes_then_fails(&args, "det_out", "read_valid", f.offset);
}

#[test]
fn merging_module_passes_on_both_simulators_and_names_a_flipped_field() {
    let d = MergeDesign {
        params: params(),
        inputs: 2,
        ..MergeDesign::default()
    };
    let fields = cosim::units::merge_module::report_fields(&d);
    let f = fields
        .fields()
        .find(|f| f.name == "union")
        .expect("a report field");
    let args = [
        "--unit",
        "merge-module",
        "--inputs",
        "2",
        "--count",
        "12",
        "--seed",
        "3",
    ];
    passes_then_fails(&args, "report", "union", f.offset);
}

/// The merger with one shared store port: the testbench's store model
/// answers `store_req` from its `$readmemh` image after the latency, on
/// Icarus (quick), its text lint-clean; an expected read count or a store
/// word changed in the files fails the run, naming the merge or the beat.
#[test]
fn a_shared_port_merger_answers_its_store_in_the_testbench() {
    if !tool_present("iverilog") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "--unit",
        "merger",
        "--inputs",
        "2",
        "--count",
        "6",
        "--store-port",
        "shared:2",
        "--store-latency",
        "3",
    ];
    export(dir.path(), &args);
    let (ok, log) = run(dir.path(), "icarus");
    assert!(ok, "{log}");
    assert!(log.contains("_sp2: 6 merges"), "{log}");
    if tool_present("verilator") {
        lint_clean(dir.path());
    }
    let vectors = dir.path().join("vectors");
    let expect = vectors.join("store.expect.hex");
    let reads = hex_line(&expect, 2);
    assert!(reads > 0);
    flip(&expect, 2, 0);
    let (ok, log) = run(dir.path(), "icarus");
    assert!(!ok, "a wrong read count passed:\n{log}");
    let want = format!(
        "FAIL: merge 2 made {reads} `store_req` reads; golden's units make {}",
        reads ^ 1
    );
    assert!(log.contains(&want), "{want}:\n{log}");
    flip(&expect, 2, 0);
    // A node record the first merge reads, changed: what the top writes
    // or reports from it differs from golden.
    flip(&vectors.join("store.words.hex"), 0, 0);
    let (ok, log) = run(dir.path(), "icarus");
    assert!(
        !ok && log.contains("FAIL: output `"),
        "a wrong store word passed:\n{log}"
    );
}

/// Every other unit and mode, and the stall patterns, on Icarus (quick):
/// the merging module's S614 stage, per-node merging, a fixed level, the
/// merger top; bursty and periodic stalls. Exports are deterministic.
#[test]
fn every_unit_exports_a_passing_testbench() {
    if !tool_present("iverilog") {
        return;
    }
    for args in [
        "--unit merge-module --stage merge-level --count 10",
        "--unit merge-module --inputs 2 --mode per-node --count 6 --stalls bursty:6,4",
        "--unit merge-module --inputs 3 --mode fixed:3 --count 10 --stalls periodic:2/5",
        "--unit merger --inputs 2 --count 6",
        "--unit merger --inputs 2 --mode per-node --count 4",
        "--unit translate --binary64 --count 40 --stalls none",
    ] {
        let a: Vec<&str> = args.split_whitespace().collect();
        let (one, two) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
        export(one.path(), &a);
        let (ok, log) = run(one.path(), "icarus");
        assert!(ok, "{args}:\n{log}");
        cycles(&log);
        export(two.path(), &a);
        // The same but for the folder named in the header's command line.
        for f in ["tb.v", "vectors/cfg.data.hex", "vectors/in.data.hex"] {
            let read = |d: &Path| {
                std::fs::read_to_string(d.join(f))
                    .ok()
                    .map(|t| t.replace(d.to_str().unwrap(), "DIR"))
            };
            assert_eq!(read(one.path()), read(two.path()), "{args}: {f} differs");
        }
    }
}

#[test]
fn bad_arguments_give_one_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("a-file");
    std::fs::write(&file, "x").unwrap();
    let out = dir.path().join("tb");
    let out = out.to_str().unwrap();
    for (args, expected) in [
        (
            vec!["--unit", "merge-module", "--count", "0", "--out", out],
            "--count 0",
        ),
        (
            vec![
                "--unit",
                "translate",
                "--stage",
                "merge-level",
                "--out",
                out,
            ],
            "--stage applies to --unit merge-module only",
        ),
        (
            vec![
                "--unit",
                "merge-module",
                "--stalls",
                "sometimes",
                "--out",
                out,
            ],
            "--stalls",
        ),
        (
            vec!["--unit", "merge-module", "--mode", "most", "--out", out],
            "--mode",
        ),
        (
            vec![
                "--unit",
                "merge-module",
                "--capacity-bits",
                "4",
                "--out",
                out,
            ],
            "--unit merger and --unit hierarchy only",
        ),
        (
            vec!["--unit", "translate", "--count", "2000000", "--out", out],
            "expected at most",
        ),
        (
            vec!["--unit", "translate", "--out", file.to_str().unwrap()],
            "refusing to write the output over a regular file",
        ),
    ] {
        let mut a = vec!["export-tb"];
        a.extend(&args);
        let o = hiermerge(&a, &[]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert_eq!(
            err.lines().count(),
            1,
            "{args:?}: one line expected:\n{err}"
        );
        assert!(err.contains(expected), "{args:?}: {err}");
    }
    assert!(!Path::new(out).exists(), "nothing written on a refusal");
}

/// The hierarchy unit's testbench (its determine commands and merge
/// commands on `cmd`, the store's answers as input streams) passes on
/// Icarus, and a flipped `det_out` expectation fails it naming the field.
#[test]
fn the_hierarchy_unit_exports_a_testbench_that_checks_det_out() {
    if !tool_present("iverilog") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    export(
        dir.path(),
        &["--unit", "hierarchy", "--count", "6", "--seed", "5"],
    );
    let (ok, log) = run(dir.path(), "icarus");
    assert!(ok, "{log}");
    assert!(log.contains("6 merges"), "{log}");
    let d = rtl_gen::merge::HierarchyUnitConfig::new(rtl_gen::merge::MergerConfig::new(
        MergeDesign::default(),
    ));
    let layout = rtl_gen::translate::ports::det_out_layout(&d.table);
    let f = layout.field("t_x").expect("a det_out field");
    let vectors = dir.path().join("vectors");
    flip(&vectors.join("det_out.expected.hex"), 1, f.offset);
    let (ok, log) = run(dir.path(), "icarus");
    assert!(!ok, "a flipped det_out expectation passed:\n{log}");
    let starred: Vec<&str> = log
        .lines()
        .filter_map(|l| l.strip_prefix("  * "))
        .filter_map(|l| l.split_whitespace().next())
        .collect();
    assert_eq!(starred, ["t_x", "beat"], "{log}");
}

/// A stream's own pattern (`--stall-stream`, as `hiermerge cosim`'s): the
/// merging module's `out` held in long stall runs, nothing else stalled,
/// passes on both simulators with the same cycles, more than with no
/// stall, and the PASS line names it; a stream the unit lacks is refused,
/// naming its streams.
#[test]
fn a_streams_own_pattern_is_exported() {
    let sims = simulators();
    let cycles_of = |extra: &[&str]| {
        let dir = tempfile::tempdir().unwrap();
        let mut args = vec![
            "--unit",
            "merge-module",
            "--count",
            "10",
            "--stalls",
            "none",
        ];
        args.extend(extra);
        export(dir.path(), &args);
        let seen: Vec<u64> = sims
            .iter()
            .map(|sim| {
                let (ok, log) = run(dir.path(), sim);
                assert!(ok, "{args:?} on {sim}:\n{log}");
                if !extra.is_empty() {
                    assert!(log.contains("stalls none out=bursty:60,3)"), "{log}");
                }
                cycles(&log)
            })
            .collect();
        assert!(seen.windows(2).all(|w| w[0] == w[1]), "cycles {seen:?}");
        seen[0]
    };
    let free = cycles_of(&[]);
    let held = cycles_of(&["--stall-stream", "out=bursty:60,3"]);
    assert!(held > 2 * free, "held {held}, free {free}");
    let dir = tempfile::tempdir().unwrap();
    let mut a = vec!["export-tb", "--unit", "merge-module", "--count", "2"];
    a.extend([
        "--stall-stream",
        "outx=none",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    let o = hiermerge(&a, &[]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("stream `outx`") && err.contains("its streams: cfg, in0"),
        "{err}"
    );
}
