//! Figures and files of `springfit compare` and `springfit pareto`.

use super::figures::symmetric_edges;
use super::output::OutputDir;
use super::plot::{BoxItem, Figure, Layer, Panel, Style, histogram, palette, render};
use crate::compare::{BudgetPoint, FitRecord, RadiusPoint, table_csv, table_md};
use crate::error::Result;

/// Writes `compare.csv`, `compare.md` and `compare.svg/.png`: the residual-angle histograms of
/// every record on shared bins and axes, and a box plot of |angle| per record.
pub fn write_compare(out: &OutputDir, records: &[FitRecord], signed: bool) -> Result<()> {
    out.write("compare.csv", table_csv(records))?;
    out.write("compare.md", table_md(records))?;
    let all: Vec<f64> = records.iter().flat_map(|r| r.angles.iter().copied()).collect();
    let edges = if signed {
        symmetric_edges(&all, 80)
    } else {
        let m = super::figures::nice_ceil(all.iter().fold(0.0f64, |a, v| a.max(*v)).max(1e-12) * 1.02);
        (0..=80).map(|k| m * k as f64 / 80.0).collect()
    };
    let hist: Vec<Layer> = records
        .iter()
        .enumerate()
        .map(|(i, r)| Layer::Histogram {
            edges: edges.clone(),
            counts: {
                // Fractions of each record's samples, so records of different sizes compare.
                let c = histogram(&r.angles, &edges);
                let n = r.angles.len().max(1) as f64;
                c.iter().map(|v| v / n).collect()
            },
            style: Style::fill(palette(i), 0.35),
            label: Some(r.label.clone()),
        })
        .collect();
    let boxes = records
        .iter()
        .enumerate()
        .map(|(i, r)| {
            BoxItem::from_samples(&r.label, &r.angles.iter().map(|a| a.abs()).collect::<Vec<_>>(), palette(i))
        })
        .collect();
    let panels = vec![
        Panel {
            title: "Residual angles on held-out geodesics (shared bins)".into(),
            x_label: if signed { "signed residual angle (°)".into() } else { "residual angle (°)".into() },
            y_label: "fraction of samples".into(),
            legend: true,
            layers: hist,
            ..Panel::default()
        },
        Panel {
            title: "|angle| per design (min, quartiles, max)".into(),
            y_label: "|residual angle| (°)".into(),
            layers: vec![Layer::Boxes { items: boxes }],
            ..Panel::default()
        },
    ];
    render(
        &Figure { title: Some("springfit compare".into()), width: 1500, height: 620, rows: 1, cols: 2, panels },
        &out.path("compare"),
    )?;
    Ok(())
}

/// Writes `pareto.csv`, `pareto.md` and `pareto.svg/.png`.
pub fn write_pareto(
    out: &OutputDir,
    design: &str,
    budgets: &[BudgetPoint],
    radii: &[RadiusPoint],
    budget_for_radii: usize,
) -> Result<()> {
    let mut csv = String::from(
        "curve,budget,radius,used,median_abs_deg,p95_abs_deg,p99_abs_deg,max_abs_deg,as_built_p99_p50_deg,as_built_p99_p95_deg,trimmed_p99_p50_deg,trimmed_p99_p95_deg\n",
    );
    let mut md = format!(
        "# What accuracy costs: {design}\n\n## Best residual per spring budget\n\nAs built: p99 over Monte Carlo builds at the design's tolerance (p50 / p95 over builds), untrimmed and after each build's trim.\n\n| budget K | springs used | median | p95 | p99 | max | as built p99 | trimmed |\n| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n"
    );
    let opt = |x: Option<f64>| x.map(|v| v.to_string()).unwrap_or_default();
    for b in budgets {
        let ab = b.as_built;
        let tr = ab.and_then(|a| a.trimmed_p99_deg);
        csv.push_str(&format!(
            "budget,{},,{},{},{},{},{},{},{},{},{}\n",
            b.budget,
            b.used,
            b.stats.median_abs,
            b.stats.p95_abs,
            b.stats.p99_abs,
            b.stats.max_abs,
            opt(ab.map(|a| a.p99_deg.p50)),
            opt(ab.map(|a| a.p99_deg.p95)),
            opt(tr.map(|t| t.p50)),
            opt(tr.map(|t| t.p95))
        ));
        md.push_str(&format!(
            "| {} | {} | {:.4}° | {:.4}° | {:.4}° | {:.4}° | {} | {} |\n",
            b.budget,
            b.used,
            b.stats.median_abs,
            b.stats.p95_abs,
            b.stats.p99_abs,
            b.stats.max_abs,
            crate::compare::spread_md(ab.map(|a| a.p99_deg)),
            crate::compare::spread_md(tr)
        ));
    }
    if let Some(best) = crate::compare::best_as_built(budgets) {
        md.push_str(&format!(
            "\n**Best as built: K = {}** (smallest as-built p95 of the p99{}): the budget to buy.\n",
            best.budget,
            if best.as_built.is_some_and(|a| a.trimmed_p99_deg.is_some()) { ", trimmed" } else { "" }
        ));
    }
    md.push_str(&format!("\n## Residual per region size (geodesic ball, budget {})\n\n| radius | springs used | median | p95 | p99 | max |\n| ---: | ---: | ---: | ---: | ---: | ---: |\n", if budget_for_radii == 0 { "none".to_string() } else { budget_for_radii.to_string() }));
    for r in radii {
        csv.push_str(&format!(
            "radius,,{},{},{},{},{},{},,,,\n",
            r.radius, r.used, r.stats.median_abs, r.stats.p95_abs, r.stats.p99_abs, r.stats.max_abs
        ));
        md.push_str(&format!(
            "| {:.2} | {} | {:.4}° | {:.4}° | {:.4}° | {:.4}° |\n",
            r.radius, r.used, r.stats.median_abs, r.stats.p95_abs, r.stats.p99_abs, r.stats.max_abs
        ));
    }
    out.write("pareto.csv", csv)?;
    out.write("pareto.md", md)?;
    let line = |pts: Vec<(f64, f64)>, i: usize, label: &str| Layer::Lines {
        lines: vec![pts],
        style: Style::line(palette(i), 2),
        label: Some(label.into()),
    };
    let dots = |pts: Vec<(f64, f64)>, i: usize| Layer::Points {
        points: pts,
        style: Style::fill(palette(i), 1.0),
        size: 3,
        label: None,
    };
    let b99: Vec<(f64, f64)> = budgets.iter().map(|b| (b.budget as f64, b.stats.p99_abs)).collect();
    let bmax: Vec<(f64, f64)> = budgets.iter().map(|b| (b.budget as f64, b.stats.max_abs)).collect();
    // As built: p95 over builds of the p99, untrimmed and trimmed.
    let ab95: Vec<(f64, f64)> =
        budgets.iter().filter_map(|b| b.as_built.map(|a| (b.budget as f64, a.p99_deg.p95))).collect();
    let tr95: Vec<(f64, f64)> = budgets
        .iter()
        .filter_map(|b| b.as_built.and_then(|a| a.trimmed_p99_deg).map(|t| (b.budget as f64, t.p95)))
        .collect();
    let mut budget_layers = vec![
        line(b99.clone(), 0, "p99 (nominal)"),
        dots(b99, 0),
        line(bmax.clone(), 1, "max (nominal)"),
        dots(bmax, 1),
    ];
    if !ab95.is_empty() {
        budget_layers.extend([line(ab95.clone(), 2, "as built: p95 of p99"), dots(ab95, 2)]);
    }
    if !tr95.is_empty() {
        budget_layers.extend([line(tr95.clone(), 3, "trimmed: p95 of p99"), dots(tr95, 3)]);
    }
    let r99: Vec<(f64, f64)> = radii.iter().map(|r| (r.radius, r.stats.p99_abs)).collect();
    let rmax: Vec<(f64, f64)> = radii.iter().map(|r| (r.radius, r.stats.max_abs)).collect();
    let panels = vec![
        Panel {
            title: "Best residual per spring budget".into(),
            x_label: "springs allowed K".into(),
            y_label: "|residual angle| (°)".into(),
            legend: true,
            layers: budget_layers,
            ..Panel::default()
        },
        Panel {
            title: "Residual per region size".into(),
            x_label: "geodesic-ball radius".into(),
            y_label: "|residual angle| (°)".into(),
            legend: true,
            layers: vec![line(r99.clone(), 0, "p99"), dots(r99, 0), line(rmax.clone(), 1, "max"), dots(rmax, 1)],
            ..Panel::default()
        },
    ];
    render(
        &Figure {
            title: Some(format!("{design}: accuracy versus springs and region")),
            width: 1400,
            height: 560,
            rows: 1,
            cols: 2,
            panels,
        },
        &out.path("pareto"),
    )?;
    Ok(())
}
