//! What a training step reports: its loss terms on the device ([`LossTerms`]), their host
//! values read in one round trip, and the finished step's [`StepReport`] and [`StepOutcome`].

use crate::grad_clip::GradNorms;
use crate::schedule::Phase;
use burn::tensor::Tensor;
use envision4d_model::host_read;

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
    /// The flow diagnostic's term before λ (`[loss] lambda_flow`; `None` when off).
    pub flow: Option<Tensor<1>>,
    pub phase: Phase,
}

/// Host values of a step's loss terms (0 for a term the step does not have).
#[derive(Debug, Clone, Copy)]
pub(crate) struct LossValues {
    pub total: f64,
    pub rgb: f64,
    pub camera: f64,
    pub depth: f64,
    pub mse: Option<f64>,
    pub flow: Option<f64>,
}

impl LossTerms {
    /// Every term's value, read back in one round trip (a log line needs them all).
    pub(crate) fn values(&self) -> LossValues {
        let zero = || Tensor::<1>::zeros([1], &self.total.device());
        let one = |t: &Tensor<1>| t.clone().reshape([1]);
        let v = host_read::read_all(vec![
            one(&self.total),
            one(&self.rgb),
            self.camera.as_ref().map_or_else(zero, one),
            self.depth.as_ref().map_or_else(zero, one),
            self.rgb_mse.as_ref().map_or_else(zero, one),
            self.flow.as_ref().map_or_else(zero, one),
        ]);
        LossValues {
            total: v[0],
            rgb: v[1],
            camera: v[2],
            depth: v[3],
            mse: self.rgb_mse.as_ref().map(|_| v[4]),
            flow: self.flow.as_ref().map(|_| v[5]),
        }
    }
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
    /// The flow diagnostic's term (`[loss] lambda_flow`), when on and the step has motion.
    pub flow: Option<f64>,
    /// The gradient norms before clipping, per module group (measured on the steps the log
    /// keeps and whenever global-norm clipping needs them; `None` otherwise).
    pub grad_norms: Option<GradNorms>,
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
            flow: None,
            grad_norms: None,
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
