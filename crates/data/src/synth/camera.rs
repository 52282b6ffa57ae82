//! The ego camera: pinhole, OpenCV axes (x right, y down, z forward), riding on the ego
//! vehicle. Rays are scaled so their parameter t is the camera z-depth of the hit.

use super::motion::Pose;
use super::shapes::Ray;
use super::world::World;
use crate::geom::{Intrinsics, Mat4, Vec3};

/// Horizontal field of view, close to Waymo's front camera (about 50 degrees).
pub const HFOV_DEG: f64 = 55.0;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub intrinsics: Intrinsics,
    pub centre: Vec3,
    pub right: Vec3,
    pub down: Vec3,
    pub forward: Vec3,
}

impl Camera {
    /// Square pixels, principal point at the image centre.
    pub fn intrinsics_for(width: usize, height: usize) -> Intrinsics {
        let f = width as f64 / (2.0 * (HFOV_DEG.to_radians() / 2.0).tan());
        Intrinsics {
            fx: f,
            fy: f,
            cx: width as f64 / 2.0,
            cy: height as f64 / 2.0,
        }
    }

    /// The camera of `world` at time `t_s` seconds.
    pub fn at(world: &World, t_s: f64, width: usize, height: usize) -> Camera {
        let Pose { position, yaw } = world.ego.lane.pose(&world.road, t_s);
        let yaw = yaw + world.ego.look.yaw(t_s);
        let p = world.ego.pitch;
        let forward = Vec3::new(yaw.cos() * p.cos(), yaw.sin() * p.cos(), -p.sin());
        let right = Vec3::new(yaw.sin(), -yaw.cos(), 0.0);
        Camera {
            intrinsics: Camera::intrinsics_for(width, height),
            centre: position + Vec3::new(0.0, 0.0, world.ego.camera_height),
            right,
            down: forward.cross(right),
            forward,
        }
    }

    /// OpenCV world-to-camera [R | -R c], rows of R = (right, down, forward).
    pub fn world_to_camera(&self) -> Mat4 {
        let r = [
            self.right.to_array(),
            self.down.to_array(),
            self.forward.to_array(),
        ];
        let t = Vec3::new(
            -self.right.dot(self.centre),
            -self.down.dot(self.centre),
            -self.forward.dot(self.centre),
        );
        Mat4::from_rt(r, t)
    }

    /// The ray through continuous pixel coordinates (x, y); its t is z-depth.
    pub fn ray(&self, x: f64, y: f64) -> Ray {
        let k = &self.intrinsics;
        let dir = self.right * ((x - k.cx) / k.fx) + self.down * ((y - k.cy) / k.fy) + self.forward;
        Ray {
            origin: self.centre,
            dir,
        }
    }
}
