//! Potentials: a fitted spring set, the exact target ½ω²r², and gravity.
//!
//! Everything downstream of the fit (residual angles, simulation, sweeps) sees a [`Potential`]:
//! value, gradient and Hessian of the *elastic* potential U_e over q. The total potential the
//! arm feels is U = U_e + U_g; gravity comes from the [`crate::model::Chain`].

use nalgebra::{DMatrix, DVector};

use crate::elements::Element;
use crate::error::Result;

mod coupled;
mod exact;
mod grouped;

pub use coupled::CouplingSet;
pub use exact::ExactPotential;
pub use grouped::GroupedSet;

/// An elastic potential U_e(q).
pub trait Potential: Sync {
    /// Number of joints.
    fn dof(&self) -> usize;
    /// U_e(q) in J.
    fn value(&self, q: &[f64]) -> Result<f64>;
    /// ∂U_e/∂q in N·m.
    fn gradient(&self, q: &[f64]) -> Result<DVector<f64>>;
    /// ∂U_e/∂q into `out` (implementations on hot paths override it to avoid allocating).
    fn gradient_into(&self, q: &[f64], out: &mut [f64]) -> Result<()> {
        out.copy_from_slice(self.gradient(q)?.as_slice());
        Ok(())
    }
    /// ∂²U_e/∂q² in N·m/rad.
    fn hessian(&self, q: &[f64]) -> Result<DMatrix<f64>>;
}

/// A set of elements with their stiffnesses: U_e = Σ kⱼ uⱼ(q).
#[derive(Debug, Clone, PartialEq)]
pub struct SpringSet {
    /// The elements.
    pub elements: Vec<Element>,
    /// Their stiffnesses (in each profile's unit), ≥ 0.
    pub stiffness: Vec<f64>,
}

impl SpringSet {
    /// Joint torques of each element at q (the spring torque a·k·u′, N·m): one row per element.
    pub fn element_torques(&self, q: &[f64]) -> Vec<DVector<f64>> {
        self.elements.iter().zip(&self.stiffness).map(|(e, k)| e.gradient(q) * *k).collect()
    }

    /// The evaluation form of the set: each cam's basis elements summed into one term (see
    /// [`GroupedSet`]). Build it once per set wherever the set is evaluated at many points.
    pub fn grouped(&self) -> GroupedSet {
        GroupedSet::new(self)
    }

    /// The same springs with each stiffness scaled by a factor (manufacturing deviations).
    pub fn scaled(&self, factors: &[f64]) -> SpringSet {
        SpringSet {
            elements: self.elements.clone(),
            stiffness: self.stiffness.iter().zip(factors).map(|(k, f)| k * f).collect(),
        }
    }

    /// Gradient without allocating (the simulation's hot loop).
    pub fn gradient_into(&self, q: &[f64], out: &mut [f64]) {
        self.gradient_scaled_into(q, None, out);
    }

    /// U_e and its gradient in one pass (one trigonometric evaluation per element), the gradient
    /// into `out`.
    pub fn value_gradient_into(&self, q: &[f64], out: &mut [f64]) -> f64 {
        out.fill(0.0);
        let mut u = 0.0;
        for (e, k) in self.elements.iter().zip(&self.stiffness) {
            if *k == 0.0 {
                continue;
            }
            let (v, slope, _) = e.profile.eval(e.deflection(q));
            u += k * v;
            for (o, a) in out.iter_mut().zip(&e.coupling) {
                *o += k * slope * a;
            }
        }
        u
    }

    /// Gradient with each stiffness multiplied by `scale[j]` (manufacturing deviations), into
    /// `out`.
    pub fn gradient_scaled_into(&self, q: &[f64], scale: Option<&[f64]>, out: &mut [f64]) {
        out.fill(0.0);
        for (j, (e, k)) in self.elements.iter().zip(&self.stiffness).enumerate() {
            let k = k * scale.map_or(1.0, |s| s[j]);
            if k == 0.0 {
                continue;
            }
            let slope = k * e.profile.slope(e.deflection(q));
            for (o, a) in out.iter_mut().zip(&e.coupling) {
                *o += slope * a;
            }
        }
    }
}

impl Potential for SpringSet {
    fn dof(&self) -> usize {
        self.elements.first().map_or(0, |e| e.coupling.len())
    }

    fn value(&self, q: &[f64]) -> Result<f64> {
        Ok(self.elements.iter().zip(&self.stiffness).map(|(e, k)| k * e.value(q)).sum())
    }

    fn gradient(&self, q: &[f64]) -> Result<DVector<f64>> {
        let mut g = DVector::zeros(q.len());
        SpringSet::gradient_into(self, q, g.as_mut_slice());
        Ok(g)
    }

    fn gradient_into(&self, q: &[f64], out: &mut [f64]) -> Result<()> {
        SpringSet::gradient_into(self, q, out);
        Ok(())
    }

    fn hessian(&self, q: &[f64]) -> Result<DMatrix<f64>> {
        let n = q.len();
        Ok(self.elements.iter().zip(&self.stiffness).fold(DMatrix::zeros(n, n), |acc, (e, k)| acc + e.hessian(q) * *k))
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;
    use crate::elements::{Profile, Side};
    use crate::model::Chain;
    use crate::numerics::ode::OdeSettings;

    #[test]
    fn spring_set_sums_its_elements() {
        let set = SpringSet {
            elements: vec![
                Element { profile: Profile::Linear, coupling: vec![1.0, 0.0], offset: 0.1 },
                Element { profile: Profile::Crank, coupling: vec![1.0, -1.0], offset: 0.3 },
                Element { profile: Profile::Compression(Side::Minus), coupling: vec![0.0, 2.0], offset: 0.5 },
            ],
            stiffness: vec![2.0, 3.0, 0.5],
        };
        let q = [0.4, -0.2];
        let g = set.gradient(&q).unwrap();
        let expected_0 = 2.0 * 0.3 + 3.0 * (0.6f64 - 0.3).sin();
        let expected_1 = -3.0 * (0.6f64 - 0.3).sin() + 0.5 * 2.0 * (2.0 * -0.2 - 0.5);
        assert!((g[0] - expected_0).abs() < 1e-14 && (g[1] - expected_1).abs() < 1e-14);
        let torques = set.element_torques(&q);
        let sum = torques.iter().fold(DVector::zeros(2), |a, t| a + t);
        assert!((sum - g).amax() < 1e-14);
        let h = 1e-6;
        let hess = set.hessian(&q).unwrap();
        for j in 0..2 {
            let mut qp = q;
            let mut qm = q;
            qp[j] += h;
            qm[j] -= h;
            let fd = (set.gradient(&qp).unwrap() - set.gradient(&qm).unwrap()) / (2.0 * h);
            assert!((hess.column(j) - fd).amax() < 1e-6);
        }
    }

    fn lcg(seed: &mut u64) -> f64 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    /// Springs and two cams (± basis elements as the fit leaves them, some stiffnesses zero, a
    /// crank between each cam's elements) on `n` joints.
    fn springs_and_cams(n: usize, seed: &mut u64) -> SpringSet {
        let mut elements = Vec::new();
        let mut stiffness = Vec::new();
        let coupling = |j: usize| -> Vec<f64> { (0..n).map(|i| [1.0, -2.0, 1.0, 3.0][(i + j) % 4]).collect() };
        elements.push(Element { profile: Profile::Linear, coupling: coupling(1), offset: 0.2 });
        stiffness.push(3.0);
        for (cam, count) in [(0usize, 30u16), (2, 7)] {
            let knots = crate::elements::spline::Knots::over(-1.5, 2.0 + cam as f64, count, 0.05);
            for j in 0..knots.basis_count() {
                for negative in [false, true] {
                    elements.push(Element {
                        profile: Profile::Spline(knots.basis(j, negative)),
                        coupling: coupling(cam),
                        offset: knots.lo,
                    });
                    let k = 40.0 * (lcg(seed) + 1.0);
                    stiffness.push(if lcg(seed) < -0.5 { 0.0 } else { k });
                }
                if j == 5 {
                    elements.push(Element { profile: Profile::Crank, coupling: coupling(3), offset: -0.4 });
                    stiffness.push(0.7);
                }
            }
        }
        SpringSet { elements, stiffness }
    }

    /// Grouping by coupling (one sine per coupling for its cranks, the angle-difference
    /// formula for each offset) gives the sum of the elements to rounding: U, ∇U and ∇²U of
    /// every profile, several elements per coupling, zero stiffnesses and cams included.
    #[test]
    fn coupling_groups_equal_the_sum_of_their_elements() {
        let mut seed = 7;
        for n in [2, 3, 5] {
            let mut set = springs_and_cams(n, &mut seed);
            let profiles = [
                Profile::Crank,
                Profile::Linear,
                Profile::Cubic,
                Profile::Compression(crate::elements::Side::Plus),
                Profile::Compression(crate::elements::Side::Minus),
            ];
            for j in 0..40 {
                let coupling: Vec<f64> = (0..n).map(|i| [1.0, -1.0, 0.0, 2.0][(i * 3 + j) % 4]).collect();
                let profile = profiles[j % profiles.len()];
                set.elements.push(Element { profile, coupling, offset: 1.5 * lcg(&mut seed) });
                set.stiffness.push(if j % 7 == 3 { 0.0 } else { 10.0 * (lcg(&mut seed) + 1.1) });
            }
            let (grouped, coupled) = (set.grouped(), CouplingSet::new(&set));
            for _ in 0..100 {
                let q: Vec<f64> = (0..n).map(|_| 2.5 * lcg(&mut seed)).collect();
                let (u, g, h) =
                    (grouped.value(&q).unwrap(), grouped.gradient(&q).unwrap(), grouped.hessian(&q).unwrap());
                let scale = g.amax().max(h.amax()).max(u.abs());
                assert!((coupled.value(&q).unwrap() - u).abs() <= 1e-12 * scale, "U at {q:?}");
                assert!((coupled.gradient(&q).unwrap() - &g).amax() <= 1e-12 * scale, "∇U at {q:?}");
                assert!((coupled.hessian(&q).unwrap() - &h).amax() <= 1e-12 * scale, "∇²U at {q:?}");
                let mut buf = vec![f64::NAN; n];
                coupled.gradient_into(&q, &mut buf).unwrap();
                assert_eq!(buf, coupled.gradient(&q).unwrap().as_slice());
            }
        }
    }

    #[test]
    fn a_build_and_its_nominal_set_evaluate_in_one_pass_bit_for_bit() {
        let mut seed = 41;
        for n in [2, 3] {
            let set = springs_and_cams(n, &mut seed);
            let scale: Vec<f64> = set.stiffness.iter().map(|_| 1.0 + 0.1 * lcg(&mut seed)).collect();
            let (nominal, built) = (set.grouped(), set.scaled(&scale).grouped());
            assert!(nominal.same_elements(&built));
            for _ in 0..200 {
                let q: Vec<f64> = (0..n).map(|_| 2.5 * lcg(&mut seed)).collect();
                let (mut fused, mut apart) = (vec![0.0; n], vec![0.0; n]);
                let u = nominal.value_and_gradient_of(&built, &q, &mut fused);
                built.gradient_into(&q, &mut apart);
                assert_eq!(u.to_bits(), nominal.value(&q).unwrap().to_bits(), "U at {q:?}");
                assert_eq!(fused, apart, "∇U at {q:?}");
            }
            // A tuned build moves offsets: its elements are not the nominal ones.
            let mut moved = set.clone();
            moved.elements[0].offset += 1e-3;
            assert!(!nominal.same_elements(&moved.grouped()));
        }
    }

    #[test]
    fn grouped_cams_equal_the_sum_of_their_basis_elements() {
        let mut seed = 23;
        for n in [2, 3] {
            let set = springs_and_cams(n, &mut seed);
            let grouped = set.grouped();
            // Three springs (one inside each cam's run of elements) and two cams.
            assert_eq!(grouped.len(), 5);
            let (mut inside, mut outside) = (0, 0);
            for _ in 0..300 {
                // Up to twice the knot spans' reach: inside the span and in its continuation.
                let q: Vec<f64> = (0..n).map(|_| 2.5 * lcg(&mut seed)).collect();
                // Per element, and the sum of |terms| that bounds the rounding of either sum.
                let (mut u, mut g, mut h) = (0.0, DVector::zeros(n), DMatrix::zeros(n, n));
                let (mut su, mut sg, mut sh) = (0.0, 0.0, 0.0);
                for (e, k) in set.elements.iter().zip(&set.stiffness) {
                    let (v, s, c) = e.profile.eval(e.deflection(&q));
                    u += k * v;
                    g += e.gradient(&q) * *k;
                    h += e.hessian(&q) * *k;
                    let a2 = e.coupling.iter().map(|a| a * a).sum::<f64>();
                    (su, sg, sh) = (su + (k * v).abs(), sg + (k * s).abs() * a2.sqrt(), sh + (k * c).abs() * a2);
                    if let Profile::Spline(b) = e.profile {
                        let t = e.deflection(&q) / b.width();
                        if (0.0..=f64::from(b.count - 1)).contains(&t) { inside += 1 } else { outside += 1 }
                    }
                }
                let tol = 1e-13 * set.elements.len() as f64;
                assert!((grouped.value(&q).unwrap() - u).abs() <= tol * su.max(1e-300), "U at {q:?}");
                let mut buf = vec![0.0; n];
                let u2 = grouped.value_gradient_into(&q, &mut buf);
                assert!((u2 - u).abs() <= tol * su.max(1e-300));
                let gg = grouped.gradient(&q).unwrap();
                assert!((&gg - &g).amax() <= tol * sg.max(1e-300), "∇U at {q:?}: {gg} vs {g}");
                assert!((DVector::from_vec(buf) - &g).amax() <= tol * sg.max(1e-300));
                let hh = grouped.hessian(&q).unwrap();
                assert!((&hh - &h).amax() <= tol * sh.max(1e-300), "∇²U at {q:?}: {hh} vs {h}");
                // The per-element sums themselves (SpringSet) agree with these.
                assert!((set.gradient(&q).unwrap() - &g).amax() <= tol * sg.max(1e-300));
            }
            // Both regimes were exercised.
            assert!(inside > 1000 && outside > 1000, "{inside} inside, {outside} outside");
        }
    }

    #[test]
    fn grouping_a_set_without_cams_changes_no_bit() {
        let set = SpringSet {
            elements: vec![
                Element { profile: Profile::Linear, coupling: vec![1.0, 0.0], offset: 0.1 },
                Element { profile: Profile::Cubic, coupling: vec![1.0, 2.0], offset: -0.2 },
                Element { profile: Profile::Crank, coupling: vec![1.0, -1.0], offset: 0.3 },
                Element { profile: Profile::Compression(Side::Minus), coupling: vec![0.0, 2.0], offset: 0.5 },
                Element { profile: Profile::Compression(Side::Plus), coupling: vec![0.0, 1.0], offset: 0.0 },
            ],
            stiffness: vec![2.0, 0.3, 3.0, 0.5, 0.0],
        };
        let grouped = set.grouped();
        let mut seed = 29;
        for _ in 0..100 {
            let q = [lcg(&mut seed), 2.0 * lcg(&mut seed)];
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(grouped.value(&q).unwrap().to_bits(), set.value(&q).unwrap().to_bits());
            assert_eq!(bits(grouped.gradient(&q).unwrap().as_slice()), bits(set.gradient(&q).unwrap().as_slice()));
            assert_eq!(bits(grouped.hessian(&q).unwrap().as_slice()), bits(set.hessian(&q).unwrap().as_slice()));
            let (mut a, mut b) = ([0.0; 2], [0.0; 2]);
            assert_eq!(
                grouped.value_gradient_into(&q, &mut a).to_bits(),
                set.value_gradient_into(&q, &mut b).to_bits()
            );
            assert_eq!(bits(&a), bits(&b));
        }
    }

    #[test]
    fn exact_gradient_matches_finite_differences_of_its_value() {
        let chain = Chain::paper_double_pendulum();
        let q_eq = DVector::from_vec(vec![0.0, PI / 2.0]);
        let ode = OdeSettings { rtol: 1e-12, atol: 1e-12, ..Default::default() };
        let exact = ExactPotential::new(&chain, &q_eq, 2.0, ode);
        for q in [[0.3, 1.9], [-0.4, 1.1], [0.2, 2.5]] {
            let g = exact.gradient(&q).unwrap();
            let h = 1e-5;
            for j in 0..2 {
                let mut qp = q;
                let mut qm = q;
                qp[j] += h;
                qm[j] -= h;
                let fd = (exact.value(&qp).unwrap() - exact.value(&qm).unwrap()) / (2.0 * h);
                assert!((g[j] - fd).abs() < 1e-6 * (1.0 + fd.abs()), "{} vs {fd}", g[j]);
            }
        }
        let hess = exact.hessian(q_eq.as_slice()).unwrap();
        assert!((hess - chain.mass_matrix(&q_eq) * 4.0).amax() < 1e-12);
    }
}
