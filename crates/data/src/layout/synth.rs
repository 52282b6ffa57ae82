//! Our synthetic layout (written by `synth::write_clip`, documented in docs/DATA.md):
//! `<root>/clip_<n:06d>/{rgb,depth,flow,dynamic_mask,instance}/<t:06d>.*`, `cameras.json`,
//! `tracks.json`, `meta.json`. The JSON types live here so writer and reader share them.

use super::{list_frames, read_dir_sorted, window_starts, ClipEntry, GtSource, Scan};
use crate::clip::{ClipSpec, DepthMap, FrameGt};
use crate::error::{DataError, Result};
use crate::exr_io::{read_gray, read_xyz};
use crate::geom::{Intrinsics, Mat4};
use crate::motion_truth::poses_at;
use crate::resize::Fit;
use serde::{Deserialize, Serialize};
use std::path::Path;

pub const CAMERAS_FILE: &str = "cameras.json";
pub const TRACKS_FILE: &str = "tracks.json";
pub const META_FILE: &str = "meta.json";
pub const RGB_DIR: &str = "rgb";
pub const DEPTH_DIR: &str = "depth";
pub const FLOW_DIR: &str = "flow";
pub const MASK_DIR: &str = "dynamic_mask";
pub const INSTANCE_DIR: &str = "instance";

/// File name of frame `t` with extension `ext`.
pub fn frame_name(t: usize, ext: &str) -> String {
    format!("{t:06}.{ext}")
}

/// One frame's camera in `cameras.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraRecord {
    pub t: usize,
    pub time_s: f64,
    pub intrinsics: Intrinsics,
    /// OpenCV world-to-camera, row-major 4x4.
    pub world_to_camera: Mat4,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CamerasFile {
    pub width: usize,
    pub height: usize,
    pub frames: Vec<CameraRecord>,
}

/// One object's state at one frame in `tracks.json` (world frame, metres, radians).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrackState {
    pub t: usize,
    /// Centre of the object's bounding box.
    pub position: [f64; 3],
    /// Rotation about world +z (up), 0 = facing world +x.
    pub yaw: f64,
    /// Box centre displacement to frame t+1, divided by the frame interval.
    pub velocity: [f64; 3],
    /// True when the object moves between t and t+1 (it is in the dynamic mask at t).
    pub moving: bool,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Track {
    /// The value of this object's pixels in `instance/*.png` (>= 1).
    pub id: u16,
    pub kind: String,
    /// Box extents (length along heading, width, height) in metres.
    pub size: [f64; 3],
    /// How it moves, in words (e.g. "lane change", "braking").
    pub motion: String,
    pub states: Vec<TrackState>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TracksFile {
    pub tracks: Vec<Track>,
}

/// Reads and parses a JSON file, naming it in errors.
pub fn read_json<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<T> {
    let text = std::fs::read_to_string(path).map_err(|e| DataError::gt(path, e.to_string()))?;
    serde_json::from_str(&text).map_err(|e| DataError::gt(path, e.to_string()))
}

pub fn scan(root: &Path, spec: &ClipSpec, stride: usize) -> Result<Scan> {
    if stride == 0 {
        return Err(DataError::config("stride", 0, "must be at least 1"));
    }
    let mut scan = Scan::default();
    // cameras.json is written last: a clip folder without it is incomplete. Count it as a
    // skipped clip rather than ignoring it silently.
    let (dirs, incomplete): (Vec<_>, Vec<_>) = read_dir_sorted(root)?
        .into_iter()
        .filter(|p| p.is_dir())
        .partition(|p| p.join(CAMERAS_FILE).is_file());
    for dir in incomplete {
        scan.skipped.push(format!(
            "{}: incomplete synthetic clip (no {CAMERAS_FILE})",
            dir.display()
        ));
    }
    if dirs.is_empty() {
        return Err(DataError::EmptyFolder {
            path: root.to_path_buf(),
        });
    }
    for dir in dirs {
        let name = dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let frames = match list_frames(&dir.join(RGB_DIR)) {
            Ok(f) => f,
            Err(e) => {
                scan.skipped.push(e.to_string());
                continue;
            }
        };
        // Ground truth is indexed by the frame number in the file name, never by the position
        // in the listing: a missing or extra file must not pair a frame with another frame's
        // cameras, depth and flow.
        let mut numbered = Vec::with_capacity(frames.len());
        let mut bad_name = None;
        for f in &frames {
            match f
                .file_stem()
                .and_then(|s| s.to_str())
                .and_then(|s| s.parse::<usize>().ok())
            {
                Some(t) => numbered.push((t, f.clone())),
                None => bad_name = Some(f.clone()),
            }
        }
        if let Some(f) = bad_name {
            scan.skipped.push(format!(
                "{}: synthetic frames are named by frame number ({}); skipping the clip",
                f.display(),
                frame_name(0, "png")
            ));
            continue;
        }
        let starts = window_starts(numbered.len(), spec.span(), stride);
        if starts.is_empty() {
            let err = DataError::TooFewFrames {
                path: dir.join(RGB_DIR),
                found: frames.len(),
                needed: spec.span(),
            };
            scan.skipped.push(err.to_string());
        }
        for s in starts {
            // The window's source frames must be consecutive in the clip (no frame missing in
            // between), taken every `frame_step`-th.
            let span = &numbered[s..s + spec.span()];
            let first = span[0].0;
            if span.iter().enumerate().any(|(k, (t, _))| *t != first + k) {
                scan.skipped.push(format!(
                    "{}: frames {first}.. are not consecutive; skipping that window",
                    dir.join(RGB_DIR).display()
                ));
                continue;
            }
            let window: Vec<_> = spec.frames_from(s).map(|i| &numbered[i]).collect();
            scan.entries.push(ClipEntry {
                id: format!("{name}@{s}"),
                group: name.clone(),
                frames: window.iter().map(|(_, p)| p.clone()).collect(),
                frame_numbers: window.iter().map(|(t, _)| *t as i64).collect(),
                gt: GtSource::Synth {
                    clip_dir: dir.clone(),
                    indices: window.iter().map(|(t, _)| *t).collect(),
                },
            });
        }
    }
    Ok(scan)
}

/// A ground-truth PNG of the frame's `(h, w)` size, decoded; `what` names it in the error.
fn read_frame_png(path: &Path, (h, w): (usize, usize), what: &str) -> Result<image::DynamicImage> {
    let bytes = std::fs::read(path).map_err(|e| DataError::gt(path, e.to_string()))?;
    let img = image::load_from_memory(&bytes).map_err(|e| DataError::gt(path, e.to_string()))?;
    if (img.height() as usize, img.width() as usize) != (h, w) {
        return Err(DataError::gt(
            path,
            format!("{what} size differs from the frame size"),
        ));
    }
    Ok(img)
}

/// A `dynamic_mask/*.png` (8-bit, 255 = moving) as booleans; it must have the frame's size.
fn read_mask(path: &Path, size: (usize, usize)) -> Result<Vec<bool>> {
    let img = read_frame_png(path, size, "mask")?.to_luma8();
    Ok(img.into_raw().iter().map(|&v| v >= MASK_ON).collect())
}

/// `tracks.json`'s tracks; `None` when the clip has no such file (a tree written before
/// tracks existed has no pairwise flow truth, nothing else is lost). A file that is there but
/// does not parse is an error naming it.
fn read_tracks(path: &Path) -> Result<Option<Vec<Track>>> {
    if !path.exists() {
        return Ok(None);
    }
    Ok(Some(read_json::<TracksFile>(path)?.tracks))
}

/// An `instance/*.png` (16-bit object ids) of the frame's size; `None` when absent.
fn read_instance(path: &Path, size: (usize, usize)) -> Result<Option<Vec<u16>>> {
    if !path.exists() {
        return Ok(None);
    }
    let img = read_frame_png(path, size, "instance map")?.to_luma16();
    Ok(Some(img.into_raw()))
}

/// Mask values at or above this are "moving" (the writer uses 0 and 255).
const MASK_ON: u8 = 128;

/// Cameras, depth and flow of the given frames of a synthetic clip.
pub fn load_synth_gt(
    dir: &Path,
    indices: &[usize],
    source_size: (usize, usize),
    fit: &Fit,
) -> Result<Vec<FrameGt>> {
    let cams_path = dir.join(CAMERAS_FILE);
    let cams: CamerasFile = read_json(&cams_path)?;
    if (cams.height, cams.width) != source_size {
        return Err(DataError::gt(
            &cams_path,
            format!(
                "cameras are for {}x{} (WxH) but the frames are {}x{}",
                cams.width, cams.height, source_size.1, source_size.0
            ),
        ));
    }
    let tracks = read_tracks(&dir.join(TRACKS_FILE))?;
    let mut out = Vec::with_capacity(indices.len());
    for &t in indices {
        let cam = cams
            .frames
            .iter()
            .find(|c| c.t == t)
            .ok_or_else(|| DataError::gt(&cams_path, format!("no camera for frame t = {t}")))?;
        let depth_path = dir.join(DEPTH_DIR).join(frame_name(t, "exr"));
        let depth = read_gray(&depth_path)?;
        let flow_path = dir.join(FLOW_DIR).join(frame_name(t, "exr"));
        let flow = read_xyz(&flow_path)?;
        if (depth.height, depth.width) != source_size {
            return Err(DataError::gt(
                &depth_path,
                "depth size differs from the frame size",
            ));
        }
        // A flow map of the wrong size would make later per-pixel reads go out of bounds.
        if (flow.height, flow.width) != source_size || flow.channels != 3 {
            return Err(DataError::gt(
                &flow_path,
                "flow must be a 3-channel map of the frame size",
            ));
        }
        out.push(FrameGt {
            intrinsics: Some(fit.intrinsics(&cam.intrinsics, source_size)),
            world_to_camera: Some(cam.world_to_camera),
            ego_to_world: None,
            depth: Some(DepthMap {
                map: depth,
                intrinsics: cam.intrinsics,
                sparse: false,
            }),
            lidar_points: None,
            flow: Some(flow),
            dynamic_mask: Some(read_mask(
                &dir.join(MASK_DIR).join(frame_name(t, "png")),
                source_size,
            )?),
            instance: match &tracks {
                Some(_) => read_instance(
                    &dir.join(INSTANCE_DIR).join(frame_name(t, "png")),
                    source_size,
                )?,
                None => None,
            },
            objects: tracks.as_ref().map(|tr| poses_at(tr, t)),
        });
    }
    Ok(out)
}
