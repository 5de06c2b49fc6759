//! `springfit.Potential`: a design's elastic potential U_e (a fitted spring set, the springs of a
//! bill of materials, or the exact ½ω²r² − U_g) with its value, gradient and Hessian over arrays
//! of points: the functions the simulator evaluates, so a loop of one's own integrates the same
//! arm.

use std::path::PathBuf;
use std::sync::Arc;

use numpy::PyArrayDyn;
use pyo3::prelude::*;
use springfit::design::Design;
use springfit::dynamics::control::ElasticPotential;
use springfit::potential::{ExactPotential, GroupedSet, Potential, SpringSet};

use crate::arrays::{points, shaped};
use crate::design::{PyDesign, map_rows};
use crate::errors::IntoPy;

/// What the potential is.
#[derive(Clone)]
pub enum Kind {
    /// A spring set, grouped for evaluation as the simulator evaluates it.
    Springs(SpringSet, Arc<GroupedSet>),
    /// ½ω²r² − U_g, ω in rad/s.
    Exact(f64),
}

/// The elastic potential of a design.
#[pyclass(name = "Potential", module = "springfit", frozen)]
#[derive(Clone)]
pub struct PyPotential {
    pub design: Arc<Design>,
    pub kind: Kind,
    /// Where the springs come from (`fit`, a bom.csv path), as `simulate` names them.
    source: String,
}

impl PyPotential {
    /// The potential of a spring set.
    pub fn springs(design: Arc<Design>, set: SpringSet, source: String) -> PyPotential {
        let grouped = Arc::new(set.grouped());
        PyPotential { design, kind: Kind::Springs(set, grouped), source }
    }

    /// The springs of the bill of materials at `path`, checked against the design's joints.
    pub fn from_bom_path(design: &PyDesign, path: &std::path::Path) -> PyResult<PyPotential> {
        let rows = springfit::files::bom::read(path).py()?;
        springfit::jobs::check_couplings(&design.design, path, &rows, springfit::jobs::Couplings::Any).py()?;
        springfit::jobs::check_equilibrium(&design.design, path, &rows).py()?;
        Ok(PyPotential::springs(
            design.design.clone(),
            springfit::fit::bill::spring_set(&rows),
            path.display().to_string(),
        ))
    }

    /// How `simulate` names this potential in its outputs.
    pub fn source_name(&self) -> String {
        match self.kind {
            Kind::Springs(..) => format!("springs ({})", self.source),
            Kind::Exact(_) => "exact ½ω²r²".into(),
        }
    }

    /// As the simulator's type.
    pub fn elastic(&self) -> ElasticPotential {
        match &self.kind {
            Kind::Springs(s, _) => ElasticPotential::Springs(s.clone()),
            Kind::Exact(omega) => ElasticPotential::Exact { omega: *omega },
        }
    }

    /// `f(potential, q, out)` for each row of `q`.
    fn each<'py, F>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        tail: &[usize],
        f: F,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>>
    where
        F: Fn(&dyn Potential, &[f64], &mut [f64]) -> springfit::Result<()> + Sync + Send,
    {
        let d = &self.design;
        let p = points(q, d.dof(), "q")?;
        let width = tail.iter().product::<usize>();
        let out = match &self.kind {
            Kind::Springs(_, g) => map_rows(py, &p, width, |i, o| f(g.as_ref(), p.row(i), o))?,
            Kind::Exact(omega) => map_rows(py, &p, width, |i, o| {
                let exact = ExactPotential::new(&d.chain, &d.q_eq, *omega, d.geodesics.ode);
                f(&exact, p.row(i), o)
            })?,
        };
        shaped(py, out, p.single, p.count, tail)
    }
}

#[pymethods]
impl PyPotential {
    /// The springs of a bill of materials (`bom.csv` as `springfit fit` writes it) on `design`.
    #[staticmethod]
    fn from_bom(design: &PyDesign, path: PathBuf) -> PyResult<PyPotential> {
        PyPotential::from_bom_path(design, &path)
    }

    /// The exact potential ½ω²r² − U_g (ω from `[fit] frequency` unless given): the physical
    /// limit a spring set approaches, one log map per point.
    #[staticmethod]
    #[pyo3(signature = (design, omega = None))]
    fn exact(design: &PyDesign, omega: Option<f64>) -> PyResult<PyPotential> {
        let omega = omega.unwrap_or(design.design.fit.frequency);
        if !(omega.is_finite() && omega > 0.0) {
            return Err(crate::errors::setting("omega", format!("must be a positive frequency (rad/s), got {omega}")));
        }
        Ok(PyPotential { design: design.design.clone(), kind: Kind::Exact(omega), source: "exact".into() })
    }

    /// Number of elements (0 for the exact potential).
    fn __len__(&self) -> usize {
        match &self.kind {
            Kind::Springs(s, _) => s.elements.len(),
            Kind::Exact(_) => 0,
        }
    }

    /// U_e(q), J; shape () or (N,).
    fn value<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        self.each(py, q, &[], |u, q, o| {
            o[0] = u.value(q)?;
            Ok(())
        })
    }

    /// ∂U_e/∂q, N·m (the springs' joint torque is its negative); shape (n,) or (N, n).
    fn gradient<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = self.design.dof();
        self.each(py, q, &[n], |u, q, o| u.gradient_into(q, o))
    }

    /// ∇²U_e, N·m/rad; shape (n, n) or (N, n, n).
    fn hessian<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = self.design.dof();
        self.each(py, q, &[n, n], |u, q, o| {
            let h = u.hessian(q)?;
            for k in 0..n * n {
                o[k] = h[(k / n, k % n)];
            }
            Ok(())
        })
    }

    fn __repr__(&self) -> String {
        match &self.kind {
            Kind::Springs(s, _) => {
                format!("<springfit.Potential: {} elements on {}>", s.elements.len(), self.design.name)
            }
            Kind::Exact(omega) => {
                format!("<springfit.Potential: exact ½ω²r² − U_g, ω = {omega} rad/s, on {}>", self.design.name)
            }
        }
    }
}
