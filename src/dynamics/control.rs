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

use crate::design::controllers::{Blend, ControllerSettings, EnergyLaw, ModeInertia};

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
        ModeInertia::Paper => {
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

/// Dot product of two slices.
#[inline]
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
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
