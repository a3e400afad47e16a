//! Hierarchy traversal against brute force: same triangle, same t, same
//! barycentrics, bit for bit, for random rays on real and generated meshes.

use golden::build::{build, GridMap};
use golden::mesh::Mesh;
use golden::params::Params;
use golden::scenes::{self, shared_mesh_path};
use golden::seed::seeded;
use golden::trace::{verify_rays, Instance, TraceScene, TraceSummary};

fn load(name: &str) -> Mesh {
    Mesh::load(&shared_mesh_path(name)).unwrap_or_else(|e| panic!("{e}"))
}

fn params(d: u8, q: u8) -> Params {
    Params::new(d, q, 24, 4).unwrap()
}

/// Builds `mesh` at each (D, Q), traces `rays_each` rays per config and
/// asserts no mismatch; returns the total number of rays.
fn check_configs(name: &str, mesh: &Mesh, rays_each: usize) -> u64 {
    let mut total = 0;
    for d in [8u8, 12, 16] {
        for q in [0u8, 4, 8] {
            let p = params(d, q);
            let (lo, hi) = mesh.bounds();
            let grid = GridMap::fit(lo, hi, &p);
            let h = build(mesh, &grid, &p, 1).unwrap_or_else(|e| panic!("{name} D={d} Q={q}: {e}"));
            let scene = TraceScene::new(grid, &[Instance::new(&h, mesh)]).unwrap();
            let s = verify_rays(&scene, rays_each, seeded(1000 + d as u64 * 31 + q as u64));
            report(name, d, q, &s);
            assert_eq!(
                s.mismatches, 0,
                "{name} D={d} Q={q}: {:?}",
                s.first_mismatch
            );
            assert!(s.hits > 0 && s.hits < s.rays, "{name}: {s:?}");
            // The hierarchy must actually cull: far fewer triangle tests than brute force.
            assert!(
                s.prim_tests_per_ray < s.brute_prim_tests_per_ray / 4.0,
                "{name} D={d} Q={q}: {s:?}"
            );
            total += s.rays;
        }
    }
    total
}

fn report(name: &str, d: u8, q: u8, s: &TraceSummary) {
    println!(
        "{name} D={d} Q={q}: {} rays, {} hits, {:.1} node tests/ray, {:.1} triangle tests/ray",
        s.rays, s.hits, s.node_tests_per_ray, s.prim_tests_per_ray
    );
}

#[test]
fn bunny_matches_brute_force() {
    let total = check_configs("bunny", &load("bunny.obj"), 11_200);
    assert!(total >= 100_000);
}

#[test]
fn teapot_matches_brute_force() {
    let total = check_configs("teapot", &load("teapot.obj"), 11_200);
    assert!(total >= 100_000);
}

#[test]
fn slivers_and_axis_aligned_match_brute_force() {
    let mesh = scenes::hard_cases(300, 42);
    check_configs("hard cases", &mesh, 2_000);
}

/// Bunny and teapot as two hierarchies in one grid, overlapping in space:
/// closest hits across the list equal brute force over both meshes.
#[test]
fn two_hierarchies_match_brute_force() {
    let bunny = load("bunny.obj");
    let teapot = load("teapot.obj");
    let (blo, bhi) = bunny.bounds();
    let (tlo, thi) = teapot.bounds();
    for (d, q) in [(10u8, 0u8), (14, 6)] {
        let p = params(d, q);
        let grid = GridMap::fit(blo.min(tlo), bhi.max(thi), &p);
        let hb = build(&bunny, &grid, &p, 3).unwrap();
        let ht = build(&teapot, &grid, &p, 2).unwrap();
        let scene = TraceScene::new(
            grid,
            &[Instance::new(&hb, &bunny), Instance::new(&ht, &teapot)],
        )
        .unwrap();
        let s = verify_rays(&scene, 10_000, seeded(7));
        report("bunny+teapot", d, q, &s);
        assert_eq!(s.mismatches, 0, "{:?}", s.first_mismatch);
        assert!(s.prim_tests_per_ray < s.brute_prim_tests_per_ray / 4.0);
    }
}

/// A hierarchy placed twice: once as built and once translated by half the
/// grid along x (an integer offset in grid units). Both copies are hit, and
/// traversal agrees with brute force on the translated triangles.
#[test]
fn translated_instance_matches_brute_force() {
    let teapot = load("teapot.obj");
    let (lo, hi) = teapot.bounds();
    let p = params(12, 8);
    // Fit the mesh into the lower half of the grid so a half-grid shift stays inside.
    let grid = GridMap::fit(lo, lo + (hi - lo) * 2.0, &p);
    let h = build(&teapot, &grid, &p, 1).unwrap();
    let moved_h = build(&teapot, &grid, &p, 2).unwrap();
    let half = 1i64 << (p.max_lod - 1);
    let moved = Instance {
        hierarchy: &moved_h,
        mesh: &teapot,
        offset: [half, 0, 0],
    };
    let scene = TraceScene::new(grid, &[Instance::new(&h, &teapot), moved]).unwrap();
    let (slo, shi) = scene.bounds();
    assert!(shi.x - slo.x > 1.5 * (hi.x - lo.x), "the copy did not move");
    let s = verify_rays(&scene, 10_000, seeded(9));
    report("teapot x2 translated", 12, 8, &s);
    assert_eq!(s.mismatches, 0, "{:?}", s.first_mismatch);
}

/// The comparison can fail: a hierarchy that lost one triangle per leaf
/// disagrees with brute force on some rays.
#[test]
fn a_damaged_hierarchy_is_caught() {
    let bunny = load("bunny.obj");
    let p = params(12, 4);
    let (lo, hi) = bunny.bounds();
    let grid = GridMap::fit(lo, hi, &p);
    let mut h = build(&bunny, &grid, &p, 1).unwrap();
    for n in h.nodes.clone() {
        if n.leaf && n.count >= 2 {
            let (a, b) = (n.first as usize, (n.first + n.count - 1) as usize);
            h.prims[b] = h.prims[a];
        }
    }
    let scene = TraceScene::new(grid, &[Instance::new(&h, &bunny)]).unwrap();
    let s = verify_rays(&scene, 5_000, seeded(5));
    assert!(s.mismatches > 0, "{s:?}");
    assert!(s.first_mismatch.is_some());
}

/// A copy translated about a million world units away (the ray origins and
/// targets are f32 world positions there, an ulp of 1/16 or 1/8): traversal
/// still agrees with brute force, and the far copy is hit.
#[test]
fn far_translated_copy_matches_brute_force() {
    let teapot = load("teapot.obj");
    let (lo, _) = teapot.bounds();
    let p = Params::new(24, 8, 24, 4).unwrap();
    let grid = GridMap {
        origin: lo.as_dvec3(),
        unit: 0.125,
    };
    let near = build(&teapot, &grid, &p, 1).unwrap();
    let far = build(&teapot, &grid, &p, 2).unwrap();
    let offset = [1i64 << 23, 1 << 22, 1 << 21];
    let scene = TraceScene::new(
        grid,
        &[
            Instance::new(&near, &teapot),
            Instance {
                hierarchy: &far,
                mesh: &teapot,
                offset,
            },
        ],
    )
    .unwrap();
    let (_, shi) = scene.bounds();
    assert!(shi.x > 1.0e6);
    let s = verify_rays(&scene, 10_000, seeded(13));
    report("teapot near + 1e6 away", 24, 8, &s);
    assert_eq!(s.mismatches, 0, "{:?}", s.first_mismatch);
    assert!(s.hits > 1000, "{s:?}");
}
