//! CubeCL kernels of the GPU rasterizer (run by `backend::cube` for every CubeCL runtime).
//!
//! Pipeline per view: `project_forward` (thread per Gaussian) → host binning (read back the
//! packed records and tile rects, sort by (depth, index) and build the CSR tile lists with
//! [`crate::cpu::bins::bin_tiles`], exactly the CPU order) → `rasterize_forward` (cube per
//! 16x16 tile, thread per pixel). Backward: the same projection and binning, then
//! `rasterize_backward` (atomics into per-Gaussian lanes) and `project_backward`
//! (thread per Gaussian, camera partials reduced with Burn ops).
//!
//! Moving the depth sort and the tile binning onto the GPU (radix sort of (tile, depth) keys)
//! is a later optimisation; the host round trip is what limits large scenes today.
//!
//! The `#[cube]` modules import `cubecl::prelude::*` and never Burn's `Tensor` (the names
//! clash); the host side lives in [`launch`].

pub mod geometry;
pub mod launch;
pub mod math;
pub mod project_backward;
pub mod project_forward;
pub mod rasterize_backward;
pub mod rasterize_forward;
