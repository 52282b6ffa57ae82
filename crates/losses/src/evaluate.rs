//! The evaluation entry point: every image metric on the same (optionally cropped) pixels.

use crate::crop::EvalCrop;
use crate::error::Result;
use crate::host::HostImages;
use crate::lpips::LpipsStatus;
use crate::psnr::psnr;
use crate::ssim::ssim;

/// Per-image metrics of a batch (release protocol: one value per image, then averaged by the
/// caller over future frames and clips).
#[derive(Debug, Clone, PartialEq)]
pub struct ImageMetrics {
    /// PSNR in dB ([`psnr`]).
    pub psnr: Vec<f64>,
    /// SSIM ([`ssim`]).
    pub ssim: Vec<f64>,
    /// LPIPS ([`crate::Lpips::forward`]); `None` when no weights are loaded (see
    /// [`LpipsStatus::notice`]), never a number from random weights.
    pub lpips: Option<Vec<f64>>,
}

/// PSNR, SSIM and (if available) LPIPS of `pred` against `gt` (`[N, 3, H, W]`, [0, 1]),
/// after applying `crop` to both, the same way for every metric.
pub fn evaluate_images(
    pred: &HostImages,
    gt: &HostImages,
    crop: EvalCrop,
    lpips: &LpipsStatus,
) -> Result<ImageMetrics> {
    crate::psnr::same_shape("evaluate", pred, gt)?;
    let (pred, gt) = (crop.apply_images(pred)?, crop.apply_images(gt)?);
    Ok(ImageMetrics {
        psnr: psnr(&pred, &gt)?,
        ssim: ssim(&pred, &gt)?,
        lpips: match lpips.get() {
            // The release calls lpips(gt, pred); the distance is symmetric anyway.
            Some(net) => Some(net.distance_host(&gt, &pred)?),
            None => None,
        },
    })
}
