//! The fit as a convex quadratic program solved by Clarabel: constraints exact.
//!
//! minimise ½ kᵀGk − (c − λ1)ᵀk subject to the equality groups, k ≥ 0, k ≤ u and the
//! inequality groups G_in k ≥ h. Columns are scaled to unit diagonal of G first. Large
//! inequality groups (monotonicity on thousands of samples) are handled by cutting planes: solve
//! without them, add the rows the solution violates, re-solve, until none is violated — Clarabel
//! given every row at once can stop with a numerical error, and only a handful are ever active.
//! When the problem is infeasible the groups are dropped one at a time to name the culprit.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use nalgebra::{DMatrix, DVector};

use super::constraint::LinearGroup;
use super::lsq::Gram;
use crate::error::{Error, Result};

/// Settings of the QP solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QpSettings {
    /// Interior-point iterations per solve.
    pub max_iterations: u32,
    /// Feasibility and gap tolerance.
    pub tolerance: f64,
    /// Most cutting-plane rounds.
    pub cut_rounds: usize,
    /// Most violated rows added per round.
    pub cuts_per_round: usize,
    /// A row counts as violated below −margin (scaled units).
    pub cut_margin: f64,
}

impl Default for QpSettings {
    fn default() -> Self {
        QpSettings { max_iterations: 200, tolerance: 1e-8, cut_rounds: 30, cuts_per_round: 200, cut_margin: 1e-9 }
    }
}

/// Ridge added to the scaled Hessian (see [`Scaled::new`]).
const RIDGE: f64 = 1e-10;

/// From this many unknowns the factor form's Cholesky is faer's: 1.7× nalgebra's at 32, 3.6× at
/// 402 (the dense fits: 2.25 ms → 0.62 ms), 5× at 1024 (`cargo bench --bench kernels`). Clarabel's
/// iterates then differ in the last bits, but the answers of the large QPs are the polished
/// vertices and every shipped design's outputs stay byte-identical. Below it nalgebra's: the
/// two take at most 2.5 µs there, and the sparse fits' final QPs over their 10–16 chosen springs
/// sometimes keep Clarabel's point (with faer's factor at 12 unknowns `double_pendulum_straight`
/// moved by 7e-11).
const FAER_CHOLESKY_FROM: usize = 32;

/// KKT systems of at least this many rows are solved by faer's blocked LU, not nalgebra's
/// (`kkt_solve`): faer's rounding moves polished vertices in their last bits, so the threshold
/// sits above every shipped design's systems (the largest, `ur5_six_cams`' 40 cams of 32 coefficients, has
/// 1,280 signed unknowns and a few rows), where nalgebra's unblocked factor costs tens of seconds a solve.
pub const FAER_KKT_FROM: usize = 2000;

/// How a QP solve ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum QpStatus {
    /// Solved to tolerance.
    Solved,
    /// Solved to Clarabel's reduced tolerance.
    AlmostSolved,
}

/// A QP solution.
#[derive(Debug, Clone, PartialEq)]
pub struct QpSolution {
    /// Stiffnesses (≥ 0 up to the solver tolerance; tiny negatives clamped to 0).
    pub k: DVector<f64>,
    /// How it ended.
    pub status: QpStatus,
    /// Interior-point iterations over all rounds.
    pub iterations: u32,
    /// Cutting-plane rounds.
    pub cut_rounds: usize,
    /// Inequality rows in the last solve.
    pub cuts: usize,
    /// Largest violation of an equality (scaled units).
    pub max_equality_residual: f64,
}

/// Solves the QP (see the module docs). `upper[j]` = None means unbounded.
pub fn qp(
    gram: &Gram,
    equalities: &[LinearGroup],
    inequalities: &[LinearGroup],
    upper: &[Option<f64>],
    l1: f64,
    settings: &QpSettings,
) -> Result<QpSolution> {
    qp_signed(gram, equalities, inequalities, upper, &[], l1, settings)
}

/// [`qp`] with some unknowns free of sign (`free[j]`; an empty slice means none): a cam's
/// B-spline coefficients. A free unknown has no k ≥ 0 row, its bound `upper[j]` = u means
/// |x| ≤ u, and the L1 weight does not apply to it (it would not be linear there).
///
/// Why free unknowns rather than ± column pairs: with cⱼ = k⁺ⱼ − k⁻ⱼ every pair adds a direction
/// (k⁺ⱼ, k⁻ⱼ) + t(1, 1) along which nothing changes but the tiny ridge, so the optimum sits at
/// the end of a nearly flat valley and an interior-point method, which keeps every pair strictly
/// inside k ≥ 0, converges there slowly or stops with a numerical error. One signed unknown per
/// coefficient removes those directions, halves the unknowns and needs no sign rows.
pub fn qp_signed(
    gram: &Gram,
    equalities: &[LinearGroup],
    inequalities: &[LinearGroup],
    upper: &[Option<f64>],
    free: &[bool],
    l1: f64,
    settings: &QpSettings,
) -> Result<QpSolution> {
    qp_cone(gram, (equalities, inequalities), upper, free, l1, settings, None)
}

/// A second-order cone ‖F k‖ ≤ s on the unknowns: what [`qp_cone`] adds to the QP (the fit's
/// bound on the builds' equilibrium shift, `fit::robust::ShiftCone`).
#[derive(Debug, Clone, PartialEq)]
pub struct NormBound {
    /// F (rows × unknowns).
    pub factor: DMatrix<f64>,
    /// s > 0.
    pub bound: f64,
    /// What the bound is, for the message of an infeasible problem (e.g. `max_shift (…)`).
    pub name: String,
}

/// [`qp_signed`] with the cone ‖F k‖ ≤ s of `cone` held as well (None: [`qp_signed`] itself).
/// With a cone the solve is Clarabel's interior point always, unpolished: the active-set
/// methods know only linear rows, and the polished vertex of the linear rows would leave the
/// cone whenever it is active (the reason it is there). An infeasible problem names the cone
/// when dropping it restores feasibility.
pub fn qp_cone(
    gram: &Gram,
    (equalities, inequalities): (&[LinearGroup], &[LinearGroup]),
    upper: &[Option<f64>],
    free: &[bool],
    l1: f64,
    settings: &QpSettings,
    cone: Option<&NormBound>,
) -> Result<QpSolution> {
    let problem = QpProblem { gram, equalities, inequalities, upper, l1 };
    let mut qp = ScaledQp::new(&problem, free, settings);
    if let Some(c) = cone {
        // ‖F D x‖ ≤ s as ‖(F D / s) x‖ ≤ 1 in the scaled unknowns.
        let mut f = c.factor.clone();
        for (j, dj) in qp.d.iter().enumerate() {
            f.column_mut(j).scale_mut(*dj / c.bound);
        }
        qp.cone = Some((f, c.name.clone()));
    }
    let (d, free) = (&qp.d, &qp.free);
    if qp.cone.is_some() {
        let (x, status, iterations, rounds, cuts) = interior_point_with_cuts(&qp)?;
        let k = DVector::from_fn(gram.dim(), |j, _| if free[j] { x[j] * d[j] } else { (x[j] * d[j]).max(0.0) });
        return Ok(QpSolution {
            k,
            status: if status == SolverStatus::Solved { QpStatus::Solved } else { QpStatus::AlmostSolved },
            iterations,
            cut_rounds: rounds,
            cuts,
            max_equality_residual: qp.max_equality_residual(&x),
        });
    }
    if free.iter().any(|&f| f) && qp.ub.iter().all(Option::is_none) {
        let x = active_set_with_cuts(&qp)?;
        let k = DVector::from_fn(gram.dim(), |j, _| if free[j] { x.0[j] * d[j] } else { (x.0[j] * d[j]).max(0.0) });
        return Ok(QpSolution {
            k,
            status: QpStatus::Solved,
            iterations: x.1,
            cut_rounds: x.2,
            cuts: x.3,
            max_equality_residual: qp.max_equality_residual(&x.0),
        });
    }
    let (x, status, iterations, rounds, cuts) = interior_point_with_cuts(&qp)?;
    let x = polish(&qp, x);
    let k = DVector::from_fn(gram.dim(), |j, _| if free[j] { x[j] * d[j] } else { (x[j] * d[j]).max(0.0) });
    Ok(QpSolution {
        k,
        status: if status == SolverStatus::Solved { QpStatus::Solved } else { QpStatus::AlmostSolved },
        iterations,
        cut_rounds: rounds,
        cuts,
        max_equality_residual: qp.max_equality_residual(&x),
    })
}

/// A QP as [`qp`] takes it: the normal equations, the equality and inequality groups, the
/// upper bounds (None: unbounded) and the L1 weight; what [`qp`] and the screened solve of
/// `screen.rs` share, crate-internal (callers pass the pieces to [`qp`]).
#[derive(Clone, Copy)]
pub(crate) struct QpProblem<'a> {
    /// ½ kᵀGk − cᵀk, the objective before the L1 term.
    pub(crate) gram: &'a Gram,
    /// Groups of rows met exactly, A k = b.
    pub(crate) equalities: &'a [LinearGroup],
    /// Groups of rows G_in k ≥ h, added by cutting planes as they are violated.
    pub(crate) inequalities: &'a [LinearGroup],
    /// u with k ≤ u per unknown (None: unbounded), in the unknown's unit.
    pub(crate) upper: &'a [Option<f64>],
    /// λ of the L1 term λ·Σk (not applied to unknowns free of sign).
    pub(crate) l1: f64,
}

/// The QP in scaled unknowns x (k = D x, D the unit-diagonal scaling of G), as every step of
/// the solve works on it; the groups as given name the culprits of an infeasible problem.
struct ScaledQp<'a> {
    gram: &'a Gram,
    equalities: &'a [LinearGroup],
    inequalities: &'a [LinearGroup],
    settings: &'a QpSettings,
    /// The scaling D.
    d: Vec<f64>,
    /// Each unknown's L1 weight (none on a free unknown: it would not be linear there).
    l1: Vec<f64>,
    /// The objective in factor form.
    s: Scaled,
    /// The equality and inequality groups on the scaled unknowns.
    eqs: Vec<(DMatrix<f64>, DVector<f64>)>,
    ineqs: Vec<(DMatrix<f64>, DVector<f64>)>,
    /// The scaled upper bounds.
    ub: Vec<Option<f64>>,
    /// Which unknowns are free of sign.
    free: Vec<bool>,
    /// A cone ‖F x‖ ≤ 1 on the scaled unknowns and its name ([`qp_cone`]).
    cone: Option<(DMatrix<f64>, String)>,
}

impl<'a> ScaledQp<'a> {
    /// `problem` scaled, with the unknowns `free` of sign (an empty slice means none).
    fn new(problem: &QpProblem<'a>, free: &[bool], settings: &'a QpSettings) -> ScaledQp<'a> {
        let gram = problem.gram;
        let p = gram.dim();
        let free: Vec<bool> = (0..p).map(|j| free.get(j).copied().unwrap_or(false)).collect();
        let l1: Vec<f64> = free.iter().map(|&f| if f { 0.0 } else { problem.l1 }).collect();
        let d: Vec<f64> =
            (0..p).map(|j| if gram.g[(j, j)] > 0.0 { 1.0 / gram.g[(j, j)].sqrt() } else { 1.0 }).collect();
        let s = Scaled::new(gram, &d, &l1);
        let eqs = problem.equalities.iter().map(|g| scale_cols(g, &d)).collect();
        let ineqs = problem.inequalities.iter().map(|g| scale_cols(g, &d)).collect();
        let ub = problem.upper.iter().zip(&d).map(|(u, dj)| u.map(|u| u / dj)).collect();
        ScaledQp {
            gram,
            equalities: problem.equalities,
            inequalities: problem.inequalities,
            settings,
            d,
            l1,
            s,
            eqs,
            ineqs,
            ub,
            free,
            cone: None,
        }
    }

    /// The objective ½ xᵀ g x − cᵀ x in the scaled unknowns: g = D G D, c = D (c − λ).
    fn objective_terms(&self) -> (DMatrix<f64>, DVector<f64>) {
        let (gram, d, l1) = (self.gram, &self.d, &self.l1);
        let n = gram.dim();
        let g = DMatrix::from_fn(n, n, |i, j| gram.g[(i, j)] * d[i] * d[j]);
        let c = DVector::from_fn(n, |i, _| (gram.c[i] - l1[i]) * d[i]);
        (g, c)
    }

    /// Every equality group's rows as equations.
    fn equality_rows(&self) -> Vec<(DVector<f64>, f64)> {
        let mut rows = Vec::new();
        for (m, f) in &self.eqs {
            for i in 0..m.nrows() {
                rows.push((m.row(i).transpose(), f[i]));
            }
        }
        rows
    }

    /// Inequality row r of group g as an equation.
    fn cut_row(&self, g: usize, r: usize) -> (DVector<f64>, f64) {
        (self.ineqs[g].0.row(r).transpose(), self.ineqs[g].1[r])
    }

    /// The inequality rows x violates by more than the cut margin, not among `active`, most
    /// violated first (ties by group and row): (violation, group, row).
    fn violated(&self, x: &DVector<f64>, active: &[(usize, usize)]) -> Vec<(f64, usize, usize)> {
        let mut violated: Vec<(f64, usize, usize)> = Vec::new();
        for (g, (m, h)) in self.ineqs.iter().enumerate() {
            let r = m * x - h;
            for (row, v) in r.iter().enumerate() {
                if *v < -self.settings.cut_margin && !active.contains(&(g, row)) {
                    violated.push((*v, g, row));
                }
            }
        }
        violated.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        violated
    }

    /// The largest violation of an equality at x (scaled units).
    fn max_equality_residual(&self, x: &DVector<f64>) -> f64 {
        self.eqs.iter().map(|(m, f)| (m * x - f).amax()).fold(0.0, f64::max)
    }
}

/// Clarabel's interior point with cutting planes: solved without the inequality rows, then
/// with the most violated ones added, until none is violated. Returns (x in scaled units, the
/// last status, interior-point iterations, rounds, cut rows at the end).
fn interior_point_with_cuts(qp: &ScaledQp) -> Result<(DVector<f64>, SolverStatus, u32, usize, usize)> {
    let settings = qp.settings;
    let mut active: Vec<(usize, usize)> = Vec::new(); // (group, row)
    let mut iterations = 0;
    let mut rounds = 0;
    loop {
        let cut_rows: Vec<(DVector<f64>, f64)> = active.iter().map(|&(g, r)| qp.cut_row(g, r)).collect();
        let cone = qp.cone.as_ref().map(|c| &c.0);
        let (status, x, iters) = solve_once(&qp.s, &qp.eqs, &cut_rows, (&qp.ub, &qp.free, cone), settings)?;
        iterations += iters;
        match status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => {}
            SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => {
                return Err(diagnose(qp));
            }
            other => {
                return Err(Error::numerical("QP (Clarabel)", format!("the solver stopped with status {other:?}")));
            }
        }
        let violated = qp.violated(&x, &active);
        if violated.is_empty() {
            return Ok((x, status, iterations, rounds, active.len()));
        }
        rounds += 1;
        if rounds > settings.cut_rounds {
            return Err(Error::numerical(
                "QP (Clarabel)",
                format!(
                    "{} inequality rows still violated after {} cutting-plane rounds",
                    violated.len(),
                    settings.cut_rounds
                ),
            ));
        }
        active.extend(violated.iter().take(settings.cuts_per_round).map(|&(_, g, r)| (g, r)));
    }
}

/// The QP with signed unknowns (cam coefficients) and no upper bounds, by a primal active-set
/// method with cutting planes instead of Clarabel.
///
/// Clarabel stops with a numerical error on the cams' problems whatever the formulation tried
/// (factor or direct form, larger ridges): a signed unknown has no cone row, so the interior
/// point's barrier never touches it, and the smoothing penalty leaves the B-spline problem with
/// a condition number near 1e11 at the weights the automatic choice tries; the KKT systems of
/// an interior point then lose their accuracy. An active-set method solves the exact KKT system
/// of each passive set instead, and with cams alone the signed unknowns need one solve per
/// round. Inequality rows enter as cuts (most violated first, like the interior-point path),
/// held as equations, and leave again when their multiplier says they pull the wrong way.
/// Returns (x in scaled units, KKT solves, rounds, cut rows at the end).
fn active_set_with_cuts(qp: &ScaledQp) -> Result<(DVector<f64>, u32, usize, usize)> {
    let (settings, free, ineqs) = (qp.settings, &qp.free, &qp.ineqs);
    let (equalities, inequalities) = (qp.equalities, qp.inequalities);
    let n = qp.gram.dim();
    let (g, c) = qp.objective_terms();
    let eq_rows = qp.equality_rows();
    let names = |groups: &[LinearGroup]| groups.iter().map(|g| g.name.clone()).collect::<Vec<_>>().join(", ");
    let mut active: Vec<(usize, usize)> = Vec::new();
    let (mut solves, mut rounds) = (0u32, 0usize);
    loop {
        let mut rows = eq_rows.clone();
        rows.extend(active.iter().map(|&(gi, r)| qp.cut_row(gi, r)));
        let Some((x, nu, k)) = active_set(&g, &c, &rows, free) else {
            return Err(Error::Infeasible {
                constraint: if active.is_empty() { names(equalities) } else { format!("{}; {}", names(equalities), names(inequalities)) },
                reason: "the active-set solve for the cams' signed coefficients found no point meeting these rows:                          the available elements cannot meet them together"
                    .into(),
            });
        };
        solves += k;
        // Cut rows whose multiplier is positive push x the wrong way (λ = −ν < 0): release them.
        let scale = c.amax().max(1e-300);
        let released: Vec<usize> = (0..active.len()).filter(|&a| nu[eq_rows.len() + a] > 1e-10 * scale).collect();
        let violated = qp.violated(&x, &active);
        if violated.is_empty() && released.is_empty() {
            // Cut rows dependent on others are left out of the KKT system: check them too.
            let worst = active
                .iter()
                .map(|&(gi, r)| ineqs[gi].0.row(r).dot(&x.transpose()) - ineqs[gi].1[r])
                .fold(0.0, f64::min);
            if worst < -settings.cut_margin {
                return Err(Error::numerical(
                    "QP (active set)",
                    format!("an inequality row held as an equation is violated by {:.2e}", -worst),
                ));
            }
            return Ok((x, solves, rounds, active.len()));
        }
        rounds += 1;
        if rounds > settings.cut_rounds {
            return Err(Error::numerical(
                "QP (active set)",
                format!(
                    "{} inequality rows still violated and {} to release after {} cutting-plane rounds",
                    violated.len(),
                    released.len(),
                    settings.cut_rounds
                ),
            ));
        }
        let keep: Vec<(usize, usize)> =
            active.iter().enumerate().filter(|(a, _)| !released.contains(a)).map(|(_, &r)| r).collect();
        active = keep;
        // Never more equations than unknowns: an active set is a vertex at most.
        let room = n.saturating_sub(eq_rows.len() + active.len()).max(1);
        active.extend(violated.iter().take(settings.cuts_per_round.min(room)).map(|&(_, gi, r)| (gi, r)));
    }
}

/// Lawson–Hanson's primal active-set iteration for min ½xᵀGx − cᵀx subject to `rows` as
/// equations and x ≥ 0 for the unknowns that are not `free`, from x = 0 with the free unknowns
/// passive (which must meet the rows on their own). Returns x, the rows' multipliers ν (G x +
/// Σ ν_r row_r = c) and the KKT solves, or None when a passive set cannot meet the rows.
fn active_set(
    g: &DMatrix<f64>,
    c: &DVector<f64>,
    rows: &[(DVector<f64>, f64)],
    free: &[bool],
) -> Option<(DVector<f64>, DVector<f64>, u32)> {
    let n = g.nrows();
    let mut passive: Vec<bool> = free.to_vec();
    let mut x = DVector::zeros(n);
    let none = vec![false; n];
    let ub = vec![None; n];
    let tol = 1e-10 * c.amax().max(1e-300);
    let mut solves = 0;
    for _ in 0..3 * n + 10 {
        let idx: Vec<usize> = (0..n).filter(|&j| passive[j]).collect();
        let (z, nu) = kkt_solve(g, c, rows, &idx, &none, &ub)?;
        solves += 1;
        if idx.iter().enumerate().all(|(a, &j)| free[j] || z[a] > 0.0) {
            for (a, &j) in idx.iter().enumerate() {
                x[j] = z[a];
            }
            let mut w = c - g * &x;
            for (r, (row, _)) in rows.iter().enumerate() {
                w -= row * nu[r];
            }
            let entering =
                (0..n).filter(|&j| !passive[j] && w[j] > tol).max_by(|&a, &b| w[a].total_cmp(&w[b]).then(b.cmp(&a)));
            match entering {
                Some(j) => passive[j] = true,
                None => return Some((x, nu, solves)),
            }
        } else {
            let xmax = x.amax().max(1e-300);
            step_back(&mut x, &z, &idx, free, &mut passive, xmax);
        }
    }
    None
}

/// Lawson–Hanson's step back: from x towards the passive subproblem's solution z (over `idx`)
/// until the first bounded unknown reaches zero; unknowns left at zero (to rounding, relative to
/// `xmax`) leave the passive set.
fn step_back(x: &mut DVector<f64>, z: &DVector<f64>, idx: &[usize], free: &[bool], passive: &mut [bool], xmax: f64) {
    let mut alpha: f64 = 1.0;
    for (a, &j) in idx.iter().enumerate() {
        if !free[j] && z[a] <= 0.0 {
            alpha = alpha.min(x[j] / (x[j] - z[a]));
        }
    }
    for (a, &j) in idx.iter().enumerate() {
        x[j] += alpha * (z[a] - x[j]);
        if !free[j] && (x[j] <= 1e-15 * xmax || (z[a] <= 0.0 && x[j] <= 1e-12 * xmax)) {
            x[j] = 0.0;
            passive[j] = false;
        }
    }
}

/// Solution polishing by an active-set method started from the interior-point solution.
///
/// Interior-point iterates approach zero bounds only like √μ when the problem is degenerate (an
/// exact fit, or hundreds of nearly dependent candidates): every element stays slightly positive
/// and the equalities hold only to the solver's tolerance. Starting from the elements the
/// interior point clearly uses, Lawson–Hanson's active-set iteration with the equalities (and the
/// inequality rows at their bound) kept exact through the KKT system of each passive set walks to
/// the exact vertex solution: few elements, equalities to round-off. The result is kept only if
/// it is feasible and no worse than the interior-point solution.
fn polish(qp: &ScaledQp, x_ipm: DVector<f64>) -> DVector<f64> {
    let (eqs, ineqs, ub, free, settings) = (&qp.eqs, &qp.ineqs, &qp.ub, &qp.free, qp.settings);
    let n = qp.s.n;
    let (g, c) = qp.objective_terms();
    let objective = |v: &DVector<f64>| 0.5 * v.dot(&(&g * v)) - c.dot(v);
    // Equations: the equality groups and the inequality rows at their bound.
    let mut rows = qp.equality_rows();
    for (m, h) in ineqs {
        let r = m * &x_ipm - h;
        for i in 0..m.nrows() {
            if r[i].abs() <= 1e-6 {
                rows.push((m.row(i).transpose(), h[i]));
            }
        }
    }
    let ne = rows.len();
    let xmax = x_ipm.amax().max(1e-300);
    // A free unknown is always passive; one at either bound is left to the interior point.
    if (0..n).any(|j| free[j] && ub[j].is_some_and(|u| x_ipm[j].abs() >= u * (1.0 - 1e-6))) {
        return x_ipm;
    }
    let at_upper: Vec<bool> = (0..n).map(|j| !free[j] && ub[j].is_some_and(|u| x_ipm[j] >= u * (1.0 - 1e-6))).collect();
    let mut passive: Vec<bool> = (0..n).map(|j| free[j] || (!at_upper[j] && x_ipm[j] > 1e-6 * xmax)).collect();
    let mut x = DVector::from_fn(n, |j, _| {
        if at_upper[j] {
            ub[j].unwrap_or(0.0)
        } else if passive[j] {
            x_ipm[j]
        } else {
            0.0
        }
    });
    let tol = 1e-10 * c.amax().max(1e-300);
    for _ in 0..3 * n + 10 {
        let idx: Vec<usize> = (0..n).filter(|&j| passive[j]).collect();
        let Some((z, nu)) = kkt_solve(&g, &c, &rows, &idx, &at_upper, ub) else { return x_ipm };
        if idx.iter().enumerate().all(|(a, &j)| free[j] || z[a] > 0.0) {
            for (a, &j) in idx.iter().enumerate() {
                x[j] = z[a];
            }
            // Dual check: an element at zero whose increase lowers the objective enters.
            let mut w = &c - &g * &x;
            for (r, (row, _)) in rows.iter().enumerate() {
                w -= row * nu[r];
            }
            let entering = (0..n)
                .filter(|&j| !passive[j] && !at_upper[j] && w[j] > tol)
                .max_by(|&a, &b| w[a].total_cmp(&w[b]).then(b.cmp(&a)));
            match entering {
                Some(j) => passive[j] = true,
                None => break,
            }
        } else {
            // Step towards z until the first passive element reaches zero; drop it.
            step_back(&mut x, &z, &idx, free, &mut passive, xmax);
            if idx.iter().all(|&j| !passive[j] || free[j]) && ne > 0 {
                return x_ipm;
            }
        }
    }
    let eq_tol = 1e-9;
    let feasible = x.iter().zip(free).all(|(v, &f)| v.is_finite() && (f || *v >= 0.0))
        && ub.iter().zip(x.iter()).all(|(u, v)| u.is_none_or(|u| v.abs() <= u * (1.0 + 1e-12)))
        && eqs.iter().all(|(m, f)| (m * &x - f).amax() <= eq_tol)
        && ineqs.iter().all(|(m, h)| (m * &x - h).min() >= -settings.cut_margin);
    let better = objective(&x) <= objective(&x_ipm) + 1e-9 * objective(&x_ipm).abs().max(1e-12);
    if feasible && better { x } else { x_ipm }
}

/// The KKT system of min ½xᵀGx − cᵀx on the passive set with the rows as equations (elements at
/// their upper bound fixed there, all others at zero). Returns the passive values and the
/// multipliers, or None when the system is singular (the passive set cannot meet the rows).
fn kkt_solve(
    g: &DMatrix<f64>,
    c: &DVector<f64>,
    all_rows: &[(DVector<f64>, f64)],
    idx: &[usize],
    at_upper: &[bool],
    ub: &[Option<f64>],
) -> Option<(DVector<f64>, DVector<f64>)> {
    // Keep a linearly independent subset of the rows restricted to the passive set (modified
    // Gram–Schmidt): equality groups are often redundant there (e.g. both components of the
    // equilibrium gradient carried by one element), which would make the KKT matrix singular.
    // Consistency of the dropped rows is checked by the caller's feasibility test.
    let mut basis: Vec<DVector<f64>> = Vec::new();
    let mut kept: Vec<&(DVector<f64>, f64)> = Vec::new();
    for row in all_rows {
        let mut v = DVector::from_fn(idx.len(), |a, _| row.0[idx[a]]);
        let norm = v.norm();
        for b in &basis {
            let p = b.dot(&v);
            v -= b * p;
        }
        if norm > 0.0 && v.norm() > 1e-10 * norm {
            let vn = v.norm();
            basis.push(v / vn);
            kept.push(row);
        }
    }
    let rows = kept;
    let (ns, ne) = (idx.len(), rows.len());
    if ns == 0 || ne > ns {
        return None;
    }
    let fixed: Vec<(usize, f64)> = (0..g.nrows()).filter(|&j| at_upper[j]).map(|j| (j, ub[j].unwrap_or(0.0))).collect();
    let mut kkt = DMatrix::zeros(ns + ne, ns + ne);
    let mut rhs = DVector::zeros(ns + ne);
    for (a, &i) in idx.iter().enumerate() {
        for (b, &j) in idx.iter().enumerate() {
            kkt[(a, b)] = g[(i, j)];
        }
        kkt[(a, a)] += 1e-13;
        rhs[a] = c[i] - fixed.iter().map(|&(j, u)| g[(i, j)] * u).sum::<f64>();
    }
    for (r, (row, val)) in rows.iter().enumerate() {
        for (a, &i) in idx.iter().enumerate() {
            kkt[(ns + r, a)] = row[i];
            kkt[(a, ns + r)] = row[i];
        }
        rhs[ns + r] = val - fixed.iter().map(|&(j, u)| row[j] * u).sum::<f64>();
    }
    // nalgebra's LU, although faer's (`dense::variants::lu_solve_faer`) is 3–4.5× faster from
    // about 100 unknowns (the dense design's 375: 4.6 → 1.3 ms; 1216 of them per fit): the
    // polished vertex is the solution of these systems, and faer's rounding changed the dense,
    // paper-window, triple-pendulum and 16-cam fits beyond their last digits (BENCHMARKS.md,
    // "Dense kernels").
    // Above [`FAER_KKT_FROM`] unknowns (no shipped design's KKT system is that large) nalgebra's
    // unblocked LU is most of a fit: a tendon catalogue's dense smoothing choice solves systems of
    // thousands of signed cam coefficients, each 20–40 s that way.
    let sol = if ns + ne >= FAER_KKT_FROM {
        super::dense::variants::lu_solve_faer(kkt, &rhs)?
    } else {
        kkt.lu().solve(&rhs)?
    };
    if sol.iter().any(|v| !v.is_finite()) {
        return None;
    }
    // Multipliers of dropped rows are zero.
    let mut nu = DVector::zeros(all_rows.len());
    let mut r = 0;
    for (k, row) in all_rows.iter().enumerate() {
        if r < ne && std::ptr::eq(row, rows[r]) {
            nu[k] = sol[ns + r];
            r += 1;
        }
    }
    Some((sol.rows(0, ns).into_owned(), nu))
}

/// The objective in scaled unknowns x (k = D x): ½ xᵀ P x + qᵀ x.
struct Scaled {
    /// Upper-triangular factor R with RᵀR = D G D + ridge·I.
    r: DMatrix<f64>,
    q: Vec<f64>,
    n: usize,
}

impl Scaled {
    /// The objective is handed to Clarabel in factor form, ½‖y‖² + qᵀx with y = R x, rather than
    /// as ½ xᵀ(DGD)x: the KKT systems then see the conditioning of R, the square root of that of
    /// G. With the hundreds of nearly dependent columns of a rich catalogue (crank phases span two
    /// functions per coupling) the direct form stalls with a numerical error. A ridge of 1e-10 on
    /// the unit diagonal keeps the factorisation defined.
    fn new(gram: &Gram, d: &[f64], l1: &[f64]) -> Self {
        let n = gram.dim();
        let mut ridge = RIDGE;
        let r = loop {
            let m = DMatrix::from_fn(n, n, |i, j| gram.g[(i, j)] * d[i] * d[j] + if i == j { ridge } else { 0.0 });
            let l = if n >= FAER_CHOLESKY_FROM { super::dense::cholesky_lower(m) } else { m.cholesky().map(|c| c.l()) };
            if let Some(l) = l {
                break l.transpose();
            }
            ridge *= 100.0;
        };
        let q = (0..n).map(|j| -(gram.c[j] - l1[j]) * d[j]).collect();
        Scaled { r, q, n }
    }
}

fn scale_cols(g: &LinearGroup, d: &[f64]) -> (DMatrix<f64>, DVector<f64>) {
    let mut m = g.matrix.clone();
    for (j, dj) in d.iter().enumerate() {
        m.column_mut(j).scale_mut(*dj);
    }
    (m, g.rhs.clone())
}

/// One Clarabel solve: equalities, the given inequality rows, bounds, and a cone ‖F x‖ ≤ 1
/// when given.
fn solve_once(
    s: &Scaled,
    eqs: &[(DMatrix<f64>, DVector<f64>)],
    cuts: &[(DVector<f64>, f64)],
    (ub, free, cone): (&[Option<f64>], &[bool], Option<&DMatrix<f64>>),
    settings: &QpSettings,
) -> Result<(SolverStatus, DVector<f64>, u32)> {
    let n = s.n;
    // Variables (x, y), y = R x. Rows of A z + s = b, s ∈ cones, built column by column.
    let mut rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); 2 * n];
    let mut b = Vec::new();
    let mut r = 0;
    // R x − y = 0.
    for i in 0..n {
        for j in i..n {
            if s.r[(i, j)] != 0.0 {
                rows[j].push((r, s.r[(i, j)]));
            }
        }
        rows[n + i].push((r, -1.0));
        b.push(0.0);
        r += 1;
    }
    let mut n_eq = n;
    for (m, f) in eqs {
        for i in 0..m.nrows() {
            for j in 0..n {
                if m[(i, j)] != 0.0 {
                    rows[j].push((r, m[(i, j)]));
                }
            }
            b.push(f[i]);
            r += 1;
            n_eq += 1;
        }
    }
    // −G x + s = −h (s ≥ 0).
    for (gr, h) in cuts {
        for j in 0..n {
            if gr[j] != 0.0 {
                rows[j].push((r, -gr[j]));
            }
        }
        b.push(-h);
        r += 1;
    }
    // −x + s = 0 (x ≥ 0), or −x + s = u (x ≥ −u) for a free unknown with a bound.
    for (j, col) in rows.iter_mut().take(n).enumerate() {
        match (free[j], ub[j]) {
            (false, _) => b.push(0.0),
            (true, Some(u)) => b.push(u),
            (true, None) => continue,
        }
        col.push((r, -1.0));
        r += 1;
    }
    // x + s = u (x ≤ u).
    for (j, u) in ub.iter().enumerate() {
        if let Some(u) = u {
            rows[j].push((r, 1.0));
            b.push(*u);
            r += 1;
        }
    }
    let n_linear = r;
    // (1, F x) in the second-order cone: s₀ = 1, sᵢ = (F x)ᵢ, ‖(s₁, …)‖ ≤ s₀.
    if let Some(f) = cone {
        b.push(1.0);
        r += 1;
        for i in 0..f.nrows() {
            for j in 0..n {
                if f[(i, j)] != 0.0 {
                    rows[j].push((r, -f[(i, j)]));
                }
            }
            b.push(0.0);
            r += 1;
        }
    }
    let mut colptr = vec![0];
    let mut rowval = Vec::new();
    let mut nzval = Vec::new();
    for col in &rows {
        for &(i, v) in col {
            rowval.push(i);
            nzval.push(v);
        }
        colptr.push(rowval.len());
    }
    let a = CscMatrix::new(r, 2 * n, colptr, rowval, nzval);
    // P = blockdiag(0, I); q = (q_x, 0).
    let p_upper = CscMatrix::new(
        2 * n,
        2 * n,
        (0..=2 * n).map(|j| j.saturating_sub(n)).collect(),
        (n..2 * n).collect(),
        vec![1.0; n],
    );
    let q: Vec<f64> = s.q.iter().copied().chain(std::iter::repeat_n(0.0, n)).collect();
    let mut cones = Vec::new();
    if n_eq > 0 {
        cones.push(SupportedConeT::ZeroConeT(n_eq));
    }
    if n_linear > n_eq {
        cones.push(SupportedConeT::NonnegativeConeT(n_linear - n_eq));
    }
    if r > n_linear {
        cones.push(SupportedConeT::SecondOrderConeT(r - n_linear));
    }
    let cs = DefaultSettings {
        verbose: false,
        max_iter: settings.max_iterations,
        tol_gap_abs: settings.tolerance,
        tol_gap_rel: settings.tolerance,
        tol_feas: settings.tolerance,
        max_threads: 1,
        presolve_enable: false,
        ..DefaultSettings::default()
    };
    let mut solver = DefaultSolver::new(&p_upper, &q, &a, &b, &cones, cs)
        .map_err(|e| Error::numerical("QP (Clarabel)", format!("could not set up the problem: {e:?}")))?;
    solver.solve();
    let x = DVector::from_column_slice(&solver.solution.x[..n]);
    if matches!(solver.solution.status, SolverStatus::Solved | SolverStatus::AlmostSolved)
        && x.iter().any(|v| !v.is_finite())
    {
        return Err(Error::numerical("QP (Clarabel)", "the solution is not finite"));
    }
    Ok((solver.solution.status, x, solver.solution.iterations))
}

/// Names the constraint group(s) that make the QP infeasible by dropping one at a time.
fn diagnose(qp: &ScaledQp) -> Error {
    let (s, equalities, eqs, inequalities, ineqs) = (&qp.s, qp.equalities, &qp.eqs, qp.inequalities, &qp.ineqs);
    let (ub, free, settings) = (&qp.ub, &qp.free, qp.settings);
    let cone = qp.cone.as_ref().map(|c| &c.0);
    let feasible_with =
        |eqs: &[(DMatrix<f64>, DVector<f64>)], cuts: &[(DVector<f64>, f64)], ub: &[Option<f64>], cone| {
            matches!(
                solve_once(s, eqs, cuts, (ub, free, cone), settings),
                Ok((SolverStatus::Solved | SolverStatus::AlmostSolved, _, _))
            )
        };
    let feasible = |eqs: &[(DMatrix<f64>, DVector<f64>)], cuts: &[(DVector<f64>, f64)], ub: &[Option<f64>]| {
        feasible_with(eqs, cuts, ub, cone)
    };
    let all_cuts: Vec<(DVector<f64>, f64)> =
        ineqs.iter().flat_map(|(m, h)| (0..m.nrows()).map(move |r| (m.row(r).transpose(), h[r]))).collect();
    let no_ub = vec![None; ub.len()];
    let mut culprits = Vec::new();
    for (i, g) in equalities.iter().enumerate() {
        let rest: Vec<_> = eqs.iter().enumerate().filter(|(j, _)| *j != i).map(|(_, e)| e.clone()).collect();
        if feasible(&rest, &all_cuts, ub) {
            culprits.push(format!("{} ({})", g.name, g.description));
        }
    }
    for (i, g) in inequalities.iter().enumerate() {
        let rest: Vec<(DVector<f64>, f64)> = ineqs
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != i)
            .flat_map(|(_, (m, h))| (0..m.nrows()).map(move |r| (m.row(r).transpose(), h[r])))
            .collect();
        if feasible(eqs, &rest, ub) {
            culprits.push(format!("{} ({})", g.name, g.description));
        }
    }
    if ub.iter().any(Option::is_some) && feasible(eqs, &all_cuts, &no_ub) {
        culprits.push("max_stiffness (the catalogue's stiffness limits)".into());
    }
    if let Some((_, name)) = &qp.cone
        && feasible_with(eqs, &all_cuts, ub, None)
    {
        culprits.push(name.clone());
    }
    let (constraint, reason) = match culprits.len() {
        0 => ("the constraints together".to_string(), "no single group can be dropped to restore feasibility; relax the requirements or widen the catalogue".to_string()),
        _ => (
            culprits.join("; "),
            "cannot be met with non-negative stiffnesses of the available elements together with the other requirements; dropping it would make the fit feasible".to_string(),
        ),
    };
    Error::Infeasible { constraint, reason }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::nnls::{NnlsSettings, nnls};
    use crate::solve::test_problems::{group, lcg};

    #[test]
    fn recovers_known_stiffnesses_and_agrees_with_nnls() {
        let mut seed = 21;
        let a = DMatrix::from_fn(60, 7, |_, _| lcg(&mut seed));
        let k_true = DVector::from_vec(vec![0.0, 1.5, 0.0, 2.0, 0.7, 0.0, 3.0]);
        let gram = Gram::from_rows(&a, &(&a * &k_true));
        let sol = qp(&gram, &[], &[], &[None; 7], 0.0, &QpSettings::default()).unwrap();
        assert!((&sol.k - &k_true).amax() < 1e-6, "{}", sol.k);
        // A noisy right-hand side: both solvers find the same optimum.
        let b = DVector::from_fn(60, |_, _| lcg(&mut seed));
        let gram = Gram::from_rows(&a, &b);
        let q = qp(&gram, &[], &[], &[None; 7], 0.0, &QpSettings::default()).unwrap();
        let n = nnls(&gram, 0.0, &NnlsSettings::default()).unwrap();
        assert!((&q.k - &n.k).amax() < 1e-6, "{} vs {}", q.k, n.k);
    }

    #[test]
    fn equalities_are_exact_and_match_heavily_weighted_nnls() {
        let mut seed = 5;
        let a = DMatrix::from_fn(40, 6, |_, _| lcg(&mut seed));
        let b = DVector::from_fn(40, |_, _| lcg(&mut seed));
        let e = DMatrix::from_row_slice(1, 6, &[1.0, 1.0, 1.0, 1.0, 1.0, 1.0]);
        let f = DVector::from_vec(vec![2.0]);
        let gram = Gram::from_rows(&a, &b);
        let q = qp(&gram, &[group("sum", e.clone(), f.clone())], &[], &[None; 6], 0.0, &QpSettings::default()).unwrap();
        assert!((q.k.sum() - 2.0).abs() < 1e-8);
        let mut weighted = gram.clone();
        weighted.add_weighted(&e, &f, 1e4);
        let n = nnls(&weighted, 0.0, &NnlsSettings::default()).unwrap();
        assert!((&q.k - &n.k).amax() < 1e-5, "{} vs {}", q.k, n.k);
    }

    #[test]
    fn infeasible_equalities_are_named() {
        let a = DMatrix::identity(3, 3);
        let gram = Gram::from_rows(&a, &DVector::from_element(3, 1.0));
        let bad =
            group("normalisation", DMatrix::from_row_slice(1, 3, &[1.0, 1.0, 1.0]), DVector::from_vec(vec![-1.0]));
        let ok = group(
            "equilibrium gradient",
            DMatrix::from_row_slice(1, 3, &[1.0, -1.0, 0.0]),
            DVector::from_vec(vec![0.0]),
        );
        let err = qp(&gram, &[ok, bad], &[], &[None; 3], 0.0, &QpSettings::default()).unwrap_err();
        match err {
            Error::Infeasible { constraint, .. } => {
                assert!(constraint.contains("normalisation"), "{constraint}");
                assert!(!constraint.contains("equilibrium"), "{constraint}");
            }
            e => panic!("{e}"),
        }
    }

    #[test]
    fn a_solver_stopped_early_is_an_error_naming_the_status() {
        let mut seed = 17;
        let a = DMatrix::from_fn(30, 6, |_, _| lcg(&mut seed));
        let b = DVector::from_fn(30, |_, _| lcg(&mut seed));
        let gram = Gram::from_rows(&a, &b);
        let s = QpSettings { max_iterations: 1, ..QpSettings::default() };
        let err = qp(&gram, &[], &[], &[None; 6], 0.0, &s).unwrap_err().to_string();
        assert!(err.contains("QP (Clarabel)") && err.contains("MaxIterations"), "{err}");
    }

    #[test]
    fn bounds_and_cutting_planes() {
        let mut seed = 9;
        let a = DMatrix::from_fn(50, 5, |_, _| lcg(&mut seed));
        let b = DVector::from_fn(50, |_, _| 3.0 * lcg(&mut seed).abs());
        let gram = Gram::from_rows(&a, &b);
        let upper = [Some(0.5), None, Some(0.1), None, None];
        // 2000 random inequality rows g·k ≥ −0.05.
        let g = DMatrix::from_fn(2000, 5, |_, _| lcg(&mut seed));
        let h = DVector::from_element(2000, -0.05);
        let ineq = group("monotonicity", g.clone(), h.clone());
        let cut = qp(&gram, &[], std::slice::from_ref(&ineq), &upper, 0.0, &QpSettings::default()).unwrap();
        assert!((&g * &cut.k - &h).min() > -1e-7);
        for (k, u) in cut.k.iter().zip(&upper) {
            if let Some(u) = u {
                assert!(*k <= u + 1e-8);
            }
        }
        // All rows at once (no cutting planes) gives the same optimum.
        let all = QpSettings { cuts_per_round: usize::MAX, ..QpSettings::default() };
        let full = qp(&gram, &[], &[ineq], &upper, 0.0, &all).unwrap();
        assert!((&cut.k - &full.k).amax() < 1e-5, "{} vs {}", cut.k, full.k);
        assert!(cut.cuts < 2000);
    }
}
