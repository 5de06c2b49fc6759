//! Shooting single geodesics from the equilibrium: sampled traces, exp and its Jacobian.

use nalgebra::{DMatrix, DVector};

use super::{Geodesic, GeodesicEnd, Region};
use crate::error::{Error, Result};
use crate::model::{Chain, Workspace};
use crate::numerics::ode::{Dopri5, OdeFailure, OdeSettings, find_root};
use crate::numerics::ode853::Dop853;

/// How far a trace goes.
#[derive(Debug, Clone, Copy)]
pub enum Stop<'r> {
    /// To arc length `s`.
    Arc(f64),
    /// Until the region's boundary (event location), or `max_arc` for a box a geodesic never
    /// leaves (an error: the box is not bounded in the metric). A clipped ball stops at its
    /// radius or at the first joint limit.
    Region {
        /// The region whose boundary ends the trace.
        region: &'r Region,
        /// The arc length a trace gives up at, √(kg·m²)·rad (`[geodesics] max_arc`).
        max_arc: f64,
    },
}

/// Integrates geodesics from one equilibrium. Holds the scratch space of one thread: create one
/// per thread (rayon's `map_init`) and reuse it for many directions.
#[derive(Debug, Clone)]
pub struct Shooter<'a> {
    chain: &'a Chain,
    q_eq: DVector<f64>,
    ws: Workspace,
    ode: Dopri5,
    /// Geodesic + Jacobi fields with error control on everything (conjugate points).
    ode_var: Dopri5,
    /// Point-to-point integrations (exp and its Jacobian for Newton): eighth order, no dense
    /// output.
    ode8: Dop853,
    /// Geodesic + Jacobi fields with error control on the geodesic only and a step cap.
    ode8_jac: Dop853,
    y: Vec<f64>,
    y_var: Vec<f64>,
    tmp: Vec<f64>,
}

/// Per arc length of [`Shooter::jacobi_samples`]: q and Φ_q (column-major n × n).
pub type JacobiSamples = Vec<(Vec<f64>, Vec<f64>)>;

/// A geodesic traced with its Jacobi fields: the trace and the first conjugate point, if any.
#[derive(Debug, Clone)]
pub struct JacobiTrace {
    /// The sampled geodesic.
    pub geodesic: Geodesic,
    /// det(d exp) at each sample (1 at s → 0; a conjugate point where it reaches 0).
    pub det: Vec<f64>,
    /// Arc length of the first conjugate point before the end of the trace.
    pub conjugate: Option<f64>,
}

fn ode_error(what: &str, e: OdeFailure) -> Error {
    Error::numerical(what, e.to_string())
}

impl<'a> Shooter<'a> {
    /// A shooter from `q_eq` with the given integrator tolerances.
    pub fn new(chain: &'a Chain, q_eq: &DVector<f64>, ode: OdeSettings) -> Self {
        let n = chain.dof();
        Shooter {
            chain,
            q_eq: q_eq.clone(),
            ws: chain.workspace(),
            ode: Dopri5::new(2 * n, ode),
            ode_var: Dopri5::new(2 * n + 2 * n * n, ode),
            ode8: Dop853::new(2 * n, ode),
            ode8_jac: Dop853::new(2 * n + 2 * n * n, ode).with_error_components(2 * n),
            y: vec![0.0; 2 * n],
            y_var: vec![0.0; 2 * n + 2 * n * n],
            tmp: vec![0.0; 2 * n + 2 * n * n],
        }
    }

    /// The equilibrium geodesics start from.
    pub fn q_eq(&self) -> &DVector<f64> {
        &self.q_eq
    }

    /// Traces the unit-speed geodesic with initial velocity `u` (uᵀ M(q_eq) u = 1), sampled every
    /// `spacing` in arc length plus the end point. Time equals arc length.
    pub fn trace(&mut self, u: &DVector<f64>, stop: Stop<'_>, spacing: f64) -> Result<Geodesic> {
        let n = self.chain.dof();
        self.y[..n].copy_from_slice(self.q_eq.as_slice());
        self.y[n..].copy_from_slice(u.as_slice());
        let (chain, ws) = (self.chain, &mut self.ws);
        let mut rhs = |_t: f64, y: &[f64], dy: &mut [f64]| chain.geodesic_rhs(ws, y, dy);
        let (s_end, region, max_arc) = match stop {
            Stop::Arc(s) => (s, None, s),
            Stop::Region { region, max_arc } => match region {
                Region::Ball { radius } => (*radius, None, *radius),
                Region::Box { .. } => (max_arc, Some(region), max_arc),
                Region::Clipped { radius, .. } => (*radius, Some(region), *radius),
            },
        };
        let mut geo = Geodesic::new(n, u.clone());
        let ode = &mut self.ode;
        ode.start(&mut rhs, 0.0, &self.y, s_end).map_err(|e| ode_error("geodesic", e))?;
        let mut next = spacing;
        let mut end = GeodesicEnd::Arc;
        loop {
            let done = ode.step(&mut rhs, s_end).map_err(|e| ode_error("geodesic", e))?;
            let mut t_stop = None;
            if let Some(region) = region
                && region.outside(&ode.y()[..n])
            {
                // Earliest face crossing on the dense output.
                let t = region.exit_time(ode, n);
                t_stop = Some(t);
            }
            let t_hi = t_stop.unwrap_or(ode.t());
            while next < t_hi - 1e-12 * spacing.max(1.0) {
                ode.dense(next, &mut self.tmp[..2 * n]);
                geo.push(next, &self.tmp[..2 * n]);
                next += spacing;
            }
            if let Some(t) = t_stop {
                ode.dense(t, &mut self.tmp[..2 * n]);
                geo.push(t, &self.tmp[..2 * n]);
                end = GeodesicEnd::Boundary;
                break;
            }
            if done {
                geo.push(ode.t(), &ode.y()[..2 * n]);
                break;
            }
        }
        if matches!(region, Some(Region::Box { .. })) && end == GeodesicEnd::Arc {
            return Err(Error::numerical(
                "geodesic",
                format!(
                    "the geodesic with initial velocity {:?} did not leave the box within arc length {max_arc}",
                    u.as_slice()
                ),
            ));
        }
        geo.end = end;
        Ok(geo)
    }

    /// exp(v): the point reached at arc length |v| along the geodesic with initial direction v.
    pub fn exp(&mut self, v: &DVector<f64>) -> Result<DVector<f64>> {
        Ok(self.exp_state(v)?.0)
    }

    /// exp(v) and the unit tangent γ̇ there (metric speed 1; zero for v = 0). By the Gauss lemma
    /// M(q) γ̇ is the gradient of the distance r = |v| at q = exp(v).
    pub fn exp_state(&mut self, v: &DVector<f64>) -> Result<(DVector<f64>, DVector<f64>)> {
        let n = self.chain.dof();
        let m = self.chain.mass_matrix(&self.q_eq);
        let s = v.dot(&(m * v)).sqrt();
        if s == 0.0 {
            return Ok((self.q_eq.clone(), DVector::zeros(n)));
        }
        self.y[..n].copy_from_slice(self.q_eq.as_slice());
        for i in 0..n {
            self.y[n + i] = v[i] / s;
        }
        let (chain, ws) = (self.chain, &mut self.ws);
        let mut rhs = |_t: f64, y: &[f64], dy: &mut [f64]| chain.geodesic_rhs(ws, y, dy);
        self.ode8.integrate(&mut rhs, &self.y, s).map_err(|e| ode_error("exp", e))?;
        let y = self.ode8.y();
        Ok((DVector::from_column_slice(&y[..n]), DVector::from_column_slice(&y[n..2 * n])))
    }

    /// exp(v) and its Jacobian d exp_v, from the variational (Jacobi-field) equations.
    ///
    /// With s = |v| and w = v/s, exp(v′) = γ_{v′/s}(s) for v′ near v (geodesics scale:
    /// γ_{cv}(t) = γ_v(ct)), so d exp_v = Φ_q(s)/s where Φ_q = ∂γ_w(s)/∂w.
    ///
    /// Integrated with the eighth-order [`Dop853`]; step-size control watches the geodesic only
    /// and the Jacobi fields ride along with steps capped at s/4: the point is as accurate as
    /// [`Shooter::exp`] and the Jacobian to about 1e-8, ample for Newton steps and label
    /// gradients ([`Shooter::trace_jacobi`], which locates conjugate points, keeps full control).
    pub fn exp_jacobian(&mut self, v: &DVector<f64>) -> Result<(DVector<f64>, DMatrix<f64>)> {
        let n = self.chain.dof();
        let m = self.chain.mass_matrix(&self.q_eq);
        let s = v.dot(&(m * v)).sqrt();
        if s == 0.0 {
            return Ok((self.q_eq.clone(), DMatrix::identity(n, n)));
        }
        let u = v / s;
        self.init_variational(&u);
        self.ode8_jac.set_max_step(s / 4.0);
        let (chain, ws) = (self.chain, &mut self.ws);
        let mut rhs = |_t: f64, y: &[f64], dy: &mut [f64]| chain.variational_rhs(ws, y, dy);
        self.ode8_jac.integrate(&mut rhs, &self.y_var, s).map_err(|e| ode_error("exp", e))?;
        let y = self.ode8_jac.y();
        let q = DVector::from_column_slice(&y[..n]);
        let jac = DMatrix::from_column_slice(n, n, &y[2 * n..2 * n + n * n]) / s;
        Ok((q, jac))
    }

    /// Initial state of geodesic + Jacobi fields: (q_eq, u, Φ_q = 0, Φ_q̇ = I).
    fn init_variational(&mut self, u: &DVector<f64>) {
        let n = self.chain.dof();
        self.y_var.fill(0.0);
        self.y_var[..n].copy_from_slice(self.q_eq.as_slice());
        self.y_var[n..2 * n].copy_from_slice(u.as_slice());
        let off = 2 * n + n * n;
        for i in 0..n {
            self.y_var[off + i + n * i] = 1.0;
        }
    }

    fn start_variational(&mut self, u: &DVector<f64>, s_end: f64, what: &str) -> Result<()> {
        self.init_variational(u);
        let (chain, ws) = (self.chain, &mut self.ws);
        let mut rhs = |_t: f64, y: &[f64], dy: &mut [f64]| chain.variational_rhs(ws, y, dy);
        self.ode_var.start(&mut rhs, 0.0, &self.y_var, s_end).map_err(|e| ode_error(what, e))
    }

    /// The point q and the Jacobi field Φ_q (column-major n × n) of the geodesic with unit initial
    /// velocity `u` at each arc length of `arcs` (ascending, > 0), from one integration with
    /// full error control and dense output: d exp at v = s·u is Φ_q(s)/s. What a fitted log map
    /// is fitted to ([`crate::geodesic::logfit`]): exact pairs (v, exp v) with their
    /// derivatives, no Newton shooting.
    pub fn jacobi_samples(&mut self, u: &DVector<f64>, arcs: &[f64]) -> Result<JacobiSamples> {
        let n = self.chain.dof();
        let Some(&s_end) = arcs.last() else { return Ok(Vec::new()) };
        self.start_variational(u, s_end, "Jacobi fields")?;
        let (chain, ws) = (self.chain, &mut self.ws);
        let mut rhs = |_t: f64, y: &[f64], dy: &mut [f64]| chain.variational_rhs(ws, y, dy);
        let ode = &mut self.ode_var;
        let mut out = Vec::with_capacity(arcs.len());
        let mut next = arcs.iter().peekable();
        loop {
            let done = ode.step(&mut rhs, s_end).map_err(|e| ode_error("Jacobi fields", e))?;
            while let Some(&&s) = next.peek() {
                if s > ode.t() && !done {
                    break;
                }
                ode.dense(s.min(ode.t()), &mut self.tmp);
                out.push((self.tmp[..n].to_vec(), self.tmp[2 * n..2 * n + n * n].to_vec()));
                next.next();
            }
            if done {
                return Ok(out);
            }
        }
    }

    /// Traces the geodesic with unit initial velocity `u` to arc length `s_end` together with its
    /// Jacobi fields, sampling every `spacing`, and locates the first conjugate point (where
    /// det d exp = det Φ_q(s)/sⁿ changes sign) on the dense output.
    pub fn trace_jacobi(&mut self, u: &DVector<f64>, s_end: f64, spacing: f64) -> Result<JacobiTrace> {
        let n = self.chain.dof();
        self.start_variational(u, s_end, "Jacobi fields")?;
        let (chain, ws) = (self.chain, &mut self.ws);
        let mut rhs = |_t: f64, y: &[f64], dy: &mut [f64]| chain.variational_rhs(ws, y, dy);
        let ode = &mut self.ode_var;
        let mut geo = Geodesic::new(n, u.clone());
        let mut det = Vec::new();
        let mut conjugate = None;
        let mut next = spacing;
        let mut prev_det = 1.0;
        let det_at = |ode: &Dopri5, t: f64, buf: &mut [f64]| -> f64 {
            ode.dense(t, buf);
            jacobi_det(&buf[2 * n..2 * n + n * n], n, t)
        };
        loop {
            let done = ode.step(&mut rhs, s_end).map_err(|e| ode_error("Jacobi fields", e))?;
            let t_hi = ode.t();
            let d_hi = jacobi_det(&ode.y()[2 * n..2 * n + n * n], n, t_hi);
            let buf = &mut self.tmp;
            if conjugate.is_none() && d_hi <= 0.0 && prev_det > 0.0 {
                let t_lo = ode.t_old();
                let d_lo = if t_lo == 0.0 { 1.0 } else { det_at(ode, t_lo, buf) };
                let root = find_root(|t| det_at(ode, t, buf), t_lo, t_hi, d_lo, d_hi, 1e-12);
                conjugate = Some(root);
            }
            prev_det = d_hi;
            while next < t_hi - 1e-12 * spacing.max(1.0) {
                let d = det_at(ode, next, buf);
                geo.push(next, &buf[..2 * n]);
                det.push(d);
                next += spacing;
            }
            if done {
                geo.push(t_hi, &ode.y()[..2 * n]);
                det.push(d_hi);
                break;
            }
        }
        Ok(JacobiTrace { geodesic: geo, det, conjugate })
    }
}

/// det(d exp) along a unit-speed geodesic at arc length s from Φ_q(s): det(Φ_q)/sⁿ.
fn jacobi_det(phi_q: &[f64], n: usize, s: f64) -> f64 {
    if s <= 0.0 {
        return 1.0;
    }
    let m = DMatrix::from_column_slice(n, n, phi_q) / s;
    m.determinant()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geodesic::directions::{MetricFrame, unit_vectors};
    use crate::model::Link;
    use std::f64::consts::PI;

    fn tight() -> OdeSettings {
        OdeSettings { rtol: 1e-12, atol: 1e-12, ..Default::default() }
    }

    #[test]
    fn metric_speed_is_conserved_along_geodesics() {
        let chain = Chain::paper_double_pendulum();
        let q_eq = DVector::from_vec(vec![0.0, PI / 2.0]);
        let frame = MetricFrame::new(&chain.mass_matrix(&q_eq)).unwrap();
        let mut shooter = Shooter::new(&chain, &q_eq, tight());
        for u in unit_vectors(2, 16, 0.1) {
            let v = frame.to_joint(&u);
            let geo = shooter.trace(&v, Stop::Arc(3.0), 0.05).unwrap();
            let mut worst: f64 = 0.0;
            for i in 0..geo.len() {
                let q = DVector::from_column_slice(geo.q(i));
                let qd = DVector::from_column_slice(geo.qd(i));
                let speed2 = qd.dot(&(chain.mass_matrix(&q) * &qd));
                worst = worst.max((speed2 - 1.0).abs());
            }
            assert!(worst <= 1e-9, "speed drift {worst}");
            assert!((geo.s(geo.len() - 1) - 3.0).abs() < 1e-14);
        }
    }

    #[test]
    fn constant_metric_gives_straight_lines() {
        let chain = Chain::new(vec![Link { mass: 2.0, length: 1.0, com: 0.5, inertia: 0.1 }], [0.0, 0.0]);
        let q_eq = DVector::from_vec(vec![0.3]);
        let mut shooter = Shooter::new(&chain, &q_eq, OdeSettings::default());
        let inertia = 2.0 * 0.25 + 0.1;
        let u = DVector::from_vec(vec![1.0 / f64::sqrt(inertia)]);
        let geo = shooter.trace(&u, Stop::Arc(2.0), 0.1).unwrap();
        for i in 0..geo.len() {
            let expected = 0.3 + geo.s(i) * u[0];
            assert!((geo.q(i)[0] - expected).abs() < 1e-12);
            assert!((geo.qd(i)[0] - u[0]).abs() < 1e-12);
        }
    }

    #[test]
    fn exp_jacobian_matches_finite_differences() {
        let chain = Chain::paper_double_pendulum();
        let q_eq = DVector::from_vec(vec![0.0, PI / 2.0]);
        let mut shooter = Shooter::new(&chain, &q_eq, tight());
        for v in
            [DVector::from_vec(vec![0.3, 0.4]), DVector::from_vec(vec![-0.2, 0.9]), DVector::from_vec(vec![0.5, -0.7])]
        {
            let (q, jac) = shooter.exp_jacobian(&v).unwrap();
            let q2 = shooter.exp(&v).unwrap();
            assert!((&q - &q2).amax() < 1e-11);
            let h = 1e-5;
            for j in 0..2 {
                let mut vp = v.clone();
                let mut vm = v.clone();
                vp[j] += h;
                vm[j] -= h;
                let fd = (shooter.exp(&vp).unwrap() - shooter.exp(&vm).unwrap()) / (2.0 * h);
                for i in 0..2 {
                    assert!((jac[(i, j)] - fd[i]).abs() < 1e-6, "{} vs {}", jac[(i, j)], fd[i]);
                }
            }
        }
    }

    #[test]
    fn first_conjugate_point_from_the_stretched_arm_is_at_two_pi() {
        // From q_eq = (0, 0) the geodesic along q₁ keeps q₂ ≡ 0 where K = 1/4: first conjugate
        // point at s = π/√K = 2π.
        let chain = Chain::paper_double_pendulum();
        let q_eq = DVector::from_vec(vec![0.0, 0.0]);
        let m = chain.mass_matrix(&q_eq);
        let mut shooter = Shooter::new(&chain, &q_eq, tight());
        let u = DVector::from_vec(vec![1.0 / m[(0, 0)].sqrt(), 0.0]);
        let trace = shooter.trace_jacobi(&u, 8.0, 0.1).unwrap();
        let s = trace.conjugate.expect("a conjugate point before s = 8");
        assert!((s - 2.0 * PI).abs() < 1e-6, "conjugate point at {s}");
        // q₂ stays 0 along this geodesic.
        for i in 0..trace.geodesic.len() {
            assert!(trace.geodesic.q(i)[1].abs() < 1e-12);
        }
    }

    #[test]
    fn box_traces_stop_exactly_on_the_boundary() {
        let chain = Chain::paper_double_pendulum();
        let q_eq = DVector::from_vec(vec![0.0, PI / 2.0]);
        let region =
            Region::Box { lower: DVector::from_vec(vec![-0.5, 1.0]), upper: DVector::from_vec(vec![0.4, 2.5]) };
        let frame = MetricFrame::new(&chain.mass_matrix(&q_eq)).unwrap();
        let mut shooter = Shooter::new(&chain, &q_eq, OdeSettings::default());
        for u in unit_vectors(2, 24, 0.3) {
            let geo =
                shooter.trace(&frame.to_joint(&u), Stop::Region { region: &region, max_arc: 100.0 }, 0.05).unwrap();
            assert_eq!(geo.end, GeodesicEnd::Boundary);
            let q = geo.q(geo.len() - 1);
            let on_face = (q[0] + 0.5).abs() < 1e-9
                || (q[0] - 0.4).abs() < 1e-9
                || (q[1] - 1.0).abs() < 1e-9
                || (q[1] - 2.5).abs() < 1e-9;
            assert!(on_face, "end point {q:?} not on the boundary");
            for i in 0..geo.len() {
                assert!(!region.outside(geo.q(i)) || i == geo.len() - 1);
            }
        }
    }
}
