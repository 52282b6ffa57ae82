//! `envision4d-train`: training of Envision4D (paper §3.4).
//!
//! - [`config`] / [`load`]: the TOML training configuration (every paper hyper-parameter).
//! - [`schedule`]: the progressive schedule as a [`PhasePlan`] per step (warm-up, α
//!   annealing, frame weights) and the cosine learning rate.
//! - [`step`]: the training step of either stage: `L_rgb` of the plan's renders through the
//!   model's scene path, plus [`distill`]ation, then Adam; [`backbone`]: the backbone stage's
//!   supervised loss; [`report`]: what a step reports; [`grad_clip`]: global-norm gradient
//!   clipping; [`freeze`]: the frozen parameter groups.
//! - [`distill`]: self-distillation: label source, the frozen teacher, `L_cam` and `L_depth`.
//! - [`batch`]: training batches and their ground-truth labels; [`dataset`]: the config's
//!   dataset and splits; [`augment`]: playback augmentation of training windows.
//! - [`run`]: the run loop (prefetch, log, validation, checkpoints, resume, NaN guard),
//!   [`log`], [`checkpoint`], [`validate`] (scored with `envision4d-eval`).
pub mod adam;
pub mod augment;
pub mod backbone;
pub mod batch;
pub mod checkpoint;
pub mod config;
pub mod dataset;
pub mod distill;
pub mod error;
pub mod finite;
pub mod freeze;
pub mod grad_clip;
pub mod init;
pub mod load;
pub mod log;
pub mod memory;
pub mod motion_signal;
pub mod parallel;
pub mod report;
pub mod run;
pub mod schedule;
mod setup;
pub mod step;
pub mod validate;

pub use config::TrainConfig;
pub use error::{Result, TrainError};
pub use load::{load, parse};
pub use schedule::{frame_weights, Phase, PhasePlan, Schedule};
pub use step::{StepOutcome, StepReport, Trainer};
