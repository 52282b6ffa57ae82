//! Integration tests of `envision4d-losses` (one binary, so the crate links once).

mod camera;
mod common;
mod depth;
mod edge;
mod gradients;
mod lpips;
mod parity;
#[path = "../../../../tests/support/paths.rs"]
mod paths;
mod properties;
mod ssim_loss;
