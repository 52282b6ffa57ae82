//! The stage-`envision4d` training step: forward on the context frames, adapt, render every
//! target frame from the other frames' Gaussians through the PREDICTED camera (so L_rgb
//! reaches the poses), weight L_rgb progressively, add the distillation terms, and take an
//! Adam step on the trainable parameters only.

use crate::batch::Batch;
use crate::config::{ClipMode, Stage, Teacher, TrainConfig};
use crate::error::{Result, TrainError};
use crate::freeze::ParamSplit;
use crate::schedule::{Phase, Schedule};
use burn::grad_clipping::GradientClippingConfig;
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, Tensor};
use envision4d_losses::{camera_distill, LpipsNet, LpipsStatus, RgbLoss};
use envision4d_model::adapter::{gaussians_at, AdaptedGaussians, Exclusion, OpacityMapping};
use envision4d_model::checkpoint::CheckpointKind;
use envision4d_model::model::Heads;
use envision4d_model::pose::pose_encoding_to_extri_intri;
use envision4d_model::Envision4d;
use envision4d_splat::{render, Cameras, Gaussians, RasterConfig};

/// FoV channels of the 9-d pose encoding (`fov_h`, `fov_w`).
const FOV_CHANNELS: std::ops::Range<usize> = 7..9;
/// FoV clamp (radians): ~3° to ~172°, wider than any real camera.
const FOV_MIN_RAD: f64 = 0.05;
const FOV_MAX_RAD: f64 = 3.0;

/// Loss terms of one step (scalar tensors `[1]`, still attached to the graph).
#[derive(Debug, Clone)]
pub struct LossTerms {
    pub total: Tensor<1>,
    /// Weighted mean of per-frame L_rgb.
    pub rgb: Tensor<1>,
    pub camera: Option<Tensor<1>>,
    pub depth: Option<Tensor<1>>,
    pub phase: Phase,
}

/// Host values of a finished step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepReport {
    pub step: u64,
    pub total: f64,
    pub rgb: f64,
    pub camera: f64,
    pub depth: f64,
    pub lr: f64,
    pub phase: Phase,
    pub outcome: StepOutcome,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepOutcome {
    Applied,
    /// The loss was not finite: no update, counted in `Trainer::skipped`.
    SkippedNonFinite,
}

/// Renders target frames `targets` of batch element `b` (each from `gaussians_at(.., j,
/// exclusion)`) with the predicted cameras; returns `[F, 3, H, W]`.
pub fn render_targets(
    adapted: &AdaptedGaussians,
    extrinsics: &Tensor<4>,
    intrinsics: &Tensor<4>,
    b: usize,
    targets: &[usize],
    exclusion: Exclusion,
    size: [usize; 2],
    raster: &RasterConfig,
) -> Result<Tensor<4>> {
    let mut frames = Vec::with_capacity(targets.len());
    for &j in targets {
        let (means, quats, scales, opacities, colors) = gaussians_at(adapted, b, j, exclusion);
        let g = Gaussians {
            means,
            quats,
            scales,
            opacities,
            colors,
        };
        let cams = Cameras {
            viewmats: extrinsics
                .clone()
                .slice([b..b + 1, j..j + 1, 0..4, 0..4])
                .reshape([1, 4, 4]),
            ks: intrinsics
                .clone()
                .slice([b..b + 1, j..j + 1, 0..3, 0..3])
                .reshape([1, 3, 3]),
            width: size[1] as u32,
            height: size[0] as u32,
        };
        let out = render(&g, &cams, raster)?;
        frames.push(out.rgb.permute([0, 3, 1, 2]));
    }
    Ok(Tensor::cat(frames, 0))
}

fn scalar(t: &Tensor<1>) -> f64 {
    t.clone()
        .into_data()
        .iter::<f64>()
        .next()
        .unwrap_or(f64::NAN)
}

/// A model with its optimiser, schedule and frozen set.
pub struct Trainer {
    pub model: Envision4d,
    pub config: TrainConfig,
    pub schedule: Schedule,
    pub split: ParamSplit,
    pub raster: RasterConfig,
    rgb_loss: RgbLoss,
    optim: ModuleOptimizer,
    /// The next step to run (0-based).
    pub step: u64,
    /// Steps skipped for a non-finite loss.
    pub skipped: u64,
}

impl Trainer {
    /// Builds the model on `device` (must be an autodiff device for [`Trainer::step`]).
    pub fn new(config: TrainConfig, device: &Device) -> Result<Self> {
        if config.stage != Stage::Envision4d {
            return Err(TrainError::invalid(
                "stage",
                "\"backbone\"",
                "stage-1 training is not in this build yet; only \"envision4d\" trains",
            ));
        }
        if config.teacher == Teacher::Backbone {
            return Err(TrainError::invalid("teacher", "\"backbone\"", "the frozen-backbone teacher is not in this build yet; use \"ground_truth\" or \"none\""));
        }
        // Seed the device RNG so the random init (and hence the run) is reproducible.
        device.seed(config.seed);
        let model = build_model(&config, device)?;
        let lpips =
            LpipsStatus::from_path(config.loss.lpips_weights.as_deref(), LpipsNet::Vgg, device)?;
        let rgb_loss = RgbLoss::new(config.loss.lambda_lpips, &lpips)?;
        let split = ParamSplit::new(&model, &config.freeze);
        let clip = match config.optim.grad_clip {
            ClipMode::Norm => Some(GradientClippingConfig::Norm(
                config.optim.grad_clip_threshold as f32,
            )),
            ClipMode::Value => Some(GradientClippingConfig::Value(
                config.optim.grad_clip_threshold as f32,
            )),
            ClipMode::None => None,
        };
        // The paper states no weight decay (model.md §3).
        let optim = AdamConfig::new().with_grad_clipping(clip).init();
        Ok(Trainer {
            model,
            schedule: Schedule::from_config(&config),
            config,
            split,
            raster: RasterConfig::default(),
            rgb_loss,
            optim,
            step: 0,
            skipped: 0,
        })
    }

    /// The loss of `batch` at schedule step `step` (forward only).
    pub fn loss(&self, batch: &Batch, step: u64) -> Result<LossTerms> {
        let m = &self.config.model;
        let (tc, n) = (m.context_frames, m.num_frames());
        let [bsz, frames, _, h, w] = batch.images.dims();
        if frames != n {
            return Err(TrainError::Batch(format!(
                "batch has {frames} frames, the model expects T_c + T_f = {n}"
            )));
        }
        let context = batch
            .images
            .clone()
            .slice([0..bsz, 0..tc, 0..3, 0..h, 0..w]);
        let mut pred = self.model.forward(context, Heads::ALL);
        let pose = pred.backbone.pose_enc();
        if !pose.clone().into_data().iter::<f64>().all(f64::is_finite) {
            return Err(TrainError::NonFinite("pose encoding"));
        }
        // Workaround: the camera head's FoV activation is a ReLU, so an untrained head can
        // predict FoV 0 (infinite focal) and the renderer rightly refuses the camera. Clamp
        // the FoV channels into a sane range (gradient passes inside it) and rebuild the
        // cameras that adapt and render use.
        let [bq, nq, _] = pose.dims();
        let fov = pose
            .clone()
            .slice([0..bq, 0..nq, FOV_CHANNELS])
            .clamp(FOV_MIN_RAD, FOV_MAX_RAD);
        let pose = pose.slice_assign([0..bq, 0..nq, FOV_CHANNELS], fov);
        let (extr, intr) = pose_encoding_to_extri_intri(pose, h, w);
        pred.backbone.extrinsics = extr;
        pred.backbone.intrinsics = intr;
        let adapted = self
            .model
            .adapt(&pred, OpacityMapping::default(), step)
            .ok_or_else(|| {
                TrainError::Model("adapt needs the depth, Gaussian and motion heads".into())
            })?;
        let phase = self.schedule.phase(step);
        let (targets, exclusion): (Vec<usize>, _) = match phase {
            Phase::Warmup => ((0..tc).collect(), Exclusion::IncludeOwn),
            Phase::Progressive => ((0..n).collect(), Exclusion::SelfExclusive),
        };
        let weights = match phase {
            Phase::Warmup => vec![1.0; n],
            Phase::Progressive => self.schedule.frame_weights(step, tc, n),
        };
        let device = batch.images.device();
        let wt: Vec<f32> = targets.iter().map(|&j| weights[j] as f32).collect();
        let wt = Tensor::<1>::from_floats(wt.as_slice(), &device);
        let bb = &pred.backbone;
        let mut rgb_sum = Tensor::<1>::zeros([1], &device);
        for b in 0..bsz {
            let rendered = render_targets(
                &adapted,
                &bb.extrinsics,
                &bb.intrinsics,
                b,
                &targets,
                exclusion,
                [h, w],
                &self.raster,
            )?;
            let gt = batch
                .images
                .clone()
                .slice([b..b + 1, 0..n, 0..3, 0..h, 0..w])
                .reshape([n, 3, h, w]);
            let gt = Tensor::cat(
                targets
                    .iter()
                    .map(|&j| gt.clone().slice([j..j + 1, 0..3, 0..h, 0..w]))
                    .collect(),
                0,
            );
            let per_frame = self.rgb_loss.per_frame(rendered, gt)?.total;
            rgb_sum = rgb_sum + (per_frame * wt.clone()).sum();
        }
        // Σ_t w̄_t·L_rgb,t / N_rendered, averaged over the batch.
        let rgb = rgb_sum / (bsz * targets.len()) as f64;
        let mut total = rgb.clone();
        let (mut camera, mut depth) = (None, None);
        if let (Teacher::GroundTruth, Some(t)) = (self.config.teacher, &batch.teacher) {
            let cam = camera_distill(bb.pose_enc(), t.pose_enc.clone().detach())?;
            let d = pred
                .depth
                .clone()
                .ok_or_else(|| TrainError::Model("depth head did not run".into()))?;
            let dl = masked_l1(d, t.depth.clone().detach());
            total = total
                + cam.clone() * self.config.loss.lambda_cam
                + dl.clone() * self.config.loss.lambda_depth;
            camera = Some(cam);
            depth = Some(dl);
        } else if self.config.teacher == Teacher::GroundTruth {
            return Err(TrainError::Batch(
                "teacher = \"ground_truth\" but the batch carries no targets".into(),
            ));
        }
        Ok(LossTerms {
            total,
            rgb,
            camera,
            depth,
            phase,
        })
    }

    /// One optimisation step on `batch`; a non-finite loss skips the update.
    pub fn train_step(&mut self, batch: &Batch) -> Result<StepReport> {
        let step = self.step;
        let lr = self.schedule.learning_rate(step);
        let terms = match self.loss(batch, step) {
            Ok(t) => t,
            Err(TrainError::NonFinite(_)) => {
                self.step += 1;
                self.skipped += 1;
                return Ok(StepReport {
                    step,
                    total: f64::NAN,
                    rgb: f64::NAN,
                    camera: f64::NAN,
                    depth: f64::NAN,
                    lr,
                    phase: self.schedule.phase(step),
                    outcome: StepOutcome::SkippedNonFinite,
                });
            }
            Err(e) => return Err(e),
        };
        let total = scalar(&terms.total);
        let report = |outcome| StepReport {
            step,
            total,
            rgb: scalar(&terms.rgb),
            camera: terms.camera.as_ref().map_or(0.0, scalar),
            depth: terms.depth.as_ref().map_or(0.0, scalar),
            lr,
            phase: terms.phase,
            outcome,
        };
        self.step += 1;
        if !total.is_finite() {
            self.skipped += 1;
            return Ok(report(StepOutcome::SkippedNonFinite));
        }
        let mut grads = terms.total.backward();
        // Frozen parameters get no gradient entry, so Adam leaves them untouched.
        let gp = GradientsParams::from_params(&mut grads, &self.model, &self.split.trainable);
        self.model = self.optim.step(lr, self.model.clone(), gp);
        Ok(report(StepOutcome::Applied))
    }
}

/// Mean |d − t| over pixels with a valid target (t > 0; the synthetic sky has depth 0).
fn masked_l1(pred: Tensor<5>, target: Tensor<5>) -> Tensor<1> {
    let mask = target.clone().greater_elem(0.0).float();
    let count = mask.clone().sum().clamp_min(1.0);
    ((pred - target).abs() * mask).sum() / count
}

/// The model of a config, from `init_checkpoint` when given.
/// Field of view (radians, both axes) a from-scratch camera head starts at (~57°).
pub const INITIAL_FOV_RAD: f32 = 1.0;
/// Scale of the camera head's last layer at a from-scratch start: small, so the first poses
/// are close to the identity but gradients still reach the whole head.
pub const POSE_OUTPUT_INIT_SCALE: f64 = 1e-3;

/// Starts a freshly initialised camera head at the identity pose with a plausible FoV.
///
/// With random weights the head predicts random poses: the Gaussians then land behind or
/// beside every camera, the renders are blank and no gradient reaches anything (and a ReLU'd
/// FoV of 0 is an infinite focal length). The head sums its 4 refinement deltas, so the last
/// layer's bias is a quarter of `[t = 0, q = (0, 0, 0, 1), fov_h, fov_w]` and its weight is
/// shrunk (as AdaLN-zero-style output layers are).
pub fn identity_pose_init(model: &mut Envision4d) {
    use burn::module::Param;
    use envision4d_model::config::CAMERA_ITERATIONS;
    let fc2 = &mut model.camera_head.pose_branch.fc2;
    let device = fc2.weight.device();
    fc2.weight = Param::from_tensor(
        fc2.weight
            .val()
            .detach()
            .mul_scalar(POSE_OUTPUT_INIT_SCALE)
            .detach(),
    );
    let k = CAMERA_ITERATIONS as f32;
    let bias = [
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        1.0 / k,
        INITIAL_FOV_RAD / k,
        INITIAL_FOV_RAD / k,
    ];
    fc2.bias = Some(Param::from_tensor(Tensor::<1>::from_floats(bias, &device)));
}

pub fn build_model(config: &TrainConfig, device: &Device) -> Result<Envision4d> {
    let mut model = Envision4d::new(&config.model, device);
    if config.init_checkpoint.is_none() {
        identity_pose_init(&mut model);
    }
    if let Some(path) = &config.init_checkpoint {
        // VGGT-1B init: the backbone must be present; new modules keep their init. A full
        // checkpoint of ours also satisfies this.
        envision4d_model::checkpoint::load_checkpoint(&mut model, path, CheckpointKind::Vggt1bInit)
            .map_err(|e| TrainError::Model(format!("init_checkpoint {}: {e}", path.display())))?;
    }
    Ok(model)
}
