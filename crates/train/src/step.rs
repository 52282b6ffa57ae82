//! The stage-`envision4d` training step: forward on the context frames, adapt, render every
//! target frame from the other frames' Gaussians through the PREDICTED camera (so L_rgb
//! reaches the poses), weight L_rgb progressively, add the distillation terms, and take an
//! Adam step on the trainable parameters only.

use crate::backbone::{backbone_loss, masked_l1, FrozenTeacher};
use crate::batch::Batch;
use crate::clip::clip_global_norm;
use crate::config::{ClipMode, Stage, Teacher, TrainConfig};
use crate::error::{Result, TrainError};
use crate::freeze::{detach_frozen, grads_finite, params_finite, ParamSplit};
use crate::infer::{gaussians_for, predict_scene, Scene};
pub use crate::init::{build_model, identity_pose_init, INITIAL_FOV_RAD, POSE_OUTPUT_INIT_SCALE};
use crate::schedule::{Phase, Schedule};
use burn::grad_clipping::GradientClippingConfig;
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, Tensor};
use envision4d_losses::{camera_distill_weighted, LpipsNet, LpipsStatus, RgbLoss};
use envision4d_model::adapter::{AdaptedGaussians, Exclusion};
use envision4d_model::Envision4d;
use envision4d_splat::{render, Cameras, RasterConfig};

/// Loss terms of one step (scalar tensors `[1]`, still attached to the graph).
#[derive(Debug, Clone)]
pub struct LossTerms {
    pub total: Tensor<1>,
    /// Weighted mean of per-frame L_rgb.
    pub rgb: Tensor<1>,
    /// Unweighted mean MSE of the rendered frames (detached; for PSNR in logs).
    pub rgb_mse: Option<Tensor<1>>,
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
    /// PSNR (dB) of the step's renders from their unweighted MSE (envision4d stage).
    pub psnr: Option<f64>,
    pub lr: f64,
    pub phase: Phase,
    pub outcome: StepOutcome,
}

impl StepReport {
    /// The report of a step that was not applied (its loss terms unknown).
    pub fn skipped(step: u64, lr: f64, phase: Phase, outcome: StepOutcome) -> StepReport {
        StepReport {
            step,
            total: f64::NAN,
            rgb: f64::NAN,
            camera: f64::NAN,
            depth: f64::NAN,
            psnr: None,
            lr,
            phase,
            outcome,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepOutcome {
    Applied,
    /// The loss (or a prediction it needs) was not finite: no update, counted.
    SkippedNonFiniteLoss,
    /// A gradient was not finite: no update, counted.
    SkippedNonFiniteGradient,
    /// The update made a parameter non-finite: rolled back, counted.
    SkippedNonFiniteUpdate,
}

impl StepOutcome {
    pub fn applied(self) -> bool {
        self == StepOutcome::Applied
    }
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
        let g = gaussians_for(adapted, b, j, exclusion);
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

pub(crate) fn scalar(t: &Tensor<1>) -> f64 {
    t.clone()
        .into_data()
        .iter::<f64>()
        .next()
        .unwrap_or(f64::NAN)
}

fn make_rgb_loss(config: &TrainConfig, device: &Device) -> Result<RgbLoss> {
    let path = config.loss.lpips_weights.as_deref();
    let lpips = LpipsStatus::from_path(path, LpipsNet::Vgg, device).map_err(|e| {
        TrainError::Input(format!(
            "loss.lpips_weights {}: {e}",
            path.map_or("(none)".into(), |p| p.display().to_string())
        ))
    })?;
    Ok(RgbLoss::new(config.loss.lambda_lpips, &lpips)?.with_ssim(config.loss.lambda_ssim)?)
}

/// Adam (no weight decay: the paper states none, model.md §3) with the configured ε and,
/// for the per-tensor modes, Burn's clipping; global-norm clipping is applied by the step.
fn make_optimizer(config: &TrainConfig) -> ModuleOptimizer {
    let o = &config.optim;
    let clip = match o.grad_clip {
        ClipMode::Norm => Some(GradientClippingConfig::Norm(o.grad_clip_threshold as f32)),
        ClipMode::Value => Some(GradientClippingConfig::Value(o.grad_clip_threshold as f32)),
        ClipMode::GlobalNorm | ClipMode::None => None,
    };
    AdamConfig::new()
        .with_epsilon(o.adam_epsilon as f32)
        .with_grad_clipping(clip)
        .init()
}

/// A model with its optimiser, schedule and frozen set.
pub struct Trainer {
    pub model: Envision4d,
    pub config: TrainConfig,
    pub schedule: Schedule,
    pub split: ParamSplit,
    pub raster: RasterConfig,
    /// The rendering loss per device (LPIPS weights live on one device; data-parallel shards
    /// score on their own). The first entry is the run's device.
    rgb_losses: Vec<(Device, RgbLoss)>,
    pub(crate) optim: ModuleOptimizer,
    teacher: Option<FrozenTeacher>,
    /// The next step to run (0-based).
    pub step: u64,
    /// Steps skipped for a non-finite loss or gradient.
    pub skipped: u64,
    /// Skipped steps in a row (reset by an applied step): the NaN guard's counter.
    pub consecutive_nonfinite: u64,
}

impl Trainer {
    /// Builds the model on `device` (must be an autodiff device for [`Trainer::step`]).
    pub fn new(config: TrainConfig, device: &Device) -> Result<Self> {
        // Seed the device RNG so the random init (and hence the run) is reproducible.
        device.seed(config.seed);
        let model = build_model(&config, device)?;
        let rgb_loss = make_rgb_loss(&config, device)?;
        let split = ParamSplit::new(&model, &config.freeze);
        let model = detach_frozen(model, &split);
        let teacher = match (config.stage, config.teacher) {
            (Stage::Envision4d, Teacher::Backbone) => {
                let path = config
                    .teacher_checkpoint
                    .as_ref()
                    .or(config.init_checkpoint.as_ref())
                    .ok_or_else(|| {
                        TrainError::invalid(
                            "teacher_checkpoint",
                            "(none)",
                            "teacher = \"backbone\" needs weights",
                        )
                    })?;
                Some(FrozenTeacher::load(&config.model, path, device)?)
            }
            _ => None,
        };
        let optim = make_optimizer(&config);
        Ok(Trainer {
            model,
            schedule: Schedule::from_config(&config),
            config,
            split,
            raster: RasterConfig::default(),
            rgb_losses: vec![(device.clone(), rgb_loss)],
            optim,
            teacher,
            step: 0,
            skipped: 0,
            consecutive_nonfinite: 0,
        })
    }

    /// The loss of `batch` at schedule step `step` (forward only), for the configured stage.
    pub fn loss(&self, batch: &Batch, step: u64) -> Result<LossTerms> {
        self.loss_with(&self.model, batch, step)
    }

    /// [`Trainer::loss`] of `model` (a fork of the trainer's model on another device for
    /// data-parallel steps; the batch lives on that device).
    pub fn loss_with(&self, model: &Envision4d, batch: &Batch, step: u64) -> Result<LossTerms> {
        match self.config.stage {
            Stage::Backbone => {
                let l = &self.config.loss;
                let t = backbone_loss(model, batch, l)?;
                Ok(LossTerms {
                    total: t.total,
                    rgb: Tensor::zeros([1], &batch.images.device()),
                    rgb_mse: None,
                    camera: Some(t.camera),
                    depth: Some(t.depth),
                    phase: Phase::Supervised,
                })
            }
            Stage::Envision4d => self.envision4d_loss(model, batch, step),
        }
    }

    /// The paper's loss (§3.4): progressive, self-exclusive rendering plus distillation.
    fn envision4d_loss(&self, model: &Envision4d, batch: &Batch, step: u64) -> Result<LossTerms> {
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
        let scene = predict_scene(model, context, step)?;
        let phase = self.schedule.phase(step);
        // Geometric warm-up is static (paper §3.4: "static geometry and pose optimization"):
        // every context frame is rendered from all context Gaussians, none moved. Letting the
        // untrained motion move the other frames' Gaussians here taught the motion head to
        // push them out of view, and the first self-exclusive renders came out empty.
        let Scene { pred, adapted } = match phase {
            Phase::Warmup => scene.without_motion(),
            Phase::Progressive | Phase::Supervised => scene,
        };
        let (targets, exclusion): (Vec<usize>, _) = match phase {
            Phase::Warmup => ((0..tc).collect(), Exclusion::IncludeOwn),
            Phase::Progressive | Phase::Supervised => ((0..n).collect(), Exclusion::SelfExclusive),
        };
        let weights = match phase {
            Phase::Warmup => vec![1.0; n],
            Phase::Progressive | Phase::Supervised => self.schedule.frame_weights(step, tc, n),
        };
        let device = batch.images.device();
        let wt: Vec<f32> = targets.iter().map(|&j| weights[j] as f32).collect();
        let wt = Tensor::<1>::from_floats(wt.as_slice(), &device);
        let bb = &pred.backbone;
        let mut rgb_sum = Tensor::<1>::zeros([1], &device);
        let mut mse_sum = Tensor::<1>::zeros([1], &device);
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
            let terms = self.rgb_loss_on(&device)?.per_frame(rendered, gt)?;
            mse_sum = mse_sum + terms.mse.sum().detach();
            rgb_sum = rgb_sum + (terms.total * wt.clone()).sum();
        }
        // Σ_t w̄_t·L_rgb,t / N_rendered, averaged over the batch.
        let rgb = rgb_sum / (bsz * targets.len()) as f64;
        let mut total = rgb.clone();
        let (mut camera, mut depth) = (None, None);
        let labels = match self.config.teacher {
            Teacher::None => None,
            Teacher::GroundTruth => Some(batch.teacher.clone().ok_or_else(|| {
                TrainError::Batch(
                    "teacher = \"ground_truth\" but the batch carries no targets".into(),
                )
            })?),
            Teacher::Backbone => {
                let teacher = self.teacher.as_ref().ok_or_else(|| {
                    TrainError::Model("teacher = \"backbone\" but no teacher is loaded".into())
                })?;
                Some(
                    teacher
                        .targets(batch.images.clone(), tc)?
                        .to_device(&device),
                )
            }
        };
        if let Some(t) = labels {
            let cam = camera_distill_weighted(
                bb.pose_enc(),
                t.pose_enc.detach(),
                self.config.loss.rotation_weight,
            )?;
            let d = pred
                .depth
                .clone()
                .ok_or_else(|| TrainError::Model("depth head did not run".into()))?;
            let dl = masked_l1(d, t.depth.detach());
            total = total
                + cam.clone() * self.config.loss.lambda_cam
                + dl.clone() * self.config.loss.lambda_depth;
            camera = Some(cam);
            depth = Some(dl);
        }
        Ok(LossTerms {
            total,
            rgb,
            rgb_mse: Some(mse_sum / (bsz * targets.len()) as f64),
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
                self.consecutive_nonfinite += 1;
                return Ok(StepReport::skipped(
                    step,
                    lr,
                    self.schedule.phase(step),
                    StepOutcome::SkippedNonFiniteLoss,
                ));
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
            psnr: terms.rgb_mse.as_ref().map(|m| -10.0 * scalar(m).log10()),
            lr,
            phase: terms.phase,
            outcome,
        };
        self.step += 1;
        if !total.is_finite() {
            self.skipped += 1;
            self.consecutive_nonfinite += 1;
            return Ok(report(StepOutcome::SkippedNonFiniteLoss));
        }
        let mut grads = terms.total.backward();
        if !grads_finite(&self.model, &grads) {
            self.skipped += 1;
            self.consecutive_nonfinite += 1;
            return Ok(report(StepOutcome::SkippedNonFiniteGradient));
        }
        // Frozen parameters get no gradient entry, so Adam leaves them untouched.
        let gp = GradientsParams::from_params(&mut grads, &self.model, &self.split.trainable);
        let outcome = self.apply(lr, gp);
        Ok(report(outcome))
    }

    /// Clips (global norm, when configured) and applies `grads`; an update that leaves any
    /// parameter non-finite is rolled back (model and Adam state) and counted as skipped, so
    /// a checkpoint never holds exploded weights.
    pub(crate) fn apply(&mut self, lr: f64, mut grads: GradientsParams) -> StepOutcome {
        if self.config.optim.grad_clip == ClipMode::GlobalNorm {
            clip_global_norm(
                &self.model,
                &mut grads,
                self.config.optim.grad_clip_threshold,
            );
        }
        let (model, optim) = (self.model.clone(), self.optim.clone());
        self.model = self.optim.step(lr, self.model.clone(), grads);
        if !params_finite(&self.model) {
            self.model = model;
            self.optim = optim;
            self.skipped += 1;
            self.consecutive_nonfinite += 1;
            return StepOutcome::SkippedNonFiniteUpdate;
        }
        self.consecutive_nonfinite = 0;
        StepOutcome::Applied
    }
}

impl Trainer {
    /// The optimiser's state (Adam moments per parameter id) for a checkpoint.
    pub fn optimizer_record(&self) -> burn::optim::OptimizerRecord {
        self.optim.to_record()
    }

    /// Restores the optimiser's state saved by [`Trainer::optimizer_record`]; the model's
    /// parameter ids must be the saved ones (see `checkpoint::restore_param_ids`).
    pub fn load_optimizer_record(&mut self, record: burn::optim::OptimizerRecord) {
        let optim = std::mem::replace(&mut self.optim, AdamConfig::new().init());
        self.optim = optim.load_record(record);
    }

    /// Recomputes the frozen/trainable split (after parameter ids changed).
    pub fn refresh_split(&mut self) {
        self.split = ParamSplit::new(&self.model, &self.config.freeze);
        self.model = detach_frozen(self.model.clone(), &self.split);
    }

    /// The rendering loss for tensors on `device`.
    fn rgb_loss_on(&self, device: &Device) -> Result<&RgbLoss> {
        self.rgb_losses
            .iter()
            .find(|(d, _)| d == device)
            .map(|(_, l)| l)
            .ok_or_else(|| TrainError::Model(format!("no rendering loss on {device:?}")))
    }

    /// Makes sure a rendering loss (with its LPIPS weights) exists on each of `devices`.
    pub(crate) fn prepare_devices(&mut self, devices: &[Device]) -> Result<()> {
        for d in devices {
            if !self.rgb_losses.iter().any(|(x, _)| x == d) {
                let l = make_rgb_loss(&self.config, d)?;
                self.rgb_losses.push((d.clone(), l));
            }
        }
        Ok(())
    }
}
