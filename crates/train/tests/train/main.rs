//! Integration tests of envision4d-train (kept small: CI has 2 cores).

mod common;
mod config;
mod run;
mod eval;
mod schedule;
mod step;
