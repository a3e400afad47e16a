//! golden against obvhs, in one run: `cargo bench -p golden --bench versus`.
//!
//! **Build.** Per mesh, golden's builder ([`golden::build::build`], one
//! thread), its parallel build ([`golden::build::build_parallel`] in a rayon
//! pool of 2 threads) and obvhs's PLOC BVH2 builder with
//! `BvhBuildParams::fastest_build()` (obvhs without its `parallel` feature:
//! one thread) are run alternately, at least `BUILDS` rounds and more on a
//! small mesh (`BUILD_TIME`). Printed per builder:
//! the best wall time and triangles per second from it, and the peak of live
//! heap bytes during one build (a counting global allocator,
//! `support/counting_alloc.rs`; the result included) per million triangles.
//! The ratios are obvhs's time over golden's (above 1: golden is faster) and
//! golden's one-thread time over its 2-thread time. A second line per mesh
//! times the builders with their buffers kept from round to
//! round, as a scene rebuilding a hierarchy every frame keeps them: golden's
//! [`BuildContext`] (one thread, and its parallel build in the pool of 2)
//! against obvhs's `PlocBuilder`, reinsertion optimizer and
//! BVH kept ([`ObvhsKept`], checked to build what `build_bvh2_from_tris`
//! builds); their peak heap is their first build's, which makes the
//! buffers. golden's time includes
//! reading the vertices through the mesh's index buffer and the grid map;
//! obvhs is handed its triangles ready (not timed). The parallel build's
//! output is checked equal to the one-thread build's.
//!
//! **Trace.** On the same seeded random rays (and shadow rays from each hit
//! to a light above the scene), golden's octree ([`TraceContext::closest_hit`]
//! and [`TraceContext::occluded`]) beside obvhs's BVH2 (`ray_traverse` with
//! its Möller-Trumbore triangle test, and `ray_traverse_miss` for shadow
//! rays), one thread, `ROUNDS` alternating rounds: rays per second of the
//! best round and node tests per ray. obvhs counts no tests, so its node
//! tests come from an untimed copy of its traversal loop with a counter
//! ([`obvhs_node_tests`]), checked to find the same hits as obvhs's own. The
//! two triangle tests differ (golden's is watertight), so the bench prints
//! how many rays the two agree on (hit or miss, and `t` within 1e-4
//! relative) instead of asserting equality.
//!
//! Meshes: the shared bunny and teapot, a generated terrain of just over a
//! million triangles, and a generated building (floors, long thin walls,
//! columns: [`golden::scenes::architecture`]). `VERSUS_BENCH=<substring>`
//! runs only the meshes whose name contains it.

#[path = "support/counting_alloc.rs"]
mod counting_alloc;
#[path = "support/shadow.rs"]
mod shadow;

use std::hint::black_box;
use std::time::{Duration, Instant};

use counting_alloc::{peak_during, Counting};
use glam::Vec3;
use glam034::Vec3A;
use golden::build::{build, build_parallel, BuildContext, GridMap};
use golden::geom::Ray;
use golden::mesh::Mesh;
use golden::scenes::{self, shared_mesh_path};
use golden::store::Hierarchy;
use golden::trace::{random_rays, Instance, TraceContext, TraceScene, TraceStats};
use golden::Params;
use obvhs::bvh2::builder::build_bvh2_from_tris;
use obvhs::bvh2::leaf_collapser::collapse;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::bvh2::Bvh2;
use obvhs::ploc::PlocBuilder;
use obvhs::ray::{Ray as ORay, RayHit};
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;
use shadow::shadow_rays;

#[global_allocator]
static ALLOC: Counting = Counting;

/// Fewest rounds of each build, alternating between the builders.
const BUILDS: usize = 5;
/// Rounds go on past [`BUILDS`] until golden's one-thread builds have taken
/// this long in all: a small mesh builds in about a millisecond, where one
/// late wake-up of the second thread is a large part of a round, so its best
/// round needs many draws to find. At most [`BUILDS_MAX`] rounds.
const BUILD_TIME: Duration = Duration::from_millis(400);
/// Most rounds of each build.
const BUILDS_MAX: usize = 300;
/// Rounds of each traversal, alternating between golden and obvhs.
const ROUNDS: usize = 3;
/// Random primary rays per mesh.
const RAYS: usize = 100_000;

/// Best wall time and peak heap of one builder over the rounds.
#[derive(Default)]
struct BuildTiming {
    best: Option<Duration>,
    peak: usize,
}

impl BuildTiming {
    fn run<T>(&mut self, f: impl FnOnce() -> T) -> T {
        let t = Instant::now();
        let (out, peak) = peak_during(|| black_box(f()));
        let wall = t.elapsed();
        self.best = Some(self.best.map_or(wall, |b| b.min(wall)));
        self.peak = self.peak.max(peak);
        out
    }

    fn secs(&self) -> f64 {
        self.best.map_or(f64::NAN, |d| d.as_secs_f64())
    }

    fn describe(&self, label: &str, tris: f64) -> String {
        format!(
            "{label} {:>8.2} ms {:>6.2} M tris/s {:>6.1} MB/M tris",
            self.secs() * 1e3,
            tris / self.secs() / 1e6,
            self.peak as f64 / 1e6 / (tris / 1e6),
        )
    }
}

fn obvhs_triangles(mesh: &Mesh) -> Vec<Triangle> {
    let v = |i: u32| {
        let p = mesh.vertices[i as usize];
        Vec3A::new(p.x, p.y, p.z)
    };
    mesh.triangles
        .iter()
        .map(|t| Triangle {
            v0: v(t[0]),
            v1: v(t[1]),
            v2: v(t[2]),
        })
        .collect()
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a rayon pool")
}

/// obvhs's `build_bvh2_from_tris` with `fastest_build()` (no pre-split)
/// step by step, with its builder, optimizer and BVH kept from build to
/// build, as its documentation suggests for repeated builds: the
/// counterpart of golden's [`BuildContext`].
#[derive(Default)]
struct ObvhsKept {
    ploc: PlocBuilder,
    reinsertion: ReinsertionOptimizer,
    bvh: Bvh2,
}

impl ObvhsKept {
    fn build(&mut self, tris: &[Triangle]) {
        let c = BvhBuildParams::fastest_build();
        assert!(!c.pre_split, "the kept build has no pre-split");
        self.ploc.build_with_bvh(
            &mut self.bvh,
            c.ploc_search_distance,
            tris,
            (0..tris.len() as u32).collect(),
            c.sort_precision,
            c.search_depth_threshold,
        );
        self.bvh.uses_spatial_splits = c.pre_split;
        self.reinsertion
            .run(&mut self.bvh, c.reinsertion_batch_ratio, None);
        collapse(
            &mut self.bvh,
            c.max_prims_per_leaf.clamp(1, 255),
            c.collapse_traversal_cost,
        );
        let post = c.reinsertion_batch_ratio * c.post_collapse_reinsertion_batch_ratio_multiplier;
        self.reinsertion.run(&mut self.bvh, post, None);
    }
}

/// The same BVH: nodes (box, first index, primitive count) and primitive
/// indices.
fn same_bvh(a: &Bvh2, b: &Bvh2) -> bool {
    let node = |n: &obvhs::bvh2::node::Bvh2Node| {
        (
            n.aabb.min.to_array().map(f32::to_bits),
            n.aabb.max.to_array().map(f32::to_bits),
            n.first_index,
            n.prim_count,
        )
    };
    a.primitive_indices == b.primitive_indices
        && a.nodes.len() == b.nodes.len()
        && a.nodes
            .iter()
            .zip(&b.nodes)
            .all(|(x, y)| node(x) == node(y))
}

/// Builds `mesh` with each builder; returns golden's hierarchy, its grid
/// map and obvhs's BVH for the trace comparison.
fn compare_builds(
    name: &str,
    mesh: &Mesh,
    tris: &[Triangle],
    p: &Params,
) -> (Hierarchy, GridMap, Bvh2) {
    let (lo, hi) = mesh.bounds();
    let grid = GridMap::fit(lo, hi, p);
    let two = pool(2);
    let (mut one_t, mut two_t, mut ob_t) = Default::default();
    let (mut kept_t, mut kept2_t, mut ob_kept_t): (BuildTiming, BuildTiming, BuildTiming) =
        Default::default();
    let (mut ctx, mut ob_kept) = (BuildContext::new(), ObvhsKept::default());
    let (mut h, mut bvh) = (None, None);
    let mut rounds = 0;
    let mut one_thread_total = Duration::ZERO;
    while rounds < BUILDS || (one_thread_total < BUILD_TIME && rounds < BUILDS_MAX) {
        rounds += 1;
        let t = Instant::now();
        let a = BuildTiming::run(&mut one_t, || {
            build(mesh, &grid, p, 0).expect("golden builds")
        });
        one_thread_total += t.elapsed();
        let b = two.install(|| {
            BuildTiming::run(&mut two_t, || {
                build_parallel(mesh, &grid, p, 0).expect("golden builds in parallel")
            })
        });
        assert!(
            a == b,
            "{name}: the parallel build differs from the one-thread build"
        );
        bvh = Some(BuildTiming::run(&mut ob_t, || {
            build_bvh2_from_tris(
                tris,
                BvhBuildParams::fastest_build(),
                &mut Duration::default(),
            )
        }));
        let c = BuildTiming::run(&mut kept_t, || {
            ctx.build(mesh, &grid, p, 0)
                .expect("golden builds in its context")
        });
        assert!(a == c, "{name}: the build in a kept context differs");
        let d = two.install(|| {
            BuildTiming::run(&mut kept2_t, || {
                ctx.build_parallel(mesh, &grid, p, 0)
                    .expect("golden builds in parallel in its context")
            })
        });
        assert!(
            a == d,
            "{name}: the parallel build in a kept context differs"
        );
        BuildTiming::run(&mut ob_kept_t, || ob_kept.build(tris));
        h = Some(a);
    }
    let bvh = bvh.expect("built");
    assert!(
        same_bvh(&bvh, &ob_kept.bvh),
        "{name}: obvhs's kept build differs from build_bvh2_from_tris"
    );
    let n = mesh.triangles.len() as f64;
    println!(
        "build {name:<16} tris {:>8} {rounds:>3} rounds | {} | {} | {} | obvhs/golden {:>5.2}x (2 threads {:>5.2}x), golden 1/2 threads {:>5.2}x",
        mesh.triangles.len(),
        one_t.describe("golden 1 thread", n),
        two_t.describe("golden 2 threads", n),
        ob_t.describe("obvhs fastest_build", n),
        ob_t.secs() / one_t.secs(),
        ob_t.secs() / two_t.secs(),
        one_t.secs() / two_t.secs(),
    );
    println!(
        "build {name:<16} kept buffers   | {} | {} | {} | obvhs/golden {:>5.2}x (2 threads {:>5.2}x), golden 1/2 threads {:>5.2}x",
        kept_t.describe("golden 1 thread, BuildContext", n),
        kept2_t.describe("golden 2 threads, BuildContext", n),
        ob_kept_t.describe("obvhs kept PlocBuilder", n),
        ob_kept_t.secs() / kept_t.secs(),
        ob_kept_t.secs() / kept2_t.secs(),
        kept_t.secs() / kept2_t.secs(),
    );
    (h.expect("built"), grid, bvh)
}

fn to_obvhs(r: &Ray) -> ORay {
    let v = |p: Vec3| Vec3A::new(p.x, p.y, p.z);
    ORay::new(v(r.origin), v(r.dir), r.tmin, r.tmax)
}

/// obvhs's closest hit: `t` or None.
fn obvhs_closest(bvh: &Bvh2, tris: &[Triangle], r: &ORay) -> Option<f32> {
    let mut hit = RayHit::none();
    bvh.ray_traverse(*r, &mut hit, |ray, id| {
        tris[bvh.primitive_indices[id] as usize].intersect(ray)
    })
    .then_some(hit.t)
}

/// obvhs's shadow-ray query.
fn obvhs_occluded(bvh: &Bvh2, tris: &[Triangle], r: &ORay) -> bool {
    !bvh.ray_traverse_miss(*r, |ray, id| {
        tris[bvh.primitive_indices[id] as usize].intersect(ray)
    })
}

/// The node (box) tests and the closest `t` of obvhs's closest-hit walk:
/// the loop of `Bvh2::ray_traverse_dynamic` with a counter, a plain `Vec`
/// as its stack (the order of the walk does not depend on the stack type).
fn obvhs_node_tests(bvh: &Bvh2, tris: &[Triangle], r: &ORay) -> (u64, Option<f32>) {
    let mut ray = *r;
    let mut hit_t = None;
    let mut leaf = |node: &obvhs::bvh2::node::Bvh2Node, ray: &mut ORay| {
        for id in node.first_index..node.first_index + node.prim_count {
            let t = tris[bvh.primitive_indices[id as usize] as usize].intersect(ray);
            if t < ray.tmax {
                ray.tmax = t;
                hit_t = Some(t);
            }
        }
    };
    let root = &bvh.nodes[0];
    let mut tests = 1;
    if root.aabb().intersect_ray(&ray) >= ray.tmax {
        return (tests, None);
    }
    if root.is_leaf() {
        leaf(root, &mut ray);
        return (tests, hit_t);
    }
    let mut stack = Vec::new();
    let mut current = root.first_index as usize;
    loop {
        let (mut l, mut rn) = (&bvh.nodes[current], &bvh.nodes[current + 1]);
        let (mut lt, mut rt) = (l.aabb().intersect_ray(&ray), rn.aabb().intersect_ray(&ray));
        tests += 2;
        if lt > rt {
            std::mem::swap(&mut lt, &mut rt);
            std::mem::swap(&mut l, &mut rn);
        }
        let mut go = [false; 2];
        for (k, (node, t)) in [(l, lt), (rn, rt)].into_iter().enumerate() {
            if t < ray.tmax {
                if node.is_leaf() {
                    leaf(node, &mut ray);
                } else {
                    go[k] = true;
                }
            }
        }
        current = match go {
            [true, true] => {
                stack.push(rn.first_index as usize);
                l.first_index as usize
            }
            [true, false] => l.first_index as usize,
            [false, true] => rn.first_index as usize,
            [false, false] => match stack.pop() {
                Some(next) => next,
                None => return (tests, hit_t),
            },
        };
    }
}

/// Best-round rays per second of `f` over `rays`, and how many it answered yes.
fn rays_per_second(best: &mut f64, rays: usize, f: impl FnOnce() -> u64) -> u64 {
    let t = Instant::now();
    let yes = f();
    *best = best.max(rays as f64 / t.elapsed().as_secs_f64());
    yes
}

fn compare_traces(
    name: &str,
    mesh: &Mesh,
    tris: &[Triangle],
    h: &Hierarchy,
    grid: GridMap,
    bvh: &Bvh2,
) {
    let inst = [Instance::new(h, mesh)];
    let scene = TraceScene::new(grid, &inst).expect("scene");
    let (blo, bhi) = scene.bounds();
    let primary = random_rays(blo, bhi, RAYS, 1);
    let shadows = shadow_rays(&scene, &primary);
    let (oprimary, oshadows): (Vec<ORay>, Vec<ORay>) = (
        primary.iter().map(to_obvhs).collect(),
        shadows.iter().map(to_obvhs).collect(),
    );

    // Untimed: test counts, agreement, and the counting copy against obvhs.
    let mut ctx = TraceContext::new();
    let (mut g_closest, mut g_occluded) = (TraceStats::default(), TraceStats::default());
    let (mut o_closest, mut o_shadow, mut agree, mut hits) = (0u64, 0u64, 0usize, 0usize);
    for (r, o) in primary.iter().zip(&oprimary) {
        let g = ctx.closest_hit(r, &scene, &mut g_closest).map(|h| h.t);
        let (tests, t) = obvhs_node_tests(bvh, tris, o);
        assert_eq!(
            t,
            obvhs_closest(bvh, tris, o),
            "{name}: the counting walk differs from obvhs's"
        );
        o_closest += tests;
        hits += g.is_some() as usize;
        agree += match (g, t) {
            (Some(a), Some(b)) => (a - b).abs() <= 1e-4 * a.abs().max(b.abs()),
            (None, None) => true,
            _ => false,
        } as usize;
    }
    for (r, o) in shadows.iter().zip(&oshadows) {
        ctx.occluded(r, &scene, &mut g_occluded);
        o_shadow += obvhs_node_tests(bvh, tris, o).0;
    }

    let (mut g_p, mut o_p, mut g_s, mut o_s) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let (mut g_shadowed, mut o_shadowed) = (0, 0);
    for _ in 0..ROUNDS {
        rays_per_second(&mut g_p, primary.len(), || {
            let mut st = TraceStats::default();
            primary
                .iter()
                .filter(|r| ctx.closest_hit(black_box(r), &scene, &mut st).is_some())
                .count() as u64
        });
        rays_per_second(&mut o_p, oprimary.len(), || {
            oprimary
                .iter()
                .filter(|r| obvhs_closest(bvh, tris, black_box(r)).is_some())
                .count() as u64
        });
        g_shadowed = rays_per_second(&mut g_s, shadows.len(), || {
            let mut st = TraceStats::default();
            shadows
                .iter()
                .filter(|r| ctx.occluded(black_box(r), &scene, &mut st))
                .count() as u64
        });
        o_shadowed = rays_per_second(&mut o_s, oshadows.len(), || {
            oshadows
                .iter()
                .filter(|r| obvhs_occluded(bvh, tris, black_box(r)))
                .count() as u64
        });
    }
    let per = |n: u64, rays: usize| n as f64 / rays.max(1) as f64;
    println!(
        "trace {name:<16} {} rays ({:.1}% hit, {:.2}% agree) | closest: golden {:>8.0} rays/s {:>5.1} node tests/ray | obvhs {:>8.0} rays/s {:>5.1} node tests/ray | golden/obvhs {:>5.2}x || {} shadow rays ({} / {} shadowed) | occluded: golden {:>8.0} rays/s {:>5.1} node tests/ray | obvhs {:>8.0} rays/s {:>5.1} node tests/ray | golden/obvhs {:>5.2}x",
        primary.len(),
        100.0 * hits as f64 / primary.len() as f64,
        100.0 * agree as f64 / primary.len() as f64,
        g_p,
        per(g_closest.node_tests, primary.len()),
        o_p,
        per(o_closest, primary.len()),
        g_p / o_p,
        shadows.len(),
        g_shadowed,
        o_shadowed,
        g_s,
        per(g_occluded.node_tests, shadows.len()),
        o_s,
        per(o_shadow, shadows.len()),
        g_s / o_s,
    );
}

fn run(name: &str, mesh: &Mesh) {
    if std::env::var("VERSUS_BENCH").is_ok_and(|f| !name.contains(&f)) {
        return;
    }
    let p = Params::default();
    let tris = obvhs_triangles(mesh);
    let (h, grid, bvh) = compare_builds(name, mesh, &tris, &p);
    compare_traces(name, mesh, &tris, &h, grid, &bvh);
}

fn main() {
    println!(
        "golden against obvhs (PLOC fastest_build, one thread); Params {:?}; {BUILDS} to {BUILDS_MAX} build rounds (until golden's one-thread builds take {BUILD_TIME:?}), {ROUNDS} trace rounds; best wall times",
        Params::default()
    );
    for name in ["bunny.obj", "teapot.obj"] {
        let mesh = Mesh::load(&shared_mesh_path(name)).expect("a shared mesh");
        run(name, &mesh);
    }
    run("architecture", &scenes::architecture(6, 12));
    run("terrain 1M", &scenes::terrain(708, 1));
}
