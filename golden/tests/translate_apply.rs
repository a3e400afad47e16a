//! Apply (aligned) and the extents rule, checked against wide-integer
//! arithmetic and against each other.

use golden::translate::{
    check_scene_extents, translate_node, Axis, TranslateError, Translation, VoxelRange,
};
use golden::{Params, VoxelAddr};
use proptest::prelude::*;

#[test]
fn d31_extremes_move_exactly_and_never_wrap() {
    let p = Params::new(31, 16, 32, 8).unwrap();
    let max = (1u32 << 31) - 1;
    let far = VoxelAddr::new(31, max, max, 0);
    let back = Translation {
        lod: 31,
        t: [-(max as i64), -(max as i64), max as i64],
    };
    assert_eq!(
        translate_node(far, &back, &p),
        Ok(VoxelAddr::new(31, 0, 0, max))
    );
    // One voxel further: 2^31 is reported as it is, not wrapped to 0.
    let over = Translation {
        lod: 31,
        t: [1, 0, 0],
    };
    assert_eq!(
        translate_node(far, &over, &p),
        Err(TranslateError::NodeOutsideScene {
            axis: Axis::X,
            value: 1 << 31,
            lod: 31
        })
    );
    let under = Translation {
        lod: 31,
        t: [0, 0, -1],
    };
    assert_eq!(
        translate_node(far, &under, &p),
        Err(TranslateError::NodeOutsideScene {
            axis: Axis::Z,
            value: -1,
            lod: 31
        })
    );
    // L = 0: one LOD-0 voxel is 2^31 LOD-31 voxels; any nonzero t leaves.
    let coarse = Translation {
        lod: 0,
        t: [0, -1, 0],
    };
    assert_eq!(
        translate_node(VoxelAddr::new(31, 5, max, 5), &coarse, &p),
        Err(TranslateError::NodeOutsideScene {
            axis: Axis::Y,
            value: max as i64 - (1i64 << 31),
            lod: 31
        })
    );
    // The largest field value at L = 0 shifted by 31 does not overflow.
    let huge = Translation {
        lod: 0,
        t: [-(max as i64), 0, 0],
    };
    assert_eq!(
        translate_node(VoxelAddr::new(31, max, 0, 0), &huge, &p),
        Err(TranslateError::NodeOutsideScene {
            axis: Axis::X,
            value: max as i64 - ((max as i64) << 31),
            lod: 31
        })
    );
}

#[test]
fn nodes_above_the_level_and_bad_inputs_are_refused() {
    let p = Params::new(12, 4, 16, 2).unwrap();
    let t = Translation {
        lod: 6,
        t: [1, 1, 1],
    };
    assert_eq!(
        translate_node(VoxelAddr::new(5, 0, 0, 0), &t, &p),
        Err(TranslateError::AboveTranslationLevel {
            node_lod: 5,
            translation_lod: 6
        })
    );
    assert!(matches!(
        translate_node(VoxelAddr::new(6, 64, 0, 0), &t, &p),
        Err(TranslateError::InvalidNode { .. })
    ));
    let wide = Translation {
        lod: 6,
        t: [1 << 12, 0, 0],
    };
    assert!(matches!(
        translate_node(VoxelAddr::new(6, 0, 0, 0), &wide, &p),
        Err(TranslateError::TranslationOutOfField {
            axis: Axis::X,
            field_bits: 13,
            ..
        })
    ));
}

fn node_at(d: u8) -> impl Strategy<Value = VoxelAddr> {
    let n = 1u32 << d;
    (0..n, 0..n, 0..n).prop_map(move |(x, y, z)| VoxelAddr::new(d, x, y, z))
}

/// A grid depth, a translation level, a node at or below it, and a
/// translation in the field.
fn case() -> impl Strategy<Value = (Params, VoxelAddr, Translation)> {
    (1u8..=31)
        .prop_flat_map(|dmax| (Just(dmax), 0u8..=dmax))
        .prop_flat_map(|(dmax, l)| (Just(dmax), Just(l), l..=dmax))
        .prop_flat_map(|(dmax, l, d)| {
            let m = (1i64 << dmax) - 1;
            // Mostly small moves that stay in, some anywhere in the field.
            let near = (1i64 << l).min(m);
            let comp = prop_oneof![-near..=near, -m..=m];
            (
                Just(dmax),
                node_at(d),
                Just(l),
                [comp.clone(), comp.clone(), comp],
            )
        })
        .prop_map(|(dmax, n, l, t)| {
            (
                Params::new(dmax, 4, 16, 2).unwrap(),
                n,
                Translation { lod: l, t },
            )
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 20000, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn matches_wide_arithmetic((p, n, t) in case()) {
        let s = n.lod - t.lod;
        let c = [n.x, n.y, n.z];
        let want: Vec<i128> = (0..3).map(|a| c[a] as i128 + t.t[a] as i128 * (1i128 << s)).collect();
        let lim = 1i128 << n.lod;
        match translate_node(n, &t, &p) {
            Ok(m) => {
                prop_assert_eq!(m.lod, n.lod);
                prop_assert_eq!([m.x as i128, m.y as i128, m.z as i128].to_vec(), want);
            }
            Err(TranslateError::NodeOutsideScene { axis, value, lod }) => {
                prop_assert_eq!(lod, n.lod);
                // The first axis out of range, with its true value.
                let first = (0..3).find(|&a| want[a] < 0 || want[a] >= lim).unwrap();
                prop_assert_eq!(axis.index(), first);
                prop_assert_eq!(value as i128, want[first]);
            }
            Err(e) => prop_assert!(false, "unexpected {e}"),
        }
    }

    #[test]
    fn extents_rule_passes_exactly_when_every_node_moves((p, n, t) in case(), extra in prop::collection::vec((0u32..8, 0u32..8, 0u32..8), 0..6)) {
        // A small hierarchy: n and a few neighbours at the same LOD.
        let span = 1u32 << n.lod;
        let mut nodes = vec![n];
        for (dx, dy, dz) in extra {
            nodes.push(VoxelAddr::new(n.lod, (n.x + dx).min(span - 1), (n.y + dy).min(span - 1), (n.z + dz).min(span - 1)));
        }
        let ext = VoxelRange::of_nodes(&nodes, t.lod, &p).unwrap();
        let rule = check_scene_extents(&ext, &t, &p).is_ok();
        let all_move = nodes.iter().all(|m| translate_node(*m, &t, &p).is_ok());
        prop_assert_eq!(rule, all_move);
    }

    #[test]
    fn aligned_moves_commute_with_parents((p, n, t) in case()) {
        // Nodes at L have no parent at or below L: nothing to compare.
        if let (true, Ok(m)) = (n.lod > t.lod, translate_node(n, &t, &p)) {
            prop_assert_eq!(translate_node(n.parent().unwrap(), &t, &p), Ok(m.parent().unwrap()));
        }
    }
}
