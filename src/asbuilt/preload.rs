//! Preload-trimmed cam builds: the adjustment a cam mechanism has of its own.
//!
//! A cam's follower spring (rate k_f, preload p₀ at the base circle) stores the cam's potential,
//! V(x) − min V = ½ k_f ((p₀ + s)² − p₀²), through the stroke s(x) the cam's pitch curve gives.
//! A built follower of rate k_f (1 + δ) scales the whole cam by 1 + δ: the error δ (V − min V)
//! reaches across the cam's whole range, far from q_eq, where trim springs (which restore the
//! Hessian at q_eq only) cannot reach it. Every follower has a preload screw. Set so that the
//! follower presses the base circle with the drawing's force, k_f (1 + δ) p₀′ = k_f p₀ (a force
//! gauge reading, no rate needs measuring), the built cam stores
//!
//! ½ k_f (1 + δ) (s² + 2 p₀′ s) = V − min V + δ · ½ k_f s²,
//!
//! so its error shrinks from δ · ½ k_f (s² + 2 p₀ s) to δ · ½ k_f s², a fraction s / (s + 2 p₀)
//! of it: at most 1 / (1 + 2f) at the largest stroke S with p₀ = f S (the family's
//! `preload_fraction`), and nothing near the cam's minimum. The term ½ k_f s(x)² is a smooth
//! function of x (p₀ > 0); it is projected onto the cam's own B-spline basis (least squares on the
//! realisation's samples), so a preload-trimmed build is the nominal cam plus δ times that
//! projection.

use nalgebra::{DMatrix, DVector};

use crate::elements::Element;
use crate::elements::spline::Knots;
use crate::fit::bill::BomRow;
use crate::potential::{Potential, SpringSet};
use crate::realise::cam::FittedCam;

/// What a preload-trimmed build adds per unit δ of one cam: ½ k_f s(x)² on the cam's basis.
#[derive(Debug, Clone, PartialEq)]
pub struct PreloadTerm {
    /// The cam's id (`C01`): its rows in the bill are `C01.…`.
    pub id: String,
    /// One element per basis function of the cam (the positive ones), offset at the first knot.
    pub elements: Vec<Element>,
    /// Their coefficients, J.
    pub coefficients: Vec<f64>,
    /// Largest |½ k_f s² − its projection| over the samples, J (the projection's error).
    pub projection_error: f64,
}

/// ½ k_f s(x)² of a realised cam projected onto its basis (the knots of its fit).
pub fn term(cam: &FittedCam) -> PreloadTerm {
    let b = cam.realisation.build;
    let knots: &Knots = &cam.knots;
    let m = knots.basis_count();
    let pts = &cam.realisation.points;
    // ½ k_f s² in J: k_f in N/mm × 1000 = N/m, s in mm / 1000 = m.
    let g: Vec<f64> = pts.iter().map(|p| 0.5 * b.follower_rate * p.stroke * p.stroke / 1000.0).collect();
    let mut phi = DMatrix::zeros(pts.len(), m);
    for (i, p) in pts.iter().enumerate() {
        for j in 0..m {
            phi[(i, j)] = knots.basis(j, false).eval(p.x - knots.lo).0;
        }
    }
    let rhs = DVector::from_vec(g.clone());
    let w = phi.clone().svd(true, true).solve(&rhs, 1e-12).unwrap_or_else(|_| DVector::zeros(m));
    let fitted = &phi * &w;
    let projection_error = g.iter().zip(fitted.iter()).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    let element = |j: usize| Element {
        profile: crate::elements::Profile::Spline(knots.basis(j, false)),
        coupling: cam.coupling.clone(),
        offset: knots.lo,
    };
    PreloadTerm {
        id: cam.id.clone(),
        elements: (0..m).map(element).collect(),
        coefficients: w.iter().copied().collect(),
        projection_error,
    }
}

/// The bill's rows of cam `id` (`C01.07+`, …).
fn rows_of<'a>(bom: &'a [BomRow], id: &'a str) -> impl Iterator<Item = usize> + 'a {
    bom.iter()
        .enumerate()
        .filter(move |(_, r)| r.id.split('.').next() == Some(id) && r.id.contains('.'))
        .map(|(i, _)| i)
}

/// A preload-trimmed build of `springs` (the bill's stiffnesses) at the build's stiffness
/// `factors` (one per row, as [`super::draw`] gives them): each cam's rows at their nominal
/// stiffness plus δ_g times its [`PreloadTerm`]; every other row as built. Returns the bill
/// extended by the terms' rows (so trims are still found by their rows) and the spring set.
pub fn build(bom: &[BomRow], springs: &SpringSet, factors: &[f64], terms: &[PreloadTerm]) -> (Vec<BomRow>, SpringSet) {
    let mut f = factors.to_vec();
    let mut rows = bom.to_vec();
    let mut extra = SpringSet { elements: Vec::new(), stiffness: Vec::new() };
    for t in terms {
        let Some(first) = rows_of(bom, &t.id).next() else { continue };
        let delta = factors[first] - 1.0;
        for i in rows_of(bom, &t.id) {
            f[i] = 1.0;
        }
        for (e, c) in t.elements.iter().zip(&t.coefficients) {
            let mut r = bom[first].clone();
            r.element = e.clone();
            r.stiffness = delta * c;
            rows.push(r);
            extra.elements.push(e.clone());
            extra.stiffness.push(delta * c);
        }
    }
    let mut built = springs.scaled(&f);
    built.elements.extend(extra.elements);
    built.stiffness.extend(extra.stiffness);
    (rows, built)
}

/// One preload-trimmed build, index `index` of `s` (the same draw as the untrimmed build of that
/// index): p99 and max |residual angle| about its own equilibrium, degrees, with the trim
/// springs (if the design has any) re-set after the preloads; NaN without a stable equilibrium.
/// `shared` is the trim step's part every build of `design` shares ([`super::TrimShared::of`]).
pub fn run_build(
    design: &crate::design::Design,
    bom: &[BomRow],
    springs: &SpringSet,
    terms: &[PreloadTerm],
    s: &super::BuildSettings,
    (index, shared): (usize, &super::TrimShared),
) -> crate::error::Result<(f64, f64)> {
    let (rows, built) = build(bom, springs, &super::draw(bom, s, index), terms);
    let nan = (f64::NAN, f64::NAN);
    if rows.iter().any(|r| r.adjust.trim_range.is_some()) {
        let q_built = super::equilibrium(design, &built);
        let Some((trimmed, q, _)) = super::trim_build_with(design, &rows, &built, shared, q_built) else {
            return Ok(nan);
        };
        let h = trimmed.hessian(q.as_slice())? + design.chain.gravity_hessian(q.as_slice());
        if h.cholesky().is_none() {
            return Ok(nan);
        }
        return super::residual_about(design, s.extent, s.directions, s.samples, &trimmed, &q);
    }
    match super::equilibrium(design, &built) {
        Some(q) => super::residual_about(design, s.extent, s.directions, s.samples, &built, &q),
        None => Ok(nan),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::realise::cam::realise;

    /// A follower built δ stiff, its preload screw set to the drawing's force on the base circle,
    /// stores V − min V + δ · ½ k_f s² (against (1 + δ)(V − min V) untouched); that error is at
    /// most 1/(1 + 2f) of the untouched one at every stroke, and ½ k_f s² lies in the cam's own
    /// basis to a small fraction of its size, so a preload-trimmed build is the cam plus δ times
    /// the projection.
    #[test]
    fn a_preload_set_by_force_leaves_the_square_of_the_stroke() {
        let knots = Knots::over(-1.3, 2.1, 12, 0.05);
        let c: Vec<f64> = (0..knots.basis_count()).map(|j| 3.0 * (j as f64 * 0.7).sin() + 0.2 * j as f64).collect();
        for f in [0.5, 4.0] {
            let r = realise(&knots, &c, None, 16.0, f, 120.0, 8.0, 30.0, 1000);
            let (kf, p0) = (r.build.follower_rate * 1000.0, r.build.preload / 1000.0);
            assert!((p0 - f * 0.016).abs() < 1e-12);
            let delta = 0.05;
            let p0_set = p0 / (1.0 + delta);
            for p in &r.points {
                let s = p.stroke / 1000.0;
                let stored = 0.5 * kf * (1.0 + delta) * ((p0_set + s).powi(2) - p0_set * p0_set);
                let want = p.potential + delta * 0.5 * kf * s * s;
                assert!((stored - want).abs() <= 1e-9 * (1.0 + want), "{stored} vs {want}");
                assert!(delta * 0.5 * kf * s * s <= delta * p.potential / (1.0 + 2.0 * f) * (1.0 + 1e-9) + 1e-15);
            }
            let cam = FittedCam {
                id: "C01".into(),
                family: "disc cam".into(),
                coupling: vec![1.0, 0.0],
                knots,
                coefficients: c.clone(),
                realisation: r.clone(),
            };
            let t = term(&cam);
            let largest = r.points.iter().map(|p| 0.5 * kf * (p.stroke / 1000.0).powi(2)).fold(0.0, f64::max);
            // Within 1 % of the term's size (0.46 % at f = 0.5, where s is steepest near the cam's
            // minimum, on 12 knots): an error of 1 % of an error already δ small.
            assert!(t.projection_error < 1e-2 * largest, "f = {f}: {} of {largest}", t.projection_error);
            assert_eq!(t.elements.len(), knots.basis_count());
        }
    }
}
