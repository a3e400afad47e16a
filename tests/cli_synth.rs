//! `hiermerge synth` on one small configuration (the merging level stage of
//! D = 6, Q = 4) for every target, in a cache of its own: the figures agree
//! across targets (flip-flops: generic, ECP5 and iCE40 map the same
//! registers), the critical path names generator lines, a rerun is all
//! cache hits with identical figures, and a bad configuration, a missing
//! tool and a failed place and route each exit non-zero with one clear
//! error. Under CI=true a missing Yosys or nextpnr fails. No timing
//! threshold: Fmax is a measurement.

mod common;

use std::path::Path;
use std::process::Output;

use serde_json::Value;

use common::{hiermerge, json_of};

const SMALL: &[&str] = &[
    "synth",
    "--unit",
    "merge",
    "--max-lod",
    "6",
    "--quant-bits",
    "4",
    "--module",
    "merge_level",
    "--seeds",
    "1",
    "--json",
];

/// True when Yosys and both nextpnr are usable; under CI=true a missing one fails.
fn tools_present() -> bool {
    use cosim::synth::tools;
    for found in [
        tools::yosys(),
        tools::nextpnr_ecp5(),
        tools::nextpnr_ice40(),
    ] {
        if let Err(e) = found {
            if cosim::tools::ci_mode() {
                panic!("CI=true and a synthesis tool is missing: {e}");
            }
            eprintln!("SKIPPING: {e}");
            return false;
        }
    }
    true
}

fn run(cache: &Path, args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut env = env.to_vec();
    let cache = cache.display().to_string();
    env.push(("HIERMERGE_CACHE", &cache));
    hiermerge(args, &env)
}

fn failure(o: &Output) -> String {
    assert!(!o.status.success(), "expected a failure");
    assert!(
        o.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!err.contains("panicked"), "{err}");
    err
}

fn u(v: &Value) -> u64 {
    v.as_u64().unwrap_or_else(|| panic!("not a count: {v}"))
}

/// Figures of one module agree with each other across targets.
fn check_figures(m: &Value) {
    let (g, e, i) = (&m["generic"], &m["ecp5"], &m["ice40"]);
    assert!(g["nand2_eq"].as_f64().unwrap() > 0.0, "{g}");
    assert!(u(&g["depth"]) > 0, "{g}");
    // The same registers on every target: ECP5 and iCE40 keep each one.
    let ff = u(&g["flip_flops"]);
    assert!(ff > 0);
    assert_eq!(u(&e["ff"]), ff, "ECP5 {e}");
    assert_eq!(u(&i["ff"]), ff, "iCE40 {i}");
    assert!(u(&e["lut4"]) > 0 && u(&i["lut4"]) > 0);
    assert_eq!(e["fits"], true, "{e}");
    let f = &e["fmax_mhz"];
    let (lo, mid, hi) = (
        f["min"].as_f64().unwrap(),
        f["median"].as_f64().unwrap(),
        f["max"].as_f64().unwrap(),
    );
    assert!(0.0 < lo && lo <= mid && mid <= hi, "{f}");
    assert_eq!(e["runs"].as_array().unwrap().len(), 1);
    // Fits by its LUT count, so it was placed and routed.
    assert_eq!(i["fits"], true, "{i}");
    assert!(
        i["verdict"].as_str().unwrap().ends_with("LUTs of 7,680"),
        "{i}"
    );
    assert_eq!(i["runs"].as_array().unwrap().len(), 1);
    let sources = e["runs"][0]["critical_path"]["sources"].as_array().unwrap();
    assert!(
        sources
            .iter()
            .any(|s| s.as_str().unwrap().starts_with("rtl-gen/src/merge/")),
        "the critical path names no generator line: {}",
        e["runs"][0]["critical_path"]
    );
}

#[test]
fn synth_small_configuration_on_every_target() {
    if !tools_present() {
        return;
    }
    let cache = tempfile::tempdir().unwrap();
    let first = run(cache.path(), SMALL, &[]);
    let r1 = json_of(&first);
    assert!(
        first.status.success(),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    let modules = r1["modules"].as_array().unwrap();
    assert_eq!(modules.len(), 1, "{r1}");
    assert!(modules[0]["module"]
        .as_str()
        .unwrap()
        .starts_with("merge_level_d6_q4_"));
    check_figures(&modules[0]);
    // Every entry this run made is listed, the iCE40 wrapper's synthesis too.
    let made: Vec<&str> = modules[0]["computed"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_str().unwrap())
        .collect();
    for want in [
        "generic",
        "ecp5 synth",
        "ecp5 seed 1",
        "ice40 synth",
        "ice40 wrapper synth",
        "ice40 seed 1",
    ] {
        assert!(made.contains(&want), "{want} not in {made:?}");
    }
    assert_eq!(u(&r1["computed"]), made.len() as u64);

    // Unchanged configuration: everything from the cache, the same figures.
    let second = run(cache.path(), SMALL, &[]);
    let r2 = json_of(&second);
    assert_eq!(u(&r2["computed"]), 0, "{r2}");
    let strip = |r: &Value| {
        let mut m = r["modules"].clone();
        for x in m.as_array_mut().unwrap() {
            x.as_object_mut().unwrap().remove("computed");
        }
        m
    };
    assert_eq!(strip(&r1), strip(&r2));

    // A place and route that fails: one error naming it, non-zero exit.
    let fake = cache.path().join("nextpnr-ecp5");
    std::fs::write(
        &fake,
        "#!/bin/sh\n[ \"$1\" = --version ] && { echo 'fake nextpnr Version 0'; exit 0; }\necho 'ERROR: no placement' >&2\nexit 1\n",
    )
    .unwrap();
    std::fs::set_permissions(&fake, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    let fake = fake.display().to_string();
    let bad = run(cache.path(), SMALL, &[("HIERMERGE_NEXTPNR_ECP5", &fake)]);
    let err = failure(&bad);
    assert!(
        err.contains("place and route") && err.contains("no placement"),
        "{err}"
    );
}

#[test]
fn synth_bad_configuration_and_missing_tool_are_clear_errors() {
    let cache = tempfile::tempdir().unwrap();
    let err = failure(&run(
        cache.path(),
        &["synth", "--unit", "merge", "--max-lod", "40", "--json"],
        &[],
    ));
    assert!(
        err.contains("configuration") || err.contains("max"),
        "{err}"
    );
    let err = failure(&run(
        cache.path(),
        &["synth", "--defaults", "--module", "no_such_module"],
        &[],
    ));
    assert!(
        err.contains("no_such_module") && err.contains("no such module"),
        "{err}"
    );
    if !tools_present() {
        return;
    }
    let missing = [("HIERMERGE_NEXTPNR_ECP5", "/nonexistent/nextpnr-ecp5")];
    let err = failure(&run(
        cache.path(),
        &["synth", "--defaults", "--target", "ecp5"],
        &missing,
    ));
    assert!(
        err.contains("nextpnr-ecp5") && err.contains("scripts/setup"),
        "{err}"
    );
}
