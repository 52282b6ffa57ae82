//! Fitting frames to the model size: bilinear resize or centre crop, plus the matching
//! change of intrinsics.

use crate::error::{DataError, Result};
use crate::frame::Image;
use crate::geom::Intrinsics;
use std::path::Path;

/// The paper's input size (H, W).
pub const MODEL_SIZE: (usize, usize) = (350, 518);

/// How a frame is brought to the output size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FitMode {
    /// Bilinear resize to (H, W); the aspect ratio may change (the official loader does this).
    Resize,
    /// Cut the centred (H, W) window; frames must be at least that large.
    CenterCrop,
}

/// Output size and mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fit {
    pub mode: FitMode,
    pub height: usize,
    pub width: usize,
}

impl Default for Fit {
    fn default() -> Self {
        Fit {
            mode: FitMode::Resize,
            height: MODEL_SIZE.0,
            width: MODEL_SIZE.1,
        }
    }
}

impl Fit {
    pub fn validate(&self) -> Result<()> {
        if self.height == 0 || self.width == 0 {
            return Err(DataError::config(
                "size",
                format!("{}x{}", self.height, self.width),
                "height and width must be positive",
            ));
        }
        Ok(())
    }
    /// Applies the fit to a frame decoded from `path` (named in errors).
    pub fn apply(&self, img: &Image, path: &Path) -> Result<Image> {
        match self.mode {
            FitMode::Resize => Ok(resize_bilinear(img, self.height, self.width)),
            FitMode::CenterCrop => center_crop(img, self.height, self.width, path),
        }
    }
    /// Intrinsics of the fitted frame, given those of the source frame of size (H, W).
    pub fn intrinsics(&self, k: &Intrinsics, from: (usize, usize)) -> Intrinsics {
        match self.mode {
            FitMode::Resize => k.resized(from, (self.height, self.width)),
            FitMode::CenterCrop => k.cropped(crop_offset(from, (self.height, self.width))),
        }
    }
}

/// Top-left (row, col) of the centred crop; the odd pixel goes to the bottom/right.
pub fn crop_offset(from: (usize, usize), to: (usize, usize)) -> (usize, usize) {
    (
        from.0.saturating_sub(to.0) / 2,
        from.1.saturating_sub(to.1) / 2,
    )
}

pub fn center_crop(img: &Image, h: usize, w: usize, path: &Path) -> Result<Image> {
    if img.height < h || img.width < w {
        return Err(DataError::CropTooLarge {
            path: path.to_path_buf(),
            w: img.width,
            h: img.height,
            crop_w: w,
            crop_h: h,
        });
    }
    let (r0, c0) = crop_offset((img.height, img.width), (h, w));
    let mut data = Vec::with_capacity(h * w * 3);
    for r in r0..r0 + h {
        let start = (r * img.width + c0) * 3;
        data.extend_from_slice(&img.data[start..start + w * 3]);
    }
    Ok(Image::new(w, h, data))
}

/// One output sample's taps: first input index and normalised weights.
struct Taps {
    start: usize,
    weights: Vec<f32>,
}

/// Triangle-filter taps along one axis, PIL-style: sample centres at (i + 0.5) * scale, and
/// when downscaling the support widens by the scale so every input pixel contributes
/// (plain 2-tap bilinear would alias). Upscaling is ordinary half-pixel bilinear.
fn axis_taps(n_in: usize, n_out: usize) -> Vec<Taps> {
    let scale = n_in as f64 / n_out as f64;
    let support = scale.max(1.0);
    (0..n_out)
        .map(|i| {
            let centre = (i as f64 + 0.5) * scale;
            let lo = ((centre - support).floor().max(0.0)) as usize;
            let hi = ((centre + support).ceil() as usize).min(n_in);
            let mut weights: Vec<f32> = (lo..hi)
                .map(|j| {
                    let d = (j as f64 + 0.5 - centre) / support;
                    (1.0 - d.abs()).max(0.0) as f32
                })
                .collect();
            let sum: f32 = weights.iter().sum();
            // Edge taps outside the image are dropped and the rest renormalised.
            for w in &mut weights {
                *w /= sum;
            }
            Taps { start: lo, weights }
        })
        .collect()
}

/// Separable bilinear (triangle-filter) resize to (h, w). Same size returns a copy.
pub fn resize_bilinear(img: &Image, h: usize, w: usize) -> Image {
    if img.height == h && img.width == w {
        return img.clone();
    }
    let cols = axis_taps(img.width, w);
    let rows = axis_taps(img.height, h);
    // Horizontal pass: (img.height, w).
    let mut tmp = vec![0.0f32; img.height * w * 3];
    for r in 0..img.height {
        for (c, taps) in cols.iter().enumerate() {
            let mut acc = [0.0f32; 3];
            for (k, wt) in taps.weights.iter().enumerate() {
                let px = img.pixel(r, taps.start + k);
                (0..3).for_each(|ch| acc[ch] += wt * px[ch]);
            }
            tmp[(r * w + c) * 3..][..3].copy_from_slice(&acc);
        }
    }
    // Vertical pass: (h, w).
    let mut out = vec![0.0f32; h * w * 3];
    for (r, taps) in rows.iter().enumerate() {
        for c in 0..w {
            let mut acc = [0.0f32; 3];
            for (k, wt) in taps.weights.iter().enumerate() {
                let i = ((taps.start + k) * w + c) * 3;
                (0..3).for_each(|ch| acc[ch] += wt * tmp[i + ch]);
            }
            out[(r * w + c) * 3..][..3].copy_from_slice(&acc);
        }
    }
    Image::new(w, h, out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the half-pixel convention of upscaling: 2 px -> 4 px gives 1/4, 3/4 mixes.
    #[test]
    fn upscale_half_pixel_weights() {
        let img = Image::new(2, 1, vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
        let out = resize_bilinear(&img, 1, 4);
        let red: Vec<f32> = out.data.chunks(3).map(|p| p[0]).collect();
        assert_eq!(red, vec![0.0, 0.25, 0.75, 1.0]);
    }

    /// Guards weight normalisation: a constant image stays constant at any size.
    #[test]
    fn constant_stays_constant() {
        let img = Image::filled(37, 23, [0.3, 0.6, 0.9]);
        for (h, w) in [(7, 11), (50, 80), (23, 37), (1, 1)] {
            let out = resize_bilinear(&img, h, w);
            assert_eq!((out.height, out.width), (h, w));
            assert!(out.data.chunks(3).all(|p| (p[0] - 0.3).abs() < 1e-5
                && (p[1] - 0.6).abs() < 1e-5
                && (p[2] - 0.9).abs() < 1e-5));
        }
    }

    /// Guards antialiased downscaling: halving averages pixel pairs (no skipped pixels).
    #[test]
    fn downscale_by_two_averages() {
        let data: Vec<f32> = [0.0f32, 1.0, 0.0, 1.0]
            .iter()
            .flat_map(|&v| [v; 3])
            .collect();
        let out = resize_bilinear(&Image::new(4, 1, data), 1, 2);
        // Support 2 px: taps 3/7, 3/7, 1/7 (edge tap dropped) give 3/7 and 4/7, not 0 and 1.
        assert!(
            out.data.chunks(3).all(|p| (p[0] - 0.5).abs() < 0.13),
            "{:?}",
            out.data
        );
    }

    /// Guards the centre-crop offsets (odd remainder to the bottom/right) and pixel copy.
    #[test]
    fn center_crop_offsets() {
        assert_eq!(crop_offset((5, 7), (2, 2)), (1, 2));
        let data: Vec<f32> = (0..5 * 7).flat_map(|i| [i as f32; 3]).collect();
        let out = center_crop(&Image::new(7, 5, data), 2, 2, Path::new("x.png")).unwrap();
        let vals: Vec<f32> = out.data.chunks(3).map(|p| p[0]).collect();
        assert_eq!(vals, vec![9.0, 10.0, 16.0, 17.0]);
        let err = center_crop(&out, 3, 3, Path::new("small.png")).unwrap_err();
        assert!(err.to_string().contains("small.png"), "{err}");
    }

    /// Guards intrinsics bookkeeping: resize scales, crop shifts the principal point.
    #[test]
    fn intrinsics_follow_fit() {
        let k = Intrinsics {
            fx: 100.0,
            fy: 80.0,
            cx: 64.0,
            cy: 48.0,
        };
        let r = Fit {
            mode: FitMode::Resize,
            height: 48,
            width: 64,
        }
        .intrinsics(&k, (96, 128));
        assert_eq!(
            r,
            Intrinsics {
                fx: 50.0,
                fy: 40.0,
                cx: 32.0,
                cy: 24.0
            }
        );
        let c = Fit {
            mode: FitMode::CenterCrop,
            height: 48,
            width: 64,
        }
        .intrinsics(&k, (96, 128));
        assert_eq!(
            c,
            Intrinsics {
                fx: 100.0,
                fy: 80.0,
                cx: 32.0,
                cy: 24.0
            }
        );
    }
}
