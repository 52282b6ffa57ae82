//! The Envision4D network (the release's `VGGT` module inside `EncoderEnvi4D`): aggregator with
//! temporal blocks → future-pose module → camera head (→ poses), plus the DPT heads.

use crate::adapter::{adapt, AdaptedGaussians, OpacityMapping, ScaleRange};
use crate::aggregator::{Aggregator, AggregatorOutput};
use crate::camera_head::CameraHead;
use crate::config::{ModelConfig, MotionModel};
use crate::dpt::{DptHead, DptKind};
use crate::future::{FuturePose, FutureTokens};
use crate::motion::{displacements, motion_tokens, still_displacements};
use crate::pose::pose_encoding_to_extri_intri;
use crate::precision::{cast_params, Precision};
use crate::vggt::run_depth_head;
pub use crate::vggt::{Vggt, VggtDepth, VggtOutput};
use burn::module::Module;
use burn::tensor::{Device, Tensor};

#[derive(Module, Debug)]
pub struct Envision4d {
    pub aggregator: Aggregator,
    pub camera_head: CameraHead,
    /// `extra_token_offset`, `extra_blocks`, `time_embedding` of the release.
    pub future: FuturePose,
    pub depth_head: DptHead,
    pub gs_head: DptHead,
    pub motion_head: DptHead,
    pub temporal_layers: [usize; 4],
    pub scale_min: f64,
    pub scale_max: f64,
    /// Frames per DPT-head pass (memory bound; results do not depend on it); 0 = as many as
    /// fit [`DPT_CHUNK_PIXELS`].
    pub dpt_frame_chunk: usize,
}

/// Default frames per DPT-head pass: automatic (see [`DPT_CHUNK_PIXELS`]).
pub const DEFAULT_DPT_FRAME_CHUNK: usize = 0;

/// Pixels per automatic DPT-head pass: one 350x518 frame. At the paper's image size that is
/// one frame at a time, which keeps the paper-size model's CPU inference well inside 24 GiB;
/// at the 56x84 of the CPU training configs it is every map at once, so the 14 motion maps
/// of a step are one pass of each op instead of 14 (forward + backward 0.73 -> 0.47-0.53 s for the
/// tiny model, docs/PERFORMANCE.md).
pub const DPT_CHUNK_PIXELS: usize = 350 * 518;

/// The frames per DPT-head pass that `chunk` (0 = automatic) means at `image_hw`.
pub fn dpt_chunk_frames(chunk: usize, image_hw: [usize; 2]) -> usize {
    if chunk > 0 {
        chunk
    } else {
        (DPT_CHUNK_PIXELS / (image_hw[0] * image_hw[1]).max(1)).max(1)
    }
}

/// Which heads a forward pass runs ("leave out what a command does not need").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Heads {
    pub depth: bool,
    pub gaussians: bool,
    pub motion: bool,
}

impl Heads {
    pub const ALL: Heads = Heads {
        depth: true,
        gaussians: true,
        motion: true,
    };
    /// Poses only (the backbone and camera head).
    pub const NONE: Heads = Heads {
        depth: false,
        gaussians: false,
        motion: false,
    };
}

/// Raw network predictions, named as the fixtures and `--export-predictions` name them.
#[derive(Debug, Clone)]
pub struct Predictions {
    pub backbone: BackboneOutput,
    /// `[B, T_c, H, W, 1]` (exp).
    pub depth: Option<Tensor<5>>,
    /// `[B, T_c, H, W]` (1 + exp).
    pub depth_conf: Option<Tensor<4>>,
    /// `[B, T_c, H, W, 11]` raw Gaussian parameters.
    pub gaussians: Option<Tensor<5>>,
    /// `[B, T_c·(N-1), H, W, 3]` raw displacements, source-major.
    pub motion_enc: Option<Tensor<5>>,
    /// The four lifted token maps fed to the motion head, `[B, T_c·(N-1), hw, 2C]`.
    pub motion_tokens: Option<[Tensor<4>; 4]>,
}

/// Backbone outputs: tokens for the heads and the predicted cameras.
#[derive(Debug, Clone)]
pub struct BackboneOutput {
    pub aggregator: AggregatorOutput,
    pub tokens: FutureTokens,
    /// `[B, N, 9]` after each camera-head iteration; the last is the prediction.
    pub pose_enc_iters: Vec<Tensor<3>>,
    /// `[B, N, 4, 4]` world-to-camera (the first context camera is the world).
    pub extrinsics: Tensor<4>,
    /// `[B, N, 3, 3]` pixel intrinsics.
    pub intrinsics: Tensor<4>,
}

impl BackboneOutput {
    pub fn pose_enc(&self) -> Tensor<3> {
        self.pose_enc_iters.last().expect("camera head ran").clone()
    }
}

impl Envision4d {
    pub fn new(cfg: &ModelConfig, device: &Device) -> Self {
        // Under the initialisation lock: the eager random draws below must not interleave
        // with another thread's seeded build (`seeded`).
        crate::seeded::with_init_lock(|| Self::build(cfg, device))
    }

    fn build(cfg: &ModelConfig, device: &Device) -> Self {
        let dpt = |kind| DptHead::new(kind, 2 * cfg.embed_dim, &cfg.dpt, cfg.patch_size, device);
        Envision4d {
            aggregator: Aggregator::new(cfg, device),
            camera_head: CameraHead::new(2 * cfg.embed_dim, cfg.camera_heads, device),
            future: FuturePose::new(cfg, device),
            depth_head: dpt(DptKind::Depth),
            gs_head: dpt(DptKind::Gaussians),
            motion_head: dpt(DptKind::Motion(cfg.motion_model)),
            temporal_layers: cfg.temporal_layers,
            scale_min: cfg.gaussian_scale_min,
            scale_max: cfg.gaussian_scale_max,
            dpt_frame_chunk: DEFAULT_DPT_FRAME_CHUNK,
        }
    }

    /// The full forward pass on context images `[B, T_c, 3, H, W]` in [0, 1].
    pub fn forward(&self, images: Tensor<5>, heads: Heads) -> Predictions {
        let [b, tc, _, h, w] = images.dims();
        let device = images.device();
        let taps_idx = self.temporal_layers;
        let backbone = self.backbone(images, &taps_idx);
        let agg = &backbone.aggregator;
        let taps: [Tensor<4>; 4] = taps_idx.map(|l| agg.layer(l));
        let (depth, depth_conf) = if heads.depth {
            let (d, c) = self.depth(&taps, agg.patch_start, [h, w]);
            (Some(d), Some(c))
        } else {
            (None, None)
        };
        let gaussians = heads.gaussians.then(|| {
            self.gs_head.forward_chunked(
                &taps,
                agg.patch_start,
                [h, w],
                Some(agg.norm_images.clone()),
                self.dpt_frame_chunk,
            )
        });
        let model = self
            .motion_head
            .motion_model()
            .expect("motion_head is built as a motion head");
        let (motion_enc, motion_tokens) = if !heads.motion {
            (None, None)
        } else if model == MotionModel::Off {
            // Nothing moves: the head (and its tokens) is skipped altogether.
            let n = backbone.tokens.time.dims()[1];
            (Some(still_displacements(b, tc, n, [h, w], &device)), None)
        } else {
            let time = backbone.tokens.time.clone();
            let n = time.dims()[1];
            let tokens = motion_tokens(model, &agg.time_list, time, agg.patch_start);
            // The motion maps carry patch tokens only, so they start at index 0.
            let raw =
                self.motion_head
                    .forward_chunked(&tokens, 0, [h, w], None, self.dpt_frame_chunk);
            (Some(displacements(model, raw, n)), Some(tokens))
        };
        Predictions {
            backbone,
            depth,
            depth_conf,
            gaussians,
            motion_enc,
            motion_tokens,
        }
    }

    /// `images: [B, T_c, 3, H, W]` in [0, 1] → tokens and cameras of all `T_c + T_f` frames.
    pub fn backbone(&self, images: Tensor<5>, taps: &[usize]) -> BackboneOutput {
        let [_, _, _, h, w] = images.dims();
        let last = self.aggregator.frame_blocks.len() - 1;
        let mut keep = taps.to_vec();
        keep.push(last);
        let agg = self.aggregator.forward(images, &keep);
        let top = agg.layer(last);
        let [b, s, _, c2] = top.dims();
        let camera_tokens = top.slice([0..b, 0..s, 0..1, 0..c2]).reshape([b, s, c2]);
        let tokens = self.future.forward(camera_tokens);
        let pose_enc_iters = self.camera_head.forward(tokens.camera.clone());
        let (extrinsics, intrinsics) =
            pose_encoding_to_extri_intri(pose_enc_iters.last().unwrap().clone(), h, w);
        BackboneOutput {
            aggregator: agg,
            tokens,
            pose_enc_iters,
            extrinsics,
            intrinsics,
        }
    }

    /// `T_f`: the number of learned future seeds (future frames a forward predicts).
    pub fn future_frames(&self) -> usize {
        self.future.extra_token_offset.dims()[1]
    }

    /// The device the parameters live on (inputs are created there).
    pub fn device(&self) -> Device {
        self.future.extra_token_offset.val().device()
    }

    /// The same network with its aggregator in `precision` (weights cast now, activations
    /// at every forward; see [`crate::precision`]). For inference: the cast weights are the
    /// ones a checkpoint saved from this model would hold.
    pub fn with_precision(mut self, precision: Precision) -> Envision4d {
        self.aggregator = cast_params(self.aggregator, precision.dtype());
        self.aggregator.precision = precision;
        self
    }

    /// The precision of the aggregator ([`Envision4d::with_precision`]).
    pub fn precision(&self) -> Precision {
        self.aggregator.precision
    }

    /// The same network predicting only its first `horizon` future frames (its first
    /// `horizon` learned future seeds; the rest is shared). `None` unless
    /// `1 <= horizon <= T_f`.
    pub fn with_horizon(&self, horizon: usize) -> Option<Envision4d> {
        let [one, tf, width] = self.future.extra_token_offset.dims();
        if horizon == 0 || horizon > tf {
            return None;
        }
        let mut m = self.clone();
        let seeds = m
            .future
            .extra_token_offset
            .val()
            .slice([0..one, 0..horizon, 0..width]);
        m.future.extra_token_offset = burn::module::Param::from_tensor(seeds);
        Some(m)
    }

    /// World-space Gaussians of the context frames (needs the depth, Gaussian and motion
    /// heads). `step` drives the opacity schedule (identity for the released config).
    pub fn adapt(
        &self,
        p: &Predictions,
        opacity: OpacityMapping,
        step: u64,
    ) -> Option<AdaptedGaussians> {
        let (depth, raw, motion) = (
            p.depth.clone()?,
            p.gaussians.clone()?,
            p.motion_enc.clone()?,
        );
        let [b, s, h, w, c] = raw.dims();
        let bb = &p.backbone;
        let extr = bb.extrinsics.clone().slice([0..b, 0..s, 0..4, 0..4]);
        // Normalised intrinsics: row 0 / W, row 1 / H.
        let scale =
            Tensor::<1>::from_floats([1.0 / w as f32, 1.0 / h as f32, 1.0], &depth.device())
                .reshape([1, 1, 3, 1]);
        let intr_n = bb.intrinsics.clone().slice([0..b, 0..s, 0..3, 0..3]) * scale;
        let opac = opacity.apply(
            burn::tensor::activation::sigmoid(
                raw.clone()
                    .slice([0..b, 0..s, 0..h, 0..w, 0..1])
                    .reshape([b, s, h, w]),
            ),
            step,
        );
        let rest = raw.slice([0..b, 0..s, 0..h, 0..w, 1..c]);
        Some(adapt(
            extr,
            intr_n,
            depth.reshape([b, s, h, w]),
            opac,
            rest,
            motion,
            ScaleRange {
                min: self.scale_min,
                max: self.scale_max,
            },
        ))
    }

    /// The depth head on the DPT taps: `([B, S, H, W, 1]` depth, `[B, S, H, W]` confidence`)`.
    fn depth(
        &self,
        taps: &[Tensor<4>; 4],
        patch_start: usize,
        size: [usize; 2],
    ) -> (Tensor<5>, Tensor<4>) {
        run_depth_head(
            &self.depth_head,
            taps,
            patch_start,
            size,
            self.dpt_frame_chunk,
        )
    }

    /// Plain VGGT on `images [B, S, 3, H, W]` (see [`Vggt`]): the backbone stage's network
    /// and the frozen distillation teacher (paper §3.4: "a frozen VGGT backbone").
    pub fn vggt(&self, images: Tensor<5>, depth: VggtDepth) -> VggtOutput {
        Vggt::of(self).forward(images, depth)
    }
}
