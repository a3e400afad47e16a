//! Hard case of paragraph 72: two characters 3 units apart moving away from
//! the origin out to 1e9 units. In binary32 world coordinates they merge;
//! placed by a voxel-aligned translation with the residual kept in local
//! coordinates they stay exactly 3 units apart.

use golden::translate::{determine, Axis, Placement, VoxelRange};
use golden::{Params, VoxelAddr};

/// The scene: D = 31, one grid unit = one world unit, grid origin at the
/// world origin, so the scene spans 0 .. 2^31 (about 2.1e9) units.
fn scene() -> Params {
    Params::new(31, 8, 24, 4).unwrap()
}

/// Translation level: LOD 26, a voxel edge of 2^5 = 32 units.
const L: u8 = 26;
/// The characters' vertex in local coordinates (binary32, as a mesh stores it).
const LOCAL_VERTEX: f32 = 0.25;
const APART: f64 = 3.0;
const TOLERANCE: f64 = 1e-4;

/// Where the character placed at `x` puts its vertex, in exact f64 scene
/// units: `t 2^(D-L)` (an integer) plus the local vertex moved by the
/// residual, written back as binary32 local coordinates.
fn placed_vertex(x: f64, p: &Params) -> f64 {
    let ext = VoxelRange::of_nodes(&[VoxelAddr::new(L, 0, 0, 0)], L, p).unwrap();
    let d = determine(&Placement::binary64([x, 0.0, 0.0]), L, &ext, p).unwrap();
    let local = (LOCAL_VERTEX as f64 + d.residual.value_f64(Axis::X)) as f32;
    d.translation.try_grid_offset(Axis::X, p).unwrap() as f64 + local as f64
}

/// The same with the placement itself given in binary32.
fn placed_vertex_f32_placement(x: f64, p: &Params) -> f64 {
    let ext = VoxelRange::of_nodes(&[VoxelAddr::new(L, 0, 0, 0)], L, p).unwrap();
    let d = determine(&Placement::binary32([x as f32, 0.0, 0.0]), L, &ext, p).unwrap();
    let local = (LOCAL_VERTEX as f64 + d.residual.value_f64(Axis::X)) as f32;
    d.translation.try_grid_offset(Axis::X, p).unwrap() as f64 + local as f64
}

#[test]
fn two_characters_three_units_apart_stay_distinct_out_to_1e9() {
    let p = scene();
    let samples = 4000;
    let (mut world_wrong, mut world_merged, mut placed_wrong, mut f32_placement_wrong) =
        (0, 0, 0, 0);
    for i in 0..=samples {
        // Geometric sweep 1 .. 1e9 with a fractional part that is not a
        // power of two, so positions fall between grid points.
        let x = 10f64.powf(9.0 * i as f64 / samples as f64) + 0.3;
        let a = (x + LOCAL_VERTEX as f64) as f32;
        let b = (x + APART + LOCAL_VERTEX as f64) as f32;
        world_merged += (a == b) as u32;
        world_wrong += ((b as f64 - a as f64 - APART).abs() > TOLERANCE) as u32;
        let sep = placed_vertex(x + APART, &p) - placed_vertex(x, &p);
        placed_wrong += ((sep - APART).abs() > TOLERANCE) as u32;
        let sep32 = placed_vertex_f32_placement(x + APART, &p) - placed_vertex_f32_placement(x, &p);
        f32_placement_wrong += ((sep32 - APART).abs() > TOLERANCE) as u32;
    }
    println!(
        "paragraph 72, {} positions 1..1e9: binary32 world coordinates wrong separation {world_wrong} \
         (indistinguishable {world_merged}); binary32 placement + translation wrong {f32_placement_wrong}; \
         binary64 placement + translation + local residual wrong {placed_wrong}",
        samples + 1
    );
    assert_eq!(placed_wrong, 0);
    assert!(
        world_merged > 0,
        "binary32 world coordinates should merge the characters far out"
    );
    assert!(world_wrong > world_merged);
}

#[test]
fn translated_positions_are_exact_at_1e9() {
    let p = scene();
    for x in [1e3, 1e6, 1e9, 1e9 + 0.5, 2147483600.0] {
        // The vertex lands where the exact placement says, within binary32
        // rounding of a local value below 32 (2^-19 at most).
        let got = placed_vertex(x, &p);
        assert!(
            (got - (x + LOCAL_VERTEX as f64)).abs() <= 2f64.powi(-19),
            "{x}: {got}"
        );
    }
}
