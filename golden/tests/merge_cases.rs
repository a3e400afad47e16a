//! Hard cases of merging, each a named test: all inputs overlapping, all
//! disjoint, single-node inputs, an input whose top has several nodes so its
//! translation breaks Morton order, boxes touching the scene extents at
//! D = 31, several merged hierarchies from subsets of the inputs with the
//! inputs untouched (67), and every refusal as an error.

mod merge_support;

use glam::Vec3;
use golden::build::build;
use golden::check::check_built;
use golden::merge::{merge, MergeError, MergeMode};
use golden::mesh::Mesh;
use golden::params::Params;
use golden::scenes::{box_mesh, random_soup, sphere, torus};
use golden::store::{Hierarchy, Reference};
use golden::translate::{translate_node, TranslateError, Translation};
use merge_support::{load, normalized, Scene};

const MODES: [MergeMode; 5] = [
    MergeMode::Overlap { num: 1, den: 2 },
    MergeMode::Fixed(0), // replaced by the lowest candidate
    MergeMode::BelowTop(1),
    MergeMode::Proportion { num: 1, den: 2 },
    MergeMode::PerNode { num: 1, den: 2 },
];

fn d16() -> Params {
    Params::new(16, 8, 24, 4).unwrap()
}

/// Four different meshes of about 8 world units, local near the origin.
fn four_meshes() -> Vec<Mesh> {
    vec![
        normalized(&load("bunny.obj"), 8.0, 1.0),
        normalized(&load("teapot.obj"), 8.0, 1.0),
        normalized(&sphere(Vec3::ZERO, 1.0, 12, 16), 7.0, 2.0),
        normalized(&torus(Vec3::ZERO, 2.0, 0.5, 16, 8), 8.0, 1.5),
    ]
}

/// Merges `inputs` of `s` with every mode into ids from `first_out`;
/// checks each, counts leaves, compares `rays` rays per mode.
fn every_mode(s: &mut Scene, inputs: &[u8], first_out: u8, rays: usize) {
    for (k, mode) in MODES.iter().enumerate() {
        let out = first_out + k as u8;
        let mode = match *mode {
            MergeMode::Fixed(_) => {
                let lo = inputs.iter().map(|i| s.top(*i)).max().unwrap();
                MergeMode::Fixed(lo)
            }
            MergeMode::BelowTop(k) => {
                let r = merge(
                    &s.store,
                    inputs,
                    &s.table,
                    MergeMode::Overlap { num: 1, den: 2 },
                    out,
                )
                .unwrap();
                let (lo, hi) = r.stats.candidates;
                MergeMode::BelowTop(k.min(hi - lo))
            }
            m => m,
        };
        let r = s.merge(inputs, mode, out);
        let rep = s.check(out, inputs);
        assert_eq!(rep.leaves, s.leaves_once(out, inputs));
        let t = s.compare(out, inputs, rays, 31 * out as u64, 2);
        t.print(&format!("{mode:?} level {:?}", r.level));
    }
}

#[test]
fn all_inputs_overlapping() {
    let mut s = Scene::new(d16(), 1.0 / 64.0);
    for (i, m) in four_meshes().into_iter().enumerate() {
        s.add(i as u8 + 1, m, [10, 10, 10]);
    }
    let r = s.merge(&[1, 2, 3, 4], MergeMode::default(), 5);
    assert!(r.stats.merge_level.created > 0, "{:?}", r.stats);
    every_mode(&mut s, &[1, 2, 3, 4], 6, 2_000);
}

#[test]
fn all_inputs_disjoint() {
    let mut s = Scene::new(d16(), 1.0 / 64.0);
    for (i, m) in four_meshes().into_iter().enumerate() {
        let k = i as i64;
        s.add(i as u8 + 1, m, [3 + 13 * k, 40 - 9 * k, 7 + 20 * (k % 2)]);
    }
    let r = s.merge(&[1, 2, 3, 4], MergeMode::default(), 5);
    // Nothing shared at any level: no node is created at the merging level.
    assert!(
        r.stats.overlap.iter().all(|o| o.shared == 0),
        "{:?}",
        r.stats
    );
    assert_eq!(r.stats.merge_level.created, 0);
    every_mode(&mut s, &[1, 2, 3, 4], 6, 2_000);
}

/// One small triangle: a hierarchy of a single leaf.
fn one_triangle(at: Vec3, size: f32) -> Mesh {
    Mesh {
        vertices: vec![
            at,
            at + Vec3::new(size, 0.0, 0.0),
            at + Vec3::new(0.0, size, size * 0.5),
        ],
        triangles: vec![[0, 1, 2]],
    }
}

#[test]
fn single_node_inputs() {
    let mut s = Scene::new(d16(), 1.0 / 64.0);
    // Two single-leaf inputs moved onto the same voxel, one elsewhere, and
    // a bunny over all of them.
    for id in 1..=3u8 {
        let h = s.add(id, one_triangle(Vec3::splat(1.0), 0.05), [0, 0, 0]);
        assert_eq!((h.nodes.len(), h.root_count), (1, 1), "a single node");
        assert!(h.nodes[0].leaf);
    }
    let l = s.top(1);
    let e = s.edge(l);
    let place = |k: i64| Translation {
        lod: l,
        t: [k, k, k],
    };
    s.table.write(1, place(640 * 64 / e)).unwrap();
    s.table.write(2, place(640 * 64 / e)).unwrap();
    s.table.write(3, place(300 * 64 / e)).unwrap();
    s.add(4, normalized(&load("bunny.obj"), 16.0, 1.0), [0, 0, 0]);
    let lb = s.top(4);
    s.table
        .write(
            4,
            Translation {
                lod: lb,
                t: [(630 * 64) / s.edge(lb); 3],
            },
        )
        .unwrap();
    // Only the single leaves: nothing to merge, a parent is made above them.
    let r = s.merge(&[1, 2], MergeMode::default(), 5);
    assert_eq!(
        (
            r.stats.merge_level.created,
            r.stats.merge_level.reused_leaves
        ),
        (0, 2)
    );
    assert_eq!(r.merged.root_count, 1);
    assert_eq!(r.merged.refs.len(), 2, "one root referencing both leaves");
    s.check(5, &[1, 2]);
    s.leaves_once(5, &[1, 2]);
    // A single input alone.
    let r = s.merge(&[3], MergeMode::default(), 6);
    assert_eq!(r.merged.nodes.len(), 1);
    // The lone leaf cannot be a root of the merged hierarchy: one grouping above it.
    assert_eq!((r.stats.lifted, r.merged.top_lod + 1), (1, s.top(3)));
    assert_eq!(r.merged.refs, vec![Reference { hier: 3, node: 0 }]);
    s.check(6, &[3]);
    s.compare(6, &[3], 500, 3, 1);
    every_mode(&mut s, &[1, 2, 3, 4], 7, 1_500);
}

/// `h` without its single root: its children become the roots (several, one
/// LOD deeper). The builder lays out the root's children right after it.
fn drop_root(h: &Hierarchy) -> Hierarchy {
    assert_eq!(h.root_count, 1);
    let root = h.nodes[0];
    let k = root.count;
    let kids: Vec<u32> = h.children_of(&root).iter().map(|r| r.node).collect();
    assert_eq!(kids, (1..=k).collect::<Vec<_>>());
    let mut out = Hierarchy {
        id: h.id,
        params: h.params,
        nodes: Vec::new(),
        refs: Vec::new(),
        prims: h.prims.clone(),
        root_count: k,
        top_lod: h.top_lod + 1,
    };
    for n in &h.nodes[1..] {
        let mut n = *n;
        if !n.leaf {
            let first = out.refs.len() as u32;
            for c in h.children_of(&h.nodes[out.nodes.len() + 1]) {
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

#[test]
fn translation_breaking_morton_order_of_several_top_nodes() {
    let p = d16();
    let mut s = Scene::new(p, 1.0 / 64.0);
    // A teapot over a voxel corner, so its top has several nodes.
    let teapot = normalized(&load("teapot.obj"), 8.0, 12.0);
    let grid = s.grid;
    let built = build(&teapot, &grid, &p, 1).unwrap();
    let h = drop_root(&built);
    let tris = grid.mesh_to_grid(&teapot, &p).unwrap();
    check_built(&h, &tris).unwrap();
    assert!(h.root_count >= 2, "several top nodes: {}", h.root_count);
    // A move at the top LOD whose carries reorder the roots.
    let l = h.top_lod;
    let t = Translation {
        lod: l,
        t: [1, 3, 2],
    };
    let roots: Vec<u128> = h
        .roots()
        .iter()
        .map(|n| translate_node(n.voxel, &t, &p).unwrap().morton())
        .collect();
    assert!(
        roots.windows(2).any(|w| w[0] > w[1]),
        "translated roots in store order {roots:?} must be out of Morton order"
    );
    s.add_built(1, teapot, h, t);
    // The bunny over the same place.
    s.add(2, normalized(&load("bunny.obj"), 8.0, 12.0), [0, 0, 0]);
    let lb = s.top(2);
    let off = (s.edge(l) * 2) / s.edge(lb);
    s.table
        .write(
            2,
            Translation {
                lod: lb,
                t: [off, 3 * off, off],
            },
        )
        .unwrap();
    every_mode(&mut s, &[1, 2], 3, 3_000);
    // Alone: its translated roots become the merged hierarchy's base in Morton order.
    let r = s.merge(&[1], MergeMode::Fixed(l), 9);
    s.check(9, &[1]);
    let base: Vec<u128> = r
        .merged
        .nodes
        .iter()
        .filter(|n| n.voxel.lod == l)
        .map(|n| n.voxel.morton())
        .collect();
    assert!(base.windows(2).all(|w| w[0] <= w[1]), "{base:?}");
}

#[test]
fn boxes_touching_the_scene_extents_at_d31() {
    let p = Params::new(31, 16, 32, 8).unwrap();
    let unit = 1.0f64;
    let mut s = Scene::new(p, unit);
    let edge = p.scene_edge() as f32; // 2^31, exact in f32
    let size = 4096.0f32;
    // 1: a box touching the far faces, not moved; 2: a box touching the
    // near faces, not moved; 3: a box near the origin moved to the last
    // voxel of its top LOD; 4: a box at the far corner moved to voxel 0.
    s.add(
        1,
        box_mesh(Vec3::splat(edge - size), Vec3::splat(edge)),
        [0, 0, 0],
    );
    s.add(2, box_mesh(Vec3::ZERO, Vec3::splat(size)), [0, 0, 0]);
    s.add(
        3,
        box_mesh(Vec3::splat(size * 0.25), Vec3::splat(size * 0.75)),
        [0, 0, 0],
    );
    let l3 = s.top(3);
    let x3 = s.store.get(3).unwrap().nodes[0].voxel.x as i64;
    let last = (1i64 << l3) - 1 - x3;
    s.table
        .write(
            3,
            Translation {
                lod: l3,
                t: [last; 3],
            },
        )
        .unwrap();
    s.add(
        4,
        box_mesh(
            Vec3::splat(edge - size * 0.75),
            Vec3::splat(edge - size * 0.25),
        ),
        [0, 0, 0],
    );
    let l4 = s.top(4);
    let x4 = s.store.get(4).unwrap().nodes[0].voxel.x as i64;
    s.table
        .write(
            4,
            Translation {
                lod: l4,
                t: [-x4; 3],
            },
        )
        .unwrap();
    // The placed roots sit at the extents.
    let placed = |id: u8| {
        let h = s.store.get(id).unwrap();
        let t = s.table.read(id as u32).unwrap();
        translate_node(h.nodes[0].voxel, &t, &p).unwrap()
    };
    assert_eq!(placed(3).x, (1 << l3) - 1);
    assert_eq!(placed(4).x, 0);
    let h1 = s.store.get(1).unwrap();
    let (_, hi) = golden::store::node_box_fine(&h1.nodes[0], &p);
    assert_eq!(
        hi,
        [(p.scene_edge()) << 16; 3],
        "box 1 touches the far faces"
    );
    every_mode(&mut s, &[1, 2, 3, 4], 10, 2_000);
    // Moving one more voxel out of the scene is an error, not a wrap.
    s.table
        .write(
            3,
            Translation {
                lod: l3,
                t: [last + 1, last, last],
            },
        )
        .unwrap();
    let e = merge(&s.store, &[1, 3], &s.table, MergeMode::default(), 20).unwrap_err();
    assert!(
        matches!(
            e,
            MergeError::TranslateNode {
                input: 3,
                error: TranslateError::NodeOutsideScene { .. },
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn several_merged_hierarchies_from_subsets_leave_inputs_untouched() {
    let mut s = Scene::new(d16(), 1.0 / 64.0);
    for (i, m) in four_meshes().into_iter().enumerate() {
        let k = i as i64;
        s.add(i as u8 + 1, m, [10 + 3 * (k % 2), 10, 10 + (k / 2)]);
    }
    let before: Vec<Hierarchy> = (1..=4).map(|i| s.store.get(i).unwrap().clone()).collect();
    let table_before = s.table.clone();
    s.merge(&[1, 2], MergeMode::default(), 10);
    s.merge(&[3, 4], MergeMode::PerNode { num: 1, den: 2 }, 11);
    s.merge(&[4, 2, 1], MergeMode::BelowTop(1), 12);
    s.merge(&[1, 2, 3, 4], MergeMode::default(), 13);
    for (out, inputs) in [
        (10u8, vec![1u8, 2]),
        (11, vec![3, 4]),
        (12, vec![4, 2, 1]),
        (13, vec![1, 2, 3, 4]),
    ] {
        s.check(out, &inputs);
        s.leaves_once(out, &inputs);
        let t = s.compare(out, &inputs, 1_500, out as u64, 2);
        t.print(&format!("subset {inputs:?}"));
    }
    for (i, b) in before.iter().enumerate() {
        assert_eq!(s.store.get(i as u8 + 1), Some(b), "input {} changed", i + 1);
    }
    assert_eq!(s.table, table_before);
    assert_eq!(s.store.len(), 8);
    // Merged hierarchies are not inputs: merging one is refused, not wrong.
    let e = merge(&s.store, &[10, 3], &s.table, MergeMode::default(), 14).unwrap_err();
    assert!(
        matches!(e, MergeError::Translation { input: 10, .. }),
        "{e}"
    );
}

#[test]
fn refusals_are_errors_naming_the_input() {
    let mut s = Scene::new(d16(), 1.0 / 64.0);
    s.add(1, random_soup(50, 0.01, 1), [0, 0, 0]);
    s.add(2, random_soup(50, 0.01, 2), [0, 0, 0]);
    let m = |s: &Scene, inputs: &[u8], out: u8| {
        merge(&s.store, inputs, &s.table, MergeMode::default(), out).unwrap_err()
    };
    assert_eq!(m(&s, &[], 3), MergeError::NoInputs);
    assert_eq!(m(&s, &[1, 1], 3), MergeError::DuplicateInput(1));
    assert_eq!(m(&s, &[1, 7], 3), MergeError::UnknownInput(7));
    // Input by input (SPEC 8.1): the first input's error is the one reported.
    assert_eq!(m(&s, &[7, 1, 1], 3), MergeError::UnknownInput(7));
    assert_eq!(m(&s, &[1, 1, 7], 3), MergeError::DuplicateInput(1));
    assert_eq!(m(&s, &[1, 2], 2), MergeError::OutIdInUse(2));
    assert_eq!(
        m(&s, &[1, 2], 16),
        MergeError::OutIdOutOfRange {
            id: 16,
            hier_bits: 4
        }
    );
    // A translation finer than the top LOD would move nodes above it.
    let top = s.top(2);
    s.table
        .write(
            2,
            Translation {
                lod: top + 1,
                t: [0; 3],
            },
        )
        .unwrap();
    let e = m(&s, &[1, 2], 3);
    assert!(
        matches!(
            e,
            MergeError::TranslateNode {
                input: 2,
                error: TranslateError::AboveTranslationLevel { .. },
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("input 2"));
    s.table.invalidate(2).unwrap();
    assert!(matches!(
        m(&s, &[1, 2], 3),
        MergeError::Translation { input: 2, .. }
    ));
    s.table.write(2, Translation::zero(top)).unwrap();
    // An input referencing another hierarchy.
    let mut bad = s.store.get(2).unwrap().clone();
    bad.id = 5;
    bad.refs[0] = Reference { hier: 1, node: 0 };
    s.table.write(5, Translation::zero(top)).unwrap();
    s.store.insert(bad).unwrap();
    let e = m(&s, &[1, 5], 3);
    assert!(
        matches!(
            e,
            MergeError::BadInput {
                input: 5,
                field: "reference",
                ..
            }
        ),
        "{e}"
    );
    // Different parameters.
    let p2 = Params::new(16, 4, 24, 4).unwrap();
    let grid = s.grid;
    let h = build(&random_soup(5, 0.01, 3), &grid, &p2, 6).unwrap();
    s.store.insert(h).unwrap();
    s.table.write(6, Translation::zero(0)).unwrap();
    assert!(matches!(
        m(&s, &[1, 6], 3),
        MergeError::ParamsMismatch { input: 6, .. }
    ));
    // Too few index bits for the merged records' references.
    let tiny = Params::new(16, 8, 4, 4).unwrap();
    let mut t = Scene::new(tiny, 1.0 / 64.0);
    t.add(1, one_triangle(Vec3::splat(1.0), 0.05), [0, 0, 0]);
    for id in 2..=15u8 {
        let h = build(
            &one_triangle(Vec3::splat(1.0 + id as f32 * 0.3), 0.05),
            &t.grid,
            &tiny,
            id,
        )
        .unwrap();
        let tr = Translation::zero(h.top_lod);
        t.add_built(id, Mesh::default(), h, tr);
    }
    let all: Vec<u8> = (1..=15).collect();
    let e = merge(
        &t.store,
        &all,
        &t.table,
        MergeMode::PerNode { num: 0, den: 1 },
        0,
    );
    match e {
        Err(e @ MergeError::IndexOverflow { index_bits: 4, .. }) => println!("{e}"),
        other => panic!("expected an index overflow at I = 4, got {other:?}"),
    }
}

#[test]
fn a_lone_input_root_is_materialized() {
    let mut s = Scene::new(d16(), 1.0 / 64.0);
    s.add(1, normalized(&load("bunny.obj"), 8.0, 1.0), [3, 4, 5]);
    let r = s.merge(&[1], MergeMode::BelowTop(0), 2);
    let h = s.store.get(1).unwrap();
    let t = s.table.read(1).unwrap();
    // The merged hierarchy is a copy of the input's root, placed, with the
    // root's references (naming the input).
    assert_eq!(
        (
            r.stats.materialized,
            r.merged.nodes.len(),
            r.merged.root_count
        ),
        (1, 1, 1)
    );
    let root = r.merged.nodes[0];
    assert_eq!(
        root.voxel,
        translate_node(h.nodes[0].voxel, &t, &h.params).unwrap()
    );
    assert_eq!((root.lo, root.hi), (h.nodes[0].lo, h.nodes[0].hi));
    assert_eq!(r.merged.children_of(&root), h.children_of(&h.nodes[0]));
    s.check(2, &[1]);
    s.compare(2, &[1], 1_000, 4, 1);
}
