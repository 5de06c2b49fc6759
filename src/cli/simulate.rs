//! `springfit simulate`: closed-loop runs of the design's scenarios.

use std::path::PathBuf;

use anyhow::Result;
use springfit::design::simulate::LabelKind;
use springfit::dynamics::backbone::{backbone, backbone_energies, backbone_modes};
use springfit::dynamics::scenario::{label_source, run_scenario};
use springfit::dynamics::simulate::ElasticPotential;
use springfit::error::Error;
use springfit::files::bom;
use springfit::fit::run::fit;

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
    if design.file.scenario.is_empty() {
        return Err(Error::invalid(&design.path, "scenario", "the design declares no [[scenario]] to simulate").into());
    }
    let indices: Vec<usize> = match &args.scenario {
        Some(name) => {
            vec![design.file.scenario.iter().position(|s| &s.name == name).ok_or_else(|| Error::Setting {
                field: "--scenario".into(),
                reason: format!(
                    "no scenario `{name}` in {} (it has: {})",
                    design.path.display(),
                    design.file.scenario.iter().map(|s| s.name.as_str()).collect::<Vec<_>>().join(", ")
                ),
            })?]
        }
        None => (0..design.file.scenario.len()).collect(),
    };
    let target = args.out.clone().unwrap_or_else(|| PathBuf::from("out").join(format!("{}_simulate", design.name)));
    let plan = session.plan_for(
        &design,
        "simulate",
        springfit::report::simulate::files(indices.iter().map(|&i| design.file.scenario[i].name.as_str())),
    );
    let claim = springfit::report::output::check(&target, &plan)?;
    let (potential, potential_name) = if args.exact {
        (ElasticPotential::Exact { omega: design.fit.frequency }, "exact ½ω²r²".to_string())
    } else if let Some(path) = &args.bom {
        let rows = bom::read(path)?;
        if rows[0].element.coupling.len() != design.dof() {
            return Err(Error::invalid(
                path,
                "coupling",
                format!(
                    "the springs act on {} joints but the design has {}",
                    rows[0].element.coupling.len(),
                    design.dof()
                ),
            )
            .into());
        }
        (ElasticPotential::Springs(springfit::fit::bill::spring_set(&rows)), format!("springs ({})", path.display()))
    } else if let Some(catalog) = &validated.catalog {
        let step = progress.step("fitting the springs");
        let outcome = fit(&design, catalog, &design.fit, &|_| {});
        step.finish();
        let outcome = outcome.map_err(|e| super::fit_failed(&design, &design.fit, Some(catalog), e))?;
        progress.say(format!(
            "fitted {} {} (p99 residual {:.4}°)",
            outcome.used(),
            outcome.used_noun(),
            outcome.metrics.stats.p99_abs
        ));
        (ElasticPotential::Springs(outcome.springs), "springs (fit)".to_string())
    } else {
        return Err(Error::invalid(
            &design.path,
            "catalog",
            "the design names no spring catalogue; give --bom or --exact",
        )
        .into());
    };
    let mut settings = design.simulate;
    if args.exact_label {
        settings.label = LabelKind::Exact;
    }
    let c = &design.controllers;
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
    let step = progress.step("preparing the mode label");
    let label = label_source(&design, &settings);
    step.finish();
    let (label, label_error) = label?;
    let label_name = if label_error.is_some() { "table" } else { "exact" };
    if let Some((err, count)) = label_error {
        progress.say(format!(
            "tabulated mode label: largest error {err:.2e}° against the exact label on {count} held-out samples"
        ));
    }
    let fan = springfit::report::simulate::plot_fan(&design)?;
    let mut dir = claim.open()?;
    if let Some(only) = &args.scenario {
        // A rerun of one scenario keeps the other scenarios' files of the previous run.
        springfit::report::simulate::keep_other_scenarios(&mut dir, only)?;
    }
    for i in indices {
        let name = design.file.scenario[i].name.clone();
        let step = progress.step(&format!("scenario {name}"));
        let outcome = run_scenario(&design, &potential, &label, &settings, &design.controllers, i);
        let secs = step.finish();
        let outcome = outcome?;
        springfit::report::simulate::write(
            &dir,
            &design,
            &outcome,
            &potential,
            &potential_name,
            label_name,
            label_error.map(|e| e.0),
            &fan,
        )?;
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
    let step = progress.step("backbone (period against energy on every mode)");
    let modes = backbone_modes(design.dof());
    let energies = backbone_energies(&design);
    let backbone = backbone(&design, &potential, &label, &settings, &modes, &energies);
    let secs = step.finish();
    let backbone = backbone?;
    springfit::report::simulate::write_backbone(&dir, &design, &potential_name, &backbone)?;
    let reached = backbone.points.iter().filter(|p| p.period_s.is_some()).count();
    progress.say(match backbone.isochrony_error {
        Some(e) => format!(
            "backbone ({reached} points: {} modes at {} J, {secs:.2} s): isochrony error max |T/T₀ − 1| = {e:.3e} (T₀ = 2π/ω = {:.4} s)",
            modes.len(),
            energies.iter().map(|e| format!("{e:.3}")).collect::<Vec<_>>().join(", "),
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
    springfit::report::html::write_simulate(&dir, &design)?;
    let written = dir.commit()?;
    progress.say(format!("wrote {}", written.display()));
    Ok(())
}
