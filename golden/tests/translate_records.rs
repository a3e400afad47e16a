//! The translation unit on real hierarchies from the builder: aligned moves
//! keep a hierarchy valid (the checker passes on the moved hierarchy over the
//! moved triangles), and the expanding variant's cost per translation level.

use glam::DVec3;
use golden::build::build_grid_triangles;
use golden::check::check_built;
use golden::scenes::sphere;
use golden::store::{node_box_fine, Hierarchy};
use golden::translate::expand::NodeBox;
use golden::translate::{
    determine, hierarchy_expansion_cost, hierarchy_extents, translate_record, Axis, Placement,
};
use golden::Params;

/// A sphere of radius 90 grid units centred at (150, 130, 110) in a D = 12,
/// Q = 4 local grid: small next to the 4096-unit scene, so it has room to move.
fn local_sphere(p: &Params) -> (Hierarchy, Vec<[DVec3; 3]>) {
    let mesh = sphere(glam::Vec3::new(150.0, 130.0, 110.0), 90.0, 12, 16);
    let tris: Vec<[DVec3; 3]> = mesh
        .triangles
        .iter()
        .map(|t| t.map(|i| mesh.vertices[i as usize].as_dvec3()))
        .collect();
    let h = build_grid_triangles(&tris, p, 1).unwrap();
    (h, tris)
}

fn params() -> Params {
    Params::new(12, 4, 24, 4).unwrap()
}

#[test]
fn fine_intervals_agree_with_the_store() {
    let p = params();
    let (h, _) = local_sphere(&p);
    for n in &h.nodes {
        let (lo, hi) = node_box_fine(n, &p);
        let b = NodeBox::from(n);
        for a in Axis::ALL {
            assert_eq!(
                b.fine_interval(a, &p).unwrap(),
                (lo[a.index()] as i128, hi[a.index()] as i128)
            );
        }
    }
}

#[test]
fn an_aligned_move_keeps_the_hierarchy_valid_over_moved_triangles() {
    let p = params();
    let (h, tris) = local_sphere(&p);
    check_built(&h, &tris).expect("the built sphere checks");
    let l = h.top_lod;
    let ext = hierarchy_extents(&h, l).unwrap();
    let d = determine(
        &Placement::binary64([2301.3, 1000.7, 3072.0 - 700.2]),
        l,
        &ext,
        &p,
    )
    .unwrap();
    let t = d.translation;
    let moved = Hierarchy {
        nodes: h
            .nodes
            .iter()
            .map(|n| translate_record(n, &t, &p).unwrap())
            .collect(),
        ..h.clone()
    };
    // Every fine box moved by exactly t 2^(D-L+Q).
    for (a, b) in h.nodes.iter().zip(&moved.nodes) {
        let ((alo, ahi), (blo, bhi)) = (node_box_fine(a, &p), node_box_fine(b, &p));
        for ax in Axis::ALL {
            let o = t.try_grid_offset(ax, &p).unwrap() as i128 * (1 << p.quant_bits);
            let i = ax.index();
            assert_eq!(
                (
                    blo[i] as i128 - alo[i] as i128,
                    bhi[i] as i128 - ahi[i] as i128
                ),
                (o, o)
            );
        }
    }
    let moved_tris: Vec<[DVec3; 3]> = tris
        .iter()
        .map(|tri| {
            tri.map(|v| {
                v + DVec3::new(
                    t.try_grid_offset(Axis::X, &p).unwrap() as f64,
                    t.try_grid_offset(Axis::Y, &p).unwrap() as f64,
                    t.try_grid_offset(Axis::Z, &p).unwrap() as f64,
                )
            })
        })
        .collect();
    let report = check_built(&moved, &moved_tris).expect("the moved sphere checks");
    assert_eq!(report.nodes, h.nodes.len());
}

#[test]
fn expansion_cost_per_translation_level() {
    let p = params();
    let (h, _) = local_sphere(&p);
    let top = h.top_lod;
    let placement = Placement::binary64([1000.3, 517.6, 2049.9]);
    println!(
        "sphere: {} nodes, top LOD {top}; placement (1000.3, 517.6, 2049.9)",
        h.nodes.len()
    );
    println!("  L  t                      nodes after  added");
    let mut last_added = 0;
    for l in top..=p.max_lod {
        let ext = hierarchy_extents(&h, l).unwrap();
        let d = determine(&placement, l, &ext, &p).unwrap();
        let cost = hierarchy_expansion_cost(&h, &d.translation).unwrap();
        println!(
            "  {l:2} {:22} {:11} {:6}",
            format!("{:?}", d.translation.t),
            cost.after,
            cost.added
        );
        assert_eq!(cost.before, h.nodes.len() as u64);
        assert!(cost.after <= 8 * cost.before);
        if l == top {
            assert_eq!(
                cost.added, 0,
                "a translation at the top level never splits a node"
            );
        }
        last_added = cost.added;
    }
    // At grid-unit granularity the fractional-voxel moves split upper nodes.
    assert!(last_added > 0);
    let residual = determine(
        &placement,
        p.max_lod,
        &hierarchy_extents(&h, p.max_lod).unwrap(),
        &p,
    )
    .unwrap()
    .residual;
    assert!(residual.value_f64(Axis::X).abs() <= 0.5);
}
