//! Dataset layouts on disk: scanning a root into clip entries, and loading one entry.
//!
//! Scanning only lists files (cheap); decoding happens in [`load_clip`], so one bad image
//! costs one clip, not the dataset.

pub mod folder;
pub mod nuscenes;
mod nuscenes_splits;
pub mod nuscenes_tables;
pub mod synth;
pub mod waymo;

use crate::clip::{Clip, ClipSpec, FrameGt};
use crate::error::{DataError, Result};
use crate::frame::{decode_image, is_frame_file};
use crate::resize::Fit;
use std::path::{Path, PathBuf};

/// Where a clip's ground truth comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum GtSource {
    None,
    /// A STORM-preprocessed Waymo scene folder, camera id, the clip's timesteps, and
    /// whether its LiDAR depth is read.
    Storm {
        scene_dir: PathBuf,
        camera: u32,
        timesteps: Vec<i64>,
        lidar: bool,
    },
    /// Resolved nuScenes keyframes of the clip (poses and LiDAR paths from the tables).
    NuScenes {
        frames: Vec<nuscenes::NuFrame>,
    },
    /// One of our synthetic clip folders and the clip's frame indices.
    Synth {
        clip_dir: PathBuf,
        indices: Vec<usize>,
    },
}

/// One clip before decoding.
#[derive(Debug, Clone, PartialEq)]
pub struct ClipEntry {
    /// Unique within the dataset, e.g. `street_taxi_pan@0` or `validation/007#3`.
    pub id: String,
    /// Clips of one video/scene share a group, so splits never leak a scene across them.
    pub group: String,
    pub frames: Vec<PathBuf>,
    /// Each frame's number in its source: the Waymo timestep, the synthetic frame index, the
    /// position in a folder or a nuScenes scene's keyframe index (what `--list-windows` shows).
    pub frame_numbers: Vec<i64>,
    pub gt: GtSource,
}

/// Result of scanning a root: usable entries and one message per skipped source.
#[derive(Debug, Default)]
pub struct Scan {
    pub entries: Vec<ClipEntry>,
    pub skipped: Vec<String>,
}

/// The image files directly inside `dir`, sorted by file name.
pub fn list_frames(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut frames: Vec<PathBuf> = read_dir_sorted(dir)?
        .into_iter()
        .filter(|p| p.is_file() && is_frame_file(p))
        .collect();
    frames.sort_by(|a, b| a.file_name().cmp(&b.file_name()));
    Ok(frames)
}

/// Entries of `dir`, sorted by path.
pub(crate) fn read_dir_sorted(dir: &Path) -> Result<Vec<PathBuf>> {
    let rd = std::fs::read_dir(dir).map_err(|e| DataError::io(dir, e))?;
    let mut out = Vec::new();
    for entry in rd {
        out.push(entry.map_err(|e| DataError::io(dir, e))?.path());
    }
    out.sort();
    Ok(out)
}

/// Start indices of windows spanning `len` frames (`ClipSpec::span`) every `stride` frames
/// over `n` frames.
pub fn window_starts(n: usize, len: usize, stride: usize) -> Vec<usize> {
    if len == 0 || stride == 0 || n < len {
        return Vec::new();
    }
    (0..=n - len).step_by(stride).collect()
}

/// Decodes and fits a clip's frames and reads its ground truth. Any bad frame or GT file
/// fails the whole clip with an error naming the file.
pub fn load_clip(entry: &ClipEntry, spec: &ClipSpec, fit: &Fit) -> Result<Clip> {
    let first = entry
        .frames
        .first()
        .ok_or_else(|| DataError::TooFewFrames {
            path: PathBuf::from(&entry.id),
            found: 0,
            needed: spec.num_frames(),
        })?;
    if entry.frames.len() < spec.num_frames() {
        return Err(DataError::TooFewFrames {
            path: first.clone(),
            found: entry.frames.len(),
            needed: spec.num_frames(),
        });
    }
    let mut frames = Vec::with_capacity(entry.frames.len());
    let mut source_size = (0, 0);
    for (i, path) in entry.frames.iter().enumerate() {
        let img = decode_image(path)?;
        if i == 0 {
            source_size = (img.height, img.width);
        } else if (img.height, img.width) != source_size {
            return Err(DataError::MixedSizes {
                path: path.clone(),
                found_w: img.width,
                found_h: img.height,
                want_w: source_size.1,
                want_h: source_size.0,
            });
        }
        frames.push(fit.apply(&img, path)?);
    }
    let gt: Vec<FrameGt> = match &entry.gt {
        GtSource::None => Vec::new(),
        GtSource::Storm {
            scene_dir,
            camera,
            timesteps,
            lidar,
        } => waymo::load_storm_gt(scene_dir, *camera, timesteps, *lidar, source_size, fit)?,
        GtSource::NuScenes { frames } => nuscenes::load_nuscenes_gt(frames, source_size, fit)?,
        GtSource::Synth { clip_dir, indices } => {
            synth::load_synth_gt(clip_dir, indices, source_size, fit)?
        }
    };
    Ok(Clip {
        id: entry.id.clone(),
        frames,
        source_size,
        gt,
        frame_paths: entry.frames.clone(),
    })
}
