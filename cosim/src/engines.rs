//! Choosing an engine by name (for the CLI's `--engine` and for tests).

use crate::design::Design;
use crate::engine::Engine;
use crate::error::{CosimError, Result};
use crate::icarus::IcarusEngine;
use crate::tools::{tool_available, INSTALL_HINT};
use crate::verilator::{VerilatorEngine, VerilatorOptions};
use crate::waves::WaveFormat;
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
/// build (Verilator `--trace`; Icarus can always trace). While the process
/// collects code coverage ([`crate::coverage::collect_into`]) a Verilator
/// engine is a coverage build that writes its counts when dropped.
pub fn open_engine(kind: EngineKind, design: &Design, trace: bool) -> Result<Box<dyn Engine>> {
    match kind {
        EngineKind::Verilator => {
            let options = crate::coverage::options(VerilatorOptions {
                trace,
                ..VerilatorOptions::default()
            });
            Ok(Box::new(VerilatorEngine::new(design, &options)?))
        }
        EngineKind::Icarus => Ok(Box::new(IcarusEngine::new(design)?)),
    }
}

/// A fresh engine of `kind` for `design` able to write `format`
/// waveforms, tracing only the instance `scope` of the top when given
/// (Verilator: `--trace` or `--trace-fst` and `dumpvars`; Icarus through its
/// pipe: VCD only, since its FST is complete only when `vvp` ends, and the
/// scope left to [`crate::tb::TraceWindow`]'s filter).
pub fn open_tracing_engine(
    kind: EngineKind,
    design: &Design,
    format: WaveFormat,
    scope: Option<&str>,
) -> Result<Box<dyn Engine>> {
    match kind {
        EngineKind::Verilator => {
            let options = crate::coverage::options(VerilatorOptions {
                trace: true,
                fst: format == WaveFormat::Fst,
                ..VerilatorOptions::default()
            });
            let mut e = VerilatorEngine::new(design, &options)?;
            if let Some(s) = scope {
                e.set_trace_scope(s)?;
            }
            Ok(Box::new(e))
        }
        EngineKind::Icarus if format == WaveFormat::Fst => Err(CosimError::Unsupported {
            what:
                "FST from Icarus comes from its batch runs (--unit merge-module, --unit merger): \
                   the pipe engine's vvp runs on after the window, and its FST is complete \
                   only when vvp ends; use VCD, or Verilator"
                    .into(),
        }),
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
