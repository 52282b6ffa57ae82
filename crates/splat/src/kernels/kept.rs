//! What a differentiated forward keeps for its backward ([`crate::BackwardBins::Keep`]): per
//! view, the projected records and the tile lists the compositing read, and every pixel's
//! final transmittance and last composited item. With them the backward composites in
//! reverse at once; without them it projects, bins and composites every view again, which
//! costs both sorts, one more host read of the intersection totals and a forward's
//! compositing.

use super::binning::DeviceBins;
use burn_cubecl::tensor::CubeTensor;

/// One view as the compositing saw it: its projection, its tile lists and where its pixels
/// stopped.
#[derive(Clone, Debug)]
pub struct ViewRender {
    /// The view's Gaussians: `rows` input rows from `first`.
    pub first: usize,
    pub rows: usize,
    pub cam_rec: CubeTensor,
    pub records: CubeTensor,
    pub meta: CubeTensor,
    pub bins: DeviceBins,
    /// `[pixels of the batch, 2]` u32: each pixel's final transmittance (f32 bits) and one
    /// past its last composited item, as the compositing left them (one buffer of the
    /// render call, shared by its views; a single unused word where nothing is kept).
    pub ends: CubeTensor,
}
