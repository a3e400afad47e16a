//! A scene over frames (paragraphs 41-42, 47, 88; claim 16): static
//! hierarchies are built once and reused, dynamic ones are rebuilt when
//! their geometry changes and only re-translated when they merely move, and
//! a merged hierarchy is redone only when one of its inputs changed. The
//! objects may be merged as one group or as several (paragraph 67): a static
//! group's merge then survives the frames in which only dynamic objects move.
//!
//! [`Frames::step`] takes the whole scene of one frame and returns what it
//! reused and what it redid, per object, so a run can print it.

use std::collections::BTreeMap;
use std::sync::Arc;

use glam::DVec3;
use serde::Serialize;

use crate::build::GridMap;
use crate::merge::{MergeMode, MergeStats};
use crate::mesh::Mesh;
use crate::params::Params;
use crate::store::Hierarchy;
use crate::world::{Fallback, Placing, World, WorldError};

/// Whether an object's geometry may change between frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Motion {
    /// Built once and reused in every frame (its hierarchy comes from the
    /// store); it may not move or change.
    Static,
    /// Rebuilt when its mesh changes, re-translated when it moves.
    Dynamic,
}

/// One object in one frame. Geometry is shared by `Arc`: a frame that hands
/// in the same `Arc` as the last one has not changed the mesh.
#[derive(Clone, Debug)]
pub struct FrameObject {
    /// Object id, also its hierarchy's id; below [`Frames::merged_id`], which is reserved.
    pub id: u8,
    /// Whether the object may change between frames.
    pub motion: Motion,
    /// Geometry in the object's local frame, world units, before `offset`.
    pub mesh: Arc<Mesh>,
    /// Placement of the local frame in the scene, world units.
    pub offset: DVec3,
}

/// What happened to one object in a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum ObjectAction {
    /// First frame: built and placed.
    Built,
    /// Its mesh changed: rebuilt and placed.
    Rebuilt,
    /// Moved by a fraction of a voxel: the residual changed, so its local
    /// geometry moved and was rebuilt (SPEC 7.10).
    Moved,
    /// Moved by whole voxels: a new translation, the hierarchy reused.
    Retranslated,
    /// Unchanged: hierarchy and translation reused.
    Reused,
}

/// What one frame did to one group of objects (paragraph 67).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GroupReport {
    /// The group's root: its merged hierarchy's id, or the object's own id
    /// when one object of the group is present (nothing to merge), or
    /// `None` when none is.
    pub root: Option<u8>,
    /// The group's objects present in this frame, ascending.
    pub inputs: Vec<u8>,
    /// True when the merge was redone; false when the last one was reused
    /// or the group has fewer than two objects.
    pub merged: bool,
    /// The merging level (None in per-node mode or with fewer than two objects).
    pub merge_level: Option<u8>,
    /// Statistics of the merge, when it was redone.
    pub merge_stats: Option<MergeStats>,
}

impl GroupReport {
    /// True when the group has a merged hierarchy this frame.
    pub fn is_merged(&self) -> bool {
        self.inputs.len() >= 2
    }
}

/// What one frame did.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FrameReport {
    /// Frame number, counted from 0 by each [`Frames`].
    pub frame: u64,
    /// Per object id, what was done.
    pub objects: BTreeMap<u8, ObjectAction>,
    /// Objects removed since the last frame.
    pub removed: Vec<u8>,
    /// Per group, in the order the groups were given, what its merge did.
    pub groups: Vec<GroupReport>,
    /// Per object placed this frame (not reused) whose translation fell
    /// back to a coarser LOD (SPEC 7.10 step 6): from which LOD and why.
    pub fallbacks: BTreeMap<u8, Fallback>,
}

impl FrameReport {
    /// How many objects had `action` in this frame.
    pub fn count(&self, action: ObjectAction) -> usize {
        self.objects.values().filter(|&&a| a == action).count()
    }

    /// True when any group's merge was redone.
    pub fn merged(&self) -> bool {
        self.groups.iter().any(|g| g.merged)
    }

    /// The roots to trace this frame from: each group's [`GroupReport::root`].
    pub fn roots(&self) -> Vec<u8> {
        self.groups.iter().filter_map(|g| g.root).collect()
    }

    /// The ids of this frame's merged hierarchies.
    pub fn merged_ids(&self) -> Vec<u8> {
        self.groups
            .iter()
            .filter(|g| g.is_merged())
            .filter_map(|g| g.root)
            .collect()
    }
}

/// A frame-to-frame error: the object and what was wrong.
#[derive(Clone, Debug, PartialEq)]
pub enum FrameError {
    /// The world refused a build, a placement or the merge.
    World(WorldError),
    /// A static object was handed a different mesh or placement than in the
    /// frame it was built.
    StaticChanged {
        /// The object's id.
        id: u8,
        /// What changed: `"motion"`, `"mesh"` or `"placement"`.
        what: &'static str,
    },
    /// The same id twice in one frame.
    DuplicateId(u8),
    /// An object uses an id reserved for a merged hierarchy.
    ReservedId(u8),
    /// An object of the frame is in no group.
    Ungrouped(u8),
    /// The groups themselves are wrong: what was expected.
    BadGroups(String),
}

impl std::fmt::Display for FrameError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FrameError::World(e) => e.fmt(f),
            FrameError::StaticChanged { id, what } => {
                write!(f, "object {id} is static but its {what} changed")
            }
            FrameError::DuplicateId(id) => write!(f, "object id {id} appears twice in one frame"),
            FrameError::ReservedId(id) => {
                write!(f, "object id {id} is reserved for a merged hierarchy")
            }
            FrameError::Ungrouped(id) => write!(
                f,
                "object id {id} is in no merge group: expected every object in exactly one"
            ),
            FrameError::BadGroups(what) => write!(f, "merge groups: {what}"),
        }
    }
}

impl std::error::Error for FrameError {}

impl From<WorldError> for FrameError {
    fn from(e: WorldError) -> Self {
        FrameError::World(e)
    }
}

/// One merge group's state between frames.
struct Group {
    /// The object ids of the group; `None`: every object (a single group).
    members: Option<Vec<u8>>,
    /// Id of the group's merged hierarchy.
    merged_id: u8,
    merged_inputs: Option<Vec<u8>>,
    last_level: Option<u8>,
}

/// The state kept between frames.
pub struct Frames {
    /// The store, translation table and objects as of the last frame.
    pub world: World,
    /// How the merge chooses its merging level (SPEC 8).
    pub mode: MergeMode,
    groups: Vec<Group>,
    last: BTreeMap<u8, (Motion, Arc<Mesh>, DVec3)>,
    frame: u64,
    /// Hierarchies given for objects' first build ([`Frames::provide`]).
    provided: BTreeMap<u8, Hierarchy>,
}

impl Frames {
    /// An empty world with `params` and `grid`, merging every object as one
    /// group in `mode`; the merged hierarchy gets id `2^H - 1`. Fails only if
    /// the world cannot be made.
    pub fn new(params: Params, grid: GridMap, mode: MergeMode) -> Result<Frames, FrameError> {
        Self::make(params, grid, mode, vec![None])
    }

    /// As [`Frames::new`], merging each of `groups` (object ids; every
    /// object of a frame in exactly one) into a hierarchy of its own
    /// (paragraph 67): group `k` gets id `2^H - 1 - k`, and those ids are
    /// reserved.
    pub fn with_groups(
        params: Params,
        grid: GridMap,
        mode: MergeMode,
        groups: Vec<Vec<u8>>,
    ) -> Result<Frames, FrameError> {
        let first_reserved = params.hier_capacity().saturating_sub(groups.len() as u64);
        if groups.is_empty() || first_reserved == 0 {
            return Err(FrameError::BadGroups(format!(
                "{} groups: expected 1 to {} (one id each, below 2^H, and one for an object)",
                groups.len(),
                params.hier_capacity() - 1
            )));
        }
        let mut seen = BTreeMap::new();
        for (k, g) in groups.iter().enumerate() {
            if g.is_empty() {
                return Err(FrameError::BadGroups(format!("group {k} is empty")));
            }
            for &id in g {
                if id as u64 >= first_reserved {
                    return Err(FrameError::ReservedId(id));
                }
                if let Some(other) = seen.insert(id, k) {
                    return Err(FrameError::BadGroups(format!(
                        "object {id} is in groups {other} and {k}: expected exactly one"
                    )));
                }
            }
        }
        Self::make(params, grid, mode, groups.into_iter().map(Some).collect())
    }

    fn make(
        params: Params,
        grid: GridMap,
        mode: MergeMode,
        members: Vec<Option<Vec<u8>>>,
    ) -> Result<Frames, FrameError> {
        let top = params.hier_capacity() - 1;
        Ok(Frames {
            world: World::new(params, grid)?,
            mode,
            groups: members
                .into_iter()
                .enumerate()
                .map(|(k, members)| Group {
                    members,
                    merged_id: (top - k as u64) as u8,
                    merged_inputs: None,
                    last_level: None,
                })
                .collect(),
            last: BTreeMap::new(),
            frame: 0,
            provided: BTreeMap::new(),
        })
    }

    /// The id of group `k`'s merged hierarchy (`2^H - 1 - k`); group 0 is
    /// the only group of [`Frames::new`].
    pub fn merged_id(&self, k: usize) -> Option<u8> {
        self.groups.get(k).map(|g| g.merged_id)
    }

    /// The group of object `id`, if any.
    fn group_of(&self, id: u8) -> Option<usize> {
        self.groups.iter().position(|g| match &g.members {
            None => true,
            Some(m) => m.contains(&id),
        })
    }

    /// Gives object `id`'s hierarchy (a saved one, SPEC 16) for the frame
    /// it first appears in, which then does not build it
    /// ([`World::add_built`]); it must be the hierarchy of that frame's mesh,
    /// built as hierarchy `id` in this world's grid.
    pub fn provide(&mut self, id: u8, hierarchy: Hierarchy) {
        self.provided.insert(id, hierarchy);
    }

    /// Brings the world to this frame's scene, redoing only what changed,
    /// and merges each group with two or more objects present into its
    /// merged hierarchy; a group's merge is redone only when one of its
    /// objects changed or left.
    pub fn step(&mut self, objects: &[FrameObject]) -> Result<FrameReport, FrameError> {
        let mut seen = BTreeMap::new();
        for o in objects {
            if self.groups.iter().any(|g| g.merged_id == o.id) {
                return Err(FrameError::ReservedId(o.id));
            }
            if seen.insert(o.id, ()).is_some() {
                return Err(FrameError::DuplicateId(o.id));
            }
            if self.group_of(o.id).is_none() {
                return Err(FrameError::Ungrouped(o.id));
            }
        }
        let mut actions = BTreeMap::new();
        let mut fallbacks = BTreeMap::new();
        for o in objects {
            let action = self.update_object(o)?;
            actions.insert(o.id, action);
            if action != ObjectAction::Reused {
                if let Some(f) = self.world.object(o.id).and_then(|p| p.fallback.clone()) {
                    fallbacks.insert(o.id, f);
                }
            }
        }
        let removed: Vec<u8> = self
            .last
            .keys()
            .copied()
            .filter(|id| !seen.contains_key(id))
            .collect();
        for id in &removed {
            self.world.remove(*id);
            self.last.remove(id);
        }
        let mut groups = Vec::with_capacity(self.groups.len());
        for k in 0..self.groups.len() {
            let inputs: Vec<u8> = actions
                .keys()
                .copied()
                .filter(|&id| self.group_of(id) == Some(k))
                .collect();
            let changed = inputs.iter().any(|id| actions[id] != ObjectAction::Reused);
            groups.push(self.merge_group(k, inputs, changed)?);
        }
        let report = FrameReport {
            frame: self.frame,
            objects: actions,
            removed,
            groups,
            fallbacks,
        };
        self.frame += 1;
        Ok(report)
    }

    /// Group `k`'s merge this frame over its present objects `inputs`
    /// (ascending); `changed` when one of them was not reused.
    fn merge_group(
        &mut self,
        k: usize,
        inputs: Vec<u8>,
        changed: bool,
    ) -> Result<GroupReport, FrameError> {
        let g = &mut self.groups[k];
        let (merged, merge_stats) = if inputs.len() < 2 {
            // Nothing to merge: an earlier merge must not stay in the store,
            // where it would still reference inputs that may be gone.
            self.world.store.remove(g.merged_id);
            g.merged_inputs = None;
            g.last_level = None;
            (false, None)
        } else if !changed && g.merged_inputs.as_deref() == Some(&inputs[..]) {
            (false, None)
        } else {
            let r = self.world.merge(&inputs, self.mode, g.merged_id)?;
            g.merged_inputs = Some(inputs.clone());
            g.last_level = r.level;
            (true, Some(r.stats))
        };
        let root = match inputs.len() {
            0 => None,
            1 => Some(inputs[0]),
            _ => Some(g.merged_id),
        };
        Ok(GroupReport {
            root,
            inputs,
            merged,
            merge_level: g.last_level,
            merge_stats,
        })
    }

    fn update_object(&mut self, o: &FrameObject) -> Result<ObjectAction, FrameError> {
        let action = match self.last.get(&o.id) {
            None => {
                let mesh = (*o.mesh).clone();
                match self.provided.remove(&o.id) {
                    Some(h) => self.world.add_built(o.id, mesh, o.offset, h)?,
                    None => self.world.add(o.id, mesh, o.offset)?,
                };
                ObjectAction::Built
            }
            Some((motion, mesh, offset)) => {
                let same_mesh = Arc::ptr_eq(mesh, &o.mesh);
                let same_place = *offset == o.offset;
                if *motion == Motion::Static || o.motion == Motion::Static {
                    if *motion != o.motion {
                        return Err(FrameError::StaticChanged {
                            id: o.id,
                            what: "motion",
                        });
                    }
                    if !same_mesh {
                        return Err(FrameError::StaticChanged {
                            id: o.id,
                            what: "mesh",
                        });
                    }
                    if !same_place {
                        return Err(FrameError::StaticChanged {
                            id: o.id,
                            what: "placement",
                        });
                    }
                    ObjectAction::Reused
                } else if !same_mesh {
                    self.world.add(o.id, (*o.mesh).clone(), o.offset)?;
                    ObjectAction::Rebuilt
                } else if !same_place {
                    match self.world.place(o.id, o.offset)? {
                        Placing::Retranslated => ObjectAction::Retranslated,
                        Placing::Rebuilt => ObjectAction::Moved,
                    }
                } else {
                    ObjectAction::Reused
                }
            }
        };
        self.last.insert(o.id, (o.motion, o.mesh.clone(), o.offset));
        Ok(action)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenes::{sphere, terrain, torus};
    use glam::Vec3;

    fn frames() -> Frames {
        let p = Params::new(12, 6, 24, 4).unwrap();
        Frames::new(
            p,
            GridMap {
                origin: DVec3::ZERO,
                unit: 1.0 / 1024.0,
            },
            MergeMode::default(),
        )
        .unwrap()
    }

    fn obj(id: u8, motion: Motion, mesh: &Arc<Mesh>, x: f64) -> FrameObject {
        FrameObject {
            id,
            motion,
            mesh: mesh.clone(),
            offset: DVec3::new(x, 0.0, 0.0),
        }
    }

    /// A placement that no LOD finer than 0 holds (the cube ends on the
    /// scene's far face) is reported with the LOD refused and why; one
    /// placed inside is not, and a reused object is not reported again.
    #[test]
    fn a_fallback_is_reported_with_its_reason() {
        let p = Params::new(12, 6, 24, 4).unwrap();
        let grid = GridMap {
            origin: DVec3::ZERO,
            unit: 1.0 / 256.0,
        };
        let mut f = Frames::new(p, grid, MergeMode::default()).unwrap();
        let side = f.world.params.voxel_edge(0) as f64 * f.world.grid.unit;
        let cube = Arc::new(crate::scenes::box_mesh(Vec3::splat(0.5), Vec3::splat(1.0)));
        let at = |x: f64| obj(1, Motion::Dynamic, &cube, x);
        let r = f.step(&[at(side - 1.0)]).unwrap();
        let fb = &r.fallbacks[&1];
        assert_eq!(fb.settled_lod, 0);
        assert!(fb.refused_lod > 0 && !fb.reason.is_empty(), "{fb:?}");
        assert!(f.step(&[at(side - 1.0)]).unwrap().fallbacks.is_empty());
        let inside = f.step(&[at(0.25)]).unwrap();
        assert!(inside.fallbacks.is_empty(), "{:?}", inside.fallbacks);
    }

    #[test]
    fn only_what_changed_is_redone() {
        let mut f = frames();
        let ground = Arc::new(terrain(24, 1));
        let ball = Arc::new(sphere(Vec3::new(0.5, 0.7, 0.5), 0.1, 8, 16));
        let ring = Arc::new(torus(Vec3::new(0.3, 0.7, 0.3), 0.1, 0.03, 16, 8));
        let step = |f: &mut Frames, x: f64, ring: &Arc<Mesh>| {
            f.step(&[
                obj(0, Motion::Static, &ground, 0.0),
                obj(1, Motion::Dynamic, &ball, x),
                obj(2, Motion::Dynamic, ring, 0.0),
            ])
            .unwrap()
        };
        let r0 = step(&mut f, 0.0, &ring);
        assert_eq!(r0.count(ObjectAction::Built), 3);
        assert!(r0.merged());
        f.world.check(f.merged_id(0).unwrap()).unwrap();

        // Nothing moved: nothing is redone, the merge is reused.
        let r1 = step(&mut f, 0.0, &ring);
        assert_eq!(r1.count(ObjectAction::Reused), 3);
        assert!(!r1.merged());
        assert_eq!(r1.groups[0].merge_level, r0.groups[0].merge_level);

        // The ball moves by a fraction of a voxel: the residual changes, so
        // its local geometry is rebuilt; the merge is redone.
        let r2 = step(&mut f, 0.25, &ring);
        assert_eq!(r2.objects[&1], ObjectAction::Moved);
        assert_eq!(r2.objects[&0], ObjectAction::Reused);
        assert!(r2.merged());
        f.world.check(f.merged_id(0).unwrap()).unwrap();

        // By whole voxels: re-translated only, the hierarchy reused.
        let t = f.world.object(1).unwrap().determined.translation;
        let edge = f.world.params.voxel_edge(t.lod) as f64 * f.world.grid.unit;
        let before = f.world.store.get(1).unwrap().clone();
        let r = step(&mut f, 0.25 + edge, &ring);
        assert_eq!(r.objects[&1], ObjectAction::Retranslated);
        assert_eq!(f.world.store.get(1).unwrap(), &before);
        assert_eq!(
            f.world.object(1).unwrap().determined.translation.t[0],
            t.t[0] + 1
        );
        assert!(r.merged());
        f.world.check(f.merged_id(0).unwrap()).unwrap();
        step(&mut f, 0.25, &ring);

        // The ring deforms: rebuilt.
        let bigger = Arc::new(torus(Vec3::new(0.3, 0.7, 0.3), 0.12, 0.03, 16, 8));
        let r3 = step(&mut f, 0.25, &bigger);
        assert_eq!(r3.objects[&2], ObjectAction::Rebuilt);
        assert!(r3.merged());
        f.world.check(f.merged_id(0).unwrap()).unwrap();
    }

    #[test]
    fn static_objects_may_not_change_and_ids_are_checked() {
        let mut f = frames();
        let a = Arc::new(sphere(Vec3::splat(0.5), 0.1, 8, 16));
        f.step(&[obj(0, Motion::Static, &a, 0.0)]).unwrap();
        let e = f.step(&[obj(0, Motion::Static, &a, 0.5)]).unwrap_err();
        assert_eq!(
            e,
            FrameError::StaticChanged {
                id: 0,
                what: "placement"
            }
        );
        let e = f
            .step(&[
                obj(1, Motion::Dynamic, &a, 0.0),
                obj(1, Motion::Dynamic, &a, 0.0),
            ])
            .unwrap_err();
        assert_eq!(e, FrameError::DuplicateId(1));
        let e = f.step(&[obj(15, Motion::Dynamic, &a, 0.0)]).unwrap_err();
        assert_eq!(e, FrameError::ReservedId(15));
    }

    #[test]
    fn removed_objects_leave_the_merge() {
        let mut f = frames();
        let a = Arc::new(sphere(Vec3::splat(0.3), 0.1, 8, 16));
        let b = Arc::new(sphere(Vec3::splat(0.6), 0.1, 8, 16));
        let c = Arc::new(sphere(Vec3::new(0.6, 0.3, 0.3), 0.1, 8, 16));
        f.step(&[
            obj(0, Motion::Dynamic, &a, 0.0),
            obj(1, Motion::Dynamic, &b, 0.0),
            obj(2, Motion::Dynamic, &c, 0.0),
        ])
        .unwrap();
        let r = f
            .step(&[
                obj(0, Motion::Dynamic, &a, 0.0),
                obj(1, Motion::Dynamic, &b, 0.0),
            ])
            .unwrap();
        assert_eq!(r.removed, vec![2]);
        assert!(r.merged());
        assert!(f.world.object(2).is_none());
        let report = f.world.check(f.merged_id(0).unwrap()).unwrap();
        assert_eq!(report.hierarchies, vec![0, 1, f.merged_id(0).unwrap()]);
        // Down to one object: no merge, and the last one leaves the store.
        let r = f.step(&[obj(0, Motion::Dynamic, &a, 0.0)]).unwrap();
        assert_eq!(
            (r.removed.clone(), r.merged(), r.groups[0].merge_level),
            (vec![1], false, None)
        );
        assert_eq!(r.roots(), vec![0]);
        assert!(f.world.store.get(f.merged_id(0).unwrap()).is_none());
        assert!(f.world.check(f.merged_id(0).unwrap()).is_err());
        // Two again: merged anew.
        let r = f
            .step(&[
                obj(0, Motion::Dynamic, &a, 0.0),
                obj(1, Motion::Dynamic, &b, 0.0),
            ])
            .unwrap();
        assert!(r.merged());
        f.world.check(f.merged_id(0).unwrap()).unwrap();
    }

    /// Paragraph 67 over frames: a static group and a dynamic group, each
    /// merged into its own hierarchy; moving a dynamic object redoes only
    /// the dynamic group's merge, and the two traced together hit what the
    /// objects hit apart.
    #[test]
    fn groups_merge_apart_and_trace_together() {
        let p = Params::new(12, 6, 24, 4).unwrap();
        let grid = GridMap {
            origin: DVec3::ZERO,
            unit: 1.0 / 1024.0,
        };
        let mode = MergeMode::default();
        let bad = |groups: Vec<Vec<u8>>| Frames::with_groups(p, grid, mode, groups).err();
        assert!(matches!(bad(vec![]), Some(FrameError::BadGroups(_))));
        assert!(matches!(
            bad(vec![vec![0], vec![]]),
            Some(FrameError::BadGroups(_))
        ));
        assert!(matches!(
            bad(vec![vec![0, 1], vec![1]]),
            Some(FrameError::BadGroups(_))
        ));
        assert_eq!(
            bad(vec![vec![0], vec![14]]),
            Some(FrameError::ReservedId(14))
        );
        let mut f = Frames::with_groups(p, grid, mode, vec![vec![0, 1], vec![2, 3]]).unwrap();
        assert_eq!((f.merged_id(0), f.merged_id(1)), (Some(15), Some(14)));
        let ground = Arc::new(terrain(24, 1));
        let post = Arc::new(sphere(Vec3::new(2.0, 0.5, 2.0), 0.3, 8, 16));
        let ball = Arc::new(sphere(Vec3::new(0.5, 0.7, 0.5), 0.1, 8, 16));
        let ring = Arc::new(torus(Vec3::new(0.3, 0.7, 0.3), 0.1, 0.03, 16, 8));
        let step = |f: &mut Frames, x: f64| {
            f.step(&[
                obj(0, Motion::Static, &ground, 0.0),
                obj(1, Motion::Static, &post, 0.0),
                obj(2, Motion::Dynamic, &ball, x),
                obj(3, Motion::Dynamic, &ring, 0.0),
            ])
        };
        let r0 = step(&mut f, 0.0).unwrap();
        assert_eq!((r0.groups[0].merged, r0.groups[1].merged), (true, true));
        assert_eq!(r0.roots(), vec![15, 14]);
        let r1 = step(&mut f, 0.3).unwrap();
        assert_eq!((r1.groups[0].merged, r1.groups[1].merged), (false, true));
        for id in r1.merged_ids() {
            f.world.check(id).unwrap();
        }
        let all = [0, 1, 2, 3];
        let gi = f.world.group_instances(&r1.merged_ids(), &all).unwrap();
        let si = f.world.separate_instances(&all).unwrap();
        let gs = f.world.trace_scene(&gi, &r1.roots()).unwrap();
        let ss = f.world.trace_scene(&si, &all).unwrap();
        let (lo, hi) = ss.bounds();
        let mut hits = 0;
        for ray in crate::trace::random_rays(lo, hi, 1000, 11) {
            let mut s = crate::trace::TraceStats::default();
            let a = crate::trace::closest_hit(&ray, &gs, &mut s);
            let b = crate::trace::closest_hit(&ray, &ss, &mut s);
            assert_eq!(
                a.map(|h| (h.hier, h.prim, h.t.to_bits())),
                b.map(|h| (h.hier, h.prim, h.t.to_bits()))
            );
            hits += a.is_some() as u32;
        }
        assert!(hits > 100, "{hits} hits");
        // An object outside every group is refused by name.
        let e = f.step(&[obj(4, Motion::Dynamic, &ball, 0.0)]).unwrap_err();
        assert_eq!(e, FrameError::Ungrouped(4));
    }
}
