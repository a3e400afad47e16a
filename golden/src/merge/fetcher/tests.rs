use super::*;
use crate::build::{build, GridMap};
use crate::merge::error::MergeError;
use crate::merge::fetcher::walk::{collect, walk_input};
use crate::merge::fetcher::walk::{morton, place_node};
use crate::merge::merge_level::unit::LevelBeat;
use crate::merge::merge_module::input_stream;
use crate::merge::per_node::unit::{PerNodeLayout, PerNodeReport};
use crate::params::Params;
use crate::scenes::random_soup;
use crate::store::{Hierarchy, NodeRecord, Reference};
use crate::translate::table::pack_entry;
use crate::translate::Translation;

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
                let tx =
                    fetch_transaction(&h, pack_entry(Some(&t), &p), &[cmd], FetchSizes::default())
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
        FetchOut::Beat(LevelBeat::of_node(
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
    let tx =
        fetch_transaction(&h, pack_entry(Some(&t0), &p), &[cmd], FetchSizes::default()).unwrap();
    assert_eq!(tx.out.len(), 3);
    assert_eq!(tx.node_reqs, vec![0, 1, 2]);
    assert_eq!(tx.ref_reqs, vec![0, 1]);
}

use crate::merge::per_node::unit::{random_per_node_case, PerNodeBeat, PerNodeCase};
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
    tx: &crate::merge::per_node::unit::PerNodeTransaction,
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
        let (lo, hi) = crate::merge::level_choice::candidate_range(&refs);
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
    let beat = |i: u32| FetchOut::Beat(LevelBeat::of_node(&place(i)));
    let cref = |i: u32| FetchOut::Beat(LevelBeat::ChildRef(h.refs[i as usize]));
    let reports = [decide(v(1, 0), true), pass_end(1, true), pass_end(2, false)];
    let run = |h: &Hierarchy, entry, reports: &[PerNodeReport]| {
        fetch_transaction_with_reports(h, entry, &[FetchCmd::per_node(1, true, true)], reports, s)
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
    let tx = fetch_transaction_with_reports(&h, t0, &cmd, &[pass_end(1, false)], tight).unwrap();
    assert_eq!(tx.out, vec![err(0, fetch_err::FRONTIER)]);
}
