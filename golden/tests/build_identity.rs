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

/// Hand-placed triangles for every branch of the placement: tiny ones
/// inside one voxel (no clip), tiny ones across a voxel face, edge or
/// corner (clip, mostly no plane crossed), triangles lying in voxel faces
/// and segments along voxel edges (planes met exactly), a vertex on a
/// corner, huge thin ones across the scene (many planes crossed), points,
/// segments, repeated vertices, and `-0.0` and `2^D` coordinates (the
/// scene's faces), at LODs from coarse to the deepest.
fn branch_triangles(p: &Params, seed: u64) -> Vec<[DVec3; 3]> {
    let d = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let s = p.scene_edge() as f64;
    let mut rng = SplitMix64::new(seed);
    let mut out = Vec::new();
    for level in [
        1u8,
        2,
        p.max_lod / 2,
        p.max_lod.saturating_sub(1),
        p.max_lod,
    ] {
        let e = p.voxel_edge(level.clamp(1, p.max_lod)) as f64;
        // A voxel corner away from the scene's faces when there is one.
        let c = d(e, e, e).min(DVec3::splat(s / 2.0));
        let tiny = e / 64.0;
        let j = |rng: &mut SplitMix64| rng.next_f64() * tiny;
        let inside = c + DVec3::splat(e / 4.0);
        out.push([
            inside,
            inside + d(tiny, 0.0, j(&mut rng)),
            inside + d(0.0, tiny, 0.0),
        ]);
        // Across a face, an edge and the corner of the voxel at c.
        out.push([
            c + d(-tiny, e / 4.0, e / 4.0),
            c + d(tiny, e / 4.0, e / 4.0),
            c + d(0.0, e / 4.0 + tiny, e / 4.0),
        ]);
        out.push([
            c + d(-tiny, -tiny, e / 4.0),
            c + d(tiny, tiny, e / 4.0),
            c + d(tiny, -tiny, e / 4.0 + j(&mut rng)),
        ]);
        out.push([
            c - DVec3::splat(tiny),
            c + DVec3::splat(tiny),
            c + d(tiny, -tiny, tiny),
        ]);
        // In the face z = c.z, and a segment along the voxel edge x = c.x, y = c.y.
        out.push([
            c + d(-e / 2.0, -e / 3.0, 0.0),
            c + d(e * 1.5, 0.0, 0.0),
            c + d(0.0, e * 1.25, 0.0),
        ]);
        out.push([
            c + d(0.0, 0.0, -e / 2.0),
            c + d(0.0, 0.0, e * 1.5),
            c + d(0.0, 0.0, e / 3.0),
        ]);
        // A vertex exactly on the corner, the rest outside the voxel.
        out.push([
            c,
            c - d(e / 2.0, e / 8.0, 0.0),
            c - d(e / 8.0, e / 2.0, e / 4.0),
        ]);
        // Points and a repeated-vertex segment on the corner and inside.
        out.push([c; 3]);
        out.push([inside; 3]);
        out.push([c, c + d(e, e / 2.0, e / 4.0), c]);
    }
    // Huge thin ones from face to face, through many voxel planes.
    for k in 0..4 {
        let w = s * 10f64.powi(-2 - k);
        out.push([d(0.0, 0.0, 0.0), d(s, s, s), d(s, s - w, s)]);
        out.push([
            d(0.0, s / 3.0, s / 2.0),
            d(s, s / 3.0 + w, s / 2.0),
            d(s, s / 3.0, s / 2.0 + w),
        ]);
        out.push([d(s, 0.0, 0.0), d(0.0, s, w), d(w, s, 0.0)]);
    }
    // The scene's faces, with negative zeros (valid grid coordinates).
    out.push([d(-0.0, 0.0, -0.0), d(s, -0.0, 0.0), d(-0.0, s, -0.0)]);
    out.push([
        d(-0.0, -0.0, -0.0),
        d(1.0, -0.0, 0.5).min(DVec3::splat(s)),
        d(-0.0, 0.5, 1.0).min(DVec3::splat(s)),
    ]);
    out.push([d(s, s, s), d(s, s / 2.0, s), d(s / 2.0, s, s)]);
    // Into the scene cube where a coarse level's offsets reach past it.
    out.iter()
        .map(|t| t.map(|v| v.clamp(DVec3::ZERO, DVec3::splat(s))))
        .collect()
}

/// Every leaf entry of the placement (the only input of the sort and the
/// levels) equals the frozen reference's, on [`branch_triangles`] at many
/// (D, Q), and so do the whole hierarchies.
#[test]
fn placement_branches_match_the_reference_entry_for_entry() {
    for (d, q) in [
        (1, 0),
        (2, 3),
        (5, 8),
        (8, 0),
        (12, 16),
        (16, 8),
        (19, 5),
        (20, 4),
        (31, 16),
    ] {
        let p = Params::new(d, q, 24, 4).unwrap();
        let tris = branch_triangles(&p, d as u64 * 31 + q as u64);
        for (i, t) in tris.iter().enumerate() {
            let what = format!("D={d} Q={q} triangle {i} {t:?}");
            golden::build::check_grid_triangle(t, i, &p).expect(&what);
            let mut new = Vec::new();
            golden::build::leaves::place_triangle(t, i as u32, &p, &mut new);
            let mut old = Vec::new();
            reference_builder::leaves::place_triangle(t, i as u32, &p, &mut old);
            assert_eq!(new.len(), old.len(), "{what}: entry count");
            for (n, o) in new.iter().zip(&old) {
                assert_eq!(
                    (n.key, n.prim, n.lo, n.hi),
                    (o.key, o.prim, o.lo, o.hi),
                    "{what}"
                );
            }
        }
        let new = build_grid_triangles(&tris, &p, 1).unwrap();
        let old = reference_builder::build_grid_triangles(&tris, &p, 1).unwrap();
        assert_same(&new, &old, &format!("branches D={d} Q={q}"));
    }
}

/// The clip's finite path returns the reference's bits, zero signs
/// included, where `-0.0` meets `0.0` (the one place its `min`/`max` could
/// pick another operand than `f64::min`/`max`).
#[test]
fn clip_keeps_the_reference_zero_signs() {
    let d = DVec3::new;
    let zs = [0.0, -0.0];
    for &a in &zs {
        for &b in &zs {
            let tri = [d(a, b, 0.5), d(1.0, a, b), d(b, 1.0, a)];
            for (lo, hi) in [
                (d(b, a, a), d(1.0, 1.0, 1.0)),
                (d(-1.0, -1.0, -1.0), d(a, b, a)),
                (d(a, a, b), d(b, b, a)),
                (d(-0.5, b, -0.5), d(0.5, 0.5, 0.5)),
            ] {
                let new = clip_triangle_to_box(&tri, lo, hi);
                let old = reference_builder::geom::clip::clip_triangle_to_box(&tri, lo, hi);
                assert!(same_bits(new, old), "{tri:?} {lo} {hi}: {new:?} vs {old:?}");
            }
            // The triangle's AABB ends at one zero where the box's starts or
            // ends at the other: the clipped box's face there is a `min` or
            // `max` of the two zeros.
            let below = [d(a, 0.2, 0.3), d(-1.0, 0.5, 0.5), d(-0.5, 0.9, 0.1)];
            let above = [d(a, 0.2, 0.3), d(1.0, 0.5, 0.5), d(0.5, 0.9, 0.1)];
            for (tri, lo, hi) in [
                (below, d(-2.0, 0.0, 0.0), d(b, 1.0, 1.0)),
                (above, d(b, 0.0, 0.0), d(2.0, 1.0, 1.0)),
            ] {
                let new = clip_triangle_to_box(&tri, lo, hi);
                let old = reference_builder::geom::clip::clip_triangle_to_box(&tri, lo, hi);
                assert!(same_bits(new, old), "{tri:?} {lo} {hi}: {new:?} vs {old:?}");
            }
        }
    }
}
