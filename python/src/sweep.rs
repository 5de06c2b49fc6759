//! `Design.sweep()`: parasitic springs, manufacturing tolerance and stock rates, as
//! `springfit sweep` computes them (one process, no shards), with the tables as the dict of
//! `sweep.json`, every item's result, and `write(folder)` through the command's writer.

use std::path::PathBuf;
use std::sync::Arc;

use pyo3::prelude::*;
use springfit::design::Design;
use springfit::jobs::sweep::{Made, SweepJob, SweepRequest, SweepRun};
use springfit::report::output::{Edits, Plan};
use springfit::studies::sweep::SweepTables;

use crate::convert::json;
use crate::design::PyDesign;
use crate::errors::{IntoPy, in_design, setting};
use crate::progress::Progress;

/// The outcome of `Design.sweep()`.
#[pyclass(name = "Sweep", module = "springfit", frozen)]
pub struct PySweep {
    design: Arc<Design>,
    run: SweepRun,
}

impl PySweep {
    /// Runs every item of the design's `[sweep]` as `springfit sweep` does (its job,
    /// [`springfit::jobs::sweep`]); `builds` and `seed` override its keys like the command's
    /// options.
    pub fn run(
        py: Python<'_>,
        d: &PyDesign,
        builds: Option<usize>,
        seed: Option<u64>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<PySweep> {
        let design = d.design.clone();
        let request = SweepRequest { builds, seed, merge: Vec::new() };
        let job = SweepJob::new(&design, d.catalog.as_deref(), request).py()?;
        let progress = Progress::new(progress);
        let result = py.detach(|| job.run(progress.observer()));
        progress.raised()?;
        let run = result.map_err(|e| in_design(e, &design.path))?;
        Ok(PySweep { design, run })
    }

    /// The tables (a sweep of every item has them; a shard, which Python does not run, not).
    fn sweep_tables(&self) -> PyResult<&SweepTables> {
        match &self.run.made {
            Made::Tables(t) => Ok(t),
            Made::Shard(_) => Err(setting("sweep", "a shard has no tables: merge the shards")),
        }
    }
}

#[pymethods]
impl PySweep {
    /// `sweep.json` as a dict: the parasitic-spring, tolerance-level and stock tables.
    #[getter]
    fn tables<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json(py, self.sweep_tables()?)
    }

    /// Every item's result (the rows of `sweep.csv`), as dicts in item order.
    #[getter]
    fn items<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json(py, &self.run.results)
    }

    /// Writes what `springfit sweep` writes into `folder` (sweep.csv, sweep.json, tolerance.md,
    /// plots, bom_stock.csv when stock rates apply, report.html), through its output folder.
    #[pyo3(signature = (folder, overwrite_edits = false))]
    fn write(&self, py: Python<'_>, folder: PathBuf, overwrite_edits: bool) -> PyResult<PathBuf> {
        let edits = if overwrite_edits { Edits::Overwrite } else { Edits::Refuse };
        let plan = Plan::new("sweep", springfit::report::sweep::FILES.iter().copied())
            .with_edits(edits)
            .for_design(&self.design);
        py.detach(|| self.run.write(&self.design, springfit::report::output::check(&folder, &plan)?)).py()
    }
}
