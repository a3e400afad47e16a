//! The merging module as one unit (`rtl_gen::merge::merge_module_unit`,
//! SPEC 8.10) against the golden `golden::merge::merge_module` transactions, bit for
//! bit on both output streams, with independent seeded stalls on every
//! stream: `cfg`, `in0`..`in{k-1}` in, `report`, `out` out. A transaction
//! is one merge (its `cfg` beat, count pass, choice, merge pass).
//!
//! Engines: the IR simulator and Verilator through
//! [`crate::tb::run_multi_stream_bench`]; Icarus through the multi-stream
//! batch ([`crate::icarus::IcarusMultiBatch`], the whole bench inside one
//! `vvp` run, same stall patterns). Every engine also counts the unit's
//! `done` pulses (one per merge, refused or not) and checks `idle` is high
//! at the end; on a mismatch or hang every engine reruns with a VCD of the
//! cycles around the first failure when a VCD path is given.

use std::path::{Path, PathBuf};
use std::time::Duration;

use golden::layout::Layout;
use golden::merge::merge_module::MergeDesign;
use golden::translate::stimulus::SplitMix64;
use golden::vectors::streams::{module_merge, module_ports, module_report};

use crate::design::Design;
use crate::error::{CosimError, Result};
use crate::icarus::IcarusMultiBatch;
use crate::tb::{
    run_multi_with_vcd_on_failure, FieldDecoder, Hang, MultiReport, Progress, PulseWatch,
    Transaction,
};

pub use super::chunked::UnitStreams;
use super::chunked::{ChunkTotals, ChunkedSim};
use super::multi_stream::{apply_patch, export_checks, export_streams, stepped_engines};
pub use super::multi_stream::{
    beat_decoder, decode_fields, decoded_pair, status_failure, ModuleEngine, ModuleMismatch,
    RunConfig, VerilogPatch, PULSES,
};
use crate::export_tb::ExportSpec;

/// The stage name `hiermerge cosim --unit merge-module` reports for this unit.
pub const STAGE: &str = "merge_module";

pub use golden::vectors::streams::{DEFAULT_MOST_VOXELS, PER_NODE_DEPTH};

/// The unit under test.
pub fn merge_module(d: &MergeDesign) -> rtl_gen::Module {
    rtl_gen::merge::merge_module_unit(d)
}

/// Names of the unit's input streams: `cfg`, `in0`..`in{k-1}`.
pub fn input_names(d: &MergeDesign) -> Vec<String> {
    std::iter::once("cfg".to_string())
        .chain((0..d.inputs).map(|i| format!("in{i}")))
        .collect()
}

/// Names of the unit's output streams.
pub const OUTPUT_NAMES: [&str; 2] = ["report", "out"];

fn golden_err(what: impl std::fmt::Display) -> CosimError {
    CosimError::Design {
        what: format!("golden merging module: {what}"),
    }
}

/// `count` random merges for `d` from `seed` (`random_top_transaction`,
/// levels of at most `most_voxels` voxels; per-node configurations:
/// `random_per_node_case`, trees [`PER_NODE_DEPTH`] LODs deep). `flip_expected = Some(n)`: bit
/// 0 of merge `n`'s first expected `report` beat is flipped (the test hook).
pub fn generate_streams(
    d: &MergeDesign,
    seed: u64,
    count: usize,
    most_voxels: usize,
    flip_expected: Option<usize>,
) -> Result<UnitStreams> {
    generate_streams_from(&mut SplitMix64(seed), d, count, most_voxels, flip_expected)
}

/// [`generate_streams`] drawing from `rng`, so chunks of one long run
/// continue one random sequence.
fn generate_streams_from(
    rng: &mut SplitMix64,
    d: &MergeDesign,
    count: usize,
    most_voxels: usize,
    flip_expected: Option<usize>,
) -> Result<UnitStreams> {
    d.validate().map_err(golden_err)?;
    let merges = (0..count)
        .map(|_| module_merge(rng, d, most_voxels).map_err(golden_err))
        .collect::<Result<Vec<_>>>()?;
    let mut streams = UnitStreams::from_merges(&module_ports(d), &merges)?;
    if let Some(n) = flip_expected {
        streams.flip_first(0, n)?;
    }
    Ok(streams)
}

/// The merges of a vectors file (`hiermerge vectors --unit merge-module`,
/// golden's `read_module_vectors`) for the merging module `d`, as its
/// streams.
pub fn streams_from_vectors(d: &MergeDesign, path: &Path) -> Result<UnitStreams> {
    let merges = golden::vectors::stream_file::read_module_vectors(path, d).map_err(|e| {
        CosimError::Design {
            what: e.to_string(),
        }
    })?;
    UnitStreams::from_merges(&module_ports(d), &merges)
}

/// Runs `streams` (merges from elsewhere: [`streams_from_vectors`])
/// through the unit `d` on `engine` as one chunk, the Verilog written to
/// `dir`: every output beat compared, `done` counted, `idle` checked.
/// `progress` gets (merges, cycle).
pub fn run_streams(
    d: &MergeDesign,
    streams: &UnitStreams,
    engine: ModuleEngine,
    config: &RunConfig,
    dir: &Path,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<ChunkTotals> {
    let module = merge_module(d);
    crate::waves::check_scope(&module, config.wave_scope.as_deref())?;
    let design: Design = crate::from_rtl::design_from_module(&module, dir)?;
    let decode = |stream: &str, e: &Transaction, g: &Transaction| {
        decoded_pair(&*decoder_of(d, stream), e, g)
    };
    super::chunked::run_streams(module, design, engine, streams, config, &decode, progress)
}

/// The `report` stream's layout (golden's `module_report`: `TopLayout`,
/// per-node configurations `PerNodeLayout`).
pub fn report_fields(d: &MergeDesign) -> Layout {
    module_report(d)
}

/// Decodes a `report` beat by field name ([`report_fields`]).
pub fn report_decoder(d: &MergeDesign) -> Box<FieldDecoder> {
    beat_decoder(module_report(d))
}

/// The exported testbench of `d` (`hiermerge export-tb --unit merge-module`):
/// `count` random merges from `seed` as [`run`] drives them (levels of at
/// most [`DEFAULT_MOST_VOXELS`] voxels), the Verilog written to `rtl`.
pub fn export_spec(
    d: &MergeDesign,
    seed: u64,
    count: usize,
    stalls: crate::tb::Stalls,
    rtl: &Path,
) -> Result<ExportSpec> {
    let streams = generate_streams(d, seed, count, DEFAULT_MOST_VOXELS, None)?;
    let design = crate::from_rtl::design_from_module(&merge_module(d), rtl)?;
    let (report, out) = (
        report_fields(d),
        super::merge_level::output_fields(&d.params),
    );
    let (inputs, outputs) = export_streams(&streams, |name| match name {
        "report" => report.clone(),
        _ => out.clone(),
    });
    Ok(ExportSpec {
        design,
        transaction: "merge".into(),
        transactions: count as u64,
        inputs,
        outputs,
        checks: export_checks(count),
        seed,
        stalls,
        stream_stalls: crate::tb::StreamStalls::default(),
        command: String::new(),
        store: None,
    })
}

/// The decoder of output stream `name` (`report` or `out`).
pub fn decoder_of(d: &MergeDesign, name: &str) -> Box<FieldDecoder> {
    match name {
        "report" => report_decoder(d),
        _ => super::merge_level::decoder(&d.params),
    }
}

/// What a run measured.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// The bench's report (counts per stream, hang, wall time).
    pub report: MultiReport,
    /// Merges run.
    pub merges: usize,
    /// Beats the unit accepted on the `in*` streams.
    pub data_beats_in: u64,
    /// Beats out on `report` and `out`.
    pub beats_out: u64,
    /// The first mismatch, decoded with the stream's fields.
    pub first_mismatch: Option<ModuleMismatch>,
    /// Cycles `done` was high (one per merge expected).
    pub done_pulses: u64,
    /// `idle` high in the last cycle.
    pub idle_at_end: bool,
    /// VCD of the cycles around the first failure (with `RunConfig::vcd_path`).
    pub vcd: Option<PathBuf>,
    /// Wall time of the bench (the Verilator build and the Icarus compile excluded).
    pub wall: Duration,
}

impl Outcome {
    /// Every beat matched, none missing, nothing hung, one `done` pulse
    /// per merge, and the unit idle at the end.
    pub fn passed(&self) -> bool {
        self.report.passed() && self.status_failure().is_none()
    }

    /// What the status outputs got wrong, if anything: `done` not pulsed
    /// once per merge, or `idle` low at the end.
    pub fn status_failure(&self) -> Option<String> {
        status_failure(self.done_pulses, self.merges, self.idle_at_end, "the run")
    }

    /// Input beats over all `in*` streams per cycle.
    pub fn records_per_cycle(&self) -> f64 {
        self.data_beats_in as f64 / self.report.cycles.max(1) as f64
    }

    /// The watchdog's finding, if it fired.
    pub fn hang(&self) -> Option<&Hang> {
        self.report.hang.as_ref()
    }
}

/// Runs `streams` through the unit `d` on `engine`, the Verilog written to
/// `dir`. Mismatches are counted to the end of the run on every engine
/// (`stop_on_mismatch` off), so counts agree between engines. `progress` is
/// called every few thousand cycles on the IR and Verilator engines (the
/// Icarus batch reports only at its end).
pub fn run(
    d: &MergeDesign,
    streams: &UnitStreams,
    engine: ModuleEngine,
    config: &RunConfig,
    dir: &Path,
    progress: &mut dyn FnMut(Progress),
) -> Result<Outcome> {
    let module = merge_module(d);
    crate::waves::check_scope(&module, config.wave_scope.as_deref())?;
    let design: Design = crate::from_rtl::design_from_module(&module, dir)?;
    if let Some(patch) = &config.verilog_patch {
        apply_patch(&design, patch, engine)?;
    }
    // One chunk, the first: the seed and the window as asked.
    let bench = super::chunked::chunk_bench(config, 0);
    let (report, watch) = match engine {
        ModuleEngine::Ir | ModuleEngine::Verilator => {
            let patched = config.verilog_patch.is_some();
            let mut make = stepped_engines(&module, &design, engine, patched, config.waves());
            run_multi_with_vcd_on_failure(
                &mut make,
                &streams.inputs,
                &streams.outputs,
                &bench,
                &PULSES,
                progress,
            )?
        }
        ModuleEngine::Iverilog => {
            let names = input_names(d);
            let names: Vec<&str> = names.iter().map(String::as_str).collect();
            let batch = IcarusMultiBatch::new_watching(&design, &names, &OUTPUT_NAMES, &PULSES)?;
            let r = batch.run(&streams.inputs, &streams.outputs, &bench)?;
            let watch = PulseWatch {
                counts: r.pulses,
                at_end: r.pulses_at_end,
                first_high: Vec::new(),
            };
            (r.report, watch)
        }
    };
    let pulse = |name: &str| watch.counts.iter().find(|p| p.0 == name).map_or(0, |p| p.1);
    let idle_at_end = watch.at_end.iter().any(|p| p.0 == "idle" && p.1);
    let wall = report.wall;
    let first_mismatch = report.first_mismatch.as_ref().map(|(stream, m)| {
        let s = OUTPUT_NAMES.iter().position(|n| n == stream).unwrap_or(0);
        ModuleMismatch {
            stream: stream.clone(),
            beat: m.output_index,
            merge: streams.merge_of(s, m.output_index as usize),
            cycle: m.cycle,
            fields: decoded_pair(&*decoder_of(d, stream), &m.expected, &m.got),
        }
    });
    Ok(Outcome {
        merges: streams.merges(),
        // Accepted, not offered: a hung run moved fewer.
        data_beats_in: report.sent.iter().skip(1).map(|s| s.1).sum(),
        beats_out: report.received.iter().map(|r| r.1).sum(),
        done_pulses: pulse("done"),
        idle_at_end,
        vcd: report.vcd.clone(),
        report,
        first_mismatch,
        wall,
    })
}

/// What a long run asks for: `count` random merges from `seed` (levels of
/// at most `most_voxels` voxels), the bench settings, and the test hook
/// (bit 0 of merge `flip_expected`'s first expected `report` beat flipped).
#[derive(Clone, Debug)]
pub struct LongRun {
    /// Merges to run.
    pub count: usize,
    /// Seed of the merges (the stalls: `bench.seed`).
    pub seed: u64,
    /// Most voxels of a random level.
    pub most_voxels: usize,
    /// The test hook.
    pub flip_expected: Option<usize>,
    /// Merges per chunk ([`super::chunked::CHUNK`]; smaller in tests of the chunking).
    pub chunk: usize,
    /// Stalls, VCD, Verilog patch.
    pub bench: RunConfig,
}

/// Runs `run.count` random merges through the unit `d` on `engine`, the
/// Verilog written to `dir`, `run.chunk` merges at a time on one simulator
/// (memory bounded at any count); stops after the first chunk that fails.
/// `progress` gets (merges done, cycle).
pub fn run_chunked(
    d: &MergeDesign,
    engine: ModuleEngine,
    run: &LongRun,
    dir: &Path,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<ChunkTotals> {
    let module = merge_module(d);
    crate::waves::check_scope(&module, run.bench.wave_scope.as_deref())?;
    let design: Design = crate::from_rtl::design_from_module(&module, dir)?;
    if let Some(patch) = &run.bench.verilog_patch {
        apply_patch(&design, patch, engine)?;
    }
    let names = input_names(d);
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let patched = run.bench.verilog_patch.is_some();
    let sim = ChunkedSim::new(module, design, engine, &names, &OUTPUT_NAMES, patched)?;
    let decode = |stream: &str, e: &Transaction, g: &Transaction| {
        decoded_pair(&*decoder_of(d, stream), e, g)
    };
    let mut rng = SplitMix64(run.seed);
    let mut totals = ChunkTotals::default();
    while totals.merges < run.count {
        let n = run.chunk.max(1).min(run.count - totals.merges);
        let t = std::time::Instant::now();
        let flip = run
            .flip_expected
            .and_then(|f| f.checked_sub(totals.merges))
            .filter(|&f| f < n);
        let streams = generate_streams_from(&mut rng, d, n, run.most_voxels, flip)?;
        totals.golden_wall += t.elapsed();
        if sim.run_chunk(&mut totals, n, &streams, &run.bench, &decode, progress)? {
            break;
        }
    }
    Ok(totals)
}

#[cfg(test)]
mod tests {
    use super::*;
    use golden::merge::MergeMode;
    use golden::params::Params;

    fn small() -> MergeDesign {
        MergeDesign {
            params: Params::new(8, 0, 12, 3).unwrap(),
            inputs: 2,
            mode: MergeMode::Overlap { num: 1, den: 2 },
            ..MergeDesign::default()
        }
    }

    fn long_run(count: usize, chunk: usize, flip_expected: Option<usize>) -> LongRun {
        LongRun {
            count,
            seed: 9,
            most_voxels: 4,
            flip_expected,
            chunk,
            bench: RunConfig {
                seed: 9,
                stall: crate::tb::Stalls::Coin(0.2),
                ..RunConfig::default()
            },
        }
    }

    /// One chunk is the unchunked run: the same merges, the same stalls,
    /// the same cycles.
    #[test]
    fn one_chunk_is_the_plain_run() {
        let (d, dir) = (small(), tempfile::tempdir().unwrap());
        let r = long_run(12, 12, None);
        let chunked = run_chunked(&d, ModuleEngine::Ir, &r, dir.path(), &mut |_, _| {}).unwrap();
        let streams = generate_streams(&d, r.seed, r.count, r.most_voxels, None).unwrap();
        let plain = run(
            &d,
            &streams,
            ModuleEngine::Ir,
            &r.bench,
            dir.path(),
            &mut |_| {},
        )
        .unwrap();
        assert!(chunked.passed() && plain.passed());
        assert_eq!(chunked.chunks, 1);
        assert_eq!(chunked.cycles, plain.report.cycles);
        assert_eq!(chunked.data_beats_in, plain.data_beats_in);
        assert_eq!(chunked.beats_out, plain.beats_out);
    }

    /// Chunks continue one random sequence and each starts from reset: the
    /// beats of three chunks are the beats of the same merges in one run,
    /// every merge pulses `done`, and a flipped expectation in the third
    /// chunk is reported at its merge over the whole run, after which the
    /// run stops.
    #[test]
    fn chunks_cover_every_merge_and_place_a_failure() {
        let (d, dir) = (small(), tempfile::tempdir().unwrap());
        let whole = long_run(25, 25, None);
        let whole = run_chunked(&d, ModuleEngine::Ir, &whole, dir.path(), &mut |_, _| {}).unwrap();
        let mut seen = Vec::new();
        let split = long_run(25, 10, None);
        let split = run_chunked(&d, ModuleEngine::Ir, &split, dir.path(), &mut |m, _| {
            seen.push(m)
        })
        .unwrap();
        assert!(whole.passed() && split.passed(), "{split:?}");
        assert_eq!((split.chunks, split.merges, split.done_pulses), (3, 25, 25));
        assert_eq!(split.cfg_accepted, 25);
        assert_eq!(split.data_beats_in, whole.data_beats_in);
        assert_eq!(split.beats_out, whole.beats_out);
        assert_eq!(seen.last(), Some(&25));

        let broken = long_run(40, 10, Some(23));
        let broken =
            run_chunked(&d, ModuleEngine::Ir, &broken, dir.path(), &mut |_, _| {}).unwrap();
        assert!(!broken.passed());
        assert_eq!(
            (broken.chunks, broken.merges),
            (3, 30),
            "stops after the failing chunk"
        );
        let m = broken.first_mismatch.expect("the flipped beat");
        assert_eq!((m.stream.as_str(), m.merge), ("report", 23));
    }
}
