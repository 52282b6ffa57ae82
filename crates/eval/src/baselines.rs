//! The baselines every number is reported next to (all on the same clips):
//!
//! - **copy-last** ([`crate::Method::CopyLast`]): every future frame is the last
//!   context frame; its poses are the model's last context pose repeated (a pose-free method
//!   has no other pose to offer, and this keeps the comparison about the future).
//! - **static + constant velocity** ([`crate::Method::StaticCv`]): the model's
//!   Gaussians with motion disabled, rendered at future poses extrapolated at constant SE(3)
//!   velocity from the model's own predicted context poses; intrinsics are the last context
//!   frame's.
//! - **no motion** ([`crate::Method::NoMotion`]): the model's own future poses, zero
//!   motion (what the motion head adds).

use crate::error::{EvalError, Result};
use crate::pose_error::extrapolate_constant_velocity;
use burn::tensor::Tensor;
use envision4d_data::geom::Mat4;
use envision4d_data::HostClip;
use envision4d_losses::HostImages;

/// Ground-truth frames `frames` of a clip as host images `[F, 3, H, W]`.
pub fn clip_images(clip: &HostClip, frames: &[usize]) -> Result<HostImages> {
    let (h, w) = (clip.height, clip.width);
    let mut data = Vec::with_capacity(frames.len() * 3 * h * w);
    for &j in frames {
        let f = clip.frames.get(j).ok_or_else(|| {
            EvalError::Unscorable(format!(
                "clip has {} frames, frame {j} requested",
                clip.frames.len()
            ))
        })?;
        data.extend(f.iter().map(|&v| v as f64));
    }
    Ok(HostImages::new(
        "ground-truth frames",
        data,
        [frames.len(), 3, h, w],
    )?)
}

/// Copy-last images: frame `context - 1` repeated `future` times.
pub fn copy_last_images(clip: &HostClip, context: usize, future: usize) -> Result<HostImages> {
    clip_images(clip, &vec![context - 1; future])
}

/// Copy-last poses: the `context` predicted context poses, then the last one repeated.
pub fn copy_last_poses(pred: &[Mat4], context: usize, future: usize) -> Vec<Mat4> {
    let mut out = pred[..context].to_vec();
    out.extend(std::iter::repeat_n(pred[context - 1], future));
    out
}

/// Constant-velocity poses: the predicted context poses, then `future` poses extrapolated
/// from the last two of them.
pub fn constant_velocity_poses(pred: &[Mat4], context: usize, future: usize) -> Vec<Mat4> {
    let mut out = pred[..context].to_vec();
    out.extend(extrapolate_constant_velocity(
        &pred[context - 2],
        &pred[context - 1],
        future,
    ));
    out
}

/// Intrinsics `[1, N, 3, 3]` for the extrapolated cameras: the context frames' own, then
/// the last context frame's repeated (a static baseline has no future intrinsics).
pub fn constant_intrinsics(intrinsics: &Tensor<4>, context: usize, future: usize) -> Tensor<4> {
    let ctx = intrinsics.clone().slice([0..1, 0..context, 0..3, 0..3]);
    let last = intrinsics
        .clone()
        .slice([0..1, context - 1..context, 0..3, 0..3])
        .repeat_dim(1, future);
    Tensor::cat(vec![ctx, last], 1)
}
