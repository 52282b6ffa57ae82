//! `SplatOps` for the CubeCL backends (wgpu; CUDA where built): f32 tensors run the CubeCL
//! kernels of [`crate::kernels`]; other float types (f64 oracle runs, half precision) take the
//! host path, which is exact but slow.

use super::{host, host_sort, Forward, SplatGrads, SplatKeep, SplatOps};
use crate::config::RasterConfig;
use crate::kernels::buffers;
use crate::kernels::kept::ViewRender;
use crate::kernels::launch::{self, Inputs};
use crate::kernels::launch_backward;
use crate::kernels::plan::KernelPlan;
use crate::kernels::readback::read_u32s;
use crate::kernels::sort;
use crate::views::{HostCameras, ViewSets};
use burn::backend::tensor::{FloatTensor, IntTensor};
use burn::backend::TensorMetadata;
use burn::tensor::DType;
use burn_cubecl::kernel::into_contiguous;
use burn_cubecl::tensor::CubeTensor;
use burn_cubecl::CubeBackend;

impl SplatOps for CubeBackend {
    fn splat_forward(
        means: FloatTensor<Self>,
        quats: FloatTensor<Self>,
        scales: FloatTensor<Self>,
        opacities: FloatTensor<Self>,
        colors: FloatTensor<Self>,
        viewmats: FloatTensor<Self>,
        ks: FloatTensor<Self>,
        width: u32,
        height: u32,
        sets: ViewSets,
        host_cameras: HostCameras,
        config: RasterConfig,
    ) -> (FloatTensor<Self>, IntTensor<Self>, IntTensor<Self>) {
        let inputs = [means, quats, scales, opacities, colors, viewmats, ks];
        forward(inputs, width, height, &sets, &host_cameras, &config, false).0
    }

    fn splat_backward(
        means: FloatTensor<Self>,
        quats: FloatTensor<Self>,
        scales: FloatTensor<Self>,
        opacities: FloatTensor<Self>,
        colors: FloatTensor<Self>,
        viewmats: FloatTensor<Self>,
        ks: FloatTensor<Self>,
        grad_image: FloatTensor<Self>,
        width: u32,
        height: u32,
        sets: ViewSets,
        host_cameras: HostCameras,
        config: RasterConfig,
    ) -> SplatGrads<Self> {
        let inputs = [means, quats, scales, opacities, colors, viewmats, ks];
        backward(
            inputs,
            grad_image,
            None,
            width,
            height,
            &sets,
            &host_cameras,
            &config,
        )
    }

    fn splat_sort_pairs(
        keys: IntTensor<Self>,
        values: IntTensor<Self>,
        bits: u32,
    ) -> (IntTensor<Self>, IntTensor<Self>) {
        if !is_32bit(&keys) || !is_32bit(&values) {
            return host_sort::sort_pairs::<Self>(keys, values, bits);
        }
        let n = keys.shape().num_elements();
        let (kd, vd) = (keys.dtype(), values.dtype());
        let (k, v) = sort::sort_pairs(&words(keys), &words(values), n, bits);
        (sort::retype(k, kd), sort::retype(v, vd))
    }

    fn splat_exclusive_scan(values: IntTensor<Self>) -> IntTensor<Self> {
        if !is_32bit(&values) {
            return host_sort::exclusive_scan::<Self>(values);
        }
        let n = values.shape().num_elements();
        let dtype = values.dtype();
        sort::retype(sort::exclusive_scan(&words(values), n, n + 1), dtype)
    }

    fn splat_scan_wrapped(offsets: IntTensor<Self>) -> bool {
        if !is_32bit(&offsets) {
            return host_sort::scan_wrapped::<Self>(offsets);
        }
        let n = offsets.shape().num_elements();
        if n < 2 {
            return false;
        }
        let words = words(offsets);
        let flag = buffers::zeros_u32(&words, 1);
        sort::flag_wrapped(&words, n, &flag, 0);
        read_u32s(flag)[0] != 0
    }

    fn splat_kernel_plan(like: FloatTensor<Self>, config: RasterConfig) -> Option<KernelPlan> {
        Some(KernelPlan::of(&like, &config))
    }
}

fn is_32bit(t: &IntTensor<CubeBackend>) -> bool {
    matches!(t.dtype(), DType::I32 | DType::U32)
}

/// A contiguous u32 view of a 32-bit integer tensor.
fn words(t: IntTensor<CubeBackend>) -> CubeTensor {
    sort::retype(into_contiguous(t), DType::U32)
}

impl SplatKeep for CubeBackend {
    /// Every view as the compositing read it (`None`: no tile intersection).
    type Kept = Vec<Option<ViewRender>>;

    fn splat_forward_kept(
        inputs: [FloatTensor<Self>; 7],
        width: u32,
        height: u32,
        sets: ViewSets,
        host_cameras: HostCameras,
        config: RasterConfig,
    ) -> (Forward<Self>, Option<Self::Kept>) {
        forward(inputs, width, height, &sets, &host_cameras, &config, true)
    }

    fn splat_backward_kept(
        inputs: [FloatTensor<Self>; 7],
        grad_image: FloatTensor<Self>,
        kept: Self::Kept,
        width: u32,
        height: u32,
        sets: ViewSets,
        host_cameras: HostCameras,
        config: RasterConfig,
    ) -> SplatGrads<Self> {
        let kept = Some(kept);
        backward(
            inputs,
            grad_image,
            kept,
            width,
            height,
            &sets,
            &host_cameras,
            &config,
        )
    }
}

/// The forward on the device for f32 inputs, on the host path otherwise; with `keep`, every
/// view as the compositing read it (`None` on the host path, which keeps nothing).
fn forward(
    inputs: [CubeTensor; 7],
    width: u32,
    height: u32,
    sets: &ViewSets,
    host_cameras: &HostCameras,
    config: &RasterConfig,
    keep: bool,
) -> (Forward<CubeBackend>, Option<Vec<Option<ViewRender>>>) {
    if inputs.iter().any(|t| t.dtype() != DType::F32) {
        return (
            host::forward::<CubeBackend>(inputs, width, height, sets, config),
            None,
        );
    }
    let inp = Inputs::new(inputs, host_cameras, width, height, sets);
    let (image, radii, counts, kept) = launch::forward(&inp, config, keep);
    ((image, radii, counts), keep.then_some(kept))
}

/// The backward on the device for f32 tensors, reusing `kept` where the forward kept it; on
/// the host path otherwise.
#[allow(clippy::too_many_arguments)]
fn backward(
    inputs: [CubeTensor; 7],
    grad_image: CubeTensor,
    kept: Option<Vec<Option<ViewRender>>>,
    width: u32,
    height: u32,
    sets: &ViewSets,
    host_cameras: &HostCameras,
    config: &RasterConfig,
) -> SplatGrads<CubeBackend> {
    if inputs.iter().any(|t| t.dtype() != DType::F32) || grad_image.dtype() != DType::F32 {
        return host::backward::<CubeBackend>(inputs, grad_image, width, height, sets, config);
    }
    let shapes = inputs.each_ref().map(|t| t.shape());
    let inp = Inputs::new(inputs, host_cameras, width, height, sets);
    launch_backward::backward(&inp, grad_image, shapes, config, kept)
}
