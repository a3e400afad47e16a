//! Snapshot tests of the emitted text. The snapshots live in
//! `tests/snapshots/<module>.v`; `UPDATE_SNAPSHOTS=1` rewrites them.

mod designs;

use rtl_gen::{emit_design, examples, Module};
use std::path::PathBuf;

fn snapshot_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests")
        .join("snapshots")
}

fn check(m: &Module) {
    let update = std::env::var("UPDATE_SNAPSHOTS")
        .map(|v| v == "1")
        .unwrap_or(false);
    for (file, text) in emit_design(m).unwrap_or_else(|e| panic!("{e}")) {
        let path = snapshot_dir().join(&file);
        if update {
            std::fs::create_dir_all(snapshot_dir()).expect("snapshot dir");
            std::fs::write(&path, &text).expect("write snapshot");
            continue;
        }
        let want = std::fs::read_to_string(&path).unwrap_or_else(|e| {
            panic!(
                "{}: {e}; run with UPDATE_SNAPSHOTS=1 to create it",
                path.display()
            )
        });
        if want != text {
            let first = want
                .lines()
                .zip(text.lines())
                .position(|(a, b)| a != b)
                .unwrap_or(0);
            panic!(
                "{} differs from the emitted text at line {}:\n  snapshot: {:?}\n  emitted:  {:?}\n(UPDATE_SNAPSHOTS=1 rewrites it after review)",
                path.display(),
                first + 1,
                want.lines().nth(first),
                text.lines().nth(first)
            );
        }
    }
}

#[test]
fn counter_snapshot() {
    check(&examples::counter(8));
}

#[test]
fn fifo_snapshot() {
    check(&examples::fifo(8, 2));
}

#[test]
fn drop_fifo_snapshot() {
    check(&examples::drop_fifo(8, 2));
}

#[test]
fn skid_buffer_snapshot() {
    check(&examples::skid_buffer(8));
}

#[test]
fn datapath_snapshot() {
    check(&examples::abs_diff_pipeline(8, 100));
}

#[test]
fn kitchen_sink_snapshot() {
    check(&designs::kitchen_sink());
}

#[test]
fn ram_snapshot() {
    check(&designs::ram());
}

#[test]
fn hierarchy_snapshot() {
    check(&designs::hierarchy());
}

#[test]
fn emission_is_byte_identical_across_builds() {
    let a = emit_design(&designs::hierarchy()).unwrap();
    let b = emit_design(&designs::hierarchy()).unwrap();
    assert_eq!(a, b);
    let k1 = rtl_gen::emit_verilog(&designs::kitchen_sink()).unwrap();
    let k2 = rtl_gen::emit_verilog(&designs::kitchen_sink()).unwrap();
    assert_eq!(k1, k2);
}

#[test]
fn emitted_text_follows_the_conventions() {
    let v = rtl_gen::emit_verilog(&designs::kitchen_sink()).unwrap();
    // Every literal is sized: outside bit selects `[..]` and repeat counts
    // `{n{..}}`, every number carries a `'` width.
    for line in v.lines().filter(|l| l.trim_start().starts_with("assign")) {
        let rhs = line.split_once('=').map(|x| x.1).unwrap_or("");
        if let Some(tok) = unsized_numbers(rhs).first() {
            panic!("unsized literal `{tok}` in: {line}");
        }
        assert!(!line.contains("_T_"), "{line}");
    }
    assert!(
        v.contains("// rtl-gen/tests/designs/mod.rs:"),
        "source comments"
    );
    assert!(v.contains("$signed("), "signed operators are explicit");
    assert!(v.ends_with("`default_nettype wire\n"));
}

/// Numbers in an expression that are neither sized literals, bit indices nor repeat counts.
fn unsized_numbers(expr: &str) -> Vec<String> {
    let chars: Vec<char> = expr.chars().collect();
    let mut out = Vec::new();
    let mut depth = 0;
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        if c == '[' {
            depth += 1;
        } else if c == ']' {
            depth -= 1;
        } else if depth == 0
            && c.is_ascii_digit()
            && (i == 0 || !(chars[i - 1].is_ascii_alphanumeric() || chars[i - 1] == '_'))
        {
            let start = i;
            while i < chars.len() && (chars[i].is_ascii_alphanumeric() || chars[i] == '\'') {
                i += 1;
            }
            let tok: String = chars[start..i].iter().collect();
            let repeat = chars.get(i) == Some(&'{');
            if !tok.contains('\'') && !repeat {
                out.push(tok);
            }
            continue;
        }
        i += 1;
    }
    out
}
