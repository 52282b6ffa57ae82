//! `HeadsOps` for the CubeCL backends: f32 tensors whose indices fit u32 take the kernels of
//! [`super::kernels`], one launch each way; anything else Burn's views and slices.

use super::kernels::{merge_heads, split_heads};
use super::{heads_kernels_on, merge, split, HeadsOps};
use burn::backend::ops::FloatTensorOps;
use burn::backend::tensor::FloatTensor;
use burn::backend::TensorMetadata;
use burn::tensor::{DType, Shape};
use burn_cubecl::tensor::CubeTensor;
use burn_cubecl::CubeBackend;
use cubecl::{calculate_cube_count_elemwise, CubeDim};
use envision4d_splat::kernels::buffers::{empty_f32, flat};

/// `[B, N, H, d]` of the projection when the kernels can take it: the switch on, f32, not
/// empty, a width of `3 · heads · d` and indices within u32.
fn layout(dims: &[usize], dtype: DType, heads: usize) -> Option<[usize; 4]> {
    let &[b, n, width] = dims else {
        return None;
    };
    let splits = heads > 0 && width.is_multiple_of(3 * heads);
    let len = b * n * width;
    let fits = len > 0 && u32::try_from(len).is_ok();
    (heads_kernels_on() && dtype == DType::F32 && splits && fits)
        .then(|| [b, n, heads, width / (3 * heads)])
}

/// A new uninitialised f32 buffer of `len` elements (see [`empty_f32`]).
fn empty(like: &CubeTensor, len: usize) -> CubeTensor {
    empty_f32(like, "q/k/v heads", len)
}

impl HeadsOps for CubeBackend {
    fn split_heads(qkv: FloatTensor<Self>, heads: usize) -> [FloatTensor<Self>; 3] {
        let Some([b, n, h, d]) = layout(&qkv.shape().to_vec(), qkv.dtype(), heads) else {
            return split::<Self>(qkv, heads);
        };
        let len = b * n * 3 * h * d;
        let qkv = flat(qkv);
        let parts = [0; 3].map(|_| empty(&qkv, len / 3));
        let client = qkv.client.clone();
        let dim = CubeDim::new(&client, len);
        split_heads::launch(
            &client,
            calculate_cube_count_elemwise(&client, len, dim),
            dim,
            qkv.into_tensor_arg(),
            parts[0].clone().into_tensor_arg(),
            parts[1].clone().into_tensor_arg(),
            parts[2].clone().into_tensor_arg(),
            n as u32,
            h as u32,
            d as u32,
            len as u32,
        );
        parts.map(|p| CubeBackend::float_reshape(p, Shape::new([b, h, n, d])))
    }

    fn merge_heads(parts: [FloatTensor<Self>; 3]) -> FloatTensor<Self> {
        let dims = parts[0].shape().to_vec();
        let alike = parts
            .iter()
            .all(|p| p.shape().to_vec() == dims && p.dtype() == DType::F32);
        let &[b, h, n, d] = dims.as_slice() else {
            return merge::<Self>(parts);
        };
        if !alike || layout(&[b, n, 3 * h * d], DType::F32, h).is_none() {
            return merge::<Self>(parts);
        }
        let len = b * n * 3 * h * d;
        let [q, k, v] = parts.map(flat);
        let out = empty(&q, len);
        let client = q.client.clone();
        let dim = CubeDim::new(&client, len);
        merge_heads::launch(
            &client,
            calculate_cube_count_elemwise(&client, len, dim),
            dim,
            q.into_tensor_arg(),
            k.into_tensor_arg(),
            v.into_tensor_arg(),
            out.clone().into_tensor_arg(),
            n as u32,
            h as u32,
            d as u32,
            len as u32,
        );
        CubeBackend::float_reshape(out, Shape::new([b, n, 3 * h * d]))
    }
}
