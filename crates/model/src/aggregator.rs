//! The VGGT aggregator with Envision4D's in-layer temporal attention (paper §3.2).
//!
//! Per context frame: `[camera | registers | DINO patch tokens]`. Each layer runs a frame
//! block (attention within one image) then a global block (attention across all frames), both
//! with 2D RoPE. After the global blocks listed in `temporal_layers`, a temporal block attends
//! over time for every token slot and its output continues into the next layer.
//!
//! The ablation [`TemporalPlacement::PostLayer`] ("appending the temporal attention module
//! after frozen backbone", paper §4.3) runs every layer untouched, so `output_list` (the DPT
//! taps and the camera tokens) is plain VGGT, then applies the same four temporal blocks one
//! after another to the last layer's global output: `Y_0 = T_0(G_last)`, `Y_t = T_t(Y_{t−1})`.
//! Its `time_list[t] = cat(G_{ℓ_t}, Y_t)` keeps the in-layer form (global output at tap layer
//! ℓ_t, then a temporal output): the global halves stay a shallow-to-deep pyramid for the
//! motion DPT and equal the in-layer model's pre-temporal taps in kind, so the ablation moves
//! only where temporal attention acts; the temporal halves get deeper with t, as in-layer.

use crate::config::{ModelConfig, TemporalPlacement, MLP_RATIO};
use crate::dino::Dino;
use crate::future::NEW_BLOCK_LAYER_SCALE;
use crate::layers::recompute;
use crate::layers::{frame_positions, Block, BlockSpec, QkNorm, RopeTables, BLOCK_NORM_EPS};
use crate::precision::Precision;
use burn::module::{Module, Param};
use burn::tensor::{DType, Device, Distribution, Tensor, TensorData};

/// ImageNet normalisation (`_resnet_mean`, `_resnet_std`).
pub const IMAGENET_MEAN: [f32; 3] = [0.485, 0.456, 0.406];
pub const IMAGENET_STD: [f32; 3] = [0.229, 0.224, 0.225];

/// Whether the temporal blocks run (Envision4D, where the config places them) or are skipped
/// (plain VGGT).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Temporal {
    Apply,
    Skip,
}

#[derive(Module, Debug)]
pub struct Aggregator {
    pub patch_embed: Dino,
    /// `[1, 2, 1, C]`: index 0 for frame 0, index 1 shared by the other frames.
    pub camera_token: Param<Tensor<4>>,
    /// `[1, 2, R, C]`, same convention.
    pub register_token: Param<Tensor<4>>,
    pub frame_blocks: Vec<Block>,
    pub global_blocks: Vec<Block>,
    pub time_blocks: Vec<Block>,
    pub temporal_layers: [usize; 4],
    pub num_heads: usize,
    /// Where [`Temporal::Apply`] runs the temporal blocks (from the config; not a parameter).
    #[module(skip)]
    pub placement: TemporalPlacement,
    /// What training keeps of the frozen frame and global blocks (a run setting, not a
    /// parameter; see [`BlockMemory`]).
    #[module(skip)]
    pub block_memory: BlockMemory,
    /// The float format of the aggregator's weights and activations (an inference setting;
    /// see [`crate::precision`]). Its outputs are f32 whatever it is.
    #[module(skip)]
    pub precision: Precision,
}

/// What the backward keeps of a frame or global block whose parameters are frozen.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum BlockMemory {
    /// Every intermediate, as autodiff records them (fastest; the most memory).
    #[default]
    Keep,
    /// Only the block's input; the backward runs the block again
    /// ([`crate::layers::recompute`]). Trainable blocks are always kept.
    RecomputeFrozen,
}

/// What the aggregator produces for the heads.
#[derive(Debug, Clone)]
pub struct AggregatorOutput {
    /// `output_list[l] = cat(frame_l, global_l)`, `[B, S, P, 2C]`, only for the layers asked for.
    pub layers: Vec<(usize, Tensor<4>)>,
    /// `time_list[t] = cat(global_l, temporal_l)` at the temporal layers, `[B, S, P, 2C]`.
    pub time_list: Vec<Tensor<4>>,
    /// `[B, S, 3, H, W]` ImageNet-normalised images (the GS head reads them).
    pub norm_images: Tensor<5>,
    /// Index of the first patch token (1 camera + R registers).
    pub patch_start: usize,
}

impl AggregatorOutput {
    pub fn layer(&self, l: usize) -> Tensor<4> {
        self.layers
            .iter()
            .find(|(i, _)| *i == l)
            .map(|(_, t)| t.clone())
            .unwrap_or_else(|| panic!("aggregator layer {l} was not kept"))
    }
}

/// ImageNet normalisation of `[B, S, 3, H, W]` images in [0, 1].
pub fn normalize_images(images: Tensor<5>) -> Tensor<5> {
    let device = images.device();
    let v =
        |a: [f32; 3]| Tensor::<5>::from_data(TensorData::new(a.to_vec(), [1, 1, 3, 1, 1]), &device);
    (images - v(IMAGENET_MEAN)) / v(IMAGENET_STD)
}

impl Aggregator {
    pub fn new(cfg: &ModelConfig, device: &Device) -> Self {
        let c = cfg.embed_dim;
        let spec = |rope_layer: bool| BlockSpec {
            dim: c,
            num_heads: cfg.num_heads,
            mlp_ratio: MLP_RATIO,
            qk_norm: QkNorm::On,
            norm_eps: BLOCK_NORM_EPS,
            layer_scale_init: if rope_layer {
                0.01
            } else {
                NEW_BLOCK_LAYER_SCALE
            },
        };
        let tiny = Distribution::Normal(0.0, 1e-6);
        Aggregator {
            patch_embed: Dino::new(&cfg.dino, cfg.patch_size, cfg.num_register_tokens, device),
            camera_token: Param::from_tensor(Tensor::random([1, 2, 1, c], tiny, device)),
            register_token: Param::from_tensor(Tensor::random(
                [1, 2, cfg.num_register_tokens, c],
                tiny,
                device,
            )),
            frame_blocks: (0..cfg.depth)
                .map(|_| Block::new(spec(true), device))
                .collect(),
            global_blocks: (0..cfg.depth)
                .map(|_| Block::new(spec(true), device))
                .collect(),
            // Without temporal attention no temporal block exists (nothing to train or load).
            time_blocks: match cfg.temporal_attention {
                TemporalPlacement::None => Vec::new(),
                _ => (0..cfg.temporal_layers.len())
                    .map(|_| Block::new(spec(false), device))
                    .collect(),
            },
            temporal_layers: cfg.temporal_layers,
            num_heads: cfg.num_heads,
            placement: cfg.temporal_attention,
            block_memory: BlockMemory::default(),
            precision: Precision::default(),
        }
    }

    /// Special tokens for S frames: frame 0 takes index 0, the others index 1. `[S, n, C]`.
    fn special(&self, token: &Param<Tensor<4>>, s: usize) -> Tensor<3> {
        let [_, _, n, c] = token.dims();
        let t = token.val();
        let first = t.clone().slice([0..1, 0..1, 0..n, 0..c]).reshape([1, n, c]);
        let rest = t
            .slice([0..1, 1..2, 0..n, 0..c])
            .reshape([1, n, c])
            .expand([s - 1, n, c]);
        Tensor::cat(vec![first, rest], 0)
    }

    /// `images: [B, S, 3, H, W]` in [0, 1]; `keep` lists the layers whose `output_list` entry
    /// is returned (the DPT taps and the last layer).
    pub fn forward(&self, images: Tensor<5>, keep: &[usize]) -> AggregatorOutput {
        self.forward_with(images, keep, Temporal::Apply)
    }

    /// [`Aggregator::forward`] with the temporal blocks applied (at `self.placement`) or
    /// skipped; skipped, this is VGGT's aggregator exactly (the backbone stage and the
    /// distillation teacher) and `time_list` is empty.
    pub fn forward_with(
        &self,
        images: Tensor<5>,
        keep: &[usize],
        temporal: Temporal,
    ) -> AggregatorOutput {
        let [b, s, _, h, w] = images.dims();
        let norm_images = normalize_images(images);
        let patch = self.patch_embed.patch_size;
        let (rows, cols) = (h / patch, w / patch);
        // Reduced precision starts at the patch embedding and ends at the outputs (`out`).
        let dtype = self.precision.dtype();
        let out = |t: Tensor<4>| t.cast(DType::F32);
        let dino = self
            .patch_embed
            .forward(norm_images.clone().reshape([b * s, 3, h, w]).cast(dtype));
        let patches = dino.patch_tokens;
        let c = patches.dims()[2];
        let cam = self.special(&self.camera_token, s);
        let reg = self.special(&self.register_token, s);
        let special = Tensor::cat(vec![cam, reg], 1);
        let n_special = special.dims()[1];
        let special = special
            .unsqueeze::<4>()
            .expand([b, s, n_special, c])
            .reshape([b * s, n_special, c]);
        let mut x = Tensor::cat(vec![special, patches], 1);
        let p = x.dims()[1];

        let device = x.device();
        let head_dim = c / self.num_heads;
        let frame_pos = frame_positions(n_special, rows, cols);
        let rope_frame =
            RopeTables::new(&vec![frame_pos.clone(); b * s], head_dim, &device).cast(dtype);
        let global_pos: Vec<[i64; 2]> = (0..s).flat_map(|_| frame_pos.iter().copied()).collect();
        let rope_global = RopeTables::new(&vec![global_pos; b], head_dim, &device).cast(dtype);

        let placement = match temporal {
            Temporal::Apply => Some(self.placement),
            Temporal::Skip => None,
        };
        let mut layers = Vec::new();
        let mut time_list = Vec::new();
        // PostLayer: the global outputs at the temporal layers, and the last one.
        let mut tap_globals = Vec::new();
        let mut last_global = None;
        for l in 0..self.frame_blocks.len() {
            let f = self.run_block(&self.frame_blocks[l], x.reshape([b * s, p, c]), &rope_frame);
            let g = self
                .run_block(
                    &self.global_blocks[l],
                    f.clone().reshape([b, s * p, c]),
                    &rope_global,
                )
                .reshape([b, s, p, c]);
            x = g.clone().reshape([b * s, p, c]);
            let time_block = self.temporal_layers.iter().position(|&tl| tl == l);
            match (placement, time_block) {
                (Some(TemporalPlacement::InLayer), Some(t)) => {
                    let y = self.temporal_block(t, g.clone());
                    time_list.push(out(Tensor::cat(vec![g.clone(), y.clone()], 3)));
                    x = y.reshape([b * s, p, c]);
                }
                (Some(TemporalPlacement::PostLayer), Some(_)) => tap_globals.push(g.clone()),
                (Some(TemporalPlacement::None), Some(_)) => {
                    time_list.push(out(Tensor::cat(vec![g.clone(), g.clone()], 3)));
                }
                _ => {}
            }
            if keep.contains(&l) {
                layers.push((
                    l,
                    out(Tensor::cat(vec![f.reshape([b, s, p, c]), g.clone()], 3)),
                ));
            }
            last_global = Some(g);
        }
        if placement == Some(TemporalPlacement::PostLayer) {
            let mut y = last_global.expect("the aggregator has at least one layer");
            for (t, g) in tap_globals.into_iter().enumerate() {
                y = self.temporal_block(t, y);
                time_list.push(out(Tensor::cat(vec![g, y.clone()], 3)));
            }
        }
        AggregatorOutput {
            layers,
            time_list,
            norm_images,
            patch_start: n_special,
        }
    }

    /// A frame or global block, recomputed in the backward when [`BlockMemory`] asks for it
    /// and the block is frozen.
    fn run_block(&self, block: &Block, x: Tensor<3>, rope: &RopeTables) -> Tensor<3> {
        match self.block_memory {
            BlockMemory::RecomputeFrozen if recompute::is_frozen(block) => {
                recompute::forward_recomputed(block, x, Some(rope))
            }
            _ => block.forward(x, Some(rope)),
        }
    }

    /// Temporal block `t` on `[B, S, P, C]` tokens: each token slot attends over the S frames
    /// (no positional encoding in time, as in the release).
    fn temporal_block(&self, t: usize, tokens: Tensor<4>) -> Tensor<4> {
        let [b, s, p, c] = tokens.dims();
        // [B, S, P, C] -> [B*P, S, C]: a sequence over time for each token slot.
        let seq = tokens.swap_dims(1, 2).reshape([b * p, s, c]);
        self.time_blocks[t]
            .forward(seq, None)
            .reshape([b, p, s, c])
            .swap_dims(1, 2)
    }
}
