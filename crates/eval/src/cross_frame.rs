//! The cross-frame table (paper appendix, "Cross-frame Scene Reconstruction"): context
//! frames rendered without their own Gaussians, so only motion estimated between context
//! frames can put the scene back where it was.
//!
//! - `per_frame`: frame `j` from every other context frame's Gaussians moved to `j` (the
//!   self-exclusive render training uses; the ablation tables' "full sequence").
//! - `pairs`: frame `j` from one source frame `i` alone, `i→j`. With two context frames
//!   `1→0` (backward) and `0→1` (forward) are the appendix table's rows, and they are the
//!   same renders as `per_frame`, so nothing is rendered twice.
//!
//! Backward rendering leaves border regions nothing covers, so these scores use their own
//! crop (`EvalOptions::cross_frame_crop`, the release's `crop_range_h [6, 6]`,
//! `crop_range_w [10, 6]` by default), reported in the JSON next to the future-frame crop.

use crate::error::Result;
use crate::protocol::{timed_render, Rendered};
use crate::report::{mean, mean_opt, CrossFrameScore, FrameScore, PairScore};
use crate::score::reported_psnr;
use crate::EvalOptions;
use burn::tensor::Tensor;
use envision4d_losses::{evaluate_images, HostImages};
use envision4d_model::adapter::{AdaptedGaussians, Exclusion};

/// Renders and scores the context frames `0..tc`; returns the scores and the seconds spent
/// on the self-exclusive renders (the `context_decoder_s` timing).
pub fn cross_frame(
    adapted: &AdaptedGaussians,
    extr: &Tensor<4>,
    intr: &Tensor<4>,
    gt: &HostImages,
    size: [usize; 2],
    opts: &EvalOptions,
) -> Result<(CrossFrameScore, f64)> {
    let tc = gt.shape()[0];
    let targets: Vec<usize> = (0..tc).collect();
    let (ctx, secs) = timed_render(
        adapted,
        extr,
        intr,
        &targets,
        size,
        opts,
        Exclusion::SelfExclusive,
    )?;
    let per_frame = frame_scores(&ctx, gt, opts)?;
    let mut pairs = Vec::new();
    for target in 0..tc {
        for source in (0..tc).filter(|&i| i != target) {
            let score = if tc == 2 {
                per_frame[target].clone()
            } else {
                let (r, _) = timed_render(
                    adapted,
                    extr,
                    intr,
                    &[target],
                    size,
                    opts,
                    Exclusion::OnlySource(source),
                )?;
                let one = one_image(gt, target)?;
                frame_scores(&r, &one, opts)?.remove(0)
            };
            pairs.push(PairScore {
                source,
                target,
                psnr: score.psnr,
                ssim: score.ssim,
                lpips: score.lpips,
            });
        }
    }
    Ok((
        CrossFrameScore {
            psnr: mean(per_frame.iter().map(|f| f.psnr)),
            ssim: mean(per_frame.iter().map(|f| f.ssim)),
            lpips: mean_opt(per_frame.iter().map(|f| f.lpips)),
            per_frame,
            pairs,
        },
        secs,
    ))
}

/// Scores of each rendered frame against `gt`, `frame` = position in `gt` (the context
/// frame number when `gt` holds frames `0..T_c`; pair scores do not use it).
fn frame_scores(r: &Rendered, gt: &HostImages, opts: &EvalOptions) -> Result<Vec<FrameScore>> {
    let [_, _, h, w] = gt.shape();
    let crop = opts.cross_frame_crop_for([h, w]);
    let m = evaluate_images(&r.images, gt, crop, &opts.lpips)?;
    Ok((0..m.psnr.len())
        .map(|j| FrameScore {
            frame: j,
            psnr: reported_psnr(m.psnr[j]),
            ssim: m.ssim[j],
            lpips: m.lpips.as_ref().map(|l| l[j]),
        })
        .collect())
}

/// Image `j` of a batch as a batch of one.
fn one_image(all: &HostImages, j: usize) -> Result<HostImages> {
    let [_, c, h, w] = all.shape();
    Ok(HostImages::new(
        "context frame",
        all.image(j).to_vec(),
        [1, c, h, w],
    )?)
}
