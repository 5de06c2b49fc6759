//! The files `springfit simulate` writes: per scenario a CSV of the samples, a JSON of the
//! metrics and the figures: the paths in configuration space (q₁–q₂; for three joints also q₁–q₃
//! and q₂–q₃), q(t), torques, the mode label (unwrapped), power, energy E(t) and, for free
//! releases, the distance to the mode's geodesic.

use serde::Serialize;

use super::figures::{
    Projection, boundary_lines, equilibrium_layer_in, fan_lines_in, joint_axis, joint_name, potential_layers,
    projections,
};
use super::output::OutputDir;
use super::plot::{Figure, Layer, Panel, Style, palette, render};
use crate::design::Design;
use crate::design::controllers::{Blend, ControllerSettings, GainBasis};
use crate::design::scenario::{ModeSpec, ScenarioKind};
use crate::dynamics::backbone::Backbone;
use crate::dynamics::scenario::{RunMetrics, ScenarioOutcome, unwrap_angles};
use crate::dynamics::simulate::{ElasticPotential, SOURCES, Trace};
use crate::error::Result;
use crate::geodesic::{Fan, FanSpec, Stop};

/// The design-level summary: the backbone and its isochrony error.
pub const SUMMARY: &str = "summary.json";
/// The backbone as a table a person reads (also in `report.html`).
pub const BACKBONE: &str = "backbone.md";

/// `summary.json` of `springfit simulate`.
#[derive(Debug, Clone, Serialize)]
pub struct SimulateSummary {
    /// The design's name.
    pub design: String,
    /// `springs (fit)`, `springs (bom.csv)` or `exact ½ω²r²`.
    pub potential: String,
    /// max |T/T₀ − 1| over the backbone's modes and energies (null without a period).
    pub isochrony_error: Option<f64>,
    /// The period of every mode against energy.
    pub backbone: Backbone,
}

/// The backbone as markdown: one row per mode, one column per energy, T/T₀ − 1 in the cells.
pub fn backbone_md(design: &Design, backbone: &Backbone) -> String {
    let mut s = format!(
        "## Backbone: period against energy\n\nFree runs from rest on each mode where U − U(q_eq) = E, {} nominal periods each; the period T read from the passages past q_eq, against T₀ = 2π/ω = {:.4} s (ω = {} rad/s). The exact potential ½ω²r² gives T = T₀ on every mode at every energy. Cells: T/T₀ − 1.\n\n| mode |",
        crate::dynamics::backbone::PERIODS,
        backbone.nominal_period_s,
        backbone.omega_rad_s
    );
    for e in &backbone.energies_j {
        s.push_str(&format!(" {e:.3} J |"));
    }
    s.push_str("\n| --- |");
    for _ in &backbone.energies_j {
        s.push_str(" ---: |");
    }
    s.push('\n');
    let mut modes: Vec<&ModeSpec> = Vec::new();
    for p in &backbone.points {
        if !modes.contains(&&p.mode) {
            modes.push(&p.mode);
        }
    }
    for (m, _) in &backbone.out_of_reach {
        if !modes.contains(&m) {
            modes.push(m);
        }
    }
    for mode in modes {
        s.push_str(&format!("| {} |", mode_name(mode)));
        for e in &backbone.energies_j {
            let cell = backbone.points.iter().find(|p| &p.mode == mode && p.energy_j == *e);
            s.push_str(&match cell {
                Some(p) => match p.rel_error {
                    Some(r) => format!(" {:+.3e} |", r),
                    None => " no period |".to_string(),
                },
                None => " out of reach |".to_string(),
            });
        }
        s.push('\n');
    }
    s.push_str(&match backbone.isochrony_error {
        Some(e) => format!("\nIsochrony error of `{}` (max |T/T₀ − 1|): {:.3e}.\n", design.name, e),
        None => "\nNo period could be read.\n".to_string(),
    });
    s
}

/// A mode as the tables name it: θ in degrees, or the direction of joint velocities.
fn mode_name(mode: &ModeSpec) -> String {
    match mode {
        ModeSpec::Angle(a) => format!("θ = {:.0}°", a.to_degrees()),
        ModeSpec::Vector(v) => format!("[{}]", v.iter().map(|x| format!("{x}")).collect::<Vec<_>>().join(", ")),
    }
}

/// Writes `summary.json` and `backbone.md`.
pub fn write_backbone(out: &OutputDir, design: &Design, potential_name: &str, backbone: &Backbone) -> Result<()> {
    let summary = SimulateSummary {
        design: design.name.clone(),
        potential: potential_name.into(),
        isochrony_error: backbone.isochrony_error,
        backbone: backbone.clone(),
    };
    out.write(SUMMARY, serde_json::to_string_pretty(&summary).expect("serialises") + "\n")?;
    out.write(BACKBONE, backbone_md(design, backbone))
}

/// `sim_<name>.json`.
#[derive(Debug, Clone, Serialize)]
pub struct ScenarioSummary {
    /// The scenario's name.
    pub scenario: String,
    /// The scenario's kind: `free`, `switch` or `swingup`.
    pub kind: ScenarioKind,
    /// `springs (fit)`, `springs (bom.csv)` or `exact ½ω²r²`.
    pub potential: String,
    /// `table` or `exact`.
    pub label: String,
    /// Largest error of the tabulated label against the exact one on held-out geodesics, degrees.
    pub label_error_deg: Option<f64>,
    /// The largest error, degrees, of the fitted log map that `label = "auto"` measured and
    /// rejected for the exact one (its bound is 0.1°); `null` when none was rejected.
    pub label_rejected_error_deg: Option<f64>,
    /// Why the label is exact when `auto` rejected a fit ("fitted log map error 6.61° > 0.1°:
    /// exact log map used"); `null` otherwise.
    pub label_note: Option<String>,
    /// How the mode controller is switched on at the ε-ball: `smooth` or `hard`.
    pub blend: Blend,
    /// The gains in force and which of them came from the arm.
    pub gains: GainsReport,
    /// How the scenario handles energy (for a switch scenario: its `energy_target`).
    pub energy_handling: String,
    /// Worst distance to the mode's geodesic over the runs, √(kg·m²)·rad (free scenarios).
    pub geodesic_deviation_max: Option<f64>,
    /// Worst cumulative label drift over the runs, degrees (free scenarios).
    pub mode_drift_deg: Option<f64>,
    /// Worst wrapped label drift over the runs, degrees (free scenarios).
    pub mode_drift_wrapped_deg: Option<f64>,
    /// Largest actuator torque over the runs, N·m.
    pub peak_actuator_torque_nm: f64,
    /// `[controllers] max_torque`, N·m per joint (null: no limit).
    pub max_torque_nm: Option<Vec<f64>>,
    /// Longest time at saturation over the runs, s.
    pub saturated_s: f64,
    /// Metrics per run.
    pub runs: std::collections::BTreeMap<String, RunMetrics>,
    /// Fingerprint of the spring set simulated (`fit::bill::fingerprint`; null for the exact potential).
    pub spring_set: Option<String>,
}

/// The controllers' gains as `simulate` ran them (`sim_<name>.json`, key `gains`).
#[derive(Debug, Clone, Serialize)]
pub struct GainsReport {
    /// k_θ, N·m per rad of label.
    pub k_theta: f64,
    /// ζ.
    pub zeta: f64,
    /// ε, rad.
    pub epsilon: f64,
    /// β_E, 1/(J·s).
    pub beta_e: f64,
    /// β_nD, N·m·s/(rad·J).
    pub beta_nd: f64,
    /// The keys the design left out and that were derived from the arm (empty: all as written).
    pub from_arm: Vec<&'static str>,
    /// What they were derived from (null when none was).
    pub basis: Option<GainBasis>,
}

impl GainsReport {
    /// The gains of `[controllers]` as resolved for the design.
    pub fn of(c: &ControllerSettings) -> GainsReport {
        let derived = c.basis.is_some();
        GainsReport {
            k_theta: c.k_theta,
            zeta: c.zeta,
            epsilon: c.epsilon,
            beta_e: c.beta_e,
            beta_nd: c.beta_nd,
            from_arm: if derived { c.from_arm.keys() } else { Vec::new() },
            basis: c.basis.filter(|_| c.from_arm.any()),
        }
    }
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
    s.push_str(",E,label,label_target,geodesic_deviation\n");
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
            let dev = t.geodesic_deviation.get(k).copied().unwrap_or(f64::NAN);
            s.push_str(&format!(",{},{},{},{dev}\n", t.energy[k], t.label[k], t.label_target[k]));
        }
    }
    s
}

/// Run colours: the palette without its orange, which draws the isolines of U.
fn run_colour(i: usize) -> (u8, u8, u8) {
    palette([0, 1, 2, 3, 5, 6][i % 6])
}

/// The names `springfit simulate` may write when it runs these scenarios (see
/// [`super::output::Plan`]), `report.html` included.
pub fn files<'a>(scenarios: impl IntoIterator<Item = &'a str>) -> Vec<String> {
    let mut files = vec![super::html::FILE.to_string(), SUMMARY.to_string(), BACKBONE.to_string()];
    for name in scenarios {
        files.extend([format!("sim_{name}.csv"), format!("sim_{name}.json"), format!("sim_{name}_*")]);
    }
    files
}

/// For a rerun of scenario `only` alone: keeps the other scenarios' files of the previous run
/// in the folder.
pub fn keep_other_scenarios(dir: &mut OutputDir, only: &str) -> Result<()> {
    let own = format!("sim_{only}");
    dir.keep_previous(|name| {
        !(name == format!("{own}.csv") || name == format!("{own}.json") || name.starts_with(&format!("{own}_")))
    })
}

/// The fan of geodesics the configuration-space figures draw behind the runs.
pub fn plot_fan(design: &Design) -> Result<Fan> {
    let region = design.valid_region()?;
    Fan::trace(
        &design.chain,
        &design.q_eq,
        FanSpec {
            count: 72,
            phase: 0.0,
            stop: Stop::Region { region: &design.region, max_arc: design.geodesics.max_arc },
            spacing: region.extent / 50.0,
        },
        design.geodesics.ode,
    )
}

/// `sim_<name>.json` of a scenario's outcome.
pub fn summary(
    design: &Design,
    outcome: &ScenarioOutcome,
    potential: &ElasticPotential,
    potential_name: &str,
    label_name: &str,
    label_error_deg: Option<f64>,
    label_rejected_error_deg: Option<f64>,
) -> ScenarioSummary {
    let runs: std::collections::BTreeMap<String, RunMetrics> =
        outcome.runs.iter().map(|(r, m)| (r.name.clone(), m.clone())).collect();
    let worst = |f: &dyn Fn(&RunMetrics) -> Option<f64>| {
        outcome.runs.iter().filter_map(|(_, m)| f(m)).fold(None, |a: Option<f64>, d| Some(a.map_or(d, |a| a.max(d))))
    };
    ScenarioSummary {
        scenario: outcome.scenario.name.clone(),
        kind: outcome.scenario.kind,
        potential: potential_name.into(),
        label: label_name.into(),
        label_error_deg,
        label_rejected_error_deg,
        label_note: label_rejected_error_deg.map(|e| crate::dynamics::scenario::rejected_label_note(e, design.dof())),
        blend: design.controllers.blend,
        gains: GainsReport::of(&design.controllers),
        energy_handling: outcome.scenario.energy_handling.clone(),
        geodesic_deviation_max: worst(&|m| m.geodesic_deviation.as_ref().map(|d| d.max)),
        mode_drift_deg: worst(&|m| m.mode_drift_deg),
        mode_drift_wrapped_deg: worst(&|m| m.mode_drift_wrapped_deg),
        peak_actuator_torque_nm: worst(&|m| Some(m.peak_actuator_torque_nm)).unwrap_or(0.0),
        max_torque_nm: design.controllers.max_torque.clone(),
        saturated_s: worst(&|m| Some(m.saturated_s)).unwrap_or(0.0),
        runs,
        spring_set: match potential {
            ElasticPotential::Springs(s) => Some(crate::fit::bill::fingerprint(s)),
            ElasticPotential::Exact { .. } => None,
        },
    }
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
    label_rejected_error_deg: Option<f64>,
    fan: &Fan,
) -> Result<()> {
    let name = &outcome.scenario.name;
    out.write(&format!("sim_{name}.csv"), scenario_csv(outcome))?;
    let summary =
        summary(design, outcome, potential, potential_name, label_name, label_error_deg, label_rejected_error_deg);
    out.write(&format!("sim_{name}.json"), serde_json::to_string_pretty(&summary).expect("serialises") + "\n")?;
    let title = |what: &str| format!("{} — scenario {name}: {what}", design.name);
    render(
        &configuration_figure(design, outcome, potential, fan, &title("paths in configuration space"))?,
        &out.path(&format!("sim_{name}_configuration")),
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
    render(&energy_figure(outcome, &title("energy E(t)")), &out.path(&format!("sim_{name}_energy")))?;
    if outcome.runs.iter().any(|(r, _)| !r.trace.geodesic_deviation.is_empty()) {
        render(
            &deviation_figure(outcome, &title("distance to the mode's geodesic")),
            &out.path(&format!("sim_{name}_deviation")),
        )?;
    }
    Ok(())
}

/// E(t) of every run with its target E_d(t) where there is one.
fn energy_figure(outcome: &ScenarioOutcome, title: &str) -> Figure {
    let mut layers = Vec::new();
    let schedules: Vec<Option<&Vec<(f64, f64)>>> =
        outcome.scenario.runs.iter().map(|s| s.energy.as_ref().map(|e| &e.schedule)).collect();
    // One black E_d line when every run has the same target, else one per run in its colour.
    let shared = schedules.iter().all(|s| s.is_some() && *s == schedules[0]);
    for (i, ((r, _), spec)) in outcome.runs.iter().zip(&outcome.scenario.runs).enumerate() {
        let t = &r.trace;
        layers.push(Layer::Lines {
            lines: vec![(0..t.t.len()).map(|k| (t.t[k], t.energy[k])).collect()],
            style: Style::line(run_colour(i), 2),
            label: Some(r.name.clone()),
        });
        if let Some(ec) = &spec.energy {
            if shared && i > 0 {
                continue;
            }
            let (colour, label) =
                if shared { ((0, 0, 0), "E_d".to_string()) } else { (run_colour(i), format!("{}: E_d", r.name)) };
            layers.push(Layer::Lines {
                lines: vec![t.t.iter().map(|&tt| (tt, ec.target(tt))).collect()],
                style: Style::line(colour, 1).dashed(),
                label: Some(label),
            });
        }
    }
    Figure::single(
        Panel {
            title: title.into(),
            x_label: "t (s)".into(),
            y_label: "E = ½q̇ᵀMq̇ + U − U(q_eq) (J)".into(),
            legend: true,
            layers,
            ..Panel::default()
        },
        1200,
        520,
    )
}

/// The metric distance from q(t) to the geodesic of the start's mode, per run, on a log axis.
fn deviation_figure(outcome: &ScenarioOutcome, title: &str) -> Figure {
    let mut layers = Vec::new();
    let mut notes = Vec::new();
    // Four decades under the smallest run's maximum: the start (distance 0) would stretch a log
    // axis without end.
    let floor = outcome
        .runs
        .iter()
        .filter_map(|(_, m)| m.geodesic_deviation.as_ref().map(|d| d.max))
        .filter(|m| *m > 0.0)
        .fold(f64::INFINITY, f64::min);
    let ceiling =
        outcome.runs.iter().filter_map(|(_, m)| m.geodesic_deviation.as_ref().map(|d| d.max)).fold(0.0, f64::max);
    let y_range = (floor.is_finite() && ceiling > 0.0).then_some((floor * 1e-4, ceiling * 1.5));
    for (i, (r, m)) in outcome.runs.iter().enumerate() {
        let t = &r.trace;
        if t.geodesic_deviation.is_empty() {
            continue;
        }
        layers.push(Layer::Lines {
            lines: vec![(0..t.t.len()).map(|k| (t.t[k], t.geodesic_deviation[k])).collect()],
            style: Style::line(run_colour(i), 1),
            label: Some(r.name.clone()),
        });
        if let Some(d) = &m.geodesic_deviation {
            notes.push(format!("{}: max {:.3e} ({:.2e} of r₀)", r.name, d.max, d.max_rel));
        }
    }
    Figure::single(
        Panel {
            title: title.into(),
            x_label: "t (s)".into(),
            y_label: "distance to the geodesic (√(kg·m²)·rad, log)".into(),
            legend: true,
            log_y: true,
            y_range,
            notes,
            layers,
            ..Panel::default()
        },
        1300,
        560,
    )
}

fn configuration_figure(
    design: &Design,
    outcome: &ScenarioOutcome,
    potential: &ElasticPotential,
    fan: &Fan,
    title: &str,
) -> Result<Figure> {
    let views = projections(design.dof());
    let mut panels = Vec::new();
    for (k, &p) in views.iter().enumerate() {
        let mut panel = configuration_panel(design, outcome, potential, fan, p, views.len() > 1)?;
        // One legend for the row of projections, on the last one.
        panel.legend = k + 1 == views.len();
        panels.push(panel);
    }
    let cols = panels.len();
    Ok(Figure {
        title: Some(title.into()),
        width: if cols > 1 { 760 * cols as u32 } else { 1050 },
        height: if cols > 1 { 700 } else { 850 },
        rows: 1,
        cols,
        panels,
    })
}

fn configuration_panel(
    design: &Design,
    outcome: &ScenarioOutcome,
    potential: &ElasticPotential,
    fan: &Fan,
    p: Projection,
    several: bool,
) -> Result<Panel> {
    let step = (fan.geodesics.len() / 24).max(1);
    let mut layers = vec![
        Layer::Lines {
            lines: fan_lines_in(fan, step, p),
            style: Style::line((190, 190, 190), 1),
            label: Some(if several { "geodesics (projected)".into() } else { "geodesics".into() }),
        },
        Layer::Lines {
            lines: vec![boundary_lines(design, fan, p)],
            style: Style::line((0, 0, 0), 1).dashed(),
            label: Some(if several { "region outline".into() } else { "region boundary".into() }),
        },
    ];
    if let ElasticPotential::Springs(s) = potential {
        let (contours, _) = potential_layers(design, s, fan, design.fit.frequency, p)?;
        if let Layer::Contours { x, y, z, levels, label, .. } = contours {
            layers.push(Layer::Contours { x, y, z, levels, style: Style::line((230, 159, 0), 1), label });
        }
    }
    for (i, (r, _)) in outcome.runs.iter().enumerate() {
        let t = &r.trace;
        let line: Vec<(f64, f64)> = (0..t.t.len()).map(|k| (t.q[k * t.n + p.0], t.q[k * t.n + p.1])).collect();
        let start = line.first().copied();
        layers.push(Layer::Lines {
            lines: vec![line],
            style: Style::line(run_colour(i), 2),
            label: Some(r.name.clone()),
        });
        if let Some(pt) = start {
            // A dot of the run's colour in a black ring: the same colour alone vanishes on its line.
            layers.push(Layer::Points { points: vec![pt], style: Style::fill((0, 0, 0), 1.0), size: 7, label: None });
            layers.push(Layer::Points {
                points: vec![pt],
                style: Style::fill(run_colour(i), 1.0),
                size: 5,
                label: None,
            });
        }
    }
    layers.push(equilibrium_layer_in(design, p));
    Ok(Panel {
        title: format!("{}–{} (start points as dots)", joint_name(p.0), joint_name(p.1)),
        x_label: joint_axis(p.0),
        y_label: joint_axis(p.1),
        equal_aspect: true,
        legend: true,
        layers,
        ..Panel::default()
    })
}

#[derive(Clone, Copy, PartialEq)]
enum TimePlot {
    Angles,
    Torques,
    Label,
    Power,
}

/// One panel per run (the first six, in two columns beyond three) of `what` against time.
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
            let (y_label, layers) = match what {
                TimePlot::Angles => ("q (rad)".into(), angle_layers(t)),
                TimePlot::Torques => ("torque (N·m)".into(), torque_layers(t)),
                TimePlot::Label => {
                    let y_label =
                        if t.n == 2 { "mode label θ (°, unwrapped)" } else { "distance to the mode Δ (°)" };
                    (y_label.into(), label_layers(t))
                }
                TimePlot::Power => ("power (W)".into(), power_layers(t)),
            };
            Panel {
                title: r.name.clone(),
                x_label: "t (s)".into(),
                y_label,
                legend: true,
                notes: run_notes(m),
                layers,
                ..Panel::default()
            }
        })
        .collect();
    Figure { title: Some(title.into()), width: 1100 * cols as u32, height: 380 * rows as u32 + 40, rows, cols, panels }
}

/// (t, f(k)) for every sample k of a trace.
fn time_series(t: &Trace, f: &dyn Fn(usize) -> f64) -> Vec<(f64, f64)> {
    (0..t.t.len()).map(|k| (t.t[k], f(k))).collect()
}

/// Each joint's angle.
fn angle_layers(t: &Trace) -> Vec<Layer> {
    let n = t.n;
    (0..n)
        .map(|i| Layer::Lines {
            lines: vec![time_series(t, &|k| t.q[k * n + i])],
            style: Style::line(palette(i), 2),
            label: Some(format!("q{}", i + 1)),
        })
        .collect()
}

/// Each source's torque on each joint, for the sources that act at all.
fn torque_layers(t: &Trace) -> Vec<Layer> {
    let n = t.n;
    let w = SOURCES.len() * n;
    let mut layers = Vec::new();
    for (s, src) in SOURCES.iter().enumerate() {
        let active = (0..t.t.len()).any(|k| (0..n).any(|i| t.tau[k * w + s * n + i] != 0.0));
        if !active {
            continue;
        }
        for i in 0..n {
            // Joint 1 solid, joint 2 dashed, joint 3 dashed and thicker.
            let style = match i {
                0 => Style::line(palette(s), 1),
                1 => Style::line(palette(s), 1).dashed(),
                _ => Style::line(palette(s), 2).dashed(),
            };
            layers.push(Layer::Lines {
                lines: vec![time_series(t, &|k| t.tau[k * w + s * n + i])],
                style,
                label: Some(format!("{src} (joint {})", i + 1)),
            });
        }
    }
    layers
}

/// The mode label (two joints: θ unwrapped; more: the distance to the mode) with its target,
/// over the spans spent in the ε-ball.
fn label_layers(t: &Trace) -> Vec<Layer> {
    let mut layers = vec![Layer::Spans {
        spans: ball_spans(t),
        style: Style::fill((150, 150, 150), 0.3),
        label: Some("ε-ball".into()),
    }];
    // θ lives on a circle: unwrapped, a label crossing ±180° goes on instead of jumping by a
    // full turn; the target is unwrapped alike and starts on the label's branch.
    let (label, target) = if t.n == 2 {
        let target = unwrap_angles(&t.label_target);
        let mut label = unwrap_angles(&t.label);
        let first = (0..t.t.len()).find(|&k| label[k].is_finite() && target[k].is_finite());
        if let Some(k) = first {
            let shift = target[k] - label[k];
            let turns = (shift / std::f64::consts::TAU).round() * std::f64::consts::TAU;
            label.iter_mut().for_each(|v| *v += turns);
        }
        (label, target)
    } else {
        (t.label.clone(), t.label_target.clone())
    };
    let lab: Vec<(f64, f64)> = (0..t.t.len()).map(|k| (t.t[k], label[k].to_degrees())).collect();
    layers.push(Layer::Lines { lines: vec![lab], style: Style::line(palette(0), 2), label: Some("label".into()) });
    if target.iter().any(|v| v.is_finite()) {
        layers.push(Layer::Lines {
            lines: vec![time_series(t, &|k| target[k].to_degrees())],
            style: Style::line((0, 0, 0), 1).dashed(),
            label: Some("desired".into()),
        });
    }
    layers
}

/// The time spans a run spends in the ε-ball (the last one closed at the end of the run).
fn ball_spans(t: &Trace) -> Vec<(f64, f64)> {
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
    spans
}

/// Each source's power, for the sources that deliver any.
fn power_layers(t: &Trace) -> Vec<Layer> {
    let mut layers = Vec::new();
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
    layers
}

/// A run's figures beside its panel: actuator share and peak torque, and where measured its
/// geodesic deviation, label drift and energy error.
fn run_notes(m: &RunMetrics) -> Vec<String> {
    let mut notes = vec![
        format!("actuator share {:.3} %", 100.0 * m.actuator_share),
        format!("peak actuator torque {:.2} N·m", m.peak_actuator_torque_nm),
    ];
    if let Some(d) = &m.geodesic_deviation {
        notes.push(format!("geodesic deviation ≤ {:.2e}", d.max));
        notes.push(format!("  √(kg·m²)·rad ({:.2e} of r₀)", d.max_rel));
    }
    if let (Some(d), Some(w)) = (m.mode_drift_deg, m.mode_drift_wrapped_deg) {
        notes.push(format!("label drift {d:.3}° ({w:.3}° wrapped)"));
    }
    if let Some(e) = m.energy_signed_error_last5s {
        notes.push(format!("E − E_d (last 5 s) {:+.2} %", 100.0 * e));
    }
    notes
}
