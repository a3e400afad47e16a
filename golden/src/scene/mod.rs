//! Scene files (SPEC.md section 12): the grid, the objects (mesh files or
//! procedural shapes, static or dynamic, placed per frame), the camera, the
//! lights and the effects a scene calls for (which units, which merge mode,
//! which rays). [`Scene::load`] reads and checks a file; every error names
//! the JSON path of the element at fault and what was expected.
//!
//! The JSON Schema of the format is `scene.schema.json` beside this file
//! ([`SCHEMA`]).

mod error;
pub mod file;
mod shapes;
mod validate;

use std::path::Path;
use std::sync::Arc;

use glam::{DVec3, Vec3};

use crate::build::GridMap;
use crate::camera::Camera;
use crate::frames::Motion;
use crate::merge::MergeMode;
use crate::mesh::Mesh;
use crate::params::Params;

pub use error::SceneError;
pub use file::SceneFile;
pub use validate::{MAX_FRAMES, MAX_IMAGE_SIDE, MAX_REFLECTION_DEPTH};

/// The JSON Schema (draft 2020-12) of the scene file.
pub const SCHEMA: &str = include_str!("scene.schema.json");

/// A point light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Position, world units; finite.
    pub position: Vec3,
    /// Brightness, finite and `>= 0`; scales the light's diffuse term (SPEC 12.2).
    pub intensity: f32,
}

/// One object, checked: its local mesh and its offset in every frame.
#[derive(Clone, Debug)]
pub struct SceneObject {
    /// Name from the file: non-empty and unique in the scene.
    pub name: String,
    /// A [`Motion::Static`] object has the same offset in every frame.
    pub motion: Motion,
    /// The mesh in its local frame (world units), shared by every frame.
    pub mesh: Arc<Mesh>,
    /// Placement of the local frame in each frame (world units); one entry
    /// per frame.
    pub offsets: Vec<DVec3>,
    /// Surface colour, RGB, each channel in [0, 1].
    pub color: Vec3,
    /// Mirror reflectance in [0, 1].
    pub mirror: f32,
    /// The saved hierarchy of a static object (SPEC 16), resolved against
    /// the scene file's folder; `hiermerge run` loads it, or builds and saves it.
    pub hierarchy: Option<std::path::PathBuf>,
}

/// What the scene calls for, checked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Effects {
    /// Placement by the translation unit; else placements are baked into
    /// vertices and a moved object is rebuilt.
    pub translation: bool,
    /// The scene's one merge mode (SPEC 8).
    pub merge: MergeMode,
    /// The merging module's upper-level stage (S616) is simulated in RTL.
    pub upper_build: bool,
    /// One camera ray per pixel; true whenever `shadow` or reflections are on.
    pub primary: bool,
    /// A shadow ray from each hit to each light that faces the surface.
    pub shadow: bool,
    /// Mirror bounces per primary ray; 0: no reflection rays.
    pub reflection_depth: u32,
    /// Rays end this far from their origin (world units, > 0).
    pub clip_distance: f32,
}

/// A checked scene.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The file's `name`, or the file name when it has none.
    pub name: String,
    /// Grid and record parameters (SPEC 1).
    pub params: Params,
    /// Maps world units to grid units.
    pub grid: GridMap,
    /// Number of frames, `1..=1000`.
    pub frames: u32,
    /// Image width in pixels, `1..=8192`.
    pub width: u32,
    /// Image height in pixels, `1..=8192`.
    pub height: u32,
    /// The camera, the same in every frame; [`Camera::is_valid`] holds.
    pub camera: Camera,
    /// Point lights; may be empty.
    pub lights: Vec<Light>,
    /// Objects in file order, `1..=2^H - 1` of them; an object's index is its id ([`Scene::object_id`]).
    pub objects: Vec<SceneObject>,
    /// Units and rays the scene calls for.
    pub effects: Effects,
    /// Merge groups as object ids (paragraph 67), every object in exactly
    /// one, in the file's order; one group of every object when the file
    /// names none.
    pub groups: Vec<Vec<u8>>,
}

impl Scene {
    /// Reads and checks the scene file at `path`; mesh files are relative
    /// to its folder.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let name = path.display().to_string();
        let text = crate::input::read_text(path, crate::input::MAX_JSON_BYTES)
            .map_err(|e| SceneError::new(&name, ".", e.expected, e.found))?;
        let base = path.parent().unwrap_or(Path::new("."));
        Scene::parse(&text, &name, base)
    }

    /// Parses and checks scene text; `file` names it in errors, `base` is
    /// the folder mesh files are relative to.
    pub fn parse(text: &str, file: &str, base: &Path) -> Result<Scene, SceneError> {
        let raw = parse_file(text, file)?;
        validate::validate(&raw, file, base)
    }

    /// The ids objects get: their index in the file.
    pub fn object_id(index: usize) -> u8 {
        index as u8
    }
}

/// Parses the JSON into the file types, naming the JSON path of the first
/// element that does not fit.
pub fn parse_file(text: &str, file: &str) -> Result<SceneFile, SceneError> {
    let doc = crate::json::parse(text)
        .map_err(|e| SceneError::new(file, ".", "well-formed JSON", e.to_string()))?;
    crate::json::from_value(&doc).map_err(|(path, e)| {
        SceneError::new(
            file,
            path,
            "the scene format (SPEC.md section 12)",
            e.to_string(),
        )
    })
}

#[cfg(test)]
mod tests;
