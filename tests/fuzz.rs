//! Fuzz targets, one per parser (issue 21): OBJ, PLY, scene files, vector
//! files, ledger entries, saved hierarchies, and the values of
//! `merge --translate`/`--mode` (and of `cosim --stalls`).
//!
//! Each target replays its seeds (real files: the shared meshes, the
//! repository's scenes and ledger entries, generated vector files) and every
//! input kept under `tests/fuzz/<target>/` (crashes found earlier, each a
//! test from then on), then mutates seeds (bytes set, inserted, removed,
//! duplicated, spliced from another seed, truncated) for a time budget:
//! `HIERMERGE_FUZZ_SECONDS` per target, 0.5 s by default (CI). A target
//! passes when no input panics and every error names the file it is about.
//! An input that fails is written to `out/fuzz/<target>/` and named; copy it
//! to `tests/fuzz/<target>/` with the fix. README.md gives the long command.

#[path = "../src/cmd/merge_args.rs"]
#[allow(dead_code)]
mod merge_args;

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use golden::scenes::SplitMix64;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A shared mesh, with a clear message when the checkout has no `../shared`.
fn shared(name: &str) -> Vec<u8> {
    let p = golden::scenes::shared_mesh_path(name);
    std::fs::read(&p).unwrap_or_else(|e| {
        panic!(
            "{}: {e}: the fuzz seeds need the project's shared/ folder beside the checkout",
            p.display()
        )
    })
}

fn budget() -> Duration {
    let s = std::env::var("HIERMERGE_FUZZ_SECONDS")
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        .unwrap_or(0.5);
    Duration::from_secs_f64(s.max(0.0))
}

/// Bytes worth inserting: separators, digits, signs, and each format's
/// structure characters.
const INTERESTING: &[u8] = b" \n\t/-+0123456789.eE#vf{}[]:,\"\\xnulaiply";

fn mutate(rng: &mut SplitMix64, seeds: &[Vec<u8>], bytes: &mut Vec<u8>) {
    for _ in 0..1 + rng.below(6) {
        let n = bytes.len().max(1) as u64;
        let at = rng.below(n) as usize;
        match rng.below(7) {
            0 if !bytes.is_empty() => bytes[at] = rng.below(256) as u8,
            1 => bytes.insert(
                at.min(bytes.len()),
                INTERESTING[rng.below(INTERESTING.len() as u64) as usize],
            ),
            2 if !bytes.is_empty() => {
                bytes.remove(at);
            }
            3 => {
                let len = (rng.below(16) as usize).min(bytes.len() - at.min(bytes.len()));
                let chunk: Vec<u8> = bytes[at.min(bytes.len())..at.min(bytes.len()) + len].to_vec();
                let to = rng.below(bytes.len() as u64 + 1) as usize;
                bytes.splice(to..to, chunk);
            }
            4 => {
                let other = &seeds[rng.below(seeds.len() as u64) as usize];
                if !other.is_empty() {
                    let from = rng.below(other.len() as u64) as usize;
                    let len = (rng.below(64) as usize).min(other.len() - from);
                    let to = at.min(bytes.len());
                    bytes.splice(to..to, other[from..from + len].iter().copied());
                }
            }
            5 if !bytes.is_empty() && rng.below(4) == 0 => bytes.truncate(at),
            _ => {
                // A digit run: numbers at the edges of their types.
                let to = at.min(bytes.len());
                let digits = [
                    "0",
                    "-1",
                    "255",
                    "65536",
                    "4294967296",
                    "1e39",
                    "nan",
                    "99999999999999999999",
                ];
                let d = digits[rng.below(digits.len() as u64) as usize];
                bytes.splice(to..to, d.bytes());
            }
        }
    }
}

/// Runs `target` on its seeds, its kept inputs, then mutations for the
/// budget. `check` returns `Err` for a wrong answer; a panic is caught.
fn fuzz(name: &str, seeds: Vec<Vec<u8>>, check: impl Fn(&[u8]) -> Result<(), String>) {
    let kept = repo().join("tests/fuzz").join(name);
    let mut replay = seeds.clone();
    if let Ok(dir) = std::fs::read_dir(&kept) {
        for f in dir {
            replay.push(std::fs::read(f.unwrap().path()).unwrap());
        }
    }
    let run = |input: &[u8]| -> Result<(), String> {
        match catch_unwind(AssertUnwindSafe(|| check(input))) {
            Ok(r) => r,
            Err(p) => Err(format!(
                "panicked: {}",
                p.downcast_ref::<String>()
                    .cloned()
                    .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default()
            )),
        }
    };
    let fail = |input: &[u8], why: String| -> ! {
        let dir = repo().join("out/fuzz").join(name);
        std::fs::create_dir_all(&dir).unwrap();
        let digest: u64 = input.iter().fold(0xcbf29ce484222325, |h, &b| {
            (h ^ b as u64).wrapping_mul(0x100000001b3)
        });
        let path = dir.join(format!("crash-{digest:016x}"));
        std::fs::write(&path, input).unwrap();
        panic!("{name}: {why}\ninput kept in {}", path.display());
    };
    for input in &replay {
        if let Err(why) = run(input) {
            fail(input, why);
        }
    }
    let seed = golden::seed::seeded(1);
    let mut rng = SplitMix64::new(seed);
    let (start, budget) = (Instant::now(), budget());
    let mut cases = 0u64;
    while start.elapsed() < budget {
        let mut bytes = seeds[rng.below(seeds.len() as u64) as usize].clone();
        mutate(&mut rng, &seeds, &mut bytes);
        if let Err(why) = run(&bytes) {
            fail(&bytes, why);
        }
        cases += 1;
    }
    eprintln!(
        "{name}: {} seeds and kept inputs, {cases} mutations in {:.1} s (seed {seed})",
        replay.len(),
        start.elapsed().as_secs_f64()
    );
}

/// An error must start with the name of the file it is about.
fn names(file: &str, r: Result<(), String>) -> Result<(), String> {
    match r {
        Err(e) if !e.starts_with(file) => Err(format!("an error without the file: {e}")),
        _ => Ok(()),
    }
}

fn mesh_check(
    parse: fn(&[u8], &str) -> Result<golden::mesh::Mesh, golden::mesh::MeshError>,
) -> impl Fn(&[u8]) -> Result<(), String> {
    move |bytes| match parse(bytes, "fuzz") {
        Ok(m) => m
            .validate("fuzz")
            .map_err(|e| format!("accepted, invalid: {e}")),
        Err(e) => names("fuzz", Err(e.to_string())),
    }
}

#[test]
fn fuzz_obj() {
    let seeds = vec![
        shared("teapot.obj"),
        shared("bunny.obj"),
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 1\nf 1/1/1 2//2 3/3 -1\nf -4 -3 -2\n".to_vec(),
    ];
    fuzz("obj", seeds, mesh_check(golden::mesh::parse_obj));
}

#[test]
fn fuzz_ply() {
    use golden::mesh::{parse_obj, write_ply, PlyFormat};
    let teapot = parse_obj(&shared("teapot.obj"), "teapot.obj").unwrap();
    let bunny = parse_obj(&shared("bunny.obj"), "bunny.obj").unwrap();
    let tiny = parse_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "t").unwrap();
    let seeds = vec![
        write_ply(&teapot, PlyFormat::Ascii),
        write_ply(&teapot, PlyFormat::BinaryLittleEndian),
        write_ply(&bunny, PlyFormat::BinaryLittleEndian),
        write_ply(&tiny, PlyFormat::Ascii),
        write_ply(&tiny, PlyFormat::BinaryLittleEndian),
    ];
    fuzz("ply", seeds, mesh_check(golden::mesh::parse_ply));
}

#[test]
fn fuzz_scene() {
    let dir = repo().join("scenes");
    let mut seeds = Vec::new();
    for f in std::fs::read_dir(&dir).unwrap() {
        let p = f.unwrap().path();
        if p.extension().is_some_and(|x| x == "json") {
            seeds.push(std::fs::read(&p).unwrap());
        }
    }
    assert!(!seeds.is_empty(), "no scene in {}", dir.display());
    fuzz("scene", seeds, |bytes| {
        let text = String::from_utf8_lossy(bytes);
        let r = golden::scene::Scene::parse(&text, "fuzz.json", &dir).map(|_| ());
        names("fuzz.json", r.map_err(|e| e.to_string()))
    });
}

/// Packs every record of `txns` into its ports, as cosim does.
fn pack_all(
    d: &golden::translate::model::TranslateDesign,
    txns: &[golden::translate::model::TranslateTxn],
) -> Result<(), String> {
    use golden::translate::model::TranslateTxn;
    use rtl_gen::translate::ports::{pack_apply_in, pack_apply_out, pack_det_in, pack_det_out};
    for (i, t) in txns.iter().enumerate() {
        let r = match t {
            TranslateTxn::Determine(r) => {
                pack_det_in(d, &r.inputs).and_then(|_| pack_det_out(d, &r.outputs))
            }
            TranslateTxn::Apply(r) => {
                pack_apply_in(d, &r.inputs).and_then(|_| pack_apply_out(d, &r.outputs))
            }
        };
        r.map_err(|e| format!("transaction {i}: {e}"))?;
    }
    Ok(())
}

#[test]
fn fuzz_vectors() {
    use golden::merge::merge_module::MergeDesign;
    use golden::translate::model::TranslateDesign;
    use golden::vectors::merge::{read_merge_vectors, write_merge_vectors};
    use golden::vectors::translate::{read_translate_vectors, write_translate_vectors};
    let dir = tempfile::tempdir().unwrap();
    let (td, md) = (TranslateDesign::default(), MergeDesign::default());
    let t = dir.path().join("t.jsonl");
    let m = dir.path().join("m.jsonl");
    write_translate_vectors(&t, &td, 3, 40).unwrap();
    write_merge_vectors(&m, &md, 3, 4).unwrap();
    let seeds = vec![std::fs::read(&t).unwrap(), std::fs::read(&m).unwrap()];
    let case = dir.path().join("fuzz.jsonl");
    let shown = case.display().to_string();
    fuzz("vectors", seeds, |bytes| {
        std::fs::write(&case, bytes).unwrap();
        // What the reader accepts fits the ports: packing it cannot fail
        // (cosim's "does not fit the design's ports" is unreachable).
        let a = match read_translate_vectors(&case, &td) {
            Ok((_, txns)) => {
                pack_all(&td, &txns).map_err(|w| format!("accepted, does not fit the ports: {w}"))
            }
            Err(e) => Err(e.to_string()),
        };
        if let Err(w) = &a {
            if w.starts_with("accepted") {
                return a;
            }
        }
        names(&shown, a)?;
        let b = read_merge_vectors(&case, &md).map(|_| ());
        names(&shown, b.map_err(|e| e.to_string()))
    });
}

#[test]
fn fuzz_ledger_entry() {
    let ledger = repo().join("longruns");
    let mut seeds = Vec::new();
    for top in std::fs::read_dir(&ledger).unwrap() {
        let top = top.unwrap().path();
        if top.is_dir() {
            let first = std::fs::read_dir(&top)
                .unwrap()
                .next()
                .unwrap()
                .unwrap()
                .path();
            seeds.push(std::fs::read(first).unwrap());
        }
    }
    assert!(!seeds.is_empty(), "no entry in {}", ledger.display());
    let dir = tempfile::tempdir().unwrap();
    let folder = dir
        .path()
        .join("hierarchy_merger_d16_q8_i24_h4_k4_ov1_2_r16_f256_c10_l4");
    std::fs::create_dir(&folder).unwrap();
    let case = folder.join("iverilog-seed1000-n10000.json");
    let shown = case.display().to_string();
    fuzz("ledger_entry", seeds, |bytes| {
        std::fs::write(&case, bytes).unwrap();
        let r = cosim::ledger::read_entry(dir.path(), &case).map(|_| ());
        names(&shown, r)
    });
}

/// Saved hierarchies (SPEC 16): every mutation is read twice, as it is
/// (the checksum refuses nearly all) and resealed (so the header and record
/// rules and then the checker see it).
#[test]
fn fuzz_saved() {
    use golden::build::{build, GridMap};
    use golden::saved::{from_bytes, seal, to_bytes};
    let teapot = golden::mesh::parse_obj(&shared("teapot.obj"), "teapot.obj").unwrap();
    let (lo, hi) = teapot.bounds();
    let mut seeds = Vec::new();
    for (d, q) in [(10, 4), (6, 0)] {
        let p = golden::Params::new(d, q, 24, 4).unwrap();
        let grid = GridMap::fit(lo, hi, &p);
        let h = build(&teapot, &grid, &p, 2).unwrap();
        seeds.push(to_bytes(&h, &grid, &teapot).unwrap());
    }
    fuzz("saved", seeds, |bytes| {
        let r = from_bytes(bytes, "fuzz.hmh").map(|_| ());
        names("fuzz.hmh", r.map_err(|e| e.to_string()))?;
        let mut sealed = bytes.to_vec();
        seal(&mut sealed);
        match from_bytes(&sealed, "fuzz.hmh") {
            Ok(s) => {
                // The checker takes any hierarchy the format accepts, as `load` runs it.
                let p = &s.hierarchy.params;
                if let Ok(tris) = s.grid.mesh_to_grid(&teapot, p) {
                    let _ = golden::check::check_built(&s.hierarchy, &tris);
                }
                Ok(())
            }
            Err(e) => names("fuzz.hmh", Err(e.to_string())),
        }
    });
}

#[test]
fn fuzz_merge_args() {
    let seeds: Vec<Vec<u8>> = [
        "overlap:1/2",
        "overlap",
        "fixed:4",
        "below-top:2",
        "proportion:1/3",
        "per-node:1/2",
        "1.5,-2,3e3",
        "-1e19,0,0",
        "bursty:16,16",
        "periodic:1/3",
        "coin:0.3",
    ]
    .iter()
    .map(|s| s.as_bytes().to_vec())
    .collect();
    fuzz("merge_args", seeds, |bytes| {
        let text = String::from_utf8_lossy(bytes);
        if let Ok(golden::merge::MergeMode::Overlap { den: 0, .. }) = merge_args::parse_mode(&text)
        {
            return Err("a ratio with denominator 0 accepted".into());
        }
        if let Ok(v) = merge_args::parse_vec3(&text) {
            if !v.is_finite() {
                return Err(format!("a translation that is not finite accepted: {v}"));
            }
        }
        // `cosim --stalls`: what is accepted is in range and reads back.
        if let Ok(s) = cosim::tb::Stalls::parse(&text, 0.3) {
            s.check()?;
            if cosim::tb::Stalls::parse(&s.to_string(), 0.3) != Ok(s) {
                return Err(format!("`{text}` read as {s}, which does not read back"));
            }
        }
        Ok(())
    });
}
