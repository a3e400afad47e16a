//! The enable idiom (`RegisterStyle::Enables`, SPEC 11) is the same logic as
//! the plain emission (`RegisterStyle::NextWires`): Yosys proves every
//! module of the example and test designs and of small merging units
//! equivalent, per module, flip-flop by flip-flop; and the emitted text has
//! the idiom's shape (grouped enables, no `_next` wire left for a folded
//! register, the generator line on each assignment).

mod common;
mod designs;

use common::{require_tool, verilator_lint, yosys_synth};
use rtl_gen::verilog::{emit_design_with_style, write_design_with_style, RegisterStyle};
use rtl_gen::{examples, Bits, Module};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Both emissions of `m` written to `dir/old` and `dir/new`.
fn both_styles(m: &Module, dir: &Path) -> (Vec<PathBuf>, Vec<PathBuf>) {
    let write = |sub: &str, style| {
        write_design_with_style(m, &dir.join(sub), style)
            .unwrap_or_else(|e| panic!("{}: {e}", m.name()))
    };
    (
        write("old", RegisterStyle::NextWires),
        write("new", RegisterStyle::Enables),
    )
}

/// The Yosys commands proving module `module` of file `old` and file `new`
/// equivalent: each elaborated alone (`proc`, memories collected into
/// cells, the modules it instantiates black boxes from `blackboxes`),
/// matched by name (`equiv_make`: registers, memories and instances keep
/// their names in both styles), then `equiv_simple -seq 2` and
/// `equiv_induct`; `equiv_status -assert` fails on any unproven cell.
pub fn equivalence_script(old: &Path, new: &Path, module: &str, blackboxes: &[&Path]) -> String {
    let bb: String = blackboxes
        .iter()
        .map(|f| format!("read_verilog -lib {}; ", f.display()))
        .collect();
    let side = |file: &Path, name: &str| {
        format!(
            "read_verilog {}; {bb}hierarchy -top {module}; proc; memory -nomap; opt_clean; \
             rename {module} {name}; design -stash {name}; ",
            file.display()
        )
    };
    format!(
        "{}{}design -copy-from gold -as gold gold; design -copy-from gate -as gate gate; \
         equiv_make gold gate equiv; hierarchy -top equiv; equiv_simple -seq 2; equiv_induct; \
         equiv_status -assert",
        side(old, "gold"),
        side(new, "gate")
    )
}

/// Runs the equivalence proof of one module; the error quotes Yosys.
pub fn prove_equivalent(
    old: &Path,
    new: &Path,
    module: &str,
    blackboxes: &[&Path],
) -> Result<(), String> {
    let script = equivalence_script(old, new, module, blackboxes);
    let out = Command::new("yosys")
        .args(["-q", "-p", &script])
        .output()
        .map_err(|e| format!("running yosys: {e}"))?;
    if out.status.success() {
        return Ok(());
    }
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let tail: Vec<&str> = text.lines().rev().take(40).collect();
    Err(format!(
        "{module}: not proven equivalent:\n{}",
        tail.into_iter().rev().collect::<Vec<_>>().join("\n")
    ))
}

/// Every module of `m`'s design proven equivalent in both styles, each
/// with the modules before it (its children come first) as black boxes.
fn check_equivalent(m: &Module) {
    check_equivalent_from(m, 0);
}

/// [`check_equivalent`] of the top module only (its children black boxes).
fn check_equivalent_top(m: &Module) {
    check_equivalent_from(m, usize::MAX);
}

/// The modules of `m`'s design from the `first`-th on (the top at least).
fn check_equivalent_from(m: &Module, first: usize) {
    if !require_tool("yosys") {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let (old, new) = both_styles(m, dir.path());
    assert_eq!(old.len(), new.len());
    let first = first.min(old.len() - 1);
    for (i, (o, n)) in old.iter().zip(&new).enumerate().skip(first) {
        let module = o.file_stem().unwrap().to_string_lossy().into_owned();
        let children: Vec<&Path> = old[..i].iter().map(PathBuf::as_path).collect();
        prove_equivalent(o, n, &module, &children).unwrap_or_else(|e| panic!("{e}"));
    }
}

/// Registers of every shape the idiom knows, each read by an output.
fn idiom_shapes() -> Module {
    let m = Module::new("idiom_shapes");
    let (en, set, clr) = (m.input("en", 1), m.input("grant", 1), m.input("drop", 1));
    let (d, stall) = (m.input("d", 8), m.input("stall", 1));
    // Two registers with one enable share one `if`.
    let a = m.reg_no_reset("a", 8);
    a.next_when(en, d);
    let b = m.reg_no_reset("b", 8);
    b.next_when(en, !d);
    // The register on the then-arm: loads when `stall` is low.
    let c = m.reg_no_reset("c", 8);
    c.next(stall.mux(c, d.add(1, 8)));
    // Holding on the other arm of `en`: the else of a and b's `if (en)`.
    let e = m.reg_no_reset("e", 8);
    e.next(en.mux(e, !d));
    // A priority chain: set, else clear, else hold.
    let s = m.reg_no_reset("s", 1);
    s.next(set.mux(m.lit(1, 1), clr.mux(m.lit(0, 1), s)));
    // A mux read twice (by the register and an output) stays a wire.
    let f = m.reg_no_reset("f", 8);
    let f_next = en.mux(d, f);
    f.next(f_next);
    // A reset register with an enable: `end else if (en)`.
    let r = m.reg_reset("r", 8, Bits::from_u128(5, 8).expect("fits"));
    r.next_when(en, d);
    // Nested enables, both folded: `if (set) if (en)`.
    let n = m.reg_no_reset("n", 8);
    n.next(set.mux(en.mux(d, n), n));
    m.output("y", m.concat(&[a, b, c, e, f, f_next, r, n]));
    m.output("s_q", s);
    m
}

pub fn text_of(m: &Module, style: RegisterStyle) -> String {
    let files = emit_design_with_style(m, style).unwrap_or_else(|e| panic!("{e}"));
    files.last().expect("a top").1.clone()
}

/// The lines of `text` from the one starting (after indentation) with
/// `first`, `count` of them, trimmed: the shape of one statement.
fn lines_from(text: &str, first: &str, count: usize) -> Vec<String> {
    let lines: Vec<&str> = text.lines().collect();
    let at = lines
        .iter()
        .position(|l| l.trim_start().starts_with(first))
        .unwrap_or_else(|| panic!("no line starts with {first:?} in\n{text}"));
    lines[at..(at + count).min(lines.len())]
        .iter()
        .map(|l| l.split(" //").next().unwrap_or("").trim().to_string())
        .collect()
}

#[test]
fn enable_idiom_has_the_documented_shape() {
    let m = idiom_shapes();
    let warnings = m.validate_design().unwrap_or_else(|e| panic!("{e}"));
    assert!(warnings.is_empty(), "{}", rtl_gen::Diagnostics(warnings));
    let old = text_of(&m, RegisterStyle::NextWires);
    let new = text_of(&m, RegisterStyle::Enables);
    for r in ["a", "b", "c", "e", "s", "f", "r", "n"] {
        assert!(
            old.contains(&format!("{r} <= {r}_next;")),
            "old style: {r}\n{old}"
        );
    }
    // Folded registers lose their next wire; the shared one keeps it.
    for r in ["a", "b", "c", "e", "s", "r", "n"] {
        assert!(
            !new.contains(&format!("{r}_next")),
            "{r}_next left in\n{new}"
        );
    }
    assert!(new.contains("f <= f_next;"), "{new}");
    assert!(new.contains("assign f_next = en ? d : f;"), "{new}");
    assert_eq!(
        lines_from(&new, "if (rst) begin", 4),
        [
            "if (rst) begin",
            "r <= 8'd5;",
            "end else if (en) begin",
            "r <= d;"
        ]
    );
    assert_eq!(
        lines_from(&new, "if (en) begin", 6),
        [
            "if (en) begin",
            "a <= d;",
            "b <= d_not;",
            "end else begin",
            "e <= d_not;",
            "end"
        ],
        "a and b share one `if (en)`, e its else; `~d` is written once:\n{new}"
    );
    assert_eq!(
        lines_from(&new, "if (!stall) begin", 3),
        ["if (!stall) begin", "c <= d + 8'd1;", "end"]
    );
    assert_eq!(
        lines_from(&new, "if (grant) begin", 6),
        [
            "if (grant) begin",
            "s <= 1'b1;",
            "if (en) begin",
            "n <= d;",
            "end",
            "end else if (drop) begin"
        ],
        "s and n share `if (grant)`; s's chain goes on with `else if`:\n{new}"
    );
    // Each assignment names the generator line of the mux that chose it.
    let line_of = |needle: &str| {
        let l = new
            .lines()
            .find(|l| l.trim_start().starts_with(needle))
            .unwrap_or_else(|| panic!("{needle}:\n{new}"));
        l.split("// ").nth(1).unwrap_or("").to_string()
    };
    assert!(line_of("a <= d;").starts_with("rtl-gen/tests/register_style.rs:"));
    assert_ne!(line_of("a <= d;"), line_of("b <= d_not;"));
    assert_eq!(new, text_of(&m, RegisterStyle::Enables), "deterministic");
}

#[test]
fn a_register_only_its_own_mux_reads_keeps_its_next_wire() {
    let m = Module::new("self_only");
    let (en, d) = (m.input("en", 1), m.input("d", 4));
    let q = m.reg("q", 4);
    q.next_when(en, d);
    m.output("y", en);
    // Folded, nothing would read q and lint would report it unused; the
    // mux, read once, is written in the load.
    let text = text_of(&m, RegisterStyle::Enables);
    assert!(text.contains("q <= en ? d : q;"), "{text}");
}

#[test]
fn idiom_lints_clean() {
    let dir = tempfile::tempdir().expect("temp dir");
    let m = idiom_shapes();
    let files = rtl_gen::write_design(&m, dir.path()).unwrap_or_else(|e| panic!("{e}"));
    if require_tool("verilator") {
        verilator_lint(&files, &m.name()).unwrap_or_else(|e| panic!("{e}"));
    }
    if require_tool("yosys") {
        yosys_synth(&files, &m.name()).unwrap_or_else(|e| panic!("{e}"));
    }
}

#[test]
fn both_styles_are_equivalent_on_examples_and_test_designs() {
    for m in [
        idiom_shapes(),
        examples::counter(8),
        examples::fifo(8, 3),
        examples::skid_buffer(16),
        examples::abs_diff_pipeline(8, 100),
        designs::ram(),
        designs::hierarchy(),
        designs::wide(),
    ] {
        check_equivalent(&m);
    }
}

#[test]
fn a_changed_enable_is_not_proven_equivalent() {
    if !require_tool("yosys") {
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let m = idiom_shapes();
    let (old, new) = both_styles(&m, dir.path());
    let text = std::fs::read_to_string(&new[0]).expect("read");
    let broken = dir.path().join("broken.v");
    std::fs::write(
        &broken,
        text.replacen("if (!stall) begin", "if (stall) begin", 1),
    )
    .expect("write");
    let r = prove_equivalent(&old[0], &broken, &m.name(), &[]);
    assert!(
        r.is_err(),
        "a design whose c loads on the wrong polarity passed"
    );
}

#[test]
fn both_styles_are_equivalent_on_merging_stages() {
    let c = rtl_gen::merge::MergeConfig::default();
    check_equivalent(&rtl_gen::merge::merge_level_unit(&c.params));
    // Its merge network takes Yosys ~40 s: the top alone here, every module
    // of the default designs once by hand (SPEC 11).
    check_equivalent_top(&rtl_gen::merge::merge_module_unit(&c));
}
