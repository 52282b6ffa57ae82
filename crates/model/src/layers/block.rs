//! The pre-norm transformer block shared by every part of VGGT/Envision4D:
//! `x += γ1 ⊙ Attn(LN1(x))`, `x += γ2 ⊙ MLP(LN2(x))`.

use super::attention::{Attention, QkNorm};
use super::gelu::linear_gelu;
use super::norm::layer_norm;
use super::residual::projected_residual;
use super::rope::RopeTables;
use burn::module::{Module, Param};
use burn::nn::{LayerNorm, LayerNormConfig, Linear, LinearConfig};
use burn::tensor::{Device, Tensor};

/// LayerNorm epsilon of aggregator, temporal, camera and future-pose blocks.
pub const BLOCK_NORM_EPS: f64 = 1e-5;
/// LayerNorm epsilon of DINOv2 blocks.
pub const DINO_NORM_EPS: f64 = 1e-6;

/// LayerScale: a learned per-channel gain. Its parameter is called `gamma` in the checkpoints
/// although it is not a LayerNorm, so it must not be renamed on import.
#[derive(Module, Debug)]
pub struct LayerScale {
    pub gamma: Param<Tensor<1>>,
}

impl LayerScale {
    pub fn new(dim: usize, init: f64, device: &Device) -> Self {
        LayerScale {
            gamma: Param::from_tensor(Tensor::ones([dim], device).mul_scalar(init)),
        }
    }

    pub fn forward(&self, x: Tensor<3>) -> Tensor<3> {
        let dim = self.gamma.dims()[0];
        x * self.gamma.val().reshape([1, 1, dim])
    }

    /// `x + self.forward(layer(h))`, the block's residual after its projection: the
    /// projection's bias, the gain and the sum one fused op on a GPU backend
    /// ([`projected_residual`]), Burn's `Linear`, product and sum elsewhere.
    pub fn residual(&self, x: Tensor<3>, layer: &Linear, h: Tensor<3>) -> Tensor<3> {
        projected_residual(x, layer, h, self.gamma.val())
    }
}

/// `fc1 → GELU (erf) → fc2`; fc1's bias and the GELU are one op on a GPU backend
/// ([`linear_gelu`]).
#[derive(Module, Debug)]
pub struct Mlp {
    pub fc1: Linear,
    pub fc2: Linear,
}

impl Mlp {
    pub fn new(dim: usize, hidden: usize, device: &Device) -> Self {
        Self::with_output(dim, hidden, dim, device)
    }

    pub fn with_output(dim_in: usize, hidden: usize, dim_out: usize, device: &Device) -> Self {
        Mlp {
            fc1: LinearConfig::new(dim_in, hidden).init(device),
            fc2: LinearConfig::new(hidden, dim_out).init(device),
        }
    }

    pub fn forward<const D: usize>(&self, x: Tensor<D>) -> Tensor<D> {
        self.fc2.forward(self.hidden(x))
    }

    /// `GELU(fc1(x))`, the input of `fc2` (a block applies `fc2` in its residual).
    pub fn hidden<const D: usize>(&self, x: Tensor<D>) -> Tensor<D> {
        linear_gelu(&self.fc1, x)
    }
}

/// How a block is built: its width, heads, norms and initial LayerScale.
#[derive(Debug, Clone, Copy)]
pub struct BlockSpec {
    pub dim: usize,
    pub num_heads: usize,
    pub mlp_ratio: usize,
    pub qk_norm: QkNorm,
    pub norm_eps: f64,
    pub layer_scale_init: f64,
}

#[derive(Module, Debug)]
pub struct Block {
    pub norm1: LayerNorm,
    pub attn: Attention,
    pub ls1: LayerScale,
    pub norm2: LayerNorm,
    pub mlp: Mlp,
    pub ls2: LayerScale,
}

impl Block {
    pub fn new(spec: BlockSpec, device: &Device) -> Self {
        let norm = || {
            LayerNormConfig::new(spec.dim)
                .with_epsilon(spec.norm_eps)
                .init(device)
        };
        Block {
            norm1: norm(),
            attn: Attention::new(spec.dim, spec.num_heads, spec.qk_norm, device),
            ls1: LayerScale::new(spec.dim, spec.layer_scale_init, device),
            norm2: norm(),
            mlp: Mlp::new(spec.dim, spec.dim * spec.mlp_ratio, device),
            ls2: LayerScale::new(spec.dim, spec.layer_scale_init, device),
        }
    }

    /// `x: [B, N, C]`; `rope` only for frame/global blocks.
    pub fn forward(&self, x: Tensor<3>, rope: Option<&RopeTables>) -> Tensor<3> {
        let attended = self.attn.heads(layer_norm(&self.norm1, x.clone()), rope);
        let x = self.ls1.residual(x, &self.attn.proj, attended);
        let hidden = self.mlp.hidden(layer_norm(&self.norm2, x.clone()));
        self.ls2.residual(x, &self.mlp.fc2, hidden)
    }
}
