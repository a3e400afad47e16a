//! Accepted means runnable (issue 19 item 5, SPEC 12.1): generated scenes
//! at the grid's limits (tiny to grid-filling objects, placements on and
//! near the scene cube's faces and corners, floors as large as a small
//! cube, far grid origins where binary32 rounding is coarse, several frames
//! of motion) are each either refused while the scene file is read, at the
//! JSON path of the element at fault, or run through the golden model to
//! the end without an error or a mismatch (`hiermerge::run` with
//! `Options::rtl` false: what `hiermerge run --no-rtl` does).
//!
//! `HIERMERGE_SCENE_CASES` (default 500) sets the number of scenes,
//! `HIERMERGE_SCENE_SEED` the seed (default 19, moved by `HIERMERGE_SEED`);
//! the seed is printed, and a failure prints the case's scene file.

use std::path::Path;

use golden::scene::Scene;
use golden::scenes::SplitMix64;
use hiermerge::run::{preflight, run, Options};
use serde_json::{json, Value};

fn env_u64(name: &str, default: u64) -> u64 {
    match std::env::var(name) {
        Ok(v) => golden::seed::parse_seed(&v)
            .unwrap_or_else(|e| panic!("{name}={v}: expected an integer ({e})")),
        Err(_) => default,
    }
}

fn pick<T: Copy>(rng: &mut SplitMix64, from: &[T]) -> T {
    from[rng.below(from.len() as u64) as usize]
}

/// A length from a millionth of `side` to all of it, log-uniform, or exactly `side`.
fn length(rng: &mut SplitMix64, side: f64) -> f64 {
    if rng.below(6) == 0 {
        side
    } else {
        side * 10f64.powf(-6.0 * rng.next_f64())
    }
}

/// A low corner coordinate for an extent `size` in a cube `[o, o + side]`
/// kept `pad` inside it: on either face, a hair inside or (without a pad,
/// rarely) outside one, or anywhere between.
fn corner(rng: &mut SplitMix64, o: f64, side: f64, size: f64, voxel: f64, pad: f64) -> f64 {
    let room = (side - size - 2.0 * pad).max(0.0);
    let hair = voxel * pick(rng, &[1e-9, 1e-4, 0.5, 1.0]);
    // A hair past a face rarely: three axes of several objects multiply it.
    let out = if pad == 0.0 && rng.below(40) == 0 {
        -1.0
    } else {
        1.0
    };
    o + pad
        + match rng.below(5) {
            0 => 0.0,
            1 => room,
            2 => (out * hair).min(room),
            3 => (room - out * hair).max(0.0),
            _ => room * rng.next_f64(),
        }
}

/// One object's shape, local mesh inside the cube `[o, o + side]` (or a
/// hair past a face), and its low/high corners.
fn shape(
    rng: &mut SplitMix64,
    o: [f64; 3],
    side: f64,
    voxel: f64,
    pad: f64,
) -> (Value, [f64; 3], [f64; 3]) {
    let floor = rng.below(4) == 0;
    let size: [f64; 3] = std::array::from_fn(|a| {
        if floor {
            if a == 1 {
                (side * 1e-3).max(voxel * 0.01)
            } else {
                side * pick(rng, &[1.0, 0.999, 0.75])
            }
        } else {
            length(rng, side)
        }
        .min(side - 2.0 * pad)
    });
    let lo: [f64; 3] = std::array::from_fn(|a| corner(rng, o[a], side, size[a], voxel, pad));
    let hi: [f64; 3] = std::array::from_fn(|a| lo[a] + size[a]);
    if floor || rng.below(2) == 0 {
        return (json!({"box": {"lo": lo, "hi": hi}}), lo, hi);
    }
    let r = size[0] / 2.0;
    let c = [lo[0] + r, lo[1] + r, lo[2] + r];
    let stacks = 2 + rng.below(3);
    let slices = 3 + rng.below(4);
    let s = json!({"sphere": {"center": c, "radius": r, "stacks": stacks, "slices": slices}});
    (
        s,
        [c[0] - r, c[1] - r, c[2] - r],
        [c[0] + r, c[1] + r, c[2] + r],
    )
}

/// Offsets over `frames` for an object at `[lo, hi]` in the cube: moves by
/// fractions of a voxel and by whole voxels, to touch a face or a hair past it.
fn offsets(
    rng: &mut SplitMix64,
    frames: usize,
    lohi: ([f64; 3], [f64; 3]),
    cube: ([f64; 3], f64),
    voxel: f64,
    pad: f64,
) -> Vec<[f64; 3]> {
    let (lo, hi) = lohi;
    let (o, side) = cube;
    (0..frames)
        .map(|_| {
            std::array::from_fn(|a| {
                let out = if pad == 0.0 && rng.below(25) == 0 {
                    -1.0
                } else {
                    1.0
                };
                let hair = out * voxel * pick(rng, &[0.0, 1e-9, 1e-3, 0.5]);
                let sign = if rng.below(2) == 0 { 1.0 } else { -1.0 };
                let (least, most) = (o[a] - lo[a] + pad, o[a] + side - hi[a] - pad);
                let v = match rng.below(6) {
                    0 => 0.0,
                    1 => most - hair,
                    2 => least + hair,
                    3 => sign * voxel * (rng.below(5) as f64 + pick(rng, &[0.0, 0.25, 0.5])),
                    4 => sign * hair.abs(),
                    _ => least + (most - least) * rng.next_f64(),
                };
                // With a pad, whole-voxel moves stay in the cube too.
                if pad > 0.0 && least <= most {
                    v.clamp(least, most)
                } else {
                    v
                }
            })
        })
        .collect()
}

/// A generated scene file.
fn scene(rng: &mut SplitMix64) -> Value {
    let d = 3 + rng.below(10) as u32;
    let q = rng.below(9) as u32;
    let unit = pick(rng, &[1.0, 0.25, 0.1, 1.0 / 3.0, 1e-3, 4.75]);
    let side = (1u64 << d) as f64 * unit;
    let o: [f64; 3] = match rng.below(4) {
        0 => [0.0; 3],
        1 => [-side / 2.0; 3],
        2 => [1e6, -3e5, 2.5e4],
        _ => std::array::from_fn(|_| (rng.next_f64() - 0.5) * 200.0),
    };
    // The finest voxel at D = 12 with unit 1e-3, and a coarser one.
    let voxel = unit * pick(rng, &[1.0, (1u64 << (d / 2)) as f64]);
    // Two scenes in three keep a few binary32 ulps of the coordinates
    // inside the faces; the others go to the faces and a hair past them.
    let magnitude = o.iter().fold(0f64, |m, c| m.max(c.abs())) + 2.0 * side;
    let pad = if rng.below(3) == 0 {
        0.0
    } else {
        magnitude * 2f64.powi(-21)
    };
    let frames = 1 + rng.below(4) as usize;
    let n = 1 + rng.below(4) as usize;
    let mut objects = Vec::new();
    for i in 0..n {
        let (shape, lo, hi) = shape(rng, o, side, voxel, pad);
        let dynamic = rng.below(3) != 0;
        let offs = offsets(
            rng,
            if dynamic { frames } else { 1 },
            (lo, hi),
            (o, side),
            voxel,
            pad,
        );
        objects.push(json!({
            "name": format!("o{i}"),
            "motion": if dynamic { "dynamic" } else { "static" },
            "shape": shape,
            "placement": {"offsets": offs},
        }));
    }
    let mode = pick(rng, &["overlap", "proportion", "per_node"]);
    let mode = json!({"mode": mode, "num": 1, "den": 2});
    let mut units = json!({"translation": rng.below(5) != 0, "merge": mode, "upper_build": false});
    if n >= 2 && rng.below(2) == 0 {
        let names: Vec<String> = (0..n).map(|i| format!("o{i}")).collect();
        let cut = 1 + rng.below(n as u64 - 1) as usize;
        units["groups"] = json!([names[..cut], names[cut..]]);
    }
    let c = [o[0] + side / 2.0, o[1] + side / 2.0, o[2] + side / 2.0];
    json!({
        "grid": {"max_lod": d, "quant_bits": q, "unit": unit, "origin": o},
        "frames": frames,
        "image": {"width": 4, "height": 3},
        "camera": {"eye": [c[0], c[1] + side, c[2] - 2.0 * side], "target": c, "fov_y_degrees": 60},
        "lights": [{"position": [c[0], c[1] + 2.0 * side, c[2]]}],
        "objects": objects,
        "effects": {
            "units": units,
            "rays": {"primary": true, "shadow": rng.below(4) == 0, "clip_distance": 10.0 * side},
        },
    })
}

/// The roots of a scene file's JSON paths.
const ROOTS: &[&str] = &[
    "objects", "grid", "frames", "effects", "camera", "lights", "image",
];

#[test]
fn every_generated_scene_is_refused_at_a_path_or_runs_to_the_end() {
    let cases = env_u64("HIERMERGE_SCENE_CASES", 500);
    let seed = env_u64("HIERMERGE_SCENE_SEED", golden::seed::seeded(19));
    println!("scene_limits: {cases} scenes, HIERMERGE_SCENE_SEED={seed}");
    let mut rng = SplitMix64::new(seed);
    let dir = tempfile::tempdir().unwrap();
    let options = Options::golden_only(dir.path());
    let (mut refused, mut ran, mut frames) = (0u64, 0u64, 0u64);
    for case in 0..cases {
        let file = scene(&mut rng);
        let text = serde_json::to_string_pretty(&file).unwrap();
        let name = format!("case {case} (HIERMERGE_SCENE_SEED={seed})");
        let fail = |what: String| -> ! { panic!("{name}: {what}\nscene:\n{text}") };
        let scene = match Scene::parse(&text, &name, Path::new(".")) {
            Ok(s) => s,
            Err(e) => {
                let root = e.path.split(['.', '[']).next().unwrap_or("");
                if !ROOTS.contains(&root) || e.expected.is_empty() || e.found.is_empty() {
                    fail(format!("refused without a JSON path of the scene: {e}"));
                }
                refused += 1;
                continue;
            }
        };
        if let Err(e) = preflight::check(&scene, &name) {
            fail(format!("accepted, then refused by the preflight: {e}"));
        }
        match run(&scene, &options) {
            Ok(r) if r.mismatches == 0 => {}
            Ok(r) => fail(format!("{} mismatches", r.mismatches)),
            Err(e) => fail(format!("accepted, then failed: {e}")),
        }
        ran += 1;
        frames += scene.frames as u64;
    }
    println!("scene_limits: {ran} ran ({frames} frames), {refused} refused");
    // Both outcomes are exercised, or the generator has drifted.
    assert!(ran * 4 >= cases, "only {ran} of {cases} scenes ran");
    assert!(refused * 10 >= cases, "only {refused} of {cases} refused");
}
