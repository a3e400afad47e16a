//! The hierarchy merger (`rtl_gen::merge::hierarchy_merger_unit`, S610-S618
//! as one top, SPEC 8.15) against
//! `golden::merge::merger_unit::merger_transaction`, bit for bit on every
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

use golden::layout::{Bits, Field};
use golden::merge::fetch_unit::FetchLayout;
use golden::merge::merger_unit::{merger_transaction, MergerLayout, MergerTransaction, ModulePass};
use golden::merge::per_node_unit::{PerNodeLayout, PerNodeReport};
use golden::merge::stimulus::{place, soup};
use golden::merge::MergeMode;
use golden::store::{HierarchyStore, NodeRecord, Reference};
use golden::translate::stimulus::SplitMix64;
use golden::translate::TranslationTable;
use rtl_gen::merge::MergerConfig;

use crate::bitvec::BitVec;
use crate::design::Design;
use crate::error::{CosimError, Result};
use crate::ledger::StimulusDigest;
use crate::tb::{FieldDecoder, StreamBeats, Transaction};

pub use super::chunked::{ChunkTotals, CHUNK};
use super::chunked::{ChunkedSim, UnitStreams};
use super::merge_module::top_report_fields;
pub use super::multi_stream::ModuleEngine as MergerEngine;
pub use super::multi_stream::ModuleMismatch as MergerMismatch;
use super::multi_stream::{
    apply_patch, beat_decoder, decoded_pair, export_checks, export_streams, flip_bit0, named,
};
pub use super::multi_stream::{RunConfig as ModuleRunConfig, VerilogPatch};
use crate::export_tb::{named_fields, ExportSpec};

/// The stage name `hiermerge cosim --unit merger` reports.
pub const STAGE: &str = "hierarchy_merger";

/// Most soups in a random merge is the merger's `k`; most triangles per soup.
pub const MOST_TRIANGLES: u64 = 40;

/// Random merges drawn before giving up on one whose leaves fit the leaf
/// FIFOs (the merger's `leaf_bits` too small for the random scenes).
pub const MOST_DRAWS: usize = 1000;

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
}

impl MergeStats {
    /// Adds `other`'s counts to these.
    pub fn add(&mut self, other: &MergeStats) {
        self.merges += other.merges;
        self.refused += other.refused;
        self.records += other.records;
        self.refs += other.refs;
        self.leaves_above += other.leaves_above;
        self.materialized += other.materialized;
        self.several_roots += other.several_roots;
        self.fetch_errors += other.fetch_errors;
        self.module_in += other.module_in;
        self.multi_pass += other.multi_pass;
        self.descents += other.descents;
        for (n, m) in &other.by_inputs {
            *self.by_inputs.entry(*n).or_default() += m;
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

/// A store read request (`f{i}_node_req`, `_ref_req`, `_cref_req`): the
/// whole beat is the index read.
fn index_field(fl: &FetchLayout) -> Field {
    Field {
        name: "index",
        offset: 0,
        width: fl.index_width,
    }
}

/// The `header` beat's fields in bit order: the writer's header, then the
/// merger's flags.
fn header_fields(ml: &MergerLayout) -> Vec<Field> {
    let w = &ml.writer;
    vec![
        w.h_out_id,
        w.h_top,
        w.h_roots,
        w.h_nodes,
        w.h_refs,
        w.h_err,
        ml.leaf_overflow,
        ml.count_overflow,
        ml.fetch_err,
        ml.fetch_rank,
    ]
}

/// The per-node module's `report` fields in bit order (8.14).
fn per_node_report_fields(l: &PerNodeLayout) -> Vec<Field> {
    let mut v = l.coord.to_vec();
    v.extend([
        l.lod, l.shared, l.union, l.descend, l.pass_end, l.more, l.err,
    ]);
    v
}

/// Whether `c` merges per node (its fetchers have a probe port, its
/// `report` is the per-node module's).
pub fn is_per_node(c: &MergerConfig) -> bool {
    matches!(c.design.mode, MergeMode::PerNode { .. })
}

/// The fields of output stream `stream`'s beats, from golden's layouts:
/// `report` the merging module's (`TopLayout`, or `per_node`'s
/// `PerNodeLayout` in per-node mode), a fetcher's `*_req` an index, `w_ref_req` and `refs` a
/// reference (`RefLayout`), `nodes` a node record (`NodeLayout`), `header`
/// (`header_fields`); None for a name that is no output stream of the
/// merger.
pub fn output_fields(
    ml: &MergerLayout,
    per_node: Option<&PerNodeLayout>,
    stream: &str,
) -> Option<Vec<Field>> {
    match stream {
        "report" => Some(match per_node {
            Some(pl) => per_node_report_fields(pl),
            None => top_report_fields(&ml.top),
        }),
        "w_ref_req" | "refs" => Some(ml.writer.reference.fields().copied().collect()),
        "nodes" => Some(ml.writer.node.fields().copied().collect()),
        "header" => Some(header_fields(ml)),
        // The other outputs are the fetchers' store reads.
        s if output_names(ml.k, per_node.is_some())
            .iter()
            .any(|n| n == s) =>
        {
            Some(vec![index_field(&ml.fetch)])
        }
        _ => None,
    }
}

/// Decodes a beat of output stream `stream` field by field
/// ([`output_fields`]; an unknown stream shows its raw bits as `data`).
pub fn decoder_of(
    ml: &MergerLayout,
    per_node: Option<&PerNodeLayout>,
    stream: &str,
) -> Box<FieldDecoder> {
    beat_decoder(named(
        output_fields(ml, per_node, stream).unwrap_or_default(),
    ))
}

/// Per-stream beats of the merges, appended merge by merge.
struct Lanes {
    names: Vec<String>,
    beats: Vec<Vec<Bits>>,
}

impl Lanes {
    fn new(names: Vec<String>) -> Lanes {
        let beats = vec![Vec::new(); names.len()];
        Lanes { names, beats }
    }

    fn into_streams(self) -> Result<Vec<StreamBeats>> {
        self.names
            .into_iter()
            .zip(self.beats)
            .map(|(name, v)| {
                Ok(StreamBeats {
                    name,
                    beats: v
                        .iter()
                        .map(|b| Ok(vec![BitVec::from_layout(b)?]))
                        .collect::<Result<_>>()?,
                })
            })
            .collect()
    }
}

fn input_names(k: usize, per_node: bool) -> Vec<String> {
    let mut v = vec!["cfg".to_string()];
    for i in 0..k {
        v.extend(["node_resp", "ref_resp", "cref_resp"].map(|s| format!("f{i}_{s}")));
    }
    if per_node {
        v.extend((0..k).map(|i| format!("f{i}_probe_resp")));
    }
    v.push("w_ref_resp".into());
    v
}

fn output_names(k: usize, per_node: bool) -> Vec<String> {
    let mut v = vec!["report".to_string()];
    for i in 0..k {
        v.extend(["node_req", "ref_req", "cref_req"].map(|s| format!("f{i}_{s}")));
    }
    if per_node {
        v.extend((0..k).map(|i| format!("f{i}_probe_req")));
    }
    v.extend(["w_ref_req", "nodes", "refs", "header"].map(String::from));
    v
}

/// The streams of `txs` for the merger `c`, and what they exercise.
pub fn merger_streams(c: &MergerConfig, txs: &[MergerTransaction]) -> Result<MergerStreams> {
    let p = &c.design.params;
    let k = c.design.inputs;
    let ml = MergerLayout::new(p, k, c.sizes.capacity_bits).map_err(golden_err)?;
    let fl = &ml.fetch;
    let index_field = index_field(fl);
    let idx = |i: &u32| -> Result<Bits> {
        let mut b = Bits::zero(fl.index_width);
        b.set(&index_field, *i as u64).map_err(golden_err)?;
        Ok(b)
    };
    let node = |n: &NodeRecord| n.pack(&fl.node).map_err(golden_err);
    let rf = |r: &Reference| r.pack(&fl.reference).map_err(golden_err);
    let per_node = is_per_node(c);
    let pl = PerNodeLayout::new(p);
    let mut ins = Lanes::new(input_names(k, per_node));
    let mut outs = Lanes::new(output_names(k, per_node));
    let mut starts = vec![Vec::with_capacity(txs.len() + 1); outs.names.len()];
    let mut stats = MergeStats::default();
    // The probe ports (per-node mode) sit between the fetchers' and the
    // writer's streams.
    let probes = 1 + 3 * k;
    let np = if per_node { k } else { 0 };
    let w_resp = probes + np;
    let (report, w_req) = (0, probes + np);
    let (nodes, refs, header) = (w_req + 1, w_req + 2, w_req + 3);
    for tx in txs {
        for (s, at) in starts.iter_mut().zip(&outs.beats) {
            s.push(at.len());
        }
        *stats.by_inputs.entry(tx.fetch.len()).or_default() += 1;
        ins.beats[0].push(tx.cfg.pack(&ml).map_err(golden_err)?);
        for r in tx.reports() {
            outs.beats[report].push(r.pack(&ml.top).map_err(golden_err)?);
        }
        let mut refused = tx.chosen.is_none();
        if let ModulePass::PerNode(pn) = &tx.module {
            for r in &pn.reports {
                outs.beats[report].push(r.pack(&pl).map_err(golden_err)?);
            }
            refused = pn.passes == 0;
            stats.multi_pass += (pn.passes > 1) as usize;
            stats.descents += pn
                .reports
                .iter()
                .filter(|r| matches!(r, PerNodeReport::Decision { descend: true, .. }))
                .count() as u64;
        }
        let w = &tx.writer;
        for n in &w.nodes {
            outs.beats[nodes].push(node(n)?);
        }
        for r in &w.refs {
            outs.beats[refs].push(rf(r)?);
        }
        for r in &w.ref_reqs {
            outs.beats[w_req].push(rf(r)?);
        }
        for r in &w.ref_resps {
            ins.beats[w_resp].push(rf(r)?);
        }
        outs.beats[header].push(tx.header.pack(&ml).map_err(golden_err)?);
        for (i, f) in tx.fetch.iter().enumerate() {
            let (fi, fo) = (1 + 3 * i, 1 + 3 * i);
            for n in &f.node_resps {
                ins.beats[fi].push(node(n)?);
            }
            for r in &f.ref_resps {
                ins.beats[fi + 1].push(rf(r)?);
            }
            for r in &f.cref_resps {
                ins.beats[fi + 2].push(rf(r)?);
            }
            for r in &f.node_reqs {
                outs.beats[fo].push(idx(r)?);
            }
            for r in &f.ref_reqs {
                outs.beats[fo + 1].push(idx(r)?);
            }
            for r in &f.cref_reqs {
                outs.beats[fo + 2].push(idx(r)?);
            }
            if per_node {
                for n in &f.probe_resps {
                    ins.beats[probes + i].push(node(n)?);
                }
                for r in &f.probe_reqs {
                    outs.beats[probes + i].push(idx(r)?);
                }
            }
            stats.module_in += f.out.len() as u64;
        }
        stats.merges += 1;
        stats.refused += refused as usize;
        stats.fetch_errors += (tx.header.fetch_err != 0) as usize;
        stats.records += w.nodes.len() as u64;
        stats.refs += w.refs.len() as u64;
        stats.leaves_above += !tx.leaves.is_empty() as usize;
        stats.materialized += !w.ref_reqs.is_empty() as usize;
        stats.several_roots += (w.header.roots > 1) as usize;
    }
    for (s, at) in starts.iter_mut().zip(&outs.beats) {
        s.push(at.len());
    }
    Ok(MergerStreams {
        streams: UnitStreams {
            inputs: ins.into_streams()?,
            outputs: outs.into_streams()?,
            starts,
        },
        stats,
    })
}

/// A random merge: 1..=k soups of 1..=[`MOST_TRIANGLES`] triangles, each
/// translated at its top LOD by a random fraction of the room left (per-node
/// mode: in half the merges every soup by the first one's fraction); drawn
/// again while the leaves overflow the merger's leaf FIFOs (at most
/// [`MOST_DRAWS`] times).
pub fn random_merge(rng: &mut SplitMix64, c: &MergerConfig) -> Result<MergerTransaction> {
    let p = &c.design.params;
    let k = c.design.inputs;
    let out_id = u8::try_from(p.hier_capacity() - 1).map_err(golden_err)?;
    // Inputs take ids 1..=k and the merge the last id, 2^H - 1.
    if k as u64 + 2 > p.hier_capacity() {
        return Err(CosimError::Design {
            what: format!(
                "{k} inputs: random merges give them ids 1..={k} and the merge id {out_id}, so at most {} inputs fit H = {}",
                p.hier_capacity() - 2,
                p.hier_bits
            ),
        });
    }
    for _ in 0..MOST_DRAWS {
        let n = 1 + rng.below(k as u64) as usize;
        // Per-node mode: half the merges place every soup where the first
        // goes, so that voxels are contested and passes descend.
        let together = is_per_node(c) && rng.below(2) == 0;
        let mut first_frac = None;
        let mut store = HierarchyStore::new();
        let mut table = TranslationTable::new(p.hier_capacity() as usize, p).map_err(golden_err)?;
        let mut ids = Vec::new();
        for r in 0..n {
            let id = 1 + r as u8;
            let tris = 1 + rng.below(MOST_TRIANGLES) as usize;
            let size = 0.02 + rng.below(30) as f32 / 100.0;
            let h = soup(p, id, tris, size, rng.next_u64());
            let mut frac = [0, 1, 2].map(|_| rng.below(101) as f64 / 100.0);
            if together {
                frac = *first_frac.get_or_insert(frac);
            }
            table
                .write(id as u32, place(&h, frac))
                .map_err(golden_err)?;
            store.insert(h).map_err(golden_err)?;
            ids.push(id);
        }
        if let Ok(tx) = merger_transaction(&store, &table, &ids, c.design.mode, out_id, k, c.sizes)
        {
            if !tx.header.leaf_overflow {
                return Ok(tx);
            }
        }
    }
    Err(golden_err(format!(
        "no random merge of {MOST_DRAWS} drawn fits leaf FIFOs of 2^{} entries: expected a larger leaf_bits",
        c.sizes.leaf_bits
    )))
}

/// How one run is driven.
#[derive(Clone, Debug, Default)]
pub struct RunConfig {
    /// As the merging module's runs: seed (of the merges too), stall, VCD
    /// and the Verilog patch hook.
    pub bench: ModuleRunConfig,
    /// Merges to run.
    pub count: usize,
    /// The test hook: bit 0 of merge `n`'s expected `header` beat (its
    /// `out_id`) flipped.
    pub flip_expected: Option<usize>,
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
}

impl Outcome {
    /// Every beat matched, none missing, nothing hung, one `done` pulse
    /// per merge, and the unit idle at the end of every chunk.
    pub fn passed(&self) -> bool {
        self.totals.passed()
    }

    /// Records written (`nodes` beats) per cycle.
    pub fn records_per_cycle(&self) -> f64 {
        self.stats.records as f64 / self.totals.cycles.max(1) as f64
    }
}

/// Flips bit 0 of merge `merge`'s expected `header` beat (its `out_id`).
fn flip_header(streams: &mut UnitStreams, merge: usize) -> Result<()> {
    let header = streams.outputs.len() - 1;
    let at = streams.starts[header][merge];
    match streams.outputs[header].beats.get_mut(at) {
        Some(beat) => flip_bit0(&mut beat[0]),
        None => Ok(()),
    }
}

/// The next chunk of `n` random merges drawn from `rng`, as the merger's
/// streams; merge `flip` (counted in the chunk) gets its expected `header`
/// beat's bit 0 flipped.
fn next_chunk(
    rng: &mut SplitMix64,
    c: &MergerConfig,
    n: usize,
    flip: Option<usize>,
) -> Result<MergerStreams> {
    let txs = (0..n)
        .map(|_| random_merge(rng, c))
        .collect::<Result<Vec<_>>>()?;
    let mut streams = merger_streams(c, &txs)?;
    if let Some(f) = flip {
        flip_header(&mut streams.streams, f)?;
    }
    Ok(streams)
}

/// The exported testbench of `c` (`hiermerge export-tb --unit merger`):
/// `count` random merges from `seed` as [`run`] draws them (one chunk),
/// the Verilog written to `rtl`.
pub fn export_spec(
    c: &MergerConfig,
    seed: u64,
    count: usize,
    stalls: crate::tb::Stalls,
    rtl: &Path,
) -> Result<ExportSpec> {
    let streams = next_chunk(&mut SplitMix64(seed), c, count, None)?.streams;
    let design = crate::from_rtl::design_from_module(&merger_module(c)?, rtl)?;
    let ml = MergerLayout::new(&c.design.params, c.design.inputs, c.sizes.capacity_bits)
        .map_err(golden_err)?;
    let pl = is_per_node(c).then(|| PerNodeLayout::new(&c.design.params));
    let (inputs, outputs) = export_streams(&streams, |name| {
        named_fields(output_fields(&ml, pl.as_ref(), name).unwrap_or_default())
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
        command: String::new(),
    })
}

/// The chunk sizes of a run of `count` merges.
fn chunk_sizes(count: usize) -> impl Iterator<Item = usize> {
    (0..count.div_ceil(CHUNK)).map(move |i| CHUNK.min(count - i * CHUNK))
}

/// The merger `c`'s netlist digest (10.2): of the design [`run`]
/// simulates without a patch.
pub fn netlist_digest(c: &MergerConfig) -> Result<String> {
    crate::ledger::netlist_digest(&merger_module(c)?)
}

/// The stimulus digest (10.2) of the run [`run`] makes of `count` merges
/// from `seed` with the stall pattern `stall`, without simulating it.
pub fn stimulus_digest(
    c: &MergerConfig,
    seed: u64,
    count: usize,
    stall: crate::tb::Stalls,
) -> Result<String> {
    let mut rng = SplitMix64(seed);
    let mut digest = StimulusDigest::new(seed, count as u64, stall);
    for n in chunk_sizes(count) {
        let s = next_chunk(&mut rng, c, n, None)?.streams;
        digest.add_chunk(&s.inputs, &s.outputs);
    }
    Ok(digest.finish())
}

fn merger_module(c: &MergerConfig) -> Result<rtl_gen::Module> {
    rtl_gen::merge::hierarchy_merger_unit(c).map_err(|what| CosimError::Design {
        what: format!("hierarchy merger: {what}"),
    })
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
    let module = merger_module(c)?;
    crate::waves::check_scope(&module, config.bench.wave_scope.as_deref())?;
    // Of the design as generated: a patched run is a test of the bench and
    // is never recorded in a ledger.
    let netlist_sha256 = crate::ledger::netlist_digest(&module)?;
    let design: Design = crate::from_rtl::design_from_module(&module, dir)?;
    if let Some(patch) = &config.bench.verilog_patch {
        apply_patch(&design, patch, engine)?;
    }
    let ml = MergerLayout::new(&c.design.params, c.design.inputs, c.sizes.capacity_bits)
        .map_err(golden_err)?;
    let k = c.design.inputs;
    let pn_layout = is_per_node(c).then(|| PerNodeLayout::new(&c.design.params));
    let (i, o) = (
        input_names(k, is_per_node(c)),
        output_names(k, is_per_node(c)),
    );
    let i: Vec<&str> = i.iter().map(String::as_str).collect();
    let o: Vec<&str> = o.iter().map(String::as_str).collect();
    let patched = config.bench.verilog_patch.is_some();
    let sim = ChunkedSim::new(module, design, engine, &i, &o, patched)?;
    let decode = |stream: &str, e: &Transaction, g: &Transaction| {
        decoded_pair(&*decoder_of(&ml, pn_layout.as_ref(), stream), e, g)
    };
    let mut rng = SplitMix64(config.bench.seed);
    let (seed, count) = (config.bench.seed, config.count as u64);
    let mut digest = StimulusDigest::new(seed, count, config.bench.stall);
    let mut out = Outcome {
        netlist_sha256,
        ..Outcome::default()
    };
    for n in chunk_sizes(config.count) {
        let first = out.totals.merges;
        let t = std::time::Instant::now();
        let flip = config
            .flip_expected
            .filter(|f| (first..first + n).contains(f))
            .map(|f| f - first);
        let MergerStreams { streams, stats } = next_chunk(&mut rng, c, n, flip)?;
        digest.add_chunk(&streams.inputs, &streams.outputs);
        out.totals.golden_wall += t.elapsed();
        out.stats.add(&stats);
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Every output stream's decoding fields tile its beats exactly, bit 0
    /// to the width golden packs them at: nothing undecoded, nothing made up.
    #[test]
    fn output_fields_tile_every_packed_beat() {
        let per_node = golden::vectors::merge::MergeDesign {
            mode: MergeMode::PerNode { num: 1, den: 2 },
            ..golden::vectors::merge::MergeDesign::default()
        };
        for design in [golden::vectors::merge::MergeDesign::default(), per_node] {
            fields_tile(&MergerConfig::new(design));
        }
    }

    fn fields_tile(c: &MergerConfig) {
        let pl = PerNodeLayout::new(&c.design.params);
        let pn = is_per_node(c).then_some(&pl);
        let ml =
            MergerLayout::new(&c.design.params, c.design.inputs, c.sizes.capacity_bits).unwrap();
        let mut rng = SplitMix64(5);
        let txs: Vec<_> = (0..30)
            .map(|_| random_merge(&mut rng, c).unwrap())
            .collect();
        let streams = merger_streams(c, &txs).unwrap().streams;
        let mut checked = 0;
        for out in &streams.outputs {
            let fields = output_fields(&ml, pn, &out.name).unwrap();
            let mut end = 0;
            for f in &fields {
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
            assert_eq!(end as usize, beat[0].width(), "`{}`", out.name);
            checked += 1;
        }
        assert!(checked >= streams.outputs.len() - c.design.inputs);
        assert_eq!(output_fields(&ml, pn, "f9_node_req"), None);
        assert_eq!(output_fields(&ml, pn, "f9_probe_req"), None);
        assert_eq!(output_fields(&ml, pn, "cfg"), None);
        assert_eq!(
            output_fields(&ml, pn, "f0_probe_req").is_some(),
            pn.is_some()
        );
    }
}
