//! The exact potential ½ω²r², the physical limit every spring set approaches.

use nalgebra::{DMatrix, DVector};

use super::Potential;
use crate::error::Result;
use crate::geodesic::logmap::{LogMap, LogSettings};
use crate::model::Chain;
use crate::numerics::ode::OdeSettings;

/// The exact potential U* = ½ ω² r(q)², less gravity: U_e = U* − U_g.
///
/// By the Gauss lemma every geodesic from q_eq is a strict mode of U*: its gradient is
/// ω² r M(q) γ̇ with γ̇ the unit tangent of the geodesic through q, tangent to it by construction.
/// It is the physical limit a spring set approaches; evaluating it costs one log map per point.
#[derive(Debug, Clone)]
pub struct ExactPotential<'a> {
    log: LogMap<'a>,
    chain: &'a Chain,
    omega: f64,
}

impl<'a> ExactPotential<'a> {
    /// U* for the arm `chain` around `q_eq` with small-oscillation frequency `omega` (rad/s).
    pub fn new(chain: &'a Chain, q_eq: &DVector<f64>, omega: f64, ode: OdeSettings) -> Self {
        ExactPotential { log: LogMap::new(chain, q_eq, ode, LogSettings::default()), chain, omega }
    }

    /// The frequency ω.
    pub fn omega(&self) -> f64 {
        self.omega
    }

    fn total_gradient(&self, q: &[f64]) -> Result<DVector<f64>> {
        let q = DVector::from_column_slice(q);
        let mut shooter = self.log.shooter();
        let p = self.log.solve(&mut shooter, &q, None)?;
        if p.r == 0.0 {
            return Ok(DVector::zeros(q.len()));
        }
        let (_, tangent) = shooter.exp_state(&p.v)?;
        Ok(self.chain.mass_matrix(&q) * tangent * (self.omega * self.omega * p.r))
    }
}

impl Potential for ExactPotential<'_> {
    fn dof(&self) -> usize {
        self.chain.dof()
    }

    fn value(&self, q: &[f64]) -> Result<f64> {
        let p = self.log.log(&DVector::from_column_slice(q))?;
        Ok(0.5 * self.omega * self.omega * p.r * p.r - self.chain.gravity_potential(q))
    }

    fn gradient(&self, q: &[f64]) -> Result<DVector<f64>> {
        Ok(self.total_gradient(q)? - self.chain.gravity_gradient(q))
    }

    /// At q_eq exactly ω² M(q_eq) − ∇²U_g; elsewhere central differences of the gradient
    /// (step 1e-5 rad), which is what the checks that use it need.
    fn hessian(&self, q: &[f64]) -> Result<DMatrix<f64>> {
        let n = q.len();
        let qv = DVector::from_column_slice(q);
        if (&qv - self.log.q_eq()).amax() == 0.0 {
            return Ok(self.chain.mass_matrix(&qv) * (self.omega * self.omega) - self.chain.gravity_hessian(q));
        }
        let h = 1e-5;
        let mut out = DMatrix::zeros(n, n);
        for j in 0..n {
            let mut qp = q.to_vec();
            let mut qm = q.to_vec();
            qp[j] += h;
            qm[j] -= h;
            let col = (self.gradient(&qp)? - self.gradient(&qm)?) / (2.0 * h);
            out.set_column(j, &col);
        }
        Ok(0.5 * (&out + out.transpose()))
    }
}
