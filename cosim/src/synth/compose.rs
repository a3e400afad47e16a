//! The hierarchy merger tops, figured bottom-up from their parts (SPEC
//! 14.6): the top's own logic is synthesized with its instances as black
//! boxes (Yosys `read_verilog -lib`), and each instance adds the figures
//! of its module synthesized alone (cached: the same results the module's
//! own row shows). The flat synthesis of a merger top repeats its four
//! fetchers and takes 18-60 minutes per Yosys step on a 2-core machine; the
//! sum differs from it only by what optimization across instance ports
//! would remove. Composed modules are never placed and routed.

use super::generic::{nand2_eq, read_files, GenericFigures};
use super::ice40::Ice40Figures;
use super::sources::{header_ports, Netlist};
use super::{ecp5, generic, stat, Flow};
use crate::cache::CacheKey;
use crate::error::Result;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// One kind of instance of a composed module.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Part {
    /// The module instantiated.
    pub module: String,
    /// How many instances.
    pub count: u64,
}

/// True for the modules whose figures are composed: the hierarchy merger tops.
pub fn is_composed(module: &str) -> bool {
    module.starts_with("hierarchy_merger_")
}

/// The modules `top` instantiates directly, with their instance counts.
pub fn parts(netlist: &Netlist, top: &str) -> Vec<Part> {
    let mut counts: BTreeMap<String, u64> = BTreeMap::new();
    for (m, _) in netlist.instances(top) {
        *counts.entry(m).or_default() += 1;
    }
    counts
        .into_iter()
        .map(|(module, count)| Part { module, count })
        .collect()
}

/// Yosys reads of `top`'s own file, its parts as black boxes.
fn glue_reads(netlist: &Netlist, top: &str) -> String {
    let mut reads = read_files(&[netlist.modules[top].path.clone()]);
    for p in parts(netlist, top) {
        reads += &format!(
            "read_verilog -lib {}\n",
            netlist.modules[&p.module].path.display()
        );
    }
    reads
}

fn glue_key(flow: &Flow, digest: &str, what: &str) -> String {
    let mut key = CacheKey::new();
    key.add("digest", digest.as_bytes())
        .add("yosys", flow.yosys.version.as_bytes())
        .add("glue", what.as_bytes());
    key.finish()
}

/// `cells` without the black-box instances of `top`'s parts.
fn own_cells(netlist: &Netlist, top: &str, cells: &BTreeMap<String, u64>) -> BTreeMap<String, u64> {
    let parts: Vec<String> = parts(netlist, top).into_iter().map(|p| p.module).collect();
    cells
        .iter()
        .filter(|(k, _)| !parts.iter().any(|p| k.trim_start_matches('\\') == p))
        .map(|(k, n)| (k.clone(), *n))
        .collect()
}

fn add_cells(into: &mut BTreeMap<String, u64>, cells: &BTreeMap<String, u64>, times: u64) {
    for (k, n) in cells {
        *into.entry(k.clone()).or_default() += n * times;
    }
}

/// The cells `synth_<fpga>` (`ecp5`, `ice40`) maps `top`'s own logic onto,
/// cached; a fresh synthesis is added to `made`.
fn glue_cells(
    flow: &Flow,
    netlist: &Netlist,
    top: &str,
    digest: &str,
    fpga: &str,
    made: &mut Vec<String>,
) -> Result<BTreeMap<String, u64>> {
    let key = glue_key(flow, digest, fpga);
    let kind = format!("synth-{fpga}-glue");
    let entry = crate::cache::get_or_build(&flow.cache_root, &kind, top, &key, |d| {
        let reads = glue_reads(netlist, top);
        let synth = format!("synth_{fpga} -top {top}");
        let cells = flow.synth_cells(&reads, top, d, fpga, &synth)?;
        super::write_json(&d.join("cells.json"), &cells)?;
        super::write_meta(d, top, digest, &flow.yosys.version)
    })?;
    if entry.built {
        made.push(format!("{fpga} glue"));
    }
    let glue: BTreeMap<String, u64> = super::read_json(&entry.dir.join("cells.json"))?;
    Ok(own_cells(netlist, top, &glue))
}

/// The generic figures of a composed `top`; the list names what this call made.
pub fn generic(
    flow: &Flow,
    netlist: &Netlist,
    top: &str,
    digest: &str,
) -> Result<(GenericFigures, Vec<String>)> {
    let mut made = Vec::new();
    // "-2": its depth counts its own gates only (black boxes deleted first).
    let key = glue_key(flow, digest, "generic-2");
    let entry =
        crate::cache::get_or_build(&flow.cache_root, "synth-generic-glue", top, &key, |d| {
            let cut: String = parts(netlist, top)
                .iter()
                .map(|p| format!("delete t:{}\n", p.module))
                .collect();
            generic::build(flow, &glue_reads(netlist, top), top, d, &cut)?;
            super::write_meta(d, top, digest, &flow.yosys.version)
        })?;
    if entry.built {
        made.push("generic glue".to_string());
    }
    let glue: GenericFigures = super::read_json(&entry.dir.join("figures.json"))?;
    let mut cells = own_cells(netlist, top, &glue.cells);
    let (mut memories, mut memory_bits, mut depth) = (glue.memories, glue.memory_bits, glue.depth);
    for p in parts(netlist, top) {
        let (g, built) = generic::generic(flow, netlist, &p.module, &netlist.digest(&p.module))?;
        if built {
            made.push(format!("generic of {}", p.module));
        }
        add_cells(&mut cells, &g.cells, p.count);
        memories += g.memories * p.count;
        memory_bits += g.memory_bits * p.count;
        depth = depth.max(g.depth);
    }
    let figures = GenericFigures {
        nand2_eq: nand2_eq(&cells),
        flip_flops: stat::count_where(&cells, |k| k.contains("DFF")),
        memories,
        memory_bits,
        depth,
        cells,
    };
    Ok((figures, made))
}

/// The `synth_ecp5` cells of a composed `top`; the list names what this call made.
pub fn ecp5_synth(
    flow: &Flow,
    netlist: &Netlist,
    top: &str,
    digest: &str,
) -> Result<(ecp5::Ecp5Synth, Vec<String>)> {
    let mut made = Vec::new();
    let mut cells = glue_cells(flow, netlist, top, digest, "ecp5", &mut made)?;
    for p in parts(netlist, top) {
        let (s, e) = ecp5::synthesis(flow, netlist, &p.module, &netlist.digest(&p.module))?;
        if e.built {
            made.push(format!("ecp5 synth of {}", p.module));
        }
        add_cells(&mut cells, &s.cells, p.count);
    }
    Ok((ecp5::Ecp5Synth::of(cells), made))
}

/// The ECP5 figures of a composed `top` (never placed).
pub fn ecp5(
    flow: &Flow,
    netlist: &Netlist,
    top: &str,
    digest: &str,
) -> Result<(ecp5::Ecp5Figures, Vec<String>)> {
    let (synth, made) = ecp5_synth(flow, netlist, top, digest)?;
    let (fits, mut verdict) = ecp5::fit(&synth);
    if fits {
        verdict += " (by the sum of its parts; a composed module is not placed)";
    }
    Ok((ecp5::Ecp5Figures::unplaced(synth, fits, verdict), made))
}

/// The iCE40 figures of a composed `top`: ruled out by its composed ECP5
/// mapping when that is far over an HX8K, else its glue's and its parts'
/// `synth_ice40` cells summed (never placed).
pub fn ice40(
    flow: &Flow,
    netlist: &Netlist,
    top: &str,
    digest: &str,
    ecp5_synth: Option<&ecp5::Ecp5Synth>,
) -> Result<(Ice40Figures, Vec<String>)> {
    if let Some(skip) = ecp5_synth.and_then(|e| super::ice40::rules_out(e.lut4, e.lutram)) {
        return Ok((skip, Vec::new()));
    }
    let mut made = Vec::new();
    let mut cells = glue_cells(flow, netlist, top, digest, "ice40", &mut made)?;
    for p in parts(netlist, top) {
        let (f, e) = super::ice40::synthesis(flow, netlist, &p.module, &netlist.digest(&p.module))?;
        if e.built {
            made.push(format!("ice40 synth of {}", p.module));
        }
        add_cells(&mut cells, &f.cells, p.count);
    }
    let mut figures = Ice40Figures::of(cells, &header_ports(&netlist.modules[top].text));
    if figures.fits {
        figures.verdict += " (by the sum of its parts; a composed module is not placed)";
    }
    Ok((figures, made))
}
