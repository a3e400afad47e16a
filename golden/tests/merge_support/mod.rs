//! Shared set-up of the merge tests: meshes built in their local frame,
//! placed by translations, merged, checked and traced.
#![allow(dead_code)]

use golden::seed::seeded;
use std::collections::{BTreeMap, BTreeSet};

use glam::{DVec3, Vec3};
use golden::build::{build, GridMap};
use golden::check::{check, CheckReport};
use golden::merge::instances::{input_instances, merged_instances};
use golden::merge::{merge_into, MergeMode, MergeResult, MergedCheckView};
use golden::mesh::Mesh;
use golden::params::Params;
use golden::scenes::shared_mesh_path;
use golden::store::{Hierarchy, HierarchyStore, Reference};
use golden::trace::{brute_force_closest, closest_hit, random_rays, Hit, TraceScene, TraceStats};
use golden::translate::{Translation, TranslationTable};

pub fn load(name: &str) -> Mesh {
    Mesh::load(&shared_mesh_path(name)).unwrap_or_else(|e| panic!("{e}"))
}

/// `mesh` scaled so its largest side is `size` world units, its minimum
/// corner at `(margin, margin, margin)`.
pub fn normalized(mesh: &Mesh, size: f32, margin: f32) -> Mesh {
    let (lo, hi) = mesh.bounds();
    let s = size / (hi - lo).max_element();
    Mesh {
        vertices: mesh
            .vertices
            .iter()
            .map(|&v| (v - lo) * s + Vec3::splat(margin))
            .collect(),
        triangles: mesh.triangles.clone(),
    }
}

/// A scene: one grid (origin 0), a store, a translation table, and each
/// input's mesh in its local frame.
pub struct Scene {
    pub params: Params,
    pub grid: GridMap,
    pub store: HierarchyStore,
    pub table: TranslationTable,
    pub meshes: BTreeMap<u8, Mesh>,
    pub local: BTreeMap<u8, Vec<[DVec3; 3]>>,
}

impl Scene {
    pub fn new(params: Params, unit: f64) -> Scene {
        Scene {
            params,
            grid: GridMap {
                origin: DVec3::ZERO,
                unit,
            },
            store: HierarchyStore::new(),
            table: TranslationTable::new(params.hier_capacity() as usize, &params).unwrap(),
            meshes: BTreeMap::new(),
            local: BTreeMap::new(),
        }
    }

    /// Builds `mesh` (local frame) as hierarchy `id`, translated at its top
    /// LOD by `t` voxels of that LOD.
    pub fn add(&mut self, id: u8, mesh: Mesh, t: [i64; 3]) -> &Hierarchy {
        let h = build(&mesh, &self.grid, &self.params, id).unwrap_or_else(|e| panic!("{e}"));
        let tr = Translation { lod: h.top_lod, t };
        self.add_built(id, mesh, h, tr)
    }

    /// Adds a built hierarchy with translation `tr`.
    pub fn add_built(&mut self, id: u8, mesh: Mesh, h: Hierarchy, tr: Translation) -> &Hierarchy {
        self.table.write(id as u32, tr).unwrap();
        self.local
            .insert(id, self.grid.mesh_to_grid(&mesh, &self.params).unwrap());
        self.meshes.insert(id, mesh);
        self.store.insert(h).unwrap();
        self.store.get(id).unwrap()
    }

    /// Edge of a LOD-`l` voxel in grid units.
    pub fn edge(&self, l: u8) -> i64 {
        self.params.voxel_edge(l) as i64
    }

    pub fn top(&self, id: u8) -> u8 {
        self.store.get(id).unwrap().top_lod
    }

    pub fn merge(&mut self, inputs: &[u8], mode: MergeMode, out: u8) -> MergeResult {
        merge_into(&mut self.store, inputs, &self.table, mode, out)
            .unwrap_or_else(|e| panic!("{e}"))
    }

    /// Runs the checker on `id` (a merged hierarchy) through the inputs'
    /// translations.
    pub fn check(&self, id: u8, inputs: &[u8]) -> CheckReport {
        let local: BTreeMap<u8, &[[DVec3; 3]]> = inputs
            .iter()
            .map(|i| (*i, self.local[i].as_slice()))
            .collect();
        let view = MergedCheckView::new(&self.store, &self.table, &local).unwrap();
        check(self.store.get(id).unwrap(), &view).unwrap_or_else(|e| panic!("check {id}: {e}"))
    }

    fn meshes_of(&self, inputs: &[u8]) -> BTreeMap<u8, &Mesh> {
        inputs.iter().map(|i| (*i, &self.meshes[i])).collect()
    }

    /// Traces `n` rays aimed at the placed inputs through merged hierarchy
    /// `merged` and through the separate inputs, and every `brute_every`-th
    /// ray by brute force; asserts identical closest hits.
    pub fn compare(
        &self,
        merged: u8,
        inputs: &[u8],
        n: usize,
        seed: u64,
        brute_every: usize,
    ) -> RayReport {
        let meshes = self.meshes_of(inputs);
        let m = self.store.get(merged).unwrap();
        let mi = merged_instances(m, &self.store, &self.table, &meshes).unwrap();
        let si = input_instances(&self.store, &self.table, &meshes).unwrap();
        let ms = TraceScene::with_roots(self.grid, &mi, &[merged]).unwrap();
        let ss = TraceScene::new(self.grid, &si).unwrap();
        // Rays aimed at each placed input in turn, so that disjoint inputs
        // far apart are hit as often as overlapping ones.
        let mut rays = Vec::with_capacity(n);
        for (k, inst) in si.iter().enumerate() {
            let (lo, hi) = TraceScene::new(self.grid, &[*inst]).unwrap().bounds();
            let share = n / si.len() + (k < n % si.len()) as usize;
            rays.extend(random_rays(lo, hi, share, seeded(seed + k as u64)));
        }
        let mut r = RayReport::default();
        for (k, ray) in rays.iter().enumerate() {
            let a = closest_hit(ray, &ms, &mut r.merged);
            let b = closest_hit(ray, &ss, &mut r.separate);
            assert!(
                same(&a, &b),
                "ray {k} {ray:?}: merged {a:?} vs separate {b:?}"
            );
            if k % brute_every == 0 {
                let c = brute_force_closest(ray, &ss, &mut TraceStats::default());
                assert!(
                    same(&a, &c),
                    "ray {k} {ray:?}: merged {a:?} vs brute force {c:?}"
                );
                r.brute += 1;
            }
            r.rays += 1;
            r.hits += a.is_some() as u64;
        }
        r
    }

    /// Every leaf of every input is reached exactly once from the merged
    /// hierarchy's roots; no input node above the merging level is entered
    /// twice. Returns the leaves reached.
    pub fn leaves_once(&self, merged: u8, inputs: &[u8]) -> usize {
        let m = self.store.get(merged).unwrap();
        let mut seen: BTreeMap<Reference, u32> = BTreeMap::new();
        let mut stack: Vec<Reference> = (0..m.root_count)
            .map(|node| Reference { hier: merged, node })
            .collect();
        while let Some(r) = stack.pop() {
            *seen.entry(r).or_default() += 1;
            let h = self.store.get(r.hier).unwrap();
            let n = &h.nodes[r.node as usize];
            stack.extend_from_slice(h.children_of(n));
        }
        assert!(seen.values().all(|&c| c == 1), "a node reached twice");
        let mut leaves = 0;
        for &i in inputs {
            let h = self.store.get(i).unwrap();
            for node in reachable_leaves(h) {
                assert_eq!(
                    seen.get(&Reference { hier: i, node }),
                    Some(&1),
                    "input {i} leaf {node}"
                );
                leaves += 1;
            }
        }
        let reached_leaves = seen
            .keys()
            .filter(|r| self.store.node(**r).unwrap().leaf)
            .count();
        assert_eq!(
            reached_leaves, leaves,
            "leaves of hierarchies other than the inputs"
        );
        leaves
    }
}

/// The leaves reachable from `h`'s roots within `h`.
pub fn reachable_leaves(h: &Hierarchy) -> BTreeSet<u32> {
    let mut out = BTreeSet::new();
    let mut stack: Vec<u32> = (0..h.root_count).collect();
    while let Some(i) = stack.pop() {
        let n = &h.nodes[i as usize];
        if n.leaf {
            out.insert(i);
        } else {
            stack.extend(h.children_of(n).iter().map(|r| r.node));
        }
    }
    out
}

fn same(a: &Option<Hit>, b: &Option<Hit>) -> bool {
    match (a, b) {
        (None, None) => true,
        (Some(a), Some(b)) => a.identical(b),
        _ => false,
    }
}

/// What [`Scene::compare`] traced.
#[derive(Debug, Default)]
pub struct RayReport {
    pub rays: u64,
    pub hits: u64,
    pub brute: u64,
    pub merged: TraceStats,
    pub separate: TraceStats,
}

impl RayReport {
    pub fn print(&self, name: &str) {
        println!(
            "{name}: {} rays ({} by brute force too), {} hits, node tests/ray merged {:.1} separate {:.1}",
            self.rays,
            self.brute,
            self.hits,
            self.merged.node_tests as f64 / self.rays as f64,
            self.separate.node_tests as f64 / self.rays as f64
        );
    }
}
