//! Optional evaluation crop, applied identically to every metric's inputs.
//!
//! The release's `config/main.yaml` has `crop_range_h: [6, 6]` and `crop_range_w: [10, 6]`,
//! meaning rows `[h0, H − h1)` and columns `[w0, W − w1)`; the Waymo experiment config sets
//! both to null (no crop). One [`EvalCrop`] value is passed to [`crate::evaluate`] so that
//! PSNR, SSIM, LPIPS and D-RMSE always see the same pixels.

use burn::tensor::Tensor;

use crate::error::{LossError, Result};
use crate::host::{HostDepths, HostImages};

/// Pixels removed from each border before evaluation. `EvalCrop::default()` is no crop.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EvalCrop {
    /// Rows removed at the top (`crop_range_h[0]`).
    pub top: usize,
    /// Rows removed at the bottom (`crop_range_h[1]`).
    pub bottom: usize,
    /// Columns removed at the left (`crop_range_w[0]`).
    pub left: usize,
    /// Columns removed at the right (`crop_range_w[1]`).
    pub right: usize,
}

impl EvalCrop {
    /// The crop of the release's `config/main.yaml` (`crop_range_h [6, 6]`,
    /// `crop_range_w [10, 6]`). The Waymo experiment overrides it with no crop.
    pub const RELEASE_MAIN: EvalCrop = EvalCrop {
        top: 6,
        bottom: 6,
        left: 10,
        right: 6,
    };

    /// Build from the release's config ranges `crop_range_h = [h0, h1]`, `crop_range_w = [w0, w1]`.
    pub fn from_ranges(crop_range_h: [usize; 2], crop_range_w: [usize; 2]) -> Self {
        Self {
            top: crop_range_h[0],
            bottom: crop_range_h[1],
            left: crop_range_w[0],
            right: crop_range_w[1],
        }
    }

    /// The size `[H, W]` the release's crops are given for (its `load_size`).
    pub const RELEASE_SIZE: [usize; 2] = [350, 518];

    /// The same border fractions on an image of `size` `[H, W]`: each side scaled by the
    /// size ratio to [`Self::RELEASE_SIZE`] and rounded (at 350x518 the crop is unchanged;
    /// at 56x84 the release's 6,6,10,6 becomes 1,1,2,1 rather than a quarter of the image).
    pub fn scaled_to(&self, size: [usize; 2]) -> Self {
        let [rh, rw] = Self::RELEASE_SIZE;
        let s = |v: usize, n: usize, r: usize| (v as f64 * n as f64 / r as f64).round() as usize;
        Self {
            top: s(self.top, size[0], rh),
            bottom: s(self.bottom, size[0], rh),
            left: s(self.left, size[1], rw),
            right: s(self.right, size[1], rw),
        }
    }

    /// True when nothing is removed.
    pub fn is_none(&self) -> bool {
        *self == Self::default()
    }

    /// The kept window `(top, height, left, width)` of an `h × w` image; an error when the
    /// crop removes everything.
    pub fn window(&self, h: usize, w: usize) -> Result<(usize, usize, usize, usize)> {
        let keep_h = h.checked_sub(self.top + self.bottom).filter(|&k| k > 0);
        let keep_w = w.checked_sub(self.left + self.right).filter(|&k| k > 0);
        match (keep_h, keep_w) {
            (Some(kh), Some(kw)) => Ok((self.top, kh, self.left, kw)),
            _ => Err(LossError::Invalid {
                what: "evaluation crop",
                reason: format!("{self:?} leaves no pixels of a {h}x{w} image"),
            }),
        }
    }

    /// Crop host images `[N, C, H, W]`.
    pub fn apply_images(&self, images: &HostImages) -> Result<HostImages> {
        let [_, _, h, w] = images.shape();
        let (top, kh, left, kw) = self.window(h, w)?;
        Ok(images.window(top, kh, left, kw))
    }

    /// Crop host depth maps `[N, H, W]`.
    pub fn apply_depths(&self, depths: &HostDepths) -> Result<HostDepths> {
        let [_, h, w] = depths.shape();
        let (top, kh, left, kw) = self.window(h, w)?;
        Ok(depths.window(top, kh, left, kw))
    }

    /// Crop the last two dimensions of a Burn tensor (`[..., H, W]`), e.g. before a loss.
    pub fn apply_tensor<const D: usize>(&self, t: Tensor<D>) -> Result<Tensor<D>> {
        if D < 2 {
            return Err(LossError::BadShape {
                what: "evaluation crop",
                expected: "a tensor with at least 2 dimensions [..., H, W]",
                got: t.dims().to_vec(),
            });
        }
        let dims = t.dims();
        let (top, kh, left, kw) = self.window(dims[D - 2], dims[D - 1])?;
        Ok(t.narrow(D - 2, top, kh).narrow(D - 1, left, kw))
    }
}
