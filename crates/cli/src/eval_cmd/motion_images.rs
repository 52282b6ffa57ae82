//! `eval --motion-images N`: for the first N scored clips that have motion truth, one PNG of
//! three panels side by side, the true displacement length, the predicted one and the
//! end-point error of pair (`T_c − 1` → `N − 1`) per pixel, on one colour scale from 0 to
//! `scale_max_m` metres (sky, which has no truth, grey), enlarged `enlarged` times (nearest
//! neighbour), and a JSON sidecar with both.

use crate::image_out::write_rgb;
use crate::render_cmd::colormap::ramp;
use anyhow::{Context, Result};
use envision4d_eval::motion_maps::PairMaps;
use std::path::Path;

/// Sub-folder of the images.
pub const MOTION_IMAGES_DIR: &str = "motion";
/// The colour scale never ends below this (metres): a clip whose movers hardly move still
/// shows errors of a few centimetres as dark.
const SCALE_FLOOR_M: f32 = 0.1;
/// Pixels between the panels.
const GAP: usize = 2;
/// Pixels without truth.
const NO_TRUTH: [f32; 3] = [0.35, 0.35, 0.35];

/// The three panels as one RGB image `(width, pixels)`.
fn panels(m: &PairMaps, scale: f32) -> (usize, Vec<f32>) {
    let (h, w) = m.size;
    let width = 3 * w + 2 * GAP;
    let mut rgb = vec![1.0f32; width * h * 3];
    for (p, values) in [&m.truth, &m.predicted, &m.error].into_iter().enumerate() {
        for y in 0..h {
            for x in 0..w {
                let v = values[y * w + x];
                let c = if v.is_finite() {
                    ramp(v / scale)
                } else {
                    NO_TRUTH
                };
                let at = (y * width + p * (w + GAP) + x) * 3;
                rgb[at..at + 3].copy_from_slice(&c);
            }
        }
    }
    (width, rgb)
}

/// Small frames are enlarged by an integer factor (nearest neighbour, so every model pixel
/// stays one flat block) until a panel is at least this tall.
const MIN_PANEL_HEIGHT: usize = 160;

/// `rgb` (`width x height`) enlarged `factor` times in both directions.
fn enlarge(width: usize, height: usize, rgb: &[f32], factor: usize) -> Vec<f32> {
    let mut out = Vec::with_capacity(rgb.len() * factor * factor);
    for y in 0..height * factor {
        for x in 0..width * factor {
            let at = ((y / factor) * width + x / factor) * 3;
            out.extend_from_slice(&rgb[at..at + 3]);
        }
    }
    out
}

/// A clip id as a file name (`clip_000003@0` → `clip_000003_0`).
pub fn file_stem(clip: &str) -> String {
    clip.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Integer enlargement of `m`'s panels.
fn enlargement(m: &PairMaps) -> usize {
    MIN_PANEL_HEIGHT.div_ceil(m.size.0.max(1)).max(1)
}

/// Writes `m`'s three panels (enlarged) as one PNG at `path`; returns the colour scale's
/// top (metres).
pub fn motion_panel(path: &Path, m: &PairMaps) -> Result<f32> {
    let scale = m.scale_max(SCALE_FLOOR_M);
    let (width, rgb) = panels(m, scale);
    let factor = enlargement(m);
    let rgb = enlarge(width, m.size.0, &rgb, factor);
    write_rgb(path, width * factor, m.size.0 * factor, &rgb)?;
    Ok(scale)
}

/// Writes the images of `maps` (clip id, maps); returns how many were written.
pub fn write_motion_images(out: &Path, maps: &[(String, PairMaps)]) -> Result<usize> {
    let dir = out.join(MOTION_IMAGES_DIR);
    let mut written = 0;
    for (clip, m) in maps {
        if written == 0 {
            envision4d_data::atomic::create_dir(&dir)
                .with_context(|| format!("creating {}", dir.display()))?;
        }
        let stem = format!("{}_{}to{}", file_stem(clip), m.source, m.target);
        let scale = motion_panel(&dir.join(format!("{stem}.png")), m)?;
        let factor = enlargement(m);
        let side = serde_json::json!({
            "clip": clip,
            "source": m.source,
            "target": m.target,
            "scale_max_m": scale,
            "enlarged": factor,
            "panels": ["true displacement length (m)", "predicted displacement length (m)", "end-point error (m)"],
            "colormap": "viridis from 0 to scale_max_m, clamped; grey: no truth (sky)",
        });
        let path = dir.join(format!("{stem}.json"));
        let text = serde_json::to_string_pretty(&side).context("motion image sidecar")?;
        envision4d_data::atomic::write_bytes(&path, text.as_bytes())
            .with_context(|| format!("writing {}", path.display()))?;
        written += 1;
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the panel layout: truth, prediction and error side by side with white gaps,
    /// one shared scale (the same value has the same colour in every panel), and grey where
    /// there is no truth.
    #[test]
    fn three_panels_one_scale() {
        let m = PairMaps {
            source: 1,
            target: 7,
            size: (1, 2),
            truth: vec![f32::NAN, 1.0],
            predicted: vec![0.5, 1.0],
            error: vec![f32::NAN, 0.0],
        };
        let (width, rgb) = panels(&m, 1.0);
        assert_eq!(width, 3 * 2 + 2 * GAP);
        let px = |x: usize| [rgb[3 * x], rgb[3 * x + 1], rgb[3 * x + 2]];
        assert_eq!(px(0), NO_TRUTH);
        assert_eq!(px(1), ramp(1.0));
        assert_eq!(px(2), [1.0; 3]);
        assert_eq!(px(2 + GAP + 1), ramp(1.0));
        assert_eq!(px(2 * (2 + GAP) + 1), ramp(0.0));
        assert_eq!(file_stem("clip_000003@0"), "clip_000003_0");
        let big = enlarge(width, 1, &rgb, 2);
        assert_eq!(big.len(), rgb.len() * 4);
        assert_eq!(big[..6], [rgb[0], rgb[1], rgb[2], rgb[0], rgb[1], rgb[2]]);
        assert_eq!(big[3 * 2 * width..3 * 2 * width + 3], rgb[..3]);
    }
}
