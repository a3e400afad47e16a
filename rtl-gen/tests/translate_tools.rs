//! Every reference configuration of the translation unit: no validator
//! warning, `verilator --lint-only -Wall` clean, and Yosys `synth; check
//! -assert` with no latch. A missing tool fails under CI=true and is a
//! printed skip otherwise (tests/common).

mod common;

use common::check_tools;
use rtl_gen::translate::{reference_designs, translate_unit};

#[test]
fn translate_units_lint_and_synthesize() {
    for d in reference_designs() {
        check_tools(&translate_unit(&d), true);
    }
}

#[test]
fn binary32_only_has_no_binary64_logic() {
    let mut d = reference_designs()[0];
    d.binary64 = false;
    let narrow = rtl_gen::emit_verilog(&translate_unit(&d)).unwrap();
    d.binary64 = true;
    let wide = rtl_gen::emit_verilog(&translate_unit(&d)).unwrap();
    assert!(
        !narrow.contains("x_wide"),
        "binary32-only design has a width check"
    );
    assert!(wide.contains("x_wide"));
    assert!(narrow.len() < wide.len());
}
