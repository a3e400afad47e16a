//! The long-run ledger (SPEC 10.2) through the CLI: `hiermerge cosim --unit
//! merger --ledger DIR` records a run; `hiermerge ledger` regenerates each
//! entry's netlist and stimulus from its own command line and finds the
//! entry current, or names the entry and the field that went stale,
//! failed or disagrees. Runs on the IR simulator (a few merges): the
//! ledger's logic, not a simulator, is under test.

mod common;

use std::path::{Path, PathBuf};

use serde_json::Value;

use common::{hiermerge, json_of};

fn record(dir: &Path, seed: &str, count: &str, extra: &[&str]) -> PathBuf {
    let d = dir.to_str().unwrap();
    let mut args = vec![
        "cosim", "--unit", "merger", "--engine", "ir", "--seed", seed, "--count", count,
        "--ledger", d, "--json",
    ];
    args.extend(extra);
    let o = hiermerge(&args, &[]);
    assert!(
        o.status.success(),
        "stderr:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let r = json_of(&o);
    let top = r["merger"]["top"].as_str().unwrap();
    assert!(top.starts_with("hierarchy_merger_"), "{r}");
    let path = dir.join(top).join(format!("ir-seed{seed}-n{count}.json"));
    assert!(path.is_file(), "no entry at {}", path.display());
    let entry: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    assert_eq!(entry["netlist_sha256"], r["merger"]["netlist_sha256"]);
    assert_eq!(entry["stimulus_sha256"], r["merger"]["stimulus_sha256"]);
    assert_eq!(entry["passed"], true);
    path
}

/// `hiermerge ledger` on `dir`: (exit success, report).
fn check(dir: &Path, stimulus: &str, need: &str) -> (bool, Value) {
    let o = hiermerge(
        &[
            "ledger",
            "--dir",
            dir.to_str().unwrap(),
            "--stimulus",
            stimulus,
            "--need",
            need,
            "--json",
        ],
        &[],
    );
    (o.status.success(), json_of(&o))
}

fn edit(path: &Path, f: impl FnOnce(&mut Value)) {
    let mut v: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    f(&mut v);
    std::fs::write(path, serde_json::to_string_pretty(&v).unwrap()).unwrap();
}

fn problems(r: &Value) -> Vec<String> {
    strings(&r["problems"])
}

fn strings(list: &Value) -> Vec<String> {
    list.as_array()
        .unwrap()
        .iter()
        .map(|p| p.as_str().unwrap().to_string())
        .collect()
}

#[test]
fn recorded_runs_are_current_and_add_up_each_seed_once() {
    let dir = tempfile::tempdir().unwrap();
    record(dir.path(), "5", "3", &[]);
    record(dir.path(), "5", "4", &[]);
    record(dir.path(), "6", "2", &[]);
    let (ok, r) = check(dir.path(), "all", "6");
    assert!(ok, "{r}");
    assert_eq!(problems(&r), Vec::<String>::new());
    let totals = r["totals"].as_array().unwrap();
    assert_eq!(totals.len(), 1, "{r}");
    // Seed 5's runs share their first 3 merges: the longer one counts.
    assert_eq!(totals[0]["merges"], 6, "{r}");
    assert_eq!(totals[0]["runs"], 3, "{r}");
    assert_eq!(totals[0]["met"], true, "{r}");
    let (_, r) = check(dir.path(), "none", "7");
    assert_eq!(r["totals"][0]["met"], false, "{r}");
    // Another configuration is its own line. A mode typed with a blank is
    // recorded in its canonical spelling, one argument, so the entry's
    // args parse again.
    let entry = record(
        dir.path(),
        "5",
        "2",
        &["--inputs", "2", "--mode", "overlap: 1/2"],
    );
    let args = serde_json::from_str::<Value>(&std::fs::read_to_string(entry).unwrap()).unwrap()
        ["args"]
        .clone();
    let args: Vec<&str> = args
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a.as_str().unwrap())
        .collect();
    assert!(
        args.windows(2).any(|w| w == ["--mode", "overlap:1/2"]),
        "{args:?}"
    );
    let (ok, r) = check(dir.path(), "first", "6");
    assert!(ok, "{r}");
    assert_eq!(r["totals"].as_array().unwrap().len(), 2, "{r}");
}

#[test]
fn an_entry_is_never_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let path = record(dir.path(), "5", "2", &[]);
    let before = std::fs::read_to_string(&path).unwrap();
    let d = dir.path().to_str().unwrap();
    let o = hiermerge(
        &[
            "cosim", "--unit", "merger", "--engine", "ir", "--seed", "5", "--count", "2",
            "--ledger", d,
        ],
        &[],
    );
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("--ledger") && err.contains("ir-seed5-n2.json"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(&path).unwrap(), before);
}

#[test]
fn stale_failed_and_inconsistent_entries_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = record(dir.path(), "5", "2", &[]);
    let name = path.file_name().unwrap().to_str().unwrap().to_string();
    let original = std::fs::read_to_string(&path).unwrap();
    let restore = || std::fs::write(&path, &original).unwrap();

    // A netlist other than today's: reported as stale, its configuration
    // as lacking evidence; an error only with --strict.
    edit(&path, |v| v["netlist_sha256"] = "0".repeat(64).into());
    let (ok, r) = check(dir.path(), "none", "1");
    assert!(ok, "{r}");
    assert!(problems(&r).is_empty(), "{r}");
    let stale = strings(&r["stale"]);
    assert!(
        stale.len() == 1 && stale[0].contains(&name) && stale[0].contains("netlist changed"),
        "{stale:?}"
    );
    assert_eq!(r["totals"].as_array().unwrap().len(), 0, "{r}");
    let lacking = r["lacking"].as_array().unwrap();
    assert!(
        lacking.len() == 1 && lacking[0]["engine"] == "ir" && lacking[0]["merges"] == 0,
        "{r}"
    );
    let o = hiermerge(
        &[
            "ledger",
            "--dir",
            dir.path().to_str().unwrap(),
            "--stimulus",
            "none",
            "--strict",
        ],
        &[],
    );
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("1 ledger entries are stale"));
    restore();

    // Another seed in both places: the netlist is today's, the stimulus
    // is not the recorded one (seen only when the stimulus is checked).
    edit(&path, |v| {
        v["seed"] = 6.into();
        let args = v["args"].as_array_mut().unwrap();
        let at = args.iter().position(|a| a == "--seed").unwrap();
        args[at + 1] = "6".into();
    });
    assert!(strings(&check(dir.path(), "none", "1").1["stale"]).is_empty());
    let (ok, r) = check(dir.path(), "all", "1");
    assert!(ok && problems(&r).is_empty(), "{r}");
    assert!(strings(&r["stale"])[0].contains("stimulus changed"), "{r}");
    restore();

    // The seed field disagreeing with the args.
    edit(&path, |v| v["seed"] = 7.into());
    let (ok, r) = check(dir.path(), "none", "1");
    assert!(!ok && problems(&r)[0].contains("differ from args"), "{r}");
    restore();

    // Args that generate another top.
    edit(&path, |v| {
        let args = v["args"].as_array_mut().unwrap();
        let at = args.iter().position(|a| a == "--inputs").unwrap();
        args[at + 1] = "3".into();
    });
    let (ok, r) = check(dir.path(), "none", "1");
    assert!(!ok && problems(&r)[0].contains("field top"), "{r}");
    restore();

    // A failed run stays a problem until it is removed.
    edit(&path, |v| {
        v["passed"] = false.into();
        v["mismatches"] = 4.into();
    });
    let (ok, r) = check(dir.path(), "none", "1");
    assert!(
        !ok && problems(&r)[0].contains("run failed (4 mismatches)"),
        "{r}"
    );
    restore();
    assert!(check(dir.path(), "all", "1").0);

    // A file that is no entry: named among the problems, the good entry
    // beside it still checked.
    std::fs::write(path.with_file_name("notes.json"), "[]").unwrap();
    let o = hiermerge(&["ledger", "--dir", dir.path().to_str().unwrap()], &[]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stdout);
    assert!(
        err.contains("notes.json") && err.contains("not a ledger entry"),
        "{err}"
    );
}

#[test]
fn only_real_merger_runs_are_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_str().unwrap();
    let o = hiermerge(
        &[
            "cosim",
            "--unit",
            "translate",
            "--engine",
            "ir",
            "--count",
            "2",
            "--ledger",
            d,
        ],
        &[],
    );
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--ledger applies to --unit merger"));
    let o = hiermerge(
        &[
            "cosim", "--unit", "merger", "--engine", "ir", "--count", "2", "--ledger", d,
        ],
        &[("HIERMERGE_COSIM_FLIP_EXPECTED", "0")],
    );
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("records real runs only"));
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[test]
fn a_plan_lists_the_runs_still_to_make() {
    let dir = tempfile::tempdir().unwrap();
    record(dir.path(), "5", "2", &[]);
    let plan = dir.path().join("plan.txt");
    let done = "--unit merger --engine ir --seed 5 --count 2";
    let left = "--unit merger --engine ir --seed 6 --count 2 # not yet";
    std::fs::write(&plan, format!("# a plan\n{done}\n\n{left}\n")).unwrap();
    let d = dir.path().to_str().unwrap();
    let p = plan.to_str().unwrap();
    let o = hiermerge(&["ledger", "--dir", d, "--plan", p, "--missing"], &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        String::from_utf8_lossy(&o.stdout),
        "--unit merger --engine ir --seed 6 --count 2\n"
    );
    let o = hiermerge(
        &["ledger", "--dir", d, "--plan", p, "--missing", "--json"],
        &[],
    );
    assert_eq!(
        json_of(&o)["missing"],
        serde_json::json!(["--unit merger --engine ir --seed 6 --count 2"])
    );
    let o = hiermerge(&["ledger", "--dir", d, "--plan", p, "--json"], &[]);
    let r = json_of(&o);
    let lines = r["plan"].as_array().unwrap();
    assert_eq!(lines.len(), 2, "{r}");
    assert_eq!(
        (lines[0]["line"].as_u64(), lines[0]["done"].as_bool()),
        (Some(2), Some(true))
    );
    assert_eq!(
        (lines[1]["line"].as_u64(), lines[1]["done"].as_bool()),
        (Some(4), Some(false))
    );
    // The plan's lines say how many merges its configuration needs (2 + 2,
    // not --need's 100,000): 2 are current, so it lacks evidence.
    let t = &r["totals"][0];
    assert_eq!(
        (t["merges"].as_u64(), t["need"].as_u64()),
        (Some(2), Some(4)),
        "{r}"
    );
    assert_eq!(t["met"], false, "{r}");
    let lacking = r["lacking"].as_array().unwrap();
    assert!(lacking.len() == 1 && lacking[0]["need"] == 4, "{r}");
    // A stale entry does not count as done.
    let entry = dir
        .path()
        .join(lines[0]["top"].as_str().unwrap())
        .join("ir-seed5-n2.json");
    edit(&entry, |v| v["netlist_sha256"] = "1".repeat(64).into());
    let o = hiermerge(&["ledger", "--dir", d, "--plan", p, "--missing"], &[]);
    assert_eq!(String::from_utf8_lossy(&o.stdout).lines().count(), 2);
    // `--stale-paths` names that entry alone (what scripts/longruns removes
    // before it reruns the line).
    let o = hiermerge(&["ledger", "--dir", d, "--stale-paths"], &[]);
    assert!(o.status.success());
    assert_eq!(
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .collect::<Vec<_>>(),
        [entry.display().to_string()]
    );
    let o = hiermerge(&["ledger", "--dir", d, "--stale-paths", "--json"], &[]);
    assert_eq!(json_of(&o)["stale"].as_array().map(Vec::len), Some(1));
    // A line that is no merger run is named by file and line.
    std::fs::write(&plan, format!("{done}\n--unit translate --count 2\n")).unwrap();
    let o = hiermerge(&["ledger", "--dir", d, "--plan", p], &[]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("plan.txt line 2") && err.contains("--unit merger"),
        "{err}"
    );
    // A line clap refuses is named with clap's reason.
    std::fs::write(&plan, format!("{done}\n{done} --sead 3\n")).unwrap();
    let o = hiermerge(&["ledger", "--dir", d, "--plan", p], &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("plan.txt line 2") && err.contains("--sead"),
        "{err}"
    );
}

/// The hierarchy unit (translation unit and merger top) has its own
/// entries: recorded with its unit and top, current while its netlist and
/// stimulus are, an entry whose `unit` contradicts its args is named, and
/// a plan line of it is done once its run is recorded.
#[test]
fn hierarchy_unit_runs_are_recorded_and_checked() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_str().unwrap();
    let small = "--unit hierarchy --engine ir --seed 9 --count 2 --max-lod 8 --quant-bits 0 --index-bits 12 --hier-bits 3 --inputs 2";
    let mut args: Vec<&str> = vec!["cosim"];
    args.extend(small.split(' '));
    args.extend(["--ledger", d, "--json"]);
    let o = hiermerge(&args, &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = json_of(&o);
    let top = r["hierarchy"]["top"].as_str().unwrap();
    assert!(top.starts_with("hierarchy_unit_d8_"), "{r}");
    let path = dir.path().join(top).join("ir-seed9-n2.json");
    let entry: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    assert_eq!(entry["unit"], "hierarchy");
    assert_eq!(entry["stimulus_sha256"], r["hierarchy"]["stimulus_sha256"]);
    let plan = dir.path().join("plan.txt");
    std::fs::write(&plan, format!("{small}\n")).unwrap();
    let p = plan.to_str().unwrap();
    let ledger = |extra: &[&str]| {
        let mut a = vec!["ledger", "--dir", d, "--plan", p, "--stimulus", "all"];
        a.extend(extra);
        a.push("--json");
        hiermerge(&a, &[])
    };
    let o = ledger(&[]);
    let r = json_of(&o);
    assert!(o.status.success(), "{r}");
    assert_eq!(r["plan"][0]["done"], true, "{r}");
    assert_eq!(r["entries"][0]["stimulus_current"], true, "{r}");
    // A run of two other merges is not this entry's evidence.
    edit(&path, |v| {
        v["stimulus_sha256"] = Value::from("0".repeat(64))
    });
    let r = json_of(&ledger(&[]));
    assert_eq!(r["plan"][0]["done"], false, "{r}");
    assert!(
        strings(&r["stale"])
            .iter()
            .any(|s| s.contains("the stimulus changed")),
        "{r}"
    );
    edit(&path, |v| v["unit"] = Value::from("merger"));
    let o = ledger(&[]);
    assert!(!o.status.success());
    let r = json_of(&o);
    assert!(
        problems(&r)
            .iter()
            .any(|p| p.contains("field unit `merger`, but its args run `--unit hierarchy`")),
        "{r}"
    );
}
