//! Choosing an engine by name (for the CLI's `--engine` and for tests).

use crate::design::Design;
use crate::engine::Engine;
use crate::error::{CosimError, Result};
use crate::icarus::IcarusEngine;
use crate::tools::{tool_available, INSTALL_HINT};
use crate::verilator::{VerilatorEngine, VerilatorOptions};
use std::str::FromStr;

/// The external-simulator engines this crate provides.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum EngineKind {
    /// Verilator, 2-state, compiled.
    Verilator,
    /// Icarus Verilog, 4-state, interpreted.
    Icarus,
}

impl EngineKind {
    /// Every kind, in the order tests run them.
    pub const ALL: [EngineKind; 2] = [EngineKind::Verilator, EngineKind::Icarus];

    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            EngineKind::Verilator => "verilator",
            EngineKind::Icarus => "iverilog",
        }
    }

    /// The programs this engine runs.
    pub fn tools(self) -> &'static [&'static str] {
        match self {
            EngineKind::Verilator => &["verilator", "g++"],
            EngineKind::Icarus => &["iverilog", "vvp"],
        }
    }

    /// `Ok` when every tool can be started, else `ToolMissing` with the install hint.
    pub fn check_tools(self) -> Result<()> {
        match self.tools().iter().find(|t| !tool_available(t)) {
            None => Ok(()),
            Some(t) => Err(CosimError::ToolMissing {
                tool: t.to_string(),
                hint: format!("needed by the {} engine; {INSTALL_HINT}", self.name()),
            }),
        }
    }
}

impl FromStr for EngineKind {
    type Err = CosimError;

    fn from_str(s: &str) -> Result<EngineKind> {
        match s {
            "verilator" => Ok(EngineKind::Verilator),
            "iverilog" | "icarus" => Ok(EngineKind::Icarus),
            other => Err(CosimError::Unsupported {
                what: format!("engine `{other}`, expected verilator or iverilog"),
            }),
        }
    }
}

/// A fresh engine of `kind` for `design`; `trace` asks for a VCD-capable
/// build (Verilator `--trace`; Icarus can always trace).
pub fn open_engine(kind: EngineKind, design: &Design, trace: bool) -> Result<Box<dyn Engine>> {
    match kind {
        EngineKind::Verilator => {
            let options = VerilatorOptions {
                trace,
                ..VerilatorOptions::default()
            };
            Ok(Box::new(VerilatorEngine::new(design, &options)?))
        }
        EngineKind::Icarus => Ok(Box::new(IcarusEngine::new(design)?)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for k in EngineKind::ALL {
            assert_eq!(k.name().parse::<EngineKind>().unwrap(), k);
        }
        assert!("ir".parse::<EngineKind>().is_err());
    }
}
