//! The multi-stream units' ports and random merges (SPEC.md 8.10, 8.14,
//! 8.15): the merging module (`cfg`, `in0`.. in; `report`, `out` out) and
//! the hierarchy merger (`cfg`, the fetchers' store responses, `w_ref_resp`
//! in; `report`, the store requests, `nodes`, `refs`, `header` out). Every
//! stream is a [`Layout`] called by the stream's name, its beat's fields
//! named from golden's layouts (`rec.lod` inside a beat); a merge is the packed beats it puts on every stream
//! ([`MergeBeats`]). The cosim benches and the vector files
//! ([`super::stream_file`]) both draw their merges from here.

use crate::bits::Bits;
use crate::layout::Layout;
use crate::merge::fetcher::FetchLayout;
use crate::merge::merge_level::unit::BeatLayout;
use crate::merge::merge_module::{random_top_transaction, TopLayout};
use crate::merge::merger::{
    merger_transaction, MergerLayout, MergerSizes, MergerTransaction, ModulePass,
};
use crate::merge::per_node::unit::{random_per_node_case, PerNodeLayout};
use crate::merge::stimulus::{place, try_soup};
use crate::merge::MergeMode;
use crate::store::{Hierarchy, HierarchyStore, NodeRecord, Reference};
use crate::translate::stimulus::SplitMix64;
use crate::translate::{Translation, TranslationTable};
use crate::vectors::hard_merges::random_cut;

use crate::merge::merge_module::MergeDesign;

/// Most voxels of a random level of the merging module's merges.
pub const DEFAULT_MOST_VOXELS: usize = 12;

/// LODs below `lo` of a random per-node merge's trees: deep enough for
/// merges of several passes.
pub const PER_NODE_DEPTH: u8 = 4;

/// Most soups in a random merger merge is the merger's `k`; most triangles per soup.
pub const MOST_TRIANGLES: u64 = 40;

/// Random merger merges drawn before giving up on one whose leaves fit the
/// leaf FIFOs (the merger's `leaf_bits` too small for the random scenes).
pub const MOST_DRAWS: usize = 1000;

/// A unit's streams, in port order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnitPorts {
    /// Input streams, each a layout called by the stream's name; the
    /// first is `cfg` (one beat per merge).
    pub inputs: Vec<Layout>,
    /// Output streams.
    pub outputs: Vec<Layout>,
}

/// One merge's beats on every stream of a unit, in [`UnitPorts`] order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MergeBeats {
    /// Per input stream, the beats driven, in stream order.
    pub inputs: Vec<Vec<Bits>>,
    /// Per output stream, the beats expected, in stream order.
    pub outputs: Vec<Vec<Bits>>,
}

fn layout_err(what: impl std::fmt::Display) -> String {
    what.to_string()
}

fn pack_all<T>(
    items: &[T],
    pack: impl Fn(&T) -> Result<Bits, crate::layout::LayoutError>,
) -> Result<Vec<Bits>, String> {
    items.iter().map(|x| pack(x).map_err(layout_err)).collect()
}

/// Stream `name` carrying S614 beats of `beat` (`l`'s layout, or the
/// per-node input's, which adds `probe`): the node record's fields as
/// `rec.*`, the reference's as `ref.*`, then `kind` and, on output beats,
/// `err`.
pub fn level_beat_stream(name: &str, l: &BeatLayout, beat: &Layout) -> Layout {
    beat.flattened(name, |f| match f.name {
        "rec" => Some(l.node.layout()),
        "ref" => Some(l.reference.layout()),
        _ => None,
    })
}

/// Whether `d` merges per node (its `report` and inputs are 8.14's).
pub fn is_per_node(d: &MergeDesign) -> bool {
    matches!(d.mode, MergeMode::PerNode { .. })
}

/// The merging module's `report` stream ([`TopLayout`]; per-node:
/// [`PerNodeLayout`]).
pub fn module_report(d: &MergeDesign) -> Layout {
    if is_per_node(d) {
        PerNodeLayout::new(&d.params).report.renamed("report")
    } else {
        TopLayout::new(&d.params).report.renamed("report")
    }
}

/// The merging module's streams (`merge_module_unit`, SPEC 8.10): `cfg`
/// (`lo`, `hi`), `in0`..`in{k-1}` (S614 input beats; per-node: and
/// `probe`) in; `report`, `out` (S614 output beats) out.
pub fn module_ports(d: &MergeDesign) -> UnitPorts {
    let p = &d.params;
    let tl = TopLayout::new(p);
    let input = |name: &str| {
        if is_per_node(d) {
            let pl = PerNodeLayout::new(p);
            level_beat_stream(name, &pl.beat, &pl.input)
        } else {
            let li = BeatLayout::input(p);
            level_beat_stream(name, &li, &li)
        }
    };
    let lo = BeatLayout::output(p);
    let mut inputs = vec![tl.cfg.renamed("cfg")];
    inputs.extend((0..d.inputs).map(|i| input(&format!("in{i}"))));
    UnitPorts {
        inputs,
        outputs: vec![module_report(d), level_beat_stream("out", &lo, &lo)],
    }
}

/// One random merge of the merging module `d`, packed: per-node
/// configurations draw a `random_per_node_case` (trees [`PER_NODE_DEPTH`]
/// LODs deep, SPEC 8.14), the others a `random_top_transaction` (levels
/// of at most `most_voxels` voxels, SPEC 8.10).
pub fn module_merge(
    rng: &mut SplitMix64,
    d: &MergeDesign,
    most_voxels: usize,
) -> Result<MergeBeats, String> {
    let p = &d.params;
    let (tl, lo) = (TopLayout::new(p), BeatLayout::output(p));
    let (cfg, mut inputs, reports, out) = if let MergeMode::PerNode { num, den } = d.mode {
        let pl = PerNodeLayout::new(p);
        let tx = random_per_node_case(rng, p, d.inputs, PER_NODE_DEPTH)
            .transaction(p, num, den)
            .map_err(layout_err)?;
        let ins = tx
            .inputs
            .iter()
            .map(|beats| pack_all(beats, |b| b.pack(&pl)))
            .collect::<Result<Vec<_>, _>>()?;
        let cfg = tl.pack_cfg(tx.lo, tx.hi).map_err(layout_err)?;
        (
            cfg,
            ins,
            pack_all(&tx.reports, |r| r.pack(&pl))?,
            pack_all(&tx.out, |b| b.pack(&lo))?,
        )
    } else {
        let li = BeatLayout::input(p);
        let tx =
            random_top_transaction(rng, p, d.inputs, &d.mode, most_voxels).map_err(layout_err)?;
        let ins = tx
            .inputs
            .iter()
            .map(|beats| pack_all(beats, |b| b.pack(&li)))
            .collect::<Result<Vec<_>, _>>()?;
        let cfg = tl.pack_cfg(tx.lo, tx.hi).map_err(layout_err)?;
        (
            cfg,
            ins,
            pack_all(&tx.reports, |r| r.pack(&tl))?,
            pack_all(&tx.out, |b| b.pack(&lo))?,
        )
    };
    inputs.insert(0, vec![cfg]);
    Ok(MergeBeats {
        inputs,
        outputs: vec![reports, out],
    })
}

/// A store read request (`f{i}_node_req`, `_ref_req`, `_cref_req`,
/// `_probe_req`) called `name`: the whole beat is the `index` read.
pub fn index_stream(fl: &FetchLayout, name: &str) -> Layout {
    Layout::packed(name, &[("index", fl.index_width)])
}

/// The merger's `cfg` stream: its `cfg` beat with each `input<i>` (a
/// fetcher `cfg` beat) shown field by field as `input<i>.*`, then `count`,
/// `lo`, `hi`, `out_id`.
pub fn merger_cfg_stream(ml: &MergerLayout) -> Layout {
    let input = &ml.fetch.cfg;
    ml.cfg
        .flattened("cfg", |f| f.name.starts_with("input").then_some(input))
}

/// The merger's input stream names: `cfg`, per fetcher `f{i}_node_resp`,
/// `f{i}_ref_resp`, `f{i}_cref_resp`, then (per-node mode) every
/// `f{i}_probe_resp`, then `w_ref_resp`.
pub fn merger_input_names(k: usize, per_node: bool) -> Vec<String> {
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

/// The merger's output stream names: `report`, per fetcher `f{i}_node_req`,
/// `f{i}_ref_req`, `f{i}_cref_req`, then (per-node mode) every
/// `f{i}_probe_req`, then `w_ref_req`, `nodes`, `refs`, `header` (always last).
pub fn merger_output_names(k: usize, per_node: bool) -> Vec<String> {
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

/// The merger's layout for `d` and `sizes`.
pub fn merger_layout(d: &MergeDesign, sizes: &MergerSizes) -> Result<MergerLayout, String> {
    MergerLayout::new(&d.params, d.inputs, sizes.capacity_bits).map_err(layout_err)
}

/// The merger's stream `name` (input or output), from golden's layouts:
/// `cfg` ([`merger_cfg_stream`]), `report` the merging module's, a store
/// request an index, a node response or `nodes` a node record, a reference
/// response, `w_ref_req` or `refs` a reference, `header` the writer's
/// header and the merger's flags; None for a name that is no stream of it.
pub fn merger_stream(ml: &MergerLayout, d: &MergeDesign, name: &str) -> Option<Layout> {
    let per_node = is_per_node(d);
    let fl = &ml.fetch;
    Some(match name {
        "cfg" => merger_cfg_stream(ml),
        "report" => module_report(d),
        "nodes" => fl.node.renamed(name),
        "w_ref_req" | "refs" | "w_ref_resp" => fl.reference.renamed(name),
        "header" => ml.header.renamed(name),
        s if merger_input_names(ml.k, per_node).iter().any(|n| n == s) => {
            if s.ends_with("node_resp") || s.ends_with("probe_resp") {
                fl.node.renamed(name)
            } else {
                fl.reference.renamed(name)
            }
        }
        s if merger_output_names(ml.k, per_node).iter().any(|n| n == s) => index_stream(fl, name),
        _ => return None,
    })
}

/// The hierarchy merger's streams (`hierarchy_merger_unit`, SPEC 8.15).
pub fn merger_ports(d: &MergeDesign, sizes: &MergerSizes) -> Result<UnitPorts, String> {
    let ml = merger_layout(d, sizes)?;
    let per_node = is_per_node(d);
    let of = |names: Vec<String>| {
        names
            .iter()
            .map(|n| merger_stream(&ml, d, n).expect("a stream of the merger"))
            .collect()
    };
    Ok(UnitPorts {
        inputs: of(merger_input_names(d.inputs, per_node)),
        outputs: of(merger_output_names(d.inputs, per_node)),
    })
}

/// The beats of merge `tx` on every stream of the merger `d` (layout `ml`),
/// in [`merger_input_names`] / [`merger_output_names`] order.
pub fn merger_beats(
    d: &MergeDesign,
    ml: &MergerLayout,
    tx: &MergerTransaction,
) -> Result<MergeBeats, String> {
    let k = d.inputs;
    let per_node = is_per_node(d);
    let fl = &ml.fetch;
    let index = index_stream(fl, "index");
    let idx = |i: &u32| index.pack(&[("index", *i as u64)]).map_err(layout_err);
    let node = |n: &NodeRecord| n.pack(&fl.node).map_err(layout_err);
    let rf = |r: &Reference| r.pack(&fl.reference).map_err(layout_err);
    let np = if per_node { k } else { 0 };
    let mut ins = vec![Vec::new(); 2 + 3 * k + np];
    let mut outs = vec![Vec::new(); 5 + 3 * k + np];
    // The probe ports (per-node mode) sit between the fetchers' and the
    // writer's streams.
    let probes = 1 + 3 * k;
    let w_resp = probes + np;
    let (report, w_req) = (0, probes + np);
    let (nodes, refs, header) = (w_req + 1, w_req + 2, w_req + 3);
    ins[0].push(tx.cfg.pack(ml).map_err(layout_err)?);
    for r in tx.reports() {
        outs[report].push(r.pack(&ml.top).map_err(layout_err)?);
    }
    if let ModulePass::PerNode(pn) = &tx.module {
        let pl = PerNodeLayout::new(&d.params);
        for r in &pn.reports {
            outs[report].push(r.pack(&pl).map_err(layout_err)?);
        }
    }
    let w = &tx.writer;
    for (lane, items) in [(nodes, &w.nodes)] {
        for n in items {
            outs[lane].push(node(n)?);
        }
    }
    for (lane, items) in [(refs, &w.refs), (w_req, &w.ref_reqs)] {
        for r in items {
            outs[lane].push(rf(r)?);
        }
    }
    for r in &w.ref_resps {
        ins[w_resp].push(rf(r)?);
    }
    outs[header].push(tx.header.pack(ml).map_err(layout_err)?);
    for (i, f) in tx.fetch.iter().enumerate() {
        let at = 1 + 3 * i;
        for n in &f.node_resps {
            ins[at].push(node(n)?);
        }
        for (lane, items) in [(at + 1, &f.ref_resps), (at + 2, &f.cref_resps)] {
            for r in items {
                ins[lane].push(rf(r)?);
            }
        }
        for (lane, items) in [
            (at, &f.node_reqs),
            (at + 1, &f.ref_reqs),
            (at + 2, &f.cref_reqs),
        ] {
            for r in items {
                outs[lane].push(idx(r)?);
            }
        }
        if per_node {
            for n in &f.probe_resps {
                ins[probes + i].push(node(n)?);
            }
            for r in &f.probe_reqs {
                outs[probes + i].push(idx(r)?);
            }
        }
    }
    Ok(MergeBeats {
        inputs: ins,
        outputs: outs,
    })
}

/// A random merge of the merger `d` (sizes `sizes`): 1..=k soups of
/// 1..=[`MOST_TRIANGLES`] triangles, each translated at its top LOD by a
/// random fraction of the room left (per-node mode: in half the merges
/// every soup by the first one's fraction); drawn again while the leaves
/// overflow the merger's leaf FIFOs (at most [`MOST_DRAWS`] times).
pub fn random_merger_merge(
    rng: &mut SplitMix64,
    d: &MergeDesign,
    sizes: MergerSizes,
) -> Result<MergerTransaction, String> {
    random_merger_merge_of(rng, d, sizes, Merges::Random)
}

/// Which merges a merger run draws (`hiermerge cosim --merges`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Merges {
    /// Random merges of 1..=k small soups ([`random_merger_merge`]): the
    /// long runs' stimulus, which the ledger records.
    #[default]
    Random,
    /// The hard merges ([`super::hard_merges::hard_merges`]) first, then
    /// random merges whose soups span every scale: the coverage
    /// regression's stimulus.
    Hard,
}

/// A random merge as `kind` draws it: [`random_merger_merge`], or for
/// [`Merges::Hard`] soups of one scale per merge, edges of `0.32 * 2^-e` of
/// the scene's `2^-3` corner with `e` in `0..=12`, in half the merges every
/// soup a voxel or two from the first, and a third of the soups cut below
/// their top into several roots stored out of order
/// ([`random_cut`]). So the merging level reaches deep
/// LODs with the merged top far above it, every level of the upper
/// builder and the writer between carries nodes, and the root sorter
/// takes roots of every LOD.
pub fn random_merger_merge_of(
    rng: &mut SplitMix64,
    d: &MergeDesign,
    sizes: MergerSizes,
    kind: Merges,
) -> Result<MergerTransaction, String> {
    random_merger_case_of(rng, d, sizes, kind).map(|c| c.tx)
}

/// A random merge with what it was made of: the store and table its
/// inputs are in, their ids (rank order) and the output id.
#[derive(Clone, Debug)]
pub struct MergerCase {
    /// The inputs.
    pub store: HierarchyStore,
    /// Their translations.
    pub table: TranslationTable,
    /// The inputs' ids, rank order.
    pub ids: Vec<u8>,
    /// The merged hierarchy's id.
    pub out_id: u8,
    /// The merge through the merger.
    pub tx: MergerTransaction,
}

/// [`random_merger_merge_of`] with its inputs (the same draws).
pub fn random_merger_case_of(
    rng: &mut SplitMix64,
    d: &MergeDesign,
    sizes: MergerSizes,
    kind: Merges,
) -> Result<MergerCase, String> {
    let p = &d.params;
    let k = d.inputs;
    let out_id = u8::try_from(p.hier_capacity() - 1).map_err(layout_err)?;
    // Inputs take ids 1..=k and the merge the last id, 2^H - 1.
    if k as u64 + 2 > p.hier_capacity() {
        return Err(format!(
            "{k} inputs: random merges give them ids 1..={k} and the merge id {out_id}, so at most {} inputs fit H = {}",
            p.hier_capacity() - 2,
            p.hier_bits
        ));
    }
    for _ in 0..MOST_DRAWS {
        let n = 1 + rng.below(k as u64) as usize;
        // Per-node mode: half the merges place every soup where the first
        // goes, so that voxels are contested and passes descend.
        let (together, scale) = match kind {
            Merges::Random => (is_per_node(d) && rng.below(2) == 0, 0.0),
            Merges::Hard => (rng.below(2) == 0, 0.32 * (-(rng.below(13) as f32)).exp2()),
        };
        let mut first_frac = None;
        let mut first_t = None;
        let mut store = HierarchyStore::new();
        let mut table = TranslationTable::new(p.hier_capacity() as usize, p).map_err(layout_err)?;
        let mut ids = Vec::new();
        for r in 0..n {
            let id = 1 + r as u8;
            let tris = 1 + rng.below(MOST_TRIANGLES) as usize;
            let size = match kind {
                Merges::Random => 0.02 + rng.below(30) as f32 / 100.0,
                Merges::Hard => scale * (1.0 + rng.below(4) as f32 / 4.0),
            };
            let mut h = try_soup(p, id, tris, size, rng.next_u64()).map_err(|e| {
                format!(
                    "a random soup of {tris} triangles does not build at D = {}, I = {}: {e}; expected parameters that hold it (a larger --index-bits)",
                    p.max_lod, p.index_bits
                )
            })?;
            if kind == Merges::Hard && rng.below(3) == 0 {
                h = random_cut(rng, &h, d.roots).unwrap_or(h);
            }
            let frac = [0, 1, 2].map(|_| rng.below(101) as f64 / 100.0);
            let t = match (kind, together, first_t) {
                (Merges::Hard, true, Some(first)) => {
                    near(&h, first, [0, 1, 2].map(|_| rng.below(3) as i64))
                }
                (Merges::Random, true, _) => place(&h, *first_frac.get_or_insert(frac)),
                _ => place(&h, frac),
            };
            first_t.get_or_insert(t);
            table.write(id as u32, t).map_err(layout_err)?;
            store.insert(h).map_err(layout_err)?;
            ids.push(id);
        }
        if let Ok(tx) = merger_transaction(&store, &table, &ids, d.mode, out_id, k, sizes) {
            if !tx.header.leaf_overflow {
                return Ok(MergerCase {
                    store,
                    table,
                    ids,
                    out_id,
                    tx,
                });
            }
        }
    }
    Err(format!(
        "no random merge of {MOST_DRAWS} drawn fits leaf FIFOs of 2^{} entries: expected a larger leaf_bits",
        sizes.leaf_bits
    ))
}

/// A translation of `h` at its top LOD `delta` voxels from `first` (moved
/// to that LOD), within the scene.
fn near(h: &Hierarchy, first: Translation, delta: [i64; 3]) -> Translation {
    let room = place(h, [1.0; 3]).t;
    let shift = h.top_lod as i32 - first.lod as i32;
    let at = |v: i64| match shift {
        s if s >= 0 => v << s,
        s => v >> -s,
    };
    Translation {
        lod: h.top_lod,
        t: [0, 1, 2].map(|a| (at(first.t[a]) + delta[a]).clamp(0, room[a])),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiles(s: &Layout) {
        let mut end = 0;
        for f in s.fields() {
            assert_eq!(
                f.offset,
                end,
                "`{}`: field {} not adjacent",
                s.name(),
                f.name
            );
            end = f.end();
        }
        assert_eq!(end, s.width(), "`{}`", s.name());
    }

    /// Every stream's fields tile its beat, and every beat of random
    /// merges is packed at its stream's width.
    #[test]
    fn stream_fields_tile_every_beat() {
        let modes = [
            MergeMode::Overlap { num: 1, den: 2 },
            MergeMode::PerNode { num: 1, den: 2 },
        ];
        for mode in modes {
            let d = MergeDesign {
                mode,
                ..MergeDesign::default()
            };
            let ports = module_ports(&d);
            let mut rng = SplitMix64(3);
            let m = module_merge(&mut rng, &d, 6).unwrap();
            let sizes = MergerSizes::new(&d.params);
            let mp = merger_ports(&d, &sizes).unwrap();
            let ml = merger_layout(&d, &sizes).unwrap();
            let tx = random_merger_merge(&mut rng, &d, sizes).unwrap();
            let mb = merger_beats(&d, &ml, &tx).unwrap();
            for (ports, m) in [(&ports, &m), (&mp, &mb)] {
                assert_eq!(ports.inputs.len(), m.inputs.len());
                assert_eq!(ports.outputs.len(), m.outputs.len());
                let all = ports.inputs.iter().zip(&m.inputs);
                for (s, beats) in all.chain(ports.outputs.iter().zip(&m.outputs)) {
                    tiles(s);
                    assert!(beats.iter().all(|b| b.width() == s.width()), "{}", s.name());
                }
            }
            assert_eq!(merger_stream(&ml, &d, "f9_node_req"), None);
        }
    }
}
