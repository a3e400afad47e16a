//! Per-node merging (8.5, paragraph 55) in the merging module as a stream
//! transaction (SPEC.md section 8.14): the beat formats of the per-node
//! configuration's ports and one merge, whose expected outputs come from the
//! golden stage functions ([`PerNode::contest`], [`level_transaction`],
//! [`walk_input`] / [`collect`]), never from a copy of the RTL.
//!
//! The hardware goes breadth first, one LOD **pass** at a time from `lo`:
//! the live voxel groups of pass `l` are every node at `lo` (pass `lo`), or
//! the children of the groups that descended in pass `l - 1`. Each input
//! stream of a pass carries, per live voxel of that input in Morton order:
//! a **probe** beat per child of its inner node (the child's translated
//! record and reference: only its voxel is read), the inner node, the leaf,
//! the inner node's child references; `End` after the pass. The unit counts
//! `S` and `U` per voxel from the probes, reports the decision of every
//! contested voxel (two or more inner nodes), drops the inner node and child
//! references of a voxel that descends and hands the rest to S614, whose
//! beats leave on `out` with an `End` per pass. A pass with a descent is
//! followed by the next; per LOD, `out` is golden per-node's base at that
//! LOD in Morton order (tested below).

use crate::bits::Bits;
use crate::grid::VoxelAddr;
use crate::layout::{Field, Layout, LayoutError};
use crate::merge::error::MergeError;
use crate::merge::fetcher::walk::{children, collect, place_node, walk_input, PlacedNode};
use crate::merge::merge_level::unit::{level_transaction, BaseBeat, BeatLayout, LevelBeat};
use crate::merge::merge_level::{sort_stream, voxel_groups, BaseKind, BaseNode};
use crate::merge::merge_module::choice_err;
use crate::merge::per_node::PerNode;
use crate::params::Params;
use crate::store::{Hierarchy, NodeRecord, Reference};
use crate::translate::stimulus::SplitMix64;
use crate::translate::Translation;

/// Width of the `shared` and `union` fields of a decision: a voxel has 8
/// child voxels, so both are at most 8.
pub const CHILD_COUNT_BITS: u32 = 4;

/// Bit layouts of the per-node configuration's input and `report` beats
/// (`cfg` is [`crate::merge::merge_module::TopLayout`]'s, `out` S614's output beat).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PerNodeLayout {
    /// The S614 input beat ([`BeatLayout::input`]) an input beat starts with.
    pub beat: BeatLayout,
    /// An input beat: the S614 beat's `rec`, `ref`, `kind`, then `probe`
    /// (1): a child's record and reference, for counting only.
    pub input: Layout,
    /// Input beat: `probe` (1 bit) after the S614 beat, set on a probe.
    pub probe: Field,
    /// The `report` beat, from bit 0: `x`, `y`, `z` (D each, the voxel of
    /// a decision), `lod` (`lod_bits`), `shared`, `union`
    /// ([`CHILD_COUNT_BITS`] each), `descend`, `pass_end`, `more` (1
    /// each), `err` (2, [`choice_err`]).
    pub report: Layout,
    /// `report`: `x`, `y`, `z` (D bits each).
    pub coord: [Field; 3],
    /// `report`: `lod` (`lod_bits`), the decision's voxel LOD or the ended pass's LOD.
    pub lod: Field,
    /// `report`: `shared`, `S`: child voxels holding children of two or more inputs.
    pub shared: Field,
    /// `report`: `union`, `U`: child voxels holding any child.
    pub union: Field,
    /// `report`: `descend`, `S * den > num * U`: the voxel descends.
    pub descend: Field,
    /// `report`: `pass_end`, set on the beat ending a pass or refusing the merge.
    pub pass_end: Field,
    /// `report`: `more`, with `pass_end`: a pass at `lod + 1` follows.
    pub more: Field,
    /// `report`: `err` (2 bits), [`choice_err::BAD_RANGE`] on a refusal, else 0.
    pub err: Field,
}

impl PerNodeLayout {
    /// The layouts for `p`.
    pub fn new(p: &Params) -> PerNodeLayout {
        let beat = BeatLayout::input(p);
        let mut input = Layout::new("per-node input");
        for f in beat.fields() {
            input.push(f.name, f.width);
        }
        let probe = input.push("probe", 1);
        let d = p.coord_bits();
        let mut report = Layout::new("per-node report");
        let coord = ["x", "y", "z"].map(|n| report.push(n, d));
        let lod = report.push("lod", p.lod_bits());
        let shared = report.push("shared", CHILD_COUNT_BITS);
        let union = report.push("union", CHILD_COUNT_BITS);
        let descend = report.push("descend", 1);
        let pass_end = report.push("pass_end", 1);
        let more = report.push("more", 1);
        let err = report.push("err", 2);
        PerNodeLayout {
            beat,
            input,
            probe,
            report,
            coord,
            lod,
            shared,
            union,
            descend,
            pass_end,
            more,
            err,
        }
    }
}

/// One beat of an input stream of the per-node configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PerNodeBeat {
    /// A child (LOD `l + 1`, translated) of the inner node that follows.
    Probe {
        /// The child's stored record with its voxel translated (only the voxel is read).
        record: NodeRecord,
        /// Where the child is stored: `(input id, node index)`.
        at: Reference,
    },
    /// An S614 input beat.
    Level(LevelBeat),
}

impl PerNodeBeat {
    /// The packed beat ([`PerNodeLayout::input`]).
    pub fn pack(&self, l: &PerNodeLayout) -> Result<Bits, LayoutError> {
        let (inner, probe) = match *self {
            PerNodeBeat::Probe { record, at } => (LevelBeat::Inner { record, at }, 1),
            PerNodeBeat::Level(b) => (b, 0),
        };
        let mut b = Bits::from_words(inner.pack(&l.beat)?.words(), l.input.width())?;
        b.set(&l.probe, probe)?;
        Ok(b)
    }
}

/// One beat of the per-node configuration's `report` stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PerNodeReport {
    /// A contested voxel (two or more inner nodes): `S`, `U`, the decision.
    Decision {
        /// The contested voxel (translated).
        voxel: VoxelAddr,
        /// `S`: child voxels holding children of two or more inputs.
        shared: u64,
        /// `U`: child voxels holding any child.
        union: u64,
        /// `S * den > num * U`: the children become groups of the next pass.
        descend: bool,
    },
    /// The end of pass `lod`; `more`: a pass at `lod + 1` follows.
    PassEnd {
        /// The LOD of the pass that ended.
        lod: u8,
        /// Some voxel descended and `lod < D`.
        more: bool,
    },
    /// The merge is refused (`cfg` with `lo > hi` or `hi > D`).
    Refused {
        /// The [`choice_err`] code: [`choice_err::BAD_RANGE`].
        err: u64,
    },
}

impl PerNodeReport {
    /// The packed beat.
    pub fn pack(&self, l: &PerNodeLayout) -> Result<Bits, LayoutError> {
        let mut b = l.report.zero();
        match *self {
            PerNodeReport::Decision {
                voxel,
                shared,
                union,
                descend,
            } => {
                for (f, v) in l.coord.iter().zip([voxel.x, voxel.y, voxel.z]) {
                    b.set(f, v as u64)?;
                }
                b.set(&l.lod, voxel.lod as u64)?;
                b.set(&l.shared, shared)?;
                b.set(&l.union, union)?;
                b.set(&l.descend, descend as u64)?;
            }
            PerNodeReport::PassEnd { lod, more } => {
                b.set(&l.lod, lod as u64)?;
                b.set(&l.pass_end, 1)?;
                b.set(&l.more, more as u64)?;
            }
            PerNodeReport::Refused { err } => {
                b.set(&l.pass_end, 1)?;
                b.set(&l.err, err)?;
            }
        }
        Ok(b)
    }
}

/// One per-node merge through the unit: the `cfg` range, each input
/// stream's beats (every pass), the expected `report` and `out` beats.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PerNodeTransaction {
    /// `cfg`: `lo`, the LOD of the first pass.
    pub lo: u8,
    /// `cfg`: `hi`, only checked against `lo` and `D`.
    pub hi: u8,
    /// `inputs[r]`: input `r`'s beats of every pass, each pass ending in `End`.
    pub inputs: Vec<Vec<PerNodeBeat>>,
    /// The expected `report` beats: every pass's decisions and its `PassEnd`, or
    /// one `Refused`.
    pub reports: Vec<PerNodeReport>,
    /// The expected `out` beats: S614's beats of every pass, each pass ending in `End`.
    pub out: Vec<BaseBeat>,
    /// Passes made (0 when refused).
    pub passes: u32,
    /// Voxels that descended (golden `stats.per_node.descents`).
    pub descents: u64,
}

/// Input `rank`'s stream of one pass over the live nodes `live` (all
/// inputs): per voxel of its own, in (Morton, leaf) order, probes (the
/// translated children of its inner node, as stored), the inner node, the
/// leaf, the child references; `End`.
pub fn pass_stream(
    live: &[PlacedNode],
    inputs: &[&Hierarchy],
    translations: &[Translation],
    rank: u16,
) -> Result<Vec<PerNodeBeat>, MergeError> {
    let mut mine: Vec<PlacedNode> = live.iter().filter(|n| n.rank == rank).copied().collect();
    sort_stream(&mut mine);
    let h = inputs[rank as usize];
    let mut out = Vec::new();
    for g in voxel_groups(&mine) {
        let group = &mine[g];
        let mut refs = Vec::new();
        for n in group.iter().filter(|n| !n.record.leaf) {
            let rs = children(h, n.at.node, &h.nodes[n.at.node as usize])?;
            for c in rs {
                let child = place_node(h, rank, &translations[rank as usize], c.node)?;
                out.push(PerNodeBeat::Probe {
                    record: child.record,
                    at: child.at,
                });
            }
            refs.extend(
                rs.iter()
                    .map(|r| PerNodeBeat::Level(LevelBeat::ChildRef(*r))),
            );
        }
        for n in group {
            out.push(PerNodeBeat::Level(LevelBeat::of_node(n)));
        }
        out.extend(refs);
    }
    out.push(PerNodeBeat::Level(LevelBeat::End));
    Ok(out)
}

/// The per-node merge (`num / den`) of `inputs` placed by `translations`,
/// from `cfg = (lo, hi)` (the candidate range of 8.2; only `lo` is used
/// beyond the range check). Every input is walked to `lo` ([`walk_input`]);
/// the leaves above `lo` are not this unit's (they go to the upper builder).
pub fn per_node_transaction(
    p: &Params,
    inputs: &[&Hierarchy],
    translations: &[Translation],
    num: u32,
    den: u32,
    lo: u8,
    hi: u8,
) -> Result<PerNodeTransaction, MergeError> {
    crate::merge::level_choice::check_ratio("PerNode", num, den)?;
    let k = inputs.len();
    let mut tx = PerNodeTransaction {
        lo,
        hi,
        inputs: vec![Vec::new(); k],
        reports: Vec::new(),
        out: Vec::new(),
        passes: 0,
        descents: 0,
    };
    if lo > hi || hi > p.max_lod {
        tx.reports.push(PerNodeReport::Refused {
            err: choice_err::BAD_RANGE,
        });
        return Ok(tx);
    }
    let walked = inputs
        .iter()
        .zip(translations)
        .enumerate()
        .map(|(r, (h, t))| walk_input(h, r as u16, t, lo))
        .collect::<Result<Vec<_>, _>>()?;
    let (_, mut live) = collect(&walked, lo);
    let decider = PerNode {
        inputs,
        translations,
        params: *p,
        num,
        den,
    };
    let mut lod = lo;
    loop {
        sort_stream(&mut live);
        for (r, stream) in tx.inputs.iter_mut().enumerate() {
            stream.extend(pass_stream(&live, inputs, translations, r as u16)?);
        }
        let mut kept = Vec::new();
        let mut next = Vec::new();
        let mut descended = false;
        for g in voxel_groups(&live) {
            let group = &live[g];
            let inner: Vec<&PlacedNode> = group.iter().filter(|n| !n.record.leaf).collect();
            let mut descend = false;
            if inner.len() >= 2 {
                let c = decider.contest(&inner)?;
                tx.reports.push(PerNodeReport::Decision {
                    voxel: group[0].record.voxel,
                    shared: c.shared,
                    union: c.union,
                    descend: c.descend,
                });
                if c.descend {
                    descend = true;
                    descended = true;
                    tx.descents += 1;
                    next.extend(c.children);
                }
            }
            kept.extend(group.iter().filter(|n| !descend || n.record.leaf));
        }
        tx.out.extend(level_transaction(&kept, inputs, p)?.outputs);
        tx.passes += 1;
        let more = descended && lod < p.max_lod;
        tx.reports.push(PerNodeReport::PassEnd { lod, more });
        if !more {
            return Ok(tx);
        }
        live = next;
        lod += 1;
    }
}

/// The base nodes of `out` (a per-node merge's beats) by LOD, each LOD in
/// stream order: created nodes with their references, reused nodes; `None`
/// when a created node's count overflowed.
pub fn base_by_lod(out: &[BaseBeat], p: &Params) -> Option<Vec<Vec<BaseNode>>> {
    let mut by_lod = vec![Vec::new(); p.max_lod as usize + 1];
    let mut last_created: Option<(u8, usize)> = None;
    for b in out {
        match *b {
            BaseBeat::Created {
                record,
                count_overflow,
            } => {
                if count_overflow {
                    return None;
                }
                let l = record.voxel.lod as usize;
                last_created = Some((record.voxel.lod, by_lod[l].len()));
                by_lod[l].push(BaseNode {
                    record,
                    kind: BaseKind::Created { refs: Vec::new() },
                });
            }
            BaseBeat::Reused { record, at } => by_lod[record.voxel.lod as usize].push(BaseNode {
                record,
                kind: BaseKind::Reused { at },
            }),
            BaseBeat::Ref(r) => {
                let (l, i) = last_created?;
                if let BaseKind::Created { refs } = &mut by_lod[l as usize][i].kind {
                    refs.push(r);
                }
            }
            BaseBeat::End => last_created = None,
        }
    }
    Some(by_lod)
}

// ---------------------------------------------------------------------------
// Stimulus

/// A random input: an octree below `roots` (voxels at `top`), each inner
/// node's children a random non-empty set of its octants (`occupancy` in
/// 1..=8 of 8), each child an inner node, a leaf or both, leaves only at
/// `deepest`; at most `limit` nodes (the rest leaves).
fn random_tree(
    rng: &mut SplitMix64,
    p: &Params,
    id: u8,
    top: u8,
    roots: &[[u32; 3]],
    deepest: u8,
    occupancy: u64,
) -> Hierarchy {
    let limit = (p.index_capacity() - 1).min(160) as usize;
    let cells = p.quant_cells() as u64;
    let boxed = |rng: &mut SplitMix64, leaf: bool, v: VoxelAddr| {
        let mut lo = [0u16; 3];
        let mut hi = [0u16; 3];
        for a in 0..3 {
            let (x, y) = (rng.below(cells), rng.below(cells));
            lo[a] = x.min(y) as u16;
            hi[a] = x.max(y) as u16;
        }
        let count = if leaf {
            1 + rng.below(p.index_capacity() - 1) as u32
        } else {
            1
        };
        NodeRecord {
            leaf,
            voxel: v,
            lo,
            hi,
            first: 0,
            count,
        }
    };
    let mut h = Hierarchy {
        id,
        params: *p,
        nodes: Vec::new(),
        refs: Vec::new(),
        prims: Vec::new(),
        root_count: roots.len() as u32,
        top_lod: top,
    };
    for r in roots {
        let v = VoxelAddr::new(top, r[0], r[1], r[2]);
        let leaf = top >= deepest;
        h.nodes.push(boxed(rng, leaf, v));
    }
    let mut i = 0;
    while i < h.nodes.len() {
        let n = h.nodes[i];
        i += 1;
        if n.leaf {
            continue;
        }
        let l = n.voxel.lod + 1;
        let mut kids = Vec::new();
        for o in 0..8u32 {
            if rng.below(8) < occupancy {
                kids.push(o);
            }
        }
        if kids.is_empty() {
            kids.push(rng.below(8) as u32);
        }
        let first = h.refs.len() as u32;
        for o in kids {
            let v = VoxelAddr::new(
                l,
                2 * n.voxel.x + (o & 1),
                2 * n.voxel.y + (o >> 1 & 1),
                2 * n.voxel.z + (o >> 2 & 1),
            );
            let room = h.nodes.len() + 2 < limit;
            let what = if l >= deepest || !room {
                1
            } else {
                rng.below(4)
            };
            // 0: inner, 1: leaf, 2: both, 3: inner.
            if what != 1 {
                h.refs.push(Reference {
                    hier: id,
                    node: h.nodes.len() as u32,
                });
                h.nodes.push(boxed(rng, false, v));
            }
            if what == 1 || what == 2 {
                h.refs.push(Reference {
                    hier: id,
                    node: h.nodes.len() as u32,
                });
                h.nodes.push(boxed(rng, true, v));
            }
        }
        h.nodes[i - 1].first = first;
        h.nodes[i - 1].count = h.refs.len() as u32 - first;
    }
    h
}

/// A random per-node merge's inputs: `k` octree inputs (distinct ids),
/// their translations (at each input's top) and the `cfg` range. The tops
/// lie at most two LODs above `lo` and are moved onto one neighbourhood so
/// that voxels are contested at every depth; `occupancy` varies per merge
/// so that every ratio descends somewhere and stays somewhere.
pub struct PerNodeCase {
    /// The `k` octree inputs in rank order (distinct ids).
    pub hierarchies: Vec<Hierarchy>,
    /// Each input's translation by rank, at its top LOD.
    pub translations: Vec<Translation>,
    /// `cfg`: `lo`.
    pub lo: u8,
    /// `cfg`: `hi`, the deepest LOD of the trees, or `lo - 1` (a bad range).
    pub hi: u8,
}

/// A random [`PerNodeCase`] for `p` with `k` inputs (`2 <= k <= 2^H`),
/// trees at most `depth` LODs below `lo` (one in 32 a bad range).
pub fn random_per_node_case(rng: &mut SplitMix64, p: &Params, k: usize, depth: u8) -> PerNodeCase {
    let d = p.max_lod;
    let lo = rng.below(d as u64 + 1) as u8;
    let deepest = (lo as u64 + rng.below(depth as u64 + 1)).min(d as u64) as u8;
    let occupancy = 1 + rng.below(8);
    let mut ids: Vec<u8> = (0..p.hier_capacity()).map(|v| v as u8).collect();
    for i in 0..k {
        let j = i + rng.below((ids.len() - i) as u64) as usize;
        ids.swap(i, j);
    }
    let anchor = [0; 3].map(|_| {
        let n = 1u64 << lo;
        match rng.below(4) {
            0 => 0,
            1 => (n - 1) as u32,
            _ => rng.below(n) as u32,
        }
    });
    let mut hierarchies = Vec::new();
    let mut translations = Vec::new();
    for &id in &ids[..k] {
        let top = lo - rng.below(lo.min(2) as u64 + 1) as u8;
        let up = lo - top;
        // Where the input's first root lands: the anchor's ancestor, moved
        // by one voxel now and then (no overlap there).
        let at = anchor.map(|a| {
            let c = a >> up;
            if rng.below(6) == 0 {
                c ^ 1.min((1u32 << top) - 1)
            } else {
                c
            }
        });
        let local = [0; 3].map(|_| rng.below(1u64 << top) as u32);
        let mut roots = vec![local];
        let second = [local[0] ^ 1, local[1], local[2]];
        let t = [0, 1, 2].map(|a| at[a] as i64 - local[a] as i64);
        if top > 0 && rng.below(4) == 0 {
            let moved = second[0] as i64 + t[0];
            if (0..1i64 << top).contains(&moved) {
                roots.push(second);
            }
        }
        hierarchies.push(random_tree(rng, p, id, top, &roots, deepest, occupancy));
        translations.push(Translation { lod: top, t });
    }
    let (lo, hi) = if rng.below(32) == 0 && lo > 0 {
        (lo, lo - 1)
    } else {
        (lo, deepest)
    };
    PerNodeCase {
        hierarchies,
        translations,
        lo,
        hi,
    }
}

impl PerNodeCase {
    /// [`per_node_transaction`] of this case with `num / den`.
    pub fn transaction(
        &self,
        p: &Params,
        num: u32,
        den: u32,
    ) -> Result<PerNodeTransaction, MergeError> {
        let hs: Vec<&Hierarchy> = self.hierarchies.iter().collect();
        per_node_transaction(p, &hs, &self.translations, num, den, self.lo, self.hi)
    }

    /// Golden per-node merging ([`PerNode::merge_from`]) of this case: the
    /// base below the leaves above `lo`, by LOD in stream order, and the
    /// descents.
    pub fn golden_base(
        &self,
        p: &Params,
        num: u32,
        den: u32,
    ) -> Result<(Vec<Vec<BaseNode>>, u64), MergeError> {
        let hs: Vec<&Hierarchy> = self.hierarchies.iter().collect();
        let walked = hs
            .iter()
            .zip(&self.translations)
            .enumerate()
            .map(|(r, (h, t))| walk_input(h, r as u16, t, self.lo))
            .collect::<Result<Vec<_>, _>>()?;
        let (_, first) = collect(&walked, self.lo);
        let decider = PerNode {
            inputs: &hs,
            translations: &self.translations,
            params: *p,
            num,
            den,
        };
        let mut counts = Default::default();
        let mut pn = Default::default();
        let base = decider.merge_from(first, &mut counts, &mut pn)?;
        let mut by_lod = vec![Vec::new(); p.max_lod as usize + 1];
        for n in base {
            by_lod[n.record.voxel.lod as usize].push(n);
        }
        Ok((by_lod, pn.descents))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::build::{build, GridMap};
    use crate::merge::{merge, MergeMode};
    use crate::scenes::random_soup;
    use crate::store::HierarchyStore;
    use crate::translate::TranslationTable;

    fn configs() -> Vec<(Params, usize)> {
        vec![
            (Params::default(), 4),
            (Params::new(31, 16, 32, 8).unwrap(), 5),
            (Params::new(8, 0, 12, 3).unwrap(), 2),
        ]
    }

    /// What the stimulus reached, so a test can assert it was exercised.
    #[derive(Default, Debug)]
    struct Seen {
        merges: usize,
        refused: usize,
        multi_pass: usize,
        decisions: usize,
        descended: usize,
        stayed: usize,
    }

    /// The breadth-first passes give golden per-node's (depth-first) base,
    /// LOD by LOD in stream order, and the same descents: random octree
    /// merges at three configurations and five ratios.
    #[test]
    fn passes_give_golden_per_node_base() {
        let mut rng = SplitMix64(21);
        let mut seen = Seen::default();
        for (p, k) in configs() {
            for (num, den) in [(1, 2), (0, 1), (1, 1), (1, 3), (3, 4)] {
                for _ in 0..150 {
                    let c = random_per_node_case(&mut rng, &p, k, 4);
                    let tx = c.transaction(&p, num, den).unwrap();
                    seen.merges += 1;
                    if tx.passes == 0 {
                        seen.refused += 1;
                        assert_eq!(
                            tx.reports,
                            vec![PerNodeReport::Refused {
                                err: choice_err::BAD_RANGE
                            }]
                        );
                        continue;
                    }
                    seen.multi_pass += (tx.passes > 1) as usize;
                    let (want, descents) = c.golden_base(&p, num, den).unwrap();
                    let got = base_by_lod(&tx.out, &p).expect("no count overflow");
                    assert_eq!(got, want, "{num}/{den}");
                    assert_eq!(tx.descents, descents);
                    let ends = tx.out.iter().filter(|b| **b == BaseBeat::End).count();
                    assert_eq!(ends as u32, tx.passes);
                    for s in &tx.inputs {
                        let ends = s
                            .iter()
                            .filter(|b| **b == PerNodeBeat::Level(LevelBeat::End))
                            .count();
                        assert_eq!(ends as u32, tx.passes);
                    }
                    for r in &tx.reports {
                        if let PerNodeReport::Decision {
                            shared,
                            union,
                            descend,
                            ..
                        } = *r
                        {
                            seen.decisions += 1;
                            seen.descended += descend as usize;
                            seen.stayed += !descend as usize;
                            assert!(shared <= union && (1..=8).contains(&union));
                            if num == den {
                                assert!(!descend);
                            }
                            if num == 0 {
                                assert_eq!(descend, shared > 0);
                            }
                        }
                    }
                }
            }
        }
        eprintln!("{seen:?}");
        assert!(seen.refused > 0 && seen.multi_pass > 100, "{seen:?}");
        assert!(seen.descended > 500 && seen.stayed > 500, "{seen:?}");
    }

    /// `num = den` never descends: one pass, whose `out` is S614 at `lo`
    /// (what `Fixed(lo)` gives).
    #[test]
    fn ratio_one_is_fixed_at_lo() {
        let mut rng = SplitMix64(4);
        let p = Params::default();
        for _ in 0..200 {
            let c = random_per_node_case(&mut rng, &p, 3, 3);
            let tx = c.transaction(&p, 2, 2).unwrap();
            if tx.passes == 0 {
                continue;
            }
            assert_eq!(tx.passes, 1);
            let hs: Vec<&Hierarchy> = c.hierarchies.iter().collect();
            let walked: Vec<_> = hs
                .iter()
                .zip(&c.translations)
                .enumerate()
                .map(|(r, (h, t))| walk_input(h, r as u16, t, c.lo).unwrap())
                .collect();
            let at = collect(&walked, c.lo).1;
            assert_eq!(tx.out, level_transaction(&at, &hs, &p).unwrap().outputs);
        }
    }

    fn soup_input(p: &Params, id: u8, n: usize, size: f32, seed: u64, shrink: u32) -> Hierarchy {
        let mesh = random_soup(n, size, seed);
        let grid = GridMap {
            origin: glam::DVec3::ZERO,
            unit: 1.0 / (p.scene_edge() >> shrink) as f64,
        };
        build(&mesh, &grid, p, id).expect("the soup builds")
    }

    /// Real merges (golden-built soups, overlapping and apart): the unit's
    /// passes give `merge`'s per-node statistics (descents, created and
    /// reused nodes at the base) and golden per-node's base.
    #[test]
    fn real_merges_agree_with_merge() {
        let p = Params::new(10, 3, 16, 3).unwrap();
        let mut rng = SplitMix64(8);
        let mut descents = 0;
        for case in 0..24u64 {
            let k = 2 + (case % 3) as usize;
            let mut store = HierarchyStore::new();
            let mut table = TranslationTable::new(8, &p).unwrap();
            let mut ids = Vec::new();
            for i in 0..k {
                let id = i as u8 + 1;
                let n = 5 + rng.below(60) as usize;
                let size = 0.05 + (rng.below(30) as f32) / 100.0;
                let h = soup_input(&p, id, n, size, case * 10 + i as u64, 2);
                let l = h.top_lod;
                let t = if case % 4 == 3 { (i as i64) % 2 } else { 0 };
                table
                    .write(
                        id as u32,
                        Translation {
                            lod: l,
                            t: [t, 0, 0],
                        },
                    )
                    .unwrap();
                store.insert(h).unwrap();
                ids.push(id);
            }
            for (num, den) in [(1, 2), (0, 1), (1, 1), (1, 4)] {
                let mode = MergeMode::PerNode { num, den };
                let Ok(r) = merge(&store, &ids, &table, mode, 0) else {
                    continue;
                };
                let c = PerNodeCase {
                    hierarchies: ids.iter().map(|i| store.get(*i).unwrap().clone()).collect(),
                    translations: ids.iter().map(|i| table.read(*i as u32).unwrap()).collect(),
                    lo: r.stats.candidates.0,
                    hi: r.stats.candidates.1,
                };
                let tx = c.transaction(&p, num, den).unwrap();
                assert_eq!(tx.descents, r.stats.per_node.descents);
                descents += tx.descents;
                let created = tx
                    .out
                    .iter()
                    .filter(|b| matches!(b, BaseBeat::Created { .. }));
                let reused = tx
                    .out
                    .iter()
                    .filter(|b| matches!(b, BaseBeat::Reused { .. }));
                let lm = r.stats.merge_level;
                assert_eq!(created.count() as u64, lm.created);
                assert_eq!(reused.count() as u64, lm.reused_inner + lm.reused_leaves);
                let (want, _) = c.golden_base(&p, num, den).unwrap();
                assert_eq!(base_by_lod(&tx.out, &p).unwrap(), want);
            }
        }
        assert!(descents > 10, "real merges descend: {descents}");
    }

    #[test]
    fn layouts_hold_their_fields() {
        for (p, _) in configs() {
            let l = PerNodeLayout::new(&p);
            assert_eq!(l.input.width(), BeatLayout::input(&p).width() + 1);
            assert_eq!(
                l.report.width(),
                3 * p.coord_bits() + p.lod_bits() + 2 * CHILD_COUNT_BITS + 5
            );
            let v = VoxelAddr::new(p.max_lod, 1, 2, 3);
            let b = PerNodeReport::Decision {
                voxel: v,
                shared: 8,
                union: 8,
                descend: true,
            }
            .pack(&l)
            .unwrap();
            assert_eq!(b.get(&l.coord[2]).unwrap(), 3);
            assert_eq!(b.get(&l.union).unwrap(), 8);
        }
    }
}
