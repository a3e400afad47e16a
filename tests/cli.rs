//! The command-line contract: every subcommand with `--json` prints one JSON
//! object; bad input gives one clear error and a non-zero exit, never a panic.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

fn hiermerge(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_hiermerge"))
        .args(args)
        .output()
        .expect("the hiermerge binary runs")
}

fn scene(name: &str) -> String {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/scenes")
        .join(name);
    assert!(p.exists(), "{} is missing", p.display());
    p.display().to_string()
}

/// Runs a command expected to succeed and parses its one JSON object.
fn json(args: &[&str]) -> Value {
    let out = hiermerge(args);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{args:?} failed: {}\n{stdout}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        stdout.trim().lines().count(),
        1,
        "{args:?}: expected one line of JSON, got {stdout}"
    );
    serde_json::from_str(stdout.trim())
        .unwrap_or_else(|e| panic!("{args:?}: not JSON ({e}): {stdout}"))
}

/// Runs a command expected to fail; returns its stderr.
fn fails(args: &[&str]) -> String {
    let out = hiermerge(args);
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(!out.status.success(), "{args:?} succeeded");
    assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
    stderr
}

#[test]
fn build_reports_every_mesh() {
    let v = json(&[
        "build",
        &scene("bunny.obj"),
        &scene("teapot.obj"),
        "--max-lod",
        "12",
        "--quant-bits",
        "4",
        "--json",
    ]);
    let hs = v["hierarchies"].as_array().unwrap();
    assert_eq!(hs.len(), 2);
    assert_eq!(hs[0]["triangles"], 3674);
    assert_eq!(hs[1]["triangles"], 992);
    for h in hs {
        let per_lod: u64 = h["nodes_per_lod"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c.as_u64().unwrap())
            .sum();
        assert_eq!(per_lod, h["nodes"].as_u64().unwrap());
        assert!(h["leaves"].as_u64().unwrap() > 0);
        assert_eq!(h["checked"], true);
    }
    assert_eq!(v["params"]["max_lod"], 12);
}

#[test]
fn trace_verify_finds_no_mismatch() {
    let v = json(&[
        "trace",
        &scene("teapot.obj"),
        "--rays",
        "3000",
        "--seed",
        "5",
        "--verify",
        "--json",
    ]);
    assert_eq!(v["rays"], 3000);
    assert_eq!(v["mismatches"], 0);
    assert!(v["hits"].as_u64().unwrap() > 0);
    assert!(v["node_tests_per_ray"].as_f64().unwrap() > 1.0);
}

/// SPEC 16: a hierarchy saved by `build --save` is traced by `trace --load`
/// with the same answers and costs as one built on the spot; a corrupt
/// file is refused naming the file and the field.
#[test]
fn build_save_then_trace_load_traces_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("bunny.hmh");
    let file = file.to_str().unwrap();
    let bunny = scene("bunny.obj");
    let grid = ["--max-lod", "12", "--quant-bits", "6"];
    let mut args = vec!["build", &bunny, "--save", file, "--json"];
    args.extend(grid);
    let v = json(&args);
    assert_eq!(v["hierarchies"][0]["saved"], file);
    let mut args = vec!["trace", &bunny, "--rays", "3000", "--verify", "--json"];
    args.extend(grid);
    let built = json(&args);
    let loaded = json(&[
        "trace", &bunny, "--rays", "3000", "--verify", "--load", file, "--json",
    ]);
    assert_eq!(loaded["loaded"], file);
    for k in [
        "params",
        "hits",
        "mismatches",
        "node_tests_per_ray",
        "prim_tests_per_ray",
    ] {
        assert_eq!(loaded[k], built[k], "{k}");
    }
    assert_eq!(loaded["mismatches"], 0);
    assert!(loaded["hits"].as_u64().unwrap() > 500);
    // The grid options belong to the file.
    let e = fails(&["trace", &bunny, "--load", file, "--max-lod", "16"]);
    assert!(e.contains("--max-lod"), "{e}");
    // Another mesh, a corrupt byte, one --save for two meshes.
    let e = fails(&["trace", &scene("teapot.obj"), "--load", file]);
    assert!(e.contains(file) && e.contains("(triangles)"), "{e}");
    let mut bytes = std::fs::read(file).unwrap();
    bytes[200] ^= 1;
    std::fs::write(file, bytes).unwrap();
    let e = fails(&["trace", &bunny, "--load", file]);
    assert!(
        e.contains(file) && e.contains("(checksum)") && e.contains("corrupt"),
        "{e}"
    );
    let e = fails(&["build", &bunny, &bunny, "--save", file]);
    assert!(e.contains("one file per mesh"), "{e}");
}

#[test]
fn merge_verify_reports_level_and_costs() {
    let v = json(&[
        "merge",
        &scene("bunny.obj"),
        &scene("teapot.obj"),
        "--translate",
        "0,0,0",
        "--translate",
        "-2,1,0.5",
        "--rays",
        "3000",
        "--verify",
        "--json",
    ]);
    assert_eq!(v["mismatches"], 0);
    let o = &v["oracle"];
    assert_eq!(o["rays"], 6000, "the random rays and as many at edges");
    for fault in ["wrong_triangle", "missed", "extra", "t_error"] {
        assert_eq!(o[fault], 0, "{fault}: {o}");
    }
    assert!(o["agree"].as_u64().unwrap() > 5000, "{o}");
    assert!(v["checker"].as_str().unwrap().starts_with("ok"));
    assert!(v["merging_level"].is_u64());
    let per = &v["node_tests_per_ray"];
    for k in ["merged", "separate", "rebuild"] {
        assert!(per[k].as_f64().unwrap() > 0.0, "{k}");
    }
    assert_eq!(v["inputs"].as_array().unwrap().len(), 2);
    let created = v["nodes_created"].as_u64().unwrap();
    let per_level: u64 = v["nodes_per_level"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p[1].as_u64().unwrap())
        .sum();
    assert_eq!(
        per_level, created,
        "every record of the merged hierarchy is created by the merge"
    );
    for mode in ["fixed:3", "below-top:1", "proportion:1/2", "per-node"] {
        let v = json(&[
            "merge",
            &scene("bunny.obj"),
            &scene("teapot.obj"),
            "--mode",
            mode,
            "--rays",
            "500",
            "--verify",
            "--json",
        ]);
        assert_eq!(v["mismatches"], 0, "mode {mode}");
    }
}

/// SPEC 7.10: a placement is honoured to binary32 precision, whatever part
/// of it the voxel grid cannot express: the teapot moved by fractions of a
/// voxel is hit where it was asked to be (the oracle agrees), and the hits
/// move with it.
#[test]
fn merge_translate_puts_the_object_where_it_was_asked_to_be() {
    let mut hits = Vec::new();
    for t in ["0,0,0", "3,1,2", "1.5,0,0", "0.3,0,0"] {
        let v = json(&[
            "merge",
            &scene("bunny.obj"),
            &scene("teapot.obj"),
            "--translate",
            "0,0,0",
            "--translate",
            t,
            "--rays",
            "1000",
            "--verify",
            "--json",
        ]);
        assert_eq!(v["oracle"]["missed"], 0, "{t}");
        assert_eq!(v["oracle"]["wrong_triangle"], 0, "{t}");
        let residual = v["inputs"][1]["residual"].as_array().unwrap().clone();
        hits.push((
            v["hits"].clone(),
            v["node_tests_per_ray"]["separate"].clone(),
            residual,
        ));
    }
    for i in 0..hits.len() {
        for j in 0..i {
            assert_ne!(
                hits[i].0.clone(),
                hits[j].0.clone(),
                "placements {i} and {j} give the same hits"
            );
        }
    }
}

/// Paragraph 67: several merged hierarchies from subsets of the inputs,
/// traced together, give the hits of the separate hierarchies.
#[test]
fn merge_groups_are_traced_together() {
    let (b, t) = (scene("bunny.obj"), scene("teapot.obj"));
    let v = json(&[
        "merge",
        &b,
        &t,
        &b,
        "--translate",
        "0,0,0",
        "--translate",
        "3,1,2",
        "--translate",
        "-2,0.5,1",
        "--group",
        "0,1",
        "--group",
        "2",
        "--rays",
        "1000",
        "--verify",
        "--json",
    ]);
    let groups = v["groups"].as_array().unwrap();
    assert_eq!(groups.len(), 2);
    assert_eq!(groups[0]["inputs"], serde_json::json!([0, 1]));
    assert_eq!(groups[1]["inputs"], serde_json::json!([2]));
    assert_ne!(groups[0]["id"], groups[1]["id"]);
    assert_eq!(v["mismatches"], 0);
    assert_eq!(v["oracle"]["missed"], 0);
    assert_eq!(v["oracle"]["wrong_triangle"], 0);
    for (args, want) in [
        (
            vec!["--group", "0", "--group", "0,1"],
            "is in group 0 and group 1",
        ),
        (vec!["--group", "0"], "mesh 1 is in no group"),
        (vec!["--group", "0,5"], "mesh 5 does not exist"),
        (vec!["--group", "0,x"], "expected mesh indices"),
    ] {
        let mut all = vec!["merge", b.as_str(), t.as_str()];
        all.extend(args);
        let e = fails(&all);
        assert!(e.contains(want), "{e}");
    }
}

#[test]
fn run_writes_images_and_report() {
    let dir = tempfile::tempdir().unwrap();
    let out: PathBuf = dir.path().join("run");
    let v = json(&[
        "run",
        "--out",
        out.to_str().unwrap(),
        "--width",
        "64",
        "--height",
        "48",
        "--json",
    ]);
    assert_eq!(v["image"]["rays"], 64 * 48);
    assert!(v["image"]["hits"].as_u64().unwrap() > 0);
    for f in ["image.png", "heat.png", "report.json"] {
        let len = std::fs::metadata(out.join(f))
            .unwrap_or_else(|e| panic!("{f}: {e}"))
            .len();
        assert!(len > 100, "{f} is {len} bytes");
    }
    let png = std::fs::read(out.join("image.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
}

#[test]
fn bad_input_is_one_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.obj");
    std::fs::write(&bad, "v 0 0 0\nv 1 0 0\nv 0 1 nan\nf 1 2 3\n").unwrap();
    let e = fails(&["build", bad.to_str().unwrap()]);
    assert!(e.contains("bad.obj") && e.contains("line 3"), "{e}");

    let empty = dir.path().join("empty.obj");
    std::fs::write(&empty, "# no faces\nv 0 0 0\n").unwrap();
    for cmd in ["build", "trace", "merge"] {
        let e = fails(&[cmd, empty.to_str().unwrap()]);
        assert!(
            e.contains("empty.obj") && e.contains("no triangles"),
            "{cmd}: {e}"
        );
    }

    let e = fails(&["build", "/no/such/mesh.obj"]);
    assert!(e.contains("/no/such/mesh.obj"), "{e}");

    let e = fails(&["build", &scene("teapot.obj"), "--max-lod", "32"]);
    assert!(e.contains("max_lod") && e.contains("1..=31"), "{e}");

    let e = fails(&["merge", &scene("teapot.obj"), "--mode", "sideways"]);
    assert!(e.contains("unknown mode"), "{e}");

    let e = fails(&["merge", &scene("teapot.obj"), "--translate", "1,2"]);
    assert!(e.contains("x,y,z"), "{e}");

    let e = fails(&["merge", &scene("teapot.obj"), "--translate", "1e300,0,0"]);
    assert!(e.contains("--translate"), "{e}");

    let e = fails(&["trace", &scene("teapot.obj"), "--rays", "0"]);
    assert!(e.contains("--rays"), "{e}");

    // The image-size limit is the scene file's own (SPEC 12.1).
    let side = golden::scene::MAX_IMAGE_SIDE;
    let too_wide = (side + 1).to_string();
    let e = fails(&[
        "run",
        "--store-port",
        "per-unit",
        "--store-latency",
        "3",
        "--no-rtl",
    ]);
    assert!(
        e.contains("--store-latency applies to a shared store port"),
        "{e}"
    );
    let e = fails(&["run", "--store-port", "shared:9", "--no-rtl"]);
    assert!(e.contains("shared:9") && e.contains("T in 1..=8"), "{e}");
    // export-tb's store flags: a shared port's latency, the merger's port.
    let tb = dir.path().join("tb");
    let tb_out = tb.to_str().unwrap();
    let e = fails(&[
        "export-tb",
        "--unit",
        "merger",
        "--store-latency",
        "3",
        "--out",
        tb_out,
    ]);
    assert!(
        e.contains("--store-latency applies to --unit merger --store-port shared only"),
        "{e}"
    );
    let e = fails(&[
        "export-tb",
        "--unit",
        "merge-module",
        "--store-port",
        "shared",
        "--out",
        tb_out,
    ]);
    assert!(
        e.contains("--store-port applies to --unit merger only"),
        "{e}"
    );
    assert!(!tb.exists(), "nothing written");
    let e = fails(&["run", "--width", &too_wide, "--no-rtl"]);
    assert!(
        e.contains(&format!("--width {too_wide}")) && e.contains(&format!("1..={side}")),
        "{e}"
    );
}

#[test]
fn vectors_are_written_with_a_header_and_one_record_per_transaction() {
    let dir = tempfile::tempdir().unwrap();
    // (--unit, extra flags, the header's `unit`, records)
    let cases: [(&str, &[&str], &str, u64); 4] = [
        ("translate", &[], "translate", 300),
        ("merge-module", &[], "merge_module", 12),
        ("merge-module", &["--stage", "merge-level"], "merge", 40),
        ("merger", &[], "hierarchy_merger", 3),
    ];
    for (n, (unit, extra, records, count)) in cases.into_iter().enumerate() {
        let write = |name: &str| {
            let path = dir.path().join(format!("{n}{name}.jsonl"));
            let count = count.to_string();
            let mut args = vec![
                "vectors",
                "--unit",
                unit,
                "--seed",
                "9",
                "--count",
                &count,
                "--out",
                path.to_str().unwrap(),
                "--json",
            ];
            args.extend(extra);
            let v = json(&args);
            assert_eq!(v["count"], count.parse::<u64>().unwrap());
            assert_eq!(v["records"], records);
            path
        };
        let path = write("a");
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len() as u64, count + 1, "{unit}: header + records");
        let header: Value = serde_json::from_str(lines[0]).unwrap();
        assert_eq!(header["unit"], records);
        assert_eq!(header["seed"], 9);
        assert_eq!(header["params"]["max_lod"], 16);
        for l in &lines[1..] {
            let r: Value = serde_json::from_str(l).unwrap();
            assert!(r.is_object());
        }
        // The same seed gives the same file.
        let again = write("b");
        assert_eq!(
            std::fs::read(&path).unwrap(),
            std::fs::read(&again).unwrap()
        );
    }
    let e = fails(&[
        "vectors",
        "--unit",
        "translate",
        "--out",
        "/no/such/dir/v.jsonl",
    ]);
    assert!(e.contains("/no/such/dir"), "{e}");
}

/// `--mode` chooses the merging module the vectors are for: another mode
/// is another file (its header names the mode, its records differ), for
/// the module and the merger; a mode, count or flag the unit does not take
/// is refused, naming it and what was expected.
#[test]
fn vectors_follow_the_mode_and_refuse_bad_options() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let write = |unit: &str, mode: &str, name: &str| {
        let path = d.join(name);
        json(&[
            "vectors",
            "--unit",
            unit,
            "--mode",
            mode,
            "--count",
            "3",
            "--out",
            path.to_str().unwrap(),
            "--json",
        ]);
        let text = std::fs::read_to_string(&path).unwrap();
        let header: Value = serde_json::from_str(text.lines().next().unwrap()).unwrap();
        assert_eq!(header["params"]["mode"], mode, "{unit}");
        text.lines().skip(1).map(String::from).collect::<Vec<_>>()
    };
    for unit in ["merge-module", "merger"] {
        let overlap = write(unit, "overlap:1/2", "o.jsonl");
        for mode in ["fixed:3", "per-node:1/2"] {
            let other = write(unit, mode, "m.jsonl");
            assert_ne!(overlap, other, "{unit} --mode {mode}: the same records");
        }
    }
    // `cosim --vectors` replays a file of whole merges through the module;
    // a file of another mode is refused, naming the parameter.
    let path = d.join("replay.jsonl");
    let file = path.to_str().unwrap();
    let replay = [
        "--unit",
        "merge-module",
        "--inputs",
        "2",
        "--mode",
        "fixed:3",
        "--count",
        "3",
    ];
    json(&[&["vectors", "--out", file, "--json"][..], &replay].concat());
    let cosim = ["cosim", "--engine", "ir", "--vectors", file, "--json"];
    let r = json(&[&cosim[..], &replay[..6]].concat());
    assert_eq!(r["passed"], true, "{r}");
    assert_eq!(
        (r["stage"].as_str(), r["transactions"].as_u64()),
        (Some("merge_module"), Some(3)),
        "{r}"
    );
    let e = fails(&[&cosim[..], &["--unit", "merge-module", "--inputs", "2"]].concat());
    assert!(e.contains("`mode` is \"fixed:3\" in the file"), "{e}");

    let out = d.join("x.jsonl");
    let out = out.to_str().unwrap();
    for (args, want) in [
        (
            vec!["--unit", "merge-module", "--mode", "sideways"],
            "--mode `sideways`: unknown mode; expected overlap",
        ),
        (
            vec!["--unit", "merger", "--mode", "fixed"],
            "--mode `fixed`: expected fixed:LEVEL",
        ),
        (
            vec!["--unit", "merge-module", "--count", "0"],
            "--count 0: expected at least one transaction",
        ),
        (
            vec!["--unit", "merger", "--stage", "merge-level"],
            "--stage applies to --unit merge-module only",
        ),
        (
            vec!["--unit", "merge-module", "--leaf-bits", "4"],
            "--leaf-bits applies to --unit merger and --unit hierarchy only, not to --unit merge-module",
        ),
    ] {
        let mut all = vec!["vectors", "--out", out];
        all.extend(&args);
        let e = fails(&all);
        assert!(e.contains(want), "{args:?}: {e}");
    }
    assert!(!d.join("x.jsonl").exists());
}

#[test]
fn gen_emits_a_configuration() {
    let dir = tempfile::tempdir().unwrap();
    let v = json(&[
        "gen",
        "--unit",
        "translate",
        "--max-lod",
        "31",
        "--quant-bits",
        "0",
        "--binary64",
        "--out",
        dir.path().to_str().unwrap(),
        "--json",
    ]);
    let files = v["files"].as_array().unwrap();
    assert_eq!(files.len(), 1);
    let text = std::fs::read_to_string(files[0].as_str().unwrap()).unwrap();
    assert!(
        text.contains("module translate_unit"),
        "{}",
        &text[..200.min(text.len())]
    );
    let v = json(&[
        "gen",
        "--unit",
        "merge",
        "--inputs",
        "3",
        "--out",
        dir.path().to_str().unwrap(),
        "--json",
    ]);
    assert!(v["files"].as_array().unwrap().len() >= 3);
    let e = fails(&[
        "gen",
        "--unit",
        "merge",
        "--mode",
        "overlap:3/2",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(e.contains("overlap:3/2") && e.contains("N <= D"), "{e}");
    // Per-node merging is built (SPEC 8.14): its module, decider and
    // network, and they lint clean together.
    let pn = tempfile::tempdir().unwrap();
    let v = json(&[
        "gen",
        "--unit",
        "merge",
        "--mode",
        "per-node:1/2",
        "--out",
        pn.path().to_str().unwrap(),
        "--json",
    ]);
    let files: Vec<String> = v["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap().to_string())
        .collect();
    let base = |f: &String| {
        std::path::Path::new(f)
            .file_name()
            .unwrap()
            .to_string_lossy()
            .into_owned()
    };
    for prefix in ["per_node_decider_", "per_node_network_"] {
        assert!(
            files.iter().any(|f| base(f).starts_with(prefix)),
            "{prefix}*.v in {files:?}"
        );
    }
    let top = files
        .iter()
        .map(base)
        .find(|n| n.ends_with("_pn1_2.v"))
        .unwrap_or_else(|| panic!("the per-node merging module in {files:?}"));
    lint_clean(top.trim_end_matches(".v"), &files);
}

/// `verilator --lint-only -Wall` of `files` with `top` is silent; without
/// Verilator a failure under CI=true, else a printed hint.
fn lint_clean(top: &str, files: &[String]) {
    let Ok(lint) = Command::new("verilator")
        .args(["--lint-only", "-Wall", "--top-module", top])
        .args(files)
        .output()
    else {
        assert!(
            std::env::var("CI").map_or(true, |v| v != "true"),
            "verilator is required under CI=true"
        );
        eprintln!("verilator missing: apt-get install verilator iverilog yosys; lint not run");
        return;
    };
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&lint.stdout),
        String::from_utf8_lossy(&lint.stderr)
    );
    assert!(
        lint.status.success() && text.trim().is_empty(),
        "verilator -Wall on {top}:\n{text}"
    );
}
