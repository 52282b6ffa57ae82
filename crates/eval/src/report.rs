//! The evaluation report: per-clip metrics, their mean over clips, and the whole report as
//! JSON. The schema is documented key by key in `docs/EVAL.md` (a test keeps the two equal).

pub use crate::sweep::{Knob, SweepPoint};
use envision4d_splat::RasterConfig;
use serde::{Deserialize, Serialize};

/// Version of the JSON layout; bump it when a key changes meaning or disappears.
pub const SCHEMA_VERSION: u32 = 2;

/// What produced a set of future frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Envision4D: moved Gaussians rendered at its predicted future poses.
    Model,
    /// Every future frame is the last context frame.
    CopyLast,
    /// Motion disabled, poses extrapolated at constant velocity.
    StaticCv,
    /// Motion disabled, the model's own future poses.
    NoMotion,
    /// The model's Gaussians and poses, each Gaussian moved by the exact scene flow of the
    /// true surface at its pixel (synthetic data): what exact motion adds to this
    /// reconstruction.
    OracleMotion,
    /// Motion disabled, rendered at the true cameras (synthetic data).
    TrueCamerasNoMotion,
    /// The model's motion, rendered at the true cameras.
    TrueCameras,
    /// The exact motion, rendered at the true cameras: what remains is depth and appearance.
    TrueCamerasOracleMotion,
}

impl Method {
    /// Short label for tables and plot legends.
    pub fn label(self) -> &'static str {
        match self {
            Method::Model => "model",
            Method::CopyLast => "copy-last",
            Method::StaticCv => "static+cv",
            Method::NoMotion => "no-motion",
            Method::OracleMotion => "oracle-motion",
            Method::TrueCamerasNoMotion => "true-cams no-motion",
            Method::TrueCameras => "true-cams model",
            Method::TrueCamerasOracleMotion => "true-cams oracle",
        }
    }
}

/// One future frame (horizon `k` is frame `T_c − 1 + k`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HorizonScore {
    pub horizon: usize,
    pub frame: usize,
    pub psnr: f64,
    pub ssim: f64,
    pub lpips: Option<f64>,
    pub rot_err_deg: Option<f64>,
    /// Camera-centre error after the clip's scale alignment, ground-truth unit (metres).
    pub trans_err: Option<f64>,
    /// The same without scale alignment, in the model's own unit (metres for a model
    /// trained against metric labels). The only one that sees motion predicted where the
    /// truth stands still: there the fitted scale is 0 and `trans_err` is 0 for anything.
    pub trans_err_unaligned: Option<f64>,
}

/// One method's future frames on one clip (or the mean over clips).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodScore {
    pub method: Method,
    /// Means over the future frames.
    pub psnr: f64,
    pub ssim: f64,
    pub lpips: Option<f64>,
    pub rot_err_deg: Option<f64>,
    pub trans_err: Option<f64>,
    pub trans_err_unaligned: Option<f64>,
    /// The scale applied to the predicted camera centres before `trans_err`.
    pub pose_scale: Option<f64>,
    /// PSNR / SSIM on the ground-truth dynamic mask of the scored frames and on the rest
    /// (`regions`); `None` without masks or where a region is empty.
    pub dynamic_psnr: Option<f64>,
    pub dynamic_ssim: Option<f64>,
    pub static_psnr: Option<f64>,
    pub static_ssim: Option<f64>,
    /// Over all `T_c + T_f` cameras; `None` without ground-truth poses.
    pub camera_auc30: Option<f64>,
    /// Seconds this method spent on the clip (encoder + its renders).
    pub time_s: f64,
    pub per_horizon: Vec<HorizonScore>,
}

/// One context frame rendered only from the other frames' Gaussians.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameScore {
    pub frame: usize,
    pub psnr: f64,
    pub ssim: f64,
    pub lpips: Option<f64>,
}

/// Context frame `target` rendered from source frame `source`'s Gaussians alone.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PairScore {
    pub source: usize,
    pub target: usize,
    pub psnr: f64,
    pub ssim: f64,
    pub lpips: Option<f64>,
}

/// The cross-frame table: context frames rendered without their own Gaussians, scored
/// after the report's `cross_frame_crop`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CrossFrameScore {
    /// Means over `per_frame`.
    pub psnr: f64,
    pub ssim: f64,
    pub lpips: Option<f64>,
    /// Each context frame from all the other context frames.
    pub per_frame: Vec<FrameScore>,
    /// Each ordered pair `source→target` (the appendix's `1→0` and `0→1`).
    pub pairs: Vec<PairScore>,
}

/// D-RMSE of some frames' depth against the clip's evaluation depth.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DepthScore {
    /// Mean over frames with valid ground truth, in the ground truth's unit (metres).
    pub rmse: f64,
    /// `none`, `median` or `least_squares`, one scale per frame.
    pub alignment: String,
    /// `dense`, `lidar_grid` or `lidar_points` (see docs/EVAL.md).
    pub source: String,
    /// The clip's frames scored, in order.
    pub frames: Vec<usize>,
    /// Scale applied to each frame's prediction; `None` where the frame has no truth.
    pub scales: Vec<Option<f64>>,
    /// `None` for a frame without a valid ground-truth pixel.
    pub per_frame: Vec<Option<f64>>,
}

/// Seconds spent on one clip; the device is synchronised before each clock stops.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Timing {
    /// Forward pass on the context frames plus adapting the Gaussians.
    pub encoder_s: f64,
    /// Rendering the `T_f` future frames.
    pub decoder_s: f64,
    /// Rendering the `T_c` context frames (cross-frame table); `None` in sweep points.
    pub context_decoder_s: Option<f64>,
}

/// Every number of one clip.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClipMetrics {
    /// The dataset's clip id (`"mean"` for the mean over clips).
    pub clip: String,
    pub timing: Timing,
    /// The model first, then the baselines (absent in sweep points).
    pub methods: Vec<MethodScore>,
    pub context: Option<CrossFrameScore>,
    /// Table 1's D-RMSE: the rendered depth of the scored (future) frames.
    pub depth_rmse: Option<DepthScore>,
    /// The depth head's maps of the context frames.
    pub context_depth_rmse: Option<DepthScore>,
    /// The predicted motion against exact scene flow and dynamic masks (synthetic data).
    pub motion: Option<crate::motion::MotionScore>,
    /// Per-pixel motion of one pair (`EvalOptions::motion_maps`); never in the JSON.
    #[serde(skip)]
    pub motion_maps: Option<crate::motion_maps::PairMaps>,
    /// The future frames behind the numbers (`EvalOptions::clip_images`); never in the JSON.
    #[serde(skip)]
    pub images: Option<crate::clip_images::ClipImages>,
}

impl ClipMetrics {
    pub fn method(&self, m: Method) -> Option<&MethodScore> {
        self.methods.iter().find(|s| s.method == m)
    }
}

/// Whether LPIPS was computed, and why not.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LpipsInfo {
    pub available: bool,
    pub reason: Option<String>,
}

/// Border crop in pixels, as `envision4d_losses::EvalCrop`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CropInfo {
    pub top: usize,
    pub bottom: usize,
    pub left: usize,
    pub right: usize,
}

impl From<envision4d_losses::EvalCrop> for CropInfo {
    fn from(c: envision4d_losses::EvalCrop) -> Self {
        CropInfo {
            top: c.top,
            bottom: c.bottom,
            left: c.left,
            right: c.right,
        }
    }
}

/// The precision of reports written before `precision` was recorded.
fn full_precision() -> String {
    "f32".into()
}

/// The whole `metrics.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Report {
    pub schema_version: u32,
    pub checkpoint: String,
    pub data: String,
    pub split: String,
    pub backend: String,
    /// The aggregator's float format (`f32`, `f16`, `bf16`); reports before it existed
    /// were f32.
    #[serde(default = "full_precision")]
    pub precision: String,
    pub context_frames: usize,
    pub future_frames: usize,
    /// Clip (render and metric) size `[H, W]`.
    pub image_size: [usize; 2],
    /// Model input size `[H, W]`.
    pub input_size: [usize; 2],
    pub crop: CropInfo,
    /// Crop of the cross-frame scores (backward renders leave the borders uncovered).
    pub cross_frame_crop: CropInfo,
    pub depth_alignment: String,
    /// How `trans_err` is aligned ([`TRANSLATION_ALIGNMENT`]) and its unit.
    pub translation_alignment: String,
    pub translation_unit: String,
    pub lpips: LpipsInfo,
    pub raster: RasterConfig,
    pub clips_evaluated: usize,
    pub clips_skipped: usize,
    pub clips: Vec<ClipMetrics>,
    /// Mean over `clips`; `None` when no clip was evaluated.
    pub mean: Option<ClipMetrics>,
    /// Sweep points (`--sweep`), Pareto flags set; `None` without a sweep.
    pub sweep: Option<Vec<SweepPoint>>,
}

impl Report {
    /// Pretty JSON. Non-finite floats cannot occur: PSNR is capped and every other metric
    /// is finite by construction (inputs are finite-checked).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("report types serialise")
    }
}

/// `translation_alignment` of every report: one least-squares scale per clip on the camera
/// centres (`pose_error::translation_scale`).
pub const TRANSLATION_ALIGNMENT: &str = "least_squares_scale_per_clip";
/// `translation_unit`: every layout with ground-truth poses is metric.
pub const TRANSLATION_UNIT: &str = "m";

/// Mean of the present values; `None` when none is present.
pub fn mean_opt(values: impl IntoIterator<Item = Option<f64>>) -> Option<f64> {
    let v: Vec<f64> = values.into_iter().flatten().collect();
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

/// Mean of values (0 for none; callers only pass non-empty sets).
pub fn mean(values: impl IntoIterator<Item = f64>) -> f64 {
    mean_opt(values.into_iter().map(Some)).unwrap_or(0.0)
}

/// The mean over clips of every number (each optional number over the clips that have it),
/// as a [`ClipMetrics`] named `"mean"`; `None` for no clips. Methods and per-frame entries
/// are matched by method and position: clips of one run share `T_c`, `T_f` and methods.
pub fn mean_metrics(clips: &[ClipMetrics]) -> Option<ClipMetrics> {
    clips.first()?;
    // Every method any clip has, in first-seen order (the oracle needs motion truth, which a
    // mixed dataset's first clip may lack), each averaged over the clips that have it.
    let mut order: Vec<Method> = Vec::new();
    for m in clips.iter().flat_map(|c| &c.methods) {
        if !order.contains(&m.method) {
            order.push(m.method);
        }
    }
    let methods = order
        .into_iter()
        .map(|method| {
            let all: Vec<&MethodScore> = clips.iter().filter_map(|c| c.method(method)).collect();
            mean_method(method, &all)
        })
        .collect();
    let contexts: Vec<&CrossFrameScore> = clips.iter().filter_map(|c| c.context.as_ref()).collect();
    let depths: Vec<&DepthScore> = clips.iter().filter_map(|c| c.depth_rmse.as_ref()).collect();
    let head: Vec<&DepthScore> = clips
        .iter()
        .filter_map(|c| c.context_depth_rmse.as_ref())
        .collect();
    Some(ClipMetrics {
        clip: "mean".into(),
        timing: Timing {
            encoder_s: mean(clips.iter().map(|c| c.timing.encoder_s)),
            decoder_s: mean(clips.iter().map(|c| c.timing.decoder_s)),
            context_decoder_s: mean_opt(clips.iter().map(|c| c.timing.context_decoder_s)),
        },
        methods,
        context: mean_context(&contexts),
        depth_rmse: mean_depth(&depths),
        context_depth_rmse: mean_depth(&head),
        motion: crate::motion::mean_motion(
            &clips
                .iter()
                .filter_map(|c| c.motion.as_ref())
                .collect::<Vec<_>>(),
        ),
        motion_maps: None,
        images: None,
    })
}

fn mean_method(method: Method, all: &[&MethodScore]) -> MethodScore {
    let horizons = all.iter().map(|m| m.per_horizon.len()).min().unwrap_or(0);
    let per_horizon = (0..horizons)
        .map(|k| {
            let at: Vec<&HorizonScore> = all.iter().map(|m| &m.per_horizon[k]).collect();
            HorizonScore {
                horizon: at[0].horizon,
                frame: at[0].frame,
                psnr: mean(at.iter().map(|h| h.psnr)),
                ssim: mean(at.iter().map(|h| h.ssim)),
                lpips: mean_opt(at.iter().map(|h| h.lpips)),
                rot_err_deg: mean_opt(at.iter().map(|h| h.rot_err_deg)),
                trans_err: mean_opt(at.iter().map(|h| h.trans_err)),
                trans_err_unaligned: mean_opt(at.iter().map(|h| h.trans_err_unaligned)),
            }
        })
        .collect();
    MethodScore {
        method,
        psnr: mean(all.iter().map(|m| m.psnr)),
        ssim: mean(all.iter().map(|m| m.ssim)),
        lpips: mean_opt(all.iter().map(|m| m.lpips)),
        rot_err_deg: mean_opt(all.iter().map(|m| m.rot_err_deg)),
        trans_err: mean_opt(all.iter().map(|m| m.trans_err)),
        trans_err_unaligned: mean_opt(all.iter().map(|m| m.trans_err_unaligned)),
        pose_scale: mean_opt(all.iter().map(|m| m.pose_scale)),
        dynamic_psnr: mean_opt(all.iter().map(|m| m.dynamic_psnr)),
        dynamic_ssim: mean_opt(all.iter().map(|m| m.dynamic_ssim)),
        static_psnr: mean_opt(all.iter().map(|m| m.static_psnr)),
        static_ssim: mean_opt(all.iter().map(|m| m.static_ssim)),
        camera_auc30: mean_opt(all.iter().map(|m| m.camera_auc30)),
        time_s: mean(all.iter().map(|m| m.time_s)),
        per_horizon,
    }
}

fn mean_context(all: &[&CrossFrameScore]) -> Option<CrossFrameScore> {
    let first = all.first()?;
    let frames = all.iter().map(|c| c.per_frame.len()).min().unwrap_or(0);
    let pairs = all.iter().map(|c| c.pairs.len()).min().unwrap_or(0);
    Some(CrossFrameScore {
        psnr: mean(all.iter().map(|c| c.psnr)),
        ssim: mean(all.iter().map(|c| c.ssim)),
        lpips: mean_opt(all.iter().map(|c| c.lpips)),
        per_frame: (0..frames)
            .map(|k| FrameScore {
                frame: first.per_frame[k].frame,
                psnr: mean(all.iter().map(|c| c.per_frame[k].psnr)),
                ssim: mean(all.iter().map(|c| c.per_frame[k].ssim)),
                lpips: mean_opt(all.iter().map(|c| c.per_frame[k].lpips)),
            })
            .collect(),
        pairs: (0..pairs)
            .map(|k| {
                let at: Vec<&PairScore> = all.iter().map(|c| &c.pairs[k]).collect();
                PairScore {
                    source: at[0].source,
                    target: at[0].target,
                    psnr: mean(at.iter().map(|p| p.psnr)),
                    ssim: mean(at.iter().map(|p| p.ssim)),
                    lpips: mean_opt(at.iter().map(|p| p.lpips)),
                }
            })
            .collect(),
    })
}

fn mean_depth(all: &[&DepthScore]) -> Option<DepthScore> {
    let first = all.first()?;
    let frames = all.iter().map(|d| d.per_frame.len()).min().unwrap_or(0);
    Some(DepthScore {
        rmse: mean(all.iter().map(|d| d.rmse)),
        alignment: first.alignment.clone(),
        source: first.source.clone(),
        frames: first.frames[..frames].to_vec(),
        scales: (0..frames)
            .map(|k| mean_opt(all.iter().map(|d| d.scales[k])))
            .collect(),
        per_frame: (0..frames)
            .map(|k| mean_opt(all.iter().map(|d| d.per_frame[k])))
            .collect(),
    })
}
