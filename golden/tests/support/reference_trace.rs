//! A frozen copy of the closest-hit traversal as it was before the reusable
//! traversal context (commit c83ba75): per ray it allocates the slack,
//! slab-ray and sheared-ray vectors and the stack. The context tests and the
//! trace bench compare the current traversal with it, hit for hit, bit for
//! bit, node test for node test. Do not "improve" this file: its value is
//! that it is old. It trusts its input (the current `TraceScene::new` checks
//! the same scenes first).
#![allow(dead_code, clippy::all)]

use glam::{DVec3, Vec3};
use golden::build::GridMap;
use golden::geom::{intersect_triangle, ray_box, Ray, ShearedRay, SlabRay};
use golden::store::node_box_grid;
use golden::store::NodeRecord;
use golden::trace::{Hit, Instance, TraceStats, BOX_SLACK_REL};

struct Placed<'a> {
    inst: Instance<'a>,
    shift: DVec3,
    frame: DVec3,
    local_magnitude: f64,
    reach: Vec<usize>,
}

/// The reference's prepared scene.
pub struct RefScene<'a> {
    grid: GridMap,
    placed: Vec<Placed<'a>>,
    by_id: Vec<Option<usize>>,
    roots: Vec<u8>,
}

impl<'a> RefScene<'a> {
    pub fn new(grid: GridMap, instances: &[Instance<'a>]) -> RefScene<'a> {
        let ids: Vec<u8> = instances.iter().map(|i| i.hierarchy.id).collect();
        RefScene::with_roots(grid, instances, &ids)
    }

    pub fn with_roots(grid: GridMap, instances: &[Instance<'a>], roots: &[u8]) -> RefScene<'a> {
        let mut by_id = vec![None; 256];
        let mut placed = Vec::with_capacity(instances.len());
        for (k, inst) in instances.iter().enumerate() {
            by_id[inst.hierarchy.id as usize] = Some(k);
            let shift = DVec3::new(
                inst.offset[0] as f64,
                inst.offset[1] as f64,
                inst.offset[2] as f64,
            ) * grid.unit;
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
            });
        }
        let mut scene = RefScene {
            grid,
            placed,
            by_id,
            roots: roots.to_vec(),
        };
        for k in 0..scene.placed.len() {
            scene.placed[k].reach = scene.reachable_with_triangles(k);
        }
        scene
    }

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

    fn frame_box(&self, p: &Placed, n: &NodeRecord, slack: f64) -> (Vec3, Vec3) {
        let (lo, hi) = node_box_grid(n, &p.inst.hierarchy.params);
        let off = p.inst.offset;
        let to_world =
            |g: f64, axis: usize| self.grid.origin[axis] + (g + off[axis] as f64) * self.grid.unit;
        let mut flo = Vec3::ZERO;
        let mut fhi = Vec3::ZERO;
        for axis in 0..3 {
            let f = p.frame[axis];
            let a = to_world(lo[axis], axis);
            let b = to_world(hi[axis], axis);
            flo[axis] = f32_down(a - f - slack - (a.abs() + f.abs()) * F64_GUARD);
            fhi[axis] = f32_up(b - f + slack + (b.abs() + f.abs()) * F64_GUARD);
        }
        (flo, fhi)
    }

    fn slacks(&self, ray: &Ray) -> Vec<f64> {
        let own: Vec<f64> = self
            .placed
            .iter()
            .map(|p| {
                let o = local_ray(ray, p).origin.abs().max_element() as f64;
                BOX_SLACK_REL * (o + p.local_magnitude)
            })
            .collect();
        self.placed
            .iter()
            .map(|p| {
                let reach = p.reach.iter().map(|&j| own[j]).fold(0.0, f64::max);
                if p.inst.mesh.is_empty() {
                    let o = frame_ray(ray, p).origin.abs().max_element() as f64;
                    reach + BOX_SLACK_REL * o
                } else {
                    reach
                }
            })
            .collect()
    }
}

const F64_GUARD: f64 = 1.0 / (1u64 << 50) as f64;

fn f32_down(x: f64) -> f32 {
    let f = x as f32;
    if f as f64 > x {
        next_toward_neg_inf(f)
    } else {
        f
    }
}

fn f32_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x {
        -next_toward_neg_inf(-f)
    } else {
        f
    }
}

fn next_toward_neg_inf(f: f32) -> f32 {
    if f == 0.0 {
        return -f32::from_bits(1);
    }
    let b = f.to_bits();
    f32::from_bits(if f > 0.0 { b - 1 } else { b + 1 })
}

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

fn frame_ray(ray: &Ray, p: &Placed) -> Ray {
    if p.frame == DVec3::ZERO {
        return *ray;
    }
    Ray {
        origin: (ray.origin.as_dvec3() - p.frame).as_vec3(),
        ..*ray
    }
}

fn local_ray(ray: &Ray, p: &Placed) -> Ray {
    if p.shift == DVec3::ZERO {
        return *ray;
    }
    Ray {
        origin: (ray.origin.as_dvec3() - p.shift).as_vec3(),
        ..*ray
    }
}

fn improves(best: &Option<Hit>, hit: &Hit) -> bool {
    match best {
        None => true,
        Some(b) => (hit.t, hit.hier, hit.prim) < (b.t, b.hier, b.prim),
    }
}

#[derive(Clone, Copy)]
struct Pending {
    placed: usize,
    node: u32,
    entry: f32,
}

/// The closest hit of `ray`, as the traversal before the context found it.
pub fn closest_hit(ray: &Ray, scene: &RefScene, stats: &mut TraceStats) -> Option<Hit> {
    let slacks = scene.slacks(ray);
    let mut slabs: Vec<Option<SlabRay>> = vec![None; scene.placed.len()];
    let mut sheared: Vec<Option<ShearedRay>> = vec![None; scene.placed.len()];
    let mut best: Option<Hit> = None;
    let mut stack: Vec<Pending> = Vec::with_capacity(64);
    let mut children: Vec<Pending> = Vec::with_capacity(8);

    let mut visit = |placed: usize,
                     nodes: &mut dyn Iterator<Item = u32>,
                     best_t: f32,
                     stack: &mut Vec<Pending>,
                     children: &mut Vec<Pending>,
                     stats: &mut TraceStats| {
        let p = &scene.placed[placed];
        let slab = *slabs[placed].get_or_insert_with(|| SlabRay::new(&frame_ray(ray, p)));
        children.clear();
        for node in nodes {
            let n = &p.inst.hierarchy.nodes[node as usize];
            stats.node_tests += 1;
            let (lo, hi) = scene.frame_box(p, n, slacks[placed]);
            if let Some((entry, _)) = ray_box(&slab, lo, hi, ray.tmin, best_t) {
                children.push(Pending {
                    placed,
                    node,
                    entry,
                });
            }
        }
        children.sort_by(|a, b| b.entry.total_cmp(&a.entry));
        stack.extend_from_slice(children);
    };

    for &id in scene.roots.iter().rev() {
        let k = scene.by_id[id as usize].expect("a root of the scene");
        let roots = scene.placed[k].inst.hierarchy.root_count;
        visit(
            k,
            &mut (0..roots),
            ray.tmax,
            &mut stack,
            &mut children,
            stats,
        );
    }
    while let Some(top) = stack.pop() {
        let best_t = best.map_or(ray.tmax, |h| h.t);
        if top.entry > best_t {
            continue;
        }
        let p = &scene.placed[top.placed];
        let h = p.inst.hierarchy;
        let n = &h.nodes[top.node as usize];
        if n.leaf {
            let s = sheared[top.placed].get_or_insert_with(|| ShearedRay::new(&local_ray(ray, p)));
            for &prim in h.prims_of(n) {
                stats.prim_tests += 1;
                let best_t = best.map_or(ray.tmax, |h| h.t);
                let tri = p.inst.mesh.triangle(prim as usize);
                if let Some(th) = intersect_triangle(&s.with_range(ray.tmin, best_t), &tri) {
                    let hit = Hit {
                        t: th.t,
                        u: th.u,
                        v: th.v,
                        w: th.w,
                        hier: h.id,
                        prim,
                    };
                    if improves(&best, &hit) {
                        best = Some(hit);
                    }
                }
            }
        } else {
            let refs = h.children_of(n);
            let mut i = 0;
            while i < refs.len() {
                let hier = refs[i].hier;
                let j = refs[i..]
                    .iter()
                    .position(|r| r.hier != hier)
                    .map_or(refs.len(), |d| i + d);
                let k = scene.by_id[hier as usize].expect("a reference into the scene");
                let mut nodes = refs[i..j].iter().map(|r| r.node);
                let best_t = best.map_or(ray.tmax, |h| h.t);
                visit(k, &mut nodes, best_t, &mut stack, &mut children, stats);
                i = j;
            }
        }
    }
    best
}
