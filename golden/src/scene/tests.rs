//! Scene files: the shipped scenes parse, placements per frame, the JSON
//! paths of errors, the schema's agreement with the serde types.

use std::path::Path;

use glam::DVec3;
use serde_json::{json, Value};

use super::*;

const DEFAULT: &str = include_str!("../../../scenes/default.json");
const BUNNY_TEAPOT: &str = include_str!("../../../scenes/bunny_teapot.json");
const GROUPS: &str = include_str!("../../../scenes/groups.json");

fn small() -> Value {
    json!({
        "grid": { "max_lod": 12, "quant_bits": 6, "unit": 0.001953125, "origin": [0, 0, 0] },
        "frames": 5,
        "image": { "width": 8, "height": 6 },
        "camera": { "eye": [4, 4, -4], "target": [4, 1, 4], "fov_y_degrees": 50 },
        "objects": [
            { "name": "ball", "motion": "dynamic",
              "shape": { "sphere": { "center": [0.5, 0.5, 0.5], "radius": 0.4 } },
              "placement": { "keyframes": [ { "frame": 1, "offset": [1, 0, 0] },
                                            { "frame": 3, "offset": [3, 2, 0] } ] } }
        ],
        "effects": {
            "units": { "translation": true, "merge": { "mode": "fixed", "level": 3 }, "upper_build": true },
            "rays": { "primary": true, "clip_distance": 10 }
        }
    })
}

fn parse(v: &Value) -> Result<Scene, SceneError> {
    Scene::parse(&v.to_string(), "t.json", Path::new("."))
}

#[test]
fn shipped_scenes_parse() {
    let d = Scene::parse(DEFAULT, "default.json", Path::new(".")).unwrap();
    assert_eq!(d.frames, 4);
    assert_eq!(d.objects.len(), 6);
    assert!(d.effects.translation && d.effects.shadow);
    assert_eq!(d.effects.reflection_depth, 2);
    let statics = d
        .objects
        .iter()
        .filter(|o| o.motion == Motion::Static)
        .count();
    assert_eq!(statics, 3);
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes");
    let b = Scene::parse(BUNNY_TEAPOT, "bunny_teapot.json", &base).unwrap();
    assert_eq!(b.objects[1].mesh.len(), 3674);
    assert_eq!(b.objects[2].mesh.len(), 992);
    assert_eq!(b.effects.merge, MergeMode::PerNode { num: 1, den: 2 });
    let g = Scene::parse(GROUPS, "groups.json", &base).unwrap();
    assert_eq!(g.groups, vec![vec![2, 3], vec![0, 1]]);
}

#[test]
fn keyframes_hold_outside_and_interpolate_between() {
    let s = parse(&small()).unwrap();
    let o = &s.objects[0].offsets;
    let x = |i: usize| o[i];
    assert_eq!(o.len(), 5);
    assert_eq!(x(0), DVec3::new(1.0, 0.0, 0.0));
    assert_eq!(x(1), DVec3::new(1.0, 0.0, 0.0));
    assert_eq!(x(2), DVec3::new(2.0, 1.0, 0.0));
    assert_eq!(x(3), DVec3::new(3.0, 2.0, 0.0));
    assert_eq!(x(4), DVec3::new(3.0, 2.0, 0.0));
    assert_eq!(s.effects.merge, MergeMode::Fixed(3));
}

fn two_objects() -> Value {
    let mut v = small();
    let mut other = v["objects"][0].clone();
    other["name"] = json!("post");
    v["objects"].as_array_mut().unwrap().push(other);
    v
}

#[test]
fn groups_name_objects_and_cover_each_once() {
    let s = parse(&small()).unwrap();
    assert_eq!(s.groups, vec![vec![0]]);
    let mut v = two_objects();
    v["effects"]["units"]["groups"] = json!([["post"], ["ball"]]);
    assert_eq!(parse(&v).unwrap().groups, vec![vec![1], vec![0]]);
    let err = |groups: Value| {
        let mut v = two_objects();
        v["effects"]["units"]["groups"] = groups;
        let e = parse(&v).unwrap_err();
        (e.path.clone(), e.to_string())
    };
    let (path, msg) = err(json!([["ball"], ["bal"]]));
    assert_eq!(path, "effects.units.groups[1][0]");
    assert!(msg.contains("\"bal\""), "{msg}");
    let (path, msg) = err(json!([["ball", "post"], ["ball"]]));
    assert_eq!(path, "effects.units.groups[1][0]");
    assert!(msg.contains("already in group 0"), "{msg}");
    let (path, msg) = err(json!([["ball"]]));
    assert_eq!(path, "effects.units.groups");
    assert!(msg.contains("\"post\" (objects[1]) in none"), "{msg}");
    assert_eq!(
        err(json!([["ball", "post"], []])).0,
        "effects.units.groups[1]"
    );
    assert_eq!(err(json!([])).0, "effects.units.groups");
    assert_eq!(err(json!({"a": 1})).0, "effects.units.groups");
}

#[test]
fn errors_name_the_json_path() {
    let path_of = |v: &Value| parse(v).unwrap_err().path;
    let mut v = small();
    v["objects"][0]["placement"]["keyframes"][1]["frame"] = json!(0);
    assert_eq!(path_of(&v), "objects[0].placement.keyframes[1].frame");
    let mut v = small();
    v["objects"][0]["shape"]["sphere"]["radius"] = json!(0);
    assert_eq!(path_of(&v), "objects[0].shape.sphere.radius");
    let mut v = small();
    v["objects"][0]["color"] = json!([0.5, 2, 0]);
    assert_eq!(path_of(&v), "objects[0].color[1]");
    let mut v = small();
    v["effects"]["units"]["merge"] = json!({ "mode": "overlap", "num": 3, "den": 2 });
    assert_eq!(path_of(&v), "effects.units.merge");
    let mut v = small();
    v["effects"]["units"]["merge"]["level"] = json!(13);
    assert_eq!(path_of(&v), "effects.units.merge.level");
    let mut v = small();
    v["effects"]["units"]["rtx"] = json!(true);
    let e = parse(&v).unwrap_err();
    assert_eq!(e.path, "effects.units.rtx");
    assert!(e.found.contains("unknown field `rtx`"), "{e}");
    let mut v = small();
    v["objects"][0]["placement"]["keyframes"][0]["offset"] = json!([1, 0]);
    assert!(path_of(&v).starts_with("objects[0].placement.keyframes[0].offset"));
    let mut v = small();
    v["effects"]["rays"]["primary"] = json!(false);
    v["effects"]["rays"]["shadow"] = json!(true);
    assert_eq!(path_of(&v), "effects.rays.primary");
    let mut v = small();
    v["grid"]["max_lod"] = json!(40);
    assert_eq!(path_of(&v), "grid");
    let e = Scene::parse("{\"grid\": ", "t.json", Path::new(".")).unwrap_err();
    assert_eq!(e.expected, "well-formed JSON");
    assert!(e.to_string().starts_with("t.json: "), "{e}");
}

/// Every key a shipped scene uses is a property the schema declares at that
/// place (through `$ref`s; the merge mode's variants through `oneOf`).
#[test]
fn schema_declares_every_key_the_shipped_scenes_use() {
    let schema: Value = serde_json::from_str(SCHEMA).unwrap();
    fn resolve<'a>(root: &'a Value, s: &'a Value) -> &'a Value {
        match s.get("$ref").and_then(Value::as_str) {
            Some(r) => resolve(root, &root["$defs"][r.trim_start_matches("#/$defs/")]),
            None => s,
        }
    }
    fn walk(root: &Value, s: &Value, v: &Value, path: &str) {
        let s = resolve(root, s);
        match v {
            Value::Object(m) => {
                for (k, child) in m {
                    let sub = s["properties"].get(k).or_else(|| {
                        s["oneOf"]
                            .as_array()?
                            .iter()
                            .find_map(|alt| alt["properties"].get(k))
                    });
                    let sub = sub.unwrap_or_else(|| panic!("{path}.{k} not in the schema"));
                    walk(root, sub, child, &format!("{path}.{k}"));
                }
            }
            Value::Array(items) if s.get("items").is_some() => {
                for (i, child) in items.iter().enumerate() {
                    walk(root, &s["items"], child, &format!("{path}[{i}]"));
                }
            }
            _ => {}
        }
    }
    for text in [DEFAULT, BUNNY_TEAPOT, GROUPS] {
        let v: Value = serde_json::from_str(text).unwrap();
        walk(&schema, &schema, &v, "");
    }
    // And the schema's top-level required keys are the serde type's.
    let required: Vec<&str> = schema["required"]
        .as_array()
        .unwrap()
        .iter()
        .map(|k| k.as_str().unwrap())
        .collect();
    let mut v = small();
    for key in &required {
        let removed = v.as_object_mut().unwrap().remove(*key).unwrap();
        let e = parse(&v).unwrap_err();
        assert!(e.found.contains(&format!("missing field `{key}`")), "{e}");
        v[*key] = removed;
    }
}

/// Issue 21: a scene with trailing garbage, two documents, the scene or its
/// `grid` written as an array of field values, or a key given twice was read
/// in silence; each is now one error at its JSON path.
#[test]
fn misread_structure_is_refused_at_its_path() {
    let ok = small().to_string();
    for text in [format!("{ok} garbage"), format!("{ok}\n{ok}")] {
        let e = Scene::parse(&text, "t.json", Path::new(".")).unwrap_err();
        assert_eq!(e.path, ".", "{e}");
        assert!(e.found.contains("trailing characters"), "{e}");
    }
    let s = small();
    let fields: Vec<Value> = [
        "name", "grid", "frames", "image", "camera", "lights", "objects", "effects",
    ]
    .iter()
    .map(|k| s.get(*k).cloned().unwrap_or(Value::Null))
    .collect();
    let e = parse(&Value::Array(fields)).unwrap_err();
    assert_eq!(e.path, ".", "{e}");
    assert!(e.found.contains("invalid type: sequence"), "{e}");
    let mut v = small();
    v["grid"] = json!([12, 6, 24, 4, 0.001953125, [0, 0, 0]]);
    let e = parse(&v).unwrap_err();
    assert_eq!(e.path, "grid", "{e}");
    let text = ok.replacen("\"frames\":5", "\"frames\":5,\"frames\":2", 1);
    assert_ne!(text, ok);
    let e = Scene::parse(&text, "t.json", Path::new(".")).unwrap_err();
    assert!(e.found.contains("`frames` twice"), "{e}");
}

/// Issue 21: scenes that failed only at frame 0 (or after seconds and
/// gigabytes) are refused while the file is read, at their JSON path.
#[test]
fn scenes_failing_late_are_refused_up_front() {
    let mut v = small();
    v["effects"]["units"]["merge"] = json!({"mode": "below_top", "levels": 99});
    assert_eq!(parse(&v).unwrap_err().path, "effects.units.merge.levels");
    let mut v = small();
    v["objects"][0]["shape"] = json!({"terrain": {"cells": 2048, "seed": 1}});
    let t = std::time::Instant::now();
    let e = parse(&v).unwrap_err();
    assert_eq!(e.path, "objects[0].shape.terrain", "{e}");
    assert!(t.elapsed().as_secs() < 2);
    let mut v = small();
    v["objects"][0]["shape"]["sphere"]["stacks"] = json!(2048);
    v["objects"][0]["shape"]["sphere"]["slices"] = json!(2048);
    assert_eq!(parse(&v).unwrap_err().path, "objects[0].shape.sphere");
    let mut v = small();
    v["grid"]["index_bits"] = json!(8);
    let e = parse(&v).unwrap_err();
    assert_eq!(e.path, "objects[0].shape", "{e}");
    assert!(e.expected.contains("index_bits"), "{e}");
}

/// Accepted means runnable (SPEC 12.1): a placement that keeps the mesh in
/// the cube in binary64 but not once its vertices are placed and rounded to
/// binary32 (binary32 steps of 1/16 near 1e6, a face between two of them)
/// is refused at its offset; one step less is accepted.
#[test]
fn placements_are_judged_on_binary32_bounds() {
    let scene = |x: f64| {
        let mut v = small();
        v["grid"]["origin"] = json!([1e6 + 0.05, 0, 0]);
        v["objects"][0]["shape"] =
            json!({"box": {"lo": [1e6 + 0.0625, 0.5, 0.5], "hi": [1e6 + 1.0, 1, 1]}});
        v["objects"][0]["placement"] = json!({"offsets": [[x, 0, 0]]});
        v
    };
    // The face is at 1e6 + 8.05; 1e6 + 8.04 rounds to 1e6 + 8.0625.
    let e = parse(&scene(7.04)).unwrap_err();
    assert_eq!(e.path, "objects[0].placement.offsets[0]", "{e}");
    assert!(e.expected.contains("binary32"), "{e}");
    assert!(e.found.contains("frame 0"), "{e}");
    for translation in [true, false] {
        let mut v = scene(7.04);
        v["effects"]["units"]["translation"] = json!(translation);
        assert!(parse(&v).is_err(), "translation {translation}");
        let mut v = scene(7.0);
        v["effects"]["units"]["translation"] = json!(translation);
        parse(&v).unwrap();
    }
}
