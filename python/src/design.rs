//! `springfit.Design`: a design file loaded and validated as the command line does, its robot's
//! dynamics and geometry over arrays of points, and the commands (fit, simulate, export, tune).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use nalgebra::DVector;
use numpy::PyArrayDyn;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use springfit::Error;
use springfit::design::Design;
use springfit::elements::catalog::Catalog;
use springfit::geodesic::Shooter;
use springfit::geodesic::logmap::{LogMap, LogSettings};

use crate::arrays::{Points, points, shaped};
use crate::convert::{json, toml_value};
use crate::errors::{IntoPy, setting};

/// A validated design: the robot, its equilibrium, the region and every settings section.
#[pyclass(name = "Design", module = "springfit", frozen)]
pub struct PyDesign {
    pub design: Arc<Design>,
    pub catalog: Option<Arc<Catalog>>,
    warnings: Vec<String>,
}

impl PyDesign {
    /// Loads `text` (the design file at `path`) with keyword overrides, validated as every
    /// command validates it first.
    fn new(path: &Path, text: &str, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<PyDesign> {
        let text = match overrides {
            Some(o) if !o.is_empty() => with_overrides(path, text, o)?,
            _ => text.to_string(),
        };
        let design = Design::parse(path, &text).py()?;
        let validated = springfit::design::validate::validate(&design).py()?;
        Ok(PyDesign {
            warnings: validated.warnings.iter().map(|w| w.to_string()).collect(),
            catalog: validated.catalog.map(Arc::new),
            design: Arc::new(design),
        })
    }

    /// The catalogue, or the error the command line gives without one.
    pub fn catalog_or(&self, reason: &str) -> PyResult<&Catalog> {
        self.catalog
            .as_deref()
            .ok_or_else(|| crate::errors::to_py(Error::invalid(&self.design.path, "catalog", reason)))
    }

    fn rows(&self, obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Points> {
        points(obj, self.design.dof(), name)
    }
}

/// The keys of `[fit]` and `[region]` replaced in the design's text. A key goes to the section
/// that accepts it (tried by deserialising it alone, so the sections' own definitions decide);
/// a key of neither is refused with serde's message for `[fit]`, as the file would be. Giving
/// `kind` replaces the whole `[region]` table.
fn with_overrides(path: &Path, text: &str, overrides: &Bound<'_, PyDict>) -> PyResult<String> {
    use springfit::design::RegionSpec;
    use springfit::design::fit::FitSettings;
    let mut table: toml::Table = springfit::design::parse_toml(path, text).py()?;
    let mut fit = toml::Table::new();
    let mut region = toml::Table::new();
    for (key, value) in overrides.iter() {
        let key: String = key.extract()?;
        let value = toml_value(&value, &key)?;
        // An integer given for a number of metres or radians is that number.
        let candidates = match &value {
            toml::Value::Integer(i) => vec![value.clone(), toml::Value::Float(*i as f64)],
            _ => vec![value.clone()],
        };
        let try_fit = |v: &toml::Value| {
            let mut t = toml::Table::new();
            t.insert(key.clone(), v.clone());
            toml::Value::Table(t).try_into::<FitSettings>().map_err(|e| e.to_string())
        };
        let try_region = |v: &toml::Value| {
            let mut t = toml::Table::new();
            t.insert("kind".into(), toml::Value::String("ball".into()));
            t.insert(key.clone(), v.clone());
            toml::Value::Table(t).try_into::<RegionSpec>().map_err(|e| e.to_string())
        };
        let unknown = |e: Option<String>| e.is_some_and(|e| e.contains("unknown field"));
        if !unknown(try_fit(&value).err()) {
            let v = candidates.iter().find(|v| try_fit(v).is_ok()).unwrap_or(&value).clone();
            fit.insert(key, v);
        } else if key == "kind" || !unknown(try_region(&value).err()) {
            let v = candidates.iter().find(|v| try_region(v).is_ok()).unwrap_or(&value).clone();
            region.insert(key, v);
        } else {
            let reason = try_fit(&value).err().unwrap_or_default();
            let reason = reason.lines().find(|l| l.contains("unknown field")).unwrap_or(&reason).trim().to_string();
            return Err(setting(
                key,
                format!("{reason} (a keyword override names a key of [fit]; of [region]: kind, radius, lower, upper)"),
            ));
        }
    }
    if !fit.is_empty() {
        let section = table.entry("fit").or_insert_with(|| toml::Value::Table(toml::Table::new()));
        if let Some(t) = section.as_table_mut() {
            t.extend(fit);
        }
    }
    if !region.is_empty() {
        let replace = region.contains_key("kind");
        let section = table.entry("region").or_insert_with(|| toml::Value::Table(toml::Table::new()));
        if let Some(t) = section.as_table_mut() {
            if replace {
                t.clear();
            }
            t.extend(region);
        }
    }
    toml::to_string(&table).map_err(|e| setting("overrides", format!("cannot be written as TOML: {e}")))
}

/// Evaluates `f` on every row of `p` into `width` numbers per row: in parallel (without the GIL)
/// for many rows, in place for a few. Each row is independent of the others, so the result does
/// not depend on the thread count.
pub fn map_rows<F>(py: Python<'_>, p: &Points, width: usize, f: F) -> PyResult<Vec<f64>>
where
    F: Fn(usize, &mut [f64]) -> springfit::Result<()> + Sync + Send,
{
    let mut out = vec![0.0; p.count * width];
    if p.count < 64 {
        for (i, chunk) in out.chunks_mut(width.max(1)).enumerate() {
            f(i, chunk).py()?;
        }
        return Ok(out);
    }
    py.detach(|| out.par_chunks_mut(width.max(1)).enumerate().with_min_len(16).try_for_each(|(i, c)| f(i, c))).py()?;
    Ok(out)
}

#[pymethods]
impl PyDesign {
    /// Reads and validates a design file; keyword arguments replace keys of its `[fit]` or
    /// `[region]` section (`max_elements=8`, `radius=1.5`).
    #[staticmethod]
    #[pyo3(signature = (path, **overrides))]
    fn load(path: PathBuf, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<PyDesign> {
        let text = springfit::design::read_text(&path).py()?;
        PyDesign::new(&path, &text, overrides)
    }

    /// A design from the text of a design file; `path` names it in messages and anchors its
    /// relative paths (the catalogue), by default `design.toml` in the working directory.
    #[staticmethod]
    #[pyo3(signature = (text, path = None, **overrides))]
    fn from_toml(text: &str, path: Option<PathBuf>, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<PyDesign> {
        PyDesign::new(&path.unwrap_or_else(|| PathBuf::from("design.toml")), text, overrides)
    }

    /// The design's name (outputs are named after it).
    #[getter]
    fn name(&self) -> String {
        self.design.name.clone()
    }

    /// The file it was read from.
    #[getter]
    fn path(&self) -> PathBuf {
        self.design.path.clone()
    }

    /// Number of joints n.
    #[getter]
    fn dof(&self) -> usize {
        self.design.dof()
    }

    /// The joints' names.
    #[getter]
    fn joints(&self) -> Vec<String> {
        self.design.chain.joint_names()
    }

    /// The equilibrium q_eq, rad, shape (n,).
    #[getter]
    fn q_eq<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        shaped(py, self.design.q_eq.as_slice().to_vec(), false, self.design.dof(), &[])
    }

    /// The warnings the command line prints on stderr for this design.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    /// The names of the design's `[[scenario]]` tables.
    #[getter]
    fn scenarios(&self) -> Vec<String> {
        self.design.scenarios.iter().map(|s| s.name.clone()).collect()
    }

    /// The `[controllers]` settings as a dict.
    #[getter]
    fn controllers<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json(py, &self.design.controllers)
    }

    /// The `[simulate]` settings as a dict (`rate`, the RK4 step rate in Hz, and the rest).
    #[getter]
    fn simulate_settings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json(py, &self.design.simulate)
    }

    /// What `springfit check --json` prints: dof, joints, q_eq, mass_matrix and gravity_torque
    /// (at q_eq) as arrays, region (the region check) as a dict. With `strict` (default) an
    /// invalid region raises the command's error after the check.
    #[pyo3(signature = (strict = true))]
    fn check<'py>(&self, py: Python<'py>, strict: bool) -> PyResult<Bound<'py, PyDict>> {
        let d = self.design.clone();
        let report = py.detach(|| d.region_report()).py()?;
        let n = d.dof();
        let out = PyDict::new(py);
        out.set_item("design", &d.name)?;
        out.set_item("dof", n)?;
        out.set_item("joints", d.chain.joint_names())?;
        out.set_item("q_eq", shaped(py, d.q_eq.as_slice().to_vec(), false, n, &[])?)?;
        let m = d.chain.mass_matrix(&d.q_eq);
        let rows: Vec<f64> = (0..n * n).map(|k| m[(k / n, k % n)]).collect();
        out.set_item("mass_matrix", shaped(py, rows, false, n, &[n])?)?;
        let g = d.chain.gravity_gradient(d.q_eq.as_slice());
        out.set_item("gravity_torque", shaped(py, g.as_slice().to_vec(), false, n, &[])?)?;
        out.set_item("region", json(py, &report)?)?;
        if strict {
            d.ensure_valid(&report).py()?;
        }
        Ok(out)
    }

    /// M(q), shape (n, n) or (N, n, n).
    fn mass_matrix<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let p = self.rows(q, "q")?;
        let (d, n) = (&self.design, self.design.dof());
        let out = map_rows(py, &p, n * n, |i, o| {
            let m = d.chain.mass_matrix(&DVector::from_column_slice(p.row(i)));
            for k in 0..n * n {
                o[k] = m[(k / n, k % n)];
            }
            Ok(())
        })?;
        shaped(py, out, p.single, p.count, &[n, n])
    }

    /// U_g(q), J, shape () or (N,).
    fn gravity_potential<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let p = self.rows(q, "q")?;
        let d = &self.design;
        let out = map_rows(py, &p, 1, |i, o| {
            o[0] = d.chain.gravity_potential(p.row(i));
            Ok(())
        })?;
        shaped(py, out, p.single, p.count, &[])
    }

    /// ∂U_g/∂q, N·m (the gravity torque is its negative), shape (n,) or (N, n).
    fn gravity_gradient<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let p = self.rows(q, "q")?;
        let (d, n) = (&self.design, self.design.dof());
        let out = map_rows(py, &p, n, |i, o| {
            d.chain.gravity_gradient_into(p.row(i), o);
            Ok(())
        })?;
        shaped(py, out, p.single, p.count, &[n])
    }

    /// q̈ of M(q) q̈ + C(q, q̇) q̇ = τ for the total joint torque τ (springs, gravity, damping and
    /// motors), the solve the simulator makes: shape (n,) or (N, n).
    fn acceleration<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        qdot: &Bound<'py, PyAny>,
        tau: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let p = self.rows(q, "q")?;
        let v = self.rows(qdot, "qdot")?;
        let t = self.rows(tau, "tau")?;
        if v.count != p.count || t.count != p.count {
            return Err(setting(
                "qdot",
                format!("q, qdot and tau need the same number of rows ({}, {}, {})", p.count, v.count, t.count),
            ));
        }
        let (d, n) = (&self.design, self.design.dof());
        let out = map_rows(py, &p, n, |i, o| {
            let mut ws = d.chain.workspace();
            if d.chain.acceleration(&mut ws, p.row(i), v.row(i), t.row(i), o) {
                Ok(())
            } else {
                Err(Error::numerical(
                    "acceleration",
                    format!("the mass matrix is not positive definite at q = {:?}", p.row(i)),
                ))
            }
        })?;
        shaped(py, out, p.single, p.count, &[n])
    }

    /// exp(v): the point reached at arc length |v|_M along the geodesic from q_eq with initial
    /// velocity v/|v|_M; shape (n,) or (N, n).
    fn exp<'py>(&self, py: Python<'py>, v: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let p = self.rows(v, "v")?;
        let (d, n) = (&self.design, self.design.dof());
        let out = map_rows(py, &p, n, |i, o| {
            let mut shooter = Shooter::new(&d.chain, &d.q_eq, d.geodesics.ode);
            let q = shooter.exp(&DVector::from_column_slice(p.row(i)))?;
            o.copy_from_slice(q.as_slice());
            Ok(())
        })?;
        shaped(py, out, p.single, p.count, &[n])
    }

    /// log(q): the v with exp(v) = q (Newton shooting from the second-order guess, each point on
    /// its own); shape (n,) or (N, n).
    fn log<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let p = self.rows(q, "q")?;
        let (d, n) = (&self.design, self.design.dof());
        let log = LogMap::new(&d.chain, &d.q_eq, d.geodesics.ode, LogSettings::default());
        let out = map_rows(py, &p, n, |i, o| {
            let lp = log.log(&DVector::from_column_slice(p.row(i)))?;
            o.copy_from_slice(lp.v.as_slice());
            Ok(())
        })?;
        shaped(py, out, p.single, p.count, &[n])
    }

    /// r(q) = |log(q)|_M, the Riemannian distance from q_eq; shape () or (N,).
    fn distance<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let p = self.rows(q, "q")?;
        let d = &self.design;
        let log = LogMap::new(&d.chain, &d.q_eq, d.geodesics.ode, LogSettings::default());
        let out = map_rows(py, &p, 1, |i, o| {
            o[0] = log.log(&DVector::from_column_slice(p.row(i)))?.r;
            Ok(())
        })?;
        shaped(py, out, p.single, p.count, &[])
    }

    /// The mode label θ(q) = 2·atan2(v₂, v₁) of v = log(q), wrapped to (−π, π] (two joints);
    /// shape () or (N,).
    fn label<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let (theta, _) = self.labels(py, q)?;
        let p = self.rows(q, "q")?;
        shaped(py, theta, p.single, p.count, &[])
    }

    /// ∂θ/∂q, the exact gradient of the mode label (two joints); shape (2,) or (N, 2).
    fn label_gradient<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let (_, grad) = self.labels(py, q)?;
        let p = self.rows(q, "q")?;
        shaped(py, grad, p.single, p.count, &[2])
    }

    /// Fits the springs from the design's catalogue as `springfit fit` does (with the as-built
    /// builds), or evaluates the exact potential ½ω²r² with `exact`. `solver` ("nnls" or "qp")
    /// and `max_elements` override the design's, like the command's options. Runs without the
    /// GIL; `progress(stage)` is called at each stage.
    #[pyo3(signature = (exact = false, solver = None, max_elements = None, progress = None))]
    fn fit(
        &self,
        py: Python<'_>,
        exact: bool,
        solver: Option<&str>,
        max_elements: Option<usize>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<crate::fit::PyFit> {
        crate::fit::PyFit::run(py, self, exact, solver, max_elements, progress)
    }

    /// Runs the design's scenarios (or the one named) in closed loop as `springfit simulate`
    /// does, with `springs` (a Fit, a Potential or a bom.csv path; default: fit them now) or the
    /// exact potential; `exact_label` uses the log map instead of the table.
    #[pyo3(signature = (scenario = None, springs = None, exact = false, exact_label = false, progress = None))]
    fn simulate(
        &self,
        py: Python<'_>,
        scenario: Option<&str>,
        springs: Option<&Bound<'_, PyAny>>,
        exact: bool,
        exact_label: bool,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<crate::simulate::PySimulation> {
        crate::simulate::PySimulation::run(py, self, scenario, springs, exact, exact_label, progress)
    }

    /// The sensitivity sweeps of `springfit sweep` (parasitic springs, manufacturing tolerance,
    /// stock rates) in one process; `builds` and `seed` override `[sweep]` like the command's
    /// options. Releases the GIL; `progress` is called as the items finish.
    #[pyo3(signature = (builds = None, seed = None, progress = None))]
    fn sweep(
        &self,
        py: Python<'_>,
        builds: Option<usize>,
        seed: Option<u64>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<crate::sweep::PySweep> {
        crate::sweep::PySweep::run(py, self, builds, seed, progress)
    }

    /// Writes the MuJoCo model of the arm with `springs` (a Fit or a bom.csv path; default: fit
    /// them now) into `folder`, as `springfit export --mujoco` does: `<name>.xml`, `elements.md`,
    /// `bom.csv`. Returns the model file's path.
    #[pyo3(signature = (folder, springs = None, overwrite_edits = false, progress = None))]
    fn export_mujoco(
        &self,
        py: Python<'_>,
        folder: PathBuf,
        springs: Option<&Bound<'_, PyAny>>,
        overwrite_edits: bool,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<PathBuf> {
        use springfit::jobs::export::{self, ExportSprings};
        use springfit::report::output::{Edits, Plan};
        let d = self.design.clone();
        let edits = if overwrite_edits { Edits::Overwrite } else { Edits::Refuse };
        let plan = Plan::new("export", export::files(&d)).with_edits(edits).for_design(&d);
        let claim = springfit::report::output::check(&folder, &plan).py()?;
        let path: PathBuf;
        let springs = match springs {
            Some(s) => match s.cast::<crate::fit::PyFit>() {
                Ok(fit) => ExportSprings::Fitted(&fit.get().run.outcome),
                Err(_) => {
                    path = s
                        .extract()
                        .map_err(|_| setting("springs", "must be a springfit.Fit or the path of a bom.csv"))?;
                    ExportSprings::Bom(&path)
                }
            },
            None => ExportSprings::Fit(self.catalog_or("the design names no spring catalogue; give springs")?),
        };
        let progress = crate::progress::Progress::new(progress);
        let run = py.detach(|| export::export(&d, springs, progress.observer()));
        progress.raised()?;
        let run = run.map_err(|e| crate::errors::in_design(e, &d.path))?;
        let (_, written) = py.detach(|| run.write(&d, claim)).py()?;
        Ok(written.join(format!("{}.xml", d.name)))
    }

    /// Offsets and trim rates for the built arm from its measured rates, as `springfit tune`
    /// computes them: `measured` is the fit's bom.csv with a `measured_stiffness` column. Returns
    /// `tune.json` as a dict, with the tuned bill's CSV text under `bom_tuned_csv`.
    fn tune<'py>(&self, py: Python<'py>, measured: PathBuf) -> PyResult<Bound<'py, PyAny>> {
        let d = self.design.clone();
        let run = py
            .detach(|| springfit::jobs::tune::tune(&d, &measured, springfit::progress::Progress::none()))
            .map_err(|e| crate::errors::in_design(e, &d.path))?;
        let out = json(py, &run.outcome)?;
        out.set_item("bom_tuned_csv", springfit::files::bom::to_csv(&run.outcome.bom))?;
        Ok(out)
    }

    fn __repr__(&self) -> String {
        format!(
            "<springfit.Design {} ({} joints) from {}>",
            self.design.name,
            self.design.dof(),
            self.design.path.display()
        )
    }
}

impl PyDesign {
    /// θ and ∂θ/∂q for every row of `q`.
    fn labels(&self, py: Python<'_>, q: &Bound<'_, PyAny>) -> PyResult<(Vec<f64>, Vec<f64>)> {
        let p = self.rows(q, "q")?;
        let d = &self.design;
        if d.dof() != 2 {
            return Err(setting(
                "label",
                format!(
                    "the angle label θ is defined for two joints; this robot has {} (its modes are lines ±u in the metric frame)",
                    d.dof()
                ),
            ));
        }
        let log = LogMap::new(&d.chain, &d.q_eq, d.geodesics.ode, LogSettings::default());
        let both = map_rows(py, &p, 3, |i, o| {
            let lp = log.log(&DVector::from_column_slice(p.row(i)))?;
            let l = log.label(&lp)?;
            o[0] = l.theta;
            o[1] = l.gradient[0];
            o[2] = l.gradient[1];
            Ok(())
        })?;
        let theta = both.chunks(3).map(|c| c[0]).collect();
        let grad = both.chunks(3).flat_map(|c| [c[1], c[2]]).collect();
        Ok((theta, grad))
    }
}
