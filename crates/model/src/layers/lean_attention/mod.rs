//! Softmax attention that trains in O(N·D) memory: the autodiff node keeps q, k, v, the
//! output and every query row's log-sum-exp, not the probabilities; forward and backward
//! work a block of query rows at a time and the backward recomputes each block's
//! probabilities from the log-sum-exp (FlashAttention's recurrence, written with ordinary
//! tensor ops). Burn's decomposed attention keeps the scores and the probabilities, two
//! `[B, H, N, N]` tensors per layer: about 450 MB per global layer at 350x518 with two
//! frames, 10 GB over the aggregator, which is what kept a paper-size training step from
//! fitting in 24 GiB (docs/PERFORMANCE.md).
//!
//! The matrix products are Burn's (tensor cores where a backend has them); the row-wise
//! steps between them go through [`ScoreRows`]. Its default, [`Decomposed`], is Burn's
//! elementwise ops and reductions: eight kernels a block forward and six backward, each a
//! pass over the `[B, H, rows, N]` scores. On the CubeCL backends the softmax is one kernel
//! and each backward step one (`cube.rs`), which a GPU pays for in launches and in passes
//! over the scores (docs/PERFORMANCE.md, "Kernel launches of a step on a GPU backend"); the
//! CPU backend keeps the decomposition its parity was checked in.

mod cube;
pub mod kernels;

use burn::backend::autodiff::checkpoint::{base::Checkpointer, strategy::CheckpointStrategy};
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::backend::autodiff::Autodiff;
use burn::backend::tensor::FloatTensor;
use burn::backend::Dispatch;
use burn::backend::{backend_extension, Backend, ExtensionType, Scalar, TensorMetadata};
use burn::tensor::{Slice, Tensor};
use std::sync::atomic::{AtomicBool, Ordering};

/// Whether the CubeCL backends take the fused row kernels (on by default; the benchmarks'
/// `--softmax burn` turns them off to measure Burn's decomposition).
static FUSED: AtomicBool = AtomicBool::new(true);

/// Switches the fused row kernels on or off for the whole process.
pub fn set_fused_softmax(on: bool) {
    FUSED.store(on, Ordering::Relaxed);
}

/// Whether the fused row kernels are on ([`set_fused_softmax`]).
pub fn fused_softmax_on() -> bool {
    FUSED.load(Ordering::Relaxed)
}

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
        forward::<Self, Decomposed>(q, k, v, scale, block)
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
        backward::<Self, Decomposed>(q, k, v, out, lse, grad, scale, block)
    }
}

impl LeanAttentionOps for burn::backend::Flex {}

/// The row-wise steps of the blocked recurrence on one block of scores, `qk = q_block kᵀ`
/// of shape `[B, H, rows, N]` (unscaled), its rows' statistics `[B, H, rows, 1]`.
pub trait ScoreRows<B: Backend> {
    /// `(softmax(qk · scale) v, log-sum-exp of qk · scale)`.
    fn attend(
        qk: FloatTensor<B>,
        v: FloatTensor<B>,
        scale: f64,
    ) -> (FloatTensor<B>, FloatTensor<B>);
    /// The probabilities again from the log-sum-exp: `exp(qk · scale - lse)`.
    fn probs(qk: FloatTensor<B>, lse: FloatTensor<B>, scale: f64) -> FloatTensor<B>;
    /// The softmax VJP, scaled back to `qk`: `p · (dp - delta) · scale`.
    fn score_grad(
        p: FloatTensor<B>,
        dp: FloatTensor<B>,
        delta: FloatTensor<B>,
        scale: f64,
    ) -> FloatTensor<B>;
    /// `Σ a · b` over the last axis, kept as an axis of 1.
    fn row_dot(a: FloatTensor<B>, b: FloatTensor<B>) -> FloatTensor<B>;
    /// The output's gradient as the backward's products read it: where the backend's matrix
    /// product would copy it into another layout first (in both products of every block),
    /// that copy made once. The default keeps it as it is.
    fn operand(grad: FloatTensor<B>) -> FloatTensor<B> {
        grad
    }
}

/// [`ScoreRows`] in Burn's ops: what the CPU backend runs, and the CubeCL backends for
/// other float types or with the kernels switched off.
#[derive(Debug)]
pub struct Decomposed;

impl<B: Backend> ScoreRows<B> for Decomposed {
    fn attend(
        qk: FloatTensor<B>,
        v: FloatTensor<B>,
        scale: f64,
    ) -> (FloatTensor<B>, FloatTensor<B>) {
        let s = B::float_mul_scalar(qk, Scalar::Float(scale));
        let m = B::float_max_dim(s.clone(), 3);
        let p = B::float_exp(B::float_sub(s, m.clone()));
        let l = B::float_sum_dim(p.clone(), 3);
        // The division after the product: `[rows, D]` values rather than `[rows, N]`.
        let out = B::float_div(B::float_matmul(p, v), l.clone());
        (out, B::float_add(m, B::float_log(l)))
    }

    fn probs(qk: FloatTensor<B>, lse: FloatTensor<B>, scale: f64) -> FloatTensor<B> {
        B::float_exp(B::float_sub(
            B::float_mul_scalar(qk, Scalar::Float(scale)),
            lse,
        ))
    }

    fn score_grad(
        p: FloatTensor<B>,
        dp: FloatTensor<B>,
        delta: FloatTensor<B>,
        scale: f64,
    ) -> FloatTensor<B> {
        B::float_mul_scalar(
            B::float_mul(p, B::float_sub(dp, delta)),
            Scalar::Float(scale),
        )
    }

    fn row_dot(a: FloatTensor<B>, b: FloatTensor<B>) -> FloatTensor<B> {
        let last = a.shape().num_dims() - 1;
        B::float_sum_dim(B::float_mul(a, b), last)
    }
}

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

/// The blocked forward, its row steps `R`'s.
pub fn forward<B: Backend, R: ScoreRows<B>>(
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
        let qk = B::float_matmul(rows::<B>(&q, r0..(r0 + step).min(nq)), kt.clone());
        let (out, lse) = R::attend(qk, v.clone(), scale);
        outs.push(out);
        lses.push(lse);
    }
    (cat::<B>(outs), cat::<B>(lses))
}

/// The blocks along the query axis; one block is itself (no copy).
fn cat<B: Backend>(mut parts: Vec<FloatTensor<B>>) -> FloatTensor<B> {
    if parts.len() == 1 {
        parts.pop().expect("one part")
    } else {
        B::float_cat(parts, 2)
    }
}

/// The recomputing backward, its row steps `R`'s.
#[allow(clippy::too_many_arguments)]
pub fn backward<B: Backend, R: ScoreRows<B>>(
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
    let grad = R::operand(grad);
    // Δ_i = Σ_d dO_id O_id = Σ_j P_ij dP_ij: the softmax VJP's row term.
    let delta = R::row_dot(grad.clone(), out);
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
        let qk = B::float_matmul(qb.clone(), kt.clone());
        let p = R::probs(qk, rows::<B>(&lse, r.clone()), scale);
        dv = acc(
            dv,
            B::float_matmul(B::float_swap_dims(p.clone(), 2, 3), gb.clone()),
        );
        let dp = B::float_matmul(gb, vt.clone());
        let ds = R::score_grad(p, dp, rows::<B>(&delta, r), scale);
        dq.push(B::float_matmul(ds.clone(), k.clone()));
        dk = acc(dk, B::float_matmul(B::float_swap_dims(ds, 2, 3), qb));
    }
    let zeros = || B::float_mul_scalar(v.clone(), Scalar::Float(0.0));
    AttentionGrads {
        q: cat::<B>(dq),
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
