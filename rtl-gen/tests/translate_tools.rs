//! Every reference configuration of the translation unit: no validator
//! warning, `verilator --lint-only -Wall` clean, and Yosys `synth; check
//! -assert` with no latch. A missing tool fails under CI=true and is a
//! printed skip otherwise (tests/common). One test per configuration, so
//! they run in parallel.

mod common;

use common::check_tools;
use rtl_gen::translate::{reference_designs, translate_unit};

fn lint_and_synthesize(n: usize) {
    let d = reference_designs()[n];
    check_tools(&translate_unit(&d), true);
}

#[test]
fn default_configuration_lints_and_synthesizes() {
    lint_and_synthesize(0);
}

#[test]
fn d31_binary64_lints_and_synthesizes() {
    lint_and_synthesize(1);
}

#[test]
fn q0_odd_depth_lints_and_synthesizes() {
    lint_and_synthesize(2);
}

#[test]
fn binary64_default_grid_lints_and_synthesizes() {
    lint_and_synthesize(3);
}

#[test]
fn smallest_grid_lints_and_synthesizes() {
    lint_and_synthesize(4);
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
    assert!(
        !narrow.contains(" format"),
        "binary32-only design has a format field"
    );
    assert!(wide.contains("x_wide"));
    assert!(narrow.len() < wide.len());
    let ports = |m: &rtl_gen::Module, name: &str| {
        m.ports()
            .into_iter()
            .find(|p| p.name == name)
            .map(|p| p.width)
    };
    d.binary64 = false;
    let m32 = translate_unit(&d);
    d.binary64 = true;
    let m64 = translate_unit(&d);
    // Three placements of 32 vs 64 bits plus the format bit.
    assert_eq!(
        ports(&m64, "det_in_data").unwrap() - ports(&m32, "det_in_data").unwrap(),
        3 * 32 + 1
    );
}
