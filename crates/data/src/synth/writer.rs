//! Writes a rendered clip in our synthetic layout (see `layout::synth` and docs/DATA.md).
//! Every file is written atomically; output bytes depend only on the config and seed.

use super::ClipRender;
use crate::atomic::{create_dir, write_bytes};
use crate::error::{DataError, Result};
use crate::exr_io::{write_gray, write_xyz, FloatMap};
use crate::frame::{encode_png, encode_png_rgb8, Image};
use crate::layout::synth::{
    frame_name, CamerasFile, TracksFile, CAMERAS_FILE, DEPTH_DIR, FLOW_DIR, INSTANCE_DIR, MASK_DIR,
    META_FILE, RGB_DIR, TRACKS_FILE,
};
use serde::Serialize;
use std::path::Path;

#[derive(Serialize)]
struct Meta<'a> {
    generator: &'static str,
    format_version: u32,
    preset: &'a str,
    seed: u64,
    clip_index: u64,
    width: usize,
    height: usize,
    frames: usize,
    supersample: usize,
    frame_interval_s: f64,
}

fn json_bytes<T: Serialize>(path: &Path, value: &T) -> Result<Vec<u8>> {
    serde_json::to_vec_pretty(value).map_err(|e| DataError::Write {
        path: path.to_path_buf(),
        msg: e.to_string(),
    })
}

fn png(path: &Path, bytes: std::result::Result<Vec<u8>, String>) -> Result<()> {
    let bytes = bytes.map_err(|msg| DataError::Write {
        path: path.to_path_buf(),
        msg,
    })?;
    write_bytes(path, &bytes)
}

/// Writes `clip` into `dir` (created if needed).
pub fn write_clip(dir: &Path, clip: &ClipRender) -> Result<()> {
    let cfg = &clip.config;
    let (w, h) = (cfg.width, cfg.height);
    for sub in [RGB_DIR, DEPTH_DIR, FLOW_DIR, MASK_DIR, INSTANCE_DIR] {
        create_dir(&dir.join(sub))?;
    }
    for (t, f) in clip.frames.iter().enumerate() {
        let rgb = Image::new(w, h, f.rgb.clone());
        let p = dir.join(RGB_DIR).join(frame_name(t, "png"));
        png(&p, encode_png_rgb8(&rgb))?;
        let depth = FloatMap {
            width: w,
            height: h,
            channels: 1,
            data: f.depth.clone(),
        };
        write_gray(&dir.join(DEPTH_DIR).join(frame_name(t, "exr")), &depth)?;
        let flow = FloatMap {
            width: w,
            height: h,
            channels: 3,
            data: f.flow.clone(),
        };
        write_xyz(&dir.join(FLOW_DIR).join(frame_name(t, "exr")), &flow)?;
        // Dynamic mask: pixels of tracks that move between t and t+1.
        let moving: Vec<u16> = clip
            .tracks
            .iter()
            .filter(|tr| tr.states.iter().any(|s| s.t == t && s.moving))
            .map(|tr| tr.id)
            .collect();
        let mask: Vec<u8> = f
            .instance
            .iter()
            .map(|id| {
                if *id > 0 && moving.contains(id) {
                    255
                } else {
                    0
                }
            })
            .collect();
        let p = dir.join(MASK_DIR).join(frame_name(t, "png"));
        png(&p, encode_png(w, h, image::ExtendedColorType::L8, &mask))?;
        // `image`'s encoder takes native-endian 16-bit samples and swaps them to PNG's order.
        let inst: Vec<u8> = f.instance.iter().flat_map(|v| v.to_ne_bytes()).collect();
        let p = dir.join(INSTANCE_DIR).join(frame_name(t, "png"));
        png(&p, encode_png(w, h, image::ExtendedColorType::L16, &inst))?;
    }
    let cams = CamerasFile {
        width: w,
        height: h,
        frames: clip.cameras.clone(),
    };
    let p = dir.join(CAMERAS_FILE);
    write_bytes(&p, &json_bytes(&p, &cams)?)?;
    let tracks = TracksFile {
        tracks: clip.tracks.clone(),
    };
    let p = dir.join(TRACKS_FILE);
    write_bytes(&p, &json_bytes(&p, &tracks)?)?;
    let meta = Meta {
        generator: "envision4d synth",
        format_version: 1,
        preset: cfg.preset.name(),
        seed: cfg.seed,
        clip_index: clip.clip_index,
        width: w,
        height: h,
        frames: cfg.frames,
        supersample: cfg.supersample,
        frame_interval_s: super::FRAME_INTERVAL_S,
    };
    let p = dir.join(META_FILE);
    write_bytes(&p, &json_bytes(&p, &meta)?)
}
