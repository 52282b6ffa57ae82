//! Front-to-back compositing of one view: one cube per 16x16 tile, one thread per pixel
//! (`raster_tile_forward` / `composite_pixel` in `cpu/raster.rs`).
//!
//! Each thread walks its tile's CSR list `items[tile_start[t] .. tile_start[t+1]]` (Gaussian
//! indices, front to back) and reads the packed records directly from global memory.
//! Shared-memory batching of records is a later optimisation.

use super::project_forward::RECORD_LANES;
use cubecl::prelude::*;

/// Tile side in pixels ([`crate::config::TILE_SIZE`]); the cube is TILE x TILE threads.
pub const TILE: u32 = crate::config::TILE_SIZE;
/// Channels written per pixel: R, G, B, accumulated depth, alpha (the CPU path's layout).
pub const OUT_CHANNELS: usize = crate::cpu::raster::OUT_CHANNELS;

/// The per-splat evaluation of `Splat::eval`: `(dx, dy, vis, alpha, skip)`.
#[derive(CubeType, Clone, Copy)]
#[expand(derive(Clone, Copy))]
pub struct Eval {
    pub dx: f32,
    pub dy: f32,
    pub vis: f32,
    pub alpha: f32,
    pub skip: bool,
}

/// Evaluates record `rec` at pixel centre `(px, py)`; forward and backward both call this, so
/// their skip decisions cannot diverge.
#[cube]
pub fn eval_splat(
    records: &Tensor<f32>,
    rec: usize,
    px: f32,
    py: f32,
    alpha_min: f32,
    alpha_max: f32,
) -> Eval {
    let dx = records[rec] - px;
    let dy = records[rec + 1] - py;
    let sigma = 0.5f32 * (records[rec + 2] * dx * dx + records[rec + 4] * dy * dy)
        + records[rec + 3] * dx * dy;
    let vis = f32::exp(0.0f32 - sigma);
    let alpha = alpha_max.min(records[rec + 5] * vis);
    Eval {
        dx,
        dy,
        vis,
        alpha,
        skip: sigma < 0.0f32 || alpha < alpha_min,
    }
}

#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn rasterize_forward(
    records: &Tensor<f32>,
    tile_start: &Tensor<u32>,
    items: &Tensor<u32>,
    out: &mut Tensor<f32>,
    width: u32,
    height: u32,
    tiles_x: u32,
    view_offset: u32,
    alpha_min: f32,
    alpha_max: f32,
    t_min: f32,
) {
    let x = CUBE_POS_X * TILE + UNIT_POS_X;
    let y = CUBE_POS_Y * TILE + UNIT_POS_Y;
    // Partial tiles at the right/bottom edge: those threads have no pixel.
    if x >= width || y >= height {
        terminate!();
    }
    let tile = (CUBE_POS_Y * tiles_x + CUBE_POS_X) as usize;
    let start = tile_start[tile];
    let end = tile_start[tile + 1];
    let px = f32::cast_from(x) + 0.5f32;
    let py = f32::cast_from(y) + 0.5f32;

    let mut t = 1.0f32;
    let mut acc_r = 0.0f32;
    let mut acc_g = 0.0f32;
    let mut acc_b = 0.0f32;
    let mut acc_d = 0.0f32;
    for k in start..end {
        let rec = items[k as usize] as usize * RECORD_LANES;
        let e = eval_splat(records, rec, px, py, alpha_min, alpha_max);
        if !e.skip {
            let next_t = t * (1.0f32 - e.alpha);
            // Exclusive stop: the splat that would drive T to the threshold is not composited.
            if next_t <= t_min {
                break;
            }
            let fac = e.alpha * t;
            acc_r += records[rec + 6] * fac;
            acc_g += records[rec + 7] * fac;
            acc_b += records[rec + 8] * fac;
            acc_d += records[rec + 9] * fac;
            t = next_t;
        }
    }
    let o = view_offset as usize + ((y * width + x) as usize) * OUT_CHANNELS;
    out[o] = acc_r;
    out[o + 1] = acc_g;
    out[o + 2] = acc_b;
    out[o + 3] = acc_d;
    out[o + 4] = 1.0f32 - t;
}
