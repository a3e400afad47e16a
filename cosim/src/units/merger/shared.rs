//! The merger with one shared store port (`StorePort::Shared`, SPEC 8.15
//! "The shared store port"): its reads reach the bench on `store_req` in an
//! order that depends on timing, so a [`StoreModel`] answers them from the
//! store's contents, stepped with the bench, instead of precomputed
//! response streams.
//!
//! The store's contents of a merge are the words golden's per-unit
//! transaction reads (each unit's requests paired with its responses), so
//! a read golden does not make finds nothing and is an error. The requests
//! cannot be checked per unit after routing (the requester of a
//! `store_req` beat is inside the top), so the bench checks what it can
//! from outside: every read is one golden's units make in its merge (the
//! merge in flight that the read's `slot` names: consecutive merges
//! overlap, so the older's writer and the newer's fetchers read at once),
//! and each merge makes exactly as many reads as golden's units do. Every
//! output stream (`report`, `nodes`, `refs`, `header`) is compared bit for
//! bit as in the per-unit bench. A failing chunk's waveform is not
//! written (the reactive bench runs once), only the window asked for
//! (`--wave-window`, of the first chunk).

use std::path::Path;

use golden::bits::Bits;
use golden::merge::merger::store_port::{StoreAddr, StoreArray, StorePortLayout, StoreWords};
use golden::merge::merger::MergerLayout;
use rtl_gen::merge::MergerConfig;

use super::{chunk_sizes, decoder_of, golden_chunk, merger_module, Draw, PULSES};
use super::{MergerEngine, Outcome, RunConfig};
use crate::design::Design;
use crate::engine::Engine;
use crate::error::Result;
use crate::export_tb::StoreSpec;
use crate::ledger::StimulusDigest;
use crate::tb::{run_multi_stream_bench_reactive, BenchConfig, Transaction};
use crate::units::chunked::{chunk_bench, ChunkTotals, PairDecoder, UnitStreams};
use crate::units::merger::store_port::{Epochs, StoreModel, StoreStats};
use crate::units::multi_stream::decoded_pair;

/// What the store saw over a run of the shared port, and whether it held
/// to golden's reads.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct StoreOutcome {
    /// Reads over every chunk, per chunk's stats added.
    pub stats: StoreStats,
    /// Reads golden's units make over the merges run.
    pub expected_reads: u64,
    /// The first way the reads broke the rules: a read outside the
    /// merge's store, or a merge with another number of reads.
    pub failure: Option<String>,
}

/// One chunk of a shared-port run: the streams the bench sees (`cfg` in;
/// `report`, `nodes`, `refs`, `header` out), each merge's store, and each
/// merge's reads as golden's units make them.
struct SharedChunk {
    streams: UnitStreams,
    stores: Vec<StoreWords>,
    reads: Vec<u64>,
    /// Merges started by the first `s` beats of the first input, per `s`
    /// (None: every beat starts one).
    starts: Option<Vec<u64>>,
}

/// Where a top's merges start: its first input stream, the merger's `cfg`
/// (a beat per merge) or the hierarchy unit's `cmd` (determine commands
/// between the merge commands, docs/hardware.md 8.16).
#[derive(Clone, Debug)]
pub(crate) enum Front {
    /// The merger top.
    Merger(Box<MergerLayout>),
    /// The hierarchy unit, its `cmd` laid out so.
    Hierarchy(Box<golden::merge::hierarchy_unit::CmdLayout>),
}

impl Front {
    /// The indices of the first input's beats that start a merge.
    fn merge_beats(&self, first: &[Transaction]) -> Result<Vec<usize>> {
        let Front::Hierarchy(cl) = self else {
            return Ok((0..first.len()).collect());
        };
        let kind = golden::merge::hierarchy_unit::KIND_MERGE;
        let mut at = Vec::new();
        for (b, t) in first.iter().enumerate() {
            let k = t[0].extract(cl.kind.offset, 1)?.to_u64();
            if k == Some(kind) {
                at.push(b);
            }
        }
        Ok(at)
    }

    /// The hierarchy fetcher `i` reads in the merge whose starting beat is
    /// `beat`: its input's `hier`.
    fn fetcher_hier(&self, beat: &Bits, i: usize) -> Result<u64> {
        let (at, width) = match self {
            Front::Merger(ml) => (
                ml.input_offset(i) + ml.fetch.hier.offset,
                ml.fetch.hier.width,
            ),
            Front::Hierarchy(cl) => {
                let f = cl.input_field(i, &cl.input.hier);
                (f.offset, f.width)
            }
        };
        Ok(beat.extract(at, width)?.to_u64().unwrap_or(u64::MAX))
    }
}

impl SharedChunk {
    /// From the per-unit streams of `n` merges (`ml` the merger's layout,
    /// `l` its port's): a fetcher's reads are of its input's hierarchy
    /// (the `hier` of its part of the merge's `cfg` beat), the writer's
    /// name theirs.
    fn of(
        per_unit: &UnitStreams,
        n: usize,
        front: &Front,
        l: &StorePortLayout,
    ) -> Result<SharedChunk> {
        let mut stores = vec![StoreWords::default(); n];
        let mut reads = vec![0u64; n];
        let first = &per_unit.inputs[0].beats;
        let merge_beats = front.merge_beats(first)?;
        let starts = matches!(front, Front::Hierarchy(..)).then(|| {
            let mut cum = vec![0u64; first.len() + 1];
            for &b in &merge_beats {
                cum[b + 1] = 1;
            }
            for s in 1..cum.len() {
                cum[s] += cum[s - 1];
            }
            cum
        });
        let err = |what: String| crate::CosimError::Design { what };
        for (s, out) in per_unit.outputs.iter().enumerate() {
            let Some(base) = out.name.strip_suffix("_req") else {
                continue;
            };
            let resp = format!("{base}_resp");
            let Some(answers) = per_unit.inputs.iter().find(|i| i.name == resp) else {
                continue;
            };
            // `f{i}_...`: fetcher i, whose hierarchy is in the cfg beat.
            let fetcher: Option<usize> = base
                .strip_prefix('f')
                .and_then(|r| r.split('_').next())
                .and_then(|i| i.parse().ok());
            for (k, (q, a)) in out.beats.iter().zip(&answers.beats).enumerate() {
                let e = per_unit.merge_of(s, k);
                let word = q[0].to_u64().unwrap_or(u64::MAX);
                let index = word & ((1u64 << l.index.width) - 1);
                let hier = match fetcher {
                    Some(i) => {
                        let beat = merge_beats.get(e).and_then(|&b| first.get(b));
                        let beat =
                            beat.ok_or_else(|| err(format!("merge {e} has no start beat")))?;
                        front.fetcher_hier(&beat[0], i)?
                    }
                    None => word >> l.hier.offset,
                };
                let array = if a[0].width() == l.node_width {
                    StoreArray::Node
                } else {
                    StoreArray::Reference
                };
                stores[e].insert(array, StoreAddr { hier, index }, a[0].clone());
                reads[e] += 1;
            }
        }
        // The hierarchy unit's `det_out` too (docs/hardware.md 8.16).
        let keep = ["det_out", "report", "nodes", "refs", "header"];
        let picked: Vec<usize> = (0..per_unit.outputs.len())
            .filter(|&s| keep.contains(&per_unit.outputs[s].name.as_str()))
            .collect();
        let streams = UnitStreams {
            inputs: per_unit.inputs[..1].to_vec(),
            outputs: picked
                .iter()
                .map(|&s| per_unit.outputs[s].clone())
                .collect(),
            starts: picked.iter().map(|&s| per_unit.starts[s].clone()).collect(),
        };
        Ok(SharedChunk {
            streams,
            stores,
            reads,
            starts,
        })
    }
}

/// The `n` merges whose per-unit streams are `per_unit` as an exported
/// testbench sees them on a shared port: the shared streams, and the store
/// its model answers from after `latency` clocks (per merge, array and
/// hierarchy a run of the words golden's units read, holes zero).
pub(super) fn export_store(
    c: &MergerConfig,
    per_unit: &UnitStreams,
    n: usize,
    latency: u64,
) -> Result<(UnitStreams, StoreSpec)> {
    let l = StorePortLayout::new(&c.design.params);
    let ml = golden::vectors::streams::merger_layout(&c.design, &c.sizes)
        .map_err(|what| crate::CosimError::Design { what })?;
    let chunk = SharedChunk::of(per_unit, n, &Front::Merger(Box::new(ml)), &l)?;
    let hiers = 1usize << l.hier.width;
    let mut runs = vec![(0u32, 0u32); n * 2 * hiers];
    let mut words = Vec::new();
    let too_many = |what: &str| crate::CosimError::Unsupported {
        what: format!("an exported store of {what} (the testbench counts in 32 bits)"),
    };
    for (e, store) in chunk.stores.iter().enumerate() {
        for array in [StoreArray::Node, StoreArray::Reference] {
            for hier in 0..hiers {
                let at = |index| StoreAddr {
                    hier: hier as u64,
                    index,
                };
                let len = store
                    .iter()
                    .filter(|w| w.0 == array && w.1.hier == hier as u64)
                    .map(|w| w.1.index + 1)
                    .max()
                    .unwrap_or(0);
                let base = u32::try_from(words.len()).map_err(|_| too_many("2^32 words"))?;
                let len32 = u32::try_from(len).map_err(|_| too_many("a run of 2^32 words"))?;
                runs[(e * 2 + array.code() as usize) * hiers + hier] = (base, len32);
                for index in 0..len {
                    let word = match store.word(array, at(index)) {
                        Some(w) => l.pack_resp(w),
                        None => Ok(Bits::zero(l.resp_width)),
                    }
                    .map_err(|what| crate::CosimError::Design { what })?;
                    words.push(word);
                }
            }
        }
    }
    let spec = StoreSpec {
        latency,
        epoch_input: "cfg".into(),
        epoch_output: "header".into(),
        index: l.index,
        hier: l.hier,
        slot: l.slot,
        array: l.array,
        runs,
        words,
        reads: chunk.reads,
    };
    Ok((chunk.streams, spec))
}

/// A fresh engine of `kind` for the merger (`module`, its Verilog in
/// `design`), able to trace when `trace`: Icarus stepped from Rust, as the
/// store answers reads as they come (the batch runs precomputed streams
/// only).
fn engine_of(
    kind: MergerEngine,
    module: &rtl_gen::Module,
    design: &Design,
    trace: bool,
) -> Result<Box<dyn Engine>> {
    Ok(match kind {
        MergerEngine::Ir => Box::new(crate::ir_engine::IrEngine::new(module, design)?),
        MergerEngine::Verilator => crate::open_engine(crate::EngineKind::Verilator, design, trace)?,
        MergerEngine::Iverilog => crate::open_engine(crate::EngineKind::Icarus, design, trace)?,
    })
}

/// A merger with a shared store port, built once and run chunk after
/// chunk, each chunk on a fresh engine from reset with a store model on
/// its `store_req` / `store_resp`.
pub(crate) struct SharedSim {
    module: rtl_gen::Module,
    design: Design,
    engine: MergerEngine,
    layout: StorePortLayout,
    front: Front,
    /// The status outputs whose pulses a chunk counts.
    pulses: &'static [&'static str],
}

impl SharedSim {
    /// The merger `c` (`module`, its Verilog, any patch applied, in
    /// `design`) on `engine`.
    pub(super) fn new(
        c: &MergerConfig,
        module: rtl_gen::Module,
        design: Design,
        engine: MergerEngine,
    ) -> Result<SharedSim> {
        let merger = golden::vectors::streams::merger_layout(&c.design, &c.sizes)
            .map_err(|what| crate::CosimError::Design { what })?;
        let front = Front::Merger(Box::new(merger));
        Ok(SharedSim::with_front(
            c,
            (module, design),
            engine,
            front,
            &PULSES,
        ))
    }

    /// A top of the merger `c` whose merges start as `front` says
    /// (`module`, its Verilog in `design`) on `engine`, counting the pulses
    /// of `pulses` (among them `done` and `idle`).
    pub(crate) fn with_front(
        c: &MergerConfig,
        (module, design): (rtl_gen::Module, Design),
        engine: MergerEngine,
        front: Front,
        pulses: &'static [&'static str],
    ) -> SharedSim {
        SharedSim {
            module,
            design,
            engine,
            layout: StorePortLayout::new(&c.design.params),
            front,
            pulses,
        }
    }

    /// Runs the `n` merges of `per_unit` as one chunk from reset (bench
    /// `bench`, the first chunk's), the store answering after the scene
    /// `store`'s latency from its image (None: after a clock, from the
    /// words golden's units read): a scene's frame, or merges from
    /// elsewhere.
    pub(crate) fn run_once(
        &self,
        per_unit: UnitStreams,
        n: usize,
        bench: &crate::units::multi_stream::RunConfig,
        store: Option<super::SceneStore>,
        decode: &PairDecoder,
    ) -> Result<(ChunkTotals, StoreOutcome)> {
        let mut totals = ChunkTotals::default();
        let mut outcome = StoreOutcome::default();
        let bench = chunk_bench(bench, 0);
        let (latency, image) = store.map_or((1, None), |s| (s.latency, Some(s.image)));
        self.run_chunk(
            &mut totals,
            &mut outcome,
            per_unit,
            n,
            &bench,
            latency,
            image,
            decode,
        )?;
        Ok((totals, outcome))
    }

    /// Runs the `n` merges whose per-unit streams are `per_unit` as one
    /// chunk (bench `bench`) and adds it to `totals` and `store`: the
    /// store answers after `latency` clocks from `image` when given (one
    /// store for every merge: a scene's), else from the words golden's
    /// units read in each merge. Returns whether the chunk failed (an
    /// output beat, a status pulse, or the reads: [`check_reads`]).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn run_chunk(
        &self,
        totals: &mut ChunkTotals,
        store: &mut StoreOutcome,
        per_unit: UnitStreams,
        n: usize,
        bench: &BenchConfig,
        latency: u64,
        image: Option<&StoreWords>,
        decode: &PairDecoder,
    ) -> Result<bool> {
        let first = totals.merges;
        let chunk = SharedChunk::of(&per_unit, n, &self.front, &self.layout)?;
        // Only the shared streams are run: the per-unit ones (every
        // response of the chunk) need not stay in memory meanwhile.
        drop(per_unit);
        let traced = bench.wave_window.is_some() && bench.vcd_path.is_some();
        let mut eng = engine_of(self.engine, &self.module, &self.design, traced)?;
        let stores = &chunk.stores;
        let lookup = move |e: usize, a: StoreArray, at: StoreAddr| match image {
            Some(words) => words.word(a, at).cloned(),
            None => stores.get(e)?.word(a, at).cloned(),
        };
        let l = self.layout.clone();
        // A read's merge is the one in flight its slot names: merges start
        // with their `cfg` beat and end with their `header` beat.
        let epochs = Epochs {
            start_input: 0,
            end_output: "header".into(),
            starts: chunk.starts.clone(),
        };
        let mut model = StoreModel::new(&*eng, l, bench, latency, Some(epochs), Box::new(lookup))?;
        let (report, watch) = run_multi_stream_bench_reactive(
            eng.as_mut(),
            &chunk.streams.inputs,
            &chunk.streams.outputs,
            bench,
            self.pulses,
            &mut model,
        )?;
        let failed = totals.add(n, &chunk.streams, &report, &watch, decode);
        let store_failed = check_reads(Some(store), &model.stats, &chunk.reads, first);
        Ok(failed || store_failed)
    }
}

/// `super::run` for a merger whose units share one store port: the same
/// merges, chunks, comparison and digests; the store answers after
/// `latency` clocks with the bench's stall pattern.
pub(super) fn run_shared(
    c: &MergerConfig,
    engine: MergerEngine,
    config: &RunConfig,
    dir: &Path,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Outcome> {
    let module = merger_module(c)?;
    let (netlist_sha256, design) = super::merger_design(&module, dir, config, engine)?;
    let sim = SharedSim::new(c, module, design, engine)?;
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
    let mut store = StoreOutcome::default();
    for n in chunk_sizes(config.count) {
        let streams = golden_chunk(&mut draw, c, config, n, &mut digest, &mut out)?;
        let bench = chunk_bench(&config.bench, out.totals.chunks);
        let latency = config.store_latency;
        let failed = sim.run_chunk(
            &mut out.totals,
            &mut store,
            streams,
            n,
            &bench,
            latency,
            None,
            &decode,
        )?;
        progress(out.totals.merges as u64, out.totals.cycles);
        if failed {
            out.stopped_early = out.totals.merges < config.count;
            break;
        }
    }
    out.store = Some(store);
    out.stimulus_sha256 = digest.finish();
    Ok(out)
}

/// Adds a chunk's store `stats` to `acc` and checks them against golden's
/// `reads` per merge (the chunk's first merge is `first` of the run);
/// returns whether they broke a rule.
fn check_reads(
    acc: Option<&mut StoreOutcome>,
    stats: &StoreStats,
    reads: &[u64],
    first: usize,
) -> bool {
    let Some(acc) = acc else {
        return false;
    };
    let a = &mut acc.stats;
    a.reads += stats.reads;
    // Each chunk counts its cycles from its own reset: its windows go after
    // the ones before, which they must not overlap.
    let base = a.windows.iter().map(|w| w.1).max().unwrap_or(0);
    let shifted = stats.windows.iter().filter(|w| w.0 > 0);
    a.windows.extend(shifted.map(|w| (w.0 + base, w.1 + base)));
    a.error_count += stats.error_count;
    a.errors.extend(stats.errors.iter().cloned());
    acc.expected_reads += reads.iter().sum::<u64>();
    if acc.failure.is_some() {
        return true;
    }
    acc.failure = match stats.errors.first() {
        Some(e) => Some(format!(
            "the store: {e} (merge {first} is the chunk's first)"
        )),
        None => reads.iter().enumerate().find_map(|(e, want)| {
            let got = stats.reads_by_epoch.get(e).copied().unwrap_or(0);
            (got != *want).then(|| {
                format!(
                    "merge {}: {got} store reads, golden's units make {want}",
                    first + e
                )
            })
        }),
    };
    acc.failure.is_some()
}
