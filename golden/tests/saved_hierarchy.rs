//! Saved hierarchies (SPEC 16): a saved and loaded hierarchy is the built
//! one bit for bit on the shared meshes and generated scenes at several
//! parameter sets; every class of bad file (wrong magic, version or
//! parameters, truncation, trailing bytes, a flipped byte, records that are
//! well sealed but wrong, another mesh, another grid) is refused with an
//! error naming the file, the field and its offset.

use std::path::Path;

use glam::Vec3;
use golden::build::{build, GridMap};
use golden::mesh::Mesh;
use golden::saved::{self, from_bytes, to_bytes, LoadError, HEADER_BYTES, MAGIC};
use golden::scenes::{self, shared_mesh_path, sphere};
use golden::store::Hierarchy;
use golden::Params;

fn fitted(mesh: &Mesh, p: &Params, id: u8) -> (GridMap, Hierarchy) {
    let (lo, hi) = mesh.bounds();
    let grid = GridMap::fit(lo, hi, p);
    (grid, build(mesh, &grid, p, id).expect("builds"))
}

fn load(name: &str) -> Mesh {
    Mesh::load(&shared_mesh_path(name)).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn saved_and_loaded_is_the_built_hierarchy_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let meshes = [
        ("bunny", load("bunny.obj")),
        ("teapot", load("teapot.obj")),
        ("hard cases", scenes::hard_cases(300, 5)),
        ("terrain", scenes::terrain(40, 2)),
    ];
    let configs = [
        (16, 8, 24, 4),
        (8, 0, 24, 4),
        (12, 16, 32, 8),
        (20, 3, 17, 1),
    ];
    for (name, mesh) in &meshes {
        for (k, &(d, q, i, h)) in configs.iter().enumerate() {
            let p = Params::new(d, q, i, h).unwrap();
            let id = (k as u8) % (1 << h);
            let (grid, built) = fitted(mesh, &p, id);
            let file = dir.path().join(format!("{name}_{k}.hmh"));
            saved::save(&file, &built, &grid, mesh).unwrap();
            let s = saved::load(&file, mesh).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(
                s.hierarchy == built,
                "{name} {}: hierarchy differs",
                p.tag()
            );
            assert_eq!(s.grid, grid, "{name}: grid");
            assert_eq!(s.triangles, mesh.triangles.len() as u64);
            s.require(&file.display().to_string(), &p, &grid, id)
                .unwrap();
            // Writing what was read gives the same bytes.
            let bytes = std::fs::read(&file).unwrap();
            assert_eq!(to_bytes(&s.hierarchy, &s.grid, mesh).unwrap(), bytes);
        }
    }
    // Atomic writes: nothing but the files themselves in the folder.
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        meshes.len() * configs.len()
    );
}

/// A small hierarchy and its file bytes.
fn sample() -> (Mesh, Params, GridMap, Hierarchy, Vec<u8>) {
    let mesh = sphere(Vec3::splat(0.5), 0.4, 8, 16);
    let p = Params::new(10, 6, 24, 4).unwrap();
    let (grid, h) = fitted(&mesh, &p, 3);
    let bytes = to_bytes(&h, &grid, &mesh).unwrap();
    (mesh, p, grid, h, bytes)
}

/// Recomputes the checksum, so that the corruption is seen by a later rule.
fn reseal(mut b: Vec<u8>) -> Vec<u8> {
    saved::seal(&mut b);
    b
}

fn refused(b: &[u8]) -> LoadError {
    from_bytes(b, "x.hmh").expect_err("refused")
}

fn expect(e: &LoadError, offset: Option<u64>, field: &str, text: &str) {
    assert_eq!(e.file, "x.hmh", "{e}");
    assert_eq!(e.offset, offset, "{e}");
    assert!(e.field.starts_with(field), "field {:?}: {e}", e.field);
    let msg = e.to_string();
    assert!(msg.contains(text), "{msg:?} lacks {text:?}");
    assert!(msg.starts_with("x.hmh: "), "{msg}");
}

#[test]
fn every_class_of_bad_file_is_refused_naming_field_and_offset() {
    let (_, p, _, h, good) = sample();
    let n = good.len();
    assert!(from_bytes(&good, "x.hmh").is_ok());

    // Not a saved hierarchy at all, or an empty file.
    let mut b = good.clone();
    b[3] = b'X';
    expect(&refused(&b), Some(0), "magic", "HIERMRGH");
    expect(&refused(b"{\"grid\": 1}"), Some(0), "magic", "found 7b22");
    expect(&refused(&[]), Some(0), "magic", "an empty file");
    // Another version.
    let mut b = good.clone();
    b[8] = 2;
    expect(&refused(&b), Some(8), "version", "expected 1");
    // Truncated: in the header, in the records, in the checksum.
    for cut in [12, HEADER_BYTES - 1, HEADER_BYTES + 7, n - 33, n - 1] {
        let e = refused(&good[..cut]);
        assert!(e.to_string().contains("truncated"), "cut {cut}: {e}");
    }
    expect(
        &refused(&good[..100]),
        Some(100),
        "header",
        "at least 152 bytes",
    );
    expect(
        &refused(&good[..n - 1]),
        Some(n as u64 - 1),
        "length (truncated)",
        "expected",
    );
    // Bytes after the checksum.
    let mut b = good.clone();
    b.push(0);
    expect(
        &refused(&b),
        Some(n as u64),
        "length (too long)",
        "after the checksum",
    );
    // A flipped bit anywhere past the parameters: the checksum.
    for at in [17, 30, 70, HEADER_BYTES + 5, n - 40, n - 3] {
        let mut b = good.clone();
        b[at] ^= 0x10;
        let e = refused(&b);
        expect(&e, Some(n as u64 - 32), "checksum", "the file is corrupt");
    }
    // Parameters out of range, or changed (records of another width).
    let mut b = good.clone();
    b[12] = 40;
    expect(&refused(&b), Some(12), "max_lod", "1..=31");
    let mut b = good.clone();
    b[15] = 0;
    expect(&refused(&b), Some(15), "hier_bits", "found 0");
    let mut b = good.clone();
    b[13] = p.quant_bits + 1;
    expect(&refused(&b), Some(n as u64), "length", "nodes of");

    // Well sealed but wrong: the format's own rules.
    let cases: [(usize, Vec<u8>, &str, &str); 4] = [
        (16, vec![200], "hierarchy id", "below 2^H = 16"),
        (
            20,
            (h.nodes.len() as u32 + 1).to_le_bytes().to_vec(),
            "root_count",
            "at most the node count",
        ),
        (
            48,
            (-1.0f64).to_bits().to_le_bytes().to_vec(),
            "grid unit",
            "finite and > 0",
        ),
        (18, vec![1], "reserved", "zero bytes"),
    ];
    for (at, patch, field, text) in cases {
        let mut b = good.clone();
        b[at..at + patch.len()].copy_from_slice(&patch);
        expect(&refused(&reseal(b)), Some(at as u64), field, text);
    }
    // A node record field out of range: its lod (bits 1.. of the record).
    let node_bytes = golden::layout::NodeLayout::new(&p).width().div_ceil(8) as usize;
    let at = HEADER_BYTES + 2 * node_bytes;
    let mut b = good.clone();
    b[at] |= 0b1111_1110;
    let e = refused(&reseal(b));
    expect(&e, Some(at as u64), "node 2 ", "expected");
    // A primitive index past the mesh's triangles.
    let mut b = good.clone();
    let last_prim = n - 32 - 4;
    b[last_prim..last_prim + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    let e = refused(&reseal(b));
    let i = h.prims.len() - 1;
    expect(
        &e,
        Some(last_prim as u64),
        &format!("primitive index {i}"),
        "below the triangle count",
    );
}

#[test]
fn load_refuses_another_mesh_other_parameters_and_what_the_checker_refuses() {
    let (mesh, p, grid, h, good) = sample();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("s.hmh");
    std::fs::write(&file, &good).unwrap();
    let name = file.display().to_string();
    let s = saved::load(&file, &mesh).unwrap();
    // Another mesh: the triangle count, then the digest.
    let e = saved::load(&file, &sphere(Vec3::splat(0.5), 0.4, 8, 15)).unwrap_err();
    assert_eq!((e.offset, e.field.as_str()), (Some(56), "triangles"), "{e}");
    let mut moved = mesh.clone();
    moved.vertices[5].x += 1e-3;
    let e = saved::load(&file, &moved).unwrap_err();
    assert_eq!(
        (e.offset, e.field.as_str()),
        (Some(64), "mesh digest"),
        "{e}"
    );
    assert!(e.to_string().starts_with(&name), "{e}");
    // What the caller builds with.
    let other = Params::new(11, 6, 24, 4).unwrap();
    let e = s.require(&name, &other, &grid, 3).unwrap_err();
    assert_eq!((e.offset, e.field.as_str()), (Some(12), "max_lod"), "{e}");
    let half = GridMap {
        unit: grid.unit * 0.5,
        ..grid
    };
    let e = s.require(&name, &p, &half, 3).unwrap_err();
    assert_eq!((e.offset, e.field.as_str()), (Some(48), "grid unit"), "{e}");
    let e = s.require(&name, &p, &grid, 4).unwrap_err();
    assert_eq!(
        (e.offset, e.field.as_str()),
        (Some(16), "hierarchy id"),
        "{e}"
    );
    // A leaf whose box no longer holds its triangles: sealed, so only the
    // checker sees it.
    let leaf = h.nodes.iter().position(|n| n.leaf).unwrap();
    let mut bad = h.clone();
    let n = &mut bad.nodes[leaf];
    n.hi = n.lo;
    std::fs::write(&file, to_bytes(&bad, &grid, &mesh).unwrap()).unwrap();
    let e = saved::load(&file, &mesh).unwrap_err();
    assert_eq!(e.field, "checker (SPEC 5)", "{e}");
    assert!(e.to_string().contains(&format!("node {leaf}")), "{e}");
    // Not a regular file; a merged hierarchy cannot be saved.
    let e = saved::load(Path::new("/dev/zero"), &mesh).unwrap_err();
    assert!(e.to_string().contains("character device"), "{e}");
    let mut merged = h.clone();
    merged.refs[0].hier = 1;
    let e = to_bytes(&merged, &grid, &mesh).unwrap_err();
    assert!(e.contains("only a hierarchy whose references"), "{e}");
    assert_eq!(&good[..8], &MAGIC);
}
