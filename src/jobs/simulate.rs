//! `springfit simulate` and Python's `Design.simulate()`: the design's scenarios in closed loop
//! with given, exact or freshly fitted springs, and the backbone (period against energy).
//!
//! The feature's files: the settings `design/simulate.rs`, `design/controllers.rs` and
//! `design/scenario.rs`, the controllers `dynamics/control.rs`, the integration
//! `dynamics/simulate.rs`, the scenarios and their metrics `dynamics/scenario.rs`, the backbone
//! `dynamics/backbone.rs`, the mode label `geodesic/label.rs`, the files written
//! `report/simulate.rs`, the command `cli/simulate.rs`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use super::{Couplings, check_couplings, check_equilibrium};
use crate::design::Design;
use crate::design::simulate::{LabelKind, SimSettings};
use crate::dynamics::backbone::{Backbone, backbone, backbone_energies, backbone_modes};
use crate::dynamics::scenario::{OUT_OF_REACH, ScenarioOutcome, choose_label, run_scenario};
use crate::dynamics::simulate::ElasticPotential;
use crate::elements::catalog::Catalog;
use crate::error::{Error, Result};
use crate::fit::FitOutcome;
use crate::geodesic::Fan;
use crate::progress::Progress;
use crate::report::output::Claim;

/// The springs a simulation runs.
#[derive(Debug, Clone)]
pub enum Springs<'a> {
    /// The exact potential ½ω²r² at `[fit] frequency`.
    Exact,
    /// Springs given by the caller (a bill read back, a potential), with the name the outputs
    /// give them.
    Given {
        /// The potential.
        potential: ElasticPotential,
        /// `springs (<source>)`.
        name: String,
    },
    /// Springs fitted now with this catalogue.
    Fit(&'a Catalog),
}

impl Springs<'_> {
    /// The springs of the bill of materials at `path`, checked against the design's joints.
    pub fn from_bom(design: &Design, path: &Path) -> Result<Springs<'static>> {
        let rows = crate::files::bom::read(path)?;
        check_couplings(design, path, &rows, Couplings::First)?;
        check_equilibrium(design, path, &rows)?;
        Ok(Springs::Given {
            potential: ElasticPotential::Springs(crate::fit::bill::spring_set(&rows)),
            name: format!("springs ({})", path.display()),
        })
    }
}

/// What a simulation is asked beyond the design.
#[derive(Debug, Clone)]
pub struct SimulateRequest<'a> {
    /// Only this scenario (None: every scenario of the design).
    pub scenario: Option<&'a str>,
    /// The springs.
    pub springs: Springs<'a>,
    /// The exact (log-map) label instead of `[simulate] label`.
    pub exact_label: bool,
    /// Also the backbone (the command writes it; the Python package's simulation has none).
    pub backbone: bool,
}

/// The indices of the design's scenarios a simulation of `only` (None: all) runs. The field
/// of the error for an unknown name is `scenario`.
pub fn scenarios(design: &Design, only: Option<&str>) -> Result<Vec<usize>> {
    let all = &design.scenarios;
    if all.is_empty() {
        return Err(Error::invalid(&design.path, "scenario", "the design declares no [[scenario]] to simulate"));
    }
    match only {
        Some(name) => Ok(vec![all.iter().position(|s| s.name == name).ok_or_else(|| Error::Setting {
            field: "scenario".into(),
            reason: format!(
                "no scenario `{name}` in {} (it has: {})",
                design.path.display(),
                all.iter().map(|s| s.name.as_str()).collect::<Vec<_>>().join(", ")
            ),
        })?]),
        None => Ok((0..all.len()).collect()),
    }
}

/// The names a simulation of the scenarios `names` may write.
pub fn files<'a>(names: impl IntoIterator<Item = &'a str>) -> Vec<String> {
    crate::report::simulate::files(names)
}

/// Simulates the scenarios of `request` (see [`scenarios`]): fits the springs when asked,
/// prepares the mode label, runs each scenario, then the backbone when asked.
pub fn simulate(design: &Design, request: &SimulateRequest<'_>, progress: Progress<'_>) -> Result<SimulateRun> {
    let indices = scenarios(design, request.scenario)?;
    let mut fit = None;
    let (potential, potential_name) = match &request.springs {
        Springs::Exact => (ElasticPotential::Exact { omega: design.fit.frequency }, "exact ½ω²r²".to_string()),
        Springs::Given { potential, name } => (potential.clone(), name.clone()),
        Springs::Fit(catalog) => {
            progress.stage("fitting the springs");
            let outcome = super::fit::springs_of(design, catalog, &design.fit, Progress::none())
                .map_err(|e| crate::fit::hints::explain(design, &design.fit, catalog, design.fit.max_elements, e))?;
            let springs = ElasticPotential::Springs(outcome.springs.clone());
            fit = Some(outcome);
            (springs, "springs (fit)".to_string())
        }
    };
    let mut settings = design.simulate;
    if request.exact_label {
        settings.label = LabelKind::Exact;
    }
    progress.stage("preparing the mode label");
    let choice = choose_label(design, &settings)?;
    let (label_name, label_error, label_rejected) = (choice.name(), choice.error, choice.rejected);
    let label = choice.source;
    let fan = crate::report::simulate::plot_fan(design)?;
    let mut scenarios = Vec::new();
    let mut not_met = Vec::new();
    for i in indices {
        progress.stage(&format!("scenario {}", design.scenarios[i].name));
        let t = Instant::now();
        // An energy the springs do not reach depends on the fit, not on the input (`check` passed
        // the design): the scenario or release is reported as not met and the others still run.
        match run_scenario(design, &potential, &label, &settings, &design.controllers, i) {
            Ok(outcome) => {
                not_met.extend(outcome.scenario.unreached.iter().cloned());
                if !outcome.runs.is_empty() {
                    scenarios.push(ScenarioRun { outcome, seconds: t.elapsed().as_secs_f64() });
                }
            }
            Err(e) if matches!(&e, Error::Invalid { reason, .. } if reason.contains(OUT_OF_REACH)) => {
                not_met.push(e.to_string())
            }
            Err(e) => return Err(e),
        }
    }
    let backbone = if request.backbone {
        progress.stage("backbone (period against energy on every mode)");
        let t = Instant::now();
        let modes = backbone_modes(design.dof());
        let energies = backbone_energies(design);
        let backbone = backbone(design, &potential, &label, &settings, &modes, &energies)?;
        Some(BackboneRun { backbone, modes: modes.len(), energies, seconds: t.elapsed().as_secs_f64() })
    } else {
        None
    };
    Ok(SimulateRun {
        fit,
        potential,
        potential_name,
        settings,
        label_name,
        label_error,
        label_rejected,
        fan,
        scenarios,
        backbone,
        only: request.scenario.map(str::to_string),
        not_met,
    })
}

/// A scenario simulated.
pub struct ScenarioRun {
    /// Its runs and their metrics.
    pub outcome: ScenarioOutcome,
    /// Seconds it took.
    pub seconds: f64,
}

/// The backbone of a simulation.
#[derive(Debug, Clone)]
pub struct BackboneRun {
    /// Periods against energy on every mode.
    pub backbone: Backbone,
    /// The number of modes followed.
    pub modes: usize,
    /// The energies visited, J.
    pub energies: Vec<f64>,
    /// Seconds it took.
    pub seconds: f64,
}

/// A simulation: the springs, the label, every scenario's runs, the backbone.
pub struct SimulateRun {
    /// The fit, when the springs were fitted for the simulation.
    pub fit: Option<FitOutcome>,
    /// The springs simulated.
    pub potential: ElasticPotential,
    /// Their name in the outputs.
    pub potential_name: String,
    /// `[simulate]` as run (the label possibly made exact).
    pub settings: SimSettings,
    /// `table` or `exact`.
    pub label_name: &'static str,
    /// The tabulated label's largest error against the exact label, degrees, and the number of
    /// held-out samples it was measured on (None for the exact label).
    pub label_error: Option<(f64, usize)>,
    /// The fitted log map `label = "auto"` measured and rejected for the exact one: its largest
    /// error, degrees, and the number of samples compared (None when none was rejected).
    pub label_rejected: Option<(f64, usize)>,
    /// The fan drawn behind the runs.
    pub fan: Fan,
    /// The scenarios in the order run.
    pub scenarios: Vec<ScenarioRun>,
    /// The backbone, when asked.
    pub backbone: Option<BackboneRun>,
    /// The one scenario asked for by name (a write keeps the others' files).
    pub only: Option<String>,
    /// The releases and scenarios the springs could not reach, each as its error's message
    /// (see [`SimulateRun::not_met`]).
    pub not_met: Vec<String>,
}

impl SimulateRun {
    /// Writes what `springfit simulate` writes into the claimed folder: per scenario
    /// `sim_<name>.csv`, `.json` and plots, the backbone's files when it ran, `report.html`. A
    /// simulation of one named scenario keeps the other scenarios' files there.
    pub fn write(&self, design: &Design, claim: Claim) -> Result<PathBuf> {
        let mut dir = claim.open()?;
        if let Some(only) = &self.only {
            crate::report::simulate::keep_other_scenarios(&mut dir, only)?;
        }
        for s in &self.scenarios {
            crate::report::simulate::write(
                &dir,
                design,
                &s.outcome,
                &self.potential,
                &self.potential_name,
                self.label_name,
                self.label_error.map(|e| e.0),
                self.label_rejected.map(|e| e.0),
                &self.fan,
            )?;
        }
        if let Some(b) = &self.backbone {
            crate::report::simulate::write_backbone(&dir, design, &self.potential_name, &b.backbone)?;
        }
        crate::report::html::write_simulate(&dir, design)?;
        dir.commit()
    }

    /// The error to end with when a release or scenario could not be reached by the springs
    /// (exit 1, not met): written after the runs that could, naming each one missed.
    pub fn not_met(&self) -> Option<Error> {
        (!self.not_met.is_empty()).then(|| {
            Error::numerical(
                format!(
                    "{} release(s) or scenario(s) the springs cannot reach (the others ran and were written)",
                    self.not_met.len()
                ),
                self.not_met.join("; "),
            )
        })
    }

    /// The names of the scenarios simulated.
    pub fn names(&self) -> Vec<String> {
        self.scenarios.iter().map(|s| s.outcome.scenario.name.clone()).collect()
    }
}
