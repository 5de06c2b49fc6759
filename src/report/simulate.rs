//! The files `springfit simulate` writes: per scenario a CSV of the samples, a JSON of the
//! metrics and five figures (phase plane, q(t), torques, label, power).

use serde::Serialize;

use super::figures::{boundary_line, equilibrium_layer, fan_lines};
use super::output::OutputDir;
use super::plot::{Figure, Layer, Panel, Style, palette, render};
use crate::design::Design;
use crate::error::Result;
use crate::geodesic::Fan;
use crate::scenario::{RunMetrics, ScenarioKind, ScenarioOutcome};
use crate::simulate::{ElasticPotential, SOURCES};

/// `sim_<name>.json`.
#[derive(Debug, Clone, Serialize)]
pub struct ScenarioSummary {
    pub scenario: String,
    pub kind: ScenarioKind,
    /// `springs (fit)`, `springs (bom.csv)` or `exact ½ω²r²`.
    pub potential: String,
    /// `table` or `exact`.
    pub label: String,
    /// Largest error of the tabulated label against the exact one on held-out geodesics, degrees.
    pub label_error_deg: Option<f64>,
    /// Worst mode drift over the runs (free scenarios).
    pub mode_drift_deg: Option<f64>,
    /// Metrics per run.
    pub runs: std::collections::BTreeMap<String, RunMetrics>,
    /// Fingerprint of the spring set simulated (`bom::fingerprint`; null for the exact potential).
    pub spring_set: Option<String>,
}

fn columns(n: usize) -> String {
    let mut s = String::from("run,t");
    for i in 1..=n {
        s.push_str(&format!(",q{i}"));
    }
    for i in 1..=n {
        s.push_str(&format!(",qd{i}"));
    }
    for src in SOURCES {
        for i in 1..=n {
            s.push_str(&format!(",tau_{src}{i}"));
        }
    }
    s.push_str(",E,label,label_target\n");
    s
}

/// The samples of every run of a scenario as CSV.
pub fn scenario_csv(outcome: &ScenarioOutcome) -> String {
    let n = outcome.runs.first().map_or(0, |r| r.0.trace.n);
    let mut s = columns(n);
    for (r, _) in &outcome.runs {
        let t = &r.trace;
        let w = SOURCES.len() * n;
        for k in 0..t.t.len() {
            s.push_str(&format!("{},{}", r.name, t.t[k]));
            for v in t.q[k * n..(k + 1) * n].iter().chain(&t.qd[k * n..(k + 1) * n]).chain(&t.tau[k * w..(k + 1) * w]) {
                s.push_str(&format!(",{v}"));
            }
            s.push_str(&format!(",{},{},{}\n", t.energy[k], t.label[k], t.label_target[k]));
        }
    }
    s
}

fn run_colour(i: usize) -> (u8, u8, u8) {
    palette(i)
}

/// Writes a scenario's outputs.
#[allow(clippy::too_many_arguments)]
pub fn write(
    out: &OutputDir,
    design: &Design,
    outcome: &ScenarioOutcome,
    potential: &ElasticPotential,
    potential_name: &str,
    label_name: &str,
    label_error_deg: Option<f64>,
    fan: &Fan,
) -> Result<()> {
    let name = &outcome.scenario.name;
    out.write(&format!("sim_{name}.csv"), scenario_csv(outcome))?;
    let runs: std::collections::BTreeMap<String, RunMetrics> =
        outcome.runs.iter().map(|(r, m)| (r.name.clone(), m.clone())).collect();
    let drift = outcome
        .runs
        .iter()
        .filter_map(|(_, m)| m.mode_drift_deg)
        .fold(None, |a: Option<f64>, d| Some(a.map_or(d, |a| a.max(d))));
    let summary = ScenarioSummary {
        scenario: name.clone(),
        kind: outcome.scenario.kind,
        potential: potential_name.into(),
        label: label_name.into(),
        label_error_deg,
        mode_drift_deg: drift,
        runs,
        spring_set: match potential {
            ElasticPotential::Springs(s) => Some(crate::bom::fingerprint(s)),
            ElasticPotential::Exact { .. } => None,
        },
    };
    out.write(&format!("sim_{name}.json"), serde_json::to_string_pretty(&summary).expect("serialises") + "\n")?;
    let title = |what: &str| format!("{} — scenario {name}: {what}", design.name);
    render(
        &phase_figure(design, outcome, potential, fan, &title("phase plane"))?,
        &out.path(&format!("sim_{name}_phase")),
    )?;
    render(&time_figure(outcome, &title("joint angles"), TimePlot::Angles), &out.path(&format!("sim_{name}_q")))?;
    render(
        &time_figure(outcome, &title("torques by source"), TimePlot::Torques),
        &out.path(&format!("sim_{name}_torques")),
    )?;
    render(
        &time_figure(outcome, &title("mode label (ε-ball passages shaded)"), TimePlot::Label),
        &out.path(&format!("sim_{name}_label")),
    )?;
    render(&time_figure(outcome, &title("power by source"), TimePlot::Power), &out.path(&format!("sim_{name}_power")))?;
    Ok(())
}

fn phase_figure(
    design: &Design,
    outcome: &ScenarioOutcome,
    potential: &ElasticPotential,
    fan: &Fan,
    title: &str,
) -> Result<Figure> {
    let mut layers = vec![
        Layer::Lines {
            lines: fan_lines(fan, (fan.geodesics.len() / 24).max(1)),
            style: Style::line((170, 170, 170), 1),
            label: Some("geodesics".into()),
        },
        Layer::Lines {
            lines: vec![boundary_line(fan)],
            style: Style::line((0, 0, 0), 1).dashed(),
            label: Some("region boundary".into()),
        },
    ];
    if let ElasticPotential::Springs(s) = potential {
        let pot = crate::report::figures::potential_figure(design, s, fan, design.fit.frequency, "")?;
        if let Some(Layer::Contours { x, y, z, levels, .. }) =
            pot.panels[0].layers.iter().find(|l| matches!(l, Layer::Contours { .. }))
        {
            layers.push(Layer::Contours {
                x: x.clone(),
                y: y.clone(),
                z: z.clone(),
                levels: levels.clone(),
                style: Style::line((230, 159, 0), 1),
                label: Some("isolines of U".into()),
            });
        }
    }
    for (i, (r, _)) in outcome.runs.iter().enumerate() {
        let t = &r.trace;
        let line: Vec<(f64, f64)> = (0..t.t.len()).map(|k| (t.q[k * t.n], t.q[k * t.n + 1.min(t.n - 1)])).collect();
        let start = line.first().copied();
        layers.push(Layer::Lines {
            lines: vec![line],
            style: Style::line(run_colour(i), 2),
            label: Some(r.name.clone()),
        });
        if let Some(p) = start {
            layers.push(Layer::Points {
                points: vec![p],
                style: Style::fill(run_colour(i), 1.0),
                size: 4,
                label: None,
            });
        }
    }
    layers.push(equilibrium_layer(design));
    Ok(Figure::single(
        Panel {
            title: title.into(),
            x_label: "q₁ (rad)".into(),
            y_label: if design.dof() >= 2 { "q₂ (rad)".into() } else { "q₁ (rad)".into() },
            equal_aspect: true,
            legend: true,
            layers,
            ..Panel::default()
        },
        1000,
        850,
    ))
}

#[derive(Clone, Copy, PartialEq)]
enum TimePlot {
    Angles,
    Torques,
    Label,
    Power,
}

fn time_figure(outcome: &ScenarioOutcome, title: &str, what: TimePlot) -> Figure {
    let runs = &outcome.runs;
    let shown: Vec<usize> = (0..runs.len()).take(6).collect();
    let cols = if shown.len() > 3 { 2 } else { 1 };
    let rows = shown.len().div_ceil(cols).max(1);
    let panels = shown
        .iter()
        .map(|&ri| {
            let (r, m) = &runs[ri];
            let t = &r.trace;
            let n = t.n;
            let mut layers = Vec::new();
            let series =
                |f: &dyn Fn(usize) -> f64| -> Vec<(f64, f64)> { (0..t.t.len()).map(|k| (t.t[k], f(k))).collect() };
            let y_label: String;
            match what {
                TimePlot::Angles => {
                    y_label = "q (rad)".into();
                    for i in 0..n {
                        layers.push(Layer::Lines {
                            lines: vec![series(&|k| t.q[k * n + i])],
                            style: Style::line(palette(i), 2),
                            label: Some(format!("q{}", i + 1)),
                        });
                    }
                }
                TimePlot::Torques => {
                    y_label = "torque (N·m)".into();
                    let w = SOURCES.len() * n;
                    for (s, src) in SOURCES.iter().enumerate() {
                        let active = (0..t.t.len()).any(|k| (0..n).any(|i| t.tau[k * w + s * n + i] != 0.0));
                        if !active {
                            continue;
                        }
                        for i in 0..n {
                            let style =
                                if i == 0 { Style::line(palette(s), 1) } else { Style::line(palette(s), 1).dashed() };
                            layers.push(Layer::Lines {
                                lines: vec![series(&|k| t.tau[k * w + s * n + i])],
                                style,
                                label: Some(format!("{src} (joint {})", i + 1)),
                            });
                        }
                    }
                }
                TimePlot::Label => {
                    y_label = if n == 2 { "label θ (rad)".into() } else { "distance to the mode Δ (rad)".into() };
                    let mut spans = Vec::new();
                    let mut open: Option<f64> = None;
                    for k in 0..t.t.len() {
                        match (t.in_ball[k], open) {
                            (true, None) => open = Some(t.t[k]),
                            (false, Some(a)) => {
                                spans.push((a, t.t[k]));
                                open = None;
                            }
                            _ => {}
                        }
                    }
                    if let Some(a) = open {
                        spans.push((a, *t.t.last().unwrap_or(&a)));
                    }
                    layers.push(Layer::Spans {
                        spans,
                        style: Style::fill((150, 150, 150), 0.3),
                        label: Some("ε-ball".into()),
                    });
                    let lab: Vec<(f64, f64)> = (0..t.t.len()).map(|k| (t.t[k], t.label[k])).collect();
                    layers.push(Layer::Lines {
                        lines: vec![lab],
                        style: Style::line(palette(0), 2),
                        label: Some("label".into()),
                    });
                    if t.label_target.iter().any(|v| v.is_finite()) {
                        layers.push(Layer::Lines {
                            lines: vec![series(&|k| t.label_target[k])],
                            style: Style::line((0, 0, 0), 1).dashed(),
                            label: Some("desired".into()),
                        });
                    }
                }
                TimePlot::Power => {
                    y_label = "power (W)".into();
                    for (s, src) in SOURCES.iter().enumerate() {
                        let p = t.power(s);
                        if p.iter().all(|v| *v == 0.0) {
                            continue;
                        }
                        layers.push(Layer::Lines {
                            lines: vec![(0..t.t.len()).map(|k| (t.t[k], p[k])).collect()],
                            style: Style::line(palette(s), if s == 0 { 1 } else { 2 }),
                            label: Some(src.to_string()),
                        });
                    }
                }
            }
            let mut notes = vec![format!("actuator share {:.3} %", 100.0 * m.actuator_share)];
            if let Some(d) = m.mode_drift_deg {
                notes.push(format!("mode drift {d:.3}°"));
            }
            if let Some(e) = m.energy_signed_error_last5s {
                notes.push(format!("E − E_d (last 5 s) {:+.2} %", 100.0 * e));
            }
            Panel {
                title: r.name.clone(),
                x_label: "t (s)".into(),
                y_label,
                legend: true,
                notes,
                layers,
                ..Panel::default()
            }
        })
        .collect();
    Figure { title: Some(title.into()), width: 1100 * cols as u32, height: 380 * rows as u32 + 40, rows, cols, panels }
}
