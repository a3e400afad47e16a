//! `hiermerge cosim --coverage` (SPEC 10.5): one translation-unit run on a
//! Verilator coverage build writes the raw counts, the merged and annotated
//! unit, the summary, the uncovered points by generator line and the
//! functional bins counted from the run. The regression itself
//! (`hiermerge coverage`) is a step of `scripts/test`; the merging, the
//! generator-line mapping and the waivers are tested in
//! `cosim/src/coverage/`.

mod common;

use common::{hiermerge, tool_present};

#[test]
fn one_run_writes_code_and_functional_coverage() {
    if !tool_present("verilator") || !tool_present("verilator_coverage") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cov");
    let o = hiermerge(
        &[
            "cosim",
            "--unit",
            "translate",
            "--count",
            "600",
            "--stalls",
            "bursty",
            "--coverage",
            out.to_str().unwrap(),
        ],
        &[],
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let top = "translate_unit_d16_q8_i24_h4_t16_b32";
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(summary.contains(&format!("| `{top}` | 1 |")), "{summary}");
    assert!(stdout.contains(&summary), "the table is printed:\n{stdout}");
    let dat = std::fs::read_to_string(out.join(top).join("coverage.dat")).unwrap();
    for page in ["v_line/", "v_branch/", "v_toggle/"] {
        assert!(dat.contains(page), "no {page} point");
    }
    assert!(out
        .join(top)
        .join("annotated")
        .join(format!("{top}.v"))
        .is_file());
    // Uncovered points name generator lines of the translation unit.
    let unc = std::fs::read_to_string(out.join("uncovered.txt")).unwrap();
    assert!(
        unc.lines().any(|l| l.contains("-> rtl-gen/src/translate/")),
        "{unc}"
    );
    // Bins from the run: its stall pattern and the vectors' categories,
    // others declared and not hit (one run is no regression: not a failure).
    let bins = std::fs::read_to_string(out.join("functional.txt")).unwrap();
    let count = |bin: &str| {
        let line = bins
            .lines()
            .find(|l| l.split_whitespace().next() == Some(bin));
        line.unwrap_or_else(|| panic!("no bin {bin}:\n{bins}"))
            .split_whitespace()
            .nth(1)
            .unwrap()
            .to_string()
    };
    assert_ne!(count("stalls.bursty"), "NOT");
    assert_eq!(count("stalls.coin"), "NOT");
    assert_ne!(count("translate.apply_ok"), "NOT");
    // Code coverage comes from Verilator only.
    let ir = hiermerge(
        &[
            "cosim",
            "--unit",
            "translate",
            "--engine",
            "ir",
            "--coverage",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert!(!ir.status.success());
    assert!(String::from_utf8_lossy(&ir.stderr).contains("--engine verilator"));
}
