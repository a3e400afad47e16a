//! Property tests: random triangle soups of every awkward kind (long thin,
//! axis-aligned on voxel boundaries, tiny, huge, degenerate, touching the
//! scene's faces) always build, and the build always passes the checker.

use glam::DVec3;
use golden::build::build_grid_triangles;
use golden::check::check_built;
use golden::scenes::SplitMix64;
use golden::Params;
use proptest::prelude::*;

/// The kinds of triangle a soup mixes.
#[derive(Clone, Copy, Debug)]
enum Kind {
    LongThin,
    AxisAligned,
    Tiny,
    Huge,
    Degenerate,
    OnSceneFaces,
}

const KINDS: [Kind; 6] = [
    Kind::LongThin,
    Kind::AxisAligned,
    Kind::Tiny,
    Kind::Huge,
    Kind::Degenerate,
    Kind::OnSceneFaces,
];

fn point(rng: &mut SplitMix64, edge: f64) -> DVec3 {
    DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * edge
}

/// One triangle of `kind` inside the closed scene cube `[0, edge]^3`.
fn triangle(kind: Kind, rng: &mut SplitMix64, edge: f64) -> [DVec3; 3] {
    let clamp = |v: DVec3| v.clamp(DVec3::ZERO, DVec3::splat(edge));
    match kind {
        Kind::LongThin => {
            let a = point(rng, edge);
            let b = point(rng, edge);
            let width = 10f64.powf(-1.0 - 6.0 * rng.next_f64());
            let side = (b - a).any_orthonormal_vector() * (b - a).length() * width;
            [a, b, clamp((a + b) * 0.5 + side)]
        }
        Kind::AxisAligned => {
            // In a plane on a voxel boundary of some LOD, legs along the axes.
            let axis = rng.below(3) as usize;
            let lod_edge = edge / (1u64 << rng.below(6)) as f64;
            let cells = (edge / lod_edge) as u64;
            let mut p = point(rng, edge);
            p[axis] = rng.below(cells + 1) as f64 * lod_edge;
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let mut b = p;
            b[u] = rng.below(cells + 1) as f64 * lod_edge;
            let mut c = p;
            c[v] = rng.below(cells + 1) as f64 * lod_edge;
            [p, b, c]
        }
        Kind::Tiny => {
            let a = point(rng, edge);
            let s = 10f64.powf(-9.0 * rng.next_f64());
            let d = |r: &mut SplitMix64| DVec3::new(r.next_f64(), r.next_f64(), r.next_f64()) * s;
            [a, clamp(a + d(rng)), clamp(a + d(rng))]
        }
        Kind::Huge => [point(rng, edge), point(rng, edge), point(rng, edge)],
        Kind::Degenerate => {
            let a = point(rng, edge);
            let b = point(rng, edge);
            match rng.below(3) {
                0 => [a, a, a],
                1 => [a, b, a],
                _ => [a, b, a + (b - a) * rng.next_f64()],
            }
        }
        Kind::OnSceneFaces => {
            let pick = |r: &mut SplitMix64| {
                let mut p = point(r, edge);
                p[r.below(3) as usize] = if r.below(2) == 0 { 0.0 } else { edge };
                p
            };
            [pick(rng), pick(rng), pick(rng)]
        }
    }
}

fn soup(kinds: &[usize], seed: u64, edge: f64) -> Vec<[DVec3; 3]> {
    let mut rng = SplitMix64::new(seed);
    kinds
        .iter()
        .map(|&k| triangle(KINDS[k], &mut rng, edge))
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn random_soups_build_and_check(
        d in prop_oneof![Just(1u8), 2u8..=20, Just(31u8)],
        q in 0u8..=16,
        kinds in prop::collection::vec(0usize..KINDS.len(), 1..30),
        seed in any::<u64>(),
    ) {
        let p = Params::new(d, q, 24, 4).unwrap();
        let tris = soup(&kinds, seed, p.scene_edge() as f64);
        let h = build_grid_triangles(&tris, &p, 3).unwrap();
        let report = check_built(&h, &tris).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert_eq!(report.prims_reached, tris.len());
        prop_assert_eq!(report.nodes, h.nodes.len());
    }

    /// One kind at a time, many triangles: dense leaves and deep sharing.
    #[test]
    fn single_kind_soups_build_and_check(
        kind in 0usize..KINDS.len(),
        d in prop_oneof![Just(4u8), Just(10u8), Just(16u8)],
        q in prop_oneof![Just(0u8), Just(3u8), Just(8u8)],
        seed in any::<u64>(),
    ) {
        let p = Params::new(d, q, 24, 4).unwrap();
        let tris = soup(&vec![kind; 60], seed, p.scene_edge() as f64);
        let h = build_grid_triangles(&tris, &p, 0).unwrap();
        check_built(&h, &tris).map_err(|e| TestCaseError::fail(e.to_string()))?;
    }
}
