//! One shown clip on disk and in the page: per future horizon a row of ground truth, the
//! model and the two image baselines (each PSNR under it), the model's rendered depth and
//! the true dynamic mask; under the rows, the motion panels (true, predicted, error) where
//! the data has exact scene flow.

use super::gallery::Shown;
use super::markdown::escape;
use crate::eval_cmd::motion_images::{file_stem, motion_panel};
use crate::image_out::write_rgb;
use crate::render_cmd::colormap::depth_colors;
use anyhow::Result;
use envision4d_losses::HostImages;
use std::fmt::Write as _;
use std::path::Path;

/// Folder (beside `report.html`) of the shown clips' images.
pub const REPORT_DIR: &str = "report";
/// Mask colours: moving pixels, the rest.
const MOVING: [f32; 3] = [1.0, 0.45, 0.1];
const STILL: [f32; 3] = [0.12, 0.12, 0.16];

/// `[H * W * 3]` interleaved RGB of frame `n` of `[N, 3, H, W]` images.
fn interleaved(images: &HostImages, n: usize) -> Vec<f32> {
    let [_, _, h, w] = images.shape();
    let planes = images.image(n);
    (0..h * w)
        .flat_map(|i| (0..3).map(move |c| planes[c * h * w + i] as f32))
        .collect()
}

/// Writes `shown`'s images under `out/report/<rank>_<clip>/` (the rank keeps two clip ids
/// that clean to one file name apart); returns its HTML section.
pub fn write_clip(out: &Path, rank: usize, kind: &str, shown: &Shown) -> Result<String> {
    let stem = format!("{rank}_{}", file_stem(&shown.clip));
    let rel = format!("{REPORT_DIR}/{stem}");
    let dir = out.join(&rel);
    envision4d_data::atomic::create_dir(&dir)?;
    let im = &shown.images;
    let (h, w) = im.size();
    let mut html = String::new();
    let psnr = shown.psnr();
    writeln!(
        html,
        "<section class=\"clip\"><h3>{} <span class=\"tag {kind}\">{kind}</span> model {psnr:.2} dB</h3>",
        escape(&shown.clip)
    )?;
    html.push_str("<table class=\"strip\"><thead><tr><th>horizon</th><th>ground truth</th>");
    for (m, _) in &im.methods {
        write!(html, "<th>{}</th>", m.label())?;
    }
    html.push_str("<th>model depth</th><th>true dynamic mask</th></tr></thead><tbody>\n");
    for k in 0..im.frames() {
        let img = |name: &str, rgb: &[f32]| -> Result<String> {
            let file = format!("h{}_{name}.png", k + 1);
            write_rgb(&dir.join(&file), w, h, rgb)?;
            Ok(format!("<img src=\"{rel}/{file}\" width=\"{w}\" height=\"{h}\" alt=\"{name}, horizon {}\">", k + 1))
        };
        write!(html, "<tr><td>{}<br>frame {}</td>", k + 1, im.context + k)?;
        write!(
            html,
            "<td>{}</td>",
            img("truth", &interleaved(&im.ground_truth, k))?
        )?;
        for (m, frames) in &im.methods {
            let score = shown
                .methods
                .iter()
                .find(|s| s.method == *m)
                .and_then(|s| s.per_horizon.get(k))
                .map_or(String::new(), |s| format!("<br>{:.2} dB", s.psnr));
            let name = m.label().replace(['+', ' '], "-");
            write!(
                html,
                "<td>{}{score}</td>",
                img(&name, &interleaved(frames, k))?
            )?;
        }
        let depth = im.depth_map(k);
        let colors = depth_colors(depth, &vec![1.0; depth.len()]);
        write!(html, "<td>{}</td>", img("depth", &colors)?)?;
        match im.dynamic_masks.get(k).and_then(Option::as_ref) {
            Some(mask) => {
                let rgb: Vec<f32> = mask
                    .iter()
                    .flat_map(|&m| if m { MOVING } else { STILL })
                    .collect();
                write!(html, "<td>{}</td>", img("mask", &rgb)?)?;
            }
            None => html.push_str("<td>no mask</td>"),
        }
        html.push_str("</tr>\n");
    }
    html.push_str("</tbody></table>\n");
    if let Some(m) = &shown.maps {
        let file = format!("motion_{}to{}.png", m.source, m.target);
        let scale = motion_panel(&dir.join(&file), m)?;
        writeln!(
            html,
            "<figure><img src=\"{rel}/{file}\" class=\"panel\" alt=\"motion {}→{}\"><figcaption>Frame {} → {}: true displacement | predicted | end-point error, metres, one colour scale 0–{scale:.2} m (grey: no truth).</figcaption></figure>",
            m.source, m.target, m.source, m.target
        )?;
    }
    html.push_str("</section>\n");
    Ok(html)
}
