//! Multi-head self-attention as in VGGT/DINOv2: fused qkv projection, optional per-head
//! LayerNorm of q and k ("qk-norm"), optional 2D RoPE, softmax attention, output projection.

use super::cpu_attention;
use super::lean_attention::BLOCK_ELEMENTS;
use super::norm::{epsilon_of, layer_norm};
use super::qkv_attention::{qkv_attention, takes_packed, QkvLayout};
use super::rope::RopeTables;
use burn::module::Module;
use burn::nn::{LayerNorm, LayerNormConfig, Linear, LinearConfig};
use burn::tensor::module::attention;
use burn::tensor::ops::AttentionModuleOptions;
use burn::tensor::{DType, Device, Tensor};

/// LayerNorm epsilon of the q/k norms (PyTorch default).
pub const QK_NORM_EPS: f64 = 1e-5;

#[derive(Module, Debug)]
pub struct Attention {
    pub qkv: Linear,
    pub proj: Linear,
    pub q_norm: Option<LayerNorm>,
    pub k_norm: Option<LayerNorm>,
    pub num_heads: usize,
}

/// Whether q and k are layer-normalised per head before attention.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum QkNorm {
    On,
    Off,
}

impl Attention {
    pub fn new(dim: usize, num_heads: usize, qk_norm: QkNorm, device: &Device) -> Self {
        let head_dim = dim / num_heads;
        let norm = || {
            LayerNormConfig::new(head_dim)
                .with_epsilon(QK_NORM_EPS)
                .init(device)
        };
        Attention {
            qkv: LinearConfig::new(dim, 3 * dim).init(device),
            proj: LinearConfig::new(dim, dim).init(device),
            q_norm: (qk_norm == QkNorm::On).then(norm),
            k_norm: (qk_norm == QkNorm::On).then(norm),
            num_heads,
        }
    }

    /// `x: [B, N, C]` → `[B, N, C]`; `rope` rotates q and k after the qk-norm.
    pub fn forward(&self, x: Tensor<3>, rope: Option<&RopeTables>) -> Tensor<3> {
        self.proj.forward(self.heads(x, rope))
    }

    /// The heads' outputs side by side `[B, N, C]`, the input of `proj` (a block applies
    /// `proj` in its residual).
    pub fn heads(&self, x: Tensor<3>, rope: Option<&RopeTables>) -> Tensor<3> {
        let [b, n, c] = x.dims();
        let h = self.num_heads;
        let d = c / h;
        let qkv = self.qkv.forward(x);
        if let Some(out) = self.packed(qkv.clone(), rope) {
            return out.swap_dims(1, 2).reshape([b, n, c]);
        }
        // [B, N, 3C] -> [3, B, H, N, d]: the 3C axis is [q | k | v], each split into heads.
        let qkv = qkv.reshape([b, n, 3, h, d]).permute([2, 0, 3, 1, 4]);
        let part = |i: usize| {
            qkv.clone()
                .slice([i..i + 1, 0..b, 0..h, 0..n, 0..d])
                .reshape([b, h, n, d])
        };
        let (mut q, mut k, v) = (part(0), part(1), part(2));
        if let (Some(qn), Some(kn)) = (&self.q_norm, &self.k_norm) {
            q = layer_norm(qn, q);
            k = layer_norm(kn, k);
        }
        if let Some(r) = rope {
            q = r.apply(q);
            k = r.apply(k);
        }
        // softmax(q kᵀ / sqrt(d)) v. Inference on the CPU backend runs our kernel (vectorised
        // softmax, see `cpu_attention`); GPU inference Burn's op.
        let device = q.device();
        // Under autodiff, the lean op: Burn's decomposed attention would keep two [B, H, N, N]
        // tensors per layer for the backward (see `lean_attention`).
        let out = if super::cpu_inference(&q) {
            cpu_attention::attention(q, k, v)
        } else if device.is_autodiff() {
            super::lean_attention::lean_attention(q, k, v)
        } else {
            attention(q, k, v, None, None, AttentionModuleOptions::default())
        };
        out.swap_dims(1, 2).reshape([b, n, c])
    }

    /// The attention `[B, H, N, d]` as one autodiff node from the projection (see
    /// `qkv_attention`), where it applies: training on a GPU backend in f32 with the fused
    /// ops on; `None` elsewhere.
    fn packed(&self, qkv: Tensor<3>, rope: Option<&RopeTables>) -> Option<Tensor<4>> {
        let norms = self.q_norm.as_ref().zip(self.k_norm.as_ref());
        if !takes_packed(&qkv.device(), qkv.dtype(), norms.is_some(), rope.is_some()) {
            return None;
        }
        let mut epsilon = QK_NORM_EPS;
        let params = match norms {
            None => None,
            Some((qn, kn)) => {
                let (Some(qe), Some(ke)) = (epsilon_of(qn), epsilon_of(kn)) else {
                    return None;
                };
                let (Some(qb), Some(kb)) = (&qn.beta, &kn.beta) else {
                    return None;
                };
                if qe != ke {
                    return None;
                }
                epsilon = qe;
                let p = [qn.gamma.val(), qb.val(), kn.gamma.val(), kb.val()];
                if p.iter().any(|t| t.dtype() != DType::F32) {
                    return None;
                }
                Some(p)
            }
        };
        let tables = rope.map(|r| (r.cos.clone(), r.signed_sin.clone()));
        let layout = QkvLayout {
            heads: self.num_heads,
            epsilon,
            block: BLOCK_ELEMENTS,
        };
        Some(qkv_attention(qkv, params, tables, layout))
    }
}
