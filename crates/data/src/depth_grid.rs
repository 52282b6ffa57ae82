//! Ground-truth depth brought onto the fitted frame grid for evaluation.
//!
//! LiDAR is sparse: STORM stores it on a quarter-resolution grid (`depth_flows_4`, 0 = no
//! return) or as points. Resampling such a map with a bilinear or nearest filter would
//! either blend real returns with the zeros of empty cells or spread one return over many
//! pixels. Instead every measurement is moved to where it lands on the target grid: the
//! centre of its cell (or the point itself) is unprojected with its own intrinsics,
//! projected with the target's, and written into the pixel that contains it. Where several
//! land in one pixel the nearest wins, as a z-buffer would (the others are occluded there).

use crate::clip::DepthMap;
use crate::error::{DataError, Result};
use crate::geom::{Intrinsics, Mat4, Vec3};
use std::path::Path;

/// How far two intrinsics may differ and still count as the same grid (pixels).
const SAME_GRID_TOLERANCE: f64 = 1e-9;

/// Where a frame's evaluation depth came from (reported next to D-RMSE).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DepthSource {
    /// A dense map on the frame grid (the synthetic layout): every pixel has truth.
    Dense,
    /// A sparse LiDAR map on its own grid (STORM's `depth_flows_4`), moved onto the frame grid.
    LidarGrid,
    /// LiDAR points projected into the frame (STORM's `lidar/*.bin`, nuScenes `LIDAR_TOP`).
    LidarPoints,
}

impl DepthSource {
    /// The name used in reports.
    pub fn name(self) -> &'static str {
        match self {
            DepthSource::Dense => "dense",
            DepthSource::LidarGrid => "lidar_grid",
            DepthSource::LidarPoints => "lidar_points",
        }
    }
}

/// Added before flooring so a centre exactly on a pixel edge (a quarter cell's centre is
/// the corner of four full-resolution pixels) lands right and below of it, whatever the
/// rounding of the projection; far above that rounding (~1e-13 px), far below a pixel.
const EDGE_NUDGE_PX: f64 = 1e-6;

/// A LiDAR file of little-endian float32 records of `columns` floats (STORM's `lidar/*.bin`,
/// nuScenes' `.pcd.bin`), the point at columns `xyz..xyz + 3`, moved into the camera frame by
/// `to_camera`; only points in front of the camera are kept. A truncated file or a
/// non-finite point is an error naming the file (and the record).
pub fn read_lidar_records(
    path: &Path,
    columns: usize,
    xyz: usize,
    to_camera: &Mat4,
) -> Result<Vec<[f32; 3]>> {
    let bytes = std::fs::read(path).map_err(|e| DataError::gt(path, e.to_string()))?;
    let record = columns * 4;
    if bytes.len() % record != 0 {
        return Err(DataError::gt(
            path,
            format!(
                "{} bytes is not a whole number of {columns}-float records",
                bytes.len()
            ),
        ));
    }
    let mut out = Vec::with_capacity(bytes.len() / record);
    for (idx, rec) in bytes.chunks_exact(record).enumerate() {
        let f = |c: usize| {
            let at = 4 * (xyz + c);
            f32::from_le_bytes([rec[at], rec[at + 1], rec[at + 2], rec[at + 3]])
        };
        let (x, y, z) = (f(0), f(1), f(2));
        if !(x.is_finite() && y.is_finite() && z.is_finite()) {
            return Err(DataError::gt(
                path,
                format!("LiDAR record {idx} is not finite"),
            ));
        }
        let p = to_camera.transform_point(Vec3::new(x as f64, y as f64, z as f64));
        if p.z > 0.0 {
            out.push([p.x as f32, p.y as f32, p.z as f32]);
        }
    }
    Ok(out)
}

/// Writes z-depth `z` at continuous pixel `(x, y)` into `grid` (H·W) if it falls inside and
/// is nearer than what the pixel holds.
fn z_write(grid: &mut [f32], (h, w): (usize, usize), x: f64, y: f64, z: f32) {
    let (x, y) = (x + EDGE_NUDGE_PX, y + EDGE_NUDGE_PX);
    if !(x >= 0.0 && y >= 0.0 && x < w as f64 && y < h as f64) {
        return;
    }
    let i = y as usize * w + x as usize;
    if grid[i] <= 0.0 || z < grid[i] {
        grid[i] = z;
    }
}

/// Points in the OpenCV camera frame (metres) as a z-depth map on an `(h, w)` grid with
/// intrinsics `k`; 0 where no point lands. Points behind the camera are dropped.
pub fn splat_points(points: &[[f32; 3]], k: &Intrinsics, size: (usize, usize)) -> Vec<f32> {
    let mut grid = vec![0.0f32; size.0 * size.1];
    for p in points {
        let z = p[2];
        if !(z > 0.0 && z.is_finite()) {
            continue;
        }
        if let Some((x, y)) = k.project(Vec3::new(p[0] as f64, p[1] as f64, z as f64)) {
            z_write(&mut grid, size, x, y, z);
        }
    }
    grid
}

/// The map's first channel when it already lies on the `(h, w)` grid with intrinsics `k`.
fn on_same_grid(map: &DepthMap, k: &Intrinsics, size: (usize, usize)) -> Option<Vec<f32>> {
    let src = &map.intrinsics;
    let same = (map.map.height, map.map.width) == size
        && [
            (src.fx, k.fx),
            (src.fy, k.fy),
            (src.cx, k.cx),
            (src.cy, k.cy),
        ]
        .iter()
        .all(|(a, b)| (a - b).abs() <= SAME_GRID_TOLERANCE);
    let channels = map.map.channels.max(1);
    same.then(|| map.map.data.iter().step_by(channels).copied().collect())
}

/// A depth map on its own grid moved onto an `(h, w)` grid with intrinsics `k` (see the
/// module comment). A map already on that grid is copied unchanged.
pub fn resample_map(map: &DepthMap, k: &Intrinsics, size: (usize, usize)) -> Vec<f32> {
    if let Some(copy) = on_same_grid(map, k, size) {
        return copy;
    }
    let (mh, mw) = (map.map.height, map.map.width);
    let src = &map.intrinsics;
    let channels = map.map.channels.max(1);
    let mut grid = vec![0.0f32; size.0 * size.1];
    for v in 0..mh {
        for u in 0..mw {
            let z = map.map.data[(v * mw + u) * channels];
            if !(z > 0.0 && z.is_finite()) {
                continue;
            }
            let p = src.unproject(u as f64 + 0.5, v as f64 + 0.5, z as f64);
            if let Some((x, y)) = k.project(p) {
                z_write(&mut grid, size, x, y, z);
            }
        }
    }
    grid
}

/// A dense map (every pixel measured, e.g. rendered depth) on another grid of the same
/// camera, sampled at the `(h, w)` grid's pixel centres (nearest source pixel): unlike the
/// LiDAR path, an upscaled dense map keeps no holes and a downscaled one no foreground bias.
/// Target pixels outside the source image get 0.
pub fn sample_dense(map: &DepthMap, k: &Intrinsics, size: (usize, usize)) -> Vec<f32> {
    if let Some(copy) = on_same_grid(map, k, size) {
        return copy;
    }
    let channels = map.map.channels.max(1);
    let first: Vec<f32> = map.map.data.iter().step_by(channels).copied().collect();
    sample_nearest(
        &first,
        (map.map.height, map.map.width),
        &map.intrinsics,
        k,
        size,
    )
}

/// Any per-pixel map of a source grid (`src_size`, intrinsics `src`) sampled at the pixel
/// centres of an `(h, w)` grid of the same camera with intrinsics `k` (nearest source pixel;
/// `T::default()` outside the source).
pub fn sample_nearest<T: Copy + Default>(
    data: &[T],
    (mh, mw): (usize, usize),
    src: &Intrinsics,
    k: &Intrinsics,
    size: (usize, usize),
) -> Vec<T> {
    let mut grid = vec![T::default(); size.0 * size.1];
    for y in 0..size.0 {
        // Same camera centre: the grids differ by a 2D affine map, independent of depth.
        let ys = (y as f64 + 0.5 - k.cy) / k.fy * src.fy + src.cy;
        for x in 0..size.1 {
            let xs = (x as f64 + 0.5 - k.cx) / k.fx * src.fx + src.cx;
            if xs >= 0.0 && ys >= 0.0 && xs < mw as f64 && ys < mh as f64 {
                grid[y * size.1 + x] = data[ys as usize * mw + xs as usize];
            }
        }
    }
    grid
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::exr_io::FloatMap;

    fn k(f: f64, w: f64, h: f64) -> Intrinsics {
        Intrinsics {
            fx: f,
            fy: f,
            cx: w / 2.0,
            cy: h / 2.0,
        }
    }

    /// Guards the quarter-grid move: a return in quarter cell (u, v) lands in full-res pixel
    /// (4u + 2, 4v + 2), the cell's centre, with its depth; empty cells stay empty.
    #[test]
    fn quarter_grid_cells_land_at_their_centres() {
        let full = k(100.0, 16.0, 8.0);
        let quarter = full.resized((8, 16), (2, 4));
        let mut data = vec![0.0; 8];
        data[5] = 7.5; // (v, u) = (1, 1)
        let map = DepthMap {
            map: FloatMap {
                width: 4,
                height: 2,
                channels: 1,
                data,
            },
            intrinsics: quarter,
            sparse: true,
        };
        let grid = resample_map(&map, &full, (8, 16));
        let hits: Vec<(usize, f32)> = grid
            .iter()
            .enumerate()
            .filter(|(_, z)| **z > 0.0)
            .map(|(i, z)| (i, *z))
            .collect();
        assert_eq!(hits, vec![(6 * 16 + 6, 7.5)]);
    }

    /// Guards the z-buffer: two points in one pixel keep the nearer; points behind the camera
    /// or outside the frame are dropped.
    #[test]
    fn nearest_point_wins_and_invisible_points_are_dropped() {
        let kk = k(10.0, 4.0, 4.0);
        let pts = [
            [0.0, 0.0, 5.0],
            [0.0, 0.0, 3.0],
            [0.0, 0.0, -2.0],
            [100.0, 0.0, 1.0],
        ];
        let grid = splat_points(&pts, &kk, (4, 4));
        assert_eq!(grid[2 * 4 + 2], 3.0);
        assert_eq!(grid.iter().filter(|z| **z > 0.0).count(), 1);
    }

    /// Guards dense resampling: a 2x upscaled dense map has no holes (every target pixel
    /// takes the source pixel it lies in).
    #[test]
    fn dense_maps_are_sampled_without_holes() {
        let small = k(5.0, 2.0, 2.0);
        let map = DepthMap {
            map: FloatMap {
                width: 2,
                height: 2,
                channels: 1,
                data: vec![1.0, 2.0, 3.0, 4.0],
            },
            intrinsics: small,
            sparse: false,
        };
        let big = small.resized((2, 2), (4, 4));
        let grid = sample_dense(&map, &big, (4, 4));
        assert_eq!(
            grid,
            vec![1.0, 1.0, 2.0, 2.0, 1.0, 1.0, 2.0, 2.0, 3.0, 3.0, 4.0, 4.0, 3.0, 3.0, 4.0, 4.0]
        );
    }

    /// Guards the same-grid shortcut: a dense map on the frame grid is copied bit for bit.
    #[test]
    fn same_grid_is_copied() {
        let kk = k(5.0, 3.0, 2.0);
        let data = vec![1.0, 2.0, 0.0, 4.0, 5.0, 6.0];
        let map = DepthMap {
            map: FloatMap {
                width: 3,
                height: 2,
                channels: 1,
                data: data.clone(),
            },
            intrinsics: kk,
            sparse: false,
        };
        assert_eq!(resample_map(&map, &kk, (2, 3)), data);
    }
}
