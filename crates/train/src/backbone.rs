//! The backbone stage: plain VGGT supervised on ground-truth cameras and depth (the weights
//! the Envision4D stage starts from and distils against, paper §3.4).

use crate::batch::Batch;
use crate::config::LossConfig;
use crate::error::{Result, TrainError};
use burn::tensor::Tensor;
use envision4d_losses::{camera_distill_weighted, depth_distill};
use envision4d_model::host_read;
use envision4d_model::model::VggtDepth;
use envision4d_model::Envision4d;

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

/// Supervised VGGT loss on all N frames of `batch` (its targets must cover every frame's
/// pose and depth): γ-weighted L1 on the pose encoding of each camera-head iteration plus
/// masked L1 on depth.
pub fn backbone_loss(
    model: &Envision4d,
    batch: &Batch,
    loss: &LossConfig,
) -> Result<BackboneTerms> {
    let t = batch.labels.as_ref().ok_or_else(|| {
        TrainError::Unusable("stage \"backbone\" needs ground-truth cameras and depth".into())
    })?;
    let frames = batch.images.dims()[1];
    if t.depth.dims()[1] != frames {
        return Err(TrainError::Unusable(format!(
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
    let camera =
        camera.ok_or_else(|| TrainError::Internal("camera head ran no iteration".into()))?;
    let (depth, _) = out
        .depth
        .ok_or_else(|| TrainError::Internal("depth head did not run".into()))?;
    let depth = depth_distill(depth, t.depth.clone())?;
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
    host_read::read(t.clone()).iter::<f64>().all(f64::is_finite)
}
