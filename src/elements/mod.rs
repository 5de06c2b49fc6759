//! Elastic elements: the building blocks of the spring potential.
//!
//! Every element acts on a transmission coordinate x = a·q (a = eᵢ for a spring on joint i, a
//! = (…, 1, …, ±r, …) for a coupled bevel-gear spring) with an offset x₀ and a stiffness k ≥ 0
//! chosen by the fit. Its potential is k·u(x − x₀) with the profile u of `docs/theory.md`:
//!
//! | profile | u(d) | u′(d) (torque on x per unit k) | unit of k |
//! | --- | --- | --- | --- |
//! | linear | ½ d² | d | N·m/rad |
//! | cubic | ¼ d⁴ | d³ | N·m/rad³ |
//! | crank | 1 − cos d | sin d | N·m |
//! | compression + | ½ max(0, d)² | max(0, d) | N·m/rad |
//! | compression − | ½ max(0, −d)² | −max(0, −d) | N·m/rad |
//!
//! Because x is linear in q, ∇U = k u′(x − x₀) a and ∇²U = k u″(x − x₀) a aᵀ: an element is
//! fully described by its profile, coupling and offset, which is also what the bill of materials
//! records.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

pub mod catalog;
pub mod group;
pub mod spline;
pub mod trim;

use spline::SplineBasis;

/// Which side a one-sided compression spring engages on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Side {
    /// Engages for x > x₀.
    #[serde(rename = "+")]
    Plus,
    /// Engages for x < x₀.
    #[serde(rename = "-")]
    Minus,
}

/// The force profile of an element.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Profile {
    /// A linear torsion spring.
    Linear,
    /// A cubic (hardening) spring.
    Cubic,
    /// A crank mechanism: a sine-shaped torque.
    Crank,
    /// A one-sided compression spring (ReLU-like torque).
    Compression(Side),
    /// One signed cubic B-spline basis function of a cam (see [`crate::elements::spline`]): a fitted cam is
    /// the sum of its basis elements, each with its coefficient as the stiffness.
    Spline(SplineBasis),
}

impl Profile {
    /// u(d), u′(d), u″(d).
    #[inline]
    pub fn eval(self, d: f64) -> (f64, f64, f64) {
        match self {
            Profile::Linear => (0.5 * d * d, d, 1.0),
            Profile::Cubic => (0.25 * d * d * d * d, d * d * d, 3.0 * d * d),
            Profile::Crank => {
                let (s, c) = d.sin_cos();
                (1.0 - c, s, c)
            }
            Profile::Compression(Side::Plus) => {
                if d > 0.0 {
                    (0.5 * d * d, d, 1.0)
                } else {
                    (0.0, 0.0, 0.0)
                }
            }
            Profile::Compression(Side::Minus) => {
                if d < 0.0 {
                    (0.5 * d * d, d, 1.0)
                } else {
                    (0.0, 0.0, 0.0)
                }
            }
            Profile::Spline(b) => b.eval(d),
        }
    }

    /// u′(d) only (the hot path of the fit's rows).
    #[inline]
    pub fn slope(self, d: f64) -> f64 {
        match self {
            Profile::Linear => d,
            Profile::Cubic => d * d * d,
            Profile::Crank => d.sin(),
            Profile::Compression(Side::Plus) => d.max(0.0),
            Profile::Compression(Side::Minus) => d.min(0.0),
            Profile::Spline(b) => b.eval(d).1,
        }
    }

    /// The profile's name in files: `linear`, `cubic`, `crank`, `compression`, `cam`.
    pub fn name(self) -> &'static str {
        match self {
            Profile::Linear => "linear",
            Profile::Cubic => "cubic",
            Profile::Crank => "crank",
            Profile::Compression(_) => "compression",
            Profile::Spline(_) => "cam",
        }
    }

    /// `+`, `-` or empty; for a cam basis function `±j/N/h` (sign, index, knots, spacing).
    pub fn side(self) -> String {
        match self {
            Profile::Compression(Side::Plus) => "+".into(),
            Profile::Compression(Side::Minus) => "-".into(),
            Profile::Spline(b) => b.side_text(),
            _ => String::new(),
        }
    }

    /// The unit of the stiffness k.
    pub fn unit(self) -> &'static str {
        match self {
            Profile::Linear | Profile::Compression(_) => "N*m/rad",
            Profile::Cubic => "N*m/rad^3",
            Profile::Crank => "N*m",
            Profile::Spline(_) => "J",
        }
    }

    /// Parses a profile name and side as written in catalogues and bills of materials.
    pub fn parse(name: &str, side: &str) -> Result<Profile, String> {
        let p = match (name, side) {
            ("linear", "") => Profile::Linear,
            ("cubic", "") => Profile::Cubic,
            ("crank", "") => Profile::Crank,
            ("compression", "+") => Profile::Compression(Side::Plus),
            ("compression", "-") => Profile::Compression(Side::Minus),
            ("cam", s) => Profile::Spline(SplineBasis::parse_side(s)?),
            ("compression", s) => {
                return Err(format!("a compression spring needs side \"+\" or \"-\", got \"{s}\""));
            }
            ("linear" | "cubic" | "crank", s) => {
                return Err(format!("profile `{name}` has no side, got \"{s}\""));
            }
            (other, _) => {
                return Err(format!("unknown profile `{other}`: expected linear, cubic, crank, compression or cam"));
            }
        };
        Ok(p)
    }
}

/// One candidate elastic element (stiffness not included: it is the fit's unknown).
#[derive(Debug, Clone, PartialEq)]
pub struct Element {
    /// Force profile.
    pub profile: Profile,
    /// Transmission vector a (x = a·q), one entry per joint.
    pub coupling: Vec<f64>,
    /// Offset x₀ in rad.
    pub offset: f64,
}

impl Element {
    /// x − x₀ at q.
    #[inline]
    pub fn deflection(&self, q: &[f64]) -> f64 {
        self.coupling.iter().zip(q).map(|(a, q)| a * q).sum::<f64>() - self.offset
    }

    /// u at q for unit stiffness.
    pub fn value(&self, q: &[f64]) -> f64 {
        self.profile.eval(self.deflection(q)).0
    }

    /// ∇u at q for unit stiffness: u′ a.
    pub fn gradient(&self, q: &[f64]) -> DVector<f64> {
        let slope = self.profile.slope(self.deflection(q));
        DVector::from_iterator(self.coupling.len(), self.coupling.iter().map(|a| slope * a))
    }

    /// ∇²u at q for unit stiffness: u″ a aᵀ.
    pub fn hessian(&self, q: &[f64]) -> DMatrix<f64> {
        let curv = self.profile.eval(self.deflection(q)).2;
        let a = DVector::from_column_slice(&self.coupling);
        &a * a.transpose() * curv
    }

    /// Preload at `q_eq` with stiffness `k`: the torque k·u′(a·q_eq − x₀) on the element's
    /// coordinate x (signed, N·m). Antagonistic elements cancel their preloads at the
    /// equilibrium; a build with a rate error un-cancels them.
    pub fn preload(&self, k: f64, q_eq: &[f64]) -> f64 {
        k * self.profile.slope(self.deflection(q_eq))
    }

    /// The coupling as written in files: entries joined by `;` (e.g. `1;-2`).
    pub fn coupling_text(&self) -> String {
        self.coupling.iter().map(|a| fmt_number(*a)).collect::<Vec<_>>().join(";")
    }

    /// A short label such as `crank (1;-1) @ 0.785`.
    pub fn label(&self) -> String {
        format!("{}{} ({}) @ {:.3}", self.profile.name(), self.profile.side(), self.coupling_text(), self.offset)
    }
}

/// Shortest exact decimal form of a number (integers without `.0`).
pub fn fmt_number(x: f64) -> String {
    if x == x.trunc() && x.abs() < 1e15 { format!("{}", x as i64) } else { format!("{x}") }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all_profiles() -> [Profile; 5] {
        [
            Profile::Linear,
            Profile::Cubic,
            Profile::Crank,
            Profile::Compression(Side::Plus),
            Profile::Compression(Side::Minus),
        ]
    }

    #[test]
    fn gradients_and_hessians_match_finite_differences() {
        let h = 1e-6;
        for profile in all_profiles() {
            for (coupling, offset) in [(vec![1.0, 0.0], 0.3), (vec![1.0, -2.0], -0.4), (vec![2.0, 1.0, -1.0], 1.1)] {
                let e = Element { profile, coupling: coupling.clone(), offset };
                let n = coupling.len();
                for q0 in [[0.7, -0.2, 0.4], [-0.9, 0.8, 0.1], [0.05, 1.3, -0.6]] {
                    let q = &q0[..n];
                    // Stay away from the kink of one-sided springs, where u″ jumps.
                    if e.deflection(q).abs() < 1e-3 {
                        continue;
                    }
                    let g = e.gradient(q);
                    let hess = e.hessian(q);
                    for j in 0..n {
                        let mut qp = q.to_vec();
                        let mut qm = q.to_vec();
                        qp[j] += h;
                        qm[j] -= h;
                        let fd = (e.value(&qp) - e.value(&qm)) / (2.0 * h);
                        assert!((g[j] - fd).abs() < 1e-7 * (1.0 + fd.abs()), "{profile:?} grad");
                        let fdg = (e.gradient(&qp) - e.gradient(&qm)) / (2.0 * h);
                        for i in 0..n {
                            assert!((hess[(i, j)] - fdg[i]).abs() < 1e-6 * (1.0 + fdg[i].abs()), "{profile:?} hess");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn profiles_follow_the_design_table() {
        let d = 0.5;
        assert_eq!(Profile::Linear.eval(d), (0.125, 0.5, 1.0));
        assert_eq!(Profile::Cubic.eval(d), (0.015625, 0.125, 0.75));
        assert!((Profile::Crank.eval(d).1 - d.sin()).abs() < 1e-15);
        assert_eq!(Profile::Compression(Side::Plus).eval(-d), (0.0, 0.0, 0.0));
        assert_eq!(Profile::Compression(Side::Minus).eval(-d), (0.125, -0.5, 1.0));
        assert_eq!(Profile::Compression(Side::Minus).eval(d), (0.0, 0.0, 0.0));
        for p in all_profiles() {
            for d in [-1.3, -0.2, 0.0, 0.4, 2.0] {
                assert_eq!(p.slope(d), p.eval(d).1);
            }
            assert_eq!(Profile::parse(p.name(), &p.side()).unwrap(), p);
        }
        assert!(Profile::parse("spiral", "").unwrap_err().contains("unknown profile"));
        assert!(Profile::parse("compression", "").is_err());
    }

    #[test]
    fn coupling_text() {
        let e = Element { profile: Profile::Linear, coupling: vec![1.0, -2.0, 0.5], offset: 0.0 };
        assert_eq!(e.coupling_text(), "1;-2;0.5");
    }
}
