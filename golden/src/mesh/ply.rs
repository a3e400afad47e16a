//! PLY import (ascii and binary little-endian) and export.
//!
//! Rules (SPEC.md, "Mesh import"): the header starts with `ply`, has one
//! `format ascii 1.0` or `format binary_little_endian 1.0` line
//! (`binary_big_endian` is refused as unsupported), `comment` and `obj_info`
//! lines, `element` and `property` lines, and ends with `end_header`. The
//! `vertex` element needs scalar properties `x`, `y`, `z` (any numeric type;
//! the value must be finite in f32); the `face` element needs a list property
//! `vertex_indices` (or `vertex_index`) with an integer count and integer
//! items, and must come after `vertex`. Every other property and element is
//! read by its type and skipped. A face of `n >= 3` indices becomes the fan
//! `(a b c) (a c d) ...`; each index must be in `0..vertex count`. Ascii
//! element instances are rows: one instance per line, all its values on it
//! (blank lines between rows are skipped); a short or long row is an error
//! at its line. Nothing may follow the declared elements (ascii: only
//! whitespace; binary: no byte). Errors in ascii name the line, in binary
//! the element and its instance.

use glam::Vec3;

use super::error::quote;
use super::obj::fan_triangulate;
use super::{Mesh, MeshError, MeshLocation};

/// The PLY body encodings this crate reads and writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlyFormat {
    /// `format ascii 1.0`: whitespace-separated text.
    Ascii,
    /// `format binary_little_endian 1.0`.
    BinaryLittleEndian,
}

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn from_name(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// The inclusive range of an integer type.
    fn int_range(self) -> (i64, i64) {
        match self {
            Scalar::I8 => (i8::MIN as i64, i8::MAX as i64),
            Scalar::U8 => (0, u8::MAX as i64),
            Scalar::I16 => (i16::MIN as i64, i16::MAX as i64),
            Scalar::U16 => (0, u16::MAX as i64),
            Scalar::I32 => (i32::MIN as i64, i32::MAX as i64),
            Scalar::U32 => (0, u32::MAX as i64),
            Scalar::F32 | Scalar::F64 => (i64::MIN, i64::MAX),
        }
    }
}

const TYPE_NAMES: &str = "char uchar short ushort int uint float double (or int8 .. float64)";

#[derive(Clone, Debug)]
enum PropKind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Clone, Debug)]
struct Property {
    name: String,
    kind: PropKind,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: u64,
    props: Vec<Property>,
}

struct Header {
    format: PlyFormat,
    elements: Vec<Element>,
    /// Byte offset of the body.
    body_start: usize,
    /// 1-based line number of the body's first line.
    body_line: u64,
}

/// A number read from the body.
#[derive(Clone, Copy)]
enum Num {
    Int(i64),
    Float(f64),
}

impl Num {
    fn as_f64(self) -> f64 {
        match self {
            Num::Int(i) => i as f64,
            Num::Float(f) => f,
        }
    }
}

/// Parses PLY bytes; `name` names the input in errors.
pub fn parse_ply(bytes: &[u8], name: &str) -> Result<Mesh, MeshError> {
    let header = parse_header(bytes, name)?;
    let layout = MeshLayout::find(&header, name)?;
    let body = &bytes[header.body_start..];
    match header.format {
        PlyFormat::Ascii => {
            let mut r = AsciiReader {
                rest: body,
                line: header.body_line,
            };
            read_body(&header, &layout, &mut r, name)
        }
        PlyFormat::BinaryLittleEndian => {
            let mut r = BinaryReader { rest: body };
            read_body(&header, &layout, &mut r, name)
        }
    }
}

fn parse_header(bytes: &[u8], name: &str) -> Result<Header, MeshError> {
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut offset = 0usize;
    let mut line_no = 0u64;
    loop {
        line_no += 1;
        let err = |field: &str, expected: &str, found: String| {
            MeshError::new(name, MeshLocation::Line(line_no), field, expected, found)
        };
        if offset >= bytes.len() {
            return Err(err("header", "`end_header`", "end of file".into()));
        }
        let end = bytes[offset..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |p| offset + p);
        let raw = &bytes[offset..end];
        offset = (end + 1).min(bytes.len());
        let line =
            std::str::from_utf8(raw).map_err(|_| err("header line", "ASCII text", quote(raw)))?;
        let words: Vec<&str> = line.split_ascii_whitespace().collect();
        if line_no == 1 {
            if words != ["ply"] {
                return Err(err("magic", "`ply`", quote(raw)));
            }
            continue;
        }
        match words.first().copied() {
            Some("end_header") => break,
            Some("comment") | Some("obj_info") => {}
            Some("format") => {
                let f = match words.get(1).copied() {
                    Some("ascii") => PlyFormat::Ascii,
                    Some("binary_little_endian") => PlyFormat::BinaryLittleEndian,
                    Some("binary_big_endian") => {
                        return Err(err(
                            "format",
                            "ascii or binary_little_endian (binary_big_endian is unsupported)",
                            "binary_big_endian".into(),
                        ))
                    }
                    _ => return Err(err("format", "ascii or binary_little_endian", quote(raw))),
                };
                if words.get(2).copied() != Some("1.0") || words.len() != 3 {
                    return Err(err("format version", "`1.0`", quote(raw)));
                }
                if format.is_some() {
                    return Err(err("format", "a single format line", "a second one".into()));
                }
                format = Some(f);
            }
            Some("element") => {
                let (Some(ename), Some(count), 3) = (words.get(1), words.get(2), words.len())
                else {
                    return Err(err("element", "`element <name> <count>`", quote(raw)));
                };
                let count = count.parse::<u64>().map_err(|_| {
                    err(
                        "element count",
                        "a non-negative integer",
                        quote(count.as_bytes()),
                    )
                })?;
                elements.push(Element {
                    name: ename.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            Some("property") => {
                let Some(element) = elements.last_mut() else {
                    return Err(err("property", "an `element` line before it", quote(raw)));
                };
                let ty = |w: &str| {
                    Scalar::from_name(w)
                        .ok_or_else(|| err("property type", TYPE_NAMES, quote(w.as_bytes())))
                };
                let prop = match words.as_slice() {
                    ["property", "list", c, i, pname] => {
                        let (count, item) = (ty(c)?, ty(i)?);
                        if !count.is_integer() {
                            return Err(err("list count type", "an integer type", quote(c.as_bytes())));
                        }
                        Property {
                            name: pname.to_string(),
                            kind: PropKind::List { count, item },
                        }
                    }
                    ["property", t, pname] => Property {
                        name: pname.to_string(),
                        kind: PropKind::Scalar(ty(t)?),
                    },
                    _ => {
                        return Err(err(
                            "property",
                            "`property <type> <name>` or `property list <count type> <item type> <name>`",
                            quote(raw),
                        ))
                    }
                };
                element.props.push(prop);
            }
            _ => {
                return Err(err(
                    "header keyword",
                    "format, comment, obj_info, element, property or end_header",
                    quote(raw),
                ))
            }
        }
    }
    let format = format.ok_or_else(|| {
        MeshError::new(
            name,
            MeshLocation::Line(line_no),
            "format",
            "a `format` line in the header",
            "none".to_string(),
        )
    })?;
    Ok(Header {
        format,
        elements,
        body_start: offset,
        body_line: line_no + 1,
    })
}

/// Where the mesh's data sits among the header's elements and properties.
struct MeshLayout {
    vertex_element: usize,
    xyz: [usize; 3],
    face_element: usize,
    indices: usize,
}

impl MeshLayout {
    fn find(h: &Header, name: &str) -> Result<MeshLayout, MeshError> {
        let missing = |field: &str, expected: &str| {
            MeshError::new(
                name,
                MeshLocation::File,
                field,
                expected,
                "none in the header".to_string(),
            )
        };
        let vertex_element = h
            .elements
            .iter()
            .position(|e| e.name == "vertex")
            .ok_or_else(|| missing("element vertex", "an `element vertex <count>` header line"))?;
        let face_element = h
            .elements
            .iter()
            .position(|e| e.name == "face")
            .ok_or_else(|| missing("element face", "an `element face <count>` header line"))?;
        if face_element < vertex_element {
            return Err(MeshError::new(
                name,
                MeshLocation::File,
                "element order",
                "element vertex before element face",
                "face first".to_string(),
            ));
        }
        let v = &h.elements[vertex_element];
        let mut xyz = [0; 3];
        for (k, axis) in ["x", "y", "z"].iter().enumerate() {
            xyz[k] = v
                .props
                .iter()
                .position(|p| p.name == *axis && matches!(p.kind, PropKind::Scalar(_)))
                .ok_or_else(|| {
                    missing(
                        &format!("vertex property {axis}"),
                        &format!("a scalar `property <type> {axis}` in element vertex"),
                    )
                })?;
        }
        let indices = h.elements[face_element]
            .props
            .iter()
            .position(|p| {
                (p.name == "vertex_indices" || p.name == "vertex_index")
                    && matches!(p.kind, PropKind::List { item, .. } if item.is_integer())
            })
            .ok_or_else(|| {
                missing(
                    "face property vertex_indices",
                    "`property list <int type> <int type> vertex_indices` (or vertex_index) in element face",
                )
            })?;
        if h.elements[vertex_element].count > u32::MAX as u64 + 1 {
            return Err(MeshError::new(
                name,
                MeshLocation::File,
                "element vertex count",
                "at most 2^32 vertices (u32 indices)",
                h.elements[vertex_element].count.to_string(),
            ));
        }
        Ok(MeshLayout {
            vertex_element,
            xyz,
            face_element,
            indices,
        })
    }
}

/// Why a value could not be read.
enum ReadFail {
    Truncated,
    Malformed(String),
    OutOfRange(String),
}

/// A source of body values: ascii tokens or little-endian bytes.
trait BodyReader {
    fn read(&mut self, ty: Scalar) -> Result<Num, ReadFail>;
    /// Bytes (binary) or a lower bound on tokens left, to refuse impossible
    /// list counts before looping over them.
    fn can_hold(&self, n: u64, ty: Scalar) -> bool;
    fn location(&self, element: &str, index: u64) -> MeshLocation;
    /// Before an instance: ascii skips blank lines.
    fn begin_instance(&mut self) {}
    /// After an instance: ascii wants the end of its line (one instance per
    /// line), `Err` with what follows instead.
    fn end_instance(&mut self) -> Result<(), String> {
        Ok(())
    }
    /// After the last element: `Err` with what follows the declared data.
    fn finish(&mut self) -> Result<(), String>;
}

struct AsciiReader<'a> {
    rest: &'a [u8],
    line: u64,
}

impl AsciiReader<'_> {
    /// Skips blanks within the line (not its end).
    fn skip_blanks(&mut self) {
        while let Some((&b, tail)) = self.rest.split_first() {
            if b == b'\n' || !b.is_ascii_whitespace() {
                break;
            }
            self.rest = tail;
        }
    }

    /// The next token of this line, quoted, for an error.
    fn next_token(&self) -> String {
        let len = self
            .rest
            .iter()
            .position(|b| b.is_ascii_whitespace())
            .unwrap_or(self.rest.len());
        quote(&self.rest[..len])
    }
}

impl BodyReader for AsciiReader<'_> {
    fn read(&mut self, ty: Scalar) -> Result<Num, ReadFail> {
        self.skip_blanks();
        match self.rest.first() {
            None => return Err(ReadFail::Truncated),
            Some(b'\n') => return Err(ReadFail::Malformed("the end of the line".into())),
            Some(_) => {}
        }
        let len = self
            .rest
            .iter()
            .position(|b| b.is_ascii_whitespace())
            .unwrap_or(self.rest.len());
        if len == 0 {
            return Err(ReadFail::Truncated);
        }
        let tok = &self.rest[..len];
        self.rest = &self.rest[len..];
        let text = std::str::from_utf8(tok).map_err(|_| ReadFail::Malformed(quote(tok)))?;
        if ty.is_integer() {
            let v: i64 = text.parse().map_err(|_| ReadFail::Malformed(quote(tok)))?;
            let (lo, hi) = ty.int_range();
            if v < lo || v > hi {
                return Err(ReadFail::OutOfRange(text.to_string()));
            }
            Ok(Num::Int(v))
        } else {
            let v: f64 = text.parse().map_err(|_| ReadFail::Malformed(quote(tok)))?;
            Ok(Num::Float(if ty == Scalar::F32 {
                v as f32 as f64
            } else {
                v
            }))
        }
    }

    fn can_hold(&self, n: u64, _ty: Scalar) -> bool {
        // Each token needs at least one byte and one separator, less one.
        n <= (self.rest.len() as u64).div_ceil(2) + 1
    }

    fn location(&self, _element: &str, _index: u64) -> MeshLocation {
        MeshLocation::Line(self.line)
    }

    fn begin_instance(&mut self) {
        loop {
            self.skip_blanks();
            match self.rest.split_first() {
                Some((b'\n', tail)) => {
                    self.rest = tail;
                    self.line += 1;
                }
                _ => return,
            }
        }
    }

    fn end_instance(&mut self) -> Result<(), String> {
        self.skip_blanks();
        match self.rest.split_first() {
            None => Ok(()),
            Some((b'\n', tail)) => {
                self.rest = tail;
                self.line += 1;
                Ok(())
            }
            Some(_) => Err(self.next_token()),
        }
    }

    fn finish(&mut self) -> Result<(), String> {
        self.begin_instance();
        match self.rest.is_empty() {
            true => Ok(()),
            false => Err(self.next_token()),
        }
    }
}

struct BinaryReader<'a> {
    rest: &'a [u8],
}

impl BodyReader for BinaryReader<'_> {
    fn read(&mut self, ty: Scalar) -> Result<Num, ReadFail> {
        let n = ty.size();
        if self.rest.len() < n {
            return Err(ReadFail::Truncated);
        }
        let (b, tail) = self.rest.split_at(n);
        self.rest = tail;
        let mut buf = [0u8; 8];
        buf[..n].copy_from_slice(b);
        Ok(match ty {
            Scalar::I8 => Num::Int(b[0] as i8 as i64),
            Scalar::U8 => Num::Int(b[0] as i64),
            Scalar::I16 => Num::Int(i16::from_le_bytes([b[0], b[1]]) as i64),
            Scalar::U16 => Num::Int(u16::from_le_bytes([b[0], b[1]]) as i64),
            Scalar::I32 => Num::Int(i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as i64),
            Scalar::U32 => Num::Int(u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as i64),
            Scalar::F32 => Num::Float(f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64),
            Scalar::F64 => Num::Float(f64::from_le_bytes(buf)),
        })
    }

    fn can_hold(&self, n: u64, ty: Scalar) -> bool {
        n.checked_mul(ty.size() as u64)
            .is_some_and(|b| b <= self.rest.len() as u64)
    }

    fn location(&self, element: &str, index: u64) -> MeshLocation {
        MeshLocation::Element {
            element: element.to_string(),
            index,
        }
    }

    fn finish(&mut self) -> Result<(), String> {
        match self.rest.len() {
            0 => Ok(()),
            n => Err(format!("{n} more bytes")),
        }
    }
}

fn read_body(
    h: &Header,
    layout: &MeshLayout,
    r: &mut dyn BodyReader,
    name: &str,
) -> Result<Mesh, MeshError> {
    let mut mesh = Mesh::default();
    let mut corners: Vec<u32> = Vec::new();
    for (ei, e) in h.elements.iter().enumerate() {
        if e.props.is_empty() {
            // Nothing to read: a huge count must not become a long empty loop.
            continue;
        }
        for index in 0..e.count {
            r.begin_instance();
            let mut xyz = [0f32; 3];
            for (pi, p) in e.props.iter().enumerate() {
                // Named only when an error is reported: this loop runs per value.
                let field = || format!("{} property {}", e.name, p.name);
                let fail = |r: &dyn BodyReader, f: ReadFail, ty: Scalar| {
                    let (expected, found) = match f {
                        ReadFail::Truncated => {
                            (format!("a {ty:?} value"), "end of data".to_string())
                        }
                        ReadFail::Malformed(t) => (format!("a {ty:?} number"), t),
                        ReadFail::OutOfRange(t) => (format!("a value in the range of {ty:?}"), t),
                    };
                    MeshError::new(name, r.location(&e.name, index), field(), expected, found)
                };
                match p.kind {
                    PropKind::Scalar(ty) => {
                        let v = r.read(ty).map_err(|f| fail(r, f, ty))?;
                        if ei == layout.vertex_element {
                            if let Some(axis) = layout.xyz.iter().position(|&k| k == pi) {
                                let c = v.as_f64() as f32;
                                if !c.is_finite() {
                                    return Err(MeshError::new(
                                        name,
                                        r.location(&e.name, index),
                                        field(),
                                        "a finite coordinate within f32 range",
                                        format!("{}", v.as_f64()),
                                    ));
                                }
                                xyz[axis] = c;
                            }
                        }
                    }
                    PropKind::List { count, item } => {
                        let n = match r.read(count).map_err(|f| fail(r, f, count))? {
                            Num::Int(n) if n >= 0 => n as u64,
                            other => {
                                return Err(MeshError::new(
                                    name,
                                    r.location(&e.name, index),
                                    format!("{} count", field()),
                                    "a non-negative count",
                                    format!("{}", other.as_f64()),
                                ))
                            }
                        };
                        if !r.can_hold(n, item) {
                            return Err(fail(r, ReadFail::Truncated, item));
                        }
                        let is_faces = ei == layout.face_element && pi == layout.indices;
                        corners.clear();
                        for _ in 0..n {
                            let v = r.read(item).map_err(|f| fail(r, f, item))?;
                            if is_faces {
                                corners.push(
                                    vertex_index(v, mesh.vertices.len() as u64).ok_or_else(
                                        || {
                                            MeshError::new(
                                                name,
                                                r.location(&e.name, index),
                                                field(),
                                                format!(
                                                    "vertex indices in 0..{}",
                                                    mesh.vertices.len()
                                                ),
                                                format!("{}", v.as_f64()),
                                            )
                                        },
                                    )?,
                                );
                            }
                        }
                        if is_faces {
                            if corners.len() < 3 {
                                return Err(MeshError::new(
                                    name,
                                    r.location(&e.name, index),
                                    field(),
                                    "at least 3 vertex indices",
                                    corners.len().to_string(),
                                ));
                            }
                            fan_triangulate(&corners, &mut mesh.triangles);
                        }
                    }
                }
            }
            r.end_instance().map_err(|found| {
                MeshError::new(
                    name,
                    r.location(&e.name, index),
                    format!("{} instance", e.name),
                    format!("the end of the line after its {} properties", e.props.len()),
                    found,
                )
            })?;
            if ei == layout.vertex_element {
                mesh.vertices.push(Vec3::from(xyz));
            }
        }
    }
    if let Err(found) = r.finish() {
        let last = h.elements.last().map_or("header", |e| e.name.as_str());
        return Err(MeshError::new(
            name,
            r.location(last, h.elements.last().map_or(0, |e| e.count)),
            "body",
            "the end of the file after the declared elements",
            found,
        ));
    }
    Ok(mesh)
}

fn vertex_index(v: Num, vertex_count: u64) -> Option<u32> {
    match v {
        Num::Int(i) if i >= 0 && (i as u64) < vertex_count => u32::try_from(i).ok(),
        _ => None,
    }
}

/// Writes a mesh as PLY: `float x y z` per vertex and
/// `list uchar uint vertex_indices` per triangle. Ascii coordinates are
/// printed in Rust's shortest round-trip form, so reading back is exact.
pub fn write_ply(mesh: &Mesh, format: PlyFormat) -> Vec<u8> {
    let mut out = Vec::new();
    let fmt = match format {
        PlyFormat::Ascii => "ascii",
        PlyFormat::BinaryLittleEndian => "binary_little_endian",
    };
    out.extend_from_slice(
        format!(
            "ply\nformat {fmt} 1.0\ncomment written by hiermerge golden\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar uint vertex_indices\nend_header\n",
            mesh.vertices.len(),
            mesh.triangles.len()
        )
        .as_bytes(),
    );
    match format {
        PlyFormat::Ascii => {
            for v in &mesh.vertices {
                out.extend_from_slice(format!("{} {} {}\n", v.x, v.y, v.z).as_bytes());
            }
            for t in &mesh.triangles {
                out.extend_from_slice(format!("3 {} {} {}\n", t[0], t[1], t[2]).as_bytes());
            }
        }
        PlyFormat::BinaryLittleEndian => {
            for v in &mesh.vertices {
                for c in v.to_array() {
                    out.extend_from_slice(&c.to_le_bytes());
                }
            }
            for t in &mesh.triangles {
                out.push(3);
                for i in t {
                    out.extend_from_slice(&i.to_le_bytes());
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const QUAD_HEADER: &str = "ply\nformat ascii 1.0\ncomment c\nelement vertex 4\nproperty float x\nproperty float y\nproperty double z\nproperty uchar red\nelement edge 1\nproperty int a\nproperty int b\nelement face 1\nproperty uchar flags\nproperty list uchar int vertex_index\nend_header\n";

    #[test]
    fn ascii_with_extra_properties_and_elements() {
        let text =
            format!("{QUAD_HEADER}0 0 0 255\n1 0 0 1\n1 1 0 2\n0 1 0.5 3\n0 1\n7 4 0 1 2 3\n");
        let m = parse_ply(text.as_bytes(), "q.ply").unwrap();
        assert_eq!(m.vertices.len(), 4);
        assert_eq!(m.vertices[3], Vec3::new(0.0, 1.0, 0.5));
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn ascii_errors_name_line_and_field() {
        let text = format!("{QUAD_HEADER}0 0 0 255\n1 0 0 1\n1 1 0 256\n");
        let e = parse_ply(text.as_bytes(), "q.ply").unwrap_err();
        assert_eq!(e.location, MeshLocation::Line(18));
        assert_eq!(e.field, "vertex property red");
        let text = format!("{QUAD_HEADER}0 0 0 255\n1 0 0 1\n1 1 nan 2\n");
        let e = parse_ply(text.as_bytes(), "q.ply").unwrap_err();
        assert_eq!(
            (e.location.clone(), e.field.as_str()),
            (MeshLocation::Line(18), "vertex property z")
        );
        let text =
            format!("{QUAD_HEADER}0 0 0 255\n1 0 0 1\n1 1 0 2\n0 1 0.5 3\n0 1\n7 4 0 1 2 4\n");
        let e = parse_ply(text.as_bytes(), "q.ply").unwrap_err();
        assert_eq!(e.field, "face property vertex_index");
        assert!(e.expected.contains("0..4"));
        let text = format!("{QUAD_HEADER}0 0 0 255\n1 0 0 1\n1 1 0 2\n0 1 0.5 3\n0 1\n7 2 0 1\n");
        let e = parse_ply(text.as_bytes(), "q.ply").unwrap_err();
        assert_eq!(e.expected, "at least 3 vertex indices");
        let text = format!("{QUAD_HEADER}0 0 0 255\n1 0 0 1\n");
        let e = parse_ply(text.as_bytes(), "q.ply").unwrap_err();
        assert_eq!(e.found, "end of data");
    }

    /// Issue 21: a short row shifted every later value by one and was blamed
    /// on a later line; extra rows and bytes after the elements were
    /// ignored, in ascii and binary.
    #[test]
    fn rows_are_strict_and_nothing_follows_the_elements() {
        let good =
            format!("{QUAD_HEADER}0 0 0 255\n1 0 0 1\n1 1 0 2\n0 1 0.5 3\n0 1\n7 4 0 1 2 3\n");
        parse_ply(good.as_bytes(), "q.ply").unwrap();
        let short =
            format!("{QUAD_HEADER}0 0 0 255\n1 0 0\n1 1 0 2\n0 1 0.5 3\n0 1\n7 4 0 1 2 3\n");
        let e = parse_ply(short.as_bytes(), "q.ply").unwrap_err();
        assert_eq!(
            (e.location.clone(), e.field.as_str(), e.found.as_str()),
            (
                MeshLocation::Line(17),
                "vertex property red",
                "the end of the line"
            )
        );
        let long =
            format!("{QUAD_HEADER}0 0 0 255 9\n1 0 0 1\n1 1 0 2\n0 1 0.5 3\n0 1\n7 4 0 1 2 3\n");
        let e = parse_ply(long.as_bytes(), "q.ply").unwrap_err();
        assert_eq!(
            (e.location.clone(), e.field.as_str(), e.found.as_str()),
            (MeshLocation::Line(16), "vertex instance", "\"9\"")
        );
        for tail in ["7 3 0 1 2\n", "garbage"] {
            let extra = format!("{good}\n{tail}");
            let e = parse_ply(extra.as_bytes(), "q.ply").unwrap_err();
            assert_eq!(
                (e.location.clone(), e.field.as_str()),
                (MeshLocation::Line(23), "body"),
                "{e}"
            );
        }
        let m = Mesh {
            vertices: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            triangles: vec![[0, 1, 2]],
        };
        let mut bytes = write_ply(&m, PlyFormat::BinaryLittleEndian);
        bytes.push(0);
        let e = parse_ply(&bytes, "t.ply").unwrap_err();
        assert_eq!(
            (e.field.as_str(), e.found.as_str()),
            ("body", "1 more bytes")
        );
    }

    #[test]
    fn header_errors() {
        let e = parse_ply(b"ply\nformat binary_big_endian 1.0\nend_header\n", "b.ply").unwrap_err();
        assert!(e.to_string().contains("unsupported"), "{e}");
        assert_eq!(e.location, MeshLocation::Line(2));
        let e = parse_ply(b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n", "b.ply").unwrap_err();
        assert_eq!(e.field, "vertex property z");
        let e = parse_ply(b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n", "b.ply").unwrap_err();
        assert_eq!(e.field, "element face");
        let e = parse_ply(b"ply\nelement vertex 0\nend_header\n", "b.ply").unwrap_err();
        assert_eq!(e.field, "format");
        let e = parse_ply(
            b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\n",
            "b.ply",
        )
        .unwrap_err();
        assert_eq!(
            (e.field.as_str(), e.found.as_str()),
            ("header", "end of file")
        );
        let e = parse_ply(b"ply\nformat ascii 1.0\nproperty float x\n", "b.ply").unwrap_err();
        assert_eq!(e.field, "property");
        let e = parse_ply(
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty flaot x\n",
            "b.ply",
        )
        .unwrap_err();
        assert_eq!(
            (e.field.as_str(), e.location.clone()),
            ("property type", MeshLocation::Line(4))
        );
        let e = parse_ply(b"obj\n", "b.ply").unwrap_err();
        assert_eq!(e.field, "magic");
    }

    #[test]
    fn binary_truncation_names_the_element() {
        let m = Mesh {
            vertices: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            triangles: vec![[0, 1, 2]],
        };
        let bytes = write_ply(&m, PlyFormat::BinaryLittleEndian);
        assert_eq!(parse_ply(&bytes, "t.ply").unwrap(), m);
        let cut = &bytes[..bytes.len() - 2];
        let e = parse_ply(cut, "t.ply").unwrap_err();
        assert_eq!(
            e.location,
            MeshLocation::Element {
                element: "face".into(),
                index: 0
            }
        );
        let header_len = bytes.len() - 3 * 12 - 13;
        let cut = &bytes[..header_len + 12 + 5];
        let e = parse_ply(cut, "t.ply").unwrap_err();
        assert_eq!(
            (e.location, e.field.as_str()),
            (
                MeshLocation::Element {
                    element: "vertex".into(),
                    index: 1
                },
                "vertex property y"
            )
        );
    }
}
