//! Self-distillation (paper §3.4), in one place: where the labels come from (a frozen
//! VGGT teacher, the ground truth of the clip, or none), the frozen teacher itself, and the
//! two terms `L_cam` (pose encodings of all `N` frames) and `L_depth` (context depth maps)
//! from the losses crate, weighted by `λ_cam` and `λ_depth`.

use crate::batch::Batch;
use crate::config::{LossConfig, Teacher};
use crate::error::{Result, TrainError};
use burn::module::Module;
use burn::tensor::{Device, Tensor};
use envision4d_losses::{camera_distill_weighted, depth_distill};
use envision4d_model::checkpoint::{load_checkpoint, CheckpointKind};
use envision4d_model::model::{Vggt, VggtDepth};
use envision4d_model::{Envision4d, ModelConfig};
use std::path::Path;

/// What the student is pulled towards.
#[derive(Debug, Clone)]
pub struct DistillTargets {
    /// `[B, N, 9]` absT_quaR_FoV pose encodings of every frame.
    pub pose_enc: Tensor<3>,
    /// `[B, T_c, H, W, 1]` depth of the context frames (0 = no label).
    pub depth: Tensor<5>,
}

impl DistillTargets {
    pub fn to_device(self, device: &Device) -> DistillTargets {
        DistillTargets {
            pose_enc: self.pose_enc.to_device(device),
            depth: self.depth.to_device(device),
        }
    }
}

/// A frozen teacher: the backbone weights, never updated, run without a graph.
#[derive(Debug, Clone)]
pub struct FrozenTeacher {
    /// Only plain VGGT's parts: a snapshot keeps none of the other trainable heads alive
    /// once the first update has replaced the model's (docs/PERFORMANCE.md).
    model: Vggt,
}

impl FrozenTeacher {
    /// Loads the teacher's backbone (aggregator, camera and depth heads) from `path`.
    pub fn load(config: &ModelConfig, path: &Path, device: &Device) -> Result<Self> {
        let mut model = Envision4d::new(config, device);
        load_checkpoint(&mut model, path, CheckpointKind::Vggt1bInit)
            .map_err(|e| TrainError::checkpoint(path, format!("teacher_checkpoint: {e}")))?;
        Ok(FrozenTeacher {
            model: Vggt::of(&model).no_grad(),
        })
    }

    /// The teacher as `model`'s current weights, sharing its tensors (a snapshot: later
    /// updates of `model` replace its tensors and leave the teacher's alone).
    pub fn snapshot(model: &Envision4d) -> Self {
        FrozenTeacher {
            model: Vggt::of(model).no_grad(),
        }
    }

    /// Pseudo-labels from all N ground-truth frames `images [B, N, 3, H, W]`: pose encodings
    /// of every frame (future ones included) and depth of the first `context` frames.
    pub fn targets(&self, images: Tensor<5>, context: usize) -> Result<DistillTargets> {
        let device = self.model.devices().into_iter().next().unwrap_or_default();
        let out = self
            .model
            .forward(images.detach().to_device(&device), VggtDepth::Run);
        let pose_enc = out.pose_enc().detach();
        let (depth, _) = out
            .depth
            .ok_or_else(|| TrainError::Internal("teacher depth head did not run".into()))?;
        let [b, _, h, w, c] = depth.dims();
        let depth = depth.slice([0..b, 0..context, 0..h, 0..w, 0..c]).detach();
        Ok(DistillTargets { pose_enc, depth })
    }
}

/// The labels of `batch` under `source` (`None` for `teacher = "none"`), on the batch's
/// device: the batch's own ground truth, or the frozen teacher's predictions on all frames.
pub fn labels(
    source: Teacher,
    teacher: Option<&FrozenTeacher>,
    batch: &Batch,
    context: usize,
) -> Result<Option<DistillTargets>> {
    match source {
        Teacher::None => Ok(None),
        Teacher::GroundTruth => batch.labels.clone().map(Some).ok_or_else(|| {
            TrainError::Unusable(
                "teacher = \"ground_truth\" but the batch carries no targets".into(),
            )
        }),
        Teacher::Backbone => {
            let teacher = teacher.ok_or_else(|| {
                TrainError::Internal("teacher = \"backbone\" but no teacher is loaded".into())
            })?;
            let t = teacher.targets(batch.images.clone(), context)?;
            Ok(Some(t.to_device(&batch.images.device())))
        }
    }
}

/// The unweighted distillation terms (scalar `[1]` tensors on the graph).
#[derive(Debug, Clone)]
pub struct DistillLoss {
    pub camera: Tensor<1>,
    pub depth: Tensor<1>,
}

impl DistillLoss {
    /// `L_cam` on the student's pose encodings `[B, N, 9]` (quaternion entries counted
    /// `loss.rotation_weight` times) and `L_depth` on its context depth `[B, T_c, H, W, 1]`.
    pub fn new(
        pose_enc: Tensor<3>,
        depth: Tensor<5>,
        targets: &DistillTargets,
        loss: &LossConfig,
    ) -> Result<DistillLoss> {
        let camera =
            camera_distill_weighted(pose_enc, targets.pose_enc.clone(), loss.rotation_weight)?;
        let depth = depth_distill(depth, targets.depth.clone())?;
        Ok(DistillLoss { camera, depth })
    }

    /// `λ_cam·L_cam + λ_depth·L_depth` added to `total` (in that order, so the sum is the
    /// one the loss curve has always had).
    pub fn add_to(&self, total: Tensor<1>, loss: &LossConfig) -> Tensor<1> {
        total + self.camera.clone() * loss.lambda_cam + self.depth.clone() * loss.lambda_depth
    }
}
