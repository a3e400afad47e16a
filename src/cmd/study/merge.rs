//! Merging in the study (SPEC 13.4): a case and a copy of it moved by half
//! its extent along x, each its own hierarchy placed by its translation,
//! merged by golden (`World::merge`); the merge timed as the median of
//! repeats, and the sweep over merging modes and thresholds.

use glam::DVec3;
use golden::merge::MergeMode;
use golden::mesh::Mesh;
use golden::world::World;
use golden::Params;
use serde::Serialize;

use super::sweep::median_time;
use crate::cmd::common::placement_grid;

/// The world of the pair: the mesh at 0 (id 0) and its copy moved (id 1).
fn pair_world(mesh: &Mesh, params: Params) -> Result<World, String> {
    let shift = super::distance::copy_shift(mesh);
    let meshes = [mesh.clone(), mesh.clone()];
    let offsets = [DVec3::ZERO, shift];
    let grid = placement_grid(&meshes, &offsets, &params)?;
    let mut world = World::new(params, grid).map_err(|e| e.to_string())?;
    for (i, (m, off)) in meshes.into_iter().zip(offsets).enumerate() {
        world.add(i as u8, m, off).map_err(|e| e.to_string())?;
    }
    Ok(world)
}

/// Median merge time (seconds) of the pair and the merging level chosen.
pub fn merge_pair(
    mesh: &Mesh,
    params: Params,
    mode: MergeMode,
    repeats: usize,
) -> Result<(f64, Option<u8>), String> {
    let mut world = pair_world(mesh, params)?;
    let out = (params.hier_capacity() - 1) as u8;
    let (s, r) = median_time(repeats, || world.merge(&[0, 1], mode, out));
    let r = r.map_err(|e| e.to_string())?;
    Ok((s, r.level))
}

/// One merging mode on the pair at one configuration.
#[derive(Serialize, Clone, Debug)]
pub struct ModeRow {
    pub case: String,
    pub mode: String,
    pub merging_level: Option<u8>,
    pub nodes_created: u64,
    pub nodes_reused: u64,
    pub merge_ms: f64,
    pub default_mode: bool,
}

/// The modes the study sweeps: overlap thresholds, fixed levels around
/// the default's, per-node merging.
pub fn modes(full: bool) -> Vec<MergeMode> {
    let mut m: Vec<MergeMode> = [(1, 4), (1, 2), (3, 4)]
        .into_iter()
        .map(|(num, den)| MergeMode::Overlap { num, den })
        .collect();
    if full {
        m.extend(
            [(0, 1), (1, 8), (7, 8), (1, 1)].map(|(num, den)| MergeMode::Overlap { num, den }),
        );
    }
    m.extend([0, 1, 2].map(MergeMode::BelowTop));
    m.push(MergeMode::Proportion { num: 1, den: 2 });
    m.push(MergeMode::PerNode { num: 1, den: 2 });
    m
}

/// Runs every mode of `modes` on the pair of `mesh`.
pub fn sweep_modes(
    case: &str,
    mesh: &Mesh,
    params: Params,
    modes: &[MergeMode],
    repeats: usize,
    progress: &mut dyn FnMut(),
) -> Result<Vec<ModeRow>, String> {
    let mut world = pair_world(mesh, params)?;
    let out = (params.hier_capacity() - 1) as u8;
    let mut rows = Vec::new();
    for &mode in modes {
        let (s, r) = median_time(repeats, || world.merge(&[0, 1], mode, out));
        let r = r.map_err(|e| format!("{case}: merge {}: {e}", mode_name(&mode)))?;
        rows.push(ModeRow {
            case: case.to_string(),
            mode: mode_name(&mode),
            merging_level: r.level,
            nodes_created: r.stats.created(),
            nodes_reused: r.stats.reused(),
            merge_ms: s * 1e3,
            default_mode: mode == MergeMode::Overlap { num: 1, den: 2 },
        });
        progress();
    }
    Ok(rows)
}

/// A mode as `--mode` spells it.
pub fn mode_name(m: &MergeMode) -> String {
    m.to_string()
}
