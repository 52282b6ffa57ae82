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
//! [`super::rasterize_backward_per_pixel`] is the same without shared memory, for a software
//! adapter ([`crate::config::TileSchedule`]); both add a splat's gradient with
//! [`reverse_step()`].
//! Lane order: mean2d (x, y), conic (q00, q01, q11), opacity, colour (r, g, b), depth.

use super::project_forward::RECORD_LANES;
use super::rasterize_forward::{
    eval_batched, load_batch, tile_pixel, Eval, BATCH, BATCH_SHARED, SHARED_LANES, TILE,
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

/// A pixel's upstream gradient, one per output channel, and its final transmittance.
#[derive(CubeType, Clone, Copy)]
#[expand(derive(Clone, Copy))]
pub struct Upstream {
    pub r: f32,
    pub g: f32,
    pub b: f32,
    pub d: f32,
    pub a: f32,
    pub t_final: f32,
}

/// The reverse pass's running state at a pixel: the transmittance in front of the next
/// splat, and the colour and depth composited behind it.
#[derive(CubeType)]
pub struct Behind {
    pub t: f32,
    pub r: f32,
    pub g: f32,
    pub b: f32,
    pub d: f32,
}

#[cube]
impl Behind {
    /// Nothing behind yet, transmittance `t_final`: the state past the last composited splat.
    pub fn new(t_final: f32) -> Behind {
        Behind {
            t: t_final,
            r: 0.0f32,
            g: 0.0f32,
            b: 0.0f32,
            d: 0.0f32,
        }
    }
}

/// The record lanes the gradient reads besides the evaluation: conic, opacity, colour, depth.
#[derive(CubeType, Clone, Copy)]
#[expand(derive(Clone, Copy))]
pub struct Shade {
    pub q00: f32,
    pub q01: f32,
    pub q11: f32,
    pub opacity: f32,
    pub r: f32,
    pub g: f32,
    pub b: f32,
    pub d: f32,
}

/// The [`Shade`] of the batched record at `s`.
#[cube]
pub fn shade_of_batch(batch: &[f32], s: usize) -> Shade {
    Shade {
        q00: batch[s + 2],
        q01: batch[s + 3],
        q11: batch[s + 4],
        opacity: batch[s + 5],
        r: batch[s + 6],
        g: batch[s + 7],
        b: batch[s + 8],
        d: batch[s + 9],
    }
}

/// The [`Shade`] of the record at `rec` in global memory.
#[cube]
pub fn shade_of_record(records: &Tensor<f32>, rec: usize) -> Shade {
    Shade {
        q00: records[rec + 2],
        q01: records[rec + 3],
        q11: records[rec + 4],
        opacity: records[rec + 5],
        r: records[rec + 6],
        g: records[rec + 7],
        b: records[rec + 8],
        d: records[rec + 9],
    }
}

/// One splat of the reverse pass (composited, evaluation `e`): adds its gradient lanes into
/// Gaussian `id`'s row of `v_proj` and steps `state` in front of it. Both backward kernels
/// come here, so their formulas cannot diverge.
#[cube]
pub fn reverse_step<A: GradAdd>(
    v_proj: &mut Tensor<Atomic<A::Proxy>>,
    id: usize,
    e: Eval,
    sh: Shade,
    up: Upstream,
    state: &mut Behind,
    alpha_max: f32,
) {
    let one_minus = 1.0f32 - e.alpha;
    let t_i = state.t / one_minus;
    let fac = e.alpha * t_i;
    let lane = id * RECORD_LANES;
    A::add(&mut v_proj[lane + 6], fac * up.r);
    A::add(&mut v_proj[lane + 7], fac * up.g);
    A::add(&mut v_proj[lane + 8], fac * up.b);
    A::add(&mut v_proj[lane + 9], fac * up.d);
    let mut v_alpha = up.a * up.t_final / one_minus;
    v_alpha += up.r * (sh.r * t_i - state.r / one_minus);
    v_alpha += up.g * (sh.g * t_i - state.g / one_minus);
    v_alpha += up.b * (sh.b * t_i - state.b / one_minus);
    v_alpha += up.d * (sh.d * t_i - state.d / one_minus);
    // When the clamp is active alpha no longer depends on opacity or geometry.
    if sh.opacity * e.vis <= alpha_max {
        let v_sigma = (0.0f32 - sh.opacity) * e.vis * v_alpha;
        A::add(&mut v_proj[lane], v_sigma * (sh.q00 * e.dx + sh.q01 * e.dy));
        A::add(
            &mut v_proj[lane + 1],
            v_sigma * (sh.q01 * e.dx + sh.q11 * e.dy),
        );
        A::add(&mut v_proj[lane + 2], 0.5f32 * e.dx * e.dx * v_sigma);
        A::add(&mut v_proj[lane + 3], e.dx * e.dy * v_sigma);
        A::add(&mut v_proj[lane + 4], 0.5f32 * e.dy * e.dy * v_sigma);
        A::add(&mut v_proj[lane + 5], e.vis * v_alpha);
    }
    state.r += sh.r * fac;
    state.g += sh.g * fac;
    state.b += sh.b * fac;
    state.d += sh.d * fac;
    state.t = t_i;
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
    let pix = tile_pixel(tile_start, width, height, tiles_x, view_offset);
    let unit = (UNIT_POS_Y * TILE + UNIT_POS_X) as usize;
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
    let (start, end, px, py) = (pix.start, pix.end, pix.px, pix.py);

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
        if active {
            let count = top - first;
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
