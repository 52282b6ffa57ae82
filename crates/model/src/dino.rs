//! DINOv2 ViT with register tokens, used as the aggregator's patch embedding
//! (`aggregator.patch_embed.` in the checkpoints).
//!
//! Patchify (conv k=s=patch) → prepend cls → add the pos-embed (antialiased-bicubic resized to
//! the patch grid; registers get none) → insert registers after cls → pre-norm blocks
//! (LayerNorm eps 1e-6, LayerScale, no qk-norm, no RoPE) → final norm → patch tokens.

use crate::config::{DinoConfig, MLP_RATIO};
use crate::layers::norm::layer_norm;
use crate::layers::{Block, BlockSpec, QkNorm, DINO_NORM_EPS};
use crate::resample::{aa_bicubic_weights, resample_separable};
use burn::module::{Module, Param};
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::{LayerNorm, LayerNormConfig};
use burn::tensor::{DType, Device, Distribution, Tensor};

/// LayerScale init of DINOv2 blocks.
pub const DINO_LAYER_SCALE: f64 = 1.0;

#[derive(Module, Debug)]
pub struct PatchProj {
    pub proj: Conv2d,
}

/// Everything DINO returns (the aggregator keeps only `patch_tokens`).
#[derive(Debug, Clone)]
pub struct DinoOutput {
    /// `[B, h*w, C]` normalised patch tokens, row-major.
    pub patch_tokens: Tensor<3>,
    /// `[B, C]` normalised cls token.
    pub cls_token: Tensor<2>,
    /// `[B, R, C]` normalised register tokens.
    pub reg_tokens: Tensor<3>,
    /// `[B, 1 + R + h*w, C]` before the final norm.
    pub prenorm: Tensor<3>,
}

#[derive(Module, Debug)]
pub struct Dino {
    pub cls_token: Param<Tensor<3>>,
    pub pos_embed: Param<Tensor<3>>,
    pub register_tokens: Param<Tensor<3>>,
    /// Unused in the forward pass, present in every checkpoint.
    pub mask_token: Param<Tensor<2>>,
    pub patch_embed: PatchProj,
    pub blocks: Vec<Block>,
    pub norm: LayerNorm,
    pub patch_size: usize,
}

impl Dino {
    pub fn new(cfg: &DinoConfig, patch_size: usize, num_registers: usize, device: &Device) -> Self {
        let c = cfg.embed_dim;
        let grid = cfg.img_size / patch_size;
        let spec = BlockSpec {
            dim: c,
            num_heads: cfg.num_heads,
            mlp_ratio: MLP_RATIO,
            qk_norm: QkNorm::Off,
            norm_eps: DINO_NORM_EPS,
            layer_scale_init: DINO_LAYER_SCALE,
        };
        let small = Distribution::Normal(0.0, 0.02);
        Dino {
            cls_token: Param::from_tensor(Tensor::random([1, 1, c], small, device)),
            pos_embed: Param::from_tensor(Tensor::random([1, 1 + grid * grid, c], small, device)),
            register_tokens: Param::from_tensor(Tensor::random(
                [1, num_registers, c],
                small,
                device,
            )),
            mask_token: Param::from_tensor(Tensor::zeros([1, c], device)),
            patch_embed: PatchProj {
                proj: Conv2dConfig::new([3, c], [patch_size, patch_size])
                    .with_stride([patch_size, patch_size])
                    .init(device),
            },
            blocks: (0..cfg.depth).map(|_| Block::new(spec, device)).collect(),
            norm: LayerNormConfig::new(c)
                .with_epsilon(DINO_NORM_EPS)
                .init(device),
            patch_size,
        }
    }

    /// The pos-embed for a `rows x cols` patch grid, `[1, 1 + rows*cols, C]` (cls first).
    pub fn interpolate_pos_embed(&self, rows: usize, cols: usize) -> Tensor<3> {
        let pe = self.pos_embed.val();
        let [_, n, c] = pe.dims();
        let m = ((n - 1) as f64).sqrt().round() as usize;
        // The pretraining grid is used as is (DINOv2 returns it unchanged).
        if rows == m && cols == m {
            return pe;
        }
        // Resampled in f32 whatever the weights' format (bicubic weights sum partial
        // products of opposite sign).
        let dtype = pe.dtype();
        let cls = pe.clone().slice([0..1, 0..1, 0..c]);
        let grid = pe
            .slice([0..1, 1..n, 0..c])
            .cast(DType::F32)
            .reshape([1, m, m, c])
            .permute([0, 3, 1, 2]);
        let resized = resample_separable(
            grid,
            aa_bicubic_weights(m, rows),
            aa_bicubic_weights(m, cols),
            rows,
            cols,
        );
        let patches = resized
            .permute([0, 2, 3, 1])
            .reshape([1, rows * cols, c])
            .cast(dtype);
        Tensor::cat(vec![cls, patches], 1)
    }

    /// `images: [B, 3, H, W]` (already normalised).
    pub fn forward(&self, images: Tensor<4>) -> DinoOutput {
        let [b, _, h, w] = images.dims();
        let (rows, cols) = (h / self.patch_size, w / self.patch_size);
        let x = self.patch_embed.proj.forward(images);
        let c = x.dims()[1];
        let patches = x.reshape([b, c, rows * cols]).swap_dims(1, 2);
        let cls = self.cls_token.val().expand([b, 1, c]);
        let x = Tensor::cat(vec![cls, patches], 1) + self.interpolate_pos_embed(rows, cols);
        let r = self.register_tokens.dims()[1];
        let regs = self.register_tokens.val().expand([b, r, c]);
        let n = x.dims()[1];
        let x = Tensor::cat(
            vec![
                x.clone().slice([0..b, 0..1, 0..c]),
                regs,
                x.slice([0..b, 1..n, 0..c]),
            ],
            1,
        );
        let prenorm = self.blocks.iter().fold(x, |x, blk| blk.forward(x, None));
        let normed = layer_norm(&self.norm, prenorm.clone());
        let total = normed.dims()[1];
        DinoOutput {
            cls_token: normed.clone().slice([0..b, 0..1, 0..c]).reshape([b, c]),
            reg_tokens: normed.clone().slice([0..b, 1..1 + r, 0..c]),
            patch_tokens: normed.slice([0..b, 1 + r..total, 0..c]),
            prenorm,
        }
    }
}
