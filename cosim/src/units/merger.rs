//! The hierarchy merger (`rtl_gen::merge::hierarchy_merger_unit`, S610-S618
//! as one top, SPEC 8.15) against
//! `golden::merge::merger::merger_transaction`, bit for bit on every
//! out stream, with independent seeded stalls on every stream. A
//! transaction is one merge: its `cfg` beat in, its `header` beat out.
//!
//! The store's responses are precomputed from golden and presented as
//! ordinary input streams (every unit raises `resp_ready` only while a
//! request is outstanding), so the same stimulus runs on the IR simulator,
//! Verilator ([`crate::tb::run_multi_stream_bench`]) and Icarus (the
//! multi-stream batch, one `vvp` run per chunk). Long runs go in chunks of
//! [`CHUNK`] merges, each chunk generated, run and dropped before the next,
//! so memory stays bounded whatever the count.

use std::path::Path;

use golden::layout::Layout;
use golden::merge::merger::store_port::StoreWords;
use golden::merge::merger::{MergerTransaction, ModulePass};
use golden::merge::per_node::unit::PerNodeReport;
use golden::merge::MergeMode;
use golden::translate::stimulus::SplitMix64;
pub use golden::vectors::streams::Merges;
use golden::vectors::streams::{
    merger_beats, merger_input_names, merger_layout, merger_output_names, merger_ports,
    merger_stream, random_merger_merge, random_merger_merge_of,
};
use rtl_gen::merge::MergerConfig;

use crate::design::Design;
use crate::error::{CosimError, Result};
use crate::ledger::StimulusDigest;
use crate::tb::{FieldDecoder, Transaction};

pub use super::chunked::{ChunkTotals, CHUNK};
use super::chunked::{ChunkedSim, UnitStreams};
pub use super::multi_stream::ModuleEngine as MergerEngine;
pub use super::multi_stream::ModuleMismatch as MergerMismatch;
use super::multi_stream::{apply_patch, beat_decoder, decoded_pair, export_checks, export_streams};
pub use super::multi_stream::{RunConfig as ModuleRunConfig, VerilogPatch};
use crate::export_tb::ExportSpec;

pub(crate) mod shared;
pub mod store_port;
pub use shared::StoreOutcome;

/// The stage name `hiermerge cosim --unit merger` reports.
pub const STAGE: &str = "hierarchy_merger";

pub use golden::vectors::streams::{MOST_DRAWS, MOST_TRIANGLES};

/// The status outputs whose pulses a run counts.
pub const PULSES: [&str; 2] = ["done", "idle"];

fn golden_err(what: impl std::fmt::Display) -> CosimError {
    CosimError::Design {
        what: format!("golden hierarchy merger: {what}"),
    }
}

/// What a list of merges exercised.
#[derive(Clone, Default, Debug, PartialEq, Eq)]
pub struct MergeStats {
    /// Merges.
    pub merges: usize,
    /// Merges the merging module refused (no candidate LOD).
    pub refused: usize,
    /// Node records written (`nodes` beats).
    pub records: u64,
    /// References written (`refs` beats).
    pub refs: u64,
    /// Merges with leaves above the merging level.
    pub leaves_above: usize,
    /// Merges whose leaves overflow a leaf FIFO (`leaf_overflow`).
    pub leaf_overflows: usize,
    /// Merges that materialized references (`w_ref_req` beats).
    pub materialized: usize,
    /// Merges whose output has several roots.
    pub several_roots: usize,
    /// Merges with a fetcher error in the header.
    pub fetch_errors: usize,
    /// Beats into the merging module's `in*` (fetcher out, over all inputs).
    pub module_in: u64,
    /// Per-node merges of more than one pass.
    pub multi_pass: usize,
    /// Per-node decisions that descended.
    pub descents: u64,
    /// Merges per number of inputs merged (1..=k).
    pub by_inputs: std::collections::BTreeMap<usize, usize>,
    /// Merges per fetcher error code in the header (`fetch_err`, not 0).
    pub fetch_codes: std::collections::BTreeMap<u64, usize>,
    /// Merges per writer error code in the header (`writer_err`, not 0).
    pub writer_errs: std::collections::BTreeMap<u64, usize>,
}

impl MergeStats {
    /// Adds `other`'s counts to these.
    pub fn add(&mut self, other: &MergeStats) {
        self.merges += other.merges;
        self.refused += other.refused;
        self.records += other.records;
        self.refs += other.refs;
        self.leaves_above += other.leaves_above;
        self.leaf_overflows += other.leaf_overflows;
        self.materialized += other.materialized;
        self.several_roots += other.several_roots;
        self.fetch_errors += other.fetch_errors;
        self.module_in += other.module_in;
        self.multi_pass += other.multi_pass;
        self.descents += other.descents;
        for (n, m) in &other.by_inputs {
            *self.by_inputs.entry(*n).or_default() += m;
        }
        for (c, m) in &other.fetch_codes {
            *self.fetch_codes.entry(*c).or_default() += m;
        }
        for (c, m) in &other.writer_errs {
            *self.writer_errs.entry(*c).or_default() += m;
        }
    }
}

/// Merges as the merger's streams, and what they exercise.
#[derive(Clone, Debug)]
pub struct MergerStreams {
    /// Inputs: `cfg`, then per fetcher `f{i}_node_resp`, `f{i}_ref_resp`,
    /// `f{i}_cref_resp`, then (per-node mode) every `f{i}_probe_resp`,
    /// then `w_ref_resp`. Outputs: `report`, per fetcher `f{i}_node_req`,
    /// `f{i}_ref_req`, `f{i}_cref_req`, then (per-node mode) every
    /// `f{i}_probe_req`, then `w_ref_req`, `nodes`, `refs`, `header`
    /// (always last).
    pub streams: UnitStreams,
    /// What the merges exercised.
    pub stats: MergeStats,
}

/// Whether `c`'s units share one store port (`StorePort::Shared`): its
/// bench answers `store_req` from a store model ([`run`]).
pub fn is_shared(c: &MergerConfig) -> bool {
    c.sizes.store_port != golden::merge::merger::store_port::StorePort::PerUnit
}

/// Refuses a shared-port merger where only precomputed streams run (the
/// shared port's reads come in an order that depends on timing, so its
/// store's answers cannot be streams fixed in advance).
fn per_unit_only(c: &MergerConfig, what: &str) -> Result<()> {
    match is_shared(c) {
        true => Err(shared_refused(what)),
        false => Ok(()),
    }
}

fn shared_refused(what: &str) -> CosimError {
    CosimError::Unsupported {
        what: format!(
            "{what} of a merger with a shared store port (its store answers reads as they come: \
             `cosim --unit merger --store-port shared` and `run --store-port shared` run it)"
        ),
    }
}

/// Whether `c` merges per node (its fetchers have a probe port, its
/// `report` is the per-node module's).
pub fn is_per_node(c: &MergerConfig) -> bool {
    matches!(c.design.mode, MergeMode::PerNode { .. })
}

/// The fields of output stream `stream`'s beats, from golden's layouts
/// (`golden::vectors::streams::merger_stream`): `report` the merging
/// module's (`TopLayout`, or `per_node`'s `PerNodeLayout` in per-node
/// mode), a fetcher's `*_req` an index, `w_ref_req` and `refs` a reference
/// (`RefLayout`), `nodes` a node record (`NodeLayout`), `header` the
/// writer's header and the merger's flags; None for a name that is no
/// output stream of the merger.
pub fn output_fields(c: &MergerConfig, stream: &str) -> Option<Layout> {
    let ml = merger_layout(&c.design, &c.sizes).ok()?;
    let per_node = is_per_node(c);
    if !merger_output_names(c.design.inputs, per_node)
        .iter()
        .any(|n| n == stream)
    {
        return None;
    }
    merger_stream(&ml, &c.design, stream)
}

/// Decodes a beat of output stream `stream` field by field
/// ([`output_fields`]; an unknown stream shows its raw bits as `data`).
pub fn decoder_of(c: &MergerConfig, stream: &str) -> Box<FieldDecoder> {
    beat_decoder(output_fields(c, stream).unwrap_or_else(|| Layout::new(stream)))
}

/// What the merges `txs` exercise.
pub fn merge_stats(txs: &[MergerTransaction]) -> MergeStats {
    let mut stats = MergeStats::default();
    for tx in txs {
        *stats.by_inputs.entry(tx.fetch.len()).or_default() += 1;
        let mut refused = tx.chosen.is_none();
        if let ModulePass::PerNode(pn) = &tx.module {
            refused = pn.passes == 0;
            stats.multi_pass += (pn.passes > 1) as usize;
            stats.descents += pn
                .reports
                .iter()
                .filter(|r| matches!(r, PerNodeReport::Decision { descend: true, .. }))
                .count() as u64;
        }
        if tx.header.fetch_err != 0 {
            *stats.fetch_codes.entry(tx.header.fetch_err).or_default() += 1;
        }
        if tx.writer.header.err != 0 {
            *stats.writer_errs.entry(tx.writer.header.err).or_default() += 1;
        }
        let w = &tx.writer;
        stats.module_in += tx.fetch.iter().map(|f| f.out.len() as u64).sum::<u64>();
        stats.merges += 1;
        stats.refused += refused as usize;
        stats.fetch_errors += (tx.header.fetch_err != 0) as usize;
        stats.records += w.nodes.len() as u64;
        stats.refs += w.refs.len() as u64;
        stats.leaves_above += !tx.leaves.is_empty() as usize;
        stats.leaf_overflows += tx.header.leaf_overflow as usize;
        stats.materialized += !w.ref_reqs.is_empty() as usize;
        stats.several_roots += (w.header.roots > 1) as usize;
    }
    stats
}

/// The streams of `txs` for the merger `c`, and what they exercise.
pub fn merger_streams(c: &MergerConfig, txs: &[MergerTransaction]) -> Result<MergerStreams> {
    let ml = merger_layout(&c.design, &c.sizes).map_err(golden_err)?;
    let ports = merger_ports(&c.design, &c.sizes).map_err(golden_err)?;
    let merges = txs
        .iter()
        .map(|tx| merger_beats(&c.design, &ml, tx).map_err(golden_err))
        .collect::<Result<Vec<_>>>()?;
    let stats = merge_stats(txs);
    Ok(MergerStreams {
        streams: UnitStreams::from_merges(&ports, &merges)?,
        stats,
    })
}

/// A random merge for the merger `c` (golden's `random_merger_merge`:
/// 1..=k soups of 1..=[`MOST_TRIANGLES`] triangles, drawn again while the
/// leaves overflow the leaf FIFOs).
pub fn random_merge(rng: &mut SplitMix64, c: &MergerConfig) -> Result<MergerTransaction> {
    random_merger_merge(rng, &c.design, c.sizes).map_err(|what| CosimError::Design { what })
}

/// How one run is driven.
#[derive(Clone, Debug, Default)]
pub struct RunConfig {
    /// As the merging module's runs: seed (of the merges too), stall, VCD
    /// and the Verilog patch hook.
    pub bench: ModuleRunConfig,
    /// Merges to run.
    pub count: usize,
    /// Which merges (the hard ones count towards `count`).
    pub merges: Merges,
    /// The test hook: bit 0 of merge `n`'s expected `header` beat (its
    /// `out_id`) flipped.
    pub flip_expected: Option<usize>,
    /// A shared store port only: the store answers a read this many clocks
    /// after taking it, at the earliest (0 counts as 1).
    pub store_latency: u64,
}

/// What a run measured (over every chunk run): the bench's totals and
/// what the merges exercised.
#[derive(Clone, Debug, Default)]
pub struct Outcome {
    /// Merges, chunks, cycles, beats, mismatches, status pulses, VCD.
    pub totals: ChunkTotals,
    /// What the merges exercised.
    pub stats: MergeStats,
    /// The simulated netlist's digest (10.2; after any patch).
    pub netlist_sha256: String,
    /// The stimulus digest of the chunks generated (10.2).
    pub stimulus_sha256: String,
    /// The run stopped after a failing chunk, before `count` merges.
    pub stopped_early: bool,
    /// A shared store port only: what the store saw.
    pub store: Option<StoreOutcome>,
}

impl Outcome {
    /// Every beat matched, none missing, nothing hung, one `done` pulse
    /// per merge, and the unit idle at the end of every chunk.
    pub fn passed(&self) -> bool {
        self.totals.passed() && self.store.as_ref().is_none_or(|s| s.failure.is_none())
    }

    /// Records written (`nodes` beats) per cycle.
    pub fn records_per_cycle(&self) -> f64 {
        self.stats.records as f64 / self.totals.cycles.max(1) as f64
    }
}

/// Flips bit 0 of merge `merge`'s expected `header` beat (its `out_id`):
/// the test hook, of generated runs and of replayed files.
pub fn flip_header(streams: &mut UnitStreams, merge: usize) -> Result<()> {
    // `header` is the last output stream; every merge has its one beat.
    streams.flip_first(streams.outputs.len() - 1, merge)
}

/// The merges a run sends, chunk by chunk: the hard ones first (for
/// [`Merges::Hard`]), then random ones drawn from the seed.
struct Draw {
    rng: SplitMix64,
    kind: Merges,
    hard: std::vec::IntoIter<MergerTransaction>,
}

impl Draw {
    fn new(c: &MergerConfig, seed: u64, kind: Merges) -> Result<Draw> {
        let hard = match kind {
            Merges::Random => Vec::new(),
            Merges::Hard => {
                golden::vectors::hard_merges::hard_merges(&c.design, c.sizes)
                    .map_err(|what| CosimError::Design { what })?
                    .merges
            }
        };
        Ok(Draw {
            rng: SplitMix64(seed),
            kind,
            hard: hard.into_iter(),
        })
    }

    fn next(&mut self, c: &MergerConfig) -> Result<MergerTransaction> {
        match self.hard.next() {
            Some(tx) => Ok(tx),
            None => random_merger_merge_of(&mut self.rng, &c.design, c.sizes, self.kind)
                .map_err(|what| CosimError::Design { what }),
        }
    }
}

/// The next chunk of `n` merges of `draw`, as the merger's streams; merge
/// `flip` (counted in the chunk) gets its expected `header` beat's bit 0
/// flipped.
fn next_chunk(
    draw: &mut Draw,
    c: &MergerConfig,
    n: usize,
    flip: Option<usize>,
) -> Result<MergerStreams> {
    let txs = (0..n).map(|_| draw.next(c)).collect::<Result<Vec<_>>>()?;
    let mut streams = merger_streams(c, &txs)?;
    if let Some(f) = flip {
        flip_header(&mut streams.streams, f)?;
    }
    Ok(streams)
}

/// The exported testbench of `c` (`hiermerge export-tb --unit merger`):
/// `count` random merges from `seed` as [`run`] draws them (one chunk),
/// the Verilog written to `rtl`. A shared store port's reads are answered
/// by the testbench's store model after `store_latency` clocks, from the
/// words golden's units read.
pub fn export_spec(
    c: &MergerConfig,
    seed: u64,
    count: usize,
    stalls: crate::tb::Stalls,
    store_latency: u64,
    rtl: &Path,
) -> Result<ExportSpec> {
    let mut draw = Draw::new(c, seed, Merges::Random)?;
    let mut streams = next_chunk(&mut draw, c, count, None)?.streams;
    let mut store = None;
    if is_shared(c) {
        let (shared, st) = shared::export_store(c, &streams, count, store_latency)?;
        (streams, store) = (shared, Some(st));
    }
    let design = crate::from_rtl::design_from_module(&merger_module(c)?, rtl)?;
    let (inputs, outputs) = export_streams(&streams, |name| {
        output_fields(c, name).unwrap_or_else(|| Layout::new(name))
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
        store,
    })
}

/// The next chunk of `n` merges of a run of `config` (the flip hook's
/// merge counted over the run), added to `digest`, its golden time and
/// what it exercises to `out`.
fn golden_chunk(
    draw: &mut Draw,
    c: &MergerConfig,
    config: &RunConfig,
    n: usize,
    digest: &mut StimulusDigest,
    out: &mut Outcome,
) -> Result<UnitStreams> {
    let first = out.totals.merges;
    let t = std::time::Instant::now();
    let flip = config
        .flip_expected
        .filter(|f| (first..first + n).contains(f))
        .map(|f| f - first);
    let MergerStreams { streams, stats } = next_chunk(draw, c, n, flip)?;
    digest.add_chunk(&streams.inputs, &streams.outputs);
    out.totals.golden_wall += t.elapsed();
    out.stats.add(&stats);
    Ok(streams)
}

/// The chunk sizes of a run of `count` merges.
pub(super) fn chunk_sizes(count: usize) -> impl Iterator<Item = usize> {
    (0..count.div_ceil(CHUNK)).map(move |i| CHUNK.min(count - i * CHUNK))
}

/// The merger `c`'s netlist digest (10.2): of the design [`run`]
/// simulates without a patch.
pub fn netlist_digest(c: &MergerConfig) -> Result<String> {
    crate::ledger::netlist_digest(&merger_module(c)?)
}

/// The stimulus digest (10.2) of the run [`run`] makes of `count` merges
/// of `merges` from `seed` with the stall pattern `stall` and the named
/// streams' own `streams`, without simulating it.
pub fn stimulus_digest(
    c: &MergerConfig,
    seed: u64,
    count: usize,
    (stall, streams): (crate::tb::Stalls, &crate::tb::StreamStalls),
    merges: Merges,
) -> Result<String> {
    let mut draw = Draw::new(c, seed, merges)?;
    let mut digest = StimulusDigest::new(seed, count as u64, stall, streams);
    for n in chunk_sizes(count) {
        let s = next_chunk(&mut draw, c, n, None)?.streams;
        digest.add_chunk(&s.inputs, &s.outputs);
    }
    Ok(digest.finish())
}

fn merger_module(c: &MergerConfig) -> Result<rtl_gen::Module> {
    rtl_gen::merge::hierarchy_merger_unit(c).map_err(|what| CosimError::Design {
        what: format!("hierarchy merger: {what}"),
    })
}

/// The merges of a vectors file (`hiermerge vectors --unit merger`,
/// golden's `read_merger_vectors`) for the merger `c`, as its streams.
pub fn streams_from_vectors(c: &MergerConfig, path: &Path) -> Result<UnitStreams> {
    per_unit_only(c, "a vectors replay")?;
    let merges = golden::vectors::stream_file::read_merger_vectors(path, &c.design, c.sizes)
        .map_err(|e| CosimError::Design {
            what: e.to_string(),
        })?;
    let ports = merger_ports(&c.design, &c.sizes).map_err(golden_err)?;
    UnitStreams::from_merges(&ports, &merges)
}

/// Runs `streams` (merges from elsewhere: [`streams_from_vectors`])
/// through the merger `c` on `engine` as one chunk, the Verilog written
/// to `dir`: every output beat compared, `done` counted, `idle` checked.
pub fn run_streams(
    c: &MergerConfig,
    streams: &UnitStreams,
    engine: MergerEngine,
    bench: &ModuleRunConfig,
    dir: &Path,
) -> Result<ChunkTotals> {
    MergerSim::new(c, engine, dir, None)?.run_streams(streams, bench)
}

/// The simulator of the merger `c` (`module`, its Verilog in `design`) on
/// `engine`, its streams named as golden names them.
fn chunked_sim(
    c: &MergerConfig,
    module: rtl_gen::Module,
    design: Design,
    engine: MergerEngine,
    patched: bool,
) -> Result<ChunkedSim> {
    let k = c.design.inputs;
    let (i, o) = (
        merger_input_names(k, is_per_node(c)),
        merger_output_names(k, is_per_node(c)),
    );
    let i: Vec<&str> = i.iter().map(String::as_str).collect();
    let o: Vec<&str> = o.iter().map(String::as_str).collect();
    ChunkedSim::new(module, design, engine, &i, &o, patched)
}

/// A merger built once and run on merges from elsewhere, each run one
/// chunk from reset with [`run`]'s bench, comparison and decoding: a
/// vectors file ([`run_streams`]), or a scene's merges frame after frame
/// (`hiermerge run`), each of them golden's transaction of the store's
/// real contents. A merger with a shared store port answers its reads
/// from a store model ([`SceneStore`]), as `cosim --unit merger
/// --store-port shared` does.
pub struct MergerSim {
    config: MergerConfig,
    sim: Sim,
}

/// How a [`MergerSim`] runs: precomputed streams (per-unit store ports) or
/// a store model on the shared port.
enum Sim {
    PerUnit(ChunkedSim),
    Shared(Box<shared::SharedSim>),
}

/// The store a shared-port merger reads in a [`MergerSim::run`]: its
/// image, and the clocks it takes to answer a read.
#[derive(Clone, Copy, Debug)]
pub struct SceneStore<'a> {
    /// Every word a read may ask for (`StoreWords::of_hierarchies`).
    pub image: &'a StoreWords,
    /// The store answers a read this many clocks after taking it, at the
    /// earliest (0 counts as 1).
    pub latency: u64,
}

/// What a [`MergerSim::run`] measured.
#[derive(Clone, Debug)]
pub struct SimOutcome {
    /// The bench's counts, comparison and status.
    pub totals: ChunkTotals,
    /// What the merges exercised.
    pub stats: MergeStats,
    /// A shared store port only: what the store saw, and whether its
    /// reads were golden's units'.
    pub store: Option<StoreOutcome>,
}

/// Builds `design` for `engine` now (or loads it from cosim's cache), so a
/// run's first chunk does not pay for the build: with tracing when
/// `traced` (a patched per-unit design, whose failure's waveform then needs
/// no second build; a shared port's reactive bench runs untraced).
pub(crate) fn prebuild(design: &Design, engine: MergerEngine, traced: bool) -> Result<()> {
    if engine == MergerEngine::Verilator {
        let (format, scope) = ModuleRunConfig::default().waves();
        match traced {
            false => crate::open_engine(crate::EngineKind::Verilator, design, false)?,
            true => crate::open_tracing_engine(
                crate::EngineKind::Verilator,
                design,
                format,
                scope.as_deref(),
            )?,
        };
    }
    Ok(())
}

impl MergerSim {
    /// The merger `c` on `engine`, its Verilog written to `dir` (which must
    /// outlive the simulator: each chunk opens the design anew) and broken
    /// by `patch` when given (the test hook; not on the IR engine).
    /// Verilator builds it here (or loads it from cosim's cache), so a
    /// run's first chunk does not pay for the build.
    pub fn new(
        c: &MergerConfig,
        engine: MergerEngine,
        dir: &Path,
        patch: Option<&VerilogPatch>,
    ) -> Result<MergerSim> {
        let module = merger_module(c)?;
        let design: Design = crate::from_rtl::design_from_module(&module, dir)?;
        if let Some(patch) = patch {
            apply_patch(&design, patch, engine)?;
        }
        let shared = is_shared(c);
        prebuild(&design, engine, patch.is_some() && !shared)?;
        let sim = match shared {
            true => Sim::Shared(Box::new(shared::SharedSim::new(c, module, design, engine)?)),
            false => Sim::PerUnit(chunked_sim(c, module, design, engine, patch.is_some())?),
        };
        Ok(MergerSim {
            config: c.clone(),
            sim,
        })
    }

    /// Runs `streams` as one chunk: every output beat compared (a
    /// mismatch decoded field by field), `done` counted, `idle` checked.
    /// Per-unit store ports only (the streams carry the store's answers).
    pub fn run_streams(
        &self,
        streams: &UnitStreams,
        bench: &ModuleRunConfig,
    ) -> Result<ChunkTotals> {
        let c = &self.config;
        let Sim::PerUnit(sim) = &self.sim else {
            return Err(shared_refused("a replay of precomputed streams"));
        };
        let decode = |stream: &str, e: &Transaction, g: &Transaction| {
            decoded_pair(&*decoder_of(c, stream), e, g)
        };
        let mut totals = ChunkTotals::default();
        sim.run_chunk(
            &mut totals,
            streams.merges(),
            streams,
            bench,
            &decode,
            &mut |_, _| {},
        )?;
        Ok(totals)
    }

    /// Runs golden's transactions `txs` as one chunk, with what they
    /// exercise; `flip_expected` (the test hook) flips bit 0 of that
    /// merge's expected `header` beat. A shared store port's reads are
    /// answered from `store` (None: from the words golden's units read)
    /// and checked against golden's units' (as many per merge, none
    /// outside the store); per-unit ports get golden's answers as streams.
    pub fn run(
        &self,
        txs: &[MergerTransaction],
        bench: &ModuleRunConfig,
        flip_expected: Option<usize>,
        store: Option<SceneStore>,
    ) -> Result<SimOutcome> {
        let c = &self.config;
        let MergerStreams { mut streams, stats } = merger_streams(c, txs)?;
        if let Some(n) = flip_expected {
            flip_header(&mut streams, n)?;
        }
        let Sim::Shared(sim) = &self.sim else {
            let totals = self.run_streams(&streams, bench)?;
            return Ok(SimOutcome {
                totals,
                stats,
                store: None,
            });
        };
        let decode = |stream: &str, e: &Transaction, g: &Transaction| {
            decoded_pair(&*decoder_of(c, stream), e, g)
        };
        let (totals, outcome) = sim.run_once(streams, txs.len(), bench, store, &decode)?;
        Ok(SimOutcome {
            totals,
            stats,
            store: Some(outcome),
        })
    }
}

/// Runs `config.count` random merges (seeded by `config.bench.seed`) through the
/// merger `c` on `engine`, the Verilog written to `dir`, [`CHUNK`] merges
/// at a time on one simulator ([`ChunkedSim`]); stops after the first chunk
/// that fails. `progress` gets (merges whose chunk is done or whose outputs
/// arrived so far, cycle).
pub fn run(
    c: &MergerConfig,
    engine: MergerEngine,
    config: &RunConfig,
    dir: &Path,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Outcome> {
    if is_shared(c) {
        return shared::run_shared(c, engine, config, dir, progress);
    }
    let module = merger_module(c)?;
    crate::waves::check_scope(&module, config.bench.wave_scope.as_deref())?;
    // Of the design as generated: a patched run is a test of the bench and
    // is never recorded in a ledger.
    let (netlist_sha256, design) = merger_design(&module, dir, config, engine)?;
    let patched = config.bench.verilog_patch.is_some();
    let sim = chunked_sim(c, module, design, engine, patched)?;
    let decode = |stream: &str, e: &Transaction, g: &Transaction| {
        decoded_pair(&*decoder_of(c, stream), e, g)
    };
    let mut draw = Draw::new(c, config.bench.seed, config.merges)?;
    let (seed, count) = (config.bench.seed, config.count as u64);
    let b = &config.bench;
    let mut digest = StimulusDigest::new(seed, count, b.stall, &b.stream_stalls);
    let mut out = Outcome {
        netlist_sha256,
        ..Outcome::default()
    };
    for n in chunk_sizes(config.count) {
        let streams = golden_chunk(&mut draw, c, config, n, &mut digest, &mut out)?;
        if sim.run_chunk(
            &mut out.totals,
            n,
            &streams,
            &config.bench,
            &decode,
            progress,
        )? {
            out.stopped_early = out.totals.merges < config.count;
            break;
        }
    }
    // A run stopped after a failing chunk simulated only part of the
    // stimulus: its digest says so by being of what ran.
    out.stimulus_sha256 = digest.finish();
    Ok(out)
}

/// The merger top's structural digest (the ledger's netlist identity) and
/// its design in `dir`, with the bench's Verilog patch applied: what every
/// merger bench (per-unit or shared store port) starts from.
pub(super) fn merger_design(
    module: &rtl_gen::Module,
    dir: &Path,
    config: &RunConfig,
    engine: MergerEngine,
) -> Result<(String, Design)> {
    let netlist_sha256 = crate::ledger::netlist_digest(module)?;
    let design: Design = crate::from_rtl::design_from_module(module, dir)?;
    if let Some(patch) = &config.bench.verilog_patch {
        apply_patch(&design, patch, engine)?;
    }
    Ok((netlist_sha256, design))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every output stream's decoding fields tile its beats exactly, bit 0
    /// to the width golden packs them at: nothing undecoded, nothing made up.
    #[test]
    fn output_fields_tile_every_packed_beat() {
        let per_node = golden::merge::merge_module::MergeDesign {
            mode: MergeMode::PerNode { num: 1, den: 2 },
            ..golden::merge::merge_module::MergeDesign::default()
        };
        for design in [
            golden::merge::merge_module::MergeDesign::default(),
            per_node,
        ] {
            fields_tile(&MergerConfig::new(design));
        }
    }

    fn fields_tile(c: &MergerConfig) {
        let per_node = is_per_node(c);
        let mut rng = SplitMix64(5);
        let txs: Vec<_> = (0..30)
            .map(|_| random_merge(&mut rng, c).unwrap())
            .collect();
        let streams = merger_streams(c, &txs).unwrap().streams;
        let mut checked = 0;
        for out in &streams.outputs {
            let fields = output_fields(c, &out.name).unwrap();
            let mut end = 0;
            for f in fields.fields() {
                assert_eq!(
                    f.offset, end,
                    "`{}`: field {} not adjacent",
                    out.name, f.name
                );
                end = f.end();
            }
            // A per-node merge at its inputs' top reads no root
            // reference (`f{i}_ref_req` may stay empty).
            let Some(beat) = out.beats.first() else {
                assert!(out.name.ends_with("_ref_req"), "no `{}` beat", out.name);
                continue;
            };
            assert_eq!(end, beat[0].width(), "`{}`", out.name);
            checked += 1;
        }
        assert!(checked >= streams.outputs.len() - c.design.inputs);
        assert_eq!(output_fields(c, "f9_node_req"), None);
        assert_eq!(output_fields(c, "f9_probe_req"), None);
        assert_eq!(output_fields(c, "cfg"), None);
        assert_eq!(output_fields(c, "f0_probe_req").is_some(), per_node);
    }
}
