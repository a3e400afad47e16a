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
    /// The octree parameters and the map from world units to grid units.
    pub grid: GridSpec,
    /// Number of frames, 1..=1000.
    pub frames: u32,
    /// The rendered image size; the CLI's `--width`/`--height` override it.
    pub image: ImageSpec,
    /// The camera, the same in every frame.
    pub camera: CameraSpec,
    /// Point lights (shadow rays go to each).
    #[serde(default)]
    pub lights: Vec<LightSpec>,
    /// The objects, 1..=`2^H - 1` of them; an object's hierarchy id is its
    /// index here, and id `2^H - 1` is the merged hierarchy's.
    pub objects: Vec<ObjectSpec>,
    /// The hardware units used and the rays traced.
    pub effects: EffectsSpec,
}

/// The grid: parameters (SPEC 1) and the map from world units to grid units.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridSpec {
    /// D, the deepest octree level, 1..=31 (SPEC 1).
    pub max_lod: u8,
    /// Q, bits per quantized box bound per axis, 0..=16 (SPEC 1).
    pub quant_bits: u8,
    /// I, bits of an index or a count, 1..=32 (SPEC 1); default 24.
    #[serde(default = "default_index_bits")]
    pub index_bits: u8,
    /// H, bits of a hierarchy id, 1..=8 (SPEC 1); default 4.
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
    /// Width in pixels, 1..=8192.
    pub width: u32,
    /// Height in pixels, 1..=8192.
    pub height: u32,
}

/// A pinhole camera, the same in every frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    /// The camera's position, world units.
    pub eye: [f32; 3],
    /// The world point the camera looks at; not `eye`.
    pub target: [f32; 3],
    /// The up direction, not along the view; default `[0, 1, 0]`.
    #[serde(default = "default_up")]
    pub up: [f32; 3],
    /// The vertical field of view in degrees, strictly between 0 and 180.
    pub fov_y_degrees: f32,
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

/// A point light.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightSpec {
    /// The light's position, world units.
    pub position: [f32; 3],
    /// Scale of the light's diffuse term, finite and >= 0; default 1.
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
    /// Never moves: the placement gives one offset for every frame.
    Static,
    /// May move from frame to frame.
    Dynamic,
}

/// One object: its geometry in its local frame, its motion, its placement
/// per frame and its look.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectSpec {
    /// A name no other object of the scene has; not empty.
    pub name: String,
    /// The geometry, in the object's local frame.
    pub shape: ShapeSpec,
    /// Whether the object may move.
    pub motion: MotionSpec,
    /// The offset from the local frame to the scene, per frame.
    pub placement: PlacementSpec,
    /// Diffuse colour, each channel in [0, 1].
    #[serde(default = "grey")]
    pub color: [f32; 3],
    /// Mirror reflectance in [0, 1] (0: not a mirror).
    #[serde(default)]
    pub mirror: f32,
    /// A saved hierarchy (SPEC 16) of this static object, relative to the
    /// scene file's folder: loaded instead of built, or built and saved
    /// there when the file does not exist yet.
    #[serde(default)]
    pub hierarchy: Option<String>,
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
        /// Path of the OBJ or PLY file, relative to the scene file's folder.
        file: String,
        /// Where the centre of the mesh's bounding box goes.
        center: [f32; 3],
        /// The largest side of the scaled bounding box, > 0.
        size: f32,
    },
    /// A UV sphere ([`crate::scenes::sphere`]).
    Sphere {
        /// The sphere's centre.
        center: [f32; 3],
        /// The radius, > 0.
        radius: f32,
        /// Latitude bands, 2..=2048; default 16.
        #[serde(default = "default_stacks")]
        stacks: u32,
        /// Longitude segments, 3..=2048; default 32.
        #[serde(default = "default_slices")]
        slices: u32,
    },
    /// A torus around the y axis ([`crate::scenes::torus`]).
    Torus {
        /// The torus's centre.
        center: [f32; 3],
        /// Radius of the ring, from the centre to the tube's axis; above `minor`.
        major: f32,
        /// Radius of the tube, > 0.
        minor: f32,
        /// Segments around the ring, 3..=2048; default 32.
        #[serde(default = "default_slices")]
        rings: u32,
        /// Segments around the tube, 3..=2048; default 16.
        #[serde(default = "default_stacks")]
        sides: u32,
    },
    /// The closed surface of the axis-aligned box `[lo, hi]`: 12 triangles.
    Box {
        /// The minimum corner; below `hi` on every axis.
        lo: [f32; 3],
        /// The maximum corner.
        hi: [f32; 3],
    },
    /// `golden::scenes::terrain(cells, seed)` (over `[0, 1]^2`, heights
    /// near 0.5) scaled by `size` in x and z and by `height` (default
    /// `size`) in y.
    Terrain {
        /// Quads per side, 1..=2048: `2 cells^2` triangles.
        cells: u32,
        /// Seed of the height noise.
        seed: u64,
        /// Scale in x and z, > 0; default 1.
        #[serde(default = "one")]
        size: f32,
        /// Scale in y, > 0; `None`: `size`.
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
    /// The frame index, below `frames` and above the previous keyframe's.
    pub frame: u32,
    /// The offset at that frame, world units.
    pub offset: [f64; 3],
}

/// What the scene calls for.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EffectsSpec {
    /// The hardware units used.
    pub units: UnitsSpec,
    /// The rays traced.
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
    /// Merge groups (paragraph 67): lists of object names, every object in
    /// exactly one; each group is merged into a hierarchy of its own and the
    /// groups are traced together. Absent: one group of every object.
    #[serde(default)]
    pub groups: Option<Vec<Vec<String>>>,
}

/// A merge mode, as `golden::merge::MergeMode`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "mode", rename_all = "snake_case", deny_unknown_fields)]
pub enum MergeSpec {
    /// The deepest candidate level whose overlap is above `num / den` (SPEC 8.2).
    Overlap {
        /// Numerator of the threshold; at most `den`.
        num: u32,
        /// Denominator of the threshold; at least 1.
        den: u32,
    },
    /// A given merging level (SPEC 8.2).
    Fixed {
        /// The merging LOD, at most `max_lod`; the merge fails unless it is a
        /// candidate level.
        level: u8,
    },
    /// A number of levels below the shallowest candidate level (SPEC 8.2).
    BelowTop {
        /// Levels below the top; the merge fails when that is past the deepest
        /// candidate level.
        levels: u8,
    },
    /// `lo + floor((hi - lo) num / den)` over the candidate levels `[lo, hi]`
    /// (SPEC 8.2).
    Proportion {
        /// Numerator of the proportion; at most `den`.
        num: u32,
        /// Denominator of the proportion; at least 1.
        den: u32,
    },
    /// No single level: a group of nodes descends while more than `num / den`
    /// of its child voxels are shared (SPEC 8.5).
    PerNode {
        /// Numerator of the threshold; at most `den`.
        num: u32,
        /// Denominator of the threshold; at least 1.
        den: u32,
    },
}

/// The kinds of rays traced.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RaysSpec {
    /// One camera ray per pixel; must be true when `shadow` or `reflections` is set.
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
    /// Most mirror bounces per primary ray, 1..=8.
    pub max_depth: u32,
}
