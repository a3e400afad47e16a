//! A scene is run through the golden model's frames (builds, placements,
//! merges; no RTL, no rays) before anything is simulated or written, so
//! that a scene the model refuses is refused with the file and the JSON
//! path of what is at fault (SPEC.md section 12), not at frame N with the
//! model's own wording: a placement whose voxel rounding leaves the scene,
//! an index that does not fit `I`, a merging mode the hierarchies cannot
//! meet.

use golden::frames::{FrameError, Frames};
use golden::merge::MergeError;
use golden::scene::{Scene, SceneError};
use golden::world::WorldError;

/// The JSON path a frame's refusal belongs to.
fn path_of(e: &FrameError) -> String {
    let object = |id: u8| format!("objects[{id}]");
    match e {
        FrameError::World(WorldError::Build { id, .. }) => format!("{}.shape", object(*id)),
        FrameError::World(WorldError::Translate { id, .. }) => {
            format!("{}.placement", object(*id))
        }
        FrameError::World(WorldError::Merge(MergeError::InputLeafAtTop { input, .. })) => {
            format!("{}.shape", object(*input))
        }
        FrameError::World(WorldError::Merge(MergeError::IndexOverflow { .. })) => {
            "grid.index_bits".into()
        }
        FrameError::World(WorldError::Merge(_)) => "effects.units.merge".into(),
        FrameError::World(WorldError::Check { id, .. }) => object(*id),
        _ => "objects".into(),
    }
}

/// Runs every frame of `scene` in the golden model; the first refusal as
/// an error naming `file`, the JSON path and the frame.
pub fn check(scene: &Scene, file: &str) -> Result<(), SceneError> {
    let fx = &scene.effects;
    let at = |path: String, frame: usize, e: &dyn std::fmt::Display| {
        SceneError::new(
            file,
            path,
            format!("a scene the golden model can run (frame {frame})"),
            e.to_string(),
        )
    };
    let mut frames = Frames::with_groups(scene.params, scene.grid, fx.merge, scene.groups.clone())
        .map_err(|e| at(path_of(&e), 0, &e))?;
    let mut baked = vec![None; scene.objects.len()];
    for k in 0..scene.frames as usize {
        let objs = super::pipeline::frame_objects(scene, k, &mut baked);
        if k == 0 {
            // Saved hierarchies that exist serve here too; none is written yet.
            super::pipeline::provide_saved(scene, &mut frames, &objs, false)
                .map_err(|e| SceneError::new(file, "objects", "saved hierarchies that load", e))?;
        }
        frames.step(&objs).map_err(|e| at(path_of(&e), k, &e))?;
    }
    Ok(())
}
