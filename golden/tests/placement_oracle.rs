//! Placements honoured exactly (SPEC 7.10), judged by the independent
//! binary64 oracle (SPEC 6.10): objects moved by fractions of a voxel, from 1
//! to 1e9 world units from the origin, with seams (two triangles sharing an
//! edge, two meshes touching), traced through the merged and the separate
//! hierarchies. And the oracle is not blind: golden geometry that dropped the
//! residual, or a wrong translation, is caught.
//!
//! The grid: D = 31, one grid unit = one world unit, from -2^30 to 2^30 on
//! every axis; local geometry sits a few units from the world origin.

use glam::{DVec3, Vec3};
use golden::build::GridMap;
use golden::geom::Ray;
use golden::merge::MergeMode;
use golden::mesh::Mesh;
use golden::oracle::{Oracle, OracleSummary};
use golden::scenes::sphere;
use golden::seed::seeded;
use golden::trace::{closest_hit, Hit, TraceScene, TraceStats};
use golden::world::World;
use golden::Params;

fn world() -> World {
    let grid = GridMap {
        origin: DVec3::splat(-((1u64 << 30) as f64)),
        unit: 1.0,
    };
    World::new(Params::new(31, 8, 24, 4).unwrap(), grid).unwrap()
}

/// A unit quad of two triangles sharing the diagonal, in z = 8.
fn quad() -> Mesh {
    let c = Vec3::new(8.0, 8.0, 8.0);
    Mesh {
        vertices: vec![c, c + Vec3::X, c + Vec3::new(1.0, 1.0, 0.0), c + Vec3::Y],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// A ball resting on the quad (touching it at its centre).
fn ball() -> Mesh {
    sphere(Vec3::new(8.5, 8.5, 8.3), 0.3, 8, 16)
}

/// Rays from a 64-unit lattice near `at` at the objects' triangles, edges
/// and vertices (exact origins in binary32 up to 2^30).
fn rays(w: &World, ids: &[u8], at: DVec3, n: usize, seed: u64) -> Vec<Ray> {
    let base = (at / 64.0).round() * 64.0;
    let r = w.lattice_rays(ids, base, n, seeded(seed), true).unwrap();
    for ray in &r {
        assert_eq!(
            ray.origin.as_dvec3(),
            ray.origin.as_dvec3().round(),
            "lattice origins are exact"
        );
    }
    r
}

fn judge(oracle: &Oracle, scene: &TraceScene, rays: &[Ray]) -> OracleSummary {
    let hits: Vec<Option<Hit>> = rays
        .iter()
        .map(|r| closest_hit(r, scene, &mut TraceStats::default()))
        .collect();
    oracle.judge_all(rays, hits.iter().map(|h| h.as_ref()))
}

#[test]
fn fractional_placements_hold_from_1_to_1e9_seams_included() {
    let dir = DVec3::new(1.0, 0.618, 0.382).normalize();
    for far in [1.0, 1e3, 1e6, 1e9] {
        for sign in [1.0, -1.0] {
            let p = dir * far * sign + DVec3::new(0.37, -0.21, 0.113);
            let mut w = world();
            w.add(1, quad(), p).unwrap();
            w.add(2, ball(), p).unwrap();
            let residual = w.object(1).unwrap().determined.residual;
            assert!(
                golden::translate::Axis::ALL
                    .iter()
                    .any(|&a| residual.value_f64(a) != 0.0),
                "the placement is not voxel-aligned at {far:e}"
            );
            w.merge(&[1, 2], MergeMode::default(), 9).unwrap();
            w.check(9).unwrap();
            let parts = w.oracle_parts(&[1, 2]).unwrap();
            let oracle = Oracle::new(&parts).unwrap();
            let r = rays(&w, &[1, 2], p + DVec3::splat(8.5), 3000, far as u64);
            let mi = w.merged_instances(9, &[1, 2]).unwrap();
            let si = w.separate_instances(&[1, 2]).unwrap();
            for (what, scene) in [
                ("merged", w.trace_scene(&mi, &[9]).unwrap()),
                ("separate", w.trace_scene(&si, &[1, 2]).unwrap()),
            ] {
                let s = judge(&oracle, &scene, &r);
                println!("{what} at {:e}: {s:?}", far * sign);
                assert_eq!(s.faults(), 0, "{what} at {:e}: {s:?}", far * sign);
                assert!(s.oracle_hits > 2500, "the rays meet the objects: {s:?}");
                assert!(s.agree > s.rays / 2, "{s:?}");
            }
        }
    }
}

#[test]
fn the_oracle_catches_a_dropped_residual_and_a_wrong_translation() {
    let mut w = world();
    let p = DVec3::new(1e6 + 0.4, 2e6 - 0.3, 3e6 + 0.2);
    w.add(1, quad(), p).unwrap();
    w.add(2, ball(), p).unwrap();
    let inst = w.separate_instances(&[1, 2]).unwrap();
    let scene = w.trace_scene(&inst, &[1, 2]).unwrap();
    let r = rays(&w, &[1, 2], p + DVec3::splat(8.5), 2000, 5);
    let honest = Oracle::new(&w.oracle_parts(&[1, 2]).unwrap()).unwrap();
    assert_eq!(judge(&honest, &scene, &r).faults(), 0);

    // Golden as it was: the source mesh traced at the translation alone,
    // the residual dropped.
    let mut dropped = world();
    for id in [1u8, 2] {
        let o = w.object(id).unwrap();
        let t = o.determined.translation;
        let shift = DVec3::from_array(
            golden::translate::Axis::ALL.map(|a| t.grid_offset(a, &w.params) as f64),
        );
        dropped.add(id, o.source.clone(), shift).unwrap();
    }
    let di = dropped.separate_instances(&[1, 2]).unwrap();
    let s = judge(&honest, &dropped.trace_scene(&di, &[1, 2]).unwrap(), &r);
    assert!(s.faults() > 100, "a dropped residual must be seen: {s:?}");

    // A translation off by one voxel of the finest LOD: one world unit.
    let mut moved = world();
    moved.add(1, quad(), p + DVec3::X).unwrap();
    moved.add(2, ball(), p + DVec3::X).unwrap();
    let mi = moved.separate_instances(&[1, 2]).unwrap();
    let s = judge(&honest, &moved.trace_scene(&mi, &[1, 2]).unwrap(), &r);
    assert!(s.faults() > 100, "a wrong translation must be seen: {s:?}");
}
