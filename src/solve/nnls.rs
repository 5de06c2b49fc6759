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
    if gram.dim() >= ORDERED_FROM {
        if l1 == 0.0
            && let Some(sol) = nnls_mirrored(gram, settings, passive_start, free)?
        {
            return Ok(sol);
        }
        nnls_with::<UpdatedFactor>(gram, l1, settings, passive_start, free)
    } else {
        nnls_with::<PassiveFactor>(gram, l1, settings, passive_start, free)
    }
}

/// For each unknown, the earlier unknown whose column of G and entry of c it is the exact negation
/// of (bit for bit), where that earlier one sits just before it, is sign-constrained, non-zero and
/// no one's mirror itself: a cam's ± basis columns (listed in that order, `lsq::mirrors`).
fn mirrored_pairs(gram: &Gram, free: &[bool]) -> Vec<Option<usize>> {
    let p = gram.dim();
    let is_free = |j: usize| free.get(j).copied().unwrap_or(false);
    let mut of = vec![None; p];
    for j in 1..p {
        let i = j - 1;
        if of[i].is_some() || is_free(i) || is_free(j) || gram.g[(i, i)] <= 0.0 || gram.c[j] != -gram.c[i] {
            continue;
        }
        if gram.g.column(j).iter().zip(gram.g.column(i).iter()).all(|(a, b)| *a == -*b) {
            of[j] = Some(i);
        }
    }
    of
}

/// NNLS without an L1 weight on a problem whose unknowns come in mirrored pairs (a cam's + and −
/// basis columns, [`mirrored_pairs`]): each pair is one unknown free of sign, k₊ = max(x, 0) and
/// k₋ = max(−x, 0). The same minimum (a pair's two columns only ever add up to one column times
/// k₊ − k₋, and at an optimum one of them is zero), reached with half the unknowns and without
/// Lawson–Hanson bringing every coefficient in one at a time: on cams alone it is one linear
/// solve. None when there are no pairs.
fn nnls_mirrored(
    gram: &Gram,
    settings: &NnlsSettings,
    passive_start: &[usize],
    free: &[bool],
) -> Result<Option<NnlsSolution>> {
    let p = gram.dim();
    let of = mirrored_pairs(gram, free);
    if of.iter().all(Option::is_none) {
        return Ok(None);
    }
    let mirrored: Vec<bool> = (0..p).map(|i| of.get(i + 1).is_some_and(|m| *m == Some(i))).collect();
    let kept: Vec<usize> = (0..p).filter(|&j| of[j].is_none()).collect();
    let at: std::collections::HashMap<usize, usize> = kept.iter().enumerate().map(|(a, &j)| (j, a)).collect();
    let reduced = gram.subset(&kept);
    let reduced_free: Vec<bool> = kept.iter().map(|&j| mirrored[j] || free.get(j).copied().unwrap_or(false)).collect();
    let start: Vec<usize> =
        passive_start.iter().filter_map(|&j| at.get(&of.get(j).copied().flatten().unwrap_or(j)).copied()).collect();
    let sol = nnls_with::<UpdatedFactor>(&reduced, 0.0, settings, &start, &reduced_free)?;
    let mut k = DVector::zeros(p);
    for (a, &j) in kept.iter().enumerate() {
        let x = sol.k[a];
        if mirrored[j] {
            if x > 0.0 {
                k[j] = x;
            } else if x < 0.0 {
                k[j + 1] = -x;
            }
        } else {
            k[j] = x;
        }
    }
    let objective = gram.objective(&k);
    Ok(Some(NnlsSolution { k, objective, iterations: sol.iterations }))
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

/// The Cholesky factor of the passive-set system kept in place and updated, for NNLS of
/// [`ORDERED_FROM`] unknowns or more (the passive set in entry order): an unknown entering appends
/// one row (a forward substitution, O(n²)), an unknown leaving deletes its row and column and
/// restores the rows after it by a rank-one update of the trailing block (Givens-style, O((n−k)²)
/// for position k), all in one buffer of fixed leading dimension that only grows. A passive set
/// that is not the stored one with unknowns removed and others appended (or a new ridge) is
/// factored from scratch by faer's blocked Cholesky. [`PassiveFactor`] instead rebuilt the factor
/// in a fresh buffer at every solve and refactored every column after a dropped one: on a tendon
/// catalogue's 9,472 cam columns that was 79 % of the selection (BENCHMARKS.md). The updates
/// round differently from a fresh factor (within a few ulps of the condition number), so below
/// the threshold, where the shipped designs' fits keep their bits, `PassiveFactor` stays.
#[derive(Debug, Default)]
struct UpdatedFactor {
    /// The passive set of `l`, in its order; empty when nothing is stored.
    idx: Vec<usize>,
    /// The ridge of `l`, as bits.
    ridge_bits: u64,
    /// L column-major with leading dimension `cap`: entry (i, j), i ≥ j, at `j * cap + i`.
    l: Vec<f64>,
    /// The leading dimension (and most unknowns `l` holds).
    cap: usize,
    /// Scratch of the updates.
    work: Vec<f64>,
}

impl PassiveSolver for UpdatedFactor {
    fn factor(&mut self, g: &DMatrix<f64>, idx: &[usize], ridge: f64) -> bool {
        let ok = self.update(g, idx, ridge);
        if !ok {
            self.idx.clear();
        }
        ok
    }
    fn solve(&self, b: &DVector<f64>) -> DVector<f64> {
        self.solve_stored(b)
    }
}

impl UpdatedFactor {
    /// Brings the stored factor to G_PP + ridge·I for P = `idx`; false if it is not numerically
    /// positive definite.
    fn update(&mut self, g: &DMatrix<f64>, idx: &[usize], ridge: f64) -> bool {
        if self.ridge_bits != ridge.to_bits() || self.idx.is_empty() {
            return self.fresh(g, idx, ridge);
        }
        // The stored unknowns that stay must be `idx`'s first entries, in the same order.
        let stays: std::collections::HashSet<usize> = idx.iter().copied().collect();
        let kept = self.idx.iter().filter(|j| stays.contains(j)).count();
        if !self.idx.iter().filter(|j| stays.contains(j)).zip(idx).all(|(a, b)| a == b) {
            return self.fresh(g, idx, ridge);
        }
        // Deletions from the last position back, so that the positions still to go stay valid.
        let gone: Vec<usize> = (0..self.idx.len()).filter(|&a| !stays.contains(&self.idx[a])).collect();
        if gone.len() + (idx.len() - kept) > idx.len() / 2 + 8 {
            // Most of the set changes: a fresh factor is cheaper than the updates.
            return self.fresh(g, idx, ridge);
        }
        for &a in gone.iter().rev() {
            self.delete(a);
        }
        for &j in &idx[kept..] {
            if !self.append(g, j, ridge) {
                return false;
            }
        }
        true
    }

    /// Factors G_PP + ridge·I from scratch (faer) into the buffer.
    fn fresh(&mut self, g: &DMatrix<f64>, idx: &[usize], ridge: f64) -> bool {
        let n = idx.len();
        self.idx.clear();
        self.ridge_bits = ridge.to_bits();
        let m = DMatrix::from_fn(n, n, |i, j| g[(idx[i], idx[j])] + if i == j { ridge } else { 0.0 });
        let Some(l) = super::dense::cholesky_lower(m) else { return false };
        if l.diagonal().iter().any(|v| !(v.is_finite() && *v > 0.0)) {
            return false;
        }
        self.reserve(n);
        let cap = self.cap;
        for j in 0..n {
            self.l[j * cap + j..j * cap + n].copy_from_slice(&l.as_slice()[j * n + j..j * n + n]);
        }
        self.idx.extend_from_slice(idx);
        true
    }

    /// Room for `n` unknowns (the stored factor moved to the larger leading dimension).
    fn reserve(&mut self, n: usize) {
        if n <= self.cap {
            return;
        }
        let cap = n.max(2 * self.cap).max(64);
        let mut l = vec![0.0; cap * cap];
        let old = self.idx.len();
        for j in 0..old {
            l[j * cap + j..j * cap + old].copy_from_slice(&self.l[j * self.cap + j..j * self.cap + old]);
        }
        self.l = l;
        self.cap = cap;
    }

    /// Appends unknown `j` as the last row: L y = G_Pj, L_nn = √(G_jj + ridge − yᵀy).
    fn append(&mut self, g: &DMatrix<f64>, j: usize, ridge: f64) -> bool {
        let n = self.idx.len();
        self.reserve(n + 1);
        let cap = self.cap;
        let mut y = std::mem::take(&mut self.work);
        y.clear();
        y.extend(self.idx.iter().map(|&i| g[(i, j)]));
        // Column-oriented forward substitution (contiguous columns of L).
        for k in 0..n {
            let col = &self.l[k * cap..k * cap + n];
            let yk = y[k] / col[k];
            y[k] = yk;
            for (v, lik) in y[k + 1..].iter_mut().zip(&col[k + 1..]) {
                *v -= lik * yk;
            }
        }
        let d = g[(j, j)] + ridge - y.iter().map(|v| v * v).sum::<f64>();
        let ok = d.is_finite() && d > 0.0;
        if ok {
            for (k, v) in y.iter().enumerate() {
                self.l[k * cap + n] = *v;
            }
            self.l[n * cap + n] = d.sqrt();
            self.idx.push(j);
        }
        self.work = y;
        ok
    }

    /// Deletes the unknown at position `a`: the rows after it keep L₃₃' L₃₃'ᵀ = L₃₃ L₃₃ᵀ + l l^T
    /// (l its column below the diagonal) by a rank-one update, then everything after moves up one.
    fn delete(&mut self, a: usize) {
        let n = self.idx.len();
        let cap = self.cap;
        let mut x = std::mem::take(&mut self.work);
        x.clear();
        x.extend_from_slice(&self.l[a * cap + a + 1..a * cap + n]);
        // Rank-one update of the trailing block (rows and columns a+1..n).
        for (t, k) in (a + 1..n).enumerate() {
            let col = &mut self.l[k * cap..k * cap + n];
            let lkk = col[k];
            let xk = x[t];
            let r = lkk.hypot(xk);
            let (c, s) = (r / lkk, xk / lkk);
            col[k] = r;
            for (lik, xi) in col[k + 1..].iter_mut().zip(x[t + 1..].iter_mut()) {
                *lik = (*lik + s * *xi) / c;
                *xi = c * *xi - s * *lik;
            }
        }
        // Close the gap: row a out of the columns before it, column a out of the rest.
        for j in 0..a {
            self.l.copy_within(j * cap + a + 1..j * cap + n, j * cap + a);
        }
        for k in a + 1..n {
            self.l.copy_within(k * cap + k..k * cap + n, (k - 1) * cap + (k - 1));
        }
        self.idx.remove(a);
        self.work = x;
    }

    /// Solves (L Lᵀ) z = b with the stored factor.
    fn solve_stored(&self, b: &DVector<f64>) -> DVector<f64> {
        let n = self.idx.len();
        let cap = self.cap;
        let mut z = b.clone();
        for k in 0..n {
            let col = &self.l[k * cap..k * cap + n];
            let zk = z[k] / col[k];
            z[k] = zk;
            for (v, lik) in z.as_mut_slice()[k + 1..].iter_mut().zip(&col[k + 1..]) {
                *v -= lik * zk;
            }
        }
        for k in (0..n).rev() {
            let col = &self.l[k * cap..k * cap + n];
            let dot: f64 = col[k + 1..].iter().zip(&z.as_slice()[k + 1..]).map(|(l, v)| l * v).sum();
            z[k] = (z[k] - dot) / col[k];
        }
        z
    }
}

/// From this many unknowns NNLS keeps its passive set in the order the unknowns entered rather
/// than sorted, factors its systems by updates in place (`UpdatedFactor`: an entering unknown
/// adds one row, a leaving one a rank-one update of the rows after it) and solves a cam's
/// mirrored ± columns as one signed unknown (`mirrored_pairs`). On a tendon catalogue's
/// thousands of cam columns refactoring was most of the fit (the dense NNLS of the selection's
/// start). The order and the updates change the factor's rounding, so the threshold sits above
/// every shipped design's problems (the largest, `ur5_six`'s 1,230 columns).
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
    fn updated_factors_equal_fresh_factors_after_many_updates() {
        // Unknowns entering at the end and leaving from anywhere (several at once, as a
        // Lawson–Hanson step back drops them), now and then a jump to an unrelated set: after every
        // change the stored factor is the Cholesky factor of G_PP + ridge·I computed afresh, and
        // its solution solves the system.
        let mut seed = 29;
        let p = 90;
        let a = DMatrix::from_fn(140, p, |_, _| lcg(&mut seed));
        let g = a.transpose() * &a;
        let c = DVector::from_fn(p, |_, _| lcg(&mut seed));
        let ridge = 1e-12;
        let mut factor = UpdatedFactor::default();
        let mut order: Vec<usize> = Vec::new();
        let mut updates = 0;
        for step in 0..300 {
            let u = ((lcg(&mut seed) + 1.0) * 0.5 * p as f64) as usize % p;
            if step % 61 == 60 {
                order = (0..p).filter(|_| lcg(&mut seed) > 0.3).collect();
            } else if order.len() > 8 && (order.contains(&u) || lcg(&mut seed) > 0.6) {
                let drop = if step % 5 == 0 { 3 } else { 1 };
                for _ in 0..drop {
                    let at = ((lcg(&mut seed) + 1.0) * 0.5 * order.len() as f64) as usize % order.len();
                    order.remove(at);
                }
            } else if !order.contains(&u) {
                order.push(u);
            }
            let before = factor.idx.clone();
            assert!(factor.factor(&g, &order, ridge), "step {step}");
            if !before.is_empty() && before != order {
                updates += 1;
            }
            let n = order.len();
            let m = DMatrix::from_fn(n, n, |i, j| g[(order[i], order[j])] + if i == j { ridge } else { 0.0 });
            let fresh = m.clone().cholesky().expect("positive definite").l();
            let cap = factor.cap;
            let scale = fresh.amax();
            for j in 0..n {
                for i in j..n {
                    let mine = factor.l[j * cap + i];
                    assert!(
                        (mine - fresh[(i, j)]).abs() <= 1e-10 * scale,
                        "step {step}, L[{i},{j}]: {mine} vs {}",
                        fresh[(i, j)]
                    );
                }
            }
            let rhs = DVector::from_fn(n, |r, _| c[order[r]]);
            let z = factor.solve(&rhs);
            assert!((&m * &z - &rhs).amax() <= 1e-9 * rhs.amax(), "step {step}");
        }
        assert!(updates > 200, "{updates} updates");
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
