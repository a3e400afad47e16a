//! The builder over the shared meshes and generated scenes, for Q in {0, 4, 8}
//! and D in {8, 12, 16}: every build passes the checker, and the structure
//! the SPEC promises (store order, top rule) holds.

use glam::DVec3;
use golden::build::{build, build_grid_triangles, BuildError, GridMap};
use golden::check::check_built;
use golden::mesh::Mesh;
use golden::scenes::{self, shared_mesh_path};
use golden::seed::seeded;
use golden::store::{node_box_fine, Hierarchy};
use golden::Params;

fn load(name: &str) -> Mesh {
    let path = shared_mesh_path(name);
    Mesh::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn params(d: u8, q: u8) -> Params {
    Params::new(d, q, 24, 4).unwrap()
}

/// Builds `mesh` fitted to the scene cube and checks it; returns the build.
fn build_and_check(mesh: &Mesh, p: &Params) -> Hierarchy {
    let (lo, hi) = mesh.bounds();
    let grid = GridMap::fit(lo, hi, p);
    let h = build(mesh, &grid, p, 1).unwrap();
    let tris = grid.mesh_to_grid(mesh, p).unwrap();
    let report = check_built(&h, &tris).unwrap_or_else(|e| panic!("{p:?}: {e}"));
    assert_eq!(report.nodes, h.nodes.len());
    assert_eq!(report.prims_reached, mesh.triangles.len());
    assert_store_order(&h);
    h
}

/// SPEC 4.6: nodes by LOD ascending, then Morton, inner before leaf; the
/// children of an inner node a contiguous, Morton-ordered run of refs.
fn assert_store_order(h: &Hierarchy) {
    for w in h.nodes.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        let ka = (a.voxel.lod, a.voxel.morton(), a.leaf);
        let kb = (b.voxel.lod, b.voxel.morton(), b.leaf);
        assert!(ka < kb, "store order broken: {a:?} then {b:?}");
    }
    for n in h.nodes.iter().filter(|n| !n.leaf) {
        let kids = h.children_of(n);
        for w in kids.windows(2) {
            assert_eq!(w[1].node, w[0].node + 1, "children not contiguous");
        }
    }
}

#[test]
fn bunny_and_teapot_pass_the_checker_at_every_q_and_d() {
    for name in ["bunny.obj", "teapot.obj"] {
        let mesh = load(name);
        for d in [8, 12, 16] {
            for q in [0, 4, 8] {
                let h = build_and_check(&mesh, &params(d, q));
                assert!(h.nodes.len() > 1, "{name} D={d} Q={q}");
            }
        }
    }
}

#[test]
fn generated_scenes_pass_the_checker() {
    let meshes = [
        scenes::random_soup(3000, 0.02, seeded(1)),
        scenes::slivers(500, 2),
        scenes::axis_aligned(500, 3),
        scenes::hard_cases(200, 4),
        scenes::terrain(40, 5),
    ];
    for mesh in &meshes {
        for (d, q) in [(8, 0), (12, 4), (16, 8), (20, 16)] {
            build_and_check(mesh, &params(d, q));
        }
    }
}

#[test]
fn builds_are_deterministic() {
    let mesh = scenes::hard_cases(100, 9);
    let p = params(12, 6);
    let (lo, hi) = mesh.bounds();
    let g = GridMap::fit(lo, hi, &p);
    assert_eq!(
        build(&mesh, &g, &p, 2).unwrap(),
        build(&mesh, &g, &p, 2).unwrap()
    );
}

/// The top rule: a single small cluster ends in one root at its own LOD; a
/// scene-filling mesh ends at LOD 1 (the LOD-0 node would cover most of it).
#[test]
fn top_rule() {
    let p = params(10, 4);
    let small = [[
        DVec3::new(100.2, 100.2, 100.2),
        DVec3::new(100.9, 100.3, 100.2),
        DVec3::new(100.4, 100.8, 100.6),
    ]];
    let h = build_grid_triangles(&small, &p, 0).unwrap();
    assert_eq!(h.root_count, 1);
    assert_eq!(h.top_lod, 10, "one leaf voxel: the leaf is the root");
    assert_eq!(h.nodes.len(), 1);
    assert!(h.nodes[0].leaf);

    // Two triangles in neighbouring voxels of LOD 10 whose parents differ up to LOD 0.
    let e = 1024.0;
    let far = [
        [
            DVec3::splat(1.0),
            DVec3::new(1.5, 1.0, 1.0),
            DVec3::new(1.0, 1.5, 1.0),
        ],
        [
            DVec3::splat(e - 2.0),
            DVec3::new(e - 1.5, e - 2.0, e - 2.0),
            DVec3::new(e - 2.0, e - 1.5, e - 2.0),
        ],
    ];
    let h = build_grid_triangles(&far, &p, 0).unwrap();
    // At LOD 0 one node covers both corners: its box spans the scene, so the top is LOD 1.
    assert_eq!(h.top_lod, 1);
    assert_eq!(h.root_count, 2);
    let tris: Vec<_> = far.to_vec();
    check_built(&h, &tris).unwrap();

    // Both in the low half of the scene on every axis: the LOD-0 node covers at most 1/8.
    let near = [
        [
            DVec3::splat(1.0),
            DVec3::new(1.5, 1.0, 1.0),
            DVec3::new(1.0, 1.5, 1.0),
        ],
        [
            DVec3::splat(300.0),
            DVec3::new(300.5, 300.0, 300.0),
            DVec3::new(300.0, 300.5, 300.0),
        ],
    ];
    let h = build_grid_triangles(&near, &p, 0).unwrap();
    let root = h.nodes[0];
    let (lo, hi) = node_box_fine(&root, &p);
    assert!(h.root_count == 1 && h.top_lod <= 1, "{h:?}");
    assert!(hi[0] - lo[0] <= (p.scene_edge() << p.quant_bits) / 2);
}

#[test]
fn bad_triangles_are_errors_naming_the_triangle() {
    let p = params(8, 4);
    let ok = [
        DVec3::ONE,
        DVec3::new(2.0, 1.0, 1.0),
        DVec3::new(1.0, 2.0, 1.0),
    ];
    let mut out = ok;
    out[2].y = 256.5;
    assert!(matches!(
        build_grid_triangles(&[ok, out], &p, 0),
        Err(BuildError::OutsideScene {
            triangle: 1,
            corner: 2,
            axis: 1,
            ..
        })
    ));
    let mut nan = ok;
    nan[0].z = f64::NAN;
    let e = build_grid_triangles(&[ok, ok, nan], &p, 0).unwrap_err();
    assert_eq!(
        e,
        BuildError::NonFinite {
            triangle: 2,
            corner: 0,
            axis: 2
        }
    );
    assert!(e.to_string().contains("triangle 2"));
    let mut neg = ok;
    neg[1].x = -1e-9;
    assert!(matches!(
        build_grid_triangles(&[neg], &p, 0),
        Err(BuildError::OutsideScene {
            triangle: 0,
            corner: 1,
            axis: 0,
            ..
        })
    ));
    assert_eq!(build_grid_triangles(&[], &p, 0), Err(BuildError::EmptyMesh));
    assert!(matches!(
        build_grid_triangles(&[ok], &p, 16),
        Err(BuildError::HierIdOutOfRange {
            id: 16,
            hier_bits: 4
        })
    ));
    let mesh = Mesh {
        vertices: vec![glam::Vec3::ZERO; 3],
        triangles: vec![[0, 1, 2], [0, 1, 3]],
    };
    let g = GridMap {
        origin: DVec3::ZERO,
        unit: 1.0,
    };
    assert!(matches!(
        build(&mesh, &g, &p, 0),
        Err(BuildError::BadVertexIndex {
            triangle: 1,
            corner: 2,
            vertex: 3,
            ..
        })
    ));
    let g = GridMap {
        origin: DVec3::ZERO,
        unit: 0.0,
    };
    assert!(matches!(
        build(&mesh, &g, &p, 0),
        Err(BuildError::BadGridMap { field: "unit", .. })
    ));
}

#[test]
fn index_overflow_is_an_error() {
    // I = 2: at most 4 nodes, prims and refs.
    let p = Params::new(8, 2, 2, 1).unwrap();
    let tris: Vec<[DVec3; 3]> = (0..4)
        .map(|i| {
            let c = DVec3::splat(10.0 + 50.0 * i as f64);
            [c, c + DVec3::X, c + DVec3::Y]
        })
        .collect();
    assert!(matches!(
        build_grid_triangles(&tris, &p, 0),
        Err(BuildError::IndexOverflow { .. })
    ));
    let five: Vec<_> = tris.iter().cycle().take(5).copied().collect();
    assert!(matches!(
        build_grid_triangles(&five, &p, 0),
        Err(BuildError::IndexOverflow {
            what: "triangle index",
            ..
        })
    ));
}

#[test]
fn grid_fit_keeps_every_vertex_inside_the_scene() {
    let awkward = [
        (
            glam::Vec3::new(-1.000_000_1, 3.0, -7.5),
            glam::Vec3::new(1.0e7, 3.000_001, -7.4),
        ),
        (glam::Vec3::splat(1.0e-30), glam::Vec3::splat(1.0e-30)),
        (
            glam::Vec3::new(-3.0e38, 0.0, 0.0),
            glam::Vec3::new(3.0e38, 1.0, 1.0),
        ),
        (
            glam::Vec3::new(0.1, 0.2, 0.3),
            glam::Vec3::new(0.1, 0.2, 0.3 + 2.0f32.powi(-20)),
        ),
    ];
    for (d, q) in [(1, 0), (16, 8), (31, 16)] {
        let p = params(d, q);
        for (lo, hi) in awkward {
            let mut rng = scenes::SplitMix64::new(seeded(d as u64));
            let mut vertices = vec![lo, hi, glam::Vec3::new(lo.x, hi.y, lo.z)];
            for _ in 0..30 {
                let t = glam::Vec3::new(
                    rng.next_f64() as f32,
                    rng.next_f64() as f32,
                    rng.next_f64() as f32,
                );
                vertices.push((lo + (hi - lo) * t).clamp(lo, hi));
            }
            let triangles = (0..vertices.len() as u32 / 3)
                .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
                .collect();
            let mesh = Mesh {
                vertices,
                triangles,
            };
            let g = GridMap::fit(lo, hi, &p);
            assert!(g.unit > 0.0 && g.unit.log2().fract() == 0.0, "{g:?}");
            let h = build(&mesh, &g, &p, 0).unwrap_or_else(|e| panic!("D={d} {lo} {hi}: {e}"));
            check_built(&h, &g.mesh_to_grid(&mesh, &p).unwrap()).unwrap();
        }
    }
}

#[test]
fn bunny_at_extreme_parameters() {
    let mesh = load("bunny.obj");
    for (d, q, i) in [(31, 16, 32), (1, 0, 16), (2, 16, 16)] {
        let p = Params::new(d, q, i, 8).unwrap();
        let h = build_and_check(&mesh, &p);
        assert!(h.top_lod <= d);
    }
}
