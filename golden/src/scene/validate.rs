//! From the file types to a checked [`Scene`]: every rule of SPEC.md
//! section 12, each failure naming the JSON path at fault.

use std::collections::BTreeSet;
use std::path::Path;
use std::sync::Arc;

use glam::{DVec3, Vec3};

use super::file::{
    KeyframeSpec, MergeSpec, MotionSpec, ObjectSpec, PlacementSpec, RaysSpec, SceneFile,
};
use super::shapes::shape_mesh;
use super::{Effects, Light, Scene, SceneError, SceneObject};
use crate::build::GridMap;
use crate::camera::Camera;
use crate::frames::Motion;
use crate::merge::MergeMode;
use crate::params::Params;
use crate::world::placed_bounds;

/// Most frames a scene may have.
pub const MAX_FRAMES: u32 = 1000;
/// Largest image side in pixels.
pub const MAX_IMAGE_SIDE: u32 = 8192;
/// Deepest mirror recursion.
pub const MAX_REFLECTION_DEPTH: u32 = 8;

pub fn validate(raw: &SceneFile, file: &str, base: &Path) -> Result<Scene, SceneError> {
    let e =
        |path: &str, expected: &str, found: String| SceneError::new(file, path, expected, found);
    let g = &raw.grid;
    let params = Params::new(g.max_lod, g.quant_bits, g.index_bits, g.hier_bits)
        .map_err(|p| e("grid", "parameters in range (SPEC 1)", p.to_string()))?;
    if !(g.unit.is_finite() && g.unit > 0.0) {
        return Err(e("grid.unit", "a finite number > 0", g.unit.to_string()));
    }
    if !g.origin.iter().all(|c| c.is_finite()) {
        return Err(e(
            "grid.origin",
            "three finite numbers",
            format!("{:?}", g.origin),
        ));
    }
    let grid = GridMap {
        origin: DVec3::from_array(g.origin),
        unit: g.unit,
    };
    if !(1..=MAX_FRAMES).contains(&raw.frames) {
        return Err(e(
            "frames",
            &format!("an integer in 1..={MAX_FRAMES}"),
            raw.frames.to_string(),
        ));
    }
    for (field, v) in [("width", raw.image.width), ("height", raw.image.height)] {
        if !(1..=MAX_IMAGE_SIDE).contains(&v) {
            return Err(e(
                &format!("image.{field}"),
                &format!("an integer in 1..={MAX_IMAGE_SIDE}"),
                v.to_string(),
            ));
        }
    }
    let c = &raw.camera;
    let camera = Camera {
        eye: Vec3::from_array(c.eye),
        target: Vec3::from_array(c.target),
        up: Vec3::from_array(c.up),
        fov_y_degrees: c.fov_y_degrees,
    };
    if !camera.is_valid() {
        return Err(e(
            "camera",
            "finite eye, target and up, eye != target, up not along the view, 0 < fov_y_degrees < 180",
            format!("{c:?}"),
        ));
    }
    let mut lights = Vec::new();
    for (i, l) in raw.lights.iter().enumerate() {
        if !l.position.iter().all(|v| v.is_finite()) {
            return Err(e(
                &format!("lights[{i}].position"),
                "three finite numbers",
                format!("{:?}", l.position),
            ));
        }
        if !(l.intensity.is_finite() && l.intensity >= 0.0) {
            return Err(e(
                &format!("lights[{i}].intensity"),
                "a finite number >= 0",
                l.intensity.to_string(),
            ));
        }
        lights.push(Light {
            position: Vec3::from_array(l.position),
            intensity: l.intensity,
        });
    }
    let effects = effects(raw, &params, file)?;
    let group_count = raw.effects.units.groups.as_ref().map_or(1, Vec::len).max(1);
    let capacity = params.hier_capacity().saturating_sub(group_count as u64);
    if raw.objects.is_empty() || raw.objects.len() as u64 > capacity {
        return Err(e(
            "objects",
            &format!(
                "1..={capacity} objects (hier_bits {}; the last {group_count} ids are the merged hierarchies')",
                params.hier_bits
            ),
            format!("{} objects", raw.objects.len()),
        ));
    }
    let mut names = BTreeSet::new();
    let mut objects = Vec::new();
    for (i, o) in raw.objects.iter().enumerate() {
        let path = format!("objects[{i}]");
        if o.name.is_empty() || !names.insert(o.name.clone()) {
            return Err(e(
                &format!("{path}.name"),
                "a non-empty name no other object has",
                format!("{:?}", o.name),
            ));
        }
        objects.push(object(o, raw, &params, &grid, file, &path, base)?);
    }
    if !effects.primary && (effects.shadow || effects.reflection_depth > 0) {
        return Err(e(
            "effects.rays.primary",
            "true when shadow rays or reflections are asked for (they start at primary hits)",
            "false".into(),
        ));
    }
    let groups = groups(raw, file)?;
    Ok(Scene {
        name: raw.name.clone().unwrap_or_else(|| file.to_string()),
        params,
        grid,
        frames: raw.frames,
        width: raw.image.width,
        height: raw.image.height,
        camera,
        lights,
        objects,
        effects,
        groups,
    })
}

/// `effects.units.groups` as object ids: every name an object's, every
/// object in exactly one group.
fn groups(raw: &SceneFile, file: &str) -> Result<Vec<Vec<u8>>, SceneError> {
    let all = || (0..raw.objects.len()).map(Scene::object_id).collect();
    let Some(named) = &raw.effects.units.groups else {
        return Ok(vec![all()]);
    };
    let e =
        |path: String, expected: &str, found: String| SceneError::new(file, path, expected, found);
    if named.is_empty() {
        return Err(e(
            "effects.units.groups".into(),
            "at least one group (or no `groups`: one group of every object)",
            "[]".into(),
        ));
    }
    let mut group_of = vec![None; raw.objects.len()];
    let mut out = Vec::with_capacity(named.len());
    for (k, g) in named.iter().enumerate() {
        if g.is_empty() {
            return Err(e(
                format!("effects.units.groups[{k}]"),
                "a group of one or more object names",
                "[]".into(),
            ));
        }
        let mut ids = Vec::with_capacity(g.len());
        for (j, name) in g.iter().enumerate() {
            let path = format!("effects.units.groups[{k}][{j}]");
            let Some(i) = raw.objects.iter().position(|o| &o.name == name) else {
                return Err(e(
                    path,
                    "the name of an object of the scene",
                    format!("{name:?}"),
                ));
            };
            if let Some(other) = group_of[i].replace(k) {
                return Err(e(
                    path,
                    "every object in exactly one group",
                    format!("{name:?}, already in group {other}"),
                ));
            }
            ids.push(Scene::object_id(i));
        }
        out.push(ids);
    }
    if let Some(i) = group_of.iter().position(Option::is_none) {
        return Err(e(
            "effects.units.groups".into(),
            "every object in exactly one group",
            format!("object {:?} (objects[{i}]) in none", raw.objects[i].name),
        ));
    }
    Ok(out)
}

fn effects(raw: &SceneFile, params: &Params, file: &str) -> Result<Effects, SceneError> {
    let e =
        |path: &str, expected: &str, found: String| SceneError::new(file, path, expected, found);
    let u = &raw.effects.units;
    let ratio = |num: u32, den: u32| {
        if den == 0 || num > den {
            Err(e(
                "effects.units.merge",
                "a ratio num/den with 1 <= den and num <= den",
                format!("{num}/{den}"),
            ))
        } else {
            Ok(())
        }
    };
    let merge = match u.merge {
        MergeSpec::Overlap { num, den } => {
            ratio(num, den)?;
            MergeMode::Overlap { num, den }
        }
        MergeSpec::Proportion { num, den } => {
            ratio(num, den)?;
            MergeMode::Proportion { num, den }
        }
        MergeSpec::PerNode { num, den } => {
            ratio(num, den)?;
            MergeMode::PerNode { num, den }
        }
        MergeSpec::Fixed { level } => {
            if level > params.max_lod {
                return Err(e(
                    "effects.units.merge.level",
                    &format!("a LOD in 0..={}", params.max_lod),
                    level.to_string(),
                ));
            }
            MergeMode::Fixed(level)
        }
        MergeSpec::BelowTop { levels } => {
            if levels > params.max_lod {
                return Err(e(
                    "effects.units.merge.levels",
                    &format!(
                        "a number of levels in 0..={} (no level lies deeper than max_lod)",
                        params.max_lod
                    ),
                    levels.to_string(),
                ));
            }
            MergeMode::BelowTop(levels)
        }
    };
    let RaysSpec {
        primary,
        shadow,
        reflections,
        clip_distance,
    } = raw.effects.rays;
    if !(clip_distance.is_finite() && clip_distance > 0.0) {
        return Err(e(
            "effects.rays.clip_distance",
            "a finite distance > 0",
            clip_distance.to_string(),
        ));
    }
    let reflection_depth = match reflections {
        None => 0,
        Some(r) if (1..=MAX_REFLECTION_DEPTH).contains(&r.max_depth) => r.max_depth,
        Some(r) => {
            return Err(e(
                "effects.rays.reflections.max_depth",
                &format!("an integer in 1..={MAX_REFLECTION_DEPTH}"),
                r.max_depth.to_string(),
            ))
        }
    };
    Ok(Effects {
        translation: u.translation,
        merge,
        upper_build: u.upper_build,
        primary,
        shadow,
        reflection_depth,
        clip_distance,
    })
}

fn object(
    o: &ObjectSpec,
    raw: &SceneFile,
    params: &Params,
    grid: &GridMap,
    file: &str,
    path: &str,
    base: &Path,
) -> Result<SceneObject, SceneError> {
    let e = |p: String, expected: &str, found: String| SceneError::new(file, p, expected, found);
    let mesh = shape_mesh(&o.shape, file, &format!("{path}.shape"), base)?;
    let index_limit = 1u64 << params.index_bits;
    if mesh.len() as u64 >= index_limit {
        return Err(e(
            format!("{path}.shape"),
            &format!(
                "fewer than 2^{} = {index_limit} triangles (a triangle index has grid.index_bits bits)",
                params.index_bits
            ),
            format!("{} triangles", mesh.len()),
        ));
    }
    for (i, c) in o.color.iter().enumerate() {
        if !(0.0..=1.0).contains(c) {
            return Err(e(
                format!("{path}.color[{i}]"),
                "a number in [0, 1]",
                c.to_string(),
            ));
        }
    }
    if !(0.0..=1.0).contains(&o.mirror) {
        return Err(e(
            format!("{path}.mirror"),
            "a number in [0, 1]",
            o.mirror.to_string(),
        ));
    }
    let offsets = offsets(&o.placement, raw.frames, file, &format!("{path}.placement"))?;
    let motion = match o.motion {
        MotionSpec::Static => Motion::Static,
        MotionSpec::Dynamic => Motion::Dynamic,
    };
    if motion == Motion::Static && offsets.iter().any(|v| *v != offsets[0]) {
        return Err(e(
            format!("{path}.placement"),
            "the same offset in every frame (the object is static)",
            "offsets that change".into(),
        ));
    }
    if o.hierarchy.is_some() && motion != Motion::Static {
        return Err(e(
            format!("{path}.hierarchy"),
            "a saved hierarchy only on a static object (a dynamic one is rebuilt as it moves)",
            "a dynamic object".into(),
        ));
    }
    // Accepted means runnable (SPEC 12.1): the bounds judged are the ones
    // the build will see, every vertex rounded to binary32 after placement.
    let bounds = mesh.bounds();
    let (glo, ghi) = placed_bounds(grid, bounds, DVec3::ZERO);
    let edge = params.scene_edge() as f64;
    let inside = |a: DVec3, b: DVec3| a.min_element() >= 0.0 && b.max_element() <= edge;
    if !inside(glo, ghi) {
        return Err(e(
            format!("{path}.shape"),
            &format!(
                "a local mesh inside the scene cube, grid units [0, {edge}] (world [{:?}, {:?}])",
                grid.origin.to_array(),
                (grid.origin + DVec3::splat(edge * grid.unit)).to_array()
            ),
            format!(
                "bounds {:?} .. {:?} in grid units",
                glo.to_array(),
                ghi.to_array()
            ),
        ));
    }
    for (k, off) in offsets.iter().enumerate() {
        // With translation the world's last resort (SPEC 7.10) is the mesh
        // moved by the whole placement in grid units; without, the offset
        // baked into the vertices.
        let by = if raw.effects.units.translation {
            *off / grid.unit * grid.unit
        } else {
            *off
        };
        let (plo, phi) = placed_bounds(grid, bounds, by);
        if !inside(plo, phi) {
            return Err(e(
                placement_path(&o.placement, &format!("{path}.placement"), k),
                &format!(
                    "a placement keeping the object inside the scene cube once its vertices are \
                     placed and rounded to binary32, grid units [0, {edge}]"
                ),
                format!(
                    "frame {k}: offset {:?} puts it at {:?} .. {:?} in grid units",
                    off.to_array(),
                    plo.to_array(),
                    phi.to_array()
                ),
            ));
        }
    }
    Ok(SceneObject {
        name: o.name.clone(),
        motion,
        mesh: Arc::new(mesh),
        offsets,
        color: Vec3::from_array(o.color),
        mirror: o.mirror,
        hierarchy: o.hierarchy.as_ref().map(|f| base.join(f)),
    })
}

/// The path of the element that gives frame `k`'s offset.
fn placement_path(p: &PlacementSpec, path: &str, k: usize) -> String {
    match p {
        PlacementSpec::Offsets(v) if v.len() == 1 => format!("{path}.offsets[0]"),
        PlacementSpec::Offsets(_) => format!("{path}.offsets[{k}]"),
        PlacementSpec::Keyframes(_) => format!("{path}.keyframes"),
    }
}

/// One offset per frame.
fn offsets(
    p: &PlacementSpec,
    frames: u32,
    file: &str,
    path: &str,
) -> Result<Vec<DVec3>, SceneError> {
    let e = |p: String, expected: &str, found: String| SceneError::new(file, p, expected, found);
    let finite = |v: [f64; 3], p: String| {
        if v.iter().all(|c| c.is_finite()) {
            Ok(DVec3::from_array(v))
        } else {
            Err(e(p, "three finite numbers", format!("{v:?}")))
        }
    };
    match p {
        PlacementSpec::Offsets(list) => {
            if list.len() != 1 && list.len() != frames as usize {
                return Err(e(
                    format!("{path}.offsets"),
                    &format!("1 or {frames} (frames) offsets"),
                    format!("{} offsets", list.len()),
                ));
            }
            let v: Vec<DVec3> = list
                .iter()
                .enumerate()
                .map(|(i, &o)| finite(o, format!("{path}.offsets[{i}]")))
                .collect::<Result<_, _>>()?;
            Ok((0..frames as usize)
                .map(|k| v[k.min(v.len() - 1)])
                .collect())
        }
        PlacementSpec::Keyframes(keys) => {
            if keys.is_empty() {
                return Err(e(
                    format!("{path}.keyframes"),
                    "at least one keyframe",
                    "none".into(),
                ));
            }
            let mut prev: Option<u32> = None;
            let mut pts = Vec::new();
            for (i, &KeyframeSpec { frame, offset }) in keys.iter().enumerate() {
                if frame >= frames || prev.is_some_and(|p| frame <= p) {
                    return Err(e(
                        format!("{path}.keyframes[{i}].frame"),
                        &format!("a frame in 0..{frames}, above the previous keyframe's",),
                        frame.to_string(),
                    ));
                }
                prev = Some(frame);
                pts.push((
                    frame,
                    finite(offset, format!("{path}.keyframes[{i}].offset"))?,
                ));
            }
            Ok((0..frames).map(|k| interpolate(&pts, k)).collect())
        }
    }
}

/// Linear between the keyframes around `k`, held outside them.
fn interpolate(keys: &[(u32, DVec3)], k: u32) -> DVec3 {
    let first = keys[0];
    let last = keys[keys.len() - 1];
    if k <= first.0 {
        return first.1;
    }
    if k >= last.0 {
        return last.1;
    }
    let i = keys
        .iter()
        .position(|&(f, _)| f > k)
        .expect("k is below the last key");
    let (f0, a) = keys[i - 1];
    let (f1, b) = keys[i];
    if k == f0 {
        return a;
    }
    let t = (k - f0) as f64 / (f1 - f0) as f64;
    a + (b - a) * t
}
