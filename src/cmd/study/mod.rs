//! `hiermerge study`: what accuracy costs in time (issue 18, SPEC 13).
//!
//! Sweeps Q and D over the cases (the shared meshes and a generated scene,
//! or the user's files), the merging modes, the translation level and the
//! number format of positions; measures box looseness, false box hits and
//! hit errors against an independent binary64 reference (accuracy) beside
//! node and primitive tests, sizes, software times and RTL cycles (cost);
//! writes a terminal table, `study.json`, `study.csv`, plots (PNG, SVG) and
//! `study.md`. One file per stage: `inputs`, `sweep`, `merge`, `distance`
//! (with `compare`), `rtl`, `synth` (the hook for area and Fmax), and the
//! outputs `table`, `plots`, `markdown`.

mod chart;
mod compare;
mod distance;
mod inputs;
mod markdown;
mod merge;
mod plots;
mod rtl;
mod run;
mod sweep;
mod synth;
mod table;

use std::path::PathBuf;

use serde::Serialize;

pub use run::main;

/// `hiermerge study [INPUT...]`.
#[derive(clap::Args, Clone, Debug)]
pub struct Args {
    /// Meshes (OBJ, PLY) or scene files (JSON); default: the shared bunny
    /// and teapot and a generated scene.
    inputs: Vec<PathBuf>,
    /// Folder of study.json, study.csv, study.md and the plots.
    #[arg(long, default_value = "out/study")]
    out: PathBuf,
    #[arg(long, default_value_t = 1, value_parser = super::common::unsigned::<u64>)]
    seed: u64,
    /// Sweep everything: D = 8..=31, more modes, rays, repeats and RTL configurations.
    #[arg(long)]
    full: bool,
    /// Skip the synthesis columns (area, Fmax, ns per merge).
    #[arg(long = "no-synth")]
    no_synth: bool,
    /// Skip the RTL co-simulation (cycles per merge and per translated record).
    #[arg(long = "no-rtl")]
    no_rtl: bool,
    /// Q values to sweep, comma-separated (default 0,1,2,3,4,6,8,10,12,16).
    #[arg(long = "quant-bits", value_delimiter = ',')]
    quant_bits: Option<Vec<u8>>,
    /// D values to sweep, comma-separated (default 8,12,16,20,24; --full 8..=31).
    #[arg(long = "max-lod", value_delimiter = ',')]
    max_lod: Option<Vec<u8>>,
    /// Rays per case and configuration (default 2000; --full 10000).
    #[arg(long)]
    rays: Option<usize>,
    /// Rays per distance and format (default 300; --full 2000).
    #[arg(long = "distance-rays")]
    distance_rays: Option<usize>,
    /// Timed repeats; times are their median (default 3; --full 7).
    #[arg(long)]
    repeats: Option<usize>,
    /// RTL configurations as D:Q, comma-separated (default: 16:0, 16:8
    /// and 24:8 where the sweep has them; --full: {8,16,24,31} x {0,4,8,16}).
    #[arg(long = "rtl-configs", value_delimiter = ',', value_parser = parse_config)]
    rtl_configs: Option<Vec<(u8, u8)>>,
    /// Merges per RTL configuration (default 100).
    #[arg(long = "rtl-merges", default_value_t = 100)]
    rtl_merges: usize,
    /// Translation-unit records per RTL configuration (default 1000).
    #[arg(long = "rtl-records", default_value_t = 1000)]
    rtl_records: usize,
    /// Print one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

fn parse_config(s: &str) -> Result<(u8, u8), String> {
    let (d, q) = s
        .split_once(':')
        .ok_or_else(|| format!("`{s}`: expected D:Q, e.g. 16:8"))?;
    let d = d.trim().parse().map_err(|e| format!("`{s}`: D: {e}"))?;
    let q = q.trim().parse().map_err(|e| format!("`{s}`: Q: {e}"))?;
    Ok((d, q))
}

/// The machine the times were taken on.
#[derive(Serialize, Clone, Debug)]
pub struct Machine {
    pub cpu: String,
    pub cores: usize,
    /// /proc/loadavg's 1-minute load when the study started.
    pub load_at_start: Option<f64>,
    pub os: String,
}

impl Machine {
    /// The load at the start, or "unknown".
    pub fn load(&self) -> String {
        self.load_at_start
            .map_or("unknown".into(), |l| format!("{l:.2}"))
    }

    pub fn here() -> Machine {
        let cpu = std::fs::read_to_string("/proc/cpuinfo")
            .ok()
            .and_then(|s| {
                s.lines()
                    .find(|l| l.starts_with("model name"))
                    .and_then(|l| l.split_once(':'))
                    .map(|(_, v)| v.trim().to_string())
            })
            .unwrap_or_else(|| "unknown".into());
        let load_at_start = std::fs::read_to_string("/proc/loadavg")
            .ok()
            .and_then(|s| s.split_whitespace().next().and_then(|v| v.parse().ok()));
        Machine {
            cpu,
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            load_at_start,
            os: format!("{} {}", std::env::consts::OS, std::env::consts::ARCH),
        }
    }
}
