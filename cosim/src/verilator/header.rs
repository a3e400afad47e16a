//! Reading the port list Verilator actually generated, from `Vhm.h`.
//!
//! Verilator declares each top port as `VL_IN8(&name,msb,lsb);`,
//! `VL_OUTW(&name,msb,lsb,words);` and so on. Comparing that with the
//! `Design` catches a port description that disagrees with the Verilog
//! before any value is silently truncated.

use crate::design::{Design, PortDir};
use crate::error::{CosimError, Result};

/// A port as declared in the Verilated model header.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HeaderPort {
    /// Port name.
    pub name: String,
    /// Width, msb - lsb + 1.
    pub width: u32,
    /// Direction (inout is reported as an error by `check_ports`).
    pub dir: Option<PortDir>,
}

/// Every `VL_IN*`/`VL_OUT*`/`VL_INOUT*` declaration in `header`.
pub fn parse_header_ports(header: &str) -> Vec<HeaderPort> {
    header.lines().filter_map(parse_port_line).collect()
}

fn parse_port_line(line: &str) -> Option<HeaderPort> {
    let line = line.trim();
    let rest = line.strip_prefix("VL_")?;
    let (dir, rest) = if let Some(r) = rest.strip_prefix("INOUT") {
        (None, r)
    } else if let Some(r) = rest.strip_prefix("IN") {
        (Some(PortDir::Input), r)
    } else if let Some(r) = rest.strip_prefix("OUT") {
        (Some(PortDir::Output), r)
    } else {
        return None;
    };
    let open = rest.find("(&")?;
    let size_class = &rest[..open];
    if !matches!(size_class, "" | "8" | "16" | "64" | "W") {
        return None;
    }
    let args = rest[open + 2..].split(')').next()?;
    let mut parts = args.split(',').map(str::trim);
    let name = parts.next()?.to_string();
    let msb: u32 = parts.next()?.parse().ok()?;
    let lsb: u32 = parts.next()?.parse().ok()?;
    Some(HeaderPort {
        name,
        width: msb.checked_sub(lsb)? + 1,
        dir,
    })
}

/// Check that the model's ports are exactly the design's ports.
pub fn check_ports(design: &Design, header_ports: &[HeaderPort]) -> Result<()> {
    for p in &design.ports {
        let Some(h) = header_ports.iter().find(|h| h.name == p.name) else {
            return Err(CosimError::PortMismatch {
                port: p.name.clone(),
                what: format!("not a port of the Verilated top `{}`", design.top),
            });
        };
        if h.width != p.width {
            return Err(CosimError::PortMismatch {
                port: p.name.clone(),
                what: format!("described as {} bits, the Verilog has {}", p.width, h.width),
            });
        }
        if h.dir != Some(p.dir) {
            return Err(CosimError::PortMismatch {
                port: p.name.clone(),
                what: format!("described as {:?}, the Verilog has {:?}", p.dir, h.dir),
            });
        }
    }
    if let Some(extra) = header_ports
        .iter()
        .find(|h| !design.ports.iter().any(|p| p.name == h.name))
    {
        return Err(CosimError::PortMismatch {
            port: extra.name.clone(),
            what: "in the Verilog but missing from the port description".to_string(),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_each_size_class() {
        let h = "    VL_IN8(&clk,0,0);\n    VL_OUTW(&sum,299,0,10);\n  VL_OUT64(&q,40,0);\n int x;";
        let ports = parse_header_ports(h);
        assert_eq!(ports.len(), 3);
        assert_eq!(ports[1].name, "sum");
        assert_eq!(ports[1].width, 300);
        assert_eq!(ports[2].dir, Some(PortDir::Output));
        assert_eq!(ports[2].width, 41);
    }
}
