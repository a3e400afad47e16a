//! Waveform formats and the scope filter (SPEC 10.4): VCD from every engine,
//! FST from Verilator (`--trace-fst`) and from the Icarus batches (`vvp
//! -fst`). A waveform's format is its file name's: `.fst` is FST, anything
//! else VCD.

use crate::error::{CosimError, Result};
use std::path::Path;

/// A waveform file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WaveFormat {
    /// Value change dump (IEEE 1364), text.
    Vcd,
    /// GTKWave's Fast Signal Trace, compressed blocks.
    Fst,
}

impl WaveFormat {
    /// The format of a waveform file named `path`.
    pub fn of(path: &Path) -> WaveFormat {
        match path.extension().and_then(|e| e.to_str()) {
            Some("fst") => WaveFormat::Fst,
            _ => WaveFormat::Vcd,
        }
    }

    /// The file name extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            WaveFormat::Vcd => "vcd",
            WaveFormat::Fst => "fst",
        }
    }
}

/// Refuses a trace into `path` that an engine writing `writes` (None: not
/// able to trace) cannot produce.
pub fn check_engine_writes(writes: Option<WaveFormat>, path: &Path, engine: &str) -> Result<()> {
    let wanted = WaveFormat::of(path);
    match writes {
        Some(f) if f == wanted => Ok(()),
        Some(f) => Err(CosimError::Unsupported {
            what: format!(
                "{}: {engine} writes {} waveforms, not {}",
                path.display(),
                f.extension().to_uppercase(),
                wanted.extension().to_uppercase()
            ),
        }),
        None => Err(CosimError::Unsupported {
            what: format!(
                "{}: tracing needs a Verilator model built with VerilatorOptions {{ trace: true }}",
                path.display()
            ),
        }),
    }
}

/// Refuses a scope that names no instance of `module` (an FST writer with
/// no signal at all is not a waveform: Verilator's crashes).
pub fn check_scope(module: &rtl_gen::Module, scope: Option<&str>) -> Result<()> {
    match scope {
        Some(s) if !module.has_instance_path(s) => Err(CosimError::Unsupported {
            what: format!(
                "wave scope `{s}`: no such instance path in {} (instance names from its top down, `u_a.u_b`)",
                module.name()
            ),
        }),
        _ => Ok(()),
    }
}

/// The header of an FST file (the first block, `FST_BL_HDR`), as GTKWave's
/// `fstapi.c` writes it: enough to tell a real, closed FST from anything else.
#[derive(Clone, Debug, PartialEq)]
pub struct FstHeader {
    /// First and last time of the dump.
    pub start_time: u64,
    /// See `start_time`.
    pub end_time: u64,
    /// Scopes and variables declared.
    pub scopes: u64,
    /// See `scopes`.
    pub vars: u64,
    /// Value-change blocks written.
    pub value_blocks: u64,
    /// The writer's version string (`Verilator ...`, `Icarus Verilog`).
    pub writer: String,
}

/// Reads the header block of an FST file, refusing anything else.
pub fn read_fst_header(bytes: &[u8]) -> std::result::Result<FstHeader, String> {
    // Block type 0, length 329, then the fields, big-endian, and a native
    // binary64 e to tell the byte order.
    const LEN: usize = 1 + 329;
    if bytes.len() < LEN || bytes[0] != 0 {
        return Err("no FST header block (type 0) at the start".into());
    }
    let u64_at = |at: usize| {
        let mut b = [0u8; 8];
        b.copy_from_slice(&bytes[at..at + 8]);
        u64::from_be_bytes(b)
    };
    if u64_at(1) != 329 {
        return Err(format!("header block length {}, expected 329", u64_at(1)));
    }
    let mut e = [0u8; 8];
    e.copy_from_slice(&bytes[25..33]);
    if f64::from_le_bytes(e) != std::f64::consts::E && f64::from_be_bytes(e) != std::f64::consts::E
    {
        return Err("no endianness test value e in the header".into());
    }
    let text = &bytes[74..74 + 128];
    let end = text.iter().position(|&b| b == 0).unwrap_or(text.len());
    Ok(FstHeader {
        start_time: u64_at(9),
        end_time: u64_at(17),
        scopes: u64_at(41),
        vars: u64_at(49),
        value_blocks: u64_at(65),
        writer: String::from_utf8_lossy(&text[..end]).into_owned(),
    })
}

/// Keeps, of a VCD's text, the signals inside scope `path` (instance
/// names from the top's scope down, `u_a.u_b`; the scope itself and below)
/// and their value changes: the scope filter for engines that dump every
/// signal. In a flat dump (the IR simulator names an instance's nets
/// `u_a_u_b_<net>` in one scope) the signals so named are kept. Scope lines
/// stay (an emptied scope is harmless); an error when no signal matches.
pub fn filter_vcd_scope(text: &str, path: &str) -> std::result::Result<String, String> {
    let want: Vec<&str> = path.split('.').collect();
    let flat = format!("{}_", path.replace('.', "_"));
    let mut out = String::with_capacity(text.len());
    let mut stack: Vec<String> = Vec::new();
    let mut kept = std::collections::HashSet::new();
    let mut lines = text.lines();
    let inside = |stack: &[String]| {
        stack
            .windows(want.len())
            .any(|w| w.iter().zip(&want).all(|(a, b)| a == b))
    };
    // A dump with the scope as a scope is cut by scopes; only a flat one by
    // names (a parent's nets to the instance share the prefix).
    let mut probe: Vec<String> = Vec::new();
    let hierarchical = text
        .lines()
        .take_while(|l| !l.starts_with("$enddefinitions"))
        .any(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            match w.first().copied() {
                Some("$scope") => {
                    probe.push(w.get(2).copied().unwrap_or("").to_string());
                    inside(&probe)
                }
                Some("$upscope") => {
                    probe.pop();
                    false
                }
                _ => false,
            }
        });
    for line in lines.by_ref() {
        let words: Vec<&str> = line.split_whitespace().collect();
        let keep = match words.first().copied() {
            Some("$scope") => {
                stack.push(words.get(2).copied().unwrap_or("").to_string());
                true
            }
            Some("$upscope") => {
                stack.pop();
                true
            }
            Some("$var") => {
                let name = words.get(4).copied().unwrap_or("");
                let take = if hierarchical {
                    inside(&stack)
                } else {
                    name.starts_with(&flat)
                };
                if take {
                    kept.insert(words.get(3).copied().unwrap_or("").to_string());
                }
                take
            }
            _ => true,
        };
        if keep {
            out.push_str(line);
            out.push('\n');
        }
        if words.first() == Some(&"$enddefinitions") {
            break;
        }
    }
    if kept.is_empty() {
        return Err(format!("no signal under scope `{path}` in the waveform"));
    }
    for line in lines {
        let id = match line.as_bytes().first() {
            Some(b'b' | b'B' | b'r' | b'R') => line.split_whitespace().nth(1),
            Some(b'0' | b'1' | b'x' | b'X' | b'z' | b'Z') => Some(&line[1..]),
            _ => None,
        };
        if id.is_none_or(|id| kept.contains(id)) {
            out.push_str(line);
            out.push('\n');
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scope_keeps_its_signals_and_drops_the_rest() {
        let vcd = "$timescale 1ns $end\n$scope module tb $end\n$var wire 1 ! clk $end\n\
                   $scope module dut $end\n$var wire 8 \" a [7:0] $end\n\
                   $scope module u_x $end\n$var wire 1 # q $end\n$upscope $end\n\
                   $upscope $end\n$upscope $end\n$enddefinitions $end\n\
                   #0\n0!\nb101 \"\n1#\n#1\n1!\nb110 \"\n0#\n";
        let f = filter_vcd_scope(vcd, "u_x").unwrap();
        assert!(f.contains("$var wire 1 # q $end"), "{f}");
        assert!(!f.contains(" clk ") && !f.contains(" a [7:0]"), "{f}");
        assert!(
            f.contains("1#\n") && f.contains("0#\n") && f.contains("#1\n"),
            "{f}"
        );
        assert!(!f.contains("0!\n") && !f.contains("b101"), "{f}");
        assert!(filter_vcd_scope(vcd, "dut.u_x").is_ok());
        let e = filter_vcd_scope(vcd, "u_y").unwrap_err();
        assert!(e.contains("no signal under scope `u_y`"), "{e}");
        // A flat dump: an instance's nets by their prefix.
        let flat = "$scope module top $end\n$var wire 1 ! u_x_q $end\n\
                    $var wire 1 # u_xy $end\n$upscope $end\n$enddefinitions $end\n#0\n1!\n1#\n";
        let f = filter_vcd_scope(flat, "u_x").unwrap();
        assert!(f.contains(" u_x_q ") && !f.contains(" u_xy "), "{f}");
        assert!(f.contains("1!\n") && !f.contains("1#\n"), "{f}");
    }

    #[test]
    fn the_format_is_the_file_name_s() {
        assert_eq!(WaveFormat::of(Path::new("a/b.fst")), WaveFormat::Fst);
        assert_eq!(WaveFormat::of(Path::new("a/b.vcd")), WaveFormat::Vcd);
        assert!(read_fst_header(b"$timescale").is_err());
    }
}
