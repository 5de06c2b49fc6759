//! `Design.sweep()`: parasitic springs, manufacturing tolerance and stock rates, as
//! `springfit sweep` computes them (one process, no shards), with the tables as the dict of
//! `sweep.json`, every item's result, and `write(folder)` through the command's writer.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use pyo3::prelude::*;
use springfit::Error;
use springfit::design::Design;
use springfit::design::sweep::SweepSettings;
use springfit::dynamics::scenario::label_source;
use springfit::fit::FitOutcome;
use springfit::report::output::{Edits, Plan};
use springfit::studies::sweep::{ItemResult, SweepContext, SweepTables, plan, tables};

use crate::convert::json;
use crate::design::PyDesign;
use crate::errors::{IntoPy, in_design, setting, to_py};
use crate::progress::Progress;

/// The outcome of `Design.sweep()`.
#[pyclass(name = "Sweep", module = "springfit", frozen)]
pub struct PySweep {
    design: Arc<Design>,
    fit: FitOutcome,
    results: Vec<ItemResult>,
    tables: SweepTables,
}

impl PySweep {
    /// Runs every item of the design's `[sweep]` as `springfit sweep` does; `builds` and `seed`
    /// override its keys like the command's options.
    pub fn run(
        py: Python<'_>,
        d: &PyDesign,
        builds: Option<usize>,
        seed: Option<u64>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<PySweep> {
        let design = d.design.clone();
        let mut settings: SweepSettings = design.file.sweep.clone();
        if let Some(b) = builds {
            if b == 0 {
                return Err(setting("builds", "must be at least 1 (Monte Carlo builds per tolerance level)"));
            }
            settings.builds = b;
        }
        if let Some(s) = seed {
            settings.seed = s;
        }
        let catalog = d.catalog_or("the design names no spring catalogue to sweep")?;
        if design.file.scenario.is_empty() {
            return Err(to_py(Error::invalid(
                &design.path,
                "scenario",
                "the design declares no [[scenario]]: a sweep reruns the [sweep] scenario for every item",
            )));
        }
        springfit::design::validate::sweep_scenario(&design).py()?;
        let progress = Progress::new(progress);
        let result = py.detach(|| -> springfit::Result<(FitOutcome, Vec<ItemResult>)> {
            progress.stage("fitting the springs");
            let fit = springfit::fit::run::fit(&design, catalog, &design.fit, &|_| {}).map_err(|e| {
                springfit::fit::hints::explain(&design, &design.fit, catalog, design.fit.max_elements, e)
            })?;
            let items = plan(&settings, fit.bom.iter().any(|r| r.stock_rate.is_some()));
            progress.stage("preparing the mode label");
            let (label, _) = label_source(&design, &design.simulate)?;
            let ctx = SweepContext::new(&design, &fit, &label, settings.clone())?;
            let done = AtomicUsize::new(0);
            let total = items.len();
            let indices: Vec<usize> = (0..total).collect();
            let results = ctx.run_observed(&items, &indices, &|| {
                let k = done.fetch_add(1, Ordering::Relaxed) + 1;
                progress.stage(&format!("sweep items: {k} of {total} done"));
            })?;
            Ok((fit, results))
        });
        progress.raised()?;
        let (fit, results) = result.map_err(|e| in_design(e, &design.path))?;
        let tables = tables(&settings, &results);
        Ok(PySweep { design, fit, results, tables })
    }
}

#[pymethods]
impl PySweep {
    /// `sweep.json` as a dict: the parasitic-spring, tolerance-level and stock tables.
    #[getter]
    fn tables<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json(py, &self.tables)
    }

    /// Every item's result (the rows of `sweep.csv`), as dicts in item order.
    #[getter]
    fn items<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json(py, &self.results)
    }

    /// Writes what `springfit sweep` writes into `folder` (sweep.csv, sweep.json, tolerance.md,
    /// plots, bom_stock.csv when stock rates apply, report.html), through its output folder.
    #[pyo3(signature = (folder, overwrite_edits = false))]
    fn write(&self, py: Python<'_>, folder: PathBuf, overwrite_edits: bool) -> PyResult<PathBuf> {
        let edits = if overwrite_edits { Edits::Overwrite } else { Edits::Refuse };
        let plan = Plan::new("sweep", springfit::report::sweep::FILES.iter().copied())
            .with_edits(edits)
            .for_design(&self.design);
        py.detach(|| {
            springfit::report::sweep::write_folder(
                springfit::report::output::check(&folder, &plan)?,
                &self.design,
                &self.tables,
                &self.results,
                &self.fit.bom,
            )
        })
        .py()
    }
}
