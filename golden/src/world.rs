//! A world of placed hierarchies: what software (a driver, an emulator, a
//! renderer) holds between frames.
//!
//! Every object is a mesh in its own **local** frame, built once into a
//! hierarchy and placed in the scene by a voxel-aligned translation (SPEC
//! section 7) kept in the translation table. Moving an object rigidly only
//! determines a new translation; no node is rebuilt or split. Merging
//! (SPEC section 8) makes one hierarchy that references the inputs; the
//! inputs stay in the store for the next frame.
//!
//! One [`GridMap`] serves the scene and every local frame: a local point `v`
//! (world units) is at grid point `(v - origin) / unit`, and after placement
//! at that point plus the translation's grid offset. An object's local mesh
//! must therefore lie inside the scene cube; its placement is the offset in
//! world units that carries it to its scene position.

use std::collections::BTreeMap;
use std::fmt;

use glam::DVec3;

use crate::build::{build, BuildError, GridMap};
use crate::check::{check, CheckError, CheckReport};
use crate::merge::instances::{input_instances, merged_instances};
use crate::merge::{merge_into, MergeError, MergeMode, MergeResult, MergedCheckView};
use crate::mesh::Mesh;
use crate::params::Params;
use crate::store::{Hierarchy, HierarchyStore};
use crate::trace::{Instance, TraceError, TraceScene};
use crate::translate::{
    determine, Determined, Placement, TranslateError, TranslationTable, VoxelRange,
};

/// One object: its local mesh (world units), the same in grid units, and
/// the translation that places it.
#[derive(Clone, Debug)]
pub struct Object {
    /// The mesh in its local frame, world units.
    pub mesh: Mesh,
    /// The mesh's triangles in local grid units (what the checker uses).
    pub local: Vec<[DVec3; 3]>,
    /// The requested placement (world units) and what determine made of it.
    pub offset: DVec3,
    /// What determine (SPEC 7.2) made of `offset`: the translation at the
    /// hierarchy's top LOD and the residual it leaves.
    pub determined: Determined,
}

/// Why a world operation failed, naming the object.
#[derive(Clone, Debug, PartialEq)]
pub enum WorldError {
    /// Building object `id`'s hierarchy, or mapping its mesh to grid units, failed.
    Build {
        /// The object's id.
        id: u8,
        /// The builder's error.
        error: BuildError,
    },
    /// Determining, writing or reading a translation failed (SPEC 7).
    Translate {
        /// The object or hierarchy concerned; 0 when there is no single one
        /// (`World::new`, `World::separate_instances`).
        id: u8,
        /// The translation unit's error.
        error: TranslateError,
    },
    /// The merge failed (SPEC 8.1), or storing a built hierarchy did (`MergeError::Store`).
    Merge(MergeError),
    /// The checker (SPEC 5) rejected hierarchy `id`.
    Check {
        /// The checked hierarchy's id.
        id: u8,
        /// The first property it violates.
        error: CheckError,
    },
    /// Making a trace scene of the instances failed.
    Trace(TraceError),
    /// No object (or no hierarchy) with this id.
    Unknown(u8),
    /// The placement is not finite in world units.
    BadOffset {
        /// The object's id.
        id: u8,
        /// The offset as given, world units (x, y, z).
        offset: [f64; 3],
    },
}

impl fmt::Display for WorldError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WorldError::Build { id, error } => write!(f, "object {id}: build: {error}"),
            WorldError::Translate { id, error } => write!(f, "object {id}: translation: {error}"),
            WorldError::Merge(e) => write!(f, "{e}"),
            WorldError::Check { id, error } => {
                write!(f, "hierarchy {id} fails the checker: {error}")
            }
            WorldError::Trace(e) => write!(f, "trace: {e}"),
            WorldError::Unknown(id) => write!(f, "no object or hierarchy with id {id}"),
            WorldError::BadOffset { id, offset } => {
                write!(f, "object {id}: placement {offset:?} is not finite")
            }
        }
    }
}

impl std::error::Error for WorldError {}

/// The store, the translation table and the objects of a scene.
pub struct World {
    /// The parameters every hierarchy is built with (SPEC 1).
    pub params: Params,
    /// The map from world units to grid units, for the scene and every local frame.
    pub grid: GridMap,
    /// The objects' hierarchies and the merged ones.
    pub store: HierarchyStore,
    /// The translation table, one entry per hierarchy id (`2^H`).
    pub table: TranslationTable,
    objects: BTreeMap<u8, Object>,
}

impl World {
    /// An empty world; the translation table holds one entry per hierarchy id.
    pub fn new(params: Params, grid: GridMap) -> Result<World, WorldError> {
        let table = TranslationTable::new(params.hier_capacity() as usize, &params)
            .map_err(|error| WorldError::Translate { id: 0, error })?;
        Ok(World {
            params,
            grid,
            store: HierarchyStore::new(),
            table,
            objects: BTreeMap::new(),
        })
    }

    /// Builds `mesh` (local frame) as hierarchy `id` and places it by
    /// `offset` world units; replaces an object of the same id.
    pub fn add(&mut self, id: u8, mesh: Mesh, offset: DVec3) -> Result<&Object, WorldError> {
        let h = build(&mesh, &self.grid, &self.params, id)
            .map_err(|error| WorldError::Build { id, error })?;
        let local = self
            .grid
            .mesh_to_grid(&mesh, &self.params)
            .map_err(|error| WorldError::Build { id, error })?;
        let determined = self.determine(id, &h, offset)?;
        self.table
            .write(id as u32, determined.translation)
            .map_err(|error| WorldError::Translate { id, error })?;
        self.store.remove(id);
        self.store
            .insert(h)
            .map_err(|e| WorldError::Merge(MergeError::Store(e)))?;
        self.objects.insert(
            id,
            Object {
                mesh,
                local,
                offset,
                determined,
            },
        );
        Ok(&self.objects[&id])
    }

    /// Moves object `id` rigidly to `offset`: a new translation, nothing rebuilt.
    pub fn place(&mut self, id: u8, offset: DVec3) -> Result<Determined, WorldError> {
        // Only an object moves: a merged hierarchy's table entry stays as it is.
        if !self.objects.contains_key(&id) {
            return Err(WorldError::Unknown(id));
        }
        let h = self.store.get(id).ok_or(WorldError::Unknown(id))?;
        let determined = self.determine(id, h, offset)?;
        self.table
            .write(id as u32, determined.translation)
            .map_err(|error| WorldError::Translate { id, error })?;
        let o = self.objects.get_mut(&id).ok_or(WorldError::Unknown(id))?;
        o.offset = offset;
        o.determined = determined;
        Ok(determined)
    }

    /// Determine (SPEC 7): the offset in grid units, as binary64, rounded to
    /// voxels of the hierarchy's top LOD, inside the scene extents.
    fn determine(&self, id: u8, h: &Hierarchy, offset: DVec3) -> Result<Determined, WorldError> {
        if !offset.is_finite() {
            return Err(WorldError::BadOffset {
                id,
                offset: offset.to_array(),
            });
        }
        let grid_units = (offset / self.grid.unit).to_array();
        let tops: Vec<_> = h.roots().iter().map(|n| n.voxel).collect();
        let extents = VoxelRange::of_nodes(&tops, h.top_lod, &self.params)
            .map_err(|error| WorldError::Translate { id, error })?;
        determine(
            &Placement::binary64(grid_units),
            h.top_lod,
            &extents,
            &self.params,
        )
        .map_err(|error| WorldError::Translate { id, error })
    }

    /// Removes object `id` (and its hierarchy and table entry).
    pub fn remove(&mut self, id: u8) -> Option<Object> {
        self.store.remove(id);
        let _ = self.table.invalidate(id as u32);
        self.objects.remove(&id)
    }

    /// Object `id`, or `None` when there is none.
    pub fn object(&self, id: u8) -> Option<&Object> {
        self.objects.get(&id)
    }

    /// The objects' ids, ascending.
    pub fn object_ids(&self) -> impl Iterator<Item = u8> + '_ {
        self.objects.keys().copied()
    }

    /// Merges objects `inputs` into hierarchy `out` (replacing an earlier
    /// merged hierarchy of that id); the inputs stay in the store.
    pub fn merge(
        &mut self,
        inputs: &[u8],
        mode: MergeMode,
        out: u8,
    ) -> Result<MergeResult, WorldError> {
        if self.objects.contains_key(&out) {
            return Err(WorldError::Merge(MergeError::OutIdInUse(out)));
        }
        self.store.remove(out);
        merge_into(&mut self.store, inputs, &self.table, mode, out).map_err(WorldError::Merge)
    }

    /// Runs the checker (SPEC 5) on hierarchy `id`: a merged hierarchy is
    /// checked through its inputs' translations.
    pub fn check(&self, id: u8) -> Result<CheckReport, WorldError> {
        let h = self.store.get(id).ok_or(WorldError::Unknown(id))?;
        let local: BTreeMap<u8, &[[DVec3; 3]]> = self
            .objects
            .iter()
            .map(|(&i, o)| (i, o.local.as_slice()))
            .collect();
        let view = MergedCheckView::new(&self.store, &self.table, &local)
            .map_err(|error| WorldError::Translate { id, error })?;
        check(h, &view).map_err(|error| WorldError::Check { id, error })
    }

    fn meshes(&self, ids: &[u8]) -> Result<BTreeMap<u8, &Mesh>, WorldError> {
        ids.iter()
            .map(|&i| Ok((i, &self.objects.get(&i).ok_or(WorldError::Unknown(i))?.mesh)))
            .collect()
    }

    /// Traversal instances of the placed objects `ids`, each its own hierarchy.
    pub fn separate_instances(&self, ids: &[u8]) -> Result<Vec<Instance<'_>>, WorldError> {
        let meshes = self.meshes(ids)?;
        input_instances(&self.store, &self.table, &meshes)
            .map_err(|error| WorldError::Translate { id: 0, error })
    }

    /// Traversal instances of merged hierarchy `merged` over objects `inputs`.
    pub fn merged_instances(
        &self,
        merged: u8,
        inputs: &[u8],
    ) -> Result<Vec<Instance<'_>>, WorldError> {
        let m = self.store.get(merged).ok_or(WorldError::Unknown(merged))?;
        let meshes = self.meshes(inputs)?;
        merged_instances(m, &self.store, &self.table, &meshes)
            .map_err(|error| WorldError::Translate { id: merged, error })
    }

    /// A trace scene starting at `roots`.
    pub fn trace_scene<'a>(
        &self,
        instances: &[Instance<'a>],
        roots: &[u8],
    ) -> Result<TraceScene<'a>, WorldError> {
        TraceScene::with_roots(self.grid, instances, roots).map_err(WorldError::Trace)
    }

    /// Every object's triangles moved to their scene positions, in world
    /// units (f32): the input of a full rebuild, and of brute force in the
    /// world frame.
    pub fn placed_mesh(&self, ids: &[u8]) -> Result<Mesh, WorldError> {
        let mut out = Mesh::default();
        for &id in ids {
            let o = self.objects.get(&id).ok_or(WorldError::Unknown(id))?;
            let t = o.determined.translation;
            let shift = DVec3::from_array(
                crate::translate::Axis::ALL.map(|a| t.grid_offset(a, &self.params) as f64),
            ) * self.grid.unit;
            let base = out.vertices.len() as u32;
            out.vertices.extend(
                o.mesh
                    .vertices
                    .iter()
                    .map(|v| (v.as_dvec3() + shift).as_vec3()),
            );
            out.triangles
                .extend(o.mesh.triangles.iter().map(|tri| tri.map(|i| i + base)));
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenes::{sphere, torus};
    use crate::trace::{closest_hit, random_rays, TraceStats};
    use glam::Vec3;

    fn world() -> World {
        let p = Params::new(12, 6, 24, 4).unwrap();
        World::new(
            p,
            GridMap {
                origin: DVec3::ZERO,
                unit: 1.0 / 256.0,
            },
        )
        .unwrap()
    }

    #[test]
    fn placing_moves_by_whole_voxels_and_reports_the_residual() {
        let mut w = world();
        let o = w
            .add(1, sphere(Vec3::splat(1.0), 0.5, 8, 16), DVec3::ZERO)
            .unwrap();
        assert_eq!(o.determined.translation.t, [0, 0, 0]);
        let lod = o.determined.translation.lod;
        let edge = w.params.voxel_edge(lod) as f64 * w.grid.unit;
        let d = w
            .place(1, DVec3::new(edge * 2.0 + 0.001, -0.0, edge))
            .unwrap();
        assert_eq!(d.translation.t, [2, 0, 1]);
        let r = d.residual.value_f64(crate::translate::Axis::X);
        assert!((r * w.grid.unit - 0.001).abs() < 1e-9, "residual {r}");
        // Far outside the scene: an error, never a clamp.
        assert!(matches!(
            w.place(1, DVec3::new(1e9, 0.0, 0.0)),
            Err(WorldError::Translate { id: 1, .. })
        ));
        assert!(matches!(
            w.place(1, DVec3::new(f64::NAN, 0.0, 0.0)),
            Err(WorldError::BadOffset { .. })
        ));
    }

    #[test]
    fn merged_world_traces_like_its_parts() {
        let mut w = world();
        let edge = w.params.voxel_edge(2) as f64 * w.grid.unit;
        w.add(1, sphere(Vec3::splat(1.0), 0.6, 12, 24), DVec3::ZERO)
            .unwrap();
        w.add(
            2,
            torus(Vec3::splat(1.0), 0.5, 0.15, 24, 12),
            DVec3::new(edge, 0.0, 0.0),
        )
        .unwrap();
        w.merge(&[1, 2], MergeMode::default(), 9).unwrap();
        w.check(9).unwrap();
        // The merged hierarchy is no object: placing it is refused, and
        // leaves its table entry (which the merge reads through) alone.
        let before = w.table.get(9);
        assert!(matches!(
            w.place(9, DVec3::splat(edge)),
            Err(WorldError::Unknown(9))
        ));
        assert_eq!(w.table.get(9), before);
        w.check(9).unwrap();
        let mi = w.merged_instances(9, &[1, 2]).unwrap();
        let si = w.separate_instances(&[1, 2]).unwrap();
        let ms = w.trace_scene(&mi, &[9]).unwrap();
        let ss = w.trace_scene(&si, &[1, 2]).unwrap();
        let (lo, hi) = ss.bounds();
        let mut hits = 0;
        for ray in random_rays(lo, hi, 2000, 3) {
            let a = closest_hit(&ray, &ms, &mut TraceStats::default());
            let b = closest_hit(&ray, &ss, &mut TraceStats::default());
            assert_eq!(
                a.map(|h| (h.hier, h.prim, h.t.to_bits())),
                b.map(|h| (h.hier, h.prim, h.t.to_bits()))
            );
            hits += a.is_some() as u32;
        }
        assert!(hits > 200, "{hits} hits");
        // The merged output id cannot be an object's.
        assert!(w.merge(&[1, 2], MergeMode::default(), 1).is_err());
        // Placed mesh: every triangle, translated.
        assert_eq!(
            w.placed_mesh(&[1, 2]).unwrap().triangles.len(),
            w.object(1).unwrap().mesh.len() + w.object(2).unwrap().mesh.len()
        );
    }
}
