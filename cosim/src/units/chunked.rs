//! Long runs of a multi-stream unit in chunks (SPEC 10.1): the stimulus of
//! [`CHUNK`] merges is generated, run and dropped before the next chunk's,
//! on one simulator built once, so memory stays bounded whatever the count
//! (100,000 per-node merges held at once took 15-24 GB). Each chunk starts
//! from reset with its own stall seed (`seed ^ chunk`); the run stops after
//! the first chunk that fails, with its VCD.

use std::path::PathBuf;
use std::time::Duration;

use golden::bits::Bits;
use golden::layout::Layout;
use golden::vectors::streams::{MergeBeats, UnitPorts};

use crate::design::Design;
use crate::error::Result;
use crate::icarus::IcarusMultiBatch;
use crate::tb::{
    run_multi_with_vcd_on_failure, BenchConfig, Hang, MultiReport, Progress, PulseWatch,
    StreamBeats, Transaction,
};

use super::multi_stream::{
    flip_bit0, status_failure, stepped_engines, ModuleEngine, ModuleMismatch, RunConfig,
};

/// Merges of stimulus held at a time on one simulator.
pub const CHUNK: usize = 10_000;

/// Merges as a multi-stream unit's streams (the merging module's, the
/// merger's), and where each merge's beats start.
#[derive(Clone, Debug)]
pub struct UnitStreams {
    /// Input streams; the first is `cfg` (one beat per merge).
    pub inputs: Vec<StreamBeats>,
    /// Output streams.
    pub outputs: Vec<StreamBeats>,
    /// Per output stream (same order), the index of each merge's first
    /// expected beat: merge `n`'s beats are `starts[s][n]..starts[s][n + 1]`.
    pub starts: Vec<Vec<usize>>,
}

impl UnitStreams {
    /// The streams of `merges` (each merge's beats in `ports` order), named
    /// by `ports`, merge after merge.
    pub fn from_merges(ports: &UnitPorts, merges: &[MergeBeats]) -> Result<UnitStreams> {
        let side = |streams: &[Layout], pick: &dyn Fn(&MergeBeats) -> &Vec<Vec<Bits>>| {
            streams
                .iter()
                .enumerate()
                .map(|(i, s)| {
                    let beats = merges
                        .iter()
                        .flat_map(|m| pick(m).get(i).into_iter().flatten())
                        .map(|b| vec![b.clone()])
                        .collect();
                    Ok(StreamBeats {
                        name: s.name().to_string(),
                        beats,
                    })
                })
                .collect::<Result<Vec<_>>>()
        };
        let starts = (0..ports.outputs.len())
            .map(|i| {
                let mut at = 0;
                let mut v: Vec<usize> = merges
                    .iter()
                    .map(|m| {
                        let start = at;
                        at += m.outputs.get(i).map_or(0, Vec::len);
                        start
                    })
                    .collect();
                v.push(at);
                v
            })
            .collect();
        Ok(UnitStreams {
            inputs: side(&ports.inputs, &|m| &m.inputs)?,
            outputs: side(&ports.outputs, &|m| &m.outputs)?,
            starts,
        })
    }

    /// Flips bit 0 of merge `merge`'s first expected beat on output stream
    /// `stream` (the test hook), if it has one.
    pub fn flip_first(&mut self, stream: usize, merge: usize) -> Result<()> {
        let at = self.starts[stream][merge];
        if at < self.starts[stream][merge + 1] {
            flip_bit0(&mut self.outputs[stream].beats[at][0])?;
        }
        Ok(())
    }

    /// Merges in the stimulus (each merge's expected beats start somewhere:
    /// a unit may take several command beats per merge).
    pub fn merges(&self) -> usize {
        self.starts.first().map_or(0, |s| s.len().saturating_sub(1))
    }

    /// The merge (0-based, in these streams) that output beat `beat` of
    /// output stream `stream` belongs to.
    pub fn merge_of(&self, stream: usize, beat: usize) -> usize {
        self.starts[stream]
            .partition_point(|&s| s <= beat)
            .saturating_sub(1)
    }
}

/// Decodes an (expected, got) pair of output stream `name` field by field.
pub type PairDecoder<'a> =
    dyn Fn(&str, &Transaction, &Transaction) -> Vec<(String, String, String)> + 'a;

/// What every chunk run so far measured.
#[derive(Clone, Debug)]
pub struct ChunkTotals {
    /// Merges run (all of them, or up to the end of the failing chunk).
    pub merges: usize,
    /// The first cycle each watched status output was high, in the first
    /// chunk (stepped engines only).
    pub first_high: Vec<(String, Option<u64>)>,
    /// Chunks run.
    pub chunks: usize,
    /// Cycles over every chunk (each chunk starts from reset).
    pub cycles: u64,
    /// `cfg` beats accepted: merges started.
    pub cfg_accepted: u64,
    /// Beats accepted on the other input streams.
    pub data_beats_in: u64,
    /// Beats out on every output stream.
    pub beats_out: u64,
    /// Beats out per output stream, by name (first seen order).
    pub received: Vec<(String, u64)>,
    /// Output beats that differed.
    pub mismatches: u64,
    /// Expected output beats that never came (failing chunk).
    pub missing: Vec<(String, usize)>,
    /// The first mismatch, decoded; its merge counted over the whole run.
    pub first_mismatch: Option<ModuleMismatch>,
    /// The watchdog's finding in the failing chunk.
    pub hang: Option<Hang>,
    /// Cycles `done` was high (one per merge expected).
    pub done_pulses: u64,
    /// `idle` high in the last cycle of every chunk.
    pub idle_at_end: bool,
    /// VCD of the cycles around the first failure.
    pub vcd: Option<PathBuf>,
    /// Wall time of the benches (stimulus generation, the Verilator build
    /// and the Icarus compile excluded).
    pub wall: Duration,
    /// Wall time of generating the golden stimulus.
    pub golden_wall: Duration,
}

impl Default for ChunkTotals {
    fn default() -> Self {
        ChunkTotals {
            merges: 0,
            first_high: Vec::new(),
            chunks: 0,
            cycles: 0,
            cfg_accepted: 0,
            data_beats_in: 0,
            beats_out: 0,
            received: Vec::new(),
            mismatches: 0,
            missing: Vec::new(),
            first_mismatch: None,
            hang: None,
            done_pulses: 0,
            // Vacuously true until a chunk ends with `idle` low.
            idle_at_end: true,
            vcd: None,
            wall: Duration::ZERO,
            golden_wall: Duration::ZERO,
        }
    }
}

impl ChunkTotals {
    /// Every beat matched, none missing, nothing hung, one `done` pulse
    /// per merge, and the unit idle at the end of every chunk.
    pub fn passed(&self) -> bool {
        self.mismatches == 0
            && self.hang.is_none()
            && self.missing.iter().all(|m| m.1 == 0)
            && self.status_failure().is_none()
    }

    /// What the status outputs got wrong, if anything.
    pub fn status_failure(&self) -> Option<String> {
        status_failure(self.done_pulses, self.merges, self.idle_at_end, "a chunk")
    }

    /// Adds one chunk of `n` merges; returns whether the chunk failed.
    pub(crate) fn add(
        &mut self,
        n: usize,
        chunk: &UnitStreams,
        report: &MultiReport,
        watch: &PulseWatch,
        decode: &PairDecoder,
    ) -> bool {
        let pulse = |name: &str| watch.counts.iter().find(|p| p.0 == name).map_or(0, |p| p.1);
        self.done_pulses += pulse("done");
        if self.chunks == 0 {
            self.first_high = watch.first_high.clone();
        }
        self.idle_at_end &= watch.at_end.iter().any(|p| p.0 == "idle" && p.1);
        self.cycles += report.cycles;
        self.cfg_accepted += report.sent.first().map_or(0, |cfg| cfg.1);
        self.data_beats_in += report.sent.iter().skip(1).map(|s| s.1).sum::<u64>();
        self.beats_out += report.received.iter().map(|s| s.1).sum::<u64>();
        for (name, n) in &report.received {
            match self.received.iter_mut().find(|r| &r.0 == name) {
                Some(r) => r.1 += n,
                None => self.received.push((name.clone(), *n)),
            }
        }
        self.mismatches += report.mismatches;
        self.wall += report.wall;
        if self.first_mismatch.is_none() {
            self.first_mismatch = report.first_mismatch.as_ref().map(|(stream, m)| {
                let s = chunk
                    .outputs
                    .iter()
                    .position(|o| &o.name == stream)
                    .unwrap_or(0);
                ModuleMismatch {
                    stream: stream.clone(),
                    beat: m.output_index,
                    merge: self.merges + chunk.merge_of(s, m.output_index as usize),
                    cycle: m.cycle,
                    fields: decode(stream, &m.expected, &m.got),
                }
            });
        }
        self.merges += n;
        self.chunks += 1;
        let failed = !report.passed() || pulse("done") != n as u64;
        if failed {
            self.missing = report.missing.clone();
            self.hang = report.hang.clone();
        }
        // A failure's waveform, or the window asked of the first chunk.
        if failed || self.vcd.is_none() {
            self.vcd = report.vcd.clone().or(self.vcd.take());
        }
        failed
    }
}

/// Cycles without a handshake at any port before a chunked run is called
/// hung. The merger top's record writer takes a merge's level beats into
/// its buffers before it writes a record, with no port moving meanwhile:
/// the hard merges' leaf flood (1,290 leaves at the default with
/// `leaf_bits` 8) keeps it busy for more than 1,000 cycles.
pub const WATCHDOG_CYCLES: u64 = 10_000;

/// The bench of chunk `chunks` (0-based) of a run of `config`: its own
/// stall seed (`seed ^ chunk`).
pub(crate) fn chunk_bench(config: &RunConfig, chunks: usize) -> BenchConfig {
    BenchConfig {
        seed: config.seed ^ chunks as u64,
        watchdog_cycles: WATCHDOG_CYCLES,
        in_stall: config.stall,
        out_stall: config.stall,
        stream_stalls: config.stream_stalls.clone(),
        stop_on_mismatch: false,
        vcd_path: config.vcd_path.clone(),
        vcd_radius: config.vcd_radius,
        wave_scope: config.wave_scope.clone(),
        // Cycles count from a chunk's start: the window is the first chunk's.
        wave_window: config.wave_window.filter(|_| chunks == 0),
        ..BenchConfig::default()
    }
}

/// How the simulator runs: stepped from Rust (IR, Verilator) or a whole
/// chunk inside one `vvp` run (Icarus).
enum Sim {
    Stepped {
        module: rtl_gen::Module,
        design: Design,
        kind: ModuleEngine,
    },
    Batch(Box<IcarusMultiBatch>),
}

/// One simulator of a multi-stream unit, built once, run chunk after chunk.
pub struct ChunkedSim {
    sim: Sim,
    patched: bool,
    /// The status outputs whose pulses a chunk counts.
    pulses: &'static [&'static str],
}

/// Runs `streams` (merges from elsewhere: a vectors file) through the
/// unit `module` (its Verilog in `design`) on `engine` as one chunk, its
/// streams named as `streams` names them: every output beat compared,
/// `done` counted, `idle` checked.
pub fn run_streams(
    module: rtl_gen::Module,
    design: Design,
    engine: ModuleEngine,
    streams: &UnitStreams,
    config: &RunConfig,
    decode: &PairDecoder,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<ChunkTotals> {
    let names = |s: &[StreamBeats]| s.iter().map(|s| s.name.clone()).collect::<Vec<_>>();
    let (i, o) = (names(&streams.inputs), names(&streams.outputs));
    let i: Vec<&str> = i.iter().map(String::as_str).collect();
    let o: Vec<&str> = o.iter().map(String::as_str).collect();
    let sim = ChunkedSim::new(module, design, engine, &i, &o, false)?;
    let mut totals = ChunkTotals::default();
    sim.run_chunk(
        &mut totals,
        streams.merges(),
        streams,
        config,
        decode,
        progress,
    )?;
    Ok(totals)
}

impl ChunkedSim {
    /// The unit `module` (its Verilog in `design`) on `engine`, with the
    /// named input and output streams; `patched`: the Verilog was broken on
    /// purpose (Verilator then builds with tracing at once).
    pub fn new(
        module: rtl_gen::Module,
        design: Design,
        engine: ModuleEngine,
        inputs: &[&str],
        outputs: &[&str],
        patched: bool,
    ) -> Result<Self> {
        let pulses = &super::merge_module::PULSES;
        Self::watching(module, design, engine, (inputs, outputs), patched, pulses)
    }

    /// [`Self::new`] counting the pulses of the status outputs `pulses`
    /// (among them `done` and `idle`).
    pub fn watching(
        module: rtl_gen::Module,
        design: Design,
        engine: ModuleEngine,
        (inputs, outputs): (&[&str], &[&str]),
        patched: bool,
        pulses: &'static [&'static str],
    ) -> Result<Self> {
        let sim = match engine {
            ModuleEngine::Iverilog => Sim::Batch(Box::new(IcarusMultiBatch::new_watching(
                &design, inputs, outputs, pulses,
            )?)),
            kind => Sim::Stepped {
                module,
                design,
                kind,
            },
        };
        Ok(ChunkedSim {
            sim,
            patched,
            pulses,
        })
    }

    /// Runs one chunk of `n` merges and adds it to `totals`; returns
    /// whether it failed. `progress` gets (merges whose chunk is done or
    /// whose outputs arrived so far, cycle over the run).
    pub fn run_chunk(
        &self,
        totals: &mut ChunkTotals,
        n: usize,
        chunk: &UnitStreams,
        config: &RunConfig,
        decode: &PairDecoder,
        progress: &mut dyn FnMut(u64, u64),
    ) -> Result<bool> {
        let bench = chunk_bench(config, totals.chunks);
        let (before, cycles_before) = (totals.merges as u64, totals.cycles);
        let (report, watch) = match &self.sim {
            Sim::Stepped {
                module,
                design,
                kind,
            } => {
                let mut make = stepped_engines(module, design, *kind, self.patched, config.waves());
                let mut on_progress = |p: Progress| {
                    // Merges by the share of expected beats arrived.
                    let total = p.expected_outputs.max(1);
                    let share = p.outputs.min(total) as f64 / total as f64;
                    progress(before + (share * n as f64) as u64, cycles_before + p.cycle);
                };
                run_multi_with_vcd_on_failure(
                    &mut make,
                    &chunk.inputs,
                    &chunk.outputs,
                    &bench,
                    self.pulses,
                    &mut on_progress,
                )?
            }
            Sim::Batch(batch) => {
                let r = batch.run(&chunk.inputs, &chunk.outputs, &bench)?;
                let watch = PulseWatch {
                    counts: r.pulses,
                    at_end: r.pulses_at_end,
                    first_high: Vec::new(),
                };
                (r.report, watch)
            }
        };
        let failed = totals.add(n, chunk, &report, &watch, decode);
        progress(totals.merges as u64, totals.cycles);
        Ok(failed)
    }
}
