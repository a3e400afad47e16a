//! Area and clock from synthesis (SPEC 13.4): what `hiermerge synth`
//! recorded in its cache for the hierarchy merger of a configuration,
//! read by `cosim::synth::record::lookup`, which runs no tool and builds
//! nothing (one synthesis of a merger takes minutes to hours on this
//! project's 2-core machines, so the study never starts one). Where nothing
//! is recorded the study says "not measured" and names the command that
//! measures it, never a guess.

use std::path::Path;

use cosim::synth::record::{lookup, Lookup};
use cosim::synth::sources::Netlist;
use rtl_gen::merge::MergerConfig;
use serde::Serialize;

/// What synthesis recorded for the hierarchy merger of one configuration.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct SynthFigures {
    /// The merger top looked up.
    pub module: String,
    /// Generic NAND2-equivalent gates (composed from its parts, SPEC 14.6),
    /// when recorded.
    pub nand2_eq: Option<f64>,
    /// ECP5 LUT4s, when recorded.
    pub ecp5_lut4: Option<u64>,
    /// ECP5 block RAMs, when recorded.
    pub ecp5_ebr: Option<u64>,
    /// The ECP5 fit verdict (LFE5U-85F), when recorded.
    pub ecp5_verdict: Option<String>,
    /// The clock, MHz: the top's own lowest ECP5 Fmax over seeds when it was
    /// placed; else (`fmax_bound`) the lowest Fmax of its parts placed alone,
    /// an upper bound of the top's clock (the top holds their paths), once
    /// every part has ECP5 figures; else `None`.
    pub fmax_mhz: Option<f64>,
    /// True when `fmax_mhz` is that upper bound.
    pub fmax_bound: bool,
    /// The module whose Fmax `fmax_mhz` is.
    pub fmax_of: Option<String>,
    /// The tools that measured them.
    pub tools: String,
}

/// The command that measures `unit`'s synthesis figures.
pub fn synth_command(unit: &MergerConfig) -> String {
    let p = &unit.design.params;
    let default = golden::Params::default();
    if p.max_lod == default.max_lod && p.quant_bits == default.quant_bits {
        "hiermerge synth --defaults".into()
    } else {
        format!(
            "hiermerge synth --unit merge --max-lod {} --quant-bits {}",
            p.max_lod, p.quant_bits
        )
    }
}

fn lowest_fmax(l: &Lookup) -> Option<f64> {
    l.ecp5.as_ref()?.figures.fmax_mhz.as_ref().map(|s| s.min)
}

/// The cached figures of the merger top of `netlist` under cache `root`.
pub fn figures_of(root: &Path, netlist: &Netlist) -> Option<SynthFigures> {
    let top = netlist
        .modules
        .keys()
        .find(|m| m.starts_with("hierarchy_merger_"))?;
    let l = lookup(root, netlist, top);
    if l.generic.is_none() && l.ecp5.is_none() {
        return None;
    }
    let (mut fmax_mhz, mut fmax_of, mut fmax_bound) = (None, None, false);
    if let Some(f) = lowest_fmax(&l) {
        (fmax_mhz, fmax_of) = (Some(f), Some(top.clone()));
    } else {
        // The parts' lowest Fmax bounds the top's clock only when every part
        // went through the ECP5 flow (placed, or found not to fit): a part
        // not yet measured may be the slowest, and a bound from the others
        // would make the configuration look faster than it is.
        let parts: Vec<(String, Lookup)> = netlist
            .closure(top)
            .iter()
            .filter(|s| &s.module != top)
            .map(|s| (s.module.clone(), lookup(root, netlist, &s.module)))
            .collect();
        if parts.iter().all(|(_, l)| l.ecp5.is_some()) {
            for (module, l) in &parts {
                if let Some(f) = lowest_fmax(l) {
                    if fmax_mhz.is_none_or(|m| f < m) {
                        (fmax_mhz, fmax_of, fmax_bound) = (Some(f), Some(module.clone()), true);
                    }
                }
            }
        }
    }
    let tools = l
        .ecp5
        .as_ref()
        .map(|r| r.tools.clone())
        .or_else(|| l.generic.as_ref().map(|r| r.tools.clone()))
        .unwrap_or_default();
    Some(SynthFigures {
        module: top.clone(),
        nand2_eq: l.generic.as_ref().map(|g| g.figures.nand2_eq),
        ecp5_lut4: l.ecp5.as_ref().map(|e| e.figures.synth.lut4),
        ecp5_ebr: l.ecp5.as_ref().map(|e| e.figures.synth.ebr),
        ecp5_verdict: l.ecp5.as_ref().map(|e| e.figures.verdict.clone()),
        fmax_mhz,
        fmax_bound,
        fmax_of,
        tools,
    })
}

/// The one lookup of synthesis figures: what `hiermerge synth` recorded in
/// the cache (`cosim::cache::cache_root()`) for the hierarchy merger
/// `unit` (the configuration whose cycles the study measures,
/// `rtl::merger_config`), or `None` when nothing is recorded. Emits the
/// configuration's Verilog into a temporary folder (the digest is over its
/// text); runs no synthesis tool.
pub fn synth_figures(unit: &MergerConfig) -> Result<Option<SynthFigures>, String> {
    let dir = tempfile::tempdir().map_err(|e| format!("a temporary folder: {e}"))?;
    let files = rtl_gen::merge::emit_merge(&unit.design, dir.path()).map_err(|e| e.to_string())?;
    let netlist = Netlist::read(&files).map_err(|e| e.to_string())?;
    Ok(figures_of(&cosim::cache::cache_root(), &netlist))
}

/// Nanoseconds per merge, cycles / Fmax, when both are measured (with an
/// Fmax bound, a lower bound of the time).
pub fn ns_per_merge(cycles_per_merge: Option<f64>, s: Option<&SynthFigures>) -> Option<f64> {
    Some(cycles_per_merge? * 1e3 / s?.fmax_mhz?)
}
