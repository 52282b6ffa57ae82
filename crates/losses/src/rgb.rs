//! The rendering loss `L_rgb = MSE + λ_lpips · LPIPS`, per frame, with an optional
//! structural term `λ_ssim · (1 − SSIM)` (off by default; see [`crate::ssim_per_frame`]).

use burn::tensor::Tensor;

use crate::error::{LossError, Result};
use crate::lpips::{Lpips, LpipsStatus};
use crate::mse::{mse_per_frame, weighted_mse_per_frame};
use crate::ssim_loss::ssim_per_frame;

/// λ_lpips of the paper (§4, implementation details).
pub const LPIPS_LOSS_WEIGHT: f64 = 0.05;

/// Per-frame terms, each `[F]`.
#[derive(Debug, Clone)]
pub struct RgbTerms {
    /// MSE per frame.
    pub mse: Tensor<1>,
    /// LPIPS per frame (`None` when λ_lpips = 0).
    pub lpips: Option<Tensor<1>>,
    /// `1 − SSIM` per frame (`None` when λ_ssim = 0).
    pub dssim: Option<Tensor<1>>,
    /// `mse + λ_lpips · lpips + λ_ssim · dssim` per frame, ready for the progressive frame
    /// weights.
    pub total: Tensor<1>,
}

/// The configured rendering loss. Construction refuses λ_lpips > 0 without LPIPS weights,
/// so training cannot silently run without its perceptual term.
#[derive(Debug, Clone)]
pub struct RgbLoss {
    lambda_lpips: f64,
    lpips: Option<Lpips>,
    lambda_ssim: f64,
}

impl RgbLoss {
    /// `lambda_lpips` must be finite and ≥ 0; if > 0, `lpips` must be available.
    pub fn new(lambda_lpips: f64, lpips: &LpipsStatus) -> Result<Self> {
        if !(lambda_lpips.is_finite() && lambda_lpips >= 0.0) {
            return Err(LossError::Invalid {
                what: "lambda_lpips",
                reason: format!("must be finite and >= 0, got {lambda_lpips}"),
            });
        }
        let lpips = if lambda_lpips > 0.0 {
            Some(lpips.require()?.clone())
        } else {
            None
        };
        Ok(Self {
            lambda_lpips,
            lpips,
            lambda_ssim: 0.0,
        })
    }

    /// Adds `λ_ssim · (1 − SSIM)` per frame; `lambda_ssim` must be finite and ≥ 0 (0 keeps
    /// the paper's loss).
    pub fn with_ssim(mut self, lambda_ssim: f64) -> Result<Self> {
        if !(lambda_ssim.is_finite() && lambda_ssim >= 0.0) {
            return Err(LossError::Invalid {
                what: "lambda_ssim",
                reason: format!("must be finite and >= 0, got {lambda_ssim}"),
            });
        }
        self.lambda_ssim = lambda_ssim;
        Ok(self)
    }

    /// λ_lpips in use.
    pub fn lambda_lpips(&self) -> f64 {
        self.lambda_lpips
    }

    /// `L_rgb` per frame of `[F, 3, H, W]` renders against targets in [0, 1]. The target is
    /// detached; gradients flow into `pred` only.
    pub fn per_frame(&self, pred: Tensor<4>, target: Tensor<4>) -> Result<RgbTerms> {
        self.per_frame_weighted(pred, target, None)
    }

    /// [`RgbLoss::per_frame`] with the MSE term of `total` weighted per pixel
    /// (`[F, 1, H, W]`, see [`weighted_mse_per_frame`]); `mse` stays the plain MSE (the
    /// log's PSNR), LPIPS and SSIM stay unweighted.
    pub fn per_frame_weighted(
        &self,
        pred: Tensor<4>,
        target: Tensor<4>,
        pixel_weight: Option<Tensor<4>>,
    ) -> Result<RgbTerms> {
        let target = target.detach();
        let mse = mse_per_frame(pred.clone(), target.clone())?;
        let weighted = match pixel_weight {
            Some(wt) => Some(weighted_mse_per_frame(pred.clone(), target.clone(), wt)?),
            None => None,
        };
        let dssim = if self.lambda_ssim > 0.0 {
            Some(ssim_per_frame(pred.clone(), target.clone())?.neg() + 1.0)
        } else {
            None
        };
        let lpips = match &self.lpips {
            Some(net) => Some(net.forward(pred, target)?),
            None => None,
        };
        let mut total = weighted.unwrap_or_else(|| mse.clone());
        if let Some(lp) = &lpips {
            total = total + lp.clone() * self.lambda_lpips;
        }
        if let Some(d) = &dssim {
            total = total + d.clone() * self.lambda_ssim;
        }
        Ok(RgbTerms {
            mse,
            lpips,
            dssim,
            total,
        })
    }
}
