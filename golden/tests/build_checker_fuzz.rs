//! The checker never panics and never hangs on a corrupted hierarchy or on
//! wild triangles: it returns a report or an error.

use glam::DVec3;
use golden::build::build_grid_triangles;
use golden::check::{check_built, CheckErrorKind};
use golden::layout::NodeLayout;
use golden::scenes::SplitMix64;
use golden::seed::seeded;
use golden::store::{Hierarchy, NodeRecord};
use golden::Params;
use proptest::prelude::*;

fn base() -> (Hierarchy, Vec<[DVec3; 3]>) {
    let p = Params::new(9, 3, 16, 4).unwrap();
    let mut rng = SplitMix64::new(seeded(5));
    let tris: Vec<[DVec3; 3]> = (0..120)
        .map(|_| {
            let c = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 480.0;
            let mut d = || DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 20.0;
            [c, c + d(), c + d()]
        })
        .collect();
    let h = build_grid_triangles(&tris, &p, 2).unwrap();
    (h, tris)
}

/// Sets field `field` (in layout order) of `n` to `value`, masked to its width.
fn set_field(n: &mut NodeRecord, l: &NodeLayout, field: usize, value: u64) {
    let f = l.fields().nth(field).unwrap();
    let v = value & f.max_value();
    match f.name {
        "leaf" => n.leaf = v == 1,
        "lod" => n.voxel.lod = v as u8,
        "x" => n.voxel.x = v as u32,
        "y" => n.voxel.y = v as u32,
        "z" => n.voxel.z = v as u32,
        "lo_x" => n.lo[0] = v as u16,
        "lo_y" => n.lo[1] = v as u16,
        "lo_z" => n.lo[2] = v as u16,
        "hi_x" => n.hi[0] = v as u16,
        "hi_y" => n.hi[1] = v as u16,
        "hi_z" => n.hi[2] = v as u16,
        "first" => n.first = v as u32,
        "count" => n.count = v as u32,
        other => panic!("unknown field {other}"),
    }
}

fn wild(bits: u64) -> f64 {
    match bits % 8 {
        0 => f64::NAN,
        1 => f64::INFINITY,
        2 => -1.0,
        3 => 1e300,
        4 => 0.0,
        5 => 512.0,
        _ => (bits >> 3) as f64 / (1u64 << 52) as f64 * 512.0,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn corrupted_hierarchies_never_panic(
        edits in prop::collection::vec((0u8..6, any::<u64>(), any::<u64>(), any::<u64>()), 1..5)
    ) {
        let (mut h, mut tris) = base();
        let l = NodeLayout::new(&h.params);
        for (what, a, b, c) in edits {
            match what {
                0 | 1 => {
                    let i = (a % h.nodes.len() as u64) as usize;
                    set_field(&mut h.nodes[i], &l, (b % 13) as usize, c);
                }
                2 => {
                    let i = (a % h.refs.len() as u64) as usize;
                    h.refs[i].hier = (b % 4) as u8;
                    h.refs[i].node = (c % (h.nodes.len() as u64 + 3)) as u32;
                }
                3 => {
                    let i = (a % h.prims.len() as u64) as usize;
                    h.prims[i] = (b % (tris.len() as u64 + 3)) as u32;
                }
                4 => {
                    h.root_count = (a % 5) as u32;
                    h.top_lod = (b % 12) as u8;
                }
                _ => {
                    let i = (a % tris.len() as u64) as usize;
                    tris[i][(b % 3) as usize][(c % 3) as usize] = wild(c / 3);
                }
            }
        }
        let _ = check_built(&h, &tris); // must return, Ok or Err
    }
}

#[test]
fn a_triangle_far_larger_than_its_leaf_lod_is_refused_quickly() {
    // Q = 0: leaf boxes are whole voxels, so only the coverage check can see it.
    let p = Params::new(16, 0, 24, 4).unwrap();
    let small = |c: f64| {
        [
            DVec3::splat(c),
            DVec3::splat(c) + DVec3::X * 0.5,
            DVec3::splat(c) + DVec3::Y * 0.5,
        ]
    };
    let mut tris = vec![small(100.25), small(30000.25)];
    let h = build_grid_triangles(&tris, &p, 0).unwrap();
    check_built(&h, &tris).unwrap();
    // The same leaf now "holds" a triangle spanning the scene.
    tris[0] = [
        DVec3::splat(100.25),
        DVec3::new(65000.0, 100.25, 100.25),
        DVec3::new(100.25, 65000.0, 65000.0),
    ];
    let e = check_built(&h, &tris).unwrap_err();
    assert!(
        matches!(
            e.kind,
            CheckErrorKind::PrimSpansTooManyVoxels {
                prim: 0,
                lod: 16,
                ..
            }
        ),
        "{e}"
    );
}
