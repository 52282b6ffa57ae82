//! The forward's non-differentiable outputs of one view, written on the device: every
//! Gaussian's radii (`radii [V, R, 2]`, R the row width: N, or the largest stacked set), and
//! `counts [V, 2]` = (visible Gaussians, tile intersections). The depth sort already puts
//! every culled Gaussian last (key [`CULLED`], above every visible depth's bits), so the
//! visible count is where its keys start: one binary search, no pass over the Gaussians and
//! nothing read back.

use super::bin_tiles::CULLED;
use super::project_forward::META_LANES;
use cubecl::prelude::*;

#[cube(launch)]
pub fn view_radii(meta: &Tensor<f32>, radii: &mut Tensor<u32>, n: u32, row_width: u32, view: u32) {
    let i = ABSOLUTE_POS;
    if i >= n as usize {
        terminate!();
    }
    let m = i * META_LANES;
    // Radii are small non-negative integers held in f32 (zero when culled).
    let o = (view as usize * row_width as usize + i) * 2;
    radii[o] = u32::cast_from(meta[m + 4]);
    radii[o + 1] = u32::cast_from(meta[m + 5]);
}

/// One unit: `counts[2 v]` = the visible Gaussians, the first position of [`CULLED`] in the
/// view's `n` ascending depth keys (a visible key is the bits of a depth in [near, far], a
/// positive finite f32, so below it); `counts[2 v + 1] = intersections`.
#[cube(launch)]
pub fn view_counts(
    sorted_keys: &Tensor<u32>,
    counts: &mut Tensor<u32>,
    n: u32,
    view: u32,
    intersections: u32,
) {
    if ABSOLUTE_POS == 0 {
        let mut lo = 0u32;
        let mut hi = n;
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            if sorted_keys[mid as usize] == CULLED {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        counts[view as usize * 2] = lo;
        counts[view as usize * 2 + 1] = intersections;
    }
}
