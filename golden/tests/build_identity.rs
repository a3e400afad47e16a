//! The optimized builder is bit-identical to the frozen reference builder
//! (`support/reference_builder.rs`, a copy of the builder before the speed
//! work): same nodes, refs, prims, roots and top LOD on meshes, generated
//! scenes and random soups at many (D, Q); and the clip kernel returns the
//! same bits as the reference clip on random and awkward inputs.

#[path = "support/reference_builder.rs"]
mod reference_builder;

use glam::{DVec3, Vec3};
use golden::build::{build, build_grid_triangles, build_parallel, BuildError, GridMap};
use golden::geom::{clip_triangle_to_box, triangle_overlaps_box};
use golden::mesh::Mesh;
use golden::scenes::{self, SplitMix64};
use golden::store::Hierarchy;
use golden::Params;
use proptest::prelude::*;

fn assert_same(new: &Hierarchy, old: &Hierarchy, what: &str) {
    assert_eq!(new.top_lod, old.top_lod, "{what}: top_lod");
    assert_eq!(new.root_count, old.root_count, "{what}: root_count");
    assert_eq!(new.nodes.len(), old.nodes.len(), "{what}: node count");
    if let Some(i) = (0..new.nodes.len()).find(|&i| new.nodes[i] != old.nodes[i]) {
        panic!(
            "{what}: node {i} differs: {:?} vs reference {:?}",
            new.nodes[i], old.nodes[i]
        );
    }
    assert!(new.refs == old.refs, "{what}: refs differ");
    assert!(new.prims == old.prims, "{what}: prims differ");
    assert_eq!(new.id, old.id, "{what}: id");
    assert_eq!(new.params, old.params, "{what}: params");
}

fn same_on_mesh(name: &str, mesh: &Mesh, dq: &[(u8, u8)]) {
    let (lo, hi) = mesh.bounds();
    for &(d, q) in dq {
        let p = Params::new(d, q, 24, 4).unwrap();
        let grid = GridMap::fit(lo, hi, &p);
        let new = build(mesh, &grid, &p, 1).unwrap();
        let old = reference_builder::build(mesh, &grid, &p, 1).unwrap();
        assert_same(&new, &old, &format!("{name} D={d} Q={q}"));
    }
}

const DQ: [(u8, u8); 9] = [
    (1, 0),
    (4, 3),
    (8, 0),
    (8, 8),
    (12, 4),
    (16, 8),
    (16, 16),
    (24, 5),
    (31, 16),
];

#[test]
fn bunny_and_teapot_match_the_reference() {
    for name in ["bunny.obj", "teapot.obj"] {
        let mesh = Mesh::load(&scenes::shared_mesh_path(name)).expect(name);
        same_on_mesh(name, &mesh, &DQ);
    }
}

#[test]
fn generated_scenes_match_the_reference() {
    same_on_mesh("terrain", &scenes::terrain(40, 3), &DQ);
    same_on_mesh("slivers", &scenes::slivers(400, 4), &DQ);
    same_on_mesh("axis_aligned", &scenes::axis_aligned(400, 5), &DQ);
    same_on_mesh("random_soup", &scenes::random_soup(600, 0.05, 6), &DQ);
    same_on_mesh("hard_cases", &scenes::hard_cases(150, 7), &DQ);
    let mut mix = scenes::sphere(Vec3::splat(0.5), 0.4, 12, 24);
    scenes::append(&mut mix, &scenes::torus(Vec3::splat(0.5), 0.3, 0.05, 16, 8));
    scenes::append(&mut mix, &scenes::box_mesh(Vec3::ZERO, Vec3::ONE));
    same_on_mesh("sphere+torus+box", &mix, &DQ);
}

/// The parallel build on 2 and 3 threads gives the reference's hierarchy on
/// meshes of several placement chunks, and the error of the lowest bad
/// triangle when two chunks hold one.
#[test]
fn parallel_build_matches_the_reference() {
    let mut mesh = scenes::terrain(110, 8); // 24,200 triangles: 3 chunks
    scenes::append(&mut mesh, &scenes::architecture(1, 2));
    scenes::append(&mut mesh, &scenes::slivers(3000, 9));
    let (lo, hi) = mesh.bounds();
    for threads in [2, 3] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        for (d, q) in [(8, 0), (16, 8), (24, 5)] {
            let p = Params::new(d, q, 24, 4).unwrap();
            let grid = GridMap::fit(lo, hi, &p);
            let par = pool
                .install(|| build_parallel(&mesh, &grid, &p, 2))
                .unwrap();
            let old = reference_builder::build(&mesh, &grid, &p, 2).unwrap();
            assert_same(&par, &old, &format!("{threads} threads D={d} Q={q}"));
        }
        let mut bad = mesh.clone();
        bad.triangles[20_000][1] = u32::MAX;
        bad.triangles[9_000][2] = u32::MAX;
        let p = Params::default();
        let grid = GridMap::fit(lo, hi, &p);
        let err = pool
            .install(|| build_parallel(&bad, &grid, &p, 0))
            .unwrap_err();
        assert_eq!(err, build(&bad, &grid, &p, 0).unwrap_err());
        assert!(
            matches!(
                err,
                BuildError::BadVertexIndex {
                    triangle: 9_000,
                    corner: 2,
                    ..
                }
            ),
            "{err:?}"
        );
    }
}

/// Grid-space soups of awkward triangles: on voxel planes, long and thin,
/// tiny, degenerate, touching the scene's faces.
fn awkward_soup(n: usize, seed: u64, edge: f64) -> Vec<[DVec3; 3]> {
    let mut rng = SplitMix64::new(seed);
    let point = |rng: &mut SplitMix64| {
        let mut p = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * edge;
        // Often snap a coordinate to a voxel plane of some LOD.
        for a in 0..3 {
            if rng.below(3) == 0 {
                let step = edge / (1u64 << rng.below(8)) as f64;
                p[a] = (p[a] / step).round() * step;
            }
        }
        p
    };
    (0..n)
        .map(|_| {
            let a = point(&mut rng);
            let kind = rng.below(5);
            let near = |rng: &mut SplitMix64, s: f64| {
                (a + DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * s)
                    .clamp(DVec3::ZERO, DVec3::splat(edge))
            };
            match kind {
                0 => [a, point(&mut rng), point(&mut rng)],
                1 => {
                    let b = point(&mut rng);
                    let w = 10f64.powf(-1.0 - 6.0 * rng.next_f64());
                    let side = (b - a).any_orthonormal_vector() * (b - a).length() * w;
                    [
                        a,
                        b,
                        ((a + b) * 0.5 + side).clamp(DVec3::ZERO, DVec3::splat(edge)),
                    ]
                }
                2 => {
                    let s = edge * 10f64.powf(-6.0 * rng.next_f64());
                    [a, near(&mut rng, s), near(&mut rng, s)]
                }
                3 => {
                    let b = point(&mut rng);
                    [a, b, if rng.below(2) == 0 { a } else { (a + b) * 0.5 }]
                }
                _ => {
                    let s = edge / 16.0;
                    [a, near(&mut rng, s), near(&mut rng, s)]
                }
            }
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn random_soups_match_the_reference(
        d in prop_oneof![Just(1u8), 2u8..=20, Just(31u8)],
        q in 0u8..=16,
        n in 1usize..60,
        seed in any::<u64>(),
    ) {
        let p = Params::new(d, q, 24, 4).unwrap();
        let tris = awkward_soup(n, seed, p.scene_edge() as f64);
        let new = build_grid_triangles(&tris, &p, 2).unwrap();
        let old = reference_builder::build_grid_triangles(&tris, &p, 2).unwrap();
        assert_same(&new, &old, &format!("soup D={d} Q={q} n={n} seed={seed}"));
    }
}

/// Coordinates on a coarse lattice (touching and on-plane cases), mixed
/// with arbitrary values and large offsets.
fn coord() -> impl Strategy<Value = f64> {
    prop_oneof![
        (-8i32..=8).prop_map(|k| k as f64 * 0.25),
        -2.0f64..2.0,
        (0u32..64, 0.0f64..1.0).prop_map(|(k, f)| k as f64 * 1024.0 + f),
    ]
}

fn point() -> impl Strategy<Value = DVec3> {
    (coord(), coord(), coord()).prop_map(|(x, y, z)| DVec3::new(x, y, z))
}

fn same_bits(a: Option<(DVec3, DVec3)>, b: Option<(DVec3, DVec3)>) -> bool {
    let bits = |v: DVec3| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()];
    match (a, b) {
        (None, None) => true,
        (Some((l1, h1)), Some((l2, h2))) => bits(l1) == bits(l2) && bits(h1) == bits(h2),
        _ => false,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(5000))]

    #[test]
    fn clip_and_overlap_match_the_reference_bit_for_bit(
        a in point(), b in point(), c in point(), p in point(), q in point(),
        collapse in 0u8..4,
    ) {
        let mut tri = [a, b, c];
        if collapse == 1 { tri[2] = tri[1]; }
        if collapse == 2 { tri[1] = tri[0]; tri[2] = tri[0]; }
        let (lo, hi) = (p.min(q), p.max(q));
        let new = clip_triangle_to_box(&tri, lo, hi);
        let old = reference_builder::geom::clip::clip_triangle_to_box(&tri, lo, hi);
        prop_assert!(same_bits(new, old), "{tri:?} {lo} {hi}: {new:?} vs {old:?}");
        prop_assert_eq!(
            triangle_overlaps_box(&tri, lo, hi),
            reference_builder::geom::overlap::triangle_overlaps_box(&tri, lo, hi)
        );
    }
}
