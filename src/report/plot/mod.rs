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
//! the glyph's left side bearing, so letters are unevenly spaced. `TextFix` wraps the bitmap
//! backend and draws text itself with the bearings and a fractional pen.
//!
//! Degenerate data never panics: non-finite values are skipped, a zero range is padded, empty
//! panels get a unit frame.

use std::path::{Path, PathBuf};

use ab_glyph::FontRef;
use plotters::prelude::*;

use crate::error::{Error, Result};

mod draw;
mod text;

use draw::draw;
pub(crate) use draw::format_tick;
use text::{FONT_BYTES, TextFix, register_font};

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
    Lines {
        /// Each line's points in the panel's data units; a non-finite point breaks the line.
        lines: Vec<Vec<(f64, f64)>>,
        /// Colour, width, opacity and dash of every line.
        style: Style,
        /// The legend entry (none: not in the legend).
        label: Option<String>,
    },
    /// Markers.
    Points {
        /// Marker centres in data units (non-finite and out-of-range points are skipped).
        points: Vec<(f64, f64)>,
        /// Colour and fill of the markers.
        style: Style,
        /// Marker radius in pixels.
        size: u32,
        /// The legend entry (none: not in the legend).
        label: Option<String>,
    },
    /// Bars between consecutive `edges` with heights `counts`.
    Histogram {
        /// Bin edges on x, one more than `counts`.
        edges: Vec<f64>,
        /// Bar heights (counts or fractions, whatever the y axis says).
        counts: Vec<f64>,
        /// Fill colour and opacity of the bars.
        style: Style,
        /// The legend entry (none: not in the legend).
        label: Option<String>,
    },
    /// Isolines of z on a grid (z y-major: z[j·nx + i]) at the given levels.
    Contours {
        /// Grid abscissae, nx of them.
        x: Vec<f64>,
        /// Grid ordinates, ny of them.
        y: Vec<f64>,
        /// The nx·ny values, row j (y) after row.
        z: Vec<f64>,
        /// The values of z an isoline is drawn at.
        levels: Vec<f64>,
        /// Colour and width of every isoline.
        style: Style,
        /// The legend entry (none: not in the legend).
        label: Option<String>,
    },
    /// Shaded vertical bands over the full height.
    Spans {
        /// Each band's x from and to, clipped to the x range.
        spans: Vec<(f64, f64)>,
        /// Fill colour and opacity.
        style: Style,
        /// The legend entry (none: not in the legend).
        label: Option<String>,
    },
    /// A horizontal line.
    HLine {
        /// Where, in data units.
        y: f64,
        /// Colour, width and dash.
        style: Style,
    },
    /// A vertical line.
    VLine {
        /// Where, in data units.
        x: f64,
        /// Colour, width and dash.
        style: Style,
    },
    /// Box plots at x = 0, 1, 2, … (the panel's x axis shows their labels).
    Boxes {
        /// The boxes, left to right.
        items: Vec<BoxItem>,
    },
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

#[cfg(test)]
mod tests {
    use ab_glyph::{Font, ScaleFont};

    use super::draw::{clip_polyline, dashes, data_range, one_two_five, thin, to_log};
    use super::text::FONT;
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
        // 0.1 px apart at 10 px per unit: thinned to points ≥ 1.5 px apart, both ends kept.
        let dense: Vec<(f64, f64)> = (0..=100).map(|i| (i as f64 * 0.01, 0.0)).collect();
        let t = thin(&dense, (10.0, 10.0), 1.5);
        assert_eq!((t[0], *t.last().unwrap()), ((0.0, 0.0), (1.0, 0.0)));
        assert!(t[..t.len() - 1].windows(2).all(|w| (w[1].0 - w[0].0) * 10.0 >= 1.5 - 1e-9), "{t:?}");
        assert!(t.len() < 10, "{}", t.len());
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
    fn short_log_axes_label_one_two_five() {
        // Ticks every 0.1 in log₁₀ land within 0.3 % of 2 and 5 × 10ᵏ; others stay unlabelled.
        let labels: Vec<String> = (-10..=10).map(|i| one_two_five(i as f64 / 10.0)).collect();
        let shown: Vec<&str> = labels.iter().map(String::as_str).filter(|s| !s.is_empty()).collect();
        assert_eq!(shown, ["0.1", "0.2", "0.5", "1", "2", "5", "10"]);
        assert_eq!(one_two_five(-2.7), "0.002");
    }

    #[test]
    fn png_wide_shallow_lines_are_continuous() {
        // A shallow line sampled every pixel, 2 px wide: plotters' polygon fill drew it as dots.
        let (w, h) = (300u32, 60u32);
        let mut buf = vec![255u8; (w * h * 3) as usize];
        {
            let font = FontRef::try_from_slice(FONT_BYTES).unwrap();
            let root = TextFix { inner: BitMapBackend::with_buffer(&mut buf, (w, h)), font }.into_drawing_area();
            let line: Vec<(i32, i32)> = (10..290).map(|x| (x, 20 + (x - 10) / 14)).collect();
            root.draw(&PathElement::new(line, ShapeStyle { color: BLACK.into(), filled: false, stroke_width: 2 }))
                .unwrap();
            root.present().unwrap();
        }
        let inked = |x: u32| (0..h).filter(|&y| buf[((y * w + x) * 3) as usize] < 128).count();
        let gaps: Vec<u32> = (11..289).filter(|&x| inked(x) < 2).collect();
        assert!(gaps.is_empty(), "columns without two inked pixels: {gaps:?}");
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
