//! A pinhole camera: one primary ray per pixel.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::geom::ray::Ray;

/// A pinhole camera looking from `eye` at `target`, `up` roughly up.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    /// Eye position, world units.
    pub eye: Vec3,
    /// Point the camera looks at, world units; must differ from `eye`.
    pub target: Vec3,
    /// Up direction, any length; must not be parallel to the view direction.
    pub up: Vec3,
    /// Vertical field of view in degrees, in (0, 180).
    pub fov_y_degrees: f32,
}

impl Camera {
    /// The ray through the centre of pixel `(px, py)` of a `width` x `height`
    /// image, row 0 at the top.
    pub fn primary_ray(&self, px: u32, py: u32, width: u32, height: u32) -> Ray {
        let forward = (self.target - self.eye).normalize();
        let right = forward.cross(self.up).normalize();
        let up = right.cross(forward);
        let half_h = (self.fov_y_degrees.to_radians() * 0.5).tan();
        let half_w = half_h * width as f32 / height as f32;
        let sx = ((px as f32 + 0.5) / width as f32 * 2.0 - 1.0) * half_w;
        let sy = (1.0 - (py as f32 + 0.5) / height as f32 * 2.0) * half_h;
        Ray::unbounded(self.eye, forward + right * sx + up * sy)
    }

    /// The camera is usable: finite, eye away from target, up not along the view.
    pub fn is_valid(&self) -> bool {
        let f = self.target - self.eye;
        self.eye.is_finite()
            && self.target.is_finite()
            && self.up.is_finite()
            && f.length_squared() > 0.0
            && f.cross(self.up).length_squared() > 0.0
            && self.fov_y_degrees > 0.0
            && self.fov_y_degrees < 180.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_pixel_looks_at_target() {
        let c = Camera {
            eye: Vec3::new(0.0, 0.0, -10.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_degrees: 60.0,
        };
        assert!(c.is_valid());
        let r = c.primary_ray(50, 50, 101, 101);
        assert!((r.dir.normalize() - Vec3::Z).length() < 1e-6);
        // Row 0 looks up, column 0 looks left (right = forward x up = -X here).
        let tl = c.primary_ray(0, 0, 101, 101);
        assert!(tl.dir.y > 0.0 && tl.dir.x > 0.0);
    }
}
