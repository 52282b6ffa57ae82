//! The training configuration (TOML). Every section denies unknown keys, so a typo is an
//! error naming the key. Defaults are the paper's values (§4 implementation details,
//! and `docs/MODEL.md` where the paper is silent); `configs/waymo.toml` spells them all out.

use envision4d_model::ModelConfig;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

mod data;
mod weights;
pub use data::{Augment, DataConfig, DataLayout, Purpose, EVAL_SPLITS};
use weights::paper_freeze;
pub use weights::{FreezeGroup, FreshGroup, Init};

/// Paper: Adam, lr 1e-4.
pub const PAPER_LR: f64 = 1e-4;
pub const PAPER_BATCH: usize = 2;
pub const PAPER_ITERATIONS: u64 = 100_000;
pub const PAPER_WARMUP_ITERATIONS: u64 = 2_500;
pub const PAPER_S_MAX: u64 = 50_000;
pub const PAPER_ALPHA0: f64 = 1.0;
/// Adam's ε in PyTorch (the reference's optimiser).
pub const PYTORCH_ADAM_EPSILON: f64 = 1e-8;
/// STORM's grad-norm clip (the paper states none; `docs/MODEL.md`).
pub const DEFAULT_GRAD_CLIP: f64 = 3.0;

/// Which network is trained.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Stage {
    /// Supervised VGGT part (aggregator, camera and depth heads) on ground truth.
    Backbone,
    /// The paper's self-supervised, progressive training.
    Envision4d,
}

/// Where the distillation pseudo-labels come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Teacher {
    /// A frozen backbone run on all N ground-truth frames (the paper).
    Backbone,
    /// Exact labels of the synthetic world.
    GroundTruth,
    /// No distillation terms.
    None,
}

/// Learning-rate schedule.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LrSchedule {
    /// Half-cosine from `lr` to `min_lr` over `iterations` (paper: "cosine schedule").
    Cosine,
    Constant,
}

/// Gradient clipping (burn's `GradientClipping`, applied per parameter tensor).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ClipMode {
    /// One L2 norm over every trainable gradient (PyTorch's `clip_grad_norm_`, STORM).
    GlobalNorm,
    /// Burn's per-parameter-tensor norm clipping.
    Norm,
    Value,
    None,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OptimConfig {
    pub lr: f64,
    pub min_lr: f64,
    pub schedule: LrSchedule,
    pub batch_size: usize,
    pub iterations: u64,
    pub grad_clip: ClipMode,
    pub grad_clip_threshold: f64,
    /// Adam's ε (PyTorch's default 1e-8; Burn's own default is 1e-5).
    pub adam_epsilon: f64,
}

impl Default for OptimConfig {
    fn default() -> Self {
        OptimConfig {
            lr: PAPER_LR,
            min_lr: 0.0,
            schedule: LrSchedule::Cosine,
            batch_size: PAPER_BATCH,
            iterations: PAPER_ITERATIONS,
            grad_clip: ClipMode::GlobalNorm,
            grad_clip_threshold: DEFAULT_GRAD_CLIP,
            adam_epsilon: PYTORCH_ADAM_EPSILON,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LossConfig {
    pub lambda_lpips: f64,
    pub lambda_cam: f64,
    pub lambda_depth: f64,
    /// How many times the quaternion entries of the pose encodings count in the camera
    /// loss (translation and FoV count once); 1 is the paper's plain L1.
    pub rotation_weight: f64,
    /// Weight of the structural term `1 − SSIM` in `L_rgb` (0, the default, is the paper's
    /// loss). A stand-in for LPIPS where its VGG weights are not available: MSE alone
    /// hardly penalises the blur a model uses to hedge uncertain motion.
    pub lambda_ssim: f64,
    /// LPIPS (VGG) weights, as `--lpips-weights` takes them (`BACKBONE.pth,LINS.pth` or one
    /// file with the package's names); required when `lambda_lpips > 0`.
    pub lpips_weights: Option<PathBuf>,
    /// Diagnostic, not the paper's loss (0, the default, is off): each target pixel on the
    /// ground-truth dynamic mask counts `1 + dynamic_weight` times in the MSE of `L_rgb`
    /// (normalised per frame, [`envision4d_losses::weighted_mse_per_frame`]), so the moving
    /// objects, a few percent of the pixels, carry more of the rendering signal. Needs
    /// clips with dynamic masks (the synthetic layout). Left out of the TOML when 0, so
    /// runs started before the key existed keep their resume identity.
    #[serde(skip_serializing_if = "is_zero")]
    pub dynamic_weight: f64,
    /// Diagnostic, not the paper's loss (0, the default, is off): λ of a supervised
    /// scene-flow term, the mean L1 distance between every predicted Gaussian displacement
    /// and the exact one of the surface at its pixel, in the model's axes and unit (the
    /// evaluation's oracle motion, docs/EVAL.md). It asks whether the motion head can
    /// represent the motion at all, apart from how much the rendering loss tells it. Needs
    /// clips with motion truth (the synthetic layout) and a motion model; reads the scene
    /// back to the host every step.
    #[serde(skip_serializing_if = "is_zero")]
    pub lambda_flow: f64,
    /// With `lambda_flow`: the moving pixels and the static ones each make half of the flow
    /// term, instead of every pixel counting once (where the static ~92% make zero motion
    /// the L1 optimum). Left out of the TOML when false.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub flow_balanced: bool,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

impl Default for LossConfig {
    fn default() -> Self {
        LossConfig {
            lambda_lpips: envision4d_losses::LPIPS_LOSS_WEIGHT,
            lambda_cam: envision4d_losses::CAMERA_DISTILL_WEIGHT,
            lambda_depth: envision4d_losses::DEPTH_DISTILL_WEIGHT,
            rotation_weight: 1.0,
            lambda_ssim: 0.0,
            lpips_weights: None,
            dynamic_weight: 0.0,
            lambda_flow: 0.0,
            flow_balanced: false,
        }
    }
}

/// Where the α annealing clock `s'` starts (the paper is ambiguous, `docs/MODEL.md`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AnnealOrigin {
    /// `s' = step - warmup_iterations` ("Subsequently ..."): the default.
    AfterWarmup,
    /// `s' = step`.
    StepZero,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ProgressiveConfig {
    pub warmup_iterations: u64,
    pub s_max: u64,
    pub alpha0: f64,
    pub anneal_origin: AnnealOrigin,
}

impl Default for ProgressiveConfig {
    fn default() -> Self {
        ProgressiveConfig {
            warmup_iterations: PAPER_WARMUP_ITERATIONS,
            s_max: PAPER_S_MAX,
            alpha0: PAPER_ALPHA0,
            anneal_origin: AnnealOrigin::AfterWarmup,
        }
    }
}

/// Motion model of the ablation table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MotionModel {
    /// Conditioned motion lifting (the paper).
    Lifting,
    /// Linear bidirectional velocity instead of CML.
    LinearVelocity,
    /// No motion at all (the motion benchmark's control; the motion head never runs).
    Off,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TemporalAttention {
    InLayer,
    PostLayer,
    /// No temporal attention (Tab. 3's rows without TAttn).
    None,
}

/// An on/off ablation switch (an enum so a config reads `warmup = "off"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Switch {
    On,
    Off,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AblationConfig {
    pub motion: MotionModel,
    pub temporal_attention: TemporalAttention,
    pub warmup: Switch,
    pub progressive_weighting: Switch,
}

impl Default for AblationConfig {
    fn default() -> Self {
        AblationConfig {
            motion: MotionModel::Lifting,
            temporal_attention: TemporalAttention::InLayer,
            warmup: Switch::On,
            progressive_weighting: Switch::On,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RunConfig {
    pub out_dir: PathBuf,
    pub log_every: u64,
    pub checkpoint_every: u64,
    pub keep_checkpoints: usize,
    /// Validation on held-out clips every this many steps (0 = never).
    pub val_every: u64,
    /// Validation clips used (the first ones of the seeded validation split).
    pub val_clips: usize,
    /// Consecutive non-finite steps after which the run stops (the last good checkpoint
    /// stays intact).
    pub max_nonfinite_steps: u64,
    /// Burn's balanced activation checkpointing on the training device(s): memory-bound
    /// activations are recomputed in the backward instead of kept. Same gradients (tested),
    /// less memory, some more time; `docs/PERFORMANCE.md` has the paper-size measurement.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub activation_checkpointing: bool,
    /// Keep only the input of every frozen frame and global block and run the block again in
    /// the backward (block-level activation checkpointing). Same gradients (tested); at paper
    /// size it removes the bulk of a step's memory for one more pass of those blocks
    /// (`docs/PERFORMANCE.md`, "A paper-size training step").
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub recompute_frozen_blocks: bool,
    /// On GPU backends, the rasterizer's backward projects and bins every view again
    /// instead of holding the forward's records and tile lists between the passes
    /// (`BackwardBins::Recompute`): about 73 bytes less per Gaussian and rendered view (0.1
    /// GiB at the paper's batch 1), for the binning's time once more. Same gradients
    /// (tested); the CPU backend keeps nothing either way.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub recompute_raster_bins: bool,
}

impl Default for RunConfig {
    fn default() -> Self {
        RunConfig {
            out_dir: PathBuf::from("runs/default"),
            log_every: 10,
            // STORM checkpoints every 5 000 iterations.
            checkpoint_every: 5_000,
            keep_checkpoints: 3,
            val_every: 5_000,
            val_clips: 8,
            max_nonfinite_steps: 10,
            activation_checkpointing: false,
            recompute_frozen_blocks: false,
            recompute_raster_bins: false,
        }
    }
}

/// The resolved configuration.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrainConfig {
    pub stage: Stage,
    pub seed: u64,
    pub teacher: Teacher,
    pub freeze: Vec<FreezeGroup>,
    /// `init = "checkpoint" | "random"` ([`Init`]). Left out of the TOML when default, so
    /// runs started before the key existed keep their resume identity.
    #[serde(skip_serializing_if = "Init::is_checkpoint")]
    pub init: Init,
    /// Initial weights (VGGT-1B release or a stage-1 checkpoint); random init when absent.
    pub init_checkpoint: Option<PathBuf>,
    /// Modules not taken from `init_checkpoint` ([`FreshGroup`]).
    pub init_fresh: Vec<FreshGroup>,
    /// Weights of the frozen teacher (`teacher = "backbone"`); default `init_checkpoint`.
    pub teacher_checkpoint: Option<PathBuf>,
    pub model: ModelConfig,
    pub optim: OptimConfig,
    pub loss: LossConfig,
    pub progressive: ProgressiveConfig,
    pub ablation: AblationConfig,
    pub data: DataConfig,
    pub run: RunConfig,
}

impl TrainConfig {
    /// The networks this config gives random weights (`init = "random"`), to be named in a
    /// run's output: numbers from them measure time and memory, not quality.
    pub fn random_weights(&self) -> Vec<&'static str> {
        if self.init != Init::Random {
            return Vec::new();
        }
        let mut out = vec!["the model"];
        if self.stage == Stage::Envision4d
            && self.teacher == Teacher::Backbone
            && self.teacher_checkpoint.is_none()
        {
            out.push("the frozen teacher");
        }
        if self.loss.lambda_lpips > 0.0 && self.loss.lpips_weights.is_none() {
            out.push("LPIPS's VGG");
        }
        out
    }
}

/// The file as written: `[model]` is a preset plus overrides, resolved in `load`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawTrainConfig {
    pub stage: Stage,
    #[serde(default)]
    pub seed: u64,
    pub teacher: Teacher,
    #[serde(default = "paper_freeze")]
    pub freeze: Vec<FreezeGroup>,
    #[serde(default)]
    pub init: Init,
    #[serde(default)]
    pub init_checkpoint: Option<PathBuf>,
    #[serde(default)]
    pub init_fresh: Vec<FreshGroup>,
    #[serde(default)]
    pub teacher_checkpoint: Option<PathBuf>,
    pub model: toml::Table,
    #[serde(default)]
    pub optim: OptimConfig,
    #[serde(default)]
    pub loss: LossConfig,
    #[serde(default)]
    pub progressive: ProgressiveConfig,
    #[serde(default)]
    pub ablation: AblationConfig,
    pub data: DataConfig,
    #[serde(default)]
    pub run: RunConfig,
}
