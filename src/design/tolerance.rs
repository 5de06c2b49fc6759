//! Manufacturing tolerance: how far a built spring's rate may stray from the drawing, and how the
//! deviations are drawn.
//!
//! A build scales each stiffness, k_i → k_i (1 + δ_i), with δ_i independent, mean 0 and bounded by
//! the element's ± tolerance t_i. Two laws are offered, as stock springs are specified either way:
//! uniform in [−t, t], or normal with σ = t/3 clipped at ±t. The fit (to design for the build),
//! the as-built figures and the sweep all draw from these laws, so they share this module.

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// What a build's trims are set for once the arm is assembled and its rates measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum TrimRule {
    /// The trim rates (within their ranges) that make the tangentiality rows of a training fan
    /// from the build's equilibrium smallest in least squares: the residual over the whole
    /// region, near the equilibrium and far from it, which is what the residual angles judge.
    #[default]
    Residual,
    /// The trim rates that make ∇²U = w² M at the build's equilibrium (w² free): every small
    /// oscillation at one frequency, whatever happens farther out.
    Hessian,
}

impl TrimRule {
    /// The name used in files.
    pub fn name(self) -> &'static str {
        match self {
            TrimRule::Residual => "residual",
            TrimRule::Hessian => "hessian",
        }
    }
}

/// How manufacturing deviations δ are drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Distribution {
    /// δ uniform in [−t, t].
    #[default]
    Uniform,
    /// δ normal with σ = t/3, clipped at ±t.
    Normal,
}

impl Distribution {
    /// The name used in files.
    pub fn name(self) -> &'static str {
        match self {
            Distribution::Uniform => "uniform",
            Distribution::Normal => "normal",
        }
    }

    /// One deviation δ/t in [−1, 1] drawn from `rng`.
    pub fn draw_unit(self, rng: &mut crate::numerics::rng::SplitMix64) -> f64 {
        match self {
            Distribution::Uniform => 2.0 * rng.uniform() - 1.0,
            Distribution::Normal => (rng.normal() / 3.0).clamp(-1.0, 1.0),
        }
    }

    /// Variance of δ for tolerance `t`: t²/3 for the uniform law. The normal law is N(0, σ²),
    /// σ = t/3, clipped at ±t (the 0.27 % of draws beyond ±3σ are set to ±t), whose variance is
    /// σ² (2Φ(3) − 1 − 6φ(3) + 18 (1 − Φ(3))) ≈ 0.99501 σ².
    pub fn variance(self, t: f64) -> f64 {
        match self {
            Distribution::Uniform => t * t / 3.0,
            Distribution::Normal => {
                // φ(3) = e^{-4.5}/√(2π); 2Φ(3) − 1 = erf(3/√2) = 0.997300203936740.
                let phi3 = (-4.5f64).exp() / (2.0 * std::f64::consts::PI).sqrt();
                let inside = 0.997_300_203_936_740;
                let s2 = (t / 3.0) * (t / 3.0);
                s2 * (inside - 6.0 * phi3 + 9.0 * (1.0 - inside))
            }
        }
    }
}

/// Which rate tolerance the fit designs for and the as-built figures assume.
///
/// In a design file: `tolerance = "none"` (the drawing only), `"catalogue"` (each family's
/// `tolerance`), `"parts"` (each chosen spring's EN 15800 tolerance), or a number (± fraction
/// for every element, e.g. `0.05`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum ToleranceSpec {
    /// Fit and report the drawing only.
    #[default]
    None,
    /// Each element's catalogue family tolerance.
    Catalogue,
    /// The same ± fraction for every element.
    Fraction(f64),
    /// The EN 15800 rate tolerance of the spring chosen for each element (`parts::fit_with_parts`
    /// sets it on the candidates and the bill); the catalogue's until the parts are chosen, and
    /// for an element no spring meets.
    Parts,
}

impl ToleranceSpec {
    /// The tolerance of an element whose catalogue family states `catalogue` (a ± fraction).
    pub fn for_element(self, catalogue: f64) -> f64 {
        match self {
            ToleranceSpec::None => 0.0,
            ToleranceSpec::Catalogue | ToleranceSpec::Parts => catalogue,
            ToleranceSpec::Fraction(t) => t,
        }
    }

    /// True for `"none"`.
    pub fn is_none(self) -> bool {
        matches!(self, ToleranceSpec::None)
    }

    /// Checks a number is a fraction in [0, 1).
    pub fn validate(self) -> Result<(), String> {
        match self {
            ToleranceSpec::Fraction(t) if !(t.is_finite() && (0.0..1.0).contains(&t)) => {
                Err(format!("must be \"none\", \"catalogue\", \"parts\" or a fraction in [0, 1), got {t}"))
            }
            _ => Ok(()),
        }
    }

    /// How it is written in files and reports: `none`, `catalogue`, `parts` or the fraction.
    pub fn label(self) -> String {
        match self {
            ToleranceSpec::None => "none".into(),
            ToleranceSpec::Catalogue => "catalogue".into(),
            ToleranceSpec::Parts => "parts".into(),
            ToleranceSpec::Fraction(t) => format!("±{}%", t * 100.0),
        }
    }
}

impl Serialize for ToleranceSpec {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            ToleranceSpec::None => s.serialize_str("none"),
            ToleranceSpec::Catalogue => s.serialize_str("catalogue"),
            ToleranceSpec::Parts => s.serialize_str("parts"),
            ToleranceSpec::Fraction(t) => s.serialize_f64(*t),
        }
    }
}

impl<'de> Deserialize<'de> for ToleranceSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Word(String),
            Number(f64),
        }
        match Raw::deserialize(d).map_err(|_| {
            serde::de::Error::custom("expected \"none\", \"catalogue\", \"parts\" or a ± fraction such as 0.05")
        })? {
            Raw::Number(t) => Ok(ToleranceSpec::Fraction(t)),
            Raw::Word(w) => match w.as_str() {
                "none" => Ok(ToleranceSpec::None),
                "catalogue" | "catalog" => Ok(ToleranceSpec::Catalogue),
                "parts" => Ok(ToleranceSpec::Parts),
                other => Err(serde::de::Error::custom(format!(
                    "unknown tolerance \"{other}\", expected \"none\", \"catalogue\", \"parts\" or a ± fraction such as 0.05"
                ))),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numerics::rng::SplitMix64;

    /// The variances used by the tolerance-aware fit match the sample variance of the draws.
    #[test]
    fn variance_matches_draws() {
        for dist in [Distribution::Uniform, Distribution::Normal] {
            let t = 0.05;
            let mut rng = SplitMix64::stream(7, 3);
            let n = 400_000;
            let (mut s1, mut s2) = (0.0, 0.0);
            for _ in 0..n {
                let d = t * dist.draw_unit(&mut rng);
                assert!(d.abs() <= t);
                s1 += d;
                s2 += d * d;
            }
            let mean = s1 / n as f64;
            let var = s2 / n as f64 - mean * mean;
            let want = dist.variance(t);
            assert!(mean.abs() < 5.0 * (want / n as f64).sqrt(), "{dist:?} mean {mean}");
            assert!((var / want - 1.0).abs() < 0.01, "{dist:?}: sample {var:e} vs {want:e}");
        }
    }

    #[test]
    fn parses_words_and_numbers() {
        #[derive(Deserialize)]
        struct F {
            tolerance: ToleranceSpec,
        }
        let p = |s: &str| toml::from_str::<F>(s).map(|f| f.tolerance);
        assert_eq!(p("tolerance = \"none\"").unwrap(), ToleranceSpec::None);
        assert_eq!(p("tolerance = \"catalogue\"").unwrap(), ToleranceSpec::Catalogue);
        assert_eq!(p("tolerance = 0.05").unwrap(), ToleranceSpec::Fraction(0.05));
        assert!(p("tolerance = \"loose\"").unwrap_err().to_string().contains("unknown tolerance"));
        assert!(ToleranceSpec::Fraction(1.5).validate().is_err());
    }
}
