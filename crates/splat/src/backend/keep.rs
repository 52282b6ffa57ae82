//! What a differentiated forward keeps for its backward ([`crate::BackwardBins`]), per
//! backend. Not part of the dispatched extension: only the autodiff node calls it, on its
//! inner backend, and the state never leaves that node.

use super::{host, SplatGrads, SplatOps};
use crate::config::RasterConfig;
use crate::views::{HostCameras, ViewSets};
use burn::backend::tensor::{FloatTensor, IntTensor};

/// `splat_forward`'s outputs: image, radii, counts.
pub type Forward<B> = (FloatTensor<B>, IntTensor<B>, IntTensor<B>);

/// A rasterizer forward that may keep intermediate buffers for its backward.
pub trait SplatKeep: SplatOps {
    /// Opaque to the autodiff node, which holds it from the forward to the backward.
    type Kept: Clone + std::fmt::Debug + Send + Sync + 'static;

    /// [`SplatOps::splat_forward`], and what its backward may reuse (`None`: nothing; the
    /// backward recomputes).
    fn splat_forward_kept(
        inputs: [FloatTensor<Self>; 7],
        width: u32,
        height: u32,
        sets: ViewSets,
        host_cameras: HostCameras,
        config: RasterConfig,
    ) -> (Forward<Self>, Option<Self::Kept>);

    /// [`SplatOps::splat_backward`] of the same inputs, given what their forward kept.
    #[allow(clippy::too_many_arguments)]
    fn splat_backward_kept(
        inputs: [FloatTensor<Self>; 7],
        grad_image: FloatTensor<Self>,
        kept: Self::Kept,
        width: u32,
        height: u32,
        sets: ViewSets,
        host_cameras: HostCameras,
        config: RasterConfig,
    ) -> SplatGrads<Self>;
}

/// The host path keeps nothing: its binning is a small share of its compositing, and it
/// would hold per-pixel lists in host memory between the passes.
impl SplatKeep for burn::backend::Flex {
    type Kept = ();

    fn splat_forward_kept(
        inputs: [FloatTensor<Self>; 7],
        width: u32,
        height: u32,
        sets: ViewSets,
        _host_cameras: HostCameras,
        config: RasterConfig,
    ) -> (Forward<Self>, Option<()>) {
        (
            host::forward::<Self>(inputs, width, height, &sets, &config),
            None,
        )
    }

    fn splat_backward_kept(
        inputs: [FloatTensor<Self>; 7],
        grad_image: FloatTensor<Self>,
        _kept: (),
        width: u32,
        height: u32,
        sets: ViewSets,
        _host_cameras: HostCameras,
        config: RasterConfig,
    ) -> SplatGrads<Self> {
        host::backward::<Self>(inputs, grad_image, width, height, &sets, &config)
    }
}
