//! Identification of a built arm from its own motion: the rate error of every spring and cam,
//! the joint damping and the Coulomb friction, from logged joint angles (and motor torques when
//! the arm is driven), with their standard errors and what the logs cannot tell apart.
//!
//! The pipeline, one module per step:
//!
//! 1. the logs are read (`files::log`) and every sample checked against the region
//!    ([`region`]);
//! 2. each run's angles are smoothed, the equation of motion is written linear in the unknowns and
//!    both of its sides are low-passed with one zero-phase filter ([`filter`], [`regression`]);
//! 3. least squares with the Newey–West covariance, the condition and the groups of rates the
//!    logs cannot tell apart ([`estimate`]);
//! 4. the rates the identified δ give, for `tune` ([`Identification::measured`]).
//!
//! [`plan`] proposes releases that make every rate identifiable before anything is logged.
//!
//! The feature's files outside this folder: the settings `design/identify.rs`, the logs
//! `files/log.rs`, the files written `report/identify.rs`, the job that runs it all
//! [`crate::jobs::identify`] and the command `cli/identify.rs`.

pub mod estimate;
pub mod filter;
pub mod log;
pub mod plan;
pub mod region;
pub mod regression;
pub mod swing;

use std::path::Path;

use serde::Serialize;

use crate::design::Design;
use crate::design::identify::IdentifySettings;
use crate::error::{Error, Result};
use crate::fit::bill::BomRow;
use crate::potential::Potential;
use estimate::{Combination, Estimate};
use log::{Log, Run};
use regression::{Filters, Model, Rows, Unknown};

/// What the logs say about one part's rate.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// δ identified on its own (standard error within the bound).
    Identified,
    /// In a group of rates the logs cannot tell apart (an index into the groups).
    Group(usize),
}

/// Where the rate `tune` gets for a part comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Source {
    /// Its own δ, identified.
    Measured,
    /// Inferred from its group's identified combinations (the smallest δ that has their values).
    Combination,
    /// As designed: the logs fix nothing about it.
    AsDesigned,
}

impl Source {
    /// The word `identified_parts.csv` and the reports use.
    pub fn word(self) -> &'static str {
        match self {
            Source::Measured => "measured",
            Source::Combination => "combination",
            Source::AsDesigned => "as designed",
        }
    }
}

/// The estimate of one part's rate error.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RateEstimate {
    /// The bill's id (`S01`, or `C01` for a cam).
    pub id: String,
    /// Its catalogue family.
    pub family: String,
    /// Whether it is a trim spring (estimated unless `trims = "known"`).
    pub trim: bool,
    /// Its rows in the bill of materials.
    #[serde(skip)]
    pub rows: Vec<usize>,
    /// δ, the rate error as a fraction of the design rate (least squares; not meaningful when
    /// not identified; NaN, `null` in the JSON, when unidentified).
    #[serde(serialize_with = "finite_or_null")]
    pub delta: f64,
    /// Standard error of δ (infinite, `null` in the JSON: the logs carry nothing about it
    /// alone, or it is unidentified).
    #[serde(serialize_with = "finite_or_null")]
    pub standard_error: f64,
    /// Why the rate is unidentified, when it is (None: δ and its standard error are figures):
    /// not estimable, or a standard error of at least
    /// [`estimate::UNIDENTIFIED_STANDARD_ERROR`] of the rate.
    pub unidentified: Option<String>,
    /// Identified, or in which group.
    pub status: Status,
    /// The δ `tune` gets (identified: as estimated; in a group: reduced to the group's
    /// identified combinations).
    pub for_tuning: f64,
    /// Where that δ comes from.
    pub source: Source,
    /// rms over the logs of the torque a change δ = 1 would make, N·m.
    pub torque_rms_nm: f64,
}

/// Rates the logs cannot tell apart, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RateGroup {
    /// The parts' ids.
    pub members: Vec<String>,
    /// Why, in words.
    pub reason: String,
    /// Combinations of their δ the logs do fix: (id, weight) and value ± standard error.
    pub identified: Vec<CombinationReport>,
}

/// An identified combination Σ wᵢ δᵢ.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CombinationReport {
    /// (part id, wᵢ): the weights sum to 1 when they share a sign, else the largest is ±1.
    pub weights: Vec<(String, f64)>,
    /// The combination's estimate Σ wᵢ δᵢ, a fraction of the design rates.
    pub value: f64,
    /// Its standard error, same unit.
    pub standard_error: f64,
}

/// A joint's damping and friction estimates (None where not estimated).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JointEstimate {
    /// `q1`, `q2`, …
    pub joint: String,
    /// Viscous damping and its standard error, N·m·s/rad.
    pub damping: Option<Value>,
    /// Coulomb friction and its standard error, N·m.
    pub friction: Option<Value>,
}

/// An estimate with its standard error (infinite: not estimable from these logs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Value {
    /// The estimate, in the unit of the quantity (N·m·s/rad for damping, N·m for friction).
    pub value: f64,
    /// Its standard error, same unit (`null` in `identify.json` when infinite).
    #[serde(serialize_with = "finite_or_null")]
    pub standard_error: f64,
}

/// One run as used.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunSummary {
    /// The log file.
    pub file: String,
    /// The run's name (empty: the whole file).
    pub run: String,
    /// Logged samples in the run.
    pub samples: usize,
    /// The run's length, s.
    pub seconds: f64,
    /// Its sample rate, 1/Δt, Hz.
    pub rate_hz: f64,
    /// Whether motor torques were logged.
    pub driven: bool,
    /// Regression rows it gave (one per kept sample and joint).
    pub rows: usize,
}

/// Torques on one run for the plots: what the motion says the elements, damping and friction
/// exerted, what the identified model predicts and what the design would have, all through L.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TorqueTrace {
    /// The log's file name, with `, run NAME` when the file holds several runs.
    pub run: String,
    /// Times of the kept samples in the log's clock, s: the run's first 10 s of rows.
    pub t: Vec<f64>,
    /// Per joint, at `t`: the torque the motion shows the elements, damping and friction
    /// exerted (the regression's y plus the designed torque), N·m.
    pub measured: Vec<Vec<f64>>,
    /// Per joint: the same as the identified model predicts it (Φθ plus the designed torque), N·m.
    pub predicted: Vec<Vec<f64>>,
    /// Per joint: the elements' torque as designed, L[−Σ kᵢ ∇uᵢ] (every δ = 0), N·m.
    pub designed: Vec<Vec<f64>>,
}

/// The outcome of `identify`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Identification {
    /// Cut-off of the regression's low-pass L, Hz.
    pub cutoff_hz: f64,
    /// Cut-off of the encoder smoothing, Hz.
    pub smoothing_hz: f64,
    /// The bound on a rate's standard error for it to count as identified.
    pub max_standard_error: f64,
    /// Every run of the logs as used, in the order given.
    pub runs: Vec<RunSummary>,
    /// Regression rows (one per kept sample and joint).
    pub rows: usize,
    /// Unknowns: a δ per part, then each joint's damping and friction where the settings
    /// estimate them.
    pub unknowns: usize,
    /// Rank of the regression.
    pub rank: usize,
    /// Condition number of the regression with its columns scaled to unit length (infinite,
    /// `null` in `identify.json`, when the rank is short).
    #[serde(serialize_with = "finite_or_null")]
    pub condition: f64,
    /// rms of the regression residual per joint, N·m.
    pub residual_rms_nm: Vec<f64>,
    /// rms of the elements' designed torque per joint, N·m: the scale the residual compares to.
    pub torque_rms_nm: Vec<f64>,
    /// Per part of the bill (a cam once): its δ, standard error and status.
    pub rates: Vec<RateEstimate>,
    /// The groups of rates the logs cannot tell apart (`rates[i].status` points into it).
    pub groups: Vec<RateGroup>,
    /// Per joint: damping and friction.
    pub joints: Vec<JointEstimate>,
    /// Per row of the bill: the rate to write as `measured_stiffness` (None: as designed).
    #[serde(skip)]
    pub measured: Vec<Option<f64>>,
    /// The torques of the longest run for `identify_torque.svg` (None: no rows).
    #[serde(skip)]
    pub trace: Option<TorqueTrace>,
}

fn finite_or_null<S: serde::Serializer>(x: &f64, s: S) -> std::result::Result<S::Ok, S::Error> {
    if x.is_finite() { s.serialize_f64(*x) } else { s.serialize_none() }
}

impl Identification {
    /// Number of parts whose rate is identified on its own.
    pub fn identified_count(&self) -> usize {
        self.rates.iter().filter(|r| r.status == Status::Identified).count()
    }
}

/// Checks that a bill of materials belongs to the design: as many joints, and its elements hold
/// the design's equilibrium (a bill of another design does not).
pub fn check_bill(design: &Design, bom_path: &Path, bom: &[BomRow]) -> Result<()> {
    let n = design.dof();
    if let Some(r) = bom.iter().find(|r| r.element.coupling.len() != n) {
        return Err(Error::invalid(
            bom_path,
            "coupling",
            format!("{}: the elements act on {} joints but the design's robot has {n}", r.id, r.element.coupling.len()),
        ));
    }
    let q = design.q_eq.as_slice();
    let set = crate::fit::bill::spring_set(bom);
    let g = set.grouped().gradient(q)? + design.chain.gravity_gradient(q);
    let scale: f64 =
        set.element_torques(q).iter().map(|t| t.amax()).sum::<f64>() + design.chain.gravity_gradient(q).amax();
    if g.amax() > 1e-2 * scale.max(1e-9) {
        return Err(Error::invalid(
            bom_path,
            "stiffness",
            format!(
                "the bill's elements do not hold the design's equilibrium q_eq: |∇U(q_eq)| = {:.3e} N·m against element \
                 torques of {:.3e} N·m there (is it the bill of another design?)",
                g.amax(),
                scale
            ),
        ));
    }
    Ok(())
}

/// The filters of a run, or an error naming the log, the line and the setting when its
/// sampling is too slow or the run too short for them.
fn run_filters(log: &Log, run: &Run, cutoff: f64, settings: &IdentifySettings) -> Result<Filters> {
    let rate = 1.0 / run.dt;
    let label = if run.name.is_empty() { "the log".to_string() } else { format!("run `{}`", run.name) };
    if settings.smoothing_hz >= 0.45 * rate {
        return Err(Error::invalid(
            &log.path,
            format!("line {}: t", run.lines[1]),
            format!(
                "{label} is sampled at {rate:.4} Hz: identify.smoothing_hz = {} needs a rate above {:.4} Hz (lower it in \
                 the design's [identify])",
                settings.smoothing_hz,
                settings.smoothing_hz / 0.45
            ),
        ));
    }
    let filters = Filters::new(run.dt, cutoff, settings.smoothing_hz);
    let shortest = filters.shortest_run(run.dt);
    if run.duration() < shortest {
        return Err(Error::invalid(
            &log.path,
            format!("line {}: t", run.lines[0]),
            format!(
                "{label} lasts {:.3} s: with a cut-off of {cutoff:.3} Hz the filters take {:.3} s to settle, so a run needs \
                 at least {shortest:.3} s",
                run.duration(),
                filters.regression.settle() as f64 * run.dt
            ),
        ));
    }
    Ok(filters)
}

/// Identifies the built arm's rates (bill `bom`, read from `bom_path`), damping and friction
/// from `logs`.
pub fn identify(
    design: &Design,
    bom_path: &Path,
    bom: &[BomRow],
    logs: &[Log],
    settings: &IdentifySettings,
) -> Result<Identification> {
    check_bill(design, bom_path, bom)?;
    let n = design.dof();
    let test = region::RegionTest::new(design, settings.region_margin);
    let mut runs: Vec<(&Log, &Run, Filters)> = Vec::new();
    for log in logs {
        if log.dof != n {
            return Err(Error::invalid(
                &log.path,
                "line 1: header",
                format!("the log has {} joints but the design's robot has {n}", log.dof),
            ));
        }
        for run in &log.runs {
            runs.push((log, run, checked_run(design, log, run, settings, &test)?));
        }
    }
    let model = Model::new(bom, n, settings);
    let pairs: Vec<(&Run, Filters)> = runs.iter().map(|(_, r, f)| (*r, f.clone())).collect();
    let rows = regression::all_rows(design, &model, &pairs);
    let first = logs.first().map_or_else(|| Path::new("(no log)"), |log| log.path.as_path());
    solve(design, bom, settings, first, &model, runs, &rows)
}

/// The filters of `log`'s run `run`, once the run is known to be long enough for them and every
/// sample to lie in the region (else an error naming the log, the line and why).
fn checked_run(
    design: &Design,
    log: &Log,
    run: &Run,
    settings: &IdentifySettings,
    test: &region::RegionTest,
) -> Result<Filters> {
    let n = design.dof();
    let filters = run_filters(log, run, settings.cutoff(design.fit.frequency), settings)?;
    if let Some(out) = test.first_outside(&run.q)? {
        return Err(Error::invalid(
            &log.path,
            format!("line {}: q", run.lines[out.sample]),
            format!(
                "{}: angles in degrees, another joint order or an encoder zero off? (q1 … q{n} are the design's \
                 joints, in rad)",
                out.reason
            ),
        ));
    }
    Ok(filters)
}

/// The least squares of the regression rows `rows` of `runs` (every run checked, its rows
/// made) and the outcome made of it; an error naming the first log (`first`) when there are
/// too few rows.
fn solve(
    design: &Design,
    bom: &[BomRow],
    settings: &IdentifySettings,
    first: &Path,
    model: &Model,
    runs: Vec<(&Log, &Run, Filters)>,
    rows: &Rows,
) -> Result<Identification> {
    if rows.len() <= model.unknowns.len() {
        return Err(Error::invalid(
            first,
            "t",
            format!(
                "the logs give {} regression rows for {} unknowns: log longer runs",
                rows.len(),
                model.unknowns.len()
            ),
        ));
    }
    let lag = std::f64::consts::TAU / design.fit.frequency;
    let estimate = estimate::least_squares(rows, lag);
    let cutoff = settings.cutoff(design.fit.frequency);
    Ok(assemble(design, bom, settings, &Solved { cutoff, model, runs, rows, estimate }))
}

/// Readings identified again and again as more are added, as the plan's D-optimal loop does
/// after each release it adds: each reading is checked against the region and turned into its
/// regression rows once, when it is added, instead of at every identification (those were
/// nine tenths of the plan's time on three joints), and its ΦᵀΦ summed once (for
/// [`Readings::may_identify_every_rate`]). A run's rows depend on that run alone and its
/// index, so [`Readings::identify`] gives exactly what [`identify`] gives on a log of the same
/// runs.
pub struct Readings<'a> {
    design: &'a Design,
    bom: &'a [BomRow],
    settings: &'a IdentifySettings,
    test: region::RegionTest<'a>,
    model: Model,
    log: Log,
    filters: Vec<Filters>,
    rows: Rows,
    /// ΦᵀΦ of `rows`, each reading's added when it is.
    gram: estimate::Gram,
}

impl<'a> Readings<'a> {
    /// No readings yet, of the arm of `design` built with `bom` (read from `bom_path`, checked
    /// here), in a log named `path` (what errors and the run summaries name).
    pub fn new(
        design: &'a Design,
        bom_path: &Path,
        bom: &'a [BomRow],
        settings: &'a IdentifySettings,
        path: &Path,
    ) -> Result<Readings<'a>> {
        check_bill(design, bom_path, bom)?;
        let model = Model::new(bom, design.dof(), settings);
        let rows = Rows { width: model.unknowns.len(), ..Rows::default() };
        let gram = estimate::Gram::zeros(model.unknowns.len());
        Ok(Readings {
            design,
            bom,
            settings,
            test: region::RegionTest::new(design, settings.region_margin),
            model,
            log: Log { path: path.to_path_buf(), dof: design.dof(), runs: Vec::new() },
            filters: Vec::new(),
            rows,
            gram,
        })
    }

    /// Adds a reading: checked against the region (an error as [`identify`] gives it when it
    /// leaves), its rows appended as [`regression::all_rows`] appends a run's.
    pub fn add(&mut self, run: Run) -> Result<()> {
        let filters = checked_run(self.design, &self.log, &run, self.settings, &self.test)?;
        let index = self.log.runs.len();
        let rows = regression::run_rows(self.design, &self.model, &run, index, &filters);
        self.gram.add(&estimate::Gram::of(&rows));
        self.rows.push_run(rows, &run, &filters);
        self.log.runs.push(run);
        self.filters.push(filters);
        Ok(())
    }

    /// The identification from every reading added so far.
    pub fn identify(&self) -> Result<Identification> {
        let runs: Vec<(&Log, &Run, Filters)> =
            self.log.runs.iter().zip(&self.filters).map(|(r, f)| (&self.log, r, f.clone())).collect();
        solve(self.design, self.bom, self.settings, &self.log.path, &self.model, runs, &self.rows)
    }

    /// Whether an identification of the readings so far could find every rate identified: false
    /// when one of them is not estimable (an infinite standard error), decided from ΦᵀΦ summed
    /// reading by reading ([`estimate::all_estimable`]), without the identification's passes over
    /// every row. The plan skips the identifications this rules out: they could not end its
    /// loop.
    pub fn may_identify_every_rate(&self) -> bool {
        let rates: Vec<usize> =
            (0..self.model.unknowns.len()).filter(|&u| matches!(self.model.unknowns[u], Unknown::Rate(_))).collect();
        estimate::all_estimable(&self.gram, &rates)
    }
}

/// What the least squares of `identify` worked on and found: the model, the runs with their
/// filters, the regression rows and the estimate; [`assemble`] makes the outcome of it.
struct Solved<'a> {
    cutoff: f64,
    model: &'a Model,
    runs: Vec<(&'a Log, &'a Run, Filters)>,
    rows: &'a Rows,
    estimate: Estimate,
}

/// Joins the estimate, the verdict on the rates and the summaries into the outcome.
fn assemble(design: &Design, bom: &[BomRow], settings: &IdentifySettings, solved: &Solved) -> Identification {
    let Solved { cutoff, model, runs, rows, estimate } = solved;
    let n = design.dof();
    let rate_unknowns: Vec<usize> =
        (0..model.unknowns.len()).filter(|&u| matches!(model.unknowns[u], Unknown::Rate(_))).collect();
    let verdict = estimate::rate_verdict(estimate, &rate_unknowns, settings.max_standard_error);
    let mut status: Vec<Status> =
        verdict.identified.iter().map(|&ok| if ok { Status::Identified } else { Status::Group(0) }).collect();
    for (g, group) in verdict.groups.iter().enumerate() {
        for &i in &group.members {
            status[i] = Status::Group(g);
        }
    }
    let residual_rms: f64 = (estimate.residual.iter().map(|e| e * e).sum::<f64>() / rows.len() as f64).sqrt();
    let groups: Vec<RateGroup> = verdict
        .groups
        .iter()
        .map(|group| rate_group(model, estimate, &rate_unknowns, group, residual_rms, settings.max_standard_error))
        .collect();
    let rates: Vec<RateEstimate> = model
        .parts
        .iter()
        .enumerate()
        .map(|(i, part)| {
            let u = rate_unknowns[i];
            let inferred = |g: usize| {
                verdict.groups[g].identified.iter().any(|c| c.weights.iter().any(|&(k, w)| k == i && w != 0.0))
            };
            let source = match status[i] {
                Status::Identified => Source::Measured,
                Status::Group(g) if inferred(g) => Source::Combination,
                Status::Group(_) => Source::AsDesigned,
            };
            let unidentified =
                if status[i] == Status::Identified { None } else { unidentified(estimate, u, residual_rms) };
            let written = unidentified.is_none();
            RateEstimate {
                id: part.id.clone(),
                family: part.family.clone(),
                trim: part.trim,
                rows: part.rows.clone(),
                delta: if written { estimate.theta[u] } else { f64::NAN },
                standard_error: if written { estimate.standard_error(u) } else { f64::INFINITY },
                unidentified,
                status: status[i].clone(),
                for_tuning: if source == Source::AsDesigned { 0.0 } else { verdict.for_tuning[i] },
                source,
                torque_rms_nm: estimate.column_rms[u],
            }
        })
        .collect();
    let value =
        |u: Option<usize>| u.map(|u| Value { value: estimate.theta[u], standard_error: estimate.standard_error(u) });
    let joints: Vec<JointEstimate> = (0..n)
        .map(|j| JointEstimate {
            joint: format!("q{}", j + 1),
            damping: value(model.unknowns.iter().position(|u| *u == Unknown::Damping(j))),
            friction: value(model.unknowns.iter().position(|u| *u == Unknown::Friction(j))),
        })
        .collect();
    Identification {
        cutoff_hz: *cutoff,
        smoothing_hz: settings.smoothing_hz,
        max_standard_error: settings.max_standard_error,
        runs: run_summaries(runs, rows),
        rows: rows.len(),
        unknowns: model.unknowns.len(),
        rank: estimate.rank,
        condition: estimate.condition,
        residual_rms_nm: per_joint_rms(rows, n, &|r| estimate.residual[r].powi(2)),
        torque_rms_nm: per_joint_rms(rows, n, &|r| rows.designed[r].powi(2)),
        measured: measured_rates(bom, &rates),
        rates,
        groups,
        joints,
        trace: trace(runs, rows, estimate, n),
    }
}

/// A group of rates the logs cannot tell apart: its members, why (nearly proportional
/// torques, a part the logs never engage, or a torque too small against the residual) and the
/// combinations of them the logs fix.
fn rate_group(
    model: &Model,
    estimate: &Estimate,
    rate_unknowns: &[usize],
    group: &estimate::Group,
    residual_rms: f64,
    max_standard_error: f64,
) -> RateGroup {
    let ids: Vec<String> = group.members.iter().map(|&i| model.parts[i].id.clone()).collect();
    let reason = if group.members.len() > 1 {
        format!(
            "Their torques over these logs are nearly proportional: the logs fix {} of their {} rates only as \
             the combinations below",
            group.identified.len(),
            group.members.len()
        )
    } else {
        let u = rate_unknowns[group.members[0]];
        let top = estimate.column_rms.iter().fold(0.0f64, |m, x| m.max(*x));
        if estimate.column_rms[u] <= 1e-9 * top.max(f64::MIN_POSITIVE) {
            "The logs never engage it: it exerts no torque anywhere along them".to_string()
        } else if let Some(why) = unidentified(estimate, u, residual_rms) {
            format!("Unidentified: {why}")
        } else {
            format!(
                "Its torque over these logs (rms {:.3e} N·m for δ = 1, against a residual of {:.3e} N·m) leaves \
                 its δ a standard error of {:.3} %, beyond the bound of {} %",
                estimate.column_rms[u],
                residual_rms,
                100.0 * estimate.standard_error(u),
                100.0 * max_standard_error
            )
        }
    };
    let combination = |c: &Combination| CombinationReport {
        weights: c.weights.iter().map(|&(i, w)| (model.parts[i].id.clone(), w)).collect(),
        value: c.value,
        standard_error: c.standard_error,
    };
    RateGroup { members: ids, reason, identified: group.identified.iter().map(combination).collect() }
}

/// Why the rate of unknown `u`, not identified, is unidentified (its δ and standard error not
/// written as figures), or None when they are figures: not estimable, or a standard error of at
/// least [`estimate::UNIDENTIFIED_STANDARD_ERROR`] of the rate, given to one digit
/// (`residual_rms`, N·m, is the scale its torque is compared to).
fn unidentified(estimate: &Estimate, u: usize, residual_rms: f64) -> Option<String> {
    let torque = format!(
        "its torque over these logs (rms {:.3e} N·m for δ = 1, against a residual of {residual_rms:.3e} N·m)",
        estimate.column_rms[u]
    );
    if !estimate.estimable[u] {
        return Some(format!(
            "{torque} is a combination of the other unknowns' (the regression's null space): the logs carry nothing \
             about it alone"
        ));
    }
    let se = estimate.standard_error(u);
    (se >= estimate::UNIDENTIFIED_STANDARD_ERROR).then(|| {
        format!(
            "{torque} leaves its δ a standard error of about {:.0e} %, at least {} % of the rate: the logs cannot \
             tell it from no spring or from twice the spring, and its δ is no estimate",
            100.0 * se,
            100.0 * estimate::UNIDENTIFIED_STANDARD_ERROR
        )
    })
}

/// The measured rates: each estimated part's rows scaled by 1 + δ (for tuning); known trims and
/// parts the logs fix nothing about stay as designed (None).
fn measured_rates(bom: &[BomRow], rates: &[RateEstimate]) -> Vec<Option<f64>> {
    let mut measured: Vec<Option<f64>> = vec![None; bom.len()];
    for r in rates {
        if r.source != Source::AsDesigned {
            for &j in &r.rows {
                measured[j] = Some(bom[j].stiffness * (1.0 + r.for_tuning));
            }
        }
    }
    measured
}

/// The root mean of f(row) over each joint's rows.
fn per_joint_rms(rows: &Rows, n: usize, f: &dyn Fn(usize) -> f64) -> Vec<f64> {
    (0..n)
        .map(|j| {
            let (s, c) = (0..rows.len()).filter(|&r| rows.joint[r] == j).fold((0.0, 0), |(s, c), r| (s + f(r), c + 1));
            (s / c.max(1) as f64).sqrt()
        })
        .collect()
}

/// One summary per run: its file and name, samples, length, rate, whether it was driven and
/// the regression rows it gave.
fn run_summaries(runs: &[(&Log, &Run, Filters)], rows: &Rows) -> Vec<RunSummary> {
    runs.iter()
        .enumerate()
        .map(|(k, (log, run, _))| RunSummary {
            file: log.path.display().to_string(),
            run: run.name.clone(),
            samples: run.len(),
            seconds: run.duration(),
            rate_hz: 1.0 / run.dt,
            driven: run.tau.is_some(),
            rows: rows.run.iter().filter(|&&r| r == k).count(),
        })
        .collect()
}

/// The torque trace of the run with the most rows, its first 10 s of rows.
fn trace(runs: &[(&Log, &Run, Filters)], rows: &Rows, estimate: &Estimate, n: usize) -> Option<TorqueTrace> {
    let best = (0..runs.len()).max_by_key(|&k| rows.run.iter().filter(|&&r| r == k).count())?;
    let picked: Vec<usize> = (0..rows.len()).filter(|&r| rows.run[r] == best).collect();
    let t0 = rows.t[*picked.first()?];
    let mut out = TorqueTrace {
        run: {
            let file = runs[best].0.path.file_name().map_or_else(String::new, |f| f.to_string_lossy().into_owned());
            if runs[best].1.name.is_empty() { file } else { format!("{file}, run {}", runs[best].1.name) }
        },
        t: Vec::new(),
        measured: vec![Vec::new(); n],
        predicted: vec![Vec::new(); n],
        designed: vec![Vec::new(); n],
    };
    for &r in picked.iter().filter(|&&r| rows.t[r] - t0 <= 10.0) {
        let j = rows.joint[r];
        if j == 0 {
            out.t.push(rows.t[r]);
        }
        let fitted: f64 = rows.row(r).iter().zip(&estimate.theta).map(|(x, t)| x * t).sum();
        out.measured[j].push(rows.y[r] + rows.designed[r]);
        out.predicted[j].push(fitted + rows.designed[r]);
        out.designed[j].push(rows.designed[r]);
    }
    Some(out)
}
