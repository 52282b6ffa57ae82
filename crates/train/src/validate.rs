//! Periodic validation on held-out clips during training: the quality of what the stage
//! trains, on clips never stepped on, with the model in inference mode (no graph). Views
//! are scored with the evaluation crate's PSNR, so the log's numbers are `eval`'s.

use crate::batch::Batch;
use crate::config::Stage;
use crate::error::Result;
use burn::module::Module;
use envision4d_data::HostClip;
use envision4d_eval::score::psnr_per_frame;
use envision4d_losses::{camera_distill, depth_distill};
use envision4d_model::adapter::Exclusion;
use envision4d_model::model::VggtDepth;
use envision4d_model::scene::predict_scene;
use envision4d_model::Envision4d;
use envision4d_splat::RasterConfig;
use serde::Serialize;

/// Means over the validation clips (`None` where the stage or data has no such number).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ValReport {
    pub step: u64,
    pub clips: usize,
    /// PSNR (dB) of the future frames, rendered from the context Gaussians.
    pub future_psnr: Option<f64>,
    /// PSNR (dB) of the context frames rendered only from the other frames' Gaussians.
    pub context_psnr: Option<f64>,
    /// L1 between predicted and ground-truth pose encodings (all frames).
    pub camera_l1: Option<f64>,
    /// Masked L1 depth error (metres) where ground truth exists.
    pub depth_l1: Option<f64>,
    pub seconds: f64,
}

fn mean(v: &[f64]) -> Option<f64> {
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

fn value(t: burn::tensor::Tensor<1>) -> f64 {
    t.into_data().iter::<f64>().next().unwrap_or(f64::NAN)
}

/// Validates `model` on `clips` for `stage`.
pub fn validate(
    model: &Envision4d,
    stage: Stage,
    clips: &[HostClip],
    context: usize,
    step: u64,
    raster: &RasterConfig,
) -> Result<ValReport> {
    let t0 = std::time::Instant::now();
    let model = model.valid();
    let device = model.devices().into_iter().next().unwrap_or_default();
    let (mut fut, mut ctx, mut cam, mut dep) = (vec![], vec![], vec![], vec![]);
    for clip in clips {
        let n = clip.frames.len();
        let gt = clip.cameras.len() == n;
        let depth_frames = match stage {
            Stage::Backbone => n,
            Stage::Envision4d => context,
        };
        let has_depth = clip.depths.len() >= depth_frames;
        let batch = Batch::from_clips(
            std::slice::from_ref(clip),
            depth_frames,
            gt && has_depth,
            &device,
        )?;
        let [_, _, _, h, w] = batch.images.dims();
        match stage {
            Stage::Backbone => {
                let out = model.vggt(batch.images.clone(), VggtDepth::Run);
                if let Some(t) = &batch.labels {
                    cam.push(value(camera_distill(out.pose_enc(), t.pose_enc.clone())?));
                    if let Some((d, _)) = out.depth {
                        dep.push(value(depth_distill(d, t.depth.clone())?));
                    }
                }
            }
            Stage::Envision4d => {
                let context_images =
                    batch
                        .images
                        .clone()
                        .slice([0..1, 0..context, 0..3, 0..h, 0..w]);
                let scene = predict_scene(&model, context_images)?;
                let bb = &scene.pred.backbone;
                let all: Vec<usize> = (0..n).collect();
                let rendered = scene.render(0, &all, Exclusion::SelfExclusive, [h, w], raster)?;
                let truth = batch.images.clone().reshape([n, 3, h, w]);
                let p = psnr_per_frame(rendered, truth)?;
                ctx.extend_from_slice(&p[..context]);
                fut.extend_from_slice(&p[context..]);
                if let Some(t) = &batch.labels {
                    cam.push(value(camera_distill(bb.pose_enc(), t.pose_enc.clone())?));
                    if let Some(d) = scene.pred.depth.clone() {
                        dep.push(value(depth_distill(d, t.depth.clone())?));
                    }
                }
            }
        }
    }
    Ok(ValReport {
        step,
        clips: clips.len(),
        future_psnr: mean(&fut),
        context_psnr: mean(&ctx),
        camera_l1: mean(&cam),
        depth_l1: mean(&dep),
        seconds: t0.elapsed().as_secs_f64(),
    })
}
