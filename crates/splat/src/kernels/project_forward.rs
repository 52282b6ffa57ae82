//! Projection of every Gaussian into one view: one thread per Gaussian, the same culls in the
//! same order as `project_one` in `cpu/project.rs`. The view's Gaussians are input rows
//! `first .. first + n` (all rows when the views share one scene, the view's own set when
//! they are stacked); the outputs are indexed from 0.
//!
//! Outputs (flat, row-major):
//! - `records [N, RECORD_LANES]` = (mean_x, mean_y, q00, q01, q11, opacity, r, g, b, depth),
//!   the packed splat the compositing kernels read (zero when culled);
//! - `meta [N, META_LANES]` = tile rect (x0, y0, x1, y1) and radii (rx, ry), all zero when
//!   culled. They are small integers (< 2^24) kept in f32 so that the host reads back one
//!   float buffer; a Gaussian is visible iff its rect is non-empty.

// The tile-grid size is written `(n + T - 1) / T`: `div_ceil` is not a CubeCL operation.
#![allow(clippy::manual_div_ceil)]

use super::geometry::geometry;
use super::math::*;
use cubecl::prelude::*;

/// Lanes of one packed splat record.
pub const RECORD_LANES: usize = 10;
/// Lanes of one meta row: tile rect (4) and radii (2).
pub const META_LANES: usize = 6;
/// Largest extent in standard deviations, from [`crate::config::EXTENT_CAP`] (an f32
/// literal in the kernel; the cast is exact to the nearest f32).
const EXTENT_CAP: f32 = crate::config::EXTENT_CAP as f32;
/// Radius clamp before the integer conversion, from [`crate::config::RADIUS_MAX`].
const RADIUS_MAX: f32 = crate::config::RADIUS_MAX as f32;
/// Tile side in pixels, from [`crate::config::TILE_SIZE`].
const TILE: f32 = crate::config::TILE_SIZE as f32;
/// The same tile side as an integer, for the tile-grid size.
const TILE_PX: u32 = crate::config::TILE_SIZE;

#[cube(launch)]
#[allow(clippy::too_many_arguments)]
pub fn project_forward(
    means: &Tensor<f32>,
    quats: &Tensor<f32>,
    scales: &Tensor<f32>,
    opacities: &Tensor<f32>,
    colors: &Tensor<f32>,
    cam_rec: &Tensor<f32>,
    records: &mut Tensor<f32>,
    meta: &mut Tensor<f32>,
    first: u32,
    n: u32,
    width: u32,
    height: u32,
    near: f32,
    far: f32,
    eps2d: f32,
    alpha_min: f32,
) {
    let i = ABSOLUTE_POS;
    if i >= n as usize {
        terminate!();
    }
    let gi = first as usize + i;
    let cam = load_cam(cam_rec);
    let opacity = opacities[gi];
    let (cr, cg, cb) = (colors[gi * 3], colors[gi * 3 + 1], colors[gi * 3 + 2]);
    let appearance_ok =
        opacity >= alpha_min && finite(opacity) && finite(cr) && finite(cg) && finite(cb);
    let geo = geometry(means, quats, scales, gi, cam, near, far, eps2d);

    // Same arithmetic as the CPU (`fx * x * rz + cx`).
    let rz = 1.0f32 / geo.m.z;
    let mx = cam.fx * geo.m.x * rz + cam.cx;
    let my = cam.fy * geo.m.y * rz + cam.cy;
    let mean_ok = finite(mx) && finite(my);

    // Opacity-aware extent: beyond sqrt(2 ln(o / alpha_min)) sigmas alpha < alpha_min anyway.
    let extent = f32::sqrt((2.0f32 * f32::ln(opacity / alpha_min)).max(0.0f32)).min(EXTENT_CAP);
    let rx = f32::ceil(extent * f32::sqrt(geo.cov2d.a)).min(RADIUS_MAX);
    let ry = f32::ceil(extent * f32::sqrt(geo.cov2d.c)).min(RADIUS_MAX);
    let radius_ok = rx > 0.0f32 || ry > 0.0f32;
    let (w, h) = (f32::cast_from(width), f32::cast_from(height));
    let on_screen = !(mx + rx <= 0.0f32 || mx - rx >= w || my + ry <= 0.0f32 || my - ry >= h);

    // Conservative tile AABB floor((mu - r)/16) .. ceil((mu + r)/16), clamped to the grid.
    let tiles_x = f32::cast_from((width + TILE_PX - 1u32) / TILE_PX);
    let tiles_y = f32::cast_from((height + TILE_PX - 1u32) / TILE_PX);
    let x0 = f32::floor((mx - rx) / TILE).max(0.0f32).min(tiles_x);
    let y0 = f32::floor((my - ry) / TILE).max(0.0f32).min(tiles_y);
    let x1 = f32::ceil((mx + rx) / TILE).max(0.0f32).min(tiles_x);
    let y1 = f32::ceil((my + ry) / TILE).max(0.0f32).min(tiles_y);
    let rect_ok = x1 > x0 && y1 > y0;

    let r = i * RECORD_LANES;
    let o = i * META_LANES;
    if appearance_ok && geo.valid && mean_ok && radius_ok && on_screen && rect_ok {
        records[r] = mx;
        records[r + 1] = my;
        records[r + 2] = geo.conic.a;
        records[r + 3] = geo.conic.b;
        records[r + 4] = geo.conic.c;
        records[r + 5] = opacity;
        records[r + 6] = cr;
        records[r + 7] = cg;
        records[r + 8] = cb;
        records[r + 9] = geo.m.z;
        meta[o] = x0;
        meta[o + 1] = y0;
        meta[o + 2] = x1;
        meta[o + 3] = y1;
        meta[o + 4] = rx;
        meta[o + 5] = ry;
    } else {
        for k in 0..RECORD_LANES {
            records[r + k] = 0.0f32;
        }
        for k in 0..META_LANES {
            meta[o + k] = 0.0f32;
        }
    }
}
