//! Front-to-back compositing without shared memory
//! ([`crate::config::TileSchedule::PerPixel`]): one cube per tile, one unit per pixel, each
//! unit reading its tile's records from global memory and stopping on its own, with no
//! barrier.
//!
//! A software adapter (lavapipe) runs a cube on one CPU thread, in SIMD groups that every
//! barrier suspends and resumes, and its shared memory is ordinary memory: there
//! [`super::rasterize_forward`]'s batches save nothing and its barriers take about as long
//! again as this kernel (docs/PERFORMANCE.md). The evaluation is
//! [`eval_splat()`]: no early reject, whose skips are the same ones (the reject only saves an
//! `exp` whose alpha would fall below `alpha_min`).

use super::project_forward::RECORD_LANES;
use super::rasterize_forward::{eval_splat, tile_pixel, write_ends};
use cubecl::prelude::*;

#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn rasterize_forward_per_pixel(
    records: &Tensor<f32>,
    tile_start: &Tensor<u32>,
    items: &Tensor<u32>,
    out: &mut Tensor<f32>,
    ends: &mut Tensor<u32>,
    width: u32,
    height: u32,
    tiles_x: u32,
    view_offset: u32,
    alpha_min: f32,
    alpha_max: f32,
    t_min: f32,
    #[comptime] keep_ends: bool,
) {
    let pix = tile_pixel(tile_start, width, height, tiles_x, view_offset);
    // Partial edge tiles: units without a pixel have nothing to do and no barrier to meet.
    if !pix.inside {
        terminate!();
    }
    let (px, py) = (pix.px, pix.py);

    let mut t = 1.0f32;
    let mut acc_r = 0.0f32;
    let mut acc_g = 0.0f32;
    let mut acc_b = 0.0f32;
    let mut acc_d = 0.0f32;
    let mut last = pix.start;
    for k in pix.start..pix.end {
        let rec = items[k as usize] as usize * RECORD_LANES;
        let e = eval_splat(records, rec, px, py, alpha_min, alpha_max);
        if !e.skip {
            let next_t = t * (1.0f32 - e.alpha);
            // Exclusive stop, as in the batched kernel.
            if next_t <= t_min {
                break;
            }
            let fac = e.alpha * t;
            acc_r += records[rec + 6] * fac;
            acc_g += records[rec + 7] * fac;
            acc_b += records[rec + 8] * fac;
            acc_d += records[rec + 9] * fac;
            t = next_t;
            last = k + 1;
        }
    }
    let o = pix.out;
    out[o] = acc_r;
    out[o + 1] = acc_g;
    out[o + 2] = acc_b;
    out[o + 3] = acc_d;
    out[o + 4] = 1.0f32 - t;
    if keep_ends {
        write_ends(ends, pix.pixel, t, last);
    }
}
