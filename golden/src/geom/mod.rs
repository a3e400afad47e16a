//! Geometric kernels: triangle/box overlap and clipping (used by the builder),
//! and the ray kernels (ray/box slab test, watertight ray/triangle test) used
//! by traversal.
//!
//! The builder's kernels work in binary64 and are **conservative**: they may
//! report an overlap, or a clipped box, slightly larger than the exact one,
//! but never smaller. The slack is [`ROUNDING_MARGIN_REL`] times the largest
//! coordinate magnitude of the inputs: far above the accumulated binary64
//! rounding error (a few tens of ulps), far below anything a grid could
//! resolve (2^-40 of the scene extent).

pub mod aabb;
pub mod clip;
pub(crate) mod lanes;
pub mod overlap;
pub mod ray;
pub mod triangle;

pub use aabb::{ray_box, ray_box_a, ray_box_entry, ray_meets_box, SlabRay};
pub use clip::clip_triangle_to_box;
pub use overlap::triangle_overlaps_box;
pub use ray::Ray;
pub use triangle::{
    intersect_each, intersect_triangle, intersect_triangle_in, ShearedRay, TriangleHit,
    TriangleLanes,
};

use glam::DVec3;

/// Relative slack of the conservative kernels: `2^-40`.
///
/// Every binary64 operation rounds by at most `2^-53` relative; the kernels
/// chain fewer than 64 of them per result, so the absolute error of any
/// computed quantity is below `2^-47` times the inputs' magnitude. A slack of
/// `2^-40` of the magnitude covers that with a factor of 128 to spare.
pub const ROUNDING_MARGIN_REL: f64 = 1.0 / (1u64 << 40) as f64;

/// The largest absolute coordinate among a triangle's vertices and a box's
/// corners: the scale that rounding errors are relative to.
pub(crate) fn magnitude(tri: &[DVec3; 3], lo: DVec3, hi: DVec3) -> f64 {
    let m = tri[0]
        .abs()
        .max(tri[1].abs())
        .max(tri[2].abs())
        .max(lo.abs())
        .max(hi.abs());
    m.max_element()
}

/// The smallest box holding the triangle's vertices.
pub(crate) fn triangle_bounds(tri: &[DVec3; 3]) -> (DVec3, DVec3) {
    (
        tri[0].min(tri[1]).min(tri[2]),
        tri[0].max(tri[1]).max(tri[2]),
    )
}
