//! SSIM matching scikit-image's
//! `structural_similarity(gt, pred, win_size=11, gaussian_weights=True, sigma=1.5,
//! data_range=1.0, channel_axis=0)`, the call of the release's `compute_ssim`.

use crate::error::{LossError, Result};
use crate::host::HostImages;
use crate::psnr::same_shape;

/// Gaussian window standard deviation (skimage `sigma`, Wang et al. 2004).
const SIGMA: f64 = 1.5;
/// scipy `gaussian_filter` truncation, as skimage passes it; radius = int(3.5·1.5 + 0.5) = 5.
const TRUNCATE: f64 = 3.5;
/// Window side (`win_size=11`): 2·radius + 1 taps.
pub const SSIM_WIN_SIZE: usize = 11;
/// Luminance stabiliser constant factor.
pub(crate) const K1: f64 = 0.01;
/// Contrast/structure stabiliser constant factor.
pub(crate) const K2: f64 = 0.03;
/// `data_range` of the release call: images are in [0, 1].
pub(crate) const DATA_RANGE: f64 = 1.0;

/// Mean structural similarity per image (mean over channels of the per-channel mean SSIM).
///
/// Definition, per channel of each image (as scikit-image 0.26 with the release's arguments):
/// * `μx, μy, μxx, μyy, μxy` = Gaussian filter (σ 1.5, 11 taps, normalised, scipy mode
///   `reflect`: `d c b a | a b c d | d c b a`) of `x, y, x², y², xy`;
/// * sample-covariance correction `cov_norm = NP / (NP − 1)` with `NP = 11² = 121`:
///   `vx = cov_norm·(μxx − μx²)`, `vy = ...`, `vxy = cov_norm·(μxy − μx·μy)`;
/// * `C1 = (0.01·1)², C2 = (0.03·1)²`;
///   `S = (2μxμy + C1)(2vxy + C2) / ((μx² + μy² + C1)(vx + vy + C2))`;
/// * the mean of `S` over the image with a 5-pixel border removed on every side.
///
/// No clipping (the release clips only for PSNR). Constant images are well defined (the
/// constants keep the denominator positive): SSIM(x, x) = 1. Both sides must be at least
/// 11 pixels, as skimage requires. Computed in f64 (the reference runs float32 numpy; the
/// two differ by ~1e-7).
pub fn ssim(pred: &HostImages, gt: &HostImages) -> Result<Vec<f64>> {
    same_shape("ssim", pred, gt)?;
    let [n, c, h, w] = pred.shape();
    check_window("ssim", h, w)?;
    let taps = gaussian_taps();
    let plane = h * w;
    Ok((0..n)
        .map(|i| {
            let (x, y) = (gt.image(i), pred.image(i));
            let total: f64 = (0..c)
                .map(|ch| {
                    let r = ch * plane..(ch + 1) * plane;
                    channel_ssim(&x[r.clone()], &y[r], h, w, &taps)
                })
                .sum();
            total / c as f64
        })
        .collect())
}

/// Both image sides must hold the 11-pixel window, as skimage requires.
pub(crate) fn check_window(what: &'static str, h: usize, w: usize) -> Result<()> {
    if h < SSIM_WIN_SIZE || w < SSIM_WIN_SIZE {
        return Err(LossError::Invalid {
            what,
            reason: format!(
                "a {h}x{w} image is smaller than the {SSIM_WIN_SIZE}x{SSIM_WIN_SIZE} window"
            ),
        });
    }
    Ok(())
}

/// scipy `_gaussian_kernel1d(sigma, order=0, radius)`: `exp(−x²/(2σ²))` normalised to sum 1.
pub(crate) fn gaussian_taps() -> Vec<f64> {
    let radius = (TRUNCATE * SIGMA + 0.5) as i64;
    let raw: Vec<f64> = (-radius..=radius)
        .map(|x| (-0.5 * (x * x) as f64 / (SIGMA * SIGMA)).exp())
        .collect();
    let sum: f64 = raw.iter().sum();
    raw.into_iter().map(|v| v / sum).collect()
}

/// scipy's `reflect` boundary (half-sample symmetric), valid for any offset.
pub(crate) fn reflect(i: i64, n: usize) -> usize {
    let n = n as i64;
    let m = i.rem_euclid(2 * n);
    (if m >= n { 2 * n - 1 - m } else { m }) as usize
}

/// Separable Gaussian filter of an `h × w` plane: axis 0 (rows) then axis 1, like scipy.
fn gaussian_filter(src: &[f64], h: usize, w: usize, taps: &[f64]) -> Vec<f64> {
    let r = (taps.len() / 2) as i64;
    let mut tmp = vec![0.0; h * w];
    for y in 0..h {
        for x in 0..w {
            tmp[y * w + x] = taps
                .iter()
                .enumerate()
                .map(|(k, t)| t * src[reflect(y as i64 + k as i64 - r, h) * w + x])
                .sum();
        }
    }
    let mut out = vec![0.0; h * w];
    for y in 0..h {
        let row = &tmp[y * w..(y + 1) * w];
        for x in 0..w {
            out[y * w + x] = taps
                .iter()
                .enumerate()
                .map(|(k, t)| t * row[reflect(x as i64 + k as i64 - r, w)])
                .sum();
        }
    }
    out
}

/// Mean SSIM of one channel over the border-cropped interior.
fn channel_ssim(x: &[f64], y: &[f64], h: usize, w: usize, taps: &[f64]) -> f64 {
    let map = channel_ssim_map(x, y, h, w, taps);
    // skimage crops (win_size − 1) / 2 pixels on each side before averaging.
    let pad = (SSIM_WIN_SIZE - 1) / 2;
    let mut sum = 0.0;
    for yy in pad..h - pad {
        for xx in pad..w - pad {
            sum += map[yy * w + xx];
        }
    }
    sum / ((h - 2 * pad) * (w - 2 * pad)) as f64
}

/// Per-pixel SSIM of each image, averaged over channels (`[H·W]` per image); only the
/// interior ([`ssim_interior`]) is what [`ssim`] averages.
pub fn ssim_maps(pred: &HostImages, gt: &HostImages) -> Result<Vec<Vec<f64>>> {
    same_shape("ssim", pred, gt)?;
    let [n, c, h, w] = pred.shape();
    check_window("ssim", h, w)?;
    let taps = gaussian_taps();
    let plane = h * w;
    Ok((0..n)
        .map(|i| {
            let (x, y) = (gt.image(i), pred.image(i));
            let mut mean = vec![0.0; plane];
            for ch in 0..c {
                let r = ch * plane..(ch + 1) * plane;
                for (m, v) in
                    mean.iter_mut()
                        .zip(channel_ssim_map(&x[r.clone()], &y[r], h, w, &taps))
                {
                    *m += v / c as f64;
                }
            }
            mean
        })
        .collect())
}

/// Whether pixel `(y, x)` of an `h × w` image is inside the border [`ssim`] leaves out.
pub fn ssim_interior(y: usize, x: usize, h: usize, w: usize) -> bool {
    let pad = (SSIM_WIN_SIZE - 1) / 2;
    y >= pad && x >= pad && y + pad < h && x + pad < w
}

/// Per-pixel SSIM of one channel (every pixel; the caller picks the interior).
fn channel_ssim_map(x: &[f64], y: &[f64], h: usize, w: usize, taps: &[f64]) -> Vec<f64> {
    let np = (SSIM_WIN_SIZE * SSIM_WIN_SIZE) as f64;
    let cov_norm = np / (np - 1.0);
    let prod = |f: &dyn Fn(usize) -> f64| (0..h * w).map(f).collect::<Vec<f64>>();
    let ux = gaussian_filter(x, h, w, taps);
    let uy = gaussian_filter(y, h, w, taps);
    let uxx = gaussian_filter(&prod(&|i| x[i] * x[i]), h, w, taps);
    let uyy = gaussian_filter(&prod(&|i| y[i] * y[i]), h, w, taps);
    let uxy = gaussian_filter(&prod(&|i| x[i] * y[i]), h, w, taps);
    let c1 = (K1 * DATA_RANGE).powi(2);
    let c2 = (K2 * DATA_RANGE).powi(2);
    (0..h * w)
        .map(|i| {
            let vx = cov_norm * (uxx[i] - ux[i] * ux[i]);
            let vy = cov_norm * (uyy[i] - uy[i] * uy[i]);
            let vxy = cov_norm * (uxy[i] - ux[i] * uy[i]);
            let a1 = 2.0 * ux[i] * uy[i] + c1;
            let a2 = 2.0 * vxy + c2;
            let b1 = ux[i] * ux[i] + uy[i] * uy[i] + c1;
            let b2 = vx + vy + c2;
            (a1 * a2) / (b1 * b2)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the scipy `reflect` mode (half-sample symmetric, not `mirror`).
    #[test]
    fn reflect_is_half_sample_symmetric() {
        assert_eq!(reflect(-1, 5), 0);
        assert_eq!(reflect(-2, 5), 1);
        assert_eq!(reflect(5, 5), 4);
        assert_eq!(reflect(6, 5), 3);
        assert_eq!(reflect(-6, 2), 1);
    }

    /// Guards the 11-tap normalised Gaussian window.
    #[test]
    fn taps_are_normalised_and_eleven() {
        let t = gaussian_taps();
        assert_eq!(t.len(), SSIM_WIN_SIZE);
        assert!((t.iter().sum::<f64>() - 1.0).abs() < 1e-15);
    }
}
