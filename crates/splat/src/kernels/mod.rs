//! CubeCL kernels of the GPU rasterizer (run by `backend::cube` for every CubeCL runtime).
//!
//! Pipeline per view (each view its own Gaussians or all views the same ones, see
//! [`crate::views`]), all on the device: `project_forward` (thread per Gaussian) → tile
//! binning (`bin_tiles`, driven by `binning`: depth keys → stable radix sort → tile counts →
//! exclusive scan, for every view; one readback of all views' intersection totals → (tile,
//! Gaussian) pairs →
//! stable radix sort by tile → CSR tile ranges; exactly the order of
//! [`crate::cpu::bins::bin_tiles`]) → `rasterize_forward` (cube per 16x16 tile, thread per
//! pixel, records in shared-memory batches; `rasterize_forward_per_pixel` without them, for
//! a software adapter, see [`crate::config::TileSchedule`]); radii and counts by
//! `view_meta`. Backward: the forward's projection, tile lists and per-pixel ends (final
//! transmittance, last composited item) where it kept them ([`crate::config::BackwardBins`],
//! `kept`), else the same projection, binning and compositing again (for the ends); then
//! `rasterize_backward` or `rasterize_backward_per_pixel` (each splat's gradient from
//! `splat_grad`, added atomically into per-Gaussian lanes, per pixel or summed over a plane
//! first: [`crate::config::GradCombine`]) and `project_backward` (thread per Gaussian, camera
//! partials reduced with Burn ops). The sort and scan (`radix_sort`, `scan`,
//! host side `sort`) are general and also exposed as tensor functions
//! ([`crate::primitives`]).
//!
//! The `#[cube]` modules import `cubecl::prelude::*` and never Burn's `Tensor` (the names
//! clash); the host side lives in [`launch`].

pub mod bin_tiles;
pub mod binning;
pub mod buffers;
pub mod camera_grad;
pub mod geometry;
pub mod kept;
pub mod launch;
pub mod launch_backward;
pub mod math;
pub mod plan;
pub mod plane_probe;
pub mod project_backward;
pub mod project_forward;
pub mod radix_sort;
pub mod rasterize_backward;
pub mod rasterize_backward_per_pixel;
pub mod rasterize_forward;
pub mod rasterize_forward_per_pixel;
pub mod readback;
pub mod scan;
pub mod sort;
pub mod splat_grad;
pub mod strides;
pub mod view_meta;
