//! The study's stages in order, each behind a progress bar, and the report.

use std::time::Instant;

use crate::progress::Progress;
use golden::merge::MergeMode;
use golden::Params;
use serde::Serialize;

use super::distance::{at_distance, distances, DistanceRow};
use super::inputs::{cases, Case};
use super::merge::{modes, sweep_modes, ModeRow};
use super::sweep::{measure, Prepared, Row};
use super::synth::{ns_per_merge, synth_command, synth_figures, SynthFigures};
use super::{markdown, plots, rtl, table, Args, Machine};
use crate::report::{emit, CmdResult};

/// Everything `study.json` holds.
#[derive(Serialize)]
pub struct Study {
    pub command: String,
    pub seed: u64,
    pub full: bool,
    pub machine: Machine,
    pub default_max_lod: u8,
    pub default_quant_bits: u8,
    pub max_lod: Vec<u8>,
    pub quant_bits: Vec<u8>,
    pub rays: usize,
    pub distance_rays: usize,
    pub repeats: usize,
    pub cases: Vec<CaseInfo>,
    pub rows: Vec<Row>,
    pub modes: Vec<ModeRow>,
    pub distance_case: String,
    pub distance: Vec<DistanceRow>,
    /// Why the RTL or synthesis columns are empty, where they are.
    pub notes: Vec<String>,
    pub outputs: Vec<String>,
    pub wall_seconds: f64,
}

#[derive(Serialize)]
pub struct CaseInfo {
    pub name: String,
    pub source: String,
    pub triangles: u64,
}

const QS: [u8; 10] = [0, 1, 2, 3, 4, 6, 8, 10, 12, 16];

fn bar(len: u64, quiet: bool, stage: &str) -> Progress {
    Progress::new(len, quiet, stage)
}

fn params(d: u8, q: u8) -> Result<Params, String> {
    let p = Params::default();
    Params::new(d, q, p.index_bits, p.hier_bits)
        .map_err(|e| format!("--max-lod {d} --quant-bits {q}: {e}"))
}

pub fn main(a: Args) -> CmdResult {
    let started = Instant::now();
    let quiet = a.json;
    let machine = Machine::here();
    let ds = a.max_lod.clone().unwrap_or_else(|| {
        if a.full {
            (8..=31).collect()
        } else {
            vec![8, 12, 16, 20, 24]
        }
    });
    let qs = a.quant_bits.clone().unwrap_or_else(|| QS.to_vec());
    let rays = a.rays.unwrap_or(if a.full { 10_000 } else { 2000 });
    let distance_rays = a.distance_rays.unwrap_or(if a.full { 2000 } else { 300 });
    let repeats = a.repeats.unwrap_or(if a.full { 7 } else { 3 });
    if ds.is_empty() || qs.is_empty() || rays == 0 || distance_rays == 0 || repeats == 0 {
        return Err(
            "--max-lod, --quant-bits, --rays, --distance-rays and --repeats: expected at least one"
                .into(),
        );
    }
    let configs: Vec<Params> = ds
        .iter()
        .flat_map(|&d| qs.iter().map(move |&q| (d, q)))
        .map(|(d, q)| params(d, q))
        .collect::<Result<_, _>>()?;
    let given = a.rtl_configs.iter().flatten();
    if let Some((d, q)) = given
        .into_iter()
        .find(|(d, q)| !ds.contains(d) || !qs.contains(q))
    {
        return Err(format!(
            "--rtl-configs {d}:{q}: not in the sweep (--max-lod {ds:?}, --quant-bits {qs:?})"
        ));
    }
    let cases = cases(&a.inputs, a.seed, quiet)?;
    let default = Params::default();
    let mode = MergeMode::default();

    // Stage 1: Q x D over every case.
    let mut pb = bar((cases.len() * configs.len()) as u64, quiet, "sweep");
    let mut rows = Vec::new();
    for case in &cases {
        let prep = Prepared::new(case, rays, a.seed);
        let mut prev: Option<(Params, golden::store::Hierarchy)> = None;
        for &p in &configs {
            pb.set_message(format!("{} {}", case.name, p.tag()));
            let coarser = prev
                .as_ref()
                .filter(|(q, _)| q.max_lod == p.max_lod && q.quant_bits < p.quant_bits)
                .map(|(_, h)| h);
            let (row, h) = measure(case, &prep, p, repeats, mode, coarser)?;
            rows.push(row);
            prev = Some((p, h));
            pb.inc(1);
        }
    }
    pb.finish_and_clear();

    // Stage 2: merging modes at the default configuration.
    let ms = modes(a.full);
    let mut pb = bar((cases.len() * ms.len()) as u64, quiet, "modes");
    let mut mode_rows = Vec::new();
    for case in &cases {
        mode_rows.extend(sweep_modes(
            &case.name,
            &case.mesh,
            default,
            &ms,
            repeats,
            &mut || pb.inc(1),
        )?);
    }
    pb.finish_and_clear();

    // Stage 3: hit error against distance, on the first case, at the
    // default configuration and at D = 31 (the finest translation grid).
    let dcase: &Case = &cases[0];
    let dlist = distances();
    let dparams = [default, params(31, default.quant_bits)?];
    let mut pb = bar((dlist.len() * dparams.len()) as u64, quiet, "distance");
    let mut drows = Vec::new();
    for p in dparams {
        for &d in &dlist {
            pb.set_message(format!("{} at {d:e}, D {}", dcase.name, p.max_lod));
            drows.extend(at_distance(dcase, p, d, distance_rays, a.seed)?);
            pb.inc(1);
        }
    }
    pb.finish_and_clear();

    let mut notes = Vec::new();
    run_rtl(&a, &mut rows, &ds, &qs, quiet, &mut notes)?;
    attach_synth(&a, &mut rows, &mut notes);

    let mut study = Study {
        command: std::iter::once("hiermerge".to_string())
            .chain(std::env::args().skip(1))
            .collect::<Vec<_>>()
            .join(" "),
        seed: a.seed,
        full: a.full,
        machine,
        default_max_lod: default.max_lod,
        default_quant_bits: default.quant_bits,
        max_lod: ds,
        quant_bits: qs,
        rays,
        distance_rays,
        repeats,
        cases: cases
            .iter()
            .map(|c| CaseInfo {
                name: c.name.clone(),
                source: c.source.clone(),
                triangles: c.mesh.triangles.len() as u64,
            })
            .collect(),
        rows,
        modes: mode_rows,
        distance_case: dcase.name.clone(),
        distance: drows,
        notes,
        outputs: Vec::new(),
        wall_seconds: 0.0,
    };
    golden::output::check_destination(&a.out, true)?;
    std::fs::create_dir_all(&a.out).map_err(|e| format!("{}: {e}", a.out.display()))?;
    let mut pb = bar(plots::COUNT as u64, quiet, "plots");
    let mut outputs = plots::write_all(&study, &a.out, &mut || pb.inc(1))?;
    pb.finish_and_clear();
    study.wall_seconds = started.elapsed().as_secs_f64();
    outputs.extend(table::write_files(&study, &a.out)?);
    outputs.push(markdown::write(&study, &a.out, &outputs)?);
    study.outputs = outputs;
    // study.json last, so it lists every output, itself included.
    table::write_json(&study, &a.out)?;
    emit(a.json, &study, table::print)
}

/// The RTL configurations (those the sweep has): the default D with Q = 0
/// and the default Q, and D = 24 at the default Q (each a Verilator build
/// when not cached: about a minute on a loaded 2-core machine); --full: D
/// in {8, 16, 24, 31} x Q in {0, 4, 8, 16}.
fn rtl_configs(full: bool, ds: &[u8], qs: &[u8]) -> Vec<(u8, u8)> {
    let p = Params::default();
    let wanted: Vec<(u8, u8)> = if full {
        [8, 16, 24, 31]
            .iter()
            .flat_map(|&d| [0, 4, 8, 16].map(|q| (d, q)))
            .collect()
    } else {
        vec![
            (p.max_lod, 0),
            (p.max_lod, p.quant_bits),
            (24, p.quant_bits),
        ]
    };
    wanted
        .into_iter()
        .filter(|(d, q)| ds.contains(d) && qs.contains(q))
        .collect()
}

fn run_rtl(
    a: &Args,
    rows: &mut [Row],
    ds: &[u8],
    qs: &[u8],
    quiet: bool,
    notes: &mut Vec<String>,
) -> Result<(), String> {
    if a.no_rtl {
        notes.push("RTL cycles: not measured (--no-rtl)".into());
        return Ok(());
    }
    let configs = match &a.rtl_configs {
        Some(c) => c.clone(),
        None => rtl_configs(a.full, ds, qs),
    };

    let mut pb = bar(configs.len() as u64, quiet, "rtl");
    let dir = tempfile::tempdir().map_err(|e| format!("temporary directory: {e}"))?;
    for (d, q) in configs {
        pb.set_message(format!("D{d} Q{q}: Verilator"));
        let p = params(d, q)?;
        let sub = dir.path().join(p.tag());
        std::fs::create_dir_all(&sub).map_err(|e| format!("{}: {e}", sub.display()))?;
        let f = rtl::measure(p, a.seed, a.rtl_merges, a.rtl_records, &sub, &mut |m, _| {
            pb.set_message(format!("D{d} Q{q}: {m} merges"))
        });
        // A configuration the RTL cannot run is a note, not the end of the study.
        let f = match f {
            Ok(f) => f,
            Err(e) => {
                notes.push(format!("RTL at D{d} Q{q}: not measured: {e}"));
                pb.inc(1);
                continue;
            }
        };
        for r in rows
            .iter_mut()
            .filter(|r| r.max_lod == d && r.quant_bits == q)
        {
            r.rtl = Some(f.clone());
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    notes.push(format!(
        "RTL cycles: measured on Verilator at the configurations that have them ({} merges, {} translation records each, seed {}, no stalls); the others: not measured",
        a.rtl_merges, a.rtl_records, a.seed
    ));
    Ok(())
}

fn attach_synth(a: &Args, rows: &mut [Row], notes: &mut Vec<String>) {
    if a.no_synth {
        notes.push("area, Fmax, ns/merge: not measured (--no-synth)".into());
        return;
    }
    // One lookup per configuration (rows of every case share them).
    let mut seen: std::collections::BTreeMap<(u8, u8), Option<SynthFigures>> =
        std::collections::BTreeMap::new();
    for r in rows.iter_mut() {
        let figures = seen
            .entry((r.max_lod, r.quant_bits))
            .or_insert_with(|| {
                let unit = params(r.max_lod, r.quant_bits).and_then(rtl::merger_config);
                let found = unit.as_ref().map_err(String::clone).and_then(synth_figures);
                match (unit.as_ref().map_err(String::clone), found) {
                    (_, Ok(Some(f))) => {
                        notes.push(format!(
                            "synthesis at D{} Q{}: read from the cache ({}; {}{})",
                            r.max_lod,
                            r.quant_bits,
                            f.module,
                            f.tools,
                            match (&f.fmax_of, f.fmax_bound) {
                                (Some(m), true) => format!("; the top is not placed ({}), Fmax is the lowest of its parts placed alone ({m}), an upper bound, so ns/merge is a lower bound", f.ecp5_verdict.as_deref().unwrap_or("no ECP5 figures")),
                                (None, _) => "; Fmax and ns/merge not measured: not every part has ECP5 figures (run it with `--target ecp5`)".into(),
                                _ => String::new(),
                            }
                        ));
                        Some(f)
                    }
                    (Ok(unit), Ok(None)) => {
                        notes.push(format!(
                            "area, Fmax, ns/merge at D{} Q{}: not measured (run `{}`)",
                            r.max_lod,
                            r.quant_bits,
                            synth_command(unit)
                        ));
                        None
                    }
                    (Err(e), _) | (Ok(_), Err(e)) => {
                        notes.push(format!(
                            "area, Fmax, ns/merge at D{} Q{}: not measured: {e}",
                            r.max_lod, r.quant_bits
                        ));
                        None
                    }
                }
            })
            .clone();
        r.synth = figures;
        r.ns_per_merge = ns_per_merge(r.rtl.as_ref().map(|f| f.cycles_per_merge), r.synth.as_ref());
    }
}
