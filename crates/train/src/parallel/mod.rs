//! Data-parallel training on several devices with Burn's own multi-device pieces: the model
//! is forked onto each device (`Module::fork`), each device runs its shard of the batch
//! forward and backward on its own host thread, and the gradients are combined
//! ([`GradientReduce`]: gathered on the first device, or all-reduced by Burn's collectives on
//! CUDA) and applied once on the first device. No communication code of ours: Burn moves
//! the tensors.

mod reduce;

pub use reduce::GradientReduce;

use crate::batch::Batch;
use crate::error::{Result, TrainError};
use crate::freeze::grads_finite;
use crate::step::{LossValues, StepOutcome, StepReport, Trainer};
use burn::module::Module;
use burn::optim::GradientsParams;
use burn::tensor::Device;
use envision4d_losses::psnr_from_mse;
use envision4d_model::Envision4d;
/// Gradients of one data-parallel step, summed on the first device, with the shards' mean
/// loss terms; or the reason the step cannot be applied.
pub enum ParallelGradients {
    Ready {
        grads: GradientsParams,
        report: StepReport,
    },
    NonFinite(StepOutcome),
}

/// One shard's forward and backward.
enum Shard {
    Ready(GradientsParams, LossValues),
    NonFinite(StepOutcome),
}

impl Trainer {
    /// Forward and backward of one shard on `device`; its loss is divided by `n`, the
    /// number of shards.
    fn shard(&self, batch: &Batch, device: &Device, n: f64, step: u64) -> Result<Shard> {
        let model: Envision4d = self.model.clone().fork(device);
        let terms = match self.loss_with(&model, batch, step) {
            Err(TrainError::NonFinite(_)) => {
                return Ok(Shard::NonFinite(StepOutcome::SkippedNonFiniteLoss))
            }
            other => other?,
        };
        let v = terms.values();
        if !v.total.is_finite() {
            return Ok(Shard::NonFinite(StepOutcome::SkippedNonFiniteLoss));
        }
        let mut grads = (terms.total / n).backward();
        if !grads_finite(&model, &grads) {
            return Ok(Shard::NonFinite(StepOutcome::SkippedNonFiniteGradient));
        }
        let gp = GradientsParams::from_params(&mut grads, &model, &self.split.trainable);
        Ok(Shard::Ready(gp, v))
    }

    /// Forward and backward of every shard (shard k on `devices[k]`, each on its own host
    /// thread so that devices work at the same time), then the gradients combined by
    /// `reduce` on the first device. Each shard's loss is divided by the number of shards,
    /// so with equal shards the sum is the gradient of the whole batch's loss.
    pub fn parallel_gradients(
        &mut self,
        shards: &[Batch],
        devices: &[Device],
        step: u64,
        reduce: GradientReduce,
    ) -> Result<ParallelGradients> {
        if shards.is_empty() || shards.len() != devices.len() {
            return Err(TrainError::Internal(format!(
                "{} shards for {} devices",
                shards.len(),
                devices.len()
            )));
        }
        self.prepare_devices(devices)?;
        let n = shards.len() as f64;
        let this = &*self;
        let outs = std::thread::scope(|s| {
            let handles: Vec<_> = shards
                .iter()
                .zip(devices)
                .map(|(batch, device)| s.spawn(move || this.shard(batch, device, n, step)))
                .collect();
            // Every thread is joined first (a scope with an unjoined panicked thread panics
            // itself); then the first failing shard, in device order, is the one reported.
            let joined: Vec<_> = handles.into_iter().map(|h| h.join()).collect();
            joined
                .into_iter()
                .map(|r| {
                    r.map_err(|p| reduce::panic_error("shard", p))
                        .and_then(|r| r)
                })
                .collect::<Result<Vec<_>>>()
        })?;
        let mut grads = Vec::with_capacity(outs.len());
        let mut vals = Vec::with_capacity(outs.len());
        for out in outs {
            match out {
                // One bad shard skips the whole step.
                Shard::NonFinite(outcome) => return Ok(ParallelGradients::NonFinite(outcome)),
                Shard::Ready(g, v) => {
                    grads.push(g);
                    vals.push(v);
                }
            }
        }
        let grads = reduce::combine(reduce, &self.model, grads, devices)?;
        let mean = |f: fn(&LossValues) -> f64| vals.iter().map(f).sum::<f64>() / n;
        let psnr = vals
            .iter()
            .all(|v| v.mse.is_some())
            .then(|| psnr_from_mse(mean(|v| v.mse.unwrap_or(f64::NAN))));
        Ok(ParallelGradients::Ready {
            grads,
            report: StepReport {
                step,
                total: mean(|v| v.total),
                rgb: mean(|v| v.rgb),
                camera: mean(|v| v.camera),
                depth: mean(|v| v.depth),
                psnr,
                flow: vals
                    .iter()
                    .all(|v| v.flow.is_some())
                    .then(|| mean(|v| v.flow.unwrap_or(f64::NAN))),
                grad_norms: None,
                lr: self.schedule.learning_rate(step),
                phase: self.schedule.phase(step),
                outcome: StepOutcome::Applied,
            },
        })
    }

    /// One data-parallel step: [`Trainer::parallel_gradients`], then one Adam step on the
    /// first device. One bad shard skips the whole step: a partial update would weight the
    /// remaining shards differently from every other step.
    pub fn train_step_parallel(
        &mut self,
        shards: &[Batch],
        devices: &[Device],
        reduce: GradientReduce,
    ) -> Result<StepReport> {
        let step = self.step;
        let lr = self.schedule.learning_rate(step);
        let result = self.parallel_gradients(shards, devices, step, reduce)?;
        self.step += 1;
        match result {
            ParallelGradients::NonFinite(outcome) => {
                self.skipped += 1;
                self.consecutive_nonfinite += 1;
                Ok(StepReport::skipped(
                    step,
                    lr,
                    self.schedule.phase(step),
                    outcome,
                ))
            }
            ParallelGradients::Ready { grads, mut report } => {
                (report.outcome, report.grad_norms) = self.apply(lr, grads);
                Ok(report)
            }
        }
    }
}
