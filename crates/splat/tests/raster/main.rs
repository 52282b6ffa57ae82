//! Rasterizer tests: f64 oracle vs f32, finite-difference gradients (camera included), edge
//! scenes from the design spec, invariances, and the Burn tensor API with autodiff.

mod burn_api;
mod common;
mod device_sort;
mod edge;
mod gradients;
mod oracle;
mod plane_fallback;
mod stacked;
mod wgpu_parity;
mod wgpu_pipeline;
