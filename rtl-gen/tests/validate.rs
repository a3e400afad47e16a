//! The validator and construction checks: each kind of error, reported with
//! the signal and the generator line that caused it.

use rtl_gen::{emit_verilog, DiagKind, Diagnostics, Module, Severity, Sim};

/// The single error of `kind` (there must be exactly one error in all).
fn only_error(m: &Module, kind: DiagKind) -> rtl_gen::Diagnostic {
    let errs: Diagnostics = m.validate().expect_err("design should be invalid");
    let errors: Vec<_> = errs.errors().cloned().collect();
    assert_eq!(errors.len(), 1, "expected one error, got:\n{errs}");
    assert_eq!(errors[0].kind, kind, "{errs}");
    // Invalid designs are neither emitted nor simulated.
    assert!(emit_verilog(m).is_err());
    assert!(Sim::new(m).is_err());
    errors[0].clone()
}

fn at_line(d: &rtl_gen::Diagnostic, line: u32) {
    assert_eq!(d.location.line(), line, "{d}");
    assert!(d.location.file().ends_with("tests/validate.rs"), "{d}");
}

#[test]
fn bitwise_width_mismatch_names_the_line() {
    let m = Module::new("m");
    let a = m.input("a", 8);
    let b = m.input("b", 7);
    let line = line!() + 1;
    let y = a & b;
    m.output("y", y);
    let d = only_error(&m, DiagKind::Width);
    at_line(&d, line);
    assert_eq!(d.signal.as_deref(), Some("a"));
    assert!(d.message.contains("8 and 7 bits"), "{d}");
}

#[test]
fn add_result_narrower_than_operands_is_an_error() {
    let m = Module::new("m");
    let a = m.input("a", 8);
    let line = line!() + 1;
    let y = a.add(1, 7);
    m.output("y", y);
    at_line(&only_error(&m, DiagKind::Width), line);
}

#[test]
fn constant_that_does_not_fit_is_an_error() {
    let m = Module::new("m");
    let a = m.input("a", 4);
    let line = line!() + 1;
    m.output("y", a ^ 16);
    let d = only_error(&m, DiagKind::Width);
    at_line(&d, line);
    assert!(d.message.contains("16 does not fit in 4 bits"), "{d}");
}

#[test]
fn negative_constant_next_to_unsigned_is_an_error() {
    let m = Module::new("m");
    let a = m.input("a", 4);
    m.output("y", a.add(-1, 4));
    only_error(&m, DiagKind::Width);
}

#[test]
fn mux_arms_and_select_widths() {
    let m = Module::new("m");
    let (s, a, b) = (m.input("s", 2), m.input("a", 4), m.input("b", 4));
    m.output("y", s.mux(a, b));
    assert!(only_error(&m, DiagKind::Width)
        .message
        .contains("select must be 1 bit"));
    let m = Module::new("m");
    let (s, a, b) = (m.input("s", 1), m.input("a", 4), m.input("b", 5));
    m.output("y", s.mux(a, b));
    assert!(only_error(&m, DiagKind::Width)
        .message
        .contains("arms differ"));
}

#[test]
fn driving_an_input_is_misuse() {
    let m = Module::new("m");
    let a = m.input("a", 4);
    let line = line!() + 1;
    a.drive(3);
    m.output("y", a);
    let d = only_error(&m, DiagKind::Misuse);
    at_line(&d, line);
    assert!(d.message.contains("input"), "{d}");
}

#[test]
fn driving_an_operator_result_and_next_on_a_wire_are_misuse() {
    let m = Module::new("m");
    let a = m.input("a", 4);
    let n = !a;
    n.drive(a);
    m.output("y", n);
    only_error(&m, DiagKind::Misuse);
    let m = Module::new("m");
    let w = m.wire("w", 4);
    w.next(m.input("a", 4));
    w.drive(0);
    m.output("y", w);
    only_error(&m, DiagKind::Misuse);
}

#[test]
fn drive_width_mismatch() {
    let m = Module::new("m");
    let w = m.wire("w", 4);
    w.drive(m.input("a", 5).slice(4, 1).zext(5));
    m.output("y", w);
    only_error(&m, DiagKind::Width);
}

#[test]
fn slice_out_of_range_is_misuse_at_the_line() {
    let m = Module::new("m");
    let a = m.input("a", 8);
    let line = line!() + 1;
    let s = a.slice(8, 1);
    m.output("y", s);
    let d = only_error(&m, DiagKind::Misuse);
    at_line(&d, line);
    assert!(
        d.message.contains("[8:1]") && d.message.contains("8-bit"),
        "{d}"
    );
}

#[test]
fn mixing_signals_of_two_modules_is_misuse() {
    let m1 = Module::new("m1");
    let m2 = Module::new("m2");
    let a = m1.input("a", 4);
    let b = m2.input("b", 4);
    m2.output("y", b ^ a);
    let d = only_error(&m2, DiagKind::Misuse);
    assert!(d.message.contains("m1"), "{d}");
}

#[test]
fn signed_shift_amount_is_misuse() {
    let m = Module::new("m");
    let a = m.input("a", 8);
    let s = m.input("s", 3).as_signed();
    m.output("y", a << s);
    only_error(&m, DiagKind::Misuse);
}

#[test]
fn bad_names_are_errors() {
    for bad in ["reg", "2x", "a-b", "clk", "logic"] {
        let m = Module::new("m");
        let a = m.input(bad, 1);
        m.output("y", a);
        only_error(&m, DiagKind::Name);
    }
    let m = Module::new("m");
    let a = m.input("a", 1);
    m.output("a", a);
    assert!(only_error(&m, DiagKind::Name)
        .message
        .contains("already exists"));
    let m = Module::new("module");
    m.output("y", m.input("a", 1));
    only_error(&m, DiagKind::Name);
}

#[test]
fn undriven_wire_output_and_register() {
    let m = Module::new("m");
    let line = line!() + 1;
    let w = m.wire("floating", 3);
    m.output("y", w);
    let d = only_error(&m, DiagKind::Undriven);
    at_line(&d, line);
    assert_eq!(d.signal.as_deref(), Some("floating"));

    let m = Module::new("m");
    m.output_wire("ready", 1);
    only_error(&m, DiagKind::Undriven);

    let m = Module::new("m");
    let r = m.reg("state", 2);
    m.output("y", r);
    assert!(only_error(&m, DiagKind::Undriven)
        .message
        .contains("register"));
}

#[test]
fn unconnected_instance_input_and_unwritten_memory() {
    let child = Module::new("child");
    let a = child.input("a", 2);
    child.output("y", a);
    let top = Module::new("top");
    let u = top.instance("u", &child);
    top.output("y", u.output("y"));
    assert!(only_error(&top, DiagKind::Undriven)
        .message
        .contains("input `a` of instance `u`"));

    let m = Module::new("rom");
    let mem = m.memory("mem", 8, 4);
    m.output("y", mem.read(m.input("a", 2)));
    only_error(&m, DiagKind::Undriven);
}

#[test]
fn instance_port_misuse() {
    let child = Module::new("child");
    let a = child.input("a", 2);
    child.output("y", a);
    let top = Module::new("top");
    let u = top.instance("u", &child);
    u.connect("a", top.input("x", 3));
    top.output("y", u.output("y"));
    only_error(&top, DiagKind::Width);

    let top = Module::new("top");
    let u = top.instance("u", &child);
    u.connect("a", top.input("x", 2));
    u.connect("nope", top.input("z", 2));
    top.output("y", u.output("y"));
    assert!(top.validate().unwrap_err().has(DiagKind::Misuse));

    let selfish = Module::new("selfish");
    selfish.instance("u", &selfish);
    assert!(selfish.validate().unwrap_err().has(DiagKind::Misuse));
}

#[test]
fn memory_shape_errors() {
    let m = Module::new("m");
    let mem = m.memory("mem", 8, 5);
    mem.write(m.input("wa", 3), m.input("wd", 8), m.input("we", 1));
    m.output("q", mem.read(m.input("ra", 3)));
    assert!(m
        .validate()
        .unwrap_err()
        .to_string()
        .contains("power of two"));

    let m = Module::new("m");
    let mem = m.memory("mem", 8, 8);
    mem.write(m.input("wa", 4), m.input("wd", 8), m.input("we", 1));
    m.output("q", mem.read(m.input("ra", 3)));
    only_error(&m, DiagKind::Width);
}

#[test]
fn multiple_drivers_list_every_driver() {
    let m = Module::new("m");
    let (a, b) = (m.input("a", 4), m.input("b", 4));
    let w = m.wire("w", 4);
    let l1 = line!() + 1;
    w.drive(a);
    let l2 = line!() + 1;
    w.drive(b);
    m.output("y", w);
    let d = only_error(&m, DiagKind::MultipleDrivers);
    let lines: Vec<u32> = d.related.iter().map(|r| r.1.line()).collect();
    assert_eq!(lines, vec![l1, l2]);

    let m = Module::new("m");
    let r = m.reg("r", 1);
    r.next(m.input("a", 1));
    r.next(m.input("b", 1));
    m.output("y", r);
    only_error(&m, DiagKind::MultipleDrivers);
}

#[test]
fn combinational_loop_reports_its_signals() {
    let m = Module::new("m");
    let a = m.input("a", 4);
    let p = m.wire("p", 4);
    let q = m.wire("q", 4);
    p.drive(q ^ a);
    q.drive(!p);
    m.output("y", q);
    let d = only_error(&m, DiagKind::CombLoop);
    assert!(
        d.message.contains("`p`") || d.message.contains("p ->") || d.message.contains(" p"),
        "{d}"
    );
    assert!(d.message.contains('q'), "{d}");
    // A register breaks the loop.
    let m = Module::new("m");
    let a = m.input("a", 4);
    let r = m.reg("r", 4);
    r.next(r ^ a);
    m.output("y", r);
    assert!(m.validate().is_ok());
}

#[test]
fn combinational_loop_through_an_instance() {
    let pass = Module::new("pass");
    let i = pass.input("i", 1);
    pass.output("o", !i);
    let top = Module::new("top");
    let u = top.instance("u", &pass);
    let w = top.wire("w", 1);
    u.connect("i", w);
    w.drive(u.output("o"));
    top.output("y", w);
    only_error(&top, DiagKind::CombLoop);

    // The same path through a child register is no loop.
    let regd = Module::new("regd");
    let i = regd.input("i", 1);
    let r = regd.reg("r", 1);
    r.next(i);
    regd.output("o", r);
    let top = Module::new("top2");
    let u = top.instance("u", &regd);
    let w = top.wire("w", 1);
    u.connect("i", w);
    w.drive(!u.output("o"));
    top.output("y", w);
    assert!(top.validate().is_ok(), "{:?}", top.validate());
}

#[test]
fn unused_logic_is_a_warning_with_bit_ranges() {
    let m = Module::new("m");
    let a = m.input("a", 8);
    let b = m.input("b", 8);
    let line = line!() + 1;
    let _dead = a.add(b, 9);
    m.output("y", a.slice(3, 0) ^ b.slice(3, 0));
    let warnings = m.validate().expect("warnings only");
    assert!(warnings
        .iter()
        .all(|w| w.severity == Severity::Warning && w.kind == DiagKind::Unused));
    let dead = warnings
        .iter()
        .find(|w| w.location.line() == line)
        .expect("dead add reported");
    assert!(dead.message.contains("nothing reads"), "{dead}");
    // `a` and `b` are fully read by the dead adder, so only it is reported.
    assert_eq!(warnings.len(), 1, "{warnings:?}");

    let m = Module::new("m");
    let a = m.input("a", 8);
    m.output("y", a.slice(3, 0));
    let w = m.validate().unwrap();
    assert_eq!(w.len(), 1);
    assert_eq!(w[0].signal.as_deref(), Some("a"));
    assert!(w[0].message.contains("[7:4]"), "{}", w[0]);
    // Warnings do not stop emission.
    assert!(emit_verilog(&m).is_ok());
}

#[test]
fn every_construction_error_is_reported_at_once() {
    let m = Module::new("m");
    let a = m.input("a", 8);
    let _ = a.slice(9, 0);
    let _ = a & m.input("b", 2);
    let _ = a.add(a, 3);
    let errs = m.validate().unwrap_err();
    assert_eq!(errs.errors().count(), 3, "{errs}");
}

#[test]
fn absurd_widths_are_errors_not_allocations() {
    let m = Module::new("m");
    let a = m.input("a", u32::MAX);
    m.output("y", a);
    assert!(m.validate().unwrap_err().has(DiagKind::Width));
}

#[test]
fn changing_a_child_after_instantiation_is_an_error() {
    let child = Module::new("child");
    let a = child.input("a", 1);
    let top = Module::new("top");
    let u = top.instance("u", &child);
    u.connect("a", top.input("x", 1));
    child.output("late", a);
    top.output("y", top.input("z", 1));
    assert!(top
        .validate()
        .unwrap_err()
        .to_string()
        .contains("after it was instantiated"));
}
