//! The evaluation plots (PNG): every metric against the future horizon, every metric
//! against the time spent per clip, and the sweep's Pareto front. Drawn with `plotters`
//! in an embedded font ([`chart`]), so no system font is needed.

mod chart;

use chart::{Draw, Panel, Series, XTicks};
use envision4d_eval::{ClipMetrics, HorizonScore, Method, MethodScore, Report, SweepPoint};
use std::io::Cursor;

/// Panels per row.
const COLUMNS: usize = 3;

/// A metric: its axis title and how to read it from each kind of score.
struct Metric {
    title: &'static str,
    horizon: fn(&HorizonScore) -> Option<f64>,
    method: fn(&MethodScore) -> Option<f64>,
    sweep: fn(&SweepPoint) -> Option<f64>,
}

/// The metric the sweep's Pareto front is defined on.
const PSNR_TITLE: &str = "PSNR (dB)";

const METRICS: [Metric; 5] = [
    Metric {
        title: PSNR_TITLE,
        horizon: |h| Some(h.psnr),
        method: |m| Some(m.psnr),
        sweep: |p| Some(p.psnr),
    },
    Metric {
        title: "SSIM",
        horizon: |h| Some(h.ssim),
        method: |m| Some(m.ssim),
        sweep: |p| Some(p.ssim),
    },
    Metric {
        title: "LPIPS",
        horizon: |h| h.lpips,
        method: |m| m.lpips,
        sweep: |p| p.lpips,
    },
    Metric {
        title: "Rotation error (deg)",
        horizon: |h| h.rot_err_deg,
        method: |m| m.rot_err_deg,
        sweep: |p| p.rot_err_deg,
    },
    Metric {
        title: "Translation error (m)",
        horizon: |h| h.trans_err,
        method: |m| m.trans_err,
        sweep: |p| p.trans_err,
    },
];

/// Keeps panels that have at least one point (LPIPS without weights, pose errors without
/// ground-truth cameras have none).
fn non_empty(panels: Vec<Panel>) -> Vec<Panel> {
    panels
        .into_iter()
        .filter(|p| p.series.iter().any(|s| !s.points.is_empty()))
        .collect()
}

/// Each metric against the future horizon, one line per method (mean over clips).
pub fn horizon_png(mean: Option<&ClipMetrics>) -> Result<Vec<u8>, String> {
    let methods = mean.map_or(&[][..], |m| &m.methods[..]);
    let panels = METRICS
        .iter()
        .map(|metric| Panel {
            title: format!("{} vs horizon", metric.title),
            x_label: "future horizon (frames)".into(),
            x_ticks: XTicks::Integer,
            series: methods
                .iter()
                .map(|m| Series {
                    name: m.method.label().into(),
                    points: m
                        .per_horizon
                        .iter()
                        .filter_map(|h| (metric.horizon)(h).map(|v| (h.horizon as f64, v)))
                        .collect(),
                    labels: vec![],
                    draw: Draw::LineMarkers,
                })
                .collect(),
        })
        .collect();
    encode(non_empty(panels))
}

/// Each metric against seconds per clip: each method's mean, the model on every clip, and
/// the sweep points with their Pareto front when there was a sweep.
pub fn time_png(report: &Report) -> Result<Vec<u8>, String> {
    let methods = report.mean.as_ref().map_or(&[][..], |m| &m.methods[..]);
    let panels = METRICS
        .iter()
        .map(|metric| {
            let mut series: Vec<Series> = methods
                .iter()
                .map(|m| Series {
                    name: m.method.label().into(),
                    points: (metric.method)(m)
                        .map(|v| (m.time_s, v))
                        .into_iter()
                        .collect(),
                    labels: vec![],
                    draw: Draw::Markers,
                })
                .collect();
            series.push(Series {
                name: "model (per clip)".into(),
                points: report
                    .clips
                    .iter()
                    .filter_map(|c| c.method(Method::Model))
                    .filter_map(|m| (metric.method)(m).map(|v| (m.time_s, v)))
                    .collect(),
                labels: vec![],
                draw: Draw::Markers,
            });
            if let Some(points) = &report.sweep {
                series.extend(sweep_series(points, metric));
            }
            Panel {
                title: format!("{} vs time", metric.title),
                x_label: "seconds per clip (encoder + decoder)".into(),
                x_ticks: XTicks::Continuous,
                series,
            }
        })
        .collect();
    encode(non_empty(panels))
}

/// The sweep alone: PSNR and SSIM against time, points labelled by their knob value, and
/// the Pareto front (fastest to best).
pub fn pareto_png(points: &[SweepPoint]) -> Result<Vec<u8>, String> {
    let panels = METRICS[..2]
        .iter()
        .map(|metric| {
            let mut series = sweep_series(points, metric);
            series[0].labels = points.iter().map(|p| p.value.clone()).collect();
            Panel {
                title: format!("{} vs time (sweep)", metric.title),
                x_label: "seconds per clip (encoder + decoder)".into(),
                x_ticks: XTicks::Continuous,
                series,
            }
        })
        .collect();
    encode(non_empty(panels))
}

/// Sweep points as markers, plus (on the PSNR panel, the metric the front is defined on)
/// the Pareto front as a line.
fn sweep_series(points: &[SweepPoint], metric: &Metric) -> Vec<Series> {
    let mut series = vec![Series {
        name: "sweep".into(),
        points: points
            .iter()
            .filter_map(|p| (metric.sweep)(p).map(|v| (p.time_s, v)))
            .collect(),
        labels: vec![],
        draw: Draw::Markers,
    }];
    if metric.title == PSNR_TITLE {
        let mut front: Vec<&SweepPoint> = points.iter().filter(|p| p.pareto).collect();
        front.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
        series.push(Series {
            name: "pareto front".into(),
            points: front.iter().map(|p| (p.time_s, p.psnr)).collect(),
            labels: vec![],
            draw: Draw::Line,
        });
    }
    series
}

fn encode(panels: Vec<Panel>) -> Result<Vec<u8>, String> {
    let img = chart::render(&panels, COLUMNS)?;
    let mut bytes = Cursor::new(Vec::new());
    img.write_to(&mut bytes, image::ImageFormat::Png)
        .map_err(|e| format!("PNG encoding failed: {e}"))?;
    Ok(bytes.into_inner())
}
