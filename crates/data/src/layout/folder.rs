//! Plain folders of frames (the in-the-wild case): either `root/` holds the frames of one
//! video, or each sub-folder `root/<video>/` does. Frames are sorted by file name; clips are
//! windows of `num_frames` frames every `stride` frames.

use super::{list_frames, read_dir_sorted, window_starts, ClipEntry, GtSource, Scan};
use crate::clip::ClipSpec;
use crate::error::{DataError, Result};
use std::path::Path;

pub fn scan(root: &Path, spec: &ClipSpec, stride: usize) -> Result<Scan> {
    if stride == 0 {
        return Err(DataError::config("stride", 0, "must be at least 1"));
    }
    if !root.is_dir() {
        return Err(DataError::io(
            root,
            std::io::Error::new(std::io::ErrorKind::NotFound, "folder not found"),
        ));
    }
    let mut scan = Scan::default();
    let direct = list_frames(root)?;
    let videos: Vec<_> = if direct.is_empty() {
        read_dir_sorted(root)?
            .into_iter()
            .filter(|p| p.is_dir())
            .collect()
    } else {
        vec![root.to_path_buf()]
    };
    if videos.is_empty() {
        return Err(DataError::EmptyFolder {
            path: root.to_path_buf(),
        });
    }
    for dir in videos {
        let name = dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let frames = if dir == root {
            direct.clone()
        } else {
            list_frames(&dir)?
        };
        if frames.is_empty() {
            scan.skipped
                .push(DataError::EmptyFolder { path: dir }.to_string());
            continue;
        }
        let starts = window_starts(frames.len(), spec.span(), stride);
        if starts.is_empty() {
            let err = DataError::TooFewFrames {
                path: dir,
                found: frames.len(),
                needed: spec.span(),
            };
            scan.skipped.push(err.to_string());
            continue;
        }
        for s in starts {
            scan.entries.push(ClipEntry {
                id: format!("{name}@{s}"),
                group: name.clone(),
                frames: spec.frames_from(s).map(|i| frames[i].clone()).collect(),
                frame_numbers: spec.frames_from(s).map(|i| i as i64).collect(),
                gt: GtSource::None,
            });
        }
    }
    Ok(scan)
}
