//! A pinhole perspective camera and its primary rays.
use crate::intersect::{Ray, MAX_COORDINATE};
use crate::vector::unit;
use glam::{Vec2, Vec3A};

/// Where the camera is and what it sees. `width`/`height` are the scene's preferred
/// resolution (from the glTF camera's aspect ratio, else 512×512); the render settings
/// decide the actual resolution, and the field of view stays vertical.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3A,
    pub target: Vec3A,
    pub up: Vec3A,
    /// Vertical field of view in degrees.
    pub vfov_deg: f32,
    pub width: u32,
    pub height: u32,
}

impl Default for Camera {
    fn default() -> Self {
        Camera { eye: Vec3A::new(0.0, 0.0, 5.0), target: Vec3A::ZERO, up: Vec3A::Y, vfov_deg: 45.0, width: 512, height: 512 }
    }
}

impl Camera {
    /// Checks that the camera defines a usable view (finite, non-degenerate).
    pub fn validate(&self) -> Result<(), String> {
        let fwd = self.target - self.eye;
        if !(self.eye.is_finite() && self.target.is_finite() && self.up.is_finite()) {
            return Err("camera position, target or up vector is not finite".into());
        }
        let far = MAX_COORDINATE;
        if self.eye.abs().max_element() > far || self.target.abs().max_element() > far {
            return Err(format!("camera position or target is farther than {far:e} from the origin"));
        }
        if fwd.length_squared() <= 0.0 {
            return Err("camera eye and target coincide".into());
        }
        if unit(fwd).cross(self.up).length_squared() < 1e-12 {
            return Err("camera up vector is parallel to the viewing direction".into());
        }
        if !(self.vfov_deg > 0.0 && self.vfov_deg < 180.0) {
            return Err(format!("vertical field of view {} degrees is outside (0, 180)", self.vfov_deg));
        }
        // Narrower, and a ray's offset from the viewing direction vanishes next to it in f32:
        // every pixel would see the same point.
        if (self.vfov_deg.to_radians() * 0.5).tan() <= f32::EPSILON {
            let min = (2.0 * f32::EPSILON.atan()).to_degrees();
            return Err(format!(
                "vertical field of view {} degrees is too narrow: below {min:.2e} degrees every camera ray points the same way",
                self.vfov_deg
            ));
        }
        Ok(())
    }

    /// The ray generator for an image of `width`×`height` pixels.
    pub fn frame(&self, width: u32, height: u32) -> CameraFrame {
        let forward = unit(self.target - self.eye);
        let right = unit(forward.cross(self.up));
        let up = right.cross(forward);
        let tan_half = (self.vfov_deg.to_radians() * 0.5).tan();
        let aspect = width as f32 / height as f32;
        CameraFrame {
            eye: self.eye,
            forward,
            right: right * (tan_half * aspect),
            up: up * tan_half,
            inv_size: Vec2::new(1.0 / width as f32, 1.0 / height as f32),
        }
    }
}

/// Precomputed camera basis, scaled so that NDC maps directly to directions.
#[derive(Clone, Copy, Debug)]
pub struct CameraFrame {
    eye: Vec3A,
    forward: Vec3A,
    right: Vec3A,
    up: Vec3A,
    inv_size: Vec2,
}

impl CameraFrame {
    /// The primary ray through pixel `(x, y)` (top row first) at sub-pixel offset `jitter ∈ [0,1)²`.
    /// The direction is normalised, so a hit's `t` is its distance from the camera.
    #[inline]
    pub fn ray(&self, x: u32, y: u32, jitter: Vec2) -> Ray {
        let sx = (x as f32 + jitter.x) * self.inv_size.x * 2.0 - 1.0;
        let sy = 1.0 - (y as f32 + jitter.y) * self.inv_size.y * 2.0;
        let dir = unit(self.forward + self.right * sx + self.up * sy);
        Ray { origin: self.eye, dir, tmin: 0.0, tmax: f32::INFINITY }
    }
}

/// A camera looking at the bounds' centre from +Z (glTF's "front"), framing the bounding sphere.
pub fn default_camera(lo: Vec3A, hi: Vec3A) -> Camera {
    let centre = (lo + hi) * 0.5;
    let radius = ((hi - lo).length() * 0.5).max(1e-3);
    let vfov: f32 = 45.0;
    let dist = radius / (vfov.to_radians() * 0.5).sin() * 1.05;
    Camera { eye: centre + Vec3A::Z * dist, target: centre, up: Vec3A::Y, vfov_deg: vfov, width: 512, height: 512 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_ray_looks_at_target_and_corners_span_the_fov() {
        let cam = Camera { eye: Vec3A::new(1.0, 2.0, 3.0), target: Vec3A::new(1.0, 2.0, -7.0), vfov_deg: 60.0, ..Default::default() };
        let f = cam.frame(200, 100);
        let c = f.ray(100, 50, Vec2::ZERO);
        assert!((c.dir - Vec3A::NEG_Z).length() < 1e-6);
        let top = f.ray(100, 0, Vec2::ZERO);
        let angle = top.dir.angle_between(Vec3A::NEG_Z).to_degrees();
        assert!((angle - 30.0).abs() < 1e-3, "{angle}");
        assert!(top.dir.y > 0.0, "top row must look up");
        let right = f.ray(199, 50, Vec2::new(1.0, 0.0));
        // Horizontal half-extent is aspect * tan(vfov/2).
        assert!((right.dir.x / -right.dir.z - 2.0 * (30f32).to_radians().tan()).abs() < 1e-4);
    }

    #[test]
    fn degenerate_cameras_are_rejected() {
        assert!(Camera::default().validate().is_ok());
        assert!(Camera { target: Camera::default().eye, ..Default::default() }.validate().is_err());
        assert!(Camera { up: Vec3A::Z, ..Default::default() }.validate().is_err());
        assert!(Camera { vfov_deg: 0.0, ..Default::default() }.validate().is_err());
        // So narrow that every ray is the viewing direction in f32 (1e-30 degrees, a denormal).
        for vfov in [1e-30, 1e-45, 1e-5] {
            let e = Camera { vfov_deg: vfov, ..Default::default() }.validate().unwrap_err();
            assert!(e.contains("too narrow"), "{e}");
        }
        assert!(Camera { vfov_deg: 1e-4, ..Default::default() }.validate().is_ok());
    }
}
