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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum ModeInertia {
    /// τ_θ = M g f, as in the paper.
    #[default]
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
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
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
    /// M in front of the mode torque: `paper` or `consistent`.
    pub inertia: ModeInertia,
    /// `smooth` (default): the mode torque fades in between ε and 2ε; `hard`: the paper's switch
    /// at ε.
    pub blend: Blend,
    /// Gain β_E of τ_E (1/(J·s)).
    pub beta_e: f64,
    /// Gain β_nD of τ_nD (N·m·s/(rad·J)).
    pub beta_nd: f64,
}

impl Default for ControllerSettings {
    fn default() -> Self {
        ControllerSettings {
            k_theta: 1.0,
            zeta: 0.7,
            epsilon: 0.1,
            gradient: LabelGradient::Exact,
            inertia: ModeInertia::Paper,
            blend: Blend::Smooth,
            beta_e: 0.13,
            beta_nd: 0.4,
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
        Ok(())
    }
}
