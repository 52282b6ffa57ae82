//! How much memory one training step needs: a model of the peak, for `train --dry-run` and
//! the "Will it fit?" table of `docs/TRAINING.md`.
//!
//! The peak is a sum of exact terms and fitted ones. Exact: the parameters (f32), LPIPS's
//! VGG, the trainable parameters' gradients, Adam's two moments (from the second step on)
//! and the teacher's own copy of what it shares with a trained model. Fitted: what autodiff
//! keeps for the backward, as bytes per unit of five counts the config decides, plus a
//! constant for the process itself:
//! - token-channels of the transformer blocks whose intermediates are kept (the blocks the
//!   gradient passes through: trainable ones, and frozen ones after the first trainable
//!   layer unless `run.recompute_frozen_blocks`), and of the frozen blocks recomputed
//!   instead (they keep their input);
//! - pixel-channels of the DPT heads that train (depth and Gaussians per context frame,
//!   motion per lifted map);
//! - rendered pixels (rasterizer, L1), and rendered pixels through LPIPS.
//!
//! The coefficients come from small measured runs
//! of the training-step benchmark (`scripts/memory_fit.sh`, `docs/PERFORMANCE.md`); the
//! estimate is the host's peak resident memory of a CPU step (f32). On a GPU the same
//! tensors live in device memory, without the process constant, plus the pool's slack,
//! which no GPU measured yet.

use crate::config::{FreezeGroup, Stage, Teacher, TrainConfig};
use crate::freeze::ParamSplit;
use burn::module::{Module, ModuleVisitor, Param, ParamId};
use burn::tensor::Tensor;
use envision4d_model::config::{MotionModel, TemporalPlacement};
use envision4d_model::model::Vggt;
use envision4d_model::Envision4d;
use std::collections::HashSet;

/// Bytes of one f32.
const F32: f64 = 4.0;
/// Parameters of LPIPS's VGG16 feature stack (conv1_1 … conv5_3) and its five linear heads.
pub const LPIPS_VGG_PARAMS: usize = 14_714_688 + 1_472;

/// The fitted coefficients (bytes per unit); `scripts/memory_fit.sh` prints them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coefficients {
    /// The process without tensors (binary, thread pools, allocator arenas).
    pub runtime: f64,
    /// Per token-channel of a kept transformer block.
    pub block: f64,
    /// Per token-channel of a recomputed frozen block.
    pub recomputed: f64,
    /// Per pixel-channel of a training DPT head's map. The fit grid trains all three heads at
    /// 4 frames, where this term grows with the block, recomputed-block and rendered-pixel
    /// terms, so the fit cannot tell them apart well: it has given 0 to this one (before
    /// LPIPS's targets ran untracked) and 0 to `recomputed` (since); the sum is what is
    /// checked (docs/PERFORMANCE.md).
    pub dpt: f64,
    /// Per rendered pixel (rasterizer and L1 state).
    pub render: f64,
    /// Per rendered pixel through LPIPS's VGG.
    pub lpips: f64,
}

/// Fitted on this project's dev machine (burn-flex, 2 threads) by `scripts/memory_fit.sh`
/// (11 runs; the largest ratio of estimate to measured peak 1.063, three held-out runs
/// included); see the module docs.
pub const FITTED: Coefficients = Coefficients {
    runtime: 6.443408e+07,
    block: 4.896922e+01,
    recomputed: 0.000000e+00,
    dpt: 1.504812e+01,
    render: 1.447192e+03,
    lpips: 3.304114e+03,
};

/// The counts the fitted terms multiply.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Counts {
    pub block_token_channels: f64,
    pub recomputed_token_channels: f64,
    pub dpt_pixel_channels: f64,
    pub rendered_pixels: f64,
    pub lpips_pixels: f64,
}

/// One step's peak memory by part, in bytes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepMemory {
    pub runtime: f64,
    /// Every parameter of the model (frozen and trainable).
    pub parameters: f64,
    pub lpips_weights: f64,
    pub gradients: f64,
    /// Adam's two moments: absent during the first step.
    pub optimizer: f64,
    /// The teacher's weights beyond what it shares with the model, in the first step and
    /// in later ones (a snapshot shares everything until the first update).
    pub teacher_first: f64,
    pub teacher_later: f64,
    pub activations: f64,
    /// What the GPU rasterizer's forward holds for its backward (`[run]
    /// recompute_raster_bins` off): device memory only, the CPU path keeps nothing.
    pub raster_bins: f64,
    pub counts: Counts,
}

impl StepMemory {
    /// Peak of the first step.
    pub fn first_step(&self) -> f64 {
        self.runtime
            + self.parameters
            + self.lpips_weights
            + self.gradients
            + self.teacher_first
            + self.activations
    }

    /// Peak of every later step (Adam's state exists): the run's peak.
    pub fn later_steps(&self) -> f64 {
        self.first_step() - self.teacher_first + self.teacher_later + self.optimizer
    }

    /// What a GPU would hold: the same tensors without the host process, plus the
    /// rasterizer's kept tile lists.
    pub fn device_tensors(&self) -> f64 {
        self.later_steps() - self.runtime + self.raster_bins
    }
}

struct Count<'a> {
    only: Option<&'a HashSet<ParamId>>,
    elements: usize,
}

impl ModuleVisitor for Count<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        if self.only.is_none_or(|ids| ids.contains(&param.id)) {
            self.elements += param.lazy_shape().num_elements();
        }
    }
}

fn count<M: Module>(m: &M, only: Option<&HashSet<ParamId>>) -> usize {
    let mut c = Count { only, elements: 0 };
    m.visit(&mut c);
    c.elements
}

/// The counts of `cfg` (see the module docs), given which groups are frozen.
pub fn counts(cfg: &TrainConfig) -> Counts {
    let m = &cfg.model;
    let frozen = |g: FreezeGroup| cfg.freeze.contains(&g);
    let b = cfg.optim.batch_size as f64;
    let [h, w] = m.image_size;
    let pixels = (h * w) as f64;
    let (context, frames) = (m.context_frames, m.num_frames());
    let backbone_stage = cfg.stage == Stage::Backbone;
    // The backbone stage runs plain VGGT on every frame; Envision4D on the context frames.
    let seen = if backbone_stage { frames } else { context } as f64;
    let tokens = b * seen * m.tokens_per_frame() as f64;
    let recompute = cfg.run.recompute_frozen_blocks;
    let in_layer = !backbone_stage && m.temporal_attention == TemporalPlacement::InLayer;
    let temporal_exists = !backbone_stage && m.temporal_attention != TemporalPlacement::None;
    let temporal_trains = temporal_exists && !frozen(FreezeGroup::TimeBlocks);

    // The first layer of each kind of block whose activations the backward needs: 0 when
    // the patch embedding, the tokens or a block of that kind or before it trains (layer
    // l's frame block runs before its global block, so when only global blocks train,
    // frame block 0 is not needed); after the first temporal layer when only in-layer
    // temporal blocks do; none when nothing in the aggregator trains.
    let inputs_train = !frozen(FreezeGroup::PatchEmbed) || !frozen(FreezeGroup::Tokens);
    let frame_trains = !frozen(FreezeGroup::FrameBlocks);
    let global_trains = !frozen(FreezeGroup::GlobalBlocks);
    let backbone_trains = inputs_train || frame_trains || global_trains;
    let first_temporal = m.temporal_layers.iter().copied().min().unwrap_or(m.depth);
    let after_temporal = (in_layer && temporal_trains).then_some(first_temporal + 1);
    let frame_start = if inputs_train || frame_trains {
        Some(0)
    } else if global_trains {
        Some(1)
    } else {
        after_temporal
    };
    let global_start = if backbone_trains {
        Some(0)
    } else {
        after_temporal
    };
    let (mut channels, mut recomputed) = (0.0, 0.0);
    for (group, start) in [
        (FreezeGroup::FrameBlocks, frame_start),
        (FreezeGroup::GlobalBlocks, global_start),
    ] {
        let Some(start) = start else { continue };
        let layer_channels = m.depth.saturating_sub(start) as f64 * m.embed_dim as f64;
        if frozen(group) && recompute {
            recomputed += layer_channels;
        } else {
            channels += layer_channels;
        }
    }
    // Temporal blocks are never recomputed; they keep everything when they train or when
    // the gradient passes through them to a training backbone.
    if temporal_exists && (temporal_trains || backbone_trains) {
        channels += m.temporal_layers.len() as f64 * m.embed_dim as f64;
    }
    let mut block_token_channels = tokens * channels;
    if !frozen(FreezeGroup::PatchEmbed) {
        // DINO sees the same tokens per frame: class, registers, patches.
        block_token_channels += tokens * (m.dino.depth * m.dino.embed_dim) as f64;
    }

    let mut maps = 0.0;
    if !frozen(FreezeGroup::DepthHead) {
        maps += seen;
    }
    if !backbone_stage {
        if !frozen(FreezeGroup::GsHead) {
            maps += seen;
        }
        if !frozen(FreezeGroup::MotionHead) {
            maps += match m.motion_model {
                MotionModel::Lifting => (context * (frames - 1)) as f64,
                MotionModel::LinearVelocity => context as f64,
                MotionModel::Off => 0.0,
            };
        }
    }
    let rendered = if backbone_stage {
        0.0
    } else {
        b * frames as f64 * pixels
    };
    let lpips = if cfg.loss.lambda_lpips > 0.0 {
        rendered
    } else {
        0.0
    };
    Counts {
        block_token_channels,
        recomputed_token_channels: tokens * recomputed,
        dpt_pixel_channels: b * maps * pixels * m.dpt.features as f64,
        rendered_pixels: rendered,
        lpips_pixels: lpips,
    }
}

/// The estimate for `cfg`, whose model (built, its parameters may stay lazy) and frozen
/// split are given, with coefficients `k`.
pub fn estimate_with(
    cfg: &TrainConfig,
    model: &Envision4d,
    split: &ParamSplit,
    k: &Coefficients,
) -> StepMemory {
    let trainable = split.trainable_count as f64;
    let all = trainable + split.frozen_count as f64;
    let c = counts(cfg);
    let teaches = cfg.stage == Stage::Envision4d && cfg.teacher == Teacher::Backbone;
    let vggt = Vggt::of(model);
    let trainable_ids: HashSet<ParamId> = split.trainable.iter().copied().collect();
    let (teacher_first, teacher_later) = match (teaches, crate::step::teacher_is_init(cfg)) {
        (false, _) => (0.0, 0.0),
        // A snapshot: its trainable parts are copied by the first update.
        (true, true) => (0.0, F32 * count(&vggt, Some(&trainable_ids)) as f64),
        // A separate load: plain VGGT's weights a second time, from the start.
        (true, false) => {
            let own = F32 * count(&vggt, None) as f64;
            (own, own)
        }
    };
    StepMemory {
        runtime: k.runtime,
        parameters: F32 * all,
        lpips_weights: if cfg.loss.lambda_lpips > 0.0 {
            F32 * LPIPS_VGG_PARAMS as f64
        } else {
            0.0
        },
        gradients: F32 * trainable,
        optimizer: 2.0 * F32 * trainable,
        teacher_first,
        teacher_later,
        activations: k.block * c.block_token_channels
            + k.recomputed * c.recomputed_token_channels
            + k.dpt * c.dpt_pixel_channels
            + k.render * c.rendered_pixels
            + k.lpips * c.lpips_pixels,
        raster_bins: raster_bins(cfg),
        counts: c,
    }
}

/// Bytes the GPU forward keeps per Gaussian and rendered view for the backward: ten record
/// and six meta f32 lanes (`envision4d_splat::BackwardBins::Keep`).
pub const KEPT_BYTES_PER_GAUSSIAN: f64 = 64.0;
/// Tile intersections per visible Gaussian, 4 bytes each, of per-pixel Gaussians at 350x518:
/// 216 842 for 94 697 in the raster bench's street scene (`docs/PERFORMANCE.md`). The only
/// part of the kept bytes that depends on the scene.
pub const KEPT_INTERSECTIONS_PER_GAUSSIAN: f64 = 2.3;
/// Bytes the GPU forward keeps per pixel of every rendered view: its final transmittance
/// and last composited item, so the backward needs no replay of the compositing.
pub const KEPT_BYTES_PER_PIXEL: f64 = 8.0;

/// What the GPU rasterizer holds from a step's forward to its backward: every rendered view
/// (B x (T_c + T_f)) renders at most the T_c context frames' per-pixel Gaussians
/// (self-exclusive views fewer), so a bound; plus where each of its pixels stopped. 0 with
/// `[run] recompute_raster_bins` (whose backward then holds 28 bytes per pixel and view, a
/// scratch image and those ends, only while it runs) and in the backbone stage, which
/// renders nothing.
pub fn raster_bins(cfg: &TrainConfig) -> f64 {
    if cfg.run.recompute_raster_bins || cfg.stage == Stage::Backbone {
        return 0.0;
    }
    let m = &cfg.model;
    let [h, w] = m.image_size;
    let views = (cfg.optim.batch_size * m.num_frames()) as f64;
    let pixels = (h * w) as f64;
    let gaussians = m.context_frames as f64 * pixels;
    views
        * (gaussians * (KEPT_BYTES_PER_GAUSSIAN + 4.0 * KEPT_INTERSECTIONS_PER_GAUSSIAN)
            + pixels * KEPT_BYTES_PER_PIXEL)
}

/// [`estimate_with`] the [`FITTED`] coefficients.
pub fn estimate(cfg: &TrainConfig, model: &Envision4d, split: &ParamSplit) -> StepMemory {
    estimate_with(cfg, model, split, &FITTED)
}

/// Bytes in one GiB.
pub const GIB: f64 = (1u64 << 30) as f64;
