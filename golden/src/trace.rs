//! Ray traversal (S410): the closest hit of a ray against one or more
//! hierarchies, with the node and primitive tests it took (SPEC.md section 6).
//!
//! Traversal is an iterative stack walk from the roots. Every node's exact
//! box (SPEC.md section 3) is taken from grid units to world units, moved
//! into its instance's frame (SPEC 6.4: near its geometry, so far from the
//! origin boxes stay as tight as near it), rounded outward to f32, grown by
//! a slack that covers the triangle test's rounding, and tested with the
//! robust slab test ([`crate::geom::aabb`]) against the ray moved likewise.
//! What of that does not depend on the ray is done once per scene
//! ([`TraceScene::new`]): each node's box in binary64 up to the slack, and
//! an f32 box around it that sorts out most misses with a plain slab test
//! before the exact box is made (see `TraceContext::visit` for why that
//! gives the same answers).
//! Leaves test their triangles with the watertight test
//! ([`crate::geom::triangle`]) on the mesh's original f32 vertices. The
//! closest hit is the smallest `t`, ties broken by the smallest
//! `(hierarchy id, primitive index)`, so it is unique and equal, bit for
//! bit, to what [`brute_force_closest`] finds.
//!
//! Per-hierarchy translation: an [`Instance`] carries an offset in grid units
//! (zero for an untranslated hierarchy). Its node boxes move by the offset;
//! its triangles stay where the mesh has them and are tested against the ray
//! moved the other way (origin minus the offset in world units, rounded to
//! f32): instancing, which keeps the original vertices exact. The slack
//! covers that rounding of the origin too.

use glam::{DVec3, Vec3, Vec3A};
use serde::Serialize;
use std::fmt;

use crate::build::GridMap;
use crate::geom::{
    intersect_each, intersect_triangle, ray_box_entry, ray_meets_box, Ray, ShearedRay, SlabRay,
    TriangleHit, TriangleLanes,
};
use crate::mesh::Mesh;
use crate::scenes::SplitMix64;
use crate::store::{node_box_grid, Hierarchy, NodeRecord};

/// Relative slack added to node boxes: `2^-20` of the magnitude of the
/// coordinates the triangle test works with, per instance: the largest
/// coordinate of the ray origin as that instance sees it plus the largest
/// coordinate of its (untranslated) vertices. The watertight test's edge
/// functions and `t`, the rounding of the moved origin and the slab test's
/// entry carry errors of a few f32 ulps of that magnitude (`2^-24` relative
/// each); `2^-20` covers them with a factor of 16.
pub const BOX_SLACK_REL: f64 = 1.0 / (1u64 << 20) as f64;

/// One hierarchy placed in the scene: its nodes, the mesh its primitive
/// indices point into, and a translation in grid units.
#[derive(Clone, Copy, Debug)]
pub struct Instance<'a> {
    /// The hierarchy; its `id` names the instance.
    pub hierarchy: &'a Hierarchy,
    /// The triangles the leaves' primitive indices point into, untranslated, world units.
    pub mesh: &'a Mesh,
    /// Added to every node's grid position and, times the grid unit, to every
    /// triangle's world position. `[0; 3]` for an untranslated hierarchy.
    pub offset: [i64; 3],
}

impl<'a> Instance<'a> {
    /// An untranslated instance.
    pub fn new(hierarchy: &'a Hierarchy, mesh: &'a Mesh) -> Instance<'a> {
        Instance {
            hierarchy,
            mesh,
            offset: [0; 3],
        }
    }
}

/// A closest hit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Hit {
    /// Ray parameter of the hit, within the ray's `[tmin, tmax]`.
    pub t: f32,
    /// Barycentric weights of the triangle's vertices 0, 1, 2.
    pub u: f32,
    /// Weight of vertex 1.
    pub v: f32,
    /// Weight of vertex 2.
    pub w: f32,
    /// The hierarchy whose leaf held the triangle.
    pub hier: u8,
    /// The triangle's index in that hierarchy's mesh.
    pub prim: u32,
}

impl Hit {
    /// The hit of a triangle test on triangle `prim` of hierarchy `hier`.
    fn on(th: &TriangleHit, hier: u8, prim: u32) -> Hit {
        Hit {
            t: th.t,
            u: th.u,
            v: th.v,
            w: th.w,
            hier,
            prim,
        }
    }

    /// The closest-hit order: `t`, then hierarchy id, then primitive index.
    fn precedes(&self, other: &Hit) -> bool {
        (self.t, self.hier, self.prim) < (other.t, other.hier, other.prim)
    }

    /// True when two hits are the same triangle at the same `t`, bit for bit.
    pub fn identical(&self, other: &Hit) -> bool {
        self.hier == other.hier
            && self.prim == other.prim
            && self.t.to_bits() == other.t.to_bits()
            && self.u.to_bits() == other.u.to_bits()
            && self.v.to_bits() == other.v.to_bits()
            && self.w.to_bits() == other.w.to_bits()
    }
}

/// What one ray (or many, summed) cost.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct TraceStats {
    /// Ray/box tests, one per node whose box was tested.
    pub node_tests: u64,
    /// Ray/triangle tests.
    pub prim_tests: u64,
}

impl std::ops::AddAssign for TraceStats {
    fn add_assign(&mut self, o: TraceStats) {
        self.node_tests += o.node_tests;
        self.prim_tests += o.prim_tests;
    }
}

/// A scene that cannot be traced: a reference, range or index that points
/// nowhere. Traversal itself never fails on a scene that passed these checks.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TraceError {
    /// The hierarchy at fault (0 for a bad grid map).
    pub hier: u8,
    /// What is wrong, e.g. `node 12 prims range`.
    pub field: String,
    /// What it should have been.
    pub expected: String,
    /// What was found instead.
    pub found: String,
}

impl fmt::Display for TraceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "hierarchy {}: {}: expected {}, found {}",
            self.hier, self.field, self.expected, self.found
        )
    }
}

impl std::error::Error for TraceError {}

/// Per-instance data prepared once.
#[derive(Clone, Debug)]
struct Placed<'a> {
    inst: Instance<'a>,
    /// The offset in world units, `offset * unit`, in binary64.
    shift: DVec3,
    /// Where the instance's frame sits in the world (binary64): its boxes
    /// are tested in it, with the ray origin moved by minus it (SPEC 6.4).
    /// `shift` for an instance with triangles (its triangles' own frame);
    /// the lower corner of its roots for one without (a merged hierarchy).
    frame: DVec3,
    /// Largest absolute coordinate of the mesh's own (untranslated) vertices.
    local_magnitude: f64,
    /// Instances with triangles whose nodes can be reached from this one's
    /// (itself included): whose slack its boxes must carry.
    reach: Vec<usize>,
    /// Every node's box in the frame, indexed like the hierarchy's nodes:
    /// the per-node part of SPEC 6.4, made once per scene so a box test
    /// does not decode the record and map it to world units again.
    boxes: Vec<FrameBox>,
    /// Every node's f32 box grown by `outer_slack` instead of the ray's
    /// slack: a box around the exact one of every ray whose slack is at
    /// most `outer_slack` (see [`TraceContext::visit`]).
    outer: Vec<(Vec3A, Vec3A)>,
    /// The largest slack the `outer` boxes cover.
    outer_slack: f64,
    /// The mesh's triangles with their vertices in place of indices, by
    /// coordinate: a leaf's triangle test reads one record instead of
    /// four, and tests the three vertices at once.
    tris: Vec<TriangleLanes>,
    /// Every node as the walk reads it, indexed like the hierarchy's nodes.
    walk: Vec<WalkNode>,
}

/// A node as the walk reads it, made once per scene: where its triangles
/// or children are, and for an inner node the instance holding them when
/// it is one (the usual case), so the walk neither decodes the record nor
/// looks the children's hierarchies up.
#[derive(Clone, Copy, Debug)]
struct WalkNode {
    /// First index into the hierarchy's `prims` (leaf) or `refs` (inner).
    first: u32,
    /// Number of triangles or children.
    count: u32,
    /// [`WalkNode::LEAF`], [`WalkNode::MIXED`] (children in more than one
    /// hierarchy), or the index in `placed` of the instance holding every child.
    target: u32,
}

impl WalkNode {
    const LEAF: u32 = u32::MAX;
    const MIXED: u32 = u32::MAX - 1;

    fn new(n: &NodeRecord, h: &Hierarchy, by_id: &[Option<usize>]) -> WalkNode {
        let target = if n.leaf {
            WalkNode::LEAF
        } else {
            let children = h.children_of(n);
            match children.first() {
                Some(c) if children.iter().all(|r| r.hier == c.hier) => {
                    by_id[c.hier as usize].map_or(WalkNode::MIXED, |k| k as u32)
                }
                _ => WalkNode::MIXED,
            }
        };
        WalkNode {
            first: n.first,
            count: n.count,
            target,
        }
    }

    /// The node's indices into `prims` or `refs`.
    fn range(&self) -> std::ops::Range<usize> {
        self.first as usize..self.first as usize + self.count as usize
    }
}

/// Instances ready to trace: checked, indexed by hierarchy id.
#[derive(Clone, Debug)]
pub struct TraceScene<'a> {
    grid: GridMap,
    placed: Vec<Placed<'a>>,
    /// Hierarchy id to index in `placed`.
    by_id: Vec<Option<usize>>,
    /// Ids whose roots traversal starts from.
    roots: Vec<u8>,
}

impl<'a> TraceScene<'a> {
    /// Checks the instances (distinct ids, every reference, range and
    /// primitive index resolvable, finite vertices) and starts traversal from
    /// the roots of all of them.
    pub fn new(grid: GridMap, instances: &[Instance<'a>]) -> Result<TraceScene<'a>, TraceError> {
        let ids: Vec<u8> = instances.iter().map(|i| i.hierarchy.id).collect();
        TraceScene::with_roots(grid, instances, &ids)
    }

    /// Like [`TraceScene::new`], starting only from the roots of `roots`;
    /// the other instances are reached through references (a merged
    /// hierarchy referencing its inputs).
    pub fn with_roots(
        grid: GridMap,
        instances: &[Instance<'a>],
        roots: &[u8],
    ) -> Result<TraceScene<'a>, TraceError> {
        let mut by_id = vec![None; 256];
        let mut placed = Vec::with_capacity(instances.len());
        for (k, inst) in instances.iter().enumerate() {
            let id = inst.hierarchy.id;
            if by_id[id as usize].replace(k).is_some() {
                return Err(err(
                    id,
                    "hierarchy id",
                    "distinct ids across instances",
                    "a repeat",
                ));
            }
            let shift = DVec3::new(
                inst.offset[0] as f64,
                inst.offset[1] as f64,
                inst.offset[2] as f64,
            ) * grid.unit;
            inst.mesh.validate("mesh").map_err(|e| {
                err(
                    id,
                    "mesh",
                    "valid indices and finite vertices",
                    e.to_string(),
                )
            })?;
            let local_magnitude = if inst.mesh.vertices.is_empty() {
                0.0
            } else {
                let (lo, hi) = inst.mesh.bounds();
                lo.as_dvec3().abs().max(hi.as_dvec3().abs()).max_element()
            };
            let frame = if inst.mesh.is_empty() {
                roots_corner(inst, &grid)
            } else {
                shift
            };
            placed.push(Placed {
                inst: *inst,
                shift,
                frame,
                local_magnitude,
                reach: Vec::new(),
                boxes: Vec::new(),
                outer: Vec::new(),
                outer_slack: 0.0,
                tris: Vec::new(),
                walk: Vec::new(),
            });
        }
        if !(grid.unit.is_finite() && grid.unit > 0.0 && grid.origin.is_finite()) {
            return Err(err(
                0,
                "grid map",
                "finite origin and unit > 0",
                format!("{grid:?}"),
            ));
        }
        let mut scene = TraceScene {
            grid,
            placed,
            by_id,
            roots: roots.to_vec(),
        };
        for &r in roots {
            if scene.by_id[r as usize].is_none() {
                return Err(err(
                    r,
                    "root hierarchy",
                    "one of the instances",
                    "no such instance",
                ));
            }
        }
        for p in &scene.placed {
            scene.check_instance(p)?;
        }
        for k in 0..scene.placed.len() {
            scene.placed[k].reach = scene.reachable_with_triangles(k);
        }
        let outer_slacks = scene.outer_slacks();
        for (k, outer_slack) in outer_slacks.into_iter().enumerate() {
            let p = &scene.placed[k];
            let boxes: Vec<FrameBox> = p
                .inst
                .hierarchy
                .nodes
                .iter()
                .map(|n| scene.frame_box(p, n))
                .collect();
            let walk = p
                .inst
                .hierarchy
                .nodes
                .iter()
                .map(|n| WalkNode::new(n, p.inst.hierarchy, &scene.by_id))
                .collect();
            let p = &mut scene.placed[k];
            p.walk = walk;
            p.outer = boxes.iter().map(|b| b.with_slack(outer_slack)).collect();
            p.outer_slack = outer_slack;
            p.boxes = boxes;
            p.tris = (0..p.inst.mesh.len())
                .map(|t| TriangleLanes::new(&p.inst.mesh.triangle(t)))
                .collect();
        }
        Ok(scene)
    }

    /// Instances with triangles reachable from instance `k` through
    /// references (a hierarchy-level walk; `k` included).
    fn reachable_with_triangles(&self, k: usize) -> Vec<usize> {
        let mut seen = vec![false; self.placed.len()];
        let mut todo = vec![k];
        seen[k] = true;
        while let Some(i) = todo.pop() {
            let h = self.placed[i].inst.hierarchy;
            let mut targets: Vec<u8> = h.refs.iter().map(|r| r.hier).collect();
            targets.sort_unstable();
            targets.dedup();
            for id in targets {
                if let Some(j) = self.by_id[id as usize] {
                    if !seen[j] {
                        seen[j] = true;
                        todo.push(j);
                    }
                }
            }
        }
        (0..self.placed.len())
            .filter(|&j| seen[j] && !self.placed[j].inst.mesh.is_empty())
            .collect()
    }

    fn check_instance(&self, p: &Placed) -> Result<(), TraceError> {
        let h = p.inst.hierarchy;
        let id = h.id;
        if h.root_count as usize > h.nodes.len() {
            return Err(err(
                id,
                "root_count",
                format!("at most {} nodes", h.nodes.len()),
                h.root_count.to_string(),
            ));
        }
        let tris = p.inst.mesh.triangles.len() as u64;
        for (i, n) in h.nodes.iter().enumerate() {
            let r = n.range();
            let len = if n.leaf { h.prims.len() } else { h.refs.len() } as u64;
            if r.end > len {
                let what = if n.leaf { "prims" } else { "refs" };
                return Err(err(
                    id,
                    format!("node {i} {what} range"),
                    format!("within 0..{len}"),
                    format!("{r:?}"),
                ));
            }
            if n.leaf {
                for &t in h.prims_of(n) {
                    if t as u64 >= tris {
                        return Err(err(
                            id,
                            format!("node {i} primitive"),
                            format!("a triangle index below {tris}"),
                            t.to_string(),
                        ));
                    }
                }
            } else {
                for c in h.children_of(n) {
                    let target = self.by_id[c.hier as usize].map(|k| self.placed[k].inst.hierarchy);
                    match target {
                        Some(t) if (c.node as usize) < t.nodes.len() => {}
                        _ => {
                            return Err(err(
                                id,
                                format!("node {i} reference"),
                                "a node of an instance in the scene",
                                format!("({}, {})", c.hier, c.node),
                            ))
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// The box of node `n` of instance `p` in the instance's frame (world
    /// box minus `p.frame`), up to the per-ray slack: what
    /// [`FrameBox::with_slack`] needs to give the box of SPEC 6.4.
    fn frame_box(&self, p: &Placed, n: &NodeRecord) -> FrameBox {
        let (lo, hi) = node_box_grid(n, &p.inst.hierarchy.params);
        let off = p.inst.offset;
        let to_world =
            |g: f64, axis: usize| self.grid.origin[axis] + (g + off[axis] as f64) * self.grid.unit;
        let (mut lo_d, mut lo_guard, mut hi_d, mut hi_guard) =
            ([0.0; 3], [0.0; 3], [0.0; 3], [0.0; 3]);
        for axis in 0..3 {
            let f = p.frame[axis];
            let a = to_world(lo[axis], axis);
            let c = to_world(hi[axis], axis);
            // Binary64 rounding of the operations above and of the move into
            // the frame is below 2^-50 of the values involved; the guard
            // takes it off before rounding to f32 outward.
            lo_d[axis] = a - f;
            lo_guard[axis] = (a.abs() + f.abs()) * F64_GUARD;
            hi_d[axis] = c - f;
            hi_guard[axis] = (c.abs() + f.abs()) * F64_GUARD;
        }
        FrameBox::new(lo_d, lo_guard, hi_d, hi_guard)
    }

    /// The slack of one ray for the boxes of each instance (world units),
    /// into `slacks` (`own` is scratch): the largest, over the instances
    /// with triangles its nodes reach, of
    /// `BOX_SLACK_REL * (max |local origin| + local magnitude)`; an instance
    /// without triangles adds the rounding of the origin in its own frame,
    /// `BOX_SLACK_REL * max |frame origin|`.
    fn slacks_into(&self, ray: &Ray, own: &mut Vec<f64>, slacks: &mut Vec<f64>) {
        own.clear();
        own.extend(self.placed.iter().map(|p| {
            let o = local_ray(ray, p).origin.abs().max_element() as f64;
            BOX_SLACK_REL * (o + p.local_magnitude)
        }));
        slacks.clear();
        slacks.extend(self.placed.iter().map(|p| {
            let reach = p.reach.iter().map(|&j| own[j]).fold(0.0, f64::max);
            if p.inst.mesh.is_empty() {
                let o = frame_ray(ray, p).origin.abs().max_element() as f64;
                reach + BOX_SLACK_REL * o
            } else {
                reach
            }
        }));
    }

    /// Per instance the slack of [`TraceScene::slacks_into`] for a ray
    /// whose origin has no coordinate above `R` in magnitude, `R` the
    /// scene's largest coordinate plus twice its diagonal (the ray
    /// generators reach 1.5 diagonals out), rounded generously up. Only
    /// speed depends on it: rays with a larger slack skip the outer boxes.
    fn outer_slacks(&self) -> Vec<f64> {
        let (lo, hi) = self.bounds();
        let reach = if lo.is_finite() && hi.is_finite() {
            lo.abs().max(hi.abs()).max_element() as f64 + 2.0 * (hi - lo).length() as f64
        } else {
            0.0
        };
        let own: Vec<f64> = self
            .placed
            .iter()
            .map(|p| {
                let o = reach + p.shift.abs().max_element();
                BOX_SLACK_REL * 2.0 * (o + p.local_magnitude)
            })
            .collect();
        self.placed
            .iter()
            .map(|p| {
                let r = p.reach.iter().map(|&j| own[j]).fold(0.0, f64::max);
                if p.inst.mesh.is_empty() {
                    r + BOX_SLACK_REL * 2.0 * (reach + p.frame.abs().max_element())
                } else {
                    r
                }
            })
            .collect()
    }

    /// Every instance, for brute force and bounds.
    pub fn instances(&self) -> impl Iterator<Item = &Instance<'a>> + '_ {
        self.placed.iter().map(|p| &p.inst)
    }

    /// The world box of every translated vertex of every instance.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for p in &self.placed {
            if p.inst.mesh.vertices.is_empty() {
                continue;
            }
            let (l, h) = p.inst.mesh.bounds();
            lo = lo.min((l.as_dvec3() + p.shift).as_vec3());
            hi = hi.max((h.as_dvec3() + p.shift).as_vec3());
        }
        (lo, hi)
    }
}

fn err(
    hier: u8,
    field: impl Into<String>,
    expected: impl Into<String>,
    found: impl Into<String>,
) -> TraceError {
    TraceError {
        hier,
        field: field.into(),
        expected: expected.into(),
        found: found.into(),
    }
}

/// Relative bound on binary64 rounding in [`TraceScene::frame_box`].
const F64_GUARD: f64 = 1.0 / (1u64 << 50) as f64;

/// A node's box in its instance's frame before the ray's slack (SPEC 6.4),
/// in binary64: the lower bounds `w - F` and the upper bounds negated,
/// `-(w - F)`, with their guards `(|w| + |F|) 2^-50`. Negating the upper
/// bounds makes all six one operation, `round_down_f32((d - s) - guard)`:
/// rounding to nearest is symmetric, so `-((-x - s) - g) = (x + s) + g`
/// bit for bit, and rounding the upper bound up is rounding its negation
/// down, negated.
#[derive(Clone, Copy, Debug, Default)]
struct FrameBox {
    d: [f64; 6],
    guard: [f64; 6],
}

impl FrameBox {
    fn new(lo: [f64; 3], lo_guard: [f64; 3], hi: [f64; 3], hi_guard: [f64; 3]) -> FrameBox {
        FrameBox {
            d: [lo[0], lo[1], lo[2], -hi[0], -hi[1], -hi[2]],
            guard: [
                lo_guard[0],
                lo_guard[1],
                lo_guard[2],
                hi_guard[0],
                hi_guard[1],
                hi_guard[2],
            ],
        }
    }

    /// The f32 box tested against the ray: SPEC 6.4's
    /// `round_down_f32(w_lo - F - s - guard)` and
    /// `round_up_f32(w_hi - F + s + guard)`, the same binary64 operations in
    /// the same order as the expression evaluated whole.
    #[inline]
    fn with_slack(&self, slack: f64) -> (Vec3A, Vec3A) {
        let y: [f64; 6] = std::array::from_fn(|i| self.d[i] - slack - self.guard[i]);
        // Six lanes of the same branch-free operations: the compiler makes
        // vector instructions of them.
        let r = y.map(f32_down);
        (
            Vec3A::new(r[0], r[1], r[2]),
            Vec3A::new(-r[3], -r[4], -r[5]),
        )
    }

    /// The ray's entry into the box grown by `slack`, if it meets it
    /// within `[tmin, tmax]` ([`ray_box_entry`]).
    #[inline]
    fn entry(&self, slab: &SlabRay, slack: f64, tmin: f32, tmax: f32) -> Option<f32> {
        let (lo, hi) = self.with_slack(slack);
        ray_box_entry(slab, lo, hi, tmin, tmax)
    }
}

/// The largest f32 not above `x` (for NaN, NaN). Free of branches: about
/// half the values round up to nearest, so a branch on it is mispredicted
/// about as often, six times per box test.
fn f32_down(x: f64) -> f32 {
    let f = x as f32;
    let bits = f.to_bits();
    let rounded_up = ((f as f64) > x) as u32;
    // One step toward -inf: a positive value's bits go down by one, a
    // negative value's up by one; +0 steps as -0 does, to the smallest
    // negative subnormal, so it takes the sign bit first.
    let b = bits | (((bits == 0) as u32 & rounded_up) << 31);
    let step = (b >> 31).wrapping_mul(2).wrapping_sub(1);
    f32::from_bits(b.wrapping_add(rounded_up.wrapping_mul(step)))
}

/// The smallest f32 not below `x`: rounding to nearest is symmetric, so it
/// is [`f32_down`] of `-x`, negated (a NaN comes back with its sign flipped;
/// node boxes are finite). [`FrameBox`] negates its upper bounds instead.
#[cfg(test)]
fn f32_up(x: f64) -> f32 {
    -f32_down(-x)
}

/// The lower corner of an instance's roots in world units (binary64): the
/// frame its boxes are tested in when it has no triangles of its own.
fn roots_corner(inst: &Instance, grid: &GridMap) -> DVec3 {
    let h = inst.hierarchy;
    let mut lo = DVec3::splat(f64::INFINITY);
    for n in h.roots() {
        let (l, _) = node_box_grid(n, &h.params);
        for axis in 0..3 {
            let w = grid.origin[axis] + (l[axis] + inst.offset[axis] as f64) * grid.unit;
            lo[axis] = lo[axis].min(w);
        }
    }
    if lo.is_finite() {
        lo
    } else {
        DVec3::ZERO
    }
}

/// The ray as instance `p`'s boxes are tested: origin moved by minus its
/// frame (exact when the frame is the origin).
fn frame_ray(ray: &Ray, p: &Placed) -> Ray {
    if p.frame == DVec3::ZERO {
        return *ray;
    }
    Ray {
        origin: (ray.origin.as_dvec3() - p.frame).as_vec3(),
        ..*ray
    }
}

/// The ray as instance `p` sees its own triangles: origin moved by minus its
/// translation (exact when the translation is zero).
fn local_ray(ray: &Ray, p: &Placed) -> Ray {
    if p.shift == DVec3::ZERO {
        return *ray;
    }
    Ray {
        origin: (ray.origin.as_dvec3() - p.shift).as_vec3(),
        ..*ray
    }
}

/// True when `hit` beats the best so far (or there is none yet).
fn improves(best: &Option<Hit>, hit: &Hit) -> bool {
    match best {
        None => true,
        Some(b) => hit.precedes(b),
    }
}

/// A node waiting on the traversal stack, with the ray's entry into its box.
#[derive(Clone, Copy, Debug)]
struct Pending {
    placed: usize,
    node: u32,
    entry: f32,
}

/// The scratch space of traversal, owned by the caller and reused from ray
/// to ray (and from scene to scene): per instance the ray's box slack and
/// its prepared slab and sheared rays, and the stack. Once its buffers have grown to a scene's size,
/// tracing a ray allocates nothing. What a context traced before never
/// changes an answer: [`TraceContext::closest_hit`] returns what
/// [`closest_hit`] does, with the same tests counted.
///
/// ```
/// use glam::Vec3;
/// use golden::build::{build, GridMap};
/// use golden::geom::Ray;
/// use golden::scenes::sphere;
/// use golden::trace::{Instance, TraceContext, TraceScene, TraceStats};
/// use golden::Params;
///
/// let mesh = sphere(Vec3::ZERO, 1.0, 16, 32);
/// let params = Params::default();
/// let (lo, hi) = mesh.bounds();
/// let grid = GridMap::fit(lo, hi, &params);
/// let hierarchy = build(&mesh, &grid, &params, 0).unwrap();
/// let scene = TraceScene::new(grid, &[Instance::new(&hierarchy, &mesh)]).unwrap();
///
/// let mut ctx = TraceContext::new();
/// let mut stats = TraceStats::default();
/// let ray = Ray::unbounded(Vec3::new(0.0, 0.0, -5.0), Vec3::Z);
/// let hit = ctx.closest_hit(&ray, &scene, &mut stats).unwrap();
/// assert!((hit.t - 4.0).abs() < 0.01);
/// // A shadow ray that stops short of the sphere is not occluded.
/// let short = Ray::new(ray.origin, ray.dir, 0.0, 3.0);
/// assert!(!ctx.occluded(&short, &scene, &mut stats));
/// assert!(ctx.occluded(&ray, &scene, &mut stats));
/// assert!(stats.node_tests > 0 && stats.prim_tests > 0);
/// ```
#[derive(Clone, Debug, Default)]
pub struct TraceContext {
    own: Vec<f64>,
    slacks: Vec<f64>,
    slabs: Vec<Option<SlabRay>>,
    sheared: Vec<Option<ShearedRay>>,
    stack: Vec<Pending>,
}

impl TraceContext {
    /// An empty context; its buffers grow on first use.
    pub fn new() -> TraceContext {
        TraceContext::default()
    }

    /// The closest hit of `ray` in `scene`, adding the tests it took to
    /// `stats`: the same hit, bit for bit, and the same counts as [`closest_hit`].
    pub fn closest_hit(
        &mut self,
        ray: &Ray,
        scene: &TraceScene,
        stats: &mut TraceStats,
    ) -> Option<Hit> {
        self.walk::<false>(ray, scene, stats)
    }

    /// True when `ray` hits some triangle of `scene` within its
    /// `[tmin, tmax]`: exactly when [`TraceContext::closest_hit`] returns a
    /// hit (SPEC 6.11). The walk is the closest-hit walk up to its first
    /// triangle hit, where it stops, so it never makes more tests.
    pub fn occluded(&mut self, ray: &Ray, scene: &TraceScene, stats: &mut TraceStats) -> bool {
        self.walk::<true>(ray, scene, stats).is_some()
    }

    /// The stack walk from the roots; `ANY` returns the first hit found.
    fn walk<const ANY: bool>(
        &mut self,
        ray: &Ray,
        scene: &TraceScene,
        stats: &mut TraceStats,
    ) -> Option<Hit> {
        scene.slacks_into(ray, &mut self.own, &mut self.slacks);
        let n = scene.placed.len();
        self.slabs.clear();
        self.slabs.resize(n, None);
        self.sheared.clear();
        self.sheared.resize(n, None);
        self.stack.clear();
        let mut best: Option<Hit> = None;
        for &id in scene.roots.iter().rev() {
            let k = scene.by_id[id as usize].expect("checked in TraceScene::with_roots");
            let roots = scene.placed[k].inst.hierarchy.root_count;
            self.visit(scene, ray, k, 0..roots, ray.tmax, stats);
        }
        while let Some(top) = self.stack.pop() {
            let best_t = best.map_or(ray.tmax, |h| h.t);
            if top.entry > best_t {
                continue;
            }
            let p = &scene.placed[top.placed];
            let h = p.inst.hierarchy;
            let w = p.walk[top.node as usize];
            if w.target == WalkNode::LEAF {
                let prims = &h.prims[w.range()];
                if self.test_leaf::<ANY>(ray, p, top.placed, prims, &mut best, stats) {
                    return best;
                }
            } else if w.target != WalkNode::MIXED {
                let nodes = h.refs[w.range()].iter().map(|r| r.node);
                self.visit(scene, ray, w.target as usize, nodes, best_t, stats);
            } else {
                // Children in other instances (a merged hierarchy).
                let refs = &h.refs[w.range()];
                let mut i = 0;
                while i < refs.len() {
                    // Group consecutive references to the same hierarchy.
                    let hier = refs[i].hier;
                    let j = refs[i..]
                        .iter()
                        .position(|r| r.hier != hier)
                        .map_or(refs.len(), |d| i + d);
                    let k = scene.by_id[hier as usize].expect("checked in TraceScene::with_roots");
                    let nodes = refs[i..j].iter().map(|r| r.node);
                    self.visit(scene, ray, k, nodes, best_t, stats);
                    i = j;
                }
            }
        }
        best
    }

    /// Tests the triangles `prims` of a leaf of instance `p` (index
    /// `placed`) against the ray over `[tmin, best_t]`, keeping the best hit
    /// in `best`; true when `ANY` and a triangle was hit (the walk ends).
    fn test_leaf<const ANY: bool>(
        &mut self,
        ray: &Ray,
        p: &Placed,
        placed: usize,
        prims: &[u32],
        best: &mut Option<Hit>,
        stats: &mut TraceStats,
    ) -> bool {
        let h = p.inst.hierarchy;
        let s = self.sheared[placed].get_or_insert_with(|| ShearedRay::new(&local_ray(ray, p)));
        let best_t = best.map_or(ray.tmax, |h| h.t);
        let mut stop = false;
        let tested = intersect_each(s, prims, &p.tris, ray.tmin, best_t, |prim, th| {
            let hit = Hit::on(th, h.id, prim);
            if ANY {
                *best = Some(hit);
                stop = true;
                return None;
            }
            if improves(best, &hit) {
                *best = Some(hit);
            }
            best.map(|b| b.t)
        });
        stats.prim_tests += tested as u64;
        stop
    }

    /// Tests the boxes of `nodes` of instance `placed` and pushes those hit,
    /// farthest first so the nearest is popped first. They are pushed in
    /// reference order and sorted where they lie on the stack.
    fn visit(
        &mut self,
        scene: &TraceScene,
        ray: &Ray,
        placed: usize,
        nodes: impl Iterator<Item = u32>,
        best_t: f32,
        stats: &mut TraceStats,
    ) {
        let p = &scene.placed[placed];
        let slab = *self.slabs[placed].get_or_insert_with(|| SlabRay::new(&frame_ray(ray, p)));
        let slack = self.slacks[placed];
        let start = self.stack.len();
        // One loop per answer, so the choice is made once per visit.
        let (lo, hi) = (ray.tmin, best_t);
        stats.node_tests += if slack <= p.outer_slack {
            self.push_hits::<true>(p, placed, &slab, slack, nodes, lo, hi)
        } else {
            self.push_hits::<false>(p, placed, &slab, slack, nodes, lo, hi)
        };
        sort_farthest_first(&mut self.stack[start..]);
    }

    /// Pushes the nodes of `nodes` whose box the ray meets within
    /// `[tmin, tmax]`, in order; returns how many boxes it tested.
    ///
    /// With `OUTER`, a ray that misses a box around the node's exact box
    /// misses the exact box too: the slab test is monotone in the box (a
    /// larger box gives an earlier or equal entry and a later or equal
    /// exit, every rounding being monotone), and the outer box holds the
    /// exact one when the ray's slack is at most `outer_slack` (outward
    /// rounding and binary64 subtraction are monotone in the slack). So
    /// the outer box, in f32 and made once, sorts out most misses for the
    /// cost of a plain slab test; the exact box decides the rest.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn push_hits<const OUTER: bool>(
        &mut self,
        p: &Placed,
        placed: usize,
        slab: &SlabRay,
        slack: f64,
        nodes: impl Iterator<Item = u32>,
        tmin: f32,
        tmax: f32,
    ) -> u64 {
        let mut tested = 0;
        for node in nodes {
            tested += 1;
            let i = node as usize;
            if OUTER {
                let (lo, hi) = p.outer[i];
                if !ray_meets_box(slab, lo, hi, tmin, tmax) {
                    continue;
                }
            }
            if let Some(entry) = p.boxes[i].entry(slab, slack, tmin, tmax) {
                self.stack.push(Pending {
                    placed,
                    node,
                    entry,
                });
            }
        }
        tested
    }
}

/// Orders pending nodes by decreasing entry, equal entries kept in the
/// order their references have: a stable insertion sort, which a node's
/// few children need and which never allocates.
fn sort_farthest_first(v: &mut [Pending]) {
    for i in 1..v.len() {
        let x = v[i];
        let mut j = i;
        while j > 0 && x.entry.total_cmp(&v[j - 1].entry) == std::cmp::Ordering::Greater {
            v[j] = v[j - 1];
            j -= 1;
        }
        v[j] = x;
    }
}

/// The closest hit of `ray` in `scene`, adding the tests it took to `stats`.
/// It makes a fresh [`TraceContext`]; to trace many rays, keep one and call
/// [`TraceContext::closest_hit`].
pub fn closest_hit(ray: &Ray, scene: &TraceScene, stats: &mut TraceStats) -> Option<Hit> {
    TraceContext::new().closest_hit(ray, scene, stats)
}

/// The closest hit by testing every triangle of every instance, in the same
/// order-independent sense as [`closest_hit`]; `prim_tests` counts them.
pub fn brute_force_closest(ray: &Ray, scene: &TraceScene, stats: &mut TraceStats) -> Option<Hit> {
    let mut best: Option<Hit> = None;
    for p in &scene.placed {
        let s = ShearedRay::new(&local_ray(ray, p));
        for prim in 0..p.inst.mesh.triangles.len() {
            stats.prim_tests += 1;
            if let Some(th) = intersect_triangle(&s, &p.inst.mesh.triangle(prim)) {
                let hit = Hit::on(&th, p.inst.hierarchy.id, prim as u32);
                if improves(&best, &hit) {
                    best = Some(hit);
                }
            }
        }
    }
    best
}

/// The most rays `hiermerge trace` and `hiermerge merge` trace
/// (`--rays`; SPEC.md section 15).
pub const MAX_RAYS: usize = 10_000_000;

/// Tries per ray the ray generators make before they give up: a valid box
/// gives a valid ray nearly every try, so the bound only ends a loop that
/// could never fill (a box whose size does not fit binary32).
const TRIES_PER_RAY: usize = 64;

/// Refuses `--rays n` above [`MAX_RAYS`] (or 0), before anything is built.
pub fn check_ray_count(n: usize) -> Result<(), String> {
    match n {
        0 => Err("--rays must be at least 1".into()),
        n if n > MAX_RAYS => Err(format!(
            "--rays {n}: expected at most {MAX_RAYS} rays (SPEC.md section 15)"
        )),
        _ => Ok(()),
    }
}

/// Refuses a box the ray generators cannot aim at: not finite, or whose
/// diagonal, times the 1.5 the generators reach out, overflows binary32
/// (an extent above about 1.3e19 per axis): every ray would be invalid.
pub fn check_ray_bounds(lo: Vec3, hi: Vec3) -> Result<(), String> {
    let reach = (hi - lo).length() * 1.5 + lo.abs().max(hi.abs()).max_element();
    if !(lo.is_finite() && hi.is_finite() && reach.is_finite()) {
        return Err(format!(
            "the scene's bounds {lo}..{hi}: expected a box whose diagonal fits binary32 \
             (rays are generated in binary32; extents below about 1e19 per axis)"
        ));
    }
    Ok(())
}

/// `n` seeded rays aimed at the box `[lo, hi]`: 70% from outside (a sphere
/// around the box) at a point inside it, 15% from inside in a random
/// direction, 15% from outside with one or two direction components exactly
/// zero (axis-parallel rays, infinite reciprocals). Fewer than `n` only
/// for a box [`check_ray_bounds`] refuses (the tries are bounded).
pub fn random_rays(lo: Vec3, hi: Vec3, n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = SplitMix64::new(seed);
    let center = (lo + hi) * 0.5;
    let radius = (hi - lo).length().max(1e-6);
    let mut rays = Vec::with_capacity(n.min(MAX_RAYS));
    let mut tries = n.saturating_mul(TRIES_PER_RAY);
    while rays.len() < n && tries > 0 {
        tries -= 1;
        let kind = rng.below(20);
        let ray = if kind < 14 {
            let origin = center + rng.unit_vector() * radius * rng.range_f32(0.6, 1.5);
            Ray::unbounded(origin, rng.point_in(lo, hi) - origin)
        } else if kind < 17 {
            Ray::unbounded(rng.point_in(lo, hi), rng.unit_vector())
        } else {
            let target = rng.point_in(lo, hi);
            let mut origin = center + rng.unit_vector() * radius;
            let keep = rng.below(3) as usize;
            let zeros = 1 + rng.below(2) as usize;
            for k in 1..=zeros {
                let a = (keep + k) % 3;
                origin[a] = target[a];
            }
            let mut dir = target - origin;
            for k in 1..=zeros {
                dir[(keep + k) % 3] = 0.0;
            }
            Ray::unbounded(origin, dir)
        };
        if ray.is_valid() {
            rays.push(ray);
        }
    }
    rays
}

/// What [`verify_rays`] found: the CLI's `hiermerge trace` prints it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TraceSummary {
    /// Rays traced.
    pub rays: u64,
    /// Rays the hierarchies hit.
    pub hits: u64,
    /// Rays whose hierarchy answer differs (in any bit) from brute force.
    pub mismatches: u64,
    /// Mean ray/box tests per ray through the hierarchies.
    pub node_tests_per_ray: f64,
    /// Mean ray/triangle tests per ray through the hierarchies.
    pub prim_tests_per_ray: f64,
    /// Most ray/box tests one ray took.
    pub max_node_tests: u64,
    /// Most ray/triangle tests one ray took.
    pub max_prim_tests: u64,
    /// Triangle tests brute force needs per ray (the scene's triangle count).
    pub brute_prim_tests_per_ray: f64,
    /// The first mismatching ray and both answers, for debugging.
    pub first_mismatch: Option<String>,
}

/// `n` seeded rays aimed at points on triangle edges and at vertices of the
/// scene (world positions, translations included), from random origins
/// around the scene: the rays where watertightness and box conservativeness
/// are put to the test (shared edges, triangles on quantization planes).
pub fn edge_rays(scene: &TraceScene, n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = SplitMix64::new(seed);
    let (lo, hi) = scene.bounds();
    let radius = (hi - lo).length().max(1e-6);
    let with_tris: Vec<&Placed> = scene
        .placed
        .iter()
        .filter(|p| !p.inst.mesh.is_empty())
        .collect();
    let mut rays = Vec::with_capacity(n.min(MAX_RAYS));
    if with_tris.is_empty() {
        return rays;
    }
    let mut tries = n.saturating_mul(TRIES_PER_RAY);
    while rays.len() < n && tries > 0 {
        tries -= 1;
        let p = with_tris[rng.below(with_tris.len() as u64) as usize];
        let tri = p
            .inst
            .mesh
            .triangle(rng.below(p.inst.mesh.len() as u64) as usize);
        let k = rng.below(3) as usize;
        // One in four aims at a vertex, the others at a point along an edge.
        let s = if rng.below(4) == 0 {
            0.0
        } else {
            rng.next_f64() as f32
        };
        let local = tri[k] + (tri[(k + 1) % 3] - tri[k]) * s;
        let target = (local.as_dvec3() + p.shift).as_vec3();
        let origin = target + rng.unit_vector() * radius * rng.range_f32(0.05, 1.5);
        let ray = Ray::unbounded(origin, target - origin);
        if ray.is_valid() {
            rays.push(ray);
        }
    }
    rays
}

/// Traces `n` seeded rays through the hierarchies and by brute force and
/// compares the answers bit for bit: [`random_rays`] aimed at the scene's
/// bounds for the first half, [`edge_rays`] for the rest.
pub fn verify_rays(scene: &TraceScene, n: usize, seed: u64) -> TraceSummary {
    verify_ray_list(scene, &verify_ray_set(scene, n, seed))
}

/// The rays [`verify_rays`] traces: `n - n/2` random rays over the scene's
/// bounds and `n/2` edge rays.
pub fn verify_ray_set(scene: &TraceScene, n: usize, seed: u64) -> Vec<Ray> {
    let (lo, hi) = scene.bounds();
    let mut rays = random_rays(lo, hi, n - n / 2, seed);
    rays.extend(edge_rays(scene, n / 2, seed ^ 0xED6E));
    rays
}

/// [`verify_rays`] over given rays.
pub fn verify_ray_list(scene: &TraceScene, rays: &[Ray]) -> TraceSummary {
    let mut total = TraceStats::default();
    let mut brute = TraceStats::default();
    let mut s = TraceSummary {
        rays: rays.len() as u64,
        hits: 0,
        mismatches: 0,
        node_tests_per_ray: 0.0,
        prim_tests_per_ray: 0.0,
        max_node_tests: 0,
        max_prim_tests: 0,
        brute_prim_tests_per_ray: 0.0,
        first_mismatch: None,
    };
    let mut ctx = TraceContext::new();
    for ray in rays {
        let mut st = TraceStats::default();
        let got = ctx.closest_hit(ray, scene, &mut st);
        let want = brute_force_closest(ray, scene, &mut brute);
        total += st;
        s.max_node_tests = s.max_node_tests.max(st.node_tests);
        s.max_prim_tests = s.max_prim_tests.max(st.prim_tests);
        s.hits += got.is_some() as u64;
        let same = match (&got, &want) {
            (Some(a), Some(b)) => a.identical(b),
            (None, None) => true,
            _ => false,
        };
        if !same {
            s.mismatches += 1;
            if s.first_mismatch.is_none() {
                s.first_mismatch =
                    Some(format!("{ray:?}: hierarchy {got:?}, brute force {want:?}"));
            }
        }
    }
    let n = rays.len().max(1) as f64;
    s.node_tests_per_ray = total.node_tests as f64 / n;
    s.prim_tests_per_ray = total.prim_tests as f64 / n;
    s.brute_prim_tests_per_ray = brute.prim_tests as f64 / n;
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::build::build;
    use crate::params::Params;
    use crate::scenes::box_mesh;
    use crate::store::Reference;

    fn setup(mesh: &Mesh, id: u8) -> (GridMap, Hierarchy) {
        let p = Params::new(8, 4, 24, 4).unwrap();
        let (lo, hi) = mesh.bounds();
        let grid = GridMap::fit(lo - Vec3::ONE, hi + Vec3::ONE, &p);
        (grid, build(mesh, &grid, &p, id).unwrap())
    }

    #[test]
    fn ties_go_to_the_smaller_primitive_then_hierarchy() {
        // Triangles 0 and 2 are the same; 1 is behind them.
        let tri = [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
        ];
        let mut m = Mesh::default();
        for z in [1.0, 2.0, 1.0] {
            crate::scenes::append(
                &mut m,
                &Mesh {
                    vertices: tri.map(|v| Vec3::new(v.x, v.y, z)).to_vec(),
                    triangles: vec![[0, 1, 2]],
                },
            );
        }
        let (grid, h) = setup(&m, 5);
        let ray = Ray::unbounded(Vec3::new(0.2, 0.2, -1.0), Vec3::Z);
        let scene = TraceScene::new(grid, &[Instance::new(&h, &m)]).unwrap();
        let mut st = TraceStats::default();
        let hit = closest_hit(&ray, &scene, &mut st).unwrap();
        assert_eq!((hit.prim, hit.hier, hit.t), (0, 5, 2.0));
        assert!(st.node_tests > 0 && st.prim_tests >= 2);
        // The same mesh as hierarchy 3 as well: 3 wins the tie.
        let mut h3 = h.clone();
        h3.id = 3;
        h3.refs.iter_mut().for_each(|r| r.hier = 3);
        let scene =
            TraceScene::new(grid, &[Instance::new(&h, &m), Instance::new(&h3, &m)]).unwrap();
        let hit = closest_hit(&ray, &scene, &mut TraceStats::default()).unwrap();
        assert_eq!((hit.prim, hit.hier), (0, 3));
        let bf = brute_force_closest(&ray, &scene, &mut TraceStats::default()).unwrap();
        assert!(bf.identical(&hit));
    }

    #[test]
    fn bad_scenes_are_refused() {
        let m = box_mesh(Vec3::ZERO, Vec3::ONE);
        let (grid, h) = setup(&m, 1);
        let mut bad = h.clone();
        bad.prims[0] = 99;
        let e = TraceScene::new(grid, &[Instance::new(&bad, &m)]).unwrap_err();
        assert!(e.field.ends_with("primitive"), "{e}");
        if let Some(i) = h.nodes.iter().position(|n| !n.leaf) {
            let mut bad = h.clone();
            bad.refs[bad.nodes[i].first as usize] = Reference { hier: 7, node: 0 };
            let e = TraceScene::new(grid, &[Instance::new(&bad, &m)]).unwrap_err();
            assert!(e.field.ends_with("reference"), "{e}");
        }
        let e = TraceScene::new(grid, &[Instance::new(&h, &m), Instance::new(&h, &m)]).unwrap_err();
        assert_eq!(e.field, "hierarchy id");
        let e = TraceScene::with_roots(grid, &[Instance::new(&h, &m)], &[4]).unwrap_err();
        assert_eq!(e.field, "root hierarchy");
    }

    /// The straightforward outward roundings the branch-free ones replace.
    fn down_by_branches(x: f64) -> f32 {
        let f = x as f32;
        if f as f64 <= x {
            f
        } else if f == 0.0 {
            -f32::from_bits(1)
        } else if f > 0.0 {
            f32::from_bits(f.to_bits() - 1)
        } else {
            f32::from_bits(f.to_bits() + 1)
        }
    }

    fn up_by_branches(x: f64) -> f32 {
        let f = x as f32;
        if f as f64 >= x {
            f
        } else if f == 0.0 {
            f32::from_bits(1)
        } else if f > 0.0 {
            f32::from_bits(f.to_bits() + 1)
        } else {
            f32::from_bits(f.to_bits() - 1)
        }
    }

    #[test]
    fn outward_f32_rounding() {
        let tiny = f32::from_bits(1) as f64;
        let mut xs = vec![
            0.1f64, -0.1, 1e-40, -1e-40, 0.0, -0.0, 3.0, 1e30, -1e39, 1e39,
        ];
        xs.extend([tiny / 2.0, -tiny / 2.0, tiny * 1.5, f32::MAX as f64 * 1.5]);
        let mut rng = SplitMix64::new(5);
        for _ in 0..20_000 {
            let e = rng.below(80) as i32 - 40;
            let x = (rng.next_f64() - 0.5) * 2f64.powi(e);
            xs.extend([x, x as f32 as f64]);
        }
        for x in xs {
            let (d, u) = (f32_down(x), f32_up(x));
            assert!((d as f64) <= x && (u as f64) >= x, "{x}");
            assert_eq!(d.to_bits(), down_by_branches(x).to_bits(), "{x}");
            assert_eq!(u.to_bits(), up_by_branches(x).to_bits(), "{x}");
        }
        assert_eq!(f32_down(-tiny / 2.0), -f32::from_bits(1));
        assert_eq!(f32_up(tiny / 2.0), f32::from_bits(1));
        assert_eq!(f32_down(3.0), 3.0);
        assert_eq!(f32_up(0.1), 0.1f32);
        assert!(f32_down(0.1) < 0.1f32);
    }

    #[test]
    fn random_rays_are_valid_and_deterministic() {
        let a = random_rays(Vec3::ZERO, Vec3::ONE, 1000, 1);
        assert_eq!(a, random_rays(Vec3::ZERO, Vec3::ONE, 1000, 1));
        assert!(a.iter().all(|r| r.is_valid()));
        assert!(a
            .iter()
            .any(|r| r.dir.x == 0.0 || r.dir.y == 0.0 || r.dir.z == 0.0));
    }
}

/// Traversal speed and cost over seeded random rays (no brute force): what
/// `hiermerge trace` and `cargo bench -p golden --bench trace`
/// report. Numbers come from here, never from tests.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TraceBench {
    /// Rays traced.
    pub rays: u64,
    /// Rays that hit something.
    pub hits: u64,
    /// Wall-clock time of the traversal, seconds.
    pub seconds: f64,
    /// `rays / seconds`.
    pub rays_per_second: f64,
    /// Mean ray/box tests per ray.
    pub node_tests_per_ray: f64,
    /// Mean ray/triangle tests per ray.
    pub prim_tests_per_ray: f64,
}

/// Traces `n` [`random_rays`] aimed at the scene's bounds and times it
/// (ray generation excluded).
pub fn bench_trace(scene: &TraceScene, n: usize, seed: u64) -> TraceBench {
    let (lo, hi) = scene.bounds();
    let rays = random_rays(lo, hi, n, seed);
    let mut stats = TraceStats::default();
    let mut hits = 0u64;
    let mut ctx = TraceContext::new();
    let start = std::time::Instant::now();
    for ray in &rays {
        hits += ctx.closest_hit(ray, scene, &mut stats).is_some() as u64;
    }
    let seconds = start.elapsed().as_secs_f64();
    let n = rays.len().max(1) as f64;
    TraceBench {
        rays: rays.len() as u64,
        hits,
        seconds,
        rays_per_second: n / seconds.max(1e-12),
        node_tests_per_ray: stats.node_tests as f64 / n,
        prim_tests_per_ray: stats.prim_tests as f64 / n,
    }
}
