//! A decoded clip as the model consumes it, still on the host (no tensors): frames planar
//! CHW in [0, 1], with the ground truth the layout provides.

use crate::clip::{Clip, FrameGt};
use crate::depth_grid::{resample_map, sample_dense, sample_nearest, splat_points, DepthSource};
use crate::error::{DataError, Result};
use crate::geom::{Intrinsics, Mat4};
use crate::motion_truth::FrameMotionTruth;

/// One clip on the host: frames CHW in [0, 1], optional ground truth.
#[derive(Debug, Clone)]
pub struct HostClip {
    pub height: usize,
    pub width: usize,
    /// `N` frames, each `3·H·W` (CHW).
    pub frames: Vec<Vec<f32>>,
    /// Per frame: OpenCV world-to-camera and pixel intrinsics (empty when unknown).
    pub cameras: Vec<(Mat4, Intrinsics)>,
    /// Per frame `H·W` z-depth (empty when unknown).
    pub depths: Vec<Vec<f32>>,
    /// Per frame `H·W` z-depth for evaluation, 0 where nothing was measured: LiDAR moved
    /// onto the frame grid (`depth_grid`), or the dense map; `None` for a frame without
    /// depth (one missing file costs that frame only). Empty when the layout has no GT.
    pub eval_depths: Vec<Option<Vec<f32>>>,
    /// Where `eval_depths` came from (the first frame's source; a clip does not mix them).
    pub eval_depth_source: Option<DepthSource>,
    /// Per frame `H·W` ground-truth dynamic mask (objects moving to the next frame) on the
    /// frame grid; `None` for a frame without one. Empty when the layout has none.
    pub dynamic_masks: Vec<Option<Vec<bool>>>,
    /// Per frame: what exact scene flow between any two frames needs, on the frame grid
    /// (`motion_truth`); `None` for a frame without it. Empty when the layout has none.
    pub motion_truth: Vec<Option<FrameMotionTruth>>,
}

/// Interleaved RGB (HWC) to planar (CHW).
pub fn hwc_to_chw(hwc: &[f32], h: usize, w: usize) -> Vec<f32> {
    let mut chw = vec![0.0; 3 * h * w];
    for p in 0..h * w {
        for c in 0..3 {
            chw[c * h * w + p] = hwc[p * 3 + c];
        }
    }
    chw
}

impl HostClip {
    /// CHW frames and, when the layout has them, cameras and depth (depth must be on the
    /// frame grid: the synthetic layout writes it there). Ground truth stops at the first
    /// frame that lacks it, so `cameras[i]` always belongs to frame `i`.
    pub fn from_clip(clip: &Clip) -> Result<HostClip> {
        let first = clip.frames.first().ok_or_else(|| DataError::EmptyClip {
            clip: clip.id.clone(),
        })?;
        let (h, w) = (first.height, first.width);
        let frames = clip
            .frames
            .iter()
            .map(crate::frame::Image::to_chw)
            .collect();
        let cameras = clip
            .gt
            .iter()
            .map_while(|g| Some((g.world_to_camera?, g.intrinsics?)))
            .collect::<Vec<_>>();
        let depths = clip
            .gt
            .iter()
            .map_while(|g| {
                let d = g.depth.as_ref()?;
                (d.map.height == h && d.map.width == w).then(|| d.map.data.clone())
            })
            .collect::<Vec<_>>();
        let mut eval_depth_source = None;
        let eval_depths = clip
            .gt
            .iter()
            .map(|g| {
                let (grid, source) = eval_depth(g, (h, w))?;
                eval_depth_source.get_or_insert(source);
                Some(grid)
            })
            .collect::<Vec<_>>();
        let dynamic_masks = if clip.gt.iter().any(|g| g.dynamic_mask.is_some()) {
            clip.gt
                .iter()
                .map(|g| dynamic_mask(g, clip.source_size, (h, w)))
                .collect()
        } else {
            Vec::new()
        };
        let motion_truth = if clip.gt.iter().any(|g| g.objects.is_some()) {
            clip.gt
                .iter()
                .map(|g| motion_truth(g, clip.source_size, (h, w)))
                .collect()
        } else {
            Vec::new()
        };
        Ok(HostClip {
            height: h,
            width: w,
            frames,
            cameras,
            depths,
            eval_depths,
            eval_depth_source,
            dynamic_masks,
            motion_truth,
        })
    }
}

/// One frame's evaluation depth on the `(h, w)` frame grid: LiDAR points when the layout has
/// them, else its depth map moved onto the grid; `None` without intrinsics or depth.
fn eval_depth(g: &FrameGt, size: (usize, usize)) -> Option<(Vec<f32>, DepthSource)> {
    let k = g.intrinsics?;
    if let Some(points) = &g.lidar_points {
        return Some((splat_points(points, &k, size), DepthSource::LidarPoints));
    }
    let d = g.depth.as_ref()?;
    Some(if d.sparse {
        (resample_map(d, &k, size), DepthSource::LidarGrid)
    } else {
        (sample_dense(d, &k, size), DepthSource::Dense)
    })
}

/// One frame's dynamic mask on the `(h, w)` frame grid: copied when the grids agree, else
/// sampled at the frame's pixel centres through the source intrinsics (those of its depth
/// map, which shares the source grid); `None` without a mask or a way to map it.
fn dynamic_mask(g: &FrameGt, source: (usize, usize), size: (usize, usize)) -> Option<Vec<bool>> {
    let mask = g.dynamic_mask.as_ref()?;
    if source == size {
        return Some(mask.clone());
    }
    let (k, d) = (g.intrinsics?, g.depth.as_ref()?);
    Some(sample_nearest(mask, source, &d.intrinsics, &k, size))
}

/// One frame's motion truth on the `(h, w)` frame grid, from its dense depth, instance map,
/// camera and object poses; `None` when any of them is missing or the depth is sparse
/// (LiDAR cells have no surface behind every pixel).
fn motion_truth(
    g: &FrameGt,
    source: (usize, usize),
    size: (usize, usize),
) -> Option<FrameMotionTruth> {
    let (k, w2c, d) = (g.intrinsics?, g.world_to_camera?, g.depth.as_ref()?);
    let (instance, objects) = (g.instance.as_ref()?, g.objects.clone()?);
    let grid = (d.map.height, d.map.width);
    if d.sparse || grid != source || d.map.channels != 1 || instance.len() != grid.0 * grid.1 {
        return None;
    }
    Some(FrameMotionTruth::from_maps(
        &d.map.data,
        instance,
        grid,
        &d.intrinsics,
        &k,
        size,
        w2c,
        objects,
    ))
}
