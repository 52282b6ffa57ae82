//! `FiniteOps` for the CubeCL backends: f32 runs [`super::kernel::flag_non_finite`] in place
//! on the pass's flag; other float types take the decomposed body.

use super::kernel::flag_non_finite;
use super::{decomposed, FiniteOps};
use burn::backend::ops::FloatTensorOps;
use burn::backend::tensor::FloatTensor;
use burn::backend::TensorMetadata;
use burn::tensor::DType;
use burn_cubecl::kernel::into_contiguous;
use burn_cubecl::tensor::CubeTensor;
use burn_cubecl::CubeBackend;
use cubecl::{calculate_cube_count_elemwise, CubeDim};
use envision4d_splat::kernels::buffers::flat;

/// `x` with its axes permuted into memory order (strides descending, ties kept in place): a
/// view, no copy. Where `x` is a permutation of a dense layout (a weight's gradient arrives
/// transposed) that view is contiguous and [`flat`] takes it as it is, where `x` itself
/// needed a copy; the check asks only whether any element is non-finite, which the order
/// does not change. Views with gaps (a slice) stay non-contiguous and are copied.
fn in_memory_order(x: CubeTensor) -> CubeTensor {
    let strides: Vec<usize> = x.meta.strides().iter().copied().collect();
    let mut axes: Vec<usize> = (0..strides.len()).collect();
    axes.sort_by(|&a, &b| strides[b].cmp(&strides[a]));
    if axes.iter().enumerate().all(|(i, &a)| i == a) {
        return x;
    }
    CubeBackend::float_permute(x, &axes)
}

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
        let x = flat(in_memory_order(x));
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
