//! Issue 21: bad input and faults, each reproduced from the input that
//! found it. Nothing hangs, aborts or is misread in silence: every input
//! gives one error naming the file and place, exits non-zero within seconds;
//! an interrupted `vectors` leaves no file, an interrupted `run` leaves the
//! previous output intact, and outputs are never written over a link or a
//! special file.

use std::os::unix::fs::PermissionsExt;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn start(args: &[&str], dir: &Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_hiermerge"))
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("hiermerge starts")
}

/// Runs `args` in `dir`, expecting a failure within 10 seconds (killed and
/// failed otherwise); returns stderr, which must not tell of a panic.
fn fails_in(dir: &Path, args: &[&str]) -> String {
    let mut child = start(args, dir);
    let t = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if t.elapsed() > Duration::from_secs(10) {
            child.kill().unwrap();
            panic!("{args:?} still runs after 10 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(!out.status.success(), "{args:?} succeeded");
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    let errors = err.lines().filter(|l| l.starts_with("error")).count();
    assert_eq!(errors, 1, "{args:?}: one error: {err}");
    err
}

fn mode_of(p: &Path) -> u32 {
    std::fs::metadata(p).unwrap().permissions().mode() & 0o777
}

/// The mode any program's new file gets here: 0666 less the umask.
fn ordinary_mode(dir: &Path) -> u32 {
    let p = dir.join("plain-file");
    std::fs::write(&p, "").unwrap();
    let mode = mode_of(&p);
    std::fs::remove_file(&p).unwrap();
    mode
}

fn mkfifo(p: &Path) {
    let ok = Command::new("mkfifo").arg(p).status().unwrap().success();
    assert!(ok, "mkfifo {}", p.display());
}

fn no_temporaries(dir: &Path) {
    let left: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .filter(|n| n.starts_with(".hiermerge"))
        .collect();
    assert!(left.is_empty(), "temporaries left: {left:?}");
}

#[test]
fn devices_and_fifos_are_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::os::unix::fs::symlink("/dev/zero", d.join("zero.obj")).unwrap();
    std::os::unix::fs::symlink("/dev/urandom", d.join("random.ply")).unwrap();
    mkfifo(&d.join("fifo.obj"));
    mkfifo(&d.join("scene.json"));
    mkfifo(&d.join("v.jsonl"));
    for (args, want) in [
        (
            vec!["build", "zero.obj"],
            "zero.obj: file: expected a regular file, found a character device",
        ),
        (
            vec!["trace", "random.ply"],
            "random.ply: file: expected a regular file, found a character device",
        ),
        (
            vec!["build", "fifo.obj"],
            "fifo.obj: file: expected a regular file, found a FIFO",
        ),
        (
            vec!["run", "scene.json", "--no-rtl"],
            "scene.json: .: expected a regular file, found a FIFO",
        ),
        (
            vec![
                "cosim",
                "--unit",
                "translate",
                "--engine",
                "ir",
                "--vectors",
                "v.jsonl",
            ],
            "v.jsonl: cannot read: expected a regular file, found a FIFO",
        ),
    ] {
        let err = fails_in(d, &args);
        assert!(err.contains(want), "{args:?}: {err}");
    }
}

#[test]
fn counts_past_the_limits_are_refused_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let huge = "1000000000000";
    for args in [
        vec![
            "vectors",
            "--unit",
            "translate",
            "--count",
            huge,
            "--out",
            "x.jsonl",
        ],
        vec![
            "vectors",
            "--unit",
            "merge-module",
            "--count",
            huge,
            "--out",
            "x.jsonl",
        ],
        vec![
            "cosim",
            "--unit",
            "translate",
            "--engine",
            "ir",
            "--count",
            huge,
        ],
        vec![
            "cosim",
            "--unit",
            "merge-module",
            "--engine",
            "ir",
            "--count",
            huge,
        ],
    ] {
        let err = fails_in(d, &args);
        assert!(
            err.contains("--count 1000000000000: expected at most"),
            "{err}"
        );
    }
    std::fs::write(d.join("t.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let err = fails_in(d, &["trace", "t.obj", "--rays", huge]);
    assert!(
        err.contains("--rays 1000000000000: expected at most"),
        "{err}"
    );
    assert!(!d.join("x.jsonl").exists());
    no_temporaries(d);
}

#[test]
fn a_mesh_binary32_rays_cannot_span_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("huge.obj"),
        "v -1e19 0 0\nv 1e19 0 0\nv 0 1e19 0\nf 1 2 3\n",
    )
    .unwrap();
    let err = fails_in(d, &["trace", "huge.obj", "--rays", "2", "--verify"]);
    assert!(err.contains("huge.obj: the scene's bounds"), "{err}");
}

/// A negative number is taken as the value of the flag before it: a
/// translation may be negative; a seed, count or ray count is refused as a
/// negative number, by its flag (clap once said "unexpected argument '-1'",
/// then "invalid digit found in string").
#[test]
fn negative_numbers_are_refused_by_their_flag() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("t.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let moved = start(
        &[
            "merge",
            "t.obj",
            "t.obj",
            "--translate",
            "-1,0,0",
            "--translate",
            "2.5,-0,3",
            "--rays",
            "10",
            "--json",
        ],
        d,
    )
    .wait_with_output()
    .unwrap();
    assert!(
        moved.status.success(),
        "{}",
        String::from_utf8_lossy(&moved.stderr)
    );
    let negative = "a negative number: expected an unsigned integer";
    for (args, flag) in [
        ("vectors --unit translate --seed -1 --out x.jsonl", "--seed"),
        ("trace t.obj --seed -1", "--seed"),
        ("trace t.obj --rays -5", "--rays"),
        ("merge t.obj t.obj --seed -7", "--seed"),
        ("cosim --unit translate --engine ir --count -3", "--count"),
        ("cosim --unit merge-module --engine ir --seed -1", "--seed"),
        ("cosim --unit translate --engine ir --stall -0.5", "--stall"),
    ] {
        let args: Vec<&str> = args.split_whitespace().collect();
        let err = fails_in(d, &args);
        if flag == "--stall" {
            // A probability may be negative to clap; its range is checked.
            assert!(
                err.contains("--stall: stall probability -0.5: expected 0 <= P <= 0.9"),
                "{err}"
            );
            continue;
        }
        assert!(err.contains(&format!("for '{flag} <")), "{args:?}: {err}");
        assert!(err.contains(negative), "{args:?}: {err}");
    }
    let err = fails_in(d, &["merge", "t.obj", "--translate", "-1,0"]);
    assert!(
        err.contains("`-1,0`: expected x,y,z (three numbers separated by commas)"),
        "{err}"
    );
    assert!(!d.join("x.jsonl").exists());
}

/// Every refusal of the golden merge starts "merge:"; no caller says it
/// again (the issue saw "merge: merge:").
#[test]
fn a_merge_error_says_merge_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("t.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    for mode in ["below-top:99", "below-top:16", "fixed:16"] {
        let err = fails_in(d, &["merge", "t.obj", "t.obj", "--mode", mode]);
        assert!(
            err.contains("merge:") && !err.contains("merge: merge:"),
            "{mode}: {err}"
        );
    }
}

/// Starts `args` in `dir`, waits until a temporary appears (or `wait`
/// passes), sends `signal`, and returns once it ended.
fn interrupt(dir: &Path, watch: &Path, args: &[&str], signal: &str) {
    let mut child = start(args, dir);
    let t = Instant::now();
    loop {
        let started = std::fs::read_dir(watch).unwrap().any(|e| {
            e.unwrap()
                .file_name()
                .to_string_lossy()
                .starts_with(".hiermerge")
        });
        if started || t.elapsed() > Duration::from_secs(20) {
            break;
        }
        assert!(child.try_wait().unwrap().is_none(), "{args:?} ended early");
        std::thread::sleep(Duration::from_millis(10));
    }
    std::thread::sleep(Duration::from_millis(100));
    let pid = child.id().to_string();
    assert!(Command::new("kill")
        .args(["-s", signal, &pid])
        .status()
        .unwrap()
        .success());
    let status = child.wait().unwrap();
    assert!(!status.success(), "{args:?} ended well after SIG{signal}");
}

#[test]
fn an_interrupted_vectors_run_leaves_no_file() {
    for signal in ["INT", "TERM"] {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let args = [
            "vectors",
            "--unit",
            "merge-module",
            "--count",
            "100000",
            "--out",
            "v.jsonl",
        ];
        interrupt(d, d, &args, signal);
        assert!(!d.join("v.jsonl").exists());
        no_temporaries(d);
    }
}

#[test]
fn an_interrupted_run_leaves_the_previous_output_intact() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let small = [
        "run", "--out", "out", "--no-rtl", "--width", "8", "--height", "6", "--json",
    ];
    let out = start(&small, d).wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report = std::fs::read(d.join("out/report.json")).unwrap();
    assert_eq!(mode_of(&d.join("out/report.json")), ordinary_mode(d));
    let big = [
        "run", "--out", "out", "--no-rtl", "--width", "4000", "--height", "3000",
    ];
    interrupt(d, d, &big, "TERM");
    assert_eq!(std::fs::read(d.join("out/report.json")).unwrap(), report);
    let frames = std::fs::read_dir(d.join("out")).unwrap().count();
    assert_eq!(frames, 11, "the old run's files, and only those");
    no_temporaries(d);
}

#[test]
fn outputs_are_never_written_over_links_or_special_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("kept"), "kept").unwrap();
    std::os::unix::fs::symlink("kept", d.join("link.jsonl")).unwrap();
    for (out, want) in [
        (
            "link.jsonl",
            "link.jsonl: refusing to write the output over a symbolic link",
        ),
        (
            "/dev/null",
            "/dev/null: refusing to write the output over a special file",
        ),
    ] {
        let args = [
            "vectors",
            "--unit",
            "translate",
            "--count",
            "3",
            "--out",
            out,
        ];
        let err = fails_in(d, &args);
        assert!(err.contains(want), "{err}");
    }
    std::fs::create_dir(d.join("folder")).unwrap();
    std::os::unix::fs::symlink("folder", d.join("linked")).unwrap();
    let err = fails_in(d, &["run", "--no-rtl", "--out", "linked"]);
    assert!(err.contains("linked: refusing"), "{err}");
    std::fs::write(d.join("folder/notes.txt"), "mine").unwrap();
    let err = fails_in(d, &["run", "--no-rtl", "--out", "folder"]);
    assert!(
        err.contains("folder: the folder holds files but no report.json"),
        "{err}"
    );
    assert!(d.join("folder/notes.txt").exists());
    assert_eq!(std::fs::read_to_string(d.join("kept")).unwrap(), "kept");
    // A file replaced keeps ordinary permissions (not the temporary's 0600).
    let out = start(
        &[
            "vectors",
            "--unit",
            "translate",
            "--count",
            "3",
            "--out",
            "v.jsonl",
        ],
        d,
    )
    .wait_with_output()
    .unwrap();
    assert!(out.status.success());
    assert_eq!(mode_of(&d.join("v.jsonl")), ordinary_mode(d));
}

#[test]
fn scene_structure_errors_name_the_file_and_path() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/default.json"))
            .unwrap();
    std::fs::write(d.join("garbage.json"), format!("{scene} x")).unwrap();
    std::fs::write(d.join("two.json"), format!("{scene}{scene}")).unwrap();
    for f in ["garbage.json", "two.json"] {
        let err = fails_in(d, &["run", f, "--no-rtl"]);
        assert!(
            err.contains(&format!("{f}: .: expected well-formed JSON")),
            "{err}"
        );
        assert!(err.contains("trailing characters"), "{err}");
    }
}

/// Scenes the golden model refuses only while running (a merging mode the
/// hierarchies cannot meet, here; voxel rounding leaving the scene, an index
/// past `I` likewise) are refused before frame 0 is
/// simulated or written, naming the file and the JSON path.
#[test]
fn scenes_failing_at_frame_0_name_their_json_path() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/default.json"))
            .unwrap();
    for (name, mode, path) in [
        (
            "deep.json",
            r#"{"mode": "below_top", "levels": 8}"#,
            "effects.units.merge",
        ),
        (
            "far.json",
            r#"{"mode": "below_top", "levels": 99}"#,
            "effects.units.merge.levels",
        ),
        (
            "fixed.json",
            r#"{"mode": "fixed", "level": 0}"#,
            "effects.units.merge",
        ),
    ] {
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        v["effects"]["units"]["merge"] = serde_json::from_str(mode).unwrap();
        std::fs::write(d.join(name), v.to_string()).unwrap();
        let err = fails_in(d, &["run", name, "--no-rtl", "--out", "out"]);
        assert!(err.contains(&format!("{name}: {path}: expected")), "{err}");
        assert!(!d.join("out").exists());
    }
    // An object as large as the scene cube (16 world units here) was
    // refused at `objects[1].shape` as a leaf that would be a root at LOD 0;
    // no primitive sits at LOD 0 now (SPEC 4.2), so the scene runs.
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["objects"][1]["shape"] = serde_json::json!({"box": {"lo": [0, 0, 0], "hi": [16, 16, 16]}});
    v["image"] = serde_json::json!({"width": 16, "height": 12});
    std::fs::write(d.join("whole.json"), v.to_string()).unwrap();
    let out = start(&["run", "whole.json", "--no-rtl", "--out", "out"], d)
        .wait_with_output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(d.join("out/report.json").exists());
    no_temporaries(d);
}

/// Every integer leaf of `v` with its JSON path (`in.placement[1]`,
/// `in.node.x`).
fn int_leaves(v: &serde_json::Value, path: String, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Object(m) => {
            for (k, x) in m {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                int_leaves(x, p, out);
            }
        }
        serde_json::Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                int_leaves(x, format!("{path}[{i}]"), out);
            }
        }
        serde_json::Value::Number(_) => out.push(path),
        _ => {}
    }
}

/// The port field a record's JSON path is carried in (SPEC 7.9:
/// `in.placement[1]` is `placement_y` of `det_in_data`, `in.node.x` is `x`
/// of `apply_in_data`).
fn port_field(path: &str) -> String {
    let leaf = path.rsplit('.').next().unwrap();
    match leaf.split_once('[') {
        Some((name, i)) => format!(
            "{name}_{}",
            ["x", "y", "z"][i[..1].parse::<usize>().unwrap()]
        ),
        None => leaf.to_string(),
    }
}

fn set_path(v: &mut serde_json::Value, path: &str, x: u64) {
    let mut at = v;
    for part in path.split('.') {
        at = match part.split_once('[') {
            Some((k, i)) => &mut at[k][i.trim_end_matches(']').parse::<usize>().unwrap()],
            None => &mut at[part],
        };
    }
    *at = x.into();
}

/// Issue 21: "transaction N does not fit the design's ports" (cosim) is not
/// reachable from a vectors file: for every integer field of a determine and
/// an apply record, in a binary32 and a binary64 design, a value one past its
/// port field's width (taken from the port layouts, not from the reader) is
/// refused while the file is read, naming the file, line, field and width.
#[test]
fn a_vector_field_wider_than_its_port_is_refused_where_it_is() {
    use golden::vectors::translate::{read_translate_vectors, write_translate_vectors};
    use rtl_gen::translate::ports::{
        apply_in_layout, apply_out_layout, det_in_layout, det_out_layout,
    };
    let dir = tempfile::tempdir().unwrap();
    let mut tried = 0;
    for binary64 in [false, true] {
        let d = golden::translate::model::TranslateDesign {
            binary64,
            ..Default::default()
        };
        let p = dir.path().join("v.jsonl");
        write_translate_vectors(&p, &d, 5, 200).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        for op in ["determine", "apply"] {
            let n = lines
                .iter()
                .position(|l| l.contains(&format!("\"op\":\"{op}\"")))
                .unwrap();
            let record: serde_json::Value = serde_json::from_str(lines[n]).unwrap();
            let mut paths = Vec::new();
            int_leaves(&record, String::new(), &mut paths);
            for path in paths {
                let layout = match (op, &path[..3]) {
                    ("determine", "in.") => det_in_layout(&d),
                    ("determine", _) => det_out_layout(&d),
                    (_, "in.") => apply_in_layout(&d),
                    _ => apply_out_layout(&d),
                };
                let name = port_field(&path);
                // `err_width` and `format` of a binary32 design have no port
                // field: every value but 0 is refused (file_tests.rs).
                // A 64-bit field (binary64 placements) cannot be exceeded by
                // a JSON integer the reader takes (u64).
                let Some(f) = layout.fields().find(|f| f.name == name && f.width < 64) else {
                    continue;
                };
                let mut wide = record.clone();
                set_path(&mut wide, &path, 1u64 << f.width);
                let mut spoiled: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
                spoiled[n] = wide.to_string();
                std::fs::write(&p, spoiled.join("\n") + "\n").unwrap();
                let e = match read_translate_vectors(&p, &d) {
                    Ok(_) => panic!("{path} = 2^{} on line {} accepted", f.width, n + 1),
                    Err(e) => e.to_string(),
                };
                let want = format!(
                    "v.jsonl:{}: field `{path}`: expected an unsigned integer of {} bits",
                    n + 1,
                    f.width
                );
                assert!(e.contains(&want), "{want}\n{e}");
                tried += 1;
            }
        }
        // And through the CLI: one error at the field, not the engine's.
        let mut spoiled: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
        let n = lines
            .iter()
            .position(|l| l.contains("\"op\":\"apply\""))
            .unwrap();
        let mut v: serde_json::Value = serde_json::from_str(lines[n]).unwrap();
        v["in"]["node"]["lod"] = 1u64.wrapping_shl(31).into();
        spoiled[n] = v.to_string();
        std::fs::write(&p, spoiled.join("\n") + "\n").unwrap();
        let mut args: Vec<&str> = "cosim --unit translate --engine ir --vectors v.jsonl"
            .split_whitespace()
            .collect();
        if binary64 {
            args.push("--binary64");
        }
        let err = fails_in(dir.path(), &args);
        assert!(
            err.contains(&format!("v.jsonl:{}: field `in.node.lod`: expected", n + 1)),
            "{err}"
        );
        assert!(!err.contains("does not fit the design's ports"), "{err}");
    }
    assert!(tried > 60, "{tried} fields tried");
}
