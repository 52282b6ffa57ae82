//! Training batches: N frames per clip and, when the clips carry them, the ground-truth
//! labels (pose encodings of all N frames, z-depth of the T_c context frames).

use crate::distill::DistillTargets;
use crate::error::{Result, TrainError};
use burn::tensor::{Device, Tensor, TensorData};
use envision4d_data::geom::{Intrinsics, Mat4};
use envision4d_data::HostClip;
use envision4d_model::pose::{encode_pose, POSE_ENCODING_DIM};

#[derive(Debug, Clone)]
pub struct Batch {
    /// `[B, N, 3, H, W]` in [0, 1].
    pub images: Tensor<5>,
    /// Ground-truth labels (the backbone stage's supervision, `teacher = "ground_truth"`).
    pub labels: Option<DistillTargets>,
}

/// The 9-d pose encodings of a clip's cameras, expressed relative to the first camera (the
/// model's world frame), inverse of `pose_encoding_to_extri_intri`.
pub fn pose_encodings(cams: &[(Mat4, Intrinsics)], height: usize, width: usize) -> Vec<f32> {
    let first_inv = cams[0].0.rigid_inverse();
    let mut out = Vec::with_capacity(cams.len() * POSE_ENCODING_DIM);
    for (w2c, k) in cams {
        let rel = w2c.mul(&first_inv).0;
        out.extend(encode_pose(&rel, k.fx, k.fy, height, width));
    }
    out
}

impl Batch {
    /// Stacks clips of N frames; `with_labels` adds ground-truth labels (the clips must
    /// carry cameras and depth).
    pub fn from_clips(
        clips: &[HostClip],
        context: usize,
        with_labels: bool,
        device: &Device,
    ) -> Result<Batch> {
        let first = clips
            .first()
            .ok_or_else(|| TrainError::Internal("a batch of no clips".into()))?;
        let (h, w, n) = (first.height, first.width, first.frames.len());
        let mut img = Vec::with_capacity(clips.len() * n * 3 * h * w);
        let (mut poses, mut depth) = (vec![], vec![]);
        for c in clips {
            if (c.height, c.width, c.frames.len()) != (h, w, n) {
                return Err(TrainError::Unusable(format!(
                    "clip sizes differ: {} frames of {}x{} vs {n} frames of {h}x{w}",
                    c.frames.len(),
                    c.height,
                    c.width
                )));
            }
            for f in &c.frames {
                img.extend_from_slice(f);
            }
            if with_labels {
                if c.cameras.len() != n || c.depths.len() < context {
                    return Err(TrainError::Unusable(format!(
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
        let labels = with_labels.then(|| DistillTargets {
            pose_enc: Tensor::from_data(TensorData::new(poses, [b, n, POSE_ENCODING_DIM]), device),
            depth: Tensor::from_data(TensorData::new(depth, [b, context, h, w, 1]), device),
        });
        Ok(Batch { images, labels })
    }
}
