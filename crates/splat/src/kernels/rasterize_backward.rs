//! Backward of the compositing (`raster_tile_backward` in `cpu/raster.rs`): one cube per tile,
//! one unit per pixel, gradients accumulated atomically into `v_proj [N, RECORD_LANES]`.
//!
//! Per pixel: the forward left the final transmittance and the end of the composited range
//! (`ends`, see [`super::rasterize_forward::write_ends()`]); a reverse pass walks back from
//! there to the tile start, recovering each splat's transmittance as `T / (1 - alpha)`
//! (gsplat's order; the CPU records T forward instead, which is the same quantity) and
//! accumulating what lies `behind` per channel. It reads the records in shared-memory
//! batches as the forward kernel does, from the furthest end any pixel of the tile reached.
//! Units without a pixel or without an upstream gradient take part in the loads and add
//! nothing.
//! [`super::rasterize_backward_per_pixel`] is the same without shared memory, for a software
//! adapter ([`crate::config::TileSchedule`]). Both compute a splat's gradient with
//! [`super::splat_grad::splat_grad()`]; with `plane_sums` the units of a plane sum theirs
//! before one atomic add per lane ([`crate::config::GradCombine`]).

use super::rasterize_forward::{
    eval_batched, load_batch, tile_pixel, BATCH, BATCH_SHARED, SHARED_LANES,
};
use super::splat_grad::{plane_step, reverse_step, shade_of_batch, Behind, GradAdd, Upstream};
use cubecl::prelude::*;

#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn rasterize_backward<A: GradAdd>(
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
    #[comptime] plane_sums: bool,
    #[comptime] plane_sync: bool,
) {
    let pix = tile_pixel(tile_start, width, height, tiles_x, view_offset);
    let unit = UNIT_POS as usize;
    let inside = pix.inside;
    let mut g_r = 0.0f32;
    let mut g_g = 0.0f32;
    let mut g_b = 0.0f32;
    let mut g_d = 0.0f32;
    let mut g_a = 0.0f32;
    if inside {
        let o = pix.out;
        g_r = grad_image[o];
        g_g = grad_image[o + 1];
        g_b = grad_image[o + 2];
        g_d = grad_image[o + 3];
        g_a = grad_image[o + 4];
    }
    // A pixel with zero upstream gradient contributes nothing (the CPU skips it too).
    let active = inside
        && !(g_r == 0.0f32 && g_g == 0.0f32 && g_b == 0.0f32 && g_d == 0.0f32 && g_a == 0.0f32);
    let (start, px, py) = (pix.start, pix.px, pix.py);

    let mut batch = Shared::<[f32]>::new_slice(BATCH_SHARED);
    let mut ids = Shared::<[u32]>::new_slice(BATCH as usize);
    let furthest = Shared::<[Atomic<u32>]>::new_slice(1usize);
    if unit == 0 {
        furthest[0].store(start);
    }
    sync_cube();

    // Pass 1 is the forward's: the pixel's final transmittance and one past its last
    // composited item, as the compositing left them (`ends`).
    let mut t = 1.0f32;
    let mut last = start;
    if active {
        t = f32::from_bits(ends[2 * pix.pixel]);
        last = ends[2 * pix.pixel + 1];
    }
    let t_final = t;
    if active {
        furthest[0].fetch_max(last);
    }
    let reach = workgroup_uniform_load_atomic(&furthest[0]);

    // Pass 2: back to front from the furthest end. Every non-skipped item in [start, last)
    // of this pixel was composited.
    let up = Upstream {
        r: g_r,
        g: g_g,
        b: g_b,
        d: g_d,
        a: g_a,
        t_final,
    };
    let mut state = Behind::new(t_final);
    let mut top = reach;
    while top > start {
        let mut first = start;
        if top - start > BATCH {
            first = top - BATCH;
        }
        load_batch(
            records, items, &mut batch, &mut ids, first, top, unit, alpha_min,
        );
        sync_cube();
        let count = top - first;
        if plane_sums {
            // Every unit walks the batch (the plane sums need them all); those whose pixel
            // did not composite a splat add zero to its sums.
            for j in 0..count {
                let k = top - 1 - j;
                let s = (k - first) as usize * SHARED_LANES;
                let e = eval_batched(&batch, s, px, py, alpha_min, alpha_max);
                let composited = active && k < last && !e.skip;
                let id = ids[(k - first) as usize] as usize;
                let shade = shade_of_batch(&batch, s);
                plane_step::<A>(
                    v_proj, id, composited, e, shade, up, &mut state, alpha_max, plane_sync,
                );
            }
        } else if active {
            for j in 0..count {
                let k = top - 1 - j;
                if k < last {
                    let s = (k - first) as usize * SHARED_LANES;
                    let e = eval_batched(&batch, s, px, py, alpha_min, alpha_max);
                    if !e.skip {
                        let id = ids[(k - first) as usize] as usize;
                        let shade = shade_of_batch(&batch, s);
                        reverse_step::<A>(v_proj, id, e, shade, up, &mut state, alpha_max);
                    }
                }
            }
        }
        // Nobody may still read the batch the next load overwrites.
        sync_cube();
        top = first;
    }
}
