//! Deterministic procedural scenes for tests, benchmarks and images.
//!
//! Every generator is a pure function of its arguments: the same seed gives
//! the same mesh, bit for bit, on every platform (integer PRNG, IEEE
//! arithmetic, no platform math functions other than `sin`/`cos` in the
//! smooth shapes, which only feed vertex positions).

use glam::Vec3;
use std::f32::consts::TAU;
use std::path::PathBuf;

use crate::mesh::Mesh;

/// One step of SplitMix64 (Steele, Lea, Flood 2014): the one definition of
/// the generator behind every seeded stream in the project (scenes, vectors,
/// cosim stall patterns), so a seed means the same numbers everywhere.
pub fn splitmix64_next(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A SplitMix64 stream stepped by [`splitmix64_next`]; its seed fixes every number it gives.
#[derive(Clone, Debug)]
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    /// A stream whose state starts at `seed`.
    pub fn new(seed: u64) -> SplitMix64 {
        SplitMix64 { state: seed }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        splitmix64_next(&mut self.state)
    }

    /// Uniform in `[0, 1)` with 53 random bits.
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in `[lo, hi)` (as f32).
    pub fn range_f32(&mut self, lo: f32, hi: f32) -> f32 {
        (lo as f64 + (hi as f64 - lo as f64) * self.next_f64()) as f32
    }

    /// Uniform integer in `0..n` (`n > 0`), by multiply-shift.
    pub fn below(&mut self, n: u64) -> u64 {
        ((self.next_u64() as u128 * n as u128) >> 64) as u64
    }

    /// A point uniform in the box `[lo, hi)`.
    pub fn point_in(&mut self, lo: Vec3, hi: Vec3) -> Vec3 {
        Vec3::new(
            self.range_f32(lo.x, hi.x),
            self.range_f32(lo.y, hi.y),
            self.range_f32(lo.z, hi.z),
        )
    }

    /// A direction uniform on the unit sphere (rejection sampling).
    pub fn unit_vector(&mut self) -> Vec3 {
        loop {
            let v = self.point_in(Vec3::splat(-1.0), Vec3::splat(1.0));
            let l2 = v.length_squared();
            if l2 > 1e-4 && l2 <= 1.0 {
                return v / l2.sqrt();
            }
        }
    }
}

/// Path of a mesh in the shared scenes folder beside the repository
/// (`../shared/scenes/NAME` from the repository root).
pub fn shared_mesh_path(name: &str) -> PathBuf {
    let crate_dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let crate_dir = crate_dir.canonicalize().unwrap_or(crate_dir);
    crate_dir.join("../../shared/scenes").join(name)
}

/// Appends a free-standing triangle (three new vertices).
pub(crate) fn push_triangle(m: &mut Mesh, a: Vec3, b: Vec3, c: Vec3) {
    let i = m.vertices.len() as u32;
    m.vertices.extend([a, b, c]);
    m.triangles.push([i, i + 1, i + 2]);
}

/// `n` random triangles in the unit cube, each inside a cube of edge
/// `size` at a random place.
pub fn random_soup(n: usize, size: f32, seed: u64) -> Mesh {
    let mut rng = SplitMix64::new(seed);
    let mut m = Mesh::default();
    let size = size.clamp(0.0, 1.0);
    for _ in 0..n {
        let corner = rng.point_in(Vec3::ZERO, Vec3::splat(1.0 - size));
        let hi = corner + Vec3::splat(size);
        let [a, b, c] = [0; 3].map(|_| rng.point_in(corner, hi));
        push_triangle(&mut m, a, b, c);
    }
    m
}

/// `n` long thin triangles crossing the unit cube in random (off-axis)
/// directions: length 0.3..1, width `1e-5..1e-2` of the length.
pub fn slivers(n: usize, seed: u64) -> Mesh {
    let mut rng = SplitMix64::new(seed);
    let mut m = Mesh::default();
    for _ in 0..n {
        let mid = rng.point_in(Vec3::splat(0.3), Vec3::splat(0.7));
        let dir = rng.unit_vector();
        let half = rng.range_f32(0.15, 0.5);
        let a = (mid - dir * half).clamp(Vec3::ZERO, Vec3::ONE);
        let b = (mid + dir * half).clamp(Vec3::ZERO, Vec3::ONE);
        let side = dir.any_orthonormal_vector();
        let width = half * 10f32.powf(rng.range_f32(-5.0, -2.0));
        let c = (mid + side * width).clamp(Vec3::ZERO, Vec3::ONE);
        push_triangle(&mut m, a, b, c);
    }
    m
}

/// `n` right triangles lying in axis planes at multiples of 1/16 (so on
/// voxel and quantization boundaries), legs along the axes, many sharing
/// edges and planes.
pub fn axis_aligned(n: usize, seed: u64) -> Mesh {
    let mut rng = SplitMix64::new(seed);
    let mut m = Mesh::default();
    let grid = |rng: &mut SplitMix64| rng.below(17) as f32 / 16.0;
    for _ in 0..n {
        let axis = rng.below(3) as usize;
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let mut p = Vec3::ZERO;
        p[axis] = grid(&mut rng);
        p[u] = grid(&mut rng);
        p[v] = grid(&mut rng);
        let lu = (rng.below(8) + 1) as f32 / 16.0 * if p[u] > 0.5 { -1.0 } else { 1.0 };
        let lv = (rng.below(8) + 1) as f32 / 16.0 * if p[v] > 0.5 { -1.0 } else { 1.0 };
        let mut b = p;
        b[u] += lu;
        let mut c = p;
        c[v] += lv;
        push_triangle(&mut m, p, b, c);
    }
    m
}

/// A mix for traversal tests: slivers, axis-aligned triangles, a random soup,
/// and a closed box whose faces share edges (a watertight surface).
pub fn hard_cases(n_each: usize, seed: u64) -> Mesh {
    let mut m = slivers(n_each, seed);
    append(&mut m, &axis_aligned(n_each, seed ^ 0x5151));
    append(&mut m, &random_soup(n_each, 0.2, seed ^ 0xA0A0));
    append(&mut m, &box_mesh(Vec3::splat(0.25), Vec3::splat(0.75)));
    m
}

/// Appends `other`'s triangles to `m`, renumbering its vertices.
pub fn append(m: &mut Mesh, other: &Mesh) {
    let base = m.vertices.len() as u32;
    m.vertices.extend_from_slice(&other.vertices);
    m.triangles
        .extend(other.triangles.iter().map(|t| t.map(|i| i + base)));
}

/// A noisy height field over `[0, 1]^2` (in x, z; height in y), `cells` by
/// `cells` quads split in two: `2 cells^2` triangles sharing edges. 708
/// cells give just over a million triangles.
pub fn terrain(cells: u32, seed: u64) -> Mesh {
    let mut rng = SplitMix64::new(seed);
    let n = cells as usize + 1;
    let mut m = Mesh::default();
    m.vertices.reserve(n * n);
    // A few random sine waves plus per-vertex noise: smooth hills, rough ground.
    let waves: Vec<(f32, f32, f32, f32)> = (0..4)
        .map(|_| {
            (
                rng.range_f32(1.0, 6.0),
                rng.range_f32(1.0, 6.0),
                rng.range_f32(0.0, TAU),
                rng.range_f32(0.02, 0.08),
            )
        })
        .collect();
    for j in 0..n {
        for i in 0..n {
            let x = i as f32 / cells as f32;
            let z = j as f32 / cells as f32;
            let mut y = 0.5;
            for &(fx, fz, ph, amp) in &waves {
                y += amp * (fx * x * TAU + fz * z * TAU + ph).sin();
            }
            y += rng.range_f32(-0.25, 0.25) / cells as f32;
            m.vertices.push(Vec3::new(x, y, z));
        }
    }
    m.triangles.reserve(2 * (n - 1) * (n - 1));
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let a = (j * n + i) as u32;
            let b = a + 1;
            let c = a + n as u32;
            let d = c + 1;
            m.triangles.push([a, b, d]);
            m.triangles.push([a, d, c]);
        }
    }
    m
}

/// A UV sphere: `stacks` >= 2 rings, `slices` >= 3 segments.
pub fn sphere(center: Vec3, radius: f32, stacks: u32, slices: u32) -> Mesh {
    let (stacks, slices) = (stacks.max(2), slices.max(3));
    let mut m = Mesh::default();
    let pi = std::f32::consts::PI;
    m.vertices.push(center + Vec3::Y * radius);
    for s in 1..stacks {
        let phi = pi * s as f32 / stacks as f32;
        for k in 0..slices {
            let th = 2.0 * pi * k as f32 / slices as f32;
            let d = Vec3::new(phi.sin() * th.cos(), phi.cos(), phi.sin() * th.sin());
            m.vertices.push(center + d * radius);
        }
    }
    m.vertices.push(center - Vec3::Y * radius);
    let ring = |s: u32, k: u32| 1 + (s - 1) * slices + k % slices;
    let south = m.vertices.len() as u32 - 1;
    for k in 0..slices {
        m.triangles.push([0, ring(1, k + 1), ring(1, k)]);
        m.triangles
            .push([south, ring(stacks - 1, k), ring(stacks - 1, k + 1)]);
    }
    for s in 1..stacks - 1 {
        for k in 0..slices {
            let (a, b) = (ring(s, k), ring(s, k + 1));
            let (c, d) = (ring(s + 1, k), ring(s + 1, k + 1));
            m.triangles.push([a, b, d]);
            m.triangles.push([a, d, c]);
        }
    }
    m
}

/// A torus around the y axis: `major` ring radius, `minor` tube radius.
pub fn torus(center: Vec3, major: f32, minor: f32, rings: u32, sides: u32) -> Mesh {
    let (rings, sides) = (rings.max(3), sides.max(3));
    let mut m = Mesh::default();
    let tau = 2.0 * std::f32::consts::PI;
    for r in 0..rings {
        let a = tau * r as f32 / rings as f32;
        for s in 0..sides {
            let b = tau * s as f32 / sides as f32;
            let rad = major + minor * b.cos();
            m.vertices
                .push(center + Vec3::new(rad * a.cos(), minor * b.sin(), rad * a.sin()));
        }
    }
    let at = |r: u32, s: u32| (r % rings) * sides + s % sides;
    for r in 0..rings {
        for s in 0..sides {
            let (a, b, c, d) = (at(r, s), at(r + 1, s), at(r, s + 1), at(r + 1, s + 1));
            m.triangles.push([a, b, d]);
            m.triangles.push([a, d, c]);
        }
    }
    m
}

/// The closed surface of the box `[lo, hi]`: 8 vertices, 12 triangles.
pub fn box_mesh(lo: Vec3, hi: Vec3) -> Mesh {
    let corner = |i: u32| {
        Vec3::new(
            if i & 1 != 0 { hi.x } else { lo.x },
            if i & 2 != 0 { hi.y } else { lo.y },
            if i & 4 != 0 { hi.z } else { lo.z },
        )
    };
    let vertices = (0..8).map(corner).collect();
    // Each face as a quad of corner indices, split along one diagonal.
    let quads = [
        [0, 2, 6, 4],
        [1, 5, 7, 3],
        [0, 4, 5, 1],
        [2, 3, 7, 6],
        [0, 1, 3, 2],
        [4, 6, 7, 5],
    ];
    let triangles = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    Mesh {
        vertices,
        triangles,
    }
}

/// A generated building: `storeys` floors, each a slab with long thin walls
/// on the boundaries of a `rooms` by `rooms` grid of 4-unit rooms, a column
/// at every wall crossing and a straight stair to the next storey (storeys
/// 3 units high). The large flat triangles of slabs and the long thin ones
/// of walls are what real architectural scenes are made of and what a
/// sparse octree handles worst (issue 19: merging must pay on them too).
pub fn architecture(storeys: u32, rooms: u32) -> Mesh {
    let (room, storey, wall, slab) = (4.0f32, 3.0f32, 0.1f32, 0.2f32);
    let side = room * rooms as f32;
    let mut m = Mesh::default();
    for s in 0..storeys {
        let y = s as f32 * storey;
        append(
            &mut m,
            &box_mesh(Vec3::new(0.0, y, 0.0), Vec3::new(side, y + slab, side)),
        );
        for k in 0..=rooms {
            let c = (k as f32 * room).clamp(wall, side - wall);
            let (lo, hi) = (y + slab, y + storey);
            append(
                &mut m,
                &box_mesh(Vec3::new(0.0, lo, c - wall), Vec3::new(side, hi, c)),
            );
            append(
                &mut m,
                &box_mesh(Vec3::new(c - wall, lo, 0.0), Vec3::new(c, hi, side)),
            );
            let cx = (k as f32 * room).clamp(0.3, side - 0.3);
            for j in 0..=rooms {
                let cz = (j as f32 * room).clamp(0.3, side - 0.3);
                append(
                    &mut m,
                    &box_mesh(
                        Vec3::new(cx - 0.3, lo, cz - 0.3),
                        Vec3::new(cx + 0.3, hi, cz + 0.3),
                    ),
                );
            }
        }
        if s + 1 < storeys {
            let steps = 10;
            for i in 0..steps {
                let t = i as f32 / steps as f32;
                let x = 0.5 + t * (room - 1.0);
                append(
                    &mut m,
                    &box_mesh(
                        Vec3::new(x, y + slab + t * storey, 0.5),
                        Vec3::new(x + 0.3, y + slab + (t + 0.1) * storey, 1.5),
                    ),
                );
            }
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generators_are_deterministic_and_valid() {
        type Maker = Box<dyn Fn(u64) -> Mesh>;
        let makers: Vec<(&str, Maker)> = vec![
            ("soup", Box::new(|s| random_soup(200, 0.1, s))),
            ("slivers", Box::new(|s| slivers(200, s))),
            ("axis", Box::new(|s| axis_aligned(200, s))),
            ("hard", Box::new(|s| hard_cases(50, s))),
            ("terrain", Box::new(|s| terrain(20, s))),
        ];
        for (name, make) in makers {
            let a = make(7);
            assert_eq!(a, make(7), "{name} not deterministic");
            assert_ne!(a, make(8), "{name} ignores its seed");
            a.validate(name).unwrap();
            let (lo, hi) = a.bounds();
            assert!(
                lo.cmpge(Vec3::ZERO).all() && hi.cmple(Vec3::ONE).all(),
                "{name}: {lo} {hi}"
            );
        }
    }

    #[test]
    fn shape_counts() {
        assert_eq!(terrain(708, 1).triangles.len(), 2 * 708 * 708);
        let s = sphere(Vec3::ZERO, 1.0, 8, 12);
        assert_eq!(s.triangles.len(), 2 * 12 * (8 - 1));
        assert_eq!(s.vertices.len(), 2 + 12 * 7);
        s.validate("sphere").unwrap();
        let t = torus(Vec3::ZERO, 2.0, 0.5, 10, 6);
        assert_eq!(t.triangles.len(), 120);
        t.validate("torus").unwrap();
        assert_eq!(box_mesh(Vec3::ZERO, Vec3::ONE).triangles.len(), 12);
    }

    #[test]
    fn closed_shapes_have_every_edge_twice() {
        use std::collections::HashMap;
        for m in [
            sphere(Vec3::ZERO, 1.0, 6, 9),
            torus(Vec3::ZERO, 2.0, 0.5, 7, 5),
            box_mesh(Vec3::ZERO, Vec3::ONE),
        ] {
            let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
            for t in &m.triangles {
                for k in 0..3 {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    // Consistent orientation: each directed edge once, reversed once.
                    *edges.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
                }
            }
            assert!(
                edges.values().all(|&c| c == 0),
                "open or inconsistently oriented"
            );
        }
    }

    #[test]
    fn splitmix_known_values() {
        // Reference output of splitmix64 seeded with 0 (Vigna's splitmix64.c).
        let mut r = SplitMix64::new(0);
        assert_eq!(r.next_u64(), 0xE220A8397B1DCDAF);
        assert_eq!(r.next_u64(), 0x6E789E6AA1B965F4);
    }
}
