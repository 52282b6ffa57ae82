//! `LeanAttentionOps` for the CubeCL backends: the blocked recurrence with [`Fused`] row
//! steps, f32 blocks through the kernels of [`super::kernels`], anything else (another float
//! type, empty blocks, indices past u32, the switch off) through [`Decomposed`].

use super::kernels::{probs_from_lse, row_dot, score_grad, softmax_rows};
use super::{
    backward, forward, fused_softmax_on, AttentionGrads, Decomposed, LeanAttentionOps, ScoreRows,
};
use crate::layers::cube_rows::ROW_THREADS;
use burn::backend::ops::FloatTensorOps;
use burn::backend::tensor::FloatTensor;
use burn::backend::TensorMetadata;
use burn::tensor::{DType, Shape};
use burn_cubecl::kernel::into_contiguous;
use burn_cubecl::tensor::CubeTensor;
use burn_cubecl::CubeBackend;
use cubecl::{calculate_cube_count_elemwise, CubeDim};
use envision4d_splat::kernels::buffers::{empty_f32, flat};
use envision4d_splat::kernels::sort::grid;

/// The row steps on a CubeCL backend.
#[derive(Debug)]
pub struct Fused;

/// `[rows, cols]` of a block of scores the kernels can take: f32, not empty, flat indices
/// within u32 (as every tensor given must be, which the callers' shapes ensure: they share
/// the scores' rows).
fn rows_of(t: &CubeTensor) -> Option<(usize, usize)> {
    let shape = t.shape();
    let cols = *shape.to_vec().last()?;
    let n = shape.num_elements();
    let ok = fused_softmax_on() && t.dtype() == DType::F32 && n > 0;
    (ok && u32::try_from(n).is_ok()).then(|| (n / cols, cols))
}

/// Whether the kernels may read `t` in its own strides: f32, stored untiled (its shape and
/// strides are then the logical ones), every element at an offset below 2^32.
fn in_place(t: &CubeTensor) -> bool {
    let dims = t.shape().to_vec();
    let last: usize = dims
        .iter()
        .zip(t.meta.strides().iter())
        .map(|(&d, &s)| d.saturating_sub(1).saturating_mul(s))
        .fold(0usize, usize::saturating_add);
    t.dtype() == DType::F32 && !t.meta.is_tiled() && u32::try_from(last).is_ok()
}

/// Whether Burn's matrix product on a CubeCL backend would copy `t` before reading it:
/// its routines take row- or column-major matrices with the batch axes in order, and copy
/// anything else, such as a batch axis striding less than a row (the attention output's
/// gradient arrives as the `[B, H, N, d]` view of a `[B, N, H, d]` buffer, whose head axis
/// strides `d` against a row's `H · d`). Broadcast axes (stride 0) are left to the product.
fn matmul_relayouts(t: &CubeTensor) -> bool {
    let strides = t.meta.strides();
    let rank = strides.len();
    if t.meta.is_tiled() || rank < 3 {
        return false;
    }
    let (row, col) = (strides[rank - 2], strides[rank - 1]);
    let mut previous = row.max(col);
    for &stride in strides[..rank - 2].iter().rev() {
        if stride == 0 {
            continue;
        }
        if stride < previous {
            return true;
        }
        previous = stride;
    }
    false
}

/// A new uninitialised f32 buffer of `len` elements (see [`empty_f32`]).
fn empty(like: &CubeTensor, what: &str, len: usize) -> CubeTensor {
    empty_f32(like, what, len)
}

/// `shape` with its last axis 1: the rows' statistics.
fn stats_shape(shape: &Shape) -> Shape {
    let mut dims = shape.to_vec();
    *dims.last_mut().expect("a shape of rank 1 or more") = 1;
    Shape::from(dims)
}

/// One unit per element of `len`.
fn elementwise(like: &CubeTensor, len: usize) -> (cubecl::prelude::CubeCount, CubeDim) {
    let dim = CubeDim::new(&like.client, len);
    (calculate_cube_count_elemwise(&like.client, len, dim), dim)
}

impl ScoreRows<CubeBackend> for Fused {
    fn operand(grad: CubeTensor) -> CubeTensor {
        if matmul_relayouts(&grad) {
            into_contiguous(grad)
        } else {
            grad
        }
    }

    fn attend(qk: CubeTensor, v: CubeTensor, scale: f64) -> (CubeTensor, CubeTensor) {
        let Some((rows, cols)) = rows_of(&qk) else {
            return <Decomposed as ScoreRows<CubeBackend>>::attend(qk, v, scale);
        };
        let shape = qk.shape();
        let s = flat(qk);
        let p = empty(&s, "attention probabilities", rows * cols);
        let lse = empty(&s, "attention log-sum-exp", rows);
        softmax_rows::launch(
            &s.client,
            grid(rows as u32),
            CubeDim::new_1d(ROW_THREADS),
            s.clone().into_tensor_arg(),
            p.clone().into_tensor_arg(),
            lse.clone().into_tensor_arg(),
            rows as u32,
            cols as u32,
            scale as f32,
        );
        let p = CubeBackend::float_reshape(p, shape.clone());
        let out = CubeBackend::float_matmul(p, v);
        (out, CubeBackend::float_reshape(lse, stats_shape(&shape)))
    }

    fn probs(qk: CubeTensor, lse: CubeTensor, scale: f64) -> CubeTensor {
        let Some((rows, cols)) = rows_of(&qk) else {
            return <Decomposed as ScoreRows<CubeBackend>>::probs(qk, lse, scale);
        };
        let shape = qk.shape();
        let (s, lse) = (flat(qk), flat(lse));
        let p = empty(&s, "attention probabilities", rows * cols);
        let (count, dim) = elementwise(&s, rows * cols);
        probs_from_lse::launch(
            &s.client,
            count,
            dim,
            s.clone().into_tensor_arg(),
            lse.into_tensor_arg(),
            p.clone().into_tensor_arg(),
            cols as u32,
            (rows * cols) as u32,
            scale as f32,
        );
        CubeBackend::float_reshape(p, shape)
    }

    fn score_grad(p: CubeTensor, dp: CubeTensor, delta: CubeTensor, scale: f64) -> CubeTensor {
        let Some((rows, cols)) = rows_of(&p) else {
            return <Decomposed as ScoreRows<CubeBackend>>::score_grad(p, dp, delta, scale);
        };
        let shape = p.shape();
        let (p, dp, delta) = (flat(p), flat(dp), flat(delta));
        let ds = empty(&p, "attention score gradient", rows * cols);
        let (count, dim) = elementwise(&p, rows * cols);
        score_grad::launch(
            &p.client,
            count,
            dim,
            p.clone().into_tensor_arg(),
            dp.into_tensor_arg(),
            delta.into_tensor_arg(),
            ds.clone().into_tensor_arg(),
            cols as u32,
            (rows * cols) as u32,
            scale as f32,
        );
        CubeBackend::float_reshape(ds, shape)
    }

    fn row_dot(a: CubeTensor, b: CubeTensor) -> CubeTensor {
        let Some((rows, cols)) = rows_of(&a) else {
            return <Decomposed as ScoreRows<CubeBackend>>::row_dot(a, b);
        };
        let shape = a.shape();
        // Read in place, in each tensor's strides: the gradient arrives as a swapped view,
        // which `flat` would copy first. Offsets are u32 like the rest (see `rows_of`).
        if !in_place(&a) || !in_place(&b) {
            return <Decomposed as ScoreRows<CubeBackend>>::row_dot(a, b);
        }
        let out = empty(&a, "attention row sums", rows);
        row_dot::launch(
            &a.client,
            grid(rows as u32),
            CubeDim::new_1d(ROW_THREADS),
            a.clone().into_tensor_arg(),
            b.into_tensor_arg(),
            out.clone().into_tensor_arg(),
            rows as u32,
            cols as u32,
        );
        CubeBackend::float_reshape(out, stats_shape(&shape))
    }
}

impl LeanAttentionOps for CubeBackend {
    fn lean_attention_forward(
        q: FloatTensor<Self>,
        k: FloatTensor<Self>,
        v: FloatTensor<Self>,
        scale: f64,
        block: usize,
    ) -> (FloatTensor<Self>, FloatTensor<Self>) {
        forward::<Self, Fused>(q, k, v, scale, block)
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
        backward::<Self, Fused>(q, k, v, out, lse, grad, scale, block)
    }
}
