//! `envision4d-train`: training of Envision4D (paper §3.4, issue 6).
//!
//! - [`config`]: the TOML training configuration (every paper hyper-parameter).
//! - [`schedule`]: the progressive schedule (warm-up, α annealing, frame weights, cosine lr).
//! - [`freeze`]: frozen parameter groups and parameter counts.
//! - [`batch`]: training batches and ground-truth teacher targets.
//! - [`step`]: the training step of either stage (self-exclusive rendering, losses, Adam).
//! - [`backbone`]: the backbone stage's supervised loss and the frozen teacher.
//! - [`infer`]: forward + safe cameras + adapted Gaussians, shared with eval and render.
//! - [`data`]: datasets and splits of a config, clips as host buffers; [`augment`]: playback
//!   augmentation of training windows.
//! - [`run`]: the run loop (log, validation, checkpoints, resume, NaN guard), [`log`],
//!   [`checkpoint`], [`validate`].

pub mod augment;
pub mod backbone;
pub mod batch;
pub mod checkpoint;
pub mod clip;
pub mod config;
pub mod data;
pub mod error;
pub mod eval;
pub mod freeze;
pub mod infer;
pub mod init;
pub mod load;
pub mod log;
pub mod parallel;
pub mod run;
pub mod schedule;
pub mod step;
pub mod validate;

pub use config::TrainConfig;
pub use error::{Result, TrainError};
pub use load::{load, parse};
pub use schedule::{frame_weights, Phase, Schedule};
pub use step::{StepOutcome, StepReport, Trainer};
