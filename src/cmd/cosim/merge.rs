//! `--unit merge-module`: the merging module as one unit (seeded merges, every
//! stream with its own stall pattern), or its S614 merge-level stage alone.

use std::path::Path;

use cosim::from_rtl::design_from_module;
use cosim::units::{merge_level, merge_module};
use golden::merge::merge_module::MergeDesign;

use super::command_line::reproduce;
use super::report::{chunked_failure, finish_report, Counts, FieldReport, MismatchReport, Report};
use super::{bar, bench_config, count, factory, module_engine, vcd_path, Args, VCD_RADIUS};

/// `--stage merge-level`: levels through the S614 stage, generated or from
/// a vectors file.
pub(super) fn run_level(
    a: &Args,
    design: &MergeDesign,
    flip: Option<usize>,
    dir: &Path,
) -> Result<Report, String> {
    let levels = match &a.vectors {
        Some(p) => merge_level::read_levels(p, design)?,
        None => {
            let count = count(a)?;
            merge_level::generate_levels(design, a.seed, count).map_err(|e| e.to_string())?
        }
    };
    let vectors = merge_level::bench_vectors(&levels, flip).map_err(|e| e.to_string())?;
    let module = merge_level::merge_level_module(&design.params);
    cosim::waves::check_scope(&module, a.wave_scope.as_deref()).map_err(|e| e.to_string())?;
    let cdesign = design_from_module(&module, dir).map_err(|e| e.to_string())?;
    let mut make = factory(a, &module, &cdesign)?;
    let expected_outputs: u64 = levels.iter().map(|l| l.outputs.len() as u64).sum();
    super::no_stream_stalls(&a.stall_stream, "--stage merge-level")?;
    let config = merge_level::RunConfig {
        seed: a.seed,
        stall: super::stalls(a)?,
        reproduce: Some(reproduce(a, flip)?),
        wave_scope: a.wave_scope.clone(),
        wave_window: a.wave_window,
    };
    let pb = bar(expected_outputs, a.json);
    let report = merge_level::run_with_vcd_on_mismatch(
        &mut make,
        &design.params,
        &vectors,
        &config,
        Some(vcd_path(a, "merge")),
        VCD_RADIUS,
        &mut |outputs, cycle| {
            pb.set_position(outputs);
            pb.set_message(format!("cycle {cycle}"));
        },
    )
    .map_err(|e| e.to_string())?;
    pb.finish_and_clear();
    // The level (transaction) of an input beat.
    let level_of = |beat: u64| -> u64 {
        let mut end = 0u64;
        for (n, l) in levels.iter().enumerate() {
            end += l.inputs.len() as u64;
            if beat < end {
                return n as u64;
            }
        }
        levels.len() as u64
    };
    let passed = report.passed();
    if passed {
        super::bins::merge_level(&cdesign.top);
    }
    let mut first = report.first_mismatch.as_ref().map(|m| MismatchReport {
        transaction: level_of(m.input_id),
        stream: None,
        beat: None,
        kind: merge_level::STAGE.to_string(),
        cycle: m.cycle,
        seed: a.seed,
        what: format!("output beat {} differs", m.output_index),
        fields: m
            .fields
            .iter()
            .map(|f| FieldReport {
                name: f.name.clone(),
                expected: f.expected.clone(),
                got: f.got.clone(),
                differs: f.differs(),
            })
            .collect(),
    });
    if first.is_none() && !passed {
        first = Some(MismatchReport {
            transaction: level_of(report.inputs_sent),
            stream: None,
            beat: None,
            kind: merge_level::STAGE.to_string(),
            cycle: report.hang.as_ref().map_or(report.cycles, |h| h.cycle),
            seed: a.seed,
            what: match &report.hang {
                Some(h) => format!("no handshake for {} cycles", h.idle_cycles),
                None => format!("outputs lost or duplicated: {}", report.accounting),
            },
            fields: Vec::new(),
        });
    }
    let counts = Counts {
        transactions: levels.len() as u64,
        records: report.inputs_sent,
        nodes: report.outputs_received,
        mismatches: report.mismatches,
        cycles: report.cycles,
        wall_seconds: report.wall.as_secs_f64(),
    };
    finish_report(
        a,
        merge_level::STAGE,
        flip,
        counts,
        first,
        report.vcd.as_ref(),
    )
}

/// `--unit merge-module`: seeded merges through the merging module, every stream
/// with its own stall pattern, 10,000 merges at a time.
pub(super) fn run_module(
    a: &Args,
    design: &MergeDesign,
    flip: Option<usize>,
    dir: &Path,
) -> Result<Report, String> {
    let engine = module_engine(a.engine)?;
    if let Some(path) = &a.vectors {
        return replay_module(a, design, flip, path, engine, dir);
    }
    let count = count(a)?;
    let run = merge_module::LongRun {
        count,
        seed: a.seed,
        most_voxels: merge_module::DEFAULT_MOST_VOXELS,
        flip_expected: flip,
        chunk: cosim::units::chunked::CHUNK,
        bench: bench_config(a, merge_module::STAGE)?,
    };
    if !a.json {
        eprintln!(
            "running {count} merges on {} in chunks of {}",
            a.engine.name(),
            cosim::units::chunked::CHUNK
        );
    }
    let pb = bar(count as u64, a.json);
    let o = merge_module::run_chunked(design, engine, &run, dir, &mut |merges, cycle| {
        pb.set_position(merges);
        pb.set_message(format!("cycle {cycle}"));
    });
    pb.finish_and_clear();
    let o = o.map_err(|e| e.to_string())?;
    module_report(a, design, flip, &o)
}

/// `--unit merge-module --vectors FILE` of whole merges (`hiermerge vectors
/// --unit merge-module`): the file's streams through the module, one chunk.
fn replay_module(
    a: &Args,
    design: &MergeDesign,
    flip: Option<usize>,
    path: &Path,
    engine: merge_module::ModuleEngine,
    dir: &Path,
) -> Result<Report, String> {
    let e = |e: cosim::CosimError| e.to_string();
    let mut streams = merge_module::streams_from_vectors(design, path).map_err(e)?;
    if let Some(n) = flip.filter(|&n| n < streams.merges()) {
        streams.flip_first(0, n).map_err(e)?;
    }
    let bench = bench_config(a, merge_module::STAGE)?;
    let pb = bar(streams.merges() as u64, a.json);
    let o = merge_module::run_streams(design, &streams, engine, &bench, dir, &mut |m, cycle| {
        pb.set_position(m);
        pb.set_message(format!("cycle {cycle}"));
    });
    pb.finish_and_clear();
    module_report(a, design, flip, &o.map_err(e)?)
}

/// The report of a module run (generated or replayed).
fn module_report(
    a: &Args,
    design: &MergeDesign,
    flip: Option<usize>,
    o: &cosim::units::chunked::ChunkTotals,
) -> Result<Report, String> {
    let stage = merge_module::STAGE;
    let first = chunked_failure(stage, a.seed, o);
    if o.passed() {
        let top = merge_module::merge_module(design).name();
        super::bins::merge_module(&design.mode, &top, design.inputs, o.merges as u64);
    }
    let counts = Counts {
        transactions: o.merges as u64,
        records: o.data_beats_in,
        nodes: o.beats_out,
        mismatches: o.mismatches,
        cycles: o.cycles,
        wall_seconds: o.wall.as_secs_f64(),
    };
    finish_report(a, stage, flip, counts, first, o.vcd.as_ref())
}
