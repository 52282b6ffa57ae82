//! Does the rendering loss point the motion head the right way? For a checkpoint and
//! synthetic clips with exact motion truth: the gradient of the future frames' MSE with
//! respect to every Gaussian's displacement, against the way from its displacement to the
//! exact one (`motion_signal::gradient_alignment`), per future timestamp, moving and
//! static pixels apart (docs/RESULTS.md, "Motion diagnostics").
//!
//! ```text
//! cargo build --release --workspace --examples
//! $CARGO_TARGET_DIR/release/examples/motion_gradient CHECKPOINT DATA [--clips N] \
//!     [--zero-motion | --toward S] [--true-cameras] [--self-target]
//! ```
//!
//! By default the gradient is taken at the checkpoint's own displacements; `--zero-motion`
//! takes it at zero (where a fresh motion head starts), `--toward S` at `S` times the exact
//! displacements (S = 1 is the truth): how close a displacement must already be before the
//! rendering loss leads it the rest of the way. `--true-cameras` renders through the true
//! cameras (as the evaluation's oracle renders do), so the cameras' error is not in the
//! gradient. `--self-target` replaces the real future frames by the model's own render with
//! the exact displacements: a control whose optimum is the exact motion by construction, so
//! what it measures is what the rasterizer's gradient can see of a displacement at all.
//! Prints a Markdown table; exit 2 on bad input.

use burn::tensor::{Device, Tensor, TensorData};
use envision4d_data::HostClip;
use envision4d_eval::motion::{exact_motions_and_cameras, MotionTruth, PredictedMotion};
use envision4d_eval::pose_error::{clip_intrinsics_tensor, extrinsics_tensor, host_extrinsics};
use envision4d_model::adapter::Exclusion;
use envision4d_model::checkpoint::{checkpoint_config, load_checkpoint, CheckpointKind};
use envision4d_model::scene::{predict_scene_with, Motion};
use envision4d_model::Envision4d;
use envision4d_splat::RasterConfig;
use envision4d_train::config::{DataConfig, DataLayout, Purpose};
use envision4d_train::dataset::open_dataset;
use envision4d_train::motion_signal::{gradient_alignment, AlignmentInputs, AlignmentRow};
use glam::DVec3;
use std::path::PathBuf;

struct Args {
    checkpoint: PathBuf,
    data: PathBuf,
    clips: usize,
    /// `None`: the checkpoint's own displacements; `Some(s)`: `s` times the exact ones.
    toward: Option<f64>,
    /// Render through the true cameras (in the model's axes and unit) instead of its own.
    true_cameras: bool,
    /// Targets: the model's own render with the exact displacements instead of the real
    /// future frames (a control whose optimum is the exact motion by construction).
    self_target: bool,
}

fn parse_args() -> Result<Args, String> {
    let mut it = std::env::args().skip(1);
    let (mut pos, mut clips, mut toward, mut true_cameras) = (vec![], usize::MAX, None, false);
    let mut self_target = false;
    while let Some(a) = it.next() {
        match a.as_str() {
            "--clips" => {
                let v = it.next().ok_or("--clips needs a number")?;
                clips = v
                    .parse()
                    .map_err(|_| format!("--clips: not a whole number: {v:?}"))?;
            }
            "--zero-motion" => toward = Some(0.0),
            "--true-cameras" => true_cameras = true,
            "--self-target" => self_target = true,
            "--toward" => {
                let v = it.next().ok_or("--toward needs a fraction")?;
                let f: f64 = v
                    .parse()
                    .map_err(|_| format!("--toward: not a number: {v:?}"))?;
                if !(0.0..=1.0).contains(&f) {
                    return Err(format!("--toward: {f} is outside [0, 1]"));
                }
                toward = Some(f);
            }
            _ if a.starts_with("--") => return Err(format!("unknown option {a}")),
            _ => pos.push(PathBuf::from(a)),
        }
    }
    let [checkpoint, data] = <[PathBuf; 2]>::try_from(pos).map_err(|_| {
        "usage: motion_gradient CHECKPOINT DATA [--clips N] [--zero-motion | --toward S] [--true-cameras] [--self-target]"
    })?;
    Ok(Args {
        checkpoint,
        data,
        clips,
        toward,
        true_cameras,
        self_target,
    })
}

/// One clip's alignment rows (`None` when its truth cannot be aligned).
fn clip_rows(
    model: &Envision4d,
    tc: usize,
    clip: &HostClip,
    (toward, true_cameras, self_target): (Option<f64>, bool, bool),
    device: &Device,
) -> Result<Option<Vec<AlignmentRow>>, String> {
    let n = clip.frames.len();
    let (h, w) = (clip.height, clip.width);
    let images: Vec<f32> = clip.frames.iter().flatten().copied().collect();
    let images = Tensor::<5>::from_data(TensorData::new(images, [1, n, 3, h, w]), device);
    let context = images.clone().slice([0..1, 0..tc, 0..3, 0..h, 0..w]);
    let mut scene =
        predict_scene_with(model, context, Motion::Predicted).map_err(|e| e.to_string())?;
    // Only the displacements are leaves: the gradient is the rendering loss's with respect
    // to them, everything else held.
    let a = &mut scene.adapted;
    for t in [&mut a.means, &mut a.scales, &mut a.rotations, &mut a.colors] {
        *t = t.clone().detach();
    }
    a.opacities = a.opacities.clone().detach();
    let bb = &mut scene.pred.backbone;
    bb.extrinsics = bb.extrinsics.clone().detach();
    bb.intrinsics = bb.intrinsics.clone().detach();
    let host = |t: Tensor<5>| -> Vec<f32> { t.into_data().iter::<f32>().collect() };
    let own = host(scene.adapted.motions.clone().detach());
    let means: Vec<f32> = scene
        .adapted
        .means
        .clone()
        .into_data()
        .iter::<f32>()
        .collect();
    let extrinsics =
        host_extrinsics(&scene.pred.backbone.extrinsics, 0).map_err(|e| e.to_string())?;
    let pred = PredictedMotion {
        context: tc,
        frames: n,
        grid: (h, w),
        means: &means,
        motions: &own,
        extrinsics: &extrinsics,
    };
    let truth = MotionTruth {
        size: (h, w),
        frames: &clip.motion_truth,
        masks: &clip.dynamic_masks,
    };
    let Some((exact, cameras)) = exact_motions_and_cameras(&pred, &truth) else {
        return Ok(None);
    };
    let mut seen_from = extrinsics.clone();
    if true_cameras {
        seen_from.clone_from(&cameras);
        let bb = &mut scene.pred.backbone;
        bb.extrinsics = extrinsics_tensor(&cameras, device);
        bb.intrinsics = clip_intrinsics_tensor(clip, n, device);
    }
    let shape = scene.adapted.motions.dims();
    let current: Vec<f32> = match toward {
        None => own,
        Some(f) => exact.iter().map(|&e| e * f as f32).collect(),
    };
    let future: Vec<usize> = (tc..n).collect();
    let raster = RasterConfig::default();
    let target = if self_target {
        let mut exact_scene = scene.clone();
        exact_scene.adapted.motions =
            Tensor::from_data(TensorData::new(exact.clone(), shape), device);
        exact_scene
            .render(0, &future, Exclusion::SelfExclusive, [h, w], &raster)
            .map_err(|e| e.to_string())?
            .detach()
    } else {
        images
            .slice([0..1, tc..n, 0..3, 0..h, 0..w])
            .reshape([n - tc, 3, h, w])
    };
    let start = Tensor::<5>::from_data(TensorData::new(current.clone(), shape), device);
    scene.adapted.motions = start.require_grad();
    let rendered = scene
        .render(0, &future, Exclusion::SelfExclusive, [h, w], &raster)
        .map_err(|e| e.to_string())?;
    let grads = (rendered - target).square().mean().backward();
    let grad = scene
        .adapted
        .motions
        .grad(&grads)
        .ok_or("the displacements got no gradient")?;
    let centres: Vec<DVec3> = seen_from
        .iter()
        .map(|e| e.to_glam().inverse().transform_point3(DVec3::ZERO))
        .collect();
    Ok(Some(gradient_alignment(&AlignmentInputs {
        grad: &host(grad),
        exact: &exact,
        current: &current,
        means: &means,
        centres: &centres,
        context: tc,
    })))
}

fn run(args: Args) -> Result<String, String> {
    let device = Device::flex().autodiff();
    let cfg = checkpoint_config(&args.checkpoint)
        .map_err(|e| e.to_string())?
        .ok_or_else(|| {
            format!(
                "{}: no model config in the checkpoint",
                args.checkpoint.display()
            )
        })?;
    let mut model = Envision4d::new(&cfg, &device);
    load_checkpoint(&mut model, &args.checkpoint, CheckpointKind::Full)
        .map_err(|e| e.to_string())?;
    // Every window of the synthetic layout, fitted to the model's size, as evaluation opens it.
    let data = DataConfig::new(DataLayout::Synth, args.data.clone(), 1);
    let ds = open_dataset(&data, &cfg, &args.data, Purpose::Eval).map_err(|e| e.to_string())?;
    let mut rows: Vec<Vec<AlignmentRow>> = vec![];
    for i in 0..ds.len().min(args.clips) {
        let clip = ds.load(i).map_err(|e| format!("clip {i}: {e}"))?;
        let clip = HostClip::from_clip(&clip).map_err(|e| format!("clip {i}: {e}"))?;
        if clip.motion_truth.is_empty() {
            return Err(format!(
                "{}: clip {i} has no motion truth",
                args.data.display()
            ));
        }
        if let Some(r) = clip_rows(
            &model,
            cfg.context_frames,
            &clip,
            (args.toward, args.true_cameras, args.self_target),
            &device,
        )? {
            rows.push(r);
        }
    }
    if rows.is_empty() {
        return Err("no clip's truth could be aligned".into());
    }
    Ok(table(&rows, &args))
}

/// Means over clips per target timestamp (a clip without a value is left out of that mean).
fn table(rows: &[Vec<AlignmentRow>], args: &Args) -> String {
    let mean = |f: &dyn Fn(&AlignmentRow) -> Option<f64>, t: usize| -> String {
        let v: Vec<f64> = rows.iter().filter_map(|r| f(&r[t])).collect();
        if v.is_empty() {
            "-".into()
        } else {
            format!("{:.3}", v.iter().sum::<f64>() / v.len() as f64)
        }
    };
    let sci = |f: &dyn Fn(&AlignmentRow) -> f64, t: usize| -> String {
        format!(
            "{:.2e}",
            rows.iter().map(|r| f(&r[t])).sum::<f64>() / rows.len() as f64
        )
    };
    let mut out = format!(
        "{} clips, displacements {}, {} cameras, targets {}\n\n| target | moving px | reached | cos moving, 3D | cos moving, image plane | mean cos moving, image plane | cos static, image plane | grad RMS moving | grad RMS static |\n|---|---|---|---|---|---|---|---|---|\n",
        rows.len(),
        args.toward
            .map_or("the model's".into(), |f| format!("{f} x the exact ones")),
        if args.true_cameras { "true" } else { "predicted" },
        if args.self_target {
            "the render with the exact displacements"
        } else {
            "the real future frames"
        },
    );
    for t in 0..rows[0].len() {
        let moving: usize = rows.iter().map(|r| r[t].moving).sum();
        let reached: usize = rows.iter().map(|r| r[t].moving_reached).sum();
        out += &format!(
            "| {} | {moving} | {:.1}% | {} | {} | {} | {} | {} | {} |\n",
            rows[0][t].target,
            100.0 * reached as f64 / moving.max(1) as f64,
            mean(&|r| r.moving_cosine, t),
            mean(&|r| r.moving_image_cosine, t),
            mean(&|r| r.moving_image_mean_cosine, t),
            mean(&|r| r.static_image_cosine, t),
            sci(&|r| r.moving_grad_rms, t),
            sci(&|r| r.static_grad_rms, t),
        );
    }
    out
}

fn main() {
    let code = match parse_args().and_then(run) {
        Ok(table) => {
            print!("{table}");
            0
        }
        Err(e) => {
            eprintln!("motion_gradient: {e}");
            2
        }
    };
    std::process::exit(code);
}
