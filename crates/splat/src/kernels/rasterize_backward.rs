//! Backward of the compositing (`raster_tile_backward` in `cpu/raster.rs`): one cube per tile,
//! one unit per pixel, gradients accumulated atomically into `v_proj [N, RECORD_LANES]`.
//!
//! Per pixel: a forward pass replays the stop rule to find the final transmittance and the end
//! of the composited range; a reverse pass then walks back to the tile start, recovering each
//! splat's transmittance as `T / (1 - alpha)` (gsplat's order; the CPU records T forward
//! instead, which is the same quantity) and accumulating what lies `behind` per channel.
//! Both passes read the records in shared-memory batches as the forward kernel does; the
//! reverse pass starts at the furthest end any pixel of the tile reached. Units without a
//! pixel or without an upstream gradient take part in the loads and add nothing.
//! Lane order: mean2d (x, y), conic (q00, q01, q11), opacity, colour (r, g, b), depth.

use super::project_forward::RECORD_LANES;
use super::rasterize_forward::{
    eval_batched, load_batch, BATCH, BATCH_SHARED, OUT_CHANNELS, SHARED_LANES, TILE,
};
use cubecl::prelude::*;

/// How a gradient lane is added to the shared buffer: a native float atomic where the device
/// has one, otherwise a compare-and-swap loop on the u32 bit pattern.
#[cube]
pub trait GradAdd: Send + Sync + 'static {
    type Proxy: Numeric;
    fn add(slot: &mut Atomic<Self::Proxy>, value: f32);
}

/// Native `Atomic<f32>::fetch_add`.
#[derive(CubeType)]
pub struct NativeAdd;

/// CAS fallback for devices without float atomics.
#[derive(CubeType)]
pub struct CasAdd;

#[cube]
impl GradAdd for NativeAdd {
    type Proxy = f32;

    fn add(slot: &mut Atomic<f32>, value: f32) {
        slot.fetch_add(value);
    }
}

#[cube]
impl GradAdd for CasAdd {
    type Proxy = u32;

    fn add(slot: &mut Atomic<u32>, value: f32) {
        // Adding zero changes nothing; skipping it saves a round trip.
        if value != 0.0f32 {
            let mut bits = slot.load();
            loop {
                let seen = bits;
                let new = (f32::from_bits(seen) + value).to_bits();
                bits = slot.compare_exchange_weak(seen, new);
                if bits == seen {
                    break;
                }
            }
        }
    }
}

#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn rasterize_backward<A: GradAdd>(
    records: &Tensor<f32>,
    tile_start: &Tensor<u32>,
    items: &Tensor<u32>,
    grad_image: &Tensor<f32>,
    v_proj: &mut Tensor<Atomic<A::Proxy>>,
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
    let unit = (UNIT_POS_Y * TILE + UNIT_POS_X) as usize;
    let inside = x < width && y < height;
    let mut g_r = 0.0f32;
    let mut g_g = 0.0f32;
    let mut g_b = 0.0f32;
    let mut g_d = 0.0f32;
    let mut g_a = 0.0f32;
    if inside {
        let o = view_offset as usize + ((y * width + x) as usize) * OUT_CHANNELS;
        g_r = grad_image[o];
        g_g = grad_image[o + 1];
        g_b = grad_image[o + 2];
        g_d = grad_image[o + 3];
        g_a = grad_image[o + 4];
    }
    // A pixel with zero upstream gradient contributes nothing (the CPU skips it too).
    let active = inside
        && !(g_r == 0.0f32 && g_g == 0.0f32 && g_b == 0.0f32 && g_d == 0.0f32 && g_a == 0.0f32);
    let tile = (CUBE_POS_Y * tiles_x + CUBE_POS_X) as usize;
    let start = tile_start[tile];
    let end = tile_start[tile + 1];
    let px = f32::cast_from(x) + 0.5f32;
    let py = f32::cast_from(y) + 0.5f32;

    let mut batch = Shared::<[f32]>::new_slice(BATCH_SHARED);
    let mut ids = Shared::<[u32]>::new_slice(BATCH as usize);
    let finished = Shared::<[Atomic<u32>]>::new_slice(1usize);
    let furthest = Shared::<[Atomic<u32>]>::new_slice(1usize);
    if unit == 0 {
        finished[0].store(0u32);
        furthest[0].store(start);
    }
    sync_cube();

    // Pass 1: replay the forward to get T_final and one past the last composited item.
    let mut done = !active;
    if done {
        finished[0].fetch_add(1u32);
    }
    let mut t = 1.0f32;
    let mut last = start;
    let mut base = start;
    while base < end {
        load_batch(
            records, items, &mut batch, &mut ids, base, end, unit, alpha_min,
        );
        sync_cube();
        if !done {
            let mut count = end - base;
            if count > BATCH {
                count = BATCH;
            }
            for j in 0..count {
                let e = eval_batched(
                    &batch,
                    j as usize * SHARED_LANES,
                    px,
                    py,
                    alpha_min,
                    alpha_max,
                );
                if !e.skip {
                    let next_t = t * (1.0f32 - e.alpha);
                    if next_t <= t_min {
                        done = true;
                        break;
                    }
                    t = next_t;
                    last = base + j + 1;
                }
            }
            if done {
                finished[0].fetch_add(1u32);
            }
        }
        base += BATCH;
        // As in the forward kernel: on CUDA the uniform load is a barrier then the load, so
        // a write to `finished` must wait for the next `sync_cube` (the batch and `furthest`
        // may be written at once: their readers met the barrier before the load).
        if workgroup_uniform_load_atomic(&finished[0]) == BATCH {
            break;
        }
    }
    let t_final = t;
    if active {
        furthest[0].fetch_max(last);
    }
    let reach = workgroup_uniform_load_atomic(&furthest[0]);

    // Pass 2: back to front from the furthest end. Every non-skipped item in [start, last)
    // of this pixel was composited.
    let mut t_cur = t_final;
    let mut behind_r = 0.0f32;
    let mut behind_g = 0.0f32;
    let mut behind_b = 0.0f32;
    let mut behind_d = 0.0f32;
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
        if active {
            let count = top - first;
            for j in 0..count {
                let k = top - 1 - j;
                if k < last {
                    let s = (k - first) as usize * SHARED_LANES;
                    let e = eval_batched(&batch, s, px, py, alpha_min, alpha_max);
                    if !e.skip {
                        let one_minus = 1.0f32 - e.alpha;
                        let t_i = t_cur / one_minus;
                        let fac = e.alpha * t_i;
                        let lane = ids[(k - first) as usize] as usize * RECORD_LANES;
                        A::add(&mut v_proj[lane + 6], fac * g_r);
                        A::add(&mut v_proj[lane + 7], fac * g_g);
                        A::add(&mut v_proj[lane + 8], fac * g_b);
                        A::add(&mut v_proj[lane + 9], fac * g_d);
                        let (f_r, f_g, f_b, f_d) =
                            (batch[s + 6], batch[s + 7], batch[s + 8], batch[s + 9]);
                        let mut v_alpha = g_a * t_final / one_minus;
                        v_alpha += g_r * (f_r * t_i - behind_r / one_minus);
                        v_alpha += g_g * (f_g * t_i - behind_g / one_minus);
                        v_alpha += g_b * (f_b * t_i - behind_b / one_minus);
                        v_alpha += g_d * (f_d * t_i - behind_d / one_minus);
                        let opacity = batch[s + 5];
                        let (q00, q01, q11) = (batch[s + 2], batch[s + 3], batch[s + 4]);
                        // When the clamp is active alpha no longer depends on opacity or
                        // geometry.
                        if opacity * e.vis <= alpha_max {
                            let v_sigma = (0.0f32 - opacity) * e.vis * v_alpha;
                            A::add(&mut v_proj[lane], v_sigma * (q00 * e.dx + q01 * e.dy));
                            A::add(&mut v_proj[lane + 1], v_sigma * (q01 * e.dx + q11 * e.dy));
                            A::add(&mut v_proj[lane + 2], 0.5f32 * e.dx * e.dx * v_sigma);
                            A::add(&mut v_proj[lane + 3], e.dx * e.dy * v_sigma);
                            A::add(&mut v_proj[lane + 4], 0.5f32 * e.dy * e.dy * v_sigma);
                            A::add(&mut v_proj[lane + 5], e.vis * v_alpha);
                        }
                        behind_r += f_r * fac;
                        behind_g += f_g * fac;
                        behind_b += f_b * fac;
                        behind_d += f_d * fac;
                        t_cur = t_i;
                    }
                }
            }
        }
        // Nobody may still read the batch the next load overwrites.
        sync_cube();
        top = first;
    }
}
