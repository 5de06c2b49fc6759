//! A spring set in evaluation form: each cam's basis elements summed into one term, for the hot
//! paths (residual angles, equilibria, the simulation's right-hand side).

use nalgebra::{DMatrix, DVector};

use super::{Potential, SpringSet};
use crate::elements::spline::{SplineBasis, spline_sum};
use crate::elements::{Element, Profile};
use crate::error::Result;

/// A spring set in evaluation form: each cam's basis elements summed into one term.
///
/// A fitted cam is N + 2 elements (one per B-spline coefficient, a ± column pair each in the
/// fit), all on one coupling with one offset and knot spacing, and at any x only four of its
/// basis functions are non-zero. Evaluated element by element, eight cams on 30 knots cost 256
/// deflections a·q and spline evaluations at every sample; grouped, eight deflections and 32
/// basis evaluations, from the signed coefficients cⱼ = Σ ±kⱼ summed once here. Elements that
/// are not cam basis functions stay as they are, in their order, and a cam's term takes the
/// place of its first element: a set without cams is evaluated with exactly the arithmetic of
/// [`SpringSet`], one with cams equals the per-element sums to rounding.
///
/// [`SpringSet`] stays the data form (files, the bill of materials, fingerprints); this is how
/// it is evaluated on hot paths (residual angles, equilibria, the simulation's right-hand side).
#[derive(Debug, Clone, PartialEq)]
pub struct GroupedSet {
    dof: usize,
    terms: Vec<Term>,
}

/// One term of a [`GroupedSet`].
#[derive(Debug, Clone, PartialEq)]
enum Term {
    /// An element with its stiffness, evaluated as in [`SpringSet`].
    Element(Element, f64),
    /// A cam: V(x) = Σⱼ cⱼ Bⱼ(x − x₀) on x = a·q.
    Cam {
        coupling: Vec<f64>,
        /// x₀, the first knot.
        offset: f64,
        /// Knot count N.
        count: u16,
        /// Knot spacing h, as bits (with `count` and the coupling, what makes basis elements
        /// one cam).
        width_bits: u64,
        /// cⱼ, j = 0 … N + 1.
        coef: Vec<f64>,
    },
}

impl GroupedSet {
    /// Groups the cam basis elements of `set` by coupling, offset and knots.
    pub fn new(set: &SpringSet) -> GroupedSet {
        let mut terms: Vec<Term> = Vec::new();
        for (e, &k) in set.elements.iter().zip(&set.stiffness) {
            let Profile::Spline(b) = e.profile else {
                terms.push(Term::Element(e.clone(), k));
                continue;
            };
            let same = |t: &Term| match t {
                Term::Cam { coupling, offset, count, width_bits, .. } => {
                    *count == b.count
                        && *width_bits == b.width_bits
                        && offset.to_bits() == e.offset.to_bits()
                        && coupling.len() == e.coupling.len()
                        && coupling.iter().zip(&e.coupling).all(|(x, y)| x.to_bits() == y.to_bits())
                }
                Term::Element(..) => false,
            };
            let at = match terms.iter().position(same) {
                Some(at) => at,
                None => {
                    terms.push(Term::Cam {
                        coupling: e.coupling.clone(),
                        offset: e.offset,
                        count: b.count,
                        width_bits: b.width_bits,
                        coef: vec![0.0; usize::from(b.count) + 2],
                    });
                    terms.len() - 1
                }
            };
            if let Term::Cam { coef, .. } = &mut terms[at] {
                let SplineBasis { index, negative, .. } = b;
                if let Some(c) = coef.get_mut(usize::from(index)) {
                    *c += if negative { -k } else { k };
                }
            }
        }
        GroupedSet { dof: set.elements.first().map_or(0, |e| e.coupling.len()), terms }
    }

    /// Number of terms: one per spring, one per cam.
    pub fn len(&self) -> usize {
        self.terms.len()
    }

    /// Whether the set has no terms.
    pub fn is_empty(&self) -> bool {
        self.terms.is_empty()
    }

    /// U_e and its gradient in one pass, the gradient into `out` (as
    /// [`SpringSet::value_gradient_into`]).
    pub fn value_gradient_into(&self, q: &[f64], out: &mut [f64]) -> f64 {
        out.fill(0.0);
        let mut u = 0.0;
        for t in &self.terms {
            match t {
                Term::Element(e, k) => {
                    if *k == 0.0 {
                        continue;
                    }
                    let (v, slope, _) = e.profile.eval(e.deflection(q));
                    u += k * v;
                    for (o, a) in out.iter_mut().zip(&e.coupling) {
                        *o += k * slope * a;
                    }
                }
                Term::Cam { coupling, offset, count, width_bits, coef } => {
                    let (v, slope, _) = spline_sum(coef, *count, f64::from_bits(*width_bits), x(coupling, q) - offset);
                    u += v;
                    for (o, a) in out.iter_mut().zip(coupling) {
                        *o += slope * a;
                    }
                }
            }
        }
        u
    }

    /// ∂U_e/∂q into `out` (as [`SpringSet::gradient_into`]).
    pub fn gradient_into(&self, q: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        for t in &self.terms {
            match t {
                Term::Element(e, k) => {
                    if *k == 0.0 {
                        continue;
                    }
                    let slope = k * e.profile.slope(e.deflection(q));
                    for (o, a) in out.iter_mut().zip(&e.coupling) {
                        *o += slope * a;
                    }
                }
                Term::Cam { coupling, offset, count, width_bits, coef } => {
                    let (_, slope, _) = spline_sum(coef, *count, f64::from_bits(*width_bits), x(coupling, q) - offset);
                    for (o, a) in out.iter_mut().zip(coupling) {
                        *o += slope * a;
                    }
                }
            }
        }
    }
}

/// x = a·q, summed as [`Element::deflection`] does.
impl GroupedSet {
    /// Whether `other` has the same terms as this set up to the stiffnesses (element for element,
    /// cam for cam): a build of these springs, whose rates alone differ.
    pub fn same_elements(&self, other: &GroupedSet) -> bool {
        self.dof == other.dof
            && self.terms.len() == other.terms.len()
            && self.terms.iter().zip(&other.terms).all(|(a, b)| match (a, b) {
                (Term::Element(e, _), Term::Element(f, _)) => e == f,
                (
                    Term::Cam { coupling, offset, count, width_bits, .. },
                    Term::Cam { coupling: c2, offset: o2, count: n2, width_bits: w2, .. },
                ) => coupling == c2 && offset.to_bits() == o2.to_bits() && count == n2 && width_bits == w2,
                _ => false,
            })
    }

    /// U of this set and ∇U of `other` (same elements, see [`GroupedSet::same_elements`]) at q,
    /// with each element's profile evaluated once: a closed-loop run of a build needs the
    /// built springs' torque for the plant and the nominal U for the energy controller. The
    /// figures are those of [`Potential::value`] and [`GroupedSet::gradient_into`] bit for bit.
    pub fn value_and_gradient_of(&self, other: &GroupedSet, q: &[f64], out: &mut [f64]) -> f64 {
        debug_assert!(self.same_elements(other));
        out.fill(0.0);
        // −0.0: the neutral element `Iterator::sum` starts from, so U matches `value` exactly.
        let mut u = -0.0;
        for (mine, theirs) in self.terms.iter().zip(&other.terms) {
            match (mine, theirs) {
                (Term::Element(e, k), Term::Element(_, k_other)) => {
                    let (v, slope, _) = e.profile.eval(e.deflection(q));
                    u += k * v;
                    if *k_other != 0.0 {
                        let slope = k_other * slope;
                        for (o, a) in out.iter_mut().zip(&e.coupling) {
                            *o += slope * a;
                        }
                    }
                }
                (Term::Cam { coupling, offset, count, width_bits, coef }, Term::Cam { coef: coef_other, .. }) => {
                    let (width, d) = (f64::from_bits(*width_bits), x(coupling, q) - offset);
                    u += spline_sum(coef, *count, width, d).0;
                    let (_, slope, _) = spline_sum(coef_other, *count, width, d);
                    for (o, a) in out.iter_mut().zip(coupling) {
                        *o += slope * a;
                    }
                }
                _ => unreachable!("same_elements checked by the caller"),
            }
        }
        u
    }
}

#[inline]
fn x(coupling: &[f64], q: &[f64]) -> f64 {
    coupling.iter().zip(q).map(|(a, q)| a * q).sum::<f64>()
}

impl Potential for GroupedSet {
    fn dof(&self) -> usize {
        self.dof
    }

    fn value(&self, q: &[f64]) -> Result<f64> {
        Ok(self
            .terms
            .iter()
            .map(|t| match t {
                Term::Element(e, k) => k * e.value(q),
                Term::Cam { coupling, offset, count, width_bits, coef } => {
                    spline_sum(coef, *count, f64::from_bits(*width_bits), x(coupling, q) - offset).0
                }
            })
            .sum())
    }

    fn gradient(&self, q: &[f64]) -> Result<DVector<f64>> {
        let mut g = DVector::zeros(q.len());
        GroupedSet::gradient_into(self, q, g.as_mut_slice());
        Ok(g)
    }

    fn gradient_into(&self, q: &[f64], out: &mut [f64]) -> Result<()> {
        GroupedSet::gradient_into(self, q, out);
        Ok(())
    }

    /// Σ k u″ a aᵀ; each entry ((aᵢ aⱼ) u″) k added in term order, as [`SpringSet`]'s sum of
    /// element Hessians computes it, without a matrix per element.
    fn hessian(&self, q: &[f64]) -> Result<DMatrix<f64>> {
        let n = q.len();
        let mut h = DMatrix::zeros(n, n);
        for t in &self.terms {
            let (coupling, curv, k) = match t {
                Term::Element(e, k) => (&e.coupling, e.profile.eval(e.deflection(q)).2, *k),
                Term::Cam { coupling, offset, count, width_bits, coef } => {
                    let (_, _, c) = spline_sum(coef, *count, f64::from_bits(*width_bits), x(coupling, q) - offset);
                    (coupling, c, 1.0)
                }
            };
            for j in 0..n.min(coupling.len()) {
                for i in 0..n.min(coupling.len()) {
                    h[(i, j)] += coupling[i] * coupling[j] * curv * k;
                }
            }
        }
        Ok(h)
    }
}
