//! Per-frame scores of rendered views, shared by the protocol and training's periodic
//! validation so the PSNR in a training log is the PSNR `eval` reports (paper §4: the
//! release's `compute_psnr`, images clipped to [0, 1]).

use crate::error::Result;
use burn::tensor::Tensor;
use envision4d_losses::{psnr, HostImages};

/// PSNR of identical images is +inf in the release; it is reported as this many dB so
/// means stay finite and JSON stays numeric. Real renders never come close.
pub const PSNR_CAP_DB: f64 = 100.0;

/// A PSNR (dB) as reported: capped at [`PSNR_CAP_DB`].
pub fn reported_psnr(db: f64) -> f64 {
    db.min(PSNR_CAP_DB)
}

/// PSNR (dB, capped) of each frame of `rendered` against `truth`, both `[F, 3, H, W]`.
pub fn psnr_per_frame(rendered: Tensor<4>, truth: Tensor<4>) -> Result<Vec<f64>> {
    let pred = HostImages::from_tensor("rendered frames", rendered)?;
    let gt = HostImages::from_tensor("ground-truth frames", truth)?;
    Ok(psnr(&pred, &gt)?.into_iter().map(reported_psnr).collect())
}
