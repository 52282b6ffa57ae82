//! PSNR and SSIM over a region of each image (e.g. the ground-truth dynamic mask and its
//! complement), so a moving object's score is not drowned by the static background.
//!
//! - PSNR: the release's formula (both images clipped to [0, 1]) on the masked pixels only:
//!   `mse = mean over channels and masked pixels of (gt − pred)²`.
//! - SSIM: the per-pixel SSIM map of [`crate::ssim`] (same window, constants and reflect
//!   padding, computed on the whole image), averaged over channels and over the masked
//!   pixels inside the border SSIM leaves out.
//!
//! A region with no pixel (none masked, or only in SSIM's border) has no score (`None`).

use crate::error::{LossError, Result};
use crate::host::HostImages;
use crate::psnr::psnr_from_mse;
use crate::ssim::{ssim_interior, ssim_maps};

fn check_masks(images: &HostImages, masks: &[Vec<bool>]) -> Result<()> {
    let [n, _, h, w] = images.shape();
    if masks.len() != n || masks.iter().any(|m| m.len() != h * w) {
        return Err(LossError::Invalid {
            what: "region metric",
            reason: format!("need {n} masks of {h}x{w} pixels, got {}", masks.len()),
        });
    }
    Ok(())
}

/// PSNR (dB) of each image over its mask's pixels; `None` for an empty mask.
pub fn masked_psnr(
    pred: &HostImages,
    gt: &HostImages,
    masks: &[Vec<bool>],
) -> Result<Vec<Option<f64>>> {
    crate::psnr::same_shape("masked psnr", pred, gt)?;
    check_masks(pred, masks)?;
    let [n, c, h, w] = pred.shape();
    let plane = h * w;
    Ok((0..n)
        .map(|i| {
            let (p, g, m) = (pred.image(i), gt.image(i), &masks[i]);
            let count = m.iter().filter(|&&b| b).count();
            (count > 0).then(|| {
                let mut sum = 0.0;
                for ch in 0..c {
                    for px in (0..plane).filter(|&px| m[px]) {
                        let k = ch * plane + px;
                        let d = p[k].clamp(0.0, 1.0) - g[k].clamp(0.0, 1.0);
                        sum += d * d;
                    }
                }
                psnr_from_mse(sum / (count * c) as f64)
            })
        })
        .collect())
}

/// Mean SSIM of each image over its mask's pixels inside SSIM's border; `None` when none.
pub fn masked_ssim(
    pred: &HostImages,
    gt: &HostImages,
    masks: &[Vec<bool>],
) -> Result<Vec<Option<f64>>> {
    Ok(masked_ssims(pred, gt, &[masks])?.remove(0))
}

/// [`masked_ssim`] for several sets of masks (e.g. a region and its complement), from one
/// SSIM map per image: the map is the costly part.
pub fn masked_ssims(
    pred: &HostImages,
    gt: &HostImages,
    mask_sets: &[&[Vec<bool>]],
) -> Result<Vec<Vec<Option<f64>>>> {
    for masks in mask_sets {
        check_masks(pred, masks)?;
    }
    let [_, _, h, w] = pred.shape();
    let maps = ssim_maps(pred, gt)?;
    Ok(mask_sets
        .iter()
        .map(|masks| {
            maps.iter()
                .zip(masks.iter())
                .map(|(map, m)| {
                    let vals: Vec<f64> = (0..h * w)
                        .filter(|&px| m[px] && ssim_interior(px / w, px % w, h, w))
                        .map(|px| map[px])
                        .collect();
                    (!vals.is_empty()).then(|| vals.iter().sum::<f64>() / vals.len() as f64)
                })
                .collect()
        })
        .collect())
}
