//! Wavefront OBJ import: positions (`v`) and faces (`f`).
//!
//! Rules (SPEC.md, "Mesh import"): `v x y z [w]` gives a vertex (`w` and any
//! further numbers, e.g. vertex colours, must be numbers and are ignored);
//! `f` takes three or more corners, each `v`, `v/vt`, `v/vt/vn` or `v//vn`,
//! of which only `v` is used; an index `k > 0` is the `k`-th vertex of the
//! file, `k < 0` counts back from the last vertex defined so far, `0` is an
//! error; both must name a vertex already defined. A polygon
//! `a b c d ...` becomes the fan `(a b c) (a c d) ...`. `vt vn vp o g s
//! usemtl mtllib l p` and comments are ignored; any other statement is an
//! error.

use glam::Vec3;

use super::error::quote;
use super::{Mesh, MeshError, MeshLocation};

/// Statements that carry nothing the mesh needs.
const IGNORED: &[&[u8]] = &[
    b"vt", b"vn", b"vp", b"o", b"g", b"s", b"usemtl", b"mtllib", b"l", b"p",
];

/// Parses OBJ text; `name` names the input in errors.
pub fn parse_obj(bytes: &[u8], name: &str) -> Result<Mesh, MeshError> {
    let mut mesh = Mesh::default();
    for (i, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let line_no = i as u64 + 1;
        let line = strip_comment(raw);
        let mut tokens = line
            .split(|b| b.is_ascii_whitespace())
            .filter(|t| !t.is_empty());
        let Some(keyword) = tokens.next() else {
            continue;
        };
        let err = |field: String, expected: String, found: String| {
            MeshError::new(name, MeshLocation::Line(line_no), field, expected, found)
        };
        match keyword {
            b"v" => mesh.vertices.push(parse_vertex(&mut tokens, &err)?),
            b"f" => parse_face(&mut tokens, &mut mesh, &err)?,
            k if IGNORED.contains(&k) => {}
            other => {
                return Err(err(
                    "statement".into(),
                    "one of v, f, vt, vn, vp, o, g, s, usemtl, mtllib, l, p or a # comment".into(),
                    quote(other),
                ))
            }
        }
    }
    Ok(mesh)
}

fn strip_comment(line: &[u8]) -> &[u8] {
    match line.iter().position(|&b| b == b'#') {
        Some(p) => &line[..p],
        None => line,
    }
}

type ErrFn<'a> = dyn Fn(String, String, String) -> MeshError + 'a;

fn parse_vertex<'t>(
    tokens: &mut impl Iterator<Item = &'t [u8]>,
    err: &ErrFn,
) -> Result<Vec3, MeshError> {
    let mut xyz = [0f32; 3];
    for (axis, c) in xyz.iter_mut().enumerate() {
        let field = format!("v coordinate {}", ["x", "y", "z"][axis]);
        let tok = tokens
            .next()
            .ok_or_else(|| err(field.clone(), "a number".into(), "end of line".into()))?;
        *c = parse_finite_f32(tok)
            .ok_or_else(|| err(field, "a finite number within f32 range".into(), quote(tok)))?;
    }
    for (k, tok) in tokens.enumerate() {
        if parse_f64(tok).is_none() {
            return Err(err(
                format!("v extra value {}", k + 4),
                "a number (w or a colour component)".into(),
                quote(tok),
            ));
        }
    }
    Ok(Vec3::from(xyz))
}

fn parse_face<'t>(
    tokens: &mut impl Iterator<Item = &'t [u8]>,
    mesh: &mut Mesh,
    err: &ErrFn,
) -> Result<(), MeshError> {
    let defined = mesh.vertices.len() as u64;
    let mut corners: Vec<u32> = Vec::with_capacity(4);
    for (k, tok) in tokens.enumerate() {
        let field = format!("f corner {} vertex index", k + 1);
        let vpart = tok.split(|&b| b == b'/').next().unwrap_or(tok);
        let index = std::str::from_utf8(vpart)
            .ok()
            .and_then(|s| s.parse::<i64>().ok())
            .ok_or_else(|| err(field.clone(), "an integer".into(), quote(tok)))?;
        let resolved = resolve_index(index, defined).ok_or_else(|| {
            err(
                field,
                if defined == 0 {
                    "a vertex defined before the face (none are yet)".to_string()
                } else {
                    format!("an index in 1..={defined} or -{defined}..=-1")
                },
                index.to_string(),
            )
        })?;
        corners.push(resolved);
    }
    if corners.len() < 3 {
        return Err(err(
            "f".into(),
            "at least 3 corners".into(),
            format!("{}", corners.len()),
        ));
    }
    fan_triangulate(&corners, &mut mesh.triangles);
    Ok(())
}

/// A 1-based or negative relative OBJ index to a 0-based one.
fn resolve_index(index: i64, defined: u64) -> Option<u32> {
    let zero_based = if index > 0 {
        index as u64 - 1
    } else if index < 0 {
        defined.checked_sub(index.unsigned_abs())?
    } else {
        return None;
    };
    if zero_based < defined {
        u32::try_from(zero_based).ok()
    } else {
        None
    }
}

/// `a b c d ...` to `(a b c) (a c d) ...`.
pub(crate) fn fan_triangulate(corners: &[u32], out: &mut Vec<[u32; 3]>) {
    for k in 1..corners.len() - 1 {
        out.push([corners[0], corners[k], corners[k + 1]]);
    }
}

fn parse_f64(tok: &[u8]) -> Option<f64> {
    std::str::from_utf8(tok).ok()?.parse::<f64>().ok()
}

/// A finite f32 (values beyond f32 range become infinite and are refused).
pub(crate) fn parse_finite_f32(tok: &[u8]) -> Option<f32> {
    let v = parse_f64(tok)? as f32;
    v.is_finite().then_some(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn all_face_forms_and_negative_indices() {
        let text = b"# a quad and a triangle\nmtllib x.mtl\no thing\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0 1.0\nvt 0 0\nvn 0 0 1\ns off\nusemtl m\nf 1/1/1 2/1/1 3//1 4/1\nf -4 -3 -1\n";
        let m = parse_obj(text, "t.obj").unwrap();
        assert_eq!(m.vertices.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 3]]);
    }

    #[test]
    fn errors_name_line_field_and_expectation() {
        let e = parse_obj(b"v 0 0 0\nv 1 x 0\n", "a.obj").unwrap_err();
        assert_eq!(e.location, MeshLocation::Line(2));
        assert_eq!(e.field, "v coordinate y");
        assert!(e
            .to_string()
            .starts_with("a.obj: line 2: v coordinate y: expected a finite"));

        let e = parse_obj(b"v 0 0 nan\n", "a.obj").unwrap_err();
        assert_eq!(e.field, "v coordinate z");
        let e = parse_obj(b"v 0 0 1e39\n", "a.obj").unwrap_err();
        assert_eq!(e.field, "v coordinate z");
        let e = parse_obj(b"v 0 0 inf\n", "a.obj").unwrap_err();
        assert_eq!(e.field, "v coordinate z");

        let e = parse_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", "a.obj").unwrap_err();
        assert_eq!(
            (e.location.clone(), e.field.as_str()),
            (MeshLocation::Line(4), "f corner 3 vertex index")
        );
        assert!(e.expected.contains("1..=3"));
        let e = parse_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "a.obj").unwrap_err();
        assert_eq!(e.found, "4");
        let e = parse_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n", "a.obj").unwrap_err();
        assert_eq!(e.found, "-4");
        let e = parse_obj(b"v 0 0 0\nv 1 0 0\nf 1 2\n", "a.obj").unwrap_err();
        assert_eq!((e.field.as_str(), e.found.as_str()), ("f", "2"));
        let e = parse_obj(b"v 0 0\n", "a.obj").unwrap_err();
        assert_eq!(
            (e.field.as_str(), e.found.as_str()),
            ("v coordinate z", "end of line")
        );
        let e = parse_obj(b"vx 0 0\n", "a.obj").unwrap_err();
        assert_eq!(e.field, "statement");
        let e = parse_obj(
            b"v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 99999999999999999999\r\n",
            "a.obj",
        )
        .unwrap_err();
        assert_eq!(e.location, MeshLocation::Line(4));
    }

    #[test]
    fn crlf_and_comments() {
        let m = parse_obj(
            b"v 0 0 0 # origin\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 3 # tri\r\n",
            "c.obj",
        )
        .unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
    }
}
