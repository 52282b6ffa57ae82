//! Per-view bookkeeping between projection and compositing: depth order and tile lists.
//!
//! Gaussians are sorted by (depth, index) — exactly the order gsplat's stable radix sort of
//! `tile | depth-bits` keys produces — and then appended to every tile they may touch, so each
//! tile's list is front-to-back with ties broken by Gaussian index, deterministically.

use super::project::Projected;
use crate::real::Real;

/// The tile lists of one view in CSR form.
#[derive(Debug, Clone, Default)]
pub struct TileBins {
    /// `tile_start[t]..tile_start[t + 1]` indexes `items` for tile `t` (row-major tile id).
    pub tile_start: Vec<usize>,
    /// Gaussian indices, per tile front to back.
    pub items: Vec<u32>,
    /// Number of Gaussians that survived culling.
    pub visible: usize,
}

impl TileBins {
    pub fn tile(&self, t: usize) -> &[u32] {
        &self.items[self.tile_start[t]..self.tile_start[t + 1]]
    }

    pub fn num_tiles(&self) -> usize {
        self.tile_start.len().saturating_sub(1)
    }

    pub fn intersections(&self) -> usize {
        self.items.len()
    }
}

/// Builds the tile lists of one view from its projected Gaussians (`None` = culled).
pub fn bin_tiles<F: Real>(
    projected: &[Option<Projected<F>>],
    tiles_x: u32,
    tiles_y: u32,
) -> TileBins {
    let num_tiles = (tiles_x * tiles_y) as usize;
    let mut order: Vec<u32> = (0..projected.len() as u32)
        .filter(|&i| projected[i as usize].is_some())
        .collect();
    // Stable sort on depth keeps index order among equal depths. Depths are finite and
    // >= near > 0, so partial_cmp never fails; Equal is a safe fallback regardless.
    let depth = |i: u32| {
        projected[i as usize]
            .as_ref()
            .map(|p| p.depth)
            .unwrap_or_else(F::zero)
    };
    order.sort_by(|&a, &b| {
        depth(a)
            .partial_cmp(&depth(b))
            .unwrap_or(std::cmp::Ordering::Equal)
    });

    let mut counts = vec![0usize; num_tiles + 1];
    for &i in &order {
        if let Some(p) = &projected[i as usize] {
            for ty in p.tiles.y0..p.tiles.y1 {
                for tx in p.tiles.x0..p.tiles.x1 {
                    counts[(ty * tiles_x + tx) as usize + 1] += 1;
                }
            }
        }
    }
    for t in 0..num_tiles {
        counts[t + 1] += counts[t];
    }
    let tile_start = counts;
    let mut cursor = tile_start.clone();
    let mut items = vec![0u32; tile_start[num_tiles]];
    for &i in &order {
        if let Some(p) = &projected[i as usize] {
            for ty in p.tiles.y0..p.tiles.y1 {
                for tx in p.tiles.x0..p.tiles.x1 {
                    let t = (ty * tiles_x + tx) as usize;
                    items[cursor[t]] = i;
                    cursor[t] += 1;
                }
            }
        }
    }
    TileBins {
        tile_start,
        items,
        visible: order.len(),
    }
}
