//! Exact 3D scene flow between *any* two frames of a synthetic clip, on the frame grid.
//!
//! The synthetic layout stores flow to the next frame only, but the model predicts where
//! every context pixel's Gaussian is at every other timestamp (paper §3.3). Objects in the
//! synthetic world are rigid and move about the world up axis, so a pixel's displacement from
//! frame `i` to frame `j` follows exactly from its surface point at `i` (depth, camera) and
//! its object's box pose at `i` and `j` (`tracks.json`):
//! `p_j = c_j + R_z(yaw_j − yaw_i)·(p_i − c_i)`. Static scenery does not move; sky has no
//! point and no truth.

use crate::geom::{Intrinsics, Mat4, Vec3};
use crate::layout::synth::Track;

/// One object's box pose at one frame (world frame, metres, radians about world +z).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObjectPose {
    /// The object's value in the instance map (>= 1).
    pub id: u16,
    pub centre: Vec3,
    pub yaw: f64,
}

/// The poses of every tracked object at frame `t` of `tracks`.
pub fn poses_at(tracks: &[Track], t: usize) -> Vec<ObjectPose> {
    tracks
        .iter()
        .filter_map(|tr| {
            let s = tr.states.iter().find(|s| s.t == t)?;
            Some(ObjectPose {
                id: tr.id,
                centre: Vec3::new(s.position[0], s.position[1], s.position[2]),
                yaw: s.yaw,
            })
        })
        .collect()
}

/// One frame's motion truth on the frame grid (`H·W`, row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct FrameMotionTruth {
    /// Surface point of each pixel's centre ray (world frame, metres); `None` for sky.
    pub points: Vec<Option<Vec3>>,
    /// Object id of each pixel (0 = static scenery, ground or sky).
    pub instance: Vec<u16>,
    /// Every tracked object's pose at this frame.
    pub objects: Vec<ObjectPose>,
    /// OpenCV world-to-camera of this frame (the true camera).
    pub world_to_camera: Mat4,
}

impl FrameMotionTruth {
    /// Truth on a `size` (H, W) grid from a z-depth map and instance map on the source grid
    /// `(mh, mw)` with intrinsics `src`; the frame grid has intrinsics `k` (same camera
    /// centre). Each frame pixel takes its nearest source pixel's surface point: the point,
    /// its object and so its displacement stay consistent (no blend across an edge).
    #[allow(clippy::too_many_arguments)]
    pub fn from_maps(
        depth: &[f32],
        instance: &[u16],
        (mh, mw): (usize, usize),
        src: &Intrinsics,
        k: &Intrinsics,
        size: (usize, usize),
        world_to_camera: Mat4,
        objects: Vec<ObjectPose>,
    ) -> FrameMotionTruth {
        let camera_to_world = world_to_camera.rigid_inverse();
        let mut points = Vec::with_capacity(mh * mw);
        for v in 0..mh {
            for u in 0..mw {
                let d = depth[v * mw + u] as f64;
                points.push((d > 0.0 && d.is_finite()).then(|| {
                    camera_to_world.transform_point(src.unproject(
                        u as f64 + 0.5,
                        v as f64 + 0.5,
                        d,
                    ))
                }));
            }
        }
        let (points, instance) = if (mh, mw) == size {
            (points, instance.to_vec())
        } else {
            (
                crate::depth_grid::sample_nearest(&points, (mh, mw), src, k, size),
                crate::depth_grid::sample_nearest(instance, (mh, mw), src, k, size),
            )
        };
        FrameMotionTruth {
            points,
            instance,
            objects,
            world_to_camera,
        }
    }

    /// Displacement of every pixel's surface point from this frame to a frame where the
    /// objects have poses `to` (world frame, metres). `None` where there is no truth: sky,
    /// or an object without a pose at either frame.
    pub fn flow_to(&self, to: &[ObjectPose]) -> Vec<Option<Vec3>> {
        self.points
            .iter()
            .zip(&self.instance)
            .map(|(p, &id)| {
                let p = (*p)?;
                if id == 0 {
                    return Some(Vec3::ZERO);
                }
                let a = self.objects.iter().find(|o| o.id == id)?;
                let b = to.iter().find(|o| o.id == id)?;
                Some(rigid_displacement(p, a, b))
            })
            .collect()
    }
}

/// Where the object point `p` (at pose `a`) goes when its object moves to pose `b`, minus
/// `p`: a turn about world +z through the box centre, then the centre's move.
pub fn rigid_displacement(p: Vec3, a: &ObjectPose, b: &ObjectPose) -> Vec3 {
    let (s, c) = (b.yaw - a.yaw).sin_cos();
    let d = p - a.centre;
    let turned = Vec3::new(c * d.x - s * d.y, s * d.x + c * d.y, d.z);
    b.centre + turned - p
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(id: u16, x: f64, y: f64, yaw: f64) -> ObjectPose {
        ObjectPose {
            id,
            centre: Vec3::new(x, y, 0.75),
            yaw,
        }
    }

    /// Guards the rigid-motion formula: a pure translation moves every point by the centre's
    /// move, and a quarter turn in place sends (1, 0) from the centre to (0, 1).
    #[test]
    fn translation_and_quarter_turn() {
        let p = Vec3::new(3.0, 1.0, 0.5);
        let d = rigid_displacement(p, &pose(1, 2.0, 1.0, 0.3), &pose(1, 4.5, 0.0, 0.3));
        assert!((d - Vec3::new(2.5, -1.0, 0.0)).norm() < 1e-12, "{d:?}");
        let d = rigid_displacement(
            p,
            &pose(1, 2.0, 1.0, 0.0),
            &pose(1, 2.0, 1.0, std::f64::consts::FRAC_PI_2),
        );
        // p − c = (1, 0, −0.25) turns to (0, 1, −0.25): p goes to (2, 2, 0.5).
        assert!((d - Vec3::new(-1.0, 1.0, 0.0)).norm() < 1e-12, "{d:?}");
    }

    /// Guards the per-pixel bookkeeping: sky has no truth, static scenery has zero flow, an
    /// object pixel is unprojected through the camera (not taken in camera coordinates) and
    /// moved with its own object, and an object missing at the target has no truth.
    #[test]
    fn pixels_unprojected_and_moved_with_their_object() {
        let k = Intrinsics {
            fx: 2.0,
            fy: 2.0,
            cx: 1.0,
            cy: 0.5,
        };
        // Camera 10 m along world +x, axes equal to the world's: world = camera + (10, 0, 0).
        let w2c = Mat4::from_rt(
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            Vec3::new(-10.0, 0.0, 0.0),
        );
        let depth = [0.0, 4.0, 4.0];
        let instance = [0, 0, 7];
        let truth = FrameMotionTruth::from_maps(
            &depth,
            &instance,
            (1, 3),
            &k,
            &k,
            (1, 3),
            w2c,
            vec![pose(7, 12.0, 0.0, 0.0)],
        );
        // Pixel 2's centre (2.5, 0.5) at z = 4: camera (3, 0, 4), world (13, 0, 4).
        assert_eq!(truth.points[2], Some(Vec3::new(13.0, 0.0, 4.0)));
        let flow = truth.flow_to(&[pose(7, 12.0, 2.0, 0.0)]);
        assert_eq!(flow[0], None);
        assert_eq!(flow[1], Some(Vec3::ZERO));
        assert_eq!(flow[2], Some(Vec3::new(0.0, 2.0, 0.0)));
        assert_eq!(truth.flow_to(&[])[2], None);
    }
}
