//! Comparing designs: fit results side by side, and what accuracy a spring budget or a region
//! size costs.

use crate::csv::csv_field;
use crate::fit::bill::BomRow;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::design::Design;
use crate::design::fit::FitSettings;
use crate::dynamics::scenario::Savings;
use crate::elements::catalog::Catalog;
use crate::error::{Error, Result};
use crate::fit::run::fit;
use crate::fit::{FitOutcome, Prepared};
use crate::geodesic::Region;
use crate::progress::Progress;
use crate::residual::AngleStats;

/// One fit as the comparison sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct FitRecord {
    /// Legend and table label.
    pub label: String,
    /// Design name.
    pub design: String,
    /// Design file, if known.
    pub design_file: Option<PathBuf>,
    /// Catalogue name (`exact` for the reference).
    pub catalog: String,
    /// Solver (`exact` for the reference).
    pub solver: String,
    /// Springs used.
    pub used: usize,
    /// Residual statistics.
    pub stats: AngleStats,
    /// Every residual angle (degrees).
    pub angles: Vec<f64>,
    /// Total stiffness per unit.
    pub totals: Vec<(String, f64)>,
    /// Actuator share from a simulation of the same spring set, if one was found.
    pub actuator_share: Option<f64>,
    /// What the springs save on that simulation's run against the arm without them (with the
    /// actuator share; None where there is none, or the simulation predates savings).
    pub savings: Option<Savings>,
    /// Why there is no actuator share (no simulation folder, another spring set simulated).
    pub share_note: Option<String>,
    /// Where it came from (a folder or a design file).
    pub source: PathBuf,
    /// As-built p99 over builds (untrimmed and trimmed), if the fit has as-built figures.
    pub as_built: Option<crate::asbuilt::Brief>,
    /// The chosen springs' total mass, kg (None: no parts chosen, the exact reference, or a fit
    /// folder without it).
    pub spring_mass_kg: Option<f64>,
    /// `spring_mass_kg` over the floor ρ·U*/u of the design (docs/parts.md).
    pub mass_over_floor: Option<f64>,
}

/// The record of a fit just computed.
pub fn record_of(outcome: &FitOutcome, design_file: &Path) -> FitRecord {
    FitRecord {
        label: outcome.design.clone(),
        design: outcome.design.clone(),
        design_file: Some(design_file.to_path_buf()),
        catalog: outcome.catalog.clone(),
        solver: outcome.solve.solver.to_string(),
        used: outcome.used(),
        stats: outcome.metrics.stats,
        angles: outcome.metrics.residuals.iter().map(|r| r.angle_deg).collect(),
        totals: totals(&outcome.bom),
        actuator_share: None,
        savings: None,
        share_note: Some("fitted on the fly: no simulation of these springs".into()),
        source: design_file.to_path_buf(),
        as_built: None,
        spring_mass_kg: None,
        mass_over_floor: None,
    }
}

/// The summed stiffness of a bill per unit (`N*m/rad`, `N*m/rad^3`, …, in the unit's ASCII
/// spelling, sorted), since rates of different profiles cannot be added: [`FitRecord::totals`].
pub fn totals(rows: &[BomRow]) -> Vec<(String, f64)> {
    let mut units: Vec<&str> = rows.iter().map(|r| r.element.profile.unit()).collect();
    units.sort_unstable();
    units.dedup();
    units
        .iter()
        .map(|u| (u.to_string(), rows.iter().filter(|r| r.element.profile.unit() == *u).map(|r| r.stiffness).sum()))
        .collect()
}

/// Makes labels unique: records of the same design get their catalogue, solver and spring count.
pub fn disambiguate(records: &mut [FitRecord]) {
    let names: Vec<String> = records.iter().map(|r| r.design.clone()).collect();
    for r in records.iter_mut() {
        if names.iter().filter(|n| **n == r.design).count() > 1 {
            r.label = if r.solver == "exact" {
                format!("{} (exact)", r.design)
            } else {
                format!("{} ({}, {}, {} springs)", r.design, r.catalog, r.solver, r.used)
            };
        }
    }
    // Still equal (the same fit twice): number them.
    for i in 0..records.len() {
        let dup = (0..i).filter(|&j| records[j].label == records[i].label).count();
        if dup > 0 {
            records[i].label = format!("{} #{}", records[i].label, dup + 1);
        }
    }
}

/// The comparison table as CSV.
pub fn table_csv(records: &[FitRecord]) -> String {
    let mut s = String::from(
        "label,design,catalog,solver,springs,total_stiffness,median_abs_deg,p95_abs_deg,p99_abs_deg,max_abs_deg,actuator_share,as_built_p99_p50_deg,as_built_p99_p95_deg,trimmed_p99_p50_deg,trimmed_p99_p95_deg,energy_saved,peak_torque_saved,rms_torque_saved,copper_loss_saved,spring_mass_kg,mass_over_floor\n",
    );
    for r in records {
        let totals = r.totals.iter().map(|(u, t)| format!("{t} {u}")).collect::<Vec<_>>().join("; ");
        s.push_str(&format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
            csv_field(&r.label),
            csv_field(&r.design),
            csv_field(&r.catalog),
            r.solver,
            r.used,
            csv_field(&totals),
            r.stats.median_abs,
            r.stats.p95_abs,
            r.stats.p99_abs,
            r.stats.max_abs,
            r.actuator_share.map(|a| a.to_string()).unwrap_or_default(),
            as_built_csv(r.as_built.as_ref()),
            savings_csv(r.savings.as_ref()),
            r.spring_mass_kg.map(|m| m.to_string()).unwrap_or_default(),
            r.mass_over_floor.map(|m| m.to_string()).unwrap_or_default()
        ));
    }
    s
}

/// The four savings columns, fractions saved against the arm without springs (empty without a
/// simulation of the fit's springs).
fn savings_csv(v: Option<&Savings>) -> String {
    let f = |x: Option<f64>| x.map(|v| v.to_string()).unwrap_or_default();
    format!(
        "{},{},{},{}",
        f(v.map(|v| v.energy_saved)),
        f(v.map(|v| v.peak_torque_saved)),
        f(v.map(|v| v.rms_torque_saved)),
        f(v.map(|v| v.copper_loss_saved))
    )
}

/// The four as-built columns (empty when the fit has none, or where a percentile falls among
/// builds without a figure: never NaN or inf).
fn as_built_csv(b: Option<&crate::asbuilt::Brief>) -> String {
    let f = |x: Option<f64>| x.filter(|v| v.is_finite()).map(|v| v.to_string()).unwrap_or_default();
    format!(
        "{},{},{},{}",
        f(b.map(|b| b.p99_deg.p50)),
        f(b.map(|b| b.p99_deg.p95)),
        f(b.and_then(|b| b.trimmed_p99_deg).map(|t| t.p50)),
        f(b.and_then(|b| b.trimmed_p99_deg).map(|t| t.p95))
    )
}

/// "p50 / p95" of a spread in degrees ("beyond X°" for a percentile among builds without a
/// figure, never NaN or ∞), or "–".
pub fn spread_md(s: Option<crate::asbuilt::Spread>) -> String {
    s.map(|s| format!("{} / {}", s.text(s.p50, 3, "°"), s.text(s.p95, 3, "°"))).unwrap_or_else(|| "–".into())
}

/// "12.117 kg (74.8×)", or "–" without parts.
fn mass_md(r: &FitRecord) -> String {
    match (r.spring_mass_kg, r.mass_over_floor) {
        (Some(m), Some(f)) => format!("{m:.3} kg ({f:.1}×)"),
        (Some(m), None) => format!("{m:.3} kg"),
        _ => "–".into(),
    }
}

/// The comparison table as Markdown.
pub fn table_md(records: &[FitRecord]) -> String {
    let mut s = String::from(
        "# Design comparison\n\nResidual angles on each fit's held-out geodesics; actuator share from a simulation of the same springs (`<fit folder>_simulate`, scenario `sensitivity`, else `switch`) where one was run.\n\n| design | catalogue | solver | springs | total stiffness | median | p95 | p99 | max | spring mass (× floor) | actuator share | as built p99 (p50 / p95 over builds) | trimmed |\n| --- | --- | --- | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n",
    );
    for r in records {
        let totals = if r.totals.is_empty() {
            "–".to_string()
        } else {
            r.totals.iter().map(|(u, t)| format!("{t:.2} {}", crate::units::shown(u))).collect::<Vec<_>>().join(", ")
        };
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
            r.label.replace('|', "/"),
            r.catalog,
            r.solver,
            r.used,
            totals,
            crate::units::deg(r.stats.median_abs),
            crate::units::deg(r.stats.p95_abs),
            crate::units::deg(r.stats.p99_abs),
            crate::units::deg(r.stats.max_abs),
            mass_md(r),
            r.actuator_share.map(|a| format!("{:.3} %", 100.0 * a)).unwrap_or_else(|| "–".into()),
            spread_md(r.as_built.map(|b| b.p99_deg)),
            spread_md(r.as_built.and_then(|b| b.trimmed_p99_deg))
        ));
    }
    let notes: Vec<String> = records
        .iter()
        .filter_map(|r| r.share_note.as_ref().map(|n| format!("- {}: no actuator share: {n}", r.label)))
        .collect();
    if !notes.is_empty() {
        s.push_str(&format!("\nActuator shares are shown only from a simulation of the same spring set (the `spring_set` fingerprint of summary.json and sim_<name>.json):\n\n{}\n", notes.join("\n")));
    }
    if records.iter().any(|r| r.savings.is_some()) {
        s.push_str(&format!("\n## Savings against the arm without springs\n\nOn the same simulated run: the actuators' energy ∫|τᵀq̇| dt, peak and RMS torque and copper losses with the springs against the same motion driven without them, and the fraction saved.\n\n| design | {} |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: |\n", Savings::MD_HEADER));
        for r in records {
            if let Some(v) = &r.savings {
                s.push_str(&format!("| {} | {} |\n", r.label.replace('|', "/"), v.md_cells()));
            }
        }
    }
    s
}

/// A point of the accuracy-versus-budget curve.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BudgetPoint {
    /// The budget K.
    pub budget: usize,
    /// Springs the best set found uses (≤ K; 0 when infeasible).
    pub used: usize,
    /// Residual statistics (NaN when infeasible).
    pub stats: AngleStats,
    /// Why no set of at most K springs meets the fit's constraints (`None`: a set was found).
    pub infeasible: Option<String>,
    /// As-built p99 over builds at the design's tolerance (None without a tolerance).
    pub as_built: Option<crate::asbuilt::Brief>,
}

/// A point of the accuracy-versus-region curve.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RadiusPoint {
    /// Geodesic-ball radius.
    pub radius: f64,
    /// Springs used (0 when infeasible).
    pub used: usize,
    /// Residual statistics (NaN when infeasible).
    pub stats: AngleStats,
    /// Why the fit on this ball cannot meet its constraints (`None`: it can).
    pub infeasible: Option<String>,
}

/// Statistics of a point without a fit.
fn no_stats() -> AngleStats {
    AngleStats { median_abs: f64::NAN, p95_abs: f64::NAN, p99_abs: f64::NAN, max_abs: f64::NAN, count: 0 }
}

/// The best residual found for every budget in `budgets`, ascending (one preparation, one solve
/// per budget, and the as-built figures of each at the design's tolerance: see
/// [`best_as_built`]). "At most K springs" allows every smaller set, so when the search for K finds a
/// worse set (by p99) than for a smaller budget, that smaller set is reported for K too.
pub fn budget_curve(
    design: &Design,
    catalog: &Catalog,
    settings: &FitSettings,
    budgets: &[usize],
    progress: Progress<'_>,
) -> Result<Vec<BudgetPoint>> {
    let prepared = Prepared::new(design, catalog, settings, progress)?;
    let mut sorted = budgets.to_vec();
    sorted.sort_unstable();
    let mut best: Option<BudgetPoint> = None;
    let mut out = Vec::new();
    for k in sorted {
        progress.stage(&format!("budget {k}"));
        let here = match prepared.solve(&FitSettings { max_elements: k, ..*settings }, Progress::none()) {
            Ok(o) => {
                let as_built = crate::asbuilt::of_fit(design, &o)?.map(|a| crate::asbuilt::Brief::of(&a));
                BudgetPoint { budget: k, used: o.used(), stats: o.metrics.stats, infeasible: None, as_built }
            }
            // An infeasible budget is a point of the curve, not the end of it.
            Err(e @ Error::Infeasible { .. }) => {
                let reason = format!(
                    "{}: no set of at most {k} springs: {}",
                    design.path.display(),
                    crate::fit::hints::explain_infeasible(design, settings, catalog, k, e)
                );
                BudgetPoint { budget: k, used: 0, stats: no_stats(), infeasible: Some(reason), as_built: None }
            }
            Err(e) => return Err(e),
        };
        let point = match &best {
            Some(b) if here.infeasible.is_some() || b.stats.p99_abs < here.stats.p99_abs => {
                BudgetPoint { budget: k, ..b.clone() }
            }
            _ => here,
        };
        if point.infeasible.is_none() {
            best = Some(point.clone());
        }
        out.push(point);
    }
    Ok(out)
}

/// The budget whose set is best as built (smallest as-built p95 of the p99: the trimmed one when
/// the design has trims), if the curve has as-built figures.
pub fn best_as_built(points: &[BudgetPoint]) -> Option<&BudgetPoint> {
    let key = |b: &BudgetPoint| b.as_built.map(|a| a.trimmed_p99_deg.unwrap_or(a.p99_deg).p95);
    points
        .iter()
        .filter(|b| key(b).is_some())
        .min_by(|a, b| key(a).unwrap_or(f64::INFINITY).total_cmp(&key(b).unwrap_or(f64::INFINITY)))
}

/// The residual of the design's fit on geodesic balls of each radius in `radii`.
pub fn radius_curve(
    design: &Design,
    catalog: &Catalog,
    settings: &FitSettings,
    radii: &[f64],
    progress: Progress<'_>,
) -> Result<Vec<RadiusPoint>> {
    radii
        .iter()
        .map(|&r| {
            progress.stage(&format!("radius {r:.2}"));
            let mut d = design.clone();
            d.region = Region::Ball { radius: r };
            match fit(&d, catalog, settings, Progress::none()) {
                Ok(o) => Ok(RadiusPoint { radius: r, used: o.used(), stats: o.metrics.stats, infeasible: None }),
                Err(e @ Error::Infeasible { .. }) => Ok(RadiusPoint {
                    radius: r,
                    used: 0,
                    stats: no_stats(),
                    infeasible: Some(format!(
                        "{}: radius {r}: {}",
                        design.path.display(),
                        crate::fit::hints::explain_infeasible(design, settings, catalog, settings.max_elements, e)
                    )),
                }),
                Err(e) => Err(e),
            }
        })
        .collect()
}

/// What the part chooser makes of a fitted bill, for a point of the mass curve (filled in by the
/// caller, which chooses the parts: `jobs::compare`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Realised {
    /// The chosen parts' total mass, trims included, kg (None: no parts were chosen).
    pub spring_mass_kg: Option<f64>,
    /// Elements of the bill the chooser found no part for (their mass is missing from
    /// `spring_mass_kg`).
    pub without_part: usize,
    /// The elements' stored energy over U* (1: no element stores more than the potential needs).
    pub stored_energy_over_potential: f64,
    /// Σ |preload| at q_eq over the parts, N·m.
    pub preload_total_nm: f64,
}

/// A point of the accuracy-versus-mass curve.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MassPoint {
    /// The budget `max_spring_mass`, kg (None: the fit without a budget, the curve's top).
    pub max_spring_mass_kg: Option<f64>,
    /// Springs used (0 when infeasible).
    pub used: usize,
    /// Residual statistics (NaN, null in JSON, when infeasible).
    pub stats: AngleStats,
    /// The fit's own measure of the mass: Σ mᵢ(kᵢ) over the fitted springs by the mass model
    /// (`fit::mass`; trims, which the fit does not weigh, left out), kg: what the budget bounds.
    pub model_mass_kg: Option<f64>,
    /// The parts chosen for the bill (None when infeasible).
    pub realised: Option<Realised>,
    /// Why no set meets the fit's constraints within this mass (`None`: a set was found).
    pub infeasible: Option<String>,
}

/// The point of budget `m` (kg) where no set was fitted, and `why`.
fn no_set(m: f64, why: String) -> MassPoint {
    MassPoint {
        max_spring_mass_kg: Some(m),
        used: 0,
        stats: no_stats(),
        model_mass_kg: None,
        realised: None,
        infeasible: Some(why),
    }
}

/// The best residual per spring mass, from the floor to the mass of the fit without a budget.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MassCurve {
    /// The design's name.
    pub design: String,
    /// The budget of elements every point is fitted with (`max_elements`, 0: none).
    pub max_elements: usize,
    /// The floor ρ·U*/u, kg: no layout is lighter (docs/parts.md, "The floor").
    pub floor_kg: f64,
    /// U* = ½ω²r² at the region's boundary, J.
    pub potential_energy_j: f64,
    /// The arm's moving mass, kg.
    pub arm_mass_kg: f64,
    /// The budgets ascending, then the fit without one (the last point).
    pub points: Vec<MassPoint>,
}

/// Default number of mass budgets between the floor and the unconstrained fit's mass.
pub const DEFAULT_MASSES: usize = 8;

/// The mass budgets of the default curve: `n` evenly from the floor up to (not including) the
/// unconstrained fit's model mass `top`. Evenly in mass, not in log: on the default design every
/// budget under 3.4× the floor is infeasible (the Hessian match needs that much steel) and the
/// residual falls from 3° to 0.37° over the top third (2.8 to 4.2 kg), so the points belong where
/// the mass is spent. Rounded up to 4 significant digits so the table and the file read the same
/// number.
pub fn default_masses(floor: f64, top: f64, n: usize) -> Vec<f64> {
    if !(floor > 0.0 && top > floor) {
        return Vec::new();
    }
    let round = |m: f64| {
        let scale = 10f64.powi(3 - m.log10().floor() as i32);
        (m * scale).ceil() / scale
    };
    let mut masses: Vec<f64> =
        (0..n).map(|i| round(floor + (top - floor) * i as f64 / n as f64)).filter(|m| *m < top).collect();
    masses.dedup();
    masses
}

/// The model mass Σ mᵢ(kᵢ) of a fitted bill's springs (trims aside: the fit does not weigh them),
/// by the same mass model the fit's term and budget use (`fit::mass`: each candidate's mass per
/// unit stiffness is read off its own coupling's duty, so the bill's rows alone give the same cᵢ
/// as the preparation's candidates).
pub fn model_mass(design: &Design, o: &FitOutcome) -> f64 {
    let rows: Vec<&BomRow> = o.bom.iter().filter(|r| r.adjust.trim_range.is_none()).collect();
    let candidates: Vec<crate::elements::catalog::Candidate> =
        rows.iter().map(|r| crate::elements::catalog::Candidate::bare(r.element.clone())).collect();
    let model = crate::fit::mass::MassModel::new(design, &candidates, &o.evaluation, o.settings.frequency);
    rows.iter().enumerate().map(|(i, r)| model.mass_at(i, r.stiffness)).sum()
}

/// The best residual per spring mass: one preparation; the fit without a mass budget (the
/// curve's top, its model mass the heaviest budget worth asking), then one fit per budget
/// `max_spring_mass` in `masses` (default: [`default_masses`] from the floor), each with the
/// design's element budget. `realise` chooses each point's parts (the caller's: parts sit above
/// the studies). As for the budget curve, a budget allows every lighter set, so where a budget's
/// search finds a worse set (by p99) than a smaller budget's, the smaller one's is reported for it
/// too. Points are fitted one after another, each solve deterministic, so the curve is the same
/// whatever the thread count.
pub fn mass_curve(
    design: &Design,
    catalog: &Catalog,
    settings: &FitSettings,
    masses: Option<&[f64]>,
    arm_mass_kg: f64,
    realise: &dyn Fn(&FitOutcome) -> Result<Realised>,
    progress: Progress<'_>,
) -> Result<MassCurve> {
    let mut prepared = Prepared::new(design, catalog, settings, progress)?;
    progress.stage("mass: the fit without a budget");
    let free = prepared.solve(&FitSettings { max_spring_mass: 0.0, ..*settings }, Progress::none())?;
    let floor = crate::fit::mass::Floor::on(design, settings.frequency, &free.evaluation);
    let top = model_mass(design, &free);
    let mut budgets = match masses {
        Some(m) => m.to_vec(),
        None => default_masses(floor.mass, top, DEFAULT_MASSES),
    };
    budgets.sort_by(f64::total_cmp);
    let point = |o: &FitOutcome, budget: Option<f64>| -> Result<MassPoint> {
        Ok(MassPoint {
            max_spring_mass_kg: budget,
            used: o.used(),
            stats: o.metrics.stats,
            model_mass_kg: Some(model_mass(design, o)),
            realised: Some(realise(o)?),
            infeasible: None,
        })
    };
    let mut out = Vec::new();
    let mut best: Option<MassPoint> = None;
    for m in budgets {
        progress.stage(&format!("mass: at most {m} kg"));
        let within = FitSettings { max_spring_mass: m, ..*settings };
        prepared.hold_budget_on_lightest_cranks();
        let mut solved = prepared.solve(&within, Progress::none()).and_then(|o| point(&o, Some(m)));
        // Parts that break the budget (the chooser rebuilt cranks within the rollers' bound):
        // solved again with the budget held on those cranks, as `fit` does
        // (`parts::fit_with_parts`), so that each point's parts are within its budget.
        let over =
            |p: &MassPoint| p.realised.as_ref().and_then(|r| r.spring_mass_kg).is_some_and(|kg| kg > m * (1.0 + 1e-9));
        if solved.as_ref().is_ok_and(over) && prepared.hold_budget_on_bounded_cranks() {
            solved = prepared.solve(&within, Progress::none()).and_then(|o| point(&o, Some(m)));
        }
        let here = match solved {
            Ok(p) => p,
            // An infeasible budget is a point of the curve, not the end of it.
            Err(e @ Error::Infeasible { .. }) => no_set(
                m,
                format!(
                    "{}: no set within {m} kg: {}",
                    design.path.display(),
                    crate::fit::hints::explain_infeasible(design, settings, catalog, settings.max_elements, e)
                ),
            ),
            // So is a budget whose refits the solver cannot finish (Clarabel stopping at its
            // iteration limit on the within-budget refits): a lighter budget's set, when there is
            // one, is within this budget too and is reported for it, as for an infeasible one.
            Err(e @ Error::Numerical { .. }) => {
                no_set(m, format!("{}: the solver failed within {m} kg: {e}", design.path.display()))
            }
            Err(e) => return Err(e),
        };
        let chosen = match &best {
            Some(b) if here.infeasible.is_some() || b.stats.p99_abs < here.stats.p99_abs => {
                MassPoint { max_spring_mass_kg: Some(m), ..b.clone() }
            }
            _ => here,
        };
        if chosen.infeasible.is_none() {
            best = Some(chosen.clone());
        }
        out.push(chosen);
    }
    progress.stage("mass: the parts of the fit without a budget");
    out.push(point(&free, None)?);
    Ok(MassCurve {
        design: design.name.clone(),
        max_elements: settings.max_elements,
        floor_kg: floor.mass,
        potential_energy_j: floor.energy,
        arm_mass_kg,
        points: out,
    })
}
