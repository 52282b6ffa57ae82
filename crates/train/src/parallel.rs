//! Data-parallel training on several devices with Burn's own multi-device pieces: the model
//! is forked onto each device (`Module::fork`), each device runs its shard of the batch
//! forward and backward, the gradients are moved to the first device
//! (`GradientsParams::to_device`), summed (`GradientsAccumulator`) and applied once. No
//! communication code of ours: Burn moves the tensors.

use crate::batch::Batch;
use crate::error::{Result, TrainError};
use crate::freeze::grads_finite;
use crate::step::{scalar, LossTerms, StepOutcome, StepReport, Trainer};
use burn::module::Module;
use burn::optim::{GradientsAccumulator, GradientsParams};
use burn::tensor::Device;
use envision4d_model::Envision4d;

/// Host values of one shard's loss terms.
struct ShardValues {
    total: f64,
    rgb: f64,
    camera: f64,
    depth: f64,
    mse: Option<f64>,
}

fn values(t: &LossTerms) -> ShardValues {
    ShardValues {
        total: scalar(&t.total),
        rgb: scalar(&t.rgb),
        camera: t.camera.as_ref().map_or(0.0, scalar),
        depth: t.depth.as_ref().map_or(0.0, scalar),
        mse: t.rgb_mse.as_ref().map(scalar),
    }
}

enum Shard {
    Done(ShardValues, GradientsParams),
    NonFinite(StepOutcome),
}

impl Trainer {
    /// One step over `shards` (shard k on `devices[k]`, each with its share of the batch).
    /// Each shard's loss is divided by the number of shards, so with equal shards the update
    /// equals a single-device step on the whole batch.
    pub fn train_step_parallel(&mut self, shards: &[Batch], devices: &[Device]) -> Result<StepReport> {
        if shards.is_empty() || shards.len() != devices.len() {
            return Err(TrainError::Batch(format!(
                "{} shards for {} devices",
                shards.len(),
                devices.len()
            )));
        }
        let step = self.step;
        let lr = self.schedule.learning_rate(step);
        let main = devices[0].clone();
        let n = shards.len() as f64;
        let mut outs = Vec::with_capacity(shards.len());
        for (batch, device) in shards.iter().zip(devices) {
            let model: Envision4d = self.model.clone().fork(device);
            let shard = match self.loss_with(&model, batch, step) {
                Err(TrainError::NonFinite(_)) => Shard::NonFinite(StepOutcome::SkippedNonFiniteLoss),
                Err(e) => return Err(e),
                Ok(terms) => {
                    let v = values(&terms);
                    if !v.total.is_finite() {
                        Shard::NonFinite(StepOutcome::SkippedNonFiniteLoss)
                    } else {
                        let mut grads = (terms.total / n).backward();
                        if !grads_finite(&model, &grads) {
                            Shard::NonFinite(StepOutcome::SkippedNonFiniteGradient)
                        } else {
                            let gp = GradientsParams::from_params(&mut grads, &model, &self.split.trainable)
                                .to_device(&main, &self.model);
                            Shard::Done(v, gp)
                        }
                    }
                }
            };
            outs.push(shard);
        }
        self.step += 1;
        let phase = self.schedule.phase(step);
        let mut report = StepReport {
            step,
            total: f64::NAN,
            rgb: f64::NAN,
            camera: f64::NAN,
            depth: f64::NAN,
            psnr: None,
            lr,
            phase,
            outcome: StepOutcome::Applied,
        };
        let mut acc = GradientsAccumulator::<Envision4d>::new();
        let mut vals = vec![];
        for o in outs {
            match o {
                Shard::NonFinite(outcome) => {
                    // One bad shard skips the whole step: a partial update would weight the
                    // remaining shards differently from every other step.
                    self.skipped += 1;
                    self.consecutive_nonfinite += 1;
                    report.outcome = outcome;
                    return Ok(report);
                }
                Shard::Done(v, gp) => {
                    acc.accumulate(&self.model, gp);
                    vals.push(v);
                }
            }
        }
        let mean = |f: fn(&ShardValues) -> f64| vals.iter().map(f).sum::<f64>() / n;
        report.total = mean(|v| v.total);
        report.rgb = mean(|v| v.rgb);
        report.camera = mean(|v| v.camera);
        report.depth = mean(|v| v.depth);
        if vals.iter().all(|v| v.mse.is_some()) {
            report.psnr = Some(-10.0 * mean(|v| v.mse.unwrap_or(f64::NAN)).log10());
        }
        self.model = self.optim.step(lr, self.model.clone(), acc.grads());
        self.consecutive_nonfinite = 0;
        Ok(report)
    }
}
