//! `springfit simulate`: closed-loop runs of the design's scenarios.

use std::path::PathBuf;

use anyhow::Result;
use springfit::design::Design;
use springfit::error::Error;
use springfit::jobs::simulate::{self, BackboneRun, ScenarioRun, SimulateRequest, SimulateRun, Springs};

use super::progress::Progress;

use super::Session;

pub struct SimArgs {
    pub design: PathBuf,
    pub scenario: Option<String>,
    pub out: Option<PathBuf>,
    pub exact: bool,
    pub bom: Option<PathBuf>,
    pub exact_label: bool,
}

pub fn run(args: SimArgs, session: &Session) -> Result<()> {
    let progress = &session.progress;
    let (design, validated) = super::load_design(&args.design, progress)?;
    let scenario = args.scenario.as_deref();
    let indices = simulate::scenarios(&design, scenario).map_err(|e| super::flag(e, "scenario", "--scenario"))?;
    let target = args.out.clone().unwrap_or_else(|| PathBuf::from("out").join(format!("{}_simulate", design.name)));
    let plan = session.plan_for(
        &design,
        "simulate",
        simulate::files(indices.iter().map(|&i| design.scenarios[i].name.as_str())),
    );
    let claim = springfit::report::output::check(&target, &plan)?;
    let springs = if args.exact {
        Springs::Exact
    } else if let Some(path) = &args.bom {
        Springs::from_bom(&design, path)?
    } else if let Some(catalog) = &validated.catalog {
        Springs::Fit(catalog)
    } else {
        return Err(Error::invalid(
            &design.path,
            "catalog",
            "the design names no spring catalogue; give --bom or --exact",
        )
        .into());
    };
    let request = SimulateRequest { scenario, springs, exact_label: args.exact_label, backbone: true };
    let run = progress.run(|p| simulate::simulate(&design, &request, p)).map_err(|e| super::in_design(&design, e))?;
    let written = run.write(&design, claim)?;
    say_setup(&design, &run, progress);
    for s in &run.scenarios {
        say_scenario(&design, s, progress);
    }
    if let Some(b) = &run.backbone {
        say_backbone(b, progress);
    }
    progress.say(format!("wrote {}", written.display()));
    match run.not_met() {
        Some(e) => Err(e.into()),
        None => Ok(()),
    }
}

/// The springs, the controllers and the label.
fn say_setup(design: &Design, run: &SimulateRun, progress: &Progress) {
    if let Some(outcome) = &run.fit {
        progress.say(format!(
            "fitted {} {} (p99 residual {:.4}°)",
            outcome.used(),
            outcome.used_noun(),
            outcome.metrics.stats.p99_abs
        ));
    }
    let c = &design.controllers;
    progress.say(c.gains_summary());
    if let Some(max) = &c.max_torque {
        let max: Vec<String> = max.iter().map(|m| format!("{m}")).collect();
        progress.say(format!(
            "actuator limits: [{}] N·m per joint (torques scaled within them, each law's direction kept)",
            max.join(", ")
        ));
    }
    progress.say(match c.blend {
        springfit::design::controllers::Blend::Smooth => format!(
            "mode controller: blended in smoothly between ε = {} and 2ε = {} rad from q_eq",
            c.epsilon,
            2.0 * c.epsilon
        ),
        springfit::design::controllers::Blend::Hard => {
            format!("mode controller: hard switch at ε = {} rad from q_eq", c.epsilon)
        }
    });
    if let Some((err, count)) = run.label_error {
        progress.say(format!(
            "tabulated mode label: largest error {err:.2e}° against the exact label on {count} held-out samples"
        ));
    }
    if let Some((err, count)) = run.label_rejected {
        progress.say(format!(
            "mode label: {} (measured on {count} held-out samples)",
            springfit::dynamics::scenario::rejected_label_note(err, design.dof())
        ));
    }
}

/// A scenario's line and one line per run: deviation, actuator share, drift, energy, settling.
fn say_scenario(design: &Design, s: &ScenarioRun, progress: &Progress) {
    let (outcome, secs, name) = (&s.outcome, s.seconds, &s.outcome.scenario.name);
    progress.say(format!("scenario {name} ({} run(s), {secs:.2} s):", outcome.runs.len()));
    if outcome.scenario.kind == springfit::design::scenario::ScenarioKind::Switch {
        progress.say(format!("  energy: {}", outcome.scenario.energy_handling));
    }
    for (r, m) in &outcome.runs {
        let mut parts = Vec::new();
        if let Some(d) = &m.geodesic_deviation {
            let pct = 100.0 * d.max_rel;
            let pct = if pct >= 0.01 { format!("{pct:.2} %") } else { format!("{pct:.1e} %") };
            parts.push(format!(
                "geodesic deviation max {:.3e} √(kg·m²)·rad ({pct} of the start's r₀ = {:.3})",
                d.max, d.start_radius
            ));
        }
        let mut share = format!(
            "actuator share {:.3} % (last 5 s {:.3} %)",
            100.0 * m.actuator_share,
            100.0 * m.actuator_share_last5s
        );
        if m.flux.mode + m.flux.energy + m.flux.compensation > 0.0 {
            share.push_str(&format!(", peak actuator torque {:.2} N·m", m.peak_actuator_torque_nm));
            if design.controllers.max_torque.is_some() {
                share.push_str(&format!(
                    " (the laws asked {:.2} N·m; saturated for {:.2} s)",
                    m.peak_demanded_torque_nm, m.saturated_s
                ));
            }
        }
        parts.push(share);
        if m.flux.mode + m.flux.energy + m.flux.compensation > 0.0 {
            let (sv, a, b) = (&m.savings, &m.savings.with_springs, &m.savings.without_springs);
            parts.push(format!(
                "against the arm without springs: energy {:.3} J vs {:.3} J ({:.1} % saved), peak torque {:.2} vs {:.2} N·m ({:.1} %), RMS {:.3} vs {:.3} N·m ({:.1} %), copper losses {:.4} vs {:.4} J ({:.1} %)",
                a.energy_j,
                b.energy_j,
                100.0 * sv.energy_saved,
                a.peak_torque_nm,
                b.peak_torque_nm,
                100.0 * sv.peak_torque_saved,
                a.rms_torque_nm,
                b.rms_torque_nm,
                100.0 * sv.rms_torque_saved,
                a.copper_loss_j,
                b.copper_loss_j,
                100.0 * sv.copper_loss_saved
            ));
        }
        if m.flux.compensation > 0.0 {
            parts.push(format!("with damping compensation {:.3} %", 100.0 * m.actuator_share_with_compensation));
        }
        if let (Some(d), Some(w)) = (m.mode_drift_deg, m.mode_drift_wrapped_deg) {
            parts.push(format!("label drift {d:.3}° cumulative, {w:.3}° wrapped"));
        }
        if let Some(e) = m.energy_signed_error_last5s {
            parts.push(format!("E − E_d over the last 5 s {:+.2} %", 100.0 * e));
            if e.abs() > 0.1 {
                parts.push(format!(
                        "hint: the energy misses E_d by more than 10 %: the energy gain controllers.beta_e = {} sets the \
                         time constant 1/(β_E·E_d); too large overshoots (gravity adds to the swing's energy exchange), too \
                         small does not reach E_d within the duration",
                        design.controllers.beta_e
                    ));
            }
        }
        if !m.settling_s.is_empty() {
            let worst = m.settling_s.iter().map(|s| s.unwrap_or(f64::INFINITY)).fold(0.0, f64::max);
            parts.push(format!("slowest mode step settles in {worst:.2} s"));
        }
        progress.say(format!("  {}: {}", r.name, parts.join(", ")));
    }
}

/// The backbone's isochrony error.
fn say_backbone(b: &BackboneRun, progress: &Progress) {
    let (backbone, secs) = (&b.backbone, b.seconds);
    let reached = backbone.points.iter().filter(|p| p.period_s.is_some()).count();
    progress.say(match backbone.isochrony_error {
        Some(e) => format!(
            "backbone ({reached} points: {} modes at {} J, {secs:.2} s): isochrony error max |T/T₀ − 1| = {e:.3e} (T₀ = 2π/ω = {:.4} s)",
            b.modes,
            b.energies.iter().map(|e| format!("{e:.3}")).collect::<Vec<_>>().join(", "),
            backbone.nominal_period_s
        ),
        None => "backbone: no period could be read (no mode reaches the energies inside the region)".to_string(),
    });
    if !backbone.out_of_reach.is_empty() {
        progress.say(format!(
            "  {} (mode, energy) point(s) out of reach inside the region: see backbone.md",
            backbone.out_of_reach.len()
        ));
    }
}
