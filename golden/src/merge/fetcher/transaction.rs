//! The fetcher's transaction: the breadth-first walk from the sorted roots
//! that the hardware promises, one read at a time, level by level or per-node
//! pass by pass, with every request, response and beat it makes.

use std::collections::VecDeque;

use super::beats::{fetch_err, FetchCfg, FetchCmd, FetchOut, LeafOut};
use crate::merge::error::MergeError;
use crate::merge::fetcher::walk::{children, morton, place_node, PlacedNode};
use crate::merge::merge_level::sort_stream;
use crate::merge::merge_level::unit::LevelBeat;
use crate::merge::per_node::unit::PerNodeReport;
use crate::store::{Hierarchy, NodeRecord, Reference};
use crate::translate::table::unpack_entry;
use crate::translate::{TranslateError, Translation};

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
            o.emit(tx, FetchOut::Beat(LevelBeat::of_node(n)));
            if leaf_of_p {
                self.send_refs(tx, o, &p);
            }
        } else {
            o.emit(tx, FetchOut::Beat(LevelBeat::of_node(n)));
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
        // Unlike the level walk's, a pass's predecessor is its highest key
        // so far (a node out of order does not lower it): the pass's
        // entries then rise strictly, and the hardware's join may pass over
        // a decision below a visited key before the pass is visited (8.13).
        if v.prev.is_some_and(|p| p >= key) {
            return self.error(tx, v, o, (n.at.node, fetch_err::ORDER));
        }
        v.prev = Some(key);
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
                o.emit(tx, FetchOut::Beat(LevelBeat::of_node(n)));
                self.send_refs(tx, o, &p);
            }
            held => {
                if let Some(p) = held {
                    self.send_refs(tx, o, &p);
                }
                if inner {
                    self.send_probes(tx, o, n, d);
                }
                o.emit(tx, FetchOut::Beat(LevelBeat::of_node(n)));
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
/// [`crate::merge::per_node::unit::PerNodeTransaction::reports`]). Refused when a
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
