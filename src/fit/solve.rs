//! The solve: the selection of at most K items, then NNLS or the QP on the chosen columns, with a
//! group's ± pairs merged into signed unknowns where the solver takes them.
//!
//! The fit's columns are the candidates; a [`Grouping`] says which of them are one part. The
//! selection counts a part as one item; the solvers see each of its (+, −) column pairs either
//! as two non-negative unknowns (NNLS) or as one signed unknown (the QP, and the smoothing
//! choice), see [`signed_unknowns`].

use nalgebra::{DMatrix, DVector};

use super::mass::MassTerm;
use super::outcome::{SolveReport, SolveStatus};
use super::problem::FitProblem;
use super::problem::unit_preloads;
use super::robust::{BuildPenalty, ShiftCone};
use crate::design::fit::{FitSettings, SolverKind};

use crate::elements::catalog::Candidate;
use crate::elements::group::{Columns, Grouping};
use crate::error::{Error, Result};
use crate::solve::LinearGroup;
use crate::solve::lawson_hanson::nnls_equalities;
use crate::solve::lsq::Gram;
use crate::solve::nnls::{NnlsSettings, nnls, nnls_bounded};
use crate::solve::qp::{NormBound, QpSettings, QpStatus, qp_cone, qp_signed};
use crate::solve::screen::qp_screened;
use crate::solve::selection::{
    Items, SelectionSettings, SubsetBudget, backward_elimination, budget_bounds, budget_multiplier, extension_bounds,
    search, select_from, subset_nnls, subset_nnls_warm, subset_nnls_within,
};

/// Largest equality residual (scaled units: ω²·mean diag M(q_eq)) NNLS may leave before the fit
/// counts as infeasible.
const NNLS_EQUALITY_TOLERANCE: f64 = 1e-3;

/// From this many unknowns (springs only, no cam coefficients) the QP is solved by the
/// Lawson–Hanson iteration with exact equalities ([`crate::solve::lawson_hanson`]) when k ≥ 0 and
/// the equalities are its only constraints, else on a working set ([`crate::solve::screen`]),
/// instead of by Clarabel over all of them. Above the 402 candidates
/// of the shipped dense designs, whose fits stay as they were; BENCHMARKS.md "Fit time against
/// the number of joints" has the measurement.
const SCREEN_FROM: usize = 600;

/// Solves the assembled problem with the chosen solver and, with `max_elements`, the sparse
/// selection. Returns the stiffness of every candidate.
///
/// `extra` is added to the normal equations (the tolerance-aware fit's expected spread of the
/// builds: a diagonal for the springs, a block per group): every solver and the selection
/// minimise the same objective. `mass` adds the springs' mass (`fit::mass`): its weight λ·Σ mᵢ(kᵢ)
/// moves the right-hand side and G's diagonal, for every solver and the selection alike; its budget Σ mᵢ(kᵢ) ≤ M is
/// an inequality of the QP when the model is a straight line. Otherwise (and always for NNLS),
/// when the fit at λ is over the budget, the selection chooses again with every support refitted
/// within the budget (supports compared at equal mass, not at one trade of residual for mass)
/// and the chosen support is solved at the least λ′ ≥ λ that brings it within (bisection on the
/// multiplier). Without `mass` nothing changes, bit for bit. A cone in `extra` (the bound on the
/// builds' equilibrium shift) is held by the QP on the selected columns; the selection and NNLS
/// do not see it (`fit::run` reports when it is not held).
pub fn solve(
    problem: &FitProblem,
    gram: &Gram,
    columns: Columns<'_>,
    q_eq: &[f64],
    settings: &FitSettings,
    extra: Option<&BuildPenalty>,
    mass: Option<&MassTerm<'_>>,
) -> Result<(Vec<f64>, SolveReport)> {
    let mut gram = gram.clone();
    if let Some(d) = extra {
        d.add_to(&mut gram.g);
    }
    let signed = settings.solver == SolverKind::Qp;
    let cone = extra.and_then(|e| e.cone.as_ref());
    let Some(m) = mass else {
        return solve_gram_with(problem, gram, columns, q_eq, settings, signed, (None, None, cone));
    };
    // The QP's signed cam coefficients would be charged λ·a·cⱼ, not λ·a·|cⱼ|: there cams weigh
    // nothing (fit::mass), in the term, the budget row and the budget's check alike.
    let uncharged: Vec<f64>;
    let cams_free;
    let m = if signed && columns.1.any() {
        uncharged =
            m.per_stiffness.iter().zip(&columns.1.of).map(|(&a, g)| if g.is_some() { 0.0 } else { a }).collect();
        cams_free = MassTerm { per_stiffness: &uncharged, ..*m };
        &cams_free
    } else {
        m
    };
    // The QP holds a straight-line budget as a row; a curved one, like NNLS, by raising λ.
    let qp_budget = (m.budget > 0.0 && settings.solver == SolverKind::Qp && !m.curved()).then_some(m);
    let first = solve_gram_with(
        problem,
        weighed(&gram, m, m.weight),
        columns,
        q_eq,
        settings,
        signed,
        (qp_budget, None, cone),
    )?;
    let within = |k: &[f64]| m.mass(k) <= m.budget * (1.0 + 1e-9);
    if m.budget <= 0.0 || qp_budget.is_some() || within(&first.0) {
        return Ok(first);
    }
    // Over the budget. The selection chooses again, comparing supports by their refits within
    // the budget (`subset_nnls_within`: each its own multiplier), and the chosen support is then
    // solved at the least λ′ ≥ λ that brings it within the budget. Raising one λ for the
    // selection too (as before) compared every support at the multiplier of the chosen one, an
    // even trade of residual for mass that passed over accurate supports near the budget.
    let weighted = with_equalities(&weighed(&gram, m, m.weight), &problem.equalities, problem.row_count(), settings);
    let limit = SubsetBudget { linear: m.per_stiffness, squared: m.per_stiffness_squared, max: m.budget };
    let mut chosen_report = first.1.clone();
    let support = select(&weighted, columns.1, settings, &mut chosen_report, Some(&limit))?;
    let on_support = |weight: f64| {
        solve_gram_with(
            problem,
            weighed(&gram, m, weight),
            columns,
            q_eq,
            settings,
            signed,
            (None, Some(&support), cone),
        )
    };
    // The bisection's bracket starts from λ per kg of the order of the residual of no springs over
    // the budget; where the rows have no right-hand side (an arm without gravity or trims), that
    // of 1° on every row: `mass_weight`'s scale (fit::mass).
    let scale = if gram.bb > 0.0 { 0.5 * gram.bb } else { MassTerm::residual_scale(problem.row_count()) };
    let (k, mut report) = least_weight_within(on_support, m, scale, settings)?;
    report.selection_evaluations = chosen_report.selection_evaluations;
    report.selection_swaps = chosen_report.selection_swaps;
    Ok((k, report))
}

/// `gram` with the mass term at weight λ = `weight`: c − λa, and 2λbᵢ on G's diagonal.
fn weighed(gram: &Gram, m: &MassTerm<'_>, weight: f64) -> Gram {
    let mut shifted = gram.clone();
    if weight > 0.0 {
        shifted.c -= m.shift(weight);
        m.bend(weight, &mut shifted.g);
    }
    shifted
}

/// The solution at the least weight λ′ ≥ λ (`m.weight`) whose solution by `at` is within the
/// budget: bracketed from λ per kg of `scale` (an objective) over the budget, grown 4× a step, then bisected to [`BUDGET_PRECISION`]; the bracket's upper end is
/// returned, so the answer is always within the budget.
fn least_weight_within<F>(
    at: F,
    m: &MassTerm<'_>,
    scale: f64,
    settings: &FitSettings,
) -> Result<(Vec<f64>, SolveReport)>
where
    F: Fn(f64) -> Result<(Vec<f64>, SolveReport)>,
{
    let within = |k: &[f64]| m.mass(k) <= m.budget * (1.0 + 1e-9);
    let first = at(m.weight)?;
    if within(&first.0) {
        return Ok(first);
    }
    let (mut lo, mut hi) = (m.weight, m.weight.max(scale / m.budget));
    let mut best = None;
    for _ in 0..BUDGET_STEPS {
        let here = at(hi)?;
        if within(&here.0) {
            best = Some(here);
            break;
        }
        (lo, hi) = (hi, 4.0 * hi);
    }
    let Some(mut best) = best else {
        return Err(Error::Infeasible {
            constraint: format!(
                "max_spring_mass ({} kg left for the fitted springs, the trims' parts taken off)",
                m.budget
            ),
            reason: format!(
                "the {} solver cannot bring the springs within it at any mass weight (the least it reached is {:.3} kg): the equalities need more steel than the budget; raise max_spring_mass",
                settings.solver.name(),
                m.mass(&at(hi)?.0)
            ),
        });
    };
    for _ in 0..BUDGET_STEPS {
        if hi - lo <= BUDGET_PRECISION * hi {
            break;
        }
        let mid = 0.5 * (lo + hi);
        let here = at(mid)?;
        if within(&here.0) {
            (hi, best) = (mid, here);
        } else {
            lo = mid;
        }
    }
    Ok(best)
}

/// Steps of the search for the mass weight that meets `max_spring_mass`: growth by 4× to
/// bracket it, then bisection to `BUDGET_PRECISION`.
const BUDGET_STEPS: usize = 40;

/// Relative width at which the bisection on the mass weight stops. The solution it returns is
/// always within the budget (the bracket's upper end); 1e-3 of λ moves the mass by far less
/// than the parts' own discreteness (wire sizes), and each step is a whole fit with its
/// selection, so a tighter bisection costs fits for digits no part can show.
const BUDGET_PRECISION: f64 = 1e-3;

/// `gram` (of `rows` rows) with the equalities folded in at weight W per row: a violation δ of
/// an equation costs as much as δ / equality_weight of residual on every tangentiality row.
pub fn with_equalities(gram: &Gram, equalities: &[LinearGroup], rows: usize, settings: &FitSettings) -> Gram {
    let weight = settings.equality_weight * (rows.max(1) as f64).sqrt();
    let mut weighted = gram.clone();
    for eq in equalities {
        weighted.add_weighted(&eq.matrix, &eq.rhs, weight);
    }
    weighted
}

/// The columns the NNLS solution of the weighted problem ([`with_equalities`]) uses: where the
/// exact solves of many springs start.
pub fn nnls_support(
    gram: &Gram,
    equalities: &[LinearGroup],
    rows: usize,
    settings: &FitSettings,
) -> Result<Vec<usize>> {
    let start = nnls(&with_equalities(gram, equalities, rows, settings), settings.l1, &NnlsSettings::default())?;
    Ok((0..gram.dim()).filter(|&a| start.k[a] > 0.0).collect())
}

/// [`solve`] with the Gram matrix of the problem's rows given (the smoothing choice adds its
/// penalty to one Gram matrix instead of rebuilding it per weight), choosing whether the groups'
/// coefficients are signed unknowns (`signed`) or kept as non-negative ± column pairs.
pub fn solve_gram(
    problem: &FitProblem,
    gram: Gram,
    columns: Columns<'_>,
    q_eq: &[f64],
    settings: &FitSettings,
    signed: bool,
) -> Result<(Vec<f64>, SolveReport)> {
    solve_gram_with(problem, gram, columns, q_eq, settings, signed, (None, None, None))
}

/// [`solve_gram`] with the QP bounding the springs' mass by `budget`'s cᵀk ≤ M and the builds'
/// equilibrium shift by `cone`, and with the selection unless `chosen` gives the support (the
/// columns a selection returned).
fn solve_gram_with(
    problem: &FitProblem,
    gram: Gram,
    (candidates, grouping): Columns<'_>,
    q_eq: &[f64],
    settings: &FitSettings,
    signed: bool,
    (budget, chosen, cone): (Option<&MassTerm<'_>>, Option<&[usize]>, Option<&ShiftCone>),
) -> Result<(Vec<f64>, SolveReport)> {
    let p = candidates.len();
    let weighted = with_equalities(&gram, &problem.equalities, problem.row_count(), settings);
    let mut report = SolveReport {
        solver: settings.solver.into(),
        status: SolveStatus::Solved,
        selection_evaluations: 0,
        selection_swaps: 0,
        cut_rounds: 0,
        expected_build_spread: None,
        budget_met_at: None,
        shift_bound: None,
    };
    let support = match chosen {
        Some(support) => support.to_vec(),
        None => select(&weighted, grouping, settings, &mut report, None)?,
    };
    // A candidate left out of the bill (no part realises it) is no unknown: the rest is solved
    // as if the catalogue lacked it, on the same path as any fit.
    let support: Vec<usize> = support.into_iter().filter(|&j| !is_dropped(&candidates[j])).collect();
    // The QP sees one signed unknown per group coefficient instead of its ± column pair (see
    // `signed_unknowns`). NNLS keeps the pairs: its active set starts from zero and brings in
    // only the columns the fit needs, which keeps parts that could cancel each other small (four
    // cams on the ball r = 2 as built at ±5 %: p99 p95 4.8° with the pairs, 15.4° with signed
    // unknowns solved exactly, at the same accuracy as drawn).
    let unknowns = if signed {
        signed_unknowns(grouping, &support)
    } else {
        let n = support.len();
        Unknowns { columns: support, signed: vec![false; n], pinned: Vec::new() }
    };
    let upper: Vec<Option<f64>> = unknowns.columns.iter().map(|&j| candidates[j].max_stiffness).collect();
    let unit = unit_preloads(candidates, q_eq);
    let k_sub = match settings.solver {
        SolverKind::Nnls => solve_nnls(problem, &weighted, &unknowns, &upper, &unit, settings)?,
        SolverKind::Qp => solve_qp(problem, &gram, &unknowns, (&upper, &unit, budget), cone, settings, &mut report)?,
    };
    Ok((unknowns.stiffnesses(grouping, p, &k_sub), report))
}

/// The `max_stiffness` of a candidate left out of the bill because no part realises it
/// ([`crate::fit::Prepared::drop_unbuildable`]): a catalogue's `max_stiffness` must be positive,
/// so no family gives it.
pub const DROPPED: f64 = 0.0;

/// Whether `c` was left out of the bill ([`DROPPED`]): the solve leaves it at zero.
pub fn is_dropped(c: &Candidate) -> bool {
    c.max_stiffness == Some(DROPPED)
}

/// Multipliers of the budget's start path ([`select`]): μ·4ʲ for j below this, μ the budget's
/// multiplier on the dense solution.
const LAMBDA_PATH: usize = 5;

/// The columns of the items a budget of `max_elements` keeps (every column without a budget):
/// backward elimination from the dense NNLS solution, then exchange moves, pair swaps and
/// restarts ([`crate::solve::selection`]). A group is one item. With `budget` every support is
/// refitted within it ([`subset_nnls_within`]), so supports are compared at equal mass.
fn select(
    weighted: &Gram,
    grouping: &Grouping,
    settings: &FitSettings,
    report: &mut SolveReport,
    budget: Option<&SubsetBudget<'_>>,
) -> Result<Vec<usize>> {
    let items = Items::from_groups(&grouping.of);
    if settings.max_elements == 0 || settings.max_elements >= items.len() {
        return Ok((0..grouping.of.len()).collect());
    }
    let dense = nnls(weighted, 0.0, &NnlsSettings::default())?;
    let mut pool = items.touching(|j| dense.k[j] > 0.0);
    let start = match budget {
        None => backward_elimination(weighted, &items, pool.clone(), settings.max_elements)?,
        Some(b) => {
            // Under a budget that binds, the unconstrained dense solution's elements are the heavy
            // ones: the start is eliminated from the dense solution within the budget instead
            // (at its multiplier), and the restarts draw from both supports.
            let all: Vec<usize> = (0..items.len()).collect();
            let every: Vec<usize> = (0..grouping.of.len()).collect();
            let mu = budget_multiplier(weighted, &items, &all, b)?;
            // A path of multipliers from the budget's up (×4 a step, `LAMBDA_PATH` of them): the
            // mass term is a weighted ℓ1 on k, so the heavier the multiplier the sparser and
            // lighter the dense solution, and the set eliminated from it is another start. Each
            // start is refitted within the budget and the best (ties: the lowest multiplier) is
            // the search's; every start's dense support joins the restarts' pool.
            let steps = if mu.is_finite() && mu > 0.0 { LAMBDA_PATH } else { 1 };
            let mut best: Option<(f64, Vec<usize>)> = None;
            for step in 0..steps {
                let at = mu * 4f64.powi(step as i32);
                let light = if at.is_finite() { b.weigh(weighted, &every, at) } else { weighted.clone() };
                let dense = nnls(&light, 0.0, &NnlsSettings::default())?;
                let near = items.touching(|j| dense.k[j] > 0.0);
                let start = backward_elimination(&light, &items, near.clone(), settings.max_elements)?;
                pool.extend(near);
                let (objective, _) = subset_nnls_within(weighted, &items, &start, b)?;
                if best.as_ref().is_none_or(|(o, _)| objective < *o) {
                    best = Some((objective, start));
                }
            }
            pool.sort_unstable();
            pool.dedup();
            best.map(|(_, s)| s).unwrap_or_default()
        }
    };
    let sel_settings = SelectionSettings {
        max_elements: settings.max_elements,
        swap_passes: settings.swap_passes,
        restarts: settings.restarts,
        pair_swaps: settings.pair_swaps,
        seed: settings.seed,
    };
    let n = items.len();
    let bound = |s: &[usize]| extension_bounds(weighted, &items, s);
    let sel = match budget {
        Some(b) if settings.restarts == 0 && !settings.pair_swaps => {
            select_from(n, sel_settings, start, |s| subset_nnls_within(weighted, &items, s, b))?
        }
        Some(b) => {
            // The refits within the budget are bounded by duality at the base's multiplier
            // (`budget_bounds`): the unconstrained bounds are far below them when it binds.
            let within = |s: &[usize]| budget_bounds(weighted, &items, s, b);
            search(n, sel_settings, start, &pool, |s| subset_nnls_within(weighted, &items, s, b), Some(&within))?
        }
        // The single exchange search, with cold-started refits as before restarts existed.
        None if settings.restarts == 0 && !settings.pair_swaps => {
            select_from(n, sel_settings, start, |s| subset_nnls(weighted, &items, s))?
        }
        None => search(n, sel_settings, start, &pool, |s| subset_nnls_warm(weighted, &items, s), Some(&bound))?,
    };
    report.selection_evaluations = sel.evaluations;
    report.selection_swaps = sel.swaps;
    Ok(items.columns(&sel.support))
}

/// NNLS (equalities weighted into `weighted`) on the unknowns, with the bounds by
/// clamp-and-refit; the preload bound and the equalities checked after, since NNLS can miss
/// them silently.
fn solve_nnls(
    problem: &FitProblem,
    weighted: &Gram,
    unknowns: &Unknowns,
    upper: &[Option<f64>],
    unit: &[f64],
    settings: &FitSettings,
) -> Result<DVector<f64>> {
    let support = &unknowns.columns;
    let k = nnls_bounded(&weighted.subset(support), settings.l1, upper, &unknowns.signed)?;
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
    Ok(k)
}

/// The Clarabel QP on the unknowns: equalities exact, monotonicity by cutting planes, the
/// preload bound Σ|τᵢ(q_eq)| ≤ P as one more inequality, the shift bound ‖Lᵀk‖ ≤ s as a cone.
#[allow(clippy::too_many_arguments)]
fn solve_qp(
    problem: &FitProblem,
    gram: &Gram,
    unknowns: &Unknowns,
    (upper, unit, budget): (&[Option<f64>], &[f64], Option<&MassTerm<'_>>),
    cone: Option<&ShiftCone>,
    settings: &FitSettings,
    report: &mut SolveReport,
) -> Result<DVector<f64>> {
    let support = &unknowns.columns;
    let p = unit.len();
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
    if settings.max_preload > 0.0 && unknowns.signed.iter().any(|&f| f) {
        // |τ| of a signed coefficient is not linear in it.
        return Err(Error::Infeasible {
            constraint: format!("max_preload ({} N·m)", settings.max_preload),
            reason: "the QP bounds the preload of springs only, and the catalogue has cams: set max_preload = 0".into(),
        });
    }
    if settings.max_preload > 0.0 {
        // Σ|pᵢ| kᵢ ≤ P: preload is linear in k with a fixed sign per element. Scaled by 1/P so
        // the cutting-plane margin is relative.
        let p_max = settings.max_preload;
        inequalities.push(LinearGroup {
            name: "preload bound".into(),
            description: format!("Σ|τᵢ(q_eq)| ≤ {p_max} N·m (max_preload)"),
            matrix: DMatrix::from_fn(1, p, |_, j| -unit[j].abs() / p_max),
            rhs: DVector::from_element(1, -1.0),
        });
    }
    if let Some(m) = budget {
        // cᵀk ≤ M, scaled by 1/M like the preload bound. Under the QP a cam's coefficients weigh
        // nothing (`solve`), so the row is linear in signed unknowns too.
        let m_max = m.budget;
        inequalities.push(LinearGroup {
            name: "spring mass budget".into(),
            description: format!("Σ cᵢ kᵢ ≤ {m_max} kg (max_spring_mass less the trims' parts)"),
            matrix: DMatrix::from_fn(1, p, |_, j| -m.per_stiffness[j] / m_max),
            rhs: DVector::from_element(1, -1.0),
        });
    }
    let (sub, equalities, inequalities) =
        (gram.subset(support), restrict(&problem.equalities), restrict(&inequalities));
    let sol = if let Some(c) = cone {
        // The cone on the support's unknowns: Clarabel over all of them (the screened and
        // active-set paths know linear rows only).
        let bound = NormBound {
            factor: c.form.factor_on(support),
            bound: c.bound,
            name: format!("max_shift (the builds' RMS metric equilibrium shift ≤ {:.4})", c.bound),
        };
        let (groups, l1) = ((&equalities[..], &inequalities[..]), settings.l1);
        qp_cone(&sub, groups, upper, &unknowns.signed, l1, &QpSettings::default(), Some(&bound))?
    } else if support.len() >= SCREEN_FROM && !unknowns.signed.iter().any(|&f| f) {
        // Many springs: started from the weighted NNLS support.
        let start = nnls_support(&sub, &equalities, problem.row_count(), settings)?;
        // Only k ≥ 0 and exact equalities: an active-set NNLS on an updated Cholesky factor is
        // exact and far cheaper than interior-point iterations on the whole Gram matrix. It
        // reports None when it cannot vouch for its answer; Clarabel then takes over.
        let bounds_only = inequalities.is_empty() && upper.iter().all(Option::is_none);
        match bounds_only.then(|| nnls_equalities(&sub, &equalities, settings.l1, &start)).flatten() {
            Some(solution) => solution,
            None => {
                qp_screened(&sub, &equalities, &inequalities, upper, settings.l1, &QpSettings::default(), &start)?
                    .solution
            }
        }
    } else {
        qp_signed(&sub, &equalities, &inequalities, upper, &unknowns.signed, settings.l1, &QpSettings::default())?
    };
    report.cut_rounds = sol.cut_rounds;
    if sol.status == QpStatus::AlmostSolved {
        report.status = SolveStatus::AlmostSolved;
    }
    Ok(sol.k)
}

/// The solver's unknowns over a support of columns.
#[derive(Debug, Clone, PartialEq)]
pub struct Unknowns {
    /// The column of each unknown (a signed unknown sits on its + column).
    pub columns: Vec<usize>,
    /// Whether each unknown is free of sign.
    pub signed: Vec<bool>,
    /// The plus columns of coefficients pinned at 0 (one per group whose whole ± basis is in play
    /// and whose coefficients have a uniform gauge).
    pub pinned: Vec<usize>,
}

impl Unknowns {
    /// The stiffness of every one of the `p` columns from the unknowns' values: signed
    /// coefficients split back into their ± pair (one of the two zero), a group with a pinned
    /// coefficient shifted to zero mean first (the same torque, and the same coefficients
    /// whichever was pinned).
    pub fn stiffnesses(&self, grouping: &Grouping, p: usize, values: &DVector<f64>) -> Vec<f64> {
        let minus = grouping.minus_of();
        let mut k = vec![0.0; p];
        // Signed coefficients by + column, the pinned ones at 0.
        let mut coef: Vec<Option<f64>> = vec![None; p];
        for &j in &self.pinned {
            coef[j] = Some(0.0);
        }
        for (a, &j) in self.columns.iter().enumerate() {
            if self.signed[a] {
                coef[j] = Some(values[a]);
            } else {
                k[j] = values[a];
            }
        }
        for &j0 in &self.pinned {
            let Some(g) = grouping.of[j0] else { continue };
            let members: Vec<usize> =
                grouping.groups[g].columns.iter().copied().filter(|&j| coef[j].is_some()).collect();
            let mean = members.iter().filter_map(|&j| coef[j]).sum::<f64>() / members.len() as f64;
            for &j in &members {
                coef[j] = coef[j].map(|c| c - mean);
            }
        }
        for j in 0..p {
            if let (Some(c), Some(neg)) = (coef[j], minus[j]) {
                // c = k⁺ − k⁻ with one of them zero.
                k[j] = c.max(0.0);
                k[neg] = (-c).max(0.0);
            }
        }
        k
    }
}

/// The solver's unknowns for the columns `support`: every column outside a pair (k ≥ 0), and for
/// each group coefficient whose ± columns are both in the support one signed unknown cⱼ on its
/// plus column, the minus column dropped. The pair spans the same potentials, but it adds a direction
/// that changes no residual (k⁺ and k⁻ grown together): the optimum is a ray, along which
/// active-set steps wander and an interior-point solver stops numerically (a ridge on the
/// coefficients bounded it before, but any ridge large enough to matter numerically also biased
/// the fit: 1e-7 relative raised the window's p99 from 0.55° to 0.83°). Signed unknowns remove
/// it, halve the group columns, and with no springs in the catalogue NNLS becomes one linear
/// solve.
///
/// The other such direction is a group's uniform gauge (a cam: Σⱼ Bⱼ = 1 everywhere, see
/// [`crate::elements::spline`], so adding t to every coefficient changes no torque, no smoothing
/// row and no condition). When a group's whole signed basis is in the support its first
/// coefficient is therefore pinned at 0 (dropped from the unknowns): the others still span every
/// torque profile, and no ridge is needed. [`Unknowns::stiffnesses`] shifts the answer back to
/// zero mean per group.
pub fn signed_unknowns(grouping: &Grouping, support: &[usize]) -> Unknowns {
    let minus = grouping.minus_of();
    let coefficient = grouping.coefficient_of();
    let in_support: std::collections::HashSet<usize> = support.iter().copied().collect();
    let paired: std::collections::HashSet<usize> =
        support.iter().filter_map(|&j| minus[j].filter(|n| in_support.contains(n))).collect();
    let signed = |j: usize| minus[j].is_some_and(|n| paired.contains(&n));
    // Per group: signed coefficients in the support, and the + column of its first coefficient.
    let mut count: Vec<(usize, Option<usize>)> = vec![(0, None); grouping.groups.len()];
    for &j in support.iter().filter(|&&j| signed(j)) {
        let (Some(g), Some((c, _))) = (grouping.of[j], coefficient[j]) else { continue };
        count[g].0 += 1;
        if c == 0 {
            count[g].1 = Some(j);
        }
    }
    let mut pinned: Vec<usize> = count
        .iter()
        .zip(&grouping.groups)
        .filter_map(|(&(n, first), group)| (group.uniform_gauge() && n == group.pairs.len()).then_some(first?))
        .collect();
    pinned.sort_unstable();
    let columns: Vec<usize> = support.iter().copied().filter(|j| !paired.contains(j) && !pinned.contains(j)).collect();
    let signed = columns.iter().map(|&j| signed(j)).collect();
    Unknowns { columns, signed, pinned }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;
    use crate::elements::catalog::Candidate;
    use crate::elements::spline::Knots;
    use crate::elements::{Element, Profile};
    use crate::fit::problem::{Requirements, assemble};
    use crate::geodesic::{Fan, FanSpec, Stop};
    use crate::model::Chain;
    use crate::numerics::ode::OdeSettings;

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
            let grouping = Grouping::new(candidates.iter().map(|c| (c.family, &c.element)));
            let (k, _) =
                solve(&problem, &gram, (&candidates, &grouping), q_eq.as_slice(), &settings, None, None).unwrap();
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
