//! `BiasGeluOps` for the CubeCL backends: f32 pre-activations and a bias as wide as their
//! rows run [`super::kernels`]; anything else (another float type, empty tensors, indices
//! past u32) takes Burn's ops.

use super::kernels::{bias_gelu_backward, bias_gelu_forward, BIAS_ROWS};
use super::{decomposed_backward, decomposed_forward, BiasGeluOps};
use crate::layers::chunked::{chunked_rows, sum_chunks};
use burn::backend::ops::FloatTensorOps;
use burn::backend::tensor::FloatTensor;
use burn::backend::TensorMetadata;
use burn::tensor::DType;
use burn_cubecl::tensor::CubeTensor;
use burn_cubecl::CubeBackend;
use cubecl::{calculate_cube_count_elemwise, CubeDim};
use envision4d_splat::kernels::buffers::{empty_f32, flat};

/// `(rows, cols)` of the pre-activations when the kernels can take them: `z` and the bias
/// in f32, the bias as wide as the rows, and a shape [`chunked_rows`] takes. Forward and
/// backward decide on the same shapes, so a node's two passes take the same path.
fn layout(z: &CubeTensor, bias: &CubeTensor) -> Option<(usize, usize)> {
    let (rows, cols) = chunked_rows(&z.shape(), BIAS_ROWS)?;
    let f32s = z.dtype() == DType::F32 && bias.dtype() == DType::F32;
    let fits = bias.shape().num_elements() == cols;
    (f32s && fits).then_some((rows, cols))
}

/// A new uninitialised f32 buffer of `len` elements (see [`empty_f32`]).
fn empty(like: &CubeTensor, len: usize) -> CubeTensor {
    empty_f32(like, "bias and GELU", len)
}

impl BiasGeluOps for CubeBackend {
    fn bias_gelu_forward(z: FloatTensor<Self>, bias: FloatTensor<Self>) -> FloatTensor<Self> {
        let Some((rows, cols)) = layout(&z, &bias) else {
            return decomposed_forward::<Self>(z, bias);
        };
        let shape = z.shape();
        let len = rows * cols;
        let (z, bias) = (flat(z), flat(bias));
        let y = empty(&z, len);
        let client = z.client.clone();
        let dim = CubeDim::new(&client, len);
        bias_gelu_forward::launch(
            &client,
            calculate_cube_count_elemwise(&client, len, dim),
            dim,
            z.into_tensor_arg(),
            bias.into_tensor_arg(),
            y.clone().into_tensor_arg(),
            cols as u32,
            len as u32,
        );
        CubeBackend::float_reshape(y, shape)
    }

    fn bias_gelu_backward(
        grad: FloatTensor<Self>,
        z: FloatTensor<Self>,
        bias: FloatTensor<Self>,
        bias_grad: bool,
    ) -> (FloatTensor<Self>, FloatTensor<Self>) {
        let same = grad.shape() == z.shape() && grad.dtype() == DType::F32;
        let Some((rows, cols)) = layout(&z, &bias).filter(|_| same) else {
            return decomposed_backward::<Self>(grad, z, bias, bias_grad);
        };
        let shape = z.shape();
        let (grad, z, bias) = (flat(grad), flat(z), flat(bias));
        let chunks = rows.div_ceil(BIAS_ROWS as usize);
        let dz = empty(&grad, rows * cols);
        // Without the bias gradient its buffer is never written: one element will do.
        let part = empty(&grad, if bias_grad { chunks * cols } else { 1 });
        let client = grad.client.clone();
        let dim = CubeDim::new(&client, chunks * cols);
        bias_gelu_backward::launch(
            &client,
            calculate_cube_count_elemwise(&client, chunks * cols, dim),
            dim,
            grad.into_tensor_arg(),
            z.into_tensor_arg(),
            bias.clone().into_tensor_arg(),
            dz.clone().into_tensor_arg(),
            part.clone().into_tensor_arg(),
            rows as u32,
            cols as u32,
            chunks as u32,
            bias_grad,
        );
        let dbias = if bias_grad {
            sum_chunks(part, chunks, cols)
        } else {
            bias
        };
        (CubeBackend::float_reshape(dz, shape), dbias)
    }
}
