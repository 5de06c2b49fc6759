//! A spring set grouped by coupling, for the held-out residuals: every element on one coupling a
//! shares x = a·q and the torque's direction a, so x, the axpy into ∇U and, for cranks, the sine
//! are computed once per coupling (sin(x − x₀) = sin x cos x₀ − cos x sin x₀ with cos x₀ and
//! sin x₀ stored), and each element adds one scalar. The seven-link chain's fit has 606 springs
//! on 80 couplings, 390 of them cranks: one `sin_cos` and one axpy per coupling where
//! [`GroupedSet`] has one of each per element. Its figures equal [`GroupedSet`]'s to rounding,
//! not bit for bit, so it serves only the held-out evaluation (`fit::evaluate`), whose figures
//! are statistics; the closed loop and the builds keep [`GroupedSet`]'s bits.

use nalgebra::{DMatrix, DVector};

use super::{GroupedSet, Potential, SpringSet};
use crate::elements::Profile;
use crate::error::Result;

/// The elements on one coupling.
#[derive(Debug, Clone)]
struct Group {
    coupling: Vec<f64>,
    /// Cranks: (k, cos x₀, sin x₀).
    cranks: Vec<[f64; 3]>,
    /// Every other profile but cams: (profile, x₀, k).
    others: Vec<(Profile, f64, f64)>,
}

/// See the module doc.
#[derive(Debug, Clone)]
pub struct CouplingSet {
    dof: usize,
    groups: Vec<Group>,
    /// Cams (their basis elements summed), as [`GroupedSet`] evaluates them.
    cams: GroupedSet,
}

impl CouplingSet {
    /// `set` grouped by coupling (couplings equal bit for bit share a group); zero stiffnesses
    /// dropped.
    pub fn new(set: &SpringSet) -> CouplingSet {
        let mut groups: Vec<Group> = Vec::new();
        let mut cams = SpringSet { elements: Vec::new(), stiffness: Vec::new() };
        for (e, &k) in set.elements.iter().zip(&set.stiffness) {
            if matches!(e.profile, Profile::Spline(_)) {
                cams.elements.push(e.clone());
                cams.stiffness.push(k);
                continue;
            }
            if k == 0.0 {
                continue;
            }
            let same = |g: &Group| {
                g.coupling.len() == e.coupling.len()
                    && g.coupling.iter().zip(&e.coupling).all(|(x, y)| x.to_bits() == y.to_bits())
            };
            let at = match groups.iter().position(same) {
                Some(at) => at,
                None => {
                    groups.push(Group { coupling: e.coupling.clone(), cranks: Vec::new(), others: Vec::new() });
                    groups.len() - 1
                }
            };
            let g = &mut groups[at];
            match e.profile {
                Profile::Crank => {
                    let (s0, c0) = e.offset.sin_cos();
                    g.cranks.push([k, c0, s0]);
                }
                p => g.others.push((p, e.offset, k)),
            }
        }
        CouplingSet { dof: set.elements.first().map_or(0, |e| e.coupling.len()), groups, cams: cams.grouped() }
    }

    /// Σ_j k_j u′_j of one group at x = a·q: the gradient's hot path, without the values and
    /// curvatures [`Self::sums`] also forms.
    #[inline]
    fn slope(g: &Group, q: &[f64]) -> f64 {
        let x: f64 = g.coupling.iter().zip(q).map(|(a, q)| a * q).sum();
        let mut du = 0.0;
        if !g.cranks.is_empty() {
            let (s, c) = x.sin_cos();
            for &[k, c0, s0] in &g.cranks {
                du += k * (s * c0 - c * s0);
            }
        }
        for &(p, x0, k) in &g.others {
            du += k * p.slope(x - x0);
        }
        du
    }

    /// Σ_j k_j (u_j, u′_j, u″_j) of one group at x = a·q.
    fn sums(g: &Group, q: &[f64]) -> (f64, f64, f64) {
        let x: f64 = g.coupling.iter().zip(q).map(|(a, q)| a * q).sum();
        let (mut u, mut du, mut ddu) = (0.0, 0.0, 0.0);
        if !g.cranks.is_empty() {
            let (s, c) = x.sin_cos();
            for &[k, c0, s0] in &g.cranks {
                // cos(x − x₀), sin(x − x₀)
                let (cd, sd) = (c * c0 + s * s0, s * c0 - c * s0);
                u += k * (1.0 - cd);
                du += k * sd;
                ddu += k * cd;
            }
        }
        for &(p, x0, k) in &g.others {
            let (v, d1, d2) = p.eval(x - x0);
            u += k * v;
            du += k * d1;
            ddu += k * d2;
        }
        (u, du, ddu)
    }
}

impl Potential for CouplingSet {
    fn dof(&self) -> usize {
        self.dof
    }

    fn value(&self, q: &[f64]) -> Result<f64> {
        Ok(self.cams.value(q)? + self.groups.iter().map(|g| Self::sums(g, q).0).sum::<f64>())
    }

    fn gradient(&self, q: &[f64]) -> Result<DVector<f64>> {
        let mut g = DVector::zeros(q.len());
        self.gradient_into(q, g.as_mut_slice())?;
        Ok(g)
    }

    fn gradient_into(&self, q: &[f64], out: &mut [f64]) -> Result<()> {
        self.cams.gradient_into(q, out);
        for g in &self.groups {
            let slope = Self::slope(g, q);
            for (o, a) in out.iter_mut().zip(&g.coupling) {
                *o += slope * a;
            }
        }
        Ok(())
    }

    fn hessian(&self, q: &[f64]) -> Result<DMatrix<f64>> {
        let mut h = self.cams.hessian(q)?;
        for g in &self.groups {
            let curv = Self::sums(g, q).2;
            let a = DVector::from_column_slice(&g.coupling);
            h += &a * a.transpose() * curv;
        }
        Ok(h)
    }
}
