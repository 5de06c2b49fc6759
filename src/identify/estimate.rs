//! Least squares with honest uncertainty: the estimate, its covariance from the residual, the
//! problem's condition, and which rate errors the logs cannot tell apart.
//!
//! **Scaling and rank.** The columns of Φ are scaled to unit length, so the condition number
//! κ = √(λ_max / λ_min) of ΦᵀΦ compares directions, not units. Directions with
//! λ ≤ [`RANK_TOLERANCE`] λ_max carry no information: the estimate is the minimum-norm one, and
//! an unknown with a component in them is not estimable at all.
//!
//! **Covariance.** The residual e = y − Φθ̂ of filtered signals is not white: L colours the
//! encoder noise, and what the model misses (friction near a reversal, a motor's ripple) repeats
//! with the swing. The covariance is therefore the sandwich (ΦᵀΦ)⁺ S (ΦᵀΦ)⁺ with S the
//! Newey–West estimate of the scores' long-run covariance: the scores gₜ = Σ φ e over the rows of
//! one sample, their autocovariances up to a lag window of one swing period summed with Bartlett
//! weights, within each run (runs are independent). It needs no noise model, and white residuals
//! give back σ² (ΦᵀΦ)⁻¹.
//!
//! **What cannot be told apart.** A rate whose standard error exceeds the
//! `max_standard_error` is not identified. The logs may still fix combinations of such rates
//! (two springs whose torques are nearly proportional over the swings): in the information of
//! the unidentified rates with every other unknown profiled out (the Schur complement), each
//! eigenvector is a combination; those with a standard error within the bound are identified
//! combinations, the others the logs cannot fix. Unidentified rates that load on a common
//! unfixed combination form a group; a group of one is a rate the logs did not excite. For
//! `tune`, an unidentified rate keeps only its identified combinations: the unfixed ones are
//! left at the design value (δ = 0), the smallest change that explains the logs.

use nalgebra::{DMatrix, DVector};

use super::regression::Rows;

/// Eigenvalues of ΦᵀΦ (unit columns) below this fraction of the largest carry no information.
pub const RANK_TOLERANCE: f64 = 1e-12;

/// A rate loads on a combination when its weight there is at least this (unit combination).
pub const LOADING: f64 = 0.2;

/// A rate that is not identified is reported as unidentified (no δ, no standard error) when
/// its standard error is at least this fraction of the rate: the logs cannot tell the rate
/// from no spring at all or from twice it, so its δ (the minimum-norm value) is no estimate and
/// its standard error says only that.
pub const UNIDENTIFIED_STANDARD_ERROR: f64 = 1.0;

/// The least-squares estimate and its covariance.
#[derive(Debug, Clone)]
pub struct Estimate {
    /// θ̂, in each unknown's unit (minimum norm in the scaled unknowns where the rank is short).
    pub theta: Vec<f64>,
    /// Covariance of θ̂ (Newey–West sandwich), in the unknowns' units.
    pub covariance: DMatrix<f64>,
    /// Whether each unknown is estimable (no component in a direction without information).
    pub estimable: Vec<bool>,
    /// ΦᵀΦ in the unknowns' units.
    pub information: DMatrix<f64>,
    /// The length of each column of Φ: unknown u in unit-column coordinates is θ_u · scale_u.
    pub scale: Vec<f64>,
    /// The exact null space of Φ: the right singular vectors whose singular value is at most
    /// √[`RANK_TOLERANCE`] of the largest, in unit-column coordinates (orthonormal). The logs
    /// fix Φθ, so a combination c·θ is identifiable exactly when c ./ scale is orthogonal to
    /// every one of them.
    pub null_space: Vec<DVector<f64>>,
    /// √(λ_max / λ_min) of ΦᵀΦ with unit columns (infinite when the rank is short).
    pub condition: f64,
    /// Rank of ΦᵀΦ.
    pub rank: usize,
    /// Residual e = y − Φθ̂ per row.
    pub residual: Vec<f64>,
    /// rms of Φ's columns (the torque each unknown's unit change makes), N·m per unit.
    pub column_rms: Vec<f64>,
    /// (ΦᵀΦ)⁺ with unit columns, from the kept eigenpairs.
    pub inverse: DMatrix<f64>,
    /// The Newey–West meat with unit columns, times the small-sample correction: the
    /// covariance with unit columns is `inverse · meat · inverse`.
    pub meat: DMatrix<f64>,
}

impl Estimate {
    /// Standard error of unknown `u` (infinite when not estimable).
    pub fn standard_error(&self, u: usize) -> f64 {
        if self.estimable[u] { self.covariance[(u, u)].max(0.0).sqrt() } else { f64::INFINITY }
    }

    /// The standard error of the combination Σ cᵤ θᵤ (`c` in the unknowns' units), as
    /// √(zᵀ S z) with z = (ΦᵀΦ)⁺ c̃ in unit columns (c̃ᵤ = cᵤ / scaleᵤ) and S the meat.
    ///
    /// Why not cᵀ C c with the covariance C: an identified combination of rates the logs
    /// cannot tell apart has a variance of 1e-10 from entries of C up to 1e4, and the quadratic
    /// form cancels fourteen digits of them; z stays of the combination's own size.
    pub fn combination_standard_error(&self, c: &DVector<f64>) -> f64 {
        let scaled = DVector::from_iterator(c.len(), c.iter().zip(&self.scale).map(|(x, s)| x / s));
        let z = &self.inverse * scaled;
        z.dot(&(&self.meat * &z)).max(0.0).sqrt()
    }
}

/// ΦᵀΦ of some rows in the unknowns' units (its upper triangle kept). It adds over rows, so the
/// plan's loop sums each simulated reading's once, when it is added, to test cheaply whether an
/// identification of the readings so far could identify every rate ([`all_estimable`]).
#[derive(Debug, Clone)]
pub struct Gram(DMatrix<f64>);

impl Gram {
    /// ΦᵀΦ of `rows`.
    pub fn of(rows: &Rows) -> Gram {
        let p = rows.width;
        let mut gram: DMatrix<f64> = DMatrix::zeros(p, p);
        // The upper triangle column by column (column-major), at unit stride.
        let upper = gram.as_mut_slice();
        for r in 0..rows.len() {
            let x = rows.row(r);
            for (c, &xc) in x.iter().enumerate() {
                for (gac, xa) in upper[c * p..=c * p + c].iter_mut().zip(x) {
                    *gac += xa * xc;
                }
            }
        }
        Gram(gram)
    }

    /// No rows yet, for `p` unknowns.
    pub fn zeros(p: usize) -> Gram {
        Gram(DMatrix::zeros(p, p))
    }

    /// Adds ΦᵀΦ of further rows.
    pub fn add(&mut self, other: &Gram) {
        self.0 += &other.0;
    }

    /// ΦᵀΦ, its lower triangle mirrored from the upper (xₐ x_b = x_b xₐ exactly).
    pub fn full(self) -> DMatrix<f64> {
        let mut g = self.0;
        for b in 0..g.ncols() {
            for a in b + 1..g.nrows() {
                g[(a, b)] = g[(b, a)];
            }
        }
        g
    }
}

/// The eigendecomposition of ΦᵀΦ with unit columns, its largest eigenvalue, the eigenpairs
/// kept (above [`RANK_TOLERANCE`] of the largest) and whether each unknown is estimable (its
/// unit vector in the span of the kept eigenvectors).
type Spectrum = (nalgebra::SymmetricEigen<f64, nalgebra::Dyn>, f64, Vec<usize>, Vec<bool>);

fn spectrum(g: DMatrix<f64>) -> Spectrum {
    let p = g.nrows();
    let eig = g.symmetric_eigen();
    let top = eig.eigenvalues.iter().fold(0.0f64, |a, v| a.max(*v));
    let kept: Vec<usize> = (0..p).filter(|&k| eig.eigenvalues[k] > RANK_TOLERANCE * top).collect();
    let estimable: Vec<bool> = (0..p)
        .map(|u| {
            let inside: f64 = kept.iter().map(|&k| eig.eigenvectors[(u, k)].powi(2)).sum();
            inside > 1.0 - 1e-8
        })
        .collect();
    (eig, top, kept, estimable)
}

/// Whether every one of `unknowns` is estimable from rows of ΦᵀΦ `gram`: the test
/// [`least_squares`] makes, on ΦᵀΦ summed reading by reading instead of row by row with unit
/// columns (equal to rounding), without the passes over every row (the normal equations, the
/// residual, the Newey–West meat). A rate that is not estimable has an infinite standard error,
/// so when this is false no identification of these rows identifies every rate; and a rate at
/// the edge of estimability, where rounding could tip the test, has an information some 1e-12
/// of the largest and a standard error far beyond any bound, so the test cannot skip an
/// identification that would have found every rate identified.
pub fn all_estimable(gram: &Gram, unknowns: &[usize]) -> bool {
    let g = &gram.0;
    let p = g.nrows();
    let scale: Vec<f64> = (0..p).map(|k| g[(k, k)]).map(|s| if s > 0.0 { s.sqrt() } else { 1.0 }).collect();
    let unit = DMatrix::from_fn(p, p, |a, c| {
        let (i, j) = if a <= c { (a, c) } else { (c, a) };
        g[(i, j)] / (scale[i] * scale[j])
    });
    let (_, _, _, estimable) = spectrum(unit);
    unknowns.iter().all(|&u| estimable[u])
}

/// Solves y = Φθ in the least-squares sense. `lag_seconds` is the Newey–West window.
pub fn least_squares(rows: &Rows, lag_seconds: f64) -> Estimate {
    let p = rows.width;
    let m = rows.len();
    let mut scale = vec![0.0; p];
    for r in 0..m {
        for (s, x) in scale.iter_mut().zip(rows.row(r)) {
            *s += x * x;
        }
    }
    let column_rms: Vec<f64> = scale.iter().map(|s| (s / m.max(1) as f64).sqrt()).collect();
    let scale: Vec<f64> = scale.iter().map(|s| if *s > 0.0 { s.sqrt() } else { 1.0 }).collect();
    // Scaled normal equations.
    let mut g: DMatrix<f64> = DMatrix::zeros(p, p);
    let mut b: DVector<f64> = DVector::zeros(p);
    let mut phi_s = vec![0.0; p];
    // The upper triangle column by column (G is column-major): each entry sums the same
    // products in the same order as row by row would, at unit stride.
    let upper = g.as_mut_slice();
    for r in 0..m {
        for (k, x) in rows.row(r).iter().enumerate() {
            phi_s[k] = x / scale[k];
        }
        for a in 0..p {
            b[a] += phi_s[a] * rows.y[r];
        }
        for (c, &xc) in phi_s.iter().enumerate() {
            for (gac, xa) in upper[c * p..=c * p + c].iter_mut().zip(&phi_s) {
                *gac += xa * xc;
            }
        }
    }
    for a in 0..p {
        for c in 0..a {
            g[(a, c)] = g[(c, a)];
        }
    }
    let (eig, top, kept, estimable) = spectrum(g.clone());
    let rank = kept.len();
    let null_space: Vec<DVector<f64>> =
        (0..p).filter(|k| !kept.contains(k)).map(|k| eig.eigenvectors.column(k).into_owned()).collect();
    let low = kept.iter().map(|&k| eig.eigenvalues[k]).fold(f64::INFINITY, f64::min);
    let condition = if rank == p && p > 0 { (top / low).sqrt() } else { f64::INFINITY };
    // G⁺ from the kept eigenpairs.
    let mut pinv = DMatrix::zeros(p, p);
    for &k in &kept {
        let v = eig.eigenvectors.column(k);
        pinv += v * v.transpose() / eig.eigenvalues[k];
    }
    let theta_s = &pinv * &b;
    let residual: Vec<f64> = (0..m)
        .map(|r| {
            rows.y[r]
                - rows.row(r).iter().zip(scale.iter().zip(theta_s.iter())).map(|(x, (s, t))| x / s * t).sum::<f64>()
        })
        .collect();
    let meat = newey_west(rows, &scale, &residual, lag_seconds);
    let correction = if m > rank { m as f64 / (m - rank) as f64 } else { 1.0 };
    let cov_s = &pinv * &meat * &pinv * correction;
    let s = DMatrix::from_diagonal(&DVector::from_iterator(p, scale.iter().map(|x| 1.0 / x)));
    let covariance = &s * cov_s * &s;
    let sinv = DMatrix::from_diagonal(&DVector::from_column_slice(&scale));
    let information = &sinv * g * &sinv;
    Estimate {
        theta: theta_s.iter().zip(&scale).map(|(t, s)| t / s).collect(),
        covariance,
        estimable,
        information,
        scale,
        null_space,
        condition,
        rank,
        residual,
        column_rms,
        inverse: pinv,
        meat: meat * correction,
    }
}

/// The Newey–West long-run covariance of the scores gₜ = Σ φₛ e over the rows of each step, with
/// Bartlett weights up to `lag_seconds`, summed over runs.
///
/// Σₜ gₜgₜᵀ + Σₗ wₗ Σₜ (gₜgₜ₊ₗᵀ + gₜ₊ₗgₜᵀ) is SᵀWS, with S a run's scores (a row per step) and W
/// the banded Toeplitz matrix of the weights (1 on the diagonal, wₗ on the l-th off-diagonals).
/// It is formed as Sᵀ(WS): WS costs a few additions per score and lag, and Sᵀ(WS) one p × p
/// product over the steps, where a product per lag cost about 60 of them (a swing period of lags)
/// and most of `identify --plan`'s time on a bill of 141 parts. The two orders of summation agree
/// to rounding; the result is made exactly symmetric.
fn newey_west(rows: &Rows, scale: &[f64], residual: &[f64], lag_seconds: f64) -> DMatrix<f64> {
    let p = rows.width;
    let mut meat = DMatrix::zeros(p, p);
    let mut start = 0;
    while start < rows.len() {
        let run = rows.run[start];
        let end = (start..rows.len()).find(|&r| rows.run[r] != run).unwrap_or(rows.len());
        let steps = rows.step[end - 1] + 1;
        let mut scores = DMatrix::zeros(steps, p);
        for r in start..end {
            let e = residual[r];
            for (k, x) in rows.row(r).iter().enumerate() {
                scores[(rows.step[r], k)] += x / scale[k] * e;
            }
        }
        let lags = ((lag_seconds / rows.step_seconds[run]).ceil() as usize).min(steps.saturating_sub(1));
        // WS, a column (one unknown's scores over the steps) at a time.
        let mut weighted = scores.clone();
        for (g, h) in scores.as_slice().chunks_exact(steps).zip(weighted.as_mut_slice().chunks_exact_mut(steps)) {
            for l in 1..=lags {
                let w = 1.0 - l as f64 / (lags + 1) as f64;
                for t in 0..steps - l {
                    h[t] += w * g[t + l];
                    h[t + l] += w * g[t];
                }
            }
        }
        meat.gemm_tr(1.0, &scores, &weighted, 1.0);
        start = end;
    }
    for j in 0..p {
        for i in 0..j {
            let m = 0.5 * (meat[(i, j)] + meat[(j, i)]);
            meat[(i, j)] = m;
            meat[(j, i)] = m;
        }
    }
    meat
}

/// A combination Σ wᵢ δᵢ of rate errors.
#[derive(Debug, Clone, PartialEq)]
pub struct Combination {
    /// (index into the rates, weight); the weights sum to 1 when they share a sign, else the
    /// largest is ±1.
    pub weights: Vec<(usize, f64)>,
    /// Its estimate.
    pub value: f64,
    /// Its standard error.
    pub standard_error: f64,
}

/// Rates the logs cannot tell apart, and what they do fix about them.
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    /// The rates (indices into the rates).
    pub members: Vec<usize>,
    /// Combinations of them the logs fix (standard error within the bound); the others, as
    /// many as the group has members less these, the logs leave open.
    pub identified: Vec<Combination>,
}

/// What the logs say about the rate errors.
#[derive(Debug, Clone, PartialEq)]
pub struct RateVerdict {
    /// Whether each rate is identified on its own.
    pub identified: Vec<bool>,
    /// The groups of rates that are not.
    pub groups: Vec<Group>,
    /// The rates for `tune`: identified ones as estimated, the others reduced to their
    /// identified combinations (δ = 0 along what the logs leave open).
    pub for_tuning: Vec<f64>,
}

/// A combination of the open rates (coefficients on their δ), its estimate and its standard
/// error (NaN and ∞ where the logs give it no information).
type OpenCombination = (DVector<f64>, f64, f64);

/// Sorts the rates (unknowns `rates`, their δ in `estimate`) into identified ones and groups.
///
/// The rates whose standard error is beyond `bound` are open: their information with the
/// other unknowns eliminated is diagonalised into combinations, each made exactly orthogonal
/// to the null space of Φ ([`Estimate::null_space`]); the identified ones give the rates for
/// tuning, and the open rates that the unidentified ones join form the groups. Each identified
/// combination is reported with the group it loads on most, with all its weights.
pub fn rate_verdict(estimate: &Estimate, rates: &[usize], bound: f64) -> RateVerdict {
    let se: Vec<f64> = rates.iter().map(|&u| estimate.standard_error(u)).collect();
    let identified: Vec<bool> = se.iter().map(|s| *s <= bound).collect();
    let mut for_tuning: Vec<f64> = rates.iter().map(|&u| estimate.theta[u]).collect();
    let open: Vec<usize> = (0..rates.len()).filter(|&i| !identified[i]).collect();
    if open.is_empty() {
        return RateVerdict { identified, groups: Vec::new(), for_tuning };
    }
    let unknowns_open: Vec<usize> = open.iter().map(|&i| rates[i]).collect();
    let combos = open_combinations(estimate, &unknowns_open);
    let fixed: Vec<&OpenCombination> = combos.iter().filter(|(_, _, se)| *se <= bound).collect();
    let reduced = reduce_to(&fixed, open.len());
    for (i, &r) in open.iter().enumerate() {
        for_tuning[r] = reduced[i];
    }
    let group_of = open_groups(&combos, bound, open.len());
    let mut labels: Vec<usize> = Vec::new();
    for &g in &group_of {
        if !labels.contains(&g) {
            labels.push(g);
        }
    }
    // Each identified combination goes to the group it loads on most.
    let home: Vec<usize> = fixed
        .iter()
        .map(|(v, _, _)| {
            let load =
                |label: usize| (0..open.len()).filter(|&i| group_of[i] == label).map(|i| v[i] * v[i]).sum::<f64>();
            (0..labels.len()).max_by(|&a, &b| load(labels[a]).total_cmp(&load(labels[b]))).unwrap_or(0)
        })
        .collect();
    let groups = labels
        .iter()
        .enumerate()
        .map(|(g, &label)| {
            let members: Vec<usize> = (0..open.len()).filter(|&i| group_of[i] == label).collect();
            let identified =
                fixed.iter().zip(&home).filter(|(_, h)| **h == g).map(|(combo, _)| combination(combo, &open)).collect();
            Group { members: members.iter().map(|&i| open[i]).collect(), identified }
        })
        .collect();
    RateVerdict { identified, groups, for_tuning }
}

/// The smallest δ of the open rates (Euclidean norm) that has the identified combinations'
/// values: what the logs leave open stays as designed.
fn reduce_to(fixed: &[&OpenCombination], n_open: usize) -> DVector<f64> {
    if fixed.is_empty() {
        return DVector::zeros(n_open);
    }
    let c = DMatrix::from_fn(fixed.len(), n_open, |k, i| fixed[k].0[i]);
    let b = DVector::from_iterator(fixed.len(), fixed.iter().map(|f| f.1));
    // The combinations are nearly orthonormal (eigenvectors, projected off a null space they
    // are already orthogonal to up to rounding), so Cᵀ is the fallback of C⁺.
    let pinv = c.clone().pseudo_inverse(1e-12).unwrap_or_else(|_| c.transpose());
    pinv * b
}

/// The combinations of the open unknowns: the eigenvectors of their information with every
/// other unknown eliminated (the Schur complement, formed in unit-column coordinates where it
/// is well scaled), each projected exactly onto the row space of Φ (off its null space), with
/// its estimate and standard error ([`Estimate::combination_standard_error`]).
///
/// Why the projection: the logs fix Φθ and nothing else, so c·θ̂ is an unbiased estimate of
/// c·θ only when c lies in the row space. An eigenvector of a nearly singular matrix is only
/// as orthogonal to the exact null space as rounding leaves it, and the minimum-norm θ̂ is
/// zero along that null space while the true θ is not: any leftover component is a bias no
/// standard error covers.
fn open_combinations(estimate: &Estimate, unknowns_open: &[usize]) -> Vec<OpenCombination> {
    let p = estimate.theta.len();
    let n_open = unknowns_open.len();
    let s = &estimate.scale;
    let rest: Vec<usize> = (0..p).filter(|u| !unknowns_open.contains(u)).collect();
    let sub = |a: &[usize], b: &[usize]| {
        DMatrix::from_fn(a.len(), b.len(), |i, j| estimate.information[(a[i], b[j])] / (s[a[i]] * s[b[j]]))
    };
    let g_uu = sub(unknowns_open, unknowns_open);
    let schur_s = if rest.is_empty() {
        g_uu
    } else {
        let g_ur = sub(unknowns_open, &rest);
        let g_rr = sub(&rest, &rest);
        let rr_inv = g_rr.clone().pseudo_inverse(RANK_TOLERANCE * g_rr.amax().max(f64::MIN_POSITIVE)).unwrap_or(g_rr);
        &g_uu - &g_ur * rr_inv * g_ur.transpose()
    };
    // Back to the rates' own units (δ): D S D with D the open columns' lengths.
    let schur = DMatrix::from_fn(n_open, n_open, |i, j| schur_s[(i, j)] * s[unknowns_open[i]] * s[unknowns_open[j]]);
    let eig = schur.symmetric_eigen();
    let top = eig.eigenvalues.iter().fold(0.0f64, |a, v| a.max(*v));
    let theta = DVector::from_iterator(n_open, unknowns_open.iter().map(|&u| estimate.theta[u]));
    (0..n_open)
        .map(|k| {
            let v = eig.eigenvectors.column(k).into_owned();
            if eig.eigenvalues[k] <= RANK_TOLERANCE * top.max(f64::MIN_POSITIVE) {
                return (v, f64::NAN, f64::INFINITY);
            }
            let v = row_space(estimate, unknowns_open, &v);
            let value = v.dot(&theta);
            let mut c = DVector::zeros(p);
            for (&u, x) in unknowns_open.iter().zip(v.iter()) {
                c[u] = *x;
            }
            let se = estimate.combination_standard_error(&c);
            (v, value, se)
        })
        .collect()
}

/// The combination `v` of the unknowns `unknowns_open` with its null-space part removed: in
/// unit-column coordinates c = v ./ scale loses its projection on each null vector, and comes
/// back as c .* scale. (A null vector has no component on an estimable unknown, so nothing
/// moves onto the other unknowns.)
fn row_space(estimate: &Estimate, unknowns_open: &[usize], v: &DVector<f64>) -> DVector<f64> {
    let s = &estimate.scale;
    let mut c = DVector::from_iterator(unknowns_open.len(), unknowns_open.iter().zip(v.iter()).map(|(&u, x)| x / s[u]));
    for n in &estimate.null_space {
        let along: f64 = unknowns_open.iter().zip(c.iter()).map(|(&u, x)| n[u] * x).sum();
        for (i, &u) in unknowns_open.iter().enumerate() {
            c[i] -= along * n[u];
        }
    }
    DVector::from_iterator(unknowns_open.len(), unknowns_open.iter().zip(c.iter()).map(|(&u, x)| x * s[u]))
}

/// Each open rate's group label: open rates joined through the space of unfixed combinations.
/// Its projector P does not depend on which basis the eigensolver picked for a repeated
/// eigenvalue: rates i and j cannot be told apart when |Pᵢⱼ| ≥ LOADING².
fn open_groups(combos: &[OpenCombination], bound: f64, n_open: usize) -> Vec<usize> {
    let mut projector = DMatrix::zeros(n_open, n_open);
    for (v, _, se) in combos {
        if *se > bound {
            projector += v * v.transpose();
        }
    }
    let mut group_of: Vec<usize> = (0..n_open).collect();
    for i in 0..n_open {
        for j in 0..i {
            if projector[(i, j)].abs() >= LOADING * LOADING {
                let (a, b) = (group_of[i], group_of[j]);
                for g in group_of.iter_mut() {
                    if *g == a {
                        *g = b;
                    }
                }
            }
        }
    }
    group_of
}

/// An identified combination as reported (indices into the rates through `open`): every
/// weight but exact zeros (dropping a small one would report a combination the value is not
/// an estimate of), scaled so that the weights sum to 1 when they share a sign, else so that
/// the largest is ±1.
fn combination((v, value, se): &OpenCombination, open: &[usize]) -> Combination {
    let largest = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let w: Vec<(usize, f64)> =
        (0..open.len()).filter(|&i| v[i].abs() > 1e-12 * largest).map(|i| (open[i], v[i])).collect();
    let sum: f64 = w.iter().map(|x| x.1).sum();
    let l1: f64 = w.iter().map(|x| x.1.abs()).sum();
    let norm = if sum.abs() > 0.999 * l1 { sum } else { largest };
    let norm = if norm == 0.0 { 1.0 } else { norm };
    Combination {
        weights: w.iter().map(|&(i, x)| (i, x / norm)).collect(),
        value: value / norm,
        standard_error: se / norm.abs(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numerics::rng::SplitMix64;

    /// Rows of y = Φθ + noise for given columns (one joint, one run).
    fn rows(columns: &[Vec<f64>], theta: &[f64], noise: f64, seed: u64) -> Rows {
        let m = columns[0].len();
        let mut rng = SplitMix64::stream(seed, 0);
        let mut r = Rows { width: columns.len(), step_seconds: vec![0.01], ..Rows::default() };
        for i in 0..m {
            let y: f64 = columns.iter().zip(theta).map(|(c, t)| c[i] * t).sum::<f64>() + noise * rng.normal();
            r.y.push(y);
            for c in columns {
                r.phi.push(c[i]);
            }
            r.designed.push(0.0);
            r.joint.push(0);
            r.t.push(i as f64 * 0.01);
            r.run.push(0);
            r.step.push(i);
        }
        r
    }

    fn signal(m: usize, f: impl Fn(f64) -> f64) -> Vec<f64> {
        (0..m).map(|i| f(i as f64 * 0.01)).collect()
    }

    #[test]
    fn white_noise_gives_the_textbook_standard_errors() {
        // Two well separated columns, white noise σ = 0.1: se = σ / |column|.
        let m = 4000;
        let c = vec![signal(m, |t| (2.0 * t).sin()), signal(m, |t| (5.3 * t).cos())];
        let e = least_squares(&rows(&c, &[0.3, -0.2], 0.1, 1), 0.0);
        for k in 0..2 {
            let norm = c[k].iter().map(|x| x * x).sum::<f64>().sqrt();
            let want = 0.1 / norm;
            assert!((e.standard_error(k) / want - 1.0).abs() < 0.1, "{} vs {want}", e.standard_error(k));
        }
        assert!((e.theta[0] - 0.3).abs() < 4.0 * e.standard_error(0));
        assert!(e.condition < 1.2 && e.rank == 2, "κ {}", e.condition);
    }

    #[test]
    fn coloured_noise_widens_the_standard_errors_as_it_should() {
        // Noise that repeats for 0.5 s (a random walk reset every 50 rows): the white formula
        // would be too optimistic; the Newey–West errors match the spread over seeds.
        let m = 6000;
        let c = vec![signal(m, |t| 1.0 + 0.3 * (0.7 * t).sin())];
        let mut spread = Vec::new();
        let mut reported = Vec::new();
        for seed in 0..40 {
            let mut r = rows(&c, &[1.0], 0.0, seed);
            let mut rng = SplitMix64::stream(100 + seed, 0);
            let mut level = 0.0;
            for i in 0..m {
                if i % 50 == 0 {
                    level = 0.05 * rng.normal();
                }
                r.y[i] += level;
            }
            let e = least_squares(&r, 1.0);
            spread.push(e.theta[0]);
            reported.push(e.standard_error(0));
        }
        let mean = spread.iter().sum::<f64>() / 40.0;
        let sd = (spread.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / 39.0).sqrt();
        let se = reported.iter().sum::<f64>() / 40.0;
        assert!((se / sd - 1.0).abs() < 0.35, "reported {se:.3e}, spread {sd:.3e}");
    }

    #[test]
    fn proportional_columns_are_a_group_with_their_combination_identified() {
        // Columns 0 and 1 proportional (1 : 2): only δ₀ + 2δ₁ shows; column 2 never excited.
        let m = 2000;
        let base = signal(m, |t| (1.3 * t).sin() + 0.2);
        let c =
            vec![base.clone(), base.iter().map(|x| 2.0 * x).collect(), vec![0.0; m], signal(m, |t| (3.1 * t).cos())];
        let e = least_squares(&rows(&c, &[0.02, 0.01, 0.03, -0.04], 1e-4, 3), 0.1);
        assert_eq!(e.rank, 2);
        assert!(e.condition.is_infinite());
        assert!(!e.estimable[0] && !e.estimable[1] && !e.estimable[2] && e.estimable[3]);
        assert!((e.theta[3] + 0.04).abs() < 1e-5);
        let v = rate_verdict(&e, &[0, 1, 2, 3], 0.005);
        assert_eq!(v.identified, vec![false, false, false, true]);
        assert_eq!(v.groups.len(), 2, "{:?}", v.groups);
        let pair = v.groups.iter().find(|g| g.members.len() == 2).unwrap();
        assert_eq!(pair.members, vec![0, 1]);
        // The identified combination is δ₀ + 2δ₁ (weights 1/3, 2/3 of it) = 0.04 / 3.
        let c = &pair.identified[0];
        assert!((c.weights[0].1 - 1.0 / 3.0).abs() < 1e-9 && (c.weights[1].1 - 2.0 / 3.0).abs() < 1e-9, "{c:?}");
        assert!((c.value - 0.04 / 3.0).abs() < 2e-5, "{c:?}");
        let lone = v.groups.iter().find(|g| g.members == vec![2]).unwrap();
        assert!(lone.identified.is_empty());
        // For tuning: the pair reduced to its combination (minimum norm), the lone rate at 0.
        let t = &v.for_tuning;
        assert!((t[0] + 2.0 * t[1] - 0.04).abs() < 2e-5 && (2.0 * t[0] - t[1]).abs() < 1e-9, "{t:?}");
        assert!(t[2].abs() < 1e-15, "{t:?}");
        assert!((t[3] + 0.04).abs() < 1e-5);
    }
}
