//! The Python package `springfit`: the library's designs, fits, simulations and exports, its
//! geometry over NumPy arrays, and the controller a robot's own loop runs. Thin over the library:
//! every figure and file comes from the same functions the command line calls; this crate only
//! converts arguments (checked: a bad array is a `springfit.SettingError`, never a crash) and
//! results, and releases the GIL around long calls.

// Index loops mirror the formulas, as in the library.
#![allow(clippy::needless_range_loop)]

mod arrays;
mod compare;
mod controller;
mod convert;
mod design;
mod errors;
mod fit;
mod potential;
mod progress;
mod simulate;
mod sweep;

use pyo3::prelude::*;

/// Seconds from each mode step until the label stays within 3° of its target for the rest of
/// the step (None: never), by the rule of `sim_<name>.json`'s `settling_s`: samples at times `t`
/// with labels and targets (NaN inside the ε-ball), whether each is in the ball, the steps'
/// start times and the run's duration.
#[pyfunction]
#[pyo3(signature = (t, label, label_target, in_ball, starts, duration, two_joints = true))]
fn settling_times(
    t: Vec<f64>,
    label: Vec<f64>,
    label_target: Vec<f64>,
    in_ball: Vec<bool>,
    starts: Vec<f64>,
    duration: f64,
    two_joints: bool,
) -> PyResult<Vec<Option<f64>>> {
    let k = t.len();
    if label.len() != k || label_target.len() != k || in_ball.len() != k {
        return Err(errors::setting(
            "label",
            format!(
                "t, label, label_target and in_ball need one entry per sample ({k}, {}, {}, {})",
                label.len(),
                label_target.len(),
                in_ball.len()
            ),
        ));
    }
    Ok(springfit::dynamics::scenario::settling_times(
        &t,
        &label,
        &label_target,
        &in_ball,
        &starts,
        duration,
        two_joints,
    ))
}

#[pymodule]
fn _springfit(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    m.add_class::<design::PyDesign>()?;
    m.add_class::<fit::PyFit>()?;
    m.add_class::<potential::PyPotential>()?;
    m.add_class::<controller::PyController>()?;
    m.add_class::<controller::PyControlOutput>()?;
    m.add_class::<simulate::PySimulation>()?;
    m.add_class::<sweep::PySweep>()?;
    m.add_class::<compare::PyComparison>()?;
    m.add_function(wrap_pyfunction!(compare::compare, m)?)?;
    m.add_function(wrap_pyfunction!(settling_times, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
