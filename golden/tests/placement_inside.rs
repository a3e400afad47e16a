//! Scenes that validate also run (issue 19, item 5): every placement that
//! keeps an object's geometry inside the scene cube — the scene file's rule
//! (SPEC 12.1) — is placed, merged and checked by the world, however the
//! voxel rounding of its translation falls: objects touching the cube's
//! faces, spanning most of it, or straddling its large voxel boundaries.

use glam::{DVec3, Vec3};
use golden::build::GridMap;
use golden::merge::MergeMode;
use golden::scenes::{box_mesh, sphere, SplitMix64};
use golden::seed::seeded;
use golden::world::World;
use golden::Params;

#[test]
fn every_placement_inside_the_cube_is_placed_merged_and_checked() {
    let p = Params::new(10, 6, 24, 4).unwrap();
    let grid = GridMap {
        origin: DVec3::ZERO,
        unit: 1.0 / 64.0,
    };
    let side = p.scene_edge() as f64 * grid.unit; // 16 world units
    let mut rng = SplitMix64::new(seeded(19));
    let mut placed = 0;
    for case in 0..120 {
        let mut w = World::new(p, grid).unwrap();
        // A floor as large as the scene, always.
        w.add(
            0,
            box_mesh(Vec3::ZERO, Vec3::new(16.0, 0.25, 16.0)),
            DVec3::ZERO,
        )
        .unwrap();
        for id in 1..4u8 {
            let size = side * 0.9f64.powi(rng.below(40) as i32);
            let mesh = if id == 1 {
                box_mesh(Vec3::ZERO, Vec3::splat(size as f32))
            } else {
                let r = size as f32 / 2.0;
                sphere(Vec3::splat(r), r, 6, 12)
            };
            let (lo, hi) = mesh.bounds();
            let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
            // Anywhere the whole mesh stays in [0, side], often touching a
            // face or sitting on a multiple of a large voxel.
            let offset = DVec3::from_array([0, 1, 2].map(|a| {
                let (min, max) = (-lo[a], side - hi[a]);
                match rng.below(4) {
                    0 => min,
                    1 => max,
                    2 => (min + (max - min) * rng.next_f64()).clamp(min, max),
                    _ => (side / 2.0 - (hi[a] - lo[a]) / 2.0).clamp(min, max),
                }
            }));
            w.add(id, mesh, offset)
                .unwrap_or_else(|e| panic!("case {case} object {id} at {offset}: {e}"));
            placed += 1;
        }
        w.merge(&[0, 1, 2, 3], MergeMode::default(), 15)
            .unwrap_or_else(|e| panic!("case {case}: merge: {e}"));
        w.check(15)
            .unwrap_or_else(|e| panic!("case {case}: check: {e}"));
    }
    assert_eq!(placed, 360);
}

/// A placement exactly half a voxel off the grid rounds one way with the
/// local frame at 0 and the other way once the frame is moved by a voxel;
/// the frame must be judged by its own residual (found by
/// `hiermerge merge t.obj t.obj --translate -1,0,0 --translate -2.5,0,0`,
/// whose grid this is).
#[test]
fn a_placement_at_a_rounding_tie_stays_in_the_cube() {
    let p = Params::default();
    let (lo, hi) = (DVec3::new(-2.5, 0.0, 0.0), DVec3::new(1.0, 1.0, 0.0));
    let fitted = GridMap::fit(lo.as_vec3(), hi.as_vec3(), &p);
    let grid = GridMap {
        origin: fitted.origin - (hi - lo) * 0.5,
        unit: fitted.unit * 2.0,
    };
    let tri = golden::mesh::Mesh {
        vertices: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
        triangles: vec![[0, 1, 2]],
    };
    for x in [-1.0, -2.5, -0.5, 0.5, 1.0] {
        let mut w = World::new(p, grid).unwrap();
        w.add(0, tri.clone(), DVec3::new(x, 0.0, 0.0))
            .unwrap_or_else(|e| panic!("placed at {x}: {e}"));
        w.check(0).unwrap();
    }
}
