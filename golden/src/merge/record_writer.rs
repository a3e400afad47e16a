//! S618 in hardware (SPEC.md section 8.12, `rtl_gen::merge::record_writer_unit`):
//! the beat formats of the record writer's streams and its transaction,
//! whose expected outputs are the merged hierarchy `merge::upper_builder::build_upper`
//! lays out (the records and references `merge()` stores), never a second
//! model of the layout.
//!
//! Streams of one merge:
//! - in `cfg`: the output hierarchy's id.
//! - in `level{d}`, `done`: the upper builder's out beats (8.11,
//!   [`BuilderLayout`]), as `upper_builder::unit::builder_transaction` makes them.
//! - in `crefs`: the references of every created node (S614's reference
//!   beats) in store order: by LOD from the shallowest, each LOD in its
//!   level order (Morton, stable), each node's references in order; then
//!   `End`. At one merging level this is S614's order; per-node merging
//!   (8.5) makes created nodes at several LODs and its driver sorts them so.
//! - out `ref_req` / in `ref_resp`: the store read of a materialized root's
//!   references (a reused inner node at the top, whose level beat carries
//!   its stored `first` and `count`, 8.3): the request is `(input id, index
//!   into its refs)`, the response the stored reference.
//! - out `nodes`: the merged hierarchy's records in store order; out `refs`:
//!   its references in order; out `header`: one beat per merge.

use crate::bits::Bits;
use crate::layout::{Field, Layout, LayoutError, NodeLayout, RefLayout};
use crate::merge::error::MergeError;
use crate::merge::merge_level::{BaseKind, BaseNode};
use crate::merge::upper_builder::unit::LevelOut;
use crate::merge::upper_builder::unit::{
    builder_transaction, level_out_kind, BuilderLayout, BuilderTransaction,
};
use crate::merge::upper_builder::{base_by_lod, build_upper};
use crate::params::Params;
use crate::store::{Hierarchy, NodeRecord, Reference};

/// Error codes of the header's `err` field, in priority order (the
/// smallest non-zero code that applies is reported).
pub mod writer_err {
    /// The merged hierarchy was written.
    pub const NONE: u64 = 0;
    /// The builder found no top (`done.err`: an empty base, or a reused
    /// leaf at the LOD-0 top, 8.1's `InputLeafAtTop`).
    pub const NO_TOP: u64 = 1;
    /// A level held more than `2^C` nodes, or the created nodes more than
    /// `2^C` references (`C` = the writer's capacity bits).
    pub const CAPACITY: u64 = 2;
    /// A level beat came with its `err` flag (8.11: a grouped node's
    /// `first` or `count`, or a position, reached `2^I`; a child box with
    /// `lo > hi`), or a node with `count` 0 (a record needs references).
    pub const LEVEL_OVERFLOW: u64 = 3;
    /// 8.1's `IndexOverflow`: more than `2^I` records or references.
    pub const INDEX_OVERFLOW: u64 = 4;
}

/// A capacity the writer cannot be built with.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CapacityError {
    /// The capacity bits asked for (`C`).
    pub capacity_bits: u32,
    /// `I`: `C` must be in `1..I`.
    pub index_bits: u8,
}

impl std::fmt::Display for CapacityError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "record writer: capacity_bits = {} is outside 1..{} (expected at least 1 and below I = {}, \
             so a position past the capacity shows in the level beats' I-bit index)",
            self.capacity_bits, self.index_bits, self.index_bits
        )
    }
}

impl std::error::Error for CapacityError {}

/// Bit layouts of the record writer's beats (fields from bit 0).
///
/// - `cfg`: `out_id` (H).
/// - `level{d}`, `done`: [`BuilderLayout`].
/// - `crefs`: `ref` (I + H), `end` (1).
/// - `ref_req`, `ref_resp`, `refs`: a reference (I + H); `nodes`: a node
///   record (W).
/// - `header`: `out_id` (H), `top` (lod bits), `roots`, `nodes`, `refs`
///   (I + 1 each: a count up to `2^I`), `err` (3, [`writer_err`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WriterLayout {
    /// The `level{d}` and `done` in beats: the upper builder's layouts.
    pub builder: BuilderLayout,
    /// Layout of a `nodes` beat (a node record).
    pub node: NodeLayout,
    /// Layout of a reference: `crefs`' `ref`, `ref_req`, `ref_resp` and `refs`.
    pub reference: RefLayout,
    /// Each level's and the created references' buffer holds `2^C` entries.
    pub capacity_bits: u32,
    /// The `cfg` beat: `out_id`.
    pub cfg: Layout,
    /// `cfg`: `out_id` (H bits), the merged hierarchy's id.
    pub cfg_out_id: Field,
    /// The `crefs` beat: `ref`, `end`.
    pub crefs: Layout,
    /// `crefs`: `ref` (I + H bits, from bit 0), a created node's reference.
    pub cref: Field,
    /// `crefs`: `end` (1 bit), set on the merge's last `crefs` beat.
    pub cref_end: Field,
    /// The `header` beat: `out_id`, `top`, `roots`, `nodes`, `refs`, `err`.
    pub header: Layout,
    /// `header`: `out_id` (H bits, from bit 0).
    pub h_out_id: Field,
    /// `header`: `top` (`lod_bits`), the LOD of the merged roots.
    pub h_top: Field,
    /// `header`: `roots` (I + 1 bits), the root count.
    pub h_roots: Field,
    /// `header`: `nodes` (I + 1 bits), the records written.
    pub h_nodes: Field,
    /// `header`: `refs` (I + 1 bits), the references written.
    pub h_refs: Field,
    /// `header`: `err` (3 bits), a [`writer_err`] code.
    pub h_err: Field,
}

impl WriterLayout {
    /// The layout for `p` with buffers of `2^capacity_bits` entries;
    /// `capacity_bits` must be in `1..I`.
    pub fn new(p: &Params, capacity_bits: u32) -> Result<WriterLayout, CapacityError> {
        let i = p.index_bits as u32;
        if capacity_bits == 0 || capacity_bits >= i {
            return Err(CapacityError {
                capacity_bits,
                index_bits: p.index_bits,
            });
        }
        let node = NodeLayout::new(p);
        let reference = RefLayout::new(p);
        let h = p.hier_bits as u32;
        let mut cfg = Layout::new("record writer cfg");
        let cfg_out_id = cfg.push("out_id", h);
        let mut crefs = Layout::new("record writer crefs");
        let cref = crefs.push("ref", reference.width());
        let cref_end = crefs.push("end", 1);
        let mut header = Layout::new("record writer header");
        let h_out_id = header.push("out_id", h);
        let h_top = header.push("top", p.lod_bits());
        let h_roots = header.push("roots", i + 1);
        let h_nodes = header.push("nodes", i + 1);
        let h_refs = header.push("refs", i + 1);
        let h_err = header.push("err", 3);
        Ok(WriterLayout {
            builder: BuilderLayout::new(p),
            capacity_bits,
            cfg,
            cfg_out_id,
            crefs,
            cref,
            cref_end,
            header,
            h_out_id,
            h_top,
            h_roots,
            h_nodes,
            h_refs,
            h_err,
            node,
            reference,
        })
    }
}

/// One beat on `crefs`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CrefBeat {
    /// A created node's reference, in store order.
    Ref(Reference),
    /// The end of the merge's created references (`end` = 1).
    End,
}

impl CrefBeat {
    /// The packed beat.
    pub fn pack(&self, l: &WriterLayout) -> Result<Bits, LayoutError> {
        let mut b = l.crefs.zero();
        match self {
            CrefBeat::Ref(r) => b.put(l.cref.offset, &r.pack(&l.reference)?)?,
            CrefBeat::End => b.set(&l.cref_end, 1)?,
        }
        Ok(b)
    }
}

/// The `header` beat of a merge. On an error every count and `top` are 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Header {
    /// The merged hierarchy's id.
    pub out_id: u8,
    /// The LOD of the merged hierarchy's roots.
    pub top: u8,
    /// The root count: the nodes of the top level.
    pub roots: u64,
    /// The records written on `nodes`.
    pub nodes: u64,
    /// The references written on `refs`.
    pub refs: u64,
    /// A [`writer_err`] code.
    pub err: u64,
}

impl Header {
    /// The packed beat.
    pub fn pack(&self, l: &WriterLayout) -> Result<Bits, LayoutError> {
        let mut b = l.header.zero();
        b.set(&l.h_out_id, self.out_id as u64)?;
        b.set(&l.h_top, self.top as u64)?;
        b.set(&l.h_roots, self.roots)?;
        b.set(&l.h_nodes, self.nodes)?;
        b.set(&l.h_refs, self.refs)?;
        b.set(&l.h_err, self.err)?;
        Ok(b)
    }
}

/// The `cfg` beat.
pub fn pack_cfg(out_id: u8, l: &WriterLayout) -> Result<Bits, LayoutError> {
    let mut b = l.cfg.zero();
    b.set(&l.cfg_out_id, out_id as u64)?;
    Ok(b)
}

/// One merge through the record writer: its in beats (the builder's
/// `level{d}` and `done` in `builder`, `cfg`, `crefs`, the store's
/// responses) and its expected out beats.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WriterTransaction {
    /// The `cfg` beat's `out_id`.
    pub out_id: u8,
    /// The upper builder's transaction: its `levels` and `done` are the
    /// writer's `level{d}` and `done` in beats.
    pub builder: BuilderTransaction,
    /// The `crefs` in beats: the created nodes' references in store order, then `End`.
    pub crefs: Vec<CrefBeat>,
    /// The expected `ref_req` beats: `(input id, index into its refs)` for every
    /// reference of every materialized root, in root order.
    pub ref_reqs: Vec<Reference>,
    /// The store's `ref_resp` beats, one per request.
    pub ref_resps: Vec<Reference>,
    /// The expected `nodes` beats: the merged records in store order (none on an error).
    pub nodes: Vec<NodeRecord>,
    /// The expected `refs` beats: the merged references in order (none on an error).
    pub refs: Vec<Reference>,
    /// The expected `header` beat.
    pub header: Header,
}

/// The created nodes' references in store order (by LOD from the
/// shallowest, each LOD in level order, S616's level lists).
pub fn created_refs_in_store_order(base: &[BaseNode], p: &Params) -> Vec<Reference> {
    let mut out = Vec::new();
    for level in base_by_lod(base, p) {
        for n in level {
            if let BaseKind::Created { refs } = &base[n.first as usize].kind {
                out.extend_from_slice(refs);
            }
        }
    }
    out
}

fn stored<'h>(inputs: &[&'h Hierarchy], at: &Reference) -> Result<&'h Hierarchy, MergeError> {
    inputs
        .iter()
        .find(|h| h.id == at.hier)
        .copied()
        .ok_or(MergeError::UnknownInput(at.hier))
}

fn stored_node(inputs: &[&Hierarchy], at: &Reference) -> Result<NodeRecord, MergeError> {
    let h = stored(inputs, at)?;
    h.nodes
        .get(at.node as usize)
        .copied()
        .ok_or_else(|| MergeError::BadInput {
            input: at.hier,
            node: Some(at.node),
            field: "node index",
            expected: format!("below {}", h.nodes.len()),
            found: at.node.to_string(),
        })
}

/// The code the writer reports before it reads the store (its fill pass):
/// no top, capacity, a level beat's error flag (in that priority).
fn fill_code(b: &BuilderTransaction, created_refs: usize, capacity: u64) -> u64 {
    let top = b.done.top as usize;
    let sent = &b.levels[top.min(b.levels.len())..];
    let over = sent.iter().any(|l| l.len() as u64 - 1 > capacity);
    let flagged = sent.iter().flatten().any(|beat| match beat {
        LevelOut::Node { err, record, .. } => *err || record.count == 0,
        LevelOut::End { err, .. } => *err,
    });
    if b.done.err {
        writer_err::NO_TOP
    } else if over || created_refs as u64 > capacity {
        writer_err::CAPACITY
    } else if flagged {
        writer_err::LEVEL_OVERFLOW
    } else {
        writer_err::NONE
    }
}

/// The reused nodes at the top (materialized roots), in level order: where
/// each is stored and its record as the level beat carries it.
fn top_reused(b: &BuilderTransaction) -> Vec<(Reference, NodeRecord)> {
    b.levels[b.done.top as usize]
        .iter()
        .filter_map(|beat| match beat {
            LevelOut::Node {
                kind, at, record, ..
            } if *kind == level_out_kind::REUSED => Some((*at, *record)),
            _ => None,
        })
        .collect()
}

fn failed(out_id: u8, err: u64) -> Header {
    Header {
        out_id,
        top: 0,
        roots: 0,
        nodes: 0,
        refs: 0,
        err,
    }
}

/// The transaction of one merge over `base` (the upper builder's input)
/// into hierarchy `out_id`, with `inputs` the stored input hierarchies
/// (read for materialized roots) and buffers of `2^capacity_bits`.
/// Errors: an input the store does not hold or a malformed input (as
/// `build_upper` reports them); every writer error is a header code.
pub fn writer_transaction(
    base: &[BaseNode],
    inputs: &[&Hierarchy],
    p: &Params,
    capacity_bits: u32,
    out_id: u8,
) -> Result<WriterTransaction, MergeError> {
    let builder = builder_transaction(base, p);
    let created = created_refs_in_store_order(base, p);
    let mut crefs: Vec<CrefBeat> = created.iter().map(|r| CrefBeat::Ref(*r)).collect();
    crefs.push(CrefBeat::End);
    let mut tx = WriterTransaction {
        out_id,
        crefs,
        ref_reqs: Vec::new(),
        ref_resps: Vec::new(),
        nodes: Vec::new(),
        refs: Vec::new(),
        header: failed(out_id, writer_err::NONE),
        builder,
    };
    let code = fill_code(&tx.builder, created.len(), 1u64 << capacity_bits);
    if code != writer_err::NONE {
        tx.header.err = code;
        return Ok(tx);
    }
    // A materialized root's references are read from the store at the
    // `first` / `count` its beat carries: the stored ones (8.3).
    let roots = top_reused(&tx.builder);
    for (at, beat) in &roots {
        let rec = stored_node(inputs, at)?;
        if (rec.first, rec.count) != (beat.first, beat.count) {
            return Err(MergeError::BadInput {
                input: at.hier,
                node: Some(at.node),
                field: "first/count",
                expected: format!("the stored ({}, {})", rec.first, rec.count),
                found: format!("({}, {}) in the base", beat.first, beat.count),
            });
        }
    }
    match build_upper(base, inputs, p, out_id) {
        Ok((h, _)) => {
            for (at, rec) in &roots {
                let input = stored(inputs, at)?;
                for k in rec.first..rec.first + rec.count {
                    tx.ref_reqs.push(Reference {
                        hier: at.hier,
                        node: k,
                    });
                    tx.ref_resps.push(input.refs[k as usize]);
                }
            }
            tx.header = Header {
                out_id,
                top: h.top_lod,
                roots: h.root_count as u64,
                nodes: h.nodes.len() as u64,
                refs: h.refs.len() as u64,
                err: writer_err::NONE,
            };
            tx.nodes = h.nodes;
            tx.refs = h.refs;
        }
        Err(MergeError::IndexOverflow { .. }) => tx.header.err = writer_err::INDEX_OVERFLOW,
        Err(e) => return Err(e),
    }
    Ok(tx)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::merge::level_choice::candidate_range;
    use crate::merge::stimulus::{per_node_base, random_case, real_cases};
    use crate::merge::upper_builder::unit::fixed_level_base;
    use crate::merge::{merge, MergeMode};
    use crate::translate::stimulus::SplitMix64;
    use crate::translate::Translation;

    /// 8.11's "What the writer adds", read off the in beats alone (the
    /// level beats, `done`, `crefs` and the store's responses): a second
    /// derivation of the layout, to show the beats carry everything the
    /// records and references need.
    fn lay_out_from_beats(tx: &WriterTransaction) -> (Vec<NodeRecord>, Vec<Reference>) {
        let b = &tx.builder;
        let top = b.done.top as usize;
        let nodes_of = |d: usize| -> Vec<(u64, NodeRecord, Reference, u32)> {
            b.levels[d]
                .iter()
                .filter_map(|beat| match beat {
                    LevelOut::Node {
                        kind,
                        record,
                        at,
                        records,
                        ..
                    } => Some((*kind, *record, *at, *records)),
                    LevelOut::End { .. } => None,
                })
                .collect()
        };
        let levels: Vec<_> = (0..b.levels.len()).map(nodes_of).collect();
        let is_record = |d: usize, kind: u64| d == top || kind != level_out_kind::REUSED;
        // off(t) = 0, off(d + 1) = off(d) + level d's records.
        let mut off = vec![0u64; levels.len() + 1];
        for d in top..levels.len() {
            let records = levels[d].iter().filter(|n| is_record(d, n.0)).count() as u64;
            off[d + 1] = off[d] + records;
        }
        let created: Vec<Reference> = tx
            .crefs
            .iter()
            .filter_map(|c| match c {
                CrefBeat::Ref(r) => Some(*r),
                CrefBeat::End => None,
            })
            .collect();
        let (mut nodes, mut refs) = (Vec::new(), Vec::new());
        let mut cref = 0usize;
        let mut mat_refs = tx.ref_resps.iter();
        for d in top..levels.len() {
            let mut child = 0usize;
            for &(kind, rec, _, _) in levels[d].iter().filter(|n| is_record(d, n.0)) {
                let first = refs.len() as u32;
                let count = match kind {
                    level_out_kind::GROUPED => {
                        for &(ck, _, cat, crecords) in
                            &levels[d + 1][child..child + rec.count as usize]
                        {
                            refs.push(if ck == level_out_kind::REUSED {
                                cat
                            } else {
                                Reference {
                                    hier: tx.out_id,
                                    node: (off[d + 1] + crecords as u64) as u32,
                                }
                            });
                        }
                        child += rec.count as usize;
                        rec.count
                    }
                    level_out_kind::CREATED => {
                        refs.extend_from_slice(&created[cref..cref + rec.count as usize]);
                        cref += rec.count as usize;
                        rec.count
                    }
                    _ => {
                        refs.extend(mat_refs.by_ref().take(rec.count as usize));
                        rec.count
                    }
                };
                nodes.push(NodeRecord {
                    leaf: false,
                    first,
                    count,
                    ..rec
                });
            }
        }
        (nodes, refs)
    }

    /// What the real merges reached.
    #[derive(Default, Debug)]
    struct Reached {
        merges: usize,
        materialized: usize,
        several_roots: usize,
        lifted: usize,
        created_lods: usize,
    }

    fn check_real(p: &Params, out_id: u8) -> Reached {
        let mut seen = Reached::default();
        for (store, table, ids) in real_cases(p).expect("the real cases build") {
            let hs: Vec<&Hierarchy> = ids.iter().map(|i| store.get(*i).unwrap()).collect();
            let inputs: Vec<(&Hierarchy, Translation)> = hs
                .iter()
                .map(|h| (*h, table.read(h.id as u32).unwrap()))
                .collect();
            let (lo, hi) = candidate_range(&hs);
            let mut runs: Vec<(MergeMode, Vec<BaseNode>)> = (lo..=hi)
                .map(|m| {
                    (
                        MergeMode::Fixed(m),
                        fixed_level_base(&inputs, m, p).unwrap(),
                    )
                })
                .collect();
            for (num, den) in [(0, 1), (1, 4), (1, 2)] {
                let mode = MergeMode::PerNode { num, den };
                runs.push((mode, per_node_base(&inputs, num, den, p).unwrap()));
            }
            for (mode, base) in runs {
                let tx = writer_transaction(&base, &hs, p, 12, out_id).unwrap();
                let r = merge(&store, &ids, &table, mode, out_id).unwrap();
                assert_eq!(tx.header.err, writer_err::NONE, "{mode}");
                assert_eq!(tx.nodes, r.merged.nodes, "{mode}");
                assert_eq!(tx.refs, r.merged.refs, "{mode}");
                assert_eq!(tx.header.roots, r.merged.root_count as u64, "{mode}");
                assert_eq!(tx.header.top, r.merged.top_lod, "{mode}");
                assert_eq!(tx.header.nodes, r.merged.nodes.len() as u64);
                assert_eq!(tx.header.refs, r.merged.refs.len() as u64);
                assert_eq!(lay_out_from_beats(&tx), (tx.nodes.clone(), tx.refs.clone()));
                seen.merges += 1;
                seen.materialized += (r.stats.materialized > 0) as usize;
                seen.several_roots += (r.merged.root_count > 1) as usize;
                seen.lifted += (r.stats.lifted > 0) as usize;
                let lods: std::collections::BTreeSet<u8> = base
                    .iter()
                    .filter(|b| matches!(b.kind, BaseKind::Created { .. }))
                    .map(|b| b.record.voxel.lod)
                    .collect();
                seen.created_lods += (lods.len() > 1) as usize;
            }
        }
        seen
    }

    /// On real merges (fixed levels and per-node mode), the transaction's
    /// expected output is `merge()`'s merged hierarchy, and the in beats
    /// alone give it back.
    #[test]
    fn expected_output_is_merges_hierarchy() {
        let p = Params::default();
        let seen = check_real(&p, 9);
        eprintln!("real merges at the default: {seen:?}");
        assert!(seen.merges >= 10 && seen.materialized > 0, "{seen:?}");
        let seen = check_real(&Params::new(8, 0, 12, 3).unwrap(), 7);
        assert!(seen.merges >= 5, "{seen:?}");
    }

    /// Random bases: every header code is reached; with no error the
    /// transaction's records and references equal the layout read off the
    /// beats, the header counts them, the store reads are the top's reused
    /// nodes; with an error nothing is written.
    #[test]
    fn random_cases_reach_every_code_and_match_the_beats() {
        for (p, cap) in [
            (Params::new(6, 2, 10, 3).unwrap(), 3),
            (Params::new(5, 2, 3, 2).unwrap(), 2),
        ] {
            let mut rng = SplitMix64(0x5a1e + cap as u64);
            let mut codes = [0usize; 5];
            let (mut materialized, mut several_roots, mut created_lods) = (0, 0, 0);
            for _ in 0..3000 {
                let n = rng.below(12) as usize;
                let (base, inputs) = random_case(&mut rng, &p, n, 0);
                let lods: std::collections::BTreeSet<u8> = base
                    .iter()
                    .filter(|b| matches!(b.kind, BaseKind::Created { .. }))
                    .map(|b| b.record.voxel.lod)
                    .collect();
                created_lods += (lods.len() > 1) as usize;
                let hs: Vec<&Hierarchy> = inputs.iter().collect();
                let tx = writer_transaction(&base, &hs, &p, cap, 0).unwrap();
                codes[tx.header.err as usize] += 1;
                if tx.header.err == writer_err::NONE {
                    assert_eq!(lay_out_from_beats(&tx), (tx.nodes.clone(), tx.refs.clone()));
                    assert_eq!(tx.header.nodes, tx.nodes.len() as u64);
                    assert_eq!(tx.header.refs, tx.refs.len() as u64);
                    assert_eq!(tx.ref_reqs.len(), tx.ref_resps.len());
                    materialized += !tx.ref_reqs.is_empty() as usize;
                    several_roots += (tx.header.roots > 1) as usize;
                } else {
                    assert!(tx.nodes.is_empty() && tx.refs.is_empty() && tx.ref_reqs.is_empty());
                }
            }
            assert!(
                materialized > 0 && several_roots > 0 && created_lods > 0,
                "{codes:?}"
            );
            // LEVEL_OVERFLOW needs a level of 2^I nodes (over the capacity,
            // which comes first) or a corrupt child box: not reached here.
            let need: &[u64] = if p.index_bits <= 3 {
                &[0, 1, 2, 4]
            } else {
                &[0, 1, 2]
            };
            for &c in need {
                assert!(codes[c as usize] > 0, "code {c} never reached: {codes:?}");
            }
        }
    }

    #[test]
    fn capacity_outside_one_to_i_is_refused() {
        let p = Params::default();
        assert!(WriterLayout::new(&p, 0).is_err());
        assert!(WriterLayout::new(&p, p.index_bits as u32).is_err());
        assert!(WriterLayout::new(&p, p.index_bits as u32 - 1).is_ok());
        let msg = WriterLayout::new(&p, 0).unwrap_err().to_string();
        assert!(msg.contains("capacity_bits = 0"), "{msg}");
    }
}
