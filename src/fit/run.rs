//! Fitting a design end to end: fans, candidates, the solve, the evaluation, the bill of
//! materials.
//!
//! Data flows one way: the region check fixes the region's extent; a training fan and a held-out
//! evaluation fan (directions between the training ones) are traced; the catalogue expands into
//! candidates over the range each coupling sweeps; candidates that never engage are dropped; the
//! problem is assembled on the training fan and solved (with sparse selection if asked); the
//! result is evaluated on the evaluation fan only.

use crate::design::validate::check_trimmed_weight;
use std::time::Instant;

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use super::problem::{FitProblem, LinearGroup, Requirements, assemble, fold_fixed};
use super::robust::{BuildPenalty, base_jacobian, spread_with, trimmed_spread};
use crate::design::Design;
use crate::design::fit::{FitSettings, SolverKind};
use crate::elements::Profile;
use crate::elements::catalog::{Candidate, Catalog};
use crate::error::{Error, Result};
use crate::fit::bill::BomRow;
use crate::geodesic::{Fan, FanSpec, RegionReport, Stop};
use crate::potential::{ExactPotential, Potential, SpringSet};
use crate::residual::{AngleSample, AngleStats, BandStats, band_stats, fan_angles, stats};
use crate::solve::lsq::Gram;
use crate::solve::nnls::{NnlsSettings, nnls, nnls_signed};
use crate::solve::qp::{QpSettings, QpStatus, qp_signed};
use crate::solve::selection::{
    Items, SelectionSettings, backward_elimination, extension_bounds, search, select_from, subset_nnls,
    subset_nnls_warm,
};

/// Wall-clock seconds per step.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Timings {
    /// Region check and fans.
    pub geodesics: f64,
    /// Candidates and problem assembly.
    pub assemble: f64,
    /// Solve and selection.
    pub solve: f64,
    /// Evaluation on the held-out fan.
    pub evaluate: f64,
    /// Everything.
    pub total: f64,
}

/// How the stiffnesses were found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SolveReport {
    /// `nnls`, `qp` or `exact`.
    pub solver: String,
    /// `solved`, `almost_solved` (QP at reduced accuracy) or `reference` (exact potential).
    pub status: String,
    /// Sparse selection: subset refits performed (0 without a limit).
    pub selection_evaluations: usize,
    /// Sparse selection: exchange moves accepted.
    pub selection_swaps: usize,
    /// QP: cutting-plane rounds for monotonicity.
    pub cut_rounds: usize,
    /// With a tolerance: the term the tolerance-aware fit adds for the final stiffnesses,
    /// λ (Σᵢ Dᵢᵢ kᵢ² + Σ_cams k_gᵀ B_g k_g) (+ the shift penalty); with λ = 1 and no shift weight, the predicted mean
    /// squared change of the training rows of a build about its own equilibrium. None without
    /// a tolerance.
    pub expected_build_spread: Option<f64>,
}

/// How well a potential does on the held-out evaluation fan.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    /// Residual angles on the evaluation fan.
    pub residuals: Vec<AngleSample>,
    /// Their statistics.
    pub stats: AngleStats,
    /// Statistics by distance band.
    pub bands: Vec<BandStats>,
    /// |∂U/∂q(q_eq)| in N·m (total potential).
    pub equilibrium_gradient_norm: f64,
    /// ‖∇²U(q_eq) − ω² M(q_eq)‖_F / ‖ω² M(q_eq)‖_F.
    pub hessian_rel_error: f64,
    /// Evaluation samples where U decreases along the geodesic (∂U/∂q·γ̇ < 0).
    pub monotone_violations: usize,
}

/// The outcome of a fit.
#[derive(Debug, Clone)]
pub struct FitOutcome {
    /// Design name.
    pub design: String,
    /// Joints.
    pub dof: usize,
    /// Catalogue name (`exact` for the reference).
    pub catalog: String,
    /// Settings used.
    pub settings: FitSettings,
    /// Candidates after expansion (before dropping).
    pub candidates: usize,
    /// Candidates dropped because they never engage in the region.
    pub dropped: usize,
    /// The bill of materials (empty for the exact reference).
    pub bom: Vec<BomRow>,
    /// Stock rates the catalogue offers, by family name (for snapping).
    pub stock_rates: std::collections::BTreeMap<String, Vec<f64>>,
    /// The fitted spring set (the BOM's elements and stiffnesses).
    pub springs: SpringSet,
    /// The fitted cams, realised (empty without cams).
    pub cams: Vec<crate::realise::cam::FittedCam>,
    /// Residuals and checks on the held-out fan.
    pub metrics: Evaluation,
    /// How the solve went.
    pub solve: SolveReport,
    /// Time per step.
    pub timings: Timings,
    /// The region check.
    pub region: RegionReport,
    /// The training fan.
    pub training: Fan,
    /// The held-out evaluation fan.
    pub evaluation: Fan,
}

impl FitOutcome {
    /// Number of elements used: the rows of `bom.csv`, a cam counting as one (as for
    /// `max_elements`) however many coefficients it has.
    pub fn used(&self) -> usize {
        self.bom.iter().filter(|r| !matches!(r.element.profile, Profile::Spline(_))).count() + self.cams.len()
    }

    /// What [`FitOutcome::used`] counts, in words: `springs`, or `elements (N cams)` with cams.
    pub fn used_noun(&self) -> String {
        if self.cams.is_empty() { "springs".into() } else { format!("elements ({} cams)", self.cams.len()) }
    }
}

/// Fits `design` with the elements of `catalog`. `stage` is told when each step starts (for
/// progress bars); the library itself prints nothing.
pub fn fit(design: &Design, catalog: &Catalog, settings: &FitSettings, stage: &dyn Fn(&str)) -> Result<FitOutcome> {
    let t0 = Instant::now();
    let prepared = Prepared::new(design, catalog, settings, stage)?;
    let mut outcome = prepared.solve(settings, stage)?;
    outcome.timings.total = t0.elapsed().as_secs_f64();
    Ok(outcome)
}

/// A fit up to the solve: region, fans, candidates and the assembled problem. One preparation
/// serves several solves that differ only in solver settings (the spring budgets of a Pareto
/// sweep).
pub struct Prepared<'a> {
    design: &'a Design,
    catalog: &'a Catalog,
    region: RegionReport,
    training: Fan,
    evaluation: Fan,
    candidates: Vec<Candidate>,
    n_expanded: usize,
    problem: FitProblem,
    /// The catalogue's trim springs at mid-range (folded into `problem`; empty without trims).
    trims: SpringSet,
    /// Normal equations of `problem.rows` (built once: every solve and the smoothing choice
    /// start from it).
    gram: Gram,
    t_geo: f64,
    t_asm: f64,
}

impl<'a> Prepared<'a> {
    /// Checks the region, traces the fans, expands the catalogue and assembles the problem.
    pub fn new(
        design: &'a Design,
        catalog: &'a Catalog,
        settings: &FitSettings,
        stage: &dyn Fn(&str),
    ) -> Result<Prepared<'a>> {
        settings.validate().map_err(|(f, r)| Error::invalid(&design.path, f, r))?;
        let t0 = Instant::now();
        stage("checking the region");
        let (region, training, evaluation) = fans(design, settings)?;
        let t_geo = t0.elapsed().as_secs_f64();

        stage("assembling the fit");
        let t1 = Instant::now();
        let q_eq = design.q_eq.as_slice();
        let range = |a: &[f64]| {
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            let at = |q: &[f64]| a.iter().zip(q).map(|(a, q)| a * q).sum::<f64>();
            for g in training.geodesics.iter().chain(&evaluation.geodesics) {
                for i in 0..g.len() {
                    let x = at(g.q(i));
                    lo = lo.min(x);
                    hi = hi.max(x);
                }
            }
            let x = at(q_eq);
            (lo.min(x), hi.max(x))
        };
        let expanded = catalog.expand(q_eq, range);
        let n_expanded = expanded.len();
        let candidates: Vec<Candidate> =
            expanded.into_iter().filter(|c| engages(c, q_eq, &training, &evaluation)).collect();
        if candidates.is_empty() {
            return Err(Error::invalid(
                &catalog.path,
                "family",
                format!("none of the {n_expanded} candidate elements engages anywhere in the region: nothing to fit"),
            ));
        }
        let req = Requirements {
            omega: settings.frequency,
            hessian_match: settings.hessian_match,
            monotone: settings.monotone,
        };
        let mut problem = assemble(&design.chain, &design.q_eq, &training, &candidates, req);
        // Trim springs sit at mid-range in every build as drawn: the fit is solved around them.
        let (_, trims) = crate::fit::bill::mid_range(catalog, q_eq);
        check_trimmed_weight(design, catalog, settings)?;
        fold_fixed(&mut problem, &design.chain, &design.q_eq, &training, &trims.elements, &trims.stiffness, req);
        let has_cams = candidates.iter().any(|c| matches!(c.element.profile, Profile::Spline(_)));
        let mut gram = if has_cams {
            Gram::from_sparse_rows(&problem.rows, &problem.rhs)
        } else {
            Gram::from_rows(&problem.rows, &problem.rhs)
        };
        if has_cams {
            stage("choosing the cams' smoothing");
            let penalty =
                cam_smoothing(design, catalog, settings, &candidates, &problem, &gram, &trims, region.extent)?;
            gram.add_weighted(&penalty.0, &penalty.1, 1.0);
            append_rows(&mut problem, &penalty);
        }
        let t_asm = t1.elapsed().as_secs_f64();
        Ok(Prepared {
            design,
            catalog,
            region,
            training,
            evaluation,
            candidates,
            n_expanded,
            problem,
            trims,
            gram,
            t_geo,
            t_asm,
        })
    }

    /// Solves and evaluates with `settings` (which must agree with the preparation's in
    /// frequency, Hessian match and monotonicity; the solver, budget and weights may differ).
    pub fn solve(&self, settings: &FitSettings, stage: &dyn Fn(&str)) -> Result<FitOutcome> {
        settings.validate().map_err(|(f, r)| Error::invalid(&self.design.path, f, r))?;
        let (design, catalog) = (self.design, self.catalog);
        stage("solving");
        let t2 = Instant::now();
        // With a tolerance the nominal pass only fixes J and H for the second: the single
        // exchange search is enough there.
        let first = if settings.tolerance.is_none() {
            *settings
        } else {
            FitSettings { restarts: 0, pair_swaps: false, ..*settings }
        };
        let (mut k, mut report) =
            solve(&self.problem, &self.gram, &self.candidates, self.design.q_eq.as_slice(), &first, None)?;
        if !settings.tolerance.is_none() {
            // Design for the build: the nominal fit fixes J and H, then the expected residual
            // over builds is minimised (see `fit::robust`).
            stage("fitting for the build tolerance");
            let d = self.build_penalty(&k, settings)?;
            let (k2, mut again) =
                solve(&self.problem, &self.gram, &self.candidates, self.design.q_eq.as_slice(), settings, Some(&d))?;
            again.selection_evaluations += report.selection_evaluations;
            again.selection_swaps += report.selection_swaps;
            again.cut_rounds += report.cut_rounds;
            again.expected_build_spread = Some(d.value(&k2));
            k = k2;
            report = again;
        }
        let t_solve = t2.elapsed().as_secs_f64();

        stage("evaluating on held-out geodesics");
        let t3 = Instant::now();
        let q_eq = design.q_eq.as_slice();
        let (mut bom, _) =
            bill_of_materials(catalog, &self.candidates, &k, &self.evaluation, q_eq, settings.used_threshold);
        // Trim springs (never candidates) join at mid-range: the fit was solved around them.
        crate::fit::bill::append(design, catalog, &mut bom, &self.evaluation);
        let springs = crate::fit::bill::spring_set(&bom);
        let metrics = evaluate(design, settings.frequency, settings.bands, &springs, &self.evaluation)?;
        let t_eval = t3.elapsed().as_secs_f64();
        let cams = crate::fit::bill::fitted_cams(catalog, &bom);
        summarise_cams(&mut bom, &cams, &self.evaluation, q_eq);
        Ok(FitOutcome {
            design: design.name.clone(),
            dof: design.dof(),
            catalog: catalog.name.clone(),
            cams,
            settings: *settings,
            candidates: self.n_expanded,
            dropped: self.n_expanded - self.candidates.len(),
            bom,
            stock_rates: catalog.families.iter().map(|f| (f.name.clone(), f.stock_rates.clone())).collect(),
            springs,
            metrics,
            solve: report,
            timings: Timings {
                geodesics: self.t_geo,
                assemble: self.t_asm,
                solve: t_solve,
                evaluate: t_eval,
                total: self.t_geo + self.t_asm + t_solve + t_eval,
            },
            region: self.region.clone(),
            training: self.training.clone(),
            evaluation: self.evaluation.clone(),
        })
    }
}

impl Prepared<'_> {
    /// What the tolerance-aware fit adds to the normal equations, from the nominal stiffnesses
    /// `k`: the diagonal Dᵢᵢ of the springs and one block per cam (one deviation per cam), plus
    /// the optional shift penalty (see `fit::robust`).
    fn build_penalty(&self, k: &[f64], settings: &FitSettings) -> Result<BuildPenalty> {
        let design = self.design;
        // The nominal potential includes the trims at mid-range (H and J are the whole arm's);
        // the trims themselves spread nothing: they are set after the build.
        let nominal = arm(&self.candidates, k, &self.trims);
        let sigma2: Vec<f64> = self
            .candidates
            .iter()
            .map(|c| settings.distribution.variance(settings.tolerance.for_element(c.tolerance)))
            .collect();
        let spacing = self.region.extent / settings.training_samples as f64;
        let (chain, ode) = (&design.chain, design.geodesics.ode);
        let jac = base_jacobian(chain, &self.training, spacing, &nominal, settings.frequency, ode)?;
        let rows = &self.problem.rows;
        let sp = spread_with(chain, &self.training, &self.candidates, rows, &nominal, &sigma2, &jac)?;
        let m = rows.nrows() as f64;
        let untrimmed = BuildPenalty::of(&sp, settings.tolerance_weight, settings.shift_weight * m);
        if settings.trimmed_weight == 0.0 {
            return Ok(untrimmed);
        }
        // Trimmed builds: the trims follow each build's equilibrium and are re-set there.
        let rest = arm(&self.candidates, k, &SpringSet { elements: Vec::new(), stiffness: Vec::new() });
        let (cands, omega) = (&self.candidates, settings.frequency);
        let tsp = trimmed_spread(chain, &self.training, cands, rows, &rest, &self.trims, &sigma2, omega, &jac)?;
        Ok(untrimmed.plus(BuildPenalty::of(&tsp, settings.trimmed_weight, 0.0)))
    }
}

/// The arm a solve describes: the candidates with k > 0 and the trims at their fixed rates (the
/// fit was solved around them).
fn arm(candidates: &[Candidate], k: &[f64], trims: &SpringSet) -> SpringSet {
    let used: Vec<usize> = (0..k.len()).filter(|&j| k[j] > 0.0).collect();
    SpringSet {
        elements: used.iter().map(|&j| candidates[j].element.clone()).chain(trims.elements.iter().cloned()).collect(),
        stiffness: used.iter().map(|&j| k[j]).chain(trims.stiffness.iter().copied()).collect(),
    }
}

/// Preload per unit stiffness of each candidate: u′(a·q_eq − x₀), the torque on its coordinate
/// at the equilibrium (signed). The preload of an element is k times this.
pub fn unit_preloads(candidates: &[Candidate], q_eq: &[f64]) -> Vec<f64> {
    candidates.iter().map(|c| c.element.profile.slope(c.element.deflection(q_eq))).collect()
}

/// The exact reference U* = ½ω²r² evaluated like a fit (no springs, no bill of materials).
pub fn exact_reference(design: &Design, settings: &FitSettings, stage: &dyn Fn(&str)) -> Result<FitOutcome> {
    settings.validate().map_err(|(f, r)| Error::invalid(&design.path, f, r))?;
    let t0 = Instant::now();
    stage("checking the region");
    let (region, training, evaluation) = fans(design, settings)?;
    let t_geo = t0.elapsed().as_secs_f64();
    stage("evaluating the exact potential (log map per sample)");
    let t3 = Instant::now();
    let exact = ExactPotential::new(&design.chain, &design.q_eq, settings.frequency, design.geodesics.ode);
    let residuals = fan_angles(&design.chain, &evaluation, &exact)?;
    let grad = exact.gradient(design.q_eq.as_slice())? + design.chain.gravity_gradient(design.q_eq.as_slice());
    let hess = exact.hessian(design.q_eq.as_slice())? + design.chain.gravity_hessian(design.q_eq.as_slice());
    let target = design.chain.mass_matrix(&design.q_eq) * settings.frequency.powi(2);
    let metrics = Evaluation {
        stats: stats(&residuals),
        bands: band_stats(&residuals, region.extent, settings.bands),
        residuals,
        equilibrium_gradient_norm: grad.norm(),
        hessian_rel_error: (hess - &target).norm() / target.norm(),
        monotone_violations: 0,
    };
    Ok(FitOutcome {
        design: design.name.clone(),
        dof: design.dof(),
        catalog: "exact".into(),
        settings: *settings,
        candidates: 0,
        dropped: 0,
        bom: Vec::new(),
        stock_rates: Default::default(),
        springs: SpringSet { elements: Vec::new(), stiffness: Vec::new() },
        cams: Vec::new(),
        metrics,
        solve: SolveReport {
            solver: "exact".into(),
            status: "reference".into(),
            selection_evaluations: 0,
            selection_swaps: 0,
            cut_rounds: 0,
            expected_build_spread: None,
        },
        timings: Timings {
            geodesics: t_geo,
            evaluate: t3.elapsed().as_secs_f64(),
            total: t0.elapsed().as_secs_f64(),
            ..Timings::default()
        },
        region,
        training,
        evaluation,
    })
}

/// The region check and the two fans.
fn fans(design: &Design, settings: &FitSettings) -> Result<(RegionReport, Fan, Fan)> {
    let region = design.valid_region()?;
    let stop = Stop::Region { region: &design.region, max_arc: design.geodesics.max_arc };
    let ode = design.geodesics.ode;
    let training = Fan::trace(
        &design.chain,
        &design.q_eq,
        FanSpec {
            count: settings.training_directions,
            phase: 0.0,
            stop,
            spacing: region.extent / settings.training_samples as f64,
        },
        ode,
    )?;
    // Held out: with the same count, phase ½ puts each direction halfway between two training
    // ones; with another count, phase ½ of its own spacing never meets a training direction
    // when the counts are multiples of each other (checked in tests).
    let evaluation = Fan::trace(
        &design.chain,
        &design.q_eq,
        FanSpec {
            count: settings.evaluation_directions,
            phase: 0.5,
            stop,
            spacing: region.extent / settings.evaluation_samples as f64,
        },
        ode,
    )?;
    Ok((region, training, evaluation))
}

/// Whether a candidate's potential changes anywhere in the region (else it is dropped).
fn engages(c: &Candidate, q_eq: &[f64], training: &Fan, evaluation: &Fan) -> bool {
    let e = &c.element;
    // A cam's basis functions stand or fall together: the smoothing penalty ties every
    // coefficient to its neighbours, so none is dropped (the fit's range covers all of them).
    if matches!(e.profile, Profile::Spline(_)) {
        return true;
    }
    let (_, slope, curv) = e.profile.eval(e.deflection(q_eq));
    if slope != 0.0 || curv != 0.0 {
        return true;
    }
    training
        .geodesics
        .iter()
        .chain(&evaluation.geodesics)
        .any(|g| (0..g.len()).any(|i| e.profile.slope(e.deflection(g.q(i))) != 0.0))
}

/// Largest equality residual (scaled units: ω²·mean diag M(q_eq)) NNLS may leave before the fit
/// counts as infeasible.
const NNLS_EQUALITY_TOLERANCE: f64 = 1e-3;

/// Solves the assembled problem with the chosen solver and, with `max_elements`, the sparse
/// selection. Returns the stiffness of every candidate.
///
/// `extra` is added to the normal equations (the tolerance-aware fit's expected spread of the
/// builds: a diagonal for the springs, a block per cam): every solver and the selection minimise
/// the same objective.
fn solve(
    problem: &FitProblem,
    gram: &Gram,
    candidates: &[Candidate],
    q_eq: &[f64],
    settings: &FitSettings,
    extra: Option<&BuildPenalty>,
) -> Result<(Vec<f64>, SolveReport)> {
    let mut gram = gram.clone();
    if let Some(d) = extra {
        d.add_to(&mut gram.g);
    }
    solve_gram(problem, gram, candidates, q_eq, settings)
}

/// [`solve`] with the Gram matrix of the problem's rows given (the cams' smoothing choice adds
/// its penalty to one Gram matrix instead of rebuilding it per weight).
fn solve_gram(
    problem: &FitProblem,
    gram: Gram,
    candidates: &[Candidate],
    q_eq: &[f64],
    settings: &FitSettings,
) -> Result<(Vec<f64>, SolveReport)> {
    solve_gram_with(problem, gram, candidates, q_eq, settings, settings.solver == SolverKind::Qp)
}

/// [`solve_gram`], choosing whether cam coefficients are signed unknowns (`signed`) or kept as
/// non-negative ± column pairs (see below).
fn solve_gram_with(
    problem: &FitProblem,
    gram: Gram,
    candidates: &[Candidate],
    q_eq: &[f64],
    settings: &FitSettings,
    signed: bool,
) -> Result<(Vec<f64>, SolveReport)> {
    let p = candidates.len();
    let unit = unit_preloads(candidates, q_eq);
    // Equalities folded in with weight W per row: a violation δ of an equation costs as much as
    // δ / equality_weight of residual on every tangentiality row.
    let weight = settings.equality_weight * (problem.rows.nrows().max(1) as f64).sqrt();
    let mut weighted = gram.clone();
    for eq in &problem.equalities {
        weighted.add_weighted(&eq.matrix, &eq.rhs, weight);
    }
    let upper: Vec<Option<f64>> = candidates.iter().map(|c| c.max_stiffness).collect();
    let mut report = SolveReport {
        solver: settings.solver.name().into(),
        status: "solved".into(),
        selection_evaluations: 0,
        selection_swaps: 0,
        cut_rounds: 0,
        expected_build_spread: None,
    };
    // The selection counts items: a spring is one, a cam (all its basis columns) is one.
    let items = Items::from_groups(&cam_groups(candidates));
    let support: Vec<usize> = if settings.max_elements > 0 && settings.max_elements < items.len() {
        let dense = nnls(&weighted, 0.0, &NnlsSettings::default())?;
        let pool = items.touching(|j| dense.k[j] > 0.0);
        let start = backward_elimination(&weighted, &items, pool.clone(), settings.max_elements)?;
        let sel_settings = SelectionSettings {
            max_elements: settings.max_elements,
            swap_passes: settings.swap_passes,
            restarts: settings.restarts,
            pair_swaps: settings.pair_swaps,
            seed: settings.seed,
        };
        let n = items.len();
        let sel = if settings.restarts == 0 && !settings.pair_swaps {
            // The single exchange search, with cold-started refits as before restarts existed.
            select_from(n, sel_settings, start, |s| subset_nnls(&weighted, &items, s))?
        } else {
            let bound = |s: &[usize]| extension_bounds(&weighted, &items, s);
            search(n, sel_settings, start, &pool, |s| subset_nnls_warm(&weighted, &items, s), Some(&bound))?
        };
        report.selection_evaluations = sel.evaluations;
        report.selection_swaps = sel.swaps;
        items.columns(&sel.support)
    } else {
        (0..p).collect()
    };
    // The QP sees one signed unknown per cam coefficient instead of its ± column pair (see
    // `signed_unknowns`). NNLS keeps the pairs: its active set starts from zero and brings in
    // only the columns the fit needs, which keeps cams that could cancel each other small (four
    // cams on the ball r = 2 as built at ±5 %: p99 p95 4.8° with the pairs, 15.4° with signed
    // unknowns solved exactly, at the same accuracy as drawn).
    let (support, free, pinned) = if signed {
        signed_unknowns(candidates, &support)
    } else {
        let n = support.len();
        (support, vec![false; n], Vec::new())
    };
    let sub_upper: Vec<Option<f64>> = support.iter().map(|&j| upper[j]).collect();
    let k_sub = match settings.solver {
        SolverKind::Nnls => {
            let k = nnls_bounded(&weighted.subset(&support), settings.l1, &sub_upper, &free)?;
            if settings.max_preload > 0.0 {
                let total: f64 = support.iter().zip(k.iter()).map(|(&j, kj)| (unit[j] * kj).abs()).sum();
                if total > settings.max_preload * (1.0 + 1e-9) {
                    return Err(Error::Infeasible {
                        constraint: format!("max_preload ({} N·m)", settings.max_preload),
                        reason: format!(
                            "NNLS cannot bound the preload and its fit needs Σ|preload| = {total:.3} N·m; use solver = \"qp\", which enforces the bound exactly"
                        ),
                    });
                }
            }
            // Weighted equalities can be missed silently: check them like the QP would.
            for g in &problem.equalities {
                let sub = DMatrix::from_fn(g.matrix.nrows(), support.len(), |r, a| g.matrix[(r, support[a])]);
                let residual = (sub * &k - &g.rhs).amax();
                if residual > NNLS_EQUALITY_TOLERANCE {
                    return Err(Error::Infeasible {
                        constraint: format!("{} ({})", g.name, g.description),
                        reason: format!(
                            "NNLS with weighted equalities leaves a residual of {residual:.2e} (in units of ω²·mean diag M(q_eq)); the available elements cannot meet it"
                        ),
                    });
                }
            }
            k
        }
        SolverKind::Qp => {
            let restrict = |groups: &[LinearGroup]| -> Vec<LinearGroup> {
                groups
                    .iter()
                    .map(|g| LinearGroup {
                        matrix: DMatrix::from_fn(g.matrix.nrows(), support.len(), |r, a| g.matrix[(r, support[a])]),
                        ..g.clone()
                    })
                    .collect()
            };
            let mut inequalities = problem.inequalities.clone();
            if settings.max_preload > 0.0 && free.iter().any(|&f| f) {
                // |τ| of a signed coefficient is not linear in it.
                return Err(Error::Infeasible {
                    constraint: format!("max_preload ({} N·m)", settings.max_preload),
                    reason:
                        "the QP bounds the preload of springs only, and the catalogue has cams: set max_preload = 0"
                            .into(),
                });
            }
            if settings.max_preload > 0.0 {
                // Σ|pᵢ| kᵢ ≤ P: preload is linear in k with a fixed sign per element. Scaled by
                // 1/P so the cutting-plane margin is relative.
                let p_max = settings.max_preload;
                inequalities.push(LinearGroup {
                    name: "preload bound".into(),
                    description: format!("Σ|τᵢ(q_eq)| ≤ {p_max} N·m (max_preload)"),
                    matrix: DMatrix::from_fn(1, p, |_, j| -unit[j].abs() / p_max),
                    rhs: DVector::from_element(1, -1.0),
                });
            }
            let sol = qp_signed(
                &gram.subset(&support),
                &restrict(&problem.equalities),
                &restrict(&inequalities),
                &sub_upper,
                &free,
                settings.l1,
                &QpSettings::default(),
            )?;
            report.cut_rounds = sol.cut_rounds;
            if sol.status == QpStatus::AlmostSolved {
                report.status = "almost_solved".into();
            }
            sol.k
        }
    };
    let mut k = vec![0.0; p];
    let partners = cam_partners(candidates);
    // Signed coefficients by +Bⱼ column, the pinned ones at 0.
    let mut coef: Vec<Option<f64>> = vec![None; p];
    for &j in &pinned {
        coef[j] = Some(0.0);
    }
    for (a, &j) in support.iter().enumerate() {
        if free[a] {
            coef[j] = Some(k_sub[a]);
        } else {
            k[j] = k_sub[a];
        }
    }
    // A cam with a pinned coefficient is shifted to zero mean: the same torque, and the same
    // coefficients whichever was pinned.
    let groups = cam_groups(candidates);
    for &j0 in &pinned {
        let members: Vec<usize> = (0..p).filter(|&j| groups[j] == groups[j0] && coef[j].is_some()).collect();
        let mean = members.iter().filter_map(|&j| coef[j]).sum::<f64>() / members.len() as f64;
        for &j in &members {
            coef[j] = coef[j].map(|c| c - mean);
        }
    }
    for j in 0..p {
        if let (Some(c), Some(neg)) = (coef[j], partners[j]) {
            // c = k⁺ − k⁻ with one of them zero.
            k[j] = c.max(0.0);
            k[neg] = (-c).max(0.0);
        }
    }
    Ok((k, report))
}

/// For each +Bⱼ cam column, the index of its −Bⱼ partner (same family, coupling, knots and
/// index); `None` for springs, −Bⱼ columns and +Bⱼ columns without a partner.
fn cam_partners(candidates: &[Candidate]) -> Vec<Option<usize>> {
    type Key = (usize, Vec<u64>, u64, crate::elements::spline::SplineBasis);
    let key = |c: &Candidate| -> Option<Key> {
        let Profile::Spline(b) = c.element.profile else { return None };
        let coupling = c.element.coupling.iter().map(|a| a.to_bits()).collect();
        Some((
            c.family,
            coupling,
            c.element.offset.to_bits(),
            crate::elements::spline::SplineBasis { negative: false, ..b },
        ))
    };
    let negatives: std::collections::HashMap<Key, usize> = candidates
        .iter()
        .enumerate()
        .filter(|(_, c)| matches!(c.element.profile, Profile::Spline(b) if b.negative))
        .filter_map(|(j, c)| key(c).map(|k| (k, j)))
        .collect();
    candidates
        .iter()
        .map(|c| match c.element.profile {
            Profile::Spline(b) if !b.negative => key(c).and_then(|k| negatives.get(&k).copied()),
            _ => None,
        })
        .collect()
}

/// The solver's unknowns for the candidates `support`: every spring (k ≥ 0), and for each cam
/// basis function whose ±Bⱼ columns are both in the support one signed unknown cⱼ on the +Bⱼ
/// column (`free`), the −Bⱼ column dropped. The pair spans the same potentials, but it adds a
/// direction that changes no residual (k⁺ and k⁻ grown together): the optimum is a ray, along
/// which active-set steps wander and an interior-point solver stops numerically (a ridge on the
/// coefficients bounded it before, but any ridge large enough to matter numerically also
/// biased the fit: 1e-7 relative raised the window's p99 from 0.55° to 0.83°). Signed unknowns remove it, halve the cam columns, and with no springs in
/// the catalogue NNLS becomes one linear solve.
///
/// The other such direction is the constant: Σⱼ Bⱼ = 1 everywhere (see [`crate::elements::spline`]), so
/// adding t to every coefficient of a cam changes no torque, no smoothing row and no condition.
/// When a cam's whole basis is in the support its first coefficient is therefore pinned at 0
/// (dropped from the unknowns): the others still span every torque profile, and no ridge is
/// needed. The answer is then shifted to zero mean per cam (the same torque).
/// Returns the unknowns' columns, which are signed, and the pinned columns.
fn signed_unknowns(candidates: &[Candidate], support: &[usize]) -> (Vec<usize>, Vec<bool>, Vec<usize>) {
    let partners = cam_partners(candidates);
    let groups = cam_groups(candidates);
    let in_support: std::collections::HashSet<usize> = support.iter().copied().collect();
    let paired: std::collections::HashSet<usize> =
        support.iter().filter_map(|&j| partners[j].filter(|n| in_support.contains(n))).collect();
    let signed = |j: usize| partners[j].is_some_and(|n| paired.contains(&n));
    // Per cam: signed coefficients in the support, and the column of its first basis function.
    let mut count: std::collections::HashMap<usize, (usize, Option<usize>)> = Default::default();
    for &j in support.iter().filter(|&&j| signed(j)) {
        let (Some(g), Profile::Spline(b)) = (groups[j], candidates[j].element.profile) else { continue };
        let e = count.entry(g).or_insert((0, None));
        e.0 += 1;
        if b.index == 0 {
            e.1 = Some(j);
        }
    }
    let mut pinned: Vec<usize> = count
        .iter()
        .filter_map(|(&g, &(n, first))| {
            let j = first?;
            let Profile::Spline(b) = candidates[j].element.profile else { return None };
            (groups[j] == Some(g) && n == usize::from(b.count) + 2).then_some(j)
        })
        .collect();
    pinned.sort_unstable();
    let keep: Vec<usize> = support.iter().copied().filter(|j| !paired.contains(j) && !pinned.contains(j)).collect();
    let free = keep.iter().map(|&j| signed(j)).collect();
    (keep, free, pinned)
}

/// NNLS with upper bounds by clamp-and-refit: elements above their bound are fixed at it and the
/// rest refitted, until none exceeds its bound. Not the exact bounded optimum in general (use the
/// QP for that) but it never violates a bound and equals NNLS when no bound is active.
///
/// `signed[j]`: unknown j is free of sign (a cam coefficient); its bound u means |k| ≤ u and it is
/// clamped at ±u.
fn nnls_bounded(gram: &Gram, l1: f64, upper: &[Option<f64>], signed: &[bool]) -> Result<DVector<f64>> {
    let p = gram.dim();
    let mut fixed: Vec<usize> = Vec::new();
    let mut values: Vec<f64> = Vec::new();
    loop {
        let free: Vec<usize> = (0..p).filter(|j| !fixed.contains(j)).collect();
        let free_signed: Vec<bool> = free.iter().map(|&j| signed[j]).collect();
        let sol = nnls_signed(&gram.fix(&free, &fixed, &values), l1, &NnlsSettings::default(), &[], &free_signed)?;
        let mut k = DVector::zeros(p);
        for (a, &j) in free.iter().enumerate() {
            k[j] = sol.k[a];
        }
        for (&j, v) in fixed.iter().zip(&values) {
            k[j] = *v;
        }
        let over: Vec<usize> = free.iter().copied().filter(|&j| upper[j].is_some_and(|u| k[j].abs() > u)).collect();
        if over.is_empty() {
            return Ok(k);
        }
        let mut pairs: Vec<(usize, f64)> = fixed.iter().copied().zip(values.iter().copied()).collect();
        pairs.extend(over.iter().map(|&j| (j, upper[j].unwrap_or(0.0).copysign(k[j]))));
        pairs.sort_unstable_by_key(|&(j, _)| j);
        fixed = pairs.iter().map(|&(j, _)| j).collect();
        values = pairs.iter().map(|&(_, v)| v).collect();
    }
}

/// The used elements (peak torque above the threshold) as bill-of-materials rows and springs.
fn bill_of_materials(
    catalog: &Catalog,
    candidates: &[Candidate],
    k: &[f64],
    evaluation: &Fan,
    q_eq: &[f64],
    threshold: f64,
) -> (Vec<BomRow>, SpringSet) {
    // A cam's +Bⱼ and −Bⱼ columns become one signed coefficient cⱼ = k⁺ − k⁻ on the column of its
    // sign, as `bom.csv` writes it: the set evaluated below is the one its files rebuild. (The
    // solve already leaves one of each pair at zero; then this changes no bit.)
    let mut k = k.to_vec();
    for (j, n) in cam_partners(candidates).into_iter().enumerate() {
        if let Some(n) = n {
            if k[j] > 0.0 && k[n] > 0.0 {
                let c = k[j] - k[n];
                k[j] = c.max(0.0);
                k[n] = (-c).max(0.0);
            }
        }
    }
    let k = k.as_slice();
    // Peak torque on x and engaged deflection of each candidate over the region.
    let peaks: Vec<(f64, f64)> = candidates
        .iter()
        .zip(k)
        .map(|(c, &kj)| {
            let e = &c.element;
            let mut torque: f64 = 0.0;
            let mut defl: f64 = 0.0;
            let mut visit = |q: &[f64]| {
                let d = e.deflection(q);
                let slope = e.profile.slope(d);
                torque = torque.max((kj * slope).abs());
                if slope != 0.0 || !matches!(e.profile, crate::elements::Profile::Compression(_)) {
                    defl = defl.max(d.abs());
                }
            };
            visit(q_eq);
            for g in &evaluation.geodesics {
                for i in 0..g.len() {
                    visit(g.q(i));
                }
            }
            (torque, defl)
        })
        .collect();
    let max_peak = peaks.iter().map(|p| p.0).fold(0.0, f64::max);
    // A cam's basis columns only make sense together: every one with k > 0 is kept.
    let is_cam = |j: usize| matches!(candidates[j].element.profile, Profile::Spline(_));
    let used: Vec<usize> =
        (0..candidates.len()).filter(|&j| k[j] > 0.0 && (is_cam(j) || peaks[j].0 > threshold * max_peak)).collect();
    let groups = cam_groups(candidates);
    let bom: Vec<BomRow> = used
        .iter()
        .enumerate()
        .map(|(i, &j)| {
            let c = &candidates[j];
            let stock_rate = nearest(&c.stock_rates, k[j]);
            let id = match (c.element.profile, groups[j]) {
                (Profile::Spline(b), Some(g)) => {
                    format!("C{:02}.{:02}{}", g + 1, b.index, if b.negative { "-" } else { "+" })
                }
                _ => format!("S{:02}", i + 1),
            };
            BomRow {
                id,
                family: catalog.families[c.family].name.clone(),
                element: c.element.clone(),
                stiffness: k[j],
                max_torque_nm: peaks[j].0,
                max_deflection_rad: peaks[j].1,
                stock_rate,
                tolerance: c.tolerance,
                preload_nm: Some(c.element.preload(k[j], q_eq)),
                adjust: crate::fit::bill::Adjustment {
                    adjust_range: catalog.families[c.family].adjust_range,
                    trim_range: None,
                },
                cam: None,
            }
        })
        .collect();
    let springs = SpringSet {
        elements: used.iter().map(|&j| candidates[j].element.clone()).collect(),
        stiffness: used.iter().map(|&j| k[j]).collect(),
    };
    (bom, springs)
}

/// Gives each cam coefficient row its cam's [`crate::fit::bill::CamSummary`]: the build, the largest
/// |V′| over the region (the equilibrium and every sample of `evaluation`) and V′ at q_eq.
fn summarise_cams(bom: &mut [BomRow], cams: &[crate::realise::cam::FittedCam], evaluation: &Fan, q_eq: &[f64]) {
    for cam in cams {
        let torque = |q: &[f64]| {
            let x: f64 = cam.coupling.iter().zip(q).map(|(a, q)| a * q).sum();
            cam.knots.eval(&cam.coefficients, x).1
        };
        let preload = torque(q_eq);
        let mut peak = preload.abs();
        for g in &evaluation.geodesics {
            for i in 0..g.len() {
                peak = peak.max(torque(g.q(i)).abs());
            }
        }
        let summary = crate::fit::bill::CamSummary {
            build: cam.realisation.build,
            max_torque_nm: peak,
            preload_nm: Some(preload),
        };
        for r in bom.iter_mut().filter(|r| {
            matches!(r.element.profile, Profile::Spline(_)) && r.id.split('.').next() == Some(cam.id.as_str())
        }) {
            r.cam = Some(summary);
        }
    }
}

/// The stock rate nearest to `k` in ratio (rates are usually geometric series).
pub fn nearest(rates: &[f64], k: f64) -> Option<f64> {
    rates.iter().copied().min_by(|a, b| (a / k).ln().abs().total_cmp(&(b / k).ln().abs()))
}

/// Residuals and checks of a spring set on a fan (held-out geodesics): the figures users compare.
pub fn evaluate(design: &Design, omega: f64, bands: usize, springs: &SpringSet, fan: &Fan) -> Result<Evaluation> {
    let chain = &design.chain;
    let q0 = design.q_eq.as_slice();
    // Grouped for the thousands of samples; the checks at q_eq element by element, as before.
    let grouped = springs.grouped();
    let residuals = fan_angles(chain, fan, &grouped)?;
    let grad = springs.gradient(q0)? + chain.gravity_gradient(q0);
    let hess = springs.hessian(q0)? + chain.gravity_hessian(q0);
    let target = chain.mass_matrix(&design.q_eq) * omega.powi(2);
    let mut monotone_violations = 0;
    for g in &fan.geodesics {
        for i in 0..g.len() {
            let q = g.q(i);
            let grad = grouped.gradient(q)? + chain.gravity_gradient(q);
            let rate: f64 = grad.iter().zip(g.qd(i)).map(|(a, b)| a * b).sum();
            if rate < -1e-12 * grad.norm() {
                monotone_violations += 1;
            }
        }
    }
    let extent = fan.geodesics.iter().map(|g| g.length()).fold(0.0, f64::max);
    Ok(Evaluation {
        stats: stats(&residuals),
        bands: band_stats(&residuals, extent, bands),
        residuals,
        equilibrium_gradient_norm: grad.norm(),
        hessian_rel_error: (hess - &target).norm() / target.norm(),
        monotone_violations,
    })
}

/// Refits the stiffnesses of `elements` on the training fan with some of them fixed
/// (`fixed[j] = Some(k)`), by NNLS with the equalities weighted as in the fit: what is left free
/// compensates what was fixed (stock-rate snapping). Returns every element's stiffness.
pub fn refit_with_fixed(
    design: &Design,
    settings: &FitSettings,
    training: &Fan,
    elements: &[crate::elements::Element],
    fixed: &[Option<f64>],
) -> Result<Vec<f64>> {
    let candidates: Vec<Candidate> = elements.iter().map(|e| Candidate::bare(e.clone())).collect();
    let req = Requirements { omega: settings.frequency, hessian_match: settings.hessian_match, monotone: false };
    let problem = assemble(&design.chain, &design.q_eq, training, &candidates, req);
    let mut weighted = Gram::from_rows(&problem.rows, &problem.rhs);
    let weight = settings.equality_weight * (problem.rows.nrows().max(1) as f64).sqrt();
    for eq in &problem.equalities {
        weighted.add_weighted(&eq.matrix, &eq.rhs, weight);
    }
    let free: Vec<usize> = (0..elements.len()).filter(|&j| fixed[j].is_none()).collect();
    let fixed_idx: Vec<usize> = (0..elements.len()).filter(|&j| fixed[j].is_some()).collect();
    let values: Vec<f64> = fixed_idx.iter().map(|&j| fixed[j].unwrap_or(0.0)).collect();
    let mut k: Vec<f64> = fixed.iter().map(|f| f.unwrap_or(0.0)).collect();
    if !free.is_empty() {
        let sol = nnls(&weighted.fix(&free, &fixed_idx, &values), 0.0, &NnlsSettings::default())?;
        for (a, &j) in free.iter().enumerate() {
            k[j] = sol.k[a];
        }
    }
    Ok(k)
}

/// The cam each candidate belongs to (its family, coupling and knots), numbered in order of
/// appearance; `None` for springs. A cam counts as one element.
pub fn cam_groups(candidates: &[Candidate]) -> Vec<Option<usize>> {
    let mut keys: Vec<(usize, Vec<u64>, u64)> = Vec::new();
    candidates
        .iter()
        .map(|c| {
            let Profile::Spline(b) = c.element.profile else { return None };
            let key = (c.family, c.element.coupling.iter().map(|a| a.to_bits()).collect(), b.width_bits);
            Some(keys.iter().position(|k| *k == key).unwrap_or_else(|| {
                keys.push(key);
                keys.len() - 1
            }))
        })
        .collect()
}

/// Weight of the ridge Σ (cⱼ/(ω² m̄))² on cam coefficients (relative like the smoothing weight).
pub const CAM_RIDGE: f64 = 1e-9;

/// Smoothing weights tried by `smoothing = "auto"`, relative to the tangentiality rows.
pub const AUTO_SMOOTHING: [f64; 5] = [1e-7, 1e-6, 1e-5, 1e-4, 1e-3];

/// The cams' smoothing penalty ∫V‴² dx as rows (rhs 0) for the chosen weights. Each cam's
/// penalty is scaled by 1/(ω² m̄)² (m̄ the mean diagonal of M(q_eq)), by the number of
/// tangentiality rows and by the family's weight λ, so λ = 1 weighs ∫(V‴/(ω² m̄))² dx like all
/// the rows together. Families with `smoothing = "auto"` share one weight, the one of
/// [`AUTO_SMOOTHING`] with the smallest p99 residual on a *validation* fan (directions at a
/// quarter of the training spacing, apart from both the training and the held-out fans), judged
/// on the dense fit (without `max_elements`). `extent` is the region's arc length from q_eq (the
/// region check's, which the fit has already made).
#[allow(clippy::too_many_arguments)]
fn cam_smoothing(
    design: &Design,
    catalog: &Catalog,
    settings: &FitSettings,
    candidates: &[Candidate],
    problem: &FitProblem,
    gram: &Gram,
    trims: &SpringSet,
    extent: f64,
) -> Result<(DMatrix<f64>, DVector<f64>)> {
    let groups = cam_groups(candidates);
    let n_groups = groups.iter().flatten().max().map_or(0, |g| g + 1);
    let m_bar = design.chain.mass_matrix(&design.q_eq).diagonal().mean();
    let base = (problem.rows.nrows().max(1) as f64).sqrt() / (settings.frequency.powi(2) * m_bar);
    // Per cam: its penalty rows over all candidates, and whether its weight is "auto".
    let mut blocks: Vec<(DMatrix<f64>, Option<f64>)> = Vec::new();
    for g in 0..n_groups {
        let members: Vec<usize> = (0..candidates.len()).filter(|&j| groups[j] == Some(g)).collect();
        let first = &candidates[members[0]];
        let Profile::Spline(b) = first.element.profile else { continue };
        let spec = catalog.families[first.family].cam.expect("cam candidates come from cam families");
        let knots = crate::elements::spline::Knots { lo: first.element.offset, width: b.width(), count: b.count };
        let d = knots.third_derivative_rows();
        let mut block = DMatrix::zeros(d.len(), candidates.len());
        for &j in &members {
            let Profile::Spline(bj) = candidates[j].element.profile else { continue };
            let sign = if bj.negative { -1.0 } else { 1.0 };
            for (r, row) in d.iter().enumerate() {
                block[(r, j)] = sign * row[usize::from(bj.index)] * base;
            }
        }
        let weight = match spec.smoothing {
            crate::elements::catalog::Smoothing::Weight(w) => Some(w),
            crate::elements::catalog::Smoothing::Auto => None,
        };
        blocks.push((block, weight));
    }
    // A tiny ridge on every cam column. Cams on four or more couplings can cancel each other
    // over the whole region (x₁², x₂², (x₁+x₂)² and (x₁−x₂)² are dependent, and so are the
    // linear functions of any three couplings): without the ridge the solve may pick large
    // antagonistic cams, accurate as drawn, whose one-δ-per-cam rate errors un-cancel in every
    // build (measured: cams4 as built p99 p95 4.8° with the ridge, 15.6° without). At this
    // weight it costs nothing measurable as drawn.
    // The QP's signed unknowns need no ridge (and it moves the QP's optimum: with it the 16-cam
    // window design turned a mode over on the held-out fan); NNLS's ± pairs keep it.
    let ridge = settings.solver == SolverKind::Nnls;
    let cam_columns: Vec<usize> =
        if ridge { (0..candidates.len()).filter(|&j| groups[j].is_some()).collect() } else { Vec::new() };
    let build = |auto: f64| -> (DMatrix<f64>, DVector<f64>) {
        let rows: usize = blocks.iter().map(|b| b.0.nrows()).sum::<usize>() + cam_columns.len();
        let mut m = DMatrix::zeros(rows, candidates.len());
        let mut r0 = 0;
        for (block, w) in &blocks {
            let w = w.unwrap_or(auto).sqrt();
            m.view_mut((r0, 0), block.shape()).copy_from(&(block * w));
            r0 += block.nrows();
        }
        if ridge {
            for (i, &j) in cam_columns.iter().enumerate() {
                m[(r0 + i, j)] = CAM_RIDGE.sqrt() * base;
            }
        }
        (m, DVector::zeros(rows))
    };
    if blocks.iter().all(|b| b.1.is_some()) {
        return Ok(build(0.0));
    }
    let stop = Stop::Region { region: &design.region, max_arc: design.geodesics.max_arc };
    let validation = Fan::trace(
        &design.chain,
        &design.q_eq,
        FanSpec {
            count: settings.evaluation_directions,
            phase: 0.25,
            stop,
            spacing: extent / settings.evaluation_samples as f64,
        },
        design.geodesics.ode,
    )?;
    let mut best: Option<(f64, f64)> = None;
    for &w in &AUTO_SMOOTHING {
        let (rows, rhs) = build(w);
        let mut trial = gram.clone();
        trial.add_weighted(&rows, &rhs, 1.0);
        // A weight whose solve fails (infeasible, numerical trouble) is simply not chosen.
        // Chosen on the dense fit (every element allowed): a sparse selection per weight would
        // cost the selection five times over, and the weight only tempers each cam's wiggle.
        let dense = FitSettings { max_elements: 0, ..*settings };
        // Signed unknowns here whatever the solver: one linear solve per weight, and the
        // validation residual does not see the cancelling components the pairs keep small.
        let Ok((k, _)) = solve_gram_with(problem, trial, candidates, design.q_eq.as_slice(), &dense, true) else {
            continue;
        };
        // The problem was solved around the trims at mid-range: judge the arm with them.
        let springs = arm(candidates, &k, trims);
        let p99 = stats(&fan_angles(&design.chain, &validation, &springs.grouped())?).p99_abs;
        if best.is_none_or(|(_, b)| p99 < b) {
            best = Some((w, p99));
        }
    }
    let (w, _) = best.ok_or_else(|| Error::Infeasible {
        constraint: "cam smoothing".into(),
        reason: "no smoothing weight of the automatic choice gave a solvable fit".into(),
    })?;
    Ok(build(w))
}

/// Appends rows (and their right-hand side) to the tangentiality rows of a problem.
fn append_rows(problem: &mut FitProblem, extra: &(DMatrix<f64>, DVector<f64>)) {
    let (m, p) = problem.rows.shape();
    let r = extra.0.nrows();
    let mut rows = DMatrix::zeros(m + r, p);
    rows.view_mut((0, 0), (m, p)).copy_from(&problem.rows);
    rows.view_mut((m, 0), (r, p)).copy_from(&extra.0);
    let mut rhs = DVector::zeros(m + r);
    rhs.rows_mut(0, m).copy_from(&problem.rhs);
    rhs.rows_mut(m, r).copy_from(&extra.1);
    problem.rows = rows;
    problem.rhs = rhs;
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;
    use std::path::Path;

    use super::*;
    use crate::elements::Element;
    use crate::elements::spline::Knots;
    use crate::fit::robust::rows_of;
    use crate::geodesic::{FanSpec, Stop};
    use crate::model::Chain;
    use crate::numerics::ode::OdeSettings;

    /// The trims folded into the fit equal the problem with the trims as extra columns whose
    /// contribution (column × mid-range rate) is subtracted by hand from every right-hand side:
    /// rows, equilibrium, Hessian match and monotonicity. The fit solved around them (nominal
    /// pass, then the tolerance-aware pass) holds ∇U(q_eq) = 0 and ∇²U(q_eq) = ω² M(q_eq) with
    /// the trims in, and the folded residual is the whole arm's residual.
    #[test]
    fn trims_are_subtracted_from_every_right_hand_side_before_the_solve() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("designs/double_pendulum.toml");
        let design = Design::load(&path).unwrap();
        let catalog = Catalog::load(design.catalog.as_ref().unwrap(), design.dof()).unwrap();
        let settings = FitSettings {
            training_directions: 24,
            training_samples: 12,
            evaluation_directions: 24,
            evaluation_samples: 12,
            restarts: 0,
            pair_swaps: false,
            builds: 0,
            monotone: true,
            ..design.fit
        };
        assert!(!settings.tolerance.is_none(), "the shipped design fits for a tolerance");
        let prepared = Prepared::new(&design, &catalog, &settings, &|_| {}).unwrap();
        let (trims, mid) = crate::fit::bill::mid_range(&catalog, design.q_eq.as_slice());
        assert_eq!(trims.len(), 3);

        let mut all = prepared.candidates.clone();
        all.extend(trims.iter().map(|t| Candidate {
            element: t.element.clone(),
            family: t.family,
            max_stiffness: None,
            stock_rates: Vec::new(),
            tolerance: 0.0,
        }));
        let req = Requirements { omega: settings.frequency, hessian_match: true, monotone: true };
        let full = assemble(&design.chain, &design.q_eq, &prepared.training, &all, req);
        let p = prepared.candidates.len();
        let by_hand = |m: &DMatrix<f64>, rhs: &DVector<f64>| -> DVector<f64> {
            let mut r = rhs.clone();
            for (i, k) in mid.stiffness.iter().enumerate() {
                for row in 0..m.nrows() {
                    r[row] -= m[(row, p + i)] * k;
                }
            }
            r
        };
        let same = |a: &DVector<f64>, b: &DVector<f64>| (a - b).amax() <= 1e-12 * (1.0 + b.amax());
        let prob = &prepared.problem;
        assert_eq!(prob.rows, full.rows.columns(0, p).into_owned());
        assert!(same(&prob.rhs, &by_hand(&full.rows, &full.rhs)));
        assert_eq!(prob.equalities.len(), 2);
        assert_eq!(prob.inequalities.len(), 1);
        for (g, f) in
            prob.equalities.iter().zip(&full.equalities).chain(prob.inequalities.iter().zip(&full.inequalities))
        {
            assert_eq!(g.matrix, f.matrix.columns(0, p).into_owned(), "{}", g.name);
            assert!(same(&g.rhs, &by_hand(&f.matrix, &f.rhs)), "{}", g.name);
        }
        // The trims matter: unfolded, the Hessian match would be off by their stiffness.
        let trims_hessian = full.equalities[1].matrix.columns(p, 3) * DVector::from_column_slice(&mid.stiffness);
        assert!(trims_hessian.amax() > 0.01, "{trims_hessian}");

        let o = prepared.solve(&settings, &|_| {}).unwrap();
        assert!(o.solve.expected_build_spread.is_some());
        assert_eq!(o.bom.iter().filter(|r| r.adjust.trim_range.is_some()).count(), 3);
        let q = design.q_eq.as_slice();
        let target = design.chain.mass_matrix(&design.q_eq) * settings.frequency.powi(2);
        let h = o.springs.hessian(q).unwrap();
        assert!((h - &target).norm() / target.norm() < 1e-8);
        assert!(o.springs.gradient(q).unwrap().amax() < 1e-8 * target.norm());
        let k: Vec<f64> = prepared
            .candidates
            .iter()
            .map(|c| {
                o.bom
                    .iter()
                    .find(|r| r.adjust.trim_range.is_none() && r.element == c.element)
                    .map_or(0.0, |r| r.stiffness)
            })
            .collect();
        let folded = &prob.rows * DVector::from_vec(k) - &prob.rhs;
        let whole = rows_of(&design.chain, &prepared.training, &o.springs, settings.frequency);
        assert!((&folded - &whole).amax() < 1e-6 * (1.0 + whole.amax()), "{}", (&folded - &whole).amax());
    }

    /// A potential built from known B-spline coefficients on two cams plus a linear spring is
    /// recovered through both solver paths (signed unknowns for the cams, the first coefficient
    /// pinned), from real geodesic rows with exact equalities and monotonicity rows.
    #[test]
    fn known_cam_coefficients_are_recovered_by_both_solvers() {
        let chain = Chain::paper_double_pendulum();
        let q_eq = DVector::from_vec(vec![0.0, PI / 2.0]);
        let spec = FanSpec { count: 32, phase: 0.0, stop: Stop::Arc(1.5), spacing: 0.05 };
        let fan = Fan::trace(&chain, &q_eq, spec, OdeSettings::default()).unwrap();
        let couplings = [[1.0, 0.0], [1.0, -1.0]];
        let candidate = |profile, coupling: &[f64], offset| Candidate {
            element: Element { profile, coupling: coupling.to_vec(), offset },
            family: 0,
            max_stiffness: None,
            stock_rates: vec![],
            tolerance: 0.0,
        };
        let (mut candidates, mut k_true, mut all_knots) = (Vec::new(), Vec::new(), Vec::new());
        for (ci, a) in couplings.iter().enumerate() {
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for g in &fan.geodesics {
                for i in 0..g.len() {
                    let x = a[0] * g.q(i)[0] + a[1] * g.q(i)[1];
                    (lo, hi) = (lo.min(x), hi.max(x));
                }
            }
            let knots = Knots::over(lo, hi, 8, 0.0);
            for j in 0..knots.basis_count() {
                let c = (j as f64 * 0.8 + ci as f64).sin() * 2.0 + 0.7;
                for negative in [false, true] {
                    candidates.push(candidate(Profile::Spline(knots.basis(j, negative)), a, knots.lo));
                    k_true.push(if (c < 0.0) == negative { c.abs() } else { 0.0 });
                }
            }
            all_knots.push(knots);
        }
        // A linear spring on q₂ (k ≥ 0) in the truth, and a cubic one that is not.
        candidates.push(candidate(Profile::Linear, &[0.0, 1.0], 0.3));
        k_true.push(5.0);
        candidates.push(candidate(Profile::Cubic, &[0.0, 1.0], -0.2));
        k_true.push(0.0);
        let k_true = DVector::from_vec(k_true);
        let req = Requirements { omega: 2.0, hessian_match: true, monotone: true };
        let mut problem = assemble(&chain, &q_eq, &fan, &candidates, req);
        // The truth fits every row and equality exactly, and is monotone with margin to spare.
        problem.rhs = &problem.rows * &k_true;
        for g in problem.equalities.iter_mut() {
            g.rhs = &g.matrix * &k_true;
        }
        for g in problem.inequalities.iter_mut() {
            g.rhs = &g.matrix * &k_true - DVector::from_element(g.rhs.len(), 1.0);
        }
        let gram = Gram::from_sparse_rows(&problem.rows, &problem.rhs);
        let per = all_knots[0].basis_count();
        for solver in [SolverKind::Nnls, SolverKind::Qp] {
            let settings = FitSettings { solver, max_elements: 0, ..FitSettings::default() };
            let (k, _) = solve(&problem, &gram, &candidates, q_eq.as_slice(), &settings, None).unwrap();
            // The QP holds the equalities exactly; NNLS weighs them (weight 30·√m), which costs
            // accuracy in the normal equations.
            let tol = if solver == SolverKind::Qp { 1e-6 } else { 1e-3 };
            for (ci, knots) in all_knots.iter().enumerate() {
                let coef = |k: &[f64]| -> Vec<f64> {
                    (0..per).map(|j| k[2 * (ci * per + j)] - k[2 * (ci * per + j) + 1]).collect()
                };
                let truth = coef(k_true.as_slice());
                let got = coef(&k);
                // The QP's signed unknowns: never both halves of a pair, zero mean (the free
                // constant is fixed that way). NNLS keeps the non-negative pairs.
                if solver == SolverKind::Qp {
                    for j in 0..per {
                        assert!(k[2 * (ci * per + j)] == 0.0 || k[2 * (ci * per + j) + 1] == 0.0);
                    }
                    assert!(got.iter().sum::<f64>().abs() < 1e-9 * per as f64, "{solver:?}: {got:?}");
                }
                // Torques agree across the span.
                for i in 0..=50 {
                    let x = knots.lo + (knots.hi() - knots.lo) * f64::from(i) / 50.0;
                    let (t, g) = (knots.eval(&truth, x).1, knots.eval(&got, x).1);
                    assert!((t - g).abs() < tol * (1.0 + t.abs()), "{solver:?} cam {ci} at x = {x}: {g} vs {t}");
                }
            }
            let n = candidates.len();
            // The spring: exact under the QP; NNLS's weighted equalities leave ~1e-6 relative.
            let ktol = if solver == SolverKind::Qp { 1e-6 } else { 1e-4 };
            assert!((k[n - 2] - 5.0).abs() < ktol && k[n - 1].abs() < ktol, "{solver:?}: {:?}", &k[n - 2..]);
        }
    }
}
