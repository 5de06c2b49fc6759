//! Non-negative least squares: Lawson–Hanson's active-set method on the normal equations.
//!
//! Working on (G, c) instead of the rows (the "fast NNLS" of Bro & de Jong, 1997) makes each
//! iteration cost O(|P|³) for the passive set P, independent of the number of samples; the
//! sparse selection calls it thousands of times on small subsets. Columns are scaled to unit
//! diagonal first (stiffness units span many orders of magnitude). Passive-set systems are solved
//! by Cholesky with a ridge of 1e-12 on the unit diagonal, so rank-deficient sets (duplicated or
//! linearly dependent columns, such as crank phases) give one of the equivalent solutions
//! deterministically instead of making the active set cycle. Equalities are not handled here: the fit folds them into (G, c)
//! with a stated weight (see `FitSettings::equality_weight`).

use nalgebra::{DMatrix, DVector};

use super::lsq::Gram;
use crate::error::{Error, Result};

/// Settings of the NNLS solver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NnlsSettings {
    /// Stop when no free variable has a gradient component above this fraction of the largest
    /// |c| (the KKT tolerance).
    pub tolerance: f64,
    /// Most outer iterations as a multiple of the number of unknowns.
    pub max_iterations_factor: usize,
}

impl Default for NnlsSettings {
    fn default() -> Self {
        NnlsSettings { tolerance: 1e-12, max_iterations_factor: 5 }
    }
}

/// A non-negative least-squares solution.
#[derive(Debug, Clone, PartialEq)]
pub struct NnlsSolution {
    /// The solution, ≥ 0.
    pub k: DVector<f64>,
    /// ‖A k − b‖² + 2λ Σ k.
    pub objective: f64,
    /// Outer iterations (elements brought into the passive set).
    pub iterations: usize,
}

/// Minimises ‖A k − b‖² + 2λ Σk over k ≥ 0 given the normal equations.
pub fn nnls(gram: &Gram, l1: f64, settings: &NnlsSettings) -> Result<NnlsSolution> {
    nnls_warm(gram, l1, settings, &[])
}

/// [`nnls`] starting with the unknowns `passive` in the passive set (a warm start from a
/// nearby problem's support: the backward elimination refits supports that differ by a few
/// elements). Starting from k = 0 with that passive set, the usual Lawson–Hanson steps first drop
/// whatever must be zero, so the answer is the same as from a cold start, only faster.
pub fn nnls_warm(gram: &Gram, l1: f64, settings: &NnlsSettings, passive_start: &[usize]) -> Result<NnlsSolution> {
    nnls_signed(gram, l1, settings, passive_start, &[])
}

/// NNLS with upper bounds by clamp-and-refit: unknowns above their bound are fixed at it and the
/// rest refitted, until none exceeds its bound. Not the exact bounded optimum in general (the QP
/// gives that) but it never violates a bound and equals NNLS when no bound is active.
///
/// `signed[j]`: unknown j is free of sign (a group's coefficient); its bound u means |k| ≤ u and
/// it is clamped at ±u.
pub fn nnls_bounded(gram: &Gram, l1: f64, upper: &[Option<f64>], signed: &[bool]) -> Result<DVector<f64>> {
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

/// [`nnls_warm`] with some unknowns free of sign (`free[j]`; an empty slice means none): a group's
/// signed coefficients (a cam's B-spline coefficients). Free unknowns are passive from the start and never leave the passive
/// set, so Lawson–Hanson's steps only ever clamp the sign-constrained ones: with springs absent
/// this is one linear solve. The L1 weight applies to the sign-constrained unknowns only (on a
/// free one it would not be linear); cams are regularised by their smoothing penalty instead.
pub fn nnls_signed(
    gram: &Gram,
    l1: f64,
    settings: &NnlsSettings,
    passive_start: &[usize],
    free: &[bool],
) -> Result<NnlsSolution> {
    nnls_with::<PassiveFactor>(gram, l1, settings, passive_start, free)
}

/// How the passive-set systems are factored: the hand-written reusing Cholesky (what the fit
/// uses) or faer's (for `benches/kernels.rs`, which measured both; see [`PassiveFactor`]).
#[doc(hidden)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PassiveVariant {
    /// [`PassiveFactor`]: shared columns reused, the rest register-blocked, nalgebra's
    /// triangular solves.
    HandWritten,
    /// The same factor with faer's triangular solves.
    HandWrittenFaerSolve,
    /// faer's blocked Cholesky of every passive set from scratch, faer's solves.
    Faer,
}

/// [`nnls_signed`] with the passive-set factorisation `variant` (for the benchmark).
#[doc(hidden)]
pub fn nnls_signed_variant(
    gram: &Gram,
    l1: f64,
    settings: &NnlsSettings,
    passive_start: &[usize],
    free: &[bool],
    variant: PassiveVariant,
) -> Result<NnlsSolution> {
    match variant {
        PassiveVariant::HandWritten => nnls_with::<PassiveFactor>(gram, l1, settings, passive_start, free),
        PassiveVariant::HandWrittenFaerSolve => {
            nnls_with::<HandFactorFaerSolve>(gram, l1, settings, passive_start, free)
        }
        PassiveVariant::Faer => nnls_with::<FaerFactor>(gram, l1, settings, passive_start, free),
    }
}

fn nnls_with<F: PassiveSolver>(
    gram: &Gram,
    l1: f64,
    settings: &NnlsSettings,
    passive_start: &[usize],
    free: &[bool],
) -> Result<NnlsSolution> {
    let p = gram.dim();
    let is_free = |j: usize| free.get(j).copied().unwrap_or(false);
    if p == 0 {
        return Ok(NnlsSolution { k: DVector::zeros(0), objective: gram.bb, iterations: 0 });
    }
    // Column scaling: k = D x with D = diag(G)^(-1/2); zero columns stay at zero.
    let d: Vec<f64> = (0..p).map(|j| if gram.g[(j, j)] > 0.0 { 1.0 / gram.g[(j, j)].sqrt() } else { 0.0 }).collect();
    let g = DMatrix::from_fn(p, p, |i, j| gram.g[(i, j)] * d[i] * d[j]);
    let c = DVector::from_fn(p, |i, _| (gram.c[i] - if is_free(i) { 0.0 } else { l1 }) * d[i]);
    if g.iter().chain(c.iter()).any(|v| !v.is_finite()) {
        return Err(Error::numerical("NNLS", "the least-squares problem has non-finite entries"));
    }
    // Only the sign-constrained entries of a passive-set solution must be positive.
    let positive = |z: &DVector<f64>, idx: &[usize]| idx.iter().enumerate().all(|(a, &j)| is_free(j) || z[a] > 0.0);
    let tol = settings.tolerance * c.amax().max(1e-300);
    let mut x = DVector::zeros(p);
    let mut passive = vec![false; p];
    let mut forbidden = vec![false; p];
    let max_outer = settings.max_iterations_factor.max(1) * p + 10;
    let mut iterations = 0;
    let mut factor = F::default();
    // From [`ORDERED_FROM`] unknowns the passive set is kept in the order its unknowns entered
    // (see there); below it, sorted, as always.
    let ordered = p >= ORDERED_FROM;
    let mut order: Vec<usize> = Vec::new();
    let passive_set = |passive: &[bool], order: &mut Vec<usize>| -> Vec<usize> {
        if ordered {
            order.retain(|&i| passive[i]);
            order.clone()
        } else {
            (0..p).filter(|&i| passive[i]).collect()
        }
    };
    let fixed_free: Vec<usize> = (0..p).filter(|&j| is_free(j) && d[j] > 0.0).collect();
    if !fixed_free.is_empty() {
        // The free unknowns alone: any signs are feasible, so this is the starting point.
        let z = solve_passive(&g, &c, &fixed_free, &mut factor);
        for (a, &j) in fixed_free.iter().enumerate() {
            passive[j] = true;
            x[j] = z[a];
        }
        order.extend_from_slice(&fixed_free);
        iterations += 1;
    }
    let warm: Vec<usize> = passive_start.iter().copied().filter(|&j| j < p && d[j] > 0.0 && !passive[j]).collect();
    if !warm.is_empty() {
        // Warm start: the whole starting set enters at once if its unconstrained solution is
        // positive (a feasible point to continue from); otherwise start cold. (Stepping from
        // x = 0 towards a solution with non-positive entries only drops the whole set again,
        // and an exactly zero entry made that step undefined.)
        let idx: Vec<usize> = (0..p).filter(|&j| passive[j] || warm.contains(&j)).collect();
        let z = solve_passive(&g, &c, &idx, &mut factor);
        if z.iter().all(|v| v.is_finite()) && positive(&z, &idx) {
            for (a, &j) in idx.iter().enumerate() {
                passive[j] = true;
                x[j] = z[a];
            }
            let new: Vec<usize> = idx.iter().copied().filter(|j| !order.contains(j)).collect();
            order.extend(new);
        }
        iterations += 1;
    }
    loop {
        let j = {
            // w = c − G x. G x adds G_·j x_j column by column in increasing j, as nalgebra's
            // product does, skipping the zero entries of x (about half: they only add zeros).
            let mut gx = DVector::zeros(p);
            for (j, &xj) in x.iter().enumerate().filter(|(_, xj)| **xj != 0.0) {
                for (y, gij) in gx.iter_mut().zip(g.column(j).iter()) {
                    *y += gij * xj;
                }
            }
            let w = &c - gx;
            let next = (0..p)
                .filter(|&j| !passive[j] && !forbidden[j] && d[j] > 0.0 && w[j] > tol)
                .max_by(|&a, &b| w[a].total_cmp(&w[b]).then(b.cmp(&a)));
            let Some(j) = next else { break };
            j
        };
        iterations += 1;
        if iterations > max_outer {
            return Err(Error::numerical("NNLS", format!("no convergence in {max_outer} iterations")));
        }
        passive[j] = true;
        if ordered {
            // (Unknowns dropped since the last solve may still be listed.)
            order.retain(|&i| i != j && passive[i]);
            order.push(j);
        }
        let mut first = true;
        loop {
            let idx: Vec<usize> = passive_set(&passive, &mut order);
            let z = solve_passive(&g, &c, &idx, &mut factor);
            if positive(&z, &idx) {
                for (a, &i) in idx.iter().enumerate() {
                    x[i] = z[a];
                }
                break;
            }
            // The element just added cannot enter (round-off at the KKT boundary): forbid it for
            // this solve instead of cycling.
            let constrained: Vec<usize> = (0..idx.len()).filter(|&a| !is_free(idx[a])).collect();
            if first && constrained.len() == 1 && z[constrained[0]] <= 0.0 {
                passive[j] = false;
                forbidden[j] = true;
                break;
            }
            first = false;
            let mut alpha = f64::INFINITY;
            for (a, &i) in idx.iter().enumerate() {
                if !is_free(i) && z[a] <= 0.0 {
                    let t = x[i] / (x[i] - z[a]);
                    if t < alpha {
                        alpha = t;
                    }
                }
            }
            for (a, &i) in idx.iter().enumerate() {
                x[i] += alpha * (z[a] - x[i]);
                if !is_free(i) && (x[i] <= 0.0 || (z[a] <= 0.0 && x[i] <= 1e-14 * x.amax())) {
                    x[i] = 0.0;
                    passive[i] = false;
                }
            }
            if idx.iter().all(|&i| !passive[i] || is_free(i)) {
                break;
            }
        }
    }
    let k = DVector::from_fn(p, |i, _| x[i] * d[i]);
    let objective = gram.objective(&k) + 2.0 * l1 * (0..p).filter(|&j| !is_free(j)).map(|j| k[j]).sum::<f64>();
    Ok(NnlsSolution { k, objective, iterations })
}

/// Solves G_PP z = c_P, with a small ridge when G_PP is (numerically) singular.
fn solve_passive<F: PassiveSolver>(g: &DMatrix<f64>, c: &DVector<f64>, idx: &[usize], factor: &mut F) -> DVector<f64> {
    let n = idx.len();
    let rhs = DVector::from_fn(n, |a, _| c[idx[a]]);
    // A ridge of 1e-12 on the unit diagonal keeps near-dependent sets (crank phases span only two
    // functions per coupling) from producing wild passive-set solutions that make the active set
    // cycle; it moves well-posed solutions by ~1e-12 relative.
    let mut ridge = 1e-12;
    loop {
        if factor.factor(g, idx, ridge) {
            let z = factor.solve(&rhs);
            if z.iter().all(|v| v.is_finite()) {
                return z;
            }
        }
        ridge *= 100.0;
        if ridge > 1.0 {
            return DVector::zeros(n);
        }
    }
}

/// The Cholesky factor L of the last passive-set system G_PP + ridge·I, kept so that the next
/// passive set reuses the columns it shares.
///
/// Lawson–Hanson changes the passive set by one or a few unknowns per solve. In the
/// left-looking Cholesky, column k of L depends only on the unknowns up to position k and, for
/// each row, on that row's own entries: the columns before the first position where the sorted
/// passive sets differ are the same numbers for every row both sets contain, and only the
/// columns from there on (and the new rows) are computed. The arithmetic is nalgebra's
/// `Cholesky::new` operation for operation (each entry A_ij − Σ_k L_ik L_jk accumulated in
/// increasing k, then divided by L_jj; the same triangular solves), so every solution is the
/// same to the last bit as before the reuse existed, and so are the fits: only faster. The
/// window's eight cams (512 ± columns, 1232 Lawson–Hanson steps, 2215 passive solves of up to
/// 246 unknowns) spent 1.25 s in these factorizations from scratch; with the shared columns
/// reused and the rest register-blocked ([`update_block`]), 0.65 s.
///
/// Kept against faer (`cargo bench --bench kernels`, [`nnls_signed_variant`]): faer's blocked
/// Cholesky of every passive set from scratch made the window cams' NNLS 18 % slower (593 →
/// 700 ms), the default design's NNLS of all 402 columns 11 % slower and 2000 refits of
/// 12-column subsets 14 % slower; the reuse beats a faster factorisation of the whole set, and
/// at a dozen unknowns faer's setup costs more than the arithmetic. faer's triangular solves
/// with this factor gained nothing measurable either (and would change the fits' last bits).
#[derive(Debug, Default)]
struct PassiveFactor {
    /// The passive set of `l` (sorted); empty when nothing is stored.
    idx: Vec<usize>,
    /// The ridge of `l`, as bits.
    ridge_bits: u64,
    /// L, |P| × |P| column-major; only the lower triangle is meaningful.
    l: Vec<f64>,
    /// Spare storage for the next factor.
    spare: Vec<f64>,
}

/// A factorisation of the passive-set systems G_PP + ridge·I.
trait PassiveSolver: Default {
    /// Factors G_PP + ridge·I for P = `idx` (sorted); false if it is not numerically positive
    /// definite (a zero, negative or NaN pivot, as nalgebra's `cholesky()` would refuse).
    fn factor(&mut self, g: &DMatrix<f64>, idx: &[usize], ridge: f64) -> bool;
    /// Solves (L Lᵀ) z = b with the stored factor.
    fn solve(&self, b: &DVector<f64>) -> DVector<f64>;
}

impl PassiveSolver for PassiveFactor {
    fn factor(&mut self, g: &DMatrix<f64>, idx: &[usize], ridge: f64) -> bool {
        PassiveFactor::factor(self, g, idx, ridge)
    }
    fn solve(&self, b: &DVector<f64>) -> DVector<f64> {
        PassiveFactor::solve(self, b)
    }
}

/// [`PassiveFactor`] with faer's triangular solves (measured, not used: see `PassiveFactor`).
#[derive(Debug, Default)]
struct HandFactorFaerSolve(PassiveFactor);

impl PassiveSolver for HandFactorFaerSolve {
    fn factor(&mut self, g: &DMatrix<f64>, idx: &[usize], ridge: f64) -> bool {
        self.0.factor(g, idx, ridge)
    }
    fn solve(&self, b: &DVector<f64>) -> DVector<f64> {
        let n = self.0.idx.len();
        let l = faer::MatRef::from_column_major_slice(&self.0.l, n, n);
        let mut z = b.clone();
        let rhs = faer::MatMut::from_column_major_slice_mut(z.as_mut_slice(), n, 1);
        faer::linalg::cholesky::llt::solve::solve_in_place(
            l,
            rhs,
            faer::Par::Seq,
            faer::dyn_stack::MemStack::new(&mut []),
        );
        z
    }
}

/// faer's Cholesky of every passive set from scratch (measured, not used: see `PassiveFactor`).
#[derive(Debug, Default)]
struct FaerFactor {
    l: DMatrix<f64>,
}

impl PassiveSolver for FaerFactor {
    fn factor(&mut self, g: &DMatrix<f64>, idx: &[usize], ridge: f64) -> bool {
        let n = idx.len();
        let m = DMatrix::from_fn(n, n, |i, j| g[(idx[i], idx[j])] + if i == j { ridge } else { 0.0 });
        match super::dense::cholesky_lower(m) {
            Some(l) => {
                self.l = l;
                true
            }
            None => false,
        }
    }
    fn solve(&self, b: &DVector<f64>) -> DVector<f64> {
        let n = self.l.nrows();
        let l = faer::MatRef::from_column_major_slice(self.l.as_slice(), n, n);
        let mut z = b.clone();
        let rhs = faer::MatMut::from_column_major_slice_mut(z.as_mut_slice(), n, 1);
        faer::linalg::cholesky::llt::solve::solve_in_place(
            l,
            rhs,
            faer::Par::Seq,
            faer::dyn_stack::MemStack::new(&mut []),
        );
        z
    }
}

impl PassiveFactor {
    /// Factors G_PP + ridge·I for P = `idx` (sorted); false if it is not numerically positive
    /// definite (a zero, negative or NaN pivot, as nalgebra's `cholesky()` would refuse).
    fn factor(&mut self, g: &DMatrix<f64>, idx: &[usize], ridge: f64) -> bool {
        let n = idx.len();
        let same_ridge = self.ridge_bits == ridge.to_bits();
        let r = if same_ridge { self.idx.iter().zip(idx).take_while(|(a, b)| a == b).count() } else { 0 };
        let old_n = self.idx.len();
        let mut l = std::mem::take(&mut self.spare);
        l.clear();
        l.resize(n * n, 0.0);
        let a = |i: usize, j: usize| {
            let v = g[(idx[i], idx[j])];
            if i == j { v + ridge } else { v }
        };
        let mut ok = true;
        if r > 0 {
            // Rows past the shared prefix: runs of rows the stored factor has (copied column by
            // column), and new rows.
            let mut runs: Vec<(usize, usize, usize)> = Vec::new(); // (new row, old row, length)
            let mut fresh: Vec<usize> = Vec::new();
            // The stored set is sorted, or (from `ORDERED_FROM` unknowns) in entry order.
            let sorted = self.idx.windows(2).all(|w| w[0] < w[1]);
            let position: std::collections::HashMap<usize, usize> = if sorted {
                std::collections::HashMap::new()
            } else {
                self.idx.iter().enumerate().map(|(o, &j)| (j, o)).collect()
            };
            let find = |row: &usize| -> std::result::Result<usize, usize> {
                if sorted { self.idx.binary_search(row) } else { position.get(row).copied().ok_or(0) }
            };
            for (i, row) in idx.iter().enumerate().skip(r) {
                match find(row) {
                    Ok(o) => match runs.last_mut() {
                        Some((ni, oi, len)) if *ni + *len == i && *oi + *len == o => *len += 1,
                        _ => runs.push((i, o, 1)),
                    },
                    Err(_) => fresh.push(i),
                }
            }
            for j in 0..r {
                // The shared column: its prefix rows and the runs, as stored.
                let (old, new) = (&self.l[j * old_n..(j + 1) * old_n], &mut l[j * n..(j + 1) * n]);
                new[j..r].copy_from_slice(&old[j..r]);
                for &(ni, oi, len) in &runs {
                    new[ni..ni + len].copy_from_slice(&old[oi..oi + len]);
                }
            }
            // A new row i of the shared columns: L_ij = (A_ij − Σ_{k<j} L_jk L_ik) / L_jj, the
            // terms of each entry added in increasing k as the column update adds them, here
            // spread from each finished L_ik over the later entries at once.
            let mut acc = vec![0.0; r];
            for &i in &fresh {
                for (j, v) in acc.iter_mut().enumerate() {
                    *v = a(i, j);
                }
                for k in 0..r {
                    let lik = acc[k] / l[k * n + k];
                    l[k * n + i] = lik;
                    for (v, ljk) in acc[k + 1..].iter_mut().zip(&l[k * n + k + 1..k * n + r]) {
                        *v += -ljk * lik;
                    }
                }
            }
        }
        // The other columns in blocks: first every finished column's contribution to the whole
        // block (register-blocked, see `update_block`), then the block's own columns in turn.
        let mut jb = r;
        while ok && jb < n {
            let je = (jb + BLOCK).min(n);
            for j in jb..je {
                for i in j..n {
                    l[j * n + i] = a(i, j);
                }
            }
            update_block(&mut l, n, jb, je);
            for j in jb..je {
                let (done, rest) = l.split_at_mut(j * n);
                let col = &mut rest[..n];
                for k in jb..j {
                    let f = -done[k * n + j];
                    for (y, x) in col[j..].iter_mut().zip(&done[k * n + j..k * n + n]) {
                        *y += f * x;
                    }
                }
                let diag = col[j];
                if diag.is_nan() || diag <= 0.0 {
                    ok = false;
                    break;
                }
                let denom = diag.sqrt();
                col[j] = denom;
                for y in &mut col[j + 1..] {
                    *y /= denom;
                }
            }
            jb = je;
        }
        self.spare = std::mem::replace(&mut self.l, l);
        if ok {
            self.idx.clear();
            self.idx.extend_from_slice(idx);
            self.ridge_bits = ridge.to_bits();
        } else {
            self.idx.clear();
        }
        ok
    }

    /// Solves (L Lᵀ) z = b with the stored factor (nalgebra's triangular solves).
    fn solve(&self, b: &DVector<f64>) -> DVector<f64> {
        let n = self.idx.len();
        let l = nalgebra::DMatrixView::from_slice(&self.l, n, n);
        let mut z = b.clone();
        l.solve_lower_triangular_unchecked_mut(&mut z);
        l.ad_solve_lower_triangular_unchecked_mut(&mut z);
        z
    }
}

/// From this many unknowns NNLS keeps its passive set in the order the unknowns entered rather
/// than sorted: an unknown entering then adds one row to the stored factor (`PassiveFactor`
/// reuses every column before the first difference) instead of refactoring every column after
/// its place, which on a tendon catalogue's thousands of cam columns was most of the fit (the
/// dense NNLS of the selection's start). The order changes the factor's rounding, so the
/// threshold sits above every shipped design's problems (the largest, `ur5_six`'s 1,230 columns).
pub const ORDERED_FROM: usize = 2000;

/// Columns factored together by [`update_block`].
const BLOCK: usize = 4;

/// Adds the contributions −L_jk L_ik of the finished columns k < `jb` to the columns
/// `jb..je` (rows from `jb` on) of the column-major n × n factor `l`, each entry's terms in
/// increasing k as the column-by-column update adds them (the same numbers). Four rows by four
/// columns are accumulated in registers over all k: one pass over the finished columns per four
/// rows instead of one per column, which is what made the plain update slow (it streamed every
/// finished column once per new column). Entries above a column's diagonal are scratch.
fn update_block(l: &mut [f64], n: usize, jb: usize, je: usize) {
    let (done, rest) = l.split_at_mut(jb * n);
    let width = je - jb;
    let mut i0 = jb;
    if width == BLOCK {
        while i0 + 4 <= n {
            let mut acc = [[0.0f64; 4]; BLOCK];
            for (c, a) in acc.iter_mut().enumerate() {
                a.copy_from_slice(&rest[c * n + i0..c * n + i0 + 4]);
            }
            for col in done.chunks_exact(n) {
                let x = &col[i0..i0 + 4];
                let f = &col[jb..jb + BLOCK];
                for (a, fc) in acc.iter_mut().zip(f) {
                    let fc = -fc;
                    for (y, xr) in a.iter_mut().zip(x) {
                        *y += fc * xr;
                    }
                }
            }
            for (c, a) in acc.iter().enumerate() {
                rest[c * n + i0..c * n + i0 + 4].copy_from_slice(a);
            }
            i0 += 4;
        }
    }
    // The rows left over (and narrow blocks): entry by entry.
    for c in 0..width {
        for i in i0..n {
            let mut acc = rest[c * n + i];
            for col in done.chunks_exact(n) {
                acc += -col[jb + c] * col[i];
            }
            rest[c * n + i] = acc;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(seed: &mut u64) -> f64 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    /// Exhaustive NNLS for tiny problems: the best unconstrained solution over every support
    /// whose entries are all positive.
    fn brute_force(gram: &Gram) -> DVector<f64> {
        let p = gram.dim();
        let mut best = (gram.bb, DVector::zeros(p));
        for mask in 1..(1u32 << p) {
            let idx: Vec<usize> = (0..p).filter(|i| mask & (1 << i) != 0).collect();
            let sub = gram.subset(&idx);
            if let Some(ch) = sub.g.clone().cholesky() {
                let z = ch.solve(&sub.c);
                if z.iter().all(|v| *v >= 0.0) {
                    let mut k = DVector::zeros(p);
                    for (a, &i) in idx.iter().enumerate() {
                        k[i] = z[a];
                    }
                    let obj = gram.objective(&k);
                    if obj < best.0 {
                        best = (obj, k);
                    }
                }
            }
        }
        best.1
    }

    /// The old passive solve: nalgebra's Cholesky of each passive system from scratch.
    fn reference_solve(g: &DMatrix<f64>, c: &DVector<f64>, idx: &[usize]) -> DVector<f64> {
        let n = idx.len();
        let sub = DMatrix::from_fn(n, n, |a, b| g[(idx[a], idx[b])]);
        let rhs = DVector::from_fn(n, |a, _| c[idx[a]]);
        let mut ridge = 1e-12;
        loop {
            let mut m = sub.clone();
            for a in 0..n {
                m[(a, a)] += ridge;
            }
            if let Some(ch) = m.cholesky() {
                let z = ch.solve(&rhs);
                if z.iter().all(|v| v.is_finite()) {
                    return z;
                }
            }
            ridge *= 100.0;
            if ridge > 1.0 {
                return DVector::zeros(n);
            }
        }
    }

    #[test]
    fn reused_factors_give_nalgebras_solutions_to_the_last_bit() {
        let mut seed = 17;
        let p = 40;
        // Full rank, and rank deficient (duplicated columns: the ridge path).
        let a = DMatrix::from_fn(60, p, |_, _| lcg(&mut seed));
        let dup = DMatrix::from_fn(60, p, |i, j| a[(i, j % 25)]);
        for rows in [a, dup] {
            let g = rows.transpose() * &rows;
            let c = DVector::from_fn(p, |_, _| lcg(&mut seed));
            let mut factor = PassiveFactor::default();
            let mut passive = vec![false; p];
            for step in 0..400 {
                // Mostly one unknown in or out at a random place (as Lawson–Hanson does), now
                // and then a jump to a fresh set.
                let u = ((lcg(&mut seed) + 1.0) * 0.5 * p as f64) as usize % p;
                if step % 37 == 0 {
                    for v in passive.iter_mut() {
                        *v = lcg(&mut seed) > 0.0;
                    }
                } else {
                    passive[u] = !passive[u];
                }
                let idx: Vec<usize> = (0..p).filter(|&j| passive[j]).collect();
                let mine = solve_passive(&g, &c, &idx, &mut factor);
                let theirs = reference_solve(&g, &c, &idx);
                assert_eq!(mine.len(), theirs.len());
                for (x, y) in mine.iter().zip(theirs.iter()) {
                    assert_eq!(x.to_bits(), y.to_bits(), "step {step}: {x} vs {y}");
                }
            }
        }
    }

    #[test]
    fn faer_passive_factors_give_the_same_solutions() {
        // The measured alternatives (faer's Cholesky from scratch, faer's solves with the reused
        // factor) solve the same problems: same support, same stiffnesses to 1e-9 relative.
        let mut seed = 23;
        for (m, p) in [(60, 8), (200, 40), (300, 120)] {
            let a = DMatrix::from_fn(m, p, |_, _| lcg(&mut seed));
            let b = DVector::from_fn(m, |_, _| lcg(&mut seed));
            let gram = Gram::from_rows(&a, &b);
            let s = NnlsSettings::default();
            let hand = nnls_signed_variant(&gram, 0.0, &s, &[], &[], PassiveVariant::HandWritten).unwrap();
            assert_eq!(hand, nnls(&gram, 0.0, &s).unwrap());
            for v in [PassiveVariant::HandWrittenFaerSolve, PassiveVariant::Faer] {
                let other = nnls_signed_variant(&gram, 0.0, &s, &[], &[], v).unwrap();
                let support = |k: &DVector<f64>| k.iter().map(|x| *x > 0.0).collect::<Vec<_>>();
                assert_eq!(support(&hand.k), support(&other.k), "{v:?}, {m} × {p}");
                assert!((&hand.k - &other.k).amax() <= 1e-9 * hand.k.amax(), "{v:?}, {m} × {p}");
            }
        }
    }

    #[test]
    fn recovers_known_non_negative_solutions() {
        let mut seed = 7;
        let a = DMatrix::from_fn(40, 8, |_, _| lcg(&mut seed));
        let k_true = DVector::from_vec(vec![1.0, 0.0, 2.5, 0.0, 0.0, 0.3, 4.0, 0.0]);
        let b = &a * &k_true;
        let sol = nnls(&Gram::from_rows(&a, &b), 0.0, &NnlsSettings::default()).unwrap();
        assert!((&sol.k - &k_true).amax() < 1e-10, "{}", sol.k);
    }

    #[test]
    fn matches_exhaustive_search_on_small_problems() {
        let mut seed = 11;
        for _ in 0..20 {
            let a = DMatrix::from_fn(10, 4, |_, _| lcg(&mut seed));
            let b = DVector::from_fn(10, |_, _| lcg(&mut seed));
            let gram = Gram::from_rows(&a, &b);
            let sol = nnls(&gram, 0.0, &NnlsSettings::default()).unwrap();
            let reference = brute_force(&gram);
            assert!((&sol.k - &reference).amax() < 1e-9, "{} vs {}", sol.k, reference);
        }
    }

    #[test]
    fn warm_starts_give_the_cold_answer() {
        let mut seed = 13;
        for _ in 0..10 {
            let a = DMatrix::from_fn(30, 8, |_, _| lcg(&mut seed));
            let b = DVector::from_fn(30, |_, _| lcg(&mut seed));
            let gram = Gram::from_rows(&a, &b);
            let cold = nnls(&gram, 0.0, &NnlsSettings::default()).unwrap();
            for start in [vec![0, 1, 2, 3, 4, 5, 6, 7], vec![2, 5], vec![]] {
                let warm = nnls_warm(&gram, 0.0, &NnlsSettings::default(), &start).unwrap();
                assert!((&warm.k - &cold.k).amax() < 1e-10, "{} vs {}", warm.k, cold.k);
            }
        }
    }

    #[test]
    fn textbook_instance() {
        // min ‖A k − b‖, A = [[1, 0], [0, 1], [1, 1]], b = (2, −1, 1): the unconstrained optimum
        // has k₂ < 0; the NNLS answer is k = (1.5, 0) with residual (0.5, −1, −0.5).
        let a = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
        let b = DVector::from_vec(vec![2.0, -1.0, 1.0]);
        let sol = nnls(&Gram::from_rows(&a, &b), 0.0, &NnlsSettings::default()).unwrap();
        assert!((sol.k[0] - 1.5).abs() < 1e-11 && sol.k[1] == 0.0);
        assert!((sol.objective - 1.5).abs() < 1e-12);
    }

    #[test]
    fn duplicated_columns_do_not_break_it() {
        let mut seed = 3;
        let base = DMatrix::from_fn(30, 3, |_, _| lcg(&mut seed));
        let a = DMatrix::from_fn(30, 5, |i, j| base[(i, [0, 1, 2, 1, 2][j])]);
        let b = &base * DVector::from_vec(vec![1.0, 2.0, 3.0]);
        let sol = nnls(&Gram::from_rows(&a, &b), 0.0, &NnlsSettings::default()).unwrap();
        // The split between duplicates is arbitrary, their sums are not.
        assert!((sol.k[0] - 1.0).abs() < 1e-8);
        assert!((sol.k[1] + sol.k[3] - 2.0).abs() < 1e-8);
        assert!((sol.k[2] + sol.k[4] - 3.0).abs() < 1e-8);
        assert!(sol.objective < 1e-12);
    }

    #[test]
    fn l1_weight_shrinks_and_sparsifies() {
        let mut seed = 5;
        let a = DMatrix::from_fn(50, 6, |_, _| lcg(&mut seed));
        let b = &a * DVector::from_vec(vec![1.0, 0.05, 2.0, 0.02, 0.0, 1.5]);
        let gram = Gram::from_rows(&a, &b);
        let plain = nnls(&gram, 0.0, &NnlsSettings::default()).unwrap();
        let sparse = nnls(&gram, 2.0, &NnlsSettings::default()).unwrap();
        assert!(sparse.k.sum() < plain.k.sum());
        let nz = |k: &DVector<f64>| k.iter().filter(|v| **v > 0.0).count();
        assert!(nz(&sparse.k) < nz(&plain.k), "{} vs {}", sparse.k, plain.k);
    }
}
