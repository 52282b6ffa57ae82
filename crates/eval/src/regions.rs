//! Future frames scored on the ground-truth dynamic mask and on its complement, so what the
//! motion head does to moving objects is not drowned by the ego motion and the static
//! background that dominate whole-image PSNR (`losses::masked_psnr`, `masked_ssim`).

use crate::error::Result;
use crate::report::mean_opt;
use crate::score::reported_psnr;
use envision4d_losses::{masked_psnr, masked_ssims, EvalCrop, HostImages};

/// Means over the scored frames whose region is not empty.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RegionScores {
    pub dynamic_psnr: Option<f64>,
    pub dynamic_ssim: Option<f64>,
    pub static_psnr: Option<f64>,
    pub static_ssim: Option<f64>,
}

/// Region scores of `pred` against `gt` (`[F, 3, H, W]`) with one mask per frame (`H·W`),
/// all after `crop`. Default (all `None`) when any frame lacks a mask.
pub fn region_scores(
    pred: &HostImages,
    gt: &HostImages,
    masks: &[Option<&Vec<bool>>],
    crop: EvalCrop,
) -> Result<RegionScores> {
    let [f, _, h, w] = gt.shape();
    if masks.len() != f || masks.iter().any(Option::is_none) {
        return Ok(RegionScores::default());
    }
    let (top, kh, left, kw) = crop.window(h, w)?;
    let cropped: Vec<Vec<bool>> = masks
        .iter()
        .flatten()
        .map(|m| {
            (top..top + kh)
                .flat_map(|y| m[y * w + left..y * w + left + kw].iter().copied())
                .collect()
        })
        .collect();
    let inverse: Vec<Vec<bool>> = cropped
        .iter()
        .map(|m| m.iter().map(|b| !b).collect())
        .collect();
    let (p, g) = (crop.apply_images(pred)?, crop.apply_images(gt)?);
    let psnr = |m: &[Vec<bool>]| -> Result<Option<f64>> {
        Ok(mean_opt(
            masked_psnr(&p, &g, m)?
                .into_iter()
                .map(|v| v.map(reported_psnr)),
        ))
    };
    // One SSIM map per frame serves both regions.
    let mut ssims = masked_ssims(&p, &g, &[&cropped, &inverse])?
        .into_iter()
        .map(mean_opt);
    let (dynamic_ssim, static_ssim) = (ssims.next().flatten(), ssims.next().flatten());
    Ok(RegionScores {
        dynamic_psnr: psnr(&cropped)?,
        dynamic_ssim,
        static_psnr: psnr(&inverse)?,
        static_ssim,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the region split and the crop: an error only on the "moving" pixels lowers the
    /// dynamic PSNR to its exact value and leaves the static region perfect (capped), with
    /// the mask cropped like the images.
    #[test]
    fn error_on_the_moving_object_only() {
        let (h, w) = (14, 14);
        let gt = HostImages::new("gt", vec![0.5; 3 * h * w], [1, 3, h, w]).unwrap();
        let mask: Vec<bool> = (0..h * w).map(|i| (i / w) >= 7).collect();
        let mut p = vec![0.5; 3 * h * w];
        for (i, v) in p.iter_mut().enumerate() {
            if mask[i % (h * w)] {
                *v = 0.7;
            }
        }
        let pred = HostImages::new("pred", p, [1, 3, h, w]).unwrap();
        let crop = EvalCrop {
            top: 1,
            bottom: 1,
            left: 0,
            right: 0,
        };
        let r = region_scores(&pred, &gt, &[Some(&mask)], crop).unwrap();
        let want = -10.0 * (0.04f64).log10();
        assert!((r.dynamic_psnr.unwrap() - want).abs() < 1e-9, "{r:?}");
        assert_eq!(r.static_psnr, Some(crate::score::PSNR_CAP_DB));
        assert!(r.static_ssim.unwrap() > r.dynamic_ssim.unwrap_or(1.0) - 1.0);
        let none = region_scores(&pred, &gt, &[None], crop).unwrap();
        assert_eq!(none, RegionScores::default());
    }
}
