//! PSNR as the release's `compute_psnr` (`src/evaluation/metrics.py`) computes it.

use crate::error::{LossError, Result};
use crate::host::HostImages;

/// Lower clip bound applied to both images (the release clips to [0, 1]).
const CLIP_MIN: f64 = 0.0;
/// Upper clip bound applied to both images.
const CLIP_MAX: f64 = 1.0;

/// Peak signal-to-noise ratio per image, in dB.
///
/// Definition (as the release): clip both images to [0, 1]; `mse = mean over (C, H, W) of
/// (gt − pred)²`; `psnr = −10 · log10(mse)`. The data range is 1, so no peak term appears.
/// Computed in f64 (the reference runs float32 torch; the two differ by < 1e-6 dB).
/// Identical images (after clipping) give `+inf`, as in the release.
pub fn psnr(pred: &HostImages, gt: &HostImages) -> Result<Vec<f64>> {
    same_shape("psnr", pred, gt)?;
    let n = pred.shape()[0];
    Ok((0..n)
        .map(|i| {
            let (p, g) = (pred.image(i), gt.image(i));
            let sum: f64 = p
                .iter()
                .zip(g)
                .map(|(a, b)| {
                    let d = a.clamp(CLIP_MIN, CLIP_MAX) - b.clamp(CLIP_MIN, CLIP_MAX);
                    d * d
                })
                .sum();
            psnr_from_mse(sum / p.len() as f64)
        })
        .collect())
}

/// PSNR (dB) of images in [0, 1] from their mean squared error: `−10·log10(mse)` (the data
/// range is 1). `+inf` for `mse = 0`. The one formula [`psnr`] and the training log share.
pub fn psnr_from_mse(mse: f64) -> f64 {
    -10.0 * mse.log10()
}

/// Shape check shared by the image metrics.
pub(crate) fn same_shape(what: &'static str, a: &HostImages, b: &HostImages) -> Result<()> {
    if a.shape() != b.shape() {
        return Err(LossError::ShapeMismatch {
            what,
            left: a.shape().to_vec(),
            right: b.shape().to_vec(),
        });
    }
    Ok(())
}
