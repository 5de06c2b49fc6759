//! `Design.simulate()`: the design's scenarios in closed loop, as `springfit simulate` runs them,
//! with each run's samples as arrays, its metrics as the dict of `sim_<name>.json`, and
//! `write(folder)` through the command's writers.

use std::path::PathBuf;
use std::sync::Arc;

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use springfit::Error;
use springfit::design::Design;
use springfit::design::simulate::LabelKind;
use springfit::dynamics::control::ElasticPotential;
use springfit::dynamics::scenario::{ScenarioOutcome, label_source, run_scenario};
use springfit::dynamics::simulate::SOURCES;
use springfit::geodesic::Fan;
use springfit::report::output::{Edits, OutputDir, Plan};

use crate::arrays::shaped;
use crate::convert::json;
use crate::design::PyDesign;
use crate::errors::{IntoPy, in_design, setting, to_py};
use crate::progress::Progress;

/// The outcome of `Design.simulate()`.
#[pyclass(name = "Simulation", module = "springfit", frozen)]
pub struct PySimulation {
    design: Arc<Design>,
    outcomes: Vec<ScenarioOutcome>,
    potential: ElasticPotential,
    potential_name: String,
    label_name: String,
    label_error_deg: Option<f64>,
    fan: Fan,
    /// The one scenario asked for by name (a write keeps the others' files).
    only: Option<String>,
}

impl PySimulation {
    /// Runs the scenarios as `springfit simulate` does.
    #[allow(clippy::too_many_arguments)]
    pub fn run(
        py: Python<'_>,
        d: &PyDesign,
        scenario: Option<&str>,
        springs: Option<&Bound<'_, PyAny>>,
        exact: bool,
        exact_label: bool,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<PySimulation> {
        let design = d.design.clone();
        if design.file.scenario.is_empty() {
            return Err(to_py(Error::invalid(
                &design.path,
                "scenario",
                "the design declares no [[scenario]] to simulate",
            )));
        }
        let indices: Vec<usize> = match scenario {
            Some(name) => vec![design.file.scenario.iter().position(|s| s.name == name).ok_or_else(|| {
                setting(
                    "scenario",
                    format!(
                        "no scenario `{name}` in {} (it has: {})",
                        design.path.display(),
                        design.file.scenario.iter().map(|s| s.name.as_str()).collect::<Vec<_>>().join(", ")
                    ),
                )
            })?],
            None => (0..design.file.scenario.len()).collect(),
        };
        if exact && springs.is_some() {
            return Err(setting("exact", "give springs or exact = True, not both"));
        }
        let given = match springs {
            Some(s) => Some((crate::controller::potential_of(d, s)?, source_name(s)?)),
            None => None,
        };
        let catalog = if exact || given.is_some() {
            None
        } else {
            Some(d.catalog_or("the design names no spring catalogue; give springs or exact = True")?)
        };
        let mut settings = design.simulate;
        if exact_label {
            settings.label = LabelKind::Exact;
        }
        let progress = Progress::new(progress);
        let result = py.detach(|| -> springfit::Result<PySimulation> {
            let (potential, potential_name) = match (exact, given, catalog) {
                (true, _, _) => (ElasticPotential::Exact { omega: design.fit.frequency }, "exact ½ω²r²".to_string()),
                (false, Some((p, name)), _) => (p, name),
                (false, None, Some(c)) => {
                    progress.stage("fitting the springs");
                    let outcome = springfit::fit::run::fit(&design, c, &design.fit, &|_| {}).map_err(|e| {
                        springfit::fit::hints::explain(&design, &design.fit, c, design.fit.max_elements, e)
                    })?;
                    (ElasticPotential::Springs(outcome.springs), "springs (fit)".to_string())
                }
                (false, None, None) => unreachable!("a catalogue was required above"),
            };
            progress.stage("preparing the mode label");
            let (label, label_error) = label_source(&design, &settings)?;
            let label_name = if label_error.is_some() { "table" } else { "exact" };
            let fan = springfit::report::simulate::plot_fan(&design)?;
            let mut outcomes = Vec::new();
            for &i in &indices {
                progress.stage(&format!("scenario {}", design.file.scenario[i].name));
                outcomes.push(run_scenario(&design, &potential, &label, &settings, &design.controllers, i)?);
            }
            Ok(PySimulation {
                design: design.clone(),
                outcomes,
                potential,
                potential_name,
                label_name: label_name.to_string(),
                label_error_deg: label_error.map(|e| e.0),
                fan,
                only: scenario.map(str::to_string),
            })
        });
        progress.raised()?;
        result.map_err(|e| in_design(e, &d.design.path))
    }

    fn outcome(&self, name: &str) -> PyResult<&ScenarioOutcome> {
        self.outcomes.iter().find(|o| o.scenario.name == name).ok_or_else(|| {
            setting("scenario", format!("`{name}` was not simulated (simulated: {})", self.names().join(", ")))
        })
    }

    fn names(&self) -> Vec<String> {
        self.outcomes.iter().map(|o| o.scenario.name.clone()).collect()
    }
}

/// How `simulate` names the springs of its outputs.
fn source_name(springs: &Bound<'_, PyAny>) -> PyResult<String> {
    if springs.cast::<crate::fit::PyFit>().is_ok() {
        return Ok("springs (fit)".into());
    }
    if let Ok(p) = springs.cast::<crate::potential::PyPotential>() {
        return Ok(p.get().source_name());
    }
    Ok(format!("springs ({})", springs.extract::<PathBuf>()?.display()))
}

#[pymethods]
impl PySimulation {
    /// The names of the scenarios simulated.
    #[getter]
    fn scenarios(&self) -> Vec<String> {
        self.names()
    }

    /// `sim_<name>.json` of scenario `name` as a dict.
    fn summary<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
        let o = self.outcome(name)?;
        let s = springfit::report::simulate::summary(
            &self.design,
            o,
            &self.potential,
            &self.potential_name,
            &self.label_name,
            self.label_error_deg,
        );
        json(py, &s)
    }

    /// The runs of scenario `name`, each a dict: `name`, `t` (K,), `q` and `qdot` (K, n), `tau` (a
    /// dict of (K, n) arrays per source: spring, gravity, damping, mode, energy, compensation),
    /// `energy`, `label`, `label_target`, `geodesic_deviation` (K,), `in_ball` (K,) and `metrics`
    /// (the run's entry of `sim_<name>.json`).
    fn runs<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyList>> {
        let o = self.outcome(name)?;
        let out = PyList::empty(py);
        for (r, m) in &o.runs {
            let tr = &r.trace;
            let (n, k) = (tr.n, tr.t.len());
            let run = PyDict::new(py);
            run.set_item("name", &r.name)?;
            run.set_item("t", shaped(py, tr.t.clone(), false, k, &[])?)?;
            run.set_item("q", shaped(py, tr.q.clone(), false, k, &[n])?)?;
            run.set_item("qdot", shaped(py, tr.qd.clone(), false, k, &[n])?)?;
            let tau = PyDict::new(py);
            let w = SOURCES.len() * n;
            for (s, src) in SOURCES.iter().enumerate() {
                let v: Vec<f64> =
                    (0..k).flat_map(|j| tr.tau[j * w + s * n..j * w + (s + 1) * n].iter().copied()).collect();
                tau.set_item(*src, shaped(py, v, false, k, &[n])?)?;
            }
            run.set_item("tau", tau)?;
            run.set_item("energy", shaped(py, tr.energy.clone(), false, k, &[])?)?;
            run.set_item("label", shaped(py, tr.label.clone(), false, k, &[])?)?;
            run.set_item("label_target", shaped(py, tr.label_target.clone(), false, k, &[])?)?;
            let dev = if tr.geodesic_deviation.is_empty() { vec![f64::NAN; k] } else { tr.geodesic_deviation.clone() };
            run.set_item("geodesic_deviation", shaped(py, dev, false, k, &[])?)?;
            run.set_item("in_ball", numpy::PyArray1::from_vec(py, tr.in_ball.clone()))?;
            run.set_item("metrics", json(py, m)?)?;
            out.append(run)?;
        }
        Ok(out)
    }

    /// Writes what `springfit simulate` writes into `folder` (per scenario sim_<name>.csv, .json
    /// and plots; report.html), through the command's output folder. A simulation of one named
    /// scenario keeps the other scenarios' files there, as the command does.
    #[pyo3(signature = (folder, overwrite_edits = false))]
    fn write(&self, py: Python<'_>, folder: PathBuf, overwrite_edits: bool) -> PyResult<PathBuf> {
        let edits = if overwrite_edits { Edits::Overwrite } else { Edits::Refuse };
        let names = self.names();
        let plan = Plan::new("simulate", springfit::report::simulate::files(names.iter().map(String::as_str)))
            .with_edits(edits)
            .for_design(&self.design);
        py.detach(|| -> springfit::Result<PathBuf> {
            let mut dir = OutputDir::create(&folder, &plan)?;
            if let Some(only) = &self.only {
                springfit::report::simulate::keep_other_scenarios(&mut dir, only)?;
            }
            for o in &self.outcomes {
                springfit::report::simulate::write(
                    &dir,
                    &self.design,
                    o,
                    &self.potential,
                    &self.potential_name,
                    &self.label_name,
                    self.label_error_deg,
                    &self.fan,
                )?;
            }
            springfit::report::html::write_simulate(&dir, &self.design)?;
            dir.commit()
        })
        .py()
    }
}
