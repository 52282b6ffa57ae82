//! The forward's non-differentiable outputs of one view, written on the device: every
//! Gaussian's radii (`radii [V, R, 2]`, R the row width: N, or the largest stacked set), and `counts [V, 2]` = (visible Gaussians, tile
//! intersections). `visible_flags` marks the visible ones; its exclusive scan's total is the
//! visible count, so nothing is read back.

use super::project_forward::META_LANES;
use cubecl::prelude::*;

#[cube(launch)]
pub fn radii_and_flags(
    meta: &Tensor<f32>,
    radii: &mut Tensor<u32>,
    flags: &mut Tensor<u32>,
    n: u32,
    row_width: u32,
    view: u32,
) {
    let i = ABSOLUTE_POS;
    if i >= n as usize {
        terminate!();
    }
    let m = i * META_LANES;
    // Radii are small non-negative integers held in f32 (zero when culled).
    let o = (view as usize * row_width as usize + i) * 2;
    radii[o] = u32::cast_from(meta[m + 4]);
    radii[o + 1] = u32::cast_from(meta[m + 5]);
    let mut visible = 0u32;
    if meta[m + 2] > meta[m] && meta[m + 3] > meta[m + 1] {
        visible = 1u32;
    }
    flags[i] = visible;
}

/// One unit: `counts[2 v] = visible_scan[n]`, `counts[2 v + 1] = intersections`.
#[cube(launch)]
pub fn view_counts(
    visible_scan: &Tensor<u32>,
    counts: &mut Tensor<u32>,
    n: u32,
    view: u32,
    intersections: u32,
) {
    if ABSOLUTE_POS == 0 {
        counts[view as usize * 2] = visible_scan[n as usize];
        counts[view as usize * 2 + 1] = intersections;
    }
}
