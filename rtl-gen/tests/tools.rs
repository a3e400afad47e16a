//! Every module the tests emit passes `verilator --lint-only -Wall` with no
//! warning and `yosys synth; check -assert` with no latch. A missing tool is
//! a failure under CI=true and a printed skip otherwise.

mod common;
mod designs;

use common::check_tools;
use rtl_gen::examples;
use rtl_gen::optest::{op_suite, WIDTHS};

#[test]
fn examples_lint_and_synthesize() {
    for m in [
        examples::counter(8),
        examples::fifo(8, 3),
        examples::fifo(33, 1),
        examples::drop_fifo(8, 2),
        examples::drop_fifo(33, 1),
        examples::skid_buffer(16),
        examples::abs_diff_pipeline(8, 100),
        examples::abs_diff_pipeline(70, 1 << 69),
    ] {
        check_tools(&m, true);
    }
}

#[test]
fn test_designs_lint_and_synthesize() {
    for m in [
        designs::kitchen_sink(),
        designs::ram(),
        designs::hierarchy(),
        designs::wide(),
    ] {
        check_tools(&m, true);
    }
}

#[test]
fn operator_suites_lint_at_every_width() {
    for &w in &WIDTHS {
        for signed in [false, true] {
            for registered in [false, true] {
                check_tools(&op_suite(w, signed, registered), false);
            }
        }
    }
}

/// Synthesis of every suite takes several minutes, so by default these
/// widths cover one bit, odd widths and both sides of the 64-bit word
/// boundaries; `RTL_GEN_FULL_SYNTH=1` synthesizes every width and signedness.
#[test]
fn operator_suites_synthesize_without_latches() {
    let full = std::env::var("RTL_GEN_FULL_SYNTH")
        .map(|v| v == "1")
        .unwrap_or(false);
    let cases: Vec<(u32, bool)> = if full {
        WIDTHS
            .iter()
            .flat_map(|&w| [(w, false), (w, true)])
            .collect()
    } else {
        vec![(1, true), (7, false), (33, true), (65, false), (129, true)]
    };
    for (w, signed) in cases {
        check_tools(&op_suite(w, signed, true), true);
    }
}
