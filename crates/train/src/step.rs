//! The training step (paper §3.4). Stage `envision4d`: forward on the context frames, the
//! schedule's [`PhasePlan`] says which frames to render and how to weigh them, each target
//! is rendered from the scene path (other frames' Gaussians moved to its time) through the
//! PREDICTED camera so `L_rgb` reaches the poses, then the distillation terms are added.
//! Either stage ends in an Adam step on the trainable parameters only.

use crate::backbone::backbone_loss;
use crate::batch::Batch;
use crate::config::{ClipMode, Stage, Teacher, TrainConfig};
use crate::distill::{labels, DistillLoss, FrozenTeacher};
use crate::error::{Result, TrainError};
use crate::freeze::{detach_frozen, grads_finite, params_finite, ParamSplit};
use crate::grad_clip::{clip_global_norm, grad_norms, GradNorms};
pub use crate::init::{build_model, identity_pose_init, INITIAL_FOV_RAD, POSE_OUTPUT_INIT_SCALE};
pub(crate) use crate::report::LossValues;
pub use crate::report::{LossTerms, StepOutcome, StepReport};
use crate::schedule::{Phase, PhasePlan, Schedule};
pub use crate::setup::raster_config;
pub(crate) use crate::setup::teacher_is_init;
use crate::setup::{make_optimizer, make_rgb_loss};
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, Tensor};
use envision4d_losses::{psnr_from_mse, RgbLoss};
use envision4d_model::aggregator::BlockMemory;
use envision4d_model::scene::{predict_scene_with, Motion};
use envision4d_model::Envision4d;
use envision4d_splat::RasterConfig;

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
        // Seeded under a process-wide lock so the random init (and hence the run) is
        // reproducible even when other threads build models at the same time.
        let model =
            envision4d_model::seeded::seeded(device, config.seed, || build_model(&config, device))?;
        let rgb_loss = make_rgb_loss(&config, device)?;
        let teacher = match (config.stage, config.teacher) {
            // The teacher is the initial weights: a snapshot of the model as built, sharing
            // every tensor with it (tensors are immutable values), so only the parameters an
            // update replaces (the trainable depth head) ever exist twice. A separate load
            // would hold a second copy of the frozen backbone (4.5 GB at paper widths).
            (Stage::Envision4d, Teacher::Backbone) if teacher_is_init(&config) => {
                Some(FrozenTeacher::snapshot(&model))
            }
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
        let split = ParamSplit::new(&model, &config.freeze);
        let mut model = detach_frozen(model, &split);
        if config.run.recompute_frozen_blocks {
            model.aggregator.block_memory = BlockMemory::RecomputeFrozen;
        }
        let optim = make_optimizer(&config);
        let raster = raster_config(&config);
        Ok(Trainer {
            model,
            schedule: Schedule::from_config(&config),
            config,
            split,
            raster,
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
                    flow: None,
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
            return Err(TrainError::Unusable(format!(
                "batch has {frames} frames, the model expects T_c + T_f = {n}"
            )));
        }
        let context = batch
            .images
            .clone()
            .slice([0..bsz, 0..tc, 0..3, 0..h, 0..w]);
        let plan = self.schedule.plan(step, tc, n);
        // A plan without motion (the static warm-up) never runs the motion head.
        let motion = if plan.motion {
            Motion::Predicted
        } else {
            Motion::Still
        };
        let scene = predict_scene_with(model, context, motion)?;
        let (rgb, mse) = self.rendering_loss(&scene, batch, &plan)?;
        let mut total = rgb.clone();
        let lambda_flow = self.config.loss.lambda_flow;
        let flow = if plan.motion && lambda_flow > 0.0 {
            Some(crate::motion_signal::flow_loss(
                &scene,
                batch,
                (tc, n),
                self.config.loss.flow_balanced,
            )?)
        } else {
            None
        };
        if let Some(f) = &flow {
            total = total + f.clone() * lambda_flow;
        }
        let (mut camera, mut depth) = (None, None);
        if let Some(t) = labels(self.config.teacher, self.teacher.as_ref(), batch, tc)? {
            let d = scene
                .pred
                .depth
                .clone()
                .ok_or_else(|| TrainError::Internal("depth head did not run".into()))?;
            let terms = DistillLoss::new(scene.pred.backbone.pose_enc(), d, &t, &self.config.loss)?;
            total = terms.add_to(total, &self.config.loss);
            camera = Some(terms.camera);
            depth = Some(terms.depth);
        }
        Ok(LossTerms {
            total,
            rgb,
            rgb_mse: Some(mse),
            camera,
            depth,
            flow,
            phase: plan.phase,
        })
    }

    /// `L_rgb` of the plan's targets, `Σ_t w̄_t·L_rgb,t / N_rendered` averaged over the batch,
    /// and the unweighted mean MSE of the renders (detached, for the log's PSNR).
    fn rendering_loss(
        &self,
        scene: &envision4d_model::Scene,
        batch: &Batch,
        plan: &PhasePlan,
    ) -> Result<(Tensor<1>, Tensor<1>)> {
        let [bsz, n, _, h, w] = batch.images.dims();
        let device = batch.images.device();
        let wt: Vec<f32> = plan.weights.iter().map(|&w| w as f32).collect();
        let wt = Tensor::<1>::from_floats(wt.as_slice(), &device);
        let mut rgb_sum = Tensor::<1>::zeros([1], &device);
        let mut mse_sum = Tensor::<1>::zeros([1], &device);
        // Every element's targets in one rasterizer call: one host readback for all views.
        let all = scene.render_batch(&plan.targets, plan.exclusion, [h, w], &self.raster)?;
        let f = plan.targets.len();
        for b in 0..bsz {
            let rendered = all.clone().slice([b * f..(b + 1) * f, 0..3, 0..h, 0..w]);
            let gt = batch
                .images
                .clone()
                .slice([b..b + 1, 0..n, 0..3, 0..h, 0..w])
                .reshape([n, 3, h, w]);
            let gt = Tensor::cat(
                plan.targets
                    .iter()
                    .map(|&j| gt.clone().slice([j..j + 1, 0..3, 0..h, 0..w]))
                    .collect(),
                0,
            );
            let weight = crate::motion_signal::pixel_weights(
                batch,
                b,
                &plan.targets,
                self.config.loss.dynamic_weight,
            );
            let terms = self
                .rgb_loss_on(&device)?
                .per_frame_weighted(rendered, gt, weight)?;
            mse_sum = mse_sum + terms.mse.sum().detach();
            rgb_sum = rgb_sum + (terms.total * wt.clone()).sum();
        }
        let rendered = (bsz * plan.targets.len()) as f64;
        Ok((rgb_sum / rendered, mse_sum / rendered))
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
        let v = terms.values();
        let total = v.total;
        let report = |outcome| StepReport {
            step,
            total,
            rgb: v.rgb,
            camera: v.camera,
            depth: v.depth,
            psnr: v.mse.map(psnr_from_mse),
            flow: v.flow,
            grad_norms: None,
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
        let (outcome, norms) = self.apply(lr, gp);
        Ok(StepReport {
            grad_norms: norms,
            ..report(outcome)
        })
    }

    /// Measures (the gradient norms, before clipping, returned for the log), clips (global
    /// norm, when configured) and applies `grads`; an update that leaves any trainable
    /// parameter non-finite is rolled back (model and Adam state) and counted as skipped, so a
    /// checkpoint never holds exploded weights.
    pub(crate) fn apply(
        &mut self,
        lr: f64,
        mut grads: GradientsParams,
    ) -> (StepOutcome, Option<GradNorms>) {
        // Measured when the clip needs them or the log keeps this step (the step counter
        // already points past it): a reduction and a host read saved on the other steps.
        let clip = self.config.optim.grad_clip == ClipMode::GlobalNorm;
        let logged = crate::log::logged(self.step.saturating_sub(1), self.config.run.log_every);
        let norms = (clip || logged)
            .then(|| grad_norms(&self.model, &grads))
            .flatten();
        if let (true, Some(n)) = (clip, norms) {
            clip_global_norm(
                &self.model,
                &mut grads,
                n.total,
                self.config.optim.grad_clip_threshold,
            );
        }
        let (model, optim) = (self.model.clone(), self.optim.clone());
        self.model = self.optim.step(lr, self.model.clone(), grads);
        if !params_finite(&self.model, &self.split.frozen) {
            self.model = model;
            self.optim = optim;
            self.skipped += 1;
            self.consecutive_nonfinite += 1;
            return (StepOutcome::SkippedNonFiniteUpdate, norms);
        }
        self.consecutive_nonfinite = 0;
        (StepOutcome::Applied, norms)
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
            .ok_or_else(|| TrainError::Internal(format!("no rendering loss on {device:?}")))
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
