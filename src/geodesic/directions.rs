//! Initial directions of a fan: unit vectors of the inertia metric at the equilibrium.
//!
//! A vector v has metric length √(vᵀ M v). With the Cholesky factor M(q_eq) = L Lᵀ, the map
//! u ↦ L⁻ᵀ u sends the Euclidean unit sphere onto the metric unit sphere, so directions are
//! chosen as Euclidean unit vectors u in this *metric frame* and mapped: equally spaced on the
//! circle for n = 2, a deterministic low-discrepancy set on the sphere for n ≥ 3.

use nalgebra::{DMatrix, DVector};

use crate::error::{Error, Result};

/// The orthonormal frame of the metric at the equilibrium: v = L⁻ᵀ u.
#[derive(Debug, Clone)]
pub struct MetricFrame {
    /// L⁻ᵀ, mapping frame coordinates u to joint velocities v.
    to_joint: DMatrix<f64>,
    /// Lᵀ, mapping joint velocities back to frame coordinates.
    to_frame: DMatrix<f64>,
}

impl MetricFrame {
    /// The frame of the metric `m` (the mass matrix at the equilibrium).
    pub fn new(m: &DMatrix<f64>) -> Result<Self> {
        let chol = m.clone().cholesky().ok_or_else(|| {
            Error::numerical("metric frame", "the mass matrix at the equilibrium is not positive definite")
        })?;
        let lt = chol.l().transpose();
        let to_joint = lt
            .clone()
            .try_inverse()
            .ok_or_else(|| Error::numerical("metric frame", "singular mass matrix at the equilibrium"))?;
        Ok(MetricFrame { to_joint, to_frame: lt })
    }

    /// Joint velocity of frame coordinates u (metric length |u|).
    pub fn to_joint(&self, u: &DVector<f64>) -> DVector<f64> {
        &self.to_joint * u
    }

    /// Frame coordinates of a joint velocity v (|u| is the metric length of v).
    pub fn to_frame(&self, v: &DVector<f64>) -> DVector<f64> {
        &self.to_frame * v
    }

    /// The transpose of [`MetricFrame::to_frame`] applied to a covector: pulls a gradient with
    /// respect to frame coordinates back to one with respect to joint velocities.
    pub fn to_frame_transpose(&self, g: &DVector<f64>) -> DVector<f64> {
        self.to_frame.tr_mul(g)
    }
}

/// `count` Euclidean unit vectors in ℝⁿ: for n = 1 the two signs, for n = 2 angles
/// 2π(i + phase)/count, for n = 3 a Fibonacci lattice, for n ≥ 4 Gaussian-normalised Halton
/// points. `phase` ∈ [0, 1) shifts the set (0.5 gives directions between those of phase 0, the
/// held-out set of an evaluation).
pub fn unit_vectors(n: usize, count: usize, phase: f64) -> Vec<DVector<f64>> {
    match n {
        1 => (0..count.max(2)).map(|i| DVector::from_element(1, if i % 2 == 0 { 1.0 } else { -1.0 })).take(2).collect(),
        2 => (0..count)
            .map(|i| {
                let a = std::f64::consts::TAU * (i as f64 + phase) / count as f64;
                DVector::from_vec(vec![a.cos(), a.sin()])
            })
            .collect(),
        3 => {
            // Fibonacci lattice: z evenly spaced, azimuth by the golden angle.
            let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
            (0..count)
                .map(|i| {
                    let z = 1.0 - 2.0 * (i as f64 + 0.5) / count as f64;
                    let rho = (1.0 - z * z).max(0.0).sqrt();
                    let a = golden * i as f64 + std::f64::consts::TAU * phase;
                    DVector::from_vec(vec![rho * a.cos(), rho * a.sin(), z])
                })
                .collect()
        }
        _ => {
            const PRIMES: [u64; 16] = [2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53];
            let dims = n.div_ceil(2) * 2;
            (0..count)
                .map(|i| {
                    let idx = (i + 1) as u64 + (phase * count as f64) as u64 * 7919;
                    let mut g = Vec::with_capacity(dims);
                    for d in (0..dims).step_by(2) {
                        // Box–Muller on two Halton coordinates.
                        let u1 = halton(idx, PRIMES[d % PRIMES.len()]).max(1e-12);
                        let u2 = halton(idx, PRIMES[(d + 1) % PRIMES.len()]);
                        let r = (-2.0 * u1.ln()).sqrt();
                        let a = std::f64::consts::TAU * u2;
                        g.push(r * a.cos());
                        g.push(r * a.sin());
                    }
                    g.truncate(n);
                    let v = DVector::from_vec(g);
                    let norm = v.norm();
                    v / norm
                })
                .collect()
        }
    }
}

/// How a fan's directions grow with the joints: `at_two` directions for n ≤ 2, times
/// `per_joint` = (numerator, denominator) for every joint beyond the second, rounded down at each
/// step. The directions cover the unit sphere of dimension n − 1, which a fixed count covers ever
/// more thinly. The count grows geometrically rather than as the h^(1−n) an even spacing h would
/// need: the residual is a smooth function of the direction, and every training direction adds
/// `training_samples` × (n − 1) rows to the fit's dense problem.
pub fn directions_for_joints(at_two: usize, n: usize, (num, den): (usize, usize)) -> usize {
    (2..n).fold(at_two, |count, _| count * num / den)
}

fn halton(mut i: u64, base: u64) -> f64 {
    let mut f = 1.0;
    let mut r = 0.0;
    while i > 0 {
        f /= base as f64;
        r += f * (i % base) as f64;
        i /= base;
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_maps_unit_vectors_to_metric_unit_vectors() {
        let m = DMatrix::from_row_slice(2, 2, &[8.0, 2.0, 2.0, 2.0]);
        let frame = MetricFrame::new(&m).unwrap();
        for u in unit_vectors(2, 12, 0.25) {
            let v = frame.to_joint(&u);
            assert!((v.dot(&(&m * &v)) - 1.0).abs() < 1e-14);
            assert!((frame.to_frame(&v) - &u).norm() < 1e-14);
        }
    }

    #[test]
    fn direction_counts_keep_two_joints_and_grow_per_joint() {
        let counts: Vec<usize> = (1..=7).map(|n| directions_for_joints(72, n, (2, 1))).collect();
        assert_eq!(counts, [72, 72, 144, 288, 576, 1152, 2304]);
        assert_eq!(directions_for_joints(720, 6, (3, 2)), 3645);
    }

    #[test]
    fn sphere_sets_are_unit_and_spread() {
        for n in [3, 4, 5] {
            let pts = unit_vectors(n, 400, 0.0);
            assert_eq!(pts.len(), 400);
            for p in &pts {
                assert!((p.norm() - 1.0).abs() < 1e-12);
            }
            // Roughly balanced: the mean of a well-spread set is near zero.
            let mean = pts.iter().fold(DVector::zeros(n), |a, p| a + p) / 400.0;
            assert!(mean.norm() < 0.1, "n = {n}: mean {}", mean.norm());
        }
    }
}
