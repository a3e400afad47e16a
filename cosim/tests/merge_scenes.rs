//! The four merging-module units on real merges: hierarchies built by the
//! golden builder from triangle soups, placed by translations (all inputs
//! overlapping, all disjoint, single-node inputs, D = 31 far from the
//! origin, and an input whose top has several nodes so that its translation
//! breaks Morton order), walked by the golden S610/S612 (`walk_input`), then
//! every candidate level through S614 and S608, every level list through
//! S616's grouping and every input's roots through the root sorter, on the
//! IR simulator and Verilator, bit for bit against the golden transactions.
mod merge_common;

use cosim::tb::Vector;
use cosim::Bits;
use golden::build::{build, GridMap};
use golden::merge::fetcher::root_sorter::*;
use golden::merge::fetcher::walk::{collect, walk_input, PlacedNode, WalkedInput};
use golden::merge::level_choice::candidate_range;
use golden::merge::level_choice::unit::*;
use golden::merge::merge_level::unit::*;
use golden::merge::upper_builder::level_unit::*;
use golden::params::Params;
use golden::scenes::random_soup;
use golden::seed::seeded;
use golden::store::{Hierarchy, NodeRecord, Reference};
use golden::translate::Translation;
use merge_common::*;

/// `h` without its single root: the root's children become the roots.
fn drop_root(h: &Hierarchy) -> Hierarchy {
    let root = h.nodes[0];
    let k = root.count;
    let mut out = Hierarchy {
        nodes: Vec::new(),
        refs: Vec::new(),
        root_count: k,
        top_lod: h.top_lod + 1,
        ..h.clone()
    };
    for (i, n) in h.nodes[1..].iter().enumerate() {
        let mut n = *n;
        if !n.leaf {
            let first = out.refs.len() as u32;
            for c in h.children_of(&h.nodes[i + 1]) {
                out.refs.push(Reference {
                    hier: h.id,
                    node: c.node - 1,
                });
            }
            n.first = first;
        }
        out.nodes.push(n);
    }
    out
}

/// A soup hierarchy `id` in a scene whose unit cube is `2^-shrink` of the
/// scene, moved by `offset` world units on every axis.
fn soup_at(
    p: &Params,
    id: u8,
    n: usize,
    size: f32,
    seed: u64,
    shrink: u32,
    offset: f64,
) -> Hierarchy {
    let mesh = random_soup(n, size, seeded(seed));
    let (lo, hi) = mesh.bounds();
    let fitted = GridMap::fit(lo, hi, p);
    let grid = GridMap {
        origin: fitted.origin * 0.0 - offset,
        unit: 1.0 / (p.scene_edge() >> shrink) as f64,
    };
    build(&mesh, &grid, p, id).expect("the soup builds")
}

fn soup(p: &Params, id: u8, n: usize, size: f32, seed: u64, shrink: u32) -> Hierarchy {
    soup_at(p, id, n, size, seed, shrink, 0.0)
}

/// A translation at `h`'s top LOD by `frac` of the room left in the scene.
fn place(h: &Hierarchy, frac: [f64; 3]) -> Translation {
    let l = h.top_lod;
    let max = [0, 1, 2].map(|a| {
        h.roots()
            .iter()
            .map(|n| [n.voxel.x, n.voxel.y, n.voxel.z][a] as i64)
            .max()
            .unwrap()
    });
    let room = [0, 1, 2].map(|a| (1i64 << l) - 1 - max[a]);
    Translation {
        lod: l,
        t: [0, 1, 2].map(|a| (room[a] as f64 * frac[a]) as i64),
    }
}

struct Case {
    name: &'static str,
    params: Params,
    inputs: Vec<(Hierarchy, Translation)>,
}

fn cases() -> Vec<Case> {
    let d16 = Params::default();
    let d31 = Params::new(31, 16, 32, 8).unwrap();
    let same = [0.4, 0.5, 0.6];
    let mut out = Vec::new();
    let hs: Vec<Hierarchy> = (1..=4)
        .map(|i| soup(&d16, i, 80, 0.2, i as u64, 3))
        .collect();
    out.push(Case {
        name: "overlapping",
        params: d16,
        inputs: hs.iter().map(|h| (h.clone(), place(h, same))).collect(),
    });
    out.push(Case {
        name: "disjoint",
        params: d16,
        inputs: hs
            .iter()
            .enumerate()
            .map(|(i, h)| {
                (
                    h.clone(),
                    place(h, [0.1 + 0.25 * i as f64, 0.9 - 0.2 * i as f64, 0.3]),
                )
            })
            .collect(),
    });
    let mut single: Vec<(Hierarchy, Translation)> = (1..=3)
        .map(|i| {
            let h = soup(&d16, i, 1, 0.001, 10 + i as u64, 3);
            let t = place(&h, if i < 3 { same } else { [0.9, 0.1, 0.2] });
            (h, t)
        })
        .collect();
    let big = soup(&d16, 4, 120, 0.3, 99, 3);
    single.push((big.clone(), place(&big, same)));
    out.push(Case {
        name: "single-node",
        params: d16,
        inputs: single,
    });
    let far: Vec<(Hierarchy, Translation)> = (1..=3)
        .map(|i| {
            let h = soup(&d31, i, 60, 0.3, 40 + i as u64, 4);
            let t = place(&h, [0.999, 0.998 - 0.001 * i as f64, 0.999]);
            (h, t)
        })
        .collect();
    out.push(Case {
        name: "d31-far",
        params: d31,
        inputs: far,
    });
    // Several top nodes: a soup over the scene's centre without its root.
    let wide = soup_at(&d16, 1, 300, 0.05, 7, 3, 0.6);
    let several = drop_root(&wide);
    assert!(
        several.root_count >= 2,
        "several roots: {}",
        several.root_count
    );
    // The first move (within the room left) whose carries reorder the roots.
    let room = place(&several, [1.0; 3]).t;
    let t = (0..=room[0])
        .flat_map(|x| (0..=room[1]).flat_map(move |y| (0..=room[2]).map(move |z| [x, y, z])))
        .map(|t| Translation {
            lod: several.top_lod,
            t,
        })
        .find(|t| {
            let m: Vec<u128> = several
                .roots()
                .iter()
                .map(|n| {
                    golden::translate::translate_node(n.voxel, t, &d16)
                        .unwrap()
                        .morton()
                })
                .collect();
            m.windows(2).any(|w| w[0] > w[1])
        })
        .expect("a move that breaks the roots' Morton order");
    let partner = soup(&d16, 2, 80, 0.3, 8, 2);
    let tp = place(&partner, same);
    out.push(Case {
        name: "several-top-nodes",
        params: d16,
        inputs: vec![(several, t), (partner, tp)],
    });
    out
}

/// The Morton-sorted nodes of one level (the order of S616's level lists).
fn sorted_level(nodes: &[PlacedNode]) -> Vec<NodeRecord> {
    let mut v: Vec<PlacedNode> = nodes.to_vec();
    v.sort_by_key(|n| n.key());
    v.iter().map(|n| n.record).collect()
}

#[derive(Default)]
struct Streams {
    level: Vec<Vector>,
    overlap: Vec<Vector>,
    upper: Vec<Vector>,
    sorter: Vec<Vector>,
    out_of_order_roots: usize,
}

fn one(beats_in: Vec<Bits>, outs: Vec<Bits>, into: &mut Vec<Vector>) {
    let expected: Vec<_> = outs.into_iter().map(|o| vec![o]).collect();
    for (j, b) in beats_in.into_iter().enumerate() {
        into.push(Vector {
            input: vec![b],
            outputs: if j == 0 { expected.clone() } else { Vec::new() },
        });
    }
}

fn streams(c: &Case) -> Streams {
    let p = &c.params;
    let hs: Vec<&Hierarchy> = c.inputs.iter().map(|(h, _)| h).collect();
    let (lo, hi) = candidate_range(&hs);
    let walked: Vec<WalkedInput> = c
        .inputs
        .iter()
        .enumerate()
        .map(|(r, (h, t))| walk_input(h, r as u16, t, hi).expect("the input walks"))
        .collect();
    let (li, lo_) = (BeatLayout::input(p), BeatLayout::output(p));
    let ol = OverlapLayout::new(p, hs.len());
    let ul = UpperLayout::new(p);
    let mut s = Streams::default();
    for l in lo..=hi {
        let (_, at) = collect(&walked, l);
        let tx = level_transaction(&at, &hs, p).expect("S614");
        one(
            tx.inputs.iter().map(|b| b.pack(&li).unwrap()).collect(),
            tx.outputs.iter().map(|b| b.pack(&lo_).unwrap()).collect(),
            &mut s.level,
        );
        let voxels: Vec<Vec<_>> = walked
            .iter()
            .map(|w| {
                w.by_lod[l as usize]
                    .iter()
                    .map(|n| n.record.voxel)
                    .collect()
            })
            .collect();
        let (beats, r) = overlap_transaction(&voxels, p, 1, 2);
        one(
            beats.iter().map(|b| b.pack(&ol).unwrap()).collect(),
            vec![r.pack(&ol).unwrap()],
            &mut s.overlap,
        );
        if l >= 1 {
            let (ins, outs) = upper_transaction(&sorted_level(&at), p);
            one(
                ins.iter().map(|b| b.pack(&ul, false).unwrap()).collect(),
                outs.iter().map(|b| b.pack(&ul, true).unwrap()).collect(),
                &mut s.upper,
            );
        }
    }
    let err_bit = lo_.err.unwrap().offset;
    for w in &walked {
        let roots = &w.by_lod[w.top_lod as usize];
        let keys: Vec<_> = roots
            .iter()
            .map(|n| (n.record.voxel.morton(), n.record.leaf))
            .collect();
        s.out_of_order_roots += keys.windows(2).any(|k| k[0] > k[1]) as usize;
        let (ins, outs) = root_sort_transaction(roots, 16);
        one(
            ins.iter().map(|b| b.pack(&li).unwrap()).collect(),
            outs.iter()
                .map(|(b, err)| {
                    let bits = b.pack(&li).unwrap();
                    let mut v = Bits::from_words(bits.words(), lo_.width()).unwrap();
                    v.set_bit(err_bit, *err).unwrap();
                    v
                })
                .collect(),
            &mut s.sorter,
        );
    }
    s
}

/// The root sorter's premise: with an input's roots in translated Morton
/// order (roots are referenced by nobody, so they may be permuted in
/// place), the walk meets every deeper level in translated Morton order.
#[test]
fn sorted_roots_give_sorted_levels() {
    let mut checked = 0;
    for c in cases() {
        for (r, (h, t)) in c.inputs.iter().enumerate() {
            let rc = h.root_count as usize;
            let mut roots: Vec<_> = h.nodes[..rc].to_vec();
            let key = |n: &NodeRecord| {
                let v = golden::translate::translate_node(n.voxel, t, &c.params).unwrap();
                (v.morton(), n.leaf)
            };
            roots.sort_by_key(key);
            let mut sorted = h.clone();
            sorted.nodes[..rc].copy_from_slice(&roots);
            let deepest = h.nodes.iter().map(|n| n.voxel.lod).max().unwrap();
            let w = walk_input(&sorted, r as u16, t, deepest).expect("walks");
            for level in &w.by_lod {
                let keys: Vec<_> = level
                    .iter()
                    .map(|n| (n.record.voxel.morton(), n.record.leaf))
                    .collect();
                assert!(
                    keys.windows(2).all(|k| k[0] <= k[1]),
                    "{}: input {r}",
                    c.name
                );
                checked += level.len();
            }
        }
    }
    assert!(checked > 1000);
}

#[test]
fn hard_case_scenes_through_every_unit() {
    if !tools_present(&["verilator"]) {
        return;
    }
    let mut broken = 0;
    for c in cases() {
        let p = c.params;
        let s = streams(&c);
        broken += s.out_of_order_roots;
        eprintln!(
            "{}: beats S614 {}, S608 {}, S616 {}, roots {} ({} inputs with roots out of order)",
            c.name,
            s.level.len(),
            s.overlap.len(),
            s.upper.len(),
            s.sorter.len(),
            s.out_of_order_roots
        );
        let units = [
            ("level", rtl_gen::merge::merge_level_unit(&p), &s.level),
            (
                "overlap",
                rtl_gen::merge::overlap_counter_unit(&p, c.inputs.len(), 1, 2),
                &s.overlap,
            ),
            ("upper", rtl_gen::merge::upper_level_unit(&p), &s.upper),
            (
                "sorter",
                rtl_gen::merge::root_sorter_unit(&p, 16),
                &s.sorter,
            ),
        ];
        for (what, m, vs) in units {
            if vs.is_empty() {
                continue;
            }
            let dir = tempfile::tempdir().unwrap();
            let design = design_of(&m, dir.path());
            for kind in ["ir", "verilator"] {
                let mut e = engine(kind, &m, &design);
                run(
                    e.as_mut(),
                    vs,
                    3,
                    0.3,
                    &format!("merge_scenes {} {what} {kind}", c.name),
                );
            }
        }
    }
    assert!(
        broken > 0,
        "some input's translated roots are out of Morton order"
    );
}

/// Every hard-case merge through the merging module as one unit
/// (`merge_module_unit`): the candidate levels of the real inputs, the count
/// pass over their walked, translated levels, the choice, the merge pass;
/// bit for bit against `golden::merge::merge_module`, whose overlap choice must equal
/// golden S608 on the fully walked inputs (`level::overlaps` +
/// `choose_level`), on the IR simulator, Verilator and Icarus.
#[test]
fn hard_case_merges_through_the_merging_module() {
    if !tools_present(&["verilator", "iverilog"]) {
        return;
    }
    use cosim::tb::{run_multi_stream_bench, BenchConfig, StreamBeats};
    use golden::merge::level_choice::{choose_level, overlaps};
    use golden::merge::merge_module::MergeDesign;
    use golden::merge::merge_module::{top_transaction, Report, TopLayout};
    use golden::merge::MergeMode;
    for c in cases() {
        let p = c.params;
        let k = c.inputs.len();
        let hs: Vec<&Hierarchy> = c.inputs.iter().map(|(h, _)| h).collect();
        let (lo, hi) = candidate_range(&hs);
        let walked: Vec<WalkedInput> = c
            .inputs
            .iter()
            .enumerate()
            .map(|(r, (h, t))| walk_input(h, r as u16, t, hi).expect("the input walks"))
            .collect();
        let levels: Vec<Option<LevelCase>> = (lo..=hi)
            .map(|l| {
                Some(LevelCase {
                    hierarchies: c.inputs.iter().map(|(h, _)| h.clone()).collect(),
                    at_level: collect(&walked, l).1,
                })
            })
            .collect();
        for mode in [
            MergeMode::Overlap { num: 1, den: 2 },
            MergeMode::BelowTop(1),
        ] {
            let tx = top_transaction(&mode, &p, k, lo, hi, &levels, true).expect("golden top");
            let want = choose_level(&mode, lo, hi, &overlaps(&walked, lo, hi));
            match (tx.reports.last(), want) {
                (Some(Report::Chosen { lod, err: 0 }), Ok(Some(l))) => assert_eq!(*lod, l),
                (Some(Report::Chosen { err, .. }), Err(_)) => assert_ne!(*err, 0),
                (got, want) => panic!("{}: {mode}: unit {got:?}, golden {want:?}", c.name),
            }
            let d = MergeDesign {
                params: p,
                inputs: k,
                mode,
                ..MergeDesign::default()
            };
            let (tl, li, lo_) = (
                TopLayout::new(&p),
                BeatLayout::input(&p),
                BeatLayout::output(&p),
            );
            let mut ins = vec![StreamBeats {
                name: "cfg".into(),
                beats: vec![vec![tl.pack_cfg(lo, hi).unwrap()]],
            }];
            for (i, s) in tx.inputs.iter().enumerate() {
                ins.push(StreamBeats {
                    name: format!("in{i}"),
                    beats: s.iter().map(|b| vec![b.pack(&li).unwrap()]).collect(),
                });
            }
            let outs = vec![
                StreamBeats {
                    name: "report".into(),
                    beats: tx
                        .reports
                        .iter()
                        .map(|r| vec![r.pack(&tl).unwrap()])
                        .collect(),
                },
                StreamBeats {
                    name: "out".into(),
                    beats: tx.out.iter().map(|b| vec![b.pack(&lo_).unwrap()]).collect(),
                },
            ];
            eprintln!(
                "{} {mode}: levels {lo}..={hi}, {} out beats",
                c.name,
                tx.out.len()
            );
            let m = rtl_gen::merge::merge_module_unit(&d);
            let dir = tempfile::tempdir().unwrap();
            let design = design_of(&m, dir.path());
            for kind in ["ir", "verilator", "iverilog"] {
                let mut e = engine(kind, &m, &design);
                let config = BenchConfig {
                    seed: 5,
                    in_stall: cosim::tb::Stalls::Coin(0.3),
                    out_stall: cosim::tb::Stalls::Coin(0.3),
                    ..BenchConfig::default()
                };
                let r = run_multi_stream_bench(e.as_mut(), &ins, &outs, &config).unwrap();
                assert!(r.passed(), "{} {mode} {kind}:\n{r}", c.name);
            }
        }
    }
}
