//! The backbone stage (plain VGGT supervised on ground-truth cameras and depth) and the
//! frozen-backbone teacher of the Envision4D stage (paper §3.4 self-distillation).

use crate::batch::{Batch, TeacherTargets};
use crate::config::LossConfig;
use crate::error::{Result, TrainError};
use burn::module::Module;
use burn::tensor::Tensor;
use envision4d_losses::camera_distill_weighted;
use envision4d_model::checkpoint::{load_checkpoint, CheckpointKind};
use envision4d_model::model::VggtDepth;
use envision4d_model::{Envision4d, ModelConfig};
use std::path::Path;

/// VGGT weighs its camera loss over the refinement iterations with `γ^(K−1−k)`, so the last
/// iteration counts most but early ones still get a direct signal.
pub const CAMERA_ITERATION_GAMMA: f64 = 0.6;

/// Loss terms of a backbone-stage step (scalar `[1]` tensors on the graph).
#[derive(Debug, Clone)]
pub struct BackboneTerms {
    pub total: Tensor<1>,
    pub camera: Tensor<1>,
    pub depth: Tensor<1>,
}

/// Mean over the batch of each sample's mean |d − t| over pixels with a valid target (t > 0;
/// the synthetic sky has depth 0). Per-sample means (rather than one pool over the batch)
/// make the loss of a batch the mean of its samples' losses, so data-parallel shards add up
/// to exactly the single-device loss whatever their sky fractions.
pub fn masked_l1(pred: Tensor<5>, target: Tensor<5>) -> Tensor<1> {
    let b = pred.dims()[0];
    let mask = target.clone().greater_elem(0.0).float();
    let err = ((pred - target).abs() * mask.clone())
        .reshape([b as i32, -1])
        .sum_dim(1);
    let count = mask.reshape([b as i32, -1]).sum_dim(1).clamp_min(1.0);
    (err / count).mean().reshape([1])
}

/// Supervised VGGT loss on all N frames of `batch` (its targets must cover every frame's
/// pose and depth): γ-weighted L1 on the pose encoding of each camera-head iteration plus
/// masked L1 on depth.
pub fn backbone_loss(
    model: &Envision4d,
    batch: &Batch,
    loss: &LossConfig,
) -> Result<BackboneTerms> {
    let t = batch.teacher.as_ref().ok_or_else(|| {
        TrainError::Batch("stage \"backbone\" needs ground-truth cameras and depth".into())
    })?;
    let frames = batch.images.dims()[1];
    if t.depth.dims()[1] != frames {
        return Err(TrainError::Batch(format!(
            "stage \"backbone\" needs depth for all {frames} frames, the batch has {}",
            t.depth.dims()[1]
        )));
    }
    let out = model.vggt(batch.images.clone(), VggtDepth::Run);
    let k = out.pose_enc_iters.len();
    let weights: Vec<f64> = (0..k)
        .map(|i| CAMERA_ITERATION_GAMMA.powi((k - 1 - i) as i32))
        .collect();
    let wsum: f64 = weights.iter().sum();
    let mut camera: Option<Tensor<1>> = None;
    for (p, w) in out.pose_enc_iters.iter().zip(&weights) {
        let term = camera_distill_weighted(p.clone(), t.pose_enc.clone(), loss.rotation_weight)?
            * (w / wsum);
        camera = Some(match camera {
            None => term,
            Some(c) => c + term,
        });
    }
    let camera = camera.ok_or_else(|| TrainError::Model("camera head ran no iteration".into()))?;
    let (depth, _) = out
        .depth
        .ok_or_else(|| TrainError::Model("depth head did not run".into()))?;
    let depth = masked_l1(depth, t.depth.clone());
    if !finite(&camera) || !finite(&depth) {
        return Err(TrainError::NonFinite("backbone loss"));
    }
    Ok(BackboneTerms {
        total: camera.clone() * loss.lambda_cam + depth.clone() * loss.lambda_depth,
        camera,
        depth,
    })
}

fn finite(t: &Tensor<1>) -> bool {
    t.clone().into_data().iter::<f64>().all(f64::is_finite)
}

/// A frozen teacher: the backbone weights, never updated, run without a graph.
#[derive(Debug, Clone)]
pub struct FrozenTeacher {
    model: Envision4d,
}

impl FrozenTeacher {
    /// Loads the teacher's backbone (aggregator, camera and depth heads) from `path`.
    pub fn load(config: &ModelConfig, path: &Path, device: &burn::tensor::Device) -> Result<Self> {
        let mut model = Envision4d::new(config, device);
        load_checkpoint(&mut model, path, CheckpointKind::Vggt1bInit).map_err(|e| {
            TrainError::Input(format!("teacher_checkpoint {}: {e}", path.display()))
        })?;
        Ok(FrozenTeacher {
            model: model.no_grad(),
        })
    }

    /// Pseudo-labels from all N ground-truth frames `images [B, N, 3, H, W]`: pose encodings
    /// of every frame (future ones included) and depth of the first `context` frames.
    pub fn targets(&self, images: Tensor<5>, context: usize) -> Result<TeacherTargets> {
        let device = self.model.devices().into_iter().next().unwrap_or_default();
        let out = self
            .model
            .vggt(images.detach().to_device(&device), VggtDepth::Run);
        let pose_enc = out.pose_enc().detach();
        let (depth, _) = out
            .depth
            .ok_or_else(|| TrainError::Model("teacher depth head did not run".into()))?;
        let [b, _, h, w, c] = depth.dims();
        let depth = depth.slice([0..b, 0..context, 0..h, 0..w, 0..c]).detach();
        Ok(TeacherTargets { pose_enc, depth })
    }
}
