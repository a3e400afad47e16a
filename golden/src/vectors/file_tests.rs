//! Vector files: round trip, determinism, parameter mismatch, malformed
//! lines, atomic writes, and the generator's coverage of every hard-case
//! category, counted from the generated records themselves.

use std::collections::BTreeMap;
use std::path::Path;

use super::classes::{classes, expected_classes};
use super::translate::*;
use super::*;
use crate::params::Params;
use crate::translate::model::*;
use crate::translate::TranslateUnitConfig;

fn design(d: u8, q: u8, i: u8, h: u8, depth: u32, binary64: bool) -> TranslateDesign {
    TranslateDesign {
        unit: TranslateUnitConfig {
            params: Params::new(d, q, i, h).unwrap(),
            table_depth: depth,
        },
        binary64,
    }
}

fn designs() -> Vec<TranslateDesign> {
    vec![
        TranslateDesign::default(),
        design(31, 16, 32, 8, 24, true),
        design(10, 0, 12, 3, 5, false),
        design(1, 0, 1, 1, 1, true),
    ]
}

#[test]
fn round_trip_is_exact_and_generation_deterministic() {
    let dir = tempfile::tempdir().unwrap();
    for d in designs() {
        let path = dir.path().join(format!("{}.jsonl", d.tag()));
        write_translate_vectors(&path, &d, 42, 3_000).unwrap();
        let (header, txns) = read_translate_vectors(&path, &d).unwrap();
        assert_eq!((header.seed, header.count), (42, 3_000));
        assert_eq!(header.unit, UnitKind::Translate);
        assert_eq!(txns, generate(&d, 42, 3_000).unwrap(), "{}", d.tag());
        let again = dir.path().join("again.jsonl");
        write_translate_vectors(&again, &d, 42, 3_000).unwrap();
        assert_eq!(
            std::fs::read(&path).unwrap(),
            std::fs::read(&again).unwrap()
        );
        let other = dir.path().join("other.jsonl");
        write_translate_vectors(&other, &d, 43, 3_000).unwrap();
        assert_ne!(
            std::fs::read(&path).unwrap(),
            std::fs::read(&other).unwrap()
        );
    }
}

#[test]
fn header_line_carries_every_parameter() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("v.jsonl");
    let d = design(31, 16, 32, 8, 200, true);
    write_translate_vectors(&path, &d, 5, 10).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let header: Value = serde_json::from_str(text.lines().next().unwrap()).unwrap();
    assert_eq!(header["format"], "hiermerge-vectors");
    assert_eq!(header["version"], 1);
    assert_eq!(header["unit"], "translate");
    assert_eq!(header["seed"], 5);
    assert_eq!(header["count"], 10);
    let params = header["params"].as_object().unwrap();
    for (k, v) in [
        ("max_lod", json!(31)),
        ("quant_bits", json!(16)),
        ("index_bits", json!(32)),
        ("hier_bits", json!(8)),
        ("table_depth", json!(200)),
        ("binary64", json!(true)),
    ] {
        assert_eq!(params[k], v, "{k}");
    }
    assert_eq!(text.lines().count(), 11);
}

use serde_json::json;

#[test]
fn differing_parameters_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("v.jsonl");
    let written = TranslateDesign::default();
    write_translate_vectors(&path, &written, 1, 50).unwrap();
    let mut dut = written;
    dut.unit.params.max_lod = 31;
    dut.binary64 = true;
    let e = read_translate_vectors(&path, &dut).unwrap_err();
    let VectorError::ParamsDiffer { diffs, .. } = &e else {
        panic!("{e}")
    };
    let names: Vec<&str> = diffs.iter().map(|d| d.name.as_str()).collect();
    assert_eq!(names, ["binary64", "max_lod"]);
    let msg = e.to_string();
    assert!(
        msg.contains("`max_lod` is 16 in the file, 31 in the design"),
        "{msg}"
    );
    assert!(msg.contains("v.jsonl"), "{msg}");
    // The other unit's reader refuses the file by its `unit`.
    let raw = read_jsonl(&path, UnitKind::Merge, &written.param_map()).unwrap_err();
    assert!(matches!(raw, VectorError::Malformed { line: 1, ref field, .. } if field == "unit"));
}

/// Rewrites line `n` (1-based) of `path` with `f`.
fn edit_line(path: &Path, n: usize, f: impl Fn(&mut Value)) {
    let text = std::fs::read_to_string(path).unwrap();
    let lines: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i + 1 == n {
                let mut v: Value = serde_json::from_str(l).unwrap();
                f(&mut v);
                v.to_string()
            } else {
                l.to_string()
            }
        })
        .collect();
    std::fs::write(path, lines.join("\n") + "\n").unwrap();
}

fn malformed_at(e: VectorError) -> (usize, String) {
    match e {
        VectorError::Malformed { line, field, .. } => (line, field),
        other => panic!("expected a malformed-line error, got {other}"),
    }
}

#[test]
fn malformed_lines_name_file_line_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let d = TranslateDesign::default();
    let fresh = |name: &str| {
        let p = dir.path().join(name);
        write_translate_vectors(&p, &d, 9, 300).unwrap();
        p
    };
    let line_of = |p: &Path, op: &str| {
        let text = std::fs::read_to_string(p).unwrap();
        text.lines()
            .position(|l| l.contains(&format!("\"op\":\"{op}\"")))
            .unwrap()
            + 1
    };
    // A placement wider than the 32-bit port of a binary32-only design.
    let p = fresh("wide.jsonl");
    let n = line_of(&p, "determine");
    edit_line(&p, n, |v| v["in"]["placement"][1] = json!(1u64 << 32));
    let e = read_translate_vectors(&p, &d).unwrap_err();
    assert!(
        e.to_string()
            .contains(&format!("wide.jsonl:{n}: field `in.placement[1]`")),
        "{e}"
    );
    assert_eq!(malformed_at(e), (n, "in.placement[1]".into()));
    // A missing field, a node field too wide, an unknown op, a bad code.
    let p = fresh("missing.jsonl");
    let n = line_of(&p, "determine");
    edit_line(&p, n, |v| {
        v["out"].as_object_mut().unwrap().remove("err_nan");
    });
    assert_eq!(
        malformed_at(read_translate_vectors(&p, &d).unwrap_err()),
        (n, "out.err_nan".into())
    );
    let p = fresh("node.jsonl");
    let n = line_of(&p, "apply");
    edit_line(&p, n, |v| v["in"]["node"]["x"] = json!(1u64 << 16));
    assert_eq!(
        malformed_at(read_translate_vectors(&p, &d).unwrap_err()),
        (n, "in.node.x".into())
    );
    let p = fresh("op.jsonl");
    edit_line(&p, 2, |v| v["op"] = json!("merge"));
    assert_eq!(
        malformed_at(read_translate_vectors(&p, &d).unwrap_err()),
        (2, "op".into())
    );
    let p = fresh("string.jsonl");
    let n = line_of(&p, "apply");
    edit_line(&p, n, |v| v["out"]["code"] = json!("0"));
    assert_eq!(
        malformed_at(read_translate_vectors(&p, &d).unwrap_err()),
        (n, "out.code".into())
    );
    // Not JSON at all, and fewer records than the header says.
    let p = fresh("garbage.jsonl");
    let mut text = std::fs::read_to_string(&p).unwrap();
    text.push_str("{not json\n");
    std::fs::write(&p, &text).unwrap();
    assert_eq!(
        malformed_at(read_translate_vectors(&p, &d).unwrap_err()).0,
        302
    );
    let p = fresh("short.jsonl");
    let text = std::fs::read_to_string(&p).unwrap();
    let cut: Vec<&str> = text.lines().take(200).collect();
    std::fs::write(&p, cut.join("\n") + "\n").unwrap();
    assert_eq!(
        malformed_at(read_translate_vectors(&p, &d).unwrap_err()).1,
        "count"
    );
    // A header of another format version.
    let p = fresh("version.jsonl");
    edit_line(&p, 1, |v| v["version"] = json!(2));
    assert_eq!(
        malformed_at(read_translate_vectors(&p, &d).unwrap_err()),
        (1, "version".into())
    );
}

/// Issue 21: an unknown field, an `err_width` a binary32 port cannot carry,
/// a record past the header's count, a count past the limit and a device as
/// the file are each one error naming file, line and field.
#[test]
fn strict_records_and_bounded_reads() {
    let dir = tempfile::tempdir().unwrap();
    let d = TranslateDesign::default();
    let fresh = |name: &str| {
        let p = dir.path().join(name);
        write_translate_vectors(&p, &d, 9, 40).unwrap();
        p
    };
    let p = fresh("unknown.jsonl");
    edit_line(&p, 3, |v| v["in"]["extra"] = json!(1));
    assert_eq!(
        malformed_at(read_translate_vectors(&p, &d).unwrap_err()),
        (3, "in.extra".into())
    );
    let p = fresh("top.jsonl");
    edit_line(&p, 2, |v| v["note"] = json!("x"));
    assert_eq!(
        malformed_at(read_translate_vectors(&p, &d).unwrap_err()),
        (2, "note".into())
    );
    let p = fresh("width.jsonl");
    edit_line(&p, 2, |v| v["out"]["err_width"] = json!(5));
    assert_eq!(
        malformed_at(read_translate_vectors(&p, &d).unwrap_err()),
        (2, "out.err_width".into())
    );
    let p = fresh("extra.jsonl");
    let mut text = std::fs::read_to_string(&p).unwrap();
    let last = text.lines().last().unwrap().to_string();
    text.push_str(&(last + "\n"));
    std::fs::write(&p, text).unwrap();
    assert_eq!(
        malformed_at(read_translate_vectors(&p, &d).unwrap_err()),
        (42, "<line>".into())
    );
    let p = fresh("count.jsonl");
    edit_line(&p, 1, |v| v["count"] = json!(1_000_000_000_000u64));
    assert_eq!(
        malformed_at(read_translate_vectors(&p, &d).unwrap_err()),
        (1, "count".into())
    );
    let e = read_translate_vectors(Path::new("/dev/zero"), &d).unwrap_err();
    assert!(e.to_string().contains("character device"), "{e}");
    let e = write_translate_vectors(&dir.path().join("big.jsonl"), &d, 1, 1 << 40).unwrap_err();
    assert!(e.to_string().contains("at most 1000000"), "{e}");
}

#[test]
fn writes_are_atomic() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("v.jsonl");
    let header = |count| Header {
        unit: UnitKind::Translate,
        params: BTreeMap::new(),
        seed: 0,
        count,
    };
    let failing = (0..1000).map(|i| {
        if i == 500 {
            Err(VectorError::Model {
                what: "boom".into(),
            })
        } else {
            Ok(json!({ "i": i }))
        }
    });
    // A failure half-way leaves no file, and no temporary file behind.
    assert!(write_jsonl(&path, &header(1000), failing.clone()).is_err());
    assert!(!path.exists());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    // Over an existing file: the old contents stay untouched.
    let ok = (0..3).map(|i| Ok(json!({ "i": i })));
    write_jsonl(&path, &header(3), ok).unwrap();
    let before = std::fs::read(&path).unwrap();
    assert!(write_jsonl(&path, &header(1000), failing).is_err());
    assert_eq!(std::fs::read(&path).unwrap(), before);
    // A count that does not match the records is refused the same way.
    let two = (0..2).map(|i| Ok(json!({ "i": i })));
    assert!(write_jsonl(&path, &header(3), two).is_err());
    assert_eq!(std::fs::read(&path).unwrap(), before);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn every_hard_case_category_is_generated_on_purpose() {
    for d in designs() {
        let n = 20_000;
        let txns = generate(&d, 77, n).unwrap();
        let c = classes(&d, &txns);
        println!("{}: {c:?}", d.tag());
        let want = expected_classes(&d);
        // A fixed share: every class in at least 0.2% of the records.
        for k in want {
            let got = c.get(k).copied().unwrap_or(0);
            assert!(got * 500 >= n, "{}: `{k}` in {got} of {n} records", d.tag());
        }
    }
}
