//! The fetcher (S610 + S612, `rtl_gen::merge::fetcher_unit`, SPEC.md
//! section 8.13) against `golden::merge::fetcher::fetch_transaction`, bit
//! for bit on `out`, `leaves`, `node_req`, `ref_req` and `cref_req` (and
//! `probe_req` for the per-node command's fetcher).
//!
//! The store's answers (`node_resp`, `ref_resp`, `cref_resp`,
//! `probe_resp`) are precomputed from golden and presented as ordinary
//! input streams: the unit raises `*_resp_ready` only with a read
//! outstanding, so a stream that waits for it answers in order. The
//! stimulus (random fetches of builder-made soups, corrupted so that every
//! error code occurs) is in [`stimulus`]; the root sorter the fetcher
//! holds has its own bench, [`root_sorter`].

pub mod root_sorter;
pub mod stimulus;

use golden::bits::Bits;
use golden::layout::{Field, LayoutError};
use golden::merge::fetcher::{FetchLayout, FetchOut, FetchSizes, FetchTransaction};
use golden::params::Params;
use golden::store::Reference;

use super::multi_stream::{packed, MultiSim, StreamSet};
use crate::error::Result;
use crate::tb::{BenchConfig, MultiReport, StreamBeats, Transaction};

/// The fetcher of the level modes.
pub fn fetcher_module(p: &Params, sizes: &FetchSizes) -> rtl_gen::Module {
    rtl_gen::merge::fetcher_unit(p, sizes)
}

/// The fetcher of the per-node command (its `report`, `probe_req` and
/// `probe_resp` streams on top of the level modes' ports).
pub fn fetcher_per_node_module(p: &Params, sizes: &FetchSizes) -> rtl_gen::Module {
    rtl_gen::merge::fetcher_per_node_unit(p, sizes)
}

/// Input streams in the order [`streams`] gives them (the per-node
/// fetcher adds `probe_resp` and `report`).
pub const INPUT_NAMES: [&str; 5] = ["cfg", "cmd", "node_resp", "ref_resp", "cref_resp"];

/// Output streams in the order [`streams`] gives them (the per-node
/// fetcher adds `probe_req`).
pub const OUTPUT_NAMES: [&str; 5] = ["node_req", "ref_req", "cref_req", "out", "leaves"];

/// What a list of fetches reached, so that a test can tell its stimulus
/// met the cases it is there for.
#[derive(Clone, Default, Debug)]
pub struct Seen {
    /// Inputs (one `cfg` beat each).
    pub inputs: usize,
    /// Commands, all inputs.
    pub cmds: usize,
    /// `out` error beats per error code (`golden::merge::fetcher::fetch_err`).
    pub codes: [usize; 15],
    /// Commands sending several levels.
    pub multi: usize,
    /// Inputs with a command sending several levels and an error.
    pub multi_errors: usize,
    /// Beats on `out`.
    pub out_beats: usize,
    /// Beats on `leaves`.
    pub leaf_beats: usize,
    /// Node reads (`node_req`).
    pub node_reads: usize,
    /// Reference reads (`ref_req` and `cref_req`).
    pub ref_reads: usize,
    /// Probe reads of the per-node command (`probe_req`).
    pub probe_reads: usize,
}

/// The fetcher's streams for a list of fetches, with what they reached.
/// Inputs: [`INPUT_NAMES`] (and `probe_resp`, `report`).
/// Outputs: [`OUTPUT_NAMES`] (and `probe_req`): the expected beats.
pub type FetchStreams = StreamSet<Seen>;

fn beat(b: std::result::Result<Bits, LayoutError>) -> Result<Transaction> {
    packed(b, "fetcher")
}

/// Index `v` as an `I`-bit request beat.
fn index_beat(v: u32, width: u32) -> Result<Transaction> {
    let mut b = Bits::zero(width);
    let index = Field {
        name: "index",
        offset: 0,
        width,
    };
    beat(b.set(&index, v as u64).map(|_| b))
}

/// The streams of `txs` for a fetcher of layout `l` (with the per-node
/// command's `probe_resp`, `report` and `probe_req` when it has them).
pub fn streams(l: &FetchLayout, txs: &[FetchTransaction]) -> Result<FetchStreams> {
    let mut s: [Vec<Transaction>; 10] = Default::default();
    let (mut probe_resp, mut report, mut probe_req) = (Vec::new(), Vec::new(), Vec::new());
    let mut seen = Seen::default();
    let refs = |rs: &[Reference]| -> Result<Vec<Transaction>> {
        rs.iter().map(|r| beat(r.pack(&l.reference))).collect()
    };
    let indices = |is: &[u32]| -> Result<Vec<Transaction>> {
        is.iter().map(|&i| index_beat(i, l.index_width)).collect()
    };
    for tx in txs {
        count(&mut seen, tx);
        s[0].push(beat(tx.cfg.pack(l))?);
        for c in &tx.cmds {
            s[1].push(beat(c.pack(l))?);
        }
        for r in &tx.node_resps {
            s[2].push(beat(r.pack(&l.node))?);
        }
        s[3].extend(refs(&tx.ref_resps)?);
        s[4].extend(refs(&tx.cref_resps)?);
        s[5].extend(indices(&tx.node_reqs)?);
        s[6].extend(indices(&tx.ref_reqs)?);
        s[7].extend(indices(&tx.cref_reqs)?);
        for o in &tx.out {
            s[8].push(beat(o.pack(l))?);
        }
        for o in &tx.leaves {
            s[9].push(beat(o.pack(l))?);
        }
        if let Some(f) = &l.pn {
            for r in &tx.probe_resps {
                probe_resp.push(beat(r.pack(&l.node))?);
            }
            for r in &tx.reports {
                report.push(beat(f.pack_report(r))?);
            }
            probe_req.extend(indices(&tx.probe_reqs)?);
        }
    }
    let names = INPUT_NAMES.iter().chain(&OUTPUT_NAMES);
    let mut inputs: Vec<StreamBeats> = names
        .zip(s)
        .map(|(n, beats)| StreamBeats {
            name: n.to_string(),
            beats,
        })
        .collect();
    let mut outputs = inputs.split_off(INPUT_NAMES.len());
    if l.pn.is_some() {
        for (name, beats) in [("probe_resp", probe_resp), ("report", report)] {
            inputs.push(StreamBeats {
                name: name.into(),
                beats,
            });
        }
        outputs.push(StreamBeats {
            name: "probe_req".into(),
            beats: probe_req,
        });
    }
    Ok(StreamSet {
        inputs,
        outputs,
        seen,
    })
}

/// Adds what `tx` reaches to `seen`.
fn count(seen: &mut Seen, tx: &FetchTransaction) {
    seen.inputs += 1;
    seen.cmds += tx.cmds.len();
    let several = tx.cmds.iter().filter(|c| c.levels() > 1).count();
    seen.multi += several;
    let error = tx.out.iter().any(|o| matches!(o, FetchOut::Error { .. }));
    seen.multi_errors += (several > 0 && error) as usize;
    for o in &tx.out {
        if let FetchOut::Error { code, .. } = o {
            seen.codes[*code as usize] += 1;
        }
    }
    seen.probe_reads += tx.probe_reqs.len();
    seen.out_beats += tx.out.len();
    seen.leaf_beats += tx.leaves.len();
    seen.node_reads += tx.node_reqs.len();
    seen.ref_reads += tx.ref_reqs.len() + tx.cref_reqs.len();
}

/// One run of `streams` on `sim` with the stalls of `config`: every output
/// beat compared bit for bit with golden's. The report says whether it
/// passed.
pub fn run(sim: MultiSim, streams: &FetchStreams, config: &BenchConfig) -> Result<MultiReport> {
    streams.run(sim, config, &[]).map(|r| r.0)
}
