//! `FiniteOps` for the CubeCL backends: f32 runs [`super::kernel::flag_non_finite`] in place
//! on the pass's flag; other float types take the decomposed body.

use super::kernel::flag_non_finite;
use super::{decomposed, FiniteOps};
use burn::backend::ops::FloatTensorOps;
use burn::backend::tensor::FloatTensor;
use burn::backend::TensorMetadata;
use burn::tensor::DType;
use burn_cubecl::kernel::into_contiguous;
use burn_cubecl::CubeBackend;
use cubecl::{calculate_cube_count_elemwise, CubeDim};
use envision4d_splat::kernels::buffers::flat;

impl FiniteOps for CubeBackend {
    fn flag_non_finite(x: FloatTensor<Self>, flags: FloatTensor<Self>) -> FloatTensor<Self> {
        let n = x.shape().num_elements();
        let f32s = x.dtype() == DType::F32 && flags.dtype() == DType::F32;
        if !f32s || u32::try_from(n).is_err() {
            return decomposed::<Self>(x, flags);
        }
        if n == 0 {
            return flags;
        }
        let x = flat(x);
        // Written in place when the pass owns the flag (moved in, handed back); a flag someone
        // else still holds is copied first, so no other handle sees it change.
        let flags = if flags.can_mut() {
            into_contiguous(flags)
        } else {
            CubeBackend::float_add_scalar(flags, burn::backend::Scalar::Float(0.0))
        };
        let client = x.client.clone();
        let dim = CubeDim::new(&client, n);
        flag_non_finite::launch(
            &client,
            calculate_cube_count_elemwise(&client, n, dim),
            dim,
            x.into_tensor_arg(),
            flags.clone().into_tensor_arg(),
            n as u32,
        );
        flags
    }
}
