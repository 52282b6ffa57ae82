//! `FusedNormOps` for the CubeCL backends: f32 runs the kernels of [`super::kernels`], one
//! cube per row; other float types and empty tensors take the decomposed bodies.

use super::kernels::{
    layer_norm_backward_input, layer_norm_backward_params, layer_norm_forward, NORM_THREADS,
    PARAM_ROWS,
};
use super::{decomposed_backward, decomposed_forward, FusedNormOps, NormGrads, NormNeeds};
use burn::backend::ops::FloatTensorOps;
use burn::backend::tensor::FloatTensor;
use burn::backend::TensorMetadata;
use burn::tensor::{DType, Shape};
use burn_cubecl::tensor::CubeTensor;
use burn_cubecl::CubeBackend;
use cubecl::{calculate_cube_count_elemwise, CubeDim};
use envision4d_splat::kernels::buffers::{empty_f32, flat};
use envision4d_splat::kernels::sort::grid;

/// A `[rows, cols]` view of the input, when the kernels can take it.
#[derive(Debug, Clone, Copy)]
struct Rows {
    rows: usize,
    cols: usize,
}

impl Rows {
    /// `None` unless the input and gamma are f32, gamma is as wide as the rows, the input is
    /// not empty and its flat indices fit the kernels' u32 arithmetic. Forward and backward
    /// decide on these two alone, so a node's two passes always take the same path.
    fn of(x: &CubeTensor, gamma: &CubeTensor) -> Option<Rows> {
        let shape = x.shape();
        let cols = *shape.to_vec().last()?;
        let n = shape.num_elements();
        let f32s = x.dtype() == DType::F32 && gamma.dtype() == DType::F32;
        // A gamma of another width is an error the decomposed body reports as a broadcast
        // failure; the kernels would read past it instead.
        let fits = gamma.shape().num_elements() == cols;
        (f32s && fits && n > 0 && u32::try_from(n).is_ok()).then_some(Rows {
            rows: n / cols,
            cols,
        })
    }
}

/// `t` in f32 (a no-op for the f32 tensors the model passes).
fn as_f32(t: CubeTensor) -> CubeTensor {
    if t.dtype() == DType::F32 {
        t
    } else {
        CubeBackend::float_cast(t, burn::tensor::FloatDType::F32)
    }
}

/// A new uninitialised f32 buffer of `len` elements (see [`empty_f32`]).
fn empty(like: &CubeTensor, len: usize) -> CubeTensor {
    empty_f32(like, "LayerNorm", len)
}

impl FusedNormOps for CubeBackend {
    fn fused_layer_norm_forward(
        x: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
        beta: FloatTensor<Self>,
        epsilon: f64,
    ) -> (FloatTensor<Self>, FloatTensor<Self>, FloatTensor<Self>) {
        // The kernel would read past a narrower gamma or beta (the backward never reads
        // beta, and its gamma is the forward's).
        super::assert_widths(&x.shape(), &gamma.shape(), &beta.shape());
        let Some(Rows { rows, cols }) = Rows::of(&x, &gamma) else {
            return decomposed_forward::<Self>(x, gamma, beta, epsilon);
        };
        let beta = as_f32(beta);
        let shape = x.shape();
        let mut stats_dims = shape.to_vec();
        *stats_dims.last_mut().expect("not empty") = 1;
        let stats_shape = Shape::from(stats_dims);
        let x = flat(x);
        let y = empty(&x, rows * cols);
        let mean = empty(&x, rows);
        let rstd = empty(&x, rows);
        let client = &x.client;
        layer_norm_forward::launch(
            client,
            grid(rows as u32),
            CubeDim::new_1d(NORM_THREADS),
            x.clone().into_tensor_arg(),
            flat(gamma).into_tensor_arg(),
            flat(beta).into_tensor_arg(),
            y.clone().into_tensor_arg(),
            mean.clone().into_tensor_arg(),
            rstd.clone().into_tensor_arg(),
            rows as u32,
            cols as u32,
            epsilon as f32,
        );
        (
            CubeBackend::float_reshape(y, shape),
            CubeBackend::float_reshape(mean, stats_shape.clone()),
            CubeBackend::float_reshape(rstd, stats_shape),
        )
    }

    fn fused_layer_norm_backward(
        x: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
        mean: FloatTensor<Self>,
        rstd: FloatTensor<Self>,
        grad: FloatTensor<Self>,
        needs: NormNeeds,
    ) -> NormGrads<Self> {
        // The forward's test on the same two tensors: the kernels' `mean` is relative to
        // each row's first value, so both passes must take the same path.
        let Some(Rows { rows, cols }) = Rows::of(&x, &gamma) else {
            return decomposed_backward::<Self>(x, gamma, mean, rstd, grad, needs);
        };
        let grad = as_f32(grad);
        let shape = x.shape();
        let (x, dy, mean, rstd) = (flat(x), flat(grad), flat(mean), flat(rstd));
        let gamma = flat(gamma);
        let client = x.client.clone();
        // What is not needed is a placeholder of the right shape, never registered.
        let dx = if needs.input {
            let dx = empty(&x, rows * cols);
            layer_norm_backward_input::launch(
                &client,
                grid(rows as u32),
                CubeDim::new_1d(NORM_THREADS),
                x.clone().into_tensor_arg(),
                gamma.clone().into_tensor_arg(),
                dy.clone().into_tensor_arg(),
                mean.clone().into_tensor_arg(),
                rstd.clone().into_tensor_arg(),
                dx.clone().into_tensor_arg(),
                rows as u32,
                cols as u32,
            );
            dx
        } else {
            dy.clone()
        };
        let (dgamma, dbeta) = if needs.params {
            let chunks = rows.div_ceil(PARAM_ROWS as usize);
            let (dgamma, dbeta) = (empty(&x, chunks * cols), empty(&x, chunks * cols));
            let dim = CubeDim::new(&client, chunks * cols);
            layer_norm_backward_params::launch(
                &client,
                calculate_cube_count_elemwise(&client, chunks * cols, dim),
                dim,
                x.into_tensor_arg(),
                dy.into_tensor_arg(),
                mean.into_tensor_arg(),
                rstd.into_tensor_arg(),
                dgamma.clone().into_tensor_arg(),
                dbeta.clone().into_tensor_arg(),
                rows as u32,
                cols as u32,
                chunks as u32,
            );
            // Up to `PARAM_ROWS` rows the one chunk is the sum; past it, one reduction each.
            let total = |part: CubeTensor| {
                let part = CubeBackend::float_reshape(part, Shape::new([chunks, cols]));
                let sum = if chunks == 1 {
                    part
                } else {
                    CubeBackend::float_sum_dim(part, 0)
                };
                CubeBackend::float_reshape(sum, Shape::new([cols]))
            };
            (total(dgamma), total(dbeta))
        } else {
            (gamma.clone(), gamma)
        };
        NormGrads {
            x: CubeBackend::float_reshape(dx, shape),
            gamma: dgamma,
            beta: dbeta,
        }
    }
}
