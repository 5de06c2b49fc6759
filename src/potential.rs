//! Potentials: a fitted spring set, the exact target ½ω²r², and gravity.
//!
//! Everything downstream of the fit (residual angles, simulation, sweeps) sees a [`Potential`]:
//! value, gradient and Hessian of the *elastic* potential U_e over q. The total potential the
//! arm feels is U = U_e + U_g; gravity comes from the [`Chain`].

use nalgebra::{DMatrix, DVector};

use crate::elements::Element;
use crate::error::Result;
use crate::geodesic::logmap::{LogMap, LogSettings};
use crate::model::Chain;
use crate::ode::OdeSettings;

/// An elastic potential U_e(q).
pub trait Potential: Sync {
    /// Number of joints.
    fn dof(&self) -> usize;
    /// U_e(q) in J.
    fn value(&self, q: &[f64]) -> Result<f64>;
    /// ∂U_e/∂q in N·m.
    fn gradient(&self, q: &[f64]) -> Result<DVector<f64>>;
    /// ∂U_e/∂q into `out` (implementations on hot paths override it to avoid allocating).
    fn gradient_into(&self, q: &[f64], out: &mut [f64]) -> Result<()> {
        out.copy_from_slice(self.gradient(q)?.as_slice());
        Ok(())
    }
    /// ∂²U_e/∂q² in N·m/rad.
    fn hessian(&self, q: &[f64]) -> Result<DMatrix<f64>>;
}

/// A set of elements with their stiffnesses: U_e = Σ kⱼ uⱼ(q).
#[derive(Debug, Clone, PartialEq)]
pub struct SpringSet {
    /// The elements.
    pub elements: Vec<Element>,
    /// Their stiffnesses (in each profile's unit), ≥ 0.
    pub stiffness: Vec<f64>,
}

impl SpringSet {
    /// Joint torques of each element at q (the spring torque a·k·u′, N·m): one row per element.
    pub fn element_torques(&self, q: &[f64]) -> Vec<DVector<f64>> {
        self.elements.iter().zip(&self.stiffness).map(|(e, k)| e.gradient(q) * *k).collect()
    }

    /// The same springs with each stiffness scaled by a factor (manufacturing deviations).
    pub fn scaled(&self, factors: &[f64]) -> SpringSet {
        SpringSet {
            elements: self.elements.clone(),
            stiffness: self.stiffness.iter().zip(factors).map(|(k, f)| k * f).collect(),
        }
    }

    /// Gradient without allocating (the simulation's hot loop).
    pub fn gradient_into(&self, q: &[f64], out: &mut [f64]) {
        self.gradient_scaled_into(q, None, out);
    }

    /// U_e and its gradient in one pass (one trigonometric evaluation per element), the gradient
    /// into `out`.
    pub fn value_gradient_into(&self, q: &[f64], out: &mut [f64]) -> f64 {
        out.fill(0.0);
        let mut u = 0.0;
        for (e, k) in self.elements.iter().zip(&self.stiffness) {
            if *k == 0.0 {
                continue;
            }
            let (v, slope, _) = e.profile.eval(e.deflection(q));
            u += k * v;
            for (o, a) in out.iter_mut().zip(&e.coupling) {
                *o += k * slope * a;
            }
        }
        u
    }

    /// Gradient with each stiffness multiplied by `scale[j]` (manufacturing deviations), into
    /// `out`.
    pub fn gradient_scaled_into(&self, q: &[f64], scale: Option<&[f64]>, out: &mut [f64]) {
        out.fill(0.0);
        for (j, (e, k)) in self.elements.iter().zip(&self.stiffness).enumerate() {
            let k = k * scale.map_or(1.0, |s| s[j]);
            if k == 0.0 {
                continue;
            }
            let slope = k * e.profile.slope(e.deflection(q));
            for (o, a) in out.iter_mut().zip(&e.coupling) {
                *o += slope * a;
            }
        }
    }
}

impl Potential for SpringSet {
    fn dof(&self) -> usize {
        self.elements.first().map_or(0, |e| e.coupling.len())
    }

    fn value(&self, q: &[f64]) -> Result<f64> {
        Ok(self.elements.iter().zip(&self.stiffness).map(|(e, k)| k * e.value(q)).sum())
    }

    fn gradient(&self, q: &[f64]) -> Result<DVector<f64>> {
        let mut g = DVector::zeros(q.len());
        SpringSet::gradient_into(self, q, g.as_mut_slice());
        Ok(g)
    }

    fn gradient_into(&self, q: &[f64], out: &mut [f64]) -> Result<()> {
        SpringSet::gradient_into(self, q, out);
        Ok(())
    }

    fn hessian(&self, q: &[f64]) -> Result<DMatrix<f64>> {
        let n = q.len();
        Ok(self.elements.iter().zip(&self.stiffness).fold(DMatrix::zeros(n, n), |acc, (e, k)| acc + e.hessian(q) * *k))
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::elements::{Profile, Side};
    use std::f64::consts::PI;

    #[test]
    fn spring_set_sums_its_elements() {
        let set = SpringSet {
            elements: vec![
                Element { profile: Profile::Linear, coupling: vec![1.0, 0.0], offset: 0.1 },
                Element { profile: Profile::Crank, coupling: vec![1.0, -1.0], offset: 0.3 },
                Element { profile: Profile::Compression(Side::Minus), coupling: vec![0.0, 2.0], offset: 0.5 },
            ],
            stiffness: vec![2.0, 3.0, 0.5],
        };
        let q = [0.4, -0.2];
        let g = set.gradient(&q).unwrap();
        let expected_0 = 2.0 * 0.3 + 3.0 * (0.6f64 - 0.3).sin();
        let expected_1 = -3.0 * (0.6f64 - 0.3).sin() + 0.5 * 2.0 * (2.0 * -0.2 - 0.5);
        assert!((g[0] - expected_0).abs() < 1e-14 && (g[1] - expected_1).abs() < 1e-14);
        let torques = set.element_torques(&q);
        let sum = torques.iter().fold(DVector::zeros(2), |a, t| a + t);
        assert!((sum - g).amax() < 1e-14);
        let h = 1e-6;
        let hess = set.hessian(&q).unwrap();
        for j in 0..2 {
            let mut qp = q;
            let mut qm = q;
            qp[j] += h;
            qm[j] -= h;
            let fd = (set.gradient(&qp).unwrap() - set.gradient(&qm).unwrap()) / (2.0 * h);
            assert!((hess.column(j) - fd).amax() < 1e-6);
        }
    }

    #[test]
    fn exact_gradient_matches_finite_differences_of_its_value() {
        let chain = Chain::paper_double_pendulum();
        let q_eq = DVector::from_vec(vec![0.0, PI / 2.0]);
        let ode = OdeSettings { rtol: 1e-12, atol: 1e-12, ..Default::default() };
        let exact = ExactPotential::new(&chain, &q_eq, 2.0, ode);
        for q in [[0.3, 1.9], [-0.4, 1.1], [0.2, 2.5]] {
            let g = exact.gradient(&q).unwrap();
            let h = 1e-5;
            for j in 0..2 {
                let mut qp = q;
                let mut qm = q;
                qp[j] += h;
                qm[j] -= h;
                let fd = (exact.value(&qp).unwrap() - exact.value(&qm).unwrap()) / (2.0 * h);
                assert!((g[j] - fd).abs() < 1e-6 * (1.0 + fd.abs()), "{} vs {fd}", g[j]);
            }
        }
        let hess = exact.hessian(q_eq.as_slice()).unwrap();
        assert!((hess - chain.mass_matrix(&q_eq) * 4.0).amax() < 1e-12);
    }
}
