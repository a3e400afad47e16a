//! An `rtl_gen::Module` as a [`Design`]: its Verilog written into a
//! directory with `rtl_gen::write_design`, its ports from
//! `Module::ports()`, `clk`/`rst` (rtl-gen's implicit clock and synchronous
//! active-high reset) as clock and reset when the module has them.

use crate::design::{Design, PortSpec};
use crate::error::{CosimError, Result};
use rtl_gen::{Direction, Module, CLOCK, RESET};
use std::path::Path;

/// Writes `module` (and its children) into `dir` and describes it.
pub fn design_from_module(module: &Module, dir: &Path) -> Result<Design> {
    let files = rtl_gen::write_design(module, dir).map_err(|e| CosimError::Design {
        what: format!("writing the Verilog of {}: {e}", module.name()),
    })?;
    let ports = module.ports();
    let specs = ports
        .iter()
        .map(|p| match p.direction {
            Direction::Input => PortSpec::input(&p.name, p.width),
            Direction::Output => PortSpec::output(&p.name, p.width),
        })
        .collect();
    let has = |name: &str| ports.iter().any(|p| p.name == name);
    Design::new(
        &module.name(),
        files,
        specs,
        has(CLOCK).then_some(CLOCK),
        has(RESET).then_some(RESET),
    )
}
