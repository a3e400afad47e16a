//! ECP5 (LFE5U-85F, speed grade 8): Yosys `synth_ecp5`, then `nextpnr-ecp5
//! --out-of-context` once per seed (SPEC 14.2).

use super::path::{critical_path, fmax_mhz, CriticalPath, SourceIndex};
use super::sources::Netlist;
use super::{Flow, Spread};
use crate::error::{io_err, CosimError, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// The device options given to nextpnr-ecp5.
pub const DEVICE: &[&str] = &["--85k", "--speed", "8", "--out-of-context"];
/// LUT4s (and flip-flops) of an LFE5U-85F.
pub const LFE5U_85F_LUTS: u64 = 83_640;
/// Block RAMs (DP16KD) of an LFE5U-85F.
pub const LFE5U_85F_EBRS: u64 = 208;
/// Multipliers (MULT18X18D) of an LFE5U-85F.
pub const LFE5U_85F_DSPS: u64 = 156;

/// What `synth_ecp5` maps a module onto.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Ecp5Synth {
    /// Cells by type.
    pub cells: BTreeMap<String, u64>,
    /// LUT4s.
    pub lut4: u64,
    /// Flip-flops (`TRELLIS_FF`).
    pub ff: u64,
    /// Carry cells (`CCU2C`, two bits each).
    pub ccu2c: u64,
    /// Block RAMs (`DP16KD`).
    pub ebr: u64,
    /// Distributed RAMs (`TRELLIS_DPR16X4`).
    pub lutram: u64,
    /// DSP multipliers (`MULT18X18D`).
    pub dsp: u64,
}

/// One place-and-route run.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct PnrRun {
    /// nextpnr's `--seed`.
    pub seed: u64,
    /// The Fmax nextpnr's timing report gives for `clk`, MHz.
    pub fmax_mhz: f64,
    /// Its critical path.
    pub critical_path: Option<CriticalPath>,
}

/// The ECP5 figures of one module.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Ecp5Figures {
    /// Synthesis.
    #[serde(flatten)]
    pub synth: Ecp5Synth,
    /// True when the synthesized cells fit an LFE5U-85F (decided before
    /// place and route).
    pub fits: bool,
    /// "fits", or "does not fit: N EBR of 208" (each resource over).
    pub verdict: String,
    /// Fmax over the seeds (none when it does not fit).
    pub fmax_mhz: Option<Spread>,
    /// True when the lowest Fmax reaches the goal (`--freq`); none when not placed.
    pub meets_goal: Option<bool>,
    /// Every seed's run.
    pub runs: Vec<PnrRun>,
}

impl Ecp5Figures {
    /// The figures of a module that is not placed and routed.
    pub fn unplaced(synth: Ecp5Synth, fits: bool, verdict: String) -> Ecp5Figures {
        Ecp5Figures {
            synth,
            fits,
            verdict,
            fmax_mhz: None,
            meets_goal: None,
            runs: Vec::new(),
        }
    }
}

/// The fit verdict of synthesized ECP5 cells on an LFE5U-85F.
pub fn fit(s: &Ecp5Synth) -> (bool, String) {
    use super::ice40::thousands;
    let over: Vec<String> = [
        (
            s.lut4 + 4 * s.lutram,
            LFE5U_85F_LUTS,
            "LUTs (LUT4 + 4 per distributed RAM)",
        ),
        (s.ff, LFE5U_85F_LUTS, "flip-flops"),
        (s.ebr, LFE5U_85F_EBRS, "EBR"),
        (s.dsp, LFE5U_85F_DSPS, "DSP"),
    ]
    .iter()
    .filter(|(n, cap, _)| n > cap)
    .map(|(n, cap, what)| format!("{} {what} of {}", thousands(*n), thousands(*cap)))
    .collect();
    if over.is_empty() {
        (true, "fits".into())
    } else {
        (false, format!("does not fit: {}", over.join(", ")))
    }
}

/// The cache kind of `synth_ecp5` results.
pub const KIND: &str = "synth-ecp5";
/// The cache kind of ECP5 place-and-route runs.
pub const PNR_KIND: &str = "synth-ecp5-pnr";

impl Ecp5Synth {
    /// The figures of synthesized cells `cells`.
    pub fn of(cells: BTreeMap<String, u64>) -> Ecp5Synth {
        let n = |k: &str| cells.get(k).copied().unwrap_or(0);
        Ecp5Synth {
            lut4: n("LUT4"),
            ff: n("TRELLIS_FF"),
            ccu2c: n("CCU2C"),
            ebr: n("DP16KD"),
            lutram: n("TRELLIS_DPR16X4"),
            dsp: n("MULT18X18D"),
            cells,
        }
    }
}

fn synth_build(flow: &Flow, netlist: &Netlist, top: &str, dir: &Path) -> Result<()> {
    let synth = format!("synth_ecp5 -top {top} -json netlist.json");
    let reads = super::generic::read_files(&netlist.files(top));
    let cells = flow.synth_cells(&reads, top, dir, "ecp5", &synth)?;
    super::write_json(&dir.join("figures.json"), &Ecp5Synth::of(cells))
}

/// Runs nextpnr (`tool`, device options `device`) on `json` with `seed`,
/// and reads Fmax and the critical path from its report.
pub(super) fn place_and_route(
    flow: &Flow,
    tool: &super::tools::Tool,
    device: &[&str],
    json: &Path,
    seed: u64,
    index: &SourceIndex,
    dir: &Path,
) -> Result<PnrRun> {
    // YoWASP's nextpnr sees only its working folder: give it a copy there.
    let local = dir.join("netlist.json");
    if json != local {
        std::fs::copy(json, &local).map_err(io_err(&local))?;
    }
    let mut args: Vec<String> = device.iter().map(|s| s.to_string()).collect();
    args.extend(
        [
            "--json",
            "netlist.json",
            "--freq",
            &flow.freq_mhz.to_string(),
            "--timing-allow-fail",
            "--seed",
            &seed.to_string(),
            "--report",
            "report.json",
        ]
        .map(String::from),
    );
    super::run::run_logged(&tool.program, &args, dir, "nextpnr.log", flow.timeout).map_err(
        |e| match e {
            CosimError::ToolFailed { tool, command, log } => CosimError::ToolFailed {
                tool: format!("{tool} (place and route)"),
                command,
                log,
            },
            other => other,
        },
    )?;
    let _ = std::fs::remove_file(&local);
    let path = dir.join("report.json");
    let text = std::fs::read_to_string(&path).map_err(io_err(&path))?;
    let report: serde_json::Value = serde_json::from_str(&text).map_err(|e| CosimError::Parse {
        text: path.display().to_string(),
        what: format!("a nextpnr JSON report: {e}"),
    })?;
    let fmax = fmax_mhz(&report, "clk").ok_or_else(|| CosimError::Parse {
        text: path.display().to_string(),
        what: "a report with an Fmax for clock `clk` (a design without a clocked path?)".into(),
    })?;
    Ok(PnrRun {
        seed,
        fmax_mhz: (fmax * 100.0).round() / 100.0,
        critical_path: critical_path(&report, "clk", index),
    })
}

/// The `synth_ecp5` result of `top` (cached) and its cache entry.
pub fn synthesis(
    flow: &Flow,
    netlist: &Netlist,
    top: &str,
    digest: &str,
) -> Result<(Ecp5Synth, crate::cache::CacheEntry)> {
    flow.synthesized(KIND, top, digest, |d| synth_build(flow, netlist, top, d))
}

/// The ECP5 figures of `top` over `seeds` seeds (1..=seeds), cached; the
/// list names what this call made.
pub fn ecp5(
    flow: &Flow,
    netlist: &Netlist,
    top: &str,
    digest: &str,
    seeds: u64,
) -> Result<(Ecp5Figures, Vec<String>)> {
    let tool = flow.tool_ecp5()?;
    let synth_key = flow.synth_key(digest);
    let root = &flow.cache_root;
    let (synth, entry) = synthesis(flow, netlist, top, digest)?;
    let mut made = Vec::new();
    if entry.built {
        made.push("ecp5 synth".to_string());
    }
    let (fits, verdict) = fit(&synth);
    if !fits {
        return Ok((Ecp5Figures::unplaced(synth, fits, verdict), made));
    }
    let json = entry.dir.join("netlist.json");
    let index = SourceIndex::new(netlist, top);
    let mut runs = Vec::new();
    for seed in 1..=seeds {
        let key = flow.pnr_key(&synth_key, tool, DEVICE, seed);
        let run = crate::cache::get_or_build(root, PNR_KIND, top, &key, |d| {
            (flow.progress)(&format!("{top}: ecp5: nextpnr-ecp5 seed {seed}"));
            let run = place_and_route(flow, tool, DEVICE, &json, seed, &index, d)?;
            super::write_json(&d.join("run.json"), &run)?;
            let tools = format!(
                "{}; {}; freq {}",
                flow.yosys.version, tool.version, flow.freq_mhz
            );
            super::write_meta(d, top, digest, &tools)
        })?;
        if run.built {
            made.push(format!("ecp5 seed {seed}"));
        }
        runs.push(super::read_json::<PnrRun>(&run.dir.join("run.json"))?);
    }
    let fmax_mhz = Spread::of(runs.iter().map(|r| r.fmax_mhz).collect());
    let figures = Ecp5Figures {
        synth,
        fits,
        verdict,
        meets_goal: Some(fmax_mhz.min >= flow.freq_mhz),
        fmax_mhz: Some(fmax_mhz),
        runs,
    };
    Ok((figures, made))
}
