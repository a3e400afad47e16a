//! The builder's rules of SPEC.md section 4, re-derived independently here
//! (LOD from logarithms, voxels from a dense point sampling) and compared.

use glam::DVec3;
use golden::build::build_grid_triangles;
use golden::check::check_built;
use golden::scenes::SplitMix64;
use golden::seed::seeded;
use golden::store::Hierarchy;
use golden::{Params, VoxelAddr};

/// SPEC 4.2 written with floating logarithms: base = D - ceil(log2(ext)),
/// sliver = clamp(floor(log2(r)) - 1, 0, 3) with r = L^2 / (2A), the sum
/// clamped to 1..=D.
fn spec_lod(t: &[DVec3; 3], d: u8) -> u8 {
    let lo = t[0].min(t[1]).min(t[2]);
    let hi = t[0].max(t[1]).max(t[2]);
    let ext = (hi - lo).max_element();
    let base = if ext <= 1.0 {
        d as i32
    } else {
        (d as i32 - ext.log2().ceil() as i32).max(0)
    };
    let l = [t[1] - t[0], t[2] - t[1], t[0] - t[2]]
        .map(|e| e.length())
        .into_iter()
        .fold(0.0, f64::max);
    let area2 = (t[1] - t[0]).cross(t[2] - t[1]).length();
    let sliver = if l == 0.0 {
        0
    } else if area2 == 0.0 {
        3
    } else {
        ((l * l / area2).log2().floor() as i32 - 1).clamp(0, 3)
    };
    (base + sliver).clamp(1, d as i32) as u8
}

/// The LOD and voxels of the leaves holding each primitive.
fn leaves_of_prims(h: &Hierarchy, n: usize) -> Vec<Vec<VoxelAddr>> {
    let mut out = vec![Vec::new(); n];
    for node in h.nodes.iter().filter(|n| n.leaf) {
        for &t in h.prims_of(node) {
            out[t as usize].push(node.voxel);
        }
    }
    out
}

fn random_triangles(seed: u64, n: usize, edge: f64) -> Vec<[DVec3; 3]> {
    let mut rng = SplitMix64::new(seeded(seed));
    let mut p =
        |s: f64, c: DVec3| c + DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * s;
    (0..n)
        .map(|i| {
            let size = edge * 0.3f64.powi((i % 12) as i32);
            let c = p(edge - size, DVec3::ZERO);
            [p(size, c), p(size, c), p(size, c)]
        })
        .collect()
}

#[test]
fn leaf_lod_follows_the_spec_formula() {
    for d in [6u8, 16, 31] {
        let p = Params::new(d, 6, 24, 4).unwrap();
        let tris = random_triangles(d as u64, 400, p.scene_edge() as f64);
        let h = build_grid_triangles(&tris, &p, 0).unwrap();
        let holders = leaves_of_prims(&h, tris.len());
        for (i, t) in tris.iter().enumerate() {
            assert!(!holders[i].is_empty(), "triangle {i} in no leaf");
            let lod = holders[i][0].lod;
            assert!(holders[i].iter().all(|v| v.lod == lod));
            // The log formula and the exact one agree except within rounding of
            // an exact power of two, which random inputs do not hit.
            assert_eq!(lod, spec_lod(t, d), "D={d} triangle {i}: {t:?}");
        }
    }
}

/// Points sampled on the triangle: every sample's voxel (at the triangle's
/// LOD) must hold it, and the triangle is in no voxel it does not reach.
#[test]
fn leaves_are_the_voxels_the_triangle_touches() {
    let p = Params::new(12, 4, 24, 4).unwrap();
    let edge = p.scene_edge() as f64;
    let mut rng = SplitMix64::new(seeded(77));
    // Long thin diagonal slivers: their AABB meets many voxels they miss.
    let tris: Vec<[DVec3; 3]> = (0..50)
        .map(|_| {
            let a = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * edge * 0.5
                + DVec3::splat(10.0);
            let dir = DVec3::new(1.0, 0.8 + 0.4 * rng.next_f64(), 0.6 + 0.8 * rng.next_f64());
            let b = a + dir * (100.0 + 400.0 * rng.next_f64());
            [a, b, a + dir.any_orthonormal_vector() * 2.0]
        })
        .collect();
    let h = build_grid_triangles(&tris, &p, 0).unwrap();
    check_built(&h, &tris).unwrap();
    let holders = leaves_of_prims(&h, tris.len());
    let mut fewer_than_aabb = 0;
    for (i, t) in tris.iter().enumerate() {
        let lod = holders[i][0].lod;
        let e = p.voxel_edge(lod) as f64;
        let voxel_at = |q: DVec3| {
            let c = (q / e).floor().as_uvec3();
            VoxelAddr::new(lod, c.x, c.y, c.z)
        };
        // Interior samples (off voxel faces with probability 1) must be covered.
        for _ in 0..2000 {
            let (mut u, mut v) = (rng.next_f64(), rng.next_f64());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            let q = t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v;
            assert!(
                holders[i].contains(&voxel_at(q)),
                "triangle {i}: sample {q} uncovered"
            );
        }
        let lo = t[0].min(t[1]).min(t[2]);
        let hi = t[0].max(t[1]).max(t[2]);
        let span = ((hi / e).floor() - (lo / e).floor() + DVec3::ONE).element_product() as usize;
        assert!(holders[i].len() <= span);
        if holders[i].len() < span {
            fewer_than_aabb += 1;
        }
    }
    assert!(
        fewer_than_aabb > 25,
        "the overlap test rejects AABB-only voxels ({fewer_than_aabb}/50)"
    );
}

#[test]
fn q0_never_keeps_a_root_at_lod_0() {
    // With Q = 0 a LOD-0 box is the whole scene: the top rule's exception applies.
    let p = Params::new(8, 0, 24, 4).unwrap();
    let tris = [
        [
            DVec3::splat(1.0),
            DVec3::new(2.0, 1.0, 1.0),
            DVec3::new(1.0, 2.0, 1.0),
        ],
        [
            DVec3::splat(200.0),
            DVec3::new(201.0, 200.0, 200.0),
            DVec3::new(200.0, 201.0, 200.0),
        ],
    ];
    let h = build_grid_triangles(&tris, &p, 0).unwrap();
    assert_eq!(h.top_lod, 1);
    assert_eq!(h.root_count, 2);
    assert!(h.roots().iter().all(|r| r.voxel.lod == 1));
    check_built(&h, &tris).unwrap();
}

#[test]
fn a_voxel_may_hold_a_leaf_and_an_inner_node() {
    // A big triangle (shallow LOD) and a small one inside the same voxel.
    let p = Params::new(10, 4, 24, 4).unwrap();
    let big = [
        DVec3::new(1.0, 1.0, 1.0),
        DVec3::new(120.0, 2.0, 1.0),
        DVec3::new(2.0, 120.0, 3.0),
    ];
    let small = [
        DVec3::new(10.0, 10.0, 10.0),
        DVec3::new(11.0, 10.0, 10.0),
        DVec3::new(10.0, 11.0, 10.5),
    ];
    let h = build_grid_triangles(&[big, small], &p, 0).unwrap();
    check_built(&h, &[big, small]).unwrap();
    let leaf_big = h
        .nodes
        .iter()
        .find(|n| n.leaf && h.prims_of(n).contains(&0))
        .unwrap();
    let twin = h
        .nodes
        .iter()
        .position(|n| !n.leaf && n.voxel == leaf_big.voxel)
        .expect("an inner node at the big triangle's leaf voxel");
    let leaf_at = h.nodes.iter().position(|n| n == leaf_big).unwrap();
    assert_eq!(
        leaf_at,
        twin + 1,
        "inner node first, then the leaf (SPEC 4.6)"
    );
}
