//! `ScaledResidualOps` for the CubeCL backends: f32 tokens, bias and gain of matching widths
//! run [`super::kernels`]; anything else (another float type, empty tensors, indices past
//! u32) takes Burn's ops.

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

/// `(rows, cols)` of the tokens when the kernels can take them: the token tensors, the bias
/// and the gain in f32, the tokens of one shape, the bias and the gain as wide as their
/// rows, and a shape [`chunked_rows`] takes. Forward and backward decide on the same
/// tensors' shapes, so a node's two passes take the same path.
fn layout(a: &CubeTensor, b: &CubeTensor, params: [&CubeTensor; 2]) -> Option<(usize, usize)> {
    let shape = a.shape();
    let (rows, cols) = chunked_rows(&shape, GAIN_ROWS)?;
    let f32s = [a, b, params[0], params[1]]
        .iter()
        .all(|t| t.dtype() == DType::F32);
    let fits = b.shape() == shape && params.iter().all(|p| p.shape().num_elements() == cols);
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
        bias: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
    ) -> FloatTensor<Self> {
        let Some((rows, cols)) = layout(&x, &u, [&bias, &gamma]) else {
            return decomposed_forward::<Self>(x, u, bias, gamma);
        };
        let shape = x.shape();
        let len = rows * cols;
        let (x, u, bias, gamma) = (flat(x), flat(u), flat(bias), flat(gamma));
        let y = empty(&x, len);
        let client = x.client.clone();
        let dim = CubeDim::new(&client, len);
        scaled_residual_forward::launch(
            &client,
            calculate_cube_count_elemwise(&client, len, dim),
            dim,
            x.into_tensor_arg(),
            u.into_tensor_arg(),
            bias.into_tensor_arg(),
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
        bias: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
        gain: bool,
        bias_grad: bool,
    ) -> (
        FloatTensor<Self>,
        Option<FloatTensor<Self>>,
        Option<FloatTensor<Self>>,
    ) {
        let Some((rows, cols)) = layout(&grad, &u, [&bias, &gamma]) else {
            return decomposed_backward::<Self>(grad, u, bias, gamma, gain, bias_grad);
        };
        let shape = grad.shape();
        let (grad, u, bias, gamma) = (flat(grad), flat(u), flat(bias), flat(gamma));
        let chunks = rows.div_ceil(GAIN_ROWS as usize);
        let du = empty(&grad, rows * cols);
        // A sum not asked for is never written: one element will do for its buffer.
        let partials = |asked: bool| empty(&grad, if asked { chunks * cols } else { 1 });
        let (gain_part, bias_part) = (partials(gain), partials(bias_grad));
        let client = grad.client.clone();
        let dim = CubeDim::new(&client, chunks * cols);
        scaled_residual_backward::launch(
            &client,
            calculate_cube_count_elemwise(&client, chunks * cols, dim),
            dim,
            grad.into_tensor_arg(),
            u.into_tensor_arg(),
            bias.into_tensor_arg(),
            gamma.into_tensor_arg(),
            du.clone().into_tensor_arg(),
            gain_part.clone().into_tensor_arg(),
            bias_part.clone().into_tensor_arg(),
            rows as u32,
            cols as u32,
            chunks as u32,
            gain,
            bias_grad,
        );
        let dgamma = gain.then(|| sum_chunks(gain_part, chunks, cols));
        let dbias = bias_grad.then(|| sum_chunks(bias_part, chunks, cols));
        (CubeBackend::float_reshape(du, shape), dgamma, dbias)
    }
}
