//! Residual angles: how far a potential is from making every geodesic a strict mode.
//!
//! For a sample (γ, γ̇) of a geodesic from q_eq, v₁ = M⁻¹ ∂U/∂q (U = U_e + U_g) must be tangent
//! to γ̇. The *residual angle* is the angle between v₁ and γ̇ as coordinate vectors: signed for
//! two joints (positive when v₁ is turned counter-clockwise from γ̇, as the paper's histogram),
//! unsigned for three or more. It is scale-free, so designs of any stiffness compare directly.
//! A potential that decreases outward gives angles near ±180°; a vanishing gradient counts as
//! 90°.

use nalgebra::DVector;
use rayon::prelude::*;
use serde::Serialize;

use crate::error::Result;
use crate::geodesic::{Fan, Geodesic};
use crate::model::Chain;
use crate::potential::Potential;

/// One evaluated sample.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AngleSample {
    /// Index of the geodesic in its fan.
    pub direction: usize,
    /// Arc length from q_eq.
    pub s: f64,
    /// Configuration.
    pub q: Vec<f64>,
    /// Residual angle in degrees.
    pub angle_deg: f64,
}

/// Summary statistics of |angle|.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AngleStats {
    /// Median of |angle| in degrees.
    pub median_abs: f64,
    /// 95th percentile.
    pub p95_abs: f64,
    /// 99th percentile.
    pub p99_abs: f64,
    /// Largest.
    pub max_abs: f64,
    /// Number of samples.
    pub count: usize,
}

/// Statistics of the samples within one distance band from q_eq.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BandStats {
    /// Inner arc length (exclusive).
    pub from: f64,
    /// Outer arc length (inclusive).
    pub to: f64,
    /// Statistics of the band.
    pub stats: AngleStats,
}

/// The residual angle (degrees) between v₁ = M⁻¹ ∇U and the tangent `qd`.
pub fn residual_angle(chain: &Chain, q: &[f64], qd: &[f64], grad_total: &DVector<f64>) -> f64 {
    let qv = DVector::from_column_slice(q);
    let m = chain.mass_matrix(&qv);
    let v1 = match m.cholesky() {
        Some(c) => c.solve(grad_total),
        None => return f64::NAN,
    };
    angle_between(v1.as_slice(), qd)
}

/// Angle from `t` to `v` in degrees: signed in 2-D, unsigned otherwise; 90 if v = 0.
pub fn angle_between(v: &[f64], t: &[f64]) -> f64 {
    let dot: f64 = v.iter().zip(t).map(|(a, b)| a * b).sum();
    let nv = v.iter().map(|a| a * a).sum::<f64>().sqrt();
    let nt = t.iter().map(|a| a * a).sum::<f64>().sqrt();
    if nv == 0.0 || nt == 0.0 {
        return 90.0;
    }
    if v.len() == 2 {
        let cross = t[0] * v[1] - t[1] * v[0];
        cross.atan2(dot).to_degrees()
    } else {
        (dot / (nv * nt)).clamp(-1.0, 1.0).acos().to_degrees()
    }
}

/// ∂θ/∂v of [`angle_between`]`(v, t)` in rad per unit of v (zero where v or t is zero, and, in
/// more than two dimensions, where v ∥ t: the unsigned angle has a kink there and zero is its
/// smallest subgradient). Written as θ = atan2(p, d) with d = v·t̂ and p = the 2-D cross product
/// (signed) or |v − d t̂| (unsigned), so dθ = (d dp − p dd) / |v|², which stays finite at θ = 0
/// and π where the arccosine's derivative does not.
pub fn angle_gradient(v: &[f64], t: &[f64], out: &mut [f64]) {
    out.iter_mut().for_each(|o| *o = 0.0);
    let nt = t.iter().map(|a| a * a).sum::<f64>().sqrt();
    let nv2 = v.iter().map(|a| a * a).sum::<f64>();
    if nv2 == 0.0 || nt == 0.0 {
        return;
    }
    let d = v.iter().zip(t).map(|(a, b)| a * b).sum::<f64>() / nt;
    if v.len() == 2 {
        // p = (t₀ v₁ − t₁ v₀) / |t|: ∂p/∂v = (−t₁, t₀) / |t|, ∂d/∂v = t / |t|.
        let p = (t[0] * v[1] - t[1] * v[0]) / nt;
        out[0] = (d * -t[1] - p * t[0]) / (nt * nv2);
        out[1] = (d * t[0] - p * t[1]) / (nt * nv2);
    } else {
        let perp: Vec<f64> = v.iter().zip(t).map(|(a, b)| a - d * b / nt).collect();
        let p = perp.iter().map(|a| a * a).sum::<f64>().sqrt();
        for ((o, e), b) in out.iter_mut().zip(&perp).zip(t) {
            let e = if p > 0.0 { e / p } else { 0.0 };
            *o = (d * e - p * b / nt) / nv2;
        }
    }
}

/// Residual angles of `potential` (elastic part; gravity added from the chain) at every sample
/// of `fan`, in fan order. Runs in parallel; the result does not depend on the thread count.
pub fn fan_angles(chain: &Chain, fan: &Fan, potential: &dyn Potential) -> Result<Vec<AngleSample>> {
    Ok(fan_angles_and_descents(chain, fan, potential)?.0)
}

/// [`fan_angles`] and the number of samples where U = U_e + U_g decreases along the geodesic
/// (∇U·γ̇ < −10⁻¹² |∇U|: the monotonicity check), from the same gradients: the held-out fan of
/// seven joints has a million samples, and a second pass over them cost a third of the fit's
/// evaluation.
pub fn fan_angles_and_descents(
    chain: &Chain,
    fan: &Fan,
    potential: &dyn Potential,
) -> Result<(Vec<AngleSample>, usize)> {
    let per: Vec<Result<(Vec<AngleSample>, usize)>> =
        fan.geodesics.par_iter().enumerate().map(|(d, g)| geodesic_angles(chain, d, g, potential)).collect();
    let mut samples = Vec::with_capacity(fan.geodesics.iter().map(|g| g.len()).sum());
    let mut descents = 0;
    for p in per {
        let (s, d) = p?;
        samples.extend(s);
        descents += d;
    }
    Ok((samples, descents))
}

fn geodesic_angles(
    chain: &Chain,
    direction: usize,
    g: &Geodesic,
    potential: &dyn Potential,
) -> Result<(Vec<AngleSample>, usize)> {
    // Scratch space reused for every sample: this runs for every sample of every evaluation fan,
    // thousands of times in a tolerance sweep.
    let n = chain.dof();
    let mut ws = chain.workspace();
    let (mut grad, mut grav) = (vec![0.0; n], vec![0.0; n]);
    let mut descents = 0;
    let samples = (0..g.len())
        .map(|i| {
            let (angle_deg, descends) = sample_angle(chain, g, i, potential, &mut ws, &mut grad, &mut grav)?;
            descents += usize::from(descends);
            Ok(AngleSample { direction, s: g.s(i), q: g.q(i).to_vec(), angle_deg })
        })
        .collect::<Result<Vec<_>>>()?;
    Ok((samples, descents))
}

/// The residual angles alone (degrees, in fan order): what [`fan_angles`] computes, without a
/// sample record per angle (the as-built builds judge 200 fans by their statistics only).
pub fn fan_angle_values(chain: &Chain, fan: &Fan, potential: &dyn Potential) -> Result<Vec<f64>> {
    let per: Vec<Result<Vec<f64>>> = fan
        .geodesics
        .par_iter()
        .map(|g| {
            let n = chain.dof();
            let mut ws = chain.workspace();
            let (mut grad, mut grav) = (vec![0.0; n], vec![0.0; n]);
            (0..g.len()).map(|i| Ok(sample_angle(chain, g, i, potential, &mut ws, &mut grad, &mut grav)?.0)).collect()
        })
        .collect();
    Ok(per.into_iter().collect::<Result<Vec<_>>>()?.into_iter().flatten().collect())
}

/// The residual angle at sample i of a geodesic (scratch space passed in), and whether U
/// decreases along the geodesic there (∇U·γ̇ < −10⁻¹² |∇U|).
fn sample_angle(
    chain: &Chain,
    g: &Geodesic,
    i: usize,
    potential: &dyn Potential,
    ws: &mut crate::model::Workspace,
    grad: &mut [f64],
    grav: &mut [f64],
) -> Result<(f64, bool)> {
    let q = g.q(i);
    potential.gradient_into(q, grad)?;
    chain.gravity_gradient_into(q, grav);
    for (a, b) in grad.iter_mut().zip(grav.iter()) {
        *a += b;
    }
    let rate: f64 = grad.iter().zip(g.qd(i)).map(|(a, b)| a * b).sum();
    let descends = rate < -1e-12 * grad.iter().map(|a| a * a).sum::<f64>().sqrt();
    let angle = if chain.factor_mass(ws, q) {
        ws.solve(grad);
        angle_between(grad, g.qd(i))
    } else {
        f64::NAN
    };
    Ok((angle, descends))
}

/// [`stats`] of bare angles (degrees).
pub fn stats_of(angles: &[f64]) -> AngleStats {
    let mut a: Vec<f64> = angles.iter().map(|x| if x.is_nan() { 180.0 } else { x.abs() }).collect();
    a.sort_by(f64::total_cmp);
    AngleStats {
        median_abs: percentile(&a, 50.0),
        p95_abs: percentile(&a, 95.0),
        p99_abs: percentile(&a, 99.0),
        max_abs: a.last().copied().unwrap_or(f64::NAN),
        count: a.len(),
    }
}

/// A distribution-free confidence interval for the p-th percentile (p in %) of the distribution
/// `sorted` was drawn from: order statistics [x₍ᵣ₎, x₍ₛ₎] with r the largest and s the smallest
/// rank such that P(B < r) ≤ (1 − confidence)/2 and P(B ≥ s) ≤ (1 − confidence)/2, B ~
/// Binomial(n, p/100) the number of draws below the percentile; so the interval holds the true
/// percentile with probability at least `confidence` whatever the distribution. Ranks beyond the
/// sample (too few draws) give ±∞ ends.
pub fn percentile_interval(sorted: &[f64], p: f64, confidence: f64) -> [f64; 2] {
    let n = sorted.len();
    if n == 0 {
        return [f64::NAN, f64::NAN];
    }
    let q = p / 100.0;
    if !(q > 0.0 && q < 1.0) {
        return [sorted[0], sorted[n - 1]];
    }
    let tail = 0.5 * (1.0 - confidence);
    // pmf of Binomial(n, q) by number of draws below, in log space (n may be 10⁶).
    let (lq, lr) = (q.ln(), (1.0 - q).ln());
    let mut log_choose = 0.0f64;
    let mut pmf = Vec::with_capacity(n + 1);
    for i in 0..=n {
        if i > 0 {
            log_choose += ((n - i + 1) as f64).ln() - (i as f64).ln();
        }
        pmf.push((log_choose + i as f64 * lq + (n - i) as f64 * lr).exp());
    }
    // r: P(B < r) ≤ tail, the largest such r ≥ 1 (1-based rank); s: P(B ≥ s) ≤ tail, smallest.
    let mut below = 0.0;
    let mut r = 0;
    while r < n && below + pmf[r] <= tail {
        below += pmf[r];
        r += 1;
    }
    let mut above = 0.0;
    let mut s = n + 1;
    while s > 1 && above + pmf[s - 1] <= tail {
        above += pmf[s - 1];
        s -= 1;
    }
    let lo = if r == 0 { f64::NEG_INFINITY } else { sorted[r - 1] };
    let hi = if s > n { f64::INFINITY } else { sorted[s - 1] };
    [lo, hi]
}

/// Percentile (0–100) of sorted values by linear interpolation between order statistics.
pub fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let pos = (p / 100.0).clamp(0.0, 1.0) * (sorted.len() - 1) as f64;
    let lo = pos.floor() as usize;
    let hi = pos.ceil() as usize;
    sorted[lo] + (sorted[hi] - sorted[lo]) * (pos - lo as f64)
}

/// Statistics of |angle| over the samples (NaN angles count as 180°, the worst).
pub fn stats(samples: &[AngleSample]) -> AngleStats {
    stats_of(&samples.iter().map(|s| s.angle_deg).collect::<Vec<_>>())
}

/// Statistics by distance band: `bands` equal bands of arc length over (0, extent].
pub fn band_stats(samples: &[AngleSample], extent: f64, bands: usize) -> Vec<BandStats> {
    (0..bands)
        .map(|b| {
            let from = extent * b as f64 / bands as f64;
            let to = extent * (b + 1) as f64 / bands as f64;
            let inside: Vec<AngleSample> =
                samples.iter().filter(|s| s.s > from && (s.s <= to || (b + 1 == bands && s.s > to))).cloned().collect();
            BandStats { from, to, stats: stats(&inside) }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_are_signed_in_the_plane() {
        assert!((angle_between(&[0.0, 1.0], &[1.0, 0.0]) - 90.0).abs() < 1e-12);
        assert!((angle_between(&[1.0, -1.0], &[1.0, 0.0]) + 45.0).abs() < 1e-12);
        assert!((angle_between(&[2.0, 0.0], &[1.0, 0.0])).abs() < 1e-12);
        assert!((angle_between(&[-1.0, 0.0], &[1.0, 0.0]).abs() - 180.0).abs() < 1e-12);
        assert!((angle_between(&[0.0, 1.0, 0.0], &[0.0, 0.0, 3.0]) - 90.0).abs() < 1e-12);
        assert_eq!(angle_between(&[0.0, 0.0], &[1.0, 0.0]), 90.0);
    }

    #[test]
    fn angle_gradients_match_finite_differences() {
        // Signed in the plane, unsigned in three and six dimensions; near 0, near 180° and in between.
        let cases: [(&[f64], &[f64]); 6] = [
            (&[0.3, 1.1], &[1.0, 0.2]),
            (&[-2.0, 0.01], &[1.0, 0.0]),
            (&[1.0, 1e-4], &[2.0, 0.0]),
            (&[0.3, -0.7, 0.2], &[1.0, 0.5, -0.3]),
            (&[1.0, 1e-3, -2e-3], &[2.0, 0.0, 0.0]),
            (&[0.2, -0.1, 0.4, 0.9, -0.3, 0.05], &[0.1, 0.2, -0.3, 0.4, 0.5, -0.6]),
        ];
        for (v, t) in cases {
            let mut g = vec![0.0; v.len()];
            angle_gradient(v, t, &mut g);
            for i in 0..v.len() {
                let h = 1e-7;
                let (mut a, mut b) = (v.to_vec(), v.to_vec());
                a[i] += h;
                b[i] -= h;
                let fd = (angle_between(&a, t) - angle_between(&b, t)).to_radians() / (2.0 * h);
                assert!(
                    (fd - g[i]).abs() < 1e-6 * (1.0 + fd.abs()),
                    "v {v:?}, t {t:?}, ∂/∂v{i}: {} against {fd}",
                    g[i]
                );
            }
        }
        let mut g = vec![1.0; 2];
        angle_gradient(&[0.0, 0.0], &[1.0, 0.0], &mut g);
        assert_eq!(g, vec![0.0, 0.0]);
    }

    #[test]
    fn the_exact_potential_has_zero_residual_angles() {
        use crate::geodesic::{FanSpec, Stop};
        use crate::numerics::ode::OdeSettings;
        use crate::potential::ExactPotential;
        let chain = Chain::paper_double_pendulum();
        let q_eq = DVector::from_vec(vec![0.0, std::f64::consts::FRAC_PI_2]);
        let ode = OdeSettings::default();
        let fan = Fan::trace(&chain, &q_eq, FanSpec { count: 36, phase: 0.5, stop: Stop::Arc(2.0), spacing: 0.1 }, ode)
            .unwrap();
        let exact = ExactPotential::new(&chain, &q_eq, 3.0, ode);
        let (angles, descents) = fan_angles_and_descents(&chain, &fan, &exact).unwrap();
        assert_eq!(descents, 0, "U* grows along every geodesic");
        let st = stats(&angles);
        assert_eq!(st.count, 36 * 20);
        assert!(st.max_abs < 1e-3, "max |angle| {}°", st.max_abs);
        // A plain quadratic bowl is not compatible: clearly non-zero angles.
        let bowl = crate::potential::SpringSet {
            elements: (0..2)
                .map(|j| crate::elements::Element {
                    profile: crate::elements::Profile::Linear,
                    coupling: (0..2).map(|k| if j == k { 1.0 } else { 0.0 }).collect(),
                    offset: q_eq[j],
                })
                .collect(),
            stiffness: vec![1.0, 1.0],
        };
        let st = stats(&fan_angles(&chain, &fan, &bowl).unwrap());
        assert!(st.p99_abs > 5.0, "{st:?}");
        // Turned over and stiff enough to beat gravity, the bowl falls along every geodesic: every
        // sample counts as a descent (none sits at q_eq), and the angles are obtuse.
        let dome = crate::potential::SpringSet { stiffness: vec![-1000.0, -1000.0], ..bowl };
        let (angles, descents) = fan_angles_and_descents(&chain, &fan, &dome).unwrap();
        assert_eq!(descents, 36 * 20);
        assert!(stats(&angles).median_abs > 90.0);
    }

    #[test]
    fn percentiles_interpolate() {
        let v: Vec<f64> = (0..=100).map(f64::from).collect();
        assert_eq!(percentile(&v, 99.0), 99.0);
        assert_eq!(percentile(&[1.0, 3.0], 50.0), 2.0);
        let samples: Vec<AngleSample> =
            (1..=4).map(|i| AngleSample { direction: 0, s: i as f64, q: vec![], angle_deg: -(i as f64) }).collect();
        let st = stats(&samples);
        assert_eq!((st.median_abs, st.max_abs, st.count), (2.5, 4.0, 4));
        let bands = band_stats(&samples, 4.0, 2);
        assert_eq!(bands[0].stats.count, 2);
        assert_eq!(bands[1].stats.max_abs, 4.0);
    }

    /// The percentile interval covers the true percentile at least as often as it says, and not
    /// far more often (it is not needlessly wide): 4000 samples of 200 uniform draws, the p95
    /// (true value 0.95) and the median (0.5).
    #[test]
    fn percentile_intervals_cover_as_stated() {
        let mut rng = crate::numerics::rng::SplitMix64::new(7);
        for (p, truth) in [(95.0, 0.95), (50.0, 0.5)] {
            let mut inside = 0;
            let trials = 4000;
            for _ in 0..trials {
                let mut v: Vec<f64> = (0..200).map(|_| rng.uniform()).collect();
                v.sort_by(f64::total_cmp);
                let [lo, hi] = percentile_interval(&v, p, 0.95);
                assert!(lo <= percentile(&v, p) && percentile(&v, p) <= hi);
                if lo <= truth && truth <= hi {
                    inside += 1;
                }
            }
            let coverage = inside as f64 / trials as f64;
            assert!((0.94..0.985).contains(&coverage), "p{p}: coverage {coverage}");
        }
        // Too few draws for a bound: 10 draws cannot bound the p95 from above.
        let v: Vec<f64> = (0..10).map(f64::from).collect();
        assert_eq!(percentile_interval(&v, 95.0, 0.95)[1], f64::INFINITY);
    }
}
