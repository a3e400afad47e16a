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
            "vectors", "--unit", "merge", "--count", huge, "--out", "x.jsonl",
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
            "cosim", "--unit", "merge", "--engine", "ir", "--count", huge,
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

#[test]
fn negative_numbers_are_refused_by_their_flag() {
    let dir = tempfile::tempdir().unwrap();
    let err = fails_in(
        dir.path(),
        &[
            "vectors",
            "--unit",
            "translate",
            "--seed",
            "-1",
            "--out",
            "x.jsonl",
        ],
    );
    assert!(err.contains("invalid value '-1' for '--seed"), "{err}");
}

#[test]
fn a_merge_error_says_merge_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("t.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let err = fails_in(d, &["merge", "t.obj", "--mode", "below-top:99"]);
    assert!(
        err.contains("merge:") && !err.contains("merge: merge:"),
        "{err}"
    );
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
            "vectors", "--unit", "merge", "--count", "100000", "--out", "v.jsonl",
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
/// hierarchies cannot meet, here; a leaf at LOD 0, voxel rounding leaving the
/// scene, an index past `I` likewise) are refused before frame 0 is
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
    no_temporaries(d);
}
