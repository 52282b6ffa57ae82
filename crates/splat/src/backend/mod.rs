//! Burn integration: the `SplatOps` backend extension and its autodiff node.
//!
//! `splat_forward` renders `[V, H, W, 5]` = (R, G, B, accumulated depth, alpha) plus
//! non-differentiable meta; `splat_backward` is its vector-Jacobian product w.r.t. all seven
//! inputs (Gaussians and cameras). The default bodies run the plain-Rust CPU rasterizer on
//! host copies of the tensors: this is the implementation for burn-flex (the CPU backend).
//! CubeCL backends override both with GPU kernels (see `cube`). The autodiff node
//! (`autodiff`) stores the inputs, and what the inner backend's forward kept for the backward
//! (`keep`), and calls the inner backend's backward.

mod autodiff;
mod cube;
mod host;
mod host_sort;
mod keep;

pub use keep::{Forward, SplatKeep};

use crate::config::RasterConfig;
use crate::kernels::plan::KernelPlan;
use crate::views::{HostCameras, ViewSets};
use burn::backend::tensor::{FloatTensor, IntTensor};
use burn::backend::Backend;
use burn::backend::{backend_extension, ExtensionType};

/// Gradients of the seven rasterizer inputs (same shapes as the inputs).
#[derive(ExtensionType)]
pub struct SplatGrads<B: Backend> {
    pub means: FloatTensor<B>,
    pub quats: FloatTensor<B>,
    pub scales: FloatTensor<B>,
    pub opacities: FloatTensor<B>,
    pub colors: FloatTensor<B>,
    /// `[V, 4, 4]`, bottom rows zero.
    pub viewmats: FloatTensor<B>,
    /// `[V, 3, 3]`, only fx, fy, cx, cy non-zero.
    pub ks: FloatTensor<B>,
}

/// The rasterizer as a Burn backend operation.
///
/// Shapes: means `[N,3]`, quats `[N,4]` (w,x,y,z), scales `[N,3]`, opacities `[N]`,
/// colors `[N,3]`, viewmats `[V,4,4]` (world-to-camera, OpenCV axes), ks `[V,3,3]`; `sets`
/// says which of the N rows each view renders; `host_cameras` are viewmats and ks as
/// validation read them (the GPU kernels use them instead of reading the device again; the
/// host path reads its own copies). Callers validate shapes, sets and cameras first (see
/// [`render`](fn@crate::render)).
#[backend_extension(Cube, Flex, Autodiff)]
pub trait SplatOps: Backend {
    /// Returns `(image [V,H,W,5], radii [V,R,2] (int; R = [`ViewSets::radii_rows`]), counts
    /// [V,2] (int: visible Gaussians, tile intersections))`.
    #[allow(clippy::too_many_arguments)]
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
        _host_cameras: HostCameras,
        config: RasterConfig,
    ) -> (FloatTensor<Self>, IntTensor<Self>, IntTensor<Self>) {
        host::forward::<Self>(
            [means, quats, scales, opacities, colors, viewmats, ks],
            width,
            height,
            &sets,
            &config,
        )
    }

    /// Vector-Jacobian product of [`SplatOps::splat_forward`]'s image w.r.t. every input.
    #[allow(clippy::too_many_arguments)]
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
        _host_cameras: HostCameras,
        config: RasterConfig,
    ) -> SplatGrads<Self> {
        host::backward::<Self>(
            [means, quats, scales, opacities, colors, viewmats, ks],
            grad_image,
            width,
            height,
            &sets,
            &config,
        )
    }

    /// Stable sort of 1-D `(keys, values)` of equal length by the keys' low
    /// [`crate::kernels::sort::sorted_bits`]`(bits)` bits, keys read as 32-bit patterns.
    /// The rasterizer's depth and tile sorts; on CubeCL backends a device radix sort.
    fn splat_sort_pairs(
        keys: IntTensor<Self>,
        values: IntTensor<Self>,
        bits: u32,
    ) -> (IntTensor<Self>, IntTensor<Self>) {
        host_sort::sort_pairs::<Self>(keys, values, bits)
    }

    /// Exclusive prefix sum of a 1-D tensor with its total appended (`n` → `n + 1`
    /// elements), summed as u32. On CubeCL backends a device scan.
    fn splat_exclusive_scan(values: IntTensor<Self>) -> IntTensor<Self> {
        host_sort::exclusive_scan::<Self>(values)
    }

    /// Whether an exclusive scan's output (as [`SplatOps::splat_exclusive_scan`] returns
    /// it) wrapped past `u32::MAX`: some element below the one before it. Reads back one
    /// flag on CubeCL backends.
    fn splat_scan_wrapped(offsets: IntTensor<Self>) -> bool {
        host_sort::scan_wrapped::<Self>(offsets)
    }

    /// The compositing kernels a render with `config` runs on the device of `like`; `None`
    /// on the CPU path, which has one.
    fn splat_kernel_plan(like: FloatTensor<Self>, config: RasterConfig) -> Option<KernelPlan> {
        let _ = (like, config);
        None
    }
}

impl SplatOps for burn::backend::Flex {}
