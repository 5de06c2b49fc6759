//! `[sweep]`: what a sensitivity sweep runs (parasitic levels, tolerance levels, builds).

use serde::{Deserialize, Serialize};

use super::tolerance::Distribution;

/// `[sweep]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SweepSettings {
    /// The scenario run for every item (a run with both controllers, e.g. a swing-up from E_d to
    /// E_d without damping; its first run is used).
    pub scenario: String,
    /// Parasitic scales ε.
    pub epsilons: Vec<f64>,
    /// Monte Carlo builds per tolerance level.
    pub builds: usize,
    /// Seed of the builds.
    pub seed: u64,
    /// `uniform` or `normal`.
    pub distribution: Distribution,
    /// Tolerance levels applied to every element (fractions); empty: each element's catalogue
    /// tolerance.
    pub tolerances: Vec<f64>,
    /// Held-out geodesics per build (from the build's own equilibrium). The default is the
    /// as-built figures' (`asbuilt::DIRECTIONS`, whose resolution is bounded there), so a tuned
    /// build's residual is the one `tune` has already computed.
    pub evaluation_directions: usize,
    /// Samples per geodesic per build.
    pub evaluation_samples: usize,
    /// Also run every build tuned as `springfit tune` would tune it (designs with trim springs
    /// or adjustable elements). Tuning costs one residual evaluation per adjustable offset per
    /// Gauss–Newton step, so a design with hundreds of adjustable elements may turn it off.
    pub tune_builds: bool,
    /// How many builds of each level (the first, by build number) are tuned when `tune_builds`
    /// is on. A tune and its closed-loop run cost about twice the build itself; the tuned figures
    /// are percentiles, and 72 builds are the fewest whose p95 has a bounded 95 % interval.
    pub tuned_builds: usize,
    /// RK4 steps per second of the sweep's closed-loop runs (Hz); `None`: half of
    /// `[simulate] rate`. A sweep runs hundreds of 20-second loops whose fluxes converge at
    /// fourth order in the step: on the default design, 500 Hz instead of 1 kHz moves every
    /// table entry by less than 5e-6 relative (the tuned builds' actuator share, a few tenths of
    /// a per cent, by 5e-4 relative) and halves the loops' cost.
    pub rate: Option<f64>,
}

impl Default for SweepSettings {
    fn default() -> Self {
        SweepSettings {
            scenario: "sensitivity".into(),
            epsilons: vec![0.0, 0.01, 0.05, 0.1, 0.5, 1.0],
            builds: 200,
            seed: 1,
            distribution: Distribution::Uniform,
            tolerances: Vec::new(),
            evaluation_directions: 60,
            evaluation_samples: 50,
            tune_builds: true,
            tuned_builds: 72,
            rate: None,
        }
    }
}

impl SweepSettings {
    /// Checks the settings, naming the bad field.
    pub fn validate(&self) -> std::result::Result<(), (String, String)> {
        for (i, e) in self.epsilons.iter().enumerate() {
            if !(e.is_finite() && *e >= 0.0) {
                return Err((format!("sweep.epsilons[{i}]"), format!("must be ≥ 0, got {e}")));
            }
        }
        for (i, t) in self.tolerances.iter().enumerate() {
            if !(t.is_finite() && (0.0..1.0).contains(t)) {
                return Err((format!("sweep.tolerances[{i}]"), format!("must be a fraction in [0, 1), got {t}")));
            }
        }
        if self.evaluation_directions < 4 || self.evaluation_samples < 2 {
            return Err(("sweep.evaluation_directions".into(), "needs at least 4 directions of 2 samples".into()));
        }
        if let Some(r) = self.rate
            && !(r.is_finite() && (10.0..=1e6).contains(&r))
        {
            return Err(("sweep.rate".into(), format!("must be 10 to 1e6 Hz, got {r}")));
        }
        if self.builds > 1_000_000 {
            return Err(("sweep.builds".into(), "at most 1 000 000".into()));
        }
        Ok(())
    }
}
