//! One fit of a design, in the order the guide's "What `fit` does" tells it (the command's
//! whole pipeline, with the parts and the as-built builds, is [`crate::jobs::fit`]):
//!
//! 1. **prepare** ([`Prepared::new`]): check the region, trace a training fan of geodesics from
//!    the equilibrium and a held-out evaluation fan between its directions, expand the catalogue
//!    into candidates over the range each coupling sweeps (dropping those that never engage),
//!    group the candidates that are one part, and **assemble** the rows and constraints on the
//!    training fan, solved around the trims at mid-range (`prepare`, `problem`, `smoothing`);
//! 2. **solve** with the **selection** of at most K items (`solve`);
//! 3. with a tolerance, the **robust refit**: the nominal solution fixes J and H, then the
//!    expected residual over builds is minimised (`robust`), and solved once more with the
//!    cone of `max_shift` when that fit's builds' equilibrium shift breaks the bound;
//! 4. **evaluate** the fitted springs on the held-out fan only (`evaluate`);
//! 5. the **bill** of materials: the used elements, the trims, the parts realised (`bill`).

use std::time::Instant;

use super::bill::{BomRow, append, bill_of_materials, realise_parts, spring_set};
use super::evaluate::evaluate;
use super::hints;
use super::mass::{Floor, MassModel, MassTerm};
use super::outcome::{
    DroppedElement, DroppedWithoutPart, Evaluation, FitOutcome, ShiftAction, ShiftBound, SolveReport, SolveStatus,
    Solver, Timings, Verdict, WithoutPart,
};
use super::prepare::{Prepared, fans};
use super::robust::{BuildPenalty, ShiftCone};
use super::solve::{DROPPED, solve};
use crate::design::Design;
use crate::design::fit::{FitSettings, SolverKind};
use crate::elements::catalog::Catalog;
use crate::elements::{Element, Profile};
use crate::error::{Error, Result};
use crate::potential::{ExactPotential, Potential, SpringSet};
use crate::progress::Progress;
use crate::residual::{band_stats, fan_angles, stats};
use nalgebra::DVector;

/// Fits `design` with the elements of `catalog`. `progress` is told when each step starts (for
/// progress bars); the library itself prints nothing.
pub fn fit(design: &Design, catalog: &Catalog, settings: &FitSettings, progress: Progress<'_>) -> Result<FitOutcome> {
    let t0 = Instant::now();
    let prepared = Prepared::new(design, catalog, settings, progress)?;
    let mut outcome = prepared.solve(settings, progress)?;
    outcome.timings.total = t0.elapsed().as_secs_f64();
    Ok(outcome)
}

impl Prepared<'_> {
    /// Solves, evaluates and writes the bill with `settings` (which must agree with the
    /// preparation's in frequency, Hessian match and monotonicity; the solver, budget and
    /// weights may differ: one preparation serves every budget of a Pareto sweep).
    pub fn solve(&self, settings: &FitSettings, progress: Progress<'_>) -> Result<FitOutcome> {
        settings.validate().map_err(|(f, r)| Error::invalid(&self.design.path, f, r))?;
        if settings.max_spring_mass > 0.0 {
            Floor::on(self.design, settings.frequency, &self.evaluation).check(self.design, settings)?;
        }
        let (design, catalog) = (self.design, self.catalog);
        let q_eq = design.q_eq.as_slice();
        progress.stage("solving");
        let t2 = Instant::now();
        let (k, report) = self.solve_within_budget(settings, progress)?;
        let t_solve = t2.elapsed().as_secs_f64();

        progress.stage("evaluating on held-out geodesics");
        let t3 = Instant::now();
        // The bill of the elements above `threshold`, and how its potential does.
        let billed = |threshold: f64| -> Result<_> {
            let mut bom =
                bill_of_materials(catalog, &self.candidates, &self.grouping, &k, &self.evaluation, q_eq, threshold);
            // Trim springs (never candidates) join at mid-range: the fit was solved around them.
            append(design, catalog, &mut bom, &self.evaluation);
            let springs = spring_set(&bom);
            let metrics = evaluate(design, settings.frequency, settings.bands, &springs, &self.evaluation)?;
            Ok((bom, springs, metrics))
        };
        let (mut bom, mut springs, mut metrics) = billed(settings.used_threshold)?;
        if self.dropped_equality_share(settings, &k, &bom, &metrics) {
            // The elements the bill left out held part of the equalities (an unlimited fit of
            // hundreds of springs, some thousands of times stronger than others, where 1e-6 of
            // the strongest is a torque q_eq cannot spare): list every element of k > 0.
            (bom, springs, metrics) = billed(0.0)?;
        }
        let t_eval = t3.elapsed().as_secs_f64();
        let cams = realise_parts(catalog, &mut bom, &self.evaluation, q_eq);
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
            auto: None,
            diagnosis: None,
            dropped_without_part: None,
            trim_sizing: None,
        })
    }

    /// Leaves out of the bill the elements no part realises, and returns the fit of the rest
    /// with its parts. `fitted` is a fit of this preparation with `settings` and its parts;
    /// `choose` chooses the parts of a fit, `verdict` judges them (the elements without a part,
    /// the realised p99). An element without a part cannot be built: left in the bill, the
    /// realised design would count its ideal potential as built, and the verdict would judge a
    /// design that does not exist (or call poor one that builds well without it, as the Panda's
    /// S140 of 0.0003 N·m peak torque did). So each such spring is left out of the candidates,
    /// the fit solved again (same solver, selection and weights), its parts chosen again, and so
    /// on while a refit's parts leave new ones out, at most [`DROP_ROUNDS`] refits. The solve
    /// leaves a dropped candidate out of its unknowns ([`super::solve::is_dropped`]), so the
    /// refit takes the path of the first fit (an unlimited QP's exact NNLS with equalities keeps
    /// its sparse support). With a budget (`max_elements`) the selection still sees a dropped
    /// candidate: when it picks one, the bill has one element fewer than the budget. The bill,
    /// parts and figures are then the buildable elements', and
    /// [`FitOutcome::dropped_without_part`] names the elements dropped, their limits and the
    /// figures before and after.
    ///
    /// A refit that fails (infeasible, a numerical error) or misses the equalities the fit held
    /// is not taken: the previous bill stands, its elements without a part stay in it and the
    /// verdict names them as before (`kept` says why). A cam's follower and a trim are not
    /// candidates of the solve and are never dropped. The candidates are restored
    /// before returning: the preparation serves further solves unchanged. A fit whose every
    /// element has a part is returned as it is, bit for bit.
    pub fn drop_unbuildable<P>(
        &mut self,
        settings: &FitSettings,
        progress: Progress<'_>,
        fitted: (FitOutcome, P),
        choose: impl Fn(&FitOutcome) -> Result<P>,
        verdict: impl Fn(&P) -> Verdict,
    ) -> Result<(FitOutcome, P)> {
        let (mut outcome, mut parts) = fitted;
        let first = verdict(&parts);
        if !first.without_part.iter().any(|w| w.too_weak) {
            return Ok((outcome, parts));
        }
        let held = hints::fit_equality_warning(self.design, settings, &outcome.metrics).is_none();
        let bounds: Vec<Option<f64>> = self.candidates.iter().map(|c| c.max_stiffness).collect();
        let mut record = DroppedWithoutPart {
            elements: Vec::new(),
            rounds: 0,
            p99_deg_before: outcome.metrics.stats.p99_abs,
            p99_deg_after: outcome.metrics.stats.p99_abs,
            realised_p99_deg_before: first.p99_deg,
            realised_p99_deg_after: first.p99_deg,
            kept: None,
        };
        let mut missing = first.without_part;
        let result = loop {
            if record.rounds == DROP_ROUNDS {
                break Ok(());
            }
            let droppable = droppable(&outcome.bom, &missing);
            if droppable.is_empty() {
                break Ok(());
            }
            for c in &mut self.candidates {
                if droppable.iter().any(|(_, e)| *e == c.element) {
                    c.max_stiffness = Some(DROPPED);
                }
            }
            let n = droppable.len();
            progress.stage(&format!("refitting without the {n} element{} no part realises", plural(n)));
            let refit = match self.solve(settings, progress) {
                Ok(o) => match hints::fit_equality_warning(self.design, settings, &o.metrics).filter(|_| held) {
                    None => Ok(o),
                    Some(w) => Err(format!("the refit without them misses the equalities: {w}")),
                },
                Err(e @ (Error::Infeasible { .. } | Error::Numerical { .. })) => {
                    Err(format!("the refit without them has no solution: {e}"))
                }
                Err(e) => break Err(e),
            };
            let mut refit = match refit {
                Ok(o) => o,
                Err(why) => {
                    // The candidates' bounds are restored once, after the loop.
                    record.kept = Some(why);
                    break Ok(());
                }
            };
            progress.stage("choosing parts");
            let chosen = match choose(&refit) {
                Ok(p) => p,
                Err(e) => break Err(e),
            };
            // The refit's own solve and evaluation, and the fits before it.
            refit.timings.solve += outcome.timings.solve;
            refit.timings.evaluate += outcome.timings.evaluate;
            refit.timings.total += outcome.timings.solve + outcome.timings.evaluate;
            (outcome, parts) = (refit, chosen);
            let v = verdict(&parts);
            record.rounds += 1;
            record.elements.extend(droppable.into_iter().map(|(d, _)| d));
            record.p99_deg_after = outcome.metrics.stats.p99_abs;
            record.realised_p99_deg_after = v.p99_deg;
            missing = v.without_part;
        };
        for (c, b) in self.candidates.iter_mut().zip(bounds) {
            c.max_stiffness = b;
        }
        result?;
        if !record.elements.is_empty() || record.kept.is_some() {
            outcome.dropped_without_part = Some(record);
        }
        Ok((outcome, parts))
    }

    /// Whether the bill of `k` left out elements whose share of the equalities spoils them: a
    /// QP fit (whose equalities hold to round-off) without budget or groups (those keep their
    /// support small), whose evaluated equilibrium gradient or Hessian error crosses
    /// [`hints::EQUALITY_WARNING`] (where `springfit fit` would warn), with elements of k > 0
    /// missing from the bill. False for every fit that holds its equalities as billed.
    fn dropped_equality_share(&self, settings: &FitSettings, k: &[f64], bom: &[BomRow], m: &Evaluation) -> bool {
        if settings.solver != SolverKind::Qp || settings.max_elements != 0 || !self.grouping.groups.is_empty() {
            return false;
        }
        hints::fit_equality_warning(self.design, settings, m).is_some()
            && (0..k.len()).any(|j| k[j] > 0.0 && !bom.iter().any(|r| r.element == self.candidates[j].element))
    }

    /// [`Prepared::solve_for_the_build`] with at most `max_elements` items. The selection
    /// searches K-item sets by a least-squares objective with the equalities weighted, and the
    /// set it picks may not meet the exact constraints even when a smaller set does (the default
    /// design: K = 3 and 5 feasible, the set found for K = 4 not). A budget that can meet the
    /// constraints is never reported infeasible: the search is repeated with K − 1, K − 2, …
    /// and the first that succeeds is the answer, noted in [`SolveReport::budget_met_at`]. Only
    /// when no budget succeeds is K's own error returned. The Pareto curve uses this same
    /// search.
    fn solve_within_budget(&self, settings: &FitSettings, progress: Progress<'_>) -> Result<(Vec<f64>, SolveReport)> {
        let asked = settings.max_elements;
        let mut first_error = None;
        for budget in (1..=asked.max(1)).rev() {
            let here = FitSettings { max_elements: if asked == 0 { 0 } else { budget }, ..*settings };
            match self.solve_for_the_build(&here, progress) {
                Ok((k, mut report)) => {
                    report.budget_met_at = (budget < asked).then_some(budget);
                    return Ok((k, report));
                }
                Err(e @ Error::Infeasible { .. }) if asked > 1 => {
                    first_error.get_or_insert(e);
                    progress.stage(&format!("budget {budget} infeasible: trying {}", budget - 1));
                }
                Err(e) => return Err(first_error.unwrap_or(e)),
            }
        }
        Err(first_error.unwrap_or_else(|| Error::numerical("fit", "no budget was tried")))
    }

    /// The stiffness of every candidate: the nominal solve, and with a tolerance the robust
    /// refit for the build (see `fit::robust`).
    fn solve_for_the_build(&self, settings: &FitSettings, progress: Progress<'_>) -> Result<(Vec<f64>, SolveReport)> {
        let q_eq = self.design.q_eq.as_slice();
        let columns = (&self.candidates[..], &self.grouping);
        // The springs' mass, only where the fit weighs or bounds it: otherwise the solves are
        // today's, bit for bit, and no part is searched.
        let weighs_mass = settings.mass_weight > 0.0 || settings.max_spring_mass > 0.0;
        // The parts built within the rollers' bound are read only for a budget held on them.
        let on_bounded = settings.max_spring_mass > 0.0 && self.bounded_cranks;
        let model = weighs_mass.then(|| self.mass_model(settings.frequency, on_bounded));
        let budget = model.map(|m| m.budget(settings, on_bounded)).transpose()?.unwrap_or(0.0);
        // A budget is held on the lightest geometries, or once their parts broke it, on the cranks
        // as the part chooser rebuilt them within the rollers' bound (`MassModel::budget_curve`).
        let bounded = model.filter(|_| budget > 0.0 && on_bounded).and_then(MassModel::budget_curve);
        let term = model.map(|m| MassTerm {
            per_stiffness: bounded.as_ref().map_or(&m.per_stiffness[..], |b| &b.0[..]),
            per_stiffness_squared: bounded.as_ref().map_or(&m.per_stiffness_squared[..], |b| &b.1[..]),
            weight: MassTerm::weight(settings, self.problem.row_count(), &m.floor),
            budget,
        });
        let mass = term.as_ref();
        if settings.tolerance.is_none() {
            return solve(&self.problem, &self.gram, columns, q_eq, settings, None, mass);
        }
        if weighs_no_spread(settings) {
            // Every term of the tolerance-aware fit weighs zero and no shift bound applies: its
            // solve adds 0 to the Gram matrix, so it is the plain solve with `settings`, the same
            // stiffnesses; the nominal pass (and the penalty's retraced fans) only fed it J and H.
            let (k, mut report) = solve(&self.problem, &self.gram, columns, q_eq, settings, None, mass)?;
            report.expected_build_spread = Some(0.0);
            return Ok((k, report));
        }
        // The nominal pass only fixes J and H for the second: the single exchange search is
        // enough there.
        let first = FitSettings { restarts: 0, pair_swaps: false, ..*settings };
        let (k, nominal) = solve(&self.problem, &self.gram, columns, q_eq, &first, None, mass)?;
        progress.stage("fitting for the build tolerance");
        let (penalty, shift) = self.build_penalty(&k, settings)?;
        let (k, mut report) = solve(&self.problem, &self.gram, columns, q_eq, settings, Some(&penalty), mass)?;
        report.selection_evaluations += nominal.selection_evaluations;
        report.selection_swaps += nominal.selection_swaps;
        report.cut_rounds += nominal.cut_rounds;
        let (k, mut report) = match settings.max_shift.bound(self.region.extent) {
            Some(bound) => {
                let cone = ShiftCone { form: shift, bound };
                self.bound_shift((k, report), (&penalty, cone, mass), settings, progress)?
            }
            None => (k, report),
        };
        report.expected_build_spread = Some(penalty.value(&k));
        Ok((k, report))
    }

    /// The bound on the builds' RMS metric equilibrium shift (`max_shift`) on the tolerance-aware
    /// fit `fitted` (solved with `penalty`, no cone): returned as it is when it meets the bound,
    /// so every fit the bound does not touch stays what it was bit for bit; otherwise solved
    /// again with the cone ‖Lᵀk‖ ≤ s in the QP, the same selection first (it does not see the
    /// cone). When the cone cannot be held (NNLS, which holds no cone; the equalities need a
    /// larger shift; a solver error) the fit without it is returned and the report says why:
    /// the fit job warns, naming the softest direction's stiffness against its load.
    fn bound_shift(
        &self,
        fitted: (Vec<f64>, SolveReport),
        (penalty, cone, mass): (&BuildPenalty, ShiftCone, Option<&MassTerm<'_>>),
        settings: &FitSettings,
        progress: Progress<'_>,
    ) -> Result<(Vec<f64>, SolveReport)> {
        let (k, mut report) = fitted;
        let unbounded_rms = cone.form.rms(&k);
        let bound = cone.bound;
        let record = |report: &mut SolveReport, rms: f64, objective_ratio: f64, action: ShiftAction| {
            report.shift_bound = Some(ShiftBound { bound, unbounded_rms, rms, objective_ratio, action });
        };
        if unbounded_rms <= bound {
            record(&mut report, unbounded_rms, 1.0, ShiftAction::Inactive);
            return Ok((k, report));
        }
        if settings.solver == SolverKind::Nnls {
            let reason = "NNLS holds no cone: set solver = \"qp\" to bound the shift".to_string();
            record(&mut report, unbounded_rms, 1.0, ShiftAction::NotMet(reason));
            return Ok((k, report));
        }
        progress.stage("bounding the builds' equilibrium shift");
        let objective = |k: &[f64]| {
            let kv = DVector::from_column_slice(k);
            kv.dot(&(&self.gram.g * &kv)) + penalty.value(k) - 2.0 * self.gram.c.dot(&kv) + self.gram.bb
        };
        let coned = BuildPenalty { cone: Some(cone.clone()), ..penalty.clone() };
        let columns = (&self.candidates[..], &self.grouping);
        let q_eq = self.design.q_eq.as_slice();
        match solve(&self.problem, &self.gram, columns, q_eq, settings, Some(&coned), mass) {
            Ok((kb, mut again)) => {
                let rms = cone.form.rms(&kb);
                let ratio = objective(&kb) / objective(&k).max(f64::MIN_POSITIVE);
                again.selection_evaluations += report.selection_evaluations;
                again.selection_swaps += report.selection_swaps;
                again.cut_rounds += report.cut_rounds;
                // Clarabel's tolerance is 1e-8 on the scaled cone; 1e-6 of the bound is far beyond it.
                let action = if rms <= bound * (1.0 + 1e-6) {
                    ShiftAction::Held
                } else {
                    ShiftAction::NotMet(format!("the QP stopped at an RMS shift of {rms:.4}"))
                };
                record(&mut again, rms, ratio, action);
                Ok((kb, again))
            }
            Err(e @ (Error::Infeasible { .. } | Error::Numerical { .. })) => {
                record(&mut report, unbounded_rms, 1.0, ShiftAction::NotMet(e.to_string()));
                Ok((k, report))
            }
            Err(e) => Err(e),
        }
    }
}

/// The most refits [`Prepared::drop_unbuildable`] solves: each drops the springs the previous
/// bill's parts could not realise; one is the rule (a refit's remaining springs keep their
/// parts), the bound keeps a design whose refits keep losing parts to a known time.
pub const DROP_ROUNDS: usize = 3;

/// The elements of `missing` that can be left out of the bill `bom`, with their elements: the
/// fitted springs too weak for any part (not a trim, which the solve does not choose, nor a
/// cam, whose part is its follower), each described as the verdict names it. A spring too
/// strong for its parts stays: it carries real torque, and neither leaving it out nor capping
/// it is a small change (on the UR10 a crank of 80 N·m peak, dropped, made the springs 1.7×
/// heavier; capped at the 46 N·m its part carries, the refit moved the torque to two other
/// cranks of 420 and 790 N·m and the springs to 35.6 kg). Its remedy is the user's
/// (`max_element_torque`, a wider envelope), and the verdict names it.
fn droppable(bom: &[BomRow], missing: &[WithoutPart]) -> Vec<(DroppedElement, Element)> {
    missing
        .iter()
        .filter(|w| w.too_weak)
        .filter_map(|w| {
            let r = bom.iter().find(|r| r.id == w.id)?;
            let spring = r.adjust.trim_range.is_none() && !matches!(r.element.profile, Profile::Spline(_));
            spring.then(|| {
                let d = DroppedElement {
                    id: w.id.clone(),
                    element: r.element.label(),
                    family: r.family.clone(),
                    max_torque_nm: r.max_torque_nm,
                    reason: w.reason.clone(),
                };
                (d, r.element.clone())
            })
        })
        .collect()
}

/// Whether the tolerance-aware fit of `settings` weighs nothing: `tolerance_weight`,
/// `trimmed_weight` and `shift_weight` all 0 and no `max_shift` bound (the shipped URDF designs
/// fit the drawing so, `tolerance_weight = 0`). Its penalty is then zero, and the fit the plain
/// solve: [`Prepared::solve_for_the_build`] skips the nominal pass that would only fix J and H
/// for it (half the solves of such a fit).
fn weighs_no_spread(settings: &FitSettings) -> bool {
    settings.tolerance_weight == 0.0
        && settings.trimmed_weight == 0.0
        && settings.shift_weight == 0.0
        && matches!(settings.max_shift, crate::design::fit::MaxShift::None)
}

/// `s` for a plural count.
fn plural(n: usize) -> &'static str {
    if n == 1 { "" } else { "s" }
}

/// The exact reference U* = ½ω²r² evaluated like a fit (no springs, no bill of materials).
pub fn exact_reference(design: &Design, settings: &FitSettings, progress: Progress<'_>) -> Result<FitOutcome> {
    settings.validate().map_err(|(f, r)| Error::invalid(&design.path, f, r))?;
    let t0 = Instant::now();
    progress.stage("checking the region");
    let (region, training, evaluation) = fans(design, settings)?;
    let t_geo = t0.elapsed().as_secs_f64();
    progress.stage("evaluating the exact potential (log map per sample)");
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
            solver: Solver::Exact,
            status: SolveStatus::Reference,
            selection_evaluations: 0,
            selection_swaps: 0,
            cut_rounds: 0,
            expected_build_spread: None,
            budget_met_at: None,
            shift_bound: None,
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
        auto: None,
        diagnosis: None,
        dropped_without_part: None,
        trim_sizing: None,
    })
}
