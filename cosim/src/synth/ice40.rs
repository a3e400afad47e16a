//! iCE40 HX8K: Yosys `synth_ice40` decides whether a module fits (by its
//! LUT count, before any place and route); a module that fits is placed
//! and routed inside a thin registered wrapper (SPEC 14.3).

use super::ecp5::PnrRun;
use super::path::SourceIndex;
use super::sources::{header_ports, Netlist};
use super::{stat, Flow, Spread};
use crate::error::{io_err, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// LUTs of an iCE40 HX8K.
pub const HX8K_LUTS: u64 = 7680;
/// Block RAMs of an iCE40 HX8K.
pub const HX8K_BRAMS: u64 = 32;
/// The device options given to nextpnr-ice40.
pub const DEVICE: &[&str] = &["--hx8k", "--package", "ct256"];
/// The cache kind of `synth_ice40` results.
pub const KIND: &str = "synth-ice40";

/// The wrapper's module name.
pub const WRAPPER: &str = "hiermerge_synth_wrap";

/// The iCE40 figures of one module.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Ice40Figures {
    /// Cells by type of the module alone.
    pub cells: BTreeMap<String, u64>,
    /// LUT4s (`SB_LUT4`); none when `synth_ice40` was not run (see `verdict`).
    pub lut4: Option<u64>,
    /// Flip-flops (`SB_DFF*`); none when not synthesized.
    pub ff: Option<u64>,
    /// Carry cells (`SB_CARRY`); none when not synthesized.
    pub carry: Option<u64>,
    /// Block RAMs (`SB_RAM40_4K`); none when not synthesized.
    pub bram: Option<u64>,
    /// True when LUTs and block RAMs fit an HX8K.
    pub fits: bool,
    /// "fits: N LUTs of 7,680", "does not fit: N LUTs of 7,680", or, when
    /// the ECP5 mapping already rules it out and `synth_ice40` is not run,
    /// "does not fit: N LUT4 (ECP5 mapping) of 7,680".
    pub verdict: String,
    /// Flip-flops the wrapper adds (one per port bit).
    pub wrapper_ff: u64,
    /// Fmax over the seeds, when placed.
    pub fmax_mhz: Option<Spread>,
    /// Every seed's run (empty when it does not fit).
    pub runs: Vec<PnrRun>,
}

/// `n` with thousands separators: 7,680.
pub fn thousands(n: u64) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// A wrapper with four pins (clk, si, load, so): the module's inputs come
/// from a shift register fed by `si`, its outputs are loaded into a shift
/// register read out at `so`, so every port is registered and the module's
/// ports need no I/O pins.
pub fn wrapper(top: &str, text: &str) -> String {
    let ports = header_ports(text);
    let n_in: u32 = ports
        .iter()
        .filter(|p| p.input && p.name != "clk")
        .map(|p| p.width)
        .sum();
    let n_out: u32 = ports.iter().filter(|p| !p.input).map(|p| p.width).sum();
    let (n_in, n_out) = (n_in.max(1), n_out.max(1));
    let mut conns = Vec::new();
    let (mut at_in, mut at_out) = (0, 0);
    for p in &ports {
        let (bus, at) = match (p.name.as_str(), p.input) {
            ("clk", true) => {
                conns.push(".clk(clk)".to_string());
                continue;
            }
            (_, true) => ("sin", &mut at_in),
            (_, false) => ("outs", &mut at_out),
        };
        conns.push(format!(".{}({bus}[{}:{}])", p.name, *at + p.width - 1, *at));
        *at += p.width;
    }
    let shift = |reg: &str, n: u32, fill: &str| {
        if n == 1 {
            fill.to_string()
        } else {
            format!("{{{reg}[{}:0], {fill}}}", n - 2)
        }
    };
    format!(
        "module {WRAPPER} (input wire clk, input wire si, input wire load, output wire so);\n\
         \x20   reg [{hi_in}:0] sin;\n\
         \x20   reg [{hi_out}:0] sout;\n\
         \x20   wire [{hi_out}:0] outs;\n\
         \x20   always @(posedge clk) sin <= {shift_in};\n\
         \x20   always @(posedge clk) sout <= load ? outs : {shift_out};\n\
         \x20   assign so = sout[{hi_out}];\n\
         \x20   {top} u_dut ({conns});\n\
         endmodule\n",
        hi_in = n_in - 1,
        hi_out = n_out - 1,
        shift_in = shift("sin", n_in, "si"),
        shift_out = shift("sout", n_out, "1'b0"),
        conns = conns.join(", "),
    )
}

fn synth_build(flow: &Flow, netlist: &Netlist, top: &str, dir: &Path) -> Result<()> {
    let reads = super::generic::read_files(&netlist.files(top));
    let cells = flow.synth_cells(
        &reads,
        top,
        dir,
        "ice40",
        &format!("synth_ice40 -top {top}"),
    )?;
    let ports = header_ports(&netlist.modules[top].text);
    super::write_json(&dir.join("figures.json"), &Ice40Figures::of(cells, &ports))
}

impl Ice40Figures {
    /// The figures of synthesized cells `cells` of a module with ports
    /// `ports`, before any place and route.
    pub fn of(cells: BTreeMap<String, u64>, ports: &[super::sources::HeaderPort]) -> Ice40Figures {
        let lut4 = cells.get("SB_LUT4").copied().unwrap_or(0);
        let bram = cells.get("SB_RAM40_4K").copied().unwrap_or(0);
        let fits = lut4 <= HX8K_LUTS && bram <= HX8K_BRAMS;
        let verdict = format!(
            "{}: {} LUTs of {}",
            if fits { "fits" } else { "does not fit" },
            thousands(lut4),
            thousands(HX8K_LUTS)
        ) + &if bram > HX8K_BRAMS {
            format!(", {bram} block RAMs of {HX8K_BRAMS}")
        } else {
            String::new()
        };
        Ice40Figures {
            lut4: Some(lut4),
            ff: Some(stat::count_where(&cells, |k| k.starts_with("SB_DFF"))),
            carry: Some(cells.get("SB_CARRY").copied().unwrap_or(0)),
            bram: Some(bram),
            fits,
            verdict,
            wrapper_ff: ports
                .iter()
                .filter(|p| p.name != "clk")
                .map(|p| p.width as u64)
                .sum(),
            fmax_mhz: None,
            runs: Vec::new(),
            cells,
        }
    }
}

/// Synthesizes the wrapper around `top` into `dir/netlist.json`.
fn wrapper_build(flow: &Flow, netlist: &Netlist, top: &str, dir: &Path) -> Result<()> {
    (flow.progress)(&format!("{top}: ice40: yosys synth_ice40 of the wrapper"));
    let wrap = dir.join("wrapper.v");
    std::fs::write(&wrap, wrapper(top, &netlist.modules[top].text)).map_err(io_err(&wrap))?;
    let mut files = netlist.files(top);
    files.push(wrap);
    let script = format!(
        "{}synth_ice40 -top {WRAPPER} -json netlist.json\n",
        super::generic::read_files(&files)
    );
    std::fs::write(dir.join("wrap.ys"), script).map_err(io_err(dir.join("wrap.ys")))?;
    flow.yosys_script(dir, "wrap.ys", "yosys.log")
}

/// How far over the HX8K's LUTs a module's ECP5 LUT4 count must be for
/// `synth_ice40` to be skipped. Both map onto LUT4s, but not the same
/// number: over the eleven default modules synthesized for both, iCE40
/// LUT4 / ECP5 LUT4 ranged from 0.45 (the per-node merging module) to
/// 1.15 (SPEC 14.3); past three times the HX8K a module would need a ratio
/// under 0.33 to fit.
pub const SKIP_FACTOR: u64 = 3;

/// The verdict without `synth_ice40` when the module's ECP5 mapping
/// (`ecp5_lut4` LUT4s plus `ecp5_lutram` distributed RAMs, 4 LUTs each) is
/// more than `SKIP_FACTOR` times the HX8K's LUTs; none when iCE40 synthesis
/// must decide.
pub fn rules_out(ecp5_lut4: u64, ecp5_lutram: u64) -> Option<Ice40Figures> {
    let luts = ecp5_lut4 + 4 * ecp5_lutram;
    (luts > SKIP_FACTOR * HX8K_LUTS).then(|| Ice40Figures {
        cells: BTreeMap::new(),
        lut4: None,
        ff: None,
        carry: None,
        bram: None,
        fits: false,
        verdict: format!(
            "does not fit: {} LUT4 (ECP5 mapping) of {}",
            thousands(luts),
            thousands(HX8K_LUTS)
        ),
        wrapper_ff: 0,
        fmax_mhz: None,
        runs: Vec::new(),
    })
}

/// The `synth_ice40` figures of `top` (cached, not placed) and their entry.
pub fn synthesis(
    flow: &Flow,
    netlist: &Netlist,
    top: &str,
    digest: &str,
) -> Result<(Ice40Figures, crate::cache::CacheEntry)> {
    flow.synthesized(KIND, top, digest, |d| synth_build(flow, netlist, top, d))
}

/// Where a timed-out iCE40 place and route of `top` (run key `key`) is remembered.
fn timeout_file(root: &Path, top: &str, key: &str) -> std::path::PathBuf {
    root.join("synth-ice40-pnr-timeout")
        .join(format!("{top}-{}.txt", &key[..24]))
}

/// The longest time limit a place and route `key` of `top` ran out of, if any.
fn timed_out(root: &Path, top: &str, key: &str) -> Option<u64> {
    let text = std::fs::read_to_string(timeout_file(root, top, key)).ok()?;
    text.trim().parse().ok()
}

/// Remembers that place and route `key` of `top` ran out of `secs` seconds,
/// so that a rerun with that limit or a shorter one does not wait again.
fn remember_timeout(root: &Path, top: &str, key: &str, secs: u64) -> Result<()> {
    let path = timeout_file(root, top, key);
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(io_err(dir))?;
    }
    let secs = secs.max(timed_out(root, top, key).unwrap_or(0));
    std::fs::write(&path, secs.to_string()).map_err(io_err(&path))
}

fn stall_note(seed: u64, secs: u64) -> String {
    format!(
        " (not placed: nextpnr-ice40 seed {seed} did not finish within {secs} s; \
         a run with a longer --timeout tries again)"
    )
}

/// The iCE40 figures of `top`, cached; the list names what this call made.
/// With `ecp5` (the module's ECP5 synthesis, when that target runs) a module
/// that `rules_out` is not synthesized for iCE40 at all.
pub fn ice40(
    flow: &Flow,
    netlist: &Netlist,
    top: &str,
    digest: &str,
    seeds: u64,
    ecp5: Option<&super::ecp5::Ecp5Synth>,
) -> Result<(Ice40Figures, Vec<String>)> {
    if let Some(skip) = ecp5.and_then(|e| rules_out(e.lut4, e.lutram)) {
        return Ok((skip, Vec::new()));
    }
    let synth_key = flow.synth_key(digest);
    let root = &flow.cache_root;
    let (mut figures, entry) = synthesis(flow, netlist, top, digest)?;
    let mut made = Vec::new();
    if entry.built {
        made.push("ice40 synth".to_string());
    }
    if !figures.fits {
        return Ok((figures, made));
    }
    let out_bits: u64 = header_ports(&netlist.modules[top].text)
        .iter()
        .filter(|p| !p.input)
        .map(|p| p.width as u64)
        .sum();
    if figures.lut4.unwrap_or(0) + out_bits > HX8K_LUTS {
        figures.verdict +=
            &format!(" (not placed: with the wrapper's {out_bits} output LUTs it would not fit)");
        return Ok((figures, made));
    }
    let tool = flow.tool_ice40()?;
    let wrapped = crate::cache::get_or_build(root, "synth-ice40-wrap", top, &synth_key, |d| {
        wrapper_build(flow, netlist, top, d)
    })?;
    if wrapped.built {
        made.push("ice40 wrapper synth".to_string());
    }
    let json = wrapped.dir.join("netlist.json");
    let index = SourceIndex::new(netlist, top).below(WRAPPER, "u_dut");
    for seed in 1..=seeds {
        let key = flow.pnr_key(&synth_key, tool, DEVICE, seed);
        let stalled = timed_out(root, top, &key);
        if let Some(secs) = stalled.filter(|s| *s >= flow.timeout.as_secs()) {
            figures.verdict += &stall_note(seed, secs);
            figures.runs.clear();
            return Ok((figures, made));
        }
        let run = crate::cache::get_or_build(root, "synth-ice40-pnr", top, &key, |d| {
            (flow.progress)(&format!("{top}: ice40: nextpnr-ice40 seed {seed}"));
            let run = super::ecp5::place_and_route(flow, tool, DEVICE, &json, seed, &index, d)?;
            super::write_json(&d.join("run.json"), &run)?;
            let tools = format!(
                "{}; {}; freq {}",
                flow.yosys.version, tool.version, flow.freq_mhz
            );
            super::write_meta(d, top, digest, &tools)
        });
        // nextpnr-ice40 0.4's placer can stall on a module that fits (SPEC
        // 14.3): a timed-out iCE40 place and route is reported, not cached,
        // and the run goes on; any other failure stops it.
        let run = match run {
            Err(crate::error::CosimError::ToolFailed { log, .. })
                if log.starts_with("timed out") =>
            {
                let secs = flow.timeout.as_secs();
                remember_timeout(root, top, &key, secs)?;
                made.push(format!("ice40 seed {seed} (timed out)"));
                figures.verdict += &stall_note(seed, secs);
                figures.runs.clear();
                return Ok((figures, made));
            }
            other => other?,
        };
        if run.built {
            made.push(format!("ice40 seed {seed}"));
        }
        figures
            .runs
            .push(super::read_json(&run.dir.join("run.json"))?);
    }
    figures.fmax_mhz = Some(Spread::of(
        figures.runs.iter().map(|r| r.fmax_mhz).collect(),
    ));
    Ok((figures, made))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ecp5_mapping_rules_out_only_far_over_the_device() {
        assert_eq!(
            rules_out(3 * HX8K_LUTS, 0),
            None,
            "at three times: synthesize"
        );
        assert_eq!(rules_out(2 * HX8K_LUTS, HX8K_LUTS / 4), None);
        let f = rules_out(23_713, 0).expect("over three times");
        assert!(!f.fits && f.lut4.is_none() && f.runs.is_empty());
        assert_eq!(
            f.verdict,
            "does not fit: 23,713 LUT4 (ECP5 mapping) of 7,680"
        );
        let f = rules_out(23_000, 100).expect("LUT RAMs count 4 LUTs each");
        assert_eq!(
            f.verdict,
            "does not fit: 23,400 LUT4 (ECP5 mapping) of 7,680"
        );
    }
}
