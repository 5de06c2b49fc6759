//! The QP over many candidates on a working set: solve it on a few of the unknowns, check the
//! full problem's optimality conditions for all the others from the Gram matrix, add those that
//! violate them, repeat.
//!
//! With no element budget the QP sees every candidate, and Clarabel's interior point factors an
//! m × m matrix at every iteration (~m³: 427 s for the 2287 candidates of a planar chain of
//! seven links). Most candidates end at zero. On a working set W the QP costs ~|W|³, and whether
//! W's optimum k (zero off W) is the optimum of the whole problem is a question of the KKT
//! conditions alone: k is feasible for the whole problem (a candidate at zero adds nothing to
//! any row), and it is optimal there if and only if, with the multipliers ν of the equalities
//! and of the inequality rows at their bound, no unknown off W could lower the objective by
//! growing from zero:
//!
//! sⱼ = (G k − c + λ)ⱼ − Σ_r ν_r Rᵣⱼ ≥ 0 for every j ∉ W,
//!
//! which costs one product of G's columns on the support of k (m·|support|). The multipliers
//! come from stationarity on W's unknowns strictly inside their bounds (a least-squares solve
//! with as many equations as those unknowns and as many unknowns as active rows). Violators
//! enter W, most violated first and ties by index, [`ENTER_PER_ROUND`] at a time; W only grows,
//! so the loop ends, at the latest with every unknown in W (the full QP). The answer is that of
//! the full QP up to the sub-problem's own accuracy, and deterministic: nothing depends on the
//! thread count.

use nalgebra::{DMatrix, DVector};

use super::constraint::LinearGroup;
use super::lsq::Gram;
use super::qp::{QpProblem, QpSettings, QpSolution, qp};
use crate::error::{Error, Result};

/// Most unknowns that enter the working set per round: enough that a support of a few hundred is
/// reached in a few rounds, few enough that W stays near the support.
pub const ENTER_PER_ROUND: usize = 64;

/// A violation counts below −`KKT_TOLERANCE` · max |cⱼ − λ| in the unit-diagonal scaling of the
/// unknowns, a hundredth of the tolerance by which the QP's polish lets an unknown enter its own
/// passive set (1e-10): candidates nearly dependent on the working set's columns (crank phases)
/// lower the objective by much more than their small violations suggest. On the
/// four-link chain of `benches/scaling.rs` (614 candidates) a tolerance of 1e-6 of ‖A k − b‖
/// stopped 0.23 % above Clarabel's optimum over all candidates, 1e-10 of max |c| 0.15 %, 1e-12
/// 2.1e-5 (BENCHMARKS.md, "Fit time against the number of joints").
pub const KKT_TOLERANCE: f64 = 1e-12;

/// A screened QP's solution and how it was found.
#[derive(Debug, Clone, PartialEq)]
pub struct Screened {
    /// The full problem's solution (zero off the working set).
    pub solution: QpSolution,
    /// The working set of the last solve, ascending.
    pub working: Vec<usize>,
    /// Sub-problem solves.
    pub rounds: usize,
    /// The largest KKT violation left off the working set, in the scaling of [`KKT_TOLERANCE`]
    /// (0 when none).
    pub violation: f64,
}

/// [`qp`] (non-negative unknowns, no signed ones) solved on a working set grown from `start`
/// (see the module docs). `start` should hold the unknowns the answer is likely to use (an NNLS
/// support); an empty start begins with the [`ENTER_PER_ROUND`] most violated at k = 0. A
/// working set that cannot meet the constraints at least doubles, by the unknowns whose growth
/// from zero lowers the objective fastest.
pub fn qp_screened(
    gram: &Gram,
    equalities: &[LinearGroup],
    inequalities: &[LinearGroup],
    upper: &[Option<f64>],
    l1: f64,
    settings: &QpSettings,
    start: &[usize],
) -> Result<Screened> {
    let p = gram.dim();
    let problem = QpProblem { gram, equalities, inequalities, upper, l1 };
    let mut in_w = vec![false; p];
    for &j in start {
        in_w[j] = true;
    }
    if start.is_empty() {
        let k0 = DVector::zeros(p);
        for j in violators(&problem, &k0, &in_w, &[]).0 {
            in_w[j] = true;
        }
    }
    let scale: Vec<f64> =
        (0..p).map(|j| if gram.g[(j, j)] > 0.0 { 1.0 / gram.g[(j, j)].sqrt() } else { 1.0 }).collect();
    let mut rounds = 0;
    loop {
        let w: Vec<usize> = (0..p).filter(|&j| in_w[j]).collect();
        let restrict = |groups: &[LinearGroup]| -> Vec<LinearGroup> {
            groups
                .iter()
                .map(|g| LinearGroup {
                    matrix: DMatrix::from_fn(g.matrix.nrows(), w.len(), |r, a| g.matrix[(r, w[a])]),
                    ..g.clone()
                })
                .collect()
        };
        let sub_upper: Vec<Option<f64>> = w.iter().map(|&j| upper[j]).collect();
        let sub = qp(&gram.subset(&w), &restrict(equalities), &restrict(inequalities), &sub_upper, l1, settings);
        rounds += 1;
        let sub = match sub {
            Ok(s) => s,
            // The working set cannot meet the constraints: it grows by the unknowns the
            // objective pulls hardest at k = 0 (the last round, over every unknown, is the full
            // QP and names the culprit when the problem itself is infeasible).
            Err(Error::Infeasible { .. }) if w.len() < p => {
                let mut out: Vec<(f64, usize)> =
                    (0..p).filter(|&j| !in_w[j]).map(|j| (-(gram.c[j] - l1) * scale[j], j)).collect();
                out.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                for &(_, j) in out.iter().take(ENTER_PER_ROUND.max(w.len())) {
                    in_w[j] = true;
                }
                continue;
            }
            Err(e) => return Err(e),
        };
        let mut k = DVector::zeros(p);
        for (a, &j) in w.iter().enumerate() {
            k[j] = sub.k[a];
        }
        let (enter, violation) = violators(&problem, &k, &in_w, &w);
        if enter.is_empty() {
            return Ok(Screened { solution: QpSolution { k, ..sub }, working: w, rounds, violation });
        }
        for j in enter {
            in_w[j] = true;
        }
    }
}

/// The unknowns off the working set (`in_w` false) whose reduced gradient at `k` says they would
/// lower the objective, at most [`ENTER_PER_ROUND`], most violated first (ties by index), and
/// the largest violation in the scaling of [`KKT_TOLERANCE`]. `w` lists the working set, whose
/// unknowns strictly inside their bounds give the multipliers.
fn violators(problem: &QpProblem, k: &DVector<f64>, in_w: &[bool], w: &[usize]) -> (Vec<usize>, f64) {
    let QpProblem { gram, equalities, inequalities, upper, l1 } = *problem;
    let p = gram.dim();
    // Unit-diagonal scaling, as the QP's own.
    let d: Vec<f64> = (0..p).map(|j| if gram.g[(j, j)] > 0.0 { 1.0 / gram.g[(j, j)].sqrt() } else { 1.0 }).collect();
    // The objective's gradient ½kᵀGk − (c − λ)ᵀk: G k over the support of k only.
    let mut grad = DVector::from_fn(p, |j, _| l1 - gram.c[j]);
    for (j, &kj) in k.iter().enumerate() {
        if kj != 0.0 {
            grad.axpy(kj, &gram.g.column(j), 1.0);
        }
    }
    // The rows that can carry a multiplier: every equality, and the inequality rows at their
    // bound, relative to the size of the row's own terms (the polish holds binding rows as
    // equations, to round-off; a row that is merely small, a monotonicity row near q_eq, is not
    // binding, and a multiplier on it would explain away any gradient).
    let mut rows: Vec<DVector<f64>> = Vec::new();
    for g in equalities {
        rows.extend(g.matrix.row_iter().map(|r| r.transpose()));
    }
    for g in inequalities {
        let r = &g.matrix * k - &g.rhs;
        let size =
            |i: usize| g.matrix.row(i).iter().zip(k.iter()).map(|(a, k)| (a * k).abs()).sum::<f64>() + g.rhs[i].abs();
        rows.extend((0..r.len()).filter(|&i| r[i].abs() <= 1e-9 * size(i)).map(|i| g.matrix.row(i).transpose()));
    }
    // Multipliers from stationarity on the unknowns strictly inside their bounds (scaled).
    let kmax = w.iter().map(|&j| k[j] / d[j]).fold(0.0, f64::max);
    let inside: Vec<usize> = w
        .iter()
        .copied()
        .filter(|&j| k[j] / d[j] > 1e-9 * kmax && upper[j].is_none_or(|u| k[j] < u * (1.0 - 1e-9)))
        .collect();
    let nu = if rows.is_empty() || inside.is_empty() {
        DVector::zeros(rows.len())
    } else {
        let a = DMatrix::from_fn(inside.len(), rows.len(), |a, r| rows[r][inside[a]] * d[inside[a]]);
        let b = DVector::from_fn(inside.len(), |a, _| grad[inside[a]] * d[inside[a]]);
        a.svd(true, true).solve(&b, 1e-12).unwrap_or_else(|_| DVector::zeros(rows.len()))
    };
    let scale = (0..p).map(|j| ((gram.c[j] - l1) * d[j]).abs()).fold(0.0, f64::max).max(1e-300);
    let mut out: Vec<(f64, usize)> = (0..p)
        .filter(|&j| !in_w[j] && gram.g[(j, j)] > 0.0 && upper[j].is_none_or(|u| u > 0.0))
        .map(|j| {
            let s = grad[j] - rows.iter().zip(nu.iter()).map(|(r, n)| r[j] * n).sum::<f64>();
            (s * d[j] / scale, j)
        })
        .filter(|&(s, _)| s < 0.0)
        .collect();
    let violation = out.iter().map(|&(s, _)| -s).fold(0.0, f64::max);
    out.retain(|&(s, _)| s < -KKT_TOLERANCE);
    out.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    (out.into_iter().take(ENTER_PER_ROUND).map(|(_, j)| j).collect(), violation)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::test_problems::{group, lcg};

    /// A problem with an equality, inequality rows, bounds and an L1 weight, over more columns
    /// than rows so that most unknowns end at zero: the screened solve from a start of three
    /// columns reaches the full Clarabel QP's optimum, solving fewer unknowns at a time.
    #[test]
    fn the_working_set_reaches_the_full_qps_optimum() {
        let mut seed = 11;
        let (rows, p) = (60, 150);
        let a = DMatrix::from_fn(rows, p, |_, _| lcg(&mut seed));
        let b = DVector::from_fn(rows, |_, _| 2.0 * lcg(&mut seed));
        let gram = Gram::from_rows(&a, &b);
        let e = DMatrix::from_fn(2, p, |r, j| if r == 0 { 1.0 } else { ((j % 7) as f64 - 3.0) / 3.0 });
        let eq = group("equations", e, DVector::from_vec(vec![3.0, 0.2]));
        let ineq = group("rows", DMatrix::from_fn(40, p, |_, _| lcg(&mut seed)), DVector::from_element(40, -0.3));
        let upper: Vec<Option<f64>> = (0..p).map(|j| (j % 5 == 0).then_some(0.2)).collect();
        let settings = QpSettings::default();
        let (eqs, ineqs) = (std::slice::from_ref(&eq), std::slice::from_ref(&ineq));
        let full = qp(&gram, eqs, ineqs, &upper, 0.01, &settings).unwrap();
        let screened = qp_screened(&gram, eqs, ineqs, &upper, 0.01, &settings, &[0, 1, 2]).unwrap();
        let k = &screened.solution.k;
        let objective = |k: &DVector<f64>| gram.objective(k) + 0.02 * k.sum();
        let (fo, so) = (objective(&full.k), objective(k));
        assert!((so - fo).abs() <= 1e-7 * fo, "screened {so} against full {fo}");
        assert!((k - &full.k).amax() < 1e-4, "{}", (k - &full.k).amax());
        assert!(screened.rounds > 1 && screened.working.len() < p, "{} of {p}", screened.working.len());
        assert!(screened.violation <= KKT_TOLERANCE);
        assert!((&eq.matrix * k - &eq.rhs).amax() < 1e-8 && (&ineq.matrix * k - &ineq.rhs).min() > -1e-7);
        assert!(k.iter().zip(&upper).all(|(k, u)| *k >= 0.0 && u.is_none_or(|u| *k <= u + 1e-9)));
    }

    /// A problem that nearly fits (the right-hand side a sparse non-negative combination plus
    /// noise of 1e-5): the violations are small beside c, and still the screened solve must
    /// reach the full QP's optimum, judged against the residual rather than against c.
    #[test]
    fn a_nearly_exact_fit_is_screened_to_its_optimum() {
        let mut seed = 29;
        let (rows, p) = (300, 200);
        let a = DMatrix::from_fn(rows, p, |_, _| lcg(&mut seed));
        let k_true = DVector::from_fn(p, |j, _| if j % 17 == 3 { 1.0 + (j % 5) as f64 } else { 0.0 });
        let b = &a * &k_true + DVector::from_fn(rows, |_, _| 1e-5 * lcg(&mut seed));
        let gram = Gram::from_rows(&a, &b);
        let eq = group("sum", DMatrix::from_element(1, p, 1.0), DVector::from_vec(vec![k_true.sum()]));
        let (eqs, upper, settings) = (std::slice::from_ref(&eq), vec![None; p], QpSettings::default());
        let full = qp(&gram, eqs, &[], &upper, 0.0, &settings).unwrap();
        let screened = qp_screened(&gram, eqs, &[], &upper, 0.0, &settings, &[0, 1, 2, 3]).unwrap();
        let (fo, so) = (gram.objective(&full.k), gram.objective(&screened.solution.k));
        assert!(fo < 1e-7 && (so - fo).abs() <= 1e-6 * fo, "screened {so:e} against full {fo:e}");
    }

    /// A bigger problem (600 columns) whose full QP is not solved: the KKT conditions of the full
    /// problem hold at the screened answer for every unknown, checked here independently: the
    /// multipliers of the equalities from the unknowns inside their bounds, then every reduced
    /// gradient ≥ 0 at zero and = 0 inside.
    #[test]
    fn the_screened_answer_meets_the_full_kkt_conditions() {
        let mut seed = 3;
        let (rows, p) = (200, 600);
        let a = DMatrix::from_fn(rows, p, |_, _| lcg(&mut seed));
        let b = DVector::from_fn(rows, |_, _| lcg(&mut seed));
        let gram = Gram::from_rows(&a, &b);
        let e = DMatrix::from_fn(1, p, |_, j| 1.0 + (j % 3) as f64);
        let eq = group("sum", e.clone(), DVector::from_vec(vec![5.0]));
        let s = qp_screened(&gram, std::slice::from_ref(&eq), &[], &vec![None; p], 0.0, &QpSettings::default(), &[])
            .unwrap();
        let k = &s.solution.k;
        assert!(s.working.len() < p / 2, "{}", s.working.len());
        assert!((&e * k - &eq.rhs).amax() < 1e-9 && k.min() >= 0.0);
        let grad = &gram.g * k - &gram.c;
        let inside: Vec<usize> = (0..p).filter(|&j| k[j] > 1e-9 * k.amax()).collect();
        let mu = inside.iter().map(|&j| grad[j] * e[(0, j)]).sum::<f64>()
            / inside.iter().map(|&j| e[(0, j)] * e[(0, j)]).sum::<f64>();
        let scale = gram.c.amax();
        for j in 0..p {
            let reduced = (grad[j] - mu * e[(0, j)]) / scale;
            if inside.contains(&j) {
                assert!(reduced.abs() < 1e-6, "column {j} inside: {reduced:e}");
            } else {
                assert!(reduced > -1e-6, "column {j} at zero: {reduced:e}");
            }
        }
    }
}
