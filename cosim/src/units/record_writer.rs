//! The record writer (S618, `rtl_gen::merge::record_writer_unit`, SPEC.md
//! section 8.12) against `golden::merge::record_writer::writer_transaction`
//! (the merged hierarchy `golden::merge::upper_builder::build_upper` lays
//! out), bit for bit on every out stream (`ref_req`, `nodes`, `refs`,
//! `header`). The store's responses (`ref_resp`) are an ordinary input
//! stream, precomputed from golden. Stimulus: random cases
//! (`golden::merge::stimulus::random_case`: every top rule, materialized
//! roots, capacity and index overflows at small I) and real merges
//! (golden-built soups at every fixed level and in per-node mode).

use golden::bits::Bits;
use golden::layout::LayoutError;
use golden::merge::level_choice::candidate_range;
use golden::merge::merge_level::BaseNode;
use golden::merge::record_writer::{pack_cfg, writer_transaction, WriterLayout, WriterTransaction};
use golden::merge::stimulus::{per_node_base, random_case, real_cases};
use golden::merge::upper_builder::unit::{fixed_level_base, level_out_kind, LevelOut};
use golden::params::Params;
use golden::store::Hierarchy;
use golden::translate::stimulus::SplitMix64;
use golden::translate::Translation;

use super::multi_stream::{packed, MultiSim, StreamSet};
use crate::error::{CosimError, Result};
use crate::tb::{BenchConfig, MultiReport, PulseCounts, StreamBeats, Transaction};

/// The unit under test: levels buffered in `2^capacity_bits` entries (an
/// error outside `1..I`).
pub fn record_writer_module(p: &Params, capacity_bits: u32) -> Result<rtl_gen::Module> {
    rtl_gen::merge::record_writer_unit(p, capacity_bits).map_err(|e| CosimError::Design {
        what: format!("record writer: {e}"),
    })
}

/// The status outputs a stepped run counts, one cycle each: filling the
/// level buffers, draining records, draining references (the throughput
/// test divides words by them).
pub const PHASES: [&str; 3] = ["filling", "drain_records", "drain_refs"];

/// What a list of merges exercised.
#[derive(Clone, Default, Debug)]
pub struct Seen {
    /// Merges.
    pub merges: usize,
    /// Merges per header error code (`golden::merge::record_writer::writer_err`).
    pub codes: [usize; 5],
    /// Merges reading references of a materialized root.
    pub materialized: usize,
    /// Merges with several roots.
    pub several_roots: usize,
    /// Merges with created nodes at two or more LODs.
    pub created_lods: usize,
    /// Beats on the `level{d}` streams.
    pub level_beats: u64,
    /// Node records written.
    pub records: u64,
    /// References written.
    pub refs: u64,
    /// Per merge, the longest in stream (a level or `crefs`), summed.
    pub longest_in: u64,
}

impl Seen {
    /// Adds the counts of `other` (another chunk of one run).
    pub fn add(&mut self, other: &Seen) {
        self.merges += other.merges;
        for (c, o) in self.codes.iter_mut().zip(other.codes) {
            *c += o;
        }
        self.materialized += other.materialized;
        self.several_roots += other.several_roots;
        self.created_lods += other.created_lods;
        self.level_beats += other.level_beats;
        self.records += other.records;
        self.refs += other.refs;
        self.longest_in += other.longest_in;
    }
}

/// The writer's streams for a list of merges, with what they exercised.
/// Inputs: `cfg`, `level0`..`level{D}`, `done`, `crefs`, `ref_resp`.
/// Outputs: `ref_req`, `nodes`, `refs`, `header`: the expected beats.
pub type WriterStreams = StreamSet<Seen>;

fn beat(b: std::result::Result<Bits, LayoutError>) -> Result<Transaction> {
    packed(b, "record writer")
}

fn named(name: &str) -> StreamBeats {
    StreamBeats {
        name: name.into(),
        beats: Vec::new(),
    }
}

/// The streams of `txs` for a writer of `2^cap` entries per level buffer.
pub fn streams(p: &Params, cap: u32, txs: &[WriterTransaction]) -> Result<WriterStreams> {
    let wl = WriterLayout::new(p, cap).map_err(|e| CosimError::Design {
        what: format!("record writer layout: {e}"),
    })?;
    let bl = &wl.builder;
    let mut cfg = named("cfg");
    let mut levels: Vec<StreamBeats> = (0..=p.max_lod as usize)
        .map(|i| named(&format!("level{i}")))
        .collect();
    let [mut done, mut crefs, mut ref_resp] = ["done", "crefs", "ref_resp"].map(named);
    let [mut ref_req, mut nodes, mut refs, mut header] =
        ["ref_req", "nodes", "refs", "header"].map(named);
    let mut seen = Seen::default();
    let r = |x: &golden::store::Reference| beat(x.pack(&wl.reference));
    for tx in txs {
        count(&mut seen, tx);
        cfg.beats.push(beat(pack_cfg(tx.out_id, &wl))?);
        for (s, beats) in levels.iter_mut().zip(&tx.builder.levels) {
            for b in beats {
                s.beats.push(beat(b.pack(bl))?);
            }
        }
        done.beats.push(beat(tx.builder.done.pack(bl))?);
        for c in &tx.crefs {
            crefs.beats.push(beat(c.pack(&wl))?);
        }
        for x in &tx.ref_reqs {
            ref_req.beats.push(r(x)?);
        }
        for x in &tx.ref_resps {
            ref_resp.beats.push(r(x)?);
        }
        for x in &tx.nodes {
            nodes.beats.push(beat(x.pack(&wl.node))?);
        }
        for x in &tx.refs {
            refs.beats.push(r(x)?);
        }
        header.beats.push(beat(tx.header.pack(&wl))?);
    }
    let mut inputs = vec![cfg];
    inputs.extend(levels);
    inputs.extend([done, crefs, ref_resp]);
    Ok(StreamSet {
        inputs,
        outputs: vec![ref_req, nodes, refs, header],
        seen,
    })
}

/// Adds what one merge reaches to `seen`.
fn count(seen: &mut Seen, tx: &WriterTransaction) {
    seen.merges += 1;
    seen.codes[tx.header.err as usize] += 1;
    seen.materialized += !tx.ref_reqs.is_empty() as usize;
    seen.several_roots += (tx.header.roots > 1) as usize;
    let created = |l: &Vec<LevelOut>| {
        l.iter()
            .any(|b| matches!(b, LevelOut::Node { kind, .. } if *kind == level_out_kind::CREATED))
    };
    let created_at = tx.builder.levels.iter().filter(|l| created(l)).count();
    seen.created_lods += (created_at > 1) as usize;
    seen.records += tx.nodes.len() as u64;
    seen.refs += tx.refs.len() as u64;
    let mut longest = tx.crefs.len();
    for beats in &tx.builder.levels {
        seen.level_beats += beats.len() as u64;
        longest = longest.max(beats.len());
    }
    seen.longest_in += longest as u64;
}

/// `merges` random cases from `seed`
/// ([`super::upper_builder::random_base_size`] base nodes), output id 0.
pub fn random_merges(
    p: &Params,
    cap: u32,
    seed: u64,
    merges: usize,
    most: u64,
) -> Result<Vec<WriterTransaction>> {
    let mut rng = SplitMix64(seed);
    (0..merges)
        .map(|_| {
            let n = super::upper_builder::random_base_size(&mut rng, most);
            let (base, inputs) = random_case(&mut rng, p, n, 0);
            let hs: Vec<&Hierarchy> = inputs.iter().collect();
            writer_transaction(&base, &hs, p, cap, 0).map_err(golden_err)
        })
        .collect()
}

fn golden_err(what: impl std::fmt::Display) -> CosimError {
    CosimError::Design {
        what: format!("golden record writer: {what}"),
    }
}

/// Real merges (`golden::merge::stimulus::real_cases`: overlapping,
/// disjoint, single-triangle soups and one input alone, a materialized
/// root) at every fixed level and in per-node mode at ratios 0, 1/4 and
/// 1/2, written as the last hierarchy id.
pub fn real_merges(p: &Params, cap: u32) -> Result<Vec<WriterTransaction>> {
    let mut out = Vec::new();
    for (store, table, ids) in real_cases(p).map_err(golden_err)? {
        let hs = ids
            .iter()
            .map(|i| {
                store
                    .get(*i)
                    .ok_or_else(|| golden_err("a case's id not stored"))
            })
            .collect::<Result<Vec<&Hierarchy>>>()?;
        let inputs = hs
            .iter()
            .map(|h| Ok((*h, table.read(h.id as u32).map_err(golden_err)?)))
            .collect::<Result<Vec<(&Hierarchy, Translation)>>>()?;
        let (lo, hi) = candidate_range(&hs);
        let mut bases: Vec<Vec<BaseNode>> = (lo..=hi)
            .map(|m| fixed_level_base(&inputs, m, p).map_err(golden_err))
            .collect::<Result<_>>()?;
        for (num, den) in [(0, 1), (1, 4), (1, 2)] {
            bases.push(per_node_base(&inputs, num, den, p).map_err(golden_err)?);
        }
        for base in bases {
            let out_id = (p.hier_capacity() - 1) as u8;
            out.push(writer_transaction(&base, &hs, p, cap, out_id).map_err(golden_err)?);
        }
    }
    Ok(out)
}

/// One run of `streams` on `sim` with the stalls of `config`: every output
/// beat compared bit for bit with golden's, and on a stepped engine the
/// cycles each of [`PHASES`] is high (the batch counts none). The report
/// says whether it passed.
pub fn run(
    sim: MultiSim,
    streams: &WriterStreams,
    config: &BenchConfig,
) -> Result<(MultiReport, PulseCounts)> {
    let pulses: &[&str] = match sim {
        MultiSim::Stepped(_) => &PHASES,
        MultiSim::Batch(_) => &[],
    };
    streams.run(sim, config, pulses)
}
