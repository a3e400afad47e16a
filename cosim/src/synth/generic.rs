//! The generic (ASIC-style) flow: Yosys `synth`, memories kept as memories,
//! flip-flops legalized onto one plain D flip-flop, `abc` onto a fixed gate
//! set (SPEC 14.1).

use super::sources::Netlist;
use super::{stat, Flow};
use crate::cache::CacheKey;
use crate::error::{io_err, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// The cache kind of generic results.
pub const KIND: &str = "synth-generic";

/// The gate set `abc -g` maps onto (NOT is always part of it).
pub const GATES: &str = "AND,NAND,OR,NOR,XOR,XNOR,ANDNOT,ORNOT,MUX";

/// NAND2-equivalent weight of each generic cell (SPEC 14.1).
pub const NAND2_WEIGHTS: &[(&str, f64)] = &[
    ("$_NOT_", 0.67),
    ("$_NAND_", 1.0),
    ("$_NOR_", 1.0),
    ("$_AND_", 1.33),
    ("$_OR_", 1.33),
    ("$_ANDNOT_", 1.33),
    ("$_ORNOT_", 1.33),
    ("$_XOR_", 2.0),
    ("$_XNOR_", 2.0),
    ("$_MUX_", 2.33),
    ("$_DFF_P_", 5.67),
];

/// What the generic flow reports for one module.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct GenericFigures {
    /// Cells by type after `abc` (memories as `$mem_v2`).
    pub cells: BTreeMap<String, u64>,
    /// Sum of cells times their NAND2 weights (memories excluded).
    pub nand2_eq: f64,
    /// Flip-flops (`$_DFF_P_`).
    pub flip_flops: u64,
    /// Memories left as memories.
    pub memories: u64,
    /// Their bits (words times width).
    pub memory_bits: u64,
    /// Gates on the longest path between flip-flops, memories and ports.
    pub depth: u64,
}

/// The NAND2-equivalent count of `cells`.
pub fn nand2_eq(cells: &BTreeMap<String, u64>) -> f64 {
    let sum: f64 = cells
        .iter()
        .map(|(k, n)| {
            let w = NAND2_WEIGHTS
                .iter()
                .find(|(c, _)| c == k)
                .map_or(0.0, |c| c.1);
            w * *n as f64
        })
        .sum();
    (sum * 100.0).round() / 100.0
}

pub(super) fn read_files(files: &[std::path::PathBuf]) -> String {
    files
        .iter()
        .map(|f| format!("read_verilog {}\n", f.display()))
        .collect()
}

fn script(reads: &str, top: &str, cut: &str) -> String {
    format!(
        "{reads}hierarchy -check -top {top}\n\
         synth -flatten -top {top} -run begin:fine\n\
         opt -fast -full\n\
         techmap\n\
         opt -fast\n\
         dfflegalize -cell $_DFF_P_ x\n\
         abc -g {GATES}\n\
         opt_clean\n\
         tee -q -o stat.txt stat\n\
         tee -q -o mem.txt dump t:$mem_v2\n\
         delete t:$mem_v2\n\
         {cut}\
         tee -q -o ltp.txt ltp -noff\n",
    )
}

/// Runs the generic flow on `top` read by the Yosys commands `reads`
/// (its whole tree, or its own file with its parts as black boxes) and
/// writes `figures.json` into `dir`; `cut` (Yosys commands) runs just
/// before `ltp` (a composed top deletes its black boxes there, so that its
/// depth counts its own gates only).
pub(super) fn build(flow: &Flow, reads: &str, top: &str, dir: &Path, cut: &str) -> Result<()> {
    (flow.progress)(&format!("{top}: generic: yosys synth + abc"));
    let ys = dir.join("generic.ys");
    std::fs::write(&ys, script(reads, top, cut)).map_err(io_err(&ys))?;
    flow.yosys_script(dir, "generic.ys", "yosys.log")?;
    let read = |f: &str| std::fs::read_to_string(dir.join(f)).map_err(io_err(dir.join(f)));
    let cells = stat::cell_counts(&read("stat.txt")?);
    let (memories, memory_bits) = stat::memory_bits(&read("mem.txt")?);
    let figures = GenericFigures {
        nand2_eq: nand2_eq(&cells),
        flip_flops: stat::count_where(&cells, |k| k.contains("DFF")),
        memories,
        memory_bits,
        depth: stat::ltp_length(&read("ltp.txt")?).unwrap_or(0),
        cells,
    };
    super::write_json(&dir.join("figures.json"), &figures)
}

/// The generic figures of `top`, from the cache or freshly made; the flag
/// is true when this call made them.
pub fn generic(
    flow: &Flow,
    netlist: &Netlist,
    top: &str,
    digest: &str,
) -> Result<(GenericFigures, bool)> {
    let mut key = CacheKey::new();
    key.add("digest", digest.as_bytes())
        .add("yosys", flow.yosys.version.as_bytes())
        .add("gates", GATES.as_bytes());
    let entry = crate::cache::get_or_build(&flow.cache_root, KIND, top, &key.finish(), |d| {
        build(flow, &read_files(&netlist.files(top)), top, d, "")?;
        super::write_meta(d, top, digest, &flow.yosys.version)
    })?;
    Ok((
        super::read_json(&entry.dir.join("figures.json"))?,
        entry.built,
    ))
}
