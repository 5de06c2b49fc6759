//! Figures and files of `springfit compare` and `springfit pareto`.

use super::output::OutputDir;
use super::plot::{BoxItem, Figure, Layer, Panel, Style, histogram, palette, render};
use crate::error::Result;
use crate::residual::AngleStats;
use crate::studies::compare::{BudgetPoint, FitRecord, MassCurve, MassPoint, RadiusPoint, table_csv, table_md};

/// Edges of `bins` bins even in log₁₀ from a decade at or under the smallest record's 1st
/// percentile of |angle| to a round value over the largest |angle| (at most 8 decades): fits whose
/// residuals differ by orders of magnitude (a dense fit, the exact potential) each get bins of
/// their own instead of sharing the first bin of a linear axis.
pub fn log_edges(records: &[FitRecord], bins: usize) -> Vec<f64> {
    let mut hi = 0.0f64;
    let mut lo = f64::INFINITY;
    for r in records {
        let mut a: Vec<f64> = r.angles.iter().map(|v| v.abs()).filter(|v| v.is_finite() && *v > 0.0).collect();
        a.sort_by(f64::total_cmp);
        if let Some(&m) = a.last() {
            hi = hi.max(m);
            lo = lo.min(crate::residual::percentile(&a, 1.0));
        }
    }
    if hi <= 0.0 {
        hi = 1.0;
    }
    let top = super::figures::nice_ceil(hi * 1.02).log10();
    let bottom = if lo.is_finite() && lo > 0.0 { lo.log10().floor() } else { top - 3.0 }.max(top - 8.0).min(top - 1.0);
    (0..=bins).map(|k| 10f64.powf(bottom + (top - bottom) * k as f64 / bins as f64)).collect()
}

/// The names `springfit compare` may write (see [`super::output::Plan`]), `report.html` included.
pub const COMPARE_FILES: &[&str] = &["compare.csv", "compare.md", "compare.svg", "compare.png", super::html::FILE];

/// The names `springfit pareto` may write, `report.html` included.
pub const PARETO_FILES: &[&str] = &[
    "pareto.csv",
    "pareto.md",
    "pareto.svg",
    "pareto.png",
    "pareto_mass.csv",
    "pareto_mass.json",
    "pareto_mass.svg",
    "pareto_mass.png",
    super::html::FILE,
];

/// Writes everything `springfit compare` writes into the folder `target` under `plan`
/// ([`COMPARE_FILES`]): the files of [`write_compare`] (signed histograms when any residual
/// angle is negative: two-joint fits) and `report.html`, staged and committed at once.
pub fn write_compare_folder(claim: super::output::Claim, records: &[FitRecord]) -> Result<std::path::PathBuf> {
    let dir = claim.open()?;
    // Two-joint residual angles are signed; three or more are unsigned (all ≥ 0).
    let signed = records.iter().any(|r| r.angles.iter().any(|a| *a < 0.0));
    write_compare(&dir, records, signed)?;
    super::html::write_compare(&dir)?;
    dir.commit()
}

/// Writes `compare.csv`, `compare.md` and `compare.svg/.png`: the histograms of |residual angle|
/// of every record on shared logarithmic bins, and a box plot of |angle| per record on a log axis.
/// Two-joint angles are signed and three-joint ones are not, so the figure compares magnitudes
/// whatever `signed` says (kept for the callers). |angle| under the first edge is counted in the
/// first bin.
pub fn write_compare(out: &OutputDir, records: &[FitRecord], signed: bool) -> Result<()> {
    let _ = signed;
    out.write("compare.csv", table_csv(records))?;
    out.write("compare.md", table_md(records))?;
    let edges = log_edges(records, 80);
    let hist: Vec<Layer> = records
        .iter()
        .enumerate()
        .map(|(i, r)| Layer::Histogram {
            edges: edges.clone(),
            counts: {
                // Fractions of each record's samples, so records of different sizes compare.
                let lowest = edges[0];
                let mags: Vec<f64> = r.angles.iter().map(|a| a.abs().max(lowest)).collect();
                let c = histogram(&mags, &edges);
                let n = r.angles.len().max(1) as f64;
                c.iter().map(|v| v / n).collect()
            },
            style: Style::fill(palette(i), 0.35),
            label: Some(r.label.clone()),
        })
        .collect();
    // The exact reference puts every sample in the first bin: a bar of height 1 that would squash
    // every real design into the bottom tenth of the axis. The axis is set by the fitted designs'
    // tallest bin; the reference's bar is cut there and a note says so.
    let tallest = |exact: bool| {
        hist.iter()
            .zip(records)
            .filter(|(_, r)| (r.solver == "exact") == exact)
            .filter_map(|(l, _)| match l {
                Layer::Histogram { counts, .. } => counts.iter().copied().reduce(f64::max),
                _ => None,
            })
            .fold(0.0, f64::max)
    };
    let (fitted_top, exact_top) = (tallest(false), tallest(true));
    let cut = fitted_top > 0.0 && exact_top > 1.2 * fitted_top;
    let mut notes = vec![format!("|angle| < {} counted in the first bin", super::plot::format_tick(edges[0]))];
    if cut {
        notes.push(format!("exact reference: {:.0} % in one bin (bar cut)", 100.0 * exact_top));
    }
    let y_range = cut.then_some((0.0, 1.15 * fitted_top));
    let short = box_labels(records.iter().map(|r| r.label.as_str()));
    let boxes = records
        .iter()
        .enumerate()
        .map(|(i, r)| {
            BoxItem::from_samples(
                &short[i],
                &r.angles.iter().map(|a| a.abs().max(edges[0])).collect::<Vec<_>>(),
                palette(i),
            )
        })
        .collect();
    let panels = vec![
        Panel {
            title: "|residual angle| on held-out geodesics (shared log bins)".into(),
            x_label: "|residual angle| (°, log scale)".into(),
            y_label: "fraction of samples".into(),
            legend: true,
            log_x: true,
            y_range,
            notes,
            layers: hist,
            ..Panel::default()
        },
        Panel {
            title: "|angle| per design (min, quartiles, max)".into(),
            y_label: "|residual angle| (°, log scale)".into(),
            log_y: true,
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

/// Writes `pareto.md`; with a budget or radius curve `pareto.csv` and `pareto.svg/.png`; with a
/// mass curve `pareto_mass.csv`, `pareto_mass.json` and `pareto_mass.svg/.png` (and its section
/// of `pareto.md`).
pub fn write_pareto(
    out: &OutputDir,
    design: &str,
    budgets: &[BudgetPoint],
    radii: &[RadiusPoint],
    mass: Option<&MassCurve>,
    budget_for_radii: usize,
) -> Result<()> {
    let (csv, mut md) = pareto_tables(design, budgets, radii, budget_for_radii);
    if !budgets.is_empty() || !radii.is_empty() {
        out.write("pareto.csv", csv)?;
        render(&pareto_figure(design, budgets, radii), &out.path("pareto"))?;
    }
    if let Some(curve) = mass {
        out.write("pareto_mass.csv", mass_csv(curve))?;
        let json = serde_json::to_string_pretty(curve).expect("the mass curve serialises");
        out.write("pareto_mass.json", json + "\n")?;
        md.push_str(&mass_md(curve));
        render(&mass_figure(curve), &out.path("pareto_mass"))?;
    }
    out.write("pareto.md", md)?;
    Ok(())
}

/// A number as a CSV cell: empty when absent or not finite.
fn cell(x: Option<f64>) -> String {
    x.filter(|v| v.is_finite()).map(|v| v.to_string()).unwrap_or_default()
}

/// `pareto_mass.csv`: one row per mass budget, ascending, then the fit without one (empty
/// `max_spring_mass_kg`); the floor and the arm's mass on every row, so that one file draws the
/// figure.
fn mass_csv(c: &MassCurve) -> String {
    let mut s = String::from(
        "max_spring_mass_kg,used,median_abs_deg,p95_abs_deg,p99_abs_deg,max_abs_deg,model_mass_kg,spring_mass_kg,without_part,stored_energy_over_potential,preload_total_nm,floor_kg,arm_mass_kg,infeasible\n",
    );
    for p in &c.points {
        let r = p.realised.as_ref();
        let used = if p.infeasible.is_none() { p.used.to_string() } else { String::new() };
        s.push_str(&format!(
            "{},{used},{},{},{},{},{},{},{},{},{},{},{},{}\n",
            cell(p.max_spring_mass_kg),
            cell(Some(p.stats.median_abs)),
            cell(Some(p.stats.p95_abs)),
            cell(Some(p.stats.p99_abs)),
            cell(Some(p.stats.max_abs)),
            cell(p.model_mass_kg),
            cell(r.and_then(|r| r.spring_mass_kg)),
            r.map(|r| r.without_part.to_string()).unwrap_or_default(),
            cell(r.map(|r| r.stored_energy_over_potential)),
            cell(r.map(|r| r.preload_total_nm)),
            c.floor_kg,
            c.arm_mass_kg,
            pareto_reason(&p.infeasible)
        ));
    }
    s
}

/// "0.412 kg", or "–".
fn kg(x: Option<f64>) -> String {
    x.filter(|v| v.is_finite()).map(|v| format!("{v:.3} kg")).unwrap_or_else(|| "–".into())
}

/// The mass section of `pareto.md`.
fn mass_md(c: &MassCurve) -> String {
    let mut md = format!(
        "\n## Best residual per spring mass (budget {})\n\nEach row fits the design with `max_spring_mass` set to the budget (the last: without one). *model* is the mass the fit bounds, Σ mᵢ(kᵢ) over the fitted springs by the mass model (trims aside); *parts* the chosen parts' total, trims included, what the arm carries. The floor ρ·U*/u is {:.3} kg (U* = {:.2} J), the arm's moving mass {:.3} kg.\n\n| max_spring_mass | springs used | median | p95 | p99 | max | model | parts | parts / floor | parts / arm | stored energy / U* | total \\|preload\\| |\n| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n",
        if c.max_elements == 0 { "none".to_string() } else { c.max_elements.to_string() },
        c.floor_kg,
        c.potential_energy_j,
        c.arm_mass_kg
    );
    for p in &c.points {
        let budget = p.max_spring_mass_kg.map(|m| format!("{m} kg")).unwrap_or_else(|| "none".into());
        let r = p.realised.as_ref();
        let parts = r.and_then(|r| r.spring_mass_kg);
        let missing = r.filter(|r| r.without_part > 0).map(|r| format!(" ({} without a part)", r.without_part));
        let ratio = |x: Option<f64>, by: f64| x.map(|v| format!("{:.1}×", v / by)).unwrap_or_else(|| "–".into());
        md.push_str(&format!(
            "| {budget} | {} | {} | {}{} | {} | {} | {} | {} |\n",
            pareto_cells(p.used, &p.stats, &p.infeasible),
            kg(p.model_mass_kg),
            kg(parts),
            missing.unwrap_or_default(),
            ratio(parts, c.floor_kg),
            ratio(parts, c.arm_mass_kg),
            r.map(|r| format!("{:.1}×", r.stored_energy_over_potential)).unwrap_or_else(|| "–".into()),
            r.map(|r| format!("{:.1} N·m", r.preload_total_nm)).unwrap_or_else(|| "–".into())
        ));
    }
    push_infeasible(
        &mut md,
        c.points
            .iter()
            .filter_map(|p| p.infeasible.as_ref().map(|w| format!("{}: {w}", kg(p.max_spring_mass_kg))))
            .collect(),
    );
    md
}

/// p99 |angle| against spring mass on log axes: by the parts chosen (what the arm carries) and by
/// the fit's model (what the budget bounds), with the floor and the arm's moving mass as
/// vertical lines; the fit without a budget is the rightmost point of each.
fn mass_figure(c: &MassCurve) -> Figure {
    let feasible: Vec<&MassPoint> = c.points.iter().filter(|p| p.infeasible.is_none()).collect();
    let parts: Vec<(f64, f64)> = feasible
        .iter()
        .filter_map(|p| p.realised.and_then(|r| r.spring_mass_kg).map(|m| (m, p.stats.p99_abs)))
        .collect();
    let model: Vec<(f64, f64)> =
        feasible.iter().filter_map(|p| p.model_mass_kg.map(|m| (m, p.stats.p99_abs))).collect();
    let layers = vec![
        Layer::VLine { x: c.floor_kg, style: Style::line(palette(6), 2).dashed() },
        Layer::VLine { x: c.arm_mass_kg, style: Style::line(palette(2), 2).dashed() },
        Layer::Lines {
            lines: vec![parts.clone()],
            style: Style::line(palette(0), 2),
            label: Some("parts chosen".into()),
        },
        Layer::Points { points: parts, style: Style::fill(palette(0), 1.0), size: 4, label: None },
        Layer::Lines {
            lines: vec![model.clone()],
            style: Style::line(palette(1), 2).dashed(),
            label: Some("mass model (Σ mᵢ(kᵢ))".into()),
        },
        Layer::Points { points: model, style: Style::fill(palette(1), 1.0), size: 3, label: None },
    ];
    let panel = Panel {
        title: format!(
            "Best residual per spring mass ({})",
            if c.max_elements == 0 {
                "no element budget".to_string()
            } else {
                format!("at most {} elements", c.max_elements)
            }
        ),
        x_label: "spring mass (kg, log scale)".into(),
        y_label: "p99 |residual angle| (°, log scale)".into(),
        legend: true,
        log_x: true,
        log_y: true,
        notes: vec![
            format!("grey dashed: floor ρ·U*/u = {:.3} kg", c.floor_kg),
            format!("green dashed: arm's moving mass {:.3} kg", c.arm_mass_kg),
        ],
        layers,
        ..Panel::default()
    };
    Figure { title: Some(format!("{}: accuracy versus spring mass", c.design)), ..Figure::single(panel, 1100, 560) }
}

/// A point's count of springs used and residual statistics as CSV cells; an infeasible point
/// keeps its row with empty numbers.
fn pareto_numbers(used: usize, s: &AngleStats, why: &Option<String>) -> String {
    match why {
        None => format!("{used},{},{},{},{}", s.median_abs, s.p95_abs, s.p99_abs, s.max_abs),
        Some(_) => ",,,,".to_string(),
    }
}

/// An infeasible point's reason as a CSV field (empty when feasible).
fn pareto_reason(why: &Option<String>) -> String {
    why.as_ref().map(|w| crate::csv::csv_field(w)).unwrap_or_default()
}

/// A point's count of springs used and residual statistics as Markdown cells.
fn pareto_cells(used: usize, s: &AngleStats, why: &Option<String>) -> String {
    match why {
        None => format!("{used} | {:.4}° | {:.4}° | {:.4}° | {:.4}°", s.median_abs, s.p95_abs, s.p99_abs, s.max_abs),
        Some(_) => "infeasible | – | – | – | –".to_string(),
    }
}

/// The reasons of the infeasible points under a table, if any.
fn push_infeasible(md: &mut String, why: Vec<String>) {
    if !why.is_empty() {
        md.push_str("\nInfeasible:\n\n");
        for w in why {
            md.push_str(&format!("- {w}\n"));
        }
    }
}

/// `pareto.csv` and `pareto.md`, a row of each per budget and per radius. The CSV has the
/// as-built spreads and, for an infeasible point, the reason in the last column; the Markdown
/// names the best budget as built and lists the infeasible points' reasons under each table.
fn pareto_tables(
    design: &str,
    budgets: &[BudgetPoint],
    radii: &[RadiusPoint],
    budget_for_radii: usize,
) -> (String, String) {
    let mut csv = String::from(
        "curve,budget,radius,used,median_abs_deg,p95_abs_deg,p99_abs_deg,max_abs_deg,as_built_p99_p50_deg,as_built_p99_p95_deg,trimmed_p99_p50_deg,trimmed_p99_p95_deg,infeasible\n",
    );
    let mut md = format!("# What accuracy costs: {design}\n");
    if !budgets.is_empty() {
        md.push_str("\n## Best residual per spring budget\n\nAs built: p99 over Monte Carlo builds at the design's tolerance (p50 / p95 over builds), untrimmed and after each build's trim.\n\n| budget K | springs used | median | p95 | p99 | max | as built p99 | trimmed |\n| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n");
    }
    // Empty where a percentile falls among builds without a figure: never NaN or inf.
    let opt = |x: Option<f64>| x.filter(|v| v.is_finite()).map(|v| v.to_string()).unwrap_or_default();
    for b in budgets {
        let ab = b.as_built.as_ref();
        let tr = ab.and_then(|a| a.trimmed_p99_deg);
        csv.push_str(&format!(
            "budget,{},,{},{},{},{},{},{}\n",
            b.budget,
            pareto_numbers(b.used, &b.stats, &b.infeasible),
            opt(ab.map(|a| a.p99_deg.p50)),
            opt(ab.map(|a| a.p99_deg.p95)),
            opt(tr.map(|t| t.p50)),
            opt(tr.map(|t| t.p95)),
            pareto_reason(&b.infeasible)
        ));
        md.push_str(&format!(
            "| {} | {} | {} | {} |\n",
            b.budget,
            pareto_cells(b.used, &b.stats, &b.infeasible),
            crate::studies::compare::spread_md(ab.map(|a| a.p99_deg)),
            crate::studies::compare::spread_md(tr)
        ));
    }
    if let Some(best) = crate::studies::compare::best_as_built(budgets) {
        md.push_str(&format!(
            "\n**Best as built: K = {}** (smallest as-built p95 of the p99{}): the budget to buy.\n",
            best.budget,
            if best.as_built.is_some_and(|a| a.trimmed_p99_deg.is_some()) { ", trimmed" } else { "" }
        ));
    }
    push_infeasible(
        &mut md,
        budgets.iter().filter_map(|b| b.infeasible.as_ref().map(|w| format!("K = {}: {w}", b.budget))).collect(),
    );
    if !radii.is_empty() {
        md.push_str(&format!("\n## Residual per region size (geodesic ball, budget {})\n\n| radius | springs used | median | p95 | p99 | max |\n| ---: | ---: | ---: | ---: | ---: | ---: |\n", if budget_for_radii == 0 { "none".to_string() } else { budget_for_radii.to_string() }));
    }
    for r in radii {
        csv.push_str(&format!(
            "radius,,{},{},,,,,{}\n",
            r.radius,
            pareto_numbers(r.used, &r.stats, &r.infeasible),
            pareto_reason(&r.infeasible)
        ));
        md.push_str(&format!("| {:.2} | {} |\n", r.radius, pareto_cells(r.used, &r.stats, &r.infeasible)));
    }
    push_infeasible(
        &mut md,
        radii.iter().filter_map(|r| r.infeasible.as_ref().map(|w| format!("r = {}: {w}", r.radius))).collect(),
    );
    (csv, md)
}

/// The two curves: p99 and max residual per budget (with the as-built p95 of the p99, untrimmed
/// and trimmed) and per radius; infeasible points have no residual to draw.
fn pareto_figure(design: &str, budgets: &[BudgetPoint], radii: &[RadiusPoint]) -> Figure {
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
    // Infeasible points have no residual to draw.
    let budgets: Vec<&BudgetPoint> = budgets.iter().filter(|b| b.infeasible.is_none()).collect();
    let radii: Vec<&RadiusPoint> = radii.iter().filter(|r| r.infeasible.is_none()).collect();
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
            y_label: "|residual angle| (°, log scale)".into(),
            legend: true,
            log_y: true,
            layers: budget_layers,
            ..Panel::default()
        },
        Panel {
            title: "Residual per region size".into(),
            x_label: "geodesic-ball radius (√(kg·m²)·rad)".into(),
            y_label: "|residual angle| (°, log scale)".into(),
            legend: true,
            log_y: true,
            layers: vec![line(r99.clone(), 0, "p99"), dots(r99, 0), line(rmax.clone(), 1, "max"), dots(rmax, 1)],
            ..Panel::default()
        },
    ];
    Figure {
        title: Some(format!("{design}: accuracy versus springs and region")),
        width: 1400,
        height: 560,
        rows: 1,
        cols: 2,
        panels,
    }
}

/// Box-plot labels sit side by side under narrow boxes: the part of the design names that most
/// inputs share (up to its last `_`, e.g. `double_pendulum_paper_`) is shown as `…` so that
/// the labels stay apart. The histogram's legend keeps the full names.
fn box_labels<'a>(labels: impl Iterator<Item = &'a str>) -> Vec<String> {
    let labels: Vec<&str> = labels.collect();
    let sharing: Vec<&str> = labels.iter().copied().filter(|l| l.contains('_')).collect();
    let prefix = match sharing.split_first() {
        Some((first, rest)) if !rest.is_empty() => {
            let mut n = first.len();
            for l in rest {
                n = n.min(first.bytes().zip(l.bytes()).take_while(|(a, b)| a == b).count());
            }
            first[..n].rfind('_').map_or("", |i| &first[..=i])
        }
        _ => "",
    };
    labels
        .iter()
        .map(|l| match l.strip_prefix(prefix) {
            Some(rest) if prefix.len() > 3 && !rest.is_empty() => format!("…{rest}"),
            _ => l.to_string(),
        })
        .collect()
}
