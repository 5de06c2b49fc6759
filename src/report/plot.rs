//! A small declarative figure model rendered to SVG and PNG with plotters.
//!
//! The rest of springfit describes figures as plain data ([`Figure`] → [`Panel`]s → [`Layer`]s)
//! and [`render`] draws each one twice: SVG (vector, no font needed) and PNG (text through
//! ab_glyph with the DejaVu Sans file shipped in `assets/fonts`, so nothing depends on the
//! system's font libraries). Nothing here knows about robots.
//!
//! Degenerate data never panics: non-finite values are skipped, a zero range is padded, empty
//! panels get a unit frame.

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;

use super::contour::isolines;
use crate::error::{Error, Result};

/// An RGB colour.
pub type Rgb = (u8, u8, u8);

/// How a layer is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Style {
    /// Colour.
    pub color: Rgb,
    /// Line width in pixels.
    pub width: u32,
    /// Opacity in [0, 1].
    pub alpha: f64,
    /// Filled shapes (histogram bars, spans, markers).
    pub filled: bool,
    /// Dashed lines.
    pub dashed: bool,
}

impl Style {
    /// A solid line of a colour.
    pub fn line(color: Rgb, width: u32) -> Style {
        Style { color, width, alpha: 1.0, filled: false, dashed: false }
    }

    /// A translucent fill.
    pub fn fill(color: Rgb, alpha: f64) -> Style {
        Style { color, width: 1, alpha, filled: true, dashed: false }
    }

    /// The same style with another opacity.
    pub fn with_alpha(self, alpha: f64) -> Style {
        Style { alpha, ..self }
    }

    /// The same style, dashed.
    pub fn dashed(self) -> Style {
        Style { dashed: true, ..self }
    }

    fn shape(&self) -> ShapeStyle {
        let c = RGBColor(self.color.0, self.color.1, self.color.2).mix(self.alpha);
        ShapeStyle { color: c, filled: self.filled, stroke_width: self.width }
    }
}

/// One box of a box plot.
#[derive(Debug, Clone, PartialEq)]
pub struct BoxItem {
    /// Category name on the x axis.
    pub label: String,
    /// Minimum, lower quartile, median, upper quartile, maximum.
    pub five: [f64; 5],
    /// Colour.
    pub color: Rgb,
}

impl BoxItem {
    /// The five-number summary of samples (non-finite values ignored).
    pub fn from_samples(label: &str, samples: &[f64], color: Rgb) -> BoxItem {
        let mut v: Vec<f64> = samples.iter().copied().filter(|x| x.is_finite()).collect();
        v.sort_by(f64::total_cmp);
        let q = |p: f64| crate::residual::percentile(&v, p);
        BoxItem { label: label.into(), five: [q(0.0), q(25.0), q(50.0), q(75.0), q(100.0)], color }
    }
}

/// What a panel draws.
#[derive(Debug, Clone, PartialEq)]
pub enum Layer {
    /// Polylines, one legend entry for all.
    Lines { lines: Vec<Vec<(f64, f64)>>, style: Style, label: Option<String> },
    /// Markers.
    Points { points: Vec<(f64, f64)>, style: Style, size: u32, label: Option<String> },
    /// Bars between consecutive `edges` with heights `counts`.
    Histogram { edges: Vec<f64>, counts: Vec<f64>, style: Style, label: Option<String> },
    /// Isolines of z on a grid (z y-major: z[j·nx + i]) at the given levels.
    Contours { x: Vec<f64>, y: Vec<f64>, z: Vec<f64>, levels: Vec<f64>, style: Style, label: Option<String> },
    /// Shaded vertical bands over the full height.
    Spans { spans: Vec<(f64, f64)>, style: Style, label: Option<String> },
    /// A horizontal line.
    HLine { y: f64, style: Style },
    /// A vertical line.
    VLine { x: f64, style: Style },
    /// Box plots at x = 0, 1, 2, … (the panel's x axis shows their labels).
    Boxes { items: Vec<BoxItem> },
}

/// One chart.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Panel {
    /// Title above the chart.
    pub title: String,
    /// x axis label.
    pub x_label: String,
    /// y axis label.
    pub y_label: String,
    /// Fixed x range (else from the data with a margin).
    pub x_range: Option<(f64, f64)>,
    /// Fixed y range.
    pub y_range: Option<(f64, f64)>,
    /// Same scale on both axes.
    pub equal_aspect: bool,
    /// Draw a legend for labelled layers.
    pub legend: bool,
    /// Lines of text in a box in the upper left corner.
    pub notes: Vec<String>,
    /// The layers, drawn in order.
    pub layers: Vec<Layer>,
}

/// A figure: panels on a grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// Title over all panels.
    pub title: Option<String>,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Grid rows.
    pub rows: usize,
    /// Grid columns.
    pub cols: usize,
    /// Panels, row by row.
    pub panels: Vec<Panel>,
}

impl Figure {
    /// A single-panel figure.
    pub fn single(panel: Panel, width: u32, height: u32) -> Figure {
        Figure { title: None, width, height, rows: 1, cols: 1, panels: vec![panel] }
    }
}

/// A qualitative palette (Okabe–Ito, colour-blind safe), cycling.
pub fn palette(i: usize) -> Rgb {
    const P: [Rgb; 8] = [
        (0, 114, 178),
        (213, 94, 0),
        (0, 158, 115),
        (204, 121, 167),
        (230, 159, 0),
        (86, 180, 233),
        (120, 120, 120),
        (240, 228, 66),
    ];
    P[i % P.len()]
}

/// A cyclic colour map for t ∈ [0, 1) (directions of a fan): hue around the circle at moderate
/// saturation and lightness, so neighbouring directions get neighbouring colours.
pub fn cyclic(t: f64) -> Rgb {
    let h = (t.rem_euclid(1.0)) * 6.0;
    let (s, l) = (0.65, 0.45);
    let c = (1.0 - (2.0 * l - 1.0f64).abs()) * s;
    let x = c * (1.0 - ((h % 2.0) - 1.0).abs());
    let (r, g, b) = match h as usize {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = l - c / 2.0;
    let to = |v: f64| ((v + m) * 255.0).round().clamp(0.0, 255.0) as u8;
    (to(r), to(g), to(b))
}

/// Counts of samples per bin; bins are [e₀, e₁), …, the last one closed [eₙ₋₁, eₙ]. Samples
/// outside the edges are not counted.
pub fn histogram(samples: &[f64], edges: &[f64]) -> Vec<f64> {
    let nb = edges.len().saturating_sub(1);
    let mut counts = vec![0.0; nb];
    for &s in samples {
        if !s.is_finite() || nb == 0 || s < edges[0] || s > edges[nb] {
            continue;
        }
        let k = edges.partition_point(|e| *e <= s).saturating_sub(1).min(nb - 1);
        counts[k] += 1.0;
    }
    counts
}

const FONT: &str = "sans-serif";

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        static BYTES: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
        // The shipped font is valid; if registration failed, PNG text would be missing, which the
        // tests would catch.
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, BYTES);
    });
}

/// Draws the figure to `<stem>.svg` and `<stem>.png`.
pub fn render(fig: &Figure, stem: &Path) -> Result<[PathBuf; 2]> {
    register_font();
    let svg = stem.with_extension("svg");
    let png = stem.with_extension("png");
    let perr = |p: &Path, e: String| Error::Plot { path: p.to_path_buf(), reason: e };
    {
        let root = SVGBackend::new(&svg, (fig.width, fig.height)).into_drawing_area();
        draw(&root, fig).map_err(|e| perr(&svg, e))?;
        root.present().map_err(|e| perr(&svg, format!("{e:?}")))?;
    }
    {
        let root = BitMapBackend::new(&png, (fig.width, fig.height)).into_drawing_area();
        draw(&root, fig).map_err(|e| perr(&png, e))?;
        root.present().map_err(|e| perr(&png, format!("{e:?}")))?;
    }
    Ok([svg, png])
}

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, fig: &Figure) -> std::result::Result<(), String> {
    let e = |x: DrawingAreaErrorKind<DB::ErrorType>| format!("{x:?}");
    root.fill(&WHITE).map_err(e)?;
    let area = match &fig.title {
        Some(t) => root.titled(t, (FONT, 22)).map_err(e)?,
        None => root.clone(),
    };
    let cells = area.split_evenly((fig.rows.max(1), fig.cols.max(1)));
    for (panel, cell) in fig.panels.iter().zip(cells.iter()) {
        draw_panel(cell, panel)?;
    }
    Ok(())
}

/// Finite (min, max) over every coordinate a panel draws.
fn data_range(panel: &Panel) -> ((f64, f64), (f64, f64)) {
    let mut xs = (f64::INFINITY, f64::NEG_INFINITY);
    let mut ys = (f64::INFINITY, f64::NEG_INFINITY);
    let mut add = |x: f64, y: f64| {
        if x.is_finite() {
            xs = (xs.0.min(x), xs.1.max(x));
        }
        if y.is_finite() {
            ys = (ys.0.min(y), ys.1.max(y));
        }
    };
    for l in &panel.layers {
        match l {
            Layer::Lines { lines, .. } => lines.iter().flatten().for_each(|&(x, y)| add(x, y)),
            Layer::Points { points, .. } => points.iter().for_each(|&(x, y)| add(x, y)),
            Layer::Histogram { edges, counts, .. } => {
                edges.iter().for_each(|&x| add(x, f64::NAN));
                counts.iter().for_each(|&c| add(f64::NAN, c));
                add(f64::NAN, 0.0);
            }
            Layer::Contours { x, y, .. } => {
                x.iter().for_each(|&v| add(v, f64::NAN));
                y.iter().for_each(|&v| add(f64::NAN, v));
            }
            Layer::Spans { spans, .. } => spans.iter().for_each(|&(a, b)| {
                add(a, f64::NAN);
                add(b, f64::NAN);
            }),
            Layer::HLine { y, .. } => add(f64::NAN, *y),
            Layer::VLine { x, .. } => add(*x, f64::NAN),
            Layer::Boxes { items } => {
                add(-0.5, f64::NAN);
                add(items.len() as f64 - 0.5, f64::NAN);
                items.iter().flat_map(|b| b.five).for_each(|v| add(f64::NAN, v));
            }
        }
    }
    let fix = |r: (f64, f64), margin: bool| {
        if !(r.0.is_finite() && r.1.is_finite()) {
            return (0.0, 1.0);
        }
        let span = r.1 - r.0;
        if span <= 0.0 {
            let pad = if r.0 == 0.0 { 1.0 } else { 0.1 * r.0.abs() };
            return (r.0 - pad, r.1 + pad);
        }
        if margin { (r.0 - 0.04 * span, r.1 + 0.04 * span) } else { r }
    };
    (fix(xs, true), fix(ys, true))
}

fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, panel: &Panel) -> std::result::Result<(), String> {
    let e = |x: DrawingAreaErrorKind<DB::ErrorType>| format!("{x:?}");
    let (dx, dy) = data_range(panel);
    let mut xr = panel.x_range.unwrap_or(dx);
    let mut yr = panel.y_range.unwrap_or(dy);
    let (w, h) = area.dim_in_pixel();
    let (plot_w, plot_h) = ((w as f64 - 80.0).max(10.0), (h as f64 - 80.0).max(10.0));
    if panel.equal_aspect {
        // Widen the range that is too narrow for the pixel aspect.
        let sx = (xr.1 - xr.0) / plot_w;
        let sy = (yr.1 - yr.0) / plot_h;
        if sx > sy {
            let c = 0.5 * (yr.0 + yr.1);
            let half = 0.5 * sx * plot_h;
            yr = (c - half, c + half);
        } else {
            let c = 0.5 * (xr.0 + xr.1);
            let half = 0.5 * sy * plot_w;
            xr = (c - half, c + half);
        }
    }
    let categories: Option<Vec<String>> = panel.layers.iter().find_map(|l| match l {
        Layer::Boxes { items } => Some(items.iter().map(|b| b.label.clone()).collect()),
        _ => None,
    });
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, (FONT, 17))
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(62)
        .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
        .map_err(e)?;
    let formatter = |v: &f64| -> String {
        match &categories {
            Some(c) => {
                let i = v.round();
                if (v - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < c.len() {
                    c[i as usize].clone()
                } else {
                    String::new()
                }
            }
            None => format_tick(*v),
        }
    };
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(&panel.x_label)
        .y_desc(&panel.y_label)
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 14))
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(215, 215, 215))
        .max_light_lines(2)
        .x_label_formatter(&formatter)
        .y_label_formatter(&|v| format_tick(*v));
    if let Some(c) = &categories {
        mesh.x_labels(c.len() * 2 + 1);
    }
    mesh.draw().map_err(e)?;

    for layer in &panel.layers {
        match layer {
            Layer::Lines { lines, style, label } => {
                let mut first = true;
                for line in lines {
                    for run in finite_runs(line) {
                        let s = style.shape();
                        let drawn = if style.dashed {
                            chart.draw_series(DashedLineSeries::new(run, 6, 4, s)).map_err(e)?
                        } else {
                            chart.draw_series(LineSeries::new(run, s)).map_err(e)?
                        };
                        if first {
                            if let Some(l) = label {
                                let s2 = style.shape();
                                drawn.label(l).legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], s2));
                            }
                            first = false;
                        }
                    }
                }
            }
            Layer::Points { points, style, size, label } => {
                let s = style.shape();
                let pts: Vec<(f64, f64)> =
                    points.iter().copied().filter(|(x, y)| x.is_finite() && y.is_finite()).collect();
                let size = *size;
                let drawn = chart.draw_series(pts.into_iter().map(|p| Circle::new(p, size, s))).map_err(e)?;
                if let Some(l) = label {
                    drawn.label(l).legend(move |(x, y)| Circle::new((x + 9, y), size, s));
                }
            }
            Layer::Histogram { edges, counts, style, label } => {
                let fill = Style { filled: true, ..*style }.shape();
                let outline = Style { filled: false, alpha: 1.0, ..*style }.shape();
                let bars: Vec<(f64, f64, f64)> = edges
                    .windows(2)
                    .zip(counts)
                    .filter(|(w, c)| w[0].is_finite() && w[1].is_finite() && c.is_finite())
                    .map(|(w, c)| (w[0], w[1], *c))
                    .collect();
                chart.draw_series(bars.iter().map(|&(a, b, c)| Rectangle::new([(a, 0.0), (b, c)], fill))).map_err(e)?;
                let drawn = chart
                    .draw_series(bars.iter().map(|&(a, b, c)| Rectangle::new([(a, 0.0), (b, c)], outline)))
                    .map_err(e)?;
                if let Some(l) = label {
                    drawn.label(l).legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], fill));
                }
            }
            Layer::Contours { x, y, z, levels, style, label } => {
                let s = style.shape();
                let mut first = true;
                for &lv in levels {
                    for line in isolines(x, y, z, lv) {
                        let drawn = chart.draw_series(LineSeries::new(line, s)).map_err(e)?;
                        if first {
                            if let Some(l) = label {
                                drawn.label(l).legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], s));
                            }
                            first = false;
                        }
                    }
                }
            }
            Layer::Spans { spans, style, label } => {
                let s = Style { filled: true, ..*style }.shape();
                let drawn = chart
                    .draw_series(
                        spans
                            .iter()
                            .filter(|(a, b)| a.is_finite() && b.is_finite())
                            .map(|&(a, b)| Rectangle::new([(a, yr.0), (b, yr.1)], s)),
                    )
                    .map_err(e)?;
                if let Some(l) = label {
                    drawn.label(l).legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], s));
                }
            }
            Layer::HLine { y, style } => {
                if y.is_finite() {
                    chart.draw_series(LineSeries::new(vec![(xr.0, *y), (xr.1, *y)], style.shape())).map_err(e)?;
                }
            }
            Layer::VLine { x, style } => {
                if x.is_finite() {
                    chart.draw_series(LineSeries::new(vec![(*x, yr.0), (*x, yr.1)], style.shape())).map_err(e)?;
                }
            }
            Layer::Boxes { items } => {
                for (i, b) in items.iter().enumerate() {
                    if b.five.iter().any(|v| !v.is_finite()) {
                        continue;
                    }
                    let x = i as f64;
                    let line = Style::line(b.color, 2).shape();
                    let fill = Style::fill(b.color, 0.25).shape();
                    let [lo, q1, med, q3, hi] = b.five;
                    chart
                        .draw_series(std::iter::once(Rectangle::new([(x - 0.3, q1), (x + 0.3, q3)], fill)))
                        .map_err(e)?;
                    chart
                        .draw_series(std::iter::once(Rectangle::new([(x - 0.3, q1), (x + 0.3, q3)], line)))
                        .map_err(e)?;
                    for seg in [
                        vec![(x - 0.3, med), (x + 0.3, med)],
                        vec![(x, q3), (x, hi)],
                        vec![(x, q1), (x, lo)],
                        vec![(x - 0.15, hi), (x + 0.15, hi)],
                        vec![(x - 0.15, lo), (x + 0.15, lo)],
                    ] {
                        chart.draw_series(LineSeries::new(seg, line)).map_err(e)?;
                    }
                }
            }
        }
    }
    if !panel.notes.is_empty() {
        let corner = (xr.0, yr.1);
        let lines = panel.notes.len() as i32;
        let width = panel.notes.iter().map(|s| s.chars().count()).max().unwrap_or(0) as i32 * 7 + 12;
        chart
            .draw_series(std::iter::once(
                EmptyElement::at(corner)
                    + Rectangle::new(
                        [(6, 6), (6 + width, 10 + 16 * lines)],
                        ShapeStyle::from(WHITE.mix(0.85)).filled(),
                    )
                    + Rectangle::new([(6, 6), (6 + width, 10 + 16 * lines)], ShapeStyle::from(RGBColor(160, 160, 160))),
            ))
            .map_err(e)?;
        for (k, note) in panel.notes.iter().enumerate() {
            chart
                .draw_series(std::iter::once(
                    EmptyElement::at(corner) + Text::new(note.clone(), (12, 10 + 16 * k as i32), (FONT, 13)),
                ))
                .map_err(e)?;
        }
    }
    if panel.legend && panel.layers.iter().any(has_label) {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font((FONT, 13))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(160, 160, 160))
            .draw()
            .map_err(e)?;
    }
    Ok(())
}

fn has_label(l: &Layer) -> bool {
    matches!(
        l,
        Layer::Lines { label: Some(_), .. }
            | Layer::Points { label: Some(_), .. }
            | Layer::Histogram { label: Some(_), .. }
            | Layer::Contours { label: Some(_), .. }
            | Layer::Spans { label: Some(_), .. }
    )
}

/// Splits a polyline at non-finite points.
fn finite_runs(line: &[(f64, f64)]) -> Vec<Vec<(f64, f64)>> {
    let mut out = Vec::new();
    let mut cur = Vec::new();
    for &(x, y) in line {
        if x.is_finite() && y.is_finite() {
            cur.push((x, y));
        } else if !cur.is_empty() {
            out.push(std::mem::take(&mut cur));
        }
    }
    if !cur.is_empty() {
        out.push(cur);
    }
    out
}

/// Short tick labels: no trailing zeros, scientific only for very large or small values.
fn format_tick(v: f64) -> String {
    // Round-off at a tick that should read 0 (e.g. 2.2e-16).
    if v.abs() < 1e-9 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        return format!("{v:.1e}");
    }
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.to_string() }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("springfit-plot-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn renders_every_layer_kind_to_svg_and_png() {
        let dir = temp("all");
        let line = Layer::Lines {
            lines: vec![(0..50).map(|i| (i as f64 * 0.1, (i as f64 * 0.1).sin())).collect()],
            style: Style::line(palette(0), 2),
            label: Some("sine".into()),
        };
        let (x, y): (Vec<f64>, Vec<f64>) =
            ((0..20).map(|i| i as f64 * 0.25).collect(), (0..20).map(|i| i as f64 * 0.1 - 1.0).collect());
        let z: Vec<f64> = y.iter().flat_map(|yy| x.iter().map(move |xx| xx + yy * yy)).collect();
        let panels = vec![
            Panel {
                title: "Lines and contours".into(),
                x_label: "q₁ (rad)".into(),
                y_label: "q₂ (rad)".into(),
                legend: true,
                notes: vec!["p99 |angle| = 0.31°".into()],
                layers: vec![
                    line,
                    Layer::Contours {
                        x,
                        y,
                        z,
                        levels: vec![1.0, 2.0],
                        style: Style::line(palette(1), 1),
                        label: Some("U".into()),
                    },
                    Layer::Points {
                        points: vec![(1.0, 0.5), (f64::NAN, 1.0)],
                        style: Style::fill(palette(2), 1.0),
                        size: 4,
                        label: None,
                    },
                    Layer::HLine { y: 0.0, style: Style::line((0, 0, 0), 1).dashed() },
                    Layer::VLine { x: 2.0, style: Style::line((0, 0, 0), 1) },
                    Layer::Spans {
                        spans: vec![(0.5, 0.8)],
                        style: Style::fill((128, 128, 128), 0.2),
                        label: Some("ε-ball".into()),
                    },
                ],
                ..Panel::default()
            },
            Panel {
                title: "Histogram".into(),
                layers: vec![Layer::Histogram {
                    edges: vec![-1.0, 0.0, 1.0, 2.0],
                    counts: vec![3.0, 5.0, 1.0],
                    style: Style::fill(palette(3), 0.5),
                    label: Some("fit".into()),
                }],
                legend: true,
                ..Panel::default()
            },
            Panel {
                title: "Boxes".into(),
                layers: vec![Layer::Boxes {
                    items: vec![
                        BoxItem::from_samples("a", &[1.0, 2.0, 3.0], palette(0)),
                        BoxItem::from_samples("b", &[0.5, 4.0], palette(1)),
                    ],
                }],
                ..Panel::default()
            },
            Panel { title: "Empty".into(), equal_aspect: true, ..Panel::default() },
        ];
        let fig = Figure { title: Some("Test figure".into()), width: 900, height: 700, rows: 2, cols: 2, panels };
        let [svg, png] = render(&fig, &dir.join("all")).unwrap();
        let text = std::fs::read_to_string(&svg).unwrap();
        assert!(text.contains("Test figure") && text.contains("Histogram") && text.contains("q₁ (rad)"));
        let bytes = std::fs::read(&png).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
        // IHDR width and height.
        assert_eq!(u32::from_be_bytes(bytes[16..20].try_into().unwrap()), 900);
        assert_eq!(u32::from_be_bytes(bytes[20..24].try_into().unwrap()), 700);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn degenerate_data_does_not_panic() {
        let dir = temp("degenerate");
        let panel = Panel {
            title: "constant".into(),
            layers: vec![
                Layer::Lines {
                    lines: vec![vec![(1.0, 2.0), (1.0, 2.0)], vec![], vec![(f64::NAN, f64::INFINITY)]],
                    style: Style::line(palette(0), 1),
                    label: None,
                },
                Layer::Histogram { edges: vec![], counts: vec![], style: Style::fill(palette(0), 0.5), label: None },
            ],
            ..Panel::default()
        };
        render(&Figure::single(panel, 300, 200), &dir.join("deg")).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn histogram_bins() {
        let counts = histogram(&[-1.0, -0.5, 0.0, 0.2, 1.0, 2.0, f64::NAN], &[-1.0, 0.0, 1.0]);
        // [-1, 0) holds -1 and -0.5; the last bin [0, 1] is closed and holds 0, 0.2 and 1.
        assert_eq!(counts, vec![2.0, 3.0]);
    }

    #[test]
    fn colours() {
        assert_ne!(palette(0), palette(1));
        assert_eq!(palette(0), palette(8));
        assert_eq!(cyclic(0.0), cyclic(1.0));
        assert_ne!(cyclic(0.0), cyclic(0.5));
        assert_eq!(format_tick(0.25), "0.25");
        assert_eq!(format_tick(2.0), "2");
        assert_eq!(format_tick(1.0e6), "1.0e6");
    }
}
