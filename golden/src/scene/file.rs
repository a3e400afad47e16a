//! The scene file as written (JSON, SPEC.md section 12): plain serde types,
//! every struct closed to unknown fields. `super::validate` turns a
//! [`SceneFile`] into a checked [`super::Scene`].

use serde::{Deserialize, Serialize};

/// The whole file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// A name shown in reports.
    #[serde(default)]
    pub name: Option<String>,
    pub grid: GridSpec,
    /// Number of frames, 1..=1000.
    pub frames: u32,
    pub image: ImageSpec,
    pub camera: CameraSpec,
    /// Point lights (shadow rays go to each).
    #[serde(default)]
    pub lights: Vec<LightSpec>,
    pub objects: Vec<ObjectSpec>,
    pub effects: EffectsSpec,
}

/// The grid: parameters (SPEC 1) and the map from world units to grid units.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridSpec {
    pub max_lod: u8,
    pub quant_bits: u8,
    #[serde(default = "default_index_bits")]
    pub index_bits: u8,
    #[serde(default = "default_hier_bits")]
    pub hier_bits: u8,
    /// World units per grid unit (> 0, finite).
    pub unit: f64,
    /// The world point at grid coordinate (0, 0, 0).
    pub origin: [f64; 3],
}

fn default_index_bits() -> u8 {
    crate::Params::default().index_bits
}

fn default_hier_bits() -> u8 {
    crate::Params::default().hier_bits
}

/// The image size in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImageSpec {
    pub width: u32,
    pub height: u32,
}

/// A pinhole camera, the same in every frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    pub eye: [f32; 3],
    pub target: [f32; 3],
    #[serde(default = "default_up")]
    pub up: [f32; 3],
    pub fov_y_degrees: f32,
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

/// A point light.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightSpec {
    pub position: [f32; 3],
    #[serde(default = "one")]
    pub intensity: f32,
}

fn one() -> f32 {
    1.0
}

/// Whether an object may move.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MotionSpec {
    Static,
    Dynamic,
}

/// One object: its geometry in its local frame, its motion, its placement
/// per frame and its look.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectSpec {
    pub name: String,
    pub shape: ShapeSpec,
    pub motion: MotionSpec,
    pub placement: PlacementSpec,
    /// Diffuse colour, each channel in [0, 1].
    #[serde(default = "grey")]
    pub color: [f32; 3],
    /// Mirror reflectance in [0, 1] (0: not a mirror).
    #[serde(default)]
    pub mirror: f32,
}

fn grey() -> [f32; 3] {
    [0.7, 0.7, 0.7]
}

/// The geometry of an object, in its local frame (world units).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeSpec {
    /// An OBJ or PLY file, relative to the scene file, scaled uniformly so
    /// that its largest side is `size` and centred at `center`.
    Mesh {
        file: String,
        center: [f32; 3],
        size: f32,
    },
    Sphere {
        center: [f32; 3],
        radius: f32,
        #[serde(default = "default_stacks")]
        stacks: u32,
        #[serde(default = "default_slices")]
        slices: u32,
    },
    Torus {
        center: [f32; 3],
        major: f32,
        minor: f32,
        #[serde(default = "default_slices")]
        rings: u32,
        #[serde(default = "default_stacks")]
        sides: u32,
    },
    Box {
        lo: [f32; 3],
        hi: [f32; 3],
    },
    /// `golden::scenes::terrain(cells, seed)` (over `[0, 1]^2`, heights
    /// near 0.5) scaled by `size` in x and z and by `height` (default
    /// `size`) in y.
    Terrain {
        cells: u32,
        seed: u64,
        #[serde(default = "one")]
        size: f32,
        #[serde(default)]
        height: Option<f32>,
    },
}

fn default_stacks() -> u32 {
    16
}

fn default_slices() -> u32 {
    32
}

/// Where an object's local frame is in each frame, in world units.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum PlacementSpec {
    /// One offset for every frame, or exactly one offset per frame.
    Offsets(Vec<[f64; 3]>),
    /// Offsets at some frames, linear in between, held before the first
    /// and after the last.
    Keyframes(Vec<KeyframeSpec>),
}

/// One keyframe.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeyframeSpec {
    pub frame: u32,
    pub offset: [f64; 3],
}

/// What the scene calls for.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EffectsSpec {
    pub units: UnitsSpec,
    pub rays: RaysSpec,
}

/// The hardware units the scene uses.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UnitsSpec {
    /// Objects are placed by the translation unit (SPEC 7). Without it a
    /// moving object's placement is baked into its vertices and it is rebuilt.
    pub translation: bool,
    /// The merging module and its one mode (SPEC 8).
    pub merge: MergeSpec,
    /// The merging module's upper-level stage (S616) is simulated in RTL.
    pub upper_build: bool,
}

/// A merge mode, as `golden::merge::MergeMode`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "mode", rename_all = "snake_case", deny_unknown_fields)]
pub enum MergeSpec {
    Overlap { num: u32, den: u32 },
    Fixed { level: u8 },
    BelowTop { levels: u8 },
    Proportion { num: u32, den: u32 },
    PerNode { num: u32, den: u32 },
}

/// The kinds of rays traced.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RaysSpec {
    pub primary: bool,
    /// One shadow ray per hit and point light.
    #[serde(default)]
    pub shadow: bool,
    /// Mirror reflections, when present.
    #[serde(default)]
    pub reflections: Option<ReflectionsSpec>,
    /// Rays end at this distance from their origin (world units, > 0).
    pub clip_distance: f32,
}

/// Mirror reflections up to a depth.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReflectionsSpec {
    pub max_depth: u32,
}
