//! Tile binning on the device, the order of [`crate::cpu::bins::bin_tiles`] exactly:
//! 1. `depth_keys`: every Gaussian's depth as a sort key (the f32 bits of a positive depth
//!    order as the depth does), culled ones `CULLED` so they sort last;
//! 2. a stable radix sort by that key: (depth, index) order ([`super::sort`]);
//! 3. `tile_counts`: tiles each sorted Gaussian touches (0 when culled), then an exclusive
//!    scan: every Gaussian's first intersection slot, and the total;
//! 4. `emit_intersections`: (tile id, Gaussian) pairs in depth order;
//! 5. a stable radix sort by tile id: each tile's list stays front to back;
//! 6. `tile_ranges`: the CSR `tile_start` from the sorted tile ids.

use super::project_forward::{META_LANES, RECORD_LANES};
use cubecl::prelude::*;

/// The key of a culled Gaussian: above every finite positive f32's bits.
pub const CULLED: u32 = u32::MAX;
/// Lane of the depth in a packed record.
const DEPTH_LANE: usize = 9;

/// The tile rect `(x0, y0, x1, y1)` of Gaussian `g` from its meta row.
#[cube]
fn rect(meta: &Tensor<f32>, g: usize) -> (u32, u32, u32, u32) {
    let m = g * META_LANES;
    (
        u32::cast_from(meta[m]),
        u32::cast_from(meta[m + 1]),
        u32::cast_from(meta[m + 2]),
        u32::cast_from(meta[m + 3]),
    )
}

#[cube(launch)]
pub fn depth_keys(
    records: &Tensor<f32>,
    meta: &Tensor<f32>,
    keys: &mut Tensor<u32>,
    values: &mut Tensor<u32>,
    n: u32,
) {
    let i = ABSOLUTE_POS;
    if i >= n as usize {
        terminate!();
    }
    let (x0, y0, x1, y1) = rect(meta, i);
    // A culled record is all zeros: reading its depth is harmless.
    let mut key = f32::to_bits(records[i * RECORD_LANES + DEPTH_LANE]);
    if x1 <= x0 || y1 <= y0 {
        key = CULLED;
    }
    keys[i] = key;
    values[i] = u32::cast_from(i);
}

/// Tiles touched by the Gaussian at sorted position `p`.
#[cube(launch)]
pub fn tile_counts(
    keys: &Tensor<u32>,
    order: &Tensor<u32>,
    meta: &Tensor<f32>,
    counts: &mut Tensor<u32>,
    n: u32,
) {
    let p = ABSOLUTE_POS;
    if p >= n as usize {
        terminate!();
    }
    let mut c = 0u32;
    if keys[p] != CULLED {
        let (x0, y0, x1, y1) = rect(meta, order[p] as usize);
        c = (x1 - x0) * (y1 - y0);
    }
    counts[p] = c;
}

/// Writes `(tile id, Gaussian)` for every tile of the Gaussian at sorted position `p`, from
/// its slot `offsets[p]` on, row by row as the CPU appends them.
#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn emit_intersections(
    keys: &Tensor<u32>,
    order: &Tensor<u32>,
    meta: &Tensor<f32>,
    offsets: &Tensor<u32>,
    tile_ids: &mut Tensor<u32>,
    items: &mut Tensor<u32>,
    n: u32,
    tiles_x: u32,
) {
    let p = ABSOLUTE_POS;
    if p >= n as usize {
        terminate!();
    }
    if keys[p] != CULLED {
        let g = order[p];
        let (x0, y0, x1, y1) = rect(meta, g as usize);
        let mut slot = offsets[p] as usize;
        for ty in y0..y1 {
            for tx in x0..x1 {
                tile_ids[slot] = ty * tiles_x + tx;
                items[slot] = g;
                slot += 1;
            }
        }
    }
}

/// `tile_start[u]` = first intersection of tile `u` (or of the next non-empty tile), for
/// `u` in `0..=num_tiles`; unit `j` of `0..=m` writes the tiles between the previous
/// intersection's tile and its own, so every entry is written once.
#[cube(launch)]
pub fn tile_ranges(tile_ids: &Tensor<u32>, tile_start: &mut Tensor<u32>, m: u32, num_tiles: u32) {
    let j = ABSOLUTE_POS as u32;
    if j > m {
        terminate!();
    }
    let mut lo = 0u32;
    if j > 0 {
        lo = tile_ids[(j - 1) as usize] + 1;
    }
    let mut hi = num_tiles;
    if j < m {
        hi = tile_ids[j as usize];
    }
    for u in lo..hi + 1 {
        tile_start[u as usize] = j;
    }
}

/// One unit: `totals[view] = offsets[n]`, the view's intersection count, so every view's
/// count comes back in one read.
#[cube(launch)]
pub fn copy_total(offsets: &Tensor<u32>, totals: &mut Tensor<u32>, n: u32, view: u32) {
    if ABSOLUTE_POS == 0 {
        totals[view as usize] = offsets[n as usize];
    }
}
