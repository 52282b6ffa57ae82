//! What a differentiated forward keeps for its backward ([`crate::BackwardBins::Keep`]): per
//! view, the projected records and the tile lists the compositing read. With them the
//! backward composites in reverse at once; without them it projects and bins every view
//! again, which costs both sorts and one more host read of the intersection totals.

use super::binning::DeviceBins;
use burn_cubecl::tensor::CubeTensor;

/// One view as the compositing saw it: its projection and its tile lists.
#[derive(Clone, Debug)]
pub struct ViewRender {
    /// The view's Gaussians: `rows` input rows from `first`.
    pub first: usize,
    pub rows: usize,
    pub cam_rec: CubeTensor,
    pub records: CubeTensor,
    pub meta: CubeTensor,
    pub bins: DeviceBins,
}
