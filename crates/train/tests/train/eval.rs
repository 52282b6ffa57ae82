//! `envision4d_eval` on a model built by training's `build_model`: one tiny-model evaluation checked for completeness and against
//! metrics computed directly, plus the host pose math, the sweep helpers and the means.

use crate::common::{synth_clip, tiny_config};
use burn::tensor::Device;
use envision4d_data::geom::{Mat4, Vec3};
use envision4d_eval::baselines::clip_images;
use envision4d_eval::pose_error::{
    extrapolate_constant_velocity, pose_error, relative_to_first, translation_scale,
};
use envision4d_eval::sweep::{mark_pareto, summarize, with_horizon, Knob, SweepSetting};
use envision4d_eval::{evaluate_clip, mean_metrics, ClipMetrics, EvalOptions, Extent, Method};
use envision4d_losses::{psnr, LpipsStatus};
use envision4d_train::step::build_model;

fn options() -> EvalOptions {
    let lpips = LpipsStatus::Unavailable {
        reason: "test".into(),
    };
    EvalOptions::new(2, lpips)
}

fn evaluated() -> ClipMetrics {
    let cfg = tiny_config();
    let model = build_model(&cfg, &Device::flex()).unwrap();
    evaluate_clip(&model, &synth_clip(7), &options()).expect("clip evaluates")
}

/// Guards the report's completeness: the model and all three baselines, one entry per future
/// horizon (frames T_c..T_c+T_f), pose errors and AUC where ground-truth cameras exist, the
/// cross-frame context table, D-RMSE, timings, and LPIPS null (never a number from nothing).
#[test]
fn full_evaluation_has_every_method_horizon_and_table() {
    let m = evaluated();
    let methods: Vec<Method> = m.methods.iter().map(|s| s.method).collect();
    assert_eq!(
        methods,
        [
            Method::Model,
            Method::CopyLast,
            Method::StaticCv,
            Method::NoMotion
        ]
    );
    for s in &m.methods {
        let h: Vec<(usize, usize)> = s.per_horizon.iter().map(|h| (h.horizon, h.frame)).collect();
        assert_eq!(h, [(1, 2), (2, 3)], "{:?}", s.method);
        assert!(s.psnr.is_finite() && s.ssim.is_finite(), "{s:?}");
        assert!(s.lpips.is_none());
        let auc = s.camera_auc30.expect("synthetic clips have GT poses");
        assert!((0.0..=1.0).contains(&auc));
        for h in &s.per_horizon {
            assert!(h.rot_err_deg.unwrap().is_finite() && h.trans_err.unwrap() >= 0.0);
        }
        assert!(s.time_s >= 0.0);
    }
    let ctx = m.context.as_ref().expect("cross-frame table");
    assert_eq!(ctx.per_frame.len(), 2);
    let d = m
        .depth_rmse
        .as_ref()
        .expect("synthetic clips have GT depth");
    assert!(d.rmse.is_finite() && d.alignment == "median");
    assert!(m.timing.encoder_s > 0.0 && m.timing.decoder_s > 0.0);
    assert!(m.timing.context_decoder_s.is_some());
}

/// Guards the copy-last baseline against scoring the wrong frame: its per-horizon PSNR is
/// the PSNR of the last context frame (1) against the true future frames (2, 3), and its
/// pose error equals the error of the model's last context pose held still.
#[test]
fn copy_last_scores_the_last_context_frame() {
    let m = evaluated();
    let clip = synth_clip(7);
    let want = psnr(
        &clip_images(&clip, &[1, 1]).unwrap(),
        &clip_images(&clip, &[2, 3]).unwrap(),
    )
    .unwrap();
    let copy = m.method(Method::CopyLast).unwrap();
    for (h, w) in copy.per_horizon.iter().zip(&want) {
        assert!((h.psnr - w).abs() < 1e-9, "{} vs {w}", h.psnr);
    }
}

fn rot_z(deg: f64) -> [[f64; 3]; 3] {
    let (s, c) = deg.to_radians().sin_cos();
    [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
}

/// Guards the constant-velocity extrapolation's multiplication order: a trajectory that
/// moves by the same camera-frame step Δ every frame (P_k = Δᵏ·P_0, with rotation, so the
/// order matters) is continued exactly.
#[test]
fn constant_velocity_continues_uniform_motion() {
    let delta = Mat4::from_rt(rot_z(7.0), Vec3::new(0.1, -0.2, -1.5));
    let p0 = Mat4::from_rt(rot_z(-20.0), Vec3::new(3.0, 1.0, 2.0));
    let traj: Vec<Mat4> = (0..5)
        .scan(p0, |p, _| {
            let out = *p;
            *p = delta.mul(p);
            Some(out)
        })
        .collect();
    let got = extrapolate_constant_velocity(&traj[1], &traj[2], 2);
    for (g, w) in got.iter().zip(&traj[3..]) {
        let e = pose_error(g, w, 1.0);
        assert!(e.rotation_deg < 1e-6 && e.translation < 1e-9, "{e:?}");
    }
}

/// Guards the pose-error definition: errors are taken relative to frame 0 on both sides (a
/// common world offset changes nothing), the rotation error is the relative angle, and the
/// translation error is the camera-centre distance.
#[test]
fn pose_error_is_relative_to_frame_zero() {
    let world = Mat4::from_rt(rot_z(33.0), Vec3::new(5.0, -4.0, 1.0));
    let gt = [
        Mat4::IDENTITY,
        Mat4::from_rt(rot_z(0.0), Vec3::new(0.0, 0.0, -2.0)),
    ];
    // Prediction: same motion, but rotated by 10° more and in another world frame.
    let pred_local = [
        Mat4::IDENTITY,
        Mat4::from_rt(rot_z(10.0), Vec3::new(0.0, 0.0, -2.0)),
    ];
    let pred: Vec<Mat4> = pred_local.iter().map(|p| p.mul(&world)).collect();
    let (p, g) = (relative_to_first(&pred), relative_to_first(&gt));
    let e = pose_error(&p[1], &g[1], 1.0);
    assert!((e.rotation_deg - 10.0).abs() < 1e-9, "{e:?}");
    // Centres: −Rᵀt; both translations are along the z axis, which rot_z leaves alone.
    assert!(e.translation < 1e-9, "{e:?}");
    let moved = [
        Mat4::IDENTITY,
        Mat4::from_rt(rot_z(0.0), Vec3::new(3.0, 4.0, -2.0)),
    ];
    let e = pose_error(&relative_to_first(&moved)[1], &g[1], 1.0);
    assert!((e.translation - 5.0).abs() < 1e-9, "{e:?}");
}

/// Guards the translation scale alignment of up-to-scale cameras: a trajectory predicted at
/// a third of the true scale is aligned with s = 3 and has zero error; a mirrored one is not
/// rescued by a negative scale; still cameras keep s = 1.
#[test]
fn translation_error_is_scale_aligned() {
    let centres = [0.0, 1.0, 2.5, 4.0];
    let cams = |k: f64| -> Vec<Mat4> {
        centres
            .iter()
            .map(|&z| Mat4::from_rt(rot_z(0.0), Vec3::new(0.0, 0.0, -z * k)))
            .collect()
    };
    let (gt, small) = (cams(1.0), cams(1.0 / 3.0));
    let s = translation_scale(&small, &gt);
    assert!((s - 3.0).abs() < 1e-12, "{s}");
    for (p, g) in small.iter().zip(&gt) {
        assert!(pose_error(p, g, s).translation < 1e-12);
    }
    assert_eq!(translation_scale(&cams(-1.0), &gt), 0.0);
    assert_eq!(translation_scale(&cams(0.0), &gt), 1.0);
    // The error is in the truth's unit: centre 4 m predicted at 4/3 unscaled, aligned exact.
    assert!((pose_error(&small[3], &gt[3], 1.0).translation - 8.0 / 3.0).abs() < 1e-12);
}

/// Guards the horizon knob of the sweep: a truncated model predicts and scores only its
/// first future frames, and a future-only run renders nothing else (no baselines).
#[test]
fn horizon_knob_truncates_future_frames() {
    let cfg = tiny_config();
    let model = build_model(&cfg, &Device::flex()).unwrap();
    let short = with_horizon(&model, 1).unwrap();
    assert_eq!(short.future_frames(), 1);
    assert!(with_horizon(&model, 3).is_err());
    let mut opts = options();
    opts.extent = Extent::FutureOnly;
    let m = evaluate_clip(&short, &synth_clip(7), &opts).unwrap();
    assert_eq!(m.methods.len(), 1);
    assert_eq!(m.methods[0].per_horizon.len(), 1);
    assert!(m.context.is_none() && m.depth_rmse.is_none());
}

/// Guards the Pareto flags and the mean over clips: a point that is slower and worse than
/// another is not on the front; means average each number over the clips.
#[test]
fn pareto_front_and_means() {
    let m = evaluated();
    let mut other = m.clone();
    other.methods[0].psnr += 2.0;
    other.timing.encoder_s += 1.0;
    let mean = mean_metrics(&[m.clone(), other.clone()]).unwrap();
    assert!((mean.methods[0].psnr - (m.methods[0].psnr + 1.0)).abs() < 1e-9);
    let setting = SweepSetting {
        knob: Knob::Base,
        backend: "cpu".into(),
        horizon: 2,
        input_size: [56, 84],
        raster: Default::default(),
    };
    let fast = summarize(&setting, std::slice::from_ref(&m)).unwrap();
    let slow_good = summarize(&setting, std::slice::from_ref(&other)).unwrap();
    let mut slow_bad = slow_good.clone();
    slow_bad.psnr = fast.psnr - 1.0;
    let mut points = vec![fast, slow_good, slow_bad];
    mark_pareto(&mut points);
    let flags: Vec<bool> = points.iter().map(|p| p.pareto).collect();
    assert_eq!(flags, [true, true, false]);
    // The Markdown's knob names are the JSON's.
    for k in [Knob::Base, Knob::InputSize, Knob::TransmittanceMin] {
        assert_eq!(serde_json::to_value(k).unwrap(), k.name());
    }
}
