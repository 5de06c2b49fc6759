//! The fit up to the solve: the region check, the training and held-out fans, the candidates the
//! catalogue expands into over the range each coupling sweeps (those that never engage dropped),
//! their grouping into parts, and the problem assembled on the training fan with the trims folded
//! in and the groups' smoothing added.

use std::sync::OnceLock;
use std::time::Instant;

use nalgebra::DMatrix;

use super::mass::{Floor, MassModel};
use super::problem::{
    FitProblem, Requirements, RowsOut, arm, assemble, assemble_factored, fold_fixed, mid_range, training_samples,
};
use super::robust::{BuildPenalty, ShiftForm, base_jacobian, spread_with, trimmed_spread};
use super::smoothing::{SmoothingInputs, append_rows, group_smoothing};
use crate::design::Design;
use crate::design::fit::FitSettings;
use crate::design::tolerance::ToleranceSpec;
use crate::design::validate::check_trimmed_weight;
use crate::elements::catalog::{Candidate, Catalog};
use crate::elements::group::Grouping;
use crate::error::{Error, Result};
use crate::geodesic::{Fan, FanSpec, RegionReport, Stop};
use crate::potential::SpringSet;
use crate::progress::Progress;
use crate::solve::lsq::{CoupledRows, Gram, from_factors};

/// A fit up to the solve: region, fans, candidates and the assembled problem. One preparation
/// serves several solves that differ only in solver settings (the spring budgets of a Pareto
/// sweep).
pub struct Prepared<'a> {
    pub(super) design: &'a Design,
    pub(super) catalog: &'a Catalog,
    pub(super) region: RegionReport,
    pub(super) training: Fan,
    pub(super) evaluation: Fan,
    /// The candidates that engage somewhere in the region.
    pub(super) candidates: Vec<Candidate>,
    /// Which candidates are one part (a cam's basis columns).
    pub(super) grouping: Grouping,
    /// Candidates the catalogue expanded into, before dropping those that never engage.
    pub(super) n_expanded: usize,
    /// The problem; its rows only where a tolerance-aware pass will read them or the normal
    /// equations of a small fit were formed from them (see [`Prepared::rows`]).
    pub(super) problem: FitProblem,
    /// What was assembled (to assemble the rows again where they were not kept).
    req: Requirements,
    /// The groups' smoothing rows appended to the problem (cams).
    appended: Option<(DMatrix<f64>, nalgebra::DVector<f64>)>,
    /// The rows, assembled again on first use where `problem` did not keep them.
    rows_again: OnceLock<DMatrix<f64>>,
    /// The candidates' mass per unit stiffness, searched on first use by a fit that weighs the
    /// mass or bounds it (`fit::mass`), on the lightest parts only.
    mass: OnceLock<MassModel>,
    /// The same with the parts built within the rollers' bound, searched on first use by a
    /// budget held on them ([`Prepared::bounded_cranks`]).
    mass_bounded: OnceLock<MassModel>,
    /// Whether a budget is held by the cranks built within the rollers' bound
    /// ([`MassModel::budget_curve`]) rather than on the lightest geometry: set by
    /// [`Prepared::hold_budget_on_bounded_cranks`] once the parts of a budgeted fit broke it.
    pub(super) bounded_cranks: bool,
    /// The catalogue's trim springs at mid-range (folded into `problem`; empty without trims).
    pub(super) trims: SpringSet,
    /// Normal equations of `problem.rows` (built once: every solve and the smoothing choice
    /// start from it).
    pub(super) gram: Gram,
    /// Seconds spent on the region check and the fans, and on the assembly.
    pub(super) t_geo: f64,
    pub(super) t_asm: f64,
}

impl<'a> Prepared<'a> {
    /// Checks the region, traces the fans, expands the catalogue and assembles the problem:
    /// the candidates that engage, the rows with the trims folded in, their normal equations,
    /// then the groups' smoothing where there are groups.
    pub fn new(
        design: &'a Design,
        catalog: &'a Catalog,
        settings: &FitSettings,
        progress: Progress<'_>,
    ) -> Result<Prepared<'a>> {
        settings.validate().map_err(|(f, r)| Error::invalid(&design.path, f, r))?;
        // A mass budget below the floor is refused before any work (a box's floor is known only
        // once its geodesics are traced: `Prepared::solve` checks it there).
        if let Some(floor) = Floor::before_work(design, settings.frequency) {
            floor.check(design, settings)?;
        }
        let t0 = Instant::now();
        progress.stage("checking the region");
        let (region, training, evaluation) = fans(design, settings)?;
        let t_geo = t0.elapsed().as_secs_f64();

        progress.stage("assembling the fit");
        let t1 = Instant::now();
        let q_eq = design.q_eq.as_slice();
        let (candidates, n_expanded) = engaging_candidates(design, catalog, settings, &training, &evaluation)?;
        let grouping = Grouping::new(candidates.iter().map(|c| (c.family, &c.element)));
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
        // Trim springs sit at mid-range in every build as drawn: the fit is solved around them.
        let (_, trims) = mid_range(catalog, q_eq);
        check_trimmed_weight(design, catalog, settings)?;
        let (mut problem, mut gram) =
            assemble_with_gram(design, settings, &training, &candidates, &grouping, &trims, req);
        let mut appended = None;
        if grouping.any() {
            progress.stage("choosing the groups' smoothing");
            let penalty = group_smoothing(&SmoothingInputs {
                design,
                catalog,
                settings,
                candidates: &candidates,
                grouping: &grouping,
                problem: &problem,
                gram: &gram,
                trims: &trims,
                extent: region.extent,
            })?;
            gram.add_sparse_rows(&penalty.0, &penalty.1);
            // Without dense rows only the right-hand side grows (the row count weighs the
            // equalities); `rows()` appends the smoothing rows to the rows it assembles again.
            append_rows(&mut problem, &penalty);
            appended = Some(penalty);
        }
        let t_asm = t1.elapsed().as_secs_f64();
        Ok(Prepared {
            design,
            catalog,
            region,
            training,
            evaluation,
            candidates,
            grouping,
            n_expanded,
            problem,
            req,
            appended,
            rows_again: OnceLock::new(),
            mass: OnceLock::new(),
            mass_bounded: OnceLock::new(),
            bounded_cranks: false,
            trims,
            gram,
            t_geo,
            t_asm,
        })
    }
}

/// The catalogue expanded over the range each coupling sweeps on both fans, the candidates that
/// never engage dropped (and, with a torque bound, those that exceed it bounded): the
/// candidates, and how many the catalogue expanded into.
fn engaging_candidates(
    design: &Design,
    catalog: &Catalog,
    settings: &FitSettings,
    training: &Fan,
    evaluation: &Fan,
) -> Result<(Vec<Candidate>, usize)> {
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
    let mut candidates: Vec<Candidate> =
        expanded.into_iter().filter(|c| engages(c, q_eq, training, evaluation)).collect();
    if settings.max_element_torque > 0.0 {
        bound_torque(&mut candidates, settings.max_element_torque, q_eq, training, evaluation);
    }
    Ok((candidates, n_expanded))
}

/// The problem assembled on the training fan with the trims folded in, and its normal
/// equations, each the cheapest way the fit's size allows.
///
/// A group's columns are zero away from its part's support (a B-spline basis function spans
/// four knot intervals): the sparse product skips the zeros. Above GRAM_BLOCK rows of two or
/// more per sample (three joints or more), G comes from the rows' factors: n − 1 times fewer
/// products (the shipped designs of up to three joints have fewer rows and keep the bits of the
/// row-by-row product). Which rows are kept, `RowsOut::for_fit` says: dense rows would be 1.7 GB
/// at seven joints and 2.4 GB for ur5_six_cams, whose first write was most of the assembly.
fn assemble_with_gram(
    design: &Design,
    settings: &FitSettings,
    training: &Fan,
    candidates: &[Candidate],
    grouping: &Grouping,
    trims: &SpringSet,
    req: Requirements,
) -> (FitProblem, Gram) {
    let rows = training_samples(training).count() * (design.dof().max(2) - 1);
    let factored = from_factors(design.dof(), rows, grouping.any());
    let tolerance = settings.tolerance != ToleranceSpec::None;
    let out = RowsOut::for_fit(design.dof(), rows, grouping.any(), !trims.elements.is_empty(), tolerance);
    let (mut problem, mut factors) = assemble_factored(&design.chain, &design.q_eq, training, candidates, req, out);
    fold_fixed(&mut problem, &design.chain, &design.q_eq, training, trims, req);
    let gram = if let Some(sparse) = factors.sparse.take() {
        Gram::from_sparse(&sparse, &problem.rhs)
    } else if grouping.any() {
        Gram::from_sparse_rows(&problem.rows, &problem.rhs)
    } else if factored {
        let c = factors.rows_times_rhs.take().unwrap_or_else(|| problem.rows.tr_mul(&problem.rhs));
        let slopes = |j: usize, s0: usize, out: &mut [f64]| factors.slopes(candidates, j, s0, out);
        let coupled = CoupledRows {
            slopes: &slopes,
            factors: &factors.factors,
            class_of: &factors.class_of,
            per_sample: design.dof() - 1,
        };
        Gram::from_coupled_rows(&coupled, c, &problem.rhs)
    } else {
        Gram::from_rows(&problem.rows, &problem.rhs)
    };
    (problem, gram)
}

impl Prepared<'_> {
    /// The assembled problem (rows, right-hand side, constraint groups).
    pub fn problem(&self) -> &FitProblem {
        &self.problem
    }

    /// The candidates' spring mass per unit stiffness and the floor (`fit::mass`), searched with
    /// the part chooser on first use, over the held-out fan at `frequency` (which every solve of
    /// one preparation shares).
    ///
    /// Read on the lightest parts alone ([`MassModel::of_catalog_lightest`]) unless `bounded`
    /// (a budget held on the cranks built within the rollers' bound, [`MassModel::of_catalog`]):
    /// the bounded reads are a second crank search per candidate that only such a budget uses.
    pub fn mass_model(&self, frequency: f64, bounded: bool) -> &MassModel {
        let (design, catalog, candidates, evaluation) = (self.design, self.catalog, &self.candidates, &self.evaluation);
        if bounded {
            self.mass_bounded.get_or_init(|| MassModel::of_catalog(design, catalog, candidates, evaluation, frequency))
        } else {
            self.mass.get_or_init(|| MassModel::of_catalog_lightest(design, catalog, candidates, evaluation, frequency))
        }
    }

    /// From now on, a budget (`[fit] max_spring_mass`) holds the cranks as the part chooser builds
    /// them within the rollers' bound ([`MassModel::budget_curve`]), not on the lightest geometry:
    /// for a budgeted fit whose parts broke the budget because `parts::choose` rebuilt its cranks
    /// within the bound (the realised design more than `ROLLER_SLACK_DEG` off its ideal elements
    /// on the lightest ones). Returns whether it changed anything (false: already set).
    pub fn hold_budget_on_bounded_cranks(&mut self) -> bool {
        !std::mem::replace(&mut self.bounded_cranks, true)
    }

    /// Back to a budget held on the lightest geometries (what a preparation starts with): for a
    /// study that solves one preparation under several budgets and holds each on the bounded
    /// cranks only where that budget's own parts broke it (`pareto`'s mass curve).
    pub fn hold_budget_on_lightest_cranks(&mut self) {
        self.bounded_cranks = false;
    }

    /// The problem's tangentiality rows: kept by the problem, or where a large fit did not keep
    /// them assembled again (the same function, so the same bits) and kept from then on.
    pub fn rows(&self) -> &DMatrix<f64> {
        if self.problem.has_rows() {
            return &self.problem.rows;
        }
        self.rows_again.get_or_init(|| {
            let design = self.design;
            let mut again = assemble(&design.chain, &design.q_eq, &self.training, &self.candidates, self.req);
            if let Some(penalty) = &self.appended {
                append_rows(&mut again, penalty);
            }
            again.rows
        })
    }

    /// The normal equations of the problem's rows.
    pub fn gram(&self) -> &Gram {
        &self.gram
    }

    /// Which candidates are one part.
    pub fn grouping(&self) -> &Grouping {
        &self.grouping
    }

    /// Sets each candidate's rate tolerance to `tolerance(candidate)` where it gives one: the
    /// chosen springs' EN 15800 tolerances for `tolerance = "parts"`. The next solve's
    /// tolerance-aware penalty and its bill use them; the assembled rows do not depend on them.
    pub fn set_tolerances(&mut self, tolerance: impl Fn(&Candidate) -> Option<f64>) {
        for c in &mut self.candidates {
            if let Some(t) = tolerance(c) {
                c.tolerance = t;
            }
        }
    }

    /// What the tolerance-aware fit adds to the normal equations, from the nominal stiffnesses
    /// `k`: the diagonal Dᵢᵢ of the springs and one block per group (one deviation per part),
    /// plus the optional shift penalty (see `fit::robust`); and the builds' expected squared
    /// equilibrium shift kᵀSk as a sum of squares, what `max_shift` bounds.
    pub(super) fn build_penalty(&self, k: &[f64], settings: &FitSettings) -> Result<(BuildPenalty, ShiftForm)> {
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
        let rows = self.rows();
        let grouping = &self.grouping;
        let sp = spread_with(chain, &self.training, (&self.candidates, grouping), rows, &nominal, &sigma2, &jac)?;
        let m = rows.nrows() as f64;
        let untrimmed = BuildPenalty::of(&sp, settings.tolerance_weight, settings.shift_weight * m);
        let shift = ShiftForm::of(&sp);
        if settings.trimmed_weight == 0.0 {
            return Ok((untrimmed, shift));
        }
        // Trimmed builds: the trims follow each build's equilibrium and are re-set there.
        let rest = arm(&self.candidates, k, &SpringSet { elements: Vec::new(), stiffness: Vec::new() });
        let (cands, omega) = (&self.candidates, settings.frequency);
        let training = &self.training;
        let tsp = trimmed_spread(
            chain,
            training,
            (cands, grouping),
            rows,
            &rest,
            &self.trims,
            &sigma2,
            omega,
            &jac,
            settings.trim_rule,
        )?;
        Ok((untrimmed.plus(BuildPenalty::of(&tsp, settings.trimmed_weight, 0.0)), shift))
    }
}

/// The region check and the two fans.
pub fn fans(design: &Design, settings: &FitSettings) -> Result<(RegionReport, Fan, Fan)> {
    let region = design.valid_region()?;
    let stop = Stop::Region { region: &design.region, max_arc: design.geodesics.max_arc };
    let ode = design.geodesics.ode;
    let training = Fan::trace(
        &design.chain,
        &design.q_eq,
        FanSpec {
            count: settings.training_count(design.dof()),
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
            count: settings.evaluation_count(design.dof()),
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
    // A part's columns stand or fall together: its smoothing ties every coefficient to its
    // neighbours, so none is dropped (a cam's knots span the fit's range anyway).
    if e.profile.member().is_some() {
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

/// `[fit] max_element_torque`: caps each spring's stiffness so that its largest torque on x over
/// the region (the equilibrium and both fans), k · max |u′|, stays within `torque` N·m. A part's
/// spring is sized by that torque (its stress, its wire), so this is the bound that keeps a part
/// possible when `springfit parts` finds none. Cams (groups) are left alone: their torque is the
/// sum of their coefficients'.
fn bound_torque(candidates: &mut [Candidate], torque: f64, q_eq: &[f64], training: &Fan, evaluation: &Fan) {
    for c in candidates.iter_mut() {
        if matches!(c.element.profile, crate::elements::Profile::Spline(_)) {
            continue;
        }
        let mut peak = c.element.profile.slope(c.element.deflection(q_eq)).abs();
        for g in training.geodesics.iter().chain(&evaluation.geodesics) {
            for i in 0..g.len() {
                peak = peak.max(c.element.profile.slope(c.element.deflection(g.q(i))).abs());
            }
        }
        if peak > 0.0 {
            let cap = torque / peak;
            c.max_stiffness = Some(c.max_stiffness.map_or(cap, |m| m.min(cap)));
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use nalgebra::{DMatrix, DVector};

    use super::*;
    use crate::fit::robust::rows_of;
    use crate::potential::Potential;
    use crate::solve::lsq::GRAM_BLOCK;

    /// Above GRAM_BLOCK rows of a three-joint arm the normal equations come from the rows'
    /// factors, and the rows are not kept: G is that of the rows assembled again, to rounding,
    /// and Aᵀb the product of those rows bit for bit.
    #[test]
    fn the_normal_equations_of_many_rows_are_those_of_the_rows() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("designs/triple_pendulum.toml");
        let design = Design::load(&path).unwrap();
        let catalog = Catalog::load(design.catalog.as_ref().unwrap(), design.dof()).unwrap();
        let settings = FitSettings { training_directions: 144, training_samples: 60, ..design.fit };
        let prepared = Prepared::new(&design, &catalog, &settings, Progress::none()).unwrap();
        assert!(!prepared.problem.has_rows(), "the rows were kept");
        let rows = prepared.rows();
        assert_eq!(rows.shape(), (prepared.problem.row_count(), prepared.candidates.len()));
        assert!(rows.nrows() > GRAM_BLOCK && !prepared.grouping.any(), "{} rows", rows.nrows());
        let want = Gram::from_rows(rows, &prepared.problem.rhs);
        let got = prepared.gram();
        assert!(got.g != want.g, "the factored product sums in another order");
        assert!((&got.g - &want.g).amax() <= 1e-12 * want.g.amax(), "{:e}", (&got.g - &want.g).amax());
        assert_eq!(got.c, rows.tr_mul(&prepared.problem.rhs));
    }

    /// A cam design's rows are read into G and, without a tolerance, dropped before the
    /// smoothing rows are appended: the row count and G are those of the fit that keeps them
    /// (a tolerance keeps them), and `rows()` assembles the same rows again, bit for bit.
    #[test]
    fn a_cam_fit_without_a_tolerance_keeps_no_rows() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("designs/double_pendulum_cams.toml");
        let design = Design::load(&path).unwrap();
        let catalog = Catalog::load(design.catalog.as_ref().unwrap(), design.dof()).unwrap();
        let bare = FitSettings { tolerance: ToleranceSpec::None, ..design.fit };
        let kept = FitSettings { tolerance: ToleranceSpec::Fraction(0.05), ..design.fit };
        let without = Prepared::new(&design, &catalog, &bare, Progress::none()).unwrap();
        let with = Prepared::new(&design, &catalog, &kept, Progress::none()).unwrap();
        assert!(without.grouping.any() && with.problem.has_rows() && !without.problem.has_rows());
        assert_eq!(without.problem.row_count(), with.problem.rows.nrows());
        assert!(with.appended.as_ref().is_some_and(|a| a.0.nrows() > 0), "no smoothing rows");
        assert_eq!(without.problem.rhs, with.problem.rhs);
        assert_eq!(without.gram, with.gram);
        assert_eq!(without.rows(), &with.problem.rows);
    }

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
        let prepared = Prepared::new(&design, &catalog, &settings, Progress::none()).unwrap();
        let (trims, mid) = mid_range(&catalog, design.q_eq.as_slice());
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
        let full = crate::fit::problem::assemble(&design.chain, &design.q_eq, &prepared.training, &all, req);
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

        let o = prepared.solve(&settings, Progress::none()).unwrap();
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
}
