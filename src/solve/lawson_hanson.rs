//! Non-negative least squares with exact equality rows, by Lawson–Hanson's active-set iteration
//! on a Cholesky factor that is updated, not recomputed, as unknowns enter and leave.
//!
//! minimise ½ xᵀ(G + ridge·I)x − (c − λ1)ᵀx subject to E x = e and x ≥ 0, in the unit-diagonal
//! scaling of [`super::qp`]. This is the fit's QP when it has no inequality rows, no upper bounds
//! and no signed unknowns: every design without `monotone`, `max_preload` or stiffness limits.
//!
//! Why a solver of its own: with many candidates and no budget the support reaches hundreds of
//! springs (400 for a planar chain of six links). Clarabel's interior point factors the whole
//! working set at each of its iterations, and the active-set polish after it solved each passive
//! set's KKT system by a fresh LU (together 23 s of a 38 s fit at six links; at seven links
//! Clarabel stopped with a numerical error). Lawson–Hanson moves one unknown at a time, so the
//! factor L Lᵀ = G_PP of the passive set P changes by one row: appending an unknown costs one
//! triangular solve (|P|²), removing one a sweep of Givens rotations (|P|²), and each KKT solve
//! two triangular solves and the small Schur complement of the equality rows,
//!
//! S ν = E_P G_PP⁻¹ c_P − e,  z = G_PP⁻¹ (c_P − E_Pᵀ ν),  S = E_P G_PP⁻¹ E_Pᵀ = WᵀW, W = L⁻¹ E_Pᵀ,
//!
//! with W and y = L⁻¹ c_P carried along the updates. One step of iterative refinement on the full
//! KKT system restores the accuracy that the Schur complement of an ill-conditioned G loses.
//! Everything runs in a fixed order (the dual products per unknown are independent, so running
//! them in parallel changes no bit): the answer does not depend on the thread count.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use super::constraint::LinearGroup;
use super::lsq::Gram;
use super::qp::{QpSolution, QpStatus};

/// Ridge on the unit diagonal of the scaled G: keeps the factor defined when columns are nearly
/// dependent (crank phases span two functions per coupling). Smaller than the QP's 1e-10
/// ([`super::qp`]), which Clarabel's interior point never solves to its end: this solver does,
/// and at 1e-10 the ridge itself shaped the large fits (chain of four links: residual 14 % above
/// Clarabel's over all candidates, held-out p99 2.13° against 1.88°); at 1e-12 the two agree to
/// 6.5e-4 (BENCHMARKS.md, "Fit time against the number of joints").
const RIDGE: f64 = 1e-12;

/// An unknown enters when its reduced gradient exceeds this fraction of max |cⱼ − λ| (scaled),
/// the working set's own tolerance ([`super::screen::KKT_TOLERANCE`]).
const ENTER_TOLERANCE: f64 = super::screen::KKT_TOLERANCE;

/// Largest equality residual (scaled units, relative to max |e|, at least 1) the answer may keep.
const EQUALITY_TOLERANCE: f64 = 1e-9;

/// The factor of the passive set and the quantities carried with it.
struct Factor {
    /// Passive unknowns in factor order.
    passive: Vec<usize>,
    /// Rows of the lower-triangular L (row a has a + 1 entries).
    l: Vec<Vec<f64>>,
    /// Rows of W = L⁻¹ E_Pᵀ (one per passive unknown, one entry per equality row).
    w: Vec<Vec<f64>>,
    /// y = L⁻¹ c_P.
    y: Vec<f64>,
}

/// The scaled problem.
struct Problem {
    g: DMatrix<f64>,
    c: DVector<f64>,
    /// Equality rows, scaled (ne × p), and their right-hand side.
    e: DMatrix<f64>,
    f: DVector<f64>,
}

impl Factor {
    fn new() -> Self {
        Factor { passive: Vec::new(), l: Vec::new(), w: Vec::new(), y: Vec::new() }
    }

    /// Appends unknown `j` (one forward solve).
    fn append(&mut self, pb: &Problem, j: usize) {
        let k = self.passive.len();
        let mut row = Vec::with_capacity(k + 1);
        for a in 0..k {
            let la = &self.l[a];
            let s: f64 = la[..a].iter().zip(&row).map(|(x, y)| x * y).sum();
            row.push((pb.g[(self.passive[a], j)] - s) / la[a]);
        }
        let d2 = pb.g[(j, j)] + RIDGE - row.iter().map(|x| x * x).sum::<f64>();
        // G + ridge·I is positive definite: d2 ≥ ridge in exact arithmetic.
        let d = d2.max(RIDGE * 1e-3).sqrt();
        let ne = pb.e.nrows();
        let mut wr: Vec<f64> = (0..ne).map(|r| pb.e[(r, j)]).collect();
        for (a, wa) in self.w.iter().enumerate() {
            for r in 0..ne {
                wr[r] -= row[a] * wa[r];
            }
        }
        wr.iter_mut().for_each(|v| *v /= d);
        let yj = (pb.c[j] - row.iter().zip(&self.y).map(|(x, y)| x * y).sum::<f64>()) / d;
        row.push(d);
        self.l.push(row);
        self.w.push(wr);
        self.y.push(yj);
        self.passive.push(j);
    }

    /// Removes the passive unknown at factor position `a`: delete L's row a and restore the
    /// triangle by Givens rotations on columns (i, i + 1), applied to the rows of W and y alike.
    fn remove(&mut self, a: usize) {
        self.l.remove(a);
        self.passive.remove(a);
        let k = self.passive.len();
        for i in a..k {
            let (x, z) = (self.l[i][i], self.l[i][i + 1]);
            let r = x.hypot(z);
            let (c, s) = (x / r, z / r);
            for t in i..k {
                let (u, v) = (self.l[t][i], self.l[t][i + 1]);
                self.l[t][i] = c * u + s * v;
                self.l[t][i + 1] = -s * u + c * v;
            }
            self.l[i].truncate(i + 1);
            let (wi, wn) = {
                let (lo, hi) = self.w.split_at_mut(i + 1);
                (&mut lo[i], &mut hi[0])
            };
            for (u, v) in wi.iter_mut().zip(wn.iter_mut()) {
                let (p, q) = (*u, *v);
                *u = c * p + s * q;
                *v = -s * p + c * q;
            }
            let (p, q) = (self.y[i], self.y[i + 1]);
            self.y[i] = c * p + s * q;
            self.y[i + 1] = -s * p + c * q;
        }
        self.w.truncate(k);
        self.y.truncate(k);
    }

    /// Solves L v = b in place.
    fn forward(&self, b: &mut [f64]) {
        for a in 0..b.len() {
            let la = &self.l[a];
            let s: f64 = la[..a].iter().zip(&b[..a]).map(|(x, y)| x * y).sum();
            b[a] = (b[a] - s) / la[a];
        }
    }

    /// Solves Lᵀ v = b in place.
    fn backward(&self, b: &mut [f64]) {
        for a in (0..b.len()).rev() {
            b[a] /= self.l[a][a];
            let v = b[a];
            for (t, lt) in self.l[a][..a].iter().enumerate() {
                b[t] -= lt * v;
            }
        }
    }

    /// The KKT solution on the passive set for the right-hand sides (y = L⁻¹ r₁, r₂): z and ν
    /// with G_PP z + E_Pᵀ ν = r₁, E_P z = r₂. Equality rows dependent on the others over P get
    /// ν = 0 (whether they hold is checked on the answer).
    fn kkt(&self, y: &[f64], r2: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let (k, ne) = (self.passive.len(), r2.len());
        // S = WᵀW and Wᵀy − r₂.
        let mut s = DMatrix::zeros(ne, ne);
        let mut rhs = DVector::from_fn(ne, |r, _| -r2[r]);
        for (wa, ya) in self.w.iter().zip(y) {
            for r in 0..ne {
                rhs[r] += wa[r] * ya;
                for t in 0..=r {
                    s[(r, t)] += wa[r] * wa[t];
                }
            }
        }
        let nu = semidefinite_solve(&mut s, rhs);
        let mut z: Vec<f64> =
            (0..k).map(|a| y[a] - self.w[a].iter().zip(&nu).map(|(w, n)| w * n).sum::<f64>()).collect();
        self.backward(&mut z);
        (z, nu)
    }

    /// The KKT solution with one step of iterative refinement on the full system.
    fn solve(&self, pb: &Problem) -> (Vec<f64>, Vec<f64>) {
        let (mut z, mut nu) = self.kkt(&self.y, pb.f.as_slice());
        let (k, ne) = (self.passive.len(), pb.e.nrows());
        // r₁ = c_P − (G_PP + ridge) z − E_Pᵀ ν, r₂ = e − E_P z.
        let mut r1: Vec<f64> = (0..k)
            .map(|a| {
                let i = self.passive[a];
                let gz: f64 = (0..k).map(|b| pb.g[(i, self.passive[b])] * z[b]).sum::<f64>() + RIDGE * z[a];
                pb.c[i] - gz - (0..ne).map(|r| pb.e[(r, i)] * nu[r]).sum::<f64>()
            })
            .collect();
        let r2: Vec<f64> =
            (0..ne).map(|r| pb.f[r] - (0..k).map(|a| pb.e[(r, self.passive[a])] * z[a]).sum::<f64>()).collect();
        self.forward(&mut r1);
        let (dz, dnu) = self.kkt(&r1, &r2);
        z.iter_mut().zip(&dz).for_each(|(v, d)| *v += d);
        nu.iter_mut().zip(&dnu).for_each(|(v, d)| *v += d);
        (z, nu)
    }
}

/// Solves S ν = b for a symmetric positive semi-definite S (lower triangle given) by a Cholesky
/// factorisation that skips pivots below 1e-12 of their diagonal: those rows depend on earlier
/// ones and get ν = 0.
fn semidefinite_solve(s: &mut DMatrix<f64>, b: DVector<f64>) -> Vec<f64> {
    let n = b.len();
    let mut keep = vec![false; n];
    for j in 0..n {
        let diag = s[(j, j)];
        let mut p = diag;
        for t in 0..j {
            if keep[t] {
                p -= s[(j, t)] * s[(j, t)];
            }
        }
        if p <= 1e-12 * diag.abs() || p <= 0.0 {
            continue;
        }
        keep[j] = true;
        let d = p.sqrt();
        s[(j, j)] = d;
        for i in j + 1..n {
            let mut v = s[(i, j)];
            for t in 0..j {
                if keep[t] {
                    v -= s[(i, t)] * s[(j, t)];
                }
            }
            s[(i, j)] = v / d;
        }
    }
    let mut v = vec![0.0; n];
    for j in 0..n {
        if keep[j] {
            let acc: f64 = (0..j).filter(|&t| keep[t]).map(|t| s[(j, t)] * v[t]).sum();
            v[j] = (b[j] - acc) / s[(j, j)];
        }
    }
    for j in (0..n).rev() {
        if keep[j] {
            let acc: f64 = (j + 1..n).filter(|&t| keep[t]).map(|t| s[(t, j)] * v[t]).sum();
            v[j] = (v[j] - acc) / s[(j, j)];
        }
    }
    v
}

/// Solves the problem (module docs) from the passive set `start` (an NNLS support: the unknowns
/// the answer is likely to use) at x = 0. Returns None when the iteration does not reach a
/// point that meets the equality rows with x ≥ 0 and the KKT conditions within its step limit
/// (the caller then uses the interior point).
pub fn nnls_equalities(gram: &Gram, equalities: &[LinearGroup], l1: f64, start: &[usize]) -> Option<QpSolution> {
    let p = gram.dim();
    let d: Vec<f64> = (0..p).map(|j| if gram.g[(j, j)] > 0.0 { 1.0 / gram.g[(j, j)].sqrt() } else { 1.0 }).collect();
    let ne: usize = equalities.iter().map(|g| g.matrix.nrows()).sum();
    let mut e = DMatrix::zeros(ne, p);
    let mut f = DVector::zeros(ne);
    let mut r0 = 0;
    for g in equalities {
        for r in 0..g.matrix.nrows() {
            for j in 0..p {
                e[(r0 + r, j)] = g.matrix[(r, j)] * d[j];
            }
            f[r0 + r] = g.rhs[r];
        }
        r0 += g.matrix.nrows();
    }
    let pb = Problem {
        g: DMatrix::from_fn(p, p, |i, j| gram.g[(i, j)] * d[i] * d[j]),
        c: DVector::from_fn(p, |j, _| (gram.c[j] - l1) * d[j]),
        e,
        f,
    };
    let tol = ENTER_TOLERANCE * pb.c.amax().max(1e-300);
    let mut factor = Factor::new();
    let mut in_p = vec![false; p];
    for &j in start {
        if !in_p[j] && gram.g[(j, j)] > 0.0 {
            in_p[j] = true;
            factor.append(&pb, j);
        }
    }
    let mut x = DVector::zeros(p);
    // Unknowns that entered and came back at once at ≤ 0 (Lawson–Hanson's guard against
    // cycling on rounding): not tried again until x moves.
    let mut refused = vec![false; p];
    let mut last_entered: Option<usize> = None;
    let mut steps = 0u32;
    // Passive sets met at a feasible point. Meeting one again means rounding has made the
    // iteration cycle (each feasible step lowers the objective in exact arithmetic); from then
    // on the unknown that enters is the first eligible one (Bland's rule) instead of the one of
    // largest reduced gradient. Runs that never repeat a set are unchanged.
    let mut seen: std::collections::HashSet<Vec<usize>> = std::collections::HashSet::new();
    let mut bland = false;
    for _ in 0..4 * p + 20 {
        if factor.passive.is_empty() {
            return None;
        }
        let (z, nu) = factor.solve(&pb);
        steps += 1;
        if z.iter().any(|v| !v.is_finite()) {
            return None;
        }
        if z.iter().all(|&v| v > 0.0) {
            for (a, &j) in factor.passive.iter().enumerate() {
                x[j] = z[a];
            }
            if last_entered.take().is_some() {
                refused.iter_mut().for_each(|r| *r = false);
            }
            let mut set = factor.passive.clone();
            set.sort_unstable();
            if !seen.insert(set) {
                bland = true;
            }
            // Reduced gradient cⱼ − (G x)ⱼ − (Eᵀν)ⱼ of every unknown outside P.
            let support: Vec<(usize, f64)> = factor.passive.iter().map(|&j| (j, x[j])).collect();
            let entering = (0..p)
                .into_par_iter()
                .filter(|&j| !in_p[j] && !refused[j] && gram.g[(j, j)] > 0.0)
                .map(|j| {
                    let gx: f64 = support.iter().map(|&(i, xi)| pb.g[(j, i)] * xi).sum();
                    let en: f64 = (0..ne).map(|r| pb.e[(r, j)] * nu[r]).sum();
                    (pb.c[j] - gx - en, j)
                })
                .filter(|&(w, _)| w > tol)
                .max_by(|a, b| if bland { b.1.cmp(&a.1) } else { a.0.total_cmp(&b.0).then(b.1.cmp(&a.1)) });
            match entering {
                Some((_, j)) => {
                    in_p[j] = true;
                    factor.append(&pb, j);
                    last_entered = Some(j);
                }
                None => return finish(&pb, x, &d, steps),
            }
        } else {
            // The unknown that just entered came back at ≤ 0: refuse it and look again.
            if let Some(j) = last_entered.take() {
                let a = factor.passive.len() - 1;
                if factor.passive[a] == j && z[a] <= 0.0 && z[..a].iter().all(|&v| v > 0.0) {
                    factor.remove(a);
                    in_p[j] = false;
                    refused[j] = true;
                    continue;
                }
            }
            // Step from x towards z until the first unknown reaches zero; drop those at zero.
            let xmax = x.amax().max(1e-300);
            let mut alpha: f64 = 1.0;
            for (a, &j) in factor.passive.iter().enumerate() {
                if z[a] <= 0.0 {
                    alpha = alpha.min(x[j] / (x[j] - z[a]));
                }
            }
            let mut leave = Vec::new();
            for (a, &j) in factor.passive.iter().enumerate() {
                x[j] += alpha * (z[a] - x[j]);
                // Only an unknown heading below zero leaves (from x = 0 the others stay at 0).
                if z[a] <= 0.0 && x[j] <= 1e-12 * xmax {
                    x[j] = 0.0;
                    leave.push(a);
                }
            }
            for &a in leave.iter().rev() {
                in_p[factor.passive[a]] = false;
                factor.remove(a);
            }
            refused.iter_mut().for_each(|r| *r = false);
        }
    }
    None
}

/// Checks the answer (x ≥ 0, equalities) and returns it in the caller's units.
fn finish(pb: &Problem, x: DVector<f64>, d: &[f64], steps: u32) -> Option<QpSolution> {
    let residual = (&pb.e * &x - &pb.f).amax();
    let scale = pb.f.amax().max(1.0);
    if !x.iter().all(|v| v.is_finite() && *v >= 0.0) || residual > EQUALITY_TOLERANCE * scale {
        return None;
    }
    let k = DVector::from_fn(x.len(), |j, _| x[j] * d[j]);
    Some(QpSolution {
        k,
        status: QpStatus::Solved,
        iterations: steps,
        cut_rounds: 0,
        cuts: 0,
        max_equality_residual: residual,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::qp::{QpSettings, qp};
    use crate::solve::test_problems::{group, lcg};

    /// The factor after appends and removals in any order is the Cholesky factor of the passive
    /// set's G (+ ridge) in its new order, and W, y follow it: L W = E_Pᵀ, L y = c_P.
    #[test]
    fn updates_keep_the_factor_of_the_passive_set() {
        let mut seed = 5;
        let (rows, p, ne) = (40, 12, 3);
        let a = DMatrix::from_fn(rows, p, |_, _| lcg(&mut seed));
        let g = a.transpose() * &a;
        let pb = Problem {
            g,
            c: DVector::from_fn(p, |_, _| lcg(&mut seed)),
            e: DMatrix::from_fn(ne, p, |_, _| lcg(&mut seed)),
            f: DVector::zeros(ne),
        };
        let mut fac = Factor::new();
        for j in [3, 7, 0, 11, 5, 9, 2] {
            fac.append(&pb, j);
        }
        fac.remove(2);
        fac.remove(0);
        fac.append(&pb, 1);
        fac.remove(4);
        let k = fac.passive.len();
        let l = DMatrix::from_fn(k, k, |i, j| if j <= i { fac.l[i][j] } else { 0.0 });
        let gp =
            DMatrix::from_fn(k, k, |i, j| pb.g[(fac.passive[i], fac.passive[j])] + if i == j { RIDGE } else { 0.0 });
        assert!((&l * l.transpose() - &gp).amax() < 1e-12 * gp.amax());
        assert!((0..k).all(|i| l[(i, i)] > 0.0));
        let w = DMatrix::from_fn(k, ne, |a, r| fac.w[a][r]);
        let ep = DMatrix::from_fn(k, ne, |a, r| pb.e[(r, fac.passive[a])]);
        assert!((&l * w - ep).amax() < 1e-12);
        let y = DVector::from_fn(k, |a, _| fac.y[a]);
        let cp = DVector::from_fn(k, |a, _| pb.c[fac.passive[a]]);
        assert!((&l * y - cp).amax() < 1e-12);
    }

    /// Random problems with more columns than rows and two equality rows, started from a few
    /// columns: the same optimum as Clarabel's QP (objective to 1e-9, x to 1e-6), the equalities
    /// to round-off, and unknowns leaving the passive set on the way.
    #[test]
    fn reaches_the_qps_optimum() {
        for (seed0, rows, p, start) in
            [(11u64, 60, 150, vec![0, 1, 2]), (17, 200, 120, vec![]), (23, 80, 300, vec![5, 9])]
        {
            let mut seed = seed0;
            let a = DMatrix::from_fn(rows, p, |_, _| lcg(&mut seed));
            let b = DVector::from_fn(rows, |_, _| 2.0 * lcg(&mut seed));
            let gram = Gram::from_rows(&a, &b);
            let e = DMatrix::from_fn(2, p, |r, j| if r == 0 { 1.0 } else { ((j % 7) as f64 - 3.0) / 3.0 });
            let eq = group("equations", e, DVector::from_vec(vec![3.0, 0.2]));
            let eqs = std::slice::from_ref(&eq);
            let full = qp(&gram, eqs, &[], &vec![None; p], 0.01, &QpSettings::default()).unwrap();
            let mut start = start;
            if start.is_empty() {
                start = (0..p).step_by(3).collect();
            }
            let s = nnls_equalities(&gram, eqs, 0.01, &start).unwrap();
            let objective = |k: &DVector<f64>| gram.objective(k) + 0.02 * k.sum();
            let (fo, so) = (objective(&full.k), objective(&s.k));
            assert!(so <= fo * (1.0 + 1e-9), "seed {seed0}: active set {so} against Clarabel {fo}");
            assert!((&s.k - &full.k).amax() < 1e-6 * full.k.amax(), "seed {seed0}: {:e}", (&s.k - &full.k).amax());
            assert!((&eq.matrix * &s.k - &eq.rhs).amax() < 1e-10 && s.k.min() >= 0.0);
        }
    }

    /// Equality rows that depend on each other over the support (the same row twice, and their
    /// sum): the dependent ones carry no multiplier and the answer still meets all of them.
    #[test]
    fn dependent_equality_rows_are_carried_by_the_others() {
        let mut seed = 41;
        let (rows, p) = (50, 80);
        let a = DMatrix::from_fn(rows, p, |_, _| lcg(&mut seed));
        let b = DVector::from_fn(rows, |_, _| lcg(&mut seed));
        let gram = Gram::from_rows(&a, &b);
        let r0: Vec<f64> = (0..p).map(|j| 1.0 + (j % 3) as f64).collect();
        let r1: Vec<f64> = (0..p).map(|j| (j % 5) as f64 - 2.0).collect();
        let e = DMatrix::from_fn(4, p, |r, j| match r {
            0 | 2 => r0[j],
            1 => r1[j],
            _ => r0[j] + r1[j],
        });
        let eq = group("rows", e, DVector::from_vec(vec![4.0, 0.5, 4.0, 4.5]));
        let s = nnls_equalities(&gram, std::slice::from_ref(&eq), 0.0, &[0, 1, 2, 3, 4, 5]).unwrap();
        assert!((&eq.matrix * &s.k - &eq.rhs).amax() < 1e-10);
        let reference = group("rows", eq.matrix.rows(0, 2).into_owned(), DVector::from_vec(vec![4.0, 0.5]));
        let full =
            qp(&gram, std::slice::from_ref(&reference), &[], &vec![None; p], 0.0, &QpSettings::default()).unwrap();
        assert!(gram.objective(&s.k) <= gram.objective(&full.k) * (1.0 + 1e-9));
    }
}
