//! A small declarative figure model rendered to SVG and PNG with plotters.
//!
//! The rest of springfit describes figures as plain data ([`Figure`] → [`Panel`]s → [`Layer`]s)
//! and [`render`] draws each one twice: SVG (vector, no font needed) and PNG (text through
//! ab_glyph with the DejaVu Sans file shipped in `assets/fonts`, so nothing depends on the
//! system's font libraries). Nothing here knows about robots.
//!
//! Layout rules that keep data readable: a panel's legend and notes go in a column to the right
//! of its chart, never over the data; lines are clipped to the chart and dashed here (the same
//! pattern in the chart and the legend); either axis can be logarithmic (`log_x`, `log_y`; the
//! values ≤ 0 are left out, histogram bars start at the bottom of the axis).
//!
//! PNG text: plotters 0.3.7 places each ab_glyph glyph at the truncated pen position and drops
//! the glyph's left side bearing, so letters are unevenly spaced. [`TextFix`] wraps the bitmap
//! backend and draws text itself with the bearings and a fractional pen.
//!
//! Degenerate data never panics: non-finite values are skipped, a zero range is padded, empty
//! panels get a unit frame.

use std::path::{Path, PathBuf};
use std::sync::Once;

use ab_glyph::{Font, FontRef, ScaleFont, point};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;
use plotters_backend::{
    BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingErrorKind, text_anchor::HPos, text_anchor::VPos,
};

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
    /// Draw a legend for labelled layers (in a column right of the chart).
    pub legend: bool,
    /// Lines of text in a box in the column right of the chart, under the legend.
    pub notes: Vec<String>,
    /// Logarithmic x axis (values ≤ 0 are not drawn).
    pub log_x: bool,
    /// Logarithmic y axis (values ≤ 0 are not drawn; histogram bars start at the axis' bottom).
    pub log_y: bool,
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
static FONT_BYTES: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The shipped font is valid; if registration failed, PNG text would be missing, which the
        // tests would catch.
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, FONT_BYTES);
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
        let font = FontRef::try_from_slice(FONT_BYTES).map_err(|e| perr(&png, format!("font: {e}")))?;
        let root = TextFix { inner: BitMapBackend::new(&png, (fig.width, fig.height)), font }.into_drawing_area();
        draw(&root, fig).map_err(|e| perr(&png, e))?;
        root.present().map_err(|e| perr(&png, format!("{e:?}")))?;
    }
    Ok([svg, png])
}

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, fig: &Figure) -> std::result::Result<(), String> {
    let e = |x: DrawingAreaErrorKind<DB::ErrorType>| format!("{x:?}");
    root.fill(&WHITE).map_err(e)?;
    let area = match &fig.title {
        Some(t) => root.titled(t, (FONT, title_size(root, t, fig.width))).map_err(e)?,
        None => root.clone(),
    };
    let cells = area.split_evenly((fig.rows.max(1), fig.cols.max(1)));
    for (panel, cell) in fig.panels.iter().zip(cells.iter()) {
        draw_panel(cell, panel)?;
    }
    Ok(())
}

/// The largest title size, 22 px at most and 12 px at least, whose text fits the figure's width:
/// titles carry the design's and catalogue's names, and a long pair ran off both edges.
fn title_size<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, title: &str, width: u32) -> f64 {
    let mut size = 22.0;
    while size > 12.0 {
        match root.estimate_text_size(title, &TextStyle::from((FONT, size).into_font())) {
            Ok((w, _)) if w + 24 > width => size -= 1.0,
            _ => break,
        }
    }
    size
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
                if panel.log_y {
                    // Counts are log₁₀ here: leave a third of a decade under the smallest bar.
                    let low = counts.iter().copied().filter(|c| c.is_finite()).fold(f64::INFINITY, f64::min);
                    add(f64::NAN, low - 0.35);
                } else {
                    add(f64::NAN, 0.0);
                }
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

/// The bitmap backend with correct glyph placement (see the module docs): every call but
/// `draw_text` goes to plotters' `BitMapBackend`.
struct TextFix<'a> {
    inner: BitMapBackend<'a>,
    font: FontRef<'static>,
}

impl DrawingBackend for TextFix<'_> {
    type ErrorType = <BitMapBackend<'static> as DrawingBackend>::ErrorType;

    fn get_size(&self) -> (u32, u32) {
        self.inner.get_size()
    }
    fn ensure_prepared(&mut self) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.ensure_prepared()
    }
    fn present(&mut self) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.present()
    }
    fn draw_pixel(
        &mut self,
        point: BackendCoord,
        color: BackendColor,
    ) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_pixel(point, color)
    }
    fn draw_line<S: BackendStyle>(
        &mut self,
        from: BackendCoord,
        to: BackendCoord,
        style: &S,
    ) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_line(from, to, style)
    }
    fn draw_rect<S: BackendStyle>(
        &mut self,
        upper_left: BackendCoord,
        bottom_right: BackendCoord,
        style: &S,
        fill: bool,
    ) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_rect(upper_left, bottom_right, style, fill)
    }
    fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        path: I,
        style: &S,
    ) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_path(path, style)
    }
    fn draw_circle<S: BackendStyle>(
        &mut self,
        center: BackendCoord,
        radius: u32,
        style: &S,
        fill: bool,
    ) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_circle(center, radius, style, fill)
    }
    fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        vert: I,
        style: &S,
    ) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.fill_polygon(vert, style)
    }
    fn blit_bitmap(
        &mut self,
        pos: BackendCoord,
        (iw, ih): (u32, u32),
        src: &[u8],
    ) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.blit_bitmap(pos, (iw, ih), src)
    }

    /// Lays the glyphs out on a fractional pen with kerning and draws each at its own pixel
    /// bounds (which include the left side bearing). The box and the anchor are those of
    /// plotters' layout (advance widths and kerning, height size/1.24), so text sits where the
    /// chart expects it.
    fn draw_text<TStyle: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &TStyle,
        pos: BackendCoord,
    ) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        let color = style.color();
        if color.alpha == 0.0 {
            return Ok(());
        }
        let size = style.size() as f32;
        let scaled = self.font.as_scaled(size);
        let mut glyphs = Vec::with_capacity(text.len());
        let mut pen = 0.0f32;
        let mut prev = None;
        for c in text.chars() {
            let id = scaled.glyph_id(c);
            if let Some(p) = prev {
                pen += scaled.kern(p, id);
            }
            glyphs.push(id.with_scale_and_position(size, point(pen, 0.0)));
            pen += scaled.h_advance(id);
            prev = Some(id);
        }
        let width = pen as i32;
        let height = (f64::from(size) / 1.24) as i32;
        let dx = match style.anchor().h_pos {
            HPos::Left => 0,
            HPos::Right => -width,
            HPos::Center => -width / 2,
        };
        let dy = match style.anchor().v_pos {
            VPos::Top => 0,
            VPos::Center => -height / 2,
            VPos::Bottom => -height,
        };
        // plotters puts the baseline half the font size below the layout's top.
        let baseline = size / 2.0;
        let trans = style.transform();
        let (w, h) = self.inner.get_size();
        for g in glyphs {
            let Some(outline) = self.font.outline_glyph(g) else { continue };
            let b = outline.px_bounds();
            let mut pixels = Vec::new();
            outline.draw(|x, y, c| pixels.push((x as i32 + b.min.x as i32, y as i32 + (b.min.y + baseline) as i32, c)));
            for (x, y, c) in pixels {
                let (x, y) = trans.transform(x + dx, y + dy);
                let (x, y) = (pos.0 + x, pos.1 + y);
                if x >= 0 && x < w as i32 && y >= 0 && y < h as i32 && c > 0.0 {
                    let alpha = color.alpha * f64::from(c.min(1.0));
                    self.inner.draw_pixel((x, y), BackendColor { alpha, rgb: color.rgb })?;
                }
            }
        }
        Ok(())
    }
}

/// One legend entry: how its sample is drawn and its text.
enum Key {
    Line(Style),
    Marker(Style, u32),
    Fill(Style),
}

fn legend_entries(panel: &Panel) -> Vec<(Key, String)> {
    let mut out = Vec::new();
    for l in &panel.layers {
        match l {
            Layer::Lines { style, label: Some(t), .. } | Layer::Contours { style, label: Some(t), .. } => {
                out.push((Key::Line(*style), t.clone()))
            }
            Layer::Points { style, size, label: Some(t), .. } => out.push((Key::Marker(*style, *size), t.clone())),
            Layer::Histogram { style, label: Some(t), .. } | Layer::Spans { style, label: Some(t), .. } => {
                out.push((Key::Fill(Style { filled: true, ..*style }), t.clone()))
            }
            _ => {}
        }
    }
    out
}

/// The panel with its logarithmic axes mapped to log₁₀ (values ≤ 0 become NaN, so are skipped).
fn to_log(panel: &Panel) -> Panel {
    let lx = |v: f64| if panel.log_x { if v > 0.0 { v.log10() } else { f64::NAN } } else { v };
    let ly = |v: f64| if panel.log_y { if v > 0.0 { v.log10() } else { f64::NAN } } else { v };
    let pt = |&(x, y): &(f64, f64)| (lx(x), ly(y));
    let layers = panel
        .layers
        .iter()
        .map(|l| match l {
            Layer::Lines { lines, style, label } => Layer::Lines {
                lines: lines.iter().map(|line| line.iter().map(pt).collect()).collect(),
                style: *style,
                label: label.clone(),
            },
            Layer::Points { points, style, size, label } => Layer::Points {
                points: points.iter().map(pt).collect(),
                style: *style,
                size: *size,
                label: label.clone(),
            },
            Layer::Histogram { edges, counts, style, label } => Layer::Histogram {
                edges: edges.iter().map(|&e| lx(e)).collect(),
                counts: counts.iter().map(|&c| ly(c)).collect(),
                style: *style,
                label: label.clone(),
            },
            Layer::Contours { x, y, z, levels, style, label } => Layer::Contours {
                x: x.iter().map(|&v| lx(v)).collect(),
                y: y.iter().map(|&v| ly(v)).collect(),
                z: z.clone(),
                levels: levels.clone(),
                style: *style,
                label: label.clone(),
            },
            Layer::Spans { spans, style, label } => Layer::Spans {
                spans: spans.iter().map(|&(a, b)| (lx(a), lx(b))).collect(),
                style: *style,
                label: label.clone(),
            },
            Layer::HLine { y, style } => Layer::HLine { y: ly(*y), style: *style },
            Layer::VLine { x, style } => Layer::VLine { x: lx(*x), style: *style },
            Layer::Boxes { items } => Layer::Boxes {
                items: items
                    .iter()
                    .map(|b| BoxItem { label: b.label.clone(), five: b.five.map(ly), color: b.color })
                    .collect(),
            },
        })
        .collect();
    let range = |r: Option<(f64, f64)>, f: &dyn Fn(f64) -> f64| r.map(|(a, b)| (f(a), f(b)));
    Panel {
        layers,
        x_range: range(panel.x_range, &lx),
        y_range: range(panel.y_range, &ly),
        notes: panel.notes.clone(),
        title: panel.title.clone(),
        x_label: panel.x_label.clone(),
        y_label: panel.y_label.clone(),
        ..*panel
    }
}

fn draw_panel<DB: DrawingBackend>(cell: &DrawingArea<DB, Shift>, original: &Panel) -> std::result::Result<(), String> {
    let e = |x: DrawingAreaErrorKind<DB::ErrorType>| format!("{x:?}");
    let panel = &to_log(original);
    let entries = if panel.legend { legend_entries(panel) } else { Vec::new() };
    // The side column for the legend and the notes: as wide as its longest text, at most 45 % of
    // the cell.
    let (w, _) = cell.dim_in_pixel();
    let label_font = TextStyle::from((FONT, 13).into_font());
    let text_width = |t: &str| cell.estimate_text_size(t, &label_font).map(|s| s.0).unwrap_or(8 * t.len() as u32);
    let widest = entries
        .iter()
        .map(|(_, t)| text_width(t) + 40)
        .chain(panel.notes.iter().map(|t| text_width(t) + 20))
        .max()
        .unwrap_or(0);
    let side = if widest > 0 { (widest + 16).min(w * 45 / 100) } else { 0 };
    let (area, column) = cell.split_horizontally(w.saturating_sub(side).max(1));
    let (dx, dy) = data_range(panel);
    let mut xr = panel.x_range.unwrap_or(dx);
    let mut yr = panel.y_range.unwrap_or(dy);
    let (aw, ah) = area.dim_in_pixel();
    let (plot_w, plot_h) = ((aw as f64 - 86.0).max(10.0), (ah as f64 - 84.0).max(10.0));
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
    let mut chart = ChartBuilder::on(&area)
        .caption(&panel.title, (FONT, 17))
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(62)
        .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
        .map_err(e)?;
    let log_tick = |v: f64| {
        let r = v.round();
        if (v - r).abs() < 1e-6 {
            let x = 10f64.powf(r);
            if (1e-3..1e5).contains(&x) { format_tick(x) } else { format!("{x:.0e}") }
        } else {
            // Between decades: two significant digits (3.2, 0.32), not 3.162.
            let x = 10f64.powf(v);
            let digits = (1.0 - v.floor()).max(0.0) as usize;
            if (1e-3..1e5).contains(&x) { format!("{x:.digits$}") } else { format!("{x:.1e}") }
        }
    };
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
            None if panel.log_x => log_tick(*v),
            None => format_tick(*v),
        }
    };
    let y_formatter = |v: &f64| if panel.log_y { log_tick(*v) } else { format_tick(*v) };
    let decades = |r: (f64, f64)| ((r.1 - r.0).ceil() as usize + 1).clamp(3, 12);
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(&panel.x_label)
        .y_desc(&panel.y_label)
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 14))
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(215, 215, 215))
        .max_light_lines(2)
        .x_label_formatter(&formatter)
        .y_label_formatter(&y_formatter);
    if let Some(c) = &categories {
        mesh.x_labels(c.len() * 2 + 1);
    } else if panel.log_x {
        mesh.x_labels(decades(xr));
    }
    if panel.log_y {
        mesh.y_labels(decades(yr));
    }
    mesh.draw().map_err(e)?;

    // Pixels per data unit, for dashes of a fixed length on screen.
    let (pw, ph) = chart.plotting_area().dim_in_pixel();
    let scale = (pw as f64 / (xr.1 - xr.0), ph as f64 / (yr.1 - yr.0));
    let clip = |line: &[(f64, f64)]| clip_polyline(line, xr, yr);
    for layer in &panel.layers {
        match layer {
            Layer::Lines { lines, style, .. } => {
                for line in lines {
                    for run in finite_runs(line) {
                        for piece in clip(&run) {
                            draw_line(&mut chart, piece, style, scale).map_err(e)?;
                        }
                    }
                }
            }
            Layer::Points { points, style, size, .. } => {
                let s = style.shape();
                let inside = |&(x, y): &(f64, f64)| {
                    x.is_finite() && y.is_finite() && x >= xr.0 && x <= xr.1 && y >= yr.0 && y <= yr.1
                };
                let pts: Vec<(f64, f64)> = points.iter().copied().filter(inside).collect();
                let size = *size;
                chart.draw_series(pts.into_iter().map(|p| Circle::new(p, size, s))).map_err(e)?;
            }
            Layer::Histogram { edges, counts, style, .. } => {
                let fill = Style { filled: true, ..*style }.shape();
                let outline = Style { filled: false, alpha: 1.0, ..*style }.shape();
                let base = if panel.log_y { yr.0 } else { 0.0f64.max(yr.0) };
                let bars: Vec<(f64, f64, f64)> = edges
                    .windows(2)
                    .zip(counts)
                    .filter(|(w, c)| w[0].is_finite() && w[1].is_finite() && c.is_finite() && **c > base)
                    .map(|(w, c)| (w[0].max(xr.0), w[1].min(xr.1), c.min(yr.1)))
                    .filter(|(a, b, _)| a < b)
                    .collect();
                chart
                    .draw_series(bars.iter().map(|&(a, b, c)| Rectangle::new([(a, base), (b, c)], fill)))
                    .map_err(e)?;
                chart
                    .draw_series(bars.iter().map(|&(a, b, c)| Rectangle::new([(a, base), (b, c)], outline)))
                    .map_err(e)?;
            }
            Layer::Contours { x, y, z, levels, style, .. } => {
                for &lv in levels {
                    for line in isolines(x, y, z, lv) {
                        for piece in clip(&line) {
                            draw_line(&mut chart, piece, style, scale).map_err(e)?;
                        }
                    }
                }
            }
            Layer::Spans { spans, style, .. } => {
                let s = Style { filled: true, ..*style }.shape();
                chart
                    .draw_series(
                        spans
                            .iter()
                            .filter(|(a, b)| a.is_finite() && b.is_finite())
                            .map(|&(a, b)| (a.max(xr.0), b.min(xr.1)))
                            .filter(|(a, b)| a < b)
                            .map(|(a, b)| Rectangle::new([(a, yr.0), (b, yr.1)], s)),
                    )
                    .map_err(e)?;
            }
            Layer::HLine { y, style } => {
                if y.is_finite() && *y >= yr.0 && *y <= yr.1 {
                    draw_line(&mut chart, vec![(xr.0, *y), (xr.1, *y)], style, scale).map_err(e)?;
                }
            }
            Layer::VLine { x, style } => {
                if x.is_finite() && *x >= xr.0 && *x <= xr.1 {
                    draw_line(&mut chart, vec![(*x, yr.0), (*x, yr.1)], style, scale).map_err(e)?;
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
    if side > 0 {
        draw_side_column(&column, &entries, &panel.notes).map_err(e)?;
    }
    Ok(())
}

/// Draws a polyline (already clipped), solid or dashed (7 px on, 4 px off on screen).
fn draw_line<DB: DrawingBackend>(
    chart: &mut ChartContext<
        '_,
        DB,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
    line: Vec<(f64, f64)>,
    style: &Style,
    scale: (f64, f64),
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let s = style.shape();
    if !style.dashed {
        chart.draw_series(std::iter::once(PathElement::new(line, s)))?;
        return Ok(());
    }
    chart.draw_series(dashes(&line, scale, 7.0, 4.0).into_iter().map(|d| PathElement::new(d, s)))?;
    Ok(())
}

/// The dashes of a polyline: pieces `on` pixels long separated by `off` pixels, measured on
/// screen (`scale` = pixels per data unit on each axis).
fn dashes(line: &[(f64, f64)], scale: (f64, f64), on: f64, off: f64) -> Vec<Vec<(f64, f64)>> {
    let mut out = Vec::new();
    let mut cur: Vec<(f64, f64)> = Vec::new();
    let (mut drawing, mut left) = (true, on);
    if let Some(&p) = line.first() {
        cur.push(p);
    }
    for w in line.windows(2) {
        let (a, b) = (w[0], w[1]);
        let len = (((b.0 - a.0) * scale.0).powi(2) + ((b.1 - a.1) * scale.1).powi(2)).sqrt();
        let mut pos = 0.0;
        while len - pos > left {
            pos += left;
            let t = pos / len;
            let p = (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
            if drawing {
                cur.push(p);
                out.push(std::mem::take(&mut cur));
            } else {
                cur = vec![p];
            }
            drawing = !drawing;
            left = if drawing { on } else { off };
        }
        left -= len - pos;
        if drawing {
            cur.push(b);
        }
    }
    if drawing && cur.len() > 1 {
        out.push(cur);
    }
    out
}

/// Clips a polyline to the rectangle [x0, x1] × [y0, y1] (Liang–Barsky per segment): the pieces
/// inside, so nothing is drawn outside its panel.
fn clip_polyline(line: &[(f64, f64)], xr: (f64, f64), yr: (f64, f64)) -> Vec<Vec<(f64, f64)>> {
    let mut out: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut cur: Vec<(f64, f64)> = Vec::new();
    let inside = |p: (f64, f64)| p.0 >= xr.0 && p.0 <= xr.1 && p.1 >= yr.0 && p.1 <= yr.1;
    if line.len() == 1 && inside(line[0]) {
        return vec![line.to_vec()];
    }
    for w in line.windows(2) {
        let (a, b) = (w[0], w[1]);
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        let mut visible = true;
        for (p, q) in [(-dx, a.0 - xr.0), (dx, xr.1 - a.0), (-dy, a.1 - yr.0), (dy, yr.1 - a.1)] {
            if p == 0.0 {
                if q < 0.0 {
                    visible = false;
                }
            } else {
                let r = q / p;
                if p < 0.0 {
                    t0 = t0.max(r);
                } else {
                    t1 = t1.min(r);
                }
            }
        }
        if !visible || t0 > t1 {
            if cur.len() > 1 {
                out.push(std::mem::take(&mut cur));
            }
            cur.clear();
            continue;
        }
        let pa = (a.0 + t0 * dx, a.1 + t0 * dy);
        let pb = (a.0 + t1 * dx, a.1 + t1 * dy);
        if cur.is_empty() || t0 > 0.0 {
            if cur.len() > 1 {
                out.push(std::mem::take(&mut cur));
            }
            cur = vec![pa];
        }
        cur.push(pb);
        if t1 < 1.0 {
            out.push(std::mem::take(&mut cur));
        }
    }
    if cur.len() > 1 {
        out.push(cur);
    }
    out
}

/// The legend (samples drawn as the layers are) and the notes, in the column right of a chart.
fn draw_side_column<DB: DrawingBackend>(
    column: &DrawingArea<DB, Shift>,
    entries: &[(Key, String)],
    notes: &[String],
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let font = (FONT, 13);
    let mut y = 44;
    for (key, text) in entries {
        let c = y + 8;
        match key {
            Key::Line(st) => {
                let s = st.shape();
                if st.dashed {
                    column.draw(&PathElement::new(vec![(6, c), (13, c)], s))?;
                    column.draw(&PathElement::new(vec![(17, c), (24, c)], s))?;
                    column.draw(&PathElement::new(vec![(28, c), (30, c)], s))?;
                } else {
                    column.draw(&PathElement::new(vec![(6, c), (30, c)], s))?;
                }
            }
            Key::Marker(st, size) => column.draw(&Circle::new((18, c), *size, st.shape()))?,
            Key::Fill(st) => {
                column.draw(&Rectangle::new([(8, c - 6), (28, c + 6)], st.shape()))?;
                column.draw(&Rectangle::new(
                    [(8, c - 6), (28, c + 6)],
                    Style { filled: false, alpha: 1.0, ..*st }.shape(),
                ))?;
            }
        }
        column.draw(&Text::new(text.clone(), (36, y), font))?;
        y += 20;
    }
    if !notes.is_empty() {
        y += if entries.is_empty() { 0 } else { 10 };
        let (cw, _) = column.dim_in_pixel();
        let box_h = 10 + 18 * notes.len() as i32;
        column
            .draw(&Rectangle::new([(4, y), (cw as i32 - 6, y + box_h)], ShapeStyle::from(RGBColor(160, 160, 160))))?;
        for (k, note) in notes.iter().enumerate() {
            column.draw(&Text::new(note.clone(), (10, y + 6 + 18 * k as i32), font))?;
        }
    }
    Ok(())
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
pub fn format_tick(v: f64) -> String {
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
    fn lines_are_clipped_to_the_panel_and_dashed_on_screen() {
        // A segment crossing the box [0, 1]² enters at x = 0 and leaves at x = 1.
        let near = |a: &[(f64, f64)], b: &[(f64, f64)]| {
            a.len() == b.len() && a.iter().zip(b).all(|(p, q)| (p.0 - q.0).abs() < 1e-12 && (p.1 - q.1).abs() < 1e-12)
        };
        let pieces = clip_polyline(&[(-1.0, 0.5), (2.0, 0.5)], (0.0, 1.0), (0.0, 1.0));
        assert_eq!(pieces.len(), 1);
        assert!(near(&pieces[0], &[(0.0, 0.5), (1.0, 0.5)]), "{pieces:?}");
        // Leaving and re-entering gives two pieces; a line wholly outside gives none.
        let pieces = clip_polyline(&[(0.5, 0.5), (0.5, 3.0), (0.7, 3.0), (0.7, 0.2)], (0.0, 1.0), (0.0, 1.0));
        assert_eq!(pieces.len(), 2);
        assert!(near(&pieces[0], &[(0.5, 0.5), (0.5, 1.0)]), "{pieces:?}");
        assert!(near(&pieces[1], &[(0.7, 1.0), (0.7, 0.2)]), "{pieces:?}");
        assert!(clip_polyline(&[(2.0, 2.0), (3.0, 3.0)], (0.0, 1.0), (0.0, 1.0)).is_empty());
        // 22 px at 1 px per unit: dashes of 7 on, 4 off → [0, 7], [11, 18], [22, 22] dropped.
        let d = dashes(&[(0.0, 0.0), (10.0, 0.0), (22.0, 0.0)], (1.0, 1.0), 7.0, 4.0);
        assert_eq!(d[0], vec![(0.0, 0.0), (7.0, 0.0)]);
        assert_eq!(d[1], vec![(11.0, 0.0), (18.0, 0.0)]);
        let on: f64 = d.iter().map(|p| p.last().unwrap().0 - p[0].0).sum();
        assert!((on - 14.0).abs() < 1e-9, "{d:?}");
    }

    #[test]
    fn log_axes_map_to_decades_and_drop_non_positive_values() {
        let panel = Panel {
            log_y: true,
            layers: vec![Layer::Histogram {
                edges: vec![0.0, 1.0, 2.0],
                counts: vec![0.0, 100.0],
                style: Style::fill(palette(0), 0.5),
                label: None,
            }],
            ..Panel::default()
        };
        let logged = to_log(&panel);
        let Layer::Histogram { counts, .. } = &logged.layers[0] else { unreachable!() };
        assert!(counts[0].is_nan() && counts[1] == 2.0);
        let (_, y) = data_range(&logged);
        assert!(y.0 < 2.0 - 0.3 && y.1 > 2.0, "{y:?}");
    }

    #[test]
    fn png_glyphs_keep_their_side_bearings() {
        // plotters 0.3.7 starts every glyph's ink at the pen; TextFix starts it at pen + left side
        // bearing, as the font says. 'l' in DejaVu Sans has a bearing of about 0.09 em.
        register_font();
        let (w, h) = (200u32, 80u32);
        let mut buf = vec![255u8; (w * h * 3) as usize];
        let font = FontRef::try_from_slice(FONT_BYTES).unwrap();
        let scaled = font.as_scaled(40.0);
        let bearing = scaled.h_side_bearing(scaled.glyph_id('l'));
        assert!(bearing > 2.0, "bearing {bearing} px");
        {
            let root =
                TextFix { inner: BitMapBackend::with_buffer(&mut buf, (w, h)), font: font.clone() }.into_drawing_area();
            root.draw(&Text::new("l", (20, 10), (FONT, 40))).unwrap();
            root.present().unwrap();
        }
        let inked = |x: u32| (0..h).any(|y| buf[((y * w + x) * 3) as usize] < 128);
        let first = (0..w).find(|&x| inked(x)).expect("the glyph is drawn");
        assert!((first as f32 - (20.0 + bearing)).abs() <= 1.0, "ink starts at {first}, bearing {bearing}");
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
