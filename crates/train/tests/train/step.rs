use crate::common::{batch, flat_params, tiny_config};
use burn::tensor::{Device, Tensor};
use envision4d_model::adapter::{Exclusion, OpacityMapping};
use envision4d_model::model::Heads;
use envision4d_model::scene::render_targets;
use envision4d_train::config::{FreezeGroup, Teacher};
use envision4d_train::freeze::grad_abs_sum;
use envision4d_train::{StepOutcome, Trainer};

fn max_abs_diff(a: Tensor<4>, b: Tensor<4>) -> f32 {
    (a - b)
        .abs()
        .max()
        .into_data()
        .iter::<f32>()
        .next()
        .unwrap()
}

/// Guards self-exclusion: frame j's own Gaussians never reach its render (zeroing source j's
/// opacities leaves target j unchanged, while it changes another target).
#[test]
fn own_gaussians_never_reach_own_render() {
    let cfg = tiny_config();
    let device = Device::flex();
    let t = Trainer::new(cfg.clone(), &device).unwrap();
    let b = batch(2, false, &device);
    let [_, _, _, h, w] = b.images.dims();
    let ctx = b.images.clone().slice([0..1, 0..2, 0..3, 0..h, 0..w]);
    let pred = t.model.forward(ctx, Heads::ALL);
    let a = t.model.adapt(&pred, OpacityMapping::default(), 0).unwrap();
    let (ex, k) = (&pred.backbone.extrinsics, &pred.backbone.intrinsics);
    let j = 0;
    let mut zeroed = a.clone();
    let g = a.opacities.dims()[2];
    zeroed.opacities = a
        .opacities
        .clone()
        .slice_assign([0..1, j..j + 1, 0..g], Tensor::zeros([1, 1, g], &device));
    let render = |ad, target| {
        render_targets(
            ad,
            ex,
            k,
            0,
            &[target],
            Exclusion::SelfExclusive,
            [h, w],
            &t.raster,
        )
        .unwrap()
    };
    assert_eq!(
        max_abs_diff(render(&a, j), render(&zeroed, j)),
        0.0,
        "own Gaussians leaked into target {j}"
    );
    assert!(
        max_abs_diff(render(&a, 1), render(&zeroed, 1)) > 0.0,
        "source {j} is invisible from target 1: the test proves nothing"
    );
}

/// Guards freezing: frozen parameters are bit-identical after a step, trainable ones move.
#[test]
fn frozen_parameters_unchanged_after_step() {
    let mut cfg = tiny_config();
    cfg.freeze = vec![
        FreezeGroup::CameraHead,
        FreezeGroup::PatchEmbed,
        FreezeGroup::Tokens,
    ];
    let device = Device::flex().autodiff();
    let mut t = Trainer::new(cfg, &device).unwrap();
    let b = batch(2, true, &device);
    let (cam0, emb0, gs0) = (
        flat_params(&t.model.camera_head),
        flat_params(&t.model.aggregator.patch_embed),
        flat_params(&t.model.gs_head),
    );
    let r = t.train_step(&b).unwrap();
    assert_eq!(r.outcome, StepOutcome::Applied);
    assert_eq!(flat_params(&t.model.camera_head), cam0);
    assert_eq!(flat_params(&t.model.aggregator.patch_embed), emb0);
    assert_ne!(
        flat_params(&t.model.gs_head),
        gs0,
        "trainable gs_head did not move"
    );
    assert!(t.split.frozen_count > 0 && t.split.trainable_count > 0);
}

/// Guards the pose gradient path: the RGB loss alone (no distillation, after warm-up)
/// gives the camera head a non-zero gradient through the renderer's camera inputs.
#[test]
fn rgb_gradient_reaches_camera_head() {
    let mut cfg = tiny_config();
    cfg.teacher = Teacher::None;
    cfg.freeze = vec![];
    let device = Device::flex().autodiff();
    let t = Trainer::new(cfg.clone(), &device).unwrap();
    let b = batch(2, false, &device);
    let terms = t.loss(&b, cfg.progressive.warmup_iterations).unwrap();
    assert!(terms.camera.is_none() && terms.depth.is_none());
    let grads = terms.total.backward();
    let g = grad_abs_sum(&t.model.camera_head, &grads).expect("camera head has gradients");
    assert!(g.is_finite() && g > 0.0, "camera-head |grad| = {g}");
}

/// Guards `loss.lambda_ssim` against being parsed but never reaching the rendering loss:
/// with the term on, the same model and batch give the same MSE and a larger L_rgb, by
/// λ·(1 − SSIM) of renders that are far from the truth.
#[test]
fn structural_term_reaches_the_rendering_loss() {
    let cfg = tiny_config();
    let device = Device::flex().autodiff();
    let b = batch(2, true, &device);
    let step = cfg.progressive.warmup_iterations;
    let plain = Trainer::new(cfg.clone(), &device).unwrap();
    let mut with = cfg.clone();
    with.loss.lambda_ssim = 0.5;
    let structural = Trainer::new(with, &device).unwrap();
    let (a, s) = (
        plain.loss(&b, step).unwrap(),
        structural.loss(&b, step).unwrap(),
    );
    let v = |t: Tensor<1>| t.into_data().iter::<f32>().next().unwrap();
    let (mse_a, mse_s) = (v(a.rgb_mse.unwrap()), v(s.rgb_mse.unwrap()));
    assert!(
        (mse_a - mse_s).abs() <= 1e-6 * mse_a.abs(),
        "{mse_a} vs {mse_s}"
    );
    let extra = v(s.rgb) - v(a.rgb);
    // An untrained model's renders have SSIM well below 1 against the frames.
    assert!(
        extra > 0.01 && extra <= 0.5 * 2.0,
        "λ·(1 − SSIM) added {extra}"
    );
    assert!(v(s.total).is_finite());
}

/// Guards the NaN guard: a non-finite loss skips the update and is counted.
#[test]
fn non_finite_loss_skips_step() {
    let cfg = tiny_config();
    let device = Device::flex().autodiff();
    let mut t = Trainer::new(cfg, &device).unwrap();
    let mut b = batch(2, true, &device);
    b.images = b.images.clone() * f32::NAN;
    let before = flat_params(&t.model.gs_head);
    let r = t.train_step(&b).unwrap();
    assert_eq!(r.outcome, StepOutcome::SkippedNonFiniteLoss);
    assert_eq!((t.skipped, t.step), (1, 1));
    assert_eq!(flat_params(&t.model.gs_head), before);
}

/// Guards that training actually learns: a few CPU steps on one tiny synthetic clip lower
/// the loss (warm-up phase, fixed schedule step so the objective does not change).
#[test]
fn smoke_loss_decreases() {
    let cfg = tiny_config();
    let device = Device::flex().autodiff();
    let mut t = Trainer::new(cfg, &device).unwrap();
    let b = batch(2, true, &device);
    let mut losses = vec![];
    for _ in 0..6 {
        let r = t.train_step(&b).unwrap();
        assert_eq!(r.outcome, StepOutcome::Applied);
        losses.push(r.total);
    }
    eprintln!("smoke losses: {losses:?}");
    assert!(
        losses.last().unwrap() < &losses[0],
        "loss did not decrease: {losses:?}"
    );
}

/// Guards the static warm-up: during geometric warm-up no Gaussian is moved, so the motion
/// head gets no gradient (it once learned to push the other frames' Gaussians out of view,
/// leaving the first self-exclusive renders empty); after warm-up it does.
#[test]
fn warmup_is_static_motion_head_untouched() {
    let cfg = tiny_config();
    let device = Device::flex().autodiff();
    let t = Trainer::new(cfg.clone(), &device).unwrap();
    let b = batch(2, true, &device);
    let grads = t.loss(&b, 0).unwrap().total.backward();
    let warm = grad_abs_sum(&t.model.motion_head, &grads).unwrap_or(0.0);
    assert_eq!(warm, 0.0, "motion head trained during warm-up");
    let after = cfg.progressive.warmup_iterations;
    let grads = t.loss(&b, after).unwrap().total.backward();
    let prog = grad_abs_sum(&t.model.motion_head, &grads).unwrap_or(0.0);
    assert!(prog > 0.0, "motion head untrained after warm-up");
}

/// Guards seeded initialisation: the freeze groups were walked in `HashSet` order, and the
/// walk initialises lazy parameters, so two runs with one seed and several frozen groups
/// started from different weights (and so different loss curves).
#[test]
fn same_seed_same_initial_weights_with_frozen_groups() {
    let mut cfg = tiny_config();
    cfg.freeze = vec![
        FreezeGroup::PatchEmbed,
        FreezeGroup::FrameBlocks,
        FreezeGroup::GlobalBlocks,
        FreezeGroup::Tokens,
        FreezeGroup::CameraHead,
    ];
    let device = Device::flex().autodiff();
    let first = flat_params(&Trainer::new(cfg.clone(), &device).unwrap().model);
    for attempt in 0..3 {
        let again = flat_params(&Trainer::new(cfg.clone(), &device).unwrap().model);
        assert!(
            first == again,
            "attempt {attempt}: the initial weights differ"
        );
    }
}

/// Guards the training step's device round trips: every target of every batch element is
/// rendered in one rasterizer call, and the step's own host reads (camera and loss finite
/// checks, the loss values, the gradient check, clipping, the post-update check) are the
/// same handful whether the step renders 1 x F or 2 x F views. A read or a render call per
/// view, the GPU stall this guards against, would make the two counts differ.
#[test]
fn a_training_step_has_a_fixed_number_of_host_round_trips() {
    use envision4d_model::host_read::host_reads;
    use envision4d_splat::render::render_calls;
    let device = Device::flex().autodiff();
    let mut counts = Vec::new();
    for bsz in [1, 2] {
        let mut cfg = tiny_config();
        cfg.optim.batch_size = bsz;
        cfg.optim.grad_clip = envision4d_train::config::ClipMode::GlobalNorm;
        let mut t = Trainer::new(cfg, &device).unwrap();
        let clips: Vec<_> = (0..bsz as u64)
            .map(|k| crate::common::synth_clip(7 + k))
            .collect();
        let b = envision4d_train::batch::Batch::from_clips(&clips, 2, true, &device).unwrap();
        let (reads, renders) = (host_reads(), render_calls());
        let r = t.train_step(&b).unwrap();
        assert_eq!(r.outcome, StepOutcome::Applied);
        counts.push((host_reads() - reads, render_calls() - renders));
    }
    assert_eq!(
        counts[0], counts[1],
        "host reads, render calls at batch 1 vs 2"
    );
    let (reads, renders) = counts[0];
    assert_eq!(renders, 1, "render calls per step");
    // Camera/pose finite check, the loss values, the gradient check, the clipping norm, the
    // post-update parameter check.
    assert_eq!(reads, 5, "host reads per step");
}
