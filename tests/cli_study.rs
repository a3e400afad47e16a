//! `hiermerge study` (issue 18, SPEC 13): a tiny sweep on the shared teapot,
//! checked for properties that must hold, never for figures: more Q never
//! loosens a box; at Q = 0 every box is its voxel; placed on the grid,
//! translated binary32 hits agree with the binary64 reference at every
//! distance; the cycles per merge and per translated record are what
//! `hiermerge cosim` counts for the same configuration, seed and stall; and
//! every output is written and well formed. Under CI=true a missing
//! Verilator fails.

mod common;

use std::path::Path;

use serde_json::Value;

use common::{hiermerge, json_of, tool_present};

const MERGES: &str = "12";
const RECORDS: &str = "60";

fn study(out: &Path, rtl: bool) -> Value {
    study_with(out, rtl, &[])
}

fn study_with(out: &Path, rtl: bool, env: &[(&str, &str)]) -> Value {
    let teapot = golden::scenes::shared_mesh_path("teapot.obj");
    let teapot = teapot.to_str().expect("utf-8 path");
    let out = out.to_str().expect("utf-8 path");
    let mut args = vec![
        "study",
        teapot,
        "--out",
        out,
        "--max-lod",
        "8,16",
        "--quant-bits",
        "0,2,8",
        "--rays",
        "150",
        "--distance-rays",
        "30",
        "--repeats",
        "1",
        "--seed",
        "3",
        "--rtl-merges",
        MERGES,
        "--rtl-records",
        RECORDS,
        "--json",
    ];
    if rtl {
        args.extend(["--rtl-configs", "16:8"]);
    } else {
        args.push("--no-rtl");
    }
    let o = hiermerge(&args, env);
    assert!(
        o.status.success(),
        "study failed:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    json_of(&o)
}

fn rows(s: &Value) -> &Vec<Value> {
    s["rows"].as_array().expect("rows")
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

/// At every D, each node's box at a larger Q lies inside the box of the same
/// voxel at the next smaller Q (the top rule may add or drop a root, so
/// nodes are matched by voxel); no stored box is tighter than the exact
/// box of its content; at Q = 0 every stored box is its voxel.
fn check_boxes(s: &Value) {
    for d in [8, 16] {
        let mut at_d: Vec<&Value> = rows(s).iter().filter(|r| r["max_lod"] == d).collect();
        at_d.sort_by_key(|r| r["quant_bits"].as_u64());
        assert_eq!(at_d.len(), 3, "D = {d}: one row per Q");
        assert!(
            at_d[0]["nesting"].is_null(),
            "the smallest Q has nothing to nest in"
        );
        for w in at_d.windows(2) {
            let n = &w[1]["nesting"];
            assert_eq!(n["lower_q"], w[0]["quant_bits"], "{n}");
            assert!(
                n["matched"].as_u64().unwrap() + 2 >= w[1]["nodes"].as_u64().unwrap(),
                "nearly every node matched: {n}"
            );
            assert_eq!(n["violations"], 0, "D = {d}: more Q loosened a box: {n}");
        }
        for r in &at_d {
            assert!(
                f(&r["looseness"]["all"]["mean"]) >= 1.0 - 1e-9,
                "a stored box is never tighter than the exact one"
            );
        }
        let q0 = &at_d[0]["looseness"];
        assert_eq!(at_d[0]["quant_bits"], 0);
        assert_eq!(
            q0["boxes_equal_voxel"], q0["nodes"],
            "D = {d}, Q = 0: every box is its voxel"
        );
    }
}

/// Placed exactly on the translation grid (residual 0), translated binary32
/// hits are the reference's at every distance and level.
fn check_aligned(s: &Value) {
    let aligned: Vec<&Value> = s["distance"]
        .as_array()
        .expect("distance")
        .iter()
        .filter(|d| d["format"] == "b64-local-aligned" && d["refused"].is_null())
        .collect();
    assert!(aligned.len() >= 20, "every distance at two D");
    for d in aligned {
        let bad = d["wrong_triangle"].as_u64().unwrap()
            + d["missed"].as_u64().unwrap()
            + d["extra"].as_u64().unwrap();
        assert_eq!(
            bad, 0,
            "aligned placement disagrees with the reference: {d}"
        );
        assert_eq!(f(&d["position_error"]), 0.0, "{d}");
    }
}

/// Placed anywhere (SPEC 7.10: the residual in the local geometry), binary64
/// translated hits are the reference's wherever binary32 local coordinates
/// hold the geometry within 1e-6; and the position error is binary32
/// rounding of the local coordinates (at most half an ulp of the largest
/// traced coordinate), never the residual itself.
fn check_translated(s: &Value) {
    let rows: Vec<&Value> = s["distance"]
        .as_array()
        .expect("distance")
        .iter()
        .filter(|d| d["format"] == "b64-local" && d["refused"].is_null())
        .collect();
    assert!(rows.len() >= 20, "every distance at two D: {}", rows.len());
    let mut with_residual = 0;
    for d in rows {
        let residual = f(&d["residual"]);
        with_residual += (residual > 0.0) as u32;
        let err = f(&d["position_error"]);
        let half_ulp = f(&d["traced_magnitude"]) * 2f64.powi(-24);
        assert!(
            err <= half_ulp,
            "position error {err} (residual {residual}): {d}"
        );
        if err <= 1e-6 {
            let bad = d["wrong_triangle"].as_u64().unwrap()
                + d["missed"].as_u64().unwrap()
                + d["extra"].as_u64().unwrap();
            assert_eq!(
                bad, 0,
                "translated placement disagrees with the reference: {d}"
            );
        }
    }
    assert!(
        with_residual >= 10,
        "the sweep places off the grid: {with_residual}"
    );
}

fn check_outputs(s: &Value, out: &Path) {
    for name in ["study.json", "study.csv", "study.md"] {
        assert!(out.join(name).is_file(), "{name} written");
    }
    let md = std::fs::read_to_string(out.join("study.md")).unwrap();
    let csv = std::fs::read_to_string(out.join("study.csv")).unwrap();
    assert_eq!(
        csv.lines().count(),
        rows(s).len() + 1,
        "a header and one line per row"
    );
    let width = csv.lines().next().unwrap().split(',').count();
    assert!(
        csv.lines().all(|l| l.split(',').count() == width),
        "every CSV line has every column"
    );
    let stems = [
        "node_tests_vs_q",
        "bytes_vs_q",
        "merge_time_vs_q",
        "hit_error_vs_distance",
        "position_error_vs_distance",
        "pareto",
    ];
    for stem in stems {
        let png = std::fs::read(out.join(format!("{stem}.png"))).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "{stem}.png is a PNG");
        let svg = std::fs::read_to_string(out.join(format!("{stem}.svg"))).unwrap();
        assert!(
            svg.contains("<svg") && svg.trim_end().ends_with("</svg>"),
            "{stem}.svg is an SVG"
        );
        assert!(svg.contains("<text"), "{stem}.svg has labels");
        assert!(
            md.contains(&format!("]({stem}.png)")),
            "study.md embeds {stem}.png"
        );
    }
    let listed: Vec<&str> = s["outputs"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(Value::as_str)
        .collect();
    assert!(
        listed.iter().all(|p| Path::new(p).is_file()),
        "every listed output exists"
    );
    let default = rows(s)
        .iter()
        .find(|r| r["default_config"] == true)
        .expect("the default row");
    // Synthesis figures come only from `hiermerge synth`'s records in the
    // cache this run reads (none in a fresh one): never a guess, and ns per
    // merge is cycles over that Fmax.
    let synth = &default["synth"];
    if synth.is_null() {
        assert!(default["ns_per_merge"].is_null(), "{default}");
    } else if let (Some(fmax), Some(cycles)) = (
        synth["fmax_mhz"].as_f64(),
        default["rtl"]["cycles_per_merge"].as_f64(),
    ) {
        let ns = default["ns_per_merge"].as_f64().unwrap();
        assert!((ns - cycles * 1e3 / fmax).abs() < 1e-6, "{default}");
    }
}

/// The RTL figures are the cosim's own counts for the same run.
fn check_cycles(s: &Value) {
    let row = rows(s)
        .iter()
        .find(|r| r["max_lod"] == 16 && r["quant_bits"] == 8)
        .expect("D16 Q8");
    let rtl = &row["rtl"];
    let m = cosim("merger", MERGES);
    assert_eq!(rtl["merges"], m["transactions"], "{m}");
    assert_eq!(
        rtl["merge_cycles"], m["cycles"],
        "cycles per merge match the cosim's count"
    );
    let t = cosim("translate", RECORDS);
    assert_eq!(rtl["translate_records"], t["transactions"], "{t}");
    assert_eq!(
        rtl["translate_cycles"], t["cycles"],
        "cycles per translated record match the cosim's count"
    );
}

/// `hiermerge cosim --unit UNIT` at D16 Q8, the study's seed, no stalls.
fn cosim(unit: &str, count: &str) -> Value {
    let args = [
        "cosim",
        "--unit",
        unit,
        "--seed",
        "3",
        "--count",
        count,
        "--stall",
        "0",
        "--max-lod",
        "16",
        "--quant-bits",
        "8",
        "--json",
    ];
    let o = hiermerge(&args, &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    json_of(&o)
}

#[test]
fn tiny_sweep_holds_its_properties() {
    let dir = tempfile::tempdir().unwrap();
    let rtl = tool_present("verilator");
    let s = study(dir.path(), rtl);
    check_boxes(&s);
    check_aligned(&s);
    check_translated(&s);
    check_outputs(&s, dir.path());
    if rtl {
        check_cycles(&s);
    }
}

#[test]
fn bad_input_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("broken.obj");
    std::fs::write(&bad, "v 0 0 0\nf 1 2 3\n").unwrap();
    let o = hiermerge(
        &[
            "study",
            bad.to_str().unwrap(),
            "--out",
            dir.path().to_str().unwrap(),
            "--no-rtl",
        ],
        &[],
    );
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("broken.obj"), "{err}");
    let o = hiermerge(&["study", "--rtl-configs", "16", "--no-rtl"], &[]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("D:Q"));
    let o = hiermerge(&["study", "--max-lod", "16", "--rtl-configs", "12:8"], &[]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--rtl-configs 12:8: not in the sweep"));
}

/// Plants synthesis records (SPEC 14.5) for the D16 Q8 merger and two of
/// its parts in a cache of its own; the figures are test data, not
/// measurements.
/// Plants synthesis records of the default configuration's merger top:
/// generic and (not placed) ECP5 for the top; ECP5 placed for the upper
/// builder (40 MHz) and `upper_level` (150), and, with `every_part`, for
/// every other part of the top's tree (120).
fn plant_records(cache: &Path, every_part: bool) {
    use cosim::synth::record::{store, Recorded};
    use cosim::synth::{ecp5, generic, sources::Netlist, Spread, Target};
    let p = golden::Params::default();
    let design = golden::merge::merge_module::MergeDesign {
        params: golden::Params::new(16, 8, p.index_bits, p.hier_bits).unwrap(),
        ..Default::default()
    };
    let dir = tempfile::tempdir().unwrap();
    let files = rtl_gen::merge::emit_merge(&design, dir.path()).unwrap();
    let n = Netlist::read(&files).unwrap();
    let module = |prefix: &str| {
        n.modules
            .keys()
            .find(|m| m.starts_with(prefix))
            .unwrap()
            .clone()
    };
    fn rec<T>(n: &Netlist, m: &str, figures: T) -> Recorded<T> {
        Recorded {
            module: m.to_string(),
            digest: n.digest(m),
            tools: "planted".into(),
            seeds: 1,
            goal_mhz: 100.0,
            figures,
        }
    }
    let synth = |lut4| ecp5::Ecp5Synth {
        cells: Default::default(),
        lut4,
        ff: 1,
        ccu2c: 0,
        ebr: 300,
        lutram: 0,
        dsp: 0,
    };
    let top = module("hierarchy_merger_");
    let g = generic::GenericFigures {
        cells: Default::default(),
        nand2_eq: 12345.0,
        flip_flops: 1,
        memories: 0,
        memory_bits: 0,
        depth: 1,
    };
    store(cache, Target::Generic, &rec(&n, &top, g)).unwrap();
    let unplaced =
        ecp5::Ecp5Figures::unplaced(synth(777), false, "does not fit: 300 EBR of 208".into());
    store(cache, Target::Ecp5, &rec(&n, &top, unplaced)).unwrap();
    let mut parts = vec![
        (module("upper_builder_"), 40.0),
        (module("upper_level_"), 150.0),
    ];
    if every_part {
        for s in n.closure(&top) {
            if s.module != top && parts.iter().all(|(m, _)| *m != s.module) {
                parts.push((s.module.clone(), 120.0));
            }
        }
    }
    for (part, fmax) in parts {
        let mut placed = ecp5::Ecp5Figures::unplaced(synth(10), true, "fits".into());
        placed.fmax_mhz = Some(Spread::of(vec![fmax]));
        store(cache, Target::Ecp5, &rec(&n, &part, placed)).unwrap();
    }
}

/// The study reads what `hiermerge synth` recorded: area and the clock
/// bound (the slowest placed part, the top not being placed) at the
/// configuration recorded, "not measured" with the command elsewhere.
#[test]
fn study_reads_synthesis_records_from_the_cache() {
    let cache = tempfile::tempdir().unwrap();
    plant_records(cache.path(), true);
    let out = tempfile::tempdir().unwrap();
    let c = cache.path().display().to_string();
    let s = study_with(out.path(), false, &[("HIERMERGE_CACHE", &c)]);
    for r in rows(&s) {
        let synth = &r["synth"];
        if r["max_lod"] == 16 && r["quant_bits"] == 8 {
            assert_eq!(synth["nand2_eq"], 12345.0, "{r}");
            assert_eq!(synth["ecp5_lut4"], 777, "{r}");
            assert_eq!(synth["fmax_mhz"], 40.0, "the slowest placed part: {r}");
            assert_eq!(synth["fmax_bound"], true, "{r}");
            assert!(synth["fmax_of"]
                .as_str()
                .unwrap()
                .starts_with("upper_builder_"));
        } else {
            assert!(
                synth.is_null(),
                "nothing recorded at this configuration: {r}"
            );
        }
    }
    let notes = s["notes"].to_string();
    assert!(
        notes.contains("hiermerge synth --unit merge --max-lod 8 --quant-bits 0"),
        "{notes}"
    );
}

/// With ECP5 figures for only some parts, the slowest of those bounds
/// nothing (an unmeasured part may be slower): area is shown, the clock
/// and ns per merge say not measured, and the notes say what to run.
#[test]
fn a_clock_bound_needs_every_part_through_ecp5() {
    let cache = tempfile::tempdir().unwrap();
    plant_records(cache.path(), false);
    let out = tempfile::tempdir().unwrap();
    let c = cache.path().display().to_string();
    let s = study_with(out.path(), false, &[("HIERMERGE_CACHE", &c)]);
    let default = rows(&s)
        .iter()
        .find(|r| r["max_lod"] == 16 && r["quant_bits"] == 8)
        .expect("the default configuration's row");
    let synth = &default["synth"];
    assert_eq!(synth["nand2_eq"], 12345.0, "{default}");
    assert!(synth["fmax_mhz"].is_null(), "{default}");
    assert!(default["ns_per_merge"].is_null(), "{default}");
    let notes = s["notes"].to_string();
    assert!(notes.contains("not every part has ECP5 figures"), "{notes}");
}
