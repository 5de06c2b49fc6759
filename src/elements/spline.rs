//! The cam profile: an arbitrary smooth potential V(x) = Σⱼ cⱼ Bⱼ(x) on a coupling x = a·q, as
//! a cubic B-spline (its realisation as a disc cam is `realise::cam`, its file `files::cam`).
//!
//! Spring profiles with k ≥ 0 (linear, cubic, compression) are convex in x, and the exact
//! potential needs non-convex one-dimensional profiles. A disc cam with a spring-loaded roller
//! follower realises any profile bounded below, so a cam is fitted as a cubic B-spline.
//!
//! **Basis.** `count = N` uniform knots t₀ = x_lo < … < t_{N−1} = x_hi, spacing h, and N + 2
//! cardinal cubic B-splines Bⱼ(x) = B((x − x_lo)/h − (j − 1)), j = 0 … N + 1, centred on
//! t₋₁ … t_N. On [x_lo, x_hi] they sum to 1, so adding a constant to every cⱼ adds a constant to
//! V and changes no torque. **Outside the knot span** every Bⱼ continues as its second-order
//! Taylor polynomial at the nearest end: V stays C², Σⱼ Bⱼ = 1 still holds and the torque V′
//! continues along its tangent line (a linear spring beyond the span). The fit's range covers
//! every sample of the region plus a margin, so the continuation only matters when a simulation
//! leaves the region.
//!
//! **Signed coefficients, k ≥ 0.** Each basis function enters the fit twice, as +Bⱼ and −Bⱼ,
//! each with a non-negative stiffness, so cⱼ = k⁺ⱼ − k⁻ⱼ: every solver and the selection keep
//! working with k ≥ 0 and one column per candidate.
//!
//! **Smoothing.** V‴ is constant on each knot interval i: (−cᵢ + 3cᵢ₊₁ − 3cᵢ₊₂ + cᵢ₊₃)/h³, so
//! ∫ V‴² dx = Σᵢ h (Δ³c)ᵢ² / h⁶ exactly: a penalty on the torque's curvature that is a sum of
//! squares of linear forms in c, added to the least-squares problem as extra rows.

use serde::Serialize;

/// One signed B-spline basis function of a cam: which one, on which knots.
///
/// The element carrying it has `offset` = x_lo (the first knot), so its deflection d = x − x_lo.
/// The knot spacing is kept as bits so that the profile stays `Eq` and `Hash`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub struct SplineBasis {
    /// j in 0 … count + 1.
    pub index: u16,
    /// Number of knots N (≥ 4).
    pub count: u16,
    /// Knot spacing h in rad, as `f64::to_bits`.
    pub width_bits: u64,
    /// −Bⱼ instead of +Bⱼ.
    pub negative: bool,
}

impl SplineBasis {
    /// Knot spacing h in rad.
    pub fn width(self) -> f64 {
        f64::from_bits(self.width_bits)
    }

    /// Bⱼ, Bⱼ′, Bⱼ″ (derivatives in x) at deflection d = x − x_lo, with the sign applied.
    #[inline]
    pub fn eval(self, d: f64) -> (f64, f64, f64) {
        let at = SplineAt::new(self.count, self.width(), d);
        let (v, s, c) = at.basis(usize::from(self.index));
        if self.negative { (-v, -s, -c) } else { (v, s, c) }
    }

    /// Text written in the bill of materials' `side` column: `+j/N/h` or `-j/N/h` (h in Rust's
    /// shortest round-trip form, so reading it back gives the same bits).
    pub fn side_text(self) -> String {
        format!("{}{}/{}/{}", if self.negative { "-" } else { "+" }, self.index, self.count, self.width())
    }

    /// Parses [`SplineBasis::side_text`].
    pub fn parse_side(text: &str) -> Result<SplineBasis, String> {
        let bad =
            || format!("a cam basis needs side `+j/N/h` or `-j/N/h` (index, knots, spacing in rad), got \"{text}\"");
        let (negative, rest) = match text.as_bytes().first() {
            Some(b'+') => (false, &text[1..]),
            Some(b'-') => (true, &text[1..]),
            _ => return Err(bad()),
        };
        let parts: Vec<&str> = rest.split('/').collect();
        if parts.len() != 3 {
            return Err(bad());
        }
        let index: u16 = parts[0].trim().parse().map_err(|_| bad())?;
        let count: u16 = parts[1].trim().parse().map_err(|_| bad())?;
        let width: f64 = parts[2].trim().parse().map_err(|_| bad())?;
        if count < 4 || index > count + 1 || !(width.is_finite() && width > 0.0) {
            return Err(bad());
        }
        Ok(SplineBasis { index, count, width_bits: width.to_bits(), negative })
    }
}

/// Where a deflection d = x − x_lo falls on a cam's knots: the point clamped to the knot span
/// and how far beyond it d lies (shared by one basis element, [`SplineBasis::eval`], and a
/// whole cam, [`spline_sum`]).
#[derive(Debug, Clone, Copy)]
struct SplineAt {
    /// Knot spacing h.
    h: f64,
    /// d in units of h, clamped to the knot span [0, N − 1].
    end: f64,
    /// How far d lies beyond the span's nearest end, in units of h (0 inside the span).
    dt: f64,
}

impl SplineAt {
    #[inline]
    fn new(count: u16, h: f64, d: f64) -> SplineAt {
        let span = f64::from(count - 1);
        let t = d / h;
        // Inside the span the basis itself; outside, its Taylor polynomial at the nearest end.
        let end = t.clamp(0.0, span);
        SplineAt { h, end, dt: t - end }
    }

    /// Bⱼ, Bⱼ′, Bⱼ″ (derivatives in x), unsigned.
    #[inline]
    fn basis(self, index: usize) -> (f64, f64, f64) {
        let (h, dt) = (self.h, self.dt);
        let centre = index as f64 - 1.0;
        let (b, b1, b2) = cardinal(self.end - centre);
        (b + dt * (b1 + 0.5 * dt * b2), (b1 + dt * b2) / h, b2 / (h * h))
    }
}

/// V, V′, V″ at deflection d = x − x_lo of the cam V = Σⱼ cⱼ Bⱼ on `count` knots of spacing `h`
/// (`coef`: one coefficient per basis function, N + 2).
///
/// Only the four basis functions whose support holds the point clamped to the span are non-zero
/// there: with the point at u ∈ [0, 1] in knot interval i₀, Bᵢ₀₊ₘ is the m-th cubic piece
/// ((1−u)³, 3u³ − 6u² + 4, −3u³ + 3u² + 3u + 1, u³)/6. Their weighted sums are formed once, and
/// beyond the span continued as a whole along the second-order Taylor polynomial at the end (as
/// each basis function is, see the module notes). The same V as Σⱼ cⱼ [`SplineBasis::eval`] up
/// to rounding (tested), at a fraction of the cost: this is what the fit's evaluation and every
/// as-built build evaluate at each sample.
#[inline]
pub fn spline_sum(coef: &[f64], count: u16, h: f64, d: f64) -> (f64, f64, f64) {
    let at = SplineAt::new(count, h, d);
    // Interval i₀ = ⌊end⌋, the last knot counted in the last interval (u = 1).
    let i0 = if at.end.is_nan() { 0 } else { (at.end.floor() as usize).min(usize::from(count) - 2) };
    let u = at.end - i0 as f64;
    let w = 1.0 - u;
    let (u2, w2) = (u * u, w * w);
    let c = |m: usize| coef.get(i0 + m).copied().unwrap_or(0.0);
    let (c0, c1, c2, c3) = (c(0), c(1), c(2), c(3));
    // B(t) and its derivatives in t = the position in knot units.
    let b =
        (c0 * w2 * w + c1 * (3.0 * u2 * u - 6.0 * u2 + 4.0) + c2 * (3.0 * w2 * w - 6.0 * w2 + 4.0) + c3 * u2 * u) / 6.0;
    let b1 = 0.5 * (-c0 * w2 + c1 * (3.0 * u2 - 4.0 * u) - c2 * (3.0 * w2 - 4.0 * w) + c3 * u2);
    let b2 = c0 * w + c1 * (3.0 * u - 2.0) + c2 * (3.0 * w - 2.0) + c3 * u;
    let dt = at.dt;
    (b + dt * (b1 + 0.5 * dt * b2), (b1 + dt * b2) / h, b2 / (h * h))
}

/// The cardinal cubic B-spline B(t) (support [−2, 2], centred at 0) and its first two
/// derivatives in t.
#[inline]
pub fn cardinal(t: f64) -> (f64, f64, f64) {
    let a = t.abs();
    let sign = if t < 0.0 { -1.0 } else { 1.0 };
    if a < 1.0 {
        (2.0 / 3.0 - a * a + 0.5 * a * a * a, sign * (-2.0 * a + 1.5 * a * a), -2.0 + 3.0 * a)
    } else if a < 2.0 {
        let u = 2.0 - a;
        (u * u * u / 6.0, -sign * 0.5 * u * u, u)
    } else {
        (0.0, 0.0, 0.0)
    }
}

/// Uniform knots over a range of x: first knot, spacing, number of knots.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Knots {
    /// First knot x_lo in rad.
    pub lo: f64,
    /// Spacing h in rad.
    pub width: f64,
    /// Number of knots N.
    pub count: u16,
}

impl Knots {
    /// `count` knots over [lo, hi] widened by `margin` (a fraction of the range) on each side.
    pub fn over(lo: f64, hi: f64, count: u16, margin: f64) -> Knots {
        let span = (hi - lo).max(1e-6);
        let (lo, hi) = (lo - margin * span, hi + margin * span);
        Knots { lo, width: (hi - lo) / f64::from(count - 1), count }
    }

    /// Last knot.
    pub fn hi(&self) -> f64 {
        self.lo + self.width * f64::from(self.count - 1)
    }

    /// Number of basis functions, N + 2.
    pub fn basis_count(&self) -> usize {
        usize::from(self.count) + 2
    }

    /// The j-th basis function with a sign.
    pub fn basis(&self, index: usize, negative: bool) -> SplineBasis {
        SplineBasis {
            index: u16::try_from(index).unwrap_or(u16::MAX),
            count: self.count,
            width_bits: self.width.to_bits(),
            negative,
        }
    }

    /// V, V′, V″ at x for coefficients c (one per basis function).
    pub fn eval(&self, c: &[f64], x: f64) -> (f64, f64, f64) {
        let mut out = (0.0, 0.0, 0.0);
        for (j, cj) in c.iter().enumerate() {
            let (v, s, k) = self.basis(j, false).eval(x - self.lo);
            out.0 += cj * v;
            out.1 += cj * s;
            out.2 += cj * k;
        }
        out
    }

    /// Rows D with ‖D c‖² = ∫ V‴(x)² dx over the knot span: N − 1 rows of N + 2 entries.
    pub fn third_derivative_rows(&self) -> Vec<Vec<f64>> {
        let h = self.width;
        let scale = (h).sqrt() / (h * h * h);
        let n = self.basis_count();
        (0..usize::from(self.count) - 1)
            .map(|i| {
                let mut row = vec![0.0; n];
                for (o, w) in [-1.0, 3.0, -3.0, 1.0].iter().enumerate() {
                    row[i + o] = w * scale;
                }
                row
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn knots() -> Knots {
        Knots::over(-1.3, 2.1, 12, 0.05)
    }

    #[test]
    fn basis_is_a_partition_of_unity_inside_and_outside_the_span() {
        let k = knots();
        let ones = vec![1.0; k.basis_count()];
        for i in 0..=400 {
            let x = k.lo - 1.0 + (k.hi() - k.lo + 2.0) * f64::from(i) / 400.0;
            let (v, s, c) = k.eval(&ones, x);
            assert!((v - 1.0).abs() < 1e-12 && s.abs() < 1e-9 && c.abs() < 1e-7, "x = {x}: {v} {s} {c}");
        }
        // A single basis function is non-negative with its peak 2/3 at its centre.
        let b = k.basis(5, false);
        assert!((b.eval(4.0 * k.width).0 - 2.0 / 3.0).abs() < 1e-14);
        assert_eq!(k.basis(5, true).eval(4.0 * k.width).0, -b.eval(4.0 * k.width).0);
    }

    #[test]
    fn derivatives_match_finite_differences_everywhere() {
        let k = knots();
        let c: Vec<f64> = (0..k.basis_count()).map(|j| ((j * 7 % 5) as f64 - 2.0) * 0.3).collect();
        let h = 1e-6;
        for i in 0..=300 {
            // Through the span and past both ends (the Taylor continuation).
            let x = k.lo - 0.7 + (k.hi() - k.lo + 1.4) * (f64::from(i) + 0.37) / 300.0;
            let (_, s, c2) = k.eval(&c, x);
            let fd1 = (k.eval(&c, x + h).0 - k.eval(&c, x - h).0) / (2.0 * h);
            let fd2 = (k.eval(&c, x + h).1 - k.eval(&c, x - h).1) / (2.0 * h);
            assert!((s - fd1).abs() < 1e-6 * (1.0 + fd1.abs()), "x = {x}: {s} vs {fd1}");
            assert!((c2 - fd2).abs() < 1e-5 * (1.0 + fd2.abs()), "x = {x}: {c2} vs {fd2}");
        }
    }

    #[test]
    fn smoothing_rows_integrate_the_third_derivative() {
        let k = knots();
        let c: Vec<f64> = (0..k.basis_count()).map(|j| (j as f64 * 0.9).sin()).collect();
        let exact: f64 =
            k.third_derivative_rows().iter().map(|r| r.iter().zip(&c).map(|(a, b)| a * b).sum::<f64>().powi(2)).sum();
        // Midpoint rule on V‴ by differences of V″ (V‴ is constant between knots).
        let steps = 20_000;
        let dx = (k.hi() - k.lo) / f64::from(steps);
        let mut integral = 0.0;
        for i in 0..steps {
            let x = k.lo + dx * (f64::from(i) + 0.5);
            let e = 1e-7;
            let v3 = (k.eval(&c, x + e).2 - k.eval(&c, x - e).2) / (2.0 * e);
            integral += v3 * v3 * dx;
        }
        assert!((integral - exact).abs() < 1e-4 * exact, "{integral} vs {exact}");
        // A quadratic has V‴ = 0: coefficients sampled from a quadratic give no penalty.
        let quad: Vec<f64> = (0..k.basis_count()).map(|j| (j as f64 - 3.0).powi(2) - 1.0 / 3.0).collect();
        let p: f64 = k
            .third_derivative_rows()
            .iter()
            .map(|r| r.iter().zip(&quad).map(|(a, b)| a * b).sum::<f64>().powi(2))
            .sum();
        assert!(p < 1e-12);
    }

    /// Torque samples of a potential built from known coefficients, fitted with the ± columns
    /// and NNLS (k ≥ 0) as the fit does: the coefficients come back up to the free constant.
    #[test]
    fn known_coefficients_are_recovered_with_signed_columns() {
        use crate::solve::lsq::Gram;
        use crate::solve::nnls::{NnlsSettings, nnls};
        use nalgebra::{DMatrix, DVector};
        let k = Knots::over(-1.0, 2.0, 10, 0.0);
        let n = k.basis_count();
        let truth: Vec<f64> = (0..n).map(|j| 2.0 * (j as f64 * 1.3).sin() - 0.5).collect();
        let xs: Vec<f64> = (0..400).map(|i| -1.0 + 3.0 * f64::from(i) / 399.0).collect();
        let a = DMatrix::from_fn(xs.len(), 2 * n, |r, col| k.basis(col / 2, col % 2 == 1).eval(xs[r] - k.lo).1);
        let b = DVector::from_iterator(xs.len(), xs.iter().map(|&x| k.eval(&truth, x).1));
        let sol = nnls(&Gram::from_rows(&a, &b), 0.0, &NnlsSettings::default()).unwrap();
        let c: Vec<f64> = (0..n).map(|j| sol.k[2 * j] - sol.k[2 * j + 1]).collect();
        let shift = truth[0] - c[0];
        for j in 0..n {
            assert!((c[j] + shift - truth[j]).abs() < 1e-8, "c[{j}] = {} vs {}", c[j] + shift, truth[j]);
        }
    }

    #[test]
    fn side_text_round_trips() {
        let b = knots().basis(7, true);
        assert_eq!(SplineBasis::parse_side(&b.side_text()).unwrap(), b);
        for bad in ["", "3/12/0.1", "+3/12", "+20/12/0.1", "+3/12/-1", "+3/2/0.1", "+a/12/0.1"] {
            assert!(SplineBasis::parse_side(bad).is_err(), "{bad}");
        }
    }
}
