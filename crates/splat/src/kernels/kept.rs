//! What a differentiated forward keeps for its backward ([`crate::BackwardBins::Keep`]): per
//! view, the projected records and the tile lists the compositing read, and every pixel's
//! final transmittance and last composited item. With them the backward composites in
//! reverse at once; without them it projects and bins every view again, which costs both
//! sorts and one more host read of the intersection totals, and replays the forward's
//! compositing to find where each pixel stopped.

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
    /// past its last composited item, written by the forward for every view of the render
    /// call (one buffer, shared by its views); `None` when the backward binned the view
    /// again and must replay the compositing instead.
    pub ends: Option<CubeTensor>,
}
