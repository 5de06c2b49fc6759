//! Controllers of the paper's section V: mode selection and energy regulation.
//!
//! **Mode selection.** With a label ℓ(q) of the mode through q and its gradient g = ∂ℓ/∂q,
//!
//! τ_θ = M g (−k_θ Δ − d_θ gᵀq̇),  d_θ = 2ζ√(k_θ m_θ),  m_θ = 1 / (gᵀ M⁻¹ g),
//!
//! switched off inside the ε-ball ‖q − q_eq‖ ≤ ε where the label is undefined and faded in across
//! the shell ε < ‖q − q_eq‖ < 2ε by the weight w of [`blend_weight`] (see [`Blend`]). For two joints
//! ℓ = θ = 2·atan2(v₂, v₁) and Δ = Δθ wrapped to (−π, π]. For three or more joints the mode is the
//! line ±u of the metric-frame direction u of v = log(q), and Δ = 2·∠(±u, u_d) ∈ [0, π] is the
//! distance to the desired line with g = ∂Δ/∂q: the same law descends ½k_θΔ², a potential on the
//! space of modes (generalising the doubled angle of the two-joint label). `docs/theory.md` names
//! two points the paper leaves loose; both are options here:
//!
//! * [`LabelGradient::Exact`] (default) uses the gradient of θ; [`LabelGradient::Paper`] uses the
//!   paper's appendix formula, which lacks the factor 1/|Λ| with |Λ| = ‖q − q_eq‖², i.e.
//!   ‖q − q_eq‖² times the exact gradient — stiffer away from q_eq;
//! * [`ModeInertia::Paper`] (default) keeps the paper's M in front of g, under which the closed
//!   loop's damping ratio is not ζ (the label's dynamics see |g|² instead of gᵀM⁻¹g);
//!   [`ModeInertia::Consistent`] drops it, τ_θ = g(−k_θΔ − d_θ gᵀq̇), so that
//!   m_θΔ̈ + d_θΔ̇ + k_θΔ = 0 and the damping ratio is ζ.
//!
//! **Energy regulation** with E = ½q̇ᵀMq̇ + U(q) − U(q_eq) (U the nominal potential, springs plus
//! gravity): the mode-compatible τ_E = β_E M (E_d − E) q̇, tangent to the motion, or negative
//! damping τ_nD = β_nD (E_d − E) q̇. A proportional τ_E leaves a steady deficit against joint
//! damping; damping compensation adds the feed-forward D q̇ (the hardware-style remedy the
//! paper recommends).
//!
//! **Saturation.** With `[controllers] max_torque` (τ_max per joint) the torques are brought
//! within |τ_c,i| ≤ τ_max,i by [`saturate`], never by clipping joints one by one (which would turn
//! the torque off the law's direction: a clipped τ_θ pushes across modes, a clipped τ_E is no longer
//! tangent to the motion). The mode torque comes first and is scaled as a whole vector, so it keeps
//! the direction M g (or g); the energy torque and the compensation then share what is left, scaled
//! together as one vector by the largest factor that fits, so τ_E stays along M q̇ and never takes
//! the mode law's headroom. The energy loop is aware of it in this sense: what it is given is the
//! headroom the mode law leaves, and while saturated its deficit E_d − E is what the next instants
//! act on. It has no integral state, so nothing winds up: once the torque fits again the law is
//! exactly the unsaturated one.
//!
//! **The controller of a loop.** [`Controller`] is the one place these laws are combined: the
//! label (from a [`LogField`]), the blend at the ε-ball, the schedules of θ_d (or u_d) and E_d,
//! the damping compensation. `springfit simulate` calls it at every stage of its integrator
//! ([`crate::dynamics::simulate::Dynamics`]) and a robot's own loop calls the same code through
//! [`Controller::torque`] (the Python package's `Controller`), so what runs on the arm is what
//! was simulated.

use nalgebra::DVector;

use crate::design::controllers::{Blend, ControllerSettings, EnergyLaw, LabelGradient, ModeInertia};
use crate::error::{Error, Result};
use crate::geodesic::MetricFrame;
use crate::geodesic::label::{LogField, LogValue, SphereError, angle_label, sphere_distance, sphere_error};
use crate::geodesic::logmap::wrap_angle;
use crate::model::{Chain, Workspace};
use crate::potential::{GroupedSet, Potential, SpringSet};

/// A desired mode: an angle θ (two joints) or a direction u in the metric frame (any number).
#[derive(Debug, Clone, PartialEq)]
pub enum ModeTarget {
    /// θ_d.
    Angle(f64),
    /// A unit vector in the metric frame at q_eq (±u the same mode).
    Direction(DVector<f64>),
}

/// Mode control of a run: the desired mode as a schedule of (start time, target).
#[derive(Debug, Clone, PartialEq)]
pub struct ModeControl {
    /// Steps of the schedule, by increasing start time (the first at t = 0).
    pub schedule: Vec<(f64, ModeTarget)>,
}

impl ModeControl {
    /// The target in force at time t.
    pub fn target(&self, t: f64) -> &ModeTarget {
        let k = self.schedule.partition_point(|(t0, _)| *t0 <= t).max(1) - 1;
        &self.schedule[k].1
    }
}

/// Energy regulation of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct EnergyControl {
    /// τ_E or τ_nD.
    pub law: EnergyLaw,
    /// E_d in J as a schedule of (start time, value), by increasing time, the first at t = 0.
    pub schedule: Vec<(f64, f64)>,
    /// Add the damping feed-forward D q̇.
    pub compensate_damping: bool,
}

impl EnergyControl {
    /// E_d at time t.
    pub fn target(&self, t: f64) -> f64 {
        let k = self.schedule.partition_point(|(t0, _)| *t0 <= t).max(1) - 1;
        self.schedule[k].1
    }

    /// The last E_d of the schedule (what the end of a run is judged against).
    pub fn final_target(&self) -> f64 {
        self.schedule.last().map_or(0.0, |s| s.1)
    }
}

/// The elastic potential: what an arm has, and what its controllers believe it has (the
/// nominal one, for the energy E).
#[derive(Debug, Clone, PartialEq)]
pub enum ElasticPotential {
    /// A spring set (fitted, or read from a bill of materials).
    Springs(SpringSet),
    /// U_e = ½ω²r² − U_g through the log field.
    Exact {
        /// ω in rad/s.
        omega: f64,
    },
}

/// The weight of the mode controller at distance `r` = ‖q − q_eq‖ from the equilibrium (joint
/// angles, rad): 0 inside the ε-ball, 1 from 2ε on (smooth) or right outside ε (hard).
pub fn blend_weight(blend: Blend, epsilon: f64, r: f64) -> f64 {
    if r <= epsilon {
        return 0.0;
    }
    match blend {
        Blend::Hard => 1.0,
        Blend::Smooth => {
            if epsilon <= 0.0 {
                return 1.0;
            }
            let x = ((r - epsilon) / epsilon).clamp(0.0, 1.0);
            x * x * (3.0 - 2.0 * x)
        }
    }
}

/// The mode torque (see the module docs) for label deviation `delta`, label gradient `g`
/// (already in the chosen variant), velocity `qd`, mass matrix `m` (row-major) and
/// `minv_g` = M⁻¹g. Writes into `tau`.
#[allow(clippy::too_many_arguments)]
pub fn mode_torque(
    settings: &ControllerSettings,
    delta: f64,
    g: &[f64],
    minv_g: &[f64],
    qd: &[f64],
    m: &[f64],
    tau: &mut [f64],
) {
    let n = g.len();
    let ginv = dot(g, minv_g);
    if ginv <= 0.0 || !ginv.is_finite() {
        tau.fill(0.0);
        return;
    }
    let m_theta = 1.0 / ginv;
    let d_theta = 2.0 * settings.zeta * (settings.k_theta * m_theta).sqrt();
    let f = -settings.k_theta * delta - d_theta * dot(g, qd);
    match settings.inertia {
        ModeInertia::Paper | ModeInertia::Auto => {
            for i in 0..n {
                tau[i] = f * (0..n).map(|j| m[i * n + j] * g[j]).sum::<f64>();
            }
        }
        ModeInertia::Consistent => {
            for i in 0..n {
                tau[i] = f * g[i];
            }
        }
    }
}

/// The mode torque on the sphere of modes (three or more joints, or a direction target on two):
/// with the tangent error e and the Jacobian J of [`sphere_error`] (rows rᵢ, already in the chosen
/// gradient variant) and `minv_jt` = M⁻¹rᵢ row by row,
///
/// τ_θ = M Jᵀ (−k_θ e − d_θ J q̇),  d_θ = 2ζ√(k_θ m_θ),  m_θ = (n − 1) / tr(J M⁻¹ Jᵀ),
///
/// the gradient of ½k_θ|e|² = ½k_θΔ² plus damping of the label's whole velocity on the sphere
/// (not only its radial part, as a law on the scalar Δ would). m_θ is the mean inertia of the
/// n − 1 directions of the sphere. For two joints with the Euclidean frame J = t gᵀ, e = Δθ t
/// (t the circle's unit tangent) and tr(J M⁻¹ Jᵀ) = gᵀM⁻¹g, so this is [`mode_torque`]
/// exactly (a test checks it). Writes into `tau`.
pub fn sphere_mode_torque(
    settings: &ControllerSettings,
    err: &SphereError,
    minv_jt: &[f64],
    qd: &[f64],
    m: &[f64],
    tau: &mut [f64],
) {
    let n = qd.len();
    let j = &err.jacobian;
    let trace: f64 = (0..n).map(|i| dot(&j[i * n..(i + 1) * n], &minv_jt[i * n..(i + 1) * n])).sum();
    if trace <= 0.0 || !trace.is_finite() {
        tau.fill(0.0);
        return;
    }
    let m_theta = (n as f64 - 1.0).max(1.0) / trace;
    let d_theta = 2.0 * settings.zeta * (settings.k_theta * m_theta).sqrt();
    // F = Jᵀ f, f = −k e − d J q̇.
    let mut force = [0.0f64; 16];
    let force = if n <= 16 { &mut force[..n] } else { return tau.fill(0.0) };
    for i in 0..n {
        let row = &j[i * n..(i + 1) * n];
        let f = -settings.k_theta * err.error[i] - d_theta * dot(row, qd);
        for (fk, r) in force.iter_mut().zip(row) {
            *fk += f * r;
        }
    }
    match settings.inertia {
        ModeInertia::Paper => {
            for i in 0..n {
                tau[i] = dot(&m[i * n..(i + 1) * n], force);
            }
        }
        ModeInertia::Consistent | ModeInertia::Auto => tau.copy_from_slice(force),
    }
}

/// The energy torque for energy error `e_err` = E_d − E.
pub fn energy_torque(
    law: EnergyLaw,
    settings: &ControllerSettings,
    e_err: f64,
    qd: &[f64],
    m: &[f64],
    tau: &mut [f64],
) {
    let n = qd.len();
    match law {
        EnergyLaw::Energy => {
            for i in 0..n {
                tau[i] = settings.beta_e * e_err * (0..n).map(|j| m[i * n + j] * qd[j]).sum::<f64>();
            }
        }
        EnergyLaw::NegativeDamping => {
            for i in 0..n {
                tau[i] = settings.beta_nd * e_err * qd[i];
            }
        }
    }
}

/// The scale factors [`saturate`] applied: 1 when the torque fitted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Saturation {
    /// The factor on τ_θ.
    pub mode: f64,
    /// The factor on τ_E + τ_comp.
    pub energy: f64,
}

impl Saturation {
    /// No saturation.
    pub const NONE: Saturation = Saturation { mode: 1.0, energy: 1.0 };

    /// Whether any torque was scaled down.
    pub fn active(&self) -> bool {
        self.mode < 1.0 || self.energy < 1.0
    }
}

/// Brings the controllers' torques within `max` (N·m per joint, each > 0), in place, keeping
/// each law's direction (see the module docs): τ_θ is scaled by s = min(1, minᵢ τ_max,i/|τ_θ,i|);
/// τ_E and τ_comp together by the largest λ ∈ [0, 1] with |s τ_θ,i + λ (τ_E,i + τ_comp,i)| ≤
/// τ_max,i for every joint.
pub fn saturate(max: &[f64], mode: &mut [f64], energy: &mut [f64], compensation: &mut [f64]) -> Saturation {
    let mut s = 1.0f64;
    for (t, m) in mode.iter().zip(max) {
        if t.abs() > *m {
            s = s.min(m / t.abs());
        }
    }
    if s < 1.0 {
        for t in mode.iter_mut() {
            *t *= s;
        }
    }
    let mut lambda = 1.0f64;
    for i in 0..max.len() {
        let rest = energy[i] + compensation[i];
        if (mode[i] + rest).abs() > max[i] {
            // |τ_θ,i| ≤ τ_max,i: the bound is met in the direction of `rest`.
            lambda = lambda.min(((max[i].copysign(rest) - mode[i]) / rest).max(0.0));
        }
    }
    if lambda < 1.0 {
        for (e, c) in energy.iter_mut().zip(compensation.iter_mut()) {
            *e *= lambda;
            *c *= lambda;
        }
    }
    Saturation { mode: s, energy: lambda }
}

/// Dot product of two slices.
#[inline]
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The controllers' torques at one state, by source (N·m per joint), with what they saw.
#[derive(Debug, Clone, PartialEq)]
pub struct ControlTorques {
    /// τ_θ, already scaled by the blend weight (and by the saturation).
    pub mode: Vec<f64>,
    /// τ_E or τ_nD (saturated with the compensation).
    pub energy: Vec<f64>,
    /// The damping feed-forward D q̇.
    pub compensation: Vec<f64>,
    /// How `[controllers] max_torque` scaled the torques ([`Saturation::NONE`] without a limit
    /// or when they fitted).
    pub saturation: Saturation,
    /// Largest |τ_θ,i + τ_E,i + τ_comp,i| over the joints as the laws asked, before saturation,
    /// N·m.
    pub demand: f64,
    /// The blend weight of the mode torque (0 inside the ε-ball or without mode control).
    pub weight: f64,
    /// E = ½q̇ᵀMq̇ + U(q) − U(q_eq) with the nominal U, when it was computed (energy control on,
    /// or [`Controller::torque`]); NaN otherwise.
    pub energy_value: f64,
}

impl ControlTorques {
    fn zeros(n: usize) -> Self {
        ControlTorques {
            mode: vec![0.0; n],
            energy: vec![0.0; n],
            compensation: vec![0.0; n],
            saturation: Saturation::NONE,
            demand: 0.0,
            weight: 0.0,
            energy_value: f64::NAN,
        }
    }

    /// τ_c = τ_θ + τ_E + τ_comp, joint i: what joint i's motor delivers.
    pub fn motor(&self, i: usize) -> f64 {
        self.mode[i] + self.energy[i] + self.compensation[i]
    }
}

/// What the controller believes the potential to be, in the form it evaluates fast.
enum Nominal {
    Springs(GroupedSet),
    /// ω² M(q_eq), row-major.
    Exact(Vec<f64>),
}

/// Mode selection and energy regulation for one arm, with their schedules: the torques a loop
/// sends to the motors at (q, q̇, t). See the module docs for the laws; every setting is the
/// design's `[controllers]` ([`ControllerSettings`]).
pub struct Controller<'a> {
    chain: &'a Chain,
    q_eq: Vec<f64>,
    frame: MetricFrame,
    settings: ControllerSettings,
    nominal: Nominal,
    /// U(q_eq) with the nominal potential: energies are measured from it.
    u0: f64,
    mode: Option<ModeControl>,
    energy: Option<EnergyControl>,
    /// The joint damping D (diagonal) that the compensation feeds forward.
    damping: Vec<f64>,
    field: Option<Box<dyn LogField + 'a>>,
    lv: LogValue,
    /// The reference mode of the label output for three or more joints without a direction
    /// target: the mode of the first labelled point.
    reference: Option<DVector<f64>>,
    out: ControlTorques,
    /// For [`Controller::torque`], which prepares M(q) itself (taken out during the call).
    ws: Option<Workspace>,
    gbuf: Vec<f64>,
    buf: Vec<f64>,
    /// The tangent error and Jacobian of the sphere law, and M⁻¹Jᵀ row by row.
    serr: SphereError,
    minv_jt: Vec<f64>,
}

impl<'a> Controller<'a> {
    /// A controller for `chain` about `q_eq` believing the potential `potential`, with the gains
    /// `settings`. `field` evaluates log(q): needed for mode control, for the exact potential and
    /// for the label. No mode or energy control and no damping until they are set.
    pub fn new(
        chain: &'a Chain,
        q_eq: &DVector<f64>,
        potential: &ElasticPotential,
        settings: ControllerSettings,
        field: Option<Box<dyn LogField + 'a>>,
    ) -> Result<Controller<'a>> {
        let n = chain.dof();
        if let Some(max) = &settings.max_torque
            && (max.len() != n || max.iter().any(|m| !(m.is_finite() && *m > 0.0)))
        {
            return Err(Error::Setting {
                field: "controllers.max_torque".into(),
                reason: format!("needs {n} finite limits > 0 N·m (one per joint), got {max:?}"),
            });
        }
        let m_eq = chain.mass_matrix(q_eq);
        let frame = MetricFrame::new(&m_eq)?;
        let nominal = match potential {
            ElasticPotential::Springs(s) => Nominal::Springs(s.grouped()),
            ElasticPotential::Exact { omega } => {
                if field.is_none() {
                    return Err(Error::Setting {
                        field: "potential".into(),
                        reason: "the exact potential needs a log field".into(),
                    });
                }
                Nominal::Exact(m_eq.iter().map(|m| m * omega * omega).collect())
            }
        };
        let mut c = Controller {
            chain,
            q_eq: q_eq.as_slice().to_vec(),
            frame,
            settings,
            nominal,
            u0: 0.0,
            mode: None,
            energy: None,
            damping: vec![0.0; n],
            field,
            lv: LogValue::zeros(n),
            reference: None,
            out: ControlTorques::zeros(n),
            ws: Some(chain.workspace()),
            gbuf: Vec::with_capacity(n),
            buf: vec![0.0; n],
            serr: SphereError::zeros(n),
            minv_jt: vec![0.0; n * n],
        };
        let q_eq = c.q_eq.clone();
        c.u0 = c.nominal_potential(&q_eq)?;
        Ok(c)
    }

    /// Sets (or, with `None`, switches off) mode selection.
    pub fn set_mode(&mut self, mode: Option<ModeControl>) {
        self.mode = mode;
    }

    /// Sets (or switches off) energy regulation.
    pub fn set_energy(&mut self, energy: Option<EnergyControl>) {
        self.energy = energy;
    }

    /// Sets the joint damping D (diagonal, N·m·s/rad) that the compensation feeds forward.
    pub fn set_damping(&mut self, damping: Vec<f64>) {
        self.damping = damping;
    }

    /// Mode selection, if on.
    pub fn mode(&self) -> Option<&ModeControl> {
        self.mode.as_ref()
    }

    /// Energy regulation, if on.
    pub fn energy(&self) -> Option<&EnergyControl> {
        self.energy.as_ref()
    }

    /// The gains.
    pub fn settings(&self) -> &ControllerSettings {
        &self.settings
    }

    /// The torques of the last [`Controller::torque`] or [`Controller::torque_at`].
    pub fn torques(&self) -> &ControlTorques {
        &self.out
    }

    /// v = log(q) and ∂v/∂q from the controller's field (the arm's exact potential uses it too).
    pub fn log_value(&mut self, q: &[f64]) -> Result<&LogValue> {
        let field = self
            .field
            .as_mut()
            .ok_or_else(|| Error::Setting { field: "label".into(), reason: "mode control needs a label".into() })?;
        field.eval(q, &mut self.lv)?;
        Ok(&self.lv)
    }

    /// U_e + U_g at q with the nominal potential.
    pub fn nominal_potential(&mut self, q: &[f64]) -> Result<f64> {
        let ue = match &self.nominal {
            Nominal::Springs(s) => s.value(q)?,
            Nominal::Exact(omega2_m_eq) => {
                let field = self.field.as_mut().expect("checked in new");
                field.eval(q, &mut self.lv)?;
                let n = q.len();
                let v = &self.lv.v;
                let mut r = 0.0;
                for i in 0..n {
                    for j in 0..n {
                        r += v[i] * omega2_m_eq[i + n * j] * v[j];
                    }
                }
                0.5 * r - self.chain.gravity_potential(q)
            }
        };
        Ok(ue + self.chain.gravity_potential(q))
    }

    /// The energy E = ½q̇ᵀMq̇ + U(q) − U(q_eq) at a state, with the nominal U.
    pub fn energy_at(&mut self, q: &[f64], qd: &[f64]) -> Result<f64> {
        let u = self.nominal_potential(q)?;
        let m = self.chain.mass_matrix(&DVector::from_column_slice(q));
        let kin = 0.5
            * qd.iter().enumerate().map(|(i, a)| a * (0..q.len()).map(|j| m[(i, j)] * qd[j]).sum::<f64>()).sum::<f64>();
        Ok(kin + u - self.u0)
    }

    /// E at (q, q̇) with M(q) given (row-major) and U_e + U_g at q if the caller has it.
    fn energy_with(&mut self, q: &[f64], qd: &[f64], m: &[f64], nominal_u: Option<f64>) -> Result<f64> {
        let n = q.len();
        let u = match nominal_u {
            Some(u) => u,
            None => self.nominal_potential(q)?,
        };
        let kin = 0.5 * (0..n).map(|i| qd[i] * (0..n).map(|j| m[i * n + j] * qd[j]).sum::<f64>()).sum::<f64>();
        Ok(kin + u - self.u0)
    }

    /// The label at q and its target at t: (θ or Δ, θ_d or 0, inside the ε-ball). The label is
    /// NaN inside the ball (and without a field); the target NaN without an angle target.
    pub fn label(&mut self, t: f64, q: &[f64]) -> Result<(f64, f64, bool)> {
        let n = q.len();
        let dist = q.iter().zip(&self.q_eq).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt();
        let in_ball = dist <= self.settings.epsilon;
        let Some(field) = self.field.as_mut() else { return Ok((f64::NAN, f64::NAN, in_ball)) };
        if dist == 0.0 {
            return Ok((f64::NAN, f64::NAN, true));
        }
        field.eval(q, &mut self.lv)?;
        if n == 2 {
            let (theta, _) = angle_label(&self.lv);
            let target = match self.mode.as_ref().map(|m| m.target(t)) {
                Some(ModeTarget::Angle(a)) => wrap_angle(*a),
                _ => f64::NAN,
            };
            Ok((if in_ball { f64::NAN } else { theta }, target, in_ball))
        } else {
            let reference = match self.mode.as_ref().map(|m| m.target(t)) {
                Some(ModeTarget::Direction(u)) => u.clone(),
                _ => {
                    if self.reference.is_none() {
                        let w = self.frame.to_frame(&DVector::from_column_slice(&self.lv.v));
                        self.reference = Some(w.normalize());
                    }
                    self.reference.clone().expect("set above")
                }
            };
            let (delta, _) = sphere_distance(&self.lv, &self.frame, &reference);
            Ok((if in_ball { f64::NAN } else { delta }, 0.0, in_ball))
        }
    }

    /// The torques at (q, q̇, t) for a loop of its own: checks the state, evaluates M(q), runs
    /// [`Controller::torque_at`] and also computes E.
    pub fn torque(&mut self, t: f64, q: &[f64], qd: &[f64]) -> Result<&ControlTorques> {
        let n = self.chain.dof();
        for (name, x) in [("q", q), ("qdot", qd)] {
            if x.len() != n {
                return Err(Error::Setting {
                    field: name.into(),
                    reason: format!("has {} entries but the robot has {n} joints", x.len()),
                });
            }
            if let Some(i) = x.iter().position(|v| !v.is_finite()) {
                return Err(Error::Setting {
                    field: format!("{name}[{i}]"),
                    reason: format!("must be finite, got {}", x[i]),
                });
            }
        }
        if !t.is_finite() {
            return Err(Error::Setting { field: "t".into(), reason: format!("must be finite, got {t}") });
        }
        let mut ws = self.ws.take().unwrap_or_else(|| self.chain.workspace());
        let prepared = self.chain.prepare(&mut ws, q, qd);
        let result = if prepared {
            self.torque_at(t, q, qd, &ws, None).map(|_| ())
        } else {
            Err(Error::numerical("controller", format!("the mass matrix is not positive definite at t = {t:.4} s")))
        };
        let result = match result {
            Ok(()) if self.out.energy_value.is_nan() => self.energy_with(q, qd, ws.mass(), None).map(|e| {
                self.out.energy_value = e;
            }),
            other => other,
        };
        self.ws = Some(ws);
        result?;
        Ok(&self.out)
    }

    /// The torques at (q, q̇, t) into [`Controller::torques`], with M(q) and its factor already in
    /// `ws` ([`Chain::prepare`]). `nominal_u` is U_e + U_g at q with the nominal potential when
    /// the caller has it (the simulator's spring gradient comes with it); otherwise it is
    /// computed when the energy law needs it.
    pub fn torque_at(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        ws: &Workspace,
        nominal_u: Option<f64>,
    ) -> Result<&ControlTorques> {
        let n = q.len();
        self.out.mode.fill(0.0);
        self.out.energy.fill(0.0);
        self.out.compensation.fill(0.0);
        self.out.weight = 0.0;
        self.out.energy_value = f64::NAN;
        // Mode selection.
        if let Some(mode) = &self.mode {
            let dist2: f64 = q.iter().zip(&self.q_eq).map(|(a, b)| (a - b).powi(2)).sum();
            let weight = blend_weight(self.settings.blend, self.settings.epsilon, dist2.sqrt());
            self.out.weight = weight;
            if weight > 0.0 {
                let field = self.field.as_mut().ok_or_else(|| Error::Setting {
                    field: "label".into(),
                    reason: "mode control needs a label".into(),
                })?;
                field.eval(q, &mut self.lv)?;
                match mode.target(t) {
                    ModeTarget::Angle(theta_d) if n == 2 => {
                        let (theta, grad) = angle_label(&self.lv);
                        let mut g = std::mem::take(&mut self.gbuf);
                        g.clear();
                        g.extend_from_slice(&grad);
                        if self.settings.gradient == LabelGradient::Paper {
                            for gi in g.iter_mut() {
                                *gi *= dist2;
                            }
                        }
                        self.buf.copy_from_slice(&g);
                        ws.solve(&mut self.buf);
                        let delta = wrap_angle(theta - theta_d);
                        mode_torque(&self.settings, delta, &g, &self.buf, qd, ws.mass(), &mut self.out.mode);
                        self.gbuf = g;
                    }
                    ModeTarget::Direction(u) => {
                        sphere_error(&self.lv, &self.frame, u, &mut self.serr);
                        if self.settings.gradient == LabelGradient::Paper {
                            for ji in self.serr.jacobian.iter_mut() {
                                *ji *= dist2;
                            }
                        }
                        self.minv_jt.copy_from_slice(&self.serr.jacobian);
                        for row in self.minv_jt.chunks_mut(n) {
                            ws.solve(row);
                        }
                        sphere_mode_torque(
                            &self.settings,
                            &self.serr,
                            &self.minv_jt,
                            qd,
                            ws.mass(),
                            &mut self.out.mode,
                        );
                    }
                    ModeTarget::Angle(_) => {
                        return Err(Error::Setting {
                            field: "mode".into(),
                            reason: "an angle mode needs two joints; give a direction vector".into(),
                        });
                    }
                }
                for t in self.out.mode.iter_mut() {
                    *t *= weight;
                }
            }
        }
        // Energy regulation and damping compensation.
        if let Some((law, target, compensate)) =
            self.energy.as_ref().map(|e| (e.law, e.target(t), e.compensate_damping))
        {
            let e = self.energy_with(q, qd, ws.mass(), nominal_u)?;
            self.out.energy_value = e;
            energy_torque(law, &self.settings, target - e, qd, ws.mass(), &mut self.out.energy);
            if compensate {
                for ((c, d), v) in self.out.compensation.iter_mut().zip(&self.damping).zip(qd) {
                    *c = d * v;
                }
            }
        }
        self.out.demand = (0..n).map(|i| self.out.motor(i).abs()).fold(0.0, f64::max);
        self.out.saturation = match &self.settings.max_torque {
            Some(max) => saturate(max, &mut self.out.mode, &mut self.out.energy, &mut self.out.compensation),
            None => Saturation::NONE,
        };
        Ok(&self.out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn energy_torque_is_tangent_to_the_velocity_and_injects_power() {
        let s = ControllerSettings::default();
        let m = [8.0, 2.0, 2.0, 2.0];
        let qd = [0.3, -0.7];
        let mut tau = [0.0; 2];
        energy_torque(EnergyLaw::Energy, &s, 5.0, &qd, &m, &mut tau);
        // τ_E = β (E_d − E) M q̇: its power is β (E_d − E) q̇ᵀMq̇ > 0 and M⁻¹τ ∥ q̇.
        let power = dot(&tau, &qd);
        let kinetic2 = qd[0] * (8.0 * qd[0] + 2.0 * qd[1]) + qd[1] * (2.0 * qd[0] + 2.0 * qd[1]);
        assert!((power - 0.13 * 5.0 * kinetic2).abs() < 1e-12);
        // M⁻¹ τ = β (E_d − E) q̇ exactly.
        let det = 8.0 * 2.0 - 2.0 * 2.0;
        let a = [(2.0 * tau[0] - 2.0 * tau[1]) / det, (-2.0 * tau[0] + 8.0 * tau[1]) / det];
        assert!((a[0] - 0.65 * qd[0]).abs() < 1e-12 && (a[1] - 0.65 * qd[1]).abs() < 1e-12);
        energy_torque(EnergyLaw::NegativeDamping, &s, -2.0, &qd, &m, &mut tau);
        assert!((tau[0] + 0.8 * 0.3).abs() < 1e-12);
    }

    #[test]
    fn saturation_keeps_each_laws_direction_and_uses_the_headroom() {
        let max = [10.0, 4.0];
        let parallel = |a: &[f64], b: &[f64]| (a[0] * b[1] - a[1] * b[0]).abs() < 1e-12 && dot(a, b) > 0.0;
        let within = |t: &[f64]| t.iter().zip(&max).all(|(t, m)| t.abs() <= m + 1e-12);
        // τ_θ = (20, −6) is beyond both limits: scaled as a whole by min(10/20, 4/6) = 0.5 to
        // (10, −3), not clipped to (10, −4), which would turn it off its direction.
        let (mut mode, mut energy, mut comp) = ([20.0, -6.0], [1.0, 3.0], [0.5, 0.0]);
        let s = saturate(&max, &mut mode, &mut energy, &mut comp);
        assert!((s.mode - 0.5).abs() < 1e-12 && s.active(), "{s:?}");
        assert!(parallel(&mode, &[20.0, -6.0]) && (mode[0] - 10.0).abs() < 1e-12);
        // No headroom left at joint 1 in the direction τ_E + τ_comp push: both vanish together.
        assert_eq!(s.energy, 0.0);
        assert_eq!((energy, comp), ([0.0, 0.0], [0.0, 0.0]));
        // τ_θ within its limits, the sum not: τ_E + τ_comp = (8, 6) scaled by the largest λ that
        // fits, min((10 − 6)/8, (4 + 1)/6) = 0.5, each along its own direction; joint 1 ends on
        // its limit, joint 2 inside.
        let (mut mode, mut energy, mut comp) = ([6.0, -1.0], [6.0, 4.0], [2.0, 2.0]);
        let s = saturate(&max, &mut mode, &mut energy, &mut comp);
        assert_eq!(s.mode, 1.0);
        assert_eq!(mode, [6.0, -1.0]);
        assert!((s.energy - 0.5).abs() < 1e-12, "{s:?}");
        assert!(parallel(&energy, &[6.0, 4.0]) && parallel(&comp, &[2.0, 2.0]));
        let total: Vec<f64> = (0..2).map(|i| mode[i] + energy[i] + comp[i]).collect();
        assert!(within(&total) && (total[0] - 10.0).abs() < 1e-12 && (total[1] - 2.0).abs() < 1e-12, "{total:?}");
        // Within the limits nothing changes.
        let (mut mode, mut energy, mut comp) = ([1.0, 1.0], [1.0, -1.0], [0.0, 0.0]);
        assert_eq!(saturate(&max, &mut mode, &mut energy, &mut comp), Saturation::NONE);
        assert_eq!((mode, energy), ([1.0, 1.0], [1.0, -1.0]));
    }

    #[test]
    fn the_smooth_blend_is_c1_and_spans_epsilon_to_two_epsilon() {
        let eps = 0.1;
        let w = |r: f64| blend_weight(Blend::Smooth, eps, r);
        assert_eq!(w(0.05), 0.0);
        assert_eq!(w(eps), 0.0);
        assert_eq!(w(2.0 * eps), 1.0);
        assert_eq!(w(1.0), 1.0);
        assert!((w(1.5 * eps) - 0.5).abs() < 1e-12);
        // Slopes by central differences: zero at both ends of the shell (C¹), ≤ 1.5/ε between.
        let h = 1e-7;
        let slope = |r: f64| (w(r + h) - w(r - h)) / (2.0 * h);
        assert!(slope(eps + 2.0 * h).abs() < 1e-3 && slope(2.0 * eps - 2.0 * h).abs() < 1e-3);
        assert!((slope(1.5 * eps) - 1.5 / eps).abs() < 1e-5);
        let mut prev = 0.0;
        for k in 0..=100 {
            let v = w(eps + eps * k as f64 / 100.0);
            assert!(v >= prev);
            prev = v;
        }
        // The hard switch steps from 0 to 1 at ε.
        assert_eq!(blend_weight(Blend::Hard, eps, eps), 0.0);
        assert_eq!(blend_weight(Blend::Hard, eps, eps + 1e-12), 1.0);
    }

    #[test]
    fn the_sphere_law_is_the_papers_law_for_two_joints() {
        use crate::geodesic::label::ExactLog;
        use crate::numerics::ode::OdeSettings;
        // The paper's double pendulum; the n-joint law on the sphere of the Euclidean frame
        // (directions of joint velocity, the paper's label) against the paper's law on θ.
        let chain = Chain::paper_double_pendulum();
        let q_eq = DVector::from_vec(vec![0.0, std::f64::consts::FRAC_PI_2]);
        let frame = MetricFrame::new(&nalgebra::DMatrix::identity(2, 2)).unwrap();
        let mut log = ExactLog::new(&chain, &q_eq, OdeSettings::default());
        let mut lv = LogValue::zeros(2);
        for (q, qd, theta_d) in [([0.35, 1.95], [0.4, -1.1], 0.3), ([-0.5, 1.2], [-0.2, 0.9], -2.9)] {
            log.eval(&q, &mut lv).unwrap();
            let mq = chain.mass_matrix(&DVector::from_column_slice(&q));
            let m: Vec<f64> = (0..4).map(|k| mq[(k / 2, k % 2)]).collect();
            let minv = mq.clone().try_inverse().unwrap();
            // `auto` is the paper's form on θ and the consistent one on the sphere: compare like
            // with like.
            for inertia in [ModeInertia::Paper, ModeInertia::Consistent] {
                let s = ControllerSettings { inertia, k_theta: 2.0, ..ControllerSettings::default() };
                let (theta, g) = angle_label(&lv);
                let minv_g: Vec<f64> = (0..2).map(|i| minv[(i, 0)] * g[0] + minv[(i, 1)] * g[1]).collect();
                let mut paper = [0.0; 2];
                mode_torque(&s, wrap_angle(theta - theta_d), &g, &minv_g, &qd, &m, &mut paper);
                let u_d = DVector::from_vec(vec![(theta_d / 2.0).cos(), (theta_d / 2.0).sin()]);
                let mut err = SphereError::zeros(2);
                sphere_error(&lv, &frame, &u_d, &mut err);
                assert!((err.delta - wrap_angle(theta - theta_d).abs()).abs() < 1e-12);
                let j = &err.jacobian;
                let minv_jt: Vec<f64> = (0..2)
                    .flat_map(|r| (0..2).map(move |i| (r, i)))
                    .map(|(r, i)| minv[(i, 0)] * j[r * 2] + minv[(i, 1)] * j[r * 2 + 1])
                    .collect();
                let mut sphere = [0.0; 2];
                sphere_mode_torque(&s, &err, &minv_jt, &qd, &m, &mut sphere);
                for i in 0..2 {
                    assert!(
                        (sphere[i] - paper[i]).abs() < 1e-9 * (1.0 + paper[i].abs()),
                        "{inertia:?}: {sphere:?} vs {paper:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_sphere_error_is_smooth_through_the_target_and_its_jacobian_is_the_directions_rate() {
        use crate::geodesic::label::ExactLog;
        use crate::numerics::ode::OdeSettings;
        let chain = Chain::paper_double_pendulum();
        let q_eq = DVector::from_vec(vec![0.0, std::f64::consts::FRAC_PI_2]);
        let frame = MetricFrame::new(&chain.mass_matrix(&q_eq)).unwrap();
        let mut log = ExactLog::new(&chain, &q_eq, OdeSettings::default());
        let mut lv = LogValue::zeros(2);
        let q = [0.3, 2.0];
        log.eval(&q, &mut lv).unwrap();
        // The target is the label itself: e = 0, Δ = 0.
        let u = frame.to_frame(&DVector::from_column_slice(&lv.v)).normalize();
        let mut err = SphereError::zeros(2);
        sphere_error(&lv, &frame, &u, &mut err);
        assert!(err.delta < 1e-7 && err.error.iter().all(|e| e.abs() < 1e-7), "{err:?}");
        // Against −u (the same line) too.
        sphere_error(&lv, &frame, &(-&u), &mut err);
        assert!(err.delta < 1e-7 && err.error.iter().all(|e| e.abs() < 1e-7), "{err:?}");
        // J q̇ is the rate of 2u: finite differences along q̇.
        let qd = [0.7, -0.4];
        sphere_error(&lv, &frame, &u, &mut err);
        let h = 1e-6;
        let dir = |q: [f64; 2], log: &mut ExactLog| {
            let mut l = LogValue::zeros(2);
            log.eval(&q, &mut l).unwrap();
            frame.to_frame(&DVector::from_column_slice(&l.v)).normalize()
        };
        let up = dir([q[0] + h * qd[0], q[1] + h * qd[1]], &mut log);
        let um = dir([q[0] - h * qd[0], q[1] - h * qd[1]], &mut log);
        for i in 0..2 {
            let fd = (up[i] - um[i]) / h; // 2 du/dt
            let jq = err.jacobian[i * 2] * qd[0] + err.jacobian[i * 2 + 1] * qd[1];
            assert!((fd - jq).abs() < 1e-5 * (1.0 + fd.abs()), "{fd} vs {jq}");
        }
    }

    #[test]
    fn consistent_mode_law_has_the_requested_damping_ratio() {
        // Along the label, m_θ Δ̈ = f with τ = g f: check the coefficient of Δ̇ is 2ζ√(k m_θ).
        let s = ControllerSettings { inertia: ModeInertia::Consistent, ..ControllerSettings::default() };
        let g = [0.5, -1.2];
        let minv = [[2.0 / 12.0, -2.0 / 12.0], [-2.0 / 12.0, 8.0 / 12.0]];
        let minv_g = [minv[0][0] * g[0] + minv[0][1] * g[1], minv[1][0] * g[0] + minv[1][1] * g[1]];
        let m_theta = 1.0 / dot(&g, &minv_g);
        let m = [8.0, 2.0, 2.0, 2.0];
        let mut tau = [0.0; 2];
        // Velocity with label rate 1 and no deviation: f = −d_θ.
        let qd = [minv_g[0] * m_theta, minv_g[1] * m_theta];
        assert!((dot(&g, &qd) - 1.0).abs() < 1e-12);
        mode_torque(&s, 0.0, &g, &minv_g, &qd, &m, &mut tau);
        let f = tau[0] / g[0];
        assert!((f + 2.0 * 0.7 * m_theta.sqrt()).abs() < 1e-12);
        // Label acceleration from τ: gᵀM⁻¹τ = f / m_θ.
        let acc = dot(&minv_g, &tau);
        assert!((acc - f / m_theta).abs() < 1e-12);
    }
}
