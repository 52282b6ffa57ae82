//! `envision4d-train`: training of Envision4D (paper §3.4, issue 6).
//!
//! - [`config`]: the TOML training configuration (every paper hyper-parameter).
//! - [`schedule`]: the progressive schedule (warm-up, α annealing, frame weights, cosine lr).
//! - [`freeze`]: frozen parameter groups and parameter counts.
//! - [`batch`]: training batches and ground-truth teacher targets.
//! - [`step`]: the stage-`envision4d` training step (self-exclusive rendering, losses, Adam).

pub mod batch;
pub mod config;
pub mod error;
pub mod freeze;
pub mod load;
pub mod schedule;
pub mod step;

pub use config::TrainConfig;
pub use error::{Result, TrainError};
pub use load::{load, parse};
pub use schedule::{frame_weights, Phase, Schedule};
pub use step::{StepOutcome, StepReport, Trainer};
