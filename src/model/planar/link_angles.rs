//! The link-angle form of the planar closed forms: M = Sᵀ (K ∘ C(φ)) S, O(n²) per evaluation
//! (see the parent module's doc for the derivation and when it is used).

use nalgebra::DMatrix;

use super::Link;
use crate::model::Workspace;
use crate::numerics::linalg;

/// K (column-major n × n, symmetric): the link-angle inertia coefficients,
/// K_{tu} = Σ_{i ≥ max(t,u)} mᵢ r_{it} r_{iu} + δ_{tu} I_t, so that M^φ = K ∘ C(φ).
#[derive(Debug, Clone)]
pub(super) struct LinkAngleForm {
    k: Vec<f64>,
}

/// Sᵀ A S in place for S the lower-triangular matrix of ones (column-major n × n):
/// (Sᵀ A S)_{jk} = Σ_{s ≥ j, t ≥ k} A_{st}, two suffix sums.
fn congruence(a: &mut [f64], n: usize) {
    for j in 0..n {
        for k in (0..n - 1).rev() {
            a[j + n * k] += a[j + n * (k + 1)];
        }
    }
    for k in 0..n {
        for j in (0..n - 1).rev() {
            a[j + n * k] += a[j + 1 + n * k];
        }
    }
}

/// Sᵀ v in place: the suffix sums v_j ← Σ_{s ≥ j} v_s.
fn suffix_sums(v: &mut [f64]) {
    for j in (0..v.len().saturating_sub(1)).rev() {
        v[j] += v[j + 1];
    }
}

/// S v into `out`: the prefix sums out_t = Σ_{i ≤ t} v_i (link-angle rates from joint rates).
fn prefix_sums(v: &[f64], out: &mut [f64]) {
    let mut acc = 0.0;
    for (o, x) in out.iter_mut().zip(v) {
        acc += x;
        *o = acc;
    }
}

impl LinkAngleForm {
    /// K of `links`; `r(i, t)` is link t's lever in link i's centre of mass (its length for
    /// t < i, the centre-of-mass distance for t = i).
    pub(super) fn new(links: &[Link], r: impl Fn(usize, usize) -> f64) -> Self {
        let n = links.len();
        let mut k = vec![0.0; n * n];
        for t in 0..n {
            for u in 0..n {
                let tail: f64 = (t.max(u)..n).map(|i| links[i].mass * r(i, t) * r(i, u)).sum();
                k[t + n * u] = tail + if t == u { links[t].inertia } else { 0.0 };
            }
        }
        LinkAngleForm { k }
    }

    /// cos and sin of φ_s − φ_t into `ws.cos`, `ws.sin` (column-major n × n; sin antisymmetric).
    /// φ_s − φ_t = q_{t+1} + … + q_s for s > t, so one `sin_cos` per joint beyond the first and
    /// a complex product per entry.
    pub(super) fn fill_trig(&self, q: &[f64], ws: &mut Workspace) {
        let n = q.len();
        for t in 0..n {
            ws.cos[t + n * t] = 1.0;
            ws.sin[t + n * t] = 0.0;
        }
        for s in 1..n {
            let (sq, cq) = q[s].sin_cos();
            for t in 0..s {
                // e^{i(φ_s − φ_t)} = e^{i(φ_{s−1} − φ_t)} e^{i q_s}
                let (c0, s0) = (ws.cos[(s - 1) + n * t], ws.sin[(s - 1) + n * t]);
                let (c, si) = (c0 * cq - s0 * sq, s0 * cq + c0 * sq);
                ws.cos[s + n * t] = c;
                ws.cos[t + n * s] = c;
                ws.sin[s + n * t] = si;
                ws.sin[t + n * s] = -si;
            }
        }
    }

    /// M = Sᵀ (K ∘ C) S into `ws.m` (after [`Self::fill_trig`]).
    pub(super) fn fill_mass(&self, ws: &mut Workspace, n: usize) {
        for ((m, k), c) in ws.m.iter_mut().zip(&self.k).zip(&ws.cos) {
            *m = k * c;
        }
        congruence(&mut ws.m, n);
    }

    /// ∂M/∂q_p = Sᵀ Y_p S with Y_p[s, t] = −K_{st} sin(φ_s − φ_t) ([s ≥ p] − [t ≥ p]) (after
    /// [`Self::fill_trig`]).
    pub(super) fn mass_derivatives(&self, ws: &Workspace, n: usize) -> Vec<DMatrix<f64>> {
        (0..n)
            .map(|p| {
                let mut y: Vec<f64> = (0..n * n)
                    .map(|idx| {
                        let (s, t) = (idx % n, idx / n);
                        let side = (s >= p) as i32 - (t >= p) as i32;
                        -self.k[idx] * ws.sin[idx] * side as f64
                    })
                    .collect();
                congruence(&mut y, n);
                DMatrix::from_column_slice(n, n, &y)
            })
            .collect()
    }

    /// h = Sᵀ h^φ with h^φ_s = Σ_t K_{st} sin(φ_s − φ_t) φ̇_t² into `ws.h`, and the link-angle
    /// rates φ̇ = S q̇ into `ws.rate` (after [`Self::fill_trig`]).
    pub(super) fn coriolis(&self, qd: &[f64], ws: &mut Workspace) {
        let n = qd.len();
        prefix_sums(qd, &mut ws.rate);
        for s in 0..n {
            let mut acc = 0.0;
            for t in 0..n {
                acc += self.k[s + n * t] * ws.sin[s + n * t] * ws.rate[t] * ws.rate[t];
            }
            ws.h[s] = acc;
        }
        suffix_sums(&mut ws.h);
    }

    /// The Jacobi-field part of the variational right-hand side, Φ̇ from Φ, once the geodesic
    /// part has left a = q̈ in `dy[n..2n]`, the factor of M in `ws.m` and φ̇ in `ws.rate`.
    pub(super) fn variational(&self, ws: &mut Workspace, y: &[f64], dy: &mut [f64], n: usize) {
        // M ∂a/∂q = −Sᵀ X S and M ∂a/∂q̇ = −Sᵀ E S, with α = S a and ω = S q̇ the link-angle
        // acceleration and rate and, for r ≠ s (K_{sr}, sin and cos of φ_s − φ_r):
        //   X[s, r] = K sin α_r − K cos ω_r²,  X[s, s] = −Σ_{t≠s} X[s, t],
        //   E[s, r] = 2 K sin ω_r,             E[s, s] = 0,
        // the link-angle Jacobians of (∂M^φ/∂φ) α + h^φ and of h^φ. The rows of X sum to zero
        // because the terms depend on φ only through differences.
        prefix_sums(&dy[n..2 * n], &mut ws.a);
        for s in 0..n {
            let mut diag = 0.0;
            for r in 0..n {
                if r == s {
                    continue;
                }
                let idx = s + n * r;
                let (kk, si, co, w) = (self.k[idx], ws.sin[idx], ws.cos[idx], ws.rate[r]);
                let x = kk * (si * ws.a[r] - co * w * w);
                ws.da_dq[idx] = x;
                diag += x;
                ws.da_dqd[idx] = 2.0 * kk * si * w;
            }
            ws.da_dq[s + n * s] = -diag;
            ws.da_dqd[s + n * s] = 0.0;
        }
        let off_q = 2 * n;
        let off_qd = 2 * n + n * n;
        // Φ̇_q = Φ_q̇
        dy[off_q..off_qd].copy_from_slice(&y[off_qd..off_qd + n * n]);
        // Φ̇_q̇ = −M⁻¹ Sᵀ (X S Φ_q + E S Φ_q̇), column by column.
        for col in 0..n {
            prefix_sums(&y[off_q + n * col..off_q + n * (col + 1)], &mut ws.tmp);
            prefix_sums(&y[off_qd + n * col..off_qd + n * (col + 1)], &mut ws.tmp2);
            let out = &mut dy[off_qd + n * col..off_qd + n * (col + 1)];
            out.fill(0.0);
            // Column by column of X and E: contiguous in memory, so the inner loop vectorises.
            for k in 0..n {
                let (u, v) = (ws.tmp[k], ws.tmp2[k]);
                let (x, e) = (&ws.da_dq[n * k..n * (k + 1)], &ws.da_dqd[n * k..n * (k + 1)]);
                for ((o, x), e) in out.iter_mut().zip(x).zip(e) {
                    *o -= x * u + e * v;
                }
            }
            suffix_sums(out);
            linalg::cholesky_solve(&ws.m, n, out);
        }
    }
}
