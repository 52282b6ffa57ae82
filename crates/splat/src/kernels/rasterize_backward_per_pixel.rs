//! Backward of the compositing without shared memory ([`crate::config::TileSchedule::PerPixel`]):
//! the same reverse pass per pixel as [`super::rasterize_backward`], from where the forward
//! stopped (`ends`), each unit reading its records from global memory, with no barrier.
//!
//! A software adapter (lavapipe) runs a cube on one CPU thread, in SIMD groups that every
//! barrier suspends and resumes, and its shared memory is ordinary memory: there the batched
//! kernel takes about twice this one's time (docs/PERFORMANCE.md). The per-splat gradient is
//! [`reverse_step()`], shared with the batched kernel; the skip decisions are
//! [`eval_splat()`]'s, which decide as the batched early reject does.

use super::project_forward::RECORD_LANES;
use super::rasterize_forward::{eval_splat, tile_pixel};
use super::splat_grad::{reverse_step, shade_of_record, Behind, GradAdd, Upstream};
use cubecl::prelude::*;

#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn rasterize_backward_per_pixel<A: GradAdd>(
    records: &Tensor<f32>,
    tile_start: &Tensor<u32>,
    items: &Tensor<u32>,
    grad_image: &Tensor<f32>,
    ends: &Tensor<u32>,
    v_proj: &mut Tensor<Atomic<A::Proxy>>,
    width: u32,
    height: u32,
    tiles_x: u32,
    view_offset: u32,
    alpha_min: f32,
    alpha_max: f32,
) {
    let pix = tile_pixel(tile_start, width, height, tiles_x, view_offset);
    // Partial edge tiles: units without a pixel have nothing to do and no barrier to meet.
    if !pix.inside {
        terminate!();
    }
    let o = pix.out;
    let (g_r, g_g, g_b, g_d, g_a) = (
        grad_image[o],
        grad_image[o + 1],
        grad_image[o + 2],
        grad_image[o + 3],
        grad_image[o + 4],
    );
    // A pixel with zero upstream gradient contributes nothing (the CPU skips it too).
    if g_r == 0.0f32 && g_g == 0.0f32 && g_b == 0.0f32 && g_d == 0.0f32 && g_a == 0.0f32 {
        terminate!();
    }
    let (start, px, py) = (pix.start, pix.px, pix.py);

    // Pass 1 is the forward's: the final transmittance and one past the last composited
    // item, as the compositing left them (`ends`).
    let t = f32::from_bits(ends[2 * pix.pixel]);
    let last = ends[2 * pix.pixel + 1];

    // Pass 2: back to front from `last`; every non-skipped item before it was composited.
    let up = Upstream {
        r: g_r,
        g: g_g,
        b: g_b,
        d: g_d,
        a: g_a,
        t_final: t,
    };
    let mut state = Behind::new(t);
    let mut k = last;
    while k > start {
        k -= 1;
        let id = items[k as usize] as usize;
        let rec = id * RECORD_LANES;
        let e = eval_splat(records, rec, px, py, alpha_min, alpha_max);
        if !e.skip {
            let shade = shade_of_record(records, rec);
            reverse_step::<A>(v_proj, id, e, shade, up, &mut state, alpha_max);
        }
    }
}
