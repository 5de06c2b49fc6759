//! The files `springfit sweep` writes.

use super::output::OutputDir;
use super::plot::{BoxItem, Figure, Layer, Panel, Style, histogram, palette, render};
use crate::design::Design;
use crate::dynamics::simulate::SOURCES;
use crate::error::Result;
use crate::files::bom;
use crate::fit::bill::BomRow;
use crate::studies::sweep::{ItemResult, SweepTables, WorkItem};

/// `sweep.csv`: one row per item.
pub fn items_csv(results: &[ItemResult]) -> String {
    let mut s = String::from(
        "index,kind,eps,tolerance,build,flux_potential,flux_mode,flux_energy,actuator_share,residual_p99_deg,\
         residual_p99_deg_trimmed,actuator_share_tuned,residual_p99_deg_tuned,equilibrium_shift_rad_tuned,\
         energy_saved,peak_torque_saved,rms_torque_saved,copper_loss_saved\n",
    );
    let mut sorted: Vec<&ItemResult> = results.iter().collect();
    sorted.sort_by_key(|r| r.index);
    for r in sorted {
        let (kind, eps, tol, build) = match r.item {
            WorkItem::Parasitic { eps } => ("parasitic", format!("{eps}"), String::new(), String::new()),
            WorkItem::Build { level, build } => (
                "build",
                String::new(),
                level.map(|l| format!("{l}")).unwrap_or_else(|| "catalogue".into()),
                format!("{build}"),
            ),
            WorkItem::Stock => ("stock", String::new(), String::new(), String::new()),
        };
        // Blank where a column does not apply (not a build, or a design without trims/tuning).
        let opt = |x: Option<f64>| x.map(|v| format!("{v}")).unwrap_or_default();
        let tuned = r.tuned.as_ref();
        s.push_str(&format!(
            "{},{kind},{eps},{tol},{build},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
            r.index,
            r.flux_potential,
            r.flux_mode,
            r.flux_energy,
            r.actuator_share,
            r.residual_p99_deg,
            opt(r.residual_p99_deg_trimmed),
            opt(tuned.map(|t| t.actuator_share)),
            opt(tuned.map(|t| t.residual_p99_deg)),
            opt(tuned.map(|t| t.equilibrium_shift_rad)),
            opt(r.savings.map(|v| v.energy_saved)),
            opt(r.savings.map(|v| v.peak_torque_saved)),
            opt(r.savings.map(|v| v.rms_torque_saved)),
            opt(r.savings.map(|v| v.copper_loss_saved))
        ));
    }
    s
}

/// `tolerance.md`: the three tables a person reads.
pub fn tables_md(design: &str, paper_arm: bool, t: &SweepTables) -> String {
    let mut s = format!("# Sensitivity of {design}\n\n## Parasitic springs (the paper's Table II)\n\n");
    s.push_str("| ε | ∫\\|P_Ũ\\| (J) | ∫\\|P_θ\\| (J) | ∫\\|P_E\\| (J) | actuator share |\n| ---: | ---: | ---: | ---: | ---: |\n");
    for r in &t.parasitic {
        s.push_str(&format!(
            "| {} | {:.2} | {:.2} | {:.2} | {:.3} % |\n",
            r.eps,
            r.flux_potential,
            r.flux_mode,
            r.flux_energy,
            100.0 * r.actuator_share
        ));
    }
    if paper_arm {
        s.push_str("\nThe paper's neural-network potential on this arm: ε = 0: 354.56 / 2.86 / 0.03 J (share 0.82 %); ε = 1: 565.60 / 20.92 / 181.83 J.\n");
    }
    s.push_str("\n## Manufacturing tolerance\n\nResidual angles of each build are taken on held-out geodesics from the equilibrium the built springs actually have (its shift from q_eq is listed); the actuator share comes from the closed-loop run, whose controllers still assume the nominal springs and q_eq.\n\n| tolerance | distribution | builds | actuator share p50 | p95 | residual p99 p50 | p95 | p95, 95 % interval | equilibrium shift p50 | p95 |\n| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n");
    for l in &t.tolerance_levels {
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} | {}° | {} | {} |\n",
            l.tolerance.map(|t| format!("±{} %", 100.0 * t)).unwrap_or_else(|| "catalogue".into()),
            l.distribution.name(),
            l.builds,
            figure(100.0 * l.actuator_share_p50, 3, " %", NOT_RUN),
            figure(100.0 * l.actuator_share_p95, 3, " %", NOT_RUN),
            figure(l.residual_p99_deg_p50, 3, "°", NO_EQUILIBRIUM),
            figure(l.residual_p99_deg_p95, 3, "°", NO_EQUILIBRIUM),
            interval(l.residual_p99_deg_p95_ci),
            figure(l.equilibrium_shift_rad_p50, 4, " rad", NO_EQUILIBRIUM),
            figure(l.equilibrium_shift_rad_p95, 4, " rad", NO_EQUILIBRIUM)
        ));
    }
    if t.tolerance_levels.iter().any(|l| l.trimmed_residual_p99_deg_p50.is_some()) {
        s.push_str("\nAfter the trim a builder would make (trim springs re-relaxed at the build's equilibrium, rates set so that ∇²U = w² M there):\n\n| tolerance | trimmed residual p99 p50 | p95 | p95, 95 % interval |\n| --- | ---: | ---: | ---: |\n");
        for l in &t.tolerance_levels {
            s.push_str(&format!(
                "| {} | {} | {} | {}° |\n",
                l.tolerance.map(|t| format!("±{} %", 100.0 * t)).unwrap_or_else(|| "catalogue".into()),
                l.trimmed_residual_p99_deg_p50.map_or("–".into(), |x| figure(x, 3, "°", NO_EQUILIBRIUM)),
                l.trimmed_residual_p99_deg_p95.map_or("–".into(), |x| figure(x, 3, "°", NO_EQUILIBRIUM)),
                l.trimmed_residual_p99_deg_p95_ci.map_or("–".into(), interval)
            ));
        }
    }
    if t.tolerance_levels.iter().any(|l| l.tuned.is_some()) {
        s.push_str("\nAfter the tuning a builder would make (each build's rates measured exactly; adjustable offsets put the equilibrium back at q_eq and trims restore ∇²U = w² M, as `springfit tune` does), the same closed-loop run with the controllers unchanged. The untuned figures above are what the build does before that; the first `tuned_builds` builds of each level are tuned.\n\n| tolerance | tuned builds | tuned actuator share p50 | p95 | tuned residual p99 p50 | p95 | equilibrium shift p50 | p95 |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n");
        for l in &t.tolerance_levels {
            let Some(u) = &l.tuned else { continue };
            s.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {} rad | {} rad |\n",
                l.tolerance.map(|t| format!("±{} %", 100.0 * t)).unwrap_or_else(|| "catalogue".into()),
                u.builds,
                u.actuator_share.text(100.0 * u.actuator_share.p50, 3, " %"),
                u.actuator_share.text(100.0 * u.actuator_share.p95, 3, " %"),
                u.residual_p99_deg.text(u.residual_p99_deg.p50, 3, "°"),
                u.residual_p99_deg.text(u.residual_p99_deg.p95, 3, "°"),
                crate::units::sci(u.equilibrium_shift_rad.p50, 2),
                crate::units::sci(u.equilibrium_shift_rad.p95, 2)
            ));
        }
    }
    if let Some(st) = &t.stock {
        s.push_str(&format!(
            "\n## Stock rates\n\nEach stiffness snapped to the nearest stock rate (largest torque first, the others refitted after each snap); see `bom_stock.csv`.\n\n| | residual p99 | actuator share |\n| --- | ---: | ---: |\n| fitted | {:.3}° | {:.3} % |\n| snapped | {:.3}° | {:.3} % |\n",
            st.residual_p99_deg_before, 100.0 * st.actuator_share_before, st.residual_p99_deg_after, 100.0 * st.actuator_share_after
        ));
    }
    s.push_str(&savings_md(t));
    s
}

/// The savings section of `tolerance.md`: what the springs save on each item's closed-loop run
/// against the same motion on the arm without them (`savings` in `sim_<name>.json`).
fn savings_md(t: &SweepTables) -> String {
    let pct = |x: f64| if x.is_finite() { format!("{:.1} %", 100.0 * x) } else { "–".into() };
    let mut s = String::from(
        "\n## Savings against the arm without springs\n\nThe same closed-loop motion driven by the actuators alone (τ_act + τ_spring): the actuators' energy ∫|τᵀq̇| dt, peak and RMS torque and copper losses with the springs against without, and the fraction saved.\n",
    );
    if t.parasitic.iter().any(|r| r.savings.is_some()) {
        s.push_str(&format!(
            "\n| ε | {} |\n| ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n",
            crate::dynamics::scenario::Savings::MD_HEADER
        ));
        for r in &t.parasitic {
            if let Some(v) = &r.savings {
                s.push_str(&format!("| {} | {} |\n", r.eps, v.md_cells()));
            }
        }
    }
    if !t.tolerance_levels.is_empty() {
        s.push_str("\nOver the builds of each tolerance level (untuned):\n\n| tolerance | energy saved p50 | p5 (95 % of builds save at least) | peak torque saved p50 | copper losses saved p50 |\n| --- | ---: | ---: | ---: | ---: |\n");
        for l in &t.tolerance_levels {
            s.push_str(&format!(
                "| {} | {} | {} | {} | {} |\n",
                l.tolerance.map(|t| format!("±{} %", 100.0 * t)).unwrap_or_else(|| "catalogue".into()),
                pct(l.energy_saved_p50),
                pct(l.energy_saved_p5),
                pct(l.peak_torque_saved_p50),
                pct(l.copper_loss_saved_p50)
            ));
        }
    }
    if let Some(st) = &t.stock {
        s.push_str(&format!(
            "\nStock rates: energy saved {} with the fitted rates, {} snapped to stock.\n",
            pct(st.energy_saved_before),
            pct(st.energy_saved_after)
        ));
    }
    s
}

/// The names `springfit sweep` may write (see [`super::output::Plan`]), `report.html` included.
pub const FILES: &[&str] = &[
    "sweep.csv",
    "sweep.json",
    "tolerance.md",
    "bom_stock.csv",
    "cams/*",
    "sweep_*.svg",
    "sweep_*.png",
    super::html::FILE,
];

/// The name a shard of `springfit sweep --shard i/N` writes.
pub const SHARD_FILES: &[&str] = &["sweep_shard.json"];

/// Writes everything `springfit sweep` writes into the folder `target` under `plan` ([`FILES`]):
/// the files of [`write()`] and `report.html`, staged and committed at once (the command and the
/// Python package's `Sweep.write`).
pub fn write_folder(
    claim: super::output::Claim,
    design: &crate::design::Design,
    tables: &SweepTables,
    results: &[ItemResult],
    bom: &[BomRow],
) -> Result<std::path::PathBuf> {
    let dir = claim.open()?;
    write(&dir, design, tables, results, bom)?;
    super::html::write_sweep(&dir, design)?;
    dir.commit()
}

/// Writes the sweep's outputs. `bom` is the nominal bill of materials (for `bom_stock.csv`).
pub fn write(
    out: &OutputDir,
    design: &Design,
    tables: &SweepTables,
    results: &[ItemResult],
    bom: &[BomRow],
) -> Result<()> {
    out.write("sweep.csv", items_csv(results))?;
    out.write("sweep.json", serde_json::to_string_pretty(tables).expect("serialises") + "\n")?;
    out.write("tolerance.md", tables_md(&design.name, design.is_paper_arm(), tables))?;
    if let Some(k) = results.iter().find_map(|r| r.stock_stiffness.clone()) {
        bom::write(out, "bom_stock.csv", &stock_bill(bom, &k))?;
    }
    let mut parasitic: Vec<&ItemResult> =
        results.iter().filter(|r| matches!(r.item, WorkItem::Parasitic { .. })).collect();
    parasitic.sort_by_key(|r| r.index);
    if !parasitic.is_empty() {
        render(&Figure::single(parasitic_phase(&parasitic), 900, 800), &out.path("sweep_parasitic_phase"))?;
        write_parasitic_power(out, &parasitic)?;
    }
    if !tables.tolerance_levels.is_empty() {
        write_tolerance(out, design, tables, results)?;
    }
    Ok(())
}

/// The nominal bill with every stiffness snapped to its stock rate `k[j]`: torques and
/// preloads scale with it.
fn stock_bill(bom: &[BomRow], k: &[f64]) -> Vec<BomRow> {
    bom.iter()
        .zip(k)
        .map(|(row, &k)| BomRow {
            stiffness: k,
            max_torque_nm: row.max_torque_nm * if row.stiffness > 0.0 { k / row.stiffness } else { 1.0 },
            stock_rate: row.stock_rate.map(|_| k),
            preload_nm: row.preload_nm.map(|p| if row.stiffness > 0.0 { p * k / row.stiffness } else { p }),
            ..row.clone()
        })
        .collect()
}

/// The ε of a parasitic run (NaN for any other item).
fn parasitic_eps(r: &ItemResult) -> f64 {
    if let WorkItem::Parasitic { eps } = r.item { eps } else { f64::NAN }
}

/// The trajectories of the parasitic runs in (q₁, q₂) (the paper's Fig. 8a).
fn parasitic_phase(parasitic: &[&ItemResult]) -> Panel {
    let lines: Vec<Layer> = parasitic
        .iter()
        .enumerate()
        .filter_map(|(i, r)| {
            let s = r.series.as_ref()?;
            let pts: Vec<(f64, f64)> = s.q.chunks(2).map(|c| (c[0], c[1])).collect();
            Some(Layer::Lines {
                lines: vec![pts],
                style: Style::line(palette(i), 1),
                label: Some(format!("ε = {}", parasitic_eps(r))),
            })
        })
        .collect();
    Panel {
        title: "Trajectories with parasitic springs (the paper's Fig. 8a)".into(),
        x_label: "q₁ (rad)".into(),
        y_label: "q₂ (rad)".into(),
        equal_aspect: true,
        legend: true,
        layers: lines,
        ..Panel::default()
    }
}

/// Power by source for three ε (the paper's Fig. 8c–e): the smallest non-zero, a middle one and
/// the largest; one panel each, when the runs kept their series.
fn write_parasitic_power(out: &OutputDir, parasitic: &[&ItemResult]) -> Result<()> {
    let nz: Vec<&ItemResult> = parasitic.iter().copied().filter(|r| parasitic_eps(r) > 0.0).collect();
    let mut picks = Vec::new();
    if let Some(f) = nz.first() {
        picks.push(*f);
    }
    if nz.len() > 2 {
        picks.push(nz[nz.len() / 2]);
    }
    if let Some(l) = nz.last()
        && picks.last().is_none_or(|x| x.index != l.index)
    {
        picks.push(*l);
    }
    let panels: Vec<Panel> = picks
        .iter()
        .filter_map(|r| {
            let s = r.series.as_ref()?;
            let ns = SOURCES.len();
            let layers = [(0usize, "spring"), (3, "mode"), (4, "energy")]
                .iter()
                .map(|&(src, name)| Layer::Lines {
                    lines: vec![s.t.iter().enumerate().map(|(k, &t)| (t, s.power[k * ns + src])).collect()],
                    style: Style::line(palette(src), if src == 0 { 1 } else { 2 }),
                    label: Some(name.into()),
                })
                .collect();
            Some(Panel {
                title: format!("ε = {}", parasitic_eps(r)),
                x_label: "t (s)".into(),
                y_label: "power (W)".into(),
                legend: true,
                layers,
                ..Panel::default()
            })
        })
        .collect();
    if panels.is_empty() {
        return Ok(());
    }
    let rows = panels.len();
    render(
        &Figure {
            title: Some("Power by source with parasitic springs".into()),
            width: 1000,
            height: 330 * rows as u32 + 40,
            rows,
            cols: 1,
            panels,
        },
        &out.path("sweep_parasitic_power"),
    )?;
    Ok(())
}

/// The tolerance distributions: the actuator share per build as a box per level, and the p99
/// residual per build as a histogram per level.
fn write_tolerance(out: &OutputDir, design: &Design, tables: &SweepTables, results: &[ItemResult]) -> Result<()> {
    let mut share_boxes = Vec::new();
    let mut resid_layers = Vec::new();
    for (i, l) in tables.tolerance_levels.iter().enumerate() {
        let builds: Vec<&ItemResult> = results
            .iter()
            .filter(|r| matches!(r.item, WorkItem::Build { level, .. } if level == l.tolerance))
            .collect();
        let name = l.tolerance.map(|t| format!("±{} %", 100.0 * t)).unwrap_or_else(|| "catalogue".into());
        let shares: Vec<f64> = builds.iter().map(|r| 100.0 * r.actuator_share).collect();
        share_boxes.push(BoxItem::from_samples(&name, &shares, palette(i)));
        let resid: Vec<f64> = builds.iter().map(|r| r.residual_p99_deg).collect();
        let hi = resid.iter().fold(0.0f64, |a, v| a.max(*v)) * 1.05 + 1e-9;
        let edges: Vec<f64> = (0..=30).map(|k| hi * k as f64 / 30.0).collect();
        let counts = histogram(&resid, &edges);
        resid_layers.push(Layer::Histogram { edges, counts, style: Style::fill(palette(i), 0.45), label: Some(name) });
    }
    let panels = vec![
        Panel {
            title: "Actuator share per build".into(),
            y_label: "actuator share (%)".into(),
            layers: vec![Layer::Boxes { items: share_boxes }],
            ..Panel::default()
        },
        Panel {
            title: "p99 residual angle per build".into(),
            x_label: "p99 |angle| (°)".into(),
            y_label: "builds".into(),
            legend: true,
            layers: resid_layers,
            ..Panel::default()
        },
    ];
    render(
        &Figure {
            title: Some(format!("{}: manufacturing tolerance", design.name)),
            width: 1300,
            height: 560,
            rows: 1,
            cols: 2,
            panels,
        },
        &out.path("sweep_tolerance"),
    )?;
    Ok(())
}

/// What a table says for a percentile that falls among builds without a stable equilibrium
/// near q_eq (their residual and shift are not numbers: they count as the worst).
const NO_EQUILIBRIUM: &str = "no equilibrium";
/// What a table says for an actuator share whose closed-loop run could not be made.
const NOT_RUN: &str = "not run";

/// A figure with `digits` after the point and its `unit`, or `why` it has none (NaN or ±∞:
/// a percentile among builds without a figure), never "NaN" or "∞".
fn figure(x: f64, digits: usize, unit: &str, why: &str) -> String {
    if x.is_finite() { format!("{x:.digits$}{unit}") } else { why.into() }
}

/// A 95 % interval as text, `2.235–2.791` ("open" for an end beyond the builds, or among
/// builds without a figure).
fn interval(ci: [f64; 2]) -> String {
    let end = |x: f64| if x.is_finite() { format!("{x:.3}") } else { "open".into() };
    format!("{}–{}", end(ci[0]), end(ci[1]))
}
