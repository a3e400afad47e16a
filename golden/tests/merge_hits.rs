//! Closest hits through a merged hierarchy equal those through the separate
//! translated inputs and brute force, bit for bit, on bunny + teapot placed
//! overlapping, disjoint, nested and far from the origin; the checker passes
//! on every merged hierarchy and every input leaf is reachable exactly once.

mod merge_support;

use golden::merge::MergeMode;
use golden::params::Params;
use merge_support::{load, normalized, Scene};

/// Rays per placement near the origin; 3 x 30,000 + 10,000 far = 100,000, each
/// also checked by brute force.
const RAYS: usize = 30_000;
const FAR_RAYS: usize = 10_000;

/// Bunny (id 1) and teapot (id 2) at the given translations (voxels of
/// each one's top LOD), merged into id 3 with the default mode; checked,
/// traced; returns the rays traced.
fn run(
    name: &str,
    params: Params,
    unit: f64,
    sizes: (f32, f32),
    tb: [i64; 3],
    tt: [i64; 3],
) -> u64 {
    let mut s = Scene::new(params, unit);
    s.add(1, normalized(&load("bunny.obj"), sizes.0, 1.0), tb);
    s.add(2, normalized(&load("teapot.obj"), sizes.1, 1.0), tt);
    let r = s.merge(&[1, 2], MergeMode::default(), 3);
    println!("{name}: level {:?}, stats {:?}", r.level, r.stats);
    let report = s.check(3, &[1, 2]);
    assert_eq!(report.hierarchies, vec![1, 2, 3]);
    let leaves = s.leaves_once(3, &[1, 2]);
    assert_eq!(report.leaves, leaves);
    let rays = s.compare(3, &[1, 2], RAYS, 7 + tb[0] as u64, 1);
    rays.print(name);
    assert!(
        rays.hits > rays.rays / 10 && rays.hits < rays.rays,
        "{rays:?}"
    );
    rays.rays
}

fn d16() -> Params {
    Params::new(16, 8, 24, 4).unwrap()
}

#[test]
fn overlapping_bunny_and_teapot() {
    // Both 8 world units (512 grid units), moved onto the same spot.
    let n = run(
        "overlapping",
        d16(),
        1.0 / 64.0,
        (8.0, 8.0),
        [10, 10, 10],
        [10, 10, 10],
    );
    assert!(n >= 30_000);
}

#[test]
fn disjoint_bunny_and_teapot() {
    let n = run(
        "disjoint",
        d16(),
        1.0 / 64.0,
        (8.0, 8.0),
        [5, 5, 5],
        [40, 20, 30],
    );
    assert!(n >= 30_000);
}

#[test]
fn nested_bunny_inside_teapot() {
    let mut s = Scene::new(d16(), 1.0 / 64.0);
    s.add(2, normalized(&load("teapot.obj"), 200.0, 1.0), [0, 0, 0]);
    let lt = s.top(2);
    // The teapot's top voxel moves by one voxel of its top LOD.
    let e = s.edge(lt);
    s.table
        .write(
            2,
            golden::translate::Translation {
                lod: lt,
                t: [1, 1, 1],
            },
        )
        .unwrap();
    s.add(1, normalized(&load("bunny.obj"), 8.0, 1.0), [0, 0, 0]);
    let lb = s.top(1);
    // The bunny goes into the middle of the teapot's box.
    let mid = e + 6400;
    let tb = mid / s.edge(lb);
    s.table
        .write(
            1,
            golden::translate::Translation {
                lod: lb,
                t: [tb, tb, tb],
            },
        )
        .unwrap();
    let r = s.merge(&[1, 2], MergeMode::default(), 3);
    println!("nested: level {:?}, stats {:?}", r.level, r.stats);
    s.check(3, &[1, 2]);
    s.leaves_once(3, &[1, 2]);
    let rays = s.compare(3, &[1, 2], RAYS, 99, 1);
    rays.print("nested");
    assert!(rays.hits > rays.rays / 10);
}

#[test]
fn far_from_the_origin_at_d31() {
    // D = 31, 1/64 world unit per grid unit: the scene is 3.4e7 world units;
    // both placed about 2^31 grid units (3.2e7 world units) from the origin.
    let p = Params::new(31, 8, 24, 4).unwrap();
    let mut s = Scene::new(p, 1.0 / 64.0);
    s.add(1, normalized(&load("bunny.obj"), 8.0, 1.0), [0, 0, 0]);
    s.add(2, normalized(&load("teapot.obj"), 8.0, 1.0), [0, 0, 0]);
    let far = 2_000_000_000i64;
    for id in [1u8, 2] {
        let l = s.top(id);
        let t = far / s.edge(l) + id as i64;
        s.table
            .write(
                id as u32,
                golden::translate::Translation {
                    lod: l,
                    t: [t, t, t],
                },
            )
            .unwrap();
    }
    let r = s.merge(&[1, 2], MergeMode::default(), 3);
    println!("far: level {:?}, stats {:?}", r.level, r.stats);
    s.check(3, &[1, 2]);
    s.leaves_once(3, &[1, 2]);
    let rays = s.compare(3, &[1, 2], FAR_RAYS, 5, 1);
    rays.print("far");
    assert!(rays.hits > rays.rays / 10);
}
