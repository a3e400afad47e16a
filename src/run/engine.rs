//! The simulator every unit of a run is driven on (`hiermerge run
//! --engine`): one choice for the translation unit, the merging module and
//! the hierarchy merger top alike, so a run's figures come from one engine.

use cosim::from_rtl::design_from_module;
use cosim::ir_engine::IrEngine;
use cosim::units::merger::MergerEngine;
use cosim::{open_engine, Engine, EngineKind};
use serde::Serialize;

/// Which simulator runs the units.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RunEngine {
    /// Verilator (cosim's content-addressed cache serves later runs).
    #[default]
    Verilator,
    /// rtl-gen's IR simulator: nothing to build, slower per cycle.
    Ir,
}

impl RunEngine {
    /// The name `--engine` takes.
    pub fn name(self) -> &'static str {
        match self {
            RunEngine::Verilator => "verilator",
            RunEngine::Ir => "ir",
        }
    }

    /// The engine `--engine NAME` names.
    pub fn parse(name: &str) -> Result<RunEngine, String> {
        match name {
            "verilator" => Ok(RunEngine::Verilator),
            "ir" => Ok(RunEngine::Ir),
            _ => Err(format!(
                "--engine {name}: expected verilator or ir (the engines a run steps from Rust)"
            )),
        }
    }

    /// What the report says of a build, `Verilator` or `IR`.
    pub fn label(self) -> &'static str {
        match self {
            RunEngine::Verilator => "Verilator",
            RunEngine::Ir => "IR",
        }
    }

    /// The merger bench's engine.
    pub fn merger(self) -> MergerEngine {
        match self {
            RunEngine::Verilator => MergerEngine::Verilator,
            RunEngine::Ir => MergerEngine::Ir,
        }
    }

    /// `m` on this engine, its Verilog written to a temporary folder
    /// (Verilator loads its model from the cache, the IR engine reads the
    /// module); `what` names the unit in errors.
    pub fn open(self, m: &rtl_gen::Module, what: &str) -> Result<Box<dyn Engine>, String> {
        if self == RunEngine::Verilator {
            EngineKind::Verilator
                .check_tools()
                .map_err(|e| format!("{what}: {e}"))?;
        }
        let dir = tempfile::tempdir().map_err(|e| format!("temporary folder: {e}"))?;
        let d = design_from_module(m, dir.path()).map_err(|e| format!("{what}: {e}"))?;
        match self {
            RunEngine::Verilator => open_engine(EngineKind::Verilator, &d, false)
                .map_err(|e| format!("{what} (Verilator): {e}")),
            RunEngine::Ir => Ok(Box::new(
                IrEngine::new(m, &d).map_err(|e| format!("{what} (IR): {e}"))?,
            )),
        }
    }
}
