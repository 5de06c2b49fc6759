//! `Design.simulate()`: the design's scenarios in closed loop, as `springfit simulate` runs them,
//! with each run's samples as arrays, its metrics as the dict of `sim_<name>.json`, and
//! `write(folder)` through the command's writers.

use std::path::PathBuf;
use std::sync::Arc;

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use springfit::design::Design;
use springfit::dynamics::scenario::ScenarioOutcome;
use springfit::dynamics::simulate::SOURCES;
use springfit::jobs::simulate::{self, SimulateRequest, SimulateRun, Springs};
use springfit::report::output::{Edits, Plan};

use crate::arrays::shaped;
use crate::convert::json;
use crate::design::PyDesign;
use crate::errors::{IntoPy, in_design, setting};
use crate::progress::Progress;

/// The outcome of `Design.simulate()`.
#[pyclass(name = "Simulation", module = "springfit", frozen)]
pub struct PySimulation {
    design: Arc<Design>,
    run: SimulateRun,
}

impl PySimulation {
    /// Runs the scenarios as `springfit simulate` does (its job, [`springfit::jobs::simulate`],
    /// without the backbone).
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
        simulate::scenarios(&design, scenario).py()?;
        if exact && springs.is_some() {
            return Err(setting("exact", "give springs or exact = True, not both"));
        }
        let springs = match springs {
            Some(s) => Springs::Given { potential: crate::controller::potential_of(d, s)?, name: source_name(s)? },
            None if exact => Springs::Exact,
            None => Springs::Fit(d.catalog_or("the design names no spring catalogue; give springs or exact = True")?),
        };
        let request = SimulateRequest { scenario, springs, exact_label, backbone: false };
        let progress = Progress::new(progress);
        let result = py.detach(|| simulate::simulate(&design, &request, progress.observer()));
        progress.raised()?;
        let run = result.map_err(|e| in_design(e, &d.design.path))?;
        // A release the springs cannot reach is not met (NumericalError), as the command's exit 1.
        if let Some(e) = run.not_met() {
            return Err(in_design(e, &d.design.path));
        }
        Ok(PySimulation { design, run })
    }

    fn outcome(&self, name: &str) -> PyResult<&ScenarioOutcome> {
        self.run.scenarios.iter().map(|s| &s.outcome).find(|o| o.scenario.name == name).ok_or_else(|| {
            setting("scenario", format!("`{name}` was not simulated (simulated: {})", self.run.names().join(", ")))
        })
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
        self.run.names()
    }

    /// `sim_<name>.json` of scenario `name` as a dict.
    fn summary<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
        let o = self.outcome(name)?;
        let r = &self.run;
        let s = springfit::report::simulate::summary(
            &self.design,
            o,
            &r.potential,
            &r.potential_name,
            r.label_name,
            r.label_error.map(|e| e.0),
            r.label_rejected.map(|e| e.0),
        );
        json(py, &s)
    }

    /// What the springs save on each run of scenario `name` against the arm without them, a dict
    /// by run name of the `savings` of `sim_<name>.json`: `with_springs` and `without_springs`
    /// (`energy_j`, `peak_torque_nm`, `rms_torque_nm`, `copper_loss_j`) and the fractions saved
    /// `energy_saved`, `peak_torque_saved`, `rms_torque_saved`, `copper_loss_saved`, beside the
    /// run's `actuator_share`.
    fn savings<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyDict>> {
        let o = self.outcome(name)?;
        let out = PyDict::new(py);
        for (r, m) in &o.runs {
            let d = json(py, &m.savings)?;
            d.set_item("actuator_share", m.actuator_share)?;
            out.set_item(&r.name, d)?;
        }
        Ok(out)
    }

    /// The controllers' gains the runs used, a dict (the `gains` of `sim_<name>.json`): `k_theta`,
    /// `zeta`, `epsilon`, `beta_e`, `beta_nd`, `from_arm` (the keys the design left out, derived
    /// from the arm) and `basis` (what they were derived from, or None).
    #[getter]
    fn gains<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json(py, &springfit::report::simulate::GainsReport::of(&self.design.controllers))
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
        let names = self.run.names();
        let plan = Plan::new("simulate", simulate::files(names.iter().map(String::as_str)))
            .with_edits(edits)
            .for_design(&self.design);
        py.detach(|| self.run.write(&self.design, springfit::report::output::check(&folder, &plan)?)).py()
    }
}
