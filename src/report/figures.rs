//! The figures of the fit and geodesics commands, built from results as plain data.

use nalgebra::DVector;

use super::plot::{Figure, Layer, Panel, Style, cyclic, histogram, palette};
use crate::design::Design;
use crate::error::Result;
use crate::geodesic::{Fan, Region};
use crate::potential::Potential;
use crate::residual::{AngleSample, AngleStats};

/// A pair of joints (i, j) a configuration-space panel shows as (x, y).
pub type Projection = (usize, usize);

/// The configuration-space views of an arm with `n` joints: (q₁, q₂) for two joints (q₁ twice for
/// one), and the three projections q₁–q₂, q₁–q₃, q₂–q₃ for three or more, so q₃ is seen too.
pub fn projections(n: usize) -> Vec<Projection> {
    match n {
        0 | 1 => vec![(0, 0)],
        2 => vec![(0, 1)],
        _ => vec![(0, 1), (0, 2), (1, 2)],
    }
}

/// Name of joint i (from 0), e.g. "q₃".
pub fn joint_name(i: usize) -> String {
    const SUB: [&str; 10] = ["₀", "₁", "₂", "₃", "₄", "₅", "₆", "₇", "₈", "₉"];
    let sub: String = (i + 1).to_string().chars().map(|c| SUB[c.to_digit(10).unwrap_or(0) as usize]).collect();
    format!("q{sub}")
}

/// Axis name of joint i (from 0), e.g. "q₃ (rad)".
pub fn joint_axis(i: usize) -> String {
    format!("{} (rad)", joint_name(i))
}

/// Every `step`-th geodesic of a fan as polylines in the (q₁, q₂) plane.
pub fn fan_lines(fan: &Fan, step: usize) -> Vec<Vec<(f64, f64)>> {
    fan_lines_in(fan, step, (0, 1))
}

/// Every `step`-th geodesic of a fan projected on the joints `p`.
pub fn fan_lines_in(fan: &Fan, step: usize, p: Projection) -> Vec<Vec<(f64, f64)>> {
    fan.geodesics
        .iter()
        .step_by(step.max(1))
        .map(|g| (0..g.len()).map(|i| (g.q(i)[p.0], g.q(i)[p.1])).collect())
        .collect()
}

/// The equilibrium as a black dot in the (q₁, q₂) plane (q₁ twice for a one-joint arm).
pub fn equilibrium_layer(design: &Design) -> Layer {
    equilibrium_layer_in(design, projections(design.dof())[0])
}

/// The equilibrium as a black dot in the projection `p`.
pub fn equilibrium_layer_in(design: &Design, p: Projection) -> Layer {
    Layer::Points {
        points: vec![(design.q_eq[p.0], design.q_eq[p.1])],
        style: Style::fill((0, 0, 0), 1.0),
        size: 4,
        label: Some("equilibrium".into()),
    }
}

/// The region's boundary as traced by a fan in the (q₁, q₂) plane (see [`boundary_lines`]).
pub fn boundary_line(fan: &Fan) -> Vec<(f64, f64)> {
    let mut b: Vec<(f64, f64)> = fan
        .geodesics
        .iter()
        .filter(|g| !g.is_empty())
        .map(|g| {
            let q = g.q(g.len() - 1);
            (q[0], q[1])
        })
        .collect();
    if let Some(&first) = b.first() {
        b.push(first);
    }
    b
}

/// The region's outline in the projection `p`, closed: a box is its rectangle (all four corners,
/// not the fan's chords across them); a two-joint ball is the fan's end points in order; for
/// three or more joints the end points of directions spread over a sphere have no order, so the
/// outline is their convex hull (the silhouette of the nearly convex ball), not a zig-zag.
pub fn boundary_lines(design: &Design, fan: &Fan, p: Projection) -> Vec<(f64, f64)> {
    if let Region::Box { lower, upper } = &design.region {
        let (x0, x1, y0, y1) = (lower[p.0], upper[p.0], lower[p.1], upper[p.1]);
        return vec![(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)];
    }
    let ends: Vec<(f64, f64)> = fan
        .geodesics
        .iter()
        .filter(|g| !g.is_empty())
        .map(|g| {
            let q = g.q(g.len() - 1);
            (q[p.0], q[p.1])
        })
        .collect();
    if design.dof() == 2 {
        let mut b = ends;
        if let Some(&first) = b.first() {
            b.push(first);
        }
        return b;
    }
    convex_hull(ends)
}

/// The convex hull of points (Andrew's monotone chain), closed (first point repeated).
pub fn convex_hull(mut pts: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    pts.retain(|p| p.0.is_finite() && p.1.is_finite());
    pts.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let cross = |o: (f64, f64), a: (f64, f64), b: (f64, f64)| (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0);
    let mut hull: Vec<(f64, f64)> = Vec::with_capacity(2 * pts.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &(f64, f64)>> =
            if pass == 0 { Box::new(pts.iter()) } else { Box::new(pts.iter().rev()) };
        for &p in iter {
            while hull.len() >= start + 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0 {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    if let Some(&first) = hull.first() {
        hull.push(first);
    }
    hull
}

/// Geodesics in joint space (coloured by direction, the region's boundary in black) and the same
/// motions in Cartesian space: the arm at the equilibrium and the path of its tip along each
/// geodesic (the paper's table of equilibria shows the idea).
pub fn geodesics_figure(design: &Design, fan: &Fan, title: &str) -> Figure {
    let count = fan.geodesics.len();
    let step = (count / 36).max(1);
    let mut joint_layers = Vec::new();
    let mut cart_layers = Vec::new();
    for (i, g) in fan.geodesics.iter().enumerate().step_by(step) {
        let color = cyclic(i as f64 / count as f64);
        let n = g.len();
        joint_layers.push(Layer::Lines {
            lines: vec![(0..n).map(|k| (g.q(k)[0], g.q(k)[1.min(design.dof() - 1)])).collect()],
            // 2 px: the bitmap backend draws a 1 px diagonal of light colour as a row of dots.
            style: Style::line(color, 2),
            label: None,
        });
        let tip: Vec<(f64, f64)> = (0..n)
            .map(|k| {
                let p = design.chain.joint_positions(g.q(k));
                let t = p[p.len() - 1];
                (t[0], t[1])
            })
            .collect();
        cart_layers.push(Layer::Lines { lines: vec![tip], style: Style::line(color, 2), label: None });
    }
    if design.dof() >= 2 {
        joint_layers.push(Layer::Lines {
            lines: vec![boundary_lines(design, fan, (0, 1))],
            style: Style::line((0, 0, 0), 2),
            label: Some(if design.dof() > 2 {
                "region outline (q₁–q₂)".into()
            } else {
                "region boundary".into()
            }),
        });
    }
    joint_layers.push(equilibrium_layer(design));
    let arm: Vec<(f64, f64)> =
        design.chain.joint_positions(design.q_eq.as_slice()).iter().map(|p| (p[0], p[1])).collect();
    cart_layers.push(Layer::Lines {
        lines: vec![arm.clone()],
        style: Style::line((40, 40, 40), 4),
        label: Some("arm at q_eq".into()),
    });
    cart_layers.push(Layer::Points { points: arm, style: Style::fill((40, 40, 40), 1.0), size: 4, label: None });
    let (xl, yl) = if design.dof() >= 2 { ("q₁ (rad)", "q₂ (rad)") } else { ("q₁ (rad)", "q₁ (rad)") };
    Figure {
        title: Some(title.into()),
        width: 1300,
        height: 620,
        rows: 1,
        cols: 2,
        panels: vec![
            Panel {
                title: format!("Geodesics from q_eq in joint space ({} of {count})", count.div_ceil(step)),
                x_label: xl.into(),
                y_label: yl.into(),
                equal_aspect: true,
                legend: true,
                layers: joint_layers,
                ..Panel::default()
            },
            Panel {
                title: "Tip paths in Cartesian space".into(),
                x_label: "x (m)".into(),
                y_label: "y (m)".into(),
                equal_aspect: true,
                legend: true,
                layers: cart_layers,
                ..Panel::default()
            },
        ],
    }
}

/// Bin edges symmetric about 0 covering every sample, with a round width.
pub fn symmetric_edges(samples: &[f64], bins: usize) -> Vec<f64> {
    let m = samples.iter().filter(|v| v.is_finite()).fold(0.0f64, |a, v| a.max(v.abs()));
    let m = if m > 0.0 { nice_ceil(m * 1.02) } else { 1.0 };
    (0..=bins).map(|k| -m + 2.0 * m * k as f64 / bins as f64).collect()
}

/// The smallest 1, 2, 2.5 or 5 × 10ᵏ at or above x.
pub fn nice_ceil(x: f64) -> f64 {
    let e = 10f64.powf(x.log10().floor());
    for f in [1.0, 2.0, 2.5, 5.0, 10.0] {
        if f * e >= x {
            return f * e;
        }
    }
    10.0 * e
}

/// Notes with the residual statistics.
pub fn stats_notes(st: &AngleStats) -> Vec<String> {
    vec![
        format!("{} samples", st.count),
        format!("median |angle| = {}", crate::units::deg(st.median_abs)),
        format!("p95 |angle| = {}", crate::units::deg(st.p95_abs)),
        format!("p99 |angle| = {}", crate::units::deg(st.p99_abs)),
        format!("max |angle| = {}", crate::units::deg(st.max_abs)),
    ]
}

/// The signed residual-angle histogram with its statistics (the paper's Fig. 4).
pub fn histogram_figure(residuals: &[AngleSample], st: &AngleStats, title: &str, signed: bool) -> Figure {
    let angles: Vec<f64> = residuals.iter().map(|r| r.angle_deg).collect();
    let edges = if signed {
        symmetric_edges(&angles, 60)
    } else {
        let m = nice_ceil(angles.iter().fold(0.0f64, |a, v| a.max(*v)).max(1e-12) * 1.02);
        (0..=60).map(|k| m * k as f64 / 60.0).collect()
    };
    let counts = histogram(&angles, &edges);
    let x_label: String = if signed { "signed residual angle (°)".into() } else { "residual angle (°)".into() };
    let layers = vec![
        Layer::Histogram { edges, counts, style: Style::fill(palette(0), 0.55), label: None },
        Layer::VLine { x: 0.0, style: Style::line((0, 0, 0), 1).dashed() },
    ];
    // The same counts on a log axis below, so the tails (the few samples that set p99 and max)
    // show as well as the bulk.
    Figure {
        title: Some(title.into()),
        width: 1000,
        height: 900,
        rows: 2,
        cols: 1,
        panels: vec![
            Panel {
                title: "samples per bin".into(),
                x_label: x_label.clone(),
                y_label: "samples".into(),
                notes: stats_notes(st),
                layers: layers.clone(),
                ..Panel::default()
            },
            Panel {
                title: "the same, log scale (tails)".into(),
                x_label,
                y_label: "samples (log scale)".into(),
                log_y: true,
                notes: stats_notes(st),
                layers,
                ..Panel::default()
            },
        ],
    }
}

/// Adds the as-built band to a residual-angle histogram: the p99 |angle| of the Monte Carlo
/// builds from its p50 to its p95 over builds (mirrored for signed angles), and the trimmed one
/// when the design has trim springs.
///
/// The x axis stays the histogram's own, widened to show a band at most to `BAND_REACH` times
/// the histogram's reach: the builds' band usually lies well beyond the drawing's residuals, and
/// an axis set by it squeezed the histogram into a fifth of the panel (issue 42 item 8). A band
/// the axis cuts says so in its legend entry, with its figures (the notes give them too).
pub fn add_as_built_band(panel: &mut Panel, ab: &crate::asbuilt::AsBuilt, signed: bool) {
    let reach = panel
        .layers
        .iter()
        .filter_map(|l| match l {
            // The bins that hold samples: the edges may span a rounder range than the data.
            Layer::Histogram { edges, counts, .. } => counts
                .iter()
                .enumerate()
                .filter(|(_, c)| **c > 0.0)
                .map(|(i, _)| edges[i].abs().max(edges[i + 1].abs()))
                .reduce(f64::max),
            _ => None,
        })
        .reduce(f64::max)
        .filter(|r| r.is_finite() && *r > 0.0);
    let bands: Vec<&crate::asbuilt::Spread> =
        std::iter::once(&ab.p99_deg).chain(ab.trimmed.as_ref().map(|t| &t.p99_deg)).collect();
    let widest = bands.iter().map(|sp| sp.p95.max(sp.p50)).filter(|x| x.is_finite()).fold(0.0, f64::max);
    let limit = reach.map(|r| (r.max(widest.min(BAND_REACH * r))) * 1.05);
    if let Some(l) = limit {
        panel.x_range = Some(if signed { (-l, l) } else { (0.0, l) });
    }
    let band = |sp: &crate::asbuilt::Spread| {
        let (a, b) = (sp.p50, sp.p95.max(sp.p50));
        if !(a.is_finite() && b.is_finite()) {
            return Vec::new();
        }
        if signed { vec![(a, b), (-b, -a)] } else { vec![(a, b)] }
    };
    let pair = |sp: &crate::asbuilt::Spread| format!("{} / {}", sp.text(sp.p50, 3, "°"), sp.text(sp.p95, 3, "°"));
    let label = |what: &str, sp: &crate::asbuilt::Spread| {
        if !sp.p95.is_finite() {
            // No band to draw (its p95 falls among builds without an equilibrium): the legend
            // says so in a line that fits the panel.
            return format!("{what}: p95 over builds {}", sp.text(sp.p95, 3, "°"));
        }
        let cut = limit.is_some_and(|l| sp.p95.max(sp.p50) > l);
        let beyond = if cut { format!(" (to {} beyond the axis)", sp.text(sp.p95, 3, "°")) } else { String::new() };
        format!("{what}: p99 |angle|, p50–p95 over builds{beyond}")
    };
    panel.layers.push(Layer::Spans {
        spans: band(&ab.p99_deg),
        style: Style::fill(palette(3), 0.25),
        label: Some(label("as built", &ab.p99_deg)),
    });
    panel.notes.push(format!(
        "as built ({}, {} builds): p99 {} (p50 / p95)",
        ab.tolerance.label(),
        ab.builds,
        pair(&ab.p99_deg)
    ));
    if let Some(t) = &ab.trimmed {
        panel.layers.push(Layer::Spans {
            spans: band(&t.p99_deg),
            style: Style::fill(palette(2), 0.25),
            label: Some(label("trimmed", &t.p99_deg)),
        });
        panel.notes.push(format!("trimmed: p99 {}", pair(&t.p99_deg)));
    }
    panel.legend = true;
}

/// How far beyond the histogram's reach (as a multiple of it) the as-built bands may widen its
/// x axis: the histogram keeps at least half the panel's width.
const BAND_REACH: f64 = 2.0;

/// Isolines of the total potential over the region's bounding box, with geodesics and the region
/// boundary on top (the paper's Fig. 5b). For a perfect potential the isolines are the geodesic
/// circles, crossed at right angles (in the metric) by the geodesics. For three or more joints one
/// panel per projection of [`projections`]: the potential on the plane through q_eq spanned by
/// the two joints shown (the other joints at q_eq), the fan's geodesics projected.
pub fn potential_figure(
    design: &Design,
    potential: &dyn Potential,
    fan: &Fan,
    omega: f64,
    title: &str,
) -> Result<Figure> {
    let views = projections(design.dof());
    let mut panels = Vec::new();
    for (k, &p) in views.iter().enumerate() {
        let sliced = views.len() > 1;
        let (contours, mut layers) = potential_layers(design, potential, fan, omega, p)?;
        layers.insert(1, contours);
        panels.push(Panel {
            title: if sliced {
                format!("{}–{} (other joints at q_eq)", joint_name(p.0), joint_name(p.1))
            } else {
                title.into()
            },
            x_label: joint_axis(p.0),
            y_label: joint_axis(p.1),
            equal_aspect: true,
            // One legend for a row of projections, on the last one.
            legend: k + 1 == views.len(),
            notes: if k + 1 == views.len() {
                vec!["isolines at U(q_eq) + ½ω²(kR/8)²,".into(), "k = 1…8".into()]
            } else {
                Vec::new()
            },
            layers,
            ..Panel::default()
        });
    }
    let cols = panels.len();
    Ok(Figure {
        title: if cols > 1 { Some(title.into()) } else { None },
        width: if cols > 1 { 760 * cols as u32 } else { 1000 },
        height: if cols > 1 { 700 } else { 800 },
        rows: 1,
        cols,
        panels,
    })
}

/// The isolines of U in projection `p` (the plane through q_eq) and the geodesics, boundary and
/// equilibrium layers that go with them.
pub fn potential_layers(
    design: &Design,
    potential: &dyn Potential,
    fan: &Fan,
    omega: f64,
    p: Projection,
) -> Result<(Layer, Vec<Layer>)> {
    let (mut lo, mut hi) = ((f64::INFINITY, f64::INFINITY), (f64::NEG_INFINITY, f64::NEG_INFINITY));
    for g in &fan.geodesics {
        for i in 0..g.len() {
            let q = g.q(i);
            lo = (lo.0.min(q[p.0]), lo.1.min(q[p.1]));
            hi = (hi.0.max(q[p.0]), hi.1.max(q[p.1]));
        }
    }
    let pad = (0.08 * (hi.0 - lo.0), 0.08 * (hi.1 - lo.1));
    let (nx, ny) = (90, 90);
    let x: Vec<f64> =
        (0..nx).map(|i| lo.0 - pad.0 + (hi.0 - lo.0 + 2.0 * pad.0) * i as f64 / (nx - 1) as f64).collect();
    let y: Vec<f64> =
        (0..ny).map(|j| lo.1 - pad.1 + (hi.1 - lo.1 + 2.0 * pad.1) * j as f64 / (ny - 1) as f64).collect();
    let mut z = Vec::with_capacity(nx * ny);
    let mut q = design.q_eq.clone();
    for &yy in &y {
        for &xx in &x {
            q[p.0] = xx;
            q[p.1] = yy;
            z.push(potential.value(q.as_slice())? + design.chain.gravity_potential(q.as_slice()));
        }
    }
    // Levels of ½ω²r² at r = R/8, 2R/8, …, R: where a perfect potential's isolines would be.
    let extent = fan.geodesics.iter().map(|g| g.length()).fold(0.0, f64::max);
    let u0 = potential.value(design.q_eq.as_slice())? + design.chain.gravity_potential(design.q_eq.as_slice());
    let levels: Vec<f64> = (1..=8).map(|k| u0 + 0.5 * omega * omega * (extent * k as f64 / 8.0).powi(2)).collect();
    let step = (fan.geodesics.len() / 24).max(1);
    let contours = Layer::Contours {
        x,
        y,
        z,
        levels,
        style: Style::line(palette(1), if design.dof() > 2 { 1 } else { 2 }),
        label: Some(if design.dof() > 2 { "isolines of U (slice)".into() } else { "isolines of U".into() }),
    };
    let layers = vec![
        Layer::Lines {
            lines: fan_lines_in(fan, step, p),
            style: Style::line((150, 150, 150), 1),
            label: Some(if design.dof() > 2 { "geodesics (projected)".into() } else { "geodesics".into() }),
        },
        Layer::Lines {
            lines: vec![boundary_lines(design, fan, p)],
            style: Style::line((0, 0, 0), 2).dashed(),
            label: Some(if design.dof() > 2 { "region outline".into() } else { "region boundary".into() }),
        },
        equilibrium_layer_in(design, p),
    ];
    Ok((contours, layers))
}

/// A joint-space vector as text.
pub fn fmt_q(q: &DVector<f64>) -> String {
    format!("({})", q.iter().map(|x| format!("{x:.4}")).collect::<Vec<_>>().join(", "))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A band whose p95 falls among builds without an equilibrium is not drawn, and its legend
    /// entry is one short line with the bound (it read "to beyond X° beyond the axis" and ran
    /// past the image's edge); a band with figures is drawn and labelled as before.
    #[test]
    fn a_lost_band_gets_a_short_legend_entry() {
        use crate::asbuilt::{AsBuilt, Spread};
        let lost = Spread::of((0..200).map(|i| if i % 3 == 0 { 0.01 * i as f64 } else { f64::NAN }));
        let kept = Spread::of((0..200).map(|i| 0.004 * i as f64));
        let ab = |p99: Spread| AsBuilt {
            tolerance: crate::design::tolerance::ToleranceSpec::Fraction(0.05),
            distribution: crate::design::tolerance::Distribution::Uniform,
            builds: 200,
            seed: 1,
            builds_without_equilibrium: p99.without,
            p99_deg: p99,
            max_deg: p99,
            shift_rad: p99,
            shift_metric: p99,
            trimmed: None,
            preload_trimmed: None,
            shift_model: None,
        };
        let labels = |p99: Spread| {
            let mut panel = Panel {
                layers: vec![Layer::Histogram {
                    edges: vec![0.0, 0.5, 1.0],
                    counts: vec![3.0, 1.0],
                    style: Style::fill(palette(0), 0.5),
                    label: None,
                }],
                ..Panel::default()
            };
            add_as_built_band(&mut panel, &ab(p99), false);
            panel
                .layers
                .iter()
                .filter_map(|l| match l {
                    Layer::Spans { spans, label, .. } => Some((spans.len(), label.clone().unwrap_or_default())),
                    _ => None,
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(labels(lost), vec![(0, "as built: p95 over builds beyond 1.980°".to_string())]);
        let drawn = labels(kept);
        assert_eq!(drawn[0].0, 1);
        assert_eq!(drawn[0].1, "as built: p99 |angle|, p50–p95 over builds");
    }

    #[test]
    fn nice_numbers() {
        assert_eq!(nice_ceil(0.7), 1.0);
        assert_eq!(nice_ceil(1.3), 2.0);
        assert_eq!(nice_ceil(2.2), 2.5);
        assert_eq!(nice_ceil(0.031), 0.05);
        let e = symmetric_edges(&[-0.3, 0.1], 4);
        assert_eq!(e, vec![-0.5, -0.25, 0.0, 0.25, 0.5]);
    }

    #[test]
    fn convex_hull_outlines_a_point_cloud() {
        // A square's corners plus interior points: the hull is the square, closed.
        let mut pts = vec![(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0), (0.5, 0.5), (0.2, 0.7), (0.9, 0.1)];
        pts.reverse();
        let h = convex_hull(pts);
        assert_eq!(h.len(), 5);
        assert_eq!(h.first(), h.last());
        for corner in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
            assert!(h.contains(&corner), "{h:?}");
        }
        // Counter-clockwise: positive signed area.
        let area: f64 = h.windows(2).map(|w| w[0].0 * w[1].1 - w[1].0 * w[0].1).sum::<f64>() / 2.0;
        assert!((area - 1.0).abs() < 1e-12);
        assert_eq!(projections(3), vec![(0, 1), (0, 2), (1, 2)]);
        assert_eq!(joint_axis(2), "q₃ (rad)");
    }
}
