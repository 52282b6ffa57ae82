//! `envision4d-losses`: Envision4D's training losses and evaluation metrics on Burn.
//!
//! * Training (differentiable Burn tensors, autodiff): [`mse_per_frame`], [`Lpips`],
//!   [`ssim_per_frame`], [`RgbLoss`]
//!   (`L_rgb = MSE + λ_lpips·LPIPS [+ λ_ssim·(1 − SSIM)]` per frame), [`camera_distill`] /
//!   [`depth_distill`] / [`distill`] (self-distillation against a frozen teacher).
//! * Evaluation (host, f64): [`psnr`], [`ssim`], LPIPS ([`Lpips::distance_host`]),
//!   [`depth_rmse`] with an explicit [`DepthAlignment`], [`camera_auc30`]; [`EvalCrop`] and
//!   [`evaluate_images`] apply one crop to every image metric.
//!
//! Bad input (NaN, mismatched shapes, too-small images) is a [`LossError`], never a panic
//! or a NaN metric.

mod camera_auc;
mod crop;
mod depth;
mod distill;
mod error;
mod evaluate;
mod host;
pub mod lpips;
mod mse;
mod psnr;
mod region;
mod rgb;
mod ssim;
mod ssim_loss;

pub use camera_auc::{
    auc_from_errors, camera_auc30, relative_pose_errors, Extrinsic, PairError,
    AUC_MAX_THRESHOLD_DEG,
};
pub use crop::EvalCrop;
pub use depth::{depth_rmse, AlignmentScope, DepthAlignment, DepthRmse};
pub use distill::{
    camera_distill, camera_distill_weighted, depth_distill, distill, DistillTerms, DistillWeights,
    CAMERA_DISTILL_WEIGHT, DEPTH_DISTILL_WEIGHT,
};
pub use error::{LossError, Result};
pub use evaluate::{evaluate_images, ImageMetrics};
pub use host::{HostDepths, HostImages};
pub use lpips::{Lpips, LpipsNet, LpipsStatus, LpipsWeights};
pub use mse::{mse_per_frame, weighted_mse_per_frame};
pub use psnr::{psnr, psnr_from_mse};
pub use region::{masked_psnr, masked_ssim, masked_ssims};
pub use rgb::{RgbLoss, RgbTerms, LPIPS_LOSS_WEIGHT};
pub use ssim::{ssim, ssim_interior, ssim_maps, SSIM_WIN_SIZE};
pub use ssim_loss::ssim_per_frame;
