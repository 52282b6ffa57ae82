//! Device buffers of the CubeCL rasterizer: flat views, uploads and zero-filled outputs, each
//! checked against the device's storage-binding limit first (the check the model's and the
//! optimiser's kernels use too).

use burn::backend::ops::FloatTensorOps;
use burn::backend::TensorMetadata;
use burn::tensor::{DType, Shape, TensorData};
use burn_cubecl::kernel::into_contiguous;
use burn_cubecl::ops::numeric::{empty_device_dtype, zeros_client};
use burn_cubecl::tensor::CubeTensor;
use burn_cubecl::CubeBackend;

/// A flat (1-D, contiguous) view of `t`, so kernels may index it with `row * lanes + k`.
pub fn flat(t: CubeTensor) -> CubeTensor {
    let n = t.shape().num_elements();
    CubeBackend::float_reshape(into_contiguous(t), Shape::new([n]))
}

/// A new uninitialised f32 buffer of `len` elements on `like`'s device for the kernel output
/// `what`, checked against the device's binding limit first (every element is written by
/// the kernel that takes it).
pub fn empty_f32(like: &CubeTensor, what: &str, len: usize) -> CubeTensor {
    check_binding(like, what, len);
    empty_device_dtype(
        like.client.clone(),
        like.device.clone(),
        Shape::new([len]),
        DType::F32,
    )
}

/// Fails loudly when a buffer of `elems` 4-byte values cannot be bound on this device.
///
/// WebGPU limits one storage binding (128 MiB on lavapipe and the WebGPU default; more on real
/// GPUs). Past it wgpu would reject or silently truncate the binding, so stop first with the
/// numbers and a way out; the op has no error channel, hence a panic with a clear message.
pub fn check_binding(like: &CubeTensor, what: &str, elems: usize) {
    let limit = like.client.properties().memory.max_page_size;
    let bytes = (elems as u64).saturating_mul(4);
    if bytes > limit {
        panic!(
            "CubeCL: the {what} buffer needs {bytes} bytes but this device binds at most \
             {limit} bytes per storage buffer; give one call less (fewer Gaussians or \
             fewer/smaller views per render, a smaller batch or image), or use the CPU backend"
        );
    }
}

pub(crate) fn upload_f32(like: &CubeTensor, v: Vec<f32>) -> CubeTensor {
    let len = v.len();
    CubeBackend::float_from_data(TensorData::new(v, [len]), &like.device)
}

/// A zero-filled u32 buffer of `len` elements.
pub(crate) fn zeros_u32(like: &CubeTensor, len: usize) -> CubeTensor {
    zeros_of(like, len, DType::U32)
}

/// A zero-filled f32 buffer of `len` elements.
pub(crate) fn zeros(like: &CubeTensor, len: usize) -> CubeTensor {
    zeros_of(like, len, DType::F32)
}

fn zeros_of(like: &CubeTensor, len: usize, dtype: DType) -> CubeTensor {
    check_binding(like, "output", len);
    zeros_client(
        like.client.clone(),
        like.device.clone(),
        Shape::new([len]),
        dtype,
    )
}
