//! Icarus is 4-state: an output that is X or Z after reset is an error naming
//! the port and the cycle; before reset X is tolerated.
mod common;

use cosim::icarus::IcarusEngine;
use cosim::{CosimError, Engine};

#[test]
fn an_uninitialized_output_is_reported_after_reset_by_port_and_cycle() {
    if !common::tools_present(&["iverilog", "vvp"]) {
        return;
    }
    let design = common::uninit();
    let mut e = IcarusEngine::new(&design).unwrap();
    let q = e.port_id("q").unwrap();
    let forgotten = e.port_id("forgotten").unwrap();
    // Before reset everything is X and that is not an error.
    e.eval().unwrap();
    assert!(e.peek_raw(q).unwrap().contains('x'));
    e.step().unwrap();
    match e.reset(2) {
        Err(CosimError::UnknownOutput { port, cycle, value }) => {
            assert_eq!(port, "forgotten");
            assert_eq!(cycle, 3, "1 free step + 2 reset edges");
            assert_eq!(value, "x");
        }
        other => panic!("expected UnknownOutput, got {other:?}"),
    }
    // The reset output itself is clean: only `forgotten` is unknown.
    assert_eq!(e.peek_raw(q).unwrap(), "0");
    assert_eq!(e.peek_raw(forgotten).unwrap(), "x");
    // Every later cycle keeps failing, with the right cycle number (a step's
    // outputs are read back lazily: by the next eval or peek).
    e.step().unwrap();
    match e.eval() {
        Err(CosimError::UnknownOutput { port, cycle, .. }) => {
            assert_eq!((port.as_str(), cycle), ("forgotten", 4))
        }
        other => panic!("expected UnknownOutput, got {other:?}"),
    }
    e.step().unwrap();
    assert!(matches!(
        e.peek(q),
        Err(CosimError::UnknownOutput { cycle: 5, .. })
    ));
}

#[test]
fn a_clean_design_passes_the_x_check() {
    if !common::tools_present(&["iverilog", "vvp"]) {
        return;
    }
    let mut e = IcarusEngine::new(&common::skid()).unwrap();
    e.reset(2).unwrap();
    for _ in 0..10 {
        e.step().unwrap();
    }
}
