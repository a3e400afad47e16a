//! The expanding variant (FIG. 11, 12a/12b): hand-checkable splits, box
//! re-quantization, and coverage properties.

use golden::translate::expand::{
    expand_node, expand_voxel, expansion_cost, expansion_cost_voxels, NodeBox,
};
use golden::translate::{translate_node, Axis, TranslateError, Translation};
use golden::{Params, VoxelAddr};
use proptest::prelude::*;

fn v(d: u8, x: u32, y: u32, z: u32) -> VoxelAddr {
    VoxelAddr::new(d, x, y, z)
}

#[test]
fn a_voxel_moved_by_half_its_edge_straddles_2_4_8_voxels() {
    // D = 4, Q = 0: a LOD-1 voxel is 8 grid units; a LOD-2 translation of 1
    // moves it by 4, half its edge.
    let p = Params::new(4, 0, 16, 2).unwrap();
    let n = v(1, 0, 0, 0);
    let one = expand_voxel(
        n,
        &Translation {
            lod: 2,
            t: [1, 0, 0],
        },
        &p,
    )
    .unwrap();
    assert_eq!(one, vec![v(1, 0, 0, 0), v(1, 1, 0, 0)]);
    let two = expand_voxel(
        n,
        &Translation {
            lod: 2,
            t: [1, 0, 1],
        },
        &p,
    )
    .unwrap();
    assert_eq!(
        two,
        vec![v(1, 0, 0, 0), v(1, 1, 0, 0), v(1, 0, 0, 1), v(1, 1, 0, 1)]
    );
    let three = expand_voxel(
        n,
        &Translation {
            lod: 2,
            t: [1, 1, 1],
        },
        &p,
    )
    .unwrap();
    assert_eq!(three.len(), 8);
    assert_eq!(three[0], v(1, 0, 0, 0));
    assert_eq!(three[7], v(1, 1, 1, 1));
    // A whole-voxel move (t = 2 at LOD 2 is one LOD-1 voxel) does not split.
    assert_eq!(
        expand_voxel(
            n,
            &Translation {
                lod: 2,
                t: [2, 0, -0]
            },
            &p
        )
        .unwrap(),
        vec![v(1, 1, 0, 0)]
    );
    // Grid-unit granularity (L = D): a move of 1 unit still splits.
    assert_eq!(
        expand_voxel(
            n,
            &Translation {
                lod: 4,
                t: [0, 1, 0]
            },
            &p
        )
        .unwrap()
        .len(),
        2
    );
}

#[test]
fn boxes_are_requantized_outward_into_each_covered_voxel() {
    // D = 4, Q = 2: a LOD-1 voxel is 8 grid units = 32 fine units, a cell 8
    // fine units (2 grid units).
    let p = Params::new(4, 2, 16, 2).unwrap();
    let left_half = NodeBox {
        addr: v(1, 0, 0, 0),
        lo: [0, 0, 0],
        hi: [1, 3, 3],
    };
    // Half a voxel to the right: exactly the right half, no split.
    let moved = expand_node(
        &left_half,
        &Translation {
            lod: 2,
            t: [1, 0, 0],
        },
        &p,
    )
    .unwrap();
    assert_eq!(
        moved,
        vec![NodeBox {
            addr: v(1, 0, 0, 0),
            lo: [2, 0, 0],
            hi: [3, 3, 3]
        }]
    );
    // The right half moved by half a voxel lands in the next voxel's left half.
    let right_half = NodeBox {
        lo: [2, 0, 0],
        hi: [3, 3, 3],
        ..left_half
    };
    let moved = expand_node(
        &right_half,
        &Translation {
            lod: 2,
            t: [1, 0, 0],
        },
        &p,
    )
    .unwrap();
    assert_eq!(
        moved,
        vec![NodeBox {
            addr: v(1, 1, 0, 0),
            lo: [0, 0, 0],
            hi: [1, 3, 3]
        }]
    );
    // An eighth of a voxel (one grid unit = half a cell): cells 0..=1 cover
    // fine [0, 16] -> [4, 20]: outward, cells 0..=2.
    let moved = expand_node(
        &left_half,
        &Translation {
            lod: 4,
            t: [1, 0, 0],
        },
        &p,
    )
    .unwrap();
    assert_eq!(
        moved,
        vec![NodeBox {
            addr: v(1, 0, 0, 0),
            lo: [0, 0, 0],
            hi: [2, 3, 3]
        }]
    );
    // Cells 1..=3 moved by 3 grid units (fine 12): [8, 32] -> [20, 44]
    // covers voxel 0 cells 2..=3 and voxel 1 fine [32, 44] -> cells 0..=1.
    let n = NodeBox {
        addr: v(1, 0, 0, 0),
        lo: [1, 0, 0],
        hi: [3, 0, 0],
    };
    let moved = expand_node(
        &n,
        &Translation {
            lod: 4,
            t: [3, 0, 0],
        },
        &p,
    )
    .unwrap();
    assert_eq!(
        moved,
        vec![
            NodeBox {
                addr: v(1, 0, 0, 0),
                lo: [2, 0, 0],
                hi: [3, 0, 0]
            },
            NodeBox {
                addr: v(1, 1, 0, 0),
                lo: [0, 0, 0],
                hi: [1, 0, 0]
            },
        ]
    );
}

#[test]
fn figure_12b_parent_splits_into_four_child_stays_one() {
    // FIG. 11/12: a node with one child; the translation is at the child's
    // level and moves by one child voxel in x and y: the parent straddles
    // four voxels (2D figure; z unmoved), the child moves aligned.
    let p = Params::new(6, 0, 16, 2).unwrap();
    let parent = v(3, 2, 2, 0);
    let child = v(4, 5, 4, 0);
    let t = Translation {
        lod: 4,
        t: [1, 1, 0],
    };
    let cost = expansion_cost_voxels(&[parent, child], &t, &p).unwrap();
    assert_eq!((cost.before, cost.after, cost.added), (2, 5, 3));
    assert_eq!(cost.per_lod[0].after, 4);
    assert_eq!(cost.per_lod[1].after, 1);
    assert_eq!(translate_node(child, &t, &p), Ok(v(4, 6, 5, 0)));
    // FIG. 13/14: the voxel-aligned alternative (one parent voxel) adds nothing.
    let aligned = Translation {
        lod: 3,
        t: [1, 1, 0],
    };
    assert_eq!(
        expansion_cost_voxels(&[parent, child], &aligned, &p)
            .unwrap()
            .added,
        0
    );
}

#[test]
fn neighbouring_copies_share_voxels_and_the_count_says_so() {
    let p = Params::new(5, 0, 16, 2).unwrap();
    // Two adjacent LOD-2 voxels moved by half an edge: 2 + 2 copies in 3 voxels.
    let cost = expansion_cost_voxels(
        &[v(2, 0, 0, 0), v(2, 1, 0, 0)],
        &Translation {
            lod: 3,
            t: [1, 0, 0],
        },
        &p,
    )
    .unwrap();
    assert_eq!((cost.before, cost.after, cost.added), (2, 4, 2));
    assert_eq!(cost.per_lod[0].distinct_voxels, 3);
}

#[test]
fn boxes_leaving_the_scene_are_errors() {
    let p = Params::new(4, 2, 16, 2).unwrap();
    // Voxel x = 1 is fine [32, 64]; half a voxel (16) to the right is [48, 80].
    let n = NodeBox::full_voxel(v(1, 1, 0, 0), &p);
    assert_eq!(
        expand_node(
            &n,
            &Translation {
                lod: 2,
                t: [1, 0, 0]
            },
            &p
        ),
        Err(TranslateError::BoxOutsideScene {
            axis: Axis::X,
            lo: 48,
            hi: 80,
            limit: 64
        })
    );
    // A box ending exactly on the scene boundary is inside.
    let n = NodeBox {
        addr: v(1, 0, 0, 0),
        lo: [0, 0, 0],
        hi: [1, 0, 0],
    };
    assert_eq!(
        expand_node(
            &n,
            &Translation {
                lod: 2,
                t: [3, 0, 0]
            },
            &p
        )
        .unwrap()
        .len(),
        1
    );
    let bad = NodeBox {
        addr: v(1, 0, 0, 0),
        lo: [2, 0, 0],
        hi: [1, 0, 0],
    };
    assert!(matches!(
        expand_node(&bad, &Translation::zero(2), &p),
        Err(TranslateError::InvalidBox { axis: Axis::X, .. })
    ));
}

fn boxed_case() -> impl Strategy<Value = (Params, NodeBox, Translation)> {
    (2u8..=12, 0u8..=6)
        .prop_flat_map(|(dmax, q)| (Just(dmax), Just(q), 0u8..=dmax, 0u8..=dmax))
        .prop_flat_map(|(dmax, q, d, l)| {
            let n = 1u32 << d;
            let cells = 1u32 << q;
            let bound = (0..cells, 0..cells).prop_map(|(a, b)| (a.min(b), a.max(b)));
            let m = (1i64 << l) - 1;
            // Mostly small moves, which keep the box in the scene and split it.
            let t = prop_oneof![3 => -m.min(3)..=m.min(3), 1 => -m..=m];
            (
                Just(Params::new(dmax, q, 16, 2).unwrap()),
                (Just(d), 0..n, 0..n, 0..n),
                [bound.clone(), bound.clone(), bound],
                Just(l),
                [t.clone(), t.clone(), t],
            )
        })
        .prop_map(|(p, (d, x, y, z), b, l, t)| {
            let node = NodeBox {
                addr: VoxelAddr::new(d, x, y, z),
                lo: b.map(|(lo, _)| lo),
                hi: b.map(|(_, hi)| hi),
            };
            (p, node, Translation { lod: l, t })
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 5000, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn copies_cover_the_moved_box_tightly((p, n, t) in boxed_case()) {
        let out = match expand_node(&n, &t, &p) {
            Ok(o) => o,
            Err(TranslateError::BoxOutsideScene { .. }) | Err(TranslateError::NodeOutsideScene { .. }) => return Ok(()),
            Err(e) => return Err(TestCaseError::fail(format!("unexpected {e}"))),
        };
        prop_assert!((1..=8).contains(&out.len()));
        for a in Axis::ALL {
            let (lo, hi) = n.fine_interval(a, &p).unwrap();
            let o = golden::translate::expand::fine_offset(&t, a, &p).unwrap();
            let (lo, hi) = (lo + o, hi + o);
            // Union of the copies' intervals on this axis contains the moved box ...
            let cmin = out.iter().map(|c| c.fine_interval(a, &p).unwrap().0).min().unwrap();
            let cmax = out.iter().map(|c| c.fine_interval(a, &p).unwrap().1).max().unwrap();
            prop_assert!(cmin <= lo && hi <= cmax);
            for c in &out {
                prop_assert!(c.validate(&p).is_ok());
                prop_assert_eq!(c.addr.lod, n.addr.lod);
                let (clo, chi) = c.fine_interval(a, &p).unwrap();
                // ... each copy overlaps it with positive width ...
                prop_assert!(clo < hi && lo < chi);
                // ... and is outward by less than one cell on each side.
                let cell = 1i128 << (p.max_lod - n.addr.lod);
                let vs = cell << p.quant_bits;
                let v0 = [c.addr.x, c.addr.y, c.addr.z][a.index()] as i128 * vs;
                prop_assert!(clo > lo.max(v0) - cell && chi < hi.min(v0 + vs) + cell);
            }
        }
        if n.addr.lod >= t.lod {
            prop_assert_eq!(out.len(), 1);
            prop_assert_eq!(Ok(out[0].addr), translate_node(n.addr, &t, &p));
            prop_assert_eq!((out[0].lo, out[0].hi), (n.lo, n.hi));
        }
        let cost = expansion_cost(&[n], &t, &p).unwrap();
        prop_assert_eq!(cost.added, out.len() as u64 - 1);
    }
}
