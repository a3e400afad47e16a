//! Hit error against distance from the origin (SPEC 13.3): a case placed
//! at distances 1 to 1e9, traced in each number format of positions and
//! compared ray by ray with the independent binary64 reference tracer on
//! the triangles at their requested world positions.

use glam::{DVec3, Vec3};
use golden::build::{build, GridMap};
use golden::geom::ray::Ray;
use golden::geom::triangle::{intersect_triangle, ShearedRay};
use golden::merge::MergeMode;
use golden::mesh::Mesh;
use golden::oracle::reference::ReferenceTracer;
use golden::scenes::SplitMix64;
use golden::trace::{closest_hit, Instance, TraceScene, TraceStats};
use golden::translate::{determine, hierarchy_expansion_cost, Axis, Placement, VoxelRange};
use golden::world::World;
use golden::Params;
use serde::Serialize;

use super::compare::{compare, HitCounts};
use super::inputs::Case;
use crate::cmd::common::placement_grid;

/// One format at one distance (and translation level, for translated formats).
#[derive(Serialize, Clone, Debug)]
pub struct DistanceRow {
    pub distance: f64,
    /// D of the grid the case is placed in.
    pub max_lod: u8,
    pub format: String,
    /// The translation level L (translated formats only).
    pub level: Option<u8>,
    /// Which L it is: "top" (the hierarchy's top LOD), "merging" (the merging
    /// level of the case and a copy moved by half its extent), "middle"
    /// (half-way from the top to D), "D"; "-" untranslated.
    pub level_role: String,
    /// The hierarchy's top LOD at this distance.
    pub top_lod: u8,
    #[serde(flatten)]
    pub hits: HitCounts,
    /// Largest per-axis distance between where the geometry is and where it
    /// was asked to be (world units).
    pub position_error: f64,
    /// Largest absolute coordinate of the vertices as traced (binary32;
    /// local for the translated formats, world for `b32-world`), world units:
    /// what their rounding is relative to.
    pub traced_magnitude: f64,
    /// The residual determine leaves (SPEC 7.1), largest axis, world units.
    pub residual: Option<f64>,
    /// Nodes the expanding variant adds to move the hierarchy at L (SPEC 7.7).
    pub nodes_added: Option<u64>,
    /// Why determine refused the move at L (then nothing was traced).
    pub refused: Option<String>,
}

/// The distances swept: 1, 10, ..., 1e9.
pub fn distances() -> Vec<f64> {
    (0..=9).map(|e| 10f64.powi(e)).collect()
}

/// Rays in the case's own frame: (origin, target), binary64.
fn local_rays(case: &Case, n: usize, seed: u64) -> Vec<(DVec3, DVec3)> {
    let (lo, hi) = case.mesh.bounds();
    let (c, r) = ((lo + hi) * 0.5, (hi - lo).length().max(1e-6));
    let mut rng = SplitMix64::new(seed ^ 0xd15);
    (0..n)
        .map(|_| {
            let o = c + rng.unit_vector() * r * 1.5;
            (o.as_dvec3(), rng.point_in(lo, hi).as_dvec3())
        })
        .collect()
}

/// The rays as the API gives them when the case sits at `p`: binary32
/// world coordinates. The origin is the binary32 point nearest `p + o`;
/// the direction aims from there at `p + target` (so far from the origin,
/// where binary32 moves the origin, the rays still meet the case).
fn world_rays(p: DVec3, local: &[(DVec3, DVec3)]) -> Vec<Ray> {
    local
        .iter()
        .map(|(o, target)| {
            let org = (p + *o).as_vec3();
            let dir = (*target - (org.as_dvec3() - p)).normalize().as_vec3();
            Ray::unbounded(org, dir)
        })
        .collect()
}

/// Measures every format at distance `d`; translated ones at the top LOD,
/// half-way to D, and D.
pub fn at_distance(
    case: &Case,
    params: Params,
    d: f64,
    rays: usize,
    seed: u64,
) -> Result<Vec<DistanceRow>, String> {
    let dir = DVec3::new(1.0, 0.618, 0.382).normalize();
    let p = dir * d;
    let mesh = &case.mesh;
    let local = local_rays(case, rays, seed);
    let rays32 = world_rays(p, &local);
    let tris: Vec<[DVec3; 3]> = (0..mesh.triangles.len())
        .map(|i| mesh.triangle_f64(i))
        .collect();
    let reference = ReferenceTracer::new(tris.clone());
    let mut out = Vec::new();

    // Untranslated: the vertices at their world positions in binary32 / binary64.
    let w32: Vec<[Vec3; 3]> = tris.iter().map(|t| t.map(|v| (v + p).as_vec3())).collect();
    let hits32: Vec<Option<(f64, u32)>> = rays32.iter().map(|r| brute_f32(r, &w32)).collect();
    let err32 = tris
        .iter()
        .flatten()
        .map(|v| {
            ((*v + p).as_vec3().as_dvec3() - (*v + p))
                .abs()
                .max_element()
        })
        .fold(0.0, f64::max);
    let w64 = ReferenceTracer::new(tris.iter().map(|t| t.map(|v| v + p)).collect());
    let hits64: Vec<Option<(f64, u32)>> = rays32
        .iter()
        .map(|r| w64.closest(r.origin.as_dvec3(), r.dir.as_dvec3(), 0.0, f64::INFINITY))
        .map(|h| h.map(|h| (h.t, h.prim)))
        .collect();
    let err64 = tris
        .iter()
        .flatten()
        .flat_map(|v| Axis::ALL.map(|a| two_sum_error(v[a.index()], p[a.index()]).abs()))
        .fold(0.0, f64::max);
    for (name, hits, err) in [("b32-world", &hits32, err32), ("b64-world", &hits64, err64)] {
        out.push(DistanceRow {
            distance: d,
            max_lod: params.max_lod,
            format: name.into(),
            level: None,
            level_role: "-".into(),
            top_lod: 0,
            hits: compare(&reference, p, &rays32, hits),
            position_error: err,
            traced_magnitude: if name == "b32-world" {
                w32.iter()
                    .flatten()
                    .map(|v| v.abs().max_element() as f64)
                    .fold(0.0, f64::max)
            } else {
                f64::NAN
            },
            residual: None,
            nodes_added: None,
            refused: None,
        });
    }

    // Translated: built in the local frame, placed by a translation at L.
    // The grid also holds the copy the merging level is found with.
    let shift = copy_shift(mesh);
    let grid = placement_grid(&[mesh.clone(), mesh.clone()], &[p, p + shift], &params)?;
    let h = build(mesh, &grid, &params, 0).map_err(|e| format!("{}: {e}", case.source))?;
    let tops: Vec<_> = h.roots().iter().map(|n| n.voxel).collect();
    let top = h.top_lod;
    let mut levels = vec![(top, "top")];
    if let Some(ml) = merging_level(mesh, grid, params, p, shift) {
        levels.push((ml, "merging"));
    }
    levels.push((top + (params.max_lod - top) / 2, "middle"));
    levels.push((params.max_lod, "D"));
    // One row per level; a level keeps its first role (top, merging, middle, D).
    let mut seen = Vec::new();
    levels.retain(|(l, _)| {
        let new = !seen.contains(l);
        seen.push(*l);
        new
    });
    let g = p / grid.unit;
    for &(l, role) in &levels {
        let extents = VoxelRange::of_nodes(&tops, l, &params).map_err(|e| e.to_string())?;
        let b32 = Placement::binary32(g.as_vec3().to_array());
        let b64 = Placement::binary64(g.to_array());
        for (name, placement) in [
            ("b32-local", b32),
            ("b64-local", b64),
            ("b64-local-aligned", b64),
        ] {
            let base = DistanceRow {
                distance: d,
                max_lod: params.max_lod,
                format: name.into(),
                level: Some(l),
                level_role: role.into(),
                top_lod: top,
                hits: HitCounts::default(),
                position_error: f64::NAN,
                traced_magnitude: f64::NAN,
                residual: None,
                nodes_added: None,
                refused: None,
            };
            let det = match determine(&placement, l, &extents, &params) {
                Ok(det) => det,
                Err(e) => {
                    // The scene-extents rule (7.4) refuses this move at L.
                    out.push(DistanceRow {
                        refused: Some(e.to_string()),
                        ..base
                    });
                    continue;
                }
            };
            let aligned = name == "b64-local-aligned";
            let t = Translated {
                h: &h,
                mesh,
                grid,
                params,
            };
            out.push(t.row(base, &det, p, aligned, &local, &rays32, &reference)?);
        }
    }
    Ok(out)
}

/// The merging level (SPEC 8.2, the default mode) of the case at `p` merged
/// with a copy of itself moved by half its extent along x, in `grid`;
/// `None` when the copy does not fit or the merge refuses.
fn merging_level(mesh: &Mesh, grid: GridMap, params: Params, p: DVec3, shift: DVec3) -> Option<u8> {
    let mut world = World::new(params, grid).ok()?;
    world.add(0, mesh.clone(), p).ok()?;
    world.add(1, mesh.clone(), p + shift).ok()?;
    let out = (params.hier_capacity() - 1) as u8;
    world.merge(&[0, 1], MergeMode::default(), out).ok()?.level
}

/// A hierarchy built in its local frame, to be placed by translations.
struct Translated<'a> {
    h: &'a golden::store::Hierarchy,
    mesh: &'a Mesh,
    grid: GridMap,
    params: Params,
}

impl Translated<'_> {
    /// Traces the rays through the hierarchy moved by `det`'s translation and
    /// compares with the reference; `aligned`: the case asked to be where the
    /// translation puts it (residual 0), with rays to match.
    #[allow(clippy::too_many_arguments)]
    fn row(
        &self,
        base: DistanceRow,
        det: &golden::translate::Determined,
        p: DVec3,
        aligned: bool,
        local: &[(DVec3, DVec3)],
        rays32: &[Ray],
        reference: &ReferenceTracer,
    ) -> Result<DistanceRow, String> {
        let off = Axis::ALL.map(|a| det.translation.grid_offset(a, &self.params));
        // None when the expanding variant refuses the move (SPEC 7.7).
        let added = hierarchy_expansion_cost(self.h, &det.translation)
            .ok()
            .map(|c| c.added);
        let applied = DVec3::from_array(off.map(|o| o as f64)) * self.grid.unit;
        let wanted = if aligned { applied } else { p };
        let rays = if aligned {
            world_rays(wanted, local)
        } else {
            rays32.to_vec()
        };
        // SPEC 7.10: the residual lives in the local geometry (the mesh moved
        // by it, rounded once to binary32), built anew; aligned, it is 0.
        // The residual of the placement as given (a binary32 placement's own
        // rounding then shows in the position error).
        let moved = if aligned {
            DVec3::ZERO
        } else {
            DVec3::from_array(Axis::ALL.map(|a| det.residual.value_f64(a))) * self.grid.unit
        };
        let geometry = if moved == DVec3::ZERO {
            self.mesh.clone()
        } else {
            Mesh {
                vertices: self
                    .mesh
                    .vertices
                    .iter()
                    .map(|v| (v.as_dvec3() + moved).as_vec3())
                    .collect(),
                triangles: self.mesh.triangles.clone(),
            }
        };
        let rebuilt;
        let h = if moved == DVec3::ZERO {
            self.h
        } else {
            match build(&geometry, &self.grid, &self.params, 0) {
                Ok(h) => {
                    rebuilt = h;
                    &rebuilt
                }
                Err(e) => {
                    return Ok(DistanceRow {
                        refused: Some(format!("the local geometry moved by the residual: {e}")),
                        ..base
                    })
                }
            }
        };
        let inst = Instance {
            offset: off,
            ..Instance::new(h, &geometry)
        };
        let scene = TraceScene::new(self.grid, &[inst]).map_err(|e| e.to_string())?;
        let hits: Vec<Option<(f64, u32)>> = rays
            .iter()
            .map(|r| closest_hit(r, &scene, &mut TraceStats::default()))
            .map(|h| h.map(|h| (h.t as f64, h.prim)))
            .collect();
        let residual = Axis::ALL
            .map(|a| (det.residual.value_f64(a) * self.grid.unit).abs())
            .into_iter()
            .fold(0.0, f64::max);
        // Where each vertex is (geometry + translation) against where it was
        // asked to be (mesh + p), per axis, in the local frame.
        let position_error = geometry
            .vertices
            .iter()
            .zip(&self.mesh.vertices)
            .map(|(g, v)| {
                ((g.as_dvec3() - v.as_dvec3()) - (wanted - applied))
                    .abs()
                    .max_element()
            })
            .fold(0.0, f64::max);
        let traced_magnitude = geometry
            .vertices
            .iter()
            .map(|v| v.abs().max_element() as f64)
            .fold(0.0, f64::max);
        Ok(DistanceRow {
            hits: compare(reference, wanted, &rays, &hits),
            position_error,
            traced_magnitude,
            residual: Some(if aligned { 0.0 } else { residual }),
            nodes_added: added,
            ..base
        })
    }
}

/// Half the mesh's extent along x: where the merged copy goes.
pub fn copy_shift(mesh: &Mesh) -> DVec3 {
    let (lo, hi) = mesh.bounds();
    DVec3::new((hi - lo).x as f64 * 0.5, 0.0, 0.0)
}

/// Closest hit over every triangle with golden's binary32 kernel (SPEC 6.2):
/// what binary32 world coordinates give (traversal gives the same, 6.5).
fn brute_f32(r: &Ray, tris: &[[Vec3; 3]]) -> Option<(f64, u32)> {
    let s = ShearedRay::new(r);
    let mut best: Option<(f32, u32)> = None;
    for (i, t) in tris.iter().enumerate() {
        if let Some(h) = intersect_triangle(&s, t) {
            if best.is_none() || best.is_some_and(|b| (h.t, i as u32) < b) {
                best = Some((h.t, i as u32));
            }
        }
    }
    best.map(|(t, i)| (t as f64, i))
}

/// The rounding error of `a + b` in binary64 (Knuth's TwoSum).
fn two_sum_error(a: f64, b: f64) -> f64 {
    let s = a + b;
    let bb = s - a;
    (a - (s - bb)) + (b - bb)
}
