//! The fetcher (S610 + S612 in hardware, SPEC.md section 8.13): one input
//! hierarchy walked from the store and translated, producing the merging
//! module's per-input stream (8.10's `in<i>`, [`super::top::input_stream`]'s
//! order) and the leaves above the walked level for the upper builder.
//!
//! This module holds the beat layouts of the fetcher's ports and its
//! transaction: a store image of one input, its `cfg` beat and a list of
//! commands give the expected memory requests (node and reference read
//! ports), the responses the memory answers with, the `out` beats and the
//! `leaves` beats. Every value comes from golden's walk functions
//! ([`super::walk::place_node`] validates and translates, [`super::walk::children`]
//! checks reference ranges, [`super::level_merge::sort_stream`] orders the
//! roots); the model adds only the visiting order the hardware promises (a
//! breadth-first walk from the sorted roots, one read at a time), and the
//! tests check that on well-formed inputs its streams equal
//! [`super::walk::walk_input`] + [`super::walk::collect`] +
//! [`super::top::input_stream`].

use std::collections::VecDeque;

use super::error::MergeError;
use super::level_merge::sort_stream;
use super::per_node_unit::{PerNodeLayout, PerNodeReport};
use super::unit::{BeatLayout, LevelBeat};
use super::walk::{children, morton, place_node, PlacedNode};
use crate::layout::{Bits, Field, LayoutError, NodeLayout, RefLayout};
use crate::params::Params;
use crate::store::{Hierarchy, NodeRecord, Reference};
use crate::translate::table::{entry_bits, unpack_entry};
use crate::translate::translation::trans_bits;
use crate::translate::{TranslateError, Translation};

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
    /// Width of the `cfg` beat in bits.
    pub cfg_width: u32,
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
    /// Width of the `cmd` beat in bits (`per_node` included when built with it).
    pub cmd_width: u32,
    /// `node_req` / `ref_req`: an index (I). `node_resp`: a record (W);
    /// `ref_resp`: a reference (I + H).
    pub index_width: u32,
    /// `out`: an S614 input beat ([`BeatLayout::input`]) then `err`
    /// ([`fetch_err::BITS`]).
    pub beat: BeatLayout,
    /// `out`: `err` ([`fetch_err::BITS`] bits), a [`fetch_err`] code; 0 but on an
    /// error beat.
    pub err: Field,
    /// Width of an `out` beat in bits (`probe` included when built with it).
    pub out_width: u32,
    /// `leaves`: `rec` (W), `ref` (I + H), `lod` (lod_bits), `end` (1).
    pub leaf_rec: Field,
    /// `leaves`: `ref` (I + H bits), where the leaf is stored: `(hier, node index)`.
    pub leaf_ref: Field,
    /// `leaves`: `lod` (`lod_bits`), the leaf record's LOD.
    pub leaf_lod: Field,
    /// `leaves`: `end` (1 bit), set on the command's last `leaves` beat.
    pub leaf_end: Field,
    /// Width of a `leaves` beat in bits.
    pub leaves_width: u32,
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
    /// Width of the fetcher's `report` beat in bits.
    pub report_width: u32,
}

impl PerNodeFetchLayout {
    /// The fetcher's `report` beat of the module's `report` beat `r`.
    pub fn pack_report(&self, r: &PerNodeReport) -> Result<Bits, LayoutError> {
        let mut b = Bits::zero(self.report_width);
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

/// Lays out `(name, width)` consecutively from bit 0.
fn consecutive<const N: usize>(spec: [(&'static str, u32); N]) -> ([Field; N], u32) {
    let mut at = 0;
    let f = spec.map(|(name, width)| {
        let f = Field {
            name,
            offset: at,
            width,
        };
        at += width;
        f
    });
    (f, at)
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
        let ([hier, roots, top, nodes, refs, entry], cfg_width) = consecutive([
            ("hier", h),
            ("roots", i),
            ("top", lb),
            ("nodes", i),
            ("refs", i),
            ("entry", entry_bits(p)),
        ]);
        let (inside, _) = consecutive([
            ("entry_valid", 1),
            ("entry_lod", lb),
            ("entry_tx", trans_bits(p)),
            ("entry_ty", trans_bits(p)),
            ("entry_tz", trans_bits(p)),
        ]);
        let at = |f: Field| Field {
            offset: f.offset + entry.offset,
            ..f
        };
        let ([lod, send_refs, send_leaves, last, from], cmd_width) = consecutive([
            ("lod", lb),
            ("send_refs", 1),
            ("send_leaves", 1),
            ("last", 1),
            ("from", lb),
        ]);
        let beat = BeatLayout::input(p);
        let err = Field {
            name: "err",
            offset: beat.width,
            width: fetch_err::BITS,
        };
        let ([leaf_rec, leaf_ref, leaf_lod, leaf_end], leaves_width) = consecutive([
            ("rec", node.width()),
            ("ref", reference.width()),
            ("lod", lb),
            ("end", 1),
        ]);
        let d = p.coord_bits();
        let (report, report_width) = consecutive([
            ("x", d),
            ("y", d),
            ("z", d),
            ("lod", p.lod_bits()),
            ("descend", 1),
            ("pass_end", 1),
            ("more", 1),
        ]);
        let pn = per_node.then(|| PerNodeFetchLayout {
            per_node: Field {
                name: "per_node",
                offset: cmd_width,
                width: 1,
            },
            probe: Field {
                name: "probe",
                offset: err.end(),
                width: 1,
            },
            report_coord: report[..3].try_into().expect("three axes"),
            report_lod: report[3],
            report_descend: report[4],
            report_pass_end: report[5],
            report_more: report[6],
            report_width,
        });
        let cmd_width = pn.as_ref().map_or(cmd_width, |f| f.per_node.end());
        let out_width = pn.as_ref().map_or(err.end(), |f| f.probe.end());
        FetchLayout {
            node,
            reference,
            hier,
            roots,
            top,
            nodes,
            refs,
            entry,
            entry_valid: at(inside[0]),
            entry_lod: at(inside[1]),
            entry_t: [at(inside[2]), at(inside[3]), at(inside[4])],
            cfg_width,
            lod,
            send_refs,
            send_leaves,
            last,
            from,
            cmd_width,
            index_width: i,
            err,
            out_width,
            beat,
            leaf_rec,
            leaf_ref,
            leaf_lod,
            leaf_end,
            leaves_width,
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
        let mut b = Bits::zero(l.cfg_width);
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
        let mut b = Bits::zero(l.cmd_width);
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
        let mut b = Bits::zero(l.out_width);
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
        let mut b = Bits::zero(l.leaves_width);
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

/// The fetcher's fixed sizes: the root sorter's capacity and the frontier
/// FIFO's depth (generator parameters).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FetchSizes {
    /// The root sorter's capacity: the most roots an input may have (else `ROOT_CAPACITY`).
    pub roots: usize,
    /// The most inner-node ranges one level (or pass) may push (else `FRONTIER`);
    /// the frontier FIFO holds `2 * frontier + 1` words.
    pub frontier: usize,
}

impl Default for FetchSizes {
    /// 16 roots (a builder-made input has at most 16), 256 ranges.
    fn default() -> Self {
        FetchSizes {
            roots: 16,
            frontier: 256,
        }
    }
}

/// One input's run through the fetcher: its `cfg`, its commands, and what
/// every stream carries, in order, over all commands.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FetchTransaction {
    /// The input's `cfg` beat.
    pub cfg: FetchCfg,
    /// The commands, in order.
    pub cmds: Vec<FetchCmd>,
    /// Node indices requested on `node_req`, and the records answered.
    pub node_reqs: Vec<u32>,
    /// One per entry of `node_reqs`: the stored record.
    pub node_resps: Vec<NodeRecord>,
    /// Reference indices requested on `ref_req`, and the references answered.
    pub ref_reqs: Vec<u32>,
    /// One per entry of `ref_reqs`: the stored reference.
    pub ref_resps: Vec<Reference>,
    /// Reference indices requested on `cref_req` (the child references of
    /// the nodes at the command's level, with `send_refs`), and the answers.
    pub cref_reqs: Vec<u32>,
    /// One per entry of `cref_reqs`: the stored reference.
    pub cref_resps: Vec<Reference>,
    /// Node indices requested on `probe_req` (the probes of per-node
    /// commands: the children of each live inner node), and the records.
    pub probe_reqs: Vec<u32>,
    /// One per entry of `probe_reqs`: the stored record.
    pub probe_resps: Vec<NodeRecord>,
    /// The `report` beats taken (per-node commands), in order.
    pub reports: Vec<PerNodeReport>,
    /// The `out` beats of every command, in order.
    pub out: Vec<FetchOut>,
    /// The `leaves` beats of every command, in order; each command with
    /// `send_leaves` ends with one `End`.
    pub leaves: Vec<LeafOut>,
}

/// The code of a [`place_node`] failure.
fn place_code(e: &MergeError) -> u64 {
    match e {
        MergeError::TranslateNode { error, .. } => match error {
            TranslateError::AboveTranslationLevel { .. } => fetch_err::ABOVE,
            TranslateError::NodeOutsideScene { axis, .. } => {
                fetch_err::OUTSIDE_X + axis.index() as u64
            }
            _ => fetch_err::RECORD,
        },
        _ => fetch_err::RECORD,
    }
}

/// A walk stopped by an error: (node named, code).
type Stop = (u32, u64);

/// The walk of one command, appending to `tx`.
struct Walk<'a> {
    h: &'a Hierarchy,
    t: Translation,
    cmd: FetchCmd,
    sizes: FetchSizes,
}

impl Walk<'_> {
    /// Reads node `i` (expected at LOD `lod`) and places it.
    fn read_node(&self, tx: &mut FetchTransaction, i: u32, lod: u8) -> Result<PlacedNode, Stop> {
        tx.node_reqs.push(i);
        let n = self.h.nodes[i as usize];
        tx.node_resps.push(n);
        if n.voxel.lod != lod {
            return Err((i, fetch_err::LOD));
        }
        place_node(self.h, 0, &self.t, i).map_err(|e| (i, place_code(&e)))
    }

    /// Reads reference `j` of parent `parent` and checks it names a node of
    /// this input.
    fn read_ref(
        &self,
        tx: &mut FetchTransaction,
        j: u32,
        parent: u32,
        child_port: bool,
    ) -> Result<Reference, Stop> {
        let r = self.h.refs[j as usize];
        if child_port {
            tx.cref_reqs.push(j);
            tx.cref_resps.push(r);
        } else {
            tx.ref_reqs.push(j);
            tx.ref_resps.push(r);
        }
        if r.hier != self.h.id {
            return Err((parent, fetch_err::REF_HIER));
        }
        if r.node as usize >= self.h.nodes.len() {
            return Err((parent, fetch_err::REF_NODE));
        }
        Ok(r)
    }

    /// An inner node's reference range must lie inside `refs` ([`children`]'s
    /// range check; the references themselves are checked as they are read).
    fn check_range(&self, n: &PlacedNode) -> Result<(), Stop> {
        match children(self.h, n.at.node, &self.h.nodes[n.at.node as usize]) {
            Err(MergeError::BadInput {
                field: "first/count",
                ..
            }) => Err((n.at.node, fetch_err::RANGE)),
            _ => Ok(()),
        }
    }

    /// The header checks after the entry's: `root_count` and the sorter's
    /// capacity (before any read).
    fn check_header(&self) -> Result<(), Stop> {
        let h = self.h;
        if h.root_count == 0 || h.root_count as usize > h.nodes.len() {
            return Err((0, fetch_err::ROOT_COUNT));
        }
        if h.root_count as usize > self.sizes.roots {
            return Err((0, fetch_err::ROOT_CAPACITY));
        }
        Ok(())
    }

    /// Roots in stored order; the first failing one is reported before any
    /// visit, the others are sorted (the top level in walk order).
    fn read_roots(
        &self,
        tx: &mut FetchTransaction,
        v: &mut Visit,
        o: &mut OutOrder,
    ) -> Vec<PlacedNode> {
        let h = self.h;
        let mut level = Vec::new();
        let mut root_err = None;
        for i in 0..h.root_count {
            match self.read_node(tx, i, h.top_lod) {
                Ok(n) => level.push(n),
                Err(e) => {
                    root_err.get_or_insert(e);
                }
            }
        }
        sort_stream(&mut level);
        if let Some(e) = root_err {
            self.error(tx, v, o, e);
        }
        level
    }

    /// The walk after the header checks: every read derived from valid
    /// data is made (so the request streams do not depend on timing);
    /// `out` stops after the first error beat, `leaves` after the first
    /// error the visit stage sees.
    fn run(&self, tx: &mut FetchTransaction, o: &mut OutOrder) -> Result<(), Stop> {
        let (h, cmd) = (self.h, self.cmd);
        self.check_header()?;
        let mut v = Visit::default();
        let level = self.read_roots(tx, &mut v, o);
        let mut frontier: VecDeque<(u32, u32, u32)> = VecDeque::new();
        let mut d = h.top_lod;
        for n in &level {
            self.visit(tx, n, d, &mut v, o, &mut frontier);
        }
        while d < cmd.lod && !frontier.is_empty() {
            // Level d is over and the walk goes on: its End when it is sent.
            if o.next_end == d {
                o.level_end(self, tx);
            }
            d += 1;
            v.prev = None;
            v.pushed = 0;
            let ranges: Vec<_> = frontier.drain(..).collect();
            for (first, count, parent) in ranges {
                for j in first..first + count {
                    let n = self
                        .read_ref(tx, j, parent, false)
                        .and_then(|c| self.read_node(tx, c.node, d));
                    match n {
                        Ok(n) => self.visit(tx, &n, d, &mut v, o, &mut frontier),
                        Err(e) => self.error(tx, &mut v, o, e),
                    }
                }
            }
        }
        if cmd.send_leaves {
            tx.leaves.push(LeafOut::End);
        }
        Ok(())
    }

    /// An error met in visit order: the visit stage stops sending leaves;
    /// the out stage sends a held node's references first.
    fn error(&self, tx: &mut FetchTransaction, v: &mut Visit, o: &mut OutOrder, e: Stop) {
        v.errored = true;
        if let Some(p) = o.pending.take() {
            self.send_refs(tx, o, &p);
        }
        o.emit(
            tx,
            FetchOut::Error {
                hier: self.h.id,
                node: e.0,
                code: e.1,
            },
        );
    }

    /// The child references of `n` at the command's level (`cref` reads),
    /// on `out`; a bad one is an error beat naming `n`.
    fn send_refs(&self, tx: &mut FetchTransaction, o: &mut OutOrder, n: &PlacedNode) {
        let r = n.record.range();
        for j in r.start as u32..r.end as u32 {
            match self.read_ref(tx, j, n.at.node, true) {
                Ok(c) => o.emit(tx, FetchOut::Beat(LevelBeat::ChildRef(c))),
                Err((node, code)) => o.emit(
                    tx,
                    FetchOut::Error {
                        hier: self.h.id,
                        node,
                        code,
                    },
                ),
            }
        }
    }

    /// One node of level `d` that passed its reference and record checks,
    /// in walk order.
    fn visit(
        &self,
        tx: &mut FetchTransaction,
        n: &PlacedNode,
        d: u8,
        v: &mut Visit,
        o: &mut OutOrder,
        frontier: &mut VecDeque<(u32, u32, u32)>,
    ) {
        let cmd = self.cmd;
        let key = (morton(&n.record.voxel), n.record.leaf);
        // Every visited node is the next one's predecessor, passing or not.
        let order_bad = v.prev.is_some_and(|p| p >= key);
        v.prev = Some(key);
        if order_bad {
            return self.error(tx, v, o, (n.at.node, fetch_err::ORDER));
        }
        let inner = !n.record.leaf;
        if inner && (d < cmd.lod || (d == cmd.lod && cmd.send_refs)) {
            if let Err(e) = self.check_range(n) {
                return self.error(tx, v, o, e);
            }
        }
        if d < cmd.lod && inner {
            if v.pushed >= self.sizes.frontier {
                return self.error(tx, v, o, (n.at.node, fetch_err::FRONTIER));
            }
            v.pushed += 1;
            frontier.push_back((n.record.first, n.record.count, n.at.node));
        }
        if d < cmd.first() {
            if !inner && cmd.send_leaves && !v.errored {
                tx.leaves.push(LeafOut::Leaf {
                    record: n.record,
                    at: n.at,
                });
            }
            return;
        }
        if d > cmd.lod {
            return;
        }
        // At the level: a voxel's inner node, its leaf, then the inner
        // node's references (held until the voxel's leaf has passed).
        if let Some(p) = o.pending.take() {
            let leaf_of_p = n.record.leaf && n.record.voxel == p.record.voxel;
            if !leaf_of_p {
                self.send_refs(tx, o, &p);
            }
            o.emit(tx, FetchOut::Beat(beat_of(n)));
            if leaf_of_p {
                self.send_refs(tx, o, &p);
            }
        } else {
            o.emit(tx, FetchOut::Beat(beat_of(n)));
        }
        if inner && cmd.send_refs {
            o.pending = Some(*n);
        }
    }
}

/// One inner node of a per-node pass, kept for the join with the module's
/// decisions: its translated voxel's Morton code and its reference range.
#[derive(Clone, Copy, Debug)]
struct PassEntry {
    key: u128,
    first: u32,
    count: u32,
    node: u32,
}

/// The `report` beats the fetcher is given, taken in order over all
/// commands.
struct ReportCursor<'r> {
    beats: &'r [PerNodeReport],
    next: usize,
}

/// A range `(first, count, parent)` of the frontier.
type Range = (u32, u32, u32);

impl Walk<'_> {
    /// The per-node command (SPEC 8.13): the walk to `lo` (the leaves above
    /// it), then pass after pass (the first at `max(lo, top)`); `header`:
    /// the entry's error, met before any read. An error (in out order)
    /// stands for its pass's `End`, and each later pass sends its `End`
    /// alone; the walk itself goes on (every read derived from valid data
    /// and the `report`'s decisions is made, so the request streams do not
    /// depend on timing) and the command takes the `report` beats pass by
    /// pass until `more` is 0, so the module's per-pass framing holds and
    /// nobody waits for this input.
    fn run_per_node(
        &self,
        tx: &mut FetchTransaction,
        o: &mut OutOrder,
        rep: &mut ReportCursor,
        header: Option<Stop>,
    ) -> Result<(), MergeError> {
        let lo = self.cmd.lod;
        let mut v = Visit::default();
        let mut entries = Vec::new();
        match header.or_else(|| self.check_header().err()) {
            Some(e) => self.error(tx, &mut v, o, e),
            None => {
                let level = self.read_roots(tx, &mut v, o);
                let mut frontier: VecDeque<Range> = VecDeque::new();
                let mut d = self.h.top_lod;
                for n in &level {
                    self.visit_per_node(tx, n, d, &mut v, o, &mut frontier, &mut entries);
                }
                while d < lo && !frontier.is_empty() {
                    d += 1;
                    v.prev = None;
                    v.pushed = 0;
                    let ranges: Vec<Range> = frontier.drain(..).collect();
                    self.walk_ranges(tx, &ranges, d, &mut v, o, &mut frontier, &mut entries);
                }
            }
        }
        if self.cmd.send_leaves {
            tx.leaves.push(LeafOut::End);
        }
        let mut l = lo.max(self.h.top_lod);
        loop {
            // The pass's `End`, after a held node's references.
            o.level_end(self, tx);
            let (descended, more) = self.join(tx, rep, &entries)?;
            entries.clear();
            if !more {
                return Ok(());
            }
            l = l.checked_add(1).ok_or(MergeError::BadInput {
                input: self.h.id,
                node: None,
                field: "report",
                expected: "a pass_end beat with more = 0 before LOD 255".into(),
                found: "more = 1".into(),
            })?;
            v.prev = None;
            v.pushed = 0;
            let mut unused = VecDeque::new();
            self.walk_ranges(tx, &descended, l, &mut v, o, &mut unused, &mut entries);
        }
    }

    /// Level `d`'s nodes: each reference of `ranges` read (`ref`), checked,
    /// its node read (`node`) at LOD `d` and visited.
    #[allow(clippy::too_many_arguments)]
    fn walk_ranges(
        &self,
        tx: &mut FetchTransaction,
        ranges: &[Range],
        d: u8,
        v: &mut Visit,
        o: &mut OutOrder,
        frontier: &mut VecDeque<Range>,
        entries: &mut Vec<PassEntry>,
    ) {
        for &(first, count, parent) in ranges {
            for j in first..first + count {
                let n = self
                    .read_ref(tx, j, parent, false)
                    .and_then(|c| self.read_node(tx, c.node, d));
                match n {
                    Ok(n) => self.visit_per_node(tx, &n, d, v, o, frontier, entries),
                    Err(e) => self.error(tx, v, o, e),
                }
            }
        }
    }

    /// A node of level `d` of a per-node command: above the first pass the
    /// level walk's visit (ranges pushed, leaves sent); at or below it a
    /// live node of the pass: the order check, an inner node's range check
    /// and the pass's capacity (`frontier` inner nodes: `FRONTIER`), its
    /// entry kept for the join, then the out stage: per voxel the inner
    /// node's probes and the node, the leaf, the inner node's references.
    #[allow(clippy::too_many_arguments)]
    fn visit_per_node(
        &self,
        tx: &mut FetchTransaction,
        n: &PlacedNode,
        d: u8,
        v: &mut Visit,
        o: &mut OutOrder,
        frontier: &mut VecDeque<Range>,
        entries: &mut Vec<PassEntry>,
    ) {
        if d < self.cmd.lod {
            return self.visit(tx, n, d, v, o, frontier);
        }
        let key = (morton(&n.record.voxel), n.record.leaf);
        let order_bad = v.prev.is_some_and(|p| p >= key);
        v.prev = Some(key);
        if order_bad {
            return self.error(tx, v, o, (n.at.node, fetch_err::ORDER));
        }
        let inner = !n.record.leaf;
        if inner {
            if let Err(e) = self.check_range(n) {
                return self.error(tx, v, o, e);
            }
            if v.pushed >= self.sizes.frontier {
                return self.error(tx, v, o, (n.at.node, fetch_err::FRONTIER));
            }
            v.pushed += 1;
            entries.push(PassEntry {
                key: key.0,
                first: n.record.first,
                count: n.record.count,
                node: n.at.node,
            });
        }
        match o.pending.take() {
            Some(p) if n.record.leaf && n.record.voxel == p.record.voxel => {
                o.emit(tx, FetchOut::Beat(beat_of(n)));
                self.send_refs(tx, o, &p);
            }
            held => {
                if let Some(p) = held {
                    self.send_refs(tx, o, &p);
                }
                if inner {
                    self.send_probes(tx, o, n, d);
                }
                o.emit(tx, FetchOut::Beat(beat_of(n)));
            }
        }
        if inner {
            o.pending = Some(*n);
        }
    }

    /// The probes of inner node `n` at LOD `d`: each child reference read
    /// (`cref`) and checked (naming `n`), its node read on the `probe` port,
    /// checked at LOD `d + 1` and moved (naming the child).
    fn send_probes(&self, tx: &mut FetchTransaction, o: &mut OutOrder, n: &PlacedNode, d: u8) {
        let r = n.record.range();
        for j in r.start as u32..r.end as u32 {
            let probe = self.read_ref(tx, j, n.at.node, true).and_then(|c| {
                tx.probe_reqs.push(c.node);
                let rec = self.h.nodes[c.node as usize];
                tx.probe_resps.push(rec);
                if d.checked_add(1) != Some(rec.voxel.lod) {
                    return Err((c.node, fetch_err::LOD));
                }
                place_node(self.h, 0, &self.t, c.node).map_err(|e| (c.node, place_code(&e)))
            });
            let beat = match probe {
                Ok(c) => FetchOut::Probe {
                    record: c.record,
                    at: c.at,
                },
                Err((node, code)) => FetchOut::Error {
                    hier: self.h.id,
                    node,
                    code,
                },
            };
            o.emit(tx, beat);
        }
    }

    /// The join of the pass's inner nodes (`entries`, in Morton order) with
    /// the module's decisions (contested voxels in Morton order, then the
    /// `pass_end` beat): a decision at an entry's voxel with `descend` (at a
    /// LOD above D: a voxel at D has no child voxels) puts the entry's
    /// range on the next pass; a decision at a voxel of no entry is passed
    /// over. Returns the descending ranges and `more` (a
    /// refusal beat ends the command as `more` = 0).
    fn join(
        &self,
        tx: &mut FetchTransaction,
        rep: &mut ReportCursor,
        entries: &[PassEntry],
    ) -> Result<(Vec<Range>, bool), MergeError> {
        let mut ranges = Vec::new();
        let mut i = 0;
        loop {
            let Some(&r) = rep.beats.get(rep.next) else {
                return Err(MergeError::BadInput {
                    input: self.h.id,
                    node: None,
                    field: "report",
                    expected: "a pass_end beat closing every pass of a per-node command".into(),
                    found: format!("the stream's end after {} beats", rep.next),
                });
            };
            rep.next += 1;
            tx.reports.push(r);
            match r {
                PerNodeReport::Decision { voxel, descend, .. } => {
                    let key = morton(&voxel);
                    while entries.get(i).is_some_and(|e| e.key < key) {
                        i += 1;
                    }
                    if let Some(e) = entries.get(i).filter(|e| e.key == key) {
                        if descend && voxel.lod < self.h.params.max_lod {
                            ranges.push((e.first, e.count, e.node));
                        }
                        i += 1;
                    }
                }
                PerNodeReport::PassEnd { more, .. } => return Ok((ranges, more)),
                PerNodeReport::Refused { .. } => return Ok((ranges, false)),
            }
        }
    }
}

/// The visit stage's state over one command.
#[derive(Default)]
struct Visit {
    /// The key (Morton code, leaf) of the level's previous visited node.
    prev: Option<(u128, bool)>,
    /// Ranges pushed at this level (the frontier's capacity rule).
    pushed: usize,
    /// An error has passed: no more leaves.
    errored: bool,
}

/// The out stage's state over one command.
#[derive(Default)]
struct OutOrder {
    /// An inner node at the level whose references wait for its leaf.
    pending: Option<PlacedNode>,
    /// The error beat has been sent: only the later levels' `End`s follow.
    errored: bool,
    /// The error beat stands for the `End` of the level it fell in: the
    /// next `End` is not sent.
    skip_end: bool,
    /// The level whose `End` is owed next (`first..=lod`).
    next_end: u8,
}

impl OutOrder {
    fn new(cmd: &FetchCmd) -> OutOrder {
        OutOrder {
            pending: None,
            errored: false,
            skip_end: false,
            next_end: cmd.first(),
        }
    }

    /// `o` in out order: after the first error beat only `End`s go on,
    /// the first of them replaced by the error.
    fn emit(&mut self, tx: &mut FetchTransaction, o: FetchOut) {
        match o {
            FetchOut::Error { .. } if !self.errored => {
                self.errored = true;
                self.skip_end = true;
                tx.out.push(o);
            }
            FetchOut::Beat(LevelBeat::End) if self.skip_end => self.skip_end = false,
            FetchOut::Beat(LevelBeat::End) => tx.out.push(o),
            _ if !self.errored => tx.out.push(o),
            _ => {}
        }
    }

    /// The `End` of level `next_end`, after a held node's references.
    fn level_end(&mut self, walk: &Walk, tx: &mut FetchTransaction) {
        if let Some(p) = self.pending.take() {
            walk.send_refs(tx, self, &p);
        }
        self.emit(tx, FetchOut::Beat(LevelBeat::End));
        self.next_end += 1;
    }

    /// The command's start: the `End`s of the levels above the top but
    /// the last (they hold no node; the last level's `End` closes the
    /// walk), before any check.
    fn start(&mut self, walk: &Walk, tx: &mut FetchTransaction) {
        while self.next_end < walk.cmd.lod.min(walk.h.top_lod) {
            self.level_end(walk, tx);
        }
    }

    /// The walk is over: every level still owed its `End`, `lod`'s last.
    fn finish(&mut self, walk: &Walk, tx: &mut FetchTransaction) {
        while self.next_end <= walk.cmd.lod {
            self.level_end(walk, tx);
        }
    }
}

/// A placed node as an S614 input beat.
fn beat_of(n: &PlacedNode) -> LevelBeat {
    if n.record.leaf {
        LevelBeat::Leaf {
            record: n.record,
            at: n.at,
        }
    } else {
        LevelBeat::Inner {
            record: n.record,
            at: n.at,
        }
    }
}

/// The fetcher's run of input `h` with translation entry `entry` (packed,
/// as the table holds it) over `cmds`. Refused (an error, never a panic)
/// when `h`'s array lengths do not fit the `cfg` fields (`I` bits), or a
/// command is per-node ([`fetch_transaction_with_reports`] gives those
/// their `report` beats).
pub fn fetch_transaction(
    h: &Hierarchy,
    entry: u128,
    cmds: &[FetchCmd],
    sizes: FetchSizes,
) -> Result<FetchTransaction, MergeError> {
    fetch_transaction_with_reports(h, entry, cmds, &[], sizes)
}

/// [`fetch_transaction`] with the `report` beats the fetcher's per-node
/// commands take, in order (the per-node module's `report` stream, e.g.
/// [`super::per_node_unit::PerNodeTransaction::reports`]). Refused when a
/// per-node command's pass finds no `pass_end` beat left.
pub fn fetch_transaction_with_reports(
    h: &Hierarchy,
    entry: u128,
    cmds: &[FetchCmd],
    reports: &[PerNodeReport],
    sizes: FetchSizes,
) -> Result<FetchTransaction, MergeError> {
    let p = &h.params;
    let cap = p.index_capacity();
    for (what, n) in [("nodes", h.nodes.len()), ("refs", h.refs.len())] {
        if n as u64 >= cap {
            return Err(MergeError::BadInput {
                input: h.id,
                node: None,
                field: what,
                expected: format!("fewer than 2^I = {cap} (the cfg field)"),
                found: n.to_string(),
            });
        }
    }
    if h.root_count as u64 >= cap {
        return Err(MergeError::BadInput {
            input: h.id,
            node: None,
            field: "root_count",
            expected: format!("below 2^I = {cap}"),
            found: h.root_count.to_string(),
        });
    }
    let mut cfg = FetchCfg::of(h, None);
    cfg.entry = entry;
    let mut tx = FetchTransaction {
        cfg,
        cmds: cmds.to_vec(),
        node_reqs: Vec::new(),
        node_resps: Vec::new(),
        ref_reqs: Vec::new(),
        ref_resps: Vec::new(),
        cref_reqs: Vec::new(),
        cref_resps: Vec::new(),
        probe_reqs: Vec::new(),
        probe_resps: Vec::new(),
        reports: Vec::new(),
        out: Vec::new(),
        leaves: Vec::new(),
    };
    let t = unpack_entry(entry, p).ok().flatten();
    let mut rep = ReportCursor {
        beats: reports,
        next: 0,
    };
    for &cmd in cmds {
        // An invalid entry reads nothing; the walk's translation is unused.
        let walk = Walk {
            h,
            t: t.unwrap_or(Translation::zero(0)),
            cmd,
            sizes,
        };
        let mut o = OutOrder::new(&cmd);
        if cmd.per_node {
            let header = t.is_none().then_some((0, fetch_err::ENTRY));
            walk.run_per_node(&mut tx, &mut o, &mut rep, header)?;
            continue;
        }
        o.start(&walk, &mut tx);
        let stop = match t {
            None => Err((0, fetch_err::ENTRY)),
            Some(_) => walk.run(&mut tx, &mut o),
        };
        if let Err((node, code)) = stop {
            o.emit(
                &mut tx,
                FetchOut::Error {
                    hier: h.id,
                    node,
                    code,
                },
            );
            if cmd.send_leaves {
                tx.leaves.push(LeafOut::End);
            }
        }
        o.finish(&walk, &mut tx);
    }
    Ok(tx)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::build::{build, GridMap};
    use crate::merge::top::input_stream;
    use crate::merge::walk::{collect, walk_input};
    use crate::scenes::random_soup;
    use crate::translate::table::pack_entry;

    fn soup(p: &Params, id: u8, n: usize, size: f32, seed: u64) -> Hierarchy {
        let mesh = random_soup(n, size, seed);
        let grid = GridMap {
            origin: glam::DVec3::ZERO,
            unit: 1.0 / (p.scene_edge() >> 3) as f64,
        };
        build(&mesh, &grid, p, id).expect("the soup builds")
    }

    /// A translation at the top LOD by about `frac` of the room left.
    fn place(h: &Hierarchy, frac: f64) -> Translation {
        let l = h.top_lod;
        let t = [0, 1, 2].map(|a| {
            let max = h
                .roots()
                .iter()
                .map(|n| [n.voxel.x, n.voxel.y, n.voxel.z][a] as i64)
                .max()
                .unwrap();
            (((1i64 << l) - 1 - max) as f64 * frac) as i64
        });
        Translation { lod: l, t }
    }

    fn deepest(h: &Hierarchy) -> u8 {
        h.nodes.iter().map(|n| n.voxel.lod).max().unwrap()
    }

    /// On builder-made inputs, every level's stream equals the walk's
    /// `input_stream` and the leaves equal `collect`'s leaves above, in
    /// (LOD, Morton) order.
    #[test]
    fn fetch_equals_the_walk_on_built_inputs() {
        let p = Params::default();
        let mut levels = 0;
        for (i, (n, size)) in [(1, 0.01), (40, 0.2), (200, 0.3), (60, 0.05)]
            .iter()
            .enumerate()
        {
            let h = soup(&p, 1 + i as u8, *n, *size, 7 + i as u64);
            for frac in [0.0, 0.5, 1.0] {
                let t = place(&h, frac);
                for l in h.top_lod.saturating_sub(1)..=deepest(&h) + 1 {
                    let cmd = FetchCmd {
                        lod: l,
                        send_refs: l % 2 == 0,
                        send_leaves: true,
                        last: true,
                        from: l,
                        per_node: false,
                    };
                    let tx = fetch_transaction(
                        &h,
                        pack_entry(Some(&t), &p),
                        &[cmd],
                        FetchSizes::default(),
                    )
                    .unwrap();
                    let w = walk_input(&h, 0, &t, l).unwrap();
                    let (above, at) = collect(std::slice::from_ref(&w), l);
                    let want = input_stream(&at, &[&h], 0, cmd.send_refs).unwrap();
                    let got: Vec<LevelBeat> = tx
                        .out
                        .iter()
                        .map(|o| match o {
                            FetchOut::Beat(b) => *b,
                            e => panic!("{e:?}"),
                        })
                        .collect();
                    assert_eq!(got, want, "level {l}");
                    let mut above = above.clone();
                    above.sort_by_key(|n| (n.record.voxel.lod, n.record.voxel.morton()));
                    let mut want_leaves: Vec<LeafOut> = above
                        .iter()
                        .map(|n| LeafOut::Leaf {
                            record: n.record,
                            at: n.at,
                        })
                        .collect();
                    want_leaves.push(LeafOut::End);
                    assert_eq!(tx.leaves, want_leaves, "level {l}");
                    assert_eq!(tx.node_reqs.len(), tx.node_resps.len());
                    let walked: usize = w.by_lod.iter().map(Vec::len).sum();
                    assert_eq!(tx.node_reqs.len(), walked, "one read per walked node");
                    levels += 1;
                }
            }
        }
        assert!(levels > 30);
    }

    /// A small hand-made input: root 0 (inner, LOD 1) with children 1, 2.
    fn tiny(p: &Params) -> Hierarchy {
        let rec = |leaf: bool, lod: u8, x: u32, first: u32, count: u32| NodeRecord {
            leaf,
            voxel: crate::grid::VoxelAddr::new(lod, x, 0, 0),
            lo: [0; 3],
            hi: [0; 3],
            first,
            count,
        };
        Hierarchy {
            id: 3,
            params: *p,
            nodes: vec![
                rec(false, 1, 0, 0, 2),
                rec(true, 2, 0, 0, 1),
                rec(true, 2, 1, 0, 1),
            ],
            refs: vec![
                Reference { hier: 3, node: 1 },
                Reference { hier: 3, node: 2 },
            ],
            prims: vec![0],
            root_count: 1,
            top_lod: 1,
        }
    }

    fn error_of(h: &Hierarchy, t: Option<&Translation>, lod: u8, sizes: FetchSizes) -> (u32, u64) {
        let cmd = FetchCmd {
            lod,
            send_refs: true,
            send_leaves: true,
            last: true,
            from: lod,
            per_node: false,
        };
        let tx = fetch_transaction(h, pack_entry(t, &h.params), &[cmd], sizes).unwrap();
        match tx.out.last() {
            Some(FetchOut::Error { node, code, .. }) => (*node, *code),
            o => panic!("no error: {o:?} in {tx:?}"),
        }
    }

    #[test]
    fn entry_fields_read_the_packed_entry() {
        for p in [Params::default(), Params::new(31, 16, 32, 8).unwrap()] {
            let l = FetchLayout::new(&p);
            let t = Translation {
                lod: 3,
                t: [-5, 7, -(1 << (p.max_lod - 1))],
            };
            let b = FetchCfg {
                hier: 1,
                root_count: 1,
                top_lod: 3,
                nodes: 1,
                refs: 0,
                entry: pack_entry(Some(&t), &p),
            }
            .pack(&l)
            .unwrap();
            assert_eq!(b.get(&l.entry_valid).unwrap(), 1);
            assert_eq!(b.get(&l.entry_lod).unwrap(), 3);
            for a in 0..3 {
                let code = b.get(&l.entry_t[a]).unwrap();
                let w = l.entry_t[a].width;
                let v = ((code << (64 - w)) as i64) >> (64 - w);
                assert_eq!(v, t.t[a], "axis {a}");
            }
            assert_eq!(l.entry_t[2].end(), l.entry.end());
        }
    }

    /// One command sending `from..=lod` is one walk to `lod`: its `out` is
    /// the single-level commands' `out`s one after the other, its node and
    /// reference reads the walk to `lod`'s, its child-reference reads the
    /// levels' in turn, its leaves those above `from`.
    #[test]
    fn one_walk_sends_every_level() {
        let p = Params::default();
        let mut runs = 0;
        for (i, (n, size)) in [(1, 0.01), (40, 0.2), (120, 0.3)].iter().enumerate() {
            let h = soup(&p, 1 + i as u8, *n, *size, 17 + i as u64);
            let entry = pack_entry(Some(&place(&h, 0.5)), &p);
            let s = FetchSizes::default();
            let top = h.top_lod;
            for from in top.saturating_sub(2)..=deepest(&h) {
                for lod in from..=deepest(&h) + 1 {
                    let refs = (from + lod) % 2 == 0;
                    let multi = FetchCmd {
                        from,
                        ..FetchCmd::level(lod, refs, true, true)
                    };
                    let tx = fetch_transaction(&h, entry, &[multi], s).unwrap();
                    let one = |l: u8| {
                        fetch_transaction(&h, entry, &[FetchCmd::level(l, refs, true, true)], s)
                            .unwrap()
                    };
                    let deep = one(lod);
                    let want: Vec<FetchOut> = (from..=lod).flat_map(|l| one(l).out).collect();
                    assert_eq!(tx.out, want, "{from}..={lod}");
                    let ends = tx
                        .out
                        .iter()
                        .filter(|o| **o == FetchOut::Beat(LevelBeat::End))
                        .count();
                    assert_eq!(ends, multi.levels());
                    assert_eq!(tx.node_reqs, deep.node_reqs);
                    assert_eq!(tx.ref_reqs, deep.ref_reqs);
                    let crefs: Vec<u32> = (from..=lod).flat_map(|l| one(l).cref_reqs).collect();
                    assert_eq!(tx.cref_reqs, crefs);
                    assert_eq!(tx.leaves, one(from).leaves);
                    runs += 1;
                }
            }
        }
        assert!(runs > 20);
        // `from` past `lod` is the single-level command.
        let h = soup(&p, 1, 40, 0.2, 3);
        let entry = pack_entry(Some(&place(&h, 0.0)), &p);
        let l = h.top_lod + 1;
        let run = |c| fetch_transaction(&h, entry, &[c], FetchSizes::default()).unwrap();
        let past = FetchCmd {
            from: l + 3,
            ..FetchCmd::level(l, true, true, true)
        };
        assert_eq!(run(past).out, run(FetchCmd::level(l, true, true, true)).out);
    }

    /// An error ends the level it falls in (the error beat for its `End`);
    /// every later level sends its `End` alone; the levels above the top
    /// but the last end before any check.
    #[test]
    fn an_error_ends_its_level_and_later_levels_send_end() {
        let p = Params::new(4, 1, 6, 2).unwrap();
        let t0 = pack_entry(Some(&Translation::zero(1)), &p);
        let cmd = |from, lod| FetchCmd {
            from,
            ..FetchCmd::level(lod, false, false, false)
        };
        let end = FetchOut::Beat(LevelBeat::End);
        let err = |node, code| FetchOut::Error {
            hier: 3,
            node,
            code,
        };
        let run = |h: &Hierarchy, entry, c| {
            fetch_transaction(h, entry, &[c], FetchSizes::default())
                .unwrap()
                .out
        };
        // tiny: the root (inner, LOD 1), leaves 1 and 2 at LOD 2.
        let h = tiny(&p);
        let beat = |i: usize| {
            FetchOut::Beat(beat_of(
                &place_node(&h, 0, &Translation::zero(1), i as u32).unwrap(),
            ))
        };
        assert_eq!(
            run(&h, t0, cmd(0, 3)),
            vec![end, beat(0), end, beat(1), beat(2), end, end]
        );
        // Node 2's LOD is wrong: level 2 ends with the error, level 3 sends End.
        let mut b = h.clone();
        b.nodes[2].voxel.lod = 3;
        assert_eq!(
            run(&b, t0, cmd(0, 3)),
            vec![end, beat(0), end, beat(1), err(2, fetch_err::LOD), end]
        );
        // The header: level 0 (above the top) ends first, then the error
        // for level 1, then level 2's End.
        assert_eq!(
            run(&h, 0, cmd(0, 2)),
            vec![end, err(0, fetch_err::ENTRY), end]
        );
        // A RANGE error at level 1 (its range is walked for level 2).
        let mut b = h.clone();
        b.nodes[0].count = 3;
        assert_eq!(run(&b, t0, cmd(1, 2)), vec![err(0, fetch_err::RANGE), end]);
        // A level above the top: its End after the roots' checks (an error
        // there stands for it).
        assert_eq!(run(&h, t0, cmd(0, 0)), vec![end]);
        let mut b = h.clone();
        b.nodes[0].voxel.x = 2;
        assert_eq!(run(&b, t0, cmd(0, 0)), vec![err(0, fetch_err::RECORD)]);
        // Levels 0..=2 with that root: level 0 ends first, the root's error
        // ends level 1, level 2 sends End.
        assert_eq!(
            run(&b, t0, cmd(0, 2)),
            vec![end, err(0, fetch_err::RECORD), end]
        );
    }

    #[test]
    fn every_error_code_names_its_record() {
        let p = Params::new(4, 1, 6, 2).unwrap();
        let h = tiny(&p);
        let t0 = Translation::zero(1);
        let s = FetchSizes::default();
        assert_eq!(error_of(&h, None, 2, s), (0, fetch_err::ENTRY));
        let mut b = h.clone();
        b.root_count = 0;
        assert_eq!(error_of(&b, Some(&t0), 2, s), (0, fetch_err::ROOT_COUNT));
        b.root_count = 4;
        assert_eq!(error_of(&b, Some(&t0), 2, s), (0, fetch_err::ROOT_COUNT));
        b.root_count = 2;
        b.nodes[1].voxel.lod = 1;
        let small = FetchSizes {
            roots: 1,
            frontier: 4,
        };
        assert_eq!(
            error_of(&b, Some(&t0), 2, small),
            (0, fetch_err::ROOT_CAPACITY)
        );
        let mut b = h.clone();
        b.nodes[2].lo[0] = 1;
        b.nodes[2].hi[0] = 0;
        assert_eq!(error_of(&b, Some(&t0), 2, s), (2, fetch_err::RECORD));
        let mut b = h.clone();
        b.nodes[2].voxel.lod = 3;
        assert_eq!(error_of(&b, Some(&t0), 2, s), (2, fetch_err::LOD));
        let mut b = h.clone();
        b.nodes[0].count = 3;
        assert_eq!(error_of(&b, Some(&t0), 2, s), (0, fetch_err::RANGE));
        let mut b = h.clone();
        b.refs[1].hier = 2;
        assert_eq!(error_of(&b, Some(&t0), 2, s), (0, fetch_err::REF_HIER));
        let mut b = h.clone();
        b.refs[1].node = 3;
        assert_eq!(error_of(&b, Some(&t0), 2, s), (0, fetch_err::REF_NODE));
        let above = Translation::zero(2);
        assert_eq!(error_of(&h, Some(&above), 2, s), (0, fetch_err::ABOVE));
        for a in 0..3 {
            let mut t = t0;
            // The root at LOD 1 leaves [0, 2) moved by 2.
            t.t[a] = 2;
            let code = error_of(&h, Some(&t), 2, s).1;
            assert_eq!(code, fetch_err::OUTSIDE_X + a as u64, "axis {a}");
        }
        let tight = FetchSizes {
            roots: 16,
            frontier: 0,
        };
        assert_eq!(error_of(&h, Some(&t0), 2, tight), (0, fetch_err::FRONTIER));
        let mut b = h.clone();
        b.refs.swap(0, 1);
        assert_eq!(error_of(&b, Some(&t0), 2, s), (1, fetch_err::ORDER));
    }

    /// After an error the walk still makes every read derived from valid
    /// data (the request streams do not depend on timing); `out` ends with
    /// the first error beat.
    #[test]
    fn reads_continue_after_the_first_error() {
        let p = Params::new(4, 1, 6, 2).unwrap();
        let mut b = tiny(&p);
        b.refs[0].hier = 2;
        b.nodes[2].voxel.lod = 3;
        let cmd = FetchCmd {
            lod: 2,
            send_refs: true,
            send_leaves: true,
            last: true,
            from: 2,
            per_node: false,
        };
        let t0 = pack_entry(Some(&Translation::zero(1)), &p);
        let tx = fetch_transaction(&b, t0, &[cmd], FetchSizes::default()).unwrap();
        assert_eq!(tx.ref_reqs, vec![0, 1]);
        assert_eq!(tx.node_reqs, vec![0, 2], "node 2 read though ref 0 failed");
        assert_eq!(
            tx.out,
            vec![FetchOut::Error {
                hier: 3,
                node: 0,
                code: fetch_err::REF_HIER
            }]
        );
        assert_eq!(tx.leaves, vec![LeafOut::End]);
        // At LOD 1 with send_refs the root's references go on `cref`.
        let cmd1 = FetchCmd {
            lod: 1,
            from: 1,
            ..cmd
        };
        let tx = fetch_transaction(&tiny(&p), t0, &[cmd1], FetchSizes::default()).unwrap();
        assert_eq!(tx.cref_reqs, vec![0, 1]);
        assert!(tx.ref_reqs.is_empty());
        assert_eq!(tx.out.len(), 4, "root, two child references, End");
    }

    /// The walk's own errors for the same defects: the codes match what
    /// `walk_input` / `input_stream` refuse.
    #[test]
    fn errors_are_the_walks_refusals() {
        let p = Params::new(4, 1, 6, 2).unwrap();
        let h = tiny(&p);
        let t0 = Translation::zero(1);
        let mut b = h.clone();
        b.refs[1].hier = 2;
        assert!(matches!(
            walk_input(&b, 0, &t0, 2),
            Err(MergeError::BadInput {
                node: Some(0),
                field: "reference",
                ..
            })
        ));
        let mut b = h.clone();
        b.nodes[2].voxel.lod = 3;
        assert!(matches!(
            walk_input(&b, 0, &t0, 2),
            Err(MergeError::BadInput {
                node: Some(2),
                field: "lod",
                ..
            })
        ));
        assert!(matches!(
            walk_input(&h, 0, &Translation::zero(2), 2),
            Err(MergeError::TranslateNode { node: 0, .. })
        ));
        // A fine input passes: End after the two leaves.
        let cmd = FetchCmd {
            lod: 2,
            send_refs: true,
            send_leaves: false,
            last: true,
            from: 2,
            per_node: false,
        };
        let tx = fetch_transaction(&h, pack_entry(Some(&t0), &p), &[cmd], FetchSizes::default())
            .unwrap();
        assert_eq!(tx.out.len(), 3);
        assert_eq!(tx.node_reqs, vec![0, 1, 2]);
        assert_eq!(tx.ref_reqs, vec![0, 1]);
    }

    use crate::merge::per_node_unit::{random_per_node_case, PerNodeBeat, PerNodeCase};
    use crate::translate::stimulus::SplitMix64;

    /// What the per-node checks reached.
    #[derive(Default, Debug)]
    struct PerNodeSeen {
        merges: usize,
        inputs: usize,
        multi_pass: usize,
        descended_inputs: usize,
        roots_reordered: usize,
        leaves: usize,
        probes: usize,
    }

    /// Input `r` of `c` through one per-node command given the module's
    /// `report` stream: its `out` must be the module's input stream for
    /// that input, every `report` beat taken, the leaves those above `lo`.
    fn check_per_node_input(
        p: &Params,
        c: &PerNodeCase,
        tx: &crate::merge::per_node_unit::PerNodeTransaction,
        r: usize,
        seen: &mut PerNodeSeen,
    ) {
        let h = &c.hierarchies[r];
        let t = c.translations[r];
        let cmd = FetchCmd::per_node(c.lo, true, true);
        let l = FetchLayout::per_node(p);
        assert!(cmd.pack(&l).is_ok() && cmd.pack(&FetchLayout::new(p)).is_err());
        let f = fetch_transaction_with_reports(
            h,
            pack_entry(Some(&t), p),
            &[cmd],
            &tx.reports,
            FetchSizes::default(),
        )
        .unwrap();
        let got: Vec<PerNodeBeat> = f
            .out
            .iter()
            .map(|o| match *o {
                FetchOut::Beat(b) => PerNodeBeat::Level(b),
                FetchOut::Probe { record, at } => PerNodeBeat::Probe { record, at },
                e => panic!("input {r}: {e:?}"),
            })
            .collect();
        assert_eq!(got, tx.inputs[r], "input {r}");
        assert_eq!(f.reports, tx.reports, "input {r}: every report beat taken");
        // The glue's narrow `report` beat is the module's, field by field.
        let (pl, module) = (l.pn.as_ref().unwrap(), PerNodeLayout::new(p));
        for rep in &tx.reports {
            let (narrow, wide) = (pl.pack_report(rep).unwrap(), rep.pack(&module).unwrap());
            for (f, g) in pl.report_sources(&module) {
                assert_eq!(narrow.get(&f).unwrap(), wide.get(&g).unwrap(), "{}", f.name);
            }
        }
        // Each probe beat packs with its bit; the layout tiles `out`.
        for o in &f.out {
            let b = o.pack(&l).unwrap();
            let probe = l.pn.as_ref().unwrap().probe;
            assert_eq!(
                b.get(&probe).unwrap(),
                matches!(o, FetchOut::Probe { .. }) as u64
            );
        }
        let w = walk_input(h, r as u16, &t, c.lo).unwrap();
        let (mut above, _) = collect(std::slice::from_ref(&w), c.lo);
        above.sort_by_key(|n| (n.record.voxel.lod, n.record.voxel.morton()));
        let mut want: Vec<LeafOut> = above
            .iter()
            .map(|n| LeafOut::Leaf {
                record: n.record,
                at: n.at,
            })
            .collect();
        want.push(LeafOut::End);
        assert_eq!(f.leaves, want, "input {r}");
        // One probe read per probe beat; the walk and the passes on `node`.
        let probes = f
            .out
            .iter()
            .filter(|o| matches!(o, FetchOut::Probe { .. }))
            .count();
        assert_eq!(f.probe_reqs.len(), probes);
        seen.inputs += 1;
        seen.probes += probes;
        seen.leaves += above.len();
        let mut stored: Vec<u128> = Vec::new();
        let mut moved = Vec::new();
        for i in 0..h.root_count {
            if let Ok(n) = place_node(h, 0, &t, i) {
                stored.push(morton(&h.nodes[i as usize].voxel));
                moved.push(morton(&n.record.voxel));
            }
        }
        let order = |v: &[u128]| {
            let mut i: Vec<usize> = (0..v.len()).collect();
            i.sort_by_key(|&j| v[j]);
            i
        };
        seen.roots_reordered += (order(&stored) != order(&moved)) as usize;
        let descents = f.reports.iter().filter(|r| {
            matches!(r, PerNodeReport::Decision { descend: true, voxel, .. }
                if got.iter().any(|b| matches!(b, PerNodeBeat::Level(LevelBeat::Inner { record, .. })
                    if record.voxel == *voxel)))
        });
        seen.descended_inputs += (descents.count() > 0) as usize;
    }

    /// Moves the second root's subtree of `h` by one voxel on y at the top
    /// (its descendants by the same distance at their LODs), so that the
    /// two roots differ on two axes and a translation can swap their
    /// Morton order; false when `h` has one root or the move leaves the grid.
    fn skew_second_root(h: &mut Hierarchy, up: bool) -> bool {
        if h.root_count != 2 {
            return false;
        }
        let top = h.top_lod;
        let y = h.nodes[1].voxel.y as i64 + if up { 1 } else { -1 };
        if !(0..1i64 << top).contains(&y) {
            return false;
        }
        let mut todo = vec![1u32];
        while let Some(i) = todo.pop() {
            let n = &mut h.nodes[i as usize];
            let d = n.voxel.lod - top;
            n.voxel.y = if up {
                n.voxel.y + (1 << d)
            } else {
                n.voxel.y - (1 << d)
            };
            if !n.leaf {
                let r = n.range();
                todo.extend(
                    h.refs[r.start as usize..r.end as usize]
                        .iter()
                        .map(|r| r.node),
                );
            }
        }
        true
    }

    /// The per-node command sends, for every input, exactly the per-node
    /// module's input stream of that input (`per_node_transaction`), pass
    /// after pass, from the module's `report` beats: random octree merges
    /// (`random_per_node_case`, translations that reorder the roots among
    /// them) at the default, D = 31 and Q = 0 and four ratios.
    #[test]
    fn per_node_command_sends_the_modules_inputs() {
        let mut rng = SplitMix64(55);
        let mut seen = PerNodeSeen::default();
        let configs = [
            (Params::default(), 4),
            (Params::new(31, 16, 32, 8).unwrap(), 5),
            (Params::new(8, 0, 12, 3).unwrap(), 2),
        ];
        for (p, k) in configs {
            for (num, den) in [(1, 2), (0, 1), (1, 1), (1, 3)] {
                for i in 0..40 {
                    let mut c = random_per_node_case(&mut rng, &p, k, 4);
                    if i % 2 == 1 {
                        for h in &mut c.hierarchies {
                            skew_second_root(h, rng.below(2) == 0);
                        }
                    }
                    let Ok(tx) = c.transaction(&p, num, den) else {
                        continue;
                    };
                    if tx.passes == 0 {
                        continue;
                    }
                    seen.merges += 1;
                    seen.multi_pass += (tx.passes > 1) as usize;
                    for r in 0..k {
                        check_per_node_input(&p, &c, &tx, r, &mut seen);
                    }
                }
            }
        }
        eprintln!("{seen:?}");
        assert!(seen.merges > 300 && seen.multi_pass > 100, "{seen:?}");
        assert!(
            seen.descended_inputs > 300 && seen.roots_reordered > 5,
            "{seen:?}"
        );
        assert!(seen.leaves > 100 && seen.probes > 10_000, "{seen:?}");
    }

    /// The same on real merges: golden-built soups, overlapping and moved
    /// apart, 2-4 inputs, at the ratios that descend and stay.
    #[test]
    fn per_node_command_on_real_merges() {
        let p = Params::new(10, 3, 16, 3).unwrap();
        let mut rng = SplitMix64(8);
        let mut seen = PerNodeSeen::default();
        for case in 0..12u64 {
            let k = 2 + (case % 3) as usize;
            let hs: Vec<Hierarchy> = (0..k)
                .map(|i| {
                    let mesh = random_soup(
                        5 + rng.below(60) as usize,
                        0.05 + rng.below(30) as f32 / 100.0,
                        case * 10 + i as u64,
                    );
                    let grid = GridMap {
                        origin: glam::DVec3::ZERO,
                        unit: 1.0 / (p.scene_edge() >> 2) as f64,
                    };
                    build(&mesh, &grid, &p, i as u8 + 1).unwrap()
                })
                .collect();
            let translations: Vec<Translation> = hs
                .iter()
                .enumerate()
                .map(|(i, h)| Translation {
                    lod: h.top_lod,
                    t: [if case % 4 == 3 { i as i64 % 2 } else { 0 }, 0, 0],
                })
                .collect();
            let refs: Vec<&Hierarchy> = hs.iter().collect();
            let (lo, hi) = crate::merge::level::candidate_range(&refs);
            let c = PerNodeCase {
                hierarchies: hs,
                translations,
                lo,
                hi,
            };
            for (num, den) in [(1, 2), (0, 1), (1, 4)] {
                let Ok(tx) = c.transaction(&p, num, den) else {
                    continue;
                };
                seen.merges += 1;
                seen.multi_pass += (tx.passes > 1) as usize;
                for r in 0..k {
                    check_per_node_input(&p, &c, &tx, r, &mut seen);
                }
            }
        }
        eprintln!("{seen:?}");
        assert!(seen.merges > 20 && seen.multi_pass > 5, "{seen:?}");
        assert!(seen.descended_inputs > 10, "{seen:?}");
    }

    /// Errors of a per-node command: the error beat stands for its pass's
    /// `End`; the command still takes every `report` beat, each later pass
    /// sending `End` alone and reading nothing; a header error reads
    /// nothing at all; a `report` stream that ends early is refused.
    #[test]
    fn per_node_errors_end_their_pass_and_follow_the_report() {
        let p = Params::new(4, 1, 6, 2).unwrap();
        let t0 = pack_entry(Some(&Translation::zero(1)), &p);
        let s = FetchSizes::default();
        let end = FetchOut::Beat(LevelBeat::End);
        let v = |lod, x| crate::grid::VoxelAddr::new(lod, x, 0, 0);
        let decide = |voxel, descend| PerNodeReport::Decision {
            voxel,
            shared: 1,
            union: 1,
            descend,
        };
        let pass_end = |lod, more| PerNodeReport::PassEnd { lod, more };
        // tiny: root 0 (inner, LOD 1, x 0), leaves 1 (x 0) and 2 (x 1) at LOD 2.
        let h = tiny(&p);
        let place = |i: u32| place_node(&h, 0, &Translation::zero(1), i).unwrap();
        let probe = |i: u32| FetchOut::Probe {
            record: place(i).record,
            at: place(i).at,
        };
        let beat = |i: u32| FetchOut::Beat(beat_of(&place(i)));
        let cref = |i: u32| FetchOut::Beat(LevelBeat::ChildRef(h.refs[i as usize]));
        let reports = [decide(v(1, 0), true), pass_end(1, true), pass_end(2, false)];
        let run = |h: &Hierarchy, entry, reports: &[PerNodeReport]| {
            fetch_transaction_with_reports(
                h,
                entry,
                &[FetchCmd::per_node(1, true, true)],
                reports,
                s,
            )
        };
        // Pass 1: probes, the root, its references; the root descends, so
        // pass 2 sends its two leaves.
        let tx = run(&h, t0, &reports).unwrap();
        assert_eq!(
            tx.out,
            vec![
                probe(1),
                probe(2),
                beat(0),
                cref(0),
                cref(1),
                end,
                beat(1),
                beat(2),
                end
            ]
        );
        assert_eq!(tx.node_reqs, vec![0, 1, 2]);
        assert_eq!(tx.ref_reqs, vec![0, 1]);
        assert_eq!(tx.cref_reqs, vec![0, 1, 0, 1]);
        assert_eq!(tx.probe_reqs, vec![1, 2]);
        // A decision at another voxel, or not descending: one pass.
        for r in [decide(v(1, 1), true), decide(v(1, 0), false)] {
            let tx = run(&h, t0, &[r, pass_end(1, true), pass_end(2, false)]).unwrap();
            assert_eq!(
                tx.out[..6],
                [probe(1), probe(2), beat(0), cref(0), cref(1), end]
            );
            assert_eq!(tx.out[6..], [end], "pass 2 is empty");
            assert_eq!(tx.node_reqs, vec![0]);
        }
        // A probe at the wrong LOD: the error (naming the child) stands for
        // pass 1's End; pass 2 sends End alone, its reads still made.
        let mut b = h.clone();
        b.nodes[2].voxel.lod = 3;
        let tx = run(&b, t0, &reports).unwrap();
        let err = |node, code| FetchOut::Error {
            hier: 3,
            node,
            code,
        };
        assert_eq!(tx.out, vec![probe(1), err(2, fetch_err::LOD), end]);
        assert_eq!(tx.node_reqs, vec![0, 1, 2], "pass-2 reads after the error");
        assert_eq!(tx.reports, reports.to_vec());
        // An invalid entry: no read, the error for pass 1, End for pass 2.
        let tx = run(&h, 0, &reports).unwrap();
        assert_eq!(tx.out, vec![err(0, fetch_err::ENTRY), end]);
        assert!(tx.node_reqs.is_empty() && tx.cref_reqs.is_empty());
        assert_eq!(tx.leaves, vec![LeafOut::End]);
        // A refusal beat ends the command like `more` = 0.
        let refused = PerNodeReport::Refused { err: 3 };
        let tx = run(&h, t0, &[refused]).unwrap();
        assert_eq!(tx.out.last(), Some(&end));
        assert_eq!(tx.reports, vec![refused]);
        // The report stream ends before the last pass: refused.
        let e = run(&h, t0, &reports[..2]).unwrap_err();
        assert!(e.to_string().contains("report"), "{e}");
        // Too many inner nodes in a pass for `frontier`.
        let tight = FetchSizes {
            roots: 16,
            frontier: 0,
        };
        let cmd = [FetchCmd::per_node(1, true, true)];
        let tx = fetch_transaction_with_reports(&h, t0, &cmd, &reports[1..2], tight);
        assert!(tx.is_err(), "pass 2 needs a pass_end too");
        let tx =
            fetch_transaction_with_reports(&h, t0, &cmd, &[pass_end(1, false)], tight).unwrap();
        assert_eq!(tx.out, vec![err(0, fetch_err::FRONTIER)]);
    }
}
