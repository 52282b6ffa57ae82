//! One clip through the paper's protocol: the model sees the first `T_c` frames; its
//! Gaussians, moved to each future time, are rendered at its predicted future cameras and
//! scored (PSNR/SSIM/LPIPS) against the real future frames. Context frames are rendered only
//! from the other frames' Gaussians (the cross-frame table, `cross_frame`). D-RMSE scores the
//! rendered depth of the future frames and, separately, the depth head on the context frames
//! (`depth_eval`); AUC@30 and the future-pose errors use ground-truth cameras where the clip
//! has them.

use crate::baselines::{
    clip_images, constant_intrinsics, constant_velocity_poses, copy_last_images, copy_last_poses,
};
use crate::clip_images::ClipImages;
use crate::cross_frame::cross_frame;
use crate::depth_eval::{depth_score, upsample_nearest, DepthTruth};
use crate::error::{EvalError, Result};
use crate::motion_scene::{motion_truth_score, oracle_renders};
use crate::pose_error::{
    extrinsics_tensor, host_extrinsics, pose_error, relative_to_first, to_extrinsic,
    translation_scale,
};
use crate::regions::region_scores;
use crate::report::{
    mean, mean_opt, ClipMetrics, DepthScore, HorizonScore, Method, MethodScore, Timing,
};
use crate::{EvalOptions, Extent};
use burn::tensor::{Device, Tensor, TensorData};
use envision4d_data::geom::Mat4;
use envision4d_data::resize::resize_bilinear;
use envision4d_data::{HostClip, Image};
use envision4d_losses::{
    camera_auc30, evaluate_images, DepthAlignment, HostDepths, HostImages, ImageMetrics,
};
use envision4d_model::adapter::{AdaptedGaussians, Exclusion};
use envision4d_model::scene::{predict_scene, render_views, Scene};
use envision4d_model::Envision4d;
use std::time::Instant;

use crate::score::reported_psnr;
pub use crate::score::PSNR_CAP_DB;

/// Evaluates one clip (`T_c + T_f` frames or more; extra frames are ignored).
pub fn evaluate_clip(
    model: &Envision4d,
    clip: &HostClip,
    opts: &EvalOptions,
) -> Result<ClipMetrics> {
    let tc = opts.context_frames;
    let tf = model.future_frames();
    let n = tc + tf;
    if tc < 2 || clip.frames.len() < n {
        return Err(EvalError::Unscorable(format!(
            "clip has {} frames; evaluation needs T_c + T_f = {tc} + {tf} (T_c >= 2)",
            clip.frames.len()
        )));
    }
    let size = [clip.height, clip.width];
    let input = opts.input_size.unwrap_or(size);
    let device = model.device();
    let context = context_tensor(clip, tc, input, &device);

    let clock = Instant::now();
    let scene = predict_scene(model, context)?;
    sync(&device)?;
    let encoder_s = clock.elapsed().as_secs_f64();

    let extr = scene.pred.backbone.extrinsics.clone();
    let intr = scale_intrinsics(scene.pred.backbone.intrinsics.clone(), input, size);
    let future: Vec<usize> = (tc..n).collect();
    let (rendered, decoder_s) = timed_render(
        &scene.adapted,
        &extr,
        &intr,
        &future,
        size,
        opts,
        Exclusion::SelfExclusive,
    )?;
    let gt_future = clip_images(clip, &future)?;
    let pred_poses = host_extrinsics(&extr, 0)?;
    let gt_poses: Option<Vec<Mat4>> =
        (clip.cameras.len() >= n).then(|| clip.cameras[..n].iter().map(|c| c.0).collect());
    let scorer = Scorer {
        gt: &gt_future,
        masks: if clip.dynamic_masks.is_empty() {
            Vec::new()
        } else {
            future
                .iter()
                .map(|&j| clip.dynamic_masks.get(j).and_then(Option::as_ref))
                .collect()
        },
        gt_poses: gt_poses.as_deref(),
        context: tc,
        opts,
    };
    let mut methods = vec![scorer.score(
        Method::Model,
        &rendered.images,
        &pred_poses,
        encoder_s + decoder_s,
    )?];
    let (mut context, mut depth, mut context_depth, mut context_decoder_s) =
        (None, None, None, None);
    let (mut motion, mut motion_maps, mut images) = (None, None, None);
    if opts.extent == Extent::Full {
        let targets: Vec<usize> = (0..tc).collect();
        let gt_context = clip_images(clip, &targets)?;
        let (ctx, secs) = cross_frame(&scene.adapted, &extr, &intr, &gt_context, size, opts)?;
        context_decoder_s = Some(secs);
        context = Some(ctx);
        depth = rendered_depth_score(&rendered, clip, &future, opts)?;
        context_depth = head_depth_score(&scene, clip, tc, opts)?;
        let truth = motion_truth_score(&scene, clip, tc, n, input, &pred_poses, opts);
        let (scores, [copy, cv]) = baselines(&scene, clip, &scorer, &pred_poses, &intr, encoder_s)?;
        methods.extend(scores);
        if opts.clip_images {
            let masks = scorer.masks.iter().map(|m| m.cloned()).collect();
            let frames = [rendered.images.clone(), copy, cv];
            images = Some(ClipImages::new(
                tc,
                &gt_future,
                frames,
                &rendered.depth,
                masks,
            )?);
        }
        if let Some(oracle) = truth.oracle {
            let f = &future;
            for o in oracle_renders(&scene, oracle, clip, &extr, &intr, &pred_poses, f, opts)? {
                methods.push(scorer.score(o.method, &o.images, &o.poses, encoder_s + o.secs)?);
            }
        }
        (motion, motion_maps) = (truth.score, truth.maps);
    }
    Ok(ClipMetrics {
        clip: String::new(),
        timing: Timing {
            encoder_s,
            decoder_s,
            context_decoder_s,
        },
        methods,
        context,
        depth_rmse: depth,
        context_depth_rmse: context_depth,
        motion,
        motion_maps,
        images,
    })
}

/// The three baselines of [`crate::baselines`], scored like the model; with the frames of
/// copy-last and static+cv (the report shows them).
fn baselines(
    scene: &Scene,
    clip: &HostClip,
    scorer: &Scorer,
    pred_poses: &[Mat4],
    intr: &Tensor<4>,
    encoder_s: f64,
) -> Result<(Vec<MethodScore>, [HostImages; 2])> {
    let (tc, opts) = (scorer.context, scorer.opts);
    let tf = pred_poses.len() - tc;
    let size = [clip.height, clip.width];
    let future: Vec<usize> = (tc..tc + tf).collect();
    let device = intr.device();

    let clock = Instant::now();
    let copy = copy_last_images(clip, tc, tf)?;
    let copy_s = clock.elapsed().as_secs_f64();
    let copy_poses = copy_last_poses(pred_poses, tc, tf);

    let still = scene.without_motion();
    let cv_poses = constant_velocity_poses(pred_poses, tc, tf);
    let cv_intr = constant_intrinsics(intr, tc, tf);
    let cv_extr = extrinsics_tensor(&cv_poses, &device);
    let own = Exclusion::SelfExclusive;
    let (cv, cv_s) = timed_render(&still.adapted, &cv_extr, &cv_intr, &future, size, opts, own)?;

    let own_extr = extrinsics_tensor(pred_poses, &device);
    let (nm, nm_s) = timed_render(&still.adapted, &own_extr, intr, &future, size, opts, own)?;

    let scores = vec![
        scorer.score(Method::CopyLast, &copy, &copy_poses, copy_s)?,
        scorer.score(Method::StaticCv, &cv.images, &cv_poses, encoder_s + cv_s)?,
        scorer.score(Method::NoMotion, &nm.images, pred_poses, encoder_s + nm_s)?,
    ];
    Ok((scores, [copy, cv.images]))
}

/// Scores future frames and poses of any method against one clip's ground truth.
struct Scorer<'a> {
    gt: &'a HostImages,
    /// The scored frames' dynamic masks (empty when the clip has none).
    masks: Vec<Option<&'a Vec<bool>>>,
    gt_poses: Option<&'a [Mat4]>,
    context: usize,
    opts: &'a EvalOptions,
}

impl Scorer<'_> {
    fn score(
        &self,
        method: Method,
        images: &HostImages,
        poses: &[Mat4],
        time_s: f64,
    ) -> Result<MethodScore> {
        let m = evaluate_images(images, self.gt, self.opts.crop, &self.opts.lpips)?;
        let regions = region_scores(images, self.gt, &self.masks, self.opts.crop)?;
        let tc = self.context;
        // Cameras are up to scale: one scale per clip maps the predicted camera centres onto
        // the true ones (`translation_scale`) before the translation error is taken.
        let errors = self.gt_poses.map(|g| {
            let (p, g) = (relative_to_first(poses), relative_to_first(g));
            let s = translation_scale(&p, &g);
            (p, g, s)
        });
        let per_horizon: Vec<HorizonScore> = (0..m.psnr.len())
            .map(|k| {
                let j = tc + k;
                let err = errors
                    .as_ref()
                    .map(|(p, g, s)| pose_error(&p[j], &g[j], *s));
                let raw = errors
                    .as_ref()
                    .map(|(p, g, _)| pose_error(&p[j], &g[j], 1.0));
                HorizonScore {
                    horizon: k + 1,
                    frame: j,
                    psnr: reported_psnr(m.psnr[k]),
                    ssim: m.ssim[k],
                    lpips: lpips_at(&m, k),
                    rot_err_deg: err.map(|e| e.rotation_deg),
                    trans_err: err.map(|e| e.translation),
                    trans_err_unaligned: raw.map(|e| e.translation),
                }
            })
            .collect();
        let auc = match self.gt_poses {
            Some(g) => {
                let p: Vec<_> = poses.iter().map(to_extrinsic).collect();
                let g: Vec<_> = g.iter().map(to_extrinsic).collect();
                Some(camera_auc30(&p, &g)?)
            }
            None => None,
        };
        Ok(MethodScore {
            method,
            psnr: mean(per_horizon.iter().map(|h| h.psnr)),
            ssim: mean(per_horizon.iter().map(|h| h.ssim)),
            lpips: mean_opt(per_horizon.iter().map(|h| h.lpips)),
            rot_err_deg: mean_opt(per_horizon.iter().map(|h| h.rot_err_deg)),
            trans_err: mean_opt(per_horizon.iter().map(|h| h.trans_err)),
            trans_err_unaligned: mean_opt(per_horizon.iter().map(|h| h.trans_err_unaligned)),
            pose_scale: errors.as_ref().map(|e| e.2),
            dynamic_psnr: regions.dynamic_psnr,
            dynamic_ssim: regions.dynamic_ssim,
            static_psnr: regions.static_psnr,
            static_ssim: regions.static_ssim,
            camera_auc30: auc,
            time_s,
            per_horizon,
        })
    }
}

fn lpips_at(m: &ImageMetrics, k: usize) -> Option<f64> {
    m.lpips.as_ref().map(|l| l[k])
}

/// Table 1's D-RMSE: the rendered depth of the scored frames against the clip's evaluation
/// depth, with the future-frame crop.
fn rendered_depth_score(
    rendered: &Rendered,
    clip: &HostClip,
    frames: &[usize],
    opts: &EvalOptions,
) -> Result<Option<DepthScore>> {
    let Some(source) = clip.eval_depth_source else {
        return Ok(None);
    };
    let pred = HostDepths::from_tensor("rendered depth", rendered.depth.clone())?;
    let truth = DepthTruth {
        maps: &clip.eval_depths,
        source,
    };
    depth_score(&pred, &truth, frames, opts.crop, opts.depth_alignment)
}

/// The depth head's maps of the context frames against the clip's evaluation depth, at the
/// clip's resolution (a prediction made at a smaller input size is upsampled
/// nearest-neighbour). `None` without ground truth or without a depth head.
fn head_depth_score(
    scene: &Scene,
    clip: &HostClip,
    tc: usize,
    opts: &EvalOptions,
) -> Result<Option<DepthScore>> {
    let (Some(depth), Some(source)) = (scene.pred.depth.clone(), clip.eval_depth_source) else {
        return Ok(None);
    };
    let [_, _, hi, wi, _] = depth.dims();
    let pred: Vec<f64> = depth.into_data().iter::<f64>().collect();
    let up = upsample_nearest(
        &pred[..tc * hi * wi],
        tc,
        [hi, wi],
        [clip.height, clip.width],
    );
    let pred = HostDepths::new("predicted depth", up, [tc, clip.height, clip.width])?;
    let truth = DepthTruth {
        maps: &clip.eval_depths,
        source,
    };
    let frames: Vec<usize> = (0..tc).collect();
    depth_score(&pred, &truth, &frames, opts.crop, opts.depth_alignment)
}

/// The JSON name of a depth alignment.
pub fn alignment_name(a: DepthAlignment) -> &'static str {
    match a {
        DepthAlignment::None => "none",
        DepthAlignment::Median => "median",
        DepthAlignment::LeastSquares => "least_squares",
    }
}

/// Rendered frames read back to the host, with their expected depth still on the device
/// (read only by the D-RMSE that needs it).
pub(crate) struct Rendered {
    pub images: HostImages,
    pub depth: Tensor<3>,
}

/// Renders `targets` and waits for the device; returns the frames and seconds.
pub(crate) fn timed_render(
    adapted: &AdaptedGaussians,
    extr: &Tensor<4>,
    intr: &Tensor<4>,
    targets: &[usize],
    size: [usize; 2],
    opts: &EvalOptions,
    exclusion: Exclusion,
) -> Result<(Rendered, f64)> {
    let clock = Instant::now();
    let out = render_views(
        adapted,
        extr,
        intr,
        0,
        targets,
        exclusion,
        size,
        &opts.raster,
    )?;
    sync(&out.rgb.device())?;
    let secs = clock.elapsed().as_secs_f64();
    let images = HostImages::from_tensor("rendered frames", out.rgb)?;
    Ok((
        Rendered {
            images,
            depth: out.depth,
        },
        secs,
    ))
}

fn sync(device: &Device) -> Result<()> {
    device
        .sync()
        .map_err(|e| EvalError::Device(format!("sync failed: {e:?}")))
}

/// Intrinsics predicted for an `input`-sized image, rescaled to render at `output` size
/// (continuous pixel coordinates scale with the size ratio; the principal point stays
/// centred).
pub fn scale_intrinsics(intr: Tensor<4>, input: [usize; 2], output: [usize; 2]) -> Tensor<4> {
    if input == output {
        return intr;
    }
    let sy = output[0] as f32 / input[0] as f32;
    let sx = output[1] as f32 / input[1] as f32;
    let scale = Tensor::<1>::from_floats([sx, sy, 1.0], &intr.device()).reshape([1, 1, 3, 1]);
    intr * scale
}

/// The first `tc` frames as a `[1, T_c, 3, H, W]` input, resized (antialiased bilinear, as
/// the data loader fits frames) when `input` differs from the clip's size.
fn context_tensor(clip: &HostClip, tc: usize, input: [usize; 2], device: &Device) -> Tensor<5> {
    let (h, w) = (clip.height, clip.width);
    let [hi, wi] = input;
    let mut data = Vec::with_capacity(tc * 3 * hi * wi);
    for f in &clip.frames[..tc] {
        if [h, w] == input {
            data.extend_from_slice(f);
            continue;
        }
        let mut hwc = vec![0.0f32; h * w * 3];
        for p in 0..h * w {
            for c in 0..3 {
                hwc[p * 3 + c] = f[c * h * w + p];
            }
        }
        data.extend(resize_bilinear(&Image::new(w, h, hwc), hi, wi).to_chw());
    }
    Tensor::from_data(TensorData::new(data, [1, tc, 3, hi, wi]), device)
}
