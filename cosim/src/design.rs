//! What a design is to the harness: Verilog files, a top module and its ports.
//!
//! The port list is the contract every engine builds against; it is checked
//! against the compiled model (Verilator's header, Icarus's port binding) so a
//! mismatch is reported by port name instead of silently truncating.

use crate::error::{io_err, CosimError, Result};
use std::collections::HashSet;
use std::path::PathBuf;

/// Direction of a top-level port.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PortDir {
    /// Driven by the testbench.
    Input,
    /// Driven by the design.
    Output,
}

/// One top-level port: a plain Verilog identifier, a width of at least one bit.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct PortSpec {
    /// The identifier in the top module.
    pub name: String,
    /// Width in bits, >= 1.
    pub width: u32,
    /// Input or output.
    pub dir: PortDir,
}

impl PortSpec {
    /// An input port.
    pub fn input(name: &str, width: u32) -> PortSpec {
        PortSpec {
            name: name.to_string(),
            width,
            dir: PortDir::Input,
        }
    }

    /// An output port.
    pub fn output(name: &str, width: u32) -> PortSpec {
        PortSpec {
            name: name.to_string(),
            width,
            dir: PortDir::Output,
        }
    }
}

/// Index of a port in `Design::ports`; obtained from `Design::port_id`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PortId(pub usize);

/// The reset input and its polarity. Reset is synchronous: it is held for a
/// number of rising clock edges by `Engine::reset`.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Reset {
    /// Name of the 1-bit input port.
    pub port: String,
    /// True when the design resets while the port is 0.
    pub active_low: bool,
}

/// A design to simulate.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Design {
    /// Top module name.
    pub top: String,
    /// Verilog-2005 sources, in the order given to the tools.
    pub verilog_files: Vec<PathBuf>,
    /// Every top-level port, clock and reset included.
    pub ports: Vec<PortSpec>,
    /// The 1-bit clock input, if the design is sequential.
    pub clock: Option<String>,
    /// The synchronous reset input, if any.
    pub reset: Option<Reset>,
}

fn is_plain_identifier(name: &str) -> bool {
    let mut chars = name.chars();
    matches!(chars.next(), Some(c) if c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// Ports wider than this are refused: the Icarus pipe carries them as one hex
/// token and nothing in hiermerge comes close.
pub const MAX_PORT_WIDTH: u32 = 65536;

impl Design {
    /// A design with an active-high reset named `reset` (pass `None` for none).
    pub fn new(
        top: &str,
        verilog_files: Vec<PathBuf>,
        ports: Vec<PortSpec>,
        clock: Option<&str>,
        reset: Option<&str>,
    ) -> Result<Design> {
        let d = Design {
            top: top.to_string(),
            verilog_files,
            ports,
            clock: clock.map(str::to_string),
            reset: reset.map(|r| Reset {
                port: r.to_string(),
                active_low: false,
            }),
        };
        d.validate()?;
        Ok(d)
    }

    /// Check names, widths, uniqueness, and that clock and reset are 1-bit inputs.
    pub fn validate(&self) -> Result<()> {
        let bad = |what: String| Err(CosimError::Design { what });
        if !is_plain_identifier(&self.top) {
            return bad(format!(
                "top `{}` is not a plain Verilog identifier",
                self.top
            ));
        }
        if self.verilog_files.is_empty() {
            return bad(format!("top `{}`: no Verilog files", self.top));
        }
        let mut seen = HashSet::new();
        for (i, p) in self.ports.iter().enumerate() {
            if !is_plain_identifier(&p.name) {
                return bad(format!("port {i} `{}` is not a plain identifier", p.name));
            }
            if p.width == 0 || p.width > MAX_PORT_WIDTH {
                return bad(format!(
                    "port `{}` has width {}, expected 1..={MAX_PORT_WIDTH}",
                    p.name, p.width
                ));
            }
            if !seen.insert(p.name.as_str()) {
                return bad(format!("port `{}` is listed twice", p.name));
            }
        }
        let special = [
            ("clock", self.clock.as_deref()),
            ("reset", self.reset.as_ref().map(|r| r.port.as_str())),
        ];
        for (role, name) in special {
            if let Some(name) = name {
                match self.ports.iter().find(|p| p.name == name) {
                    Some(p) if p.dir == PortDir::Input && p.width == 1 => {}
                    Some(p) => {
                        return bad(format!(
                            "{role} `{name}` must be a 1-bit input, is {:?} of width {}",
                            p.dir, p.width
                        ))
                    }
                    None => return bad(format!("{role} `{name}` is not in the port list")),
                }
            }
        }
        Ok(())
    }

    /// The id of the port called `name`.
    pub fn port_id(&self, name: &str) -> Result<PortId> {
        self.ports
            .iter()
            .position(|p| p.name == name)
            .map(PortId)
            .ok_or_else(|| CosimError::UnknownPort {
                name: name.to_string(),
            })
    }

    /// The port with id `id`.
    pub fn port(&self, id: PortId) -> Result<&PortSpec> {
        self.ports.get(id.0).ok_or(CosimError::BadPortId {
            index: id.0,
            count: self.ports.len(),
        })
    }

    /// Ids of every output port, in port-list order.
    pub fn output_ids(&self) -> Vec<PortId> {
        self.ports
            .iter()
            .enumerate()
            .filter(|(_, p)| p.dir == PortDir::Output)
            .map(|(i, _)| PortId(i))
            .collect()
    }

    /// The Verilog sources, read in order as (path, contents) pairs.
    pub fn read_sources(&self) -> Result<Vec<(PathBuf, Vec<u8>)>> {
        self.verilog_files
            .iter()
            .map(|p| std::fs::read(p).map(|b| (p.clone(), b)).map_err(io_err(p)))
            .collect()
    }

    /// Check that `value` may be poked into `id`: an input of the same width.
    pub fn check_poke(&self, id: PortId, value: &crate::Bits) -> Result<&PortSpec> {
        let p = self.port(id)?;
        if p.dir != PortDir::Input {
            return Err(CosimError::NotAnInput {
                port: p.name.clone(),
            });
        }
        if value.width() != p.width {
            return Err(CosimError::Width {
                port: p.name.clone(),
                width: p.width,
                value_bits: value.width(),
            });
        }
        Ok(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ports() -> Vec<PortSpec> {
        vec![
            PortSpec::input("clk", 1),
            PortSpec::input("rst", 1),
            PortSpec::output("q", 8),
        ]
    }

    #[test]
    fn bad_descriptions_are_refused_with_the_reason() {
        let f = || vec![PathBuf::from("x.v")];
        assert!(Design::new("t", f(), ports(), Some("clk"), Some("rst")).is_ok());
        let err = |d: Result<Design>| d.unwrap_err().to_string();
        assert!(err(Design::new("t", f(), ports(), Some("q"), None)).contains("clock `q`"));
        assert!(err(Design::new("t", f(), ports(), Some("nope"), None))
            .contains("not in the port list"));
        let mut dup = ports();
        dup.push(PortSpec::output("q", 8));
        assert!(err(Design::new("t", f(), dup, None, None)).contains("listed twice"));
        let mut bad = ports();
        bad.push(PortSpec::input("a b", 1));
        assert!(err(Design::new("t", f(), bad, None, None)).contains("plain identifier"));
        let mut zero = ports();
        zero.push(PortSpec::input("z", 0));
        assert!(err(Design::new("t", f(), zero, None, None)).contains("width 0"));
        assert!(Design::new("t", vec![], ports(), None, None).is_err());
        assert!(Design::new("1t", f(), ports(), None, None).is_err());
    }

    #[test]
    fn pokes_are_checked_for_direction_and_width() {
        let d = Design::new("t", vec![PathBuf::from("x.v")], ports(), None, None).unwrap();
        let q = d.port_id("q").unwrap();
        let clk = d.port_id("clk").unwrap();
        assert!(d.check_poke(q, &crate::Bits::zero(8)).is_err());
        assert!(d.check_poke(clk, &crate::Bits::zero(2)).is_err());
        assert!(d.check_poke(clk, &crate::Bits::zero(1)).is_ok());
        assert!(d.port(PortId(9)).is_err());
    }
}
