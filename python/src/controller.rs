//! `springfit.Controller`: the mode selection and energy regulation of a design for a robot's own
//! loop. It is the library's [`springfit::dynamics::control::Controller`], the very code
//! `springfit simulate` calls at every stage of its integrator, built from the design's
//! `[controllers]`, the springs, the label `simulate` uses and (optionally) a scenario's
//! schedules of θ_d and E_d.

use std::sync::{Arc, Mutex};

use nalgebra::DVector;
use numpy::PyArrayDyn;
use pyo3::prelude::*;
use springfit::design::Design;
use springfit::design::controllers::EnergyLaw;
use springfit::design::simulate::LabelKind;
use springfit::dynamics::control::{Controller, ElasticPotential, EnergyControl, ModeControl, ModeTarget};
use springfit::dynamics::scenario::{choose_label, resolve_scenario};
use springfit::dynamics::simulate::RunSpec;

use crate::arrays::{shaped, vector};
use crate::design::PyDesign;
use crate::errors::{IntoPy, in_design, setting};
use crate::potential::PyPotential;

/// What the controller borrows: the design and the nominal potential it believes.
pub struct Owner {
    design: Arc<Design>,
    potential: ElasticPotential,
}

self_cell::self_cell!(
    struct Cell {
        owner: Owner,
        #[covariant]
        dependent: Controller,
    }
);

/// The controller with the time of its last call (for the targets' getters).
struct State {
    cell: Cell,
    last_t: f64,
}

/// The motor torques at one state and what the controller saw there.
#[pyclass(name = "ControlOutput", module = "springfit", frozen)]
pub struct PyControlOutput {
    mode: Vec<f64>,
    energy_torque: Vec<f64>,
    compensation: Vec<f64>,
    /// θ (two joints) or Δ (more), NaN inside the ε-ball.
    #[pyo3(get)]
    label: f64,
    /// θ_d (NaN without an angle target), 0 for Δ.
    #[pyo3(get)]
    label_target: f64,
    /// Whether q is inside the ε-ball, where the mode law is off.
    #[pyo3(get)]
    in_ball: bool,
    /// E = ½q̇ᵀMq̇ + U(q) − U(q_eq) with the nominal potential, J.
    #[pyo3(get)]
    energy: f64,
    /// The blend weight of the mode torque.
    #[pyo3(get)]
    weight: f64,
    /// Whether `[controllers] max_torque` scaled the torques down at this call (the mode law's
    /// and the energy law's directions are kept; see `saturation`).
    #[pyo3(get)]
    saturated: bool,
    /// The factors the saturation applied: (on τ_θ, on τ_E + τ_comp), both 1 when it fitted.
    #[pyo3(get)]
    saturation: (f64, f64),
    /// Largest |τ_θ,i + τ_E,i + τ_comp,i| over the joints as the laws asked, before saturation,
    /// N·m.
    #[pyo3(get)]
    demand: f64,
}

#[pymethods]
impl PyControlOutput {
    /// τ_c = τ_θ + τ_E + τ_comp: what each joint's motor delivers, N·m, shape (n,).
    #[getter]
    fn tau<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let t =
            self.mode.iter().zip(&self.energy_torque).zip(&self.compensation).map(|((a, b), c)| a + b + c).collect();
        shaped(py, t, false, self.mode.len(), &[])
    }

    /// τ_θ, the mode selection (blend included), N·m.
    #[getter]
    fn mode<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        shaped(py, self.mode.clone(), false, self.mode.len(), &[])
    }

    /// τ_E or τ_nD, the energy regulation, N·m.
    #[getter]
    fn energy_torque<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        shaped(py, self.energy_torque.clone(), false, self.energy_torque.len(), &[])
    }

    /// D q̇, the damping compensation, N·m.
    #[getter]
    fn compensation<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        shaped(py, self.compensation.clone(), false, self.compensation.len(), &[])
    }

    fn __repr__(&self) -> String {
        let tau: Vec<String> = (0..self.mode.len())
            .map(|i| format!("{:.4}", self.mode[i] + self.energy_torque[i] + self.compensation[i]))
            .collect();
        format!("<springfit.ControlOutput tau=[{}] label={:.4} energy={:.4}>", tau.join(", "), self.label, self.energy)
    }
}

/// (q, q̇) as arrays.
type State2<'py> = (Bound<'py, PyArrayDyn<f64>>, Bound<'py, PyArrayDyn<f64>>);

/// The paper's controllers for a design's arm, as `simulate` runs them.
#[pyclass(name = "Controller", module = "springfit", frozen)]
pub struct PyController {
    state: Mutex<State>,
    n: usize,
    start: Option<(Vec<f64>, Vec<f64>, f64)>,
    damping: Vec<f64>,
    label_error_deg: Option<f64>,
    /// The rejected fitted log map's error, degrees (see `label_note`).
    label_rejected_error_deg: Option<f64>,
}

impl PyController {
    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        // A panic cannot happen while the lock is held (the library returns errors), so a
        // poisoned lock still holds a consistent controller.
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }
}

#[pymethods]
impl PyController {
    /// The controller of `design` believing the springs `springs` (a Fit, a Potential, or the
    /// path of a bom.csv). With `scenario` (a name of the design's `[[scenario]]`), it follows
    /// that scenario's run `run` (its θ_d and E_d schedules and damping, as `simulate` does);
    /// without one, mode and energy control are off until targets are set. `label` is `"auto"`,
    /// `"table"` (the grid table for two joints, the fitted log map for more; its error in
    /// `label_error_deg`) or `"exact"` (Newton shooting per call), as `[simulate] label`, which is
    /// the default. `damping` (n,) is the joint damping D the compensation feeds forward.
    #[new]
    #[pyo3(signature = (design, springs, scenario = None, run = 0, label = None, damping = None))]
    fn new(
        py: Python<'_>,
        design: &PyDesign,
        springs: &Bound<'_, PyAny>,
        scenario: Option<&str>,
        run: usize,
        label: Option<&str>,
        damping: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyController> {
        let d = design.design.clone();
        let n = d.dof();
        let potential = potential_of(design, springs)?;
        let mut sim = d.simulate;
        sim.label = match label {
            None => sim.label,
            Some("auto") => LabelKind::Auto,
            Some("table") => LabelKind::Table,
            Some("exact") => LabelKind::Exact,
            Some(other) => {
                return Err(setting("label", format!("must be \"auto\", \"table\" or \"exact\", got \"{other}\"")));
            }
        };
        let index = match scenario {
            None => None,
            Some(name) => Some(d.scenarios.iter().position(|s| s.name == name).ok_or_else(|| {
                setting(
                    "scenario",
                    format!(
                        "no scenario `{name}` in {} (it has: {})",
                        d.path.display(),
                        d.scenarios.iter().map(|s| s.name.as_str()).collect::<Vec<_>>().join(", ")
                    ),
                )
            })?),
        };
        let damping = damping.map(|x| vector(x, n, "damping")).transpose()?;
        type Built = (Cell, Option<RunSpec>, Option<f64>, Option<f64>);
        let built = py.detach(|| -> springfit::Result<Built> {
            let (mut spec, mut label_error, mut label_rejected) = (None, None, None);
            let cell = Cell::try_new(Owner { design: d.clone(), potential }, |o| {
                let choice = choose_label(&o.design, &sim)?;
                label_error = choice.error.map(|e| e.0);
                label_rejected = choice.rejected.map(|e| e.0);
                let label = choice.source;
                if let Some(i) = index {
                    let mut runs = resolve_scenario(&o.design, &o.potential, &label, i)?.runs;
                    if run >= runs.len() {
                        return Err(springfit::Error::Setting {
                            field: "run".into(),
                            reason: format!(
                                "scenario {} has {} run(s), numbered from 0",
                                o.design.scenarios[i].name,
                                runs.len()
                            ),
                        });
                    }
                    spec = Some(runs.swap_remove(run));
                }
                Controller::new(
                    &o.design.chain,
                    &o.design.q_eq,
                    &o.potential,
                    o.design.controllers.clone(),
                    Some(label.field()),
                )
            })?;
            Ok((cell, spec, label_error, label_rejected))
        });
        let (mut cell, spec, label_error_deg, label_rejected_error_deg) =
            built.map_err(|e| in_design(e, &design.design.path))?;
        let damping = damping.or_else(|| spec.as_ref().map(|s| s.damping.clone())).unwrap_or_else(|| vec![0.0; n]);
        cell.with_dependent_mut(|_, c| {
            c.set_damping(damping.clone());
            if let Some(s) = &spec {
                c.set_mode(s.mode.clone());
                c.set_energy(s.energy.clone());
            }
        });
        Ok(PyController {
            state: Mutex::new(State { cell, last_t: 0.0 }),
            n,
            start: spec.map(|s| (s.q0, s.qd0, s.duration)),
            damping,
            label_error_deg,
            label_rejected_error_deg,
        })
    }

    /// The motor torques at joint angles `q` (n,), velocities `qdot` (n,) and time `t` (s):
    /// τ_θ + τ_E + τ_comp, the label and the energy (a ControlOutput).
    fn torque(&self, q: &Bound<'_, PyAny>, qdot: &Bound<'_, PyAny>, t: f64) -> PyResult<PyControlOutput> {
        let q = vector(q, self.n, "q")?;
        let qd = vector(qdot, self.n, "qdot")?;
        let mut st = self.lock();
        st.last_t = t;
        st.cell
            .with_dependent_mut(|_, c| -> springfit::Result<PyControlOutput> {
                let (mode, energy_torque, compensation, weight, energy, sat, demand) = {
                    let out = c.torque(t, &q, &qd)?;
                    let (m, e, comp) = (out.mode.clone(), out.energy.clone(), out.compensation.clone());
                    (m, e, comp, out.weight, out.energy_value, out.saturation, out.demand)
                };
                let (label, label_target, in_ball) = c.label(t, &q)?;
                Ok(PyControlOutput {
                    mode,
                    energy_torque,
                    compensation,
                    label,
                    label_target,
                    in_ball,
                    energy,
                    weight,
                    saturated: sat.active(),
                    saturation: (sat.mode, sat.energy),
                    demand,
                })
            })
            .py()
    }

    /// The label at q: θ (two joints, NaN inside the ε-ball) or Δ to the reference mode.
    fn label(&self, q: &Bound<'_, PyAny>) -> PyResult<f64> {
        let q = vector(q, self.n, "q")?;
        let mut st = self.lock();
        let t = st.last_t;
        st.cell.with_dependent_mut(|_, c| c.label(t, &q)).py().map(|l| l.0)
    }

    /// θ_d in force at the last call's time (None without mode control, or with a direction
    /// target). Setting a number holds that mode from now on (replacing any schedule); None
    /// switches mode selection off.
    #[getter]
    fn get_theta_d(&self) -> Option<f64> {
        let mut st = self.lock();
        let t = st.last_t;
        st.cell.with_dependent_mut(|_, c| match c.mode().map(|m| m.target(t)) {
            Some(ModeTarget::Angle(a)) => Some(*a),
            _ => None,
        })
    }

    #[setter]
    fn set_theta_d(&self, theta: Option<f64>) -> PyResult<()> {
        if let Some(a) = theta {
            if !a.is_finite() {
                return Err(setting("theta_d", format!("must be finite, got {a}")));
            }
            if self.n != 2 {
                return Err(setting(
                    "theta_d",
                    format!(
                        "an angle names a mode of a two-joint arm; this one has {} joints: set mode_direction",
                        self.n
                    ),
                ));
            }
        }
        let mut st = self.lock();
        st.cell.with_dependent_mut(|_, c| {
            c.set_mode(theta.map(|a| ModeControl { schedule: vec![(0.0, ModeTarget::Angle(a))] }))
        });
        Ok(())
    }

    /// Holds the mode of joint velocity `direction` (n,) from now on: the mode of any number of
    /// joints (its unit vector in the metric frame at q_eq is the target u_d).
    fn set_mode_direction(&self, direction: &Bound<'_, PyAny>) -> PyResult<()> {
        let v = vector(direction, self.n, "direction")?;
        let mut st = self.lock();
        st.cell
            .with_dependent_mut(|o, c| -> springfit::Result<()> {
                let d = &o.design;
                let frame = springfit::geodesic::MetricFrame::new(&d.chain.mass_matrix(&d.q_eq))?;
                let u = frame.to_frame(&DVector::from_column_slice(&v));
                if u.norm() == 0.0 {
                    return Err(springfit::Error::Setting {
                        field: "direction".into(),
                        reason: "must be non-zero".into(),
                    });
                }
                c.set_mode(Some(ModeControl { schedule: vec![(0.0, ModeTarget::Direction(u.normalize()))] }));
                Ok(())
            })
            .py()
    }

    /// E_d in force at the last call's time, J (None without energy regulation). Setting a
    /// number holds it from now on with the current law (τ_E if none); None switches energy
    /// regulation off.
    #[getter]
    fn get_energy_target(&self) -> Option<f64> {
        let mut st = self.lock();
        let t = st.last_t;
        st.cell.with_dependent_mut(|_, c| c.energy().map(|e| e.target(t)))
    }

    #[setter]
    fn set_energy_target(&self, target: Option<f64>) -> PyResult<()> {
        // E = kinetic + U − U(q_eq) is never negative: a negative target is a sign slip, and the
        // energy law would push the arm towards it for ever.
        if let Some(e) = target
            && !(e.is_finite() && e >= 0.0)
        {
            return Err(setting(
                "energy_target",
                format!("must be a finite energy ≥ 0 J (kinetic plus U − U(q_eq), never negative), got {e}"),
            ));
        }
        let mut st = self.lock();
        st.cell.with_dependent_mut(|_, c| {
            let (law, compensate) =
                c.energy().map(|e| (e.law, e.compensate_damping)).unwrap_or((EnergyLaw::Energy, false));
            c.set_energy(target.map(|e| EnergyControl {
                law,
                schedule: vec![(0.0, e)],
                compensate_damping: compensate,
            }));
        });
        Ok(())
    }

    /// The energy law: `"energy"` (τ_E), `"negative_damping"` (τ_nD), or None when off.
    #[getter]
    fn get_energy_law(&self) -> Option<&'static str> {
        let mut st = self.lock();
        st.cell.with_dependent_mut(|_, c| {
            c.energy().map(|e| match e.law {
                EnergyLaw::Energy => "energy",
                EnergyLaw::NegativeDamping => "negative_damping",
            })
        })
    }

    #[setter]
    fn set_energy_law(&self, law: &str) -> PyResult<()> {
        let law = match law {
            "energy" => EnergyLaw::Energy,
            "negative_damping" => EnergyLaw::NegativeDamping,
            other => {
                return Err(setting(
                    "energy_law",
                    format!("must be \"energy\" or \"negative_damping\", got \"{other}\""),
                ));
            }
        };
        let mut st = self.lock();
        st.cell.with_dependent_mut(|_, c| {
            if let Some(mut e) = c.energy().cloned() {
                e.law = law;
                c.set_energy(Some(e));
            }
        });
        Ok(())
    }

    /// Whether the damping compensation D q̇ is fed forward (with energy regulation on).
    #[getter]
    fn get_compensate_damping(&self) -> bool {
        let mut st = self.lock();
        st.cell.with_dependent_mut(|_, c| c.energy().is_some_and(|e| e.compensate_damping))
    }

    #[setter]
    fn set_compensate_damping(&self, on: bool) {
        let mut st = self.lock();
        st.cell.with_dependent_mut(|_, c| {
            if let Some(mut e) = c.energy().cloned() {
                e.compensate_damping = on;
                c.set_energy(Some(e));
            }
        });
    }

    /// The joint damping D (diagonal) the compensation feeds forward, N·m·s/rad.
    #[getter]
    fn damping<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        shaped(py, self.damping.clone(), false, self.n, &[])
    }

    /// The scenario run's start (q0, qdot0) as arrays, or None without a scenario.
    #[getter]
    fn start<'py>(&self, py: Python<'py>) -> PyResult<Option<State2<'py>>> {
        match &self.start {
            Some((q, qd, _)) => {
                Ok(Some((shaped(py, q.clone(), false, self.n, &[])?, shaped(py, qd.clone(), false, self.n, &[])?)))
            }
            None => Ok(None),
        }
    }

    /// The scenario run's duration, s (None without a scenario).
    #[getter]
    fn duration(&self) -> Option<f64> {
        self.start.as_ref().map(|s| s.2)
    }

    /// The start times of the θ_d schedule, s (the steps whose settling `simulate` reports).
    #[getter]
    fn mode_steps(&self) -> Vec<f64> {
        let mut st = self.lock();
        st.cell
            .with_dependent_mut(|_, c| c.mode().map(|m| m.schedule.iter().map(|s| s.0).collect()).unwrap_or_default())
    }

    /// The tabulated label's largest error against the exact one, degrees (None for the exact label).
    #[getter]
    fn label_error_deg(&self) -> Option<f64> {
        self.label_error_deg
    }

    /// The error, degrees, of the fitted log map that `label = "auto"` measured and rejected for
    /// the exact one (None when none was rejected).
    #[getter]
    fn label_rejected_error_deg(&self) -> Option<f64> {
        self.label_rejected_error_deg
    }

    /// Why the label is exact when `auto` rejected a fit, e.g. "fitted log map error 6.61° >
    /// 0.1°: exact log map used" (None otherwise).
    #[getter]
    fn label_note(&self) -> Option<String> {
        self.label_rejected_error_deg.map(|e| springfit::dynamics::scenario::rejected_label_note(e, self.n))
    }

    /// The `[controllers]` gains in use, as a dict.
    #[getter]
    fn settings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let s = {
            let mut st = self.lock();
            st.cell.with_dependent_mut(|_, c| c.settings().clone())
        };
        crate::convert::json(py, &s)
    }
}

/// The nominal potential from a Fit, a Potential or a bom.csv path.
pub fn potential_of(design: &PyDesign, springs: &Bound<'_, PyAny>) -> PyResult<ElasticPotential> {
    if let Ok(fit) = springs.cast::<crate::fit::PyFit>() {
        return Ok(fit.get().potential_springs()?.elastic());
    }
    if let Ok(p) = springs.cast::<PyPotential>() {
        return Ok(p.get().elastic());
    }
    if let Ok(path) = springs.extract::<std::path::PathBuf>() {
        return Ok(PyPotential::from_bom_path(design, &path)?.elastic());
    }
    Err(setting("springs", "must be a springfit.Fit, a springfit.Potential or the path of a bom.csv"))
}
