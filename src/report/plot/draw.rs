//! Drawing a [`Figure`] with plotters: one chart per panel with its axes (linear or
//! logarithmic), its layers clipped to the chart and dashed here, and a column to the right for
//! the legend and notes, never over the data.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::text::FONT;
use super::*;
use crate::report::contour::isolines;

pub(super) fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, fig: &Figure) -> std::result::Result<(), String> {
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
pub(super) fn data_range(panel: &Panel) -> ((f64, f64), (f64, f64)) {
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

/// One legend entry: how its sample is drawn and its text.
pub(super) enum Key {
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
pub(super) fn to_log(panel: &Panel) -> Panel {
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

/// A panel's chart: both axes linear in the values drawn (logarithmic axes are mapped to log₁₀
/// by [`to_log`] first).
type Chart<'a, DB> =
    ChartContext<'a, DB, Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>>;

/// The data window of a chart: its ranges and its pixels per data unit on each axis (for dashes
/// of a fixed length on screen).
#[derive(Clone, Copy)]
struct Window {
    xr: (f64, f64),
    yr: (f64, f64),
    scale: (f64, f64),
}

/// Draws one panel: the side column's width from its texts, the axes' ranges, the chart with
/// its mesh, each layer clipped to the window, then the legend and notes beside it.
fn draw_panel<DB: DrawingBackend>(cell: &DrawingArea<DB, Shift>, original: &Panel) -> std::result::Result<(), String> {
    let e = |x: DrawingAreaErrorKind<DB::ErrorType>| format!("{x:?}");
    let panel = &to_log(original);
    let entries = if panel.legend { legend_entries(panel) } else { Vec::new() };
    let side = side_width(cell, panel, &entries);
    let (w, _) = cell.dim_in_pixel();
    let (area, column) = cell.split_horizontally(w.saturating_sub(side).max(1));
    let (aw, ah) = area.dim_in_pixel();
    let (plot_w, plot_h) = ((aw as f64 - 86.0).max(10.0), (ah as f64 - 84.0).max(10.0));
    let (xr, yr) = axis_ranges(panel, plot_w, plot_h);
    let mut chart = ChartBuilder::on(&area)
        .caption(&panel.title, (FONT, 17))
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(62)
        .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
        .map_err(e)?;
    draw_mesh(&mut chart, cell, panel, (xr, yr), plot_w).map_err(e)?;
    let (pw, ph) = chart.plotting_area().dim_in_pixel();
    let window = Window { xr, yr, scale: (pw as f64 / (xr.1 - xr.0), ph as f64 / (yr.1 - yr.0)) };
    for layer in &panel.layers {
        draw_layer(&mut chart, layer, panel.log_y, window).map_err(e)?;
    }
    if side > 0 {
        draw_side_column(&column, &entries, &panel.notes).map_err(e)?;
    }
    Ok(())
}

/// The width of a text in the legend's and labels' font, in pixels (8 px a character when the
/// backend cannot say).
fn text_width<DB: DrawingBackend>(cell: &DrawingArea<DB, Shift>, t: &str) -> u32 {
    let label_font = TextStyle::from((FONT, 13).into_font());
    cell.estimate_text_size(t, &label_font).map(|s| s.0).unwrap_or(8 * t.len() as u32)
}

/// The side column for the legend and the notes: as wide as its longest text, at most 45 % of
/// the cell; none without either.
fn side_width<DB: DrawingBackend>(cell: &DrawingArea<DB, Shift>, panel: &Panel, entries: &[(Key, String)]) -> u32 {
    let (w, _) = cell.dim_in_pixel();
    let widest = entries
        .iter()
        .map(|(_, t)| text_width(cell, t) + 40)
        .chain(panel.notes.iter().map(|t| text_width(cell, t) + 20))
        .max()
        .unwrap_or(0);
    if widest > 0 { (widest + 16).min(w * 45 / 100) } else { 0 }
}

/// The axes' ranges: the panel's own or its data's, the too narrow one widened for an equal
/// aspect on a plot of `plot_w` × `plot_h` pixels.
fn axis_ranges(panel: &Panel, plot_w: f64, plot_h: f64) -> ((f64, f64), (f64, f64)) {
    let (dx, dy) = data_range(panel);
    let mut xr = panel.x_range.unwrap_or(dx);
    let mut yr = panel.y_range.unwrap_or(dy);
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
    (xr, yr)
}

/// The label of a log₁₀ tick at `v`: the power of ten at a whole decade, two significant digits
/// between decades (3.2, 0.32, not 3.162).
fn log_tick(v: f64) -> String {
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
}

/// Whether a log₁₀ range spans few decades: it then gets ticks every 0.1 in log₁₀ and labels
/// only at 1, 2 and 5 × 10ᵏ (0.1, 0.2, 0.5, 1, 2, 5 instead of 0.32 and 3.2 alone); wider ones
/// a label per decade.
fn few_decades(r: (f64, f64)) -> bool {
    r.1 - r.0 <= 2.5
}

/// How many labels a log₁₀ axis over `r` asks for.
fn log_labels(r: (f64, f64)) -> usize {
    if few_decades(r) {
        ((r.1 - r.0) * 10.0).ceil() as usize + 1
    } else {
        ((r.1 - r.0).ceil() as usize + 1).clamp(3, 12)
    }
}

/// `label` shortened in the middle, where names of a family agree least, until it is at most
/// `slot` pixels wide (less a margin) or 4 characters long.
fn fit_slot<DB: DrawingBackend>(cell: &DrawingArea<DB, Shift>, label: &str, slot: u32) -> String {
    let chars: Vec<char> = label.chars().collect();
    let mut keep = chars.len();
    let shown = |k: usize| -> String {
        if k >= chars.len() {
            return label.to_string();
        }
        let head: String = chars[..k.div_ceil(2)].iter().collect();
        let tail: String = chars[chars.len() - k / 2..].iter().collect();
        format!("{head}…{tail}")
    };
    while keep > 4 && text_width(cell, &shown(keep)) > slot.saturating_sub(6) {
        keep -= 1;
    }
    shown(keep)
}

/// The axes, their descriptions, the grid and the tick labels: box plots label their
/// categories, logarithmic axes their decades (or 1, 2, 5 × 10ᵏ over few decades).
fn draw_mesh<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    cell: &DrawingArea<DB, Shift>,
    panel: &Panel,
    (xr, yr): ((f64, f64), (f64, f64)),
    plot_w: f64,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let categories: Option<Vec<String>> = panel.layers.iter().find_map(|l| match l {
        Layer::Boxes { items } => Some(items.iter().map(|b| b.label.clone()).collect()),
        _ => None,
    });
    // A category label at most as wide as its box's slot (else the first is cut at the panel's
    // edge and neighbours overlap).
    let slot = categories.as_ref().map_or(0, |c| (plot_w / c.len().max(1) as f64) as u32);
    let formatter = |v: &f64| -> String {
        match &categories {
            Some(c) => {
                let i = v.round();
                if (v - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < c.len() {
                    fit_slot(cell, &c[i as usize], slot)
                } else {
                    String::new()
                }
            }
            None if panel.log_x && few_decades(xr) => one_two_five(*v),
            None if panel.log_x => log_tick(*v),
            None => format_tick(*v),
        }
    };
    let y_formatter = |v: &f64| match (panel.log_y, few_decades(yr)) {
        (true, true) => one_two_five(*v),
        (true, false) => log_tick(*v),
        _ => format_tick(*v),
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
        .y_label_formatter(&y_formatter);
    if let Some(c) = &categories {
        mesh.x_labels(c.len() * 2 + 1);
    } else if panel.log_x {
        mesh.x_labels(log_labels(xr));
    }
    if panel.log_y {
        mesh.y_labels(log_labels(yr));
    }
    mesh.draw()
}

/// Draws one layer inside the window, clipped to it (`log_y`: the counts of a histogram are
/// log₁₀, its bars stand on the bottom of the window).
fn draw_layer<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    layer: &Layer,
    log_y: bool,
    window: Window,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let Window { xr, yr, scale } = window;
    let clip = |line: &[(f64, f64)]| clip_polyline(line, xr, yr);
    match layer {
        Layer::Lines { lines, style, .. } => {
            for line in lines {
                for run in finite_runs(line) {
                    for piece in clip(&run) {
                        draw_line(chart, piece, style, scale)?;
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
            chart.draw_series(pts.into_iter().map(|p| Circle::new(p, size, s)))?;
        }
        Layer::Histogram { edges, counts, style, .. } => {
            let fill = Style { filled: true, ..*style }.shape();
            let outline = Style { filled: false, alpha: 1.0, ..*style }.shape();
            let base = if log_y { yr.0 } else { 0.0f64.max(yr.0) };
            let bars: Vec<(f64, f64, f64)> = edges
                .windows(2)
                .zip(counts)
                .filter(|(w, c)| w[0].is_finite() && w[1].is_finite() && c.is_finite() && **c > base)
                .map(|(w, c)| (w[0].max(xr.0), w[1].min(xr.1), c.min(yr.1)))
                .filter(|(a, b, _)| a < b)
                .collect();
            chart.draw_series(bars.iter().map(|&(a, b, c)| Rectangle::new([(a, base), (b, c)], fill)))?;
            chart.draw_series(bars.iter().map(|&(a, b, c)| Rectangle::new([(a, base), (b, c)], outline)))?;
        }
        Layer::Contours { x, y, z, levels, style, .. } => {
            for &lv in levels {
                for line in isolines(x, y, z, lv) {
                    for piece in clip(&line) {
                        draw_line(chart, piece, style, scale)?;
                    }
                }
            }
        }
        Layer::Spans { spans, style, .. } => {
            let s = Style { filled: true, ..*style }.shape();
            chart.draw_series(
                spans
                    .iter()
                    .filter(|(a, b)| a.is_finite() && b.is_finite())
                    .map(|&(a, b)| (a.max(xr.0), b.min(xr.1)))
                    .filter(|(a, b)| a < b)
                    .map(|(a, b)| Rectangle::new([(a, yr.0), (b, yr.1)], s)),
            )?;
        }
        Layer::HLine { y, style } => {
            if y.is_finite() && *y >= yr.0 && *y <= yr.1 {
                draw_line(chart, vec![(xr.0, *y), (xr.1, *y)], style, scale)?;
            }
        }
        Layer::VLine { x, style } => {
            if x.is_finite() && *x >= xr.0 && *x <= xr.1 {
                draw_line(chart, vec![(*x, yr.0), (*x, yr.1)], style, scale)?;
            }
        }
        Layer::Boxes { items } => draw_boxes(chart, items)?,
    }
    Ok(())
}

/// Box plots, one per category at x = 0, 1, …: the box from the first to the third quartile, the
/// median across it, whiskers to the extremes (a box with a non-finite value is left out).
fn draw_boxes<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    items: &[BoxItem],
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    for (i, b) in items.iter().enumerate() {
        if b.five.iter().any(|v| !v.is_finite()) {
            continue;
        }
        let x = i as f64;
        let line = Style::line(b.color, 2).shape();
        let fill = Style::fill(b.color, 0.25).shape();
        let [lo, q1, med, q3, hi] = b.five;
        chart.draw_series(std::iter::once(Rectangle::new([(x - 0.3, q1), (x + 0.3, q3)], fill)))?;
        chart.draw_series(std::iter::once(Rectangle::new([(x - 0.3, q1), (x + 0.3, q3)], line)))?;
        for seg in [
            vec![(x - 0.3, med), (x + 0.3, med)],
            vec![(x, q3), (x, hi)],
            vec![(x, q1), (x, lo)],
            vec![(x - 0.15, hi), (x + 0.15, hi)],
            vec![(x - 0.15, lo), (x + 0.15, lo)],
        ] {
            chart.draw_series(LineSeries::new(seg, line))?;
        }
    }
    Ok(())
}

/// The polyline without the points closer than `min_px` pixels on screen to the last one kept
/// (the last point always kept). A densely sampled line (a geodesic's tip path: a sample every
/// pixel) is otherwise drawn as one-pixel segments between rounded pixel positions, which the
/// bitmap backend renders as a row of dots.
pub(super) fn thin(line: &[(f64, f64)], scale: (f64, f64), min_px: f64) -> Vec<(f64, f64)> {
    let mut out: Vec<(f64, f64)> = Vec::with_capacity(line.len());
    for (i, &p) in line.iter().enumerate() {
        let far =
            out.last().is_none_or(|&(x, y): &(f64, f64)| ((p.0 - x) * scale.0).hypot((p.1 - y) * scale.1) >= min_px);
        if far || i + 1 == line.len() {
            out.push(p);
        }
    }
    out
}

/// Draws a polyline (already clipped), solid or dashed (7 px on, 4 px off on screen).
fn draw_line<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    line: Vec<(f64, f64)>,
    style: &Style,
    scale: (f64, f64),
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let s = style.shape();
    if !style.dashed {
        chart.draw_series(std::iter::once(PathElement::new(thin(&line, scale, 4.0), s)))?;
        return Ok(());
    }
    chart.draw_series(dashes(&line, scale, 7.0, 4.0).into_iter().map(|d| PathElement::new(d, s)))?;
    Ok(())
}

/// The dashes of a polyline: pieces `on` pixels long separated by `off` pixels, measured on
/// screen (`scale` = pixels per data unit on each axis).
pub(super) fn dashes(line: &[(f64, f64)], scale: (f64, f64), on: f64, off: f64) -> Vec<Vec<(f64, f64)>> {
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
pub(super) fn clip_polyline(line: &[(f64, f64)], xr: (f64, f64), yr: (f64, f64)) -> Vec<Vec<(f64, f64)>> {
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
pub(super) fn finite_runs(line: &[(f64, f64)]) -> Vec<Vec<(f64, f64)>> {
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
/// The label of a log₁₀ tick at `v` when it sits at 1, 2 or 5 × 10ᵏ (within 1 %), else none: a
/// log axis of few decades has a tick every 0.1 in log₁₀ and labels only these.
pub(super) fn one_two_five(v: f64) -> String {
    let x = 10f64.powf(v);
    let k = x.log10().floor();
    let m = x / 10f64.powf(k);
    match [1.0, 2.0, 5.0, 10.0].into_iter().find(|c| (m / c - 1.0).abs() < 0.01) {
        Some(c) => {
            let x = c * 10f64.powf(k);
            let digits = (-(x.log10().floor())).max(0.0) as usize;
            if (1e-3..1e5).contains(&x) { format!("{x:.digits$}") } else { format!("{x:.0e}") }
        }
        None => String::new(),
    }
}

/// A tick label (and the histogram's first-bin note): at most three decimals without trailing
/// zeros, scientific notation outside [1e-3, 1e5), and `0` for round-off at a tick meant as zero.
pub(crate) fn format_tick(v: f64) -> String {
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
