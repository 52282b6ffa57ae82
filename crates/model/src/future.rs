//! Future pose prediction (paper §3.3; `extra_token_offset`, `time_embedding`,
//! `extra_blocks` of the release).
//!
//! The last layer's camera tokens of the context frames are extended with T_f learned
//! offsets of the last context token, interleaved with time tokens (an MLP of a cos|sin
//! sinusoid of the 0-based frame index), refined by a shared 2-block stack applied several
//! times, and split back into refined camera tokens (→ camera head) and refined time tokens
//! (→ conditioned motion lifting). There is no positional encoding: pairing is by content.

use crate::config::{ModelConfig, MLP_RATIO, TIME_SINUSOID_DIM};
use crate::layers::{Block, BlockSpec, QkNorm, BLOCK_NORM_EPS};
use burn::module::{Module, Param};
use burn::nn::{Linear, LinearConfig};
use burn::tensor::activation::silu;
use burn::tensor::{Device, Distribution, Tensor, TensorData};

/// Base of the time sinusoid (`sinusoidal_embedding_1d`).
pub const SINUSOID_BASE: f64 = 10_000.0;
/// LayerScale init of new blocks (keeps a fresh module close to the identity).
pub const NEW_BLOCK_LAYER_SCALE: f64 = 0.01;

/// `[cos(p ω_k) | sin(p ω_k)]`, `ω_k = 10000^(-k / (dim/2))`, computed in f64 (as the
/// reference) and returned as f32 rows, one per position.
pub fn sinusoid(positions: &[f64], dim: usize) -> Vec<f32> {
    let half = dim / 2;
    let mut out = Vec::with_capacity(positions.len() * dim);
    for &p in positions {
        let omega = |k: usize| SINUSOID_BASE.powf(-(k as f64) / half as f64);
        out.extend((0..half).map(|k| (p * omega(k)).cos() as f32));
        out.extend((0..half).map(|k| (p * omega(k)).sin() as f32));
    }
    out
}

/// `Linear → SiLU → Linear` on the sinusoid (`time_embedding.{0,2}` in the release).
#[derive(Module, Debug)]
pub struct TimeEmbedding {
    pub fc1: Linear,
    pub fc2: Linear,
}

impl TimeEmbedding {
    pub fn new(width: usize, device: &Device) -> Self {
        TimeEmbedding {
            fc1: LinearConfig::new(TIME_SINUSOID_DIM, width).init(device),
            fc2: LinearConfig::new(width, width).init(device),
        }
    }

    pub fn forward(&self, x: Tensor<3>) -> Tensor<3> {
        self.fc2.forward(silu(self.fc1.forward(x)))
    }
}

/// What the future-pose module hands on.
#[derive(Debug, Clone)]
pub struct FutureTokens {
    /// `[B, N, 2C]` refined camera tokens of all N frames (camera-head input).
    pub camera: Tensor<3>,
    /// `[B, N, 2C]` refined time tokens (the motion prior E of conditioned motion lifting).
    pub time: Tensor<3>,
}

/// The future-pose module's parameters, named as in the release (`extra_token_offset` and
/// `extra_blocks` live on the model root; see [`crate::Envision4d`]).
#[derive(Module, Debug)]
pub struct FuturePose {
    pub extra_token_offset: Param<Tensor<3>>,
    pub extra_blocks: Vec<Block>,
    pub time_embedding: TimeEmbedding,
    pub iterations: usize,
}

impl FuturePose {
    pub fn new(cfg: &ModelConfig, device: &Device) -> Self {
        let width = 2 * cfg.embed_dim;
        let spec = BlockSpec {
            dim: width,
            num_heads: cfg.future_heads,
            mlp_ratio: MLP_RATIO,
            qk_norm: QkNorm::Off,
            norm_eps: BLOCK_NORM_EPS,
            layer_scale_init: NEW_BLOCK_LAYER_SCALE,
        };
        FuturePose {
            extra_token_offset: Param::from_tensor(Tensor::random(
                [1, cfg.future_frames, width],
                Distribution::Normal(0.0, 1.0),
                device,
            )),
            extra_blocks: (0..cfg.future_blocks)
                .map(|_| Block::new(spec, device))
                .collect(),
            time_embedding: TimeEmbedding::new(width, device),
            iterations: cfg.future_iterations,
        }
    }

    /// Time tokens `[1, N, 2C]` for frames `0..N` before refinement (`time_mlp`).
    pub fn time_tokens(&self, num_frames: usize, device: &Device) -> Tensor<3> {
        let positions: Vec<f64> = (0..num_frames).map(|t| t as f64).collect();
        let s = Tensor::from_data(
            TensorData::new(
                sinusoid(&positions, TIME_SINUSOID_DIM),
                [1, num_frames, TIME_SINUSOID_DIM],
            ),
            device,
        );
        self.time_embedding.forward(s)
    }

    /// `camera_tokens: [B, T_c, 2C]` (the last layer's raw camera tokens) → refined tokens of
    /// all `T_c + T_f` frames.
    pub fn forward(&self, camera_tokens: Tensor<3>) -> FutureTokens {
        let [b, tc, w] = camera_tokens.dims();
        let tf = self.extra_token_offset.dims()[1];
        let n = tc + tf;
        let last = camera_tokens.clone().slice([0..b, tc - 1..tc, 0..w]);
        let seeds = last + self.extra_token_offset.val();
        let z = Tensor::cat(vec![camera_tokens, seeds], 1);
        let e0 = self.time_tokens(n, &z.device()).expand([b, n, w]);
        // Interleave as separate tokens: [Z0, E0, Z1, E1, ...].
        let mut s = Tensor::stack::<4>(vec![z, e0], 2).reshape([b, 2 * n, w]);
        for _ in 0..self.iterations {
            for block in &self.extra_blocks {
                s = block.forward(s, None);
            }
        }
        let pairs = s.reshape([b, n, 2, w]);
        FutureTokens {
            camera: pairs
                .clone()
                .slice([0..b, 0..n, 0..1, 0..w])
                .reshape([b, n, w]),
            time: pairs.slice([0..b, 0..n, 1..2, 0..w]).reshape([b, n, w]),
        }
    }
}
