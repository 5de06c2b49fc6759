//! Closed-loop simulation: the arm with its springs, damping and controllers.
//!
//! M q̈ + C q̇ + ∂U_g/∂q + D q̇ + ∂U_e/∂q = τ_c, with τ_c the sum of the active controllers
//! ([`crate::dynamics::control::Controller`], the same code a robot's own loop runs). The state carries, besides (q, q̇), one quadrature per torque source
//! accumulating ∫|τᵀq̇| dt, so the energy fluxes of the paper's Table II come out of the same
//! integration at the same order (the paper's Σ|τᵀq̇|δt is its rectangle-rule version). Fixed-step
//! RK4 at a given rate is the default; the adaptive option uses Dormand–Prince with error control
//! on (q, q̇) and samples the output on its dense interpolant.
//!
//! The right-hand side allocates nothing; a run is sequential, runs go in parallel.

use crate::design::simulate::{Integrator, SimSettings};
use nalgebra::DVector;
use serde::Serialize;

use crate::design::controllers::ControllerSettings;
use crate::dynamics::control::{Controller, dot};
pub use crate::dynamics::control::{ElasticPotential, EnergyControl, ModeControl, ModeTarget};
use crate::error::{Error, Result};
use crate::geodesic::label::LogField;
use crate::model::{Chain, Workspace};
use crate::numerics::ode::{Dopri5, OdeSettings};
use crate::potential::GroupedSet;

/// The torque sources, in the order of the output columns.
pub const SOURCES: [&str; 6] = ["spring", "gravity", "damping", "mode", "energy", "compensation"];
const SPRING: usize = 0;
const GRAVITY: usize = 1;
const DAMPING: usize = 2;
const MODE: usize = 3;
const ENERGY: usize = 4;
const COMPENSATION: usize = 5;
const NSRC: usize = 6;
/// Quadratures carried with (q, q̇): ∫|P| per source, then the time at saturation.
const NQUAD: usize = NSRC + 1;

/// Parasitic springs ½ ε (q − q_eq)ᵀ diag(κ) (q − q_eq): unknown to the controllers.
#[derive(Debug, Clone, PartialEq)]
pub struct Parasitic {
    /// Scale ε.
    pub eps: f64,
    /// κᵢ in N·m/rad.
    pub kappa: Vec<f64>,
}

/// One simulation run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSpec {
    /// Name of the run within its scenario.
    pub name: String,
    /// Start configuration.
    pub q0: Vec<f64>,
    /// Start velocity.
    pub qd0: Vec<f64>,
    /// Duration, s.
    pub duration: f64,
    /// Diagonal of the joint damping D, N·m·s/rad.
    pub damping: Vec<f64>,
    /// Mode selection, if on.
    pub mode: Option<ModeControl>,
    /// Energy regulation, if on.
    pub energy: Option<EnergyControl>,
    /// Parasitic springs, if any.
    pub parasitic: Option<Parasitic>,
    /// Built stiffness / nominal stiffness per element of a spring-set potential (manufacturing
    /// deviations); like parasitic springs, unknown to the controllers.
    pub stiffness_scale: Option<Vec<f64>>,
    /// The springs actually built and tuned (rates, offsets and trims as a builder set them),
    /// in place of a spring-set potential; like `stiffness_scale`, unknown to the controllers,
    /// which keep the nominal potential. Takes precedence over `stiffness_scale`.
    pub built: Option<crate::potential::SpringSet>,
}

/// The sampled result of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct Trace {
    /// Joints.
    pub n: usize,
    /// Sample times.
    pub t: Vec<f64>,
    /// q per sample (flat, n per sample).
    pub q: Vec<f64>,
    /// q̇ per sample.
    pub qd: Vec<f64>,
    /// Torques per sample: NSRC sources × n (flat).
    pub tau: Vec<f64>,
    /// E = ½q̇ᵀMq̇ + U(q) − U(q_eq) with the nominal U (springs and gravity).
    pub energy: Vec<f64>,
    /// Label per sample: θ (two joints) or the distance Δ to the reference mode (three or
    /// more), NaN inside the ε-ball.
    pub label: Vec<f64>,
    /// Desired label per sample (NaN without mode control; 0 for Δ).
    pub label_target: Vec<f64>,
    /// Whether the sample is inside the ε-ball.
    pub in_ball: Vec<bool>,
    /// Metric distance from q to the geodesic of the start's mode per sample, √(kg·m²)·rad
    /// (free runs, filled in by [`crate::dynamics::scenario::run_scenario`]; empty otherwise).
    pub geodesic_deviation: Vec<f64>,
}

impl Trace {
    /// Power τᵀq̇ of source `source` (index into [`SOURCES`]) at each sample, W.
    pub fn power(&self, source: usize) -> Vec<f64> {
        let (n, w) = (self.n, NSRC * self.n);
        (0..self.t.len()).map(|k| (0..n).map(|i| self.tau[k * w + source * n + i] * self.qd[k * n + i]).sum()).collect()
    }

    /// ∫|P| of a source over samples with t ≥ `from`, by the rectangle rule on the samples.
    pub fn flux_from(&self, source: usize, from: f64) -> f64 {
        let p = self.power(source);
        let mut total = 0.0;
        for k in 0..self.t.len().saturating_sub(1) {
            if self.t[k] >= from {
                total += p[k].abs() * (self.t[k + 1] - self.t[k]);
            }
        }
        total
    }
}

/// ∫|τᵀq̇| dt per source, J.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Fluxes {
    /// The elastic potential (springs and parasitic springs).
    pub potential: f64,
    /// Gravity.
    pub gravity: f64,
    /// Joint damping.
    pub damping: f64,
    /// Mode selection.
    pub mode: f64,
    /// Energy regulation.
    pub energy: f64,
    /// Damping compensation.
    pub compensation: f64,
}

/// A finished run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunResult {
    /// The run's name.
    pub name: String,
    /// Samples.
    pub trace: Trace,
    /// Energy fluxes.
    pub fluxes: Fluxes,
    /// Largest |τᵢ| per source over the run, N·m.
    pub peak_torque: [f64; NSRC],
    /// Largest |τ_θ,ᵢ + τ_E,ᵢ + τ_comp,ᵢ| over the run: what the joint's actuator delivers, N·m.
    pub peak_actuator_torque: f64,
    /// The same as the controllers' laws asked it, before `[controllers] max_torque`, N·m.
    pub peak_demanded_torque: f64,
    /// Time the controllers spent saturated (any torque scaled down by `max_torque`), s.
    pub saturated_s: f64,
}

/// Everything a run's right-hand side needs, with its scratch space: the arm as it is (its
/// springs, parasitic springs, gravity and damping) and its [`Controller`].
pub struct Dynamics<'a> {
    chain: &'a Chain,
    q_eq: Vec<f64>,
    potential: &'a ElasticPotential,
    /// A spring-set potential grouped for evaluation ([`GroupedSet`]): the nominal springs, and
    /// the springs the arm actually has when they differ (built or scaled).
    nominal: Option<GroupedSet>,
    actual: Option<GroupedSet>,
    /// Whether `actual` has the nominal elements with other rates (a build as built): then the
    /// nominal U and the built ∇U come from one pass over the profiles.
    actual_shares_elements: bool,
    omega2_m_eq: Vec<f64>,
    controller: Controller<'a>,
    spec: &'a RunSpec,
    ws: Workspace,
    tau: [Vec<f64>; NSRC],
    buf: Vec<f64>,
    buf2: Vec<f64>,
    peak: [f64; NSRC],
    peak_actuator: f64,
    peak_demand: f64,
    error: Option<Error>,
}

impl<'a> Dynamics<'a> {
    /// Sets up the dynamics of a run. `field` evaluates log(q): needed for mode control, for the
    /// exact potential and for the label output.
    pub fn new(
        chain: &'a Chain,
        q_eq: &DVector<f64>,
        potential: &'a ElasticPotential,
        controllers: ControllerSettings,
        spec: &'a RunSpec,
        field: Option<Box<dyn LogField + 'a>>,
    ) -> Result<Dynamics<'a>> {
        let n = chain.dof();
        let omega2 = match potential {
            ElasticPotential::Exact { omega } => omega * omega,
            ElasticPotential::Springs(_) => 0.0,
        };
        let (nominal, actual) = match potential {
            ElasticPotential::Springs(s) => {
                let actual = match (&spec.built, &spec.stiffness_scale) {
                    (Some(b), _) => Some(b.grouped()),
                    (None, Some(scale)) => Some(s.scaled(scale).grouped()),
                    (None, None) => None,
                };
                (Some(s.grouped()), actual)
            }
            ElasticPotential::Exact { .. } => (None, None),
        };
        let actual_shares_elements = matches!((&nominal, &actual), (Some(n), Some(a)) if n.same_elements(a));
        let mut controller = Controller::new(chain, q_eq, potential, controllers, field)?;
        controller.set_mode(spec.mode.clone());
        controller.set_energy(spec.energy.clone());
        controller.set_damping(spec.damping.clone());
        Ok(Dynamics {
            chain,
            q_eq: q_eq.as_slice().to_vec(),
            potential,
            nominal,
            actual,
            actual_shares_elements,
            omega2_m_eq: chain.mass_matrix(q_eq).iter().map(|m| m * omega2).collect(),
            controller,
            spec,
            ws: chain.workspace(),
            tau: std::array::from_fn(|_| vec![0.0; n]),
            buf: vec![0.0; n],
            buf2: vec![0.0; n],
            peak: [0.0; NSRC],
            peak_actuator: 0.0,
            peak_demand: 0.0,
            error: None,
        })
    }

    /// The energy E at a state (the nominal potential: what the controllers see).
    pub fn energy(&mut self, q: &[f64], qd: &[f64]) -> Result<f64> {
        self.controller.energy_at(q, qd)
    }

    /// Label at q: (θ or Δ, target) for output; NaN inside the ε-ball.
    pub fn label(&mut self, t: f64, q: &[f64]) -> Result<(f64, f64, bool)> {
        self.controller.label(t, q)
    }

    /// The state derivative: (q̇, q̈, |P| per source).
    pub fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> bool {
        match self.rhs_inner(t, y, dy) {
            Ok(()) => true,
            Err(e) => {
                self.error = Some(e);
                false
            }
        }
    }

    fn rhs_inner(&mut self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<()> {
        let n = self.chain.dof();
        let (q, rest) = y.split_at(n);
        let qd = &rest[..n];
        if !self.chain.prepare(&mut self.ws, q, qd) {
            return Err(Error::numerical(
                "simulation",
                format!("the mass matrix is not positive definite at t = {t:.4} s"),
            ));
        }
        for tau in self.tau.iter_mut() {
            tau.fill(0.0);
        }
        // Elastic potential (and parasitic springs).
        // The nominal U (for the energy controller) comes with the spring gradient when the
        // springs are as designed.
        let mut nominal_u = None;
        match self.potential {
            ElasticPotential::Springs(_) => {
                if let Some(actual) = &self.actual {
                    if self.actual_shares_elements {
                        let nominal = self.nominal.as_ref().expect("set in new");
                        let ue = nominal.value_and_gradient_of(actual, q, &mut self.buf);
                        nominal_u = Some(ue + self.chain.gravity_potential(q));
                    } else {
                        actual.gradient_into(q, &mut self.buf);
                    }
                } else {
                    let ue = self.nominal.as_ref().expect("set in new").value_gradient_into(q, &mut self.buf);
                    nominal_u = Some(ue + self.chain.gravity_potential(q));
                }
                for i in 0..n {
                    self.tau[SPRING][i] = -self.buf[i];
                }
            }
            ElasticPotential::Exact { .. } => {
                let lv = self.controller.log_value(q)?;
                // ∇U* = ω² (∂v/∂q)ᵀ M_eq v.
                for j in 0..n {
                    self.buf2[j] = (0..n).map(|k| self.omega2_m_eq[j + n * k] * lv.v[k]).sum();
                }
                self.chain.gravity_gradient_into(q, &mut self.buf);
                for i in 0..n {
                    let g: f64 = (0..n).map(|j| lv.dvdq[j * n + i] * self.buf2[j]).sum();
                    // U_e = U* − U_g: its torque is −∇U* + ∇U_g.
                    self.tau[SPRING][i] = -g + self.buf[i];
                }
            }
        }
        if let Some(p) = &self.spec.parasitic {
            for i in 0..n {
                self.tau[SPRING][i] -= p.eps * p.kappa[i] * (q[i] - self.q_eq[i]);
            }
        }
        self.chain.gravity_gradient_into(q, &mut self.buf);
        for i in 0..n {
            self.tau[GRAVITY][i] = -self.buf[i];
            self.tau[DAMPING][i] = -self.spec.damping[i] * qd[i];
        }
        // The controllers: mode selection, energy regulation and damping compensation.
        let c = self.controller.torque_at(t, q, qd, &self.ws, nominal_u)?;
        let (saturated, demand) = (c.saturation.active(), c.demand);
        self.tau[MODE].copy_from_slice(&c.mode);
        self.tau[ENERGY].copy_from_slice(&c.energy);
        self.tau[COMPENSATION].copy_from_slice(&c.compensation);
        // q̈ = M⁻¹ (Σ τ − h).
        for i in 0..n {
            self.buf[i] = self.tau.iter().map(|t| t[i]).sum::<f64>() - self.ws.coriolis()[i];
        }
        self.ws.solve(&mut self.buf);
        dy[..n].copy_from_slice(qd);
        dy[n..2 * n].copy_from_slice(&self.buf);
        let flux = |k: usize| dot(&self.tau[k], qd).abs();
        dy[2 * n] = flux(SPRING);
        dy[2 * n + 1] = flux(GRAVITY);
        dy[2 * n + 2] = flux(DAMPING);
        dy[2 * n + 3] = flux(MODE);
        dy[2 * n + 4] = flux(ENERGY);
        dy[2 * n + 5] = flux(COMPENSATION);
        dy[2 * n + NSRC] = if saturated { 1.0 } else { 0.0 };
        self.peak_demand = self.peak_demand.max(demand);
        for (k, tau) in self.tau.iter().enumerate() {
            for v in tau {
                self.peak[k] = self.peak[k].max(v.abs());
            }
        }
        for i in 0..n {
            let a = self.tau[MODE][i] + self.tau[ENERGY][i] + self.tau[COMPENSATION][i];
            self.peak_actuator = self.peak_actuator.max(a.abs());
        }
        Ok(())
    }

    fn take_error(&mut self, fallback: String) -> Error {
        self.error.take().unwrap_or_else(|| Error::numerical("simulation", fallback))
    }
}

/// The RK4 steps at which output samples are taken: sample j is due at t = j·`every`, taken at the
/// first step k with k/`rate` ≥ that time (less a round-off allowance). Each is computed from j
/// and k by one multiplication, never by adding intervals, so a 100 s run at 1 kHz sampled every
/// 10 ms has its 10 001 samples exactly on the grid, the last at 100 s. Samples are never denser
/// than the steps.
pub fn output_steps(steps: usize, rate: f64, every: f64) -> Vec<usize> {
    let per_sample = (every * rate).max(1.0);
    let mut out = Vec::new();
    let mut last = None;
    for j in 0.. {
        let k = (j as f64 * per_sample - 1e-9 * per_sample.max(1.0)).ceil().max(0.0);
        if k > steps as f64 {
            break;
        }
        let k = k as usize;
        if last != Some(k) {
            out.push(k);
            last = Some(k);
        }
    }
    out
}

/// Runs one simulation: the start state checked, the integrator's run recorded into a trace,
/// then the fluxes and peaks it accumulated.
pub fn run(dynamics: &mut Dynamics<'_>, settings: &SimSettings) -> Result<RunResult> {
    let spec = dynamics.spec;
    let n = dynamics.chain.dof();
    if spec.q0.len() != n || spec.qd0.len() != n || spec.damping.len() != n {
        return Err(Error::Setting {
            field: "run".into(),
            reason: format!("start state and damping need {n} entries"),
        });
    }
    let dim = 2 * n + NQUAD;
    let mut y = vec![0.0; dim];
    y[..n].copy_from_slice(&spec.q0);
    y[n..2 * n].copy_from_slice(&spec.qd0);
    let mut trace = Trace {
        n,
        t: Vec::new(),
        q: Vec::new(),
        qd: Vec::new(),
        tau: Vec::new(),
        energy: Vec::new(),
        label: Vec::new(),
        label_target: Vec::new(),
        in_ball: Vec::new(),
        geodesic_deviation: Vec::new(),
    };
    match settings.integrator {
        Integrator::Rk4 => integrate_rk4(dynamics, settings, &mut y, &mut trace)?,
        Integrator::Adaptive => integrate_adaptive(dynamics, settings, &mut y, &mut trace)?,
    }
    let f = &y[2 * n..];
    Ok(RunResult {
        name: spec.name.clone(),
        trace,
        fluxes: Fluxes { potential: f[0], gravity: f[1], damping: f[2], mode: f[3], energy: f[4], compensation: f[5] },
        peak_torque: dynamics.peak,
        peak_actuator_torque: dynamics.peak_actuator,
        peak_demanded_torque: dynamics.peak_demand,
        saturated_s: f[NSRC],
    })
}

/// The time between output samples: the settings' interval, never shorter than a step.
fn output_every(settings: &SimSettings) -> f64 {
    settings.output_interval.max(1.0 / settings.rate)
}

/// Records the state y at t; `dy` receives the right-hand side there (which sets the torques
/// recorded), so that the RK4 step from this state reuses it as its first stage.
fn record(d: &mut Dynamics<'_>, t: f64, y: &[f64], trace: &mut Trace, dy: &mut [f64]) -> Result<()> {
    let n = trace.n;
    if !d.rhs(t, y, dy) {
        return Err(d.take_error(format!("right-hand side failed at t = {t:.4} s")));
    }
    trace.t.push(t);
    trace.q.extend_from_slice(&y[..n]);
    trace.qd.extend_from_slice(&y[n..2 * n]);
    for tau in &d.tau {
        trace.tau.extend_from_slice(tau);
    }
    let e = d.energy(&y[..n], &y[n..2 * n])?;
    trace.energy.push(e);
    let (label, target, in_ball) = d.label(t, &y[..n])?;
    trace.label.push(label);
    trace.label_target.push(target);
    trace.in_ball.push(in_ball);
    Ok(())
}

/// Classical RK4 at the settings' rate from y (left at the end state), recording the samples
/// [`output_steps`] schedules.
fn integrate_rk4(dynamics: &mut Dynamics<'_>, settings: &SimSettings, y: &mut [f64], trace: &mut Trace) -> Result<()> {
    let spec = dynamics.spec;
    let (n, dim) = (trace.n, y.len());
    let h = 1.0 / settings.rate;
    let steps = (spec.duration * settings.rate).round();
    if steps > 1e9 {
        return Err(Error::Setting {
            field: "simulate.rate".into(),
            reason: format!("{:.0} steps for {} s at {} Hz: at most 10⁹", steps, spec.duration, settings.rate),
        });
    }
    let steps = steps as usize;
    let due = output_steps(steps, settings.rate, output_every(settings));
    let mut next_sample = 0;
    let (mut k1, mut k2, mut k3, mut k4) = (vec![0.0; dim], vec![0.0; dim], vec![0.0; dim], vec![0.0; dim]);
    let mut tmp = vec![0.0; dim];
    for step in 0..=steps {
        // Times from the step count (k/rate), never from repeated additions of h.
        let t = step as f64 / settings.rate;
        // The right-hand side is a function of (t, y) alone (its caches and peak torques
        // aside, which a second call at the same point leaves as they are), so a recorded
        // state's evaluation is the step's first stage.
        let recorded = due.get(next_sample) == Some(&step);
        if recorded {
            record(dynamics, t, y, trace, &mut k1)?;
            next_sample += 1;
        }
        if step == steps {
            break;
        }
        let fail = |d: &mut Dynamics<'_>| d.take_error(format!("right-hand side failed at t = {t:.4} s"));
        if !recorded && !dynamics.rhs(t, y, &mut k1) {
            return Err(fail(dynamics));
        }
        for i in 0..dim {
            tmp[i] = y[i] + 0.5 * h * k1[i];
        }
        if !dynamics.rhs(t + 0.5 * h, &tmp, &mut k2) {
            return Err(fail(dynamics));
        }
        for i in 0..dim {
            tmp[i] = y[i] + 0.5 * h * k2[i];
        }
        if !dynamics.rhs(t + 0.5 * h, &tmp, &mut k3) {
            return Err(fail(dynamics));
        }
        for i in 0..dim {
            tmp[i] = y[i] + h * k3[i];
        }
        if !dynamics.rhs(t + h, &tmp, &mut k4) {
            return Err(fail(dynamics));
        }
        for i in 0..dim {
            y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        if y[..2 * n].iter().any(|v| !v.is_finite()) {
            return Err(Error::numerical("simulation", format!("the state became non-finite at t = {:.4} s", t + h)));
        }
    }
    Ok(())
}

/// Dormand–Prince 5(4) with the error controlled on the state alone (not the accumulated fluxes)
/// and steps of at most one RK4 step, from y (left at the end state); samples are taken from the
/// dense output at multiples of the output interval, then recorded.
fn integrate_adaptive(
    dynamics: &mut Dynamics<'_>,
    settings: &SimSettings,
    y: &mut [f64],
    trace: &mut Trace,
) -> Result<()> {
    let spec = dynamics.spec;
    let (n, dim) = (trace.n, y.len());
    let h = 1.0 / settings.rate;
    let out_every = output_every(settings);
    let mut ode = Dopri5::new(dim, OdeSettings { max_step: h.max(settings.ode.max_step), ..settings.ode })
        .with_error_components(2 * n);
    let mut rhs = |t: f64, yy: &[f64], d: &mut [f64]| dynamics.rhs(t, yy, d);
    ode.start(&mut rhs, 0.0, y, spec.duration).map_err(|e| Error::numerical("simulation", e.to_string()))?;
    let mut samples: Vec<(f64, Vec<f64>)> = vec![(0.0, y.to_vec())];
    // Sample j at j·every (one multiplication, no accumulated round-off); a time within
    // round-off of the end is the end.
    let slack = 1e-9 * out_every;
    let sample_time = |j: usize| {
        let t = j as f64 * out_every;
        if (t - spec.duration).abs() <= slack { spec.duration } else { t }
    };
    let mut next_j = 1;
    loop {
        let done = ode.step(&mut rhs, spec.duration).map_err(|e| Error::numerical("simulation", e.to_string()))?;
        while sample_time(next_j) <= spec.duration && sample_time(next_j) <= ode.t() + slack {
            let tj = sample_time(next_j).min(ode.t());
            let mut s = vec![0.0; dim];
            ode.dense(tj, &mut s);
            samples.push((sample_time(next_j), s));
            next_j += 1;
        }
        if done {
            break;
        }
    }
    y.copy_from_slice(ode.y());
    let mut dy = vec![0.0; dim];
    for (t, s) in samples {
        record(dynamics, t, &s, trace, &mut dy)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_samples_are_scheduled_on_the_step_grid() {
        // 100 s at 1 kHz every 10 ms: 10 001 samples, every 10th step, the last one the last step.
        let due = output_steps(100_000, 1000.0, 0.01);
        assert_eq!(due.len(), 10_001);
        assert!(due.iter().enumerate().all(|(j, &k)| k == 10 * j));
        // Their times k/rate are exactly j/100, ending at 100 s.
        assert!(due.iter().enumerate().all(|(j, &k)| k as f64 / 1000.0 == j as f64 / 100.0));
        assert_eq!(*due.last().unwrap() as f64 / 1000.0, 100.0);
        // An interval that is not a multiple of the step: the first step at or after each time.
        assert_eq!(output_steps(10, 1.0, 2.5), vec![0, 3, 5, 8, 10]);
        // Intervals shorter than a step never repeat a step.
        assert_eq!(output_steps(3, 1.0, 0.4), vec![0, 1, 2, 3]);
    }
}
