//! Integration tests of `envision4d-losses` (one binary, so the crate links once).

mod camera;
mod common;
mod depth;
mod edge;
mod gradients;
mod lpips;
mod parity;
mod properties;
mod ssim_loss;
