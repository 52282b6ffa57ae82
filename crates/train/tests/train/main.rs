//! Integration tests of envision4d-train (kept small: CI has 2 cores).

mod augment;
mod checkpointing;
mod common;
mod config;
mod eval;
mod grad_norms;
mod memory;
mod motion_signal;
#[path = "../../../../tests/support/paths.rs"]
mod paths;
mod pose;
mod run;
mod schedule;
mod step;
mod wgpu_step;
