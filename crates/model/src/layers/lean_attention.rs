//! Softmax attention that trains in O(N·D) memory: the autodiff node keeps q, k, v, the
//! output and every query row's log-sum-exp, not the probabilities; forward and backward
//! work a block of query rows at a time and the backward recomputes each block's
//! probabilities from the log-sum-exp (FlashAttention's recurrence, written with ordinary
//! tensor ops). Burn's decomposed attention keeps the scores and the probabilities, two
//! `[B, H, N, N]` tensors per layer: about 450 MB per global layer at 350x518 with two
//! frames, 10 GB over the aggregator, which is what kept a paper-size training step from
//! fitting in 24 GiB (docs/PERFORMANCE.md).

use burn::backend::autodiff::checkpoint::{base::Checkpointer, strategy::CheckpointStrategy};
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::backend::autodiff::Autodiff;
use burn::backend::tensor::FloatTensor;
use burn::backend::Dispatch;
use burn::backend::{backend_extension, Backend, ExtensionType, Scalar, TensorMetadata};
use burn::tensor::{Slice, Tensor};

/// Elements of one block's `[B, H, rows, N]` scores: blocks are sized to stay near this
/// (64 MB in f32), whatever N.
pub const BLOCK_ELEMENTS: usize = 1 << 24;

/// Gradients of q, k and v.
#[derive(ExtensionType)]
pub struct AttentionGrads<B: Backend> {
    pub q: FloatTensor<B>,
    pub k: FloatTensor<B>,
    pub v: FloatTensor<B>,
}

/// The op. Shapes: q `[B, H, Nq, D]`, k and v `[B, H, Nk, D]`; `scale` multiplies q kᵀ;
/// blocks of query rows hold about `block` score elements.
#[backend_extension(Cube, Flex, Autodiff)]
pub trait LeanAttentionOps: Backend {
    /// `(softmax(q kᵀ · scale) v [B, H, Nq, D], log-sum-exp of each row [B, H, Nq, 1])`.
    fn lean_attention_forward(
        q: FloatTensor<Self>,
        k: FloatTensor<Self>,
        v: FloatTensor<Self>,
        scale: f64,
        block: usize,
    ) -> (FloatTensor<Self>, FloatTensor<Self>) {
        forward::<Self>(q, k, v, scale, block)
    }

    /// Vector-Jacobian product of the output w.r.t. q, k and v.
    #[allow(clippy::too_many_arguments)]
    fn lean_attention_backward(
        q: FloatTensor<Self>,
        k: FloatTensor<Self>,
        v: FloatTensor<Self>,
        out: FloatTensor<Self>,
        lse: FloatTensor<Self>,
        grad: FloatTensor<Self>,
        scale: f64,
        block: usize,
    ) -> AttentionGrads<Self> {
        backward::<Self>(q, k, v, out, lse, grad, scale, block)
    }
}

impl LeanAttentionOps for burn::backend::Flex {}
impl LeanAttentionOps for burn_cubecl::CubeBackend {}

/// Query rows per block for `[b, h, _, nk]` scores.
fn block_rows(dims: &[usize], nk: usize, block: usize) -> usize {
    (block / (dims[0] * dims[1] * nk).max(1)).max(1)
}

fn rows<B: Backend>(t: &FloatTensor<B>, r: std::ops::Range<usize>) -> FloatTensor<B> {
    let d = t.shape().to_vec();
    B::float_slice(
        t.clone(),
        &[
            Slice::from(0..d[0]),
            Slice::from(0..d[1]),
            Slice::from(r),
            Slice::from(0..d[3]),
        ],
    )
}

/// `q_block kᵀ · scale`.
fn scores<B: Backend>(qb: FloatTensor<B>, kt: &FloatTensor<B>, scale: f64) -> FloatTensor<B> {
    B::float_mul_scalar(B::float_matmul(qb, kt.clone()), Scalar::Float(scale))
}

fn forward<B: Backend>(
    q: FloatTensor<B>,
    k: FloatTensor<B>,
    v: FloatTensor<B>,
    scale: f64,
    block: usize,
) -> (FloatTensor<B>, FloatTensor<B>) {
    let dims = q.shape().to_vec();
    let (nq, nk) = (dims[2], k.shape()[2]);
    let kt = B::float_swap_dims(k, 2, 3);
    let step = block_rows(&dims, nk, block);
    let (mut outs, mut lses) = (Vec::new(), Vec::new());
    for r0 in (0..nq).step_by(step) {
        let s = scores::<B>(rows::<B>(&q, r0..(r0 + step).min(nq)), &kt, scale);
        let m = B::float_max_dim(s.clone(), 3);
        let p = B::float_exp(B::float_sub(s, m.clone()));
        let l = B::float_sum_dim(p.clone(), 3);
        outs.push(B::float_div(B::float_matmul(p, v.clone()), l.clone()));
        lses.push(B::float_add(m, B::float_log(l)));
    }
    (B::float_cat(outs, 2), B::float_cat(lses, 2))
}

#[allow(clippy::too_many_arguments)]
fn backward<B: Backend>(
    q: FloatTensor<B>,
    k: FloatTensor<B>,
    v: FloatTensor<B>,
    out: FloatTensor<B>,
    lse: FloatTensor<B>,
    grad: FloatTensor<B>,
    scale: f64,
    block: usize,
) -> AttentionGrads<B> {
    let dims = q.shape().to_vec();
    let (nq, nk) = (dims[2], k.shape()[2]);
    // Δ_i = Σ_d dO_id O_id = Σ_j P_ij dP_ij: the softmax VJP's row term.
    let delta = B::float_sum_dim(B::float_mul(grad.clone(), out), 3);
    let kt = B::float_swap_dims(k.clone(), 2, 3);
    let vt = B::float_swap_dims(v.clone(), 2, 3);
    let step = block_rows(&dims, nk, block);
    let mut dq = Vec::new();
    let (mut dk, mut dv): (Option<FloatTensor<B>>, Option<FloatTensor<B>>) = (None, None);
    let acc = |a: Option<FloatTensor<B>>, b: FloatTensor<B>| match a {
        None => Some(b),
        Some(a) => Some(B::float_add(a, b)),
    };
    for r0 in (0..nq).step_by(step) {
        let r = r0..(r0 + step).min(nq);
        let qb = rows::<B>(&q, r.clone());
        let gb = rows::<B>(&grad, r.clone());
        let p = B::float_exp(B::float_sub(
            scores::<B>(qb.clone(), &kt, scale),
            rows::<B>(&lse, r.clone()),
        ));
        dv = acc(
            dv,
            B::float_matmul(B::float_swap_dims(p.clone(), 2, 3), gb.clone()),
        );
        let dp = B::float_matmul(gb, vt.clone());
        let ds = B::float_mul_scalar(
            B::float_mul(p, B::float_sub(dp, rows::<B>(&delta, r))),
            Scalar::Float(scale),
        );
        dq.push(B::float_matmul(ds.clone(), k.clone()));
        dk = acc(dk, B::float_matmul(B::float_swap_dims(ds, 2, 3), qb));
    }
    let zeros = || B::float_mul_scalar(v.clone(), Scalar::Float(0.0));
    AttentionGrads {
        q: B::float_cat(dq, 2),
        k: dk.unwrap_or_else(zeros),
        v: dv.unwrap_or_else(zeros),
    }
}

#[derive(Debug)]
struct LeanAttentionBackward;

impl<B: LeanAttentionOps> Backward<B, 3> for LeanAttentionBackward {
    type State = (
        [FloatTensor<B>; 3],
        FloatTensor<B>,
        FloatTensor<B>,
        f64,
        usize,
    );

    fn backward(self, ops: Ops<Self::State, 3>, grads: &mut Gradients, _: &mut Checkpointer) {
        let grad = grads.consume::<B>(&ops.node);
        let ([q, k, v], out, lse, scale, block) = ops.state;
        let g = B::lean_attention_backward(q, k, v, out, lse, grad, scale, block);
        for (parent, grad) in ops.parents.into_iter().zip([g.q, g.k, g.v]) {
            if let Some(node) = parent {
                grads.register::<B>(node.id, grad);
            }
        }
    }
}

impl<B: LeanAttentionOps, C: CheckpointStrategy> LeanAttentionOps for Autodiff<B, C> {
    fn lean_attention_forward(
        q: FloatTensor<Self>,
        k: FloatTensor<Self>,
        v: FloatTensor<Self>,
        scale: f64,
        block: usize,
    ) -> (FloatTensor<Self>, FloatTensor<Self>) {
        let tensors = [q, k, v];
        let nodes = tensors.each_ref().map(|t| t.node());
        let inner = tensors.map(|t| t.into_primitive());
        let [qi, ki, vi] = inner.clone();
        let (out, lse) = B::lean_attention_forward(qi, ki, vi, scale, block);
        let lse_out = <Self as burn::backend::AutodiffBackend>::from_inner(lse.clone());
        let out = match LeanAttentionBackward
            .prepare::<C>(nodes)
            .compute_bound()
            .stateful()
        {
            OpsKind::Tracked(prep) => prep.finish((inner, out.clone(), lse, scale, block), out),
            OpsKind::UnTracked(prep) => prep.finish(out),
        };
        (out, lse_out)
    }

    fn lean_attention_backward(
        q: FloatTensor<Self>,
        k: FloatTensor<Self>,
        v: FloatTensor<Self>,
        out: FloatTensor<Self>,
        lse: FloatTensor<Self>,
        grad: FloatTensor<Self>,
        scale: f64,
        block: usize,
    ) -> AttentionGrads<Self> {
        let g = B::lean_attention_backward(
            q.into_primitive(),
            k.into_primitive(),
            v.into_primitive(),
            out.into_primitive(),
            lse.into_primitive(),
            grad.into_primitive(),
            scale,
            block,
        );
        let lift = <Self as burn::backend::AutodiffBackend>::from_inner;
        AttentionGrads {
            q: lift(g.q),
            k: lift(g.k),
            v: lift(g.v),
        }
    }
}

/// `softmax(q kᵀ / sqrt(D)) v` for q `[B, H, Nq, D]`, k and v `[B, H, Nk, D]`,
/// differentiable with O(N·D) saved state.
pub fn lean_attention(q: Tensor<4>, k: Tensor<4>, v: Tensor<4>) -> Tensor<4> {
    lean_attention_blocked(q, k, v, BLOCK_ELEMENTS)
}

/// [`lean_attention`] with blocks of about `block` score elements (tests use small ones).
pub fn lean_attention_blocked(q: Tensor<4>, k: Tensor<4>, v: Tensor<4>, block: usize) -> Tensor<4> {
    let d = q.dims()[3];
    let (out, _lse) = <Dispatch as LeanAttentionOps>::lean_attention_forward(
        q.into_dispatch(),
        k.into_dispatch(),
        v.into_dispatch(),
        1.0 / (d as f64).sqrt(),
        block,
    );
    Tensor::from_dispatch(out)
}
