//! Designing for the build: the expected residual over manufacturing deviations.
//!
//! A build scales each stiffness, kᵢ → kᵢ (1 + δᵢ), with δᵢ independent, mean 0 and variance
//! σᵢ² (see [`crate::tolerance`]), and it is judged about its *own* equilibrium: that is where
//! it rests and how `sweep` and the as-built figures judge it. To first order the build's
//! gradient at q_eq changes by Δg = Σᵢ δᵢ kᵢ gᵢ (gᵢ = ∇uᵢ(q_eq)), so its equilibrium moves by
//! Δq = −H⁻¹ Δg (H = ∇²U(q_eq), = ω² M(q_eq) with the Hessian match), and the training rows taken
//! about the moved equilibrium change by
//!
//! ΔR = Σᵢ δᵢ kᵢ (Aᵢ − J H⁻¹ gᵢ),
//!
//! where Aᵢ is candidate i's (weighted) column of the rows and J = ∂R/∂(base point) is how the
//! rows of the nominal potential change when the training fan starts elsewhere: the same
//! directions (in the metric frame of the new base point) and arc lengths, traced from
//! q_eq ± ε eⱼ, central differences. Hence
//!
//! E‖R(build)‖² ≈ ‖A k − b‖² + Σᵢ Dᵢᵢ kᵢ²,  Dᵢᵢ = σᵢ² ‖Aᵢ − J H⁻¹ gᵢ‖²:
//!
//! a diagonal added to the normal equations, which every solver and the sparse selection see as
//! one least-squares problem (equivalently extra rows √Dᵢᵢ eᵢ). Charging the rows about the *old*
//! equilibrium instead (Dᵢᵢ = σᵢ² ‖Aᵢ‖²) penalises every preloaded element for a shift the
//! build absorbs, and throws out the useful antagonistic pairs. The expected squared metric
//! shift of the equilibrium, E‖Δq‖²_M = Σᵢ σᵢ² kᵢ² ‖H⁻¹ gᵢ‖²_M, can be penalised as well (an
//! optional weight; tuning after the build can put the equilibrium back instead).

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use super::problem::{Requirements, assemble};
use crate::catalog::Candidate;
use crate::error::{Error, Result};
use crate::geodesic::{Fan, MetricFrame, Shooter, Stop};
use crate::model::Chain;
use crate::ode::OdeSettings;
use crate::potential::{Potential, SpringSet};

/// Step of the central differences in the base point, rad. The rows are smooth in the base
/// point; the geodesics are integrated to ≤ 1e-9, so the differences carry ~1e-5 of noise and
/// ~1e-8 of truncation error.
pub const BASE_STEP: f64 = 1e-4;

/// First-order effect of the deviations, per candidate and per unit kᵢ².
#[derive(Debug, Clone, PartialEq)]
pub struct Spread {
    /// Dᵢᵢ = σᵢ² ‖Aᵢ − J H⁻¹ gᵢ‖²: expected squared change of the training rows about the build's
    /// own equilibrium.
    pub rows: DVector<f64>,
    /// σᵢ² ‖H⁻¹ gᵢ‖²_M(q_eq): expected squared metric shift of the equilibrium (rad²·kg·m²).
    pub shift: DVector<f64>,
}

/// The fan `nominal` traced again from `base`: the same directions in the metric frame at
/// `base`, the same arc lengths and sample spacing `spacing`. Sample i of geodesic d corresponds
/// to sample i of the nominal geodesic d.
pub fn retrace(chain: &Chain, base: &DVector<f64>, nominal: &Fan, spacing: f64, ode: OdeSettings) -> Result<Fan> {
    let frame = MetricFrame::new(&chain.mass_matrix(base))?;
    let results: Vec<Result<crate::geodesic::Geodesic>> = nominal
        .frame_directions
        .par_iter()
        .zip(nominal.geodesics.par_iter())
        .map_init(
            || Shooter::new(chain, base, ode),
            |shooter, (u, g)| {
                let t = shooter.trace(&frame.to_joint(u), Stop::Arc(g.length()), spacing)?;
                let same =
                    t.len() == g.len() && (0..t.len()).all(|i| (t.s(i) - g.s(i)).abs() <= 1e-9 * spacing.max(1.0));
                if !same {
                    return Err(Error::numerical(
                        "tolerance-aware fit",
                        format!(
                            "the training geodesic retraced from {:?} has {} samples where the nominal one has {}",
                            base.as_slice(),
                            t.len(),
                            g.len()
                        ),
                    ));
                }
                Ok(t)
            },
        )
        .collect();
    let geodesics = results.into_iter().collect::<Result<Vec<_>>>()?;
    Ok(Fan { q_eq: base.clone(), frame_directions: nominal.frame_directions.clone(), geodesics })
}

/// The training rows R = A k − b of a spring set on a fan (weighted as in the fit).
pub fn rows_of(chain: &Chain, fan: &Fan, springs: &SpringSet, omega: f64) -> DVector<f64> {
    let candidates: Vec<Candidate> = springs
        .elements
        .iter()
        .map(|e| Candidate {
            element: e.clone(),
            family: 0,
            max_stiffness: None,
            stock_rates: Vec::new(),
            tolerance: 0.0,
        })
        .collect();
    let req = Requirements { omega, hessian_match: false, monotone: false };
    let problem = assemble(chain, &fan.q_eq, fan, &candidates, req);
    &problem.rows * DVector::from_column_slice(&springs.stiffness) - problem.rhs
}

/// J = ∂R/∂(base point) (m × n) of the nominal spring set's rows, by central differences of fans
/// retraced from q_eq ± [`BASE_STEP`] eⱼ.
pub fn base_jacobian(
    chain: &Chain,
    training: &Fan,
    spacing: f64,
    nominal: &SpringSet,
    omega: f64,
    ode: OdeSettings,
) -> Result<DMatrix<f64>> {
    let n = chain.dof();
    let q_eq = &training.q_eq;
    let mut cols = Vec::with_capacity(n);
    for j in 0..n {
        let mut rows = Vec::with_capacity(2);
        for sign in [1.0, -1.0] {
            let mut base = q_eq.clone();
            base[j] += sign * BASE_STEP;
            let fan = retrace(chain, &base, training, spacing, ode)?;
            rows.push(rows_of(chain, &fan, nominal, omega));
        }
        cols.push((&rows[0] - &rows[1]) / (2.0 * BASE_STEP));
    }
    Ok(DMatrix::from_columns(&cols))
}

/// The first-order spread of every candidate (see the module docs). `rows` are the fit's
/// weighted rows (one column per candidate), `nominal` the nominal fit's spring set whose rows
/// define J and whose Hessian at q_eq is H, `sigma2[i]` the variance of candidate i's deviation.
#[allow(clippy::too_many_arguments)]
pub fn spread(
    chain: &Chain,
    training: &Fan,
    spacing: f64,
    candidates: &[Candidate],
    rows: &DMatrix<f64>,
    nominal: &SpringSet,
    sigma2: &[f64],
    omega: f64,
    ode: OdeSettings,
) -> Result<Spread> {
    let q_eq = training.q_eq.as_slice();
    let hess = nominal.hessian(q_eq)? + chain.gravity_hessian(q_eq);
    let h_inv = hess.clone().cholesky().map(|c| c.inverse()).ok_or_else(|| {
        Error::numerical(
            "tolerance-aware fit",
            "the nominal fit's Hessian at q_eq is not positive definite: a build has no nearby equilibrium to judge it about",
        )
    })?;
    let jac = base_jacobian(chain, training, spacing, nominal, omega, ode)?;
    if jac.nrows() != rows.nrows() {
        return Err(Error::numerical(
            "tolerance-aware fit",
            format!("{} retraced rows against {} training rows", jac.nrows(), rows.nrows()),
        ));
    }
    let jh = &jac * &h_inv;
    let m_eq = chain.mass_matrix(&training.q_eq);
    let mut d_rows = DVector::zeros(candidates.len());
    let mut d_shift = DVector::zeros(candidates.len());
    for (i, c) in candidates.iter().enumerate() {
        if sigma2[i] == 0.0 {
            continue;
        }
        let g = c.element.gradient(q_eq);
        let col = rows.column(i);
        if g.iter().all(|v| *v == 0.0) {
            d_rows[i] = sigma2[i] * col.norm_squared();
            continue;
        }
        d_rows[i] = sigma2[i] * (col - &jh * &g).norm_squared();
        let h = &h_inv * &g;
        d_shift[i] = sigma2[i] * h.dot(&(&m_eq * &h));
    }
    Ok(Spread { rows: d_rows, shift: d_shift })
}
