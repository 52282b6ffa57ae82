//! `envision4d-eval`: evaluation of a trained model on held-out clips (paper §4): the future-frame
//! protocol, the cross-frame context table, D-RMSE, camera AUC@30, future-pose errors per
//! horizon, three baselines on the same clips, timings, and the quality-vs-time sweep.
//!
//! - [`protocol`]: [`evaluate_clip`], one clip, every number of the report.
//! - [`baselines`]: copy-last-frame and constant-velocity pose extrapolation.
//! - [`motion`]: predicted scene flow and dynamic masks against exact truth (synthetic).
//! - [`pose_error`]: host SE(3) helpers and the per-frame pose error against ground truth.
//! - [`report`]: the JSON schema (`docs/EVAL.md`) and means over clips; [`markdown`]: the
//!   Markdown tables.
//! - [`sweep`]: the knobs that trade quality for time, and the Pareto front.
//! - [`score`]: per-frame PSNR of rendered views, the one definition the protocol, training's
//!   periodic validation and its log share.
//!
//! The crate depends on the model, losses and data crates, never on training: training's
//! validation calls [`score`] with a model on a plain (non-autodiff) device.

pub mod baselines;
pub mod clip_images;
pub mod cross_frame;
pub mod depth_eval;
pub mod error;
pub mod markdown;
pub mod motion;
pub mod motion_maps;
mod motion_scene;
pub mod pose_error;
pub mod protocol;
pub mod regions;
pub mod report;
pub mod score;
pub mod sweep;

pub use error::{EvalError, Result};
pub use markdown::{markdown, summary};
pub use protocol::evaluate_clip;
pub use report::{
    mean_metrics, ClipMetrics, CrossFrameScore, DepthScore, FrameScore, HorizonScore, Method,
    MethodScore, PairScore, Report, Timing, TRANSLATION_ALIGNMENT, TRANSLATION_UNIT,
};
pub use sweep::{SweepPoint, SweepSetting};

use envision4d_data::{ClipDataset, HostClip};
use envision4d_losses::{DepthAlignment, EvalCrop, LpipsStatus};
use envision4d_model::Envision4d;
use envision4d_splat::RasterConfig;

/// How much of the protocol a call runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Extent {
    /// Future frames, cross-frame context frames, depth, and the three baselines.
    Full,
    /// Only the model's future frames (a sweep point: the other numbers do not change with
    /// the knobs, and rendering them would distort the time axis).
    FutureOnly,
}

/// Settings of one evaluation.
#[derive(Debug, Clone)]
pub struct EvalOptions {
    /// `T_c`: the first `T_c` frames of a clip are the model's input.
    pub context_frames: usize,
    /// Pixels removed from every future image (and depth map) before the metrics.
    pub crop: EvalCrop,
    /// Pixels removed before the cross-frame scores (the paper's boundary crop; see
    /// [`EvalOptions::release_cross_frame_crop`]). `None`: the release's crop scaled to each
    /// clip's size.
    pub cross_frame_crop: Option<EvalCrop>,
    /// LPIPS network, or the reason it is not reported.
    pub lpips: LpipsStatus,
    /// Rasterizer settings (the culling thresholds are sweep knobs).
    pub raster: RasterConfig,
    /// Scale alignment of the predicted depth before D-RMSE (reported next to the number).
    pub depth_alignment: DepthAlignment,
    /// Model input size `[H, W]`; `None` = the clip's size. Renders are always at the clip's
    /// size (intrinsics scaled), so every setting is scored against the same pixels.
    pub input_size: Option<[usize; 2]>,
    pub extent: Extent,
    /// Keep each clip's per-pixel motion maps (`motion_maps`) in
    /// [`ClipMetrics::motion_maps`], where the clip has motion truth.
    pub motion_maps: bool,
    /// Keep each clip's future frames, baselines, depth and masks in
    /// [`ClipMetrics::images`] (the HTML report's strips).
    pub clip_images: bool,
}

impl EvalOptions {
    /// The cross-frame crop for clips of `size` `[H, W]`: the release's `6, 6, 10, 6` pixels,
    /// given for 350x518, scaled to the clip size (`EvalCrop::scaled_to`).
    pub fn release_cross_frame_crop(size: [usize; 2]) -> EvalCrop {
        EvalCrop::RELEASE_MAIN.scaled_to(size)
    }

    /// The cross-frame crop used for clips of `size`.
    pub fn cross_frame_crop_for(&self, size: [usize; 2]) -> EvalCrop {
        self.cross_frame_crop
            .unwrap_or_else(|| Self::release_cross_frame_crop(size))
    }

    /// The paper's protocol: no crop of the future frames, the release's crop (scaled to the
    /// clip size) for the cross-frame scores, default rasterizer, median depth alignment,
    /// full extent.
    pub fn new(context_frames: usize, lpips: LpipsStatus) -> Self {
        EvalOptions {
            context_frames,
            crop: EvalCrop::default(),
            cross_frame_crop: None,
            lpips,
            raster: RasterConfig::default(),
            depth_alignment: DepthAlignment::Median,
            input_size: None,
            extent: Extent::Full,
            motion_maps: false,
            clip_images: false,
        }
    }
}

/// Clips evaluated by [`evaluate_dataset`].
#[derive(Debug, Clone)]
pub struct EvalRun {
    pub clips: Vec<ClipMetrics>,
    /// Clips that could not be decoded (each already warned about by the dataset).
    pub skipped: usize,
}

/// Evaluates clips `indices` of `dataset`, calling `on_clip` after each (progress, logs;
/// it may take what the run need not keep, such as `motion_maps`).
/// A clip that fails to decode is skipped and counted; an evaluation error stops the run and
/// names the clip.
pub fn evaluate_dataset(
    model: &Envision4d,
    dataset: &ClipDataset,
    indices: &[usize],
    opts: &EvalOptions,
    mut on_clip: impl FnMut(&mut ClipMetrics),
) -> Result<EvalRun> {
    let mut run = EvalRun {
        clips: Vec::with_capacity(indices.len()),
        skipped: 0,
    };
    for &i in indices {
        let Some(clip) = dataset.get(i) else {
            run.skipped += 1;
            continue;
        };
        let id = clip.id.clone();
        let host = HostClip::from_clip(&clip).map_err(|e| EvalError::from(e).in_clip(&id))?;
        let mut m = evaluate_clip(model, &host, opts).map_err(|e| e.in_clip(&id))?;
        m.clip = id.clone();
        on_clip(&mut m);
        run.clips.push(m);
    }
    Ok(run)
}
