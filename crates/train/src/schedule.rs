//! The progressive training schedule (paper §3.4) as pure functions of the step:
//! geometric warm-up, α annealing, extrapolation frame weights, and the cosine learning rate.

use crate::config::{AnnealOrigin, LrSchedule, Switch, TrainConfig};
use envision4d_model::adapter::Exclusion;

/// Which rendering regime a step is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Context frames only, each rendered from all context Gaussians incl. its own, unmoved.
    Warmup,
    /// All N frames, self-exclusive, motion applied, progressively weighted.
    Progressive,
    /// The backbone stage: supervised on ground truth, no rendering.
    Supervised,
}

/// What one Envision4D-stage step renders and how it weighs it (paper §3.4).
#[derive(Debug, Clone, PartialEq)]
pub struct PhasePlan {
    pub phase: Phase,
    /// Frames rendered and compared with the truth.
    pub targets: Vec<usize>,
    /// Whether a target's own Gaussians take part.
    pub exclusion: Exclusion,
    /// `w̄_t` of each target, in the order of `targets`.
    pub weights: Vec<f64>,
    /// Whether the Gaussians move with the predicted motion.
    pub motion: bool,
}

/// Everything the schedule needs, copied out of a [`TrainConfig`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Schedule {
    /// 0 when the warm-up ablation switch is off.
    pub warmup_iterations: u64,
    pub s_max: u64,
    pub alpha0: f64,
    pub origin: AnnealOrigin,
    pub weighting: Switch,
    pub lr: f64,
    pub min_lr: f64,
    pub lr_schedule: LrSchedule,
    pub iterations: u64,
}

impl Schedule {
    pub fn from_config(cfg: &TrainConfig) -> Self {
        Schedule {
            warmup_iterations: match cfg.ablation.warmup {
                Switch::On => cfg.progressive.warmup_iterations,
                Switch::Off => 0,
            },
            s_max: cfg.progressive.s_max,
            alpha0: cfg.progressive.alpha0,
            origin: cfg.progressive.anneal_origin,
            weighting: cfg.ablation.progressive_weighting,
            lr: cfg.optim.lr,
            min_lr: cfg.optim.min_lr,
            lr_schedule: cfg.optim.schedule,
            iterations: cfg.optim.iterations,
        }
    }

    /// Steps are 0-based: steps `0..warmup_iterations` are warm-up.
    pub fn phase(&self, step: u64) -> Phase {
        if step < self.warmup_iterations {
            Phase::Warmup
        } else {
            Phase::Progressive
        }
    }

    /// The plan of step `step` for `context` of `frames` frames.
    ///
    /// Geometric warm-up is static ("static geometry and pose optimization"): every context
    /// frame is rendered from all context Gaussians, its own included, none moved. Letting
    /// the untrained motion move the other frames' Gaussians here taught the motion head to
    /// push them out of view, and the first self-exclusive renders came out empty. After
    /// it, all `N` frames are rendered self-exclusively with motion, progressively weighted.
    pub fn plan(&self, step: u64, context: usize, frames: usize) -> PhasePlan {
        match self.phase(step) {
            Phase::Warmup => PhasePlan {
                phase: Phase::Warmup,
                targets: (0..context).collect(),
                exclusion: Exclusion::IncludeOwn,
                weights: vec![1.0; context],
                motion: false,
            },
            phase @ (Phase::Progressive | Phase::Supervised) => PhasePlan {
                phase,
                targets: (0..frames).collect(),
                exclusion: Exclusion::SelfExclusive,
                weights: self.frame_weights(step, context, frames),
                motion: true,
            },
        }
    }

    /// `α(s) = α₀·max(0, 1 − s'/S_max)`, with `s'` counted from step 0 or from the end of
    /// the warm-up ([`AnnealOrigin`]); during warm-up under `AfterWarmup`, `s' = 0`.
    pub fn alpha(&self, step: u64) -> f64 {
        let s_prime = match self.origin {
            AnnealOrigin::AfterWarmup => step.saturating_sub(self.warmup_iterations),
            AnnealOrigin::StepZero => step,
        };
        self.alpha0 * (1.0 - s_prime as f64 / self.s_max as f64).max(0.0)
    }

    /// Normalised weights `w̄_t` of all N frames at `step` (all 1 when weighting is off).
    pub fn frame_weights(&self, step: u64, context: usize, frames: usize) -> Vec<f64> {
        match self.weighting {
            Switch::On => frame_weights(self.alpha(step), context, frames),
            Switch::Off => vec![1.0; frames],
        }
    }

    /// The learning rate of `step`: half-cosine from `lr` (step 0) to `min_lr` (step =
    /// iterations), or constant.
    pub fn learning_rate(&self, step: u64) -> f64 {
        match self.lr_schedule {
            LrSchedule::Constant => self.lr,
            LrSchedule::Cosine => {
                let progress = (step as f64 / self.iterations as f64).min(1.0);
                self.min_lr
                    + 0.5
                        * (self.lr - self.min_lr)
                        * (1.0 + (std::f64::consts::PI * progress).cos())
            }
        }
    }
}

/// `w_t = exp(−α·max(0, t − T_c + 1))` for 0-based `t ∈ 0..frames` (context frames get 1,
/// future frame m (1-based) gets `e^{−α m}`), renormalised so the mean is 1:
/// `w̄_t = N·w_t / Σ w`.
pub fn frame_weights(alpha: f64, context: usize, frames: usize) -> Vec<f64> {
    let raw: Vec<f64> = (0..frames)
        .map(|t| {
            let ahead = (t + 1).saturating_sub(context) as f64;
            (-alpha * ahead).exp()
        })
        .collect();
    let sum: f64 = raw.iter().sum();
    raw.iter().map(|w| w * frames as f64 / sum).collect()
}
