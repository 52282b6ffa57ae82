//! Training batches: N frames per clip and the ground-truth teacher targets (pose
//! encodings of all N frames, z-depth of the T_c context frames).

use crate::error::{Result, TrainError};
use burn::tensor::{Device, Tensor, TensorData};
use envision4d_data::geom::{Intrinsics, Mat4};

/// One clip on the host: frames CHW in [0, 1], optional ground truth.
#[derive(Debug, Clone)]
pub struct HostClip {
    pub height: usize,
    pub width: usize,
    /// `N` frames, each `3·H·W` (CHW).
    pub frames: Vec<Vec<f32>>,
    /// Per frame: OpenCV world-to-camera and pixel intrinsics (empty when unknown).
    pub cameras: Vec<(Mat4, Intrinsics)>,
    /// Per frame `H·W` z-depth (empty when unknown).
    pub depths: Vec<Vec<f32>>,
}

/// Distillation targets.
#[derive(Debug, Clone)]
pub struct TeacherTargets {
    /// `[B, N, 9]` absT_quaR_FoV.
    pub pose_enc: Tensor<3>,
    /// `[B, T_c, H, W, 1]`.
    pub depth: Tensor<5>,
}

impl TeacherTargets {
    pub fn to_device(self, device: &Device) -> TeacherTargets {
        TeacherTargets {
            pose_enc: self.pose_enc.to_device(device),
            depth: self.depth.to_device(device),
        }
    }
}

#[derive(Debug, Clone)]
pub struct Batch {
    /// `[B, N, 3, H, W]` in [0, 1].
    pub images: Tensor<5>,
    pub teacher: Option<TeacherTargets>,
}

/// Quaternion `[x, y, z, w]` (w ≥ 0) of a rotation matrix (Shepperd's method: pick the
/// largest diagonal combination for numerical stability).
pub fn quat_xyzw(r: [[f64; 3]; 3]) -> [f64; 4] {
    let tr = r[0][0] + r[1][1] + r[2][2];
    let q = if tr > 0.0 {
        let s = (tr + 1.0).sqrt() * 2.0;
        [
            (r[2][1] - r[1][2]) / s,
            (r[0][2] - r[2][0]) / s,
            (r[1][0] - r[0][1]) / s,
            0.25 * s,
        ]
    } else if r[0][0] > r[1][1] && r[0][0] > r[2][2] {
        let s = (1.0 + r[0][0] - r[1][1] - r[2][2]).sqrt() * 2.0;
        [
            0.25 * s,
            (r[0][1] + r[1][0]) / s,
            (r[0][2] + r[2][0]) / s,
            (r[2][1] - r[1][2]) / s,
        ]
    } else if r[1][1] > r[2][2] {
        let s = (1.0 + r[1][1] - r[0][0] - r[2][2]).sqrt() * 2.0;
        [
            (r[0][1] + r[1][0]) / s,
            0.25 * s,
            (r[1][2] + r[2][1]) / s,
            (r[0][2] - r[2][0]) / s,
        ]
    } else {
        let s = (1.0 + r[2][2] - r[0][0] - r[1][1]).sqrt() * 2.0;
        [
            (r[0][2] + r[2][0]) / s,
            (r[1][2] + r[2][1]) / s,
            0.25 * s,
            (r[1][0] - r[0][1]) / s,
        ]
    };
    if q[3] < 0.0 {
        q.map(|v| -v)
    } else {
        q
    }
}

/// The 9-d pose encodings of a clip's cameras, expressed relative to the first camera (the
/// model's world frame), inverse of `pose_encoding_to_extri_intri`.
pub fn pose_encodings(cams: &[(Mat4, Intrinsics)], height: usize, width: usize) -> Vec<f32> {
    let first_inv = cams[0].0.rigid_inverse();
    let mut out = Vec::with_capacity(cams.len() * 9);
    for (w2c, k) in cams {
        let rel = w2c.mul(&first_inv).0;
        let r = [
            [rel[0][0], rel[0][1], rel[0][2]],
            [rel[1][0], rel[1][1], rel[1][2]],
            [rel[2][0], rel[2][1], rel[2][2]],
        ];
        let q = quat_xyzw(r);
        let fov_h = 2.0 * ((height as f64 / 2.0) / k.fy).atan();
        let fov_w = 2.0 * ((width as f64 / 2.0) / k.fx).atan();
        let enc = [
            rel[0][3], rel[1][3], rel[2][3], q[0], q[1], q[2], q[3], fov_h, fov_w,
        ];
        out.extend(enc.iter().map(|&v| v as f32));
    }
    out
}

impl Batch {
    /// Stacks clips of N frames; `with_teacher` adds ground-truth targets (the clips must
    /// carry cameras and depth).
    pub fn from_clips(
        clips: &[HostClip],
        context: usize,
        with_teacher: bool,
        device: &Device,
    ) -> Result<Batch> {
        let first = clips
            .first()
            .ok_or_else(|| TrainError::Batch("no clips".into()))?;
        let (h, w, n) = (first.height, first.width, first.frames.len());
        let mut img = Vec::with_capacity(clips.len() * n * 3 * h * w);
        let (mut poses, mut depth) = (vec![], vec![]);
        for c in clips {
            if (c.height, c.width, c.frames.len()) != (h, w, n) {
                return Err(TrainError::Batch(format!(
                    "clip sizes differ: {} frames of {}x{} vs {n} frames of {h}x{w}",
                    c.frames.len(),
                    c.height,
                    c.width
                )));
            }
            for f in &c.frames {
                img.extend_from_slice(f);
            }
            if with_teacher {
                if c.cameras.len() != n || c.depths.len() < context {
                    return Err(TrainError::Batch(format!(
                        "exact labels (stage \"backbone\" or teacher = \"ground_truth\") need cameras for all {n} frames and depth on the {h}x{w} frame grid for {context}; a clip has {} cameras and {} usable depth maps (depth on another grid is not usable)",
                        c.cameras.len(),
                        c.depths.len()
                    )));
                }
                poses.extend(pose_encodings(&c.cameras, h, w));
                for d in &c.depths[..context] {
                    depth.extend_from_slice(d);
                }
            }
        }
        let b = clips.len();
        let images = Tensor::from_data(TensorData::new(img, [b, n, 3, h, w]), device);
        let teacher = with_teacher.then(|| TeacherTargets {
            pose_enc: Tensor::from_data(TensorData::new(poses, [b, n, 9]), device),
            depth: Tensor::from_data(TensorData::new(depth, [b, context, h, w, 1]), device),
        });
        Ok(Batch { images, teacher })
    }
}
