//! The fetcher's ports as bits: its error codes, the layouts of `cfg`,
//! `cmd`, `out` and `leaves` and of the store's read ports, and the beats
//! packed with them.

use crate::bits::Bits;
use crate::layout::{Field, Layout, LayoutError, NodeLayout, RefLayout};
use crate::merge::merge_level::unit::{BeatLayout, LevelBeat};
use crate::merge::per_node::unit::{PerNodeLayout, PerNodeReport};
use crate::params::Params;
use crate::store::{Hierarchy, NodeRecord, Reference};
use crate::translate::table::entry_bits;
use crate::translate::translation::trans_bits;
use crate::translate::Translation;

/// Error codes of an `out` error beat (the `err` field), each naming the
/// record it found wrong in the beat's `ref`.
pub mod fetch_err {
    /// No error (every beat but an error beat).
    pub const NONE: u64 = 0;
    /// The `cfg` translation entry is invalid (`valid` 0, `L > D`, or a
    /// component code `-2^D`). Node 0.
    pub const ENTRY: u64 = 1;
    /// `root_count` is 0 or above `nodes`. Node 0.
    pub const ROOT_COUNT: u64 = 2;
    /// More roots than the root sorter holds. Node 0.
    pub const ROOT_CAPACITY: u64 = 3;
    /// A record that does not validate (section 3). The node.
    pub const RECORD: u64 = 4;
    /// A node not at its parent's LOD + 1 (a root: not at `top_lod`). The node.
    pub const LOD: u64 = 5;
    /// An inner node whose reference range leaves `refs`. The node.
    pub const RANGE: u64 = 6;
    /// A reference naming another hierarchy. The parent node.
    pub const REF_HIER: u64 = 7;
    /// A reference to a node at or above `nodes`. The parent node.
    pub const REF_NODE: u64 = 8;
    /// `AboveTranslationLevel`: the node's LOD is below `L`. The node.
    pub const ABOVE: u64 = 9;
    /// `NodeOutsideScene` on x; y and z are the next two codes. The node.
    pub const OUTSIDE_X: u64 = 10;
    /// `NodeOutsideScene` on y. The node.
    pub const OUTSIDE_Y: u64 = 11;
    /// `NodeOutsideScene` on z. The node.
    pub const OUTSIDE_Z: u64 = 12;
    /// One level (or per-node pass) would push more inner-node ranges than
    /// `FetchSizes::frontier` allows (the frontier FIFO holds `2 * frontier + 1`
    /// words). The node.
    pub const FRONTIER: u64 = 13;
    /// A node not after the previous node of its level in (Morton code,
    /// inner before leaf) order: the walk would not be the stream's order
    /// (two inner nodes at one voxel, a child outside its parent's voxel or
    /// children stored out of order). The node.
    pub const ORDER: u64 = 14;
    /// Bits of the `err` field.
    pub const BITS: u32 = 4;
}

/// The bit layouts of the fetcher's streams, from bit 0 upward; widths from
/// [`Params`], [`NodeLayout`], [`RefLayout`] and the translation table's
/// [`entry_bits`] only.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FetchLayout {
    /// Layout of a node record: `node_resp`, and `rec` of `out` and `leaves`.
    pub node: NodeLayout,
    /// Layout of a reference: `ref_resp`, `cref_resp`, and `ref` of `out` and `leaves`.
    pub reference: RefLayout,
    /// `cfg`: `hier` (H), `roots` (I: root_count), `top` (lod_bits),
    /// `nodes`, `refs` (I each: the input's array lengths), `entry` (the
    /// translation table's packed entry, section 7.5).
    pub hier: Field,
    /// `cfg`: `roots` (I bits), the input's `root_count`.
    pub roots: Field,
    /// `cfg`: `top` (`lod_bits`), the LOD of the input's roots.
    pub top: Field,
    /// `cfg`: `nodes` (I bits), the length of the input's `nodes` array.
    pub nodes: Field,
    /// `cfg`: `refs` (I bits), the length of the input's `refs` array.
    pub refs: Field,
    /// `cfg`: `entry` ([`entry_bits`] bits), the table's packed entry for `hier`.
    pub entry: Field,
    /// The entry's own fields inside `cfg` (section 7.5's packing: `valid`,
    /// `L`, `tx`, `ty`, `tz`), tested against [`pack_entry`](crate::translate::table::pack_entry).
    pub entry_valid: Field,
    /// `cfg`: the entry's `L` (`lod_bits`), the translation level.
    pub entry_lod: Field,
    /// `cfg`: the entry's `tx`, `ty`, `tz` (D + 1 bits each), the translation codes.
    pub entry_t: [Field; 3],
    /// The `cfg` beat: `hier`, `roots`, `top`, `nodes`, `refs`, `entry`.
    pub cfg: Layout,
    /// `cmd`: `lod` (lod_bits), `send_refs`, `send_leaves`, `last` (1
    /// each), `from` (lod_bits: the first level sent, [`FetchCmd::from`]).
    pub lod: Field,
    /// `cmd`: `send_refs`, send the inner nodes' child references on the sent levels.
    pub send_refs: Field,
    /// `cmd`: `send_leaves`, send the leaves above the first sent level on `leaves`.
    pub send_leaves: Field,
    /// `cmd`: `last`, the input's last command; the next `cfg` beat follows.
    pub last: Field,
    /// `cmd`: `from` (`lod_bits`); the first level sent is `min(from, lod)`.
    pub from: Field,
    /// The `cmd` beat (`per_node` included when built with it).
    pub cmd: Layout,
    /// `node_req` / `ref_req`: an index (I). `node_resp`: a record (W);
    /// `ref_resp`: a reference (I + H).
    pub index_width: u32,
    /// `out`: an S614 input beat ([`BeatLayout::input`]) then `err`
    /// ([`fetch_err::BITS`]).
    pub beat: BeatLayout,
    /// `out`: `err` ([`fetch_err::BITS`] bits), a [`fetch_err`] code; 0 but on an
    /// error beat.
    pub err: Field,
    /// The `out` beat: `rec`, `ref`, `kind`, `err` (`probe` included when
    /// built with it).
    pub out: Layout,
    /// `leaves`: `rec` (W), `ref` (I + H), `lod` (lod_bits), `end` (1).
    pub leaf_rec: Field,
    /// `leaves`: `ref` (I + H bits), where the leaf is stored: `(hier, node index)`.
    pub leaf_ref: Field,
    /// `leaves`: `lod` (`lod_bits`), the leaf record's LOD.
    pub leaf_lod: Field,
    /// `leaves`: `end` (1 bit), set on the command's last `leaves` beat.
    pub leaf_end: Field,
    /// The `leaves` beat: `rec`, `ref`, `lod`, `end`.
    pub leaves: Layout,
    /// The per-node command's fields, only in a fetcher built for
    /// per-node merging ([`FetchLayout::per_node`]); without them the
    /// layout (and the fetcher) is exactly the level modes' one.
    pub pn: Option<PerNodeFetchLayout>,
}

/// What a fetcher built for per-node merging adds to [`FetchLayout`]: a
/// `cmd` bit, an `out` bit, the `report` input and the `probe` read port
/// (request an index, I bits; response a record, W bits, as `node`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PerNodeFetchLayout {
    /// `cmd`: `per_node` (1), after `from`: the per-node command
    /// ([`FetchCmd::per_node`]).
    pub per_node: Field,
    /// `out`: `probe` (1), after `err`: the beat is a probe (a child of the
    /// inner node that follows, section 8.14).
    pub probe: Field,
    /// The `report` input, the fields of the per-node module's `report`
    /// beat ([`PerNodeLayout`]) the fetcher reads, which the merger's glue
    /// takes out of it, from bit 0: `x`, `y`, `z` (D each), `lod`
    /// (`lod_bits`), `descend`, `pass_end`, `more` (1 each). A refusal beat
    /// is `pass_end` 1, `more` 0.
    pub report_coord: [Field; 3],
    /// `report`: `lod`, the decision's voxel LOD or the ended pass's LOD.
    pub report_lod: Field,
    /// `report`: `descend`, 1 when the voxel descends.
    pub report_descend: Field,
    /// `report`: `pass_end`, 1 on the beat ending a pass (or a refusal).
    pub report_pass_end: Field,
    /// `report`: `more`, with `pass_end`: another pass follows.
    pub report_more: Field,
    /// The fetcher's `report` beat: `x`, `y`, `z`, `lod`, `descend`,
    /// `pass_end`, `more`.
    pub report: Layout,
}

impl PerNodeFetchLayout {
    /// The fetcher's `report` beat of the module's `report` beat `r`.
    pub fn pack_report(&self, r: &PerNodeReport) -> Result<Bits, LayoutError> {
        let mut b = self.report.zero();
        match *r {
            PerNodeReport::Decision { voxel, descend, .. } => {
                for (f, v) in self.report_coord.iter().zip([voxel.x, voxel.y, voxel.z]) {
                    b.set(f, v as u64)?;
                }
                b.set(&self.report_lod, voxel.lod as u64)?;
                b.set(&self.report_descend, descend as u64)?;
            }
            PerNodeReport::PassEnd { lod, more } => {
                b.set(&self.report_lod, lod as u64)?;
                b.set(&self.report_pass_end, 1)?;
                b.set(&self.report_more, more as u64)?;
            }
            PerNodeReport::Refused { .. } => b.set(&self.report_pass_end, 1)?,
        }
        Ok(b)
    }

    /// Where each field of the fetcher's `report` beat sits in the module's
    /// `report` beat ([`PerNodeLayout`]): (fetcher field, module field).
    pub fn report_sources(&self, module: &PerNodeLayout) -> [(Field, Field); 7] {
        [
            (self.report_coord[0], module.coord[0]),
            (self.report_coord[1], module.coord[1]),
            (self.report_coord[2], module.coord[2]),
            (self.report_lod, module.lod),
            (self.report_descend, module.descend),
            (self.report_pass_end, module.pass_end),
            (self.report_more, module.more),
        ]
    }
}

impl FetchLayout {
    /// The layouts for `p` (no per-node command).
    pub fn new(p: &Params) -> FetchLayout {
        FetchLayout::build(p, false)
    }

    /// The layouts for `p` of a fetcher built with the per-node command:
    /// [`FetchLayout::new`]'s fields and, after them, `cmd`'s `per_node`
    /// and `out`'s `probe` bit ([`PerNodeFetchLayout`]).
    pub fn per_node(p: &Params) -> FetchLayout {
        FetchLayout::build(p, true)
    }

    /// The layouts, with the per-node fields when `per_node`.
    pub fn build(p: &Params, per_node: bool) -> FetchLayout {
        let node = NodeLayout::new(p);
        let reference = RefLayout::new(p);
        let (i, h, lb) = (p.index_bits as u32, p.hier_bits as u32, p.lod_bits());
        let mut cfg = Layout::new("fetcher cfg");
        let hier = cfg.push("hier", h);
        let roots = cfg.push("roots", i);
        let top = cfg.push("top", lb);
        let nodes = cfg.push("nodes", i);
        let refs = cfg.push("refs", i);
        let entry = cfg.push("entry", entry_bits(p));
        // The entry's own fields, at their place inside `entry`.
        let mut inside = Layout::from_fields("table entry", &[], entry.offset);
        let entry_valid = inside.push("entry_valid", 1);
        let entry_lod = inside.push("entry_lod", lb);
        let entry_t = ["entry_tx", "entry_ty", "entry_tz"].map(|n| inside.push(n, trans_bits(p)));
        let mut cmd = Layout::new("fetcher cmd");
        let lod = cmd.push("lod", lb);
        let send_refs = cmd.push("send_refs", 1);
        let send_leaves = cmd.push("send_leaves", 1);
        let last = cmd.push("last", 1);
        let from = cmd.push("from", lb);
        let beat = BeatLayout::input(p);
        let mut out = Layout::new("fetcher out");
        for f in beat.fields() {
            out.push(f.name, f.width);
        }
        let err = out.push("err", fetch_err::BITS);
        let mut leaves = Layout::new("fetcher leaves");
        let leaf_rec = leaves.push("rec", node.width());
        let leaf_ref = leaves.push("ref", reference.width());
        let leaf_lod = leaves.push("lod", lb);
        let leaf_end = leaves.push("end", 1);
        let pn = per_node.then(|| {
            let d = p.coord_bits();
            let mut report = Layout::new("fetcher report");
            let report_coord = ["x", "y", "z"].map(|n| report.push(n, d));
            let report_lod = report.push("lod", lb);
            let report_descend = report.push("descend", 1);
            let report_pass_end = report.push("pass_end", 1);
            let report_more = report.push("more", 1);
            PerNodeFetchLayout {
                per_node: cmd.push("per_node", 1),
                probe: out.push("probe", 1),
                report_coord,
                report_lod,
                report_descend,
                report_pass_end,
                report_more,
                report,
            }
        });
        FetchLayout {
            node,
            reference,
            hier,
            roots,
            top,
            nodes,
            refs,
            entry,
            entry_valid,
            entry_lod,
            entry_t,
            cfg,
            lod,
            send_refs,
            send_leaves,
            last,
            from,
            cmd,
            index_width: i,
            err,
            out,
            beat,
            leaf_rec,
            leaf_ref,
            leaf_lod,
            leaf_end,
            leaves,
            pn,
        }
    }
}

/// Sets a field wider than 64 bits (the translation entry) from a `u128`.
fn set_wide(b: &mut Bits, f: &Field, v: u128) -> Result<(), LayoutError> {
    if f.width < 128 && v >> f.width != 0 {
        return Err(LayoutError::DoesNotFit {
            field: f.name,
            value: v as u64,
            width: f.width,
        });
    }
    let mut at = 0;
    while at < f.width {
        let w = (f.width - at).min(64);
        let part = Field {
            name: f.name,
            offset: f.offset + at,
            width: w,
        };
        let mask = if w == 64 { u64::MAX } else { (1u64 << w) - 1 };
        b.set(&part, (v >> at) as u64 & mask)?;
        at += w;
    }
    Ok(())
}

/// The header of one input as the `cfg` beat carries it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FetchCfg {
    /// `hier`: the input's hierarchy id.
    pub hier: u8,
    /// `roots`: the input's `root_count`.
    pub root_count: u32,
    /// `top`: the LOD of the input's roots.
    pub top_lod: u8,
    /// `nodes`: the length of the input's `nodes` array.
    pub nodes: u32,
    /// `refs`: the length of the input's `refs` array.
    pub refs: u32,
    /// The translation table's packed entry for `hier` (section 7.5).
    pub entry: u128,
}

impl FetchCfg {
    /// The header of `h` with translation `t` (`None`: an invalid entry).
    pub fn of(h: &Hierarchy, t: Option<&Translation>) -> FetchCfg {
        FetchCfg {
            hier: h.id,
            root_count: h.root_count,
            top_lod: h.top_lod,
            nodes: h.nodes.len() as u32,
            refs: h.refs.len() as u32,
            entry: crate::translate::table::pack_entry(t, &h.params),
        }
    }

    /// The packed `cfg` beat; an error when a count needs more than `I` bits.
    pub fn pack(&self, l: &FetchLayout) -> Result<Bits, LayoutError> {
        let mut b = l.cfg.zero();
        b.set(&l.hier, self.hier as u64)?;
        b.set(&l.roots, self.root_count as u64)?;
        b.set(&l.top, self.top_lod as u64)?;
        b.set(&l.nodes, self.nodes as u64)?;
        b.set(&l.refs, self.refs as u64)?;
        set_wide(&mut b, &l.entry, self.entry)?;
        Ok(b)
    }
}

/// One command: one walk to LOD `lod` that sends on `out` every level
/// [`first`](FetchCmd::first)`..=lod` in turn (each level's nodes, with the
/// inner nodes' child references when `send_refs`, then `End`), and the
/// leaves above the first level on `leaves` when `send_leaves`; `last`: the
/// next beat on `cfg` starts another input. `from >= lod` is the
/// single-level command at `lod` (the merge pass); `from < lod` sends
/// several levels from one walk (the count pass, SPEC 8.13).
///
/// `per_node` (a fetcher built for per-node merging only): the **per-node
/// command** at `lo = lod`: the walk to `lo`, then pass after pass the
/// per-node module's input stream for this input (8.14: per live voxel the
/// probes, the inner node, the leaf, the child references; `End`), the
/// live voxels of pass `l + 1` the children of this input's inner nodes
/// whose voxel the module's `report` says descended in pass `l`; the
/// command ends with the pass whose `report` `pass_end` beat has `more` 0.
/// `from` and `send_refs` are not read (a pass always carries the
/// references).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FetchCmd {
    /// The deepest level walked and sent (`lo` for the per-node command).
    pub lod: u8,
    /// Send each inner node's child references after its voxel's node beats.
    pub send_refs: bool,
    /// Send the leaves above the first sent level on `leaves`, then the end beat.
    pub send_leaves: bool,
    /// The input's last command: the next `cfg` beat starts another input.
    pub last: bool,
    /// The first level sent when below `lod` ([`FetchCmd::first`]); at or
    /// above `lod` only `lod` is sent.
    pub from: u8,
    /// The per-node command (only in a layout from [`FetchLayout::per_node`]).
    pub per_node: bool,
}

impl FetchCmd {
    /// The single-level command at `lod`.
    pub fn level(lod: u8, send_refs: bool, send_leaves: bool, last: bool) -> FetchCmd {
        FetchCmd {
            lod,
            send_refs,
            send_leaves,
            last,
            from: lod,
            per_node: false,
        }
    }

    /// The per-node command from pass `lo` (references always sent; `from`
    /// = `lo`).
    pub fn per_node(lo: u8, send_leaves: bool, last: bool) -> FetchCmd {
        FetchCmd {
            per_node: true,
            ..FetchCmd::level(lo, true, send_leaves, last)
        }
    }

    /// The first (shallowest) level sent: `min(from, lod)` (`lod` for the
    /// per-node command).
    pub fn first(&self) -> u8 {
        if self.per_node {
            self.lod
        } else {
            self.from.min(self.lod)
        }
    }

    /// Levels sent by a level command, each closed by one `End` (or the
    /// error beat in its place): `lod - first + 1`. (A per-node command
    /// sends one `End` per pass, as many as its `report` says.)
    pub fn levels(&self) -> usize {
        (self.lod - self.first()) as usize + 1
    }

    /// The packed `cmd` beat; `per_node` needs a layout that has the field
    /// ([`FetchLayout::per_node`]).
    pub fn pack(&self, l: &FetchLayout) -> Result<Bits, LayoutError> {
        let mut b = l.cmd.zero();
        b.set(&l.lod, self.lod as u64)?;
        b.set(&l.send_refs, self.send_refs as u64)?;
        b.set(&l.send_leaves, self.send_leaves as u64)?;
        b.set(&l.last, self.last as u64)?;
        b.set(&l.from, self.from as u64)?;
        match &l.pn {
            Some(f) => b.set(&f.per_node, self.per_node as u64)?,
            None if self.per_node => return Err(no_per_node_field("per_node")),
            None => {}
        }
        Ok(b)
    }
}

/// The refusal to pack a per-node field into a layout built without them.
fn no_per_node_field(field: &'static str) -> LayoutError {
    LayoutError::DoesNotFit {
        field,
        value: 1,
        width: 0,
    }
}

/// One beat of `out`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FetchOut {
    /// An S614 input beat (`End` closes a command's level).
    Beat(LevelBeat),
    /// A per-node probe: a child (translated, where it is stored) of the
    /// inner node that follows; packed as an inner-node beat with `probe`
    /// 1 (the per-node module's input beat, 8.14).
    Probe {
        /// The child's stored record with its voxel translated.
        record: NodeRecord,
        /// Where the child is stored: `(hier, node index)`.
        at: Reference,
    },
    /// The walk stopped: `kind` END, `ref` = (hier, node), `err` = code.
    Error {
        /// The input's hierarchy id.
        hier: u8,
        /// The node named: the record found wrong, the parent for `REF_HIER` and
        /// `REF_NODE`, 0 for the header codes.
        node: u32,
        /// The [`fetch_err`] code.
        code: u64,
    },
}

impl FetchOut {
    /// The packed beat.
    pub fn pack(&self, l: &FetchLayout) -> Result<Bits, LayoutError> {
        let mut b = l.out.zero();
        match self {
            FetchOut::Beat(beat) => b.put(0, &beat.pack(&l.beat)?)?,
            FetchOut::Probe { record, at } => {
                let inner = LevelBeat::Inner {
                    record: *record,
                    at: *at,
                };
                b.put(0, &inner.pack(&l.beat)?)?;
                let probe = l.pn.as_ref().ok_or(no_per_node_field("probe"))?.probe;
                b.set(&probe, 1)?;
            }
            FetchOut::Error { hier, node, code } => {
                let r = Reference {
                    hier: *hier,
                    node: *node,
                };
                b.put(0, &LevelBeat::End.pack(&l.beat)?)?;
                b.put(l.beat.refer.offset, &r.pack(&l.reference)?)?;
                b.set(&l.err, *code)?;
            }
        }
        Ok(b)
    }
}

/// One beat of `leaves`: a translated leaf above the command's LOD, where it
/// is stored; or the command's `End`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LeafOut {
    /// A leaf above the first sent level.
    Leaf {
        /// The leaf's stored record with its voxel translated.
        record: NodeRecord,
        /// Where the leaf is stored: `(hier, node index)`.
        at: Reference,
    },
    /// The command's last `leaves` beat (`end` = 1).
    End,
}

impl LeafOut {
    /// The packed beat (`lod` = the record's LOD).
    pub fn pack(&self, l: &FetchLayout) -> Result<Bits, LayoutError> {
        let mut b = l.leaves.zero();
        match self {
            LeafOut::Leaf { record, at } => {
                b.put(l.leaf_rec.offset, &record.pack(&l.node)?)?;
                b.put(l.leaf_ref.offset, &at.pack(&l.reference)?)?;
                b.set(&l.leaf_lod, record.voxel.lod as u64)?;
            }
            LeafOut::End => b.set(&l.leaf_end, 1)?,
        }
        Ok(b)
    }
}
