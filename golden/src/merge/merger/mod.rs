//! The hierarchy merger as one unit (SPEC.md section 8.15,
//! `rtl_gen::merge::hierarchy_merger_unit`): S610-S618 end to end, as the
//! chain of the units' golden transactions. Nothing here recomputes a merge:
//! every stream is what a unit's own transaction says it carries, and the
//! chain only routes one unit's out beats to the next unit's in beats the way
//! the merger's glue does.
//!
//! One merge:
//! 1. `cfg`: per input its fetcher `cfg` ([`FetchCfg`]: header and packed
//!    translation entry), the number of inputs `n <= k`, the candidate range
//!    `(lo, hi)` (8.2, computed by software from the headers: the hardware
//!    does not scan the inputs' node arrays for `deep(i)`) and `out_id`.
//! 2. The controller sends the merging module `(lo, hi)` and, in overlap
//!    mode with a good range, one fetcher command to every used fetcher that
//!    walks once to `hi` and sends every candidate level `lo..=hi` in turn
//!    (the **count pass**: no references, no leaves); the fetchers' `out`
//!    beats are the module's `in<i>` (an unused input `i >= n` gets one
//!    `End` per level from the glue).
//! 3. The module's `report` ends with the choice. Chosen `m`: every fetcher
//!    gets the **merge pass** (LOD `m`, references, the leaves above `m`,
//!    last) ([`controller_cmds`]);
//!    refused: a **closing** command (LOD `lo`, nothing sent but the walk,
//!    last) whose `out` beats the glue drops, and the base is empty.
//! 4. The module's `out` at `m`: created and reused nodes go to the upper
//!    builder's `base{m}`, reference beats to the writer's `crefs`. The
//!    fetchers' `leaves` (each in (LOD, Morton) order) are merged by
//!    (LOD, Morton, rank) into the builder's `base{d}`, `d < m`.
//! 5. The builder's `level{d}` and `done` feed the writer, which reads the
//!    materialized roots from the store and writes `nodes`, `refs`, `header`.
//!
//! Per-node mode (8.5): [`per_node_transaction`] is the module; with a
//! good range every used fetcher gets one **per-node command** at `lo`
//! (leaves above `lo`, last) and the module's `report` beats, and sends the
//! module's input stream pass after pass (probes, nodes, references; 8.13),
//! which the chain checks equal to the module's inputs; a bad range gets
//! the closing command.

pub mod store_port;

use crate::bits::Bits;
use crate::layout::{Field, Layout, LayoutError};
use crate::merge::error::MergeError;
use crate::merge::fetcher::walk::{collect, morton, walk_input, PlacedNode};
use crate::merge::fetcher::{
    fetch_err, fetch_transaction_with_reports, FetchCfg, FetchCmd, FetchLayout, FetchOut,
    FetchSizes, FetchTransaction, LeafOut,
};
use crate::merge::level_choice::candidate_range;
use crate::merge::level_choice::unit::rank_bits;
use crate::merge::merge_level::unit::{BaseBeat, LevelBeat, LevelCase};
use crate::merge::merge_level::{BaseKind, BaseNode};
use crate::merge::merge_module::{
    choice_err, choose, top_transaction, Report, TopLayout, TopTransaction,
};
use crate::merge::merger::store_port::StorePort;
use crate::merge::per_node::unit::{per_node_transaction, PerNodeBeat, PerNodeTransaction};
use crate::merge::record_writer::{
    writer_transaction, CapacityError, Header, WriterLayout, WriterTransaction,
};
use crate::merge::upper_builder::unit::BuilderTransaction;
use crate::merge::MergeMode;
use crate::params::{bits_to_hold, Params};
use crate::store::{Hierarchy, HierarchyStore, Reference};
use crate::translate::table::pack_entry;
use crate::translate::{Translation, TranslationTable};

/// The merger's fixed sizes: the fetchers' (root sorter, frontier FIFO),
/// the writer's buffers (`2^capacity_bits` entries) and the leaf FIFO of
/// every LOD (`2^leaf_bits` leaves).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MergerSizes {
    /// Every fetcher's root sorter capacity and frontier depth.
    pub fetch: FetchSizes,
    /// `C`: the writer's buffers hold `2^C` entries (`1..I`).
    pub capacity_bits: u32,
    /// Each LOD's leaf FIFO holds `2^leaf_bits` entries (`1..=16`).
    pub leaf_bits: u32,
    /// How the units reach the store: each its own read streams (the
    /// default), or one shared port.
    pub store_port: StorePort,
}

impl MergerSizes {
    /// The default fetcher sizes, a writer of `2^10` entries per buffer and
    /// leaf FIFOs of 16.
    pub fn new(p: &Params) -> MergerSizes {
        MergerSizes {
            fetch: FetchSizes::default(),
            capacity_bits: 10.min(p.index_bits as u32 - 1),
            leaf_bits: 4,
            store_port: StorePort::PerUnit,
        }
    }
}

/// The merger's `header` beat: the writer's header, then flags of what the
/// merger's glue saw.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MergerHeader {
    /// The record writer's `header` beat (the low bits).
    pub writer: Header,
    /// A leaf FIFO was full when a leaf of its LOD came: the leaf was not
    /// stored and the merged hierarchy is wrong (make `leaf_bits` larger).
    pub leaf_overflow: bool,
    /// A created node's reference count reached `2^I` (S614's `err`).
    pub count_overflow: bool,
    /// The first fetcher error code of the merge ([`fetch_err`]; 0 none) and
    /// the input rank that reported it.
    pub fetch_err: u64,
    /// The rank of the input whose fetcher reported `fetch_err` (0 when none).
    pub fetch_rank: u16,
}

impl MergerHeader {
    /// The packed beat.
    pub fn pack(&self, l: &MergerLayout) -> Result<Bits, LayoutError> {
        let mut b = l.header.zero();
        b.put(0, &self.writer.pack(&l.writer)?)?;
        b.set(&l.leaf_overflow, self.leaf_overflow as u64)?;
        b.set(&l.count_overflow, self.count_overflow as u64)?;
        b.set(&l.fetch_err, self.fetch_err)?;
        b.set(&l.fetch_rank, self.fetch_rank as u64)?;
        Ok(b)
    }
}

/// Bit layout of the merger's `cfg` beat, from bit 0: `input0` ..
/// `input{k-1}` (each a fetcher `cfg` beat, [`FetchLayout::cfg`]), `count` (`bits_to_hold(k)`: inputs used, `1..=k`), `lo`, `hi`
/// (`lod_bits` each), `out_id` (H). `report` is the merging module's
/// ([`TopLayout`]). `header`, from bit 0: the writer's header
/// ([`WriterLayout`]), `leaf_overflow`, `count_overflow` (1 each),
/// `fetch_err` ([`fetch_err::BITS`]), `fetch_rank` (`rank_bits(k)`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MergerLayout {
    /// The number of inputs (fetchers) the merger is built with.
    pub k: usize,
    /// Every fetcher's layouts; `input<i>` is a fetcher `cfg` beat.
    pub fetch: FetchLayout,
    /// The merging module's layouts; `report` is its `report` beat.
    pub top: TopLayout,
    /// The record writer's layouts; `header` starts with its header.
    pub writer: WriterLayout,
    /// Width of each `input<i>` field of `cfg`, the fetcher's `cfg` beat
    /// (`fetch.cfg.width()`); `input<i>` starts at [`Self::input_offset`].
    pub input_width: u32,
    /// `cfg`: `count` (`bits_to_hold(k)`), the inputs used, after `input{k-1}`.
    pub count: Field,
    /// `cfg`: `lo` (`lod_bits`), the shallowest candidate level.
    pub lo: Field,
    /// `cfg`: `hi` (`lod_bits`), the deepest candidate level.
    pub hi: Field,
    /// `cfg`: `out_id` (H bits), the merged hierarchy's id.
    pub out_id: Field,
    /// The `cfg` beat: `input0` .. `input{k-1}`, `count`, `lo`, `hi`, `out_id`.
    pub cfg: Layout,
    /// `header`: `leaf_overflow` (1 bit), right after the writer's header.
    pub leaf_overflow: Field,
    /// `header`: `count_overflow` (1 bit).
    pub count_overflow: Field,
    /// `header`: `fetch_err` ([`fetch_err::BITS`] bits), the first fetcher error code.
    pub fetch_err: Field,
    /// `header`: `fetch_rank` (`rank_bits(k)`), the rank that reported it.
    pub fetch_rank: Field,
    /// The `header` beat: the writer's header fields, then `leaf_overflow`,
    /// `count_overflow`, `fetch_err`, `fetch_rank`.
    pub header: Layout,
}

impl MergerLayout {
    /// The layout for `p`, `k` inputs and writer buffers of `2^capacity_bits`.
    pub fn new(p: &Params, k: usize, capacity_bits: u32) -> Result<MergerLayout, CapacityError> {
        let fetch = FetchLayout::new(p);
        let input_width = fetch.cfg.width();
        let lb = p.lod_bits();
        let mut cfg = Layout::new("merger cfg");
        for i in 0..k {
            cfg.push(&format!("input{i}"), input_width);
        }
        let count = cfg.push("count", bits_to_hold(k as u64));
        let lo = cfg.push("lo", lb);
        let hi = cfg.push("hi", lb);
        let out_id = cfg.push("out_id", p.hier_bits as u32);
        let writer = WriterLayout::new(p, capacity_bits)?;
        let mut header = Layout::new("merger header");
        for f in writer.header.fields() {
            header.push(f.name, f.width);
        }
        let leaf_overflow = header.push("leaf_overflow", 1);
        let count_overflow = header.push("count_overflow", 1);
        let fetch_err = header.push("fetch_err", fetch_err::BITS);
        let fetch_rank = header.push("fetch_rank", rank_bits(k));
        Ok(MergerLayout {
            k,
            top: TopLayout::new(p),
            writer,
            leaf_overflow,
            count_overflow,
            fetch_err,
            fetch_rank,
            header,
            fetch,
            input_width,
            count,
            lo,
            hi,
            out_id,
            cfg,
        })
    }

    /// Where `input<i>` starts in `cfg`.
    pub fn input_offset(&self, i: usize) -> u32 {
        i as u32 * self.input_width
    }
}

/// The merger's `cfg` beat.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MergerCfg {
    /// The used inputs' fetcher configurations, in rank order.
    pub inputs: Vec<FetchCfg>,
    /// The shallowest candidate level (8.2's `lo`, or any range software sends).
    pub lo: u8,
    /// The deepest candidate level.
    pub hi: u8,
    /// The merged hierarchy's id.
    pub out_id: u8,
}

impl MergerCfg {
    /// The packed beat (unused inputs' fields 0); an error when more inputs
    /// than `k` or a value does not fit its field.
    pub fn pack(&self, l: &MergerLayout) -> Result<Bits, LayoutError> {
        if self.inputs.len() > l.k {
            return Err(LayoutError::DoesNotFit {
                field: "count",
                value: self.inputs.len() as u64,
                width: l.count.width,
            });
        }
        let mut b = l.cfg.zero();
        for (i, c) in self.inputs.iter().enumerate() {
            b.put(l.input_offset(i), &c.pack(&l.fetch)?)?;
        }
        b.set(&l.count, self.inputs.len() as u64)?;
        b.set(&l.lo, self.lo as u64)?;
        b.set(&l.hi, self.hi as u64)?;
        b.set(&l.out_id, self.out_id as u64)?;
        Ok(b)
    }
}

/// The merging module's run inside the merger.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ModulePass {
    /// A single merging level (overlap, fixed, below-top, proportion).
    Level(TopTransaction),
    /// Per-node merging.
    PerNode(PerNodeTransaction),
}

impl ModulePass {
    /// The module's `out` beats.
    pub fn out(&self) -> &[BaseBeat] {
        match self {
            ModulePass::Level(t) => &t.out,
            ModulePass::PerNode(t) => &t.out,
        }
    }
}

/// One merge through the merger: the in beats (`cfg`, the store's
/// responses inside each unit's transaction) and every unit's streams.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MergerTransaction {
    /// The merging mode built into the merger.
    pub mode: MergeMode,
    /// The `cfg` beat.
    pub cfg: MergerCfg,
    /// The commands the controller issues to every used fetcher.
    pub cmds: Vec<FetchCmd>,
    /// Per used input (rank order): the fetcher's run over `cmds`, with its
    /// memory requests and responses.
    pub fetch: Vec<FetchTransaction>,
    /// The merging module's run: count pass, choice and merge pass, or the
    /// per-node passes.
    pub module: ModulePass,
    /// The merging level (`None`: per-node mode or refused).
    pub chosen: Option<u8>,
    /// The inputs' leaves above the merging level, reused, merged by
    /// (LOD, Morton, rank): what the leaf merge pushes into the leaf FIFOs.
    pub leaves: Vec<BaseNode>,
    /// The builder's base: the leaves the FIFOs kept ([`kept_leaves`]), then
    /// the module's nodes.
    pub base: Vec<BaseNode>,
    /// Whether the RTL writes this merge bit for bit whatever the timing of
    /// its streams: false when per-node mode's FIFO of a LOD receives more of
    /// the module's nodes than it holds ([`MergerHeader::leaf_overflow`]),
    /// since a dropped created node's references still reach the writer's
    /// `crefs`, a merged hierarchy golden does not model (its `writer` is of
    /// every node). Dropped leaves are modelled in every mode
    /// ([`kept_leaves`]).
    pub exact: bool,
    /// The writer's run (its `builder` is the upper builder's run).
    pub writer: WriterTransaction,
    /// The merger's `header` beat.
    pub header: MergerHeader,
}

impl MergerTransaction {
    /// The upper builder's run.
    pub fn builder(&self) -> &BuilderTransaction {
        &self.writer.builder
    }

    /// The merging module's `report` beats (level modes; per-node mode's
    /// reports are [`PerNodeTransaction::reports`]).
    pub fn reports(&self) -> &[Report] {
        match &self.module {
            ModulePass::Level(t) => &t.reports,
            ModulePass::PerNode(_) => &[],
        }
    }
}

/// The fetcher commands of a merge: the count pass (`count`: overlap mode,
/// a good range `(lo, hi)`: one walk to `hi` sending every level
/// `lo..=hi`); then, chosen `m`, the **merge pass** (LOD
/// `m`, references, the leaves above `m`, last); refused, the **closing**
/// command at `lo` (its beats are dropped). The leaves come with level `m`
/// in one walk: the fetcher ends its `leaves` stream before it visits level
/// `m`, so the leaf merge never waits on a fetcher whose level beats wait
/// in the merging module (SPEC 8.15's deadlock argument).
pub fn controller_cmds(count: Option<(u8, u8)>, chosen: Option<u8>, lo: u8) -> Vec<FetchCmd> {
    let mut cmds: Vec<FetchCmd> = count
        .map(|(from, hi)| FetchCmd {
            from,
            ..FetchCmd::level(hi, false, false, false)
        })
        .into_iter()
        .collect();
    match chosen {
        Some(m) => cmds.push(FetchCmd::level(m, true, true, true)),
        None => cmds.push(FetchCmd::level(lo, false, false, true)),
    }
    cmds
}

/// Each command of `cmds` once per level it sends: the per-level passes of
/// a fetcher's `out` ([`fetch_passes`]) line up with these.
pub fn cmd_per_level(cmds: &[FetchCmd]) -> Vec<FetchCmd> {
    cmds.iter()
        .flat_map(|c| std::iter::repeat_n(*c, c.levels()))
        .collect()
}

/// Whether a command's `out` beats go to the merging module (count, merge
/// and per-node passes) or are dropped by the glue (the closing command).
pub fn feeds_module(c: &FetchCmd) -> bool {
    c.send_refs || !c.last
}

/// A fetcher's `out` beats split per sent level (each ends with `End`); an
/// error beat is refused naming the input, record and code.
pub fn fetch_passes(tx: &FetchTransaction) -> Result<Vec<Vec<LevelBeat>>, MergeError> {
    let mut passes = vec![Vec::new()];
    for o in &tx.out {
        match *o {
            FetchOut::Beat(b) => {
                passes.last_mut().expect("one open pass").push(b);
                if b == LevelBeat::End {
                    passes.push(Vec::new());
                }
            }
            FetchOut::Error { hier, node, code } => return Err(fetch_error(hier, node, code)),
            FetchOut::Probe { at, .. } => {
                return Err(MergeError::BadInput {
                    input: at.hier,
                    node: Some(at.node),
                    field: "fetcher out",
                    expected: "no probe beat from a level command".into(),
                    found: "a probe".into(),
                })
            }
        }
    }
    passes.pop();
    Ok(passes)
}

/// A fetcher error beat as the chain's refusal.
fn fetch_error(hier: u8, node: u32, code: u64) -> MergeError {
    MergeError::BadInput {
        input: hier,
        node: Some(node),
        field: "fetcher walk",
        expected: "no fetcher error (fetcher::fetch_err)".into(),
        found: format!("error code {code} ({})", fetch_err_name(code)),
    }
}

/// A fetcher's `out` beats of a per-node command as the per-node module's
/// input stream (probes and S614 beats, every pass); an error beat is
/// refused naming the input, record and code.
pub fn fetch_per_node_stream(tx: &FetchTransaction) -> Result<Vec<PerNodeBeat>, MergeError> {
    tx.out
        .iter()
        .map(|o| match *o {
            FetchOut::Beat(b) => Ok(PerNodeBeat::Level(b)),
            FetchOut::Probe { record, at } => Ok(PerNodeBeat::Probe { record, at }),
            FetchOut::Error { hier, node, code } => Err(fetch_error(hier, node, code)),
        })
        .collect()
}

/// What a [`fetch_err`] code means, for error messages.
pub fn fetch_err_name(code: u64) -> &'static str {
    match code {
        fetch_err::ENTRY => "invalid translation entry",
        fetch_err::ROOT_COUNT => "root_count 0 or above nodes",
        fetch_err::ROOT_CAPACITY => "more roots than the root sorter holds",
        fetch_err::RECORD => "record does not validate",
        fetch_err::LOD => "node not at its parent's LOD + 1",
        fetch_err::RANGE => "reference range outside refs",
        fetch_err::REF_HIER => "reference names another hierarchy",
        fetch_err::REF_NODE => "reference to a missing node",
        fetch_err::ABOVE => "node above the translation level",
        fetch_err::OUTSIDE_X | fetch_err::OUTSIDE_Y | fetch_err::OUTSIDE_Z => {
            "node moved outside the scene"
        }
        fetch_err::FRONTIER => "frontier FIFO full",
        fetch_err::ORDER => "node out of Morton order",
        _ => "unknown code",
    }
}

/// The leaves of a fetcher's last command, as reused base nodes of `rank`.
fn fetched_leaves(tx: &FetchTransaction, rank: u16) -> Vec<(PlacedNode, u16)> {
    tx.leaves
        .iter()
        .filter_map(|l| match *l {
            LeafOut::Leaf { record, at } => Some((PlacedNode { rank, at, record }, rank)),
            LeafOut::End => None,
        })
        .collect()
}

/// The k-way merge of the fetchers' leaves by (LOD, Morton, rank): each
/// stream is in (LOD, Morton) order, so this is a stable sort of their
/// concatenation in rank order.
pub fn merge_leaves(fetch: &[FetchTransaction]) -> Vec<BaseNode> {
    let mut all: Vec<(PlacedNode, u16)> = fetch
        .iter()
        .enumerate()
        .flat_map(|(r, tx)| fetched_leaves(tx, r as u16))
        .collect();
    all.sort_by_key(|(n, r)| (n.record.voxel.lod, morton(&n.record.voxel), *r));
    all.iter().map(|(n, _)| BaseNode::reused(n)).collect()
}

/// The leaves the leaf FIFOs keep: the first `2^leaf_bits` of each LOD, in
/// the order of `leaves` (the leaf merge's). A leaf pushed into a full FIFO
/// is dropped (8.15 step 4), and no FIFO is read before the leaves are
/// complete (the level modes' `base{d}` above the merging level waits for
/// them; per-node mode's builder sees nothing before the module is done and
/// the leaves are complete), so what a FIFO keeps is a function of the data.
pub fn kept_leaves(leaves: &[BaseNode], leaf_bits: u32) -> Vec<BaseNode> {
    let mut per_lod = std::collections::BTreeMap::<u8, u64>::new();
    leaves
        .iter()
        .filter(|n| {
            let c = per_lod.entry(n.record.voxel.lod).or_default();
            *c += 1;
            *c <= 1u64 << leaf_bits
        })
        .cloned()
        .collect()
}

/// Whether some LOD has more leaves than its FIFO holds (`2^leaf_bits`).
pub fn leaf_overflow(leaves: &[BaseNode], leaf_bits: u32) -> bool {
    let mut per_lod = std::collections::BTreeMap::<u8, u64>::new();
    for n in leaves {
        *per_lod.entry(n.record.voxel.lod).or_default() += 1;
    }
    per_lod.values().any(|&c| c > 1u64 << leaf_bits)
}

/// The base nodes the module's `out` beats carry (created nodes with the
/// reference beats that follow them), in stream order per LOD, shallowest
/// LOD first; an error when a created node's reference count overflowed.
pub fn module_base(out: &[BaseBeat], p: &Params) -> Result<Vec<BaseNode>, MergeError> {
    let by_lod =
        crate::merge::per_node::unit::base_by_lod(out, p).ok_or(MergeError::IndexOverflow {
            what: "created node's reference count",
            value: p.index_capacity(),
            index_bits: p.index_bits,
        })?;
    Ok(by_lod.into_iter().flatten().collect())
}

/// The inputs of a merge: hierarchies and translations, checked as the
/// merger needs them (1..=k inputs in the store; entries read from `table`,
/// an invalid one packed as 0 for the fetcher to refuse).
fn inputs_of<'s>(
    store: &'s HierarchyStore,
    table: &TranslationTable,
    ids: &[u8],
    k: usize,
) -> Result<(Vec<&'s Hierarchy>, Vec<Option<Translation>>), MergeError> {
    if ids.is_empty() {
        return Err(MergeError::NoInputs);
    }
    if ids.len() > k {
        return Err(MergeError::IndexOverflow {
            what: "inputs of the merger (its k)",
            value: ids.len() as u64,
            index_bits: bits_to_hold(k as u64) as u8,
        });
    }
    let hs = ids
        .iter()
        .map(|&id| store.get(id).ok_or(MergeError::UnknownInput(id)))
        .collect::<Result<Vec<_>, _>>()?;
    let ts = ids
        .iter()
        .map(|&id| table.get(id as u32).ok().flatten())
        .collect();
    Ok((hs, ts))
}

/// One level's placed nodes of all inputs, as the merging module's
/// transaction takes them.
fn level_case(hs: &[&Hierarchy], ts: &[Translation], lod: u8) -> Result<LevelCase, MergeError> {
    let walked = hs
        .iter()
        .zip(ts)
        .enumerate()
        .map(|(r, (h, t))| walk_input(h, r as u16, t, lod))
        .collect::<Result<Vec<_>, _>>()?;
    let (_, at_level) = collect(&walked, lod);
    Ok(LevelCase {
        hierarchies: hs.iter().map(|h| (*h).clone()).collect(),
        at_level,
    })
}

/// The merge of `ids` (rank order) of `store`, placed by `table`, into
/// `out_id`, through a merger of `k` inputs with `sizes`: every unit's
/// streams. Errors (never a panic): inputs missing or more than `k`, a
/// malformed input or translation (the walk's and the fetcher's refusals),
/// a created node's reference count at `2^I`, a writer capacity outside
/// `1..I`.
pub fn merger_transaction(
    store: &HierarchyStore,
    table: &TranslationTable,
    ids: &[u8],
    mode: MergeMode,
    out_id: u8,
    k: usize,
    sizes: MergerSizes,
) -> Result<MergerTransaction, MergeError> {
    merger_transaction_in_range(store, table, ids, mode, out_id, k, sizes, None)
}

/// [`merger_transaction`] with the `cfg` beat's `(lo, hi)` given instead of
/// 8.2's candidate range (software may send any range: a bad one, `lo > hi`
/// or `hi > D`, is the merging module's refusal).
#[allow(clippy::too_many_arguments)]
pub fn merger_transaction_in_range(
    store: &HierarchyStore,
    table: &TranslationTable,
    ids: &[u8],
    mode: MergeMode,
    out_id: u8,
    k: usize,
    sizes: MergerSizes,
    range: Option<(u8, u8)>,
) -> Result<MergerTransaction, MergeError> {
    let (hs, entries) = inputs_of(store, table, ids, k)?;
    let p = hs[0].params;
    let (lo, hi) = range.unwrap_or_else(|| candidate_range(&hs));
    let ts: Vec<Translation> = entries
        .iter()
        .zip(ids)
        .map(|(t, &id)| {
            t.ok_or(MergeError::Translation {
                input: id,
                error: crate::translate::TranslateError::EmptyEntry { id: id as u32 },
            })
        })
        .collect::<Result<_, _>>()?;
    let cfg = MergerCfg {
        inputs: hs
            .iter()
            .zip(&entries)
            .map(|(h, t)| FetchCfg::of(h, t.as_ref()))
            .collect(),
        lo,
        hi,
        out_id,
    };
    let range_ok = lo <= hi && hi <= p.max_lod;
    let (module, cmds, chosen) = match mode {
        MergeMode::PerNode { num, den } => {
            let pn = per_node_transaction(&p, &hs, &ts, num, den, lo, hi)?;
            let cmds = vec![if range_ok {
                FetchCmd::per_node(lo, true, true)
            } else {
                FetchCmd::level(lo, false, false, true)
            }];
            (ModulePass::PerNode(pn), cmds, None)
        }
        _ => {
            let count_pass: Vec<u8> = match mode {
                MergeMode::Overlap { .. } if range_ok => (lo..=hi).collect(),
                _ => Vec::new(),
            };
            let mut levels: Vec<Option<LevelCase>> = vec![None; (hi.max(lo) - lo) as usize + 1];
            for &l in &count_pass {
                levels[(l - lo) as usize] = Some(level_case(&hs, &ts, l)?);
            }
            // Outside overlap mode the choice needs no counts: only the
            // chosen level is walked.
            if count_pass.is_empty() {
                if let Report::Chosen {
                    lod,
                    err: choice_err::NONE,
                } = choose(&mode, &p, lo, hi, &[])
                {
                    levels[(lod - lo) as usize] = Some(level_case(&hs, &ts, lod)?);
                }
            }
            let top = top_transaction(&mode, &p, k, lo, hi, &levels, false)?;
            let chosen = top.reports.iter().find_map(|r| match *r {
                Report::Chosen {
                    lod,
                    err: choice_err::NONE,
                } => Some(lod),
                _ => None,
            });
            let count = (!count_pass.is_empty()).then_some((lo, hi));
            let cmds = controller_cmds(count, chosen, lo);
            (ModulePass::Level(top), cmds, chosen)
        }
    };
    // Every fetcher takes the whole `report` stream (per-node commands).
    let reports = match &module {
        ModulePass::PerNode(pn) => pn.reports.as_slice(),
        ModulePass::Level(_) => &[],
    };
    let fetch = hs
        .iter()
        .zip(&entries)
        .map(|(h, t)| {
            let entry = pack_entry(t.as_ref(), &p);
            fetch_transaction_with_reports(h, entry, &cmds, reports, sizes.fetch)
        })
        .collect::<Result<Vec<_>, _>>()?;
    for f in &fetch {
        match cmds[0].per_node {
            true => fetch_per_node_stream(f).map(|_| ())?,
            false => fetch_passes(f).map(|_| ())?,
        }
    }
    let ok = match &module {
        ModulePass::Level(_) => chosen.is_some(),
        ModulePass::PerNode(pn) => pn.passes > 0,
    };
    let (leaves, nodes) = if ok {
        (merge_leaves(&fetch), module_base(module.out(), &p)?)
    } else {
        (Vec::new(), Vec::new())
    };
    // Per-node mode's FIFOs hold the module's nodes as well (SPEC 8.15), at
    // LODs from `lo` down, where no leaf is.
    let nodes_over =
        matches!(module, ModulePass::PerNode(_)) && leaf_overflow(&nodes, sizes.leaf_bits);
    let exact = !nodes_over;
    let mut base = kept_leaves(&leaves, sizes.leaf_bits);
    base.extend(nodes);
    let writer = writer_transaction(&base, &hs, &p, sizes.capacity_bits, out_id)?;
    let header = MergerHeader {
        writer: writer.header,
        leaf_overflow: leaf_overflow(&leaves, sizes.leaf_bits) || nodes_over,
        count_overflow: false,
        fetch_err: fetch_err::NONE,
        fetch_rank: 0,
    };
    Ok(MergerTransaction {
        header,
        mode,
        cfg,
        cmds,
        fetch,
        module,
        chosen,
        leaves,
        base,
        exact,
        writer,
    })
}

/// The reference beats of the module's `out` in stream order: the writer's
/// `crefs` (before its `End`) at a single merging level.
pub fn module_refs(out: &[BaseBeat]) -> Vec<Reference> {
    out.iter()
        .filter_map(|b| match b {
            BaseBeat::Ref(r) => Some(*r),
            _ => None,
        })
        .collect()
}

/// The module's created and reused nodes at `m` as the builder's `base{m}`
/// beats (reference beats dropped), `End` last.
pub fn module_nodes(out: &[BaseBeat]) -> Vec<BaseBeat> {
    out.iter()
        .filter(|b| !matches!(b, BaseBeat::Ref(_)))
        .copied()
        .collect()
}

/// The base kinds of `base` (for counting what a case reached).
pub fn created_count(base: &[BaseNode]) -> usize {
    base.iter()
        .filter(|b| matches!(b.kind, BaseKind::Created { .. }))
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::merge::record_writer::{writer_err, CrefBeat};
    use crate::merge::stimulus::{real_cases, several_roots_case, soup, try_scene_soup, RealCase};
    use crate::merge::{merge, MergeMode};

    fn modes(lo: u8, hi: u8) -> Vec<MergeMode> {
        let mut v = vec![
            MergeMode::Overlap { num: 1, den: 2 },
            MergeMode::Overlap { num: 0, den: 1 },
            MergeMode::Overlap { num: 1, den: 1 },
            MergeMode::BelowTop(0),
            MergeMode::BelowTop(hi - lo),
            MergeMode::Proportion { num: 1, den: 2 },
            MergeMode::Proportion { num: 1, den: 1 },
            MergeMode::PerNode { num: 0, den: 1 },
            MergeMode::PerNode { num: 1, den: 2 },
            MergeMode::PerNode { num: 1, den: 4 },
            MergeMode::PerNode { num: 1, den: 1 },
        ];
        v.extend((lo..=hi).map(MergeMode::Fixed));
        v
    }

    /// Every hand-off between two units carries what the receiving unit's
    /// transaction expects.
    fn check_hand_offs(tx: &MergerTransaction, p: &Params, k: usize) {
        let b = tx.builder();
        if let ModulePass::PerNode(pn) = &tx.module {
            // Fetcher out -> module in<i>: every pass of the per-node
            // command is the module's input stream; each fetcher took the
            // module's whole `report`.
            if pn.passes > 0 {
                assert!(tx.cmds.len() == 1 && tx.cmds[0].per_node);
                for (r, f) in tx.fetch.iter().enumerate() {
                    assert_eq!(fetch_per_node_stream(f).unwrap(), pn.inputs[r], "input {r}");
                    assert_eq!(f.reports, pn.reports, "input {r}");
                }
                // Module out -> builder base{d} at and below lo.
                let by_lod = crate::merge::per_node::unit::base_by_lod(&pn.out, p).unwrap();
                for (d, nodes) in by_lod.iter().enumerate().skip(tx.cfg.lo as usize) {
                    let got: Vec<&BaseBeat> =
                        b.base[d].iter().filter(|x| **x != BaseBeat::End).collect();
                    assert_eq!(got.len(), nodes.len(), "base{d}");
                }
                // Module out -> writer crefs: every pass's reference beats
                // in stream order (shallow pass first), then End.
                let mut crefs: Vec<CrefBeat> = module_refs(&pn.out)
                    .into_iter()
                    .map(CrefBeat::Ref)
                    .collect();
                crefs.push(CrefBeat::End);
                assert_eq!(tx.writer.crefs, crefs);
            } else {
                assert!(!tx.cmds[0].per_node && !feeds_module(&tx.cmds[0]));
            }
        }
        if let ModulePass::Level(top) = &tx.module {
            // Fetcher out -> module in<i>, pass by pass (the closing
            // command's beats are dropped).
            for (r, f) in tx.fetch.iter().enumerate() {
                let passes = fetch_passes(f).unwrap();
                let per_level = cmd_per_level(&tx.cmds);
                assert_eq!(passes.len(), per_level.len());
                let fed: Vec<LevelBeat> = passes
                    .iter()
                    .zip(&per_level)
                    .filter(|(_, c)| feeds_module(c))
                    .flat_map(|(p, _)| p.iter().copied())
                    .collect();
                assert_eq!(fed, top.inputs[r], "input {r}");
            }
            for r in tx.fetch.len()..k {
                assert!(top.inputs[r].iter().all(|b| *b == LevelBeat::End));
            }
            if let Some(m) = tx.chosen {
                // Module out -> builder base{m} and writer crefs.
                assert_eq!(b.base[m as usize], module_nodes(&top.out));
                let mut crefs: Vec<CrefBeat> = module_refs(&top.out)
                    .into_iter()
                    .map(CrefBeat::Ref)
                    .collect();
                crefs.push(CrefBeat::End);
                assert_eq!(tx.writer.crefs, crefs);
            }
        }
        // Fetcher leaves -> builder base{d} above the level: each fetcher's
        // stream is in (LOD, Morton) order, the merge keeps rank order.
        for f in &tx.fetch {
            let keys: Vec<(u8, u128)> = f
                .leaves
                .iter()
                .filter_map(|l| match l {
                    LeafOut::Leaf { record, .. } => Some((record.voxel.lod, morton(&record.voxel))),
                    LeafOut::End => None,
                })
                .collect();
            assert!(keys.windows(2).all(|w| w[0] < w[1]), "{keys:?}");
        }
        let top_lod = tx.chosen.unwrap_or(tx.cfg.lo) as usize;
        for d in 0..top_lod.min(p.max_lod as usize + 1) {
            let want: Vec<BaseBeat> = tx
                .leaves
                .iter()
                .filter(|n| n.record.voxel.lod as usize == d)
                .map(|n| match n.kind {
                    BaseKind::Reused { at } => BaseBeat::Reused {
                        record: n.record,
                        at,
                    },
                    _ => unreachable!("leaves are reused"),
                })
                .chain([BaseBeat::End])
                .collect();
            assert_eq!(b.base[d], want, "base{d}");
        }
    }

    #[derive(Default, Debug)]
    struct Reached {
        merges: usize,
        per_node: usize,
        per_node_multi_pass: usize,
        count_passes: usize,
        leaves_above: usize,
        materialized: usize,
        several_roots: usize,
        several_root_inputs: usize,
        created: usize,
    }

    fn run_cases(
        p: &Params,
        k: usize,
        out_id: u8,
        cases: Vec<(HierarchyStore, TranslationTable, Vec<u8>)>,
    ) -> Reached {
        let mut seen = Reached::default();
        // The scene-filling input has thousands of nodes per level.
        let sizes = MergerSizes {
            fetch: FetchSizes {
                roots: 16,
                frontier: 8192,
            },
            capacity_bits: 13.min(p.index_bits as u32 - 1),
            leaf_bits: 12,
            store_port: StorePort::PerUnit,
        };
        for (store, table, ids) in cases {
            let hs: Vec<&Hierarchy> = ids.iter().map(|i| store.get(*i).unwrap()).collect();
            seen.several_root_inputs += hs.iter().filter(|h| h.root_count > 1).count();
            let (lo, hi) = candidate_range(&hs);
            for mode in modes(lo, hi) {
                let tx = merger_transaction(&store, &table, &ids, mode, out_id, k, sizes).unwrap();
                check_hand_offs(&tx, p, k);
                let r = merge(&store, &ids, &table, mode, out_id).unwrap();
                let w = &tx.writer;
                assert_eq!(w.header.err, writer_err::NONE, "{mode}");
                assert!(!tx.header.leaf_overflow, "{mode}");
                assert_eq!(tx.header.writer, w.header);
                assert_eq!(w.nodes, r.merged.nodes, "{mode}");
                assert_eq!(w.refs, r.merged.refs, "{mode}");
                assert_eq!(w.header.roots, r.merged.root_count as u64, "{mode}");
                assert_eq!(w.header.top, r.merged.top_lod, "{mode}");
                assert_eq!(w.header.nodes, r.merged.nodes.len() as u64);
                assert_eq!(w.header.refs, r.merged.refs.len() as u64);
                assert_eq!(tx.chosen, r.level, "{mode}");
                assert_eq!(tx.leaves.len() as u64, r.stats.leaves_above, "{mode}");
                if let MergeMode::Overlap { .. } = mode {
                    let counted: Vec<(u8, u64, u64)> = tx
                        .reports()
                        .iter()
                        .filter_map(|r| match r {
                            Report::Counted { lod, result } => {
                                Some((*lod, result.shared, result.union))
                            }
                            _ => None,
                        })
                        .collect();
                    let want: Vec<(u8, u64, u64)> = r
                        .stats
                        .overlap
                        .iter()
                        .map(|o| (o.lod, o.shared, o.union))
                        .collect();
                    assert_eq!(counted, want, "{mode}");
                    seen.count_passes += 1;
                }
                seen.merges += 1;
                seen.per_node += matches!(tx.module, ModulePass::PerNode(_)) as usize;
                if let ModulePass::PerNode(pn) = &tx.module {
                    seen.per_node_multi_pass += (pn.passes > 1) as usize;
                }
                seen.leaves_above += !tx.leaves.is_empty() as usize;
                seen.materialized += (r.stats.materialized > 0) as usize;
                seen.several_roots += (r.merged.root_count > 1) as usize;
                seen.created += (created_count(&tx.base) > 0) as usize;
            }
        }
        seen
    }

    /// An input filling the scene (its LOD-0 root gives way to several
    /// roots, 4.7) with a small translated input, in both rank orders.
    fn several_roots_cases(p: &Params) -> Vec<RealCase> {
        let big = try_scene_soup(p, 1, 1500, 0.05, 77).expect("the soup builds");
        let small = soup(p, 2, 40, 0.2, 78);
        [vec![1u8, 2], vec![2, 1]]
            .into_iter()
            .map(|ids| several_roots_case(p, big.clone(), small.clone(), ids).unwrap())
            .collect()
    }

    /// The chain's output is `merge()`'s hierarchy on real merges in every
    /// level mode, and every unit hands the next what it expects.
    #[test]
    fn chain_equals_merge_on_real_merges() {
        let p = Params::default();
        let mut cases = real_cases(&p).expect("the real cases build");
        cases.extend(several_roots_cases(&p));
        let seen = run_cases(&p, 4, 9, cases);
        eprintln!("default: {seen:?}");
        assert!(seen.merges >= 40, "{seen:?}");
        assert!(seen.per_node > 0 && seen.count_passes > 0, "{seen:?}");
        assert!(seen.per_node_multi_pass > 0, "{seen:?}");
        assert!(seen.leaves_above > 0 && seen.materialized > 0, "{seen:?}");
        assert!(
            seen.several_roots > 0 && seen.several_root_inputs > 0,
            "{seen:?}"
        );
        assert!(seen.created > 0, "{seen:?}");
        let q0 = Params::new(8, 0, 12, 3).unwrap();
        let seen = run_cases(&q0, 3, 7, real_cases(&q0).expect("the real cases build"));
        eprintln!("D = 8, Q = 0: {seen:?}");
        assert!(seen.merges >= 20 && seen.per_node > 0, "{seen:?}");
    }

    /// A refused choice: the closing command, no base, the writer's
    /// `NO_TOP` header; the report says why.
    #[test]
    fn refused_choice_closes_the_fetchers() {
        let p = Params::default();
        let (store, table, ids) = real_cases(&p).expect("the real cases build").remove(0);
        let hs: Vec<&Hierarchy> = ids.iter().map(|i| store.get(*i).unwrap()).collect();
        let (lo, hi) = candidate_range(&hs);
        let sizes = MergerSizes::new(&p);
        for mode in [MergeMode::Fixed(hi + 1), MergeMode::BelowTop(hi - lo + 1)] {
            let tx = merger_transaction(&store, &table, &ids, mode, 9, 4, sizes).unwrap();
            check_hand_offs(&tx, &p, 4);
            assert_eq!(tx.chosen, None);
            assert_eq!(
                tx.reports(),
                &[Report::Chosen {
                    lod: 0,
                    err: choice_err::NOT_CANDIDATE
                }]
            );
            assert_eq!(tx.cmds.len(), 1);
            assert!(tx.cmds[0].last && !tx.cmds[0].send_leaves);
            assert!(!feeds_module(&tx.cmds[0]));
            assert!(tx.base.is_empty());
            assert_eq!(tx.writer.header.err, writer_err::NO_TOP);
            assert!(merge(&store, &ids, &table, mode, 9).is_err());
        }
    }

    /// A bad range from software: the module refuses it, the fetchers get
    /// the closing command, the writer's header says `NO_TOP`.
    #[test]
    fn bad_range_is_refused() {
        let p = Params::default();
        let (store, table, ids) = real_cases(&p).expect("the real cases build").remove(0);
        let sizes = MergerSizes::new(&p);
        for mode in [MergeMode::default(), MergeMode::Fixed(4)] {
            for (lo, hi) in [(5, 4), (3, p.max_lod + 1)] {
                let tx = merger_transaction_in_range(
                    &store,
                    &table,
                    &ids,
                    mode,
                    9,
                    4,
                    sizes,
                    Some((lo, hi)),
                )
                .unwrap();
                check_hand_offs(&tx, &p, 4);
                assert_eq!(
                    tx.reports(),
                    &[Report::Chosen {
                        lod: 0,
                        err: choice_err::BAD_RANGE
                    }]
                );
                assert_eq!(tx.cmds.len(), 1);
                assert_eq!(tx.writer.header.err, writer_err::NO_TOP);
            }
        }
    }

    /// Refusals of the chain itself: more inputs than `k`, an unknown id,
    /// an input the fetcher cannot walk (a frontier too small).
    #[test]
    fn chain_refuses_what_the_merger_cannot_do() {
        let p = Params::default();
        let (store, table, ids) = real_cases(&p).expect("the real cases build").remove(0);
        let sizes = MergerSizes::new(&p);
        let mode = MergeMode::default();
        assert!(matches!(
            merger_transaction(&store, &table, &ids, mode, 9, 2, sizes),
            Err(MergeError::IndexOverflow { .. })
        ));
        assert!(matches!(
            merger_transaction(&store, &table, &[1, 12], mode, 9, 4, sizes),
            Err(MergeError::UnknownInput(12))
        ));
        let tiny = MergerSizes {
            fetch: FetchSizes {
                roots: 16,
                frontier: 1,
            },
            ..sizes
        };
        let e = merger_transaction(&store, &table, &ids, mode, 9, 4, tiny).unwrap_err();
        assert!(e.to_string().contains("fetcher"), "{e}");
    }

    /// The header flags a LOD with more leaves than its FIFO holds.
    #[test]
    fn leaf_overflow_is_flagged() {
        let p = Params::default();
        let mut flagged = 0;
        for (store, table, ids) in real_cases(&p).expect("the real cases build") {
            for leaf_bits in [0, 12] {
                let sizes = MergerSizes {
                    leaf_bits,
                    ..MergerSizes::new(&p)
                };
                let mode = MergeMode::BelowTop(2);
                let tx = merger_transaction(&store, &table, &ids, mode, 9, 4, sizes).unwrap();
                let most = tx
                    .leaves
                    .iter()
                    .map(|a| {
                        let lod = a.record.voxel.lod;
                        tx.leaves
                            .iter()
                            .filter(|b| b.record.voxel.lod == lod)
                            .count()
                    })
                    .max()
                    .unwrap_or(0);
                assert_eq!(tx.header.leaf_overflow, most > 1 << leaf_bits);
                assert!(
                    tx.exact,
                    "a level mode drops leaves only, which golden models"
                );
                flagged += tx.header.leaf_overflow as usize;
            }
        }
        assert!(flagged > 0);
    }

    /// Per-node mode: a merge whose module sends some LOD more nodes than
    /// its FIFO holds is flagged and not exact (golden does not model the
    /// dropped node's references in `crefs`); one whose leaves alone
    /// overflow is exact, its base holding the first `2^leaf_bits` leaves
    /// of each LOD.
    #[test]
    fn per_node_dropped_nodes_make_a_merge_inexact() {
        let p = Params::default();
        let mode = MergeMode::PerNode { num: 1, den: 2 };
        let (mut inexact, mut exact_over) = (0, 0);
        for (store, table, ids) in real_cases(&p).expect("the real cases build") {
            for leaf_bits in [0, 1, 2] {
                let sizes = MergerSizes {
                    leaf_bits,
                    ..MergerSizes::new(&p)
                };
                let tx = merger_transaction(&store, &table, &ids, mode, 9, 4, sizes).unwrap();
                let count = |lods: &mut std::collections::BTreeMap<u8, usize>, n: &BaseNode| {
                    *lods.entry(n.record.voxel.lod).or_default() += 1;
                };
                let mut leaves = std::collections::BTreeMap::new();
                tx.leaves.iter().for_each(|n| count(&mut leaves, n));
                let mut base = std::collections::BTreeMap::new();
                tx.base.iter().for_each(|n| count(&mut base, n));
                let held = 1usize << leaf_bits;
                // The base: at most `held` leaves of a LOD, every node.
                let nodes: usize =
                    tx.base.len() - leaves.values().map(|&c| c.min(held)).sum::<usize>();
                let nodes_over = base
                    .iter()
                    .any(|(lod, &c)| c - leaves.get(lod).map_or(0, |&l| l.min(held)) > held);
                assert_eq!(tx.exact, !nodes_over, "L = {leaf_bits}, {nodes} nodes");
                let leaves_over = leaves.values().any(|&c| c > held);
                assert_eq!(tx.header.leaf_overflow, leaves_over || nodes_over);
                inexact += !tx.exact as usize;
                exact_over += (tx.exact && leaves_over) as usize;
            }
        }
        assert!(inexact > 0 && exact_over > 0, "{inexact} {exact_over}");
    }

    #[test]
    fn cfg_packs_every_input_and_the_range() {
        let p = Params::default();
        let l = MergerLayout::new(&p, 4, 10).unwrap();
        assert_eq!(l.fetch_rank.width, 2);
        assert_eq!(l.header.width(), l.writer.header.width() + 8);
        let (store, _, ids) = real_cases(&p).expect("the real cases build").remove(0);
        let cfg = MergerCfg {
            inputs: ids
                .iter()
                .map(|i| FetchCfg::of(store.get(*i).unwrap(), None))
                .collect(),
            lo: 3,
            hi: 5,
            out_id: 9,
        };
        let b = cfg.pack(&l).unwrap();
        assert_eq!(b.get(&l.count).unwrap(), ids.len() as u64);
        assert_eq!(b.get(&l.lo).unwrap(), 3);
        assert_eq!(b.get(&l.hi).unwrap(), 5);
        assert_eq!(b.get(&l.out_id).unwrap(), 9);
        let roots = Field {
            offset: l.input_offset(1) + l.fetch.roots.offset,
            ..l.fetch.roots
        };
        assert_eq!(
            b.get(&roots).unwrap(),
            store.get(ids[1]).unwrap().root_count as u64
        );
        let five = MergerCfg {
            inputs: vec![cfg.inputs[0]; 5],
            ..cfg
        };
        assert!(five.pack(&l).is_err());
    }
}
