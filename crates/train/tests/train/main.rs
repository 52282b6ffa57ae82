//! Integration tests of envision4d-train (kept small: CI has 2 cores).

mod augment;
mod common;
mod config;
mod eval;
mod pose;
mod run;
mod schedule;
mod step;
