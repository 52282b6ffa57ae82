//! Inference shared by training, validation, eval and render: run the model on context
//! frames, make its cameras safe to render, lift the Gaussians to world space, and render
//! any timestamp from them.

use crate::error::{Result, TrainError};
use burn::tensor::Tensor;
use envision4d_model::adapter::{gaussians_at, AdaptedGaussians, Exclusion, OpacityMapping};
use envision4d_model::model::{Heads, Predictions};
use envision4d_model::pose::pose_encoding_to_extri_intri;
use envision4d_model::Envision4d;
use envision4d_splat::Gaussians;

/// FoV channels of the 9-d pose encoding (`fov_h`, `fov_w`).
pub const FOV_CHANNELS: std::ops::Range<usize> = 7..9;
/// FoV clamp (radians): ~3° to ~172°, wider than any real camera.
pub const FOV_MIN_RAD: f64 = 0.05;
pub const FOV_MAX_RAD: f64 = 3.0;

/// A predicted scene: raw predictions (poses of all N frames, depth, ...) and the adapted
/// world-space Gaussians with their motion to every timestamp.
#[derive(Debug, Clone)]
pub struct Scene {
    pub pred: Predictions,
    pub adapted: AdaptedGaussians,
}

/// Clamps the FoV channels of pose encodings `[B, N, 9]` (the gradient passes inside).
///
/// The camera head's FoV activation is a ReLU, so an untrained or diverging head can
/// predict FoV 0 (an infinite focal length) that the renderer rightly refuses.
pub fn clamp_fov(pose: Tensor<3>) -> Tensor<3> {
    let [b, n, _] = pose.dims();
    let fov = pose
        .clone()
        .slice([0..b, 0..n, FOV_CHANNELS])
        .clamp(FOV_MIN_RAD, FOV_MAX_RAD);
    pose.slice_assign([0..b, 0..n, FOV_CHANNELS], fov)
}

/// Forward on `context [B, T_c, 3, H, W]` with every head, cameras rebuilt from the clamped
/// pose encoding, then adapted (opacity schedule at `step`).
pub fn predict_scene(model: &Envision4d, context: Tensor<5>, step: u64) -> Result<Scene> {
    let [_, _, _, h, w] = context.dims();
    let mut pred = model.forward(context, Heads::ALL);
    let pose = pred.backbone.pose_enc();
    if !pose.clone().into_data().iter::<f64>().all(f64::is_finite) {
        return Err(TrainError::NonFinite("pose encoding"));
    }
    let (extr, intr) = pose_encoding_to_extri_intri(clamp_fov(pose), h, w);
    // A finite encoding can still decode to NaN cameras (a zero quaternion): the NaN guard's
    // business, not a render error that ends the run.
    let finite = |t: &Tensor<4>| {
        t.clone()
            .is_finite()
            .bool_not()
            .any()
            .into_data()
            .iter::<bool>()
            .all(|b| !b)
    };
    if !finite(&extr) || !finite(&intr) {
        return Err(TrainError::NonFinite("camera"));
    }
    pred.backbone.extrinsics = extr;
    pred.backbone.intrinsics = intr;
    let adapted = model
        .adapt(&pred, OpacityMapping::default(), step)
        .ok_or_else(|| {
            TrainError::Model("adapt needs the depth, Gaussian and motion heads".into())
        })?;
    Ok(Scene { pred, adapted })
}

impl Scene {
    /// The same scene with every displacement zeroed (the "motion disabled" baseline and
    /// ablation: Gaussians stay where their frame put them).
    pub fn without_motion(&self) -> Scene {
        let mut s = self.clone();
        s.adapted.motions = s.adapted.motions.zeros_like();
        s
    }
}

/// The Gaussians of batch element `b` at timestamp `j` as the rasterizer takes them.
pub fn gaussians_for(a: &AdaptedGaussians, b: usize, j: usize, exclusion: Exclusion) -> Gaussians {
    let (means, quats, scales, opacities, colors) = gaussians_at(a, b, j, exclusion);
    Gaussians {
        means,
        quats,
        scales,
        opacities,
        colors,
    }
}
