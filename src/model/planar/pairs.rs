//! The link-pair form of the planar closed forms: M = M₀ + Σ_{a<b} W_{ab} cos(φ_b − φ_a), one
//! constant n × n matrix per link pair, O(n⁴) per evaluation (see the parent module's doc for
//! when it is used).

use nalgebra::DMatrix;

use super::Link;
use crate::model::Workspace;
use crate::numerics::linalg;

/// One link pair (a < b) and its share of the mass matrix: `M += w · cos(ψ)`,
/// ψ = φ_b − φ_a = Σ_{p=a+1..=b} q_p (0-based indices).
#[derive(Debug, Clone)]
struct PairTerm {
    a: usize,
    b: usize,
    /// Column-major n × n coefficient matrix (symmetric).
    w: Vec<f64>,
}

impl PairTerm {
    /// ∂ψ/∂q_p: 1 for a < p ≤ b, else 0.
    #[inline]
    fn touches(&self, p: usize) -> bool {
        p > self.a && p <= self.b
    }

    #[inline]
    fn angle(&self, q: &[f64]) -> f64 {
        q[self.a + 1..=self.b].iter().sum()
    }
}

/// M₀ and the pair terms.
#[derive(Debug, Clone)]
pub(super) struct PairForm {
    /// Constant part of M (column-major n × n).
    m_const: Vec<f64>,
    pairs: Vec<PairTerm>,
}

impl PairForm {
    /// The pair terms of `links`; `r(i, t)` as for [`super::link_angles::LinkAngleForm::new`].
    pub(super) fn new(links: &[Link], r: impl Fn(usize, usize) -> f64) -> Self {
        let n = links.len();
        let mut m_const = vec![0.0; n * n];
        let mut pairs: Vec<PairTerm> = Vec::new();
        for a in 0..n {
            for b in a + 1..n {
                pairs.push(PairTerm { a, b, w: vec![0.0; n * n] });
            }
        }
        let pair_index = |a: usize, b: usize| -> usize {
            // Index of (a, b), a < b, in the order generated above.
            a * n - a * (a + 1) / 2 + (b - a - 1)
        };
        for (i, link) in links.iter().enumerate() {
            for j in 0..=i {
                for k in 0..=i {
                    m_const[j + n * k] += link.inertia;
                    for t in j..=i {
                        for u in k..=i {
                            let c = link.mass * r(i, t) * r(i, u);
                            if t == u {
                                m_const[j + n * k] += c;
                            } else {
                                let (a, b) = if t < u { (t, u) } else { (u, t) };
                                pairs[pair_index(a, b)].w[j + n * k] += c;
                            }
                        }
                    }
                }
            }
        }
        PairForm { m_const, pairs }
    }

    /// sin and cos of each pair's angle into `ws.sin`, `ws.cos` (one `sin_cos` per pair).
    pub(super) fn fill_trig(&self, q: &[f64], ws: &mut Workspace) {
        for (k, pair) in self.pairs.iter().enumerate() {
            let (s, c) = pair.angle(q).sin_cos();
            ws.sin[k] = s;
            ws.cos[k] = c;
        }
    }

    /// M into `ws.m` (after [`Self::fill_trig`]).
    pub(super) fn fill_mass(&self, ws: &mut Workspace) {
        ws.m.copy_from_slice(&self.m_const);
        for (pair, &c) in self.pairs.iter().zip(&ws.cos) {
            for (m, w) in ws.m.iter_mut().zip(&pair.w) {
                *m += w * c;
            }
        }
    }

    /// ∂M/∂q_p, p = 1..n (after [`Self::fill_trig`]).
    pub(super) fn mass_derivatives(&self, ws: &Workspace, n: usize) -> Vec<DMatrix<f64>> {
        let mut out = vec![DMatrix::zeros(n, n); n];
        for (pair, &s) in self.pairs.iter().zip(&ws.sin) {
            let dw = DMatrix::from_column_slice(n, n, &pair.w) * (-s);
            for (p, d) in out.iter_mut().enumerate() {
                if pair.touches(p) {
                    *d += &dw;
                }
            }
        }
        out
    }

    /// h = Σ_pairs −sin ψ (ψ̇ w q̇ − ½ (q̇ᵀ w q̇) d), d the indicator of the joints in ψ, into
    /// `ws.h` (after [`Self::fill_trig`]).
    pub(super) fn coriolis(&self, qd: &[f64], ws: &mut Workspace) {
        let n = qd.len();
        let h = &mut ws.h;
        h.fill(0.0);
        for (pair, &s) in self.pairs.iter().zip(&ws.sin) {
            let psi_dot = pair.angle(qd);
            let mut quad = 0.0;
            for j in 0..n {
                let wq: f64 = (0..n).map(|k| pair.w[j + n * k] * qd[k]).sum();
                quad += qd[j] * wq;
                h[j] -= s * psi_dot * wq;
            }
            for (p, hp) in h.iter_mut().enumerate() {
                if pair.touches(p) {
                    *hp += 0.5 * s * quad;
                }
            }
        }
    }

    /// The Jacobi-field part of the variational right-hand side, Φ̇ from Φ, once the geodesic
    /// part has left a = q̈ in `dy[n..2n]` and the factor of M in `ws.m`.
    pub(super) fn variational(&self, ws: &mut Workspace, y: &[f64], dy: &mut [f64], n: usize) {
        let qd = &y[n..2 * n];
        ws.a.copy_from_slice(&dy[n..2 * n]);
        // With d the joint indicator of a pair, s = sin ψ, c = cos ψ, ψ̇ = dᵀq̇, Q = q̇ᵀwq̇:
        //   M ∂a/∂q  = Σ [ s (w a) + c (ψ̇ w q̇ − ½ Q d) ] dᵀ
        //   M ∂a/∂q̇ = Σ s (w q̇ dᵀ + ψ̇ w − d (w q̇)ᵀ)
        ws.da_dq.fill(0.0);
        ws.da_dqd.fill(0.0);
        for ((pair, &s), &c) in self.pairs.iter().zip(&ws.sin).zip(&ws.cos) {
            let psi_dot = pair.angle(qd);
            let w = &pair.w;
            let mut quad = 0.0;
            for j in 0..n {
                let wq: f64 = (0..n).map(|k| w[j + n * k] * qd[k]).sum();
                let wa: f64 = (0..n).map(|k| w[j + n * k] * ws.a[k]).sum();
                ws.tmp[j] = wq;
                quad += qd[j] * wq;
                // Column vector for ∂a/∂q before the dᵀ: s·wa + c·ψ̇·wq (the −½Qd part below).
                let col = s * wa + c * psi_dot * wq;
                for p in (pair.a + 1)..=pair.b {
                    ws.da_dq[j + n * p] += col;
                    ws.da_dqd[j + n * p] += s * wq;
                }
                for k in 0..n {
                    ws.da_dqd[j + n * k] += s * psi_dot * w[j + n * k];
                }
            }
            for j in (pair.a + 1)..=pair.b {
                for p in (pair.a + 1)..=pair.b {
                    ws.da_dq[j + n * p] -= 0.5 * c * quad;
                }
                for k in 0..n {
                    ws.da_dqd[j + n * k] -= s * ws.tmp[k];
                }
            }
        }
        // Solve M X = (…) column by column with the factor left in ws.m.
        for col in 0..n {
            linalg::cholesky_solve(&ws.m, n, &mut ws.da_dq[n * col..n * (col + 1)]);
            linalg::cholesky_solve(&ws.m, n, &mut ws.da_dqd[n * col..n * (col + 1)]);
        }
        let off_q = 2 * n;
        let off_qd = 2 * n + n * n;
        // Φ̇_q = Φ_q̇
        dy[off_q..off_qd].copy_from_slice(&y[off_qd..off_qd + n * n]);
        // Φ̇_q̇ = ∂a/∂q Φ_q + ∂a/∂q̇ Φ_q̇
        for col in 0..n {
            for row in 0..n {
                let mut acc = 0.0;
                for k in 0..n {
                    acc += ws.da_dq[row + n * k] * y[off_q + k + n * col]
                        + ws.da_dqd[row + n * k] * y[off_qd + k + n * col];
                }
                dy[off_qd + row + n * col] = acc;
            }
        }
    }
}
