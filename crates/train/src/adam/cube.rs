//! `AdamOps` for the CubeCL backends: f32 runs [`super::kernel::adam_update`], one unit per
//! element; other float types take the decomposed body.

use super::kernel::adam_update;
use super::{decomposed, AdamOps, AdamStep};
use burn::backend::ops::FloatTensorOps;
use burn::backend::tensor::FloatTensor;
use burn::backend::TensorMetadata;
use burn::tensor::{DType, Shape};
use burn_cubecl::ops::numeric::empty_device_dtype;
use burn_cubecl::CubeBackend;
use cubecl::{calculate_cube_count_elemwise, CubeDim};
use envision4d_splat::kernels::buffers::{check_binding, flat};

impl AdamOps for CubeBackend {
    fn adam_update(
        param: FloatTensor<Self>,
        grad: FloatTensor<Self>,
        moment_1: FloatTensor<Self>,
        moment_2: FloatTensor<Self>,
        step: AdamStep,
    ) -> (FloatTensor<Self>, FloatTensor<Self>, FloatTensor<Self>) {
        let shape = param.shape();
        let n = shape.num_elements();
        let all_f32 = [&param, &grad, &moment_1, &moment_2]
            .iter()
            .all(|t| t.dtype() == DType::F32);
        if !all_f32 || n == 0 || u32::try_from(n).is_err() {
            return decomposed::<Self>(param, grad, moment_1, moment_2, step);
        }
        let param = flat(param);
        check_binding(&param, "Adam moment", n);
        // A gradient that is not one contiguous run (a weight used transposed gets a
        // transposed view) is read through its strides: a copy first was one launch more per
        // such tensor, 72 a step of the tiny model (docs/PERFORMANCE.md).
        let strided = !grad.is_contiguous();
        // The first step reads no moments (the caller passes the gradient in their place):
        // bind the flat parameter there, so a transposed gradient is not copied for them.
        let (moment_1, moment_2) = if step.first {
            (param.clone(), param.clone())
        } else {
            (flat(moment_1), flat(moment_2))
        };
        let empty = || {
            empty_device_dtype(
                param.client.clone(),
                param.device.clone(),
                Shape::new([n]),
                DType::F32,
            )
        };
        let (p_out, m_out, v_out) = (empty(), empty(), empty());
        let client = param.client.clone();
        let dim = CubeDim::new(&client, n);
        adam_update::launch(
            &client,
            calculate_cube_count_elemwise(&client, n, dim),
            dim,
            param.into_tensor_arg(),
            if strided { grad } else { flat(grad) }.into_tensor_arg(),
            moment_1.into_tensor_arg(),
            moment_2.into_tensor_arg(),
            p_out.clone().into_tensor_arg(),
            m_out.clone().into_tensor_arg(),
            v_out.clone().into_tensor_arg(),
            n as u32,
            step.beta_1,
            step.beta_2,
            step.factor,
            step.eps_hat,
            step.lr,
            step.first,
            strided,
        );
        let shaped = |t| CubeBackend::float_reshape(t, shape.clone());
        (shaped(p_out), shaped(m_out), shaped(v_out))
    }
}
