//! `ScaledResidualOps` for the CubeCL backends: f32 tokens and gain of matching widths run
//! [`super::kernels`]; anything else (another float type, empty tensors, indices past u32)
//! takes Burn's ops.

use super::kernels::{scaled_residual_backward, scaled_residual_forward, GAIN_ROWS};
use super::{decomposed_backward, decomposed_forward, ScaledResidualOps};
use crate::layers::chunked::{chunked_rows, sum_chunks};
use burn::backend::ops::FloatTensorOps;
use burn::backend::tensor::FloatTensor;
use burn::backend::TensorMetadata;
use burn::tensor::DType;
use burn_cubecl::tensor::CubeTensor;
use burn_cubecl::CubeBackend;
use cubecl::{calculate_cube_count_elemwise, CubeDim};
use envision4d_splat::kernels::buffers::{empty_f32, flat};

/// `(rows, cols)` of the tokens when the kernels can take them: both token tensors and the
/// gain in f32, the tokens of one shape, the gain as wide as their rows, and a shape
/// [`chunked_rows`] takes. Forward and backward decide on the same tensors' shapes, so a
/// node's two passes take the same path.
fn layout(a: &CubeTensor, b: &CubeTensor, gamma: &CubeTensor) -> Option<(usize, usize)> {
    let shape = a.shape();
    let (rows, cols) = chunked_rows(&shape, GAIN_ROWS)?;
    let f32s = [a, b, gamma].iter().all(|t| t.dtype() == DType::F32);
    let fits = b.shape() == shape && gamma.shape().num_elements() == cols;
    (f32s && fits).then_some((rows, cols))
}

/// A new uninitialised f32 buffer of `len` elements (see [`empty_f32`]).
fn empty(like: &CubeTensor, len: usize) -> CubeTensor {
    empty_f32(like, "scaled residual", len)
}

impl ScaledResidualOps for CubeBackend {
    fn scaled_residual_forward(
        x: FloatTensor<Self>,
        u: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
    ) -> FloatTensor<Self> {
        let Some((rows, cols)) = layout(&x, &u, &gamma) else {
            return decomposed_forward::<Self>(x, u, gamma);
        };
        let shape = x.shape();
        let len = rows * cols;
        let (x, u, gamma) = (flat(x), flat(u), flat(gamma));
        let y = empty(&x, len);
        let client = x.client.clone();
        let dim = CubeDim::new(&client, len);
        scaled_residual_forward::launch(
            &client,
            calculate_cube_count_elemwise(&client, len, dim),
            dim,
            x.into_tensor_arg(),
            u.into_tensor_arg(),
            gamma.into_tensor_arg(),
            y.clone().into_tensor_arg(),
            cols as u32,
            len as u32,
        );
        CubeBackend::float_reshape(y, shape)
    }

    fn scaled_residual_backward(
        grad: FloatTensor<Self>,
        u: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
        gain: bool,
    ) -> (FloatTensor<Self>, FloatTensor<Self>) {
        let Some((rows, cols)) = layout(&grad, &u, &gamma) else {
            return decomposed_backward::<Self>(grad, u, gamma, gain);
        };
        let shape = grad.shape();
        let (grad, u, gamma) = (flat(grad), flat(u), flat(gamma));
        let chunks = rows.div_ceil(GAIN_ROWS as usize);
        let du = empty(&grad, rows * cols);
        // Without the gain's gradient its buffer is never written: one element will do.
        let part = empty(&grad, if gain { chunks * cols } else { 1 });
        let client = grad.client.clone();
        let dim = CubeDim::new(&client, chunks * cols);
        scaled_residual_backward::launch(
            &client,
            calculate_cube_count_elemwise(&client, chunks * cols, dim),
            dim,
            grad.into_tensor_arg(),
            u.into_tensor_arg(),
            gamma.clone().into_tensor_arg(),
            du.clone().into_tensor_arg(),
            part.clone().into_tensor_arg(),
            rows as u32,
            cols as u32,
            chunks as u32,
            gain,
        );
        let dgamma = if gain {
            sum_chunks(part, chunks, cols)
        } else {
            gamma
        };
        (CubeBackend::float_reshape(du, shape), dgamma)
    }
}
