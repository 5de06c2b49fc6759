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

/// `[controllers]`: gains shared by the scenarios (the paper's settings by default).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
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
}

impl Default for ControllerSettings {
    fn default() -> Self {
        ControllerSettings {
            k_theta: 1.0,
            zeta: 0.7,
            epsilon: 0.1,
            gradient: LabelGradient::Exact,
            inertia: ModeInertia::Auto,
            blend: Blend::Smooth,
            beta_e: 0.13,
            beta_nd: 0.4,
            max_torque: None,
            motor_constant: None,
        }
    }
}

impl ControllerSettings {
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
