//! Front-to-back compositing of one view: one cube per 16x16 tile, one unit per pixel
//! (`raster_tile_forward` / `composite_pixel` in `cpu/raster.rs`).
//!
//! The cube walks its tile's CSR list `items[tile_start[t] .. tile_start[t+1]]` (Gaussian
//! indices, front to back) in batches of `BATCH` records: each unit copies one record into
//! shared memory, with its early-reject distance, so a record is read from global memory
//! once per tile instead of once per pixel. A unit whose pixel has reached the transmittance
//! stop counts itself done; when all are, the tile stops (per-tile early exit). Units
//! outside the image (partial edge tiles) load their share and write nothing.
//! [`super::rasterize_forward_per_pixel`] is the same without shared memory, for a software
//! adapter ([`crate::config::TileSchedule`]).

use super::project_forward::RECORD_LANES;
use cubecl::prelude::*;

/// Records per shared-memory batch: one per unit of the cube.
pub const BATCH: u32 = TILE * TILE;
/// Lanes of a batched record: the packed record, then its early-reject distance.
pub const SHARED_LANES: usize = RECORD_LANES + 1;
/// The early-reject distance's lane.
const CUT_LANE: usize = RECORD_LANES;
/// Shared floats of one batch (11 KiB: within WebGPU's 16 KiB minimum).
pub const BATCH_SHARED: usize = BATCH as usize * SHARED_LANES;
/// Safety margin of the early reject ([`crate::cpu::raster::SIGMA_CUT_MARGIN`]): at
/// `sigma > ln(opacity / alpha_min) + margin` alpha is certainly below `alpha_min`, so the
/// `exp` is skipped without changing any decision.
const SIGMA_CUT_MARGIN: f32 = crate::cpu::raster::SIGMA_CUT_MARGIN as f32;
/// An early-reject distance that rejects nothing early (a finite literal: WGSL has no inf).
const NO_CUT: f32 = f32::MAX;

/// Tile side in pixels ([`crate::config::TILE_SIZE`]); a tile's cube is TILE x TILE units
/// in one row (unit = row x TILE + column).
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

/// Evaluates a splat (offset `(dx, dy)` from the pixel centre, conic, opacity) with
/// early-reject distance `cut`; forward and backward both come here, so their skip
/// decisions cannot diverge. Past `cut` the splat is skipped without its `exp`.
#[cube]
#[allow(clippy::too_many_arguments)]
pub fn eval_values(
    dx: f32,
    dy: f32,
    q00: f32,
    q01: f32,
    q11: f32,
    opacity: f32,
    cut: f32,
    alpha_min: f32,
    alpha_max: f32,
) -> Eval {
    let sigma = 0.5f32 * (q00 * dx * dx + q11 * dy * dy) + q01 * dx * dy;
    let mut vis = 0.0f32;
    let mut alpha = 0.0f32;
    let mut skip = true;
    if sigma >= 0.0f32 && sigma <= cut {
        vis = f32::exp(0.0f32 - sigma);
        alpha = alpha_max.min(opacity * vis);
        skip = alpha < alpha_min;
    }
    Eval {
        dx,
        dy,
        vis,
        alpha,
        skip,
    }
}

/// Evaluates record `rec` of `records` at pixel centre `(px, py)` (no early reject).
#[cube]
pub fn eval_splat(
    records: &Tensor<f32>,
    rec: usize,
    px: f32,
    py: f32,
    alpha_min: f32,
    alpha_max: f32,
) -> Eval {
    eval_values(
        records[rec] - px,
        records[rec + 1] - py,
        records[rec + 2],
        records[rec + 3],
        records[rec + 4],
        records[rec + 5],
        NO_CUT,
        alpha_min,
        alpha_max,
    )
}

/// Copies the records of items `[first, end)` into the batch (unit `u` copies item
/// `first + u`, with its early-reject distance) and their Gaussian indices into `ids`.
#[cube]
#[allow(clippy::too_many_arguments)]
pub fn load_batch(
    records: &Tensor<f32>,
    items: &Tensor<u32>,
    batch: &mut [f32],
    ids: &mut [u32],
    first: u32,
    end: u32,
    unit: usize,
    alpha_min: f32,
) {
    let k = first + unit as u32;
    if k < end {
        let id = items[k as usize];
        let rec = id as usize * RECORD_LANES;
        let s = unit * SHARED_LANES;
        for l in 0..RECORD_LANES {
            batch[s + l] = records[rec + l];
        }
        batch[s + CUT_LANE] = f32::ln(records[rec + 5] / alpha_min) + SIGMA_CUT_MARGIN;
        ids[unit] = id;
    }
}

/// Evaluates the batched record at `s` at pixel centre `(px, py)`, with its early reject.
#[cube]
pub fn eval_batched(
    batch: &[f32],
    s: usize,
    px: f32,
    py: f32,
    alpha_min: f32,
    alpha_max: f32,
) -> Eval {
    eval_values(
        batch[s] - px,
        batch[s + 1] - py,
        batch[s + 2],
        batch[s + 3],
        batch[s + 4],
        batch[s + 5],
        batch[s + CUT_LANE],
        alpha_min,
        alpha_max,
    )
}

/// Where a unit of a tile cube draws: its pixel, the pixel centre, the pixel's first output
/// lane in the image batch and its index among the batch's pixels (`pixel`, that lane over
/// [`OUT_CHANNELS`]), and the tile's item range `[start, end)` in the CSR lists.
/// `inside` is false for the units of a partial edge tile past the image (their `out` is
/// meaningless and must not be used).
#[derive(CubeType, Clone, Copy)]
#[expand(derive(Clone, Copy))]
pub struct TilePixel {
    pub inside: bool,
    pub px: f32,
    pub py: f32,
    pub out: usize,
    pub pixel: usize,
    pub start: u32,
    pub end: u32,
}

/// The [`TilePixel`] of this unit, for the cube of tile `(CUBE_POS_X, CUBE_POS_Y)`.
#[cube]
pub fn tile_pixel(
    tile_start: &Tensor<u32>,
    width: u32,
    height: u32,
    tiles_x: u32,
    view_offset: u32,
) -> TilePixel {
    // Cubes are one-dimensional (WGSL offers subgroup ids only there): unit = row * TILE + col.
    let x = CUBE_POS_X * TILE + UNIT_POS % TILE;
    let y = CUBE_POS_Y * TILE + UNIT_POS / TILE;
    let tile = (CUBE_POS_Y * tiles_x + CUBE_POS_X) as usize;
    let pixel = view_offset as usize / OUT_CHANNELS + (y * width + x) as usize;
    TilePixel {
        inside: x < width && y < height,
        px: f32::cast_from(x) + 0.5f32,
        py: f32::cast_from(y) + 0.5f32,
        out: pixel * OUT_CHANNELS,
        pixel,
        start: tile_start[tile],
        end: tile_start[tile + 1],
    }
}

#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn rasterize_forward(
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
    let unit = UNIT_POS as usize;
    let (inside, start, end, px, py) = (pix.inside, pix.start, pix.end, pix.px, pix.py);

    let mut batch = Shared::<[f32]>::new_slice(BATCH_SHARED);
    // The indices are the backward's (it adds into per-Gaussian lanes); loaded here too so
    // both kernels share one loader.
    let mut ids = Shared::<[u32]>::new_slice(BATCH as usize);
    let finished = Shared::<[Atomic<u32>]>::new_slice(1usize);
    if unit == 0 {
        finished[0].store(0u32);
    }
    sync_cube();
    // Units without a pixel are done from the start.
    let mut done = !inside;
    if done {
        finished[0].fetch_add(1u32);
    }
    let mut t = 1.0f32;
    let mut acc_r = 0.0f32;
    let mut acc_g = 0.0f32;
    let mut acc_b = 0.0f32;
    let mut acc_d = 0.0f32;
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
                let s = j as usize * SHARED_LANES;
                let e = eval_batched(&batch, s, px, py, alpha_min, alpha_max);
                if !e.skip {
                    let next_t = t * (1.0f32 - e.alpha);
                    // Exclusive stop: the splat that would drive T to the threshold is not
                    // composited.
                    if next_t <= t_min {
                        done = true;
                        break;
                    }
                    let fac = e.alpha * t;
                    acc_r += batch[s + 6] * fac;
                    acc_g += batch[s + 7] * fac;
                    acc_b += batch[s + 8] * fac;
                    acc_d += batch[s + 9] * fac;
                    t = next_t;
                    last = base + j + 1;
                }
            }
            if done {
                finished[0].fetch_add(1u32);
            }
        }
        base += BATCH;
        // The uniform load meets the whole cube first, so nobody still reads the batch the
        // next iteration overwrites; and it tells every unit at once whether all are done.
        // CUDA lowers it to a barrier then the load, with no barrier after (WGSL has both):
        // rewriting the batch right after is safe (its readers met that barrier), but a
        // write to `finished` must wait for the next `sync_cube`, after every unit loaded it
        // (the `fetch_add`s above sit after the sync that follows `load_batch`).
        if workgroup_uniform_load_atomic(&finished[0]) == BATCH {
            break;
        }
    }
    if inside {
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
}

/// Keeps a pixel's final transmittance and one past its last composited item for the
/// backward, which then needs no replay of the forward (gsplat keeps `last_ids` and the
/// alpha for the same reason). `t` itself, not `1 - alpha`: that would lose T's low bits
/// where the pixel is nearly opaque.
#[cube]
pub fn write_ends(ends: &mut Tensor<u32>, pixel: usize, t: f32, last: u32) {
    ends[2 * pixel] = f32::to_bits(t);
    ends[2 * pixel + 1] = last;
}
