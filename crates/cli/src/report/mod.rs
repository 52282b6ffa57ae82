//! `report.html`, written by `eval` and `demo` beside `metrics.json`: one self-contained page
//! that works offline (no scripts, no network references; images are files beside it): the
//! settings and metric tables of `metrics.md`, the plots, and the worst and best clips as
//! strips of ground truth | model | copy-last | static+cv per horizon, with the model's depth,
//! the true dynamic mask and the motion panels.

pub mod gallery;
pub mod markdown;
pub mod strips;

use anyhow::{Context, Result};
use envision4d_eval::report::Report;
use gallery::Gallery;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The page's file name.
pub const REPORT_HTML: &str = "report.html";
/// Where `metrics.md`'s detailed tables start (shown after the clips).
const DETAIL_HEADING: &str = "\n## Per future horizon";
/// Clips shown by default (half worst, half best).
pub const DEFAULT_CLIPS: usize = 6;

const STYLE: &str = "body{font-family:system-ui,sans-serif;margin:1.5em auto;max-width:76em;\
padding:0 1em;color:#1d1d22;background:#fcfcfd}table{border-collapse:collapse;margin:.6em 0 1.2em}\
th,td{border:1px solid #d6d6de;padding:.25em .55em;text-align:right;vertical-align:top}\
th{background:#eef0f5}td:first-child,th:first-child{text-align:left}code{background:#eef0f5;\
padding:0 .2em}.plots img{max-width:48%;margin:.3em}.strip td{text-align:center;font-size:.85em}\
.strip img{width:13em;height:auto;image-rendering:pixelated;display:block}\
.panel{width:40em;max-width:100%;height:auto;image-rendering:pixelated}\
.tag{font-size:.7em;padding:.1em .5em;border-radius:.8em;color:#fff;vertical-align:middle}\
.worst{background:#b3261e}.best{background:#1e6b3a}.only{background:#5b5b66}section.clip{margin:1.5em 0}";

/// Writes the shown clips' images and `out/report.html` (atomically); `markdown` is the
/// text of `metrics.md`, `plots` the PNGs written beside it. Returns the page's path.
pub fn write_report(
    out: &Path,
    report: &Report,
    markdown: &str,
    plots: &[PathBuf],
    gallery: Gallery,
) -> Result<PathBuf> {
    let mut html = String::new();
    writeln!(
        html,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width\">\
         <title>Envision4D evaluation: {}</title><style>{STYLE}</style></head><body>",
        markdown::escape(&report.data)
    )?;
    let shown = gallery.into_ordered();
    if !shown.is_empty() {
        html.push_str(
            "<p><a href=\"#clips\">Clips: worst and best</a> · <a href=\"#plots\">Plots</a></p>\n",
        );
    }
    // The headline tables, then the pictures, then the long per-horizon and per-clip tables.
    let (head, detail) = markdown
        .find(DETAIL_HEADING)
        .map_or((markdown, ""), |i| markdown.split_at(i));
    html.push_str(&markdown::to_html(head, 0));
    html.push_str("<h2 id=\"plots\">Plots</h2>\n<div class=\"plots\">");
    for p in plots {
        let name = p
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        write!(
            html,
            "<img src=\"{0}\" alt=\"{0}\">",
            markdown::escape(&name)
        )?;
    }
    html.push_str("</div>\n");
    if !shown.is_empty() {
        writeln!(
            html,
            "<h2 id=\"clips\">Clips: worst and best</h2>\n<p>{} of {} clips, ranked by the \
             model's future-frame PSNR (worst first, then best); each row is one future \
             frame, with its PSNR under each method.</p>",
            shown.len(),
            report.clips_evaluated
        )?;
        // report/ is this page's own folder: an earlier run's clips leave with it.
        let dir = out.join(strips::REPORT_DIR);
        if dir.is_dir() {
            std::fs::remove_dir_all(&dir).with_context(|| format!("clearing {}", dir.display()))?;
        }
        for (rank, (kind, clip)) in shown.iter().enumerate() {
            html.push_str(&strips::write_clip(out, rank, kind, clip)?);
        }
    }
    html.push_str(&markdown::to_html(detail, 0));
    html.push_str("</body></html>\n");
    let path = out.join(REPORT_HTML);
    envision4d_data::atomic::write_bytes(&path, html.as_bytes())
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(path)
}
