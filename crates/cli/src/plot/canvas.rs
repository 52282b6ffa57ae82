//! Line/scatter panels drawn pixel by pixel on an `image::RgbImage`: axes with "nice" ticks,
//! a light grid, series as lines and/or square markers with optional point labels, a legend.

use super::font::{is_set, text_width, ADVANCE, GLYPH_H, GLYPH_W};
use image::{Rgb, RgbImage};

/// One panel's size in pixels.
pub const PANEL_W: u32 = 460;
pub const PANEL_H: u32 = 360;
/// Plot-area margins inside a panel (room for tick labels, title and x label).
const MARGIN_LEFT: u32 = 70;
const MARGIN_RIGHT: u32 = 16;
const MARGIN_TOP: u32 = 36;
const MARGIN_BOTTOM: u32 = 46;
/// About this many ticks per axis.
const TICKS_TARGET: f64 = 5.0;
/// Fraction of the data range added above and below the data.
const PAD_FRACTION: f64 = 0.08;
/// Legend rows below the x label: row height, and the gap after each entry.
const LEGEND_ROW_H: i64 = GLYPH_H as i64 + 5;
const LEGEND_GAP: i64 = 14;
/// Legend swatch width and the space between swatch and name.
const SWATCH_W: i64 = 10;
const SWATCH_PAD: i64 = 4;
/// Marker half-size and line thickness in pixels.
const MARKER_HALF: i64 = 3;
const LINE_HALF: i64 = 1;
const TITLE_SCALE: u32 = 2;
const TEXT_SCALE: u32 = 1;

const WHITE: Rgb<u8> = Rgb([255, 255, 255]);
const BLACK: Rgb<u8> = Rgb([20, 20, 20]);
const GRID: Rgb<u8> = Rgb([225, 225, 225]);
/// Series colours (colour-blind-friendly order, Okabe-Ito).
const PALETTE: [Rgb<u8>; 8] = [
    Rgb([0, 114, 178]),
    Rgb([213, 94, 0]),
    Rgb([0, 158, 115]),
    Rgb([204, 121, 167]),
    Rgb([230, 159, 0]),
    Rgb([86, 180, 233]),
    Rgb([120, 120, 120]),
    Rgb([240, 228, 66]),
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
    /// 1-2-5 steps with as many decimals as the step needs.
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

/// Draws `panels` in a grid of `columns` columns.
pub fn render(panels: &[Panel], columns: usize) -> RgbImage {
    let columns = columns.clamp(1, panels.len().max(1));
    let rows = panels.len().div_ceil(columns).max(1);
    let mut img = RgbImage::from_pixel(PANEL_W * columns as u32, PANEL_H * rows as u32, WHITE);
    for (i, p) in panels.iter().enumerate() {
        let (cx, cy) = (
            (i % columns) as u32 * PANEL_W,
            (i / columns) as u32 * PANEL_H,
        );
        draw_panel(&mut img, p, cx as i64, cy as i64);
    }
    img
}

/// Axis range with padding; a single value gets a unit-sized window around it.
fn range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    if !lo.is_finite() || !hi.is_finite() {
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

/// A 1-2-5 step near `span / TICKS_TARGET`.
fn nice_step(span: f64) -> f64 {
    let raw = span / TICKS_TARGET;
    let mag = 10f64.powf(raw.log10().floor());
    let f = raw / mag;
    mag * if f < 1.5 {
        1.0
    } else if f < 3.5 {
        2.0
    } else if f < 7.5 {
        5.0
    } else {
        10.0
    }
}

fn ticks(lo: f64, hi: f64, kind: XTicks) -> (Vec<f64>, usize) {
    let step = match kind {
        XTicks::Continuous => nice_step(hi - lo),
        XTicks::Integer => nice_step(hi - lo).max(1.0).round(),
    };
    let decimals = (-step.log10().floor()).clamp(0.0, 6.0) as usize;
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    ((first..=last).map(|k| k as f64 * step).collect(), decimals)
}

fn draw_panel(img: &mut RgbImage, p: &Panel, ox: i64, oy: i64) {
    let title_scale = if text_width(&p.title, TITLE_SCALE) + 8 < PANEL_W {
        TITLE_SCALE
    } else {
        TEXT_SCALE
    };
    let tw = text_width(&p.title, title_scale) as i64;
    text(
        img,
        ox + (PANEL_W as i64 - tw) / 2,
        oy + 8,
        &p.title,
        title_scale,
        BLACK,
    );
    let pts = || {
        p.series
            .iter()
            .flat_map(|s| s.points.iter())
            .filter(|(x, y)| x.is_finite() && y.is_finite())
    };
    let (Some((x0, x1)), Some((y0, y1))) = (range(pts().map(|q| q.0)), range(pts().map(|q| q.1)))
    else {
        text(
            img,
            ox + PANEL_W as i64 / 2 - 20,
            oy + PANEL_H as i64 / 2,
            "NO DATA",
            TEXT_SCALE,
            BLACK,
        );
        return;
    };
    let (left, top) = (ox + MARGIN_LEFT as i64, oy + MARGIN_TOP as i64);
    let right = ox + (PANEL_W - MARGIN_RIGHT) as i64;
    let legend = legend_layout(p, right - left);
    let rows = legend.iter().map(|e| e.1).max().map_or(0, |r| r + 1);
    let bottom = oy + PANEL_H as i64 - MARGIN_BOTTOM as i64 - rows * LEGEND_ROW_H;
    let sx = |x: f64| left + ((x - x0) / (x1 - x0) * (right - left) as f64).round() as i64;
    let sy = |y: f64| bottom - ((y - y0) / (y1 - y0) * (bottom - top) as f64).round() as i64;
    let (yt, yd) = ticks(y0, y1, XTicks::Continuous);
    for v in yt {
        let y = sy(v);
        hline(img, left, right, y, GRID);
        let label = format!("{v:.yd$}");
        let w = text_width(&label, TEXT_SCALE) as i64;
        text(
            img,
            left - 6 - w,
            y - GLYPH_H as i64 / 2,
            &label,
            TEXT_SCALE,
            BLACK,
        );
    }
    let (xt, xd) = ticks(x0, x1, p.x_ticks);
    for v in xt {
        let x = sx(v);
        vline(img, x, top, bottom, GRID);
        let label = format!("{v:.xd$}");
        let w = text_width(&label, TEXT_SCALE) as i64;
        text(img, x - w / 2, bottom + 6, &label, TEXT_SCALE, BLACK);
    }
    hline(img, left, right, bottom, BLACK);
    vline(img, left, top, bottom, BLACK);
    let xw = text_width(&p.x_label, TEXT_SCALE) as i64;
    text(
        img,
        (left + right - xw) / 2,
        bottom + 24,
        &p.x_label,
        TEXT_SCALE,
        BLACK,
    );
    // Drawn last to first, so the first series (the model) ends up on top.
    for (i, s) in p.series.iter().enumerate().rev() {
        let color = PALETTE[i % PALETTE.len()];
        let px: Vec<(i64, i64)> = s
            .points
            .iter()
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .map(|&(x, y)| (sx(x), sy(y)))
            .collect();
        if s.draw != Draw::Markers {
            for w in px.windows(2) {
                line(img, w[0], w[1], color);
            }
        }
        if s.draw != Draw::Line {
            for &(x, y) in &px {
                fill(
                    img,
                    x - MARKER_HALF,
                    y - MARKER_HALF,
                    x + MARKER_HALF,
                    y + MARKER_HALF,
                    color,
                );
            }
        }
        for ((x, y), label) in px.iter().zip(&s.labels) {
            text(
                img,
                x + MARKER_HALF + 2,
                y - GLYPH_H as i64 - 1,
                label,
                TEXT_SCALE,
                color,
            );
        }
    }
    // The legend sits below the x label, outside the data, so it never hides a point.
    let legend_top = bottom + MARGIN_BOTTOM as i64 - 4;
    for (i, (s, (x, row))) in p.series.iter().zip(legend).enumerate() {
        let y = legend_top + row * LEGEND_ROW_H;
        let color = PALETTE[i % PALETTE.len()];
        let x = left + x;
        fill(
            img,
            x,
            y + 1,
            x + SWATCH_W - 1,
            y + GLYPH_H as i64 - 2,
            color,
        );
        text(
            img,
            x + SWATCH_W + SWATCH_PAD,
            y,
            &s.name,
            TEXT_SCALE,
            BLACK,
        );
    }
}

/// Legend entries flowed into rows of at most `width` pixels: (x offset, row) per series.
fn legend_layout(p: &Panel, width: i64) -> Vec<(i64, i64)> {
    let (mut x, mut row) = (0, 0);
    p.series
        .iter()
        .map(|s| {
            let w = SWATCH_W + SWATCH_PAD + text_width(&s.name, TEXT_SCALE) as i64;
            if x > 0 && x + w > width {
                (x, row) = (0, row + 1);
            }
            let at = (x, row);
            x += w + LEGEND_GAP;
            at
        })
        .collect()
}

fn put(img: &mut RgbImage, x: i64, y: i64, c: Rgb<u8>) {
    if x >= 0 && y >= 0 && (x as u32) < img.width() && (y as u32) < img.height() {
        img.put_pixel(x as u32, y as u32, c);
    }
}

fn fill(img: &mut RgbImage, x0: i64, y0: i64, x1: i64, y1: i64, c: Rgb<u8>) {
    for y in y0..=y1 {
        for x in x0..=x1 {
            put(img, x, y, c);
        }
    }
}

fn hline(img: &mut RgbImage, x0: i64, x1: i64, y: i64, c: Rgb<u8>) {
    fill(img, x0, y, x1, y, c);
}

fn vline(img: &mut RgbImage, x: i64, y0: i64, y1: i64, c: Rgb<u8>) {
    fill(img, x, y0, x, y1, c);
}

/// A thick line by stepping along its longer axis.
fn line(img: &mut RgbImage, a: (i64, i64), b: (i64, i64), c: Rgb<u8>) {
    let steps = (b.0 - a.0).abs().max((b.1 - a.1).abs()).max(1);
    for k in 0..=steps {
        let t = k as f64 / steps as f64;
        let x = a.0 + ((b.0 - a.0) as f64 * t).round() as i64;
        let y = a.1 + ((b.1 - a.1) as f64 * t).round() as i64;
        fill(
            img,
            x - LINE_HALF,
            y - LINE_HALF,
            x + LINE_HALF,
            y + LINE_HALF,
            c,
        );
    }
}

/// `s` with its top-left corner at (`x`, `y`).
fn text(img: &mut RgbImage, x: i64, y: i64, s: &str, scale: u32, c: Rgb<u8>) {
    for (i, ch) in s.chars().enumerate() {
        let gx = x + (i as u32 * ADVANCE * scale) as i64;
        for row in 0..GLYPH_H {
            for col in 0..GLYPH_W {
                if is_set(ch, col, row) {
                    let (px, py) = (gx + (col * scale) as i64, y + (row * scale) as i64);
                    fill(img, px, py, px + scale as i64 - 1, py + scale as i64 - 1, c);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the tick helper: steps are 1-2-5 multiples and ticks stay inside the range.
    #[test]
    fn ticks_are_nice_and_inside() {
        assert_eq!(nice_step(10.0), 2.0);
        assert!((nice_step(0.3) - 0.05).abs() < 1e-12);
        let (t, d) = ticks(13.2, 17.9, XTicks::Continuous);
        assert!(t.iter().all(|&v| (13.2..=17.9).contains(&v)), "{t:?}");
        assert_eq!(d, 0);
        let (t, _) = ticks(0.9, 2.1, XTicks::Integer);
        assert_eq!(t, [1.0, 2.0]);
    }

    /// Guards degenerate data: a single point still gets a non-empty axis range.
    #[test]
    fn single_value_range_is_widened() {
        let (lo, hi) = range([2.0].into_iter()).unwrap();
        assert!(lo < 2.0 && hi > 2.0);
        assert!(range(std::iter::empty()).is_none());
    }
}
