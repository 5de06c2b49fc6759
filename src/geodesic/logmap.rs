//! The log map: the initial velocity v with exp(v) = q, by Newton shooting.
//!
//! Newton's method on F(v) = exp(v) − q uses the exact Jacobian d exp_v from the Jacobi-field
//! equations ([`Shooter::exp_jacobian`]), with backtracking on |F| and, if that fails from the
//! first-order guess v₀ = q − q_eq, continuation along the straight segment from q_eq to q.
//! From v follow r(q) = |v|_M, the Riemannian distance to q_eq, and for n = 2 the mode label
//! θ(q) = 2·atan2(v₂, v₁) with ∂θ/∂q = ∂θ/∂v · (d exp_v)⁻¹.

use nalgebra::{DMatrix, DVector, RowDVector};
use serde::{Deserialize, Serialize};

use super::shoot::Shooter;
use crate::error::{Error, Result};
use crate::model::Chain;
use crate::numerics::ode::OdeSettings;

/// Settings of the Newton shooting.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LogSettings {
    /// Converged when max |exp(v) − q| ≤ tol (rad).
    pub tol: f64,
    /// Newton iterations per attempt.
    pub max_iterations: usize,
    /// Continuation stages tried when Newton fails from the first-order guess.
    pub continuation_stages: usize,
    /// A Newton step at most this long (rad) from a residual at most 1000 times it is taken as
    /// the last one without integrating again to confirm: Newton's quadratic convergence puts
    /// the result within ~|step|² of the root.
    pub final_step: f64,
}

impl Default for LogSettings {
    fn default() -> Self {
        LogSettings { tol: 1e-11, max_iterations: 25, continuation_stages: 8, final_step: 1e-6 }
    }
}

/// log(q) and what comes with it.
#[derive(Debug, Clone, PartialEq)]
pub struct LogPoint {
    /// The initial velocity with exp(v) = q.
    pub v: DVector<f64>,
    /// r(q) = |v|_M, the Riemannian distance from q_eq.
    pub r: f64,
    /// d exp_v (so ∂v/∂q = jacobian⁻¹).
    pub jacobian: DMatrix<f64>,
    /// Newton iterations used (over all continuation stages).
    pub iterations: usize,
}

/// The mode label of a two-joint arm and its gradient.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Label {
    /// θ = 2·atan2(v₂, v₁) wrapped to (−π, π] (v and −v are the same mode).
    pub theta: f64,
    /// ∂θ/∂q (1/rad).
    pub gradient: [f64; 2],
}

/// The log map of one equilibrium.
#[derive(Debug, Clone)]
pub struct LogMap<'a> {
    chain: &'a Chain,
    q_eq: DVector<f64>,
    m_eq: DMatrix<f64>,
    m_eq_inv: DMatrix<f64>,
    /// Christoffel symbols of the first kind at q_eq.
    christoffel: Vec<DMatrix<f64>>,
    ode: OdeSettings,
    settings: LogSettings,
}

impl<'a> LogMap<'a> {
    /// The log map at `q_eq` with the integrator tolerances used for exp.
    pub fn new(chain: &'a Chain, q_eq: &DVector<f64>, ode: OdeSettings, settings: LogSettings) -> Self {
        let m_eq = chain.mass_matrix(q_eq);
        LogMap {
            chain,
            q_eq: q_eq.clone(),
            m_eq_inv: m_eq.clone().try_inverse().unwrap_or_else(|| DMatrix::identity(q_eq.len(), q_eq.len())),
            christoffel: chain.christoffel(q_eq),
            m_eq,
            ode,
            settings,
        }
    }

    /// A shooter for this equilibrium (one per thread; pass it to [`LogMap::solve`]).
    pub fn shooter(&self) -> Shooter<'a> {
        Shooter::new(self.chain, &self.q_eq, self.ode)
    }

    /// The equilibrium.
    pub fn q_eq(&self) -> &DVector<f64> {
        &self.q_eq
    }

    /// Metric length |v|_M at the equilibrium.
    pub fn norm(&self, v: &DVector<f64>) -> f64 {
        v.dot(&(&self.m_eq * v)).sqrt()
    }

    /// log(q) with a fresh shooter.
    pub fn log(&self, q: &DVector<f64>) -> Result<LogPoint> {
        self.solve(&mut self.shooter(), q, None)
    }

    /// The second-order guess log(q) ≈ Δ + ½ Γ(Δ, Δ), Δ = q − q_eq, from the geodesic
    /// expansion exp(v) = q_eq + v − ½ Γ(v, v) + O(|v|³) (Γ of the second kind at q_eq).
    pub fn guess(&self, q: &DVector<f64>) -> DVector<f64> {
        let delta = q - &self.q_eq;
        let quad = DVector::from_iterator(delta.len(), self.christoffel.iter().map(|g| delta.dot(&(g * &delta))));
        let correction = self.m_eq_inv.clone() * quad * 0.5;
        let v = &delta + &correction;
        // Far from q_eq the expansion can overshoot; keep it only while it is a correction.
        if correction.norm() < 0.5 * delta.norm() { v } else { delta }
    }

    /// log(q), starting Newton from `guess` if given (a nearby solution), else from
    /// [`LogMap::guess`].
    pub fn solve(&self, shooter: &mut Shooter<'_>, q: &DVector<f64>, guess: Option<&DVector<f64>>) -> Result<LogPoint> {
        let v0 = guess.cloned().unwrap_or_else(|| self.guess(q));
        let mut total = 0;
        match self.newton(shooter, q, v0, &mut total) {
            Ok(p) => {
                return Ok(LogPoint { iterations: total, ..p });
            }
            Err(_) if self.settings.continuation_stages > 1 => {}
            Err(e) => return Err(e),
        }
        // Continuation: walk the target from q_eq to q, warm-starting each stage.
        let stages = self.settings.continuation_stages;
        let mut v = DVector::zeros(q.len());
        let mut last = None;
        for k in 1..=stages {
            let target = &self.q_eq + (q - &self.q_eq) * (k as f64 / stages as f64);
            let p = self.newton(shooter, &target, v.clone(), &mut total).map_err(|_| {
                Error::numerical(
                    "log map",
                    format!(
                        "Newton shooting did not converge for q = {:?} (continuation stage {k} of {stages}); the point is probably outside the region where exp is one-to-one",
                        q.as_slice()
                    ),
                )
            })?;
            v = p.v.clone();
            last = Some(p);
        }
        let p = last.expect("at least one stage");
        Ok(LogPoint { iterations: total, ..p })
    }

    fn newton(
        &self,
        shooter: &mut Shooter<'_>,
        q: &DVector<f64>,
        mut v: DVector<f64>,
        total: &mut usize,
    ) -> Result<LogPoint> {
        let (x, mut jac) = shooter.exp_jacobian(&v)?;
        let mut f = &x - q;
        let mut fnorm = f.amax();
        for _ in 0..self.settings.max_iterations {
            if fnorm <= self.settings.tol {
                let r = self.norm(&v);
                return Ok(LogPoint { v, r, jacobian: jac, iterations: *total });
            }
            *total += 1;
            let step = jac
                .clone()
                .lu()
                .solve(&f)
                .ok_or_else(|| Error::numerical("log map", "d exp is singular (a conjugate point)"))?;
            // A tiny full Newton step from a small residual lands within O(|step|²) of the root:
            // take it without paying for another integration to confirm. The Jacobian returned
            // is then the one at the previous iterate, within |step| of v.
            if step.amax() <= self.settings.final_step && fnorm <= 1e3 * self.settings.final_step {
                v -= &step;
                let r = self.norm(&v);
                return Ok(LogPoint { v, r, jacobian: jac, iterations: *total });
            }
            // Backtracking on max |F|.
            let mut alpha = 1.0;
            loop {
                let trial = &v - &step * alpha;
                let (xt, jt) = shooter.exp_jacobian(&trial)?;
                let ft = &xt - q;
                let ftn = ft.amax();
                if ftn < fnorm || alpha < 1e-3 {
                    v = trial;
                    jac = jt;
                    f = ft;
                    fnorm = ftn;
                    break;
                }
                alpha *= 0.5;
            }
        }
        if fnorm <= self.settings.tol {
            let r = self.norm(&v);
            return Ok(LogPoint { v, r, jacobian: jac, iterations: *total });
        }
        Err(Error::numerical(
            "log map",
            format!("Newton shooting did not converge for q = {:?} (residual {fnorm:.2e})", q.as_slice()),
        ))
    }

    /// The mode label θ(q) and ∂θ/∂q of a two-joint arm from its log point.
    pub fn label(&self, p: &LogPoint) -> Result<Label> {
        if p.v.len() != 2 {
            return Err(Error::Setting {
                field: "label".into(),
                reason: "the angle label θ is defined for two joints".into(),
            });
        }
        let (v1, v2) = (p.v[0], p.v[1]);
        let rho2 = v1 * v1 + v2 * v2;
        if rho2 == 0.0 {
            return Err(Error::numerical("mode label", "undefined at the equilibrium"));
        }
        let theta = wrap_angle(2.0 * v2.atan2(v1));
        let dtheta_dv = RowDVector::from_vec(vec![-2.0 * v2 / rho2, 2.0 * v1 / rho2]);
        let inv =
            p.jacobian.clone().try_inverse().ok_or_else(|| Error::numerical("mode label", "d exp is singular"))?;
        let g = dtheta_dv * inv;
        Ok(Label { theta, gradient: [g[0], g[1]] })
    }
}

/// Wraps an angle to (−π, π].
pub fn wrap_angle(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let w = a - TAU * ((a + PI) / TAU).floor();
    if w <= -PI { w + TAU } else { w }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geodesic::directions::{MetricFrame, unit_vectors};
    use crate::geodesic::shoot::Stop;
    use std::f64::consts::PI;

    fn setup() -> (Chain, DVector<f64>) {
        (Chain::paper_double_pendulum(), DVector::from_vec(vec![0.0, PI / 2.0]))
    }

    #[test]
    fn exp_of_log_is_identity_over_the_region() {
        let (chain, q_eq) = setup();
        let log = LogMap::new(&chain, &q_eq, OdeSettings::default(), LogSettings::default());
        let mut shooter = log.shooter();
        // Points spread over the ball of radius 2 (directions × radii).
        let frame = MetricFrame::new(&chain.mass_matrix(&q_eq)).unwrap();
        for u in unit_vectors(2, 24, 0.37) {
            for r in [0.05, 0.5, 1.2, 1.99] {
                let v_true = frame.to_joint(&u) * r;
                let q = shooter.exp(&v_true).unwrap();
                let p = log.solve(&mut shooter, &q, None).unwrap();
                let back = shooter.exp(&p.v).unwrap();
                assert!((&back - &q).amax() <= 1e-9, "round trip error {}", (&back - &q).amax());
                assert!((&p.v - &v_true).amax() < 1e-7, "log {:?} vs {:?}", p.v, v_true);
                assert!((p.r - r).abs() < 1e-7);
            }
        }
    }

    #[test]
    fn distance_equals_the_arc_length_at_which_the_fan_reaches_q() {
        let (chain, q_eq) = setup();
        let log = LogMap::new(&chain, &q_eq, OdeSettings::default(), LogSettings::default());
        let frame = MetricFrame::new(&chain.mass_matrix(&q_eq)).unwrap();
        let mut shooter = log.shooter();
        for u in unit_vectors(2, 10, 0.2) {
            let geo = shooter.trace(&frame.to_joint(&u), Stop::Arc(2.0), 0.25).unwrap();
            for i in 0..geo.len() {
                let q = DVector::from_column_slice(geo.q(i));
                let p = log.solve(&mut shooter, &q, None).unwrap();
                assert!((p.r - geo.s(i)).abs() < 1e-8, "r = {} at s = {}", p.r, geo.s(i));
            }
        }
    }

    #[test]
    fn label_gradient_matches_finite_differences() {
        let (chain, q_eq) = setup();
        let log = LogMap::new(
            &chain,
            &q_eq,
            OdeSettings { rtol: 1e-12, atol: 1e-12, ..Default::default() },
            LogSettings::default(),
        );
        let mut shooter = log.shooter();
        for q in [[0.3, 1.9], [-0.4, 1.2], [0.1, 2.6], [-0.2, 0.9]] {
            let q = DVector::from_vec(q.to_vec());
            let p = log.solve(&mut shooter, &q, None).unwrap();
            let label = log.label(&p).unwrap();
            let h = 1e-6;
            for j in 0..2 {
                let mut qp = q.clone();
                let mut qm = q.clone();
                qp[j] += h;
                qm[j] -= h;
                let tp = log.label(&log.solve(&mut shooter, &qp, Some(&p.v)).unwrap()).unwrap().theta;
                let tm = log.label(&log.solve(&mut shooter, &qm, Some(&p.v)).unwrap()).unwrap().theta;
                let fd = wrap_angle(tp - tm) / (2.0 * h);
                assert!((fd - label.gradient[j]).abs() < 1e-5 * (1.0 + fd.abs()), "{fd} vs {}", label.gradient[j]);
            }
        }
    }

    #[test]
    fn opposite_directions_share_a_label() {
        let (chain, q_eq) = setup();
        let log = LogMap::new(&chain, &q_eq, OdeSettings::default(), LogSettings::default());
        let mut shooter = log.shooter();
        let v = DVector::from_vec(vec![0.2, 0.3]);
        let (qa, qb) = (shooter.exp(&v).unwrap(), shooter.exp(&-v).unwrap());
        let a = log.label(&log.solve(&mut shooter, &qa, None).unwrap()).unwrap();
        let b = log.label(&log.solve(&mut shooter, &qb, None).unwrap()).unwrap();
        assert!(wrap_angle(a.theta - b.theta).abs() < 1e-9);
    }

    #[test]
    fn a_point_beyond_the_valid_region_is_reported_not_returned() {
        // Far beyond the conjugate locus of (0, 0) exp is not one-to-one; Newton with
        // continuation must either find a genuine solution or say where it failed.
        let chain = Chain::paper_double_pendulum();
        let q_eq = DVector::from_vec(vec![0.0, 0.0]);
        let log = LogMap::new(
            &chain,
            &q_eq,
            OdeSettings::default(),
            LogSettings { max_iterations: 6, ..LogSettings::default() },
        );
        let q = DVector::from_vec(vec![9.0, 25.0]);
        match log.log(&q) {
            Ok(p) => {
                // A root was found: it must really map to q.
                let back = log.shooter().exp(&p.v).unwrap();
                assert!((back - &q).amax() < 1e-8);
            }
            Err(e) => {
                let msg = e.to_string();
                assert!(msg.contains("log map") && msg.contains("9.0") && msg.contains("25.0"), "{msg}");
            }
        }
    }

    #[test]
    fn wraps_angles() {
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(0.5) - 0.5).abs() < 1e-15);
        assert!((wrap_angle(-7.0) - (-7.0 + 2.0 * PI)).abs() < 1e-12);
    }
}
