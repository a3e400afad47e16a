//! Seeded random merges: random parameters (Q = 0 included), 1 to 5 inputs
//! of random meshes, random translations at random levels at or above each
//! input's top, random modes (invalid ones included). Every merge either
//! passes the checker, reaches every input leaf exactly once and traces like
//! the separate inputs and brute force, or is refused with an error that
//! the case explains; nothing panics.

mod merge_support;

use glam::Vec3;
use golden::merge::fetcher::walk::{collect, walk_input};
use golden::merge::level_choice::{candidate_range, overlaps, overlaps_pruned};
use golden::merge::{merge, MergeError, MergeMode};
use golden::mesh::Mesh;
use golden::params::Params;
use golden::scenes::{random_soup, sphere, torus, SplitMix64};
use golden::seed::seeded;
use golden::store::Hierarchy;
use golden::translate::{TranslateError, Translation};
use merge_support::{normalized, Scene};

fn random_mesh(r: &mut SplitMix64, size: f32) -> Mesh {
    let m = match r.below(4) {
        0 => random_soup(
            1 + r.below(60) as usize,
            0.05 + r.next_f64() as f32 * 0.3,
            r.next_u64(),
        ),
        1 => sphere(
            Vec3::ZERO,
            1.0,
            4 + r.below(8) as u32,
            5 + r.below(8) as u32,
        ),
        2 => torus(
            Vec3::ZERO,
            2.0,
            0.6,
            6 + r.below(8) as u32,
            4 + r.below(5) as u32,
        ),
        _ => random_soup(1, 0.01, r.next_u64()),
    };
    normalized(&m, size, size * 0.1)
}

fn random_mode(r: &mut SplitMix64) -> MergeMode {
    let ratio = |r: &mut SplitMix64| {
        let den = 1 + r.below(5) as u32;
        (r.below(den as u64 + 2) as u32, den) // num may exceed den: refused
    };
    match r.below(5) {
        0 => {
            let (num, den) = ratio(r);
            MergeMode::Overlap { num, den }
        }
        1 => MergeMode::Fixed(r.below(17) as u8),
        2 => MergeMode::BelowTop(r.below(6) as u8),
        3 => {
            let (num, den) = ratio(r);
            MergeMode::Proportion { num, den }
        }
        _ => {
            let (num, den) = ratio(r);
            MergeMode::PerNode { num, den }
        }
    }
}

/// The overlap mode's pruned counts equal the plain k-way stream counts
/// over every translated node of every candidate level.
fn pruned_overlaps_equal_streamed(s: &Scene, inputs: &[u8]) {
    let hs: Vec<&Hierarchy> = inputs.iter().map(|i| s.store.get(*i).unwrap()).collect();
    let ts: Vec<Translation> = inputs
        .iter()
        .map(|i| s.table.read(*i as u32).unwrap())
        .collect();
    let (lo, hi) = candidate_range(&hs);
    let walked: Result<Vec<_>, _> = hs
        .iter()
        .zip(&ts)
        .enumerate()
        .map(|(k, (h, t))| walk_input(h, k as u16, t, hi))
        .collect();
    let Ok(walked) = walked else { return }; // a translation out of the scene
    let (_, at_lo) = collect(&walked, lo);
    assert_eq!(
        overlaps_pruned(&hs, &ts, at_lo, lo, hi),
        Ok(overlaps(&walked, lo, hi))
    );
}

#[test]
fn random_merges_check_and_trace_or_are_refused() {
    let mut r = SplitMix64::new(seeded(2024));
    let (mut merged, mut refused) = (0, 0);
    for case in 0..400 {
        let d = [8u8, 12, 16][r.below(3) as usize];
        let q = [0u8, 4, 8][r.below(3) as usize];
        let p = Params::new(d, q, 24, 4).unwrap();
        // A scene of 256 world units; meshes of 2 to 40 units near the origin.
        let unit = 256.0 / p.scene_edge() as f64;
        let mut s = Scene::new(p, unit);
        let k = 1 + r.below(5) as u8;
        for id in 1..=k {
            let size = 2.0 + r.next_f64() as f32 * 38.0;
            s.add(id, random_mesh(&mut r, size), [0, 0, 0]);
            let top = s.top(id);
            let lod = top - r.below(top.min(3) as u64 + 1) as u8;
            // Anywhere in the scene, now and then one voxel too far.
            let span = 1i64 << lod;
            let t =
                [0; 3].map(|_| r.below(span as u64) as i64 / 2 + (r.below(40) == 0) as i64 * span);
            s.table.write(id as u32, Translation { lod, t }).unwrap();
        }
        let inputs: Vec<u8> = (1..=k).collect();
        pruned_overlaps_equal_streamed(&s, &inputs);
        let mode = random_mode(&mut r);
        match merge(&s.store, &inputs, &s.table, mode, 15) {
            Ok(res) => {
                s.store.insert(res.merged.clone()).unwrap();
                let rep = s.check(15, &inputs);
                assert_eq!(rep.leaves, s.leaves_once(15, &inputs), "case {case}");
                s.compare(15, &inputs, 200, case, 1);
                merged += 1;
            }
            Err(e) => {
                let explained = match &e {
                    MergeError::TranslateNode {
                        error: TranslateError::NodeOutsideScene { .. },
                        ..
                    } => true,
                    MergeError::LevelNotCandidate { .. } | MergeError::BelowTopTooDeep { .. } => {
                        true
                    }
                    MergeError::BadRatio { num, den, .. } => num > den || *den == 0,
                    _ => false,
                };
                assert!(explained, "case {case} {mode:?}: unexpected refusal {e}");
                assert!(!e.to_string().is_empty());
                refused += 1;
            }
        }
    }
    println!("{merged} merged, {refused} refused");
    assert!(
        merged >= 40 && refused >= 10,
        "{merged} merged, {refused} refused"
    );
}
