//! `springfit.compare()`: fits side by side as `springfit compare` sets them (histograms on
//! shared bins, box plots, the table), from Fit objects and fit output folders.

use std::path::PathBuf;

use pyo3::prelude::*;
use springfit::jobs::compare::{self as job, Comparison};
use springfit::progress::Progress;
use springfit::report::output::{Edits, Plan};
use springfit::studies::compare::table_csv;

use crate::design::PyDesign;
use crate::errors::{IntoPy, in_design, setting};
use crate::fit::{PyFit, csv_records};

/// The records of a comparison.
#[pyclass(name = "Comparison", module = "springfit", frozen)]
pub struct PyComparison {
    comparison: Comparison,
}

/// Compares fits: each input a `Fit` or the output folder of `springfit fit` (or `Fit.write`);
/// `exact` (a Design) adds its exact potential ½ω²r² as a reference, as `--exact` does.
#[pyfunction]
#[pyo3(signature = (inputs, exact = None))]
pub fn compare(py: Python<'_>, inputs: Vec<Bound<'_, PyAny>>, exact: Option<&PyDesign>) -> PyResult<PyComparison> {
    job::inputs(inputs.len()).py()?;
    let mut records = Vec::new();
    for input in &inputs {
        if let Ok(fit) = input.cast::<PyFit>() {
            records.push(fit.get().record());
        } else {
            let path: PathBuf = input
                .extract()
                .map_err(|_| setting("inputs", "each input must be a springfit.Fit or a fit output folder"))?;
            records.push(springfit::files::fit_folder::load_fit_dir(&path).py()?);
        }
    }
    if let Some(d) = exact {
        let design = d.design.clone();
        let record = py.detach(|| job::exact(&design, &design.path, Progress::none()));
        records.push(record.map_err(|e| in_design(e, &design.path))?);
    }
    Ok(PyComparison { comparison: Comparison::new(records).py()? })
}

#[pymethods]
impl PyComparison {
    /// The table of `compare.csv` as records (one dict per fit).
    #[getter]
    fn table<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyList>> {
        csv_records(py, &table_csv(&self.comparison.records))
    }

    /// The text of `compare.csv`.
    #[getter]
    fn csv(&self) -> String {
        table_csv(&self.comparison.records)
    }

    /// Writes what `springfit compare` writes into `folder` (compare.csv, compare.md,
    /// compare.svg/.png, report.html), through its output folder.
    #[pyo3(signature = (folder, overwrite_edits = false))]
    fn write(&self, py: Python<'_>, folder: PathBuf, overwrite_edits: bool) -> PyResult<PathBuf> {
        let edits = if overwrite_edits { Edits::Overwrite } else { Edits::Refuse };
        let plan = Plan::new("compare", springfit::report::compare::COMPARE_FILES.iter().copied()).with_edits(edits);
        py.detach(|| self.comparison.write(springfit::report::output::check(&folder, &plan)?)).py()
    }
}
