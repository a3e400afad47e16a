//! Far from the origin (paragraphs 71-75): a merged hierarchy of bunny +
//! teapot moved 1e3, 1e6 and 1e9 world units away gives hits identical
//! (same triangle, same t, u, v, w) to the same merge near the origin, for
//! the same rays moved by the same amount; the inputs' triangles are tested
//! in their local frames.

mod merge_support;

use golden::seed::seeded;
use std::collections::BTreeMap;

use golden::geom::Ray;
use golden::merge::instances::merged_instances;
use golden::merge::MergeMode;
use golden::mesh::Mesh;
use golden::params::Params;
use golden::trace::{closest_hit, random_rays, Hit, TraceScene, TraceStats};
use golden::translate::Translation;
use merge_support::{load, normalized, Scene};

/// Bunny (1) and teapot (2), 64 world units each, D = 31, one grid unit per
/// world unit, both moved by `base` grid units plus a small per-input step
/// (so they overlap), merged into 3.
fn placed(base: i64) -> Scene {
    let p = Params::new(31, 8, 24, 4).unwrap();
    let mut s = Scene::new(p, 1.0);
    s.add(1, normalized(&load("bunny.obj"), 64.0, 4.0), [0, 0, 0]);
    s.add(2, normalized(&load("teapot.obj"), 64.0, 4.0), [0, 0, 0]);
    for (id, step) in [(1u8, 0i64), (2, 1)] {
        let l = s.top(id);
        let e = s.edge(l);
        assert_eq!(base % e, 0, "base must be a whole number of LOD-{l} voxels");
        let t = base / e + step;
        s.table
            .write(
                id as u32,
                Translation {
                    lod: l,
                    t: [t, t, t],
                },
            )
            .unwrap();
    }
    s.merge(&[1, 2], MergeMode::default(), 3);
    s.check(3, &[1, 2]);
    s
}

fn trace_all(s: &Scene, rays: &[Ray]) -> Vec<Option<Hit>> {
    let meshes: BTreeMap<u8, &Mesh> = [(1u8, &s.meshes[&1]), (2, &s.meshes[&2])]
        .into_iter()
        .collect();
    let m = s.store.get(3).unwrap();
    let inst = merged_instances(m, &s.store, &s.table, &meshes).unwrap();
    let scene = TraceScene::with_roots(s.grid, &inst, &[3]).unwrap();
    let mut st = TraceStats::default();
    rays.iter()
        .map(|r| closest_hit(r, &scene, &mut st))
        .collect()
}

#[test]
fn far_merged_hits_are_identical_to_the_same_merge_at_the_origin() {
    // A whole number of the coarsest translation voxel used (LOD 20 at most
    // moves by 2^11), so both placements are exact.
    let near_base = 1i64 << 12;
    let near = placed(near_base);
    for far_world in [1.0e3f64, 1.0e6, 1.0e9] {
        // Round the move to 2^12 grid units (a multiple of every translation
        // step and of the f32 spacing of the far ray origins, at most 2^6 at 1e9).
        let delta = ((far_world / 4096.0).round() as i64).max(1) * 4096;
        let far = placed(near_base + delta);
        // Ray origins on the f32 grid of the far position: `near + delta` is
        // then exact in f32 for both.
        let spacing = 64.0f32;
        let (lo, hi) = (
            glam::Vec3::splat(near_base as f32 + 4.0),
            glam::Vec3::splat(near_base as f32 + 68.0),
        );
        let rays: Vec<Ray> = random_rays(lo, hi, 6_000, seeded(far_world as u64))
            .into_iter()
            .map(|r| Ray {
                origin: (r.origin / spacing).round() * spacing,
                ..r
            })
            .collect();
        let moved: Vec<Ray> = rays
            .iter()
            .map(|r| {
                let o = r.origin.as_dvec3() + glam::DVec3::splat(delta as f64);
                assert_eq!(
                    o.as_vec3().as_dvec3(),
                    o,
                    "the moved origin must be exact in f32"
                );
                Ray {
                    origin: o.as_vec3(),
                    ..*r
                }
            })
            .collect();
        let a = trace_all(&near, &rays);
        let b = trace_all(&far, &moved);
        let mut hits = 0;
        for (k, (x, y)) in a.iter().zip(&b).enumerate() {
            match (x, y) {
                (None, None) => {}
                (Some(x), Some(y)) => {
                    assert!(x.identical(y), "ray {k} at {far_world}: {x:?} vs {y:?}");
                    hits += 1;
                }
                _ => panic!("ray {k} at {far_world}: {x:?} vs {y:?}"),
            }
        }
        println!(
            "offset {far_world:e}: {} rays, {hits} identical hits",
            rays.len()
        );
        assert!(hits > rays.len() / 10, "{hits}");
        // And through the far merged hierarchy, against the separate inputs and brute force.
        // At 1e9 the f32 world boxes are coarse (section 6.4), so fewer rays.
        let n = if far_world > 1e8 { 300 } else { 1_000 };
        let r = far.compare(3, &[1, 2], n, 3, 1);
        r.print(&format!("far {far_world:e}"));
    }
}
