//! Mesh import on the shared real meshes, PLY round trips, and a fuzz-style
//! check that neither parser panics on random or mutated input.

use golden::mesh::{parse_obj, parse_ply, write_ply, Mesh, MeshLocation, PlyFormat};
use golden::scenes::shared_mesh_path;
use proptest::prelude::*;

fn load(name: &str) -> Mesh {
    let path = shared_mesh_path(name);
    Mesh::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// Counts from /work/shared/scenes/README.md.
#[test]
fn bunny_and_teapot_have_their_published_counts() {
    let bunny = load("bunny.obj");
    assert_eq!((bunny.triangles.len(), bunny.vertices.len()), (3674, 1839));
    let teapot = load("teapot.obj");
    assert_eq!((teapot.triangles.len(), teapot.vertices.len()), (992, 792));
    for m in [&bunny, &teapot] {
        m.validate("mesh").unwrap();
        let (lo, hi) = m.bounds();
        assert!(lo.cmplt(hi).all());
    }
}

#[test]
fn bunny_ply_round_trip_ascii_and_binary() {
    let bunny = load("bunny.obj");
    let dir = tempfile::tempdir().unwrap();
    for (format, file) in [
        (PlyFormat::Ascii, "bunny_ascii.ply"),
        (PlyFormat::BinaryLittleEndian, "bunny_binary.ply"),
    ] {
        let path = dir.path().join(file);
        std::fs::write(&path, write_ply(&bunny, format)).unwrap();
        let back = Mesh::load(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(back.triangles, bunny.triangles);
        // Bit-identical positions, not merely close.
        let bits = |m: &Mesh| -> Vec<[u32; 3]> {
            m.vertices
                .iter()
                .map(|v| v.to_array().map(f32::to_bits))
                .collect()
        };
        assert_eq!(bits(&back), bits(&bunny));
    }
}

#[test]
fn load_refuses_unknown_extension_and_missing_file() {
    let e = Mesh::load(std::path::Path::new("x.stl")).unwrap_err();
    assert_eq!(e.field, "file extension");
    let e = Mesh::load(std::path::Path::new("/nonexistent/x.obj")).unwrap_err();
    assert_eq!(
        (e.field.as_str(), &e.location),
        ("file", &MeshLocation::File)
    );
    assert!(e
        .to_string()
        .starts_with("/nonexistent/x.obj: file: expected a readable regular file"));
}

fn small_mesh() -> Mesh {
    Mesh {
        vertices: vec![
            glam::Vec3::new(0.0, 0.0, 0.0),
            glam::Vec3::new(1.5, 0.0, -2.0),
            glam::Vec3::new(0.0, 1.0, 3.25),
            glam::Vec3::new(1.0, 1.0, 1.0),
        ],
        triangles: vec![[0, 1, 2], [2, 1, 3]],
    }
}

/// Seeds for mutation: valid files of each kind.
fn seeds() -> Vec<Vec<u8>> {
    let m = small_mesh();
    vec![
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 1\nf 1/1/1 2//2 3/3 -1\nf -4 -3 -2\n".to_vec(),
        write_ply(&m, PlyFormat::Ascii),
        write_ply(&m, PlyFormat::BinaryLittleEndian),
    ]
}

#[derive(Debug, Clone)]
enum Mutation {
    Set(usize, u8),
    Insert(usize, u8),
    Remove(usize),
    Truncate(usize),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Mutation::Set(i, b)),
        (
            any::<usize>(),
            prop::sample::select(b" \n/-0123456789.eE#vfnaiply".to_vec())
        )
            .prop_map(|(i, b)| Mutation::Insert(i, b)),
        any::<usize>().prop_map(Mutation::Remove),
        any::<usize>().prop_map(Mutation::Truncate),
    ]
}

fn apply(bytes: &mut Vec<u8>, m: &Mutation) {
    if bytes.is_empty() {
        return;
    }
    let n = bytes.len();
    match *m {
        Mutation::Set(i, b) => bytes[i % n] = b,
        Mutation::Insert(i, b) => bytes.insert(i % (n + 1), b),
        Mutation::Remove(i) => {
            bytes.remove(i % n);
        }
        Mutation::Truncate(i) => bytes.truncate(i % n),
    }
}

/// Either answer is fine; a panic fails the test. An error must still say
/// which file it is about.
fn parse_both(bytes: &[u8]) {
    for r in [parse_obj(bytes, "fuzz"), parse_ply(bytes, "fuzz")] {
        match r {
            Ok(m) => m.validate("fuzz").unwrap(),
            Err(e) => assert!(e.to_string().starts_with("fuzz")),
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(10000))]
    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..512)) {
        parse_both(&bytes);
        let mut with_header = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
        with_header.extend_from_slice(&bytes);
        parse_both(&with_header);
    }

    #[test]
    fn mutated_valid_files_never_panic(seed in 0usize..3, muts in prop::collection::vec(mutation(), 1..8)) {
        let mut bytes = seeds()[seed].clone();
        for m in &muts {
            apply(&mut bytes, m);
        }
        parse_both(&bytes);
    }
}
