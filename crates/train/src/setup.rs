//! What a [`Trainer`](crate::step::Trainer) is built from: the RGB loss (LPIPS weights or
//! none), the optimiser, whether the teacher is the initial model, and the rasterizer
//! settings of a run.

use crate::adam::FusedAdam;
use crate::config::{ClipMode, Init, TrainConfig};
use crate::error::{Result, TrainError};
use burn::grad_clipping::GradientClippingConfig;
use burn::optim::ModuleOptimizer;
use burn::tensor::{DType, Device};
use envision4d_losses::{Lpips, LpipsNet, LpipsStatus, LpipsWeights, RgbLoss};
use envision4d_splat::{BackwardBins, RasterConfig};

pub(crate) fn make_rgb_loss(config: &TrainConfig, device: &Device) -> Result<RgbLoss> {
    let path = config.loss.lpips_weights.as_deref();
    if path.is_none() && config.init == Init::Random && config.loss.lambda_lpips > 0.0 {
        // Random VGG weights: what LPIPS costs, named by `random_weights`.
        let weights = LpipsWeights::random(LpipsNet::Vgg, config.seed);
        let lpips = LpipsStatus::Available(Lpips::new(&weights, device, DType::F32));
        return Ok(
            RgbLoss::new(config.loss.lambda_lpips, &lpips)?.with_ssim(config.loss.lambda_ssim)?
        );
    }
    let lpips = LpipsStatus::from_path(path, LpipsNet::Vgg, device).map_err(|e| {
        TrainError::invalid(
            "loss.lpips_weights",
            path.map_or("(none)".into(), |p| p.display().to_string()),
            e.to_string(),
        )
    })?;
    Ok(RgbLoss::new(config.loss.lambda_lpips, &lpips)?.with_ssim(config.loss.lambda_ssim)?)
}

/// Adam (no weight decay: the paper states none, `docs/MODEL.md`) with the configured ε and,
/// for the per-tensor modes, Burn's clipping; global-norm clipping is applied by the step.
/// [`FusedAdam`]: one kernel per tensor on GPU backends, Burn's Adam on the CPU, Burn's
/// state and record either way.
pub(crate) fn make_optimizer(config: &TrainConfig) -> ModuleOptimizer {
    let o = &config.optim;
    let clip = match o.grad_clip {
        ClipMode::Norm => Some(GradientClippingConfig::Norm(o.grad_clip_threshold as f32)),
        ClipMode::Value => Some(GradientClippingConfig::Value(o.grad_clip_threshold as f32)),
        ClipMode::GlobalNorm | ClipMode::None => None,
    };
    let optim = ModuleOptimizer::from(FusedAdam::new(o.adam_epsilon as f32));
    match clip {
        Some(clip) => optim.with_grad_clipping(clip.init()),
        None => optim,
    }
}

/// Whether the frozen teacher's weights are the model's initial weights: its checkpoint is
/// the init checkpoint (the default), or both are random (`init = "random"`).
pub(crate) fn teacher_is_init(config: &TrainConfig) -> bool {
    match (&config.teacher_checkpoint, &config.init_checkpoint) {
        (None, Some(_)) => true,
        (Some(t), Some(i)) => t == i,
        (None, None) => config.init == Init::Random,
        (Some(_), None) => false,
    }
}

/// The rasterizer settings of a run: gsplat 1.5.3's, with what the GPU forward keeps for
/// its backward from `[run] recompute_raster_bins`.
pub fn raster_config(config: &TrainConfig) -> RasterConfig {
    RasterConfig {
        backward_bins: if config.run.recompute_raster_bins {
            BackwardBins::Recompute
        } else {
            BackwardBins::Keep
        },
        ..RasterConfig::default()
    }
}
