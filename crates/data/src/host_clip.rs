//! A decoded clip as the model consumes it, still on the host (no tensors): frames planar
//! CHW in [0, 1], with the ground truth the layout provides.

use crate::clip::Clip;
use crate::error::{DataError, Result};
use crate::geom::{Intrinsics, Mat4};

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
        Ok(HostClip {
            height: h,
            width: w,
            frames,
            cameras,
            depths,
        })
    }
}
