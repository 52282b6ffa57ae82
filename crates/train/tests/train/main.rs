//! Integration tests of envision4d-train (kept small: CI has 2 cores).

mod common;
mod config;
mod schedule;
mod step;
