//! `[controllers]`: the gains and the options of the mode-selection and energy-regulation
//! controllers (the laws themselves are `dynamics::control`).

use serde::{Deserialize, Serialize};

/// Which gradient of the label the mode controller uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum LabelGradient {
    /// ∂θ/∂q.
    #[default]
    Exact,
    /// ‖q − q_eq‖² ∂θ/∂q, as the paper's appendix writes it.
    Paper,
}

/// Whether M multiplies the mode controller's torque.
///
/// The default, `auto`, takes the paper's M in front for the two-joint θ law (the paper's
/// figures) and the consistent law on the sphere of modes (three or more joints, or a direction
/// target). Why: with M in front the label's closed loop sees J Jᵀ, which ignores the arm's
/// inertia, so a light distal link is driven as hard as a heavy proximal one and the gains would
/// need tuning arm by arm (on a three-joint arm the paper's form asked 900 N·m at the mode steps
/// and one step in five never settled); without it the label obeys m_θΔ̈ + d_θΔ̇ + k_θΔ = 0 with
/// m_θ from the arm's own metric (about r²/4 at metric distance r from q_eq), so the damping ratio
/// is ζ on any arm and the mode turns at ω_θ ≈ 2√k_θ / r.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum ModeInertia {
    /// `paper` for the two-joint θ law, `consistent` on the sphere of modes (default).
    #[default]
    Auto,
    /// τ_θ = M g f, as in the paper.
    Paper,
    /// τ_θ = g f: the closed-loop damping ratio is ζ.
    Consistent,
}

/// How the mode controller is switched on at the ε-ball.
///
/// The label's gradient grows like 1/‖q − q_eq‖ towards q_eq, so at the ball's edge the full law
/// is at its stiffest; switching it on there in one step (the paper's rule) kicks the arm each time
/// it leaves the ball with a mode error, which shows as torque spikes after every mode step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Blend {
    /// τ_θ scaled by the C¹ smoothstep w(r) = 3x² − 2x³, x = (r − ε)/ε clamped to [0, 1], with
    /// r = ‖q − q_eq‖: off inside the ball, full from 2ε on, no step in the torque (default).
    #[default]
    Smooth,
    /// The paper's hard switch: off for r ≤ ε, full for r > ε.
    Hard,
}

/// The energy regulation law.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EnergyLaw {
    /// τ_E = β_E M (E_d − E) q̇: tangent to the motion, mode-compatible.
    Energy,
    /// τ_nD = β_nD (E_d − E) q̇.
    NegativeDamping,
}

/// `[controllers]`: gains shared by the scenarios. The gains a design leaves out (k_θ, ε, β_E,
/// β_nD) are derived from the arm when the design is loaded ([`ControllerSettings::derive_from_arm`]);
/// until then they hold the paper's values.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(from = "ControllerFile")]
pub struct ControllerSettings {
    /// Mode stiffness k_θ.
    pub k_theta: f64,
    /// Damping ratio ζ of the mode controller.
    pub zeta: f64,
    /// Radius of the ball around q_eq (joint angles, rad) where the mode controller is off.
    pub epsilon: f64,
    /// Label gradient: `exact` or `paper`.
    pub gradient: LabelGradient,
    /// M in front of the mode torque: `auto` (default), `paper` or `consistent`.
    pub inertia: ModeInertia,
    /// `smooth` (default): the mode torque fades in between ε and 2ε; `hard`: the paper's switch
    /// at ε.
    pub blend: Blend,
    /// Gain β_E of τ_E (1/(J·s)).
    pub beta_e: f64,
    /// Gain β_nD of τ_nD (N·m·s/(rad·J)).
    pub beta_nd: f64,
    /// The largest torque each joint's actuator gives, N·m (one entry per joint; none: no limit).
    /// The controllers saturate within it keeping their laws' directions (see
    /// `dynamics::control::saturate`); the design refuses a limit that cannot hold the arm
    /// against gravity at q_eq.
    pub max_torque: Option<Vec<f64>>,
    /// The motors' constants k_m, N·m/√W per joint (none: 1 N·m/√W each), for the copper losses
    /// Σ τᵢ²/k_m,ᵢ² that the savings against the arm without springs report. With equal constants
    /// the fraction saved does not depend on their value.
    pub motor_constant: Option<Vec<f64>>,
    /// Which gains the design left out, so that they are (or, before
    /// [`ControllerSettings::derive_from_arm`], will be) derived from the arm; not a key of the
    /// file.
    #[serde(skip)]
    pub from_arm: FromArm,
    /// What the derived gains were computed from (None until derived, or when nothing was).
    #[serde(skip)]
    pub basis: Option<GainBasis>,
}

/// Which of the gains come from the arm rather than from the design (see
/// [`ControllerSettings::derive_from_arm`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct FromArm {
    /// k_θ.
    pub k_theta: bool,
    /// ε (and with it the blend's shell ε to 2ε).
    pub epsilon: bool,
    /// β_E.
    pub beta_e: bool,
    /// β_nD.
    pub beta_nd: bool,
}

impl FromArm {
    /// Every gain from the arm: what a design without them gets.
    pub const ALL: FromArm = FromArm { k_theta: true, epsilon: true, beta_e: true, beta_nd: true };

    /// Whether any gain is to come from the arm.
    pub fn any(&self) -> bool {
        self.k_theta || self.epsilon || self.beta_e || self.beta_nd
    }

    /// The keys of the gains from the arm, in table order.
    pub fn keys(&self) -> Vec<&'static str> {
        [("k_theta", self.k_theta), ("epsilon", self.epsilon), ("beta_e", self.beta_e), ("beta_nd", self.beta_nd)]
            .into_iter()
            .filter_map(|(k, on)| on.then_some(k))
            .collect()
    }
}

/// The figures of the arm and of its task that the derived gains come from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GainBasis {
    /// The energy E the gains are sized for, J: the largest energy a switch or swing-up scenario
    /// names (defaults included), else the largest release energy.
    pub energy_j: f64,
    /// ω, rad/s (`[fit] frequency`).
    pub omega: f64,
    /// r_E = √(2E)/ω, √(kg·m²)·rad: the metric amplitude of a swing at E under ½ω²r².
    pub amplitude: f64,
    /// Smallest and largest eigenvalue of M(q_eq), kg·m².
    pub eig_min: f64,
    /// Largest eigenvalue of M(q_eq), kg·m².
    pub eig_max: f64,
    /// Whether the actuators' limits lowered k_θ below E/2 (see
    /// [`ControllerSettings::derive_from_arm`]).
    pub torque_limited: bool,
    /// Whether the mode law is the paper's form with M in front (the two-joint θ law), for which
    /// k_θ is divided by tr M/n.
    pub paper_form: bool,
}

/// The paper's gains (section V), what a design that sets none gets where nothing can be derived.
const PAPER: (f64, f64, f64, f64) = (1.0, 0.1, 0.13, 0.4);

/// `[controllers]` as written: the gains the design leaves out are `None`.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct ControllerFile {
    k_theta: Option<f64>,
    zeta: Option<f64>,
    epsilon: Option<f64>,
    gradient: LabelGradient,
    inertia: ModeInertia,
    blend: Blend,
    beta_e: Option<f64>,
    beta_nd: Option<f64>,
    max_torque: Option<Vec<f64>>,
    motor_constant: Option<Vec<f64>>,
}

impl From<ControllerFile> for ControllerSettings {
    fn from(f: ControllerFile) -> Self {
        ControllerSettings {
            k_theta: f.k_theta.unwrap_or(PAPER.0),
            zeta: f.zeta.unwrap_or(0.7),
            epsilon: f.epsilon.unwrap_or(PAPER.1),
            gradient: f.gradient,
            inertia: f.inertia,
            blend: f.blend,
            beta_e: f.beta_e.unwrap_or(PAPER.2),
            beta_nd: f.beta_nd.unwrap_or(PAPER.3),
            max_torque: f.max_torque,
            motor_constant: f.motor_constant,
            from_arm: FromArm {
                k_theta: f.k_theta.is_none(),
                epsilon: f.epsilon.is_none(),
                beta_e: f.beta_e.is_none(),
                beta_nd: f.beta_nd.is_none(),
            },
            basis: None,
        }
    }
}

impl Default for ControllerSettings {
    /// The paper's gains, every one marked to be derived from the arm when a design is loaded
    /// (a design without `[controllers]` gets this).
    fn default() -> Self {
        ControllerFile::default().into()
    }
}

/// The mode error at which the derived k_θ asks at most the actuators' limits at the swing's
/// amplitude: the paper's mode step, π/6.
const LIMIT_ERROR: f64 = std::f64::consts::FRAC_PI_6;

/// The arm at q_eq and its task, as [`ControllerSettings::derive_from_arm`] reads them.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmScale {
    /// M(q_eq), row-major n × n, kg·m².
    pub mass: Vec<f64>,
    /// ω, rad/s.
    pub omega: f64,
    /// The energy the controllers work at, J (None: no scenario names one).
    pub energy: Option<f64>,
    /// Whether the mode law is the two-joint θ law in the paper's form (M in front).
    pub paper_form: bool,
}

impl ControllerSettings {
    /// Fills in the gains the design left out ([`FromArm`]) from the arm and its task; the gains
    /// it set are kept as they are. The reasoning (`docs/simulation.md`, "Gains from the arm"):
    /// with r_E = √(2E)/ω the metric amplitude of a swing at the scenarios' energy E,
    ///
    /// * k_θ = E/2 on the sphere of modes: the mode law's potential ½k_θΔ² is E/4 at a one-radian
    ///   error, and with the label's inertia m_θ ≈ r²/4 the mode turns at ω_θ = 2√k_θ/r = ω at the
    ///   swing's amplitude, whatever the arm's masses; lowered, with `max_torque`, until a mode
    ///   error of π/6 at the amplitude asks at most each joint's limit (|τᵢ| ≤ √Mᵢᵢ·k_θΔ·2/r_E),
    ///   so the law runs unsaturated over the outer swing and saturation (which keeps its
    ///   direction) is left to the inner one. For the paper's two-joint θ law, with M in front,
    ///   the label's loop sees the covector's Euclidean length instead of its metric one, on
    ///   average tr M/n times larger, so k_θ is divided by tr M/n.
    /// * ε = r_E/(4√λ_max): the blend's full weight (2ε) is reached at half the smallest
    ///   joint-space amplitude of the swing (the heaviest direction, r_E/√λ_max).
    /// * β_E = ω/(πE): the energy loop dE/dt ≈ β_E·E·(E_d − E) then closes in half a period
    ///   (its time constant 1/(β_E·E) = π/ω).
    /// * β_nD = β_E·n/tr(M⁻¹): the negative-damping law's power β_nD·ΔE·|q̇|² matched to τ_E's
    ///   β_E·ΔE·q̇ᵀMq̇ on average over the directions of a swing (|q̇|²/q̇ᵀMq̇ averages tr(M⁻¹)/n).
    ///
    /// On the paper's double pendulum (10 J, ω = 4 rad/s, no limit) this gives k_θ = 1.00,
    /// ε = 0.095 rad, β_E = 0.127 and β_nD = 0.31: the paper's hand-tuned 1, 0.1, 0.13 and 0.4.
    /// Without an energy (no scenario names one) the paper's values stay.
    pub fn derive_from_arm(&mut self, arm: &ArmScale) {
        let n = (arm.mass.len() as f64).sqrt().round() as usize;
        let Some(energy) = arm.energy.filter(|e| e.is_finite() && *e > 0.0) else { return };
        if !self.from_arm.any() || n == 0 || n * n != arm.mass.len() || !(arm.omega.is_finite() && arm.omega > 0.0) {
            return;
        }
        let m = nalgebra::DMatrix::from_row_slice(n, n, &arm.mass);
        let eig = m.clone().symmetric_eigen().eigenvalues;
        let (eig_min, eig_max) = eig.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &l| (a.min(l), b.max(l)));
        let Some(minv) = m.clone().try_inverse() else { return };
        if !(eig_min > 0.0 && eig_min.is_finite() && eig_max.is_finite()) {
            return;
        }
        let mean_mass = m.trace() / n as f64;
        let harmonic_mass = n as f64 / minv.trace();
        let amplitude = (2.0 * energy).sqrt() / arm.omega;
        let mut k = energy / 2.0;
        let mut torque_limited = false;
        if let Some(max) = self.max_torque.as_ref().filter(|m| m.len() == n) {
            let cap = (0..n)
                .map(|i| max[i] * amplitude / (2.0 * m[(i, i)].sqrt() * LIMIT_ERROR))
                .fold(f64::INFINITY, f64::min);
            if cap < k {
                k = cap;
                torque_limited = true;
            }
        }
        if arm.paper_form {
            k /= mean_mass;
        }
        let beta_e = arm.omega / (std::f64::consts::PI * energy);
        if self.from_arm.k_theta {
            self.k_theta = k;
        }
        if self.from_arm.epsilon {
            self.epsilon = amplitude / (4.0 * eig_max.sqrt());
        }
        if self.from_arm.beta_e {
            self.beta_e = beta_e;
        }
        if self.from_arm.beta_nd {
            self.beta_nd = beta_e * harmonic_mass;
        }
        self.basis = Some(GainBasis {
            energy_j: energy,
            omega: arm.omega,
            amplitude,
            eig_min,
            eig_max,
            torque_limited,
            paper_form: arm.paper_form,
        });
    }

    /// The gains in force, one line each source named: what `simulate` prints.
    pub fn gains_summary(&self) -> String {
        let from = |on: bool| if on && self.basis.is_some() { " (from the arm)" } else { "" };
        let mut s = format!(
            "gains: k_θ = {:.4} N·m/rad{}, ζ = {}, ε = {:.4} rad{}, β_E = {:.4} 1/(J·s){}, β_nD = {:.4}{}",
            self.k_theta,
            from(self.from_arm.k_theta),
            self.zeta,
            self.epsilon,
            from(self.from_arm.epsilon),
            self.beta_e,
            from(self.from_arm.beta_e),
            self.beta_nd,
            from(self.from_arm.beta_nd)
        );
        if let Some(b) = self.basis.filter(|_| self.from_arm.any()) {
            s.push_str(&format!(
                "; sized for E = {} J at ω = {} rad/s (swing amplitude r_E = {:.4} √(kg·m²)·rad, M(q_eq) eigenvalues {:.4}…{:.4} kg·m²{})",
                b.energy_j,
                b.omega,
                b.amplitude,
                b.eig_min,
                b.eig_max,
                if b.torque_limited { "; k_θ lowered to fit max_torque" } else { "" }
            ));
        }
        s
    }

    /// Checks the settings, naming the bad field.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let nonneg = |v: f64| v.is_finite() && v >= 0.0;
        for (name, v) in [
            ("k_theta", self.k_theta),
            ("zeta", self.zeta),
            ("epsilon", self.epsilon),
            ("beta_e", self.beta_e),
            ("beta_nd", self.beta_nd),
        ] {
            if !nonneg(v) {
                return Err((format!("controllers.{name}"), format!("must be a finite number ≥ 0, got {v}")));
            }
        }
        for (i, &v) in self.max_torque.iter().flatten().enumerate() {
            if !(v.is_finite() && v > 0.0) {
                return Err((
                    format!("controllers.max_torque[{i}]"),
                    format!("must be a finite torque > 0 N·m, got {v}"),
                ));
            }
        }
        for (i, &v) in self.motor_constant.iter().flatten().enumerate() {
            if !(v.is_finite() && v > 0.0) {
                return Err((
                    format!("controllers.motor_constant[{i}]"),
                    format!("must be a finite motor constant > 0 N·m/√W, got {v}"),
                ));
            }
        }
        Ok(())
    }

    /// k_m per joint for an arm of `n` joints: `motor_constant`, or 1 N·m/√W each (also when the
    /// list has the wrong length, which [`ControllerSettings::check_max_torque`] refuses first).
    pub fn motor_constants(&self, n: usize) -> Vec<f64> {
        match &self.motor_constant {
            Some(k) if k.len() == n => k.clone(),
            _ => vec![1.0; n],
        }
    }

    /// Checks `max_torque` against the arm: one entry per joint, each at least the torque that
    /// holds the arm against gravity at q_eq (`holding`, N·m per joint: the actuators hold it
    /// there while the springs are fitted and trimmed, and a limit below it could not).
    pub fn check_max_torque(&self, holding: &[f64]) -> Result<(), (String, String)> {
        let n = holding.len();
        if let Some(k) = &self.motor_constant
            && k.len() != n
        {
            return Err((
                "controllers.motor_constant".into(),
                format!("has {} entries but the robot has {n} joints (one constant per joint, N·m/√W)", k.len()),
            ));
        }
        let Some(max) = &self.max_torque else { return Ok(()) };
        if max.len() != n {
            return Err((
                "controllers.max_torque".into(),
                format!("has {} entries but the robot has {n} joints (one limit per joint, N·m)", max.len()),
            ));
        }
        let needed = holding.iter().map(|g| format!("{:.3}", g.abs())).collect::<Vec<_>>().join(", ");
        for i in 0..n {
            if max[i] < holding[i].abs() {
                return Err((
                    format!("controllers.max_torque[{i}]"),
                    format!(
                        "{} N·m cannot hold the arm against gravity at q_eq: joint {} needs {:.3} N·m (all joints: [{needed}] N·m)",
                        max[i],
                        i + 1,
                        holding[i].abs()
                    ),
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The paper's double pendulum at q_eq = (0, π/2): M = [[8, 2], [2, 2]] kg·m².
    fn paper_arm(energy: f64) -> ArmScale {
        ArmScale { mass: vec![8.0, 2.0, 2.0, 2.0], omega: 4.0, energy: Some(energy), paper_form: true }
    }

    #[test]
    fn on_the_papers_arm_the_derived_gains_are_the_papers() {
        let mut c: ControllerSettings = toml::from_str("").unwrap();
        assert_eq!(c.from_arm, FromArm::ALL);
        c.derive_from_arm(&paper_arm(10.0));
        // k_θ = (E/2)/(tr M/n) = 5/5; ε = r_E/(4√λ_max) with r_E = √20/4; β_E = ω/(πE);
        // β_nD = β_E·n/tr(M⁻¹) = β_E·2.4.
        assert!((c.k_theta - 1.0).abs() < 1e-12, "{c:?}");
        let eps = 20f64.sqrt() / 4.0 / (4.0 * (5.0 + 13f64.sqrt()).sqrt());
        assert!((c.epsilon - eps).abs() < 1e-12 && (c.epsilon - 0.0953).abs() < 1e-4, "{c:?}");
        assert!((c.beta_e - 4.0 / (std::f64::consts::PI * 10.0)).abs() < 1e-12 && (c.beta_e - 0.13).abs() < 0.005);
        assert!((c.beta_nd - 2.4 * c.beta_e).abs() < 1e-12, "{c:?}");
        let b = c.basis.unwrap();
        assert!(!b.torque_limited && b.paper_form && (b.amplitude - 20f64.sqrt() / 4.0).abs() < 1e-12);
        assert!(c.gains_summary().contains("k_θ = 1.0000 N·m/rad (from the arm)"), "{}", c.gains_summary());
    }

    #[test]
    fn gains_the_design_sets_are_kept_and_limits_lower_k_theta() {
        let mut c: ControllerSettings = toml::from_str("k_theta = 2.5\nbeta_e = 0.2").unwrap();
        c.derive_from_arm(&paper_arm(10.0));
        assert_eq!((c.k_theta, c.beta_e), (2.5, 0.2));
        assert!(c.from_arm.epsilon && c.from_arm.beta_nd && (c.epsilon - 0.0953).abs() < 1e-4);
        assert_eq!(c.from_arm.keys(), ["epsilon", "beta_nd"]);
        // Everything set: nothing derived, the summary says so by naming no source.
        let mut all: ControllerSettings =
            toml::from_str("k_theta = 1.0\nepsilon = 0.1\nbeta_e = 0.13\nbeta_nd = 0.4").unwrap();
        let before = all.clone();
        all.derive_from_arm(&paper_arm(10.0));
        assert_eq!(all, before);
        assert!(!all.gains_summary().contains("from the arm"));
        // ±10 N·m: a π/6 error at the amplitude may ask at most 10 N·m at joint 1 (√M₁₁ = √8),
        // so k_θ (before the paper form's 1/(tr M/n)) is 10·r_E/(2√8·π/6).
        let mut c: ControllerSettings = toml::from_str("max_torque = [10.0, 10.0]").unwrap();
        c.derive_from_arm(&paper_arm(10.0));
        let cap = 10.0 * (20f64.sqrt() / 4.0) / (2.0 * 8f64.sqrt() * std::f64::consts::FRAC_PI_6);
        assert!((c.k_theta - cap / 5.0).abs() < 1e-12 && c.basis.unwrap().torque_limited, "{c:?}");
        // Without an energy to size them for, the paper's values stay.
        let mut c = ControllerSettings::default();
        c.derive_from_arm(&ArmScale { energy: None, ..paper_arm(10.0) });
        assert_eq!((c.k_theta, c.epsilon, c.beta_e, c.beta_nd), (1.0, 0.1, 0.13, 0.4));
        assert!(c.basis.is_none());
    }
}
