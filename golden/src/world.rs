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
//!
//! Placements are honoured exactly (SPEC 7.10): the part of a placement the
//! voxel grid cannot express, the residual, is added to the mesh in binary32
//! local coordinates (the object's *local geometry*), and the hierarchy is
//! built on that. A move reuses the hierarchy only while the residual stays
//! bit-identical (a move by whole voxels at the translation's LOD); any
//! other move rebuilds it.

use std::collections::BTreeMap;
use std::fmt;

use glam::DVec3;
use serde::Serialize;

use crate::build::{build, BuildError, GridMap};
use crate::check::{check, CheckError, CheckReport};
use crate::merge::instances::{group_instances, input_instances, merged_instances};
use crate::merge::{merge_into, MergeError, MergeMode, MergeResult, MergedCheckView};
use crate::mesh::Mesh;
use crate::params::Params;
use crate::store::{Hierarchy, HierarchyStore};
use crate::trace::{Instance, TraceError, TraceScene};
use crate::translate::{
    determine, round_placement, Axis, Determined, Placement, TranslateError, TranslationTable,
    VoxelRange,
};

/// One object: its mesh as given, its local geometry (the mesh plus the
/// residual), the same in grid units, and the translation that places it.
#[derive(Clone, Debug)]
pub struct Object {
    /// The local geometry: the source mesh with the residual added, binary32
    /// world units. The hierarchy is built on it and traversal tests its
    /// triangles; it equals `source` when the residual is zero.
    pub mesh: Mesh,
    /// The mesh as given, in its local frame, world units.
    pub source: Mesh,
    /// The local geometry's triangles in local grid units (what the checker uses).
    pub local: Vec<[DVec3; 3]>,
    /// The requested placement, world units.
    pub offset: DVec3,
    /// Whole voxels (grid units, per axis) the local frame holds the
    /// geometry by, so that it stays inside the scene cube: `0`, or one
    /// voxel edge of the translation's LOD up or down (SPEC 7.10).
    pub frame: DVec3,
    /// What determine is given: `offset / unit - frame`, grid units, binary64.
    pub placement: Placement,
    /// What determine (SPEC 7.2) made of `placement`: the translation, at a
    /// LOD no finer than the hierarchy's top LOD, and the residual it leaves,
    /// which `mesh` carries.
    pub determined: Determined,
    /// The top LOD of the source mesh's own hierarchy: where determine starts (SPEC 7.10).
    pub base_lod: u8,
    /// Set when the last placement settled its translation at a coarser LOD
    /// than a finer one it tried (SPEC 7.10 step 6): which, and why.
    pub fallback: Option<Fallback>,
}

/// A finer LOD that a placement's translation could not take (SPEC 7.10
/// step 6): the world fell back from `refused_lod` to the LOD the
/// translation holds now.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Fallback {
    /// The finest LOD refused.
    pub refused_lod: u8,
    /// The LOD the translation settled at.
    pub settled_lod: u8,
    /// Why `refused_lod` was refused.
    pub reason: String,
}

/// What placing an object did to its hierarchy (SPEC 7.10).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Placing {
    /// The residual is bit-identical to the hierarchy's: only the translation changed.
    Retranslated,
    /// The residual changed (a move by a fraction of a voxel): the local
    /// geometry moved and its hierarchy was rebuilt.
    Rebuilt,
}

/// Where settling a placement ended.
enum Step {
    /// The object's current hierarchy serves: the new translation.
    Reuse(Split),
    /// A new local geometry and hierarchy.
    Settled(Settled),
}

/// A settled placement: the local geometry, its hierarchy and translation.
struct Settled {
    hierarchy: Hierarchy,
    mesh: Mesh,
    local: Vec<[DVec3; 3]>,
    at: Split,
}

/// One split of a placement: the local frame's shift, what determine was
/// given and what it returned.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Split {
    frame: DVec3,
    placement: Placement,
    determined: Determined,
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
///
/// ```
/// use glam::{DVec3, Vec3};
/// use golden::build::GridMap;
/// use golden::merge::MergeMode;
/// use golden::scenes::sphere;
/// use golden::world::{Placing, World};
/// use golden::Params;
///
/// let params = Params::new(12, 6, 24, 4).unwrap();
/// let grid = GridMap { origin: DVec3::ZERO, unit: 1.0 / 256.0 };
/// let mut world = World::new(params, grid).unwrap();
/// world.add(1, sphere(Vec3::splat(1.0), 0.5, 12, 24), DVec3::ZERO).unwrap();
/// world.add(2, sphere(Vec3::splat(1.0), 0.3, 12, 24), DVec3::new(0.5, 0.0, 0.0)).unwrap();
/// // A move by whole voxels of the translation's LOD reuses the hierarchy.
/// let lod = world.object(1).unwrap().determined.translation.lod;
/// let step = params.voxel_edge(lod) as f64 * grid.unit;
/// assert_eq!(world.place(1, DVec3::new(step, 0.0, 0.0)).unwrap(), Placing::Retranslated);
/// // Merged into hierarchy 9; the inputs stay in the store for the next frame.
/// world.merge(&[1, 2], MergeMode::default(), 9).unwrap();
/// world.check(9).unwrap();
/// let instances = world.merged_instances(9, &[1, 2]).unwrap();
/// let scene = world.trace_scene(&instances, &[9]).unwrap();
/// assert!(scene.bounds().0.x < scene.bounds().1.x);
/// ```
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
        let base = build(&mesh, &self.grid, &self.params, id)
            .map_err(|error| WorldError::Build { id, error })?;
        self.add_built(id, mesh, offset, base)
    }

    /// [`World::add`] with `base`, the hierarchy of `mesh` built as hierarchy
    /// `id` in this world's grid, given (a saved hierarchy, SPEC 16) instead
    /// of built; it serves as is when the placement leaves no residual.
    pub fn add_built(
        &mut self,
        id: u8,
        mesh: Mesh,
        offset: DVec3,
        base: Hierarchy,
    ) -> Result<&Object, WorldError> {
        let base_lod = base.top_lod;
        let (step, fallback) = self.settle(id, &mesh, base_lod, offset, Some(base), None)?;
        let Step::Settled(s) = step else {
            unreachable!("settle reuses only a current hierarchy, and there is none")
        };
        self.install(id, &s)?;
        self.objects.insert(
            id,
            Object {
                mesh: s.mesh,
                source: mesh,
                local: s.local,
                offset,
                frame: s.at.frame,
                placement: s.at.placement,
                determined: s.at.determined,
                base_lod,
                fallback,
            },
        );
        Ok(&self.objects[&id])
    }

    /// Moves object `id` rigidly to `offset`. The hierarchy is reused (a new
    /// translation only) when the residual stays bit-identical, and rebuilt
    /// on the moved local geometry otherwise (SPEC 7.10).
    pub fn place(&mut self, id: u8, offset: DVec3) -> Result<Placing, WorldError> {
        // Only an object moves: a merged hierarchy's table entry stays as it is.
        let o = self.objects.get(&id).ok_or(WorldError::Unknown(id))?;
        let h = self.store.get(id).ok_or(WorldError::Unknown(id))?;
        let current = Split {
            frame: o.frame,
            placement: o.placement,
            determined: o.determined,
        };
        let source = o.source.clone();
        let (step, fallback) =
            self.settle(id, &source, o.base_lod, offset, None, Some((current, h)))?;
        let (at, how) = match step {
            Step::Reuse(at) => {
                self.table
                    .write(id as u32, at.determined.translation)
                    .map_err(|error| WorldError::Translate { id, error })?;
                (at, Placing::Retranslated)
            }
            Step::Settled(s) => {
                self.install(id, &s)?;
                let o = self.objects.get_mut(&id).ok_or(WorldError::Unknown(id))?;
                o.mesh = s.mesh;
                o.local = s.local;
                (s.at, Placing::Rebuilt)
            }
        };
        let o = self.objects.get_mut(&id).ok_or(WorldError::Unknown(id))?;
        o.offset = offset;
        o.frame = at.frame;
        o.placement = at.placement;
        o.determined = at.determined;
        o.fallback = fallback;
        Ok(how)
    }

    /// Writes a settled placement's translation and hierarchy.
    fn install(&mut self, id: u8, s: &Settled) -> Result<(), WorldError> {
        self.table
            .write(id as u32, s.at.determined.translation)
            .map_err(|error| WorldError::Translate { id, error })?;
        self.store.remove(id);
        self.store
            .insert(s.hierarchy.clone())
            .map_err(|e| WorldError::Merge(MergeError::Store(e)))
    }

    /// The placement `offset` (world units) in grid units, as binary64.
    fn placement(&self, id: u8, offset: DVec3) -> Result<Placement, WorldError> {
        if !offset.is_finite() {
            return Err(WorldError::BadOffset {
                id,
                offset: offset.to_array(),
            });
        }
        Ok(Placement::binary64((offset / self.grid.unit).to_array()))
    }

    /// SPEC 7.10: split the placement at `lod` (first the source mesh's top
    /// LOD), add the residual to the source mesh in binary32, build; while
    /// the build's top LOD is coarser than `lod`, its voxels would not stay
    /// aligned, so split again at that LOD. Where no split at `lod` keeps
    /// the binary32 local geometry and the voxels it touches inside the
    /// scene, or the extents rule refuses the built roots, `lod` falls back
    /// one level coarser: at LOD 0 the translation is zero and the local
    /// geometry is the mesh where the scene puts it, which scene validation
    /// checks ([`placed_bounds`]). `lod` only decreases: at most `D` steps,
    /// and the result is a function of (source, offset) alone. `base` is the
    /// source mesh's own hierarchy when the caller has it; `current` the
    /// object's split and hierarchy, reused when a step reaches the same
    /// split (the build would give it again, bit for bit).
    fn settle(
        &self,
        id: u8,
        source: &Mesh,
        base_lod: u8,
        offset: DVec3,
        mut base: Option<Hierarchy>,
        current: Option<(Split, &Hierarchy)>,
    ) -> Result<(Step, Option<Fallback>), WorldError> {
        let requested = self.placement(id, offset)?;
        let bounds = source.bounds();
        let mut lod = base_lod;
        let mut refused: Option<(u8, String)> = None;
        let fallback = |refused: Option<(u8, String)>, settled_lod: u8| {
            refused.map(|(refused_lod, reason)| Fallback {
                refused_lod,
                settled_lod,
                reason,
            })
        };
        loop {
            let mut coarser = |lod: u8, e: WorldError| {
                if lod == 0 {
                    return Err(e);
                }
                refused.get_or_insert_with(|| (lod, e.to_string()));
                Ok(lod - 1)
            };
            let at = match self.split(id, &requested, lod, bounds) {
                Ok(at) => at,
                Err(e) => {
                    lod = coarser(lod, e)?;
                    continue;
                }
            };
            if let Some((c, h)) = current {
                if c.determined.translation.lod == lod
                    && c.determined.residual == at.determined.residual
                    && c.frame == at.frame
                {
                    match self.check_extents(id, h, &at.placement, lod) {
                        Ok(determined) => {
                            let step = Step::Reuse(Split { determined, ..at });
                            return Ok((step, fallback(refused, lod)));
                        }
                        Err(e) => {
                            lod = coarser(lod, e)?;
                            continue;
                        }
                    }
                }
            }
            let moved = at.frame + residual_of(&at.determined);
            let (mesh, hierarchy) = match base.take() {
                Some(h) if moved == DVec3::ZERO => (source.clone(), h),
                _ => {
                    let mesh = if moved == DVec3::ZERO {
                        source.clone()
                    } else {
                        moved_by(source, moved * self.grid.unit)
                    };
                    let h = build(&mesh, &self.grid, &self.params, id)
                        .map_err(|error| WorldError::Build { id, error })?;
                    (mesh, h)
                }
            };
            if hierarchy.top_lod < lod {
                lod = hierarchy.top_lod;
                continue;
            }
            let determined = match self.check_extents(id, &hierarchy, &at.placement, lod) {
                Ok(d) => d,
                Err(e) => {
                    lod = coarser(lod, e)?;
                    continue;
                }
            };
            let local = self
                .grid
                .mesh_to_grid(&mesh, &self.params)
                .map_err(|error| WorldError::Build { id, error })?;
            let step = Step::Settled(Settled {
                hierarchy,
                mesh,
                local,
                at: Split { determined, ..at },
            });
            return Ok((step, fallback(refused, lod)));
        }
    }

    /// Splits `requested` (grid units) at `lod` (SPEC 7.10). The local frame
    /// may hold the geometry up or down by one voxel edge `E` of `lod` per
    /// axis, which leaves its scene position alone. A frame serves an axis
    /// when the local geometry it gives, rounded to binary32 as the build
    /// will see it ([`placed_bounds`] of the source's world `bounds`), lies
    /// in the scene cube and the LOD-`lod` voxels it touches stay in the
    /// scene once translated (the extents rule, 7.4). Among those it prefers
    /// one where the geometry straddles no two voxels of `lod` in different
    /// parents: moved by `E`, the two share a parent, so the next step
    /// settles one LOD coarser instead of wherever the common ancestor of a
    /// large boundary is. An axis no frame serves is an error: the caller
    /// falls back to a coarser LOD.
    fn split(
        &self,
        id: u8,
        requested: &Placement,
        lod: u8,
        bounds: (glam::Vec3, glam::Vec3),
    ) -> Result<Split, WorldError> {
        let edge = self.params.voxel_edge(lod) as f64;
        let side = self.params.voxel_edge(0) as f64;
        let last = ((1u64 << lod) - 1) as f64;
        let round = |frame: DVec3| -> Result<Split, WorldError> {
            let placement =
                Placement::binary64(Axis::ALL.map(|a| requested.value_f64(a) - frame[a.index()]));
            let determined = round_placement(&placement, lod, &self.params)
                .map_err(|error| WorldError::Translate { id, error })?;
            Ok(Split {
                frame,
                placement,
                determined,
            })
        };
        // Each axis's candidate frame is judged by the residual and the
        // translation its own rounding gives: at a placement half a voxel
        // off the grid the rounding may fall the other way once the frame
        // has moved, so frame 0's cannot stand for the others'. Axes round
        // independently (7.2), so each is rounded alone: a candidate whose
        // rounding fails on one axis (a translation past the field) is no
        // candidate there and still one on the others.
        let candidates = [0.0, edge, -edge];
        let round_axis = |i: usize, f: f64| -> Result<(f64, f64), WorldError> {
            let mut alone = DVec3::ZERO;
            alone[i] = requested.value_f64(Axis::ALL[i]) - f;
            let d = round_placement(&Placement::binary64(alone.to_array()), lod, &self.params)
                .map_err(|error| WorldError::Translate { id, error })?;
            Ok((residual_of(&d)[i], d.translation.t[i] as f64))
        };
        let mut frame = DVec3::ZERO;
        for a in Axis::ALL {
            let i = a.index();
            let splits: Vec<Result<(f64, f64), WorldError>> =
                candidates.iter().map(|&f| round_axis(i, f)).collect();
            let moved = |k: usize| {
                let &(r, t) = splits[k].as_ref().ok()?;
                let by = (r + candidates[k]) * self.grid.unit;
                let (lo, hi) = placed_bounds(&self.grid, bounds, DVec3::splat(by));
                Some((lo[i], hi[i], t))
            };
            let fits = |k: usize| {
                moved(k).is_some_and(|(a, b, t)| {
                    let (va, vb) = ((a / edge).floor(), (b / edge).floor().min(last));
                    a >= 0.0 && b <= side && va + t >= 0.0 && vb + t <= last
                })
            };
            // The voxels of `lod` the moved bounds touch share a parent.
            let shares_parent = |k: usize| {
                let Some((a, b, _)) = moved(k) else {
                    return false;
                };
                let (va, vb) = ((a / edge).floor(), (b / edge).ceil() - 1.0);
                vb <= va || (vb == va + 1.0 && va.rem_euclid(2.0) == 0.0)
            };
            let Some(k) = (0..candidates.len())
                .find(|&k| fits(k) && shares_parent(k))
                .or_else(|| (0..candidates.len()).find(|&k| fits(k)))
            else {
                // Frame 0's own failure: a rounding past the field, or
                // the voxels it would put outside the scene.
                splits[0].clone()?;
                let (lo, hi, t) = moved(0).unwrap_or_default();
                return Err(WorldError::Translate {
                    id,
                    error: TranslateError::OutsideScene {
                        axis: a,
                        lo: (lo / edge).floor() as i64 + t as i64,
                        hi: (hi / edge).floor() as i64 + t as i64,
                        lod,
                    },
                });
            };
            frame[i] = candidates[k];
        }
        round(frame)
    }

    /// Determine (SPEC 7.2) at `lod` with the extents rule (7.4) on `h`'s roots.
    fn check_extents(
        &self,
        id: u8,
        h: &Hierarchy,
        placement: &Placement,
        lod: u8,
    ) -> Result<Determined, WorldError> {
        let tops: Vec<_> = h.roots().iter().map(|n| n.voxel).collect();
        let extents = VoxelRange::of_nodes(&tops, lod, &self.params)
            .map_err(|error| WorldError::Translate { id, error })?;
        determine(placement, lod, &extents, &self.params)
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

    /// Traversal instances of several merged hierarchies `merged`, each over
    /// a subset of objects `inputs` (paragraph 67), to be traced together
    /// with the merged ids as roots.
    pub fn group_instances(
        &self,
        merged: &[u8],
        inputs: &[u8],
    ) -> Result<Vec<Instance<'_>>, WorldError> {
        let hs = merged
            .iter()
            .map(|&m| self.store.get(m).ok_or(WorldError::Unknown(m)))
            .collect::<Result<Vec<_>, _>>()?;
        let meshes = self.meshes(inputs)?;
        let id = merged.first().copied().unwrap_or(0);
        group_instances(&hs, &self.store, &self.table, &meshes)
            .map_err(|error| WorldError::Translate { id, error })
    }

    /// A trace scene starting at `roots`.
    pub fn trace_scene<'a>(
        &self,
        instances: &[Instance<'a>],
        roots: &[u8],
    ) -> Result<TraceScene<'a>, WorldError> {
        TraceScene::with_roots(self.grid, instances, roots).map_err(WorldError::Trace)
    }

    /// Objects `ids` as the oracle of `--verify` sees them (SPEC 6.10): the
    /// source mesh where it was asked to be, beside the local geometry and
    /// translation golden traces.
    pub fn oracle_parts(&self, ids: &[u8]) -> Result<Vec<crate::oracle::Part<'_>>, WorldError> {
        ids.iter()
            .map(|&id| {
                let o = self.objects.get(&id).ok_or(WorldError::Unknown(id))?;
                let t = o.determined.translation;
                let shift =
                    DVec3::from_array(Axis::ALL.map(|a| t.grid_offset(a, &self.params) as f64))
                        * self.grid.unit;
                Ok(crate::oracle::Part {
                    hier: id,
                    source: &o.source,
                    offset: o.offset,
                    traced: &o.mesh,
                    shift,
                })
            })
            .collect()
    }

    /// `n` seeded rays at objects `ids` as they were asked to be placed: from
    /// points of a 64-unit lattice around `base` (a multiple of 64: exact in
    /// binary32 up to 2^30, so the same relative rays at any distance) at
    /// random points of random triangles; with `edges`, half of those points
    /// on an edge or at a vertex (the seams).
    pub fn lattice_rays(
        &self,
        ids: &[u8],
        base: DVec3,
        n: usize,
        seed: u64,
        edges: bool,
    ) -> Result<Vec<crate::geom::Ray>, WorldError> {
        let objects = ids
            .iter()
            .map(|&id| self.objects.get(&id).ok_or(WorldError::Unknown(id)))
            .collect::<Result<Vec<_>, _>>()?;
        let mut rng = crate::scenes::SplitMix64::new(seed);
        let mut out = Vec::with_capacity(n);
        while out.len() < n && !objects.is_empty() {
            let o = objects[rng.below(objects.len() as u64) as usize];
            if o.source.is_empty() {
                break;
            }
            let tri = o
                .source
                .triangle_f64(rng.below(o.source.len() as u64) as usize);
            let (mut a, mut b) = (rng.next_f64(), rng.next_f64());
            match (edges, rng.below(4)) {
                (true, 0) => b = 0.0,
                (true, 1) => (a, b) = (1.0, 0.0),
                _ => {}
            }
            if a + b > 1.0 {
                (a, b) = (1.0 - a, 1.0 - b);
            }
            let target = tri[0] + (tri[1] - tri[0]) * a + (tri[2] - tri[0]) * b + o.offset;
            let lattice = DVec3::new(
                rng.below(3) as f64 - 1.0,
                rng.below(3) as f64 - 1.0,
                1.0 + rng.below(2) as f64,
            ) * 64.0;
            let origin = (base + lattice).as_vec3();
            out.push(crate::geom::Ray::unbounded(
                origin,
                (target - origin.as_dvec3()).as_vec3(),
            ));
        }
        Ok(out)
    }

    /// Every object's triangles at their requested scene positions (source
    /// mesh plus placement, binary64, rounded once to f32), world units: the
    /// input of a full rebuild, and of brute force in the world frame.
    pub fn placed_mesh(&self, ids: &[u8]) -> Result<Mesh, WorldError> {
        let mut out = Mesh::default();
        for &id in ids {
            let o = self.objects.get(&id).ok_or(WorldError::Unknown(id))?;
            let base = out.vertices.len() as u32;
            out.vertices.extend(
                o.source
                    .vertices
                    .iter()
                    .map(|v| (v.as_dvec3() + o.offset).as_vec3()),
            );
            out.triangles
                .extend(o.source.triangles.iter().map(|tri| tri.map(|i| i + base)));
        }
        Ok(out)
    }
}

/// The grid bounds (grid units) of a mesh whose world bounds are `bounds`
/// once every vertex is moved by `by` world units in binary64 and rounded
/// once to binary32: the bounds the build sees of an object's local
/// geometry (`by` its frame plus residual, SPEC 7.10) or of a mesh with its
/// placement baked in. Both roundings are monotone, so the moved bounds are
/// the bounds moved; `by = 0` gives the mesh's own.
pub fn placed_bounds(
    grid: &GridMap,
    bounds: (glam::Vec3, glam::Vec3),
    by: DVec3,
) -> (DVec3, DVec3) {
    let at = |v: glam::Vec3| grid.to_grid((v.as_dvec3() + by).as_vec3());
    (at(bounds.0), at(bounds.1))
}

/// The residual of `d`, grid units.
fn residual_of(d: &Determined) -> DVec3 {
    DVec3::from_array(Axis::ALL.map(|a| d.residual.value_f64(a)))
}

/// The source mesh moved by `by` world units, each vertex rounded once to
/// binary32: the object's local geometry.
fn moved_by(source: &Mesh, by: DVec3) -> Mesh {
    Mesh {
        vertices: source
            .vertices
            .iter()
            .map(|v| (v.as_dvec3() + by).as_vec3())
            .collect(),
        triangles: source.triangles.clone(),
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

    /// Merged hierarchy `merged` of `ids` hits what the separate
    /// hierarchies hit, bit for bit, on `rays` random rays, more than
    /// `min_hits` of which hit.
    fn traces_like_separate(w: &World, merged: u8, ids: &[u8], rays: usize, min_hits: u32) {
        let mi = w.merged_instances(merged, ids).unwrap();
        let si = w.separate_instances(ids).unwrap();
        let ms = w.trace_scene(&mi, &[merged]).unwrap();
        let ss = w.trace_scene(&si, ids).unwrap();
        let (lo, hi) = ss.bounds();
        let mut hits = 0;
        for ray in random_rays(lo, hi, rays, 3) {
            let a = closest_hit(&ray, &ms, &mut TraceStats::default());
            let b = closest_hit(&ray, &ss, &mut TraceStats::default());
            assert_eq!(
                a.map(|h| (h.hier, h.prim, h.t.to_bits())),
                b.map(|h| (h.hier, h.prim, h.t.to_bits()))
            );
            hits += a.is_some() as u32;
        }
        assert!(hits > min_hits, "{hits} hits");
    }

    #[test]
    fn placing_keeps_the_residual_in_the_local_geometry() {
        let mut w = world();
        let ball = sphere(Vec3::splat(1.0), 0.5, 8, 16);
        let o = w.add(1, ball.clone(), DVec3::ZERO).unwrap();
        assert_eq!(o.determined.translation.t, [0, 0, 0]);
        assert_eq!(o.mesh, o.source);
        let lod = o.determined.translation.lod;
        let edge = w.params.voxel_edge(lod) as f64 * w.grid.unit;
        // Whole voxels: the hierarchy is reused, only the translation moves.
        let before = w.store.get(1).unwrap().clone();
        assert_eq!(
            w.place(1, DVec3::new(edge * 2.0, -0.0, edge)).unwrap(),
            Placing::Retranslated
        );
        assert_eq!(w.store.get(1).unwrap(), &before);
        assert_eq!(w.object(1).unwrap().determined.translation.t, [2, 0, 1]);
        // A fraction of a voxel: the local geometry moves by the residual and
        // is rebuilt; the translation still takes the whole voxels.
        let off = DVec3::new(edge * 2.0 + 0.001, -0.0, edge);
        assert_eq!(w.place(1, off).unwrap(), Placing::Rebuilt);
        let o = w.object(1).unwrap();
        assert_eq!(o.determined.translation.t, [2, 0, 1]);
        let r = o.determined.residual.value_f64(Axis::X) * w.grid.unit;
        assert!((r - 0.001).abs() < 1e-9, "residual {r}");
        let shift = DVec3::new(edge * 2.0, 0.0, edge);
        for (g, s) in o.mesh.vertices.iter().zip(&ball.vertices) {
            let want = s.as_dvec3() + off;
            let got = g.as_dvec3() + shift;
            // binary32 local coordinates: half an ulp of the local magnitude.
            assert!(
                (got - want).abs().max_element() < 2.0 * 2f64.powi(-24),
                "{got} vs {want}"
            );
        }
        // The same move again reuses the rebuilt hierarchy; the same result
        // as adding the object there afresh.
        let moved = w.store.get(1).unwrap().clone();
        assert_eq!(w.place(1, off).unwrap(), Placing::Retranslated);
        let mut fresh = world();
        fresh.add(1, ball, off).unwrap();
        assert_eq!(fresh.store.get(1).unwrap(), &moved);
        assert_eq!(
            fresh.object(1).unwrap().determined,
            w.object(1).unwrap().determined
        );
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

    /// Paragraph 67: merged hierarchies of subsets, traced together, give
    /// the separate hierarchies' hits bit for bit; a single-input merge
    /// traces at the cost of its input.
    #[test]
    fn subset_merges_trace_together() {
        let mut w = world();
        let edge = w.params.voxel_edge(3) as f64 * w.grid.unit;
        w.add(1, sphere(Vec3::splat(1.0), 0.4, 12, 24), DVec3::ZERO)
            .unwrap();
        w.add(
            2,
            torus(Vec3::splat(1.0), 0.5, 0.1, 24, 12),
            DVec3::new(edge, 0.0, 0.0),
        )
        .unwrap();
        w.add(
            3,
            sphere(Vec3::splat(1.0), 0.3, 8, 16),
            DVec3::new(0.3, edge, 0.1),
        )
        .unwrap();
        w.merge(&[1, 2], MergeMode::default(), 9).unwrap();
        w.merge(&[3], MergeMode::default(), 10).unwrap();
        w.check(9).unwrap();
        w.check(10).unwrap();
        let gi = w.group_instances(&[9, 10], &[1, 2, 3]).unwrap();
        let si = w.separate_instances(&[1, 2, 3]).unwrap();
        let gs = w.trace_scene(&gi, &[9, 10]).unwrap();
        let ss = w.trace_scene(&si, &[1, 2, 3]).unwrap();
        let single_i = w.merged_instances(10, &[3]).unwrap();
        let single = w.trace_scene(&single_i, &[10]).unwrap();
        let alone_i = w.separate_instances(&[3]).unwrap();
        let alone = w.trace_scene(&alone_i, &[3]).unwrap();
        let (lo, hi) = ss.bounds();
        let (mut hits, mut single_tests, mut alone_tests) =
            (0, TraceStats::default(), TraceStats::default());
        for ray in random_rays(lo, hi, 2000, 5) {
            let a = closest_hit(&ray, &gs, &mut TraceStats::default());
            let b = closest_hit(&ray, &ss, &mut TraceStats::default());
            assert_eq!(
                a.map(|h| (h.hier, h.prim, h.t.to_bits())),
                b.map(|h| (h.hier, h.prim, h.t.to_bits()))
            );
            hits += a.is_some() as u32;
            let c = closest_hit(&ray, &single, &mut single_tests);
            let d = closest_hit(&ray, &alone, &mut alone_tests);
            assert_eq!(
                c.map(|h| (h.prim, h.t.to_bits())),
                d.map(|h| (h.prim, h.t.to_bits()))
            );
        }
        assert!(hits > 200, "{hits} hits");
        assert!(
            single_tests.node_tests <= alone_tests.node_tests + 2000,
            "a single-input merge costs at most its root test more: {single_tests:?} vs {alone_tests:?}"
        );
    }

    /// Issue 19 item 5: a floor as large as the scene (its triangles'
    /// base LOD is 0) merges with a small object and traces like the two
    /// apart; before SPEC 4.2's LOD-1 floor it was refused as a leaf at the
    /// LOD-0 top.
    #[test]
    fn a_floor_as_large_as_the_scene_merges() {
        let mut w = world();
        let side = w.params.voxel_edge(0) as f32 * w.grid.unit as f32;
        let floor = crate::scenes::box_mesh(Vec3::ZERO, Vec3::new(side, side / 64.0, side));
        w.add(1, floor, DVec3::ZERO).unwrap();
        let h = w.store.get(1).unwrap();
        assert!(h.nodes.iter().all(|n| !n.leaf || n.voxel.lod >= 1));
        w.add(
            2,
            sphere(Vec3::splat(1.0), 0.4, 12, 24),
            DVec3::new(3.0, 1.0, 2.0),
        )
        .unwrap();
        w.merge(&[1, 2], MergeMode::default(), 9).unwrap();
        w.check(9).unwrap();
        traces_like_separate(&w, 9, &[1, 2], 1000, 100);
    }

    /// SPEC 7.10 step 6: an object placed to end exactly on the scene's far
    /// face, from a local geometry ending on an inner voxel face, touches a
    /// voxel past the scene at every LOD but 0: the world falls back to LOD
    /// 0 (no translation, the mesh where the scene puts it) instead of
    /// refusing; the object merges and traces like the two apart.
    #[test]
    fn a_placement_no_finer_lod_holds_falls_back() {
        let mut w = world();
        let side = w.params.voxel_edge(0) as f64 * w.grid.unit;
        let cube = crate::scenes::box_mesh(Vec3::splat(0.5), Vec3::splat(1.0));
        let o = w.add(1, cube.clone(), DVec3::ZERO).unwrap();
        assert!(o.determined.translation.lod > 0);
        assert_eq!(o.fallback, None);
        let to_face = DVec3::new(side - 1.0, 0.0, 0.0);
        let o = w.add(2, cube, to_face).unwrap();
        assert_eq!(o.determined.translation.lod, 0);
        assert_eq!(o.determined.translation.t, [0, 0, 0]);
        // The object says which finer LOD it tried and why it fell back.
        let f = o.fallback.clone().expect("a fallback is recorded");
        assert_eq!(f.settled_lod, 0);
        assert!(f.refused_lod > 0 && !f.reason.is_empty(), "{f:?}");
        assert_eq!(o.mesh.bounds().1.x as f64, side);
        w.check(2).unwrap();
        w.merge(&[1, 2], MergeMode::default(), 9).unwrap();
        w.check(9).unwrap();
        traces_like_separate(&w, 9, &[1, 2], 1000, 50);
        // Moved back inside, it is translated at a finer LOD again.
        w.place(2, to_face - DVec3::new(2.0, 0.0, 0.0)).unwrap();
        assert!(w.object(2).unwrap().determined.translation.lod > 0);
        assert_eq!(w.object(2).unwrap().fallback, None);
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
        traces_like_separate(&w, 9, &[1, 2], 2000, 200);
        // The merged output id cannot be an object's.
        assert!(w.merge(&[1, 2], MergeMode::default(), 1).is_err());
        // Placed mesh: every triangle, translated.
        assert_eq!(
            w.placed_mesh(&[1, 2]).unwrap().triangles.len(),
            w.object(1).unwrap().mesh.len() + w.object(2).unwrap().mesh.len()
        );
    }
}
