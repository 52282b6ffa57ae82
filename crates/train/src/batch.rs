//! Training batches: N frames per clip and, when the clips carry them, the ground-truth
//! labels (pose encodings of all N frames, z-depth of the T_c context frames).

use crate::config::LossConfig;
use crate::distill::DistillTargets;
use crate::error::{Result, TrainError};
use burn::tensor::{Device, Tensor, TensorData};
use envision4d_data::geom::{Intrinsics, Mat4};
use envision4d_data::{FrameMotionTruth, HostClip};
use envision4d_eval::motion::MotionTruth;
use envision4d_model::pose::{encode_pose, POSE_ENCODING_DIM};

#[derive(Debug, Clone)]
pub struct Batch {
    /// `[B, N, 3, H, W]` in [0, 1].
    pub images: Tensor<5>,
    /// Ground-truth labels (the backbone stage's supervision, `teacher = "ground_truth"`).
    pub labels: Option<DistillTargets>,
    /// `[B, N, 1, H, W]`: 1 on each frame's ground-truth dynamic mask, 0 elsewhere and on
    /// a frame without one (`[loss] dynamic_weight`; `None` when not asked for).
    pub dynamic: Option<Tensor<5>>,
    /// Each element's exact motion truth, on the host (`[loss] lambda_flow`).
    pub motion: Option<Vec<ClipMotion>>,
}

/// One clip's motion truth as the flow diagnostic needs it (`envision4d_eval::motion`).
#[derive(Debug, Clone)]
pub struct ClipMotion {
    pub size: (usize, usize),
    pub frames: Vec<Option<FrameMotionTruth>>,
    pub masks: Vec<Option<Vec<bool>>>,
}

impl ClipMotion {
    pub fn truth(&self) -> MotionTruth<'_> {
        MotionTruth {
            size: self.size,
            frames: &self.frames,
            masks: &self.masks,
        }
    }
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
        Ok(Batch {
            images,
            labels,
            dynamic: None,
            motion: None,
        })
    }

    /// [`Batch::from_clips`] plus the truth `loss`'s diagnostics need (`dynamic_weight`,
    /// `lambda_flow`); a clip without it is an error naming the key.
    pub fn for_training(
        clips: &[HostClip],
        context: usize,
        with_labels: bool,
        loss: &LossConfig,
        device: &Device,
    ) -> Result<Batch> {
        let mut batch = Batch::from_clips(clips, context, with_labels, device)?;
        if loss.dynamic_weight > 0.0 {
            batch.dynamic = Some(dynamic_masks(clips, device)?);
        }
        if loss.lambda_flow > 0.0 {
            batch.motion = Some(clips.iter().map(clip_motion).collect::<Result<_>>()?);
        }
        Ok(batch)
    }
}

/// `[B, N, 1, H, W]` of the clips' dynamic masks (see [`Batch::dynamic`]).
fn dynamic_masks(clips: &[HostClip], device: &Device) -> Result<Tensor<5>> {
    let (h, w, n) = (clips[0].height, clips[0].width, clips[0].frames.len());
    let mut out = Vec::with_capacity(clips.len() * n * h * w);
    for c in clips {
        if c.dynamic_masks.is_empty() {
            return Err(TrainError::Unusable(
                "loss.dynamic_weight needs clips with ground-truth dynamic masks (the synthetic layout); these have none".into(),
            ));
        }
        for t in 0..n {
            match c.dynamic_masks.get(t).and_then(Option::as_ref) {
                Some(m) => out.extend(m.iter().map(|&on| f32::from(u8::from(on)))),
                None => out.extend(std::iter::repeat_n(0.0, h * w)),
            }
        }
    }
    let data = TensorData::new(out, [clips.len(), n, 1, h, w]);
    Ok(Tensor::from_data(data, device))
}

/// The motion truth of a clip's `N` frames (see [`Batch::motion`]).
fn clip_motion(c: &HostClip) -> Result<ClipMotion> {
    let n = c.frames.len();
    if c.motion_truth.len() < n || c.motion_truth[..n].iter().any(Option::is_none) {
        return Err(TrainError::Unusable(format!(
            "loss.lambda_flow needs exact motion truth on all {n} frames of every clip (the synthetic layout's depth, instances and tracks); a clip has it on {} of them",
            c.motion_truth.iter().flatten().count()
        )));
    }
    Ok(ClipMotion {
        size: (c.height, c.width),
        frames: c.motion_truth[..n].to_vec(),
        masks: c.dynamic_masks.clone(),
    })
}
