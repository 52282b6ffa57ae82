//! The attention's middle as one autodiff node: the packed q/k/v projection split into
//! heads, the qk-norm, RoPE and the lean attention (paper Sec. 3; the backbone's blocks).
//!
//! Why: Burn's autodiff has one output per node, so splitting the `[B, N, 3C]` projection
//! into q, k and v records three slices. Each slice's backward fills a zero tensor of the
//! whole projection's size and assigns its part into it, and the three are then summed:
//! eight launches, and passes over three times the projection, per attention backward, plus
//! the copy back out of the head layout (docs/PERFORMANCE.md, "Kernel launches of a step on
//! a GPU backend"). Here one node consumes the projection itself: the three gradients are
//! written into one uninitialised buffer in the projection's layout. On the CubeCL backends
//! the split and that merge are one kernel each ([`heads`]), where the reshape of each
//! permuted third was a copy (three a forward) and the merge three slice assignments.
//!
//! Inside, the node runs the same backend ops in the same order as the separate nodes do
//! ([`FusedNormOps`], [`RopeOps`], [`LeanAttentionOps`]), so values and gradients are the
//! same values (a negative zero, which the old sum with zeros made positive, stays
//! negative); only the bookkeeping between them changes. It is taken where all of those take
//! their fused kernels (CubeCL backends, f32; see [`takes_packed`]); the CPU backend, whose
//! qk-norm is Burn's own, keeps the separate ops.

pub mod heads;
mod node;

pub use heads::HeadsOps;

use super::lean_attention::LeanAttentionOps;
use super::norm::{FusedNormOps, NormNeeds};
use super::rope::RopeOps;
use burn::backend::tensor::FloatTensor;
use burn::backend::Dispatch;
use burn::backend::{backend_extension, Backend, ExtensionType, TensorMetadata};
use burn::tensor::{DType, Device, Tensor};
use std::sync::atomic::{AtomicBool, Ordering};

/// Whether autodiff attention on the CubeCL backends takes the one node (on by default; the
/// benchmarks' `--qkv burn` turns it off to measure the separate nodes).
static PACKED: AtomicBool = AtomicBool::new(true);

/// Switches the one node on or off for the whole process.
pub fn set_packed_qkv(on: bool) {
    PACKED.store(on, Ordering::Relaxed);
}

/// Whether the one node is on ([`set_packed_qkv`]).
pub fn packed_qkv_on() -> bool {
    PACKED.load(Ordering::Relaxed)
}

/// What the node needs besides its tensors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QkvLayout {
    pub heads: usize,
    /// The qk-norms' epsilon (unused without them).
    pub epsilon: f64,
    /// Score elements per block of query rows ([`super::lean_attention::BLOCK_ELEMENTS`]).
    pub block: usize,
}

/// The qk-norms' parameters as the op takes them.
#[derive(ExtensionType, Clone, Debug)]
pub enum QkNormParams<B: Backend> {
    Off,
    On(#[extension_type] QkNorms<B>),
}

/// RoPE's tables `[B or 1, 1, N, d]` (`sin` signed per quarter, as `RopeTables` keeps it).
#[derive(ExtensionType, Clone, Debug)]
pub enum RopeParams<B: Backend> {
    Off,
    On {
        cos: FloatTensor<B>,
        sin: FloatTensor<B>,
    },
}

/// `softmax(q kᵀ / sqrt(d)) v` `[B, H, N, d]` from the projection `qkv [B, N, 3C]` (the 3C
/// axis is `[q | k | v]`, each split into H heads of d), q and k layer-normalised per head
/// and then rotated, where `norms` and `rope` are on.
#[backend_extension(Cube, Flex, Autodiff)]
pub trait QkvAttentionOps: FusedNormOps + RopeOps + LeanAttentionOps + HeadsOps {
    fn qkv_attention(
        qkv: FloatTensor<Self>,
        #[extension_type] norms: QkNormParams<Self>,
        #[extension_type] rope: RopeParams<Self>,
        layout: QkvLayout,
    ) -> FloatTensor<Self> {
        let norms = norms.on();
        forward::<Self>(qkv, norms.as_ref(), tables(rope).as_ref(), layout).out
    }
}

impl QkvAttentionOps for burn::backend::Flex {}
impl QkvAttentionOps for burn_cubecl::CubeBackend {}

/// RoPE's tables as a pair, if on.
pub(crate) fn tables<B: Backend>(rope: RopeParams<B>) -> Option<(FloatTensor<B>, FloatTensor<B>)> {
    match rope {
        RopeParams::Off => None,
        RopeParams::On { cos, sin } => Some((cos, sin)),
    }
}

/// The qk-norms' parameters, each `[d]`.
#[derive(ExtensionType, Debug, Clone)]
pub struct QkNorms<B: Backend> {
    pub q_gamma: FloatTensor<B>,
    pub q_beta: FloatTensor<B>,
    pub k_gamma: FloatTensor<B>,
    pub k_beta: FloatTensor<B>,
}

impl<B: Backend> QkNormParams<B> {
    /// The parameters, if on.
    pub(crate) fn on(self) -> Option<QkNorms<B>> {
        match self {
            QkNormParams::Off => None,
            QkNormParams::On(p) => Some(p),
        }
    }
}

/// What the forward keeps for the backward: the norms' inputs and row statistics (with
/// norms), the rotated q and k, v, the output and its rows' log-sum-exp.
#[derive(Clone, Debug)]
pub(crate) struct Saved<B: Backend> {
    pub normed: Option<[NormSaved<B>; 2]>,
    pub q: FloatTensor<B>,
    pub k: FloatTensor<B>,
    pub v: FloatTensor<B>,
    pub out: FloatTensor<B>,
    pub lse: FloatTensor<B>,
}

/// One qk-norm's input and row statistics.
#[derive(Clone, Debug)]
pub(crate) struct NormSaved<B: Backend> {
    pub x: FloatTensor<B>,
    pub mean: FloatTensor<B>,
    pub rstd: FloatTensor<B>,
}

/// The forward on the inner backend, keeping what the backward reads.
pub(crate) fn forward<B: QkvAttentionOps>(
    qkv: FloatTensor<B>,
    norms: Option<&QkNorms<B>>,
    rope: Option<&(FloatTensor<B>, FloatTensor<B>)>,
    layout: QkvLayout,
) -> Saved<B> {
    let [mut q, mut k, v] = B::split_heads(qkv, layout.heads);
    let mut normed = None;
    if let Some(p) = norms {
        let norm = |x: FloatTensor<B>, gamma: &FloatTensor<B>, beta: &FloatTensor<B>| {
            let (y, mean, rstd) =
                B::fused_layer_norm_forward(x.clone(), gamma.clone(), beta.clone(), layout.epsilon);
            (y, NormSaved { x, mean, rstd })
        };
        let (qn, qs) = norm(q, &p.q_gamma, &p.q_beta);
        let (kn, ks) = norm(k, &p.k_gamma, &p.k_beta);
        (q, k) = (qn, kn);
        normed = Some([qs, ks]);
    }
    if let Some((cos, sin)) = rope {
        q = B::rope_forward(q, cos.clone(), sin.clone());
        k = B::rope_forward(k, cos.clone(), sin.clone());
    }
    let d = q.shape()[3];
    let scale = 1.0 / (d as f64).sqrt();
    let (out, lse) =
        B::lean_attention_forward(q.clone(), k.clone(), v.clone(), scale, layout.block);
    Saved {
        normed,
        q,
        k,
        v,
        out,
        lse,
    }
}

/// Gradients from the backward: the projection's (if asked) and the four norm parameters'
/// `[q_gamma, q_beta, k_gamma, k_beta]` (if asked and the node has norms).
pub(crate) struct QkvGrads<B: Backend> {
    pub qkv: Option<FloatTensor<B>>,
    pub norms: Option<[FloatTensor<B>; 4]>,
}

/// The backward on the inner backend, the separate nodes' ops in their order: attention,
/// then RoPE's and the norms' VJPs, then the merge into the projection's layout.
pub(crate) fn backward<B: QkvAttentionOps>(
    saved: Saved<B>,
    norms: Option<&QkNorms<B>>,
    rope: Option<&(FloatTensor<B>, FloatTensor<B>)>,
    grad: FloatTensor<B>,
    needs: [NormNeeds; 2],
    block: usize,
) -> QkvGrads<B> {
    let Saved {
        normed,
        q,
        k,
        v,
        out,
        lse,
    } = saved;
    let d = q.shape()[3];
    let scale = 1.0 / (d as f64).sqrt();
    let g = B::lean_attention_backward(q, k, v, out, lse, grad, scale, block);
    let (mut dq, mut dk) = (g.q, g.k);
    if let Some((cos, sin)) = rope {
        dq = B::rope_backward(dq, cos.clone(), sin.clone());
        dk = B::rope_backward(dk, cos.clone(), sin.clone());
    }
    let mut param_grads = None;
    if let (Some(p), Some([qs, ks])) = (norms, normed) {
        let [q_needs, k_needs] = needs;
        let gq =
            B::fused_layer_norm_backward(qs.x, p.q_gamma.clone(), qs.mean, qs.rstd, dq, q_needs);
        let gk =
            B::fused_layer_norm_backward(ks.x, p.k_gamma.clone(), ks.mean, ks.rstd, dk, k_needs);
        (dq, dk) = (gq.x, gk.x);
        // A norm whose parameters are frozen returns placeholders, which its untracked
        // parents never receive.
        if q_needs.params || k_needs.params {
            param_grads = Some([gq.gamma, gq.beta, gk.gamma, gk.beta]);
        }
    }
    QkvGrads {
        qkv: needs[0].input.then(|| B::merge_heads([dq, dk, g.v])),
        norms: param_grads,
    }
}

/// Whether [`Attention`](super::Attention) takes the one node for these tensors: autodiff on
/// a CubeCL device, f32 throughout, the switch on, and the qk-norm and RoPE, where present,
/// on their fused ops (else the separate path runs Burn's, so `--norm burn` and `--rope
/// burn` also turn the one node off). The lean attention's row kernels decide for
/// themselves inside either path.
pub fn takes_packed(device: &Device, dtype: DType, has_norms: bool, has_rope: bool) -> bool {
    packed_qkv_on()
        && device.is_autodiff()
        && *device != Device::flex()
        && dtype == DType::F32
        && (!has_norms || super::norm::takes_fused(device, dtype))
        && (!has_rope || super::rope::fused_rope_on())
}

/// The op through the dispatch backend: the qk-norms as `[q_gamma, q_beta, k_gamma, k_beta]`
/// and RoPE as `(cos, signed sin)`.
///
/// # Panics
/// On a projection whose width is not `3 · heads · d`, or a norm parameter whose length is
/// not the head width `d`, naming the widths: the split would mislabel the heads, and the
/// norm's kernels would read past the parameter.
pub fn qkv_attention(
    qkv: Tensor<3>,
    norms: Option<[Tensor<1>; 4]>,
    rope: Option<(Tensor<4>, Tensor<4>)>,
    layout: QkvLayout,
) -> Tensor<4> {
    let width = qkv.dims()[2];
    let heads = layout.heads;
    assert!(
        heads > 0 && width.is_multiple_of(3 * heads),
        "packed q/k/v projection of width {width} does not split into 3 x {heads} heads"
    );
    let head_dim = width / (3 * heads);
    if let Some(params) = &norms {
        let names = ["q_norm.gamma", "q_norm.beta", "k_norm.gamma", "k_norm.beta"];
        for (name, t) in names.iter().zip(params) {
            let len = t.dims()[0];
            assert_eq!(
                len, head_dim,
                "qk-norm {name} of width {len} applied to heads of {head_dim}"
            );
        }
    }
    let norms = match norms {
        None => QkNormParams::Off,
        Some([q_gamma, q_beta, k_gamma, k_beta]) => QkNormParams::On(QkNorms {
            q_gamma: q_gamma.into_dispatch(),
            q_beta: q_beta.into_dispatch(),
            k_gamma: k_gamma.into_dispatch(),
            k_beta: k_beta.into_dispatch(),
        }),
    };
    let rope = match rope {
        None => RopeParams::Off,
        Some((cos, sin)) => RopeParams::On {
            cos: cos.into_dispatch(),
            sin: sin.into_dispatch(),
        },
    };
    Tensor::from_dispatch(<Dispatch as QkvAttentionOps>::qkv_attention(
        qkv.into_dispatch(),
        norms,
        rope,
        layout,
    ))
}
