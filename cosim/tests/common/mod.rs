//! Fixture designs and tool checks shared by the integration tests.
#![allow(dead_code)]

use cosim::tools::{ci_mode, tool_available, INSTALL_HINT};
use cosim::{Design, PortSpec};
use std::path::PathBuf;

pub fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests")
        .join("fixtures")
        .join(name)
}

/// True when the simulators can run. Under CI=true a missing tool panics
/// (a failure, never a skip); locally the test prints how to install and passes.
pub fn tools_present(tools: &[&str]) -> bool {
    let missing: Vec<&str> = tools
        .iter()
        .copied()
        .filter(|t| !tool_available(t))
        .collect();
    if missing.is_empty() {
        return true;
    }
    if ci_mode() {
        panic!("CI=true and {missing:?} missing: {INSTALL_HINT}");
    }
    eprintln!("SKIPPING: {missing:?} not installed; {INSTALL_HINT}");
    false
}

pub fn counter() -> Design {
    Design::new(
        "counter",
        vec![fixture("counter.v")],
        vec![
            PortSpec::input("clk", 1),
            PortSpec::input("rst", 1),
            PortSpec::input("en", 1),
            PortSpec::output("count", 8),
        ],
        Some("clk"),
        Some("rst"),
    )
    .unwrap()
}

pub const SKID_WIDTH: u32 = 16;

pub fn skid_from(file: &str) -> Design {
    Design::new(
        "skid",
        vec![fixture(file)],
        vec![
            PortSpec::input("clk", 1),
            PortSpec::input("rst", 1),
            PortSpec::input("in_valid", 1),
            PortSpec::output("in_ready", 1),
            PortSpec::input("in_data", SKID_WIDTH),
            PortSpec::output("out_valid", 1),
            PortSpec::input("out_ready", 1),
            PortSpec::output("out_data", SKID_WIDTH),
        ],
        Some("clk"),
        Some("rst"),
    )
    .unwrap()
}

pub fn skid() -> Design {
    skid_from("skid.v")
}

pub const WIDE: u32 = 300;

pub fn wide() -> Design {
    Design::new(
        "wide",
        vec![fixture("wide.v")],
        vec![
            PortSpec::input("a", WIDE),
            PortSpec::input("b", WIDE),
            PortSpec::output("sum", WIDE),
            PortSpec::output("mix", WIDE),
            PortSpec::output("low65", 65),
        ],
        None,
        None,
    )
    .unwrap()
}

pub fn uninit() -> Design {
    Design::new(
        "uninit",
        vec![fixture("uninit.v")],
        vec![
            PortSpec::input("clk", 1),
            PortSpec::input("rst", 1),
            PortSpec::input("d", 4),
            PortSpec::output("q", 4),
            PortSpec::output("forgotten", 4),
        ],
        Some("clk"),
        Some("rst"),
    )
    .unwrap()
}

use cosim::{open_engine, Engine, EngineKind};

/// The engines every fixture runs on.
pub const ENGINES: [&str; 2] = ["verilator", "iverilog"];

/// A fresh engine of `kind` for `design`; `trace` asks for a VCD-capable build.
pub fn make_engine(kind: &str, design: &Design, trace: bool) -> cosim::Result<Box<dyn Engine>> {
    open_engine(kind.parse::<EngineKind>()?, design, trace)
}

pub fn all_tools_present() -> bool {
    tools_present(&["verilator", "iverilog", "vvp", "g++"])
}
