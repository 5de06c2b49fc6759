//! `[identify]`: how `springfit identify` reads a built arm's spring rates, damping and friction
//! from logged motion, and what its excitation plan (`identify --plan`) may propose.

use serde::{Deserialize, Serialize};

/// What to assume about the trim springs' rates while the arm is logged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum TrimRates {
    /// As the bill of materials gives them: the builder set them and trusts the setting.
    Known,
    /// Estimated like every other element's (the default): a trim leaf's rate goes with the cube
    /// of its thickness, so a set rate is off by a few per cent, and taking it as exact puts its
    /// torque into every other estimate.
    #[default]
    Estimated,
}

/// `[identify]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct IdentifySettings {
    /// Cut-off of the zero-phase low-pass applied to both sides of the regression, Hz (default:
    /// six times the design frequency, 6 ω / 2π).
    pub cutoff_hz: Option<f64>,
    /// Cut-off of the zero-phase low-pass that smooths the encoder angles before the velocities
    /// are taken, Hz: far above the motion, below the encoder's quantisation steps.
    pub smoothing_hz: f64,
    /// Estimate a viscous damping D per joint.
    pub damping: bool,
    /// Estimate a Coulomb friction f_c per joint.
    pub friction: bool,
    /// `estimated` (every spring an unknown, the default) or `known` (the bill's trim rates are
    /// the ones set).
    pub trims: TrimRates,
    /// An element's rate counts as identified when the standard error of its δ is at most this
    /// fraction of its rate.
    pub max_standard_error: f64,
    /// How far a log may reach beyond the design's region, as a fraction of its extent (the
    /// region's arc length for a ball, each side of a box) before it is refused.
    pub region_margin: f64,
    /// The plan: viscous damping per joint its simulated releases assume, N·m·s/rad (what the
    /// built arm is expected to have: damping shortens a swing, so it changes what a release
    /// tells).
    pub expected_damping: f64,
    /// The plan: Coulomb friction per joint its simulated releases assume, N·m.
    pub expected_friction: f64,
    /// The plan: encoder resolution the predicted standard errors assume, bits per turn.
    pub encoder_bits: u32,
    /// The plan: rms noise of an encoder reading before quantisation, in counts.
    pub encoder_noise_counts: f64,
    /// The plan: sampling rate of the logs it proposes, Hz.
    pub rate_hz: f64,
    /// The plan: log length of one release, s.
    pub release_seconds: f64,
    /// The plan: longest total log it may propose, s.
    pub max_log_seconds: f64,
    /// The plan: candidate release directions (metric unit vectors at q_eq).
    pub directions: usize,
    /// The plan: candidate release distances, as fractions of the region's extent along each
    /// direction.
    pub radii: Vec<f64>,
    /// The plan: seed of the simulated encoder noise behind its predicted standard errors.
    pub seed: u64,
}

impl Default for IdentifySettings {
    fn default() -> Self {
        IdentifySettings {
            cutoff_hz: None,
            smoothing_hz: 50.0,
            damping: true,
            friction: true,
            trims: TrimRates::Estimated,
            max_standard_error: 0.005,
            region_margin: 0.05,
            expected_damping: 0.0,
            expected_friction: 0.0,
            encoder_bits: 17,
            encoder_noise_counts: 1.0,
            rate_hz: 1000.0,
            release_seconds: 10.0,
            max_log_seconds: 120.0,
            directions: 12,
            radii: vec![0.5, 0.7, 0.9],
            seed: 1,
        }
    }
}

impl IdentifySettings {
    /// The regression's cut-off for a design of frequency `omega` (rad/s), Hz.
    pub fn cutoff(&self, omega: f64) -> f64 {
        self.cutoff_hz.unwrap_or(6.0 * omega / std::f64::consts::TAU)
    }

    /// Checks the settings, naming the bad field.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let positive = |v: f64, field: &str| -> Result<(), (String, String)> {
            if v.is_finite() && v > 0.0 { Ok(()) } else { Err((field.into(), format!("must be positive, got {v}"))) }
        };
        if let Some(c) = self.cutoff_hz {
            positive(c, "identify.cutoff_hz")?;
            if c >= self.smoothing_hz {
                return Err((
                    "identify.cutoff_hz".into(),
                    format!(
                        "must be below identify.smoothing_hz = {} (the encoder smoothing), got {c}",
                        self.smoothing_hz
                    ),
                ));
            }
        }
        positive(self.smoothing_hz, "identify.smoothing_hz")?;
        if !(self.max_standard_error.is_finite() && self.max_standard_error > 0.0 && self.max_standard_error < 1.0) {
            return Err((
                "identify.max_standard_error".into(),
                format!("must be a fraction of a rate in (0, 1), got {}", self.max_standard_error),
            ));
        }
        if !(self.region_margin.is_finite() && (0.0..=1.0).contains(&self.region_margin)) {
            return Err(("identify.region_margin".into(), format!("must be in [0, 1], got {}", self.region_margin)));
        }
        for (v, field) in [
            (self.expected_damping, "identify.expected_damping"),
            (self.expected_friction, "identify.expected_friction"),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err((field.into(), format!("must be ≥ 0, got {v}")));
            }
        }
        if !(8..=32).contains(&self.encoder_bits) {
            return Err(("identify.encoder_bits".into(), format!("must be 8 to 32 bits, got {}", self.encoder_bits)));
        }
        if !(self.encoder_noise_counts.is_finite() && self.encoder_noise_counts >= 0.0) {
            return Err((
                "identify.encoder_noise_counts".into(),
                format!("must be ≥ 0, got {}", self.encoder_noise_counts),
            ));
        }
        if !(self.rate_hz.is_finite() && (10.0..=1e5).contains(&self.rate_hz)) {
            return Err(("identify.rate_hz".into(), format!("must be 10 to 1e5 Hz, got {}", self.rate_hz)));
        }
        if self.smoothing_hz >= 0.5 * self.rate_hz {
            return Err((
                "identify.smoothing_hz".into(),
                format!("must be below half of identify.rate_hz = {} (the Nyquist frequency)", self.rate_hz),
            ));
        }
        positive(self.release_seconds, "identify.release_seconds")?;
        if !(self.max_log_seconds.is_finite() && self.max_log_seconds >= self.release_seconds) {
            return Err((
                "identify.max_log_seconds".into(),
                format!("must be at least identify.release_seconds = {}", self.release_seconds),
            ));
        }
        if self.max_log_seconds > 3600.0 {
            return Err(("identify.max_log_seconds".into(), "at most 3600 s (an hour of swinging)".into()));
        }
        if !(1..=720).contains(&self.directions) {
            return Err(("identify.directions".into(), format!("must be 1 to 720, got {}", self.directions)));
        }
        if self.radii.is_empty() {
            return Err(("identify.radii".into(), "needs at least one release distance".into()));
        }
        for (i, r) in self.radii.iter().enumerate() {
            if !(r.is_finite() && *r > 0.0 && *r <= 1.0) {
                return Err((format!("identify.radii[{i}]"), format!("must be a fraction in (0, 1], got {r}")));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_are_valid_and_bad_values_name_their_field() {
        let s = IdentifySettings::default();
        assert!(s.validate().is_ok());
        // 6 ω / 2π for the paper's ω = 4 rad/s.
        assert!((s.cutoff(4.0) - 3.8197).abs() < 1e-4);
        let bad = |s: IdentifySettings| s.validate().unwrap_err().0;
        assert_eq!(bad(IdentifySettings { cutoff_hz: Some(80.0), ..s.clone() }), "identify.cutoff_hz");
        assert_eq!(bad(IdentifySettings { max_standard_error: 0.0, ..s.clone() }), "identify.max_standard_error");
        assert_eq!(bad(IdentifySettings { radii: vec![0.5, 1.5], ..s.clone() }), "identify.radii[1]");
        assert_eq!(bad(IdentifySettings { rate_hz: 80.0, ..s.clone() }), "identify.smoothing_hz");
        assert_eq!(bad(IdentifySettings { expected_friction: -0.1, ..s.clone() }), "identify.expected_friction");
        assert_eq!(bad(IdentifySettings { max_log_seconds: 5.0, ..s }), "identify.max_log_seconds");
    }
}
