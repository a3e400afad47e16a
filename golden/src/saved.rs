//! Saved hierarchies (SPEC.md section 16): a built hierarchy in a versioned
//! binary file, so that it is built once and loaded by later runs.
//!
//! The file holds a header with every parameter (`D, Q, I, H`, the id, the
//! top LOD, the root count, the grid map), the triangle count and SHA-256
//! digest of the mesh it was built over, the node records packed bit for bit
//! as the hardware stores them ([`crate::layout`]), the references packed
//! likewise, the primitive indices, and a SHA-256 checksum of everything
//! before it. [`save`] writes it atomically ([`crate::output::write_atomic`]);
//! [`load`] reads it with the bounded reader ([`crate::input`]), refuses a
//! wrong magic, version, parameter, length, checksum or record with an error
//! naming the file, the field and its byte offset, then requires the mesh to
//! be the one the hierarchy was built over and runs the checker (SPEC 5).
//!
//! ```
//! use glam::Vec3;
//! use golden::build::{build, GridMap};
//! use golden::saved;
//! use golden::scenes::torus;
//! use golden::Params;
//!
//! let mesh = torus(Vec3::ZERO, 1.0, 0.25, 32, 16);
//! let params = Params::default();
//! let (lo, hi) = mesh.bounds();
//! let grid = GridMap::fit(lo, hi, &params);
//! let built = build(&mesh, &grid, &params, 0).unwrap();
//!
//! let dir = tempfile::tempdir().unwrap();
//! let file = dir.path().join("torus.hmh");
//! saved::save(&file, &built, &grid, &mesh).unwrap();
//! let loaded = saved::load(&file, &mesh).unwrap();
//! assert_eq!(loaded.hierarchy, built);
//! assert_eq!(loaded.grid, grid);
//!
//! // Another mesh is refused, naming the header field that differs.
//! let other = torus(Vec3::ZERO, 1.0, 0.3, 32, 16);
//! let e = saved::load(&file, &other).unwrap_err();
//! assert_eq!(e.field, "mesh digest");
//! ```

use std::fmt;
use std::path::Path;

use glam::DVec3;
use sha2::{Digest, Sha256};

use crate::bits::Bits;
use crate::build::GridMap;
use crate::check::check_built;
use crate::layout::{NodeLayout, RefLayout};
use crate::mesh::Mesh;
use crate::params::Params;
use crate::store::{Hierarchy, NodeRecord, Reference};

/// The first 8 bytes of every saved hierarchy.
pub const MAGIC: [u8; 8] = *b"HIERMRGH";
/// The format version this code writes and reads.
pub const VERSION: u32 = 1;
/// Bytes of the header, before the node records.
pub const HEADER_BYTES: usize = 120;
/// Bytes of the checksum at the end.
pub const CHECKSUM_BYTES: usize = 32;
/// The most bytes a saved hierarchy may have (1 GiB; SPEC.md section 15).
pub const MAX_SAVED_BYTES: u64 = 1 << 30;

/// Byte offsets of the header fields (SPEC 16.1).
mod at {
    pub const VERSION: usize = 8;
    pub const MAX_LOD: usize = 12;
    pub const QUANT_BITS: usize = 13;
    pub const INDEX_BITS: usize = 14;
    pub const HIER_BITS: usize = 15;
    pub const ID: usize = 16;
    pub const TOP_LOD: usize = 17;
    pub const RESERVED: usize = 18;
    pub const ROOT_COUNT: usize = 20;
    pub const ORIGIN: usize = 24;
    pub const UNIT: usize = 48;
    pub const TRIANGLES: usize = 56;
    pub const MESH_DIGEST: usize = 64;
    pub const NODES: usize = 96;
    pub const REFS: usize = 104;
    pub const PRIMS: usize = 112;
}

/// A saved hierarchy as read back: the hierarchy, the grid map it was built
/// in, and what it says of its mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct SavedHierarchy {
    /// The hierarchy, its parameters and id included.
    pub hierarchy: Hierarchy,
    /// The map from world units to grid units it was built with.
    pub grid: GridMap,
    /// The triangle count of the mesh it was built over.
    pub triangles: u64,
    /// [`mesh_digest`] of that mesh.
    pub mesh_digest: [u8; 32],
}

/// A saved hierarchy refused: the file, where in it, and what was wrong.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LoadError {
    /// The file, as given.
    pub file: String,
    /// The byte offset of the field at fault, when there is one.
    pub offset: Option<u64>,
    /// The field, as SPEC 16 names it (`version`, `max_lod`, `node 12 count`, ...).
    pub field: String,
    /// What it should have been.
    pub expected: String,
    /// What was found.
    pub found: String,
}

impl fmt::Display for LoadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.offset {
            Some(o) => write!(f, "{}: offset {o} ({})", self.file, self.field)?,
            None => write!(f, "{}: {}", self.file, self.field)?,
        }
        write!(f, ": expected {}, found {}", self.expected, self.found)
    }
}

impl std::error::Error for LoadError {}

/// SHA-256 of the mesh's triangles as the builder sees them: for each
/// triangle in order, its three vertices' coordinates as binary32
/// little-endian bits (x, y, z). Two meshes with the same digest build the
/// same hierarchy in the same grid.
pub fn mesh_digest(mesh: &Mesh) -> [u8; 32] {
    let mut h = Sha256::new();
    for t in &mesh.triangles {
        for &v in t {
            let p = mesh
                .vertices
                .get(v as usize)
                .copied()
                .unwrap_or(glam::Vec3::NAN);
            for c in p.to_array() {
                h.update(c.to_bits().to_le_bytes());
            }
        }
    }
    h.finalize().into()
}

fn record_bytes(width: u32) -> usize {
    width.div_ceil(8) as usize
}

fn put_bits(out: &mut Vec<u8>, b: &Bits) {
    for k in 0..record_bytes(b.width()) {
        out.push((b.words()[k / 8] >> (8 * (k % 8))) as u8);
    }
}

/// The file's bytes for hierarchy `h`, built in `grid` over `mesh`. Only a
/// self-contained hierarchy can be saved: every reference must point into
/// `h` itself (a built hierarchy; a merged one references its inputs).
pub fn to_bytes(h: &Hierarchy, grid: &GridMap, mesh: &Mesh) -> Result<Vec<u8>, String> {
    if let Some(r) = h.refs.iter().find(|r| r.hier != h.id) {
        return Err(format!(
            "hierarchy {}: a reference to hierarchy {}: only a hierarchy whose references \
             all point into itself (a built one) can be saved",
            h.id, r.hier
        ));
    }
    let p = &h.params;
    let mut out = Vec::with_capacity(
        HEADER_BYTES
            + h.nodes.len() * record_bytes(NodeLayout::new(p).width())
            + h.refs.len() * record_bytes(RefLayout::new(p).width())
            + h.prims.len() * 4
            + CHECKSUM_BYTES,
    );
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&[
        p.max_lod,
        p.quant_bits,
        p.index_bits,
        p.hier_bits,
        h.id,
        h.top_lod,
        0,
        0,
    ]);
    out.extend_from_slice(&h.root_count.to_le_bytes());
    for c in grid.origin.to_array().into_iter().chain([grid.unit]) {
        out.extend_from_slice(&c.to_bits().to_le_bytes());
    }
    out.extend_from_slice(&(mesh.triangles.len() as u64).to_le_bytes());
    out.extend_from_slice(&mesh_digest(mesh));
    for n in [h.nodes.len(), h.refs.len(), h.prims.len()] {
        out.extend_from_slice(&(n as u64).to_le_bytes());
    }
    debug_assert_eq!(out.len(), HEADER_BYTES);
    let node_layout = NodeLayout::new(p);
    for (i, n) in h.nodes.iter().enumerate() {
        let b = n.pack(&node_layout).map_err(|e| format!("node {i}: {e}"))?;
        put_bits(&mut out, &b);
    }
    let ref_layout = RefLayout::new(p);
    for (i, r) in h.refs.iter().enumerate() {
        let b = r
            .pack(&ref_layout)
            .map_err(|e| format!("reference {i}: {e}"))?;
        put_bits(&mut out, &b);
    }
    for &t in &h.prims {
        out.extend_from_slice(&t.to_le_bytes());
    }
    out.extend_from_slice(&[0; CHECKSUM_BYTES]);
    seal(&mut out);
    Ok(out)
}

/// Rewrites the checksum (the last 32 bytes) of a saved hierarchy's bytes
/// to match the rest: for tools and tests that patch a file on purpose, so
/// that a later rule than the checksum sees the patch. Bytes shorter than
/// a checksum are left alone.
pub fn seal(bytes: &mut [u8]) {
    if let Some(body) = bytes.len().checked_sub(CHECKSUM_BYTES) {
        let sum: [u8; 32] = Sha256::digest(&bytes[..body]).into();
        bytes[body..].copy_from_slice(&sum);
    }
}

/// Writes hierarchy `h` (built in `grid` over `mesh`) to `path`, atomically.
pub fn save(path: &Path, h: &Hierarchy, grid: &GridMap, mesh: &Mesh) -> Result<(), String> {
    let bytes = to_bytes(h, grid, mesh).map_err(|e| format!("{}: {e}", path.display()))?;
    crate::output::write_atomic(path, &bytes)
}

/// Reads the saved hierarchy at `path` (a regular file of at most
/// [`MAX_SAVED_BYTES`]), requires `mesh` to be the mesh it was built over
/// (triangle count and [`mesh_digest`]) and runs the checker on it over
/// `mesh`'s triangles.
pub fn load(path: &Path, mesh: &Mesh) -> Result<SavedHierarchy, LoadError> {
    let file = path.display().to_string();
    let bytes = crate::input::read_bytes(path, MAX_SAVED_BYTES).map_err(|e| LoadError {
        file: file.clone(),
        offset: None,
        field: "file".into(),
        expected: e.expected,
        found: e.found,
    })?;
    let s = from_bytes(&bytes, &file)?;
    s.require_mesh(&file, mesh)?;
    let h = &s.hierarchy;
    let refuse = |what: String| LoadError {
        file: file.clone(),
        offset: None,
        field: "checker (SPEC 5)".into(),
        expected: "a hierarchy the checker accepts over the mesh".into(),
        found: what,
    };
    let tris = s
        .grid
        .mesh_to_grid(mesh, &h.params)
        .map_err(|e| refuse(format!("the mesh does not fit the saved grid map: {e}")))?;
    check_built(h, &tris).map_err(|e| refuse(e.to_string()))?;
    Ok(s)
}

/// Where [`load_or_build`]'s hierarchy came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Provenance {
    /// Read from the file and checked.
    Loaded,
    /// The file did not exist: built, then saved there.
    Saved,
}

/// Hierarchy `id` of `mesh` built with `params` in `grid`: loaded from
/// `path` when it exists (and refused unless it was saved over `mesh` with
/// these parameters, grid and id), else built and saved to `path`, so that
/// later runs load it.
pub fn load_or_build(
    path: &Path,
    mesh: &Mesh,
    grid: &GridMap,
    params: &Params,
    id: u8,
) -> Result<(Hierarchy, Provenance), String> {
    if std::fs::symlink_metadata(path).is_ok() {
        let s = load(path, mesh).map_err(|e| e.to_string())?;
        s.require(&path.display().to_string(), params, grid, id)
            .map_err(|e| e.to_string())?;
        return Ok((s.hierarchy, Provenance::Loaded));
    }
    let h = crate::build::build(mesh, grid, params, id)
        .map_err(|e| format!("{}: building the hierarchy to save: {e}", path.display()))?;
    save(path, &h, grid, mesh)?;
    Ok((h, Provenance::Saved))
}

impl SavedHierarchy {
    fn require_mesh(&self, file: &str, mesh: &Mesh) -> Result<(), LoadError> {
        let n = mesh.triangles.len() as u64;
        if n != self.triangles {
            return Err(header(
                file,
                at::TRIANGLES,
                "triangles",
                format!("{n}, the given mesh's triangle count"),
                self.triangles.to_string(),
            ));
        }
        let d = mesh_digest(mesh);
        if d != self.mesh_digest {
            return Err(header(
                file,
                at::MESH_DIGEST,
                "mesh digest",
                format!("{}, the given mesh's digest", hex(&d)),
                format!("{} (saved from another mesh)", hex(&self.mesh_digest)),
            ));
        }
        Ok(())
    }

    /// Requires the header to say what the caller builds with: `params`,
    /// `grid` and hierarchy `id`; an error names the first field that differs.
    pub fn require(
        &self,
        file: &str,
        params: &Params,
        grid: &GridMap,
        id: u8,
    ) -> Result<(), LoadError> {
        let p = &self.hierarchy.params;
        let fields = [
            (at::MAX_LOD, "max_lod", p.max_lod, params.max_lod),
            (
                at::QUANT_BITS,
                "quant_bits",
                p.quant_bits,
                params.quant_bits,
            ),
            (
                at::INDEX_BITS,
                "index_bits",
                p.index_bits,
                params.index_bits,
            ),
            (at::HIER_BITS, "hier_bits", p.hier_bits, params.hier_bits),
            (at::ID, "hierarchy id", self.hierarchy.id, id),
        ];
        for (offset, name, found, want) in fields {
            if found != want {
                return Err(header(
                    file,
                    offset,
                    name,
                    want.to_string(),
                    found.to_string(),
                ));
            }
        }
        if self.grid.origin != grid.origin {
            return Err(header(
                file,
                at::ORIGIN,
                "grid origin",
                format!("{:?}", grid.origin),
                format!("{:?}", self.grid.origin),
            ));
        }
        if self.grid.unit.to_bits() != grid.unit.to_bits() {
            return Err(header(
                file,
                at::UNIT,
                "grid unit",
                grid.unit.to_string(),
                self.grid.unit.to_string(),
            ));
        }
        Ok(())
    }
}

fn header(
    file: &str,
    offset: usize,
    field: &str,
    expected: impl Into<String>,
    found: impl Into<String>,
) -> LoadError {
    LoadError {
        file: file.to_string(),
        offset: Some(offset as u64),
        field: field.to_string(),
        expected: expected.into(),
        found: found.into(),
    }
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// Little-endian reads at known-good offsets (the length is checked first).
fn u32_at(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes(b[o..o + 4].try_into().expect("4 bytes"))
}

fn u64_at(b: &[u8], o: usize) -> u64 {
    u64::from_le_bytes(b[o..o + 8].try_into().expect("8 bytes"))
}

/// The `width`-bit record at byte `o` (`what` names it in the error when
/// bits above the width are set).
fn bits_at(b: &[u8], o: usize, width: u32, file: &str, what: String) -> Result<Bits, LoadError> {
    let n = record_bytes(width);
    let mut words = vec![0u64; width.div_ceil(64) as usize];
    for (k, &byte) in b[o..o + n].iter().enumerate() {
        words[k / 8] |= (byte as u64) << (8 * (k % 8));
    }
    Bits::from_words(&words, width).map_err(|_| {
        header(
            file,
            o,
            &what,
            format!("{width} record bits and zero padding"),
            "bits set above the record width",
        )
    })
}

/// Parses the bytes of a saved hierarchy (`file` names it in errors): the
/// format's own rules (SPEC 16.2), not yet the mesh or the checker.
pub fn from_bytes(b: &[u8], file: &str) -> Result<SavedHierarchy, LoadError> {
    let err = |offset: usize, field: &str, expected: String, found: String| {
        header(file, offset, field, expected, found)
    };
    let len = b.len();
    let minimum = HEADER_BYTES + CHECKSUM_BYTES;
    if len < MAGIC.len() || b[..MAGIC.len()] != MAGIC {
        let found = hex(&b[..len.min(MAGIC.len())]);
        return Err(err(
            0,
            "magic",
            format!(
                "the bytes {} (\"HIERMRGH\": a saved hierarchy)",
                hex(&MAGIC)
            ),
            if found.is_empty() {
                "an empty file".into()
            } else {
                found
            },
        ));
    }
    if len < minimum {
        return Err(err(
            len,
            "header",
            format!("at least {minimum} bytes (header and checksum)"),
            format!("{len} bytes: the file is truncated"),
        ));
    }
    let version = u32_at(b, at::VERSION);
    if version != VERSION {
        return Err(err(
            at::VERSION,
            "version",
            format!("{VERSION} (the version this program reads)"),
            version.to_string(),
        ));
    }
    let params = Params {
        max_lod: b[at::MAX_LOD],
        quant_bits: b[at::QUANT_BITS],
        index_bits: b[at::INDEX_BITS],
        hier_bits: b[at::HIER_BITS],
    };
    params.validate().map_err(|e| {
        let offset = match e.field {
            "max_lod" => at::MAX_LOD,
            "quant_bits" => at::QUANT_BITS,
            "index_bits" => at::INDEX_BITS,
            _ => at::HIER_BITS,
        };
        err(offset, e.field, e.expected, e.value.to_string())
    })?;
    let counts = [at::NODES, at::REFS, at::PRIMS].map(|o| u64_at(b, o));
    let cap = params.index_capacity();
    for (o, (name, n)) in [at::NODES, at::REFS, at::PRIMS].into_iter().zip(
        ["node count", "reference count", "primitive count"]
            .into_iter()
            .zip(counts),
    ) {
        if n > cap {
            return Err(err(o, name, format!("at most 2^I = {cap}"), n.to_string()));
        }
    }
    let node_w = NodeLayout::new(&params).width();
    let ref_w = RefLayout::new(&params).width();
    let (nb, rb) = (record_bytes(node_w), record_bytes(ref_w));
    // Counts are at most 2^32 and records a few dozen bytes: no overflow in u128.
    let want = HEADER_BYTES as u128
        + counts[0] as u128 * nb as u128
        + counts[1] as u128 * rb as u128
        + counts[2] as u128 * 4
        + CHECKSUM_BYTES as u128;
    if want != len as u128 {
        let (what, found) = if (len as u128) < want {
            ("truncated", format!("{len} bytes: the file is truncated"))
        } else {
            ("too long", format!("{len} bytes: bytes after the checksum"))
        };
        return Err(err(
            len.min(want as usize),
            &format!("length ({what})"),
            format!(
                "{want} bytes for {} nodes of {nb} bytes, {} references of {rb} bytes and {} \
                 primitive indices of 4 bytes",
                counts[0], counts[1], counts[2]
            ),
            found,
        ));
    }
    let body = len - CHECKSUM_BYTES;
    let sum: [u8; 32] = Sha256::digest(&b[..body]).into();
    if sum[..] != b[body..] {
        return Err(err(
            body,
            "checksum",
            format!("{} (SHA-256 of bytes 0..{body})", hex(&sum)),
            format!("{}: the file is corrupt", hex(&b[body..])),
        ));
    }
    decode_body(b, file, params, counts, [nb, rb])
}

/// The header's remaining fields and the records, after the checksum held.
fn decode_body(
    b: &[u8],
    file: &str,
    params: Params,
    counts: [u64; 3],
    [nb, rb]: [usize; 2],
) -> Result<SavedHierarchy, LoadError> {
    let err = |offset: usize, field: &str, expected: String, found: String| {
        header(file, offset, field, expected, found)
    };
    let id = b[at::ID];
    if id as u64 >= params.hier_capacity() {
        return Err(err(
            at::ID,
            "hierarchy id",
            format!("below 2^H = {}", params.hier_capacity()),
            id.to_string(),
        ));
    }
    let top_lod = b[at::TOP_LOD];
    if top_lod > params.max_lod {
        return Err(err(
            at::TOP_LOD,
            "top_lod",
            format!("0..={}", params.max_lod),
            top_lod.to_string(),
        ));
    }
    if b[at::RESERVED..at::RESERVED + 2] != [0, 0] {
        return Err(err(
            at::RESERVED,
            "reserved",
            "zero bytes".into(),
            hex(&b[at::RESERVED..at::RESERVED + 2]),
        ));
    }
    let root_count = u32_at(b, at::ROOT_COUNT);
    if root_count as u64 > counts[0] {
        return Err(err(
            at::ROOT_COUNT,
            "root_count",
            format!("at most the node count {}", counts[0]),
            root_count.to_string(),
        ));
    }
    let origin =
        DVec3::from_array([0, 1, 2].map(|k| f64::from_bits(u64_at(b, at::ORIGIN + 8 * k))));
    if !origin.is_finite() {
        return Err(err(
            at::ORIGIN,
            "grid origin",
            "finite coordinates".into(),
            format!("{origin:?}"),
        ));
    }
    let unit = f64::from_bits(u64_at(b, at::UNIT));
    if !(unit.is_finite() && unit > 0.0) {
        return Err(err(
            at::UNIT,
            "grid unit",
            "finite and > 0".into(),
            unit.to_string(),
        ));
    }
    let triangles = u64_at(b, at::TRIANGLES);
    let mesh_digest: [u8; 32] = b[at::MESH_DIGEST..at::MESH_DIGEST + 32]
        .try_into()
        .expect("32 bytes");
    let node_layout = NodeLayout::new(&params);
    let mut o = HEADER_BYTES;
    let mut nodes = Vec::with_capacity(counts[0] as usize);
    for i in 0..counts[0] {
        let bits = bits_at(b, o, node_layout.width(), file, format!("node {i}"))?;
        let n = NodeRecord::unpack(&bits, &node_layout).expect("the layout's width");
        n.validate(&params).map_err(|e| {
            err(
                o,
                &format!("node {i} {}", e.field),
                e.expected.clone(),
                e.value.to_string(),
            )
        })?;
        let len = if n.leaf { counts[2] } else { counts[1] };
        if n.range().end > len {
            let what = if n.leaf { "primitive" } else { "reference" };
            return Err(err(
                o,
                &format!("node {i} first + count"),
                format!("at most the {what} count {len}"),
                n.range().end.to_string(),
            ));
        }
        nodes.push(n);
        o += nb;
    }
    let ref_layout = RefLayout::new(&params);
    let mut refs = Vec::with_capacity(counts[1] as usize);
    for i in 0..counts[1] {
        let bits = bits_at(b, o, ref_layout.width(), file, format!("reference {i}"))?;
        let r = Reference::unpack(&bits, &ref_layout).expect("the layout's width");
        if r.hier != id || r.node as u64 >= counts[0] {
            return Err(err(
                o,
                &format!("reference {i}"),
                format!("a node of hierarchy {id} below {}", counts[0]),
                format!("({}, {})", r.hier, r.node),
            ));
        }
        refs.push(r);
        o += rb;
    }
    let mut prims = Vec::with_capacity(counts[2] as usize);
    for i in 0..counts[2] {
        let t = u32_at(b, o);
        if t as u64 >= triangles {
            return Err(err(
                o,
                &format!("primitive index {i}"),
                format!("below the triangle count {triangles}"),
                t.to_string(),
            ));
        }
        prims.push(t);
        o += 4;
    }
    Ok(SavedHierarchy {
        hierarchy: Hierarchy {
            id,
            params,
            nodes,
            refs,
            prims,
            root_count,
            top_lod,
        },
        grid: GridMap { origin, unit },
        triangles,
        mesh_digest,
    })
}
