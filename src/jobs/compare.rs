//! `springfit compare` (and Python's `springfit.compare()`): fits side by side; `springfit
//! pareto`: the best residual per spring budget, per region size and per spring mass.
//!
//! The feature's files: the records and curves `studies/compare.rs`, a fit's folder read back
//! `files/fit_folder.rs`, the files written `report/compare.rs`, the command `cli/compare.rs`.

use std::path::{Path, PathBuf};

use crate::design::Design;
use crate::elements::catalog::Catalog;
use crate::error::{Error, Result};
use crate::progress::Progress;
use crate::report::output::Claim;
use crate::studies::compare::{
    BudgetPoint, FitRecord, MassCurve, RadiusPoint, Realised, budget_curve, disambiguate, mass_curve, radius_curve,
    record_of,
};

/// The record of a design fitted for a comparison (with the catalogue's fit as `springfit fit`
/// makes it, and its as-built brief); an infeasible fit's error names the key to change.
pub fn fitted(design: &Design, catalog: &Catalog, path: &Path, progress: Progress<'_>) -> Result<FitRecord> {
    progress.stage(&format!("fitting {}", path.display()));
    let outcome = super::fit::springs_of(design, catalog, &design.fit, Progress::none())
        .map_err(|e| crate::fit::hints::explain(design, &design.fit, catalog, design.fit.max_elements, e))?;
    let as_built = crate::asbuilt::of_fit(design, &outcome)?;
    let stock = crate::files::stock::of_design(design)?;
    let parts = crate::parts::of_fit(design, &outcome, design.fit.frequency, &stock)?;
    let mut r = record_of(&outcome, path);
    r.as_built = as_built.as_ref().map(crate::asbuilt::Brief::of);
    with_mass(&mut r, crate::report::mass::MassSummary::new(design, &outcome, Some(&parts)));
    Ok(r)
}

/// Puts the springs' mass and its ratio to the floor into a record (what `compare` shows beside
/// the residuals).
pub fn with_mass(r: &mut FitRecord, mass: Option<crate::report::mass::MassSummary>) {
    r.spring_mass_kg = mass.and_then(|m| m.spring_mass_kg);
    r.mass_over_floor = mass.and_then(|m| m.mass_over_floor);
}

/// The record of the exact potential ½ω²r² of `design` (read from `file`), labelled as the
/// reference.
pub fn exact(design: &Design, file: &Path, progress: Progress<'_>) -> Result<FitRecord> {
    progress.stage("evaluating the exact potential");
    let outcome = crate::fit::run::exact_reference(design, &design.fit, Progress::none())?;
    let mut r = record_of(&outcome, file);
    r.design = "exact ½ω²r²".to_string();
    r.label = r.design.clone();
    Ok(r)
}

/// The design file a comparison's exact reference comes from: the first the records name. The
/// field of the error is `exact`.
pub fn exact_file<'a>(files: impl IntoIterator<Item = Option<&'a Path>>) -> Result<PathBuf> {
    files.into_iter().flatten().next().map(Path::to_path_buf).ok_or_else(|| Error::Setting {
        field: "exact".into(),
        reason: "no input names its design file (fit folders of older springfit versions do not): add a design file"
            .into(),
    })
}

/// Refuses a comparison of no inputs, before anything is read or fitted. The field of the error
/// is `inputs`.
pub fn inputs(count: usize) -> Result<()> {
    if count == 0 {
        return Err(Error::Setting {
            field: "inputs".into(),
            reason: "give fit output folders or design files to compare".into(),
        });
    }
    Ok(())
}

/// Fits compared: their records with labels made unique.
#[derive(Debug, Clone)]
pub struct Comparison {
    /// One per fit, in the order given.
    pub records: Vec<FitRecord>,
}

impl Comparison {
    /// The comparison of `records` (fit folders read back, fits, the exact reference). The field
    /// of the error for none is `inputs`.
    pub fn new(mut records: Vec<FitRecord>) -> Result<Comparison> {
        inputs(records.len())?;
        disambiguate(&mut records);
        Ok(Comparison { records })
    }

    /// Writes `compare.csv`, `compare.md`, `compare.svg`/`.png` and `report.html` into the claimed
    /// folder.
    pub fn write(&self, claim: Claim) -> Result<PathBuf> {
        crate::report::compare::write_compare_folder(claim, &self.records)
    }
}

/// What `pareto` is asked beyond the design.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ParetoRequest {
    /// The largest budget (default: the design's `max_elements`, at least 16).
    pub k_max: Option<usize>,
    /// The radii of the region-size curve (default: [`DEFAULT_RADII`] up to the largest valid
    /// radius).
    pub radii: Option<Vec<f64>>,
    /// The curves to draw (default: [`ParetoAxis::DEFAULT`], budget and radius).
    pub axes: Option<Vec<ParetoAxis>>,
    /// The mass budgets of the mass curve, kg (default: [`crate::studies::compare::DEFAULT_MASSES`]
    /// from the floor to the unconstrained fit's mass).
    pub masses: Option<Vec<f64>>,
}

/// A curve of `pareto`: what is varied against the residual.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParetoAxis {
    /// The element budget K = 2 … K_max.
    Budget,
    /// The geodesic-ball radius, at the design's element budget.
    Radius,
    /// The spring-mass budget `max_spring_mass`, at the design's element budget, with each
    /// point's parts chosen (their realised mass beside the model's).
    Mass,
}

impl ParetoAxis {
    /// The curves drawn when none are asked: the two that need no parts chosen (the mass curve
    /// chooses every point's parts and takes about as long again, so it is asked for).
    pub const DEFAULT: [ParetoAxis; 2] = [ParetoAxis::Budget, ParetoAxis::Radius];
}

/// Number of radii of the default region-size curve.
pub const DEFAULT_RADII: usize = 8;

/// The largest budget `pareto` accepts.
const MOST_BUDGETS: usize = 1000;

/// A Pareto study checked and ready to run.
#[derive(Debug)]
pub struct ParetoJob<'a> {
    design: &'a Design,
    catalog: &'a Catalog,
    k_max: usize,
    radii: Option<Vec<f64>>,
    axes: Vec<ParetoAxis>,
    masses: Option<Vec<f64>>,
}

impl<'a> ParetoJob<'a> {
    /// Checks `request` against `design` and its validated `catalog`. The fields of the errors
    /// are `k_max`, `radii[i]`, `masses[i]` (a mass below the floor is refused here, before any
    /// work, where the region is a ball) and `axes`.
    pub fn new(design: &'a Design, catalog: &'a Catalog, request: ParetoRequest) -> Result<ParetoJob<'a>> {
        let k_max = request.k_max.unwrap_or(design.fit.max_elements.max(16));
        if k_max < 2 {
            return Err(Error::Setting { field: "k_max".into(), reason: "must be at least 2".into() });
        }
        if k_max > MOST_BUDGETS {
            return Err(Error::Setting {
                field: "k_max".into(),
                reason: format!("at most {MOST_BUDGETS}, got {k_max}"),
            });
        }
        for (i, r) in request.radii.iter().flatten().enumerate() {
            if !(r.is_finite() && *r > 0.0) {
                return Err(Error::Setting {
                    field: format!("radii[{i}]"),
                    reason: format!("must be a positive geodesic-ball radius, got {r}"),
                });
            }
        }
        let axes = request.axes.unwrap_or_else(|| ParetoAxis::DEFAULT.to_vec());
        if axes.is_empty() {
            return Err(Error::Setting {
                field: "axes".into(),
                reason: "give at least one of budget, radius, mass".into(),
            });
        }
        for (field, given, axis, name) in [
            ("radii", request.radii.is_some(), ParetoAxis::Radius, "radius"),
            ("masses", request.masses.is_some(), ParetoAxis::Mass, "mass"),
        ] {
            if given && !axes.contains(&axis) {
                return Err(Error::Setting {
                    field: field.into(),
                    reason: format!(
                        "set the points of the {name} curve, which the axes asked do not include: add {name} to the axes"
                    ),
                });
            }
        }
        if let Some(masses) = &request.masses {
            if masses.is_empty() {
                return Err(Error::Setting { field: "masses".into(), reason: "give at least one mass".into() });
            }
            let floor = crate::fit::mass::Floor::before_work(design, design.fit.frequency);
            for (i, m) in masses.iter().enumerate() {
                if !(m.is_finite() && *m > 0.0) {
                    return Err(Error::Setting {
                        field: format!("masses[{i}]"),
                        reason: format!("must be a positive spring mass in kg, got {m}"),
                    });
                }
                if let Some(f) = floor.filter(|f| *m < f.mass) {
                    return Err(Error::Setting {
                        field: format!("masses[{i}]"),
                        reason: format!(
                            "{m} kg is below the floor of {:.3} kg of {} (U* = ½ω²r² = {:.2} J over {:.3} MJ/m³ of steel: docs/parts.md, \"The floor\"): no springs that hold the potential are lighter",
                            f.mass,
                            design.path.display(),
                            f.energy,
                            f.density / 1e6
                        ),
                    });
                }
            }
        }
        Ok(ParetoJob { design, catalog, k_max, radii: request.radii, axes, masses: request.masses })
    }

    /// Checks the radii against the region (before any fit, so that a radius past the largest
    /// valid one is blamed on the radii, not on the design's `region.radius`), then fits every
    /// budget 2 … K on one preparation, the design's budget on every radius, and on every mass
    /// budget with its parts chosen: the curves asked, in that order.
    pub fn run(self, progress: Progress<'_>) -> Result<ParetoRun> {
        let (design, catalog) = (self.design, self.catalog);
        let wants = |a: ParetoAxis| self.axes.contains(&a);
        let radii = if wants(ParetoAxis::Radius) { radii(design, self.radii, progress)? } else { Vec::new() };
        let budgets = if wants(ParetoAxis::Budget) {
            let budgets: Vec<usize> = (2..=self.k_max).collect();
            progress.stage(&format!("budgets 2 … {}", self.k_max));
            budget_curve(design, catalog, &design.fit, &budgets, Progress::none())?
        } else {
            Vec::new()
        };
        let radii = if radii.is_empty() {
            Vec::new()
        } else {
            progress.stage("region sizes");
            radius_curve(design, catalog, &design.fit, &radii, Progress::none())?
        };
        let mass = if wants(ParetoAxis::Mass) {
            progress.stage("spring masses");
            let stock = crate::files::stock::of_design(design)?;
            let realise = |o: &crate::fit::FitOutcome| -> Result<Realised> {
                let parts = crate::parts::of_fit(design, o, o.settings.frequency, &stock)?;
                let m = crate::report::mass::MassSummary::new(design, o, Some(&parts));
                Ok(Realised {
                    spring_mass_kg: m.and_then(|m| m.spring_mass_kg),
                    without_part: parts.missing().count(),
                    stored_energy_over_potential: m.map_or(f64::NAN, |m| m.stored_energy_over_potential),
                    preload_total_nm: m.map_or(f64::NAN, |m| m.preload_total_nm),
                })
            };
            let arm = crate::report::mass::arm_mass(&design.chain);
            Some(mass_curve(design, catalog, &design.fit, self.masses.as_deref(), arm, &realise, progress)?)
        } else {
            None
        };
        Ok(ParetoRun { k_max: self.k_max, budgets, radii, mass })
    }
}

/// The radii of the region-size curve: the given ones, each checked against the largest valid
/// geodesic-ball radius, or [`DEFAULT_RADII`] evenly from 0.5 (less for small regions) up to the
/// largest valid radius.
fn radii(design: &Design, given: Option<Vec<f64>>, progress: Progress<'_>) -> Result<Vec<f64>> {
    let Some(radii) = given else {
        progress.stage("checking the region");
        let report = design.region_report()?;
        // A probed bound is itself valid; a conjugate point or a crossing is not: stay below.
        let top =
            if report.largest_radius_is_lower_bound { report.largest_radius } else { 0.98 * report.largest_radius };
        let top = (top * 100.0).floor() / 100.0;
        let start = 0.5_f64.min(top / 4.0);
        let mut radii: Vec<f64> = (0..DEFAULT_RADII)
            .map(|i| start + (top - start) * i as f64 / (DEFAULT_RADII - 1) as f64)
            .map(|r| (r * 100.0).round() / 100.0)
            .filter(|r| *r > 0.0 && *r <= top)
            .collect();
        radii.dedup();
        return Ok(radii);
    };
    let Some(top) = radii.iter().copied().reduce(f64::max) else {
        return Err(Error::Setting { field: "radii".into(), reason: "give at least one radius".into() });
    };
    let mut probe = design.clone();
    probe.region = crate::geodesic::Region::Ball { radius: top };
    progress.stage("checking the largest radius");
    let report = probe.region_report()?;
    if !report.valid {
        let i = radii.iter().position(|r| *r > report.largest_radius).unwrap_or(0);
        return Err(Error::Setting {
            field: format!("radii[{i}]"),
            reason: format!(
                "{} is past the largest valid geodesic-ball radius {:.4} of {}: {}",
                radii[i],
                report.largest_radius,
                design.path.display(),
                report.reason
            ),
        });
    }
    Ok(radii)
}

/// The Pareto curves of a design.
#[derive(Debug, Clone)]
pub struct ParetoRun {
    /// The largest budget.
    pub k_max: usize,
    /// The best residual per budget 2 … K (empty when not asked).
    pub budgets: Vec<BudgetPoint>,
    /// The residual per region radius (empty when not asked).
    pub radii: Vec<RadiusPoint>,
    /// The best residual per spring mass (None when not asked).
    pub mass: Option<MassCurve>,
}

impl ParetoRun {
    /// The error when no point of any curve has a feasible fit: nothing to plot. (The mass
    /// curve's top, the fit without a mass budget, is feasible whenever the curve exists: its
    /// failure is the run's error.)
    pub fn feasible(&self) -> Result<()> {
        let mass = self.mass.as_ref().is_some_and(|m| m.points.iter().any(|p| p.infeasible.is_none()));
        if self.budgets.iter().all(|b| b.infeasible.is_some())
            && self.radii.iter().all(|r| r.infeasible.is_some())
            && !mass
        {
            let last = self
                .budgets
                .last()
                .and_then(|b| b.infeasible.clone())
                .or_else(|| self.radii.last().and_then(|r| r.infeasible.clone()))
                .unwrap_or_default();
            return Err(Error::Infeasible {
                constraint: format!("every budget K = 2 … {} and every radius", self.k_max),
                reason: last,
            });
        }
        Ok(())
    }

    /// Writes `pareto.md`, `report.html`, and for the curves run `pareto.csv` with
    /// `pareto.svg`/`.png` (budget, radius) and `pareto_mass.csv`, `pareto_mass.json`,
    /// `pareto_mass.svg`/`.png` (mass) into the claimed folder.
    pub fn write(&self, design: &Design, claim: Claim) -> Result<PathBuf> {
        let dir = claim.open()?;
        crate::report::compare::write_pareto(
            &dir,
            &design.name,
            &self.budgets,
            &self.radii,
            self.mass.as_ref(),
            design.fit.max_elements,
        )?;
        crate::report::html::write_pareto(&dir, design)?;
        dir.commit()
    }
}
