//! What a loaded clip is: frames, their size before fitting, and optional ground truth.

use crate::error::{DataError, Result};
use crate::exr_io::FloatMap;
use crate::frame::Image;
use crate::geom::{Intrinsics, Mat4};
use std::path::PathBuf;

/// Frames per clip: the first `context` are the model's input, the rest are predicted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClipSpec {
    pub context: usize,
    pub future: usize,
    /// Source frames from one clip frame to the next: 1 takes consecutive frames, 2 every
    /// other one (a 10 Hz recording played at 5 Hz, so everything moves twice as far between
    /// the model's frames).
    pub frame_step: usize,
}

impl Default for ClipSpec {
    /// The paper's T_c = T_f = 2 (spec §1: N = 4), consecutive frames.
    fn default() -> Self {
        ClipSpec {
            context: 2,
            future: 2,
            frame_step: 1,
        }
    }
}

impl ClipSpec {
    pub fn num_frames(&self) -> usize {
        self.context + self.future
    }
    /// Source frames a window covers, first to last: `(num_frames - 1) · frame_step + 1`.
    pub fn span(&self) -> usize {
        self.num_frames()
            .saturating_sub(1)
            .saturating_mul(self.frame_step)
            .saturating_add(1)
    }
    /// Source-frame indices of the window that starts at source frame `start`.
    pub fn frames_from(&self, start: usize) -> impl Iterator<Item = usize> + '_ {
        (0..self.num_frames()).map(move |k| start + k * self.frame_step)
    }
    pub fn validate(&self) -> Result<()> {
        if self.context == 0 {
            return Err(DataError::config(
                "context",
                0,
                "need at least one context frame",
            ));
        }
        if self.frame_step == 0 {
            return Err(DataError::config("frame_step", 0, "must be at least 1"));
        }
        Ok(())
    }
}

/// A depth map on its own pixel grid (e.g. STORM's quarter-resolution LiDAR), with the
/// intrinsics valid for that grid. Values are z-depth in metres; 0 = no measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthMap {
    pub map: FloatMap,
    pub intrinsics: Intrinsics,
    /// LiDAR-like: most cells hold no measurement (0), so the map must never be
    /// interpolated. False for a rendered dense map (the synthetic layout).
    pub sparse: bool,
}

/// Optional per-frame ground truth. Intrinsics refer to the fitted (output) frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameGt {
    pub intrinsics: Option<Intrinsics>,
    /// OpenCV world-to-camera (x right, y down, z forward).
    pub world_to_camera: Option<Mat4>,
    /// Vehicle-to-world (STORM's `ego_to_world`).
    pub ego_to_world: Option<Mat4>,
    pub depth: Option<DepthMap>,
    /// LiDAR returns in this frame's OpenCV camera coordinates (metres), when the layout
    /// has points (STORM's `lidar/*.bin`); preferred over `depth` for evaluation.
    pub lidar_points: Option<Vec<[f32; 3]>>,
    /// Scene flow to the next frame, world frame, metres, on the depth grid (synthetic only).
    pub flow: Option<FloatMap>,
    /// Pixels of objects that move between this frame and the next, on the source grid
    /// (`H·W`, row-major; synthetic only).
    pub dynamic_mask: Option<Vec<bool>>,
    /// Object id per pixel (0 = static scenery or sky), on the source grid (synthetic only).
    pub instance: Option<Vec<u16>>,
    /// Every tracked object's box pose at this frame (synthetic only; `motion_truth`).
    pub objects: Option<Vec<crate::motion_truth::ObjectPose>>,
}

/// A decoded clip.
#[derive(Debug, Clone, PartialEq)]
pub struct Clip {
    pub id: String,
    /// Fitted frames, all the same size.
    pub frames: Vec<Image>,
    /// Size (H, W) of the source frames before fitting.
    pub source_size: (usize, usize),
    /// One entry per frame, or empty when the layout has no ground truth.
    pub gt: Vec<FrameGt>,
    pub frame_paths: Vec<PathBuf>,
}
