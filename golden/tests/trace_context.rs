//! The reusable traversal context (SPEC 6.11): one context carried across
//! many rays and several scenes (the shared meshes, a translated and merged
//! world) gives, ray by ray, the hit bit for bit and the node and triangle
//! test counts of the frozen traversal before the context
//! (`support/reference_trace.rs`) and of a fresh context per ray; `occluded`
//! says yes exactly when the closest hit within the ray's `[tmin, tmax]`
//! exists, never testing more; and a warmed context traces without
//! allocating.

#[path = "support/reference_trace.rs"]
mod reference_trace;

use golden::seed::seeded;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use glam::{DVec3, Vec3};
use golden::build::{build, GridMap};
use golden::geom::Ray;
use golden::merge::MergeMode;
use golden::mesh::Mesh;
use golden::scenes::{self, shared_mesh_path, sphere, torus, SplitMix64};
use golden::store::Hierarchy;
use golden::trace::{
    closest_hit, edge_rays, random_rays, Hit, Instance, TraceContext, TraceScene, TraceStats,
};
use golden::world::World;
use golden::Params;
use reference_trace::RefScene;

/// Counts this thread's allocations (tests run on several threads).
struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.with(|a| a.set(a.get() + 1));
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.with(|a| a.set(a.get() + 1));
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations() -> u64 {
    ALLOCATIONS.with(|a| a.get())
}

fn bits(h: &Option<Hit>) -> Option<(u8, u32, [u32; 4])> {
    h.map(|h| {
        (
            h.hier,
            h.prim,
            [h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.w.to_bits()],
        )
    })
}

/// Random and edge rays over the scene, a third of them cut short at a
/// random fraction of their closest hit (or of the scene's size), some
/// exactly at it: the shadow rays' finite `tmax`.
fn rays(scene: &TraceScene, n: usize, seed: u64) -> Vec<Ray> {
    let (lo, hi) = scene.bounds();
    let seed = seeded(seed);
    let mut rays = random_rays(lo, hi, n - n / 2, seed);
    rays.extend(edge_rays(scene, n / 2, seed ^ 0x5EED));
    let mut rng = SplitMix64::new(seed);
    let size = (hi - lo).length();
    for r in rays.iter_mut() {
        match rng.below(6) {
            0 => {
                let t = closest_hit(r, scene, &mut TraceStats::default())
                    .map_or(size / r.dir.length(), |h| h.t);
                *r = r.with_tmax(t * rng.range_f32(0.3, 1.3));
            }
            1 => {
                if let Some(h) = closest_hit(r, scene, &mut TraceStats::default()) {
                    *r = r.with_tmax(h.t);
                }
            }
            _ => {}
        }
    }
    rays
}

/// Every ray through `scene` with one shared context `ctx`, a fresh one
/// and the frozen reference: same hit bits, same counts; `occluded` agrees.
fn agree(name: &str, ctx: &mut TraceContext, scene: &TraceScene, old: &RefScene, rays: &[Ray]) {
    let (mut hits, mut short_hits, mut short_misses) = (0, 0, 0);
    for (i, ray) in rays.iter().enumerate() {
        let (mut a, mut b, mut c, mut o) = Default::default();
        let got = ctx.closest_hit(ray, scene, &mut a);
        let fresh = closest_hit(ray, scene, &mut b);
        let want = reference_trace::closest_hit(ray, old, &mut c);
        assert_eq!(bits(&got), bits(&want), "{name} ray {i} {ray:?}: hit");
        assert_eq!(bits(&fresh), bits(&want), "{name} ray {i}: fresh hit");
        assert_eq!(a, c, "{name} ray {i} {ray:?}: counts");
        assert_eq!(b, c, "{name} ray {i}: fresh counts");
        let blocked = ctx.occluded(ray, scene, &mut o);
        assert_eq!(blocked, got.is_some(), "{name} ray {i} {ray:?}: occluded");
        assert!(
            o.node_tests <= a.node_tests && o.prim_tests <= a.prim_tests,
            "{name} ray {i}: occluded {o:?} tested more than closest {a:?}"
        );
        hits += got.is_some() as u32;
        if ray.tmax.is_finite() {
            short_hits += got.is_some() as u32;
            short_misses += got.is_none() as u32;
        }
    }
    // The rays exercise both answers, also for finite tmax.
    assert!(hits > 50 && hits < rays.len() as u32, "{name}: {hits} hits");
    assert!(
        short_hits > 20 && short_misses > 20,
        "{name}: short rays {short_hits} hit, {short_misses} missed"
    );
}

fn fitted(mesh: &Mesh, p: &Params) -> (GridMap, Hierarchy) {
    let (lo, hi) = mesh.bounds();
    let grid = GridMap::fit(lo, hi, p);
    (grid, build(mesh, &grid, p, 1).expect("builds"))
}

#[test]
fn one_context_over_many_scenes_equals_the_reference() {
    let mut ctx = TraceContext::new();
    let bunny = Mesh::load(&shared_mesh_path("bunny.obj")).unwrap_or_else(|e| panic!("{e}"));
    let teapot = Mesh::load(&shared_mesh_path("teapot.obj")).unwrap_or_else(|e| panic!("{e}"));
    let soup = scenes::hard_cases(400, 3);
    // Alternating scenes of different instance counts, the context carried along.
    for round in 0..2u64 {
        for (name, mesh, d, q) in [
            ("bunny", &bunny, 16, 8),
            ("teapot", &teapot, 12, 4),
            ("hard cases", &soup, 16, 0),
        ] {
            let p = Params::new(d, q, 24, 4).unwrap();
            let (grid, h) = fitted(mesh, &p);
            let inst = [Instance::new(&h, mesh)];
            let scene = TraceScene::new(grid, &inst).unwrap();
            let old = RefScene::new(grid, &inst);
            agree(name, &mut ctx, &scene, &old, &rays(&scene, 1500, 7 + round));
        }
        merged_world(&mut ctx, 11 + round);
    }
}

/// Three translated objects, two of them merged: the merged hierarchy's
/// nodes reference the inputs (several instances per ray).
fn merged_world(ctx: &mut TraceContext, seed: u64) {
    let p = Params::new(12, 6, 24, 4).unwrap();
    let grid = GridMap {
        origin: DVec3::ZERO,
        unit: 1.0 / 256.0,
    };
    let mut w = World::new(p, grid).unwrap();
    let edge = p.voxel_edge(3) as f64 * grid.unit;
    w.add(1, sphere(Vec3::splat(1.0), 0.4, 12, 24), DVec3::ZERO)
        .unwrap();
    let ring = torus(Vec3::splat(1.0), 0.5, 0.1, 24, 12);
    w.add(2, ring, DVec3::new(edge, 0.0, 0.0)).unwrap();
    let ball = sphere(Vec3::splat(1.0), 0.3, 8, 16);
    w.add(3, ball, DVec3::new(0.3, edge, 0.1)).unwrap();
    w.merge(&[1, 2], MergeMode::default(), 9).unwrap();
    let mut inst = w.merged_instances(9, &[1, 2]).unwrap();
    inst.extend(w.separate_instances(&[3]).unwrap());
    let scene = w.trace_scene(&inst, &[9, 3]).unwrap();
    let old = RefScene::with_roots(grid, &inst, &[9, 3]);
    agree("merged world", ctx, &scene, &old, &rays(&scene, 1500, seed));
}

#[test]
fn a_warmed_context_traces_without_allocating() {
    let bunny = Mesh::load(&shared_mesh_path("bunny.obj")).unwrap_or_else(|e| panic!("{e}"));
    let p = Params::default();
    let (grid, h) = fitted(&bunny, &p);
    let scene = TraceScene::new(grid, &[Instance::new(&h, &bunny)]).unwrap();
    let (lo, hi) = scene.bounds();
    let rays = random_rays(lo, hi, 2000, seeded(3));
    let mut ctx = TraceContext::new();
    let mut stats = TraceStats::default();
    // Warm: the buffers grow to what the deepest ray needs.
    for r in &rays {
        ctx.closest_hit(r, &scene, &mut stats);
    }
    let before = allocations();
    let mut hits = 0;
    for r in &rays {
        hits += ctx.closest_hit(r, &scene, &mut stats).is_some() as u32;
        hits += ctx.occluded(r, &scene, &mut stats) as u32;
    }
    let during = allocations() - before;
    assert!(hits > 100, "{hits}");
    assert_eq!(during, 0, "allocations while tracing {} rays", rays.len());
    // The counter counts: the allocating entry point is seen.
    let before = allocations();
    closest_hit(&rays[0], &scene, &mut stats);
    assert!(allocations() > before, "closest_hit makes a fresh context");
}
