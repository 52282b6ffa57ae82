//! Line/scatter panels drawn with `plotters` (bitmap backend) in DejaVu Sans, embedded so no
//! system font is needed (`assets/fonts/`, license beside it): a grid of panels, each with
//! axes, a light mesh, series as lines and/or markers with optional point labels, and a
//! legend that says which series coincide (drawn on top of each other, one would hide).

use image::RgbImage;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};
use std::sync::OnceLock;

/// One panel's size in pixels.
pub const PANEL_W: u32 = 640;
/// Width of the legend column at a panel's right (outside the plot, so it hides no data).
const LEGEND_W: u32 = 190;
const LEGEND_ROW: i32 = 16;
pub const PANEL_H: u32 = 400;
/// The family name the embedded font is registered under.
const FONT: &str = "sans-serif";
static FONT_BYTES: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
const TITLE_PX: u32 = 17;
const LABEL_PX: u32 = 13;
const LEGEND_PX: u32 = 12;
/// Fraction of the data range added on each side.
const PAD_FRACTION: f64 = 0.08;
/// Two values closer than this (relative) are the same point.
const SAME: f64 = 1e-9;
const MARKER_PX: i32 = 3;

/// Series colours (colour-blind-friendly order, Okabe-Ito, then greys).
const PALETTE: [RGBColor; 10] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(120, 120, 120),
    RGBColor(200, 180, 30),
    RGBColor(30, 30, 30),
    RGBColor(140, 86, 75),
];

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Draw {
    /// Markers joined by a line, in the given order.
    LineMarkers,
    /// Markers only.
    Markers,
    /// A line only (e.g. a Pareto front).
    Line,
}

#[derive(Debug, Clone)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    /// Optional text drawn next to each point (same length as `points`, or empty).
    pub labels: Vec<String>,
    pub draw: Draw,
}

/// How the x axis is ticked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum XTicks {
    /// Chosen by plotters (1-2-5 steps).
    Continuous,
    /// Whole numbers only (frame counts, horizons).
    Integer,
}

#[derive(Debug, Clone)]
pub struct Panel {
    pub title: String,
    pub x_label: String,
    pub x_ticks: XTicks,
    pub series: Vec<Series>,
}

/// Axis range with padding; a single value gets a window around it.
pub fn range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        return None;
    }
    if hi - lo < 1e-12 {
        let d = if lo.abs() > 1e-12 {
            lo.abs() * 0.1
        } else {
            1.0
        };
        return Some((lo - d, hi + d));
    }
    let pad = (hi - lo) * PAD_FRACTION;
    Some((lo - pad, hi + pad))
}

/// Legend names: a series whose points equal an earlier one's says so (`b (= a)`), since
/// it is drawn exactly over it.
pub fn legend_names(series: &[Series]) -> Vec<String> {
    let same = |a: &[(f64, f64)], b: &[(f64, f64)]| {
        !a.is_empty()
            && a.len() == b.len()
            && a.iter().zip(b).all(|(p, q)| {
                let close = |x: f64, y: f64| (x - y).abs() <= SAME * x.abs().max(y.abs()).max(1.0);
                close(p.0, q.0) && close(p.1, q.1)
            })
    };
    series
        .iter()
        .enumerate()
        .map(
            |(j, s)| match series[..j].iter().find(|e| same(&e.points, &s.points)) {
                Some(e) => format!("{} (= {})", s.name, e.name),
                None => s.name.clone(),
            },
        )
        .collect()
}

fn font_registered() -> Result<(), String> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        register_font(FONT, FontStyle::Normal, FONT_BYTES)
            .map_err(|_| "the embedded plot font is invalid".to_owned())
    })
    .clone()
}

/// Draws `panels` in a grid of `columns` columns.
pub fn render(panels: &[Panel], columns: usize) -> Result<RgbImage, String> {
    font_registered()?;
    let columns = columns.clamp(1, panels.len().max(1));
    let rows = panels.len().div_ceil(columns).max(1);
    let (w, h) = (PANEL_W * columns as u32, PANEL_H * rows as u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        let err = |e: &dyn std::fmt::Display| format!("plot: {e}");
        root.fill(&WHITE).map_err(|e| err(&e))?;
        for (area, panel) in root.split_evenly((rows, columns)).iter().zip(panels) {
            draw_panel(area, panel).map_err(|e| err(&e))?;
        }
        root.present().map_err(|e| err(&e))?;
    }
    RgbImage::from_raw(w, h, buf).ok_or_else(|| "plot: buffer size mismatch".into())
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

type DrawResult =
    Result<(), DrawingAreaErrorKind<<BitMapBackend<'static> as DrawingBackend>::ErrorType>>;

fn draw_panel(area: &Area<'_>, panel: &Panel) -> DrawResult {
    let (plot, legend) = area.split_horizontally(PANEL_W - LEGEND_W);
    let points = || panel.series.iter().flat_map(|s| s.points.iter());
    let (Some((x0, x1)), Some((y0, y1))) =
        (range(points().map(|p| p.0)), range(points().map(|p| p.1)))
    else {
        return Ok(());
    };
    let (x0, x1) = match panel.x_ticks {
        // Whole numbers at both ends, so the ticks fall on the horizons.
        XTicks::Integer => (x0.floor(), x1.ceil()),
        XTicks::Continuous => (x0, x1),
    };
    let mut chart = ChartBuilder::on(&plot)
        .caption(&panel.title, (FONT, TITLE_PX))
        .margin(8)
        .x_label_area_size(38)
        .y_label_area_size(52)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    let integer = |x: &f64| {
        if (x - x.round()).abs() < 1e-6 {
            format!("{}", x.round() as i64)
        } else {
            String::new()
        }
    };
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(&panel.x_label)
        .label_style((FONT, LABEL_PX))
        .axis_desc_style((FONT, LABEL_PX))
        .light_line_style(RGBColor(238, 238, 238));
    if panel.x_ticks == XTicks::Integer {
        mesh.x_label_formatter(&integer)
            .x_labels(((x1 - x0).round() as usize + 1).clamp(2, 12));
    }
    mesh.draw()?;
    let names = legend_names(&panel.series);
    for (i, s) in panel.series.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        let pts = s.points.iter().copied();
        if s.draw != Draw::Markers {
            chart.draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))?;
        }
        if s.draw != Draw::Line {
            chart.draw_series(pts.map(|p| Circle::new(p, MARKER_PX, color.filled())))?;
        }
        if !s.labels.is_empty() {
            chart.draw_series(s.points.iter().zip(&s.labels).map(|(&p, l)| {
                Text::new(l.clone(), p, (FONT, LEGEND_PX).into_font().color(&BLACK))
            }))?;
        }
    }
    draw_legend(&legend, &panel.series, &names)?;
    Ok(())
}

/// The legend column: a swatch and the name per series; a coincidence note (`(= a)`)
/// goes on its own line under the name.
fn draw_legend(area: &Area<'_>, series: &[Series], names: &[String]) -> DrawResult {
    let font = (FONT, LEGEND_PX).into_font().color(&BLACK);
    let mut y = 40;
    for (i, (s, name)) in series.iter().zip(names).enumerate() {
        if s.points.is_empty() {
            continue;
        }
        let color = PALETTE[i % PALETTE.len()];
        match s.draw {
            Draw::Markers => area.draw(&Circle::new((10, y), MARKER_PX + 1, color.filled()))?,
            _ => area.draw(&PathElement::new(
                vec![(2, y), (18, y)],
                color.stroke_width(3),
            ))?,
        }
        let (first, note) = match name.find(" (= ") {
            Some(at) => (&name[..at], Some(&name[at + 1..])),
            None => (name.as_str(), None),
        };
        area.draw(&Text::new(first.to_owned(), (24, y - 7), font.clone()))?;
        if let Some(note) = note {
            y += LEGEND_ROW - 2;
            area.draw(&Text::new(note.to_owned(), (24, y - 7), font.clone()))?;
        }
        y += LEGEND_ROW;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards degenerate data: a single point still gets a non-empty axis range, and no
    /// point gives none.
    #[test]
    fn single_value_range_is_widened() {
        let (lo, hi) = range([2.0].into_iter()).unwrap();
        assert!(lo < 2.0 && hi > 2.0);
        assert!(range(std::iter::empty()).is_none());
    }

    /// Guards hidden lines: a series drawn exactly over an earlier one is named with it in
    /// the legend; one differing in any point, or empty, is not.
    #[test]
    fn coinciding_series_are_named_in_the_legend() {
        let s = |name: &str, pts: &[(f64, f64)]| Series {
            name: name.into(),
            points: pts.to_vec(),
            labels: vec![],
            draw: Draw::LineMarkers,
        };
        let names = legend_names(&[
            s("model", &[(1.0, 20.0), (2.0, 19.0)]),
            s("no-motion", &[(1.0, 20.0), (2.0, 19.0)]),
            s("copy-last", &[(1.0, 20.0), (2.0, 18.0)]),
            s("empty", &[]),
            s("empty too", &[]),
        ]);
        assert_eq!(
            names,
            [
                "model",
                "no-motion (= model)",
                "copy-last",
                "empty",
                "empty too"
            ]
        );
    }

    /// Guards the drawing itself: a two-panel figure is the grid's size and not blank.
    #[test]
    fn renders_a_grid_of_panels() {
        let panel = Panel {
            title: "PSNR (dB) vs horizon".into(),
            x_label: "future horizon (frames)".into(),
            x_ticks: XTicks::Integer,
            series: vec![Series {
                name: "model".into(),
                points: vec![(1.0, 20.0), (2.0, 19.0)],
                labels: vec![],
                draw: Draw::LineMarkers,
            }],
        };
        let img = render(&[panel.clone(), panel], 3).unwrap();
        assert_eq!((img.width(), img.height()), (2 * PANEL_W, PANEL_H));
        assert!(img.pixels().any(|p| p.0 != [255, 255, 255]));
    }
}
