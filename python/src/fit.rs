//! `Design.fit()` and its result: the bill of materials (as data), the residual angles as
//! arrays, the summary and the as-built figures, the fitted potential, and `write(folder)`
//! through the command's own writer. The fit is the library's fit job
//! ([`springfit::jobs::fit`]), the one `springfit fit` runs.

use std::path::PathBuf;
use std::sync::Arc;

use numpy::PyArrayDyn;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use springfit::design::Design;
use springfit::design::fit::SolverKind;
use springfit::files::bom::{HEADER, Value, records};
use springfit::jobs::fit::{FitJob, FitRequest, FitRun};
use springfit::report::output::{Edits, Plan};

use crate::arrays::shaped;
use crate::convert::json;
use crate::design::PyDesign;
use crate::errors::{IntoPy, in_design, setting};
use crate::potential::PyPotential;
use crate::progress::Progress;

/// A fit of a design (or the exact reference ½ω²r²), with its parts and as-built figures.
#[pyclass(name = "Fit", module = "springfit", frozen)]
pub struct PyFit {
    pub design: Arc<Design>,
    /// What `springfit fit` computes: the fit, its parts, its as-built figures.
    pub run: FitRun,
}

impl PyFit {
    /// Runs the fit job `springfit fit` runs (same settings, checks, parts and as-built builds).
    pub fn run(
        py: Python<'_>,
        d: &PyDesign,
        exact: bool,
        solver: Option<&str>,
        max_elements: Option<usize>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<PyFit> {
        let design = d.design.clone();
        let solver = match solver {
            None => None,
            Some("nnls") => Some(SolverKind::Nnls),
            Some("qp") => Some(SolverKind::Qp),
            Some(other) => return Err(setting("solver", format!("must be \"nnls\" or \"qp\", got \"{other}\""))),
        };
        let job = FitJob::new(&design, d.catalog.as_deref(), FitRequest { exact, solver, max_elements }).py()?;
        let progress = Progress::new(progress);
        let result = py.detach(|| job.run(progress.observer()));
        progress.raised()?;
        let run = result.map_err(|e| in_design(e, &design.path))?;
        Ok(PyFit { design, run })
    }

    /// The fit as `compare` records it (with its as-built brief and its springs' mass).
    pub fn record(&self) -> springfit::studies::compare::FitRecord {
        let mut r = self.run.record(&self.design.path);
        let mass = springfit::report::mass::MassSummary::new(&self.design, &self.run.outcome, self.run.parts.as_ref());
        springfit::jobs::compare::with_mass(&mut r, mass);
        r
    }

    /// The fitted springs as a potential (an error for the exact reference).
    pub fn potential_springs(&self) -> PyResult<PyPotential> {
        if self.run.exact {
            return Err(setting("potential", "the exact reference has no springs: use Potential.exact(design)"));
        }
        Ok(PyPotential::springs(self.design.clone(), self.run.outcome.springs.clone(), "fit".into()))
    }
}

#[pymethods]
impl PyFit {
    /// The bill of materials as records: one dict per row of `bom.csv`, keyed by its columns
    /// (numbers as floats, blanks as None).
    #[getter]
    fn bom<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let out = PyList::empty(py);
        for line in records(&self.run.outcome.bom) {
            let row = PyDict::new(py);
            for (k, v) in HEADER.split(',').zip(line) {
                match cell(v) {
                    Cell::Blank => row.set_item(k, py.None())?,
                    Cell::Number(x) => row.set_item(k, x)?,
                    Cell::Text(t) => row.set_item(k, t)?,
                }
            }
            out.append(row)?;
        }
        Ok(out)
    }

    /// The bill of materials as a NumPy structured array, one field per column of `bom.csv`:
    /// float64 where every entry is a number (blanks NaN), a string otherwise.
    #[getter]
    fn bom_array<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let lines: Vec<Vec<Cell>> =
            records(&self.run.outcome.bom).into_iter().map(|l| l.into_iter().map(cell).collect()).collect();
        let columns: Vec<&str> = HEADER.split(',').collect();
        let numeric: Vec<bool> =
            (0..columns.len()).map(|c| lines.iter().all(|l| !matches!(l.get(c), Some(Cell::Text(_))))).collect();
        let dtype = PyList::empty(py);
        for (c, name) in columns.iter().enumerate() {
            let width = lines.iter().map(|l| l.get(c).map_or(0, Cell::width)).max().unwrap_or(0).max(1);
            let kind = if numeric[c] { "f8".to_string() } else { format!("U{width}") };
            dtype.append((*name, kind))?;
        }
        let rows = PyList::empty(py);
        for l in &lines {
            let fields = PyList::empty(py);
            for (c, v) in l.iter().enumerate() {
                match (numeric[c], v) {
                    (true, Cell::Number(x)) => fields.append(*x)?,
                    (true, _) => fields.append(f64::NAN)?,
                    (false, Cell::Text(t)) => fields.append(t)?,
                    (false, Cell::Number(x)) => fields.append(format!("{x}"))?,
                    (false, Cell::Blank) => fields.append("")?,
                }
            }
            rows.append(pyo3::types::PyTuple::new(py, fields)?)?;
        }
        py.import("numpy")?.call_method1("array", (rows, dtype))
    }

    /// The text of `bom.csv`, byte for byte what `springfit fit` writes.
    #[getter]
    fn bom_csv(&self) -> String {
        springfit::files::bom::to_csv(&self.run.outcome.bom)
    }

    /// Number of elements used (a cam counts as one).
    #[getter]
    fn used(&self) -> usize {
        self.run.outcome.used()
    }

    /// Residual angles on the held-out geodesics, degrees, shape (N,) (signed for two joints).
    #[getter]
    fn residuals<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let r = &self.run.outcome.metrics.residuals;
        shaped(py, r.iter().map(|s| s.angle_deg).collect(), false, r.len(), &[])
    }

    /// The samples of the residual angles, as the columns of `residuals.csv`: `direction` (N,),
    /// `s` (N,), `q` (N, n) and `angle_deg` (N,).
    #[getter]
    fn residual_samples<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let r = &self.run.outcome.metrics.residuals;
        let n = self.run.outcome.dof;
        let out = PyDict::new(py);
        let dirs: Vec<i64> = r.iter().map(|s| s.direction as i64).collect();
        out.set_item("direction", numpy::PyArray1::from_vec(py, dirs))?;
        out.set_item("s", shaped(py, r.iter().map(|s| s.s).collect(), false, r.len(), &[])?)?;
        out.set_item("q", shaped(py, r.iter().flat_map(|s| s.q.iter().copied()).collect(), false, r.len(), &[n])?)?;
        out.set_item("angle_deg", shaped(py, r.iter().map(|s| s.angle_deg).collect(), false, r.len(), &[])?)?;
        Ok(out)
    }

    /// `summary.json` as a dict (with the as-built figures).
    #[getter]
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let run = &self.run;
        let s = springfit::report::fit::Summary::with_parts(
            &run.outcome,
            &self.design,
            run.as_built.as_ref(),
            run.parts.as_ref(),
        );
        json(py, &s)
    }

    /// The as-built figures (Monte Carlo builds at the design's tolerance) as a dict, or None
    /// when the fit states no tolerance (or for the exact reference).
    #[getter]
    fn as_built<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        match &self.run.as_built {
            Some(a) => json(py, a),
            None => Ok(py.None().into_bound(py)),
        }
    }

    /// The fitted elastic potential U_e (the springs), for value, gradient and Hessian.
    #[getter]
    fn potential(&self) -> PyResult<PyPotential> {
        self.potential_springs()
    }

    /// Writes every file `springfit fit` writes into `folder` (bom.csv, bom.md, parts.csv, parts.md, summary.json,
    /// residuals.csv, plots, report.md, report.html, cams/), through the command's output folder:
    /// refused before writing if the folder holds files springfit did not write, or edited since
    /// (unless `overwrite_edits`). Returns the folder.
    #[pyo3(signature = (folder, overwrite_edits = false))]
    fn write(&self, py: Python<'_>, folder: PathBuf, overwrite_edits: bool) -> PyResult<PathBuf> {
        let edits = if overwrite_edits { Edits::Overwrite } else { Edits::Refuse };
        let (design, run) = (&self.design, &self.run);
        let files = FitRequest { exact: run.exact, ..FitRequest::default() }.files();
        let plan = Plan::new("fit", files).with_edits(edits).for_design(design);
        py.detach(|| run.write(design, springfit::report::output::check(&folder, &plan)?)).py()
    }

    fn __repr__(&self) -> String {
        let o = &self.run.outcome;
        let st = &o.metrics.stats;
        format!(
            "<springfit.Fit {}: {} {}, p99 {:.4}°, max {:.4}°>",
            o.design,
            o.used(),
            o.used_noun(),
            st.p99_abs,
            st.max_abs
        )
    }
}

/// Records from CSV text (a bill of materials, a comparison's table): a dict per line, numbers
/// parsed, blanks None.
pub fn csv_records<'py>(py: Python<'py>, text: &str) -> PyResult<Bound<'py, PyList>> {
    let mut lines = text.lines();
    let header = springfit::files::split_csv_line(lines.next().unwrap_or("")).map_err(|e| setting("bom", e))?;
    let out = PyList::empty(py);
    for line in lines.filter(|l| !l.trim().is_empty()) {
        let fields = springfit::files::split_csv_line(line).map_err(|e| setting("bom", e))?;
        let row = PyDict::new(py);
        for (k, v) in header.iter().zip(fields) {
            if v.is_empty() {
                row.set_item(k, py.None())?;
            } else if let Ok(x) = v.parse::<f64>() {
                row.set_item(k, x)?;
            } else {
                row.set_item(k, v)?;
            }
        }
        out.append(row)?;
    }
    Ok(out)
}

/// A value of the bill as `Fit.bom` and `Fit.bom_array` give it: the CSV's rule kept (a text
/// that reads as a number, as a one-joint coupling `1`, has always come out as that number).
enum Cell {
    Blank,
    Number(f64),
    Text(String),
}

impl Cell {
    /// Characters of the value as the CSV writes it (the width of a text column).
    fn width(&self) -> usize {
        match self {
            Cell::Blank => 0,
            Cell::Number(x) => format!("{x}").chars().count(),
            Cell::Text(t) => t.chars().count(),
        }
    }
}

fn cell(v: Value) -> Cell {
    match v {
        Value::Blank => Cell::Blank,
        Value::Number(x) => Cell::Number(x),
        Value::Text(t) => match t.parse::<f64>() {
            Ok(x) => Cell::Number(x),
            Err(_) => Cell::Text(t),
        },
    }
}
