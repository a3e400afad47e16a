//! Paragraphs 71-75 and 72's hard cases, through placed hierarchies
//! (golden::world): geometry kept in small local coordinates and placed by a
//! voxel-aligned translation is traced exactly as at the origin, while the
//! same triangles written in binary32 world coordinates go wrong.
//!
//! The grid: D = 31, one grid unit = one world unit, origin at 0, so the
//! scene spans 0 .. 2^31 (about 2.1e9) world units.

use glam::{DVec3, Vec3};
use golden::build::{build, GridMap};
use golden::mesh::Mesh;
use golden::scenes::shared_mesh_path;
use golden::seed::seeded;
use golden::trace::{brute_force_closest, closest_hit, Hit, Instance, TraceScene, TraceStats};
use golden::world::World;
use golden::Params;

fn params() -> Params {
    Params::new(31, 8, 24, 4).unwrap()
}

fn grid() -> GridMap {
    GridMap {
        origin: DVec3::ZERO,
        unit: 1.0,
    }
}

/// A move of about `far` world units, a whole number of 2^12 units: a
/// multiple of every translation step used here and of the binary32
/// spacing of coordinates up to 2^30 (64), so moved ray origins stay exact.
fn delta(far: f64) -> f64 {
    ((far / 4096.0).round()).max(1.0) * 4096.0
}

/// `ray` moved by `d` on every axis, exactly.
fn moved(origin: Vec3, d: f64) -> Vec3 {
    let o = origin.as_dvec3() + DVec3::splat(d);
    assert_eq!(
        o.as_vec3().as_dvec3(),
        o,
        "moved origin must be exact in binary32"
    );
    o.as_vec3()
}

/// The same triangles written in binary32 world coordinates `d` away.
fn in_world_f32(mesh: &Mesh, d: f64) -> Mesh {
    Mesh {
        vertices: mesh
            .vertices
            .iter()
            .map(|v| (v.as_dvec3() + DVec3::splat(d)).as_vec3())
            .collect(),
        triangles: mesh.triangles.clone(),
    }
}

/// The same triangle (or both miss).
fn same_triangle(a: &Option<Hit>, b: &Option<Hit>) -> bool {
    a.map(|h| h.prim) == b.map(|h| h.prim)
}

/// The same triangle at the same `t`, bit for bit.
fn same(a: &Option<Hit>, b: &Option<Hit>) -> bool {
    same_triangle(a, b) && a.map(|h| h.t.to_bits()) == b.map(|h| h.t.to_bits())
}

/// Ray origins: points of a 64-unit lattice around the local geometry.
const LATTICE: [Vec3; 6] = [
    Vec3::new(0.0, 0.0, 64.0),
    Vec3::new(64.0, 0.0, 64.0),
    Vec3::new(0.0, 64.0, 64.0),
    Vec3::new(64.0, 64.0, 64.0),
    Vec3::new(-64.0, 0.0, 64.0),
    Vec3::new(0.0, -64.0, -64.0),
];

/// A unit quad of two triangles sharing the diagonal (0,0)-(1,1), in z = 0,
/// placed 8 units from the local origin.
fn quad() -> Mesh {
    let c = Vec3::new(8.0, 8.0, 8.0);
    Mesh {
        vertices: vec![c, c + Vec3::X, c + Vec3::new(1.0, 1.0, 0.0), c + Vec3::Y],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

#[test]
fn quad_shows_no_crack_at_1e6_and_1e9() {
    for far in [1.0e6, 1.0e9] {
        let d = delta(far);
        let mut w = World::new(params(), grid()).unwrap();
        w.add(1, quad(), DVec3::splat(d)).unwrap();
        let inst = w.separate_instances(&[1]).unwrap();
        let placed = w.trace_scene(&inst, &[1]).unwrap();
        let world32 = in_world_f32(&quad(), d);
        let h32 = build(&world32, &grid(), &params(), 2);
        let brute32 = h32.as_ref().map_err(|e| e.to_string()).and_then(|h| {
            TraceScene::new(grid(), &[Instance::new(h, &world32)]).map_err(|e| e.to_string())
        });
        let (mut misses, mut misses32) = (0, 0);
        let n = 4000;
        for k in 0..n {
            // A point on the shared diagonal (away from the quad's corners),
            // seen from above at a slant, in local coordinates ...
            let s = 0.05 + 0.9 * (k as f32 + 0.5) / n as f32;
            let target = Vec3::new(8.0 + s, 8.0 + s, 8.0);
            // Seen from a point of the 64-unit lattice (binary32 spacing at
            // 1e9), so the moved origin is exact; the direction is local.
            let origin = LATTICE[k % LATTICE.len()];
            let ray = golden::geom::ray::Ray::unbounded(moved(origin, d), target - origin);
            let mut st = TraceStats::default();
            misses += closest_hit(&ray, &placed, &mut st).is_none() as u32;
            if let Ok(scene32) = &brute32 {
                misses32 += brute_force_closest(&ray, scene32, &mut st).is_none() as u32;
            } else {
                misses32 += 1;
            }
        }
        println!(
            "quad at {far:e}: {n} rays at the shared edge: {misses} misses placed by translation, {misses32} misses in binary32 world coordinates"
        );
        assert_eq!(misses, 0, "a crack at {far:e}");
        if far >= 1.0e9 {
            // 1e9 in binary32 has a spacing of 64: the unit quad collapses.
            assert!(
                misses32 > 0,
                "binary32 world coordinates were expected to fail at {far:e}"
            );
        }
    }
}

#[test]
fn far_hits_equal_those_at_the_origin_and_binary32_world_coordinates_do_not() {
    let teapot = Mesh::load(&shared_mesh_path("teapot.obj")).unwrap();
    // The teapot scaled to 8 units, its corner at (16, 16, 16): small local floats.
    let (lo, hi) = teapot.bounds();
    let s = 8.0 / (hi - lo).max_element();
    let local = Mesh {
        vertices: teapot
            .vertices
            .iter()
            .map(|&v| (v - lo) * s + Vec3::splat(16.0))
            .collect(),
        triangles: teapot.triangles.clone(),
    };
    let mut near_world = World::new(params(), grid()).unwrap();
    near_world.add(1, local.clone(), DVec3::ZERO).unwrap();
    let near_inst = near_world.separate_instances(&[1]).unwrap();
    let near = near_world.trace_scene(&near_inst, &[1]).unwrap();
    // Rays from points of the 64-unit lattice (exact when moved) at random
    // points of the teapot's box.
    let mut rng = golden::scenes::SplitMix64::new(seeded(11));
    let rays: Vec<_> = (0..5000)
        .map(|k| {
            let origin = LATTICE[k % LATTICE.len()];
            let target = rng.point_in(Vec3::splat(16.0), Vec3::splat(24.0));
            golden::geom::ray::Ray::unbounded(origin, target - origin)
        })
        .collect();
    let at_origin: Vec<Option<Hit>> = rays
        .iter()
        .map(|r| closest_hit(r, &near, &mut TraceStats::default()))
        .collect();
    assert!(at_origin.iter().filter(|h| h.is_some()).count() > 500);
    for far in [1.0e3, 1.0e6, 1.0e9] {
        let d = delta(far);
        let mut w = World::new(params(), grid()).unwrap();
        let o = w.add(1, local.clone(), DVec3::splat(d)).unwrap();
        assert!(
            o.determined.residual.value_f64(golden::translate::Axis::X) == 0.0,
            "the move is voxel-aligned"
        );
        let inst = w.separate_instances(&[1]).unwrap();
        let placed = w.trace_scene(&inst, &[1]).unwrap();
        let world32 = in_world_f32(&local, d);
        let h32 = build(&world32, &grid(), &params(), 2).ok();
        let scene32 = h32
            .as_ref()
            .map(|h| TraceScene::new(grid(), &[Instance::new(h, &world32)]).unwrap());
        let (mut wrong_placed, mut wrong_f32, mut other_t_f32) = (0, 0, 0);
        for (r, want) in rays.iter().zip(&at_origin) {
            let ray = golden::geom::ray::Ray {
                origin: moved(r.origin, d),
                ..*r
            };
            let got = closest_hit(&ray, &placed, &mut TraceStats::default());
            wrong_placed += !same(&got, want) as u32;
            let got32 = scene32
                .as_ref()
                .and_then(|s| brute_force_closest(&ray, s, &mut TraceStats::default()));
            wrong_f32 += !same_triangle(&got32, want) as u32;
            other_t_f32 += (same_triangle(&got32, want) && !same(&got32, want)) as u32;
        }
        println!(
            "offset {far:e}: {} rays: placed by translation {wrong_placed} differ from the origin (triangle or t); in binary32 world coordinates {wrong_f32} hit another triangle or miss, {other_t_f32} more the same triangle at another t",
            rays.len()
        );
        assert_eq!(wrong_placed, 0, "translated hits differ at {far:e}");
        if far >= 1.0e6 {
            assert!(
                wrong_f32 > 0,
                "binary32 world coordinates were expected to go wrong at {far:e}"
            );
        }
    }
}
