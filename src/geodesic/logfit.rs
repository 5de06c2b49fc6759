//! A fitted log map for any number of joints: the mode label without Newton shooting.
//!
//! **What is fitted.** In the scaled metric frame at q_eq, x = Lᵀ(q − q_eq)/R and
//! w = Lᵀ log(q)/R (M(q_eq) = L Lᵀ, R the radius of the fitted ball), the log map is
//! w = x + P(x) with P = O(|x|²): log(q_eq) = 0 and d log = I there. P is a polynomial of total
//! degree 2 … d in x, one per component of w, with coefficients found by least squares on exact
//! pairs (w, x) *and* their derivatives ∂w/∂x, each sample weighted by 1/|x|.
//!
//! **Why this scheme.** The cost per call must not depend on shooting and must stay flat in n:
//! a grid (the two-joint [`super::label::LogTable`]) has kⁿ nodes, 121⁶ for six joints, while
//! a polynomial of degree 5 in six variables has 462 terms. The log map is analytic inside the
//! region (no conjugate point, one geodesic per point), so a low-degree polynomial converges
//! fast there. The data cost no Newton step: the geodesic of frame direction u reaches q at arc
//! length s, so log(q) = s·u exactly, and its Jacobi fields give d exp = Φ_q(s)/s, whence
//! ∂v/∂q = s Φ_q⁻¹ ([`super::shoot::Shooter::jacobi_samples`]). Fitting the derivatives too
//! makes the gradient of the label, which the mode law uses, as good as the label. The weight
//! 1/|x| makes the fit minimise the *relative* error of w, which is the angle of the label
//! direction u = w/|w| (what a controller reads): the angle error is |δw⊥|/|w|. Writing
//! w = x + P with P starting at degree 2 makes that relative error vanish at q_eq rather than
//! blow up where the label is undefined.
//!
//! A Gauss–Newton correction from the fit's value (one exp with its Jacobian) was the other
//! candidate; it is one variational integration per call, 2n + 2n² states at the integrator's
//! tolerance, the bulk of what Newton shooting costs, so it would not meet the target.
//!
//! **Cost.** One call evaluates the monomials and their gradients by a recursion (each monomial
//! is a lower one times one coordinate) and multiplies them by the coefficients in one matrix
//! product: about (n + 1)·n·m multiply–adds for m monomials (at most [`MAX_TERMS`]: m = 165 for
//! three joints at degree 8, 210 for six at degree 4), a few µs. Memory: m·n coefficients
//! (4 kB for three joints, 10 kB for six) plus the scratch basis m·(n + 1). The build traces
//! (3m/(n + 1) or more) directions with their Jacobi fields once (no Newton) and solves one
//! least-squares problem of m unknowns with n right-hand sides: about 0.15–0.4 s for three
//! joints and 1.5 s for six on the 2-core machine (`cargo bench --bench controller`,
//! `BENCHMARKS.md`).
//!
//! **Where it does not serve.** On the shipped three-joint arms the largest label error is 3e-5°
//! (`ur5_pan_lift_elbow`) and 2e-3° (`panda_three`). On `ur5_six` it is 6.61°, and `label =
//! "auto"` keeps the exact log map there (saying so: [`crate::dynamics::scenario::LabelChoice`]).
//! Measured on that arm (its check fan of 180 geodesics, 3600 samples; times under load):
//! - the wrist roll is *not* what the metric is trigonometric in: M(q) does not change at all
//!   when q₆ turns (a cyclic coordinate; it changes by 22 % per radian of wrist 2 and 44 % of the
//!   elbow), so coordinates (cos q₆, sin q₆) cannot help, although q₆ turns by 4.1 rad inside
//!   the ball (the others by 0.39, 0.42, 0.94, 1.23 and 1.12 rad);
//! - a higher degree converges slowly: degree 3 (84 terms) 6.27°, 4 (210) 6.61°, 5 (462) 3.90°
//!   on the default 144 directions; more directions help a little: degree 4 on 600 directions
//!   3.82°, 5 on 1200 2.44°, 6 (924 terms) on 2000 directions 2.03°, built in 115 s;
//! - a smaller ball converges: the fit over 0.5 × the region's extent misses by 1.94°, over
//!   0.25 × by 0.096°, so sub-ball charts would need to be about a quarter of the radius across,
//!   hundreds of them to cover a six-dimensional ball;
//! - a Gauss–Newton correction needs exp and its Jacobian, 10 ms per call
//!   ([`Shooter::exp_jacobian`]; `exp` alone 110 µs): beyond the 20 µs budget (measured again
//!   under heavy load: 0.7 ms, against 2.5 ms for `exp` in the same run; and at load 16: 1.5 ms,
//!   `exp` 79 µs; either way far beyond);
//! - cells ([`crate::geodesic::logcells`]): local quadratic polynomials on a k-d tree fitted to
//!   exact geodesic points, 1.76° with 72 000 geodesics (1.19° with 96 000), the
//!   best of these but not 0.1°; `label = "table"` takes them where they beat the one
//!   polynomial ([`fit_label`]), `auto` does not build them; fitted to the Jacobi fields'
//!   derivatives as well (cubic cells, 24 000 geodesics × 4: the six-joint default), 1.00°,
//!   about twice the build; with this polynomial's form over the inner quarter of the radius
//!   (through q_eq with slope I), 0.025° there, 1.00° still at the edge.
//!
//! **Domain.** The fit covers the geodesic ball of radius R = (1 + margin) × the region's
//! extent. A query whose fitted metric distance |Lᵀv| is beyond R falls back to the exact log
//! map, as the two-joint table does outside its grid. The error reported
//! ([`LogFit::label_error`]) is the doubled angle between the fitted and exact label lines,
//! 2·∠(±u_fit, u), the same measure as the two-joint θ error, on held-out geodesics.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::geodesic::label::{ExactLog, LogField, LogValue};
use crate::geodesic::logcells::{CellSpec, CellTree, line_angle_deg};
pub use crate::geodesic::polynomial::monomial_count;
use crate::geodesic::polynomial::{fill_basis, mat_mul, monomials};
use crate::geodesic::shoot::JacobiSamples;
use crate::geodesic::{Fan, MetricFrame, Shooter, unit_vectors};
use crate::model::Chain;
use crate::numerics::ode::OdeSettings;

/// How a [`LogFit`] is built.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LogFitSpec {
    /// The region's extent (largest arc length from q_eq inside it), √(kg·m²)·rad.
    pub extent: f64,
    /// The fitted ball reaches (1 + margin) × extent, so that a swing a little past the region
    /// still gets the fast label.
    pub margin: f64,
    /// Total degree of the polynomial (≥ 2).
    pub degree: usize,
    /// Directions of the training fan.
    pub directions: usize,
    /// Samples per direction, equally spaced in arc length up to the ball's radius.
    pub radii: usize,
}

impl LogFitSpec {
    /// The default for `n` joints over a region of extent `extent`: the highest degree with at
    /// most [`MAX_TERMS`] monomials (capped at 8, where monomials on the unit ball are still
    /// well conditioned in double precision), and directions enough for about twice as many
    /// conditions as unknowns on each sphere of directions.
    pub fn for_joints(n: usize, extent: f64) -> Self {
        let mut degree = 2;
        while degree < 8 && monomial_count(n, degree + 1) <= MAX_TERMS {
            degree += 1;
        }
        let terms = monomial_count(n, degree);
        LogFitSpec {
            extent,
            margin: 0.1,
            degree,
            directions: (3 * terms / (n + 1)).max(4 * n * n).max(60),
            radii: degree + 2,
        }
    }
}

/// The most monomials a fit uses: what keeps one call within a few µs (degree 8 for three
/// joints, 6 for four, 4 for five and six).
pub const MAX_TERMS: usize = 220;

/// The log map of one equilibrium fitted by a polynomial in the scaled metric frame (see the
/// module docs), with the exact log map beyond its ball.
#[derive(Clone)]
pub struct LogFit<'a> {
    n: usize,
    q_eq: Vec<f64>,
    /// Lᵀ/R (row-major): x = lt·(q − q_eq).
    lt: Vec<f64>,
    /// R·L⁻ᵀ (row-major): v = lt_inv·w.
    lt_inv: Vec<f64>,
    /// What maps x to w.
    model: Model,
    /// Scratch: monomials' values (column 0) and gradients (columns 1 … n).
    basis: DMatrix<f64>,
    /// Scratch: coefᵀ·basis (n × (n + 1)).
    product: DMatrix<f64>,
    /// The last point the fit answered and its value: the potential and the mode controller of
    /// one right-hand side ask at the same point.
    last: Option<(Vec<f64>, LogValue)>,
    fallback: ExactLog<'a>,
}

/// What a [`LogFit`] evaluates: one polynomial over the ball or a tree of cells.
#[derive(Clone)]
enum Model {
    /// One polynomial w = x + P(x) over the whole ball.
    Global {
        /// Monomials by increasing degree: (parent, variable), the monomial being
        /// parent·x[variable]; the first is the constant 1 (its entry unused).
        monomials: Vec<(usize, usize)>,
        /// Coefficients (monomials × n), zero on the rows of degree 0 and 1.
        coef: DMatrix<f64>,
        degree: usize,
    },
    /// Cells with their own polynomials ([`crate::geodesic::logcells`]), shared by the clones
    /// each run takes, and the one polynomial of the inner ball where it answers instead
    /// ([`CellSpec::inner`]).
    Cells { tree: std::sync::Arc<CellTree>, inner: Option<Inner> },
}

/// The polynomial of the inner ball |x| < ρ of a fit by cells: w = x + ρ·P(x/ρ), P of degree
/// 2 … d ([`LogFit::build`]'s form over the ball of radius ρ·R), so exact in value and slope
/// at q_eq.
#[derive(Clone)]
struct Inner {
    /// ρ, a fraction of the fitted ball's radius.
    rho: f64,
    monomials: Vec<(usize, usize)>,
    /// Coefficients (monomials × n), zero on the rows of degree 0 and 1.
    coef: DMatrix<f64>,
    /// Scratch: the monomials' values and gradients at x/ρ.
    basis: DMatrix<f64>,
}

/// Directions of the inner ball's fit per direction of [`LogFitSpec::for_joints`]: its
/// geodesics are short (a quarter of the radius), so four times the default costs well under a
/// second and makes the fit's error the polynomial's, not the sampling's.
const INNER_DIRECTIONS: usize = 4;

/// w = x + ρ·P(x/ρ) and ∂w/∂x = I + ∂P/∂z at z = x/ρ, for P = Σ coef·monomial, with `basis`
/// (monomials × (n + 1)) and `product` (n × (n + 1)) as scratch.
#[allow(clippy::too_many_arguments)]
fn eval_polynomial(
    monomials: &[(usize, usize)],
    coef: &DMatrix<f64>,
    rho: f64,
    x: &[f64],
    basis: &mut DMatrix<f64>,
    product: &mut DMatrix<f64>,
    w: &mut [f64],
    g: &mut [f64],
) {
    let n = x.len();
    let mut z = [0.0f64; 16];
    let z = &mut z[..n];
    for (zi, xi) in z.iter_mut().zip(x) {
        *zi = xi / rho;
    }
    fill_basis(monomials, z, basis);
    product.gemm_tr(1.0, coef, basis, 0.0);
    for i in 0..n {
        w[i] = x[i] + rho * product[(i, 0)];
        for j in 0..n {
            let id = if i == j { 1.0 } else { 0.0 };
            g[i * n + j] = id + product[(i, 1 + j)];
        }
    }
}

/// The scaled metric frame of a fit over the ball of radius R: Lᵀ/R and R·L⁻ᵀ, row-major, with
/// the metric frame the directions are drawn in.
struct Scaling {
    lt: Vec<f64>,
    lt_inv: Vec<f64>,
    frame: MetricFrame,
}

impl Scaling {
    fn new(chain: &Chain, q_eq: &DVector<f64>, radius: f64) -> Result<Scaling> {
        let n = chain.dof();
        let m_eq = chain.mass_matrix(q_eq);
        let frame = MetricFrame::new(&m_eq)?;
        let l = m_eq
            .cholesky()
            .ok_or_else(|| {
                Error::numerical("fitted label", "the mass matrix at the equilibrium is not positive definite")
            })?
            .l();
        let lt_m = l.transpose() / radius;
        let lt_inv_m = lt_m
            .clone()
            .try_inverse()
            .ok_or_else(|| Error::numerical("fitted label", "singular mass matrix at the equilibrium"))?;
        Ok(Scaling { lt: row_major(&lt_m, n), lt_inv: row_major(&lt_inv_m, n), frame })
    }
}

/// An n × n matrix as a row-major slice.
fn row_major(m: &DMatrix<f64>, n: usize) -> Vec<f64> {
    (0..n * n).map(|k| m[(k / n, k % n)]).collect()
}

impl<'a> LogFit<'a> {
    /// Fits the log map of `q_eq` over the ball of `spec` (see the module docs). Directions are
    /// traced in parallel and the least-squares sums are accumulated in direction order, so the
    /// result does not depend on the thread count.
    pub fn build(chain: &'a Chain, q_eq: &DVector<f64>, ode: OdeSettings, spec: LogFitSpec) -> Result<LogFit<'a>> {
        let n = chain.dof();
        if spec.degree < 2 || !(spec.extent.is_finite() && spec.extent > 0.0) {
            return Err(Error::Setting {
                field: "label".into(),
                reason: format!(
                    "a fitted label needs a degree ≥ 2 and a region of positive extent, got degree {} and extent {}",
                    spec.degree, spec.extent
                ),
            });
        }
        let radius = spec.extent * (1.0 + spec.margin);
        let Scaling { lt, lt_inv, frame } = Scaling::new(chain, q_eq, radius)?;
        let monomials = monomials(n, spec.degree);
        let terms = monomials.len();
        let first = 1 + n;
        let fitted = terms - first;
        let arcs: Vec<f64> = (1..=spec.radii).map(|k| radius * k as f64 / spec.radii as f64).collect();
        let dirs = unit_vectors(n, spec.directions, 0.0);
        let traces: Vec<Result<JacobiSamples>> = dirs
            .par_iter()
            .map_init(|| Shooter::new(chain, q_eq, ode), |shooter, u| shooter.jacobi_samples(&frame.to_joint(u), &arcs))
            .collect();
        // Normal equations Nc = b over the monomials of degree ≥ 2, one right-hand side per
        // component of w, accumulated direction by direction.
        let mut normal = DMatrix::<f64>::zeros(fitted, fitted);
        let mut rhs = DMatrix::<f64>::zeros(fitted, n);
        let mut basis = DMatrix::<f64>::zeros(terms, n + 1);
        let rows_per = spec.radii * (n + 1);
        let mut a = DMatrix::<f64>::zeros(rows_per, fitted);
        let mut y = DMatrix::<f64>::zeros(rows_per, n);
        let mut x = vec![0.0; n];
        let mut tmp = vec![0.0; n * n];
        let mut dwdx = vec![0.0; n * n];
        for (u, trace) in dirs.iter().zip(traces) {
            let trace = trace?;
            for (k, ((q, phi), &s)) in trace.iter().zip(&arcs).enumerate() {
                for i in 0..n {
                    x[i] = (0..n).map(|j| lt[i * n + j] * (q[j] - q_eq[j])).sum();
                }
                let xn = x.iter().map(|v| v * v).sum::<f64>().sqrt();
                // ∂v/∂q = s Φ_q⁻¹; ∂w/∂x = (Lᵀ/R) ∂v/∂q (R L⁻ᵀ).
                let phi = DMatrix::from_column_slice(n, n, phi);
                let dvdq = phi.try_inverse().ok_or_else(|| {
                    Error::numerical(
                        "fitted label",
                        format!("d exp is singular at arc length {s:.4} (a conjugate point inside the fitted ball)"),
                    )
                })? * s;
                let dvdq = row_major(&dvdq, n);
                mat_mul(&lt, &dvdq, n, &mut tmp);
                mat_mul(&tmp, &lt_inv, n, &mut dwdx);
                fill_basis(&monomials, &x, &mut basis);
                let weight = 1.0 / xn.max(1e-12);
                let row0 = k * (n + 1);
                for c in 0..fitted {
                    for r in 0..=n {
                        a[(row0 + r, c)] = basis[(first + c, r)] * weight;
                    }
                }
                for i in 0..n {
                    // w = (s/R)·u, P = w − x; ∂P/∂x = ∂w/∂x − I.
                    y[(row0, i)] = (s / radius * u[i] - x[i]) * weight;
                    for j in 0..n {
                        let id = if i == j { 1.0 } else { 0.0 };
                        y[(row0 + 1 + j, i)] = (dwdx[i * n + j] - id) * weight;
                    }
                }
            }
            normal.gemm_tr(1.0, &a, &a, 1.0);
            rhs.gemm_tr(1.0, &a, &y, 1.0);
        }
        // Equilibrate the columns (high-degree monomials are small on the unit ball), then
        // Cholesky.
        let scale: Vec<f64> = (0..fitted).map(|c| 1.0 / normal[(c, c)].max(1e-300).sqrt()).collect();
        for c in 0..fitted {
            for r in 0..fitted {
                normal[(r, c)] *= scale[r] * scale[c];
            }
            for i in 0..n {
                rhs[(c, i)] *= scale[c];
            }
        }
        let chol = normal.cholesky().ok_or_else(|| {
            Error::numerical(
                "fitted label",
                format!(
                    "the least-squares fit of degree {} on {} directions is singular: too few directions",
                    spec.degree, spec.directions
                ),
            )
        })?;
        let sol = chol.solve(&rhs);
        let mut coef = DMatrix::<f64>::zeros(terms, n);
        for c in 0..fitted {
            for i in 0..n {
                coef[(first + c, i)] = sol[(c, i)] * scale[c];
            }
        }
        Ok(LogFit {
            n,
            q_eq: q_eq.as_slice().to_vec(),
            lt,
            lt_inv,
            model: Model::Global { monomials, coef, degree: spec.degree },
            basis,
            product: DMatrix::zeros(n, n + 1),
            last: None,
            fallback: ExactLog::new(chain, q_eq, ode),
        })
    }

    /// Fits the log map of `q_eq` cell by cell ([`crate::geodesic::logcells`]) over the ball of
    /// radius (1 + `margin`) × `extent`, with the exact log map beyond it as [`LogFit::build`].
    pub fn build_cells(
        chain: &'a Chain,
        q_eq: &DVector<f64>,
        ode: OdeSettings,
        extent: f64,
        margin: f64,
        spec: CellSpec,
    ) -> Result<LogFit<'a>> {
        let n = chain.dof();
        if !(extent.is_finite() && extent > 0.0 && margin >= 0.0) {
            return Err(Error::Setting {
                field: "label".into(),
                reason: format!("a fitted label needs a region of positive extent, got extent {extent}"),
            });
        }
        let radius = extent * (1.0 + margin);
        let Scaling { lt, lt_inv, frame } = Scaling::new(chain, q_eq, radius)?;
        let tree = CellTree::build(chain, q_eq, ode, &frame, &lt, &lt_inv, radius, spec)?;
        let terms = tree.terms();
        let inner = if spec.inner > 0.0 {
            let base = LogFitSpec::for_joints(n, spec.inner * radius);
            let inner_spec = LogFitSpec { margin: 0.0, directions: INNER_DIRECTIONS * base.directions, ..base };
            let Model::Global { monomials, coef, .. } = LogFit::build(chain, q_eq, ode, inner_spec)?.model else {
                return Err(Error::numerical("fitted label", "the inner ball's fit is not one polynomial"));
            };
            Some(Inner { rho: spec.inner, basis: DMatrix::zeros(monomials.len(), n + 1), monomials, coef })
        } else {
            None
        };
        Ok(LogFit {
            n,
            q_eq: q_eq.as_slice().to_vec(),
            lt,
            lt_inv,
            model: Model::Cells { tree: std::sync::Arc::new(tree), inner },
            basis: DMatrix::zeros(terms, n + 1),
            product: DMatrix::zeros(n, n + 1),
            last: None,
            fallback: ExactLog::new(chain, q_eq, ode),
        })
    }

    /// The polynomial's total degree (each cell's, for a fit by cells).
    pub fn degree(&self) -> usize {
        match &self.model {
            Model::Global { degree, .. } => *degree,
            Model::Cells { tree, .. } => tree.degree(),
        }
    }

    /// The number of monomials (of every degree; for the global fit, 0 and 1 included: their
    /// coefficients are 0; for cells, per cell).
    pub fn terms(&self) -> usize {
        match &self.model {
            Model::Global { monomials, .. } => monomials.len(),
            Model::Cells { tree, .. } => tree.terms(),
        }
    }

    /// The tree of cells, for a fit by cells.
    pub fn cells(&self) -> Option<&CellTree> {
        match &self.model {
            Model::Global { .. } => None,
            Model::Cells { tree, .. } => Some(tree),
        }
    }

    /// The radius of the inner ball one polynomial serves in a fit by cells, as a fraction of
    /// the fitted ball's ([`CellSpec::inner`]); None without one.
    pub fn inner_radius(&self) -> Option<f64> {
        match &self.model {
            Model::Cells { inner: Some(inner), .. } => Some(inner.rho),
            _ => None,
        }
    }

    /// Bytes the fitted model holds: the coefficients, and for cells their centres, scales and
    /// nodes ([`CellTree::bytes`]) with the inner ball's coefficients.
    pub fn bytes(&self) -> usize {
        let f = std::mem::size_of::<f64>();
        match &self.model {
            Model::Global { coef, .. } => coef.len() * f,
            Model::Cells { tree, inner } => tree.bytes() + inner.as_ref().map_or(0, |i| i.coef.len() * f),
        }
    }

    /// The fit's value at q, or None beyond its ball (|w| > 1, i.e. the fitted metric distance
    /// beyond R).
    fn fitted(&mut self, q: &[f64], out: &mut LogValue) -> bool {
        let n = self.n;
        let mut x = [0.0f64; 16];
        if n > x.len() {
            return false;
        }
        let x = &mut x[..n];
        for i in 0..n {
            x[i] = (0..n).map(|j| self.lt[i * n + j] * (q[j] - self.q_eq[j])).sum();
        }
        // w and g = ∂w/∂x.
        let mut w = [0.0f64; 16];
        let w = &mut w[..n];
        let mut g = [0.0f64; 256];
        let g = &mut g[..n * n];
        match &mut self.model {
            Model::Global { monomials, coef, .. } => {
                eval_polynomial(monomials, coef, 1.0, x, &mut self.basis, &mut self.product, w, g)
            }
            Model::Cells { inner: Some(inner), .. } if x.iter().map(|v| v * v).sum::<f64>() < inner.rho * inner.rho => {
                eval_polynomial(&inner.monomials, &inner.coef, inner.rho, x, &mut inner.basis, &mut self.product, w, g)
            }
            Model::Cells { tree, .. } => tree.eval(x, &mut self.basis, &mut self.product, w, g),
        }
        if w.iter().map(|v| v * v).sum::<f64>() > 1.0 {
            return false;
        }
        for i in 0..n {
            out.v[i] = (0..n).map(|k| self.lt_inv[i * n + k] * w[k]).sum();
        }
        // ∂v/∂q = (R L⁻ᵀ)(∂w/∂x)(Lᵀ/R).
        let mut t = [0.0f64; 256];
        let t = &mut t[..n * n];
        mat_mul(&self.lt_inv, g, n, t);
        mat_mul(t, &self.lt, n, &mut out.dvdq);
        true
    }

    /// Largest doubled angle 2·∠(±u_fit, ±u) between the fitted and the exact label lines, in
    /// degrees, over the samples of `fan` farther than `min_r` from q_eq, and the number of
    /// samples compared. The exact label at a sample is its geodesic's own direction (log(q) =
    /// s·u: the fan is the exact log map, no Newton needed); samples the fit leaves to the exact
    /// fallback count with error 0 (they get the exact label).
    pub fn label_error(&mut self, frame: &MetricFrame, fan: &Fan, min_r: f64) -> Result<(f64, usize)> {
        let mut out = LogValue::zeros(self.n);
        let mut worst: f64 = 0.0;
        let mut count = 0;
        for (g, u) in fan.geodesics.iter().zip(&fan.frame_directions) {
            for i in 0..g.len() {
                if g.s(i) < min_r {
                    continue;
                }
                count += 1;
                if !self.fitted(g.q(i), &mut out) {
                    continue;
                }
                let w = frame.to_frame(&DVector::from_column_slice(&out.v));
                worst = worst.max(line_angle_deg(w.as_slice(), u.as_slice()));
            }
        }
        Ok((worst, count))
    }
}

/// The fitted label of three or more joints, with its error on the held-out fan `check`
/// (samples farther than 5 % of `extent` from q_eq, as [`LogFit::label_error`]): the one
/// polynomial of [`LogFitSpec::for_joints`] where its error is at most `accept_deg` (it costs a
/// fraction of a second to build); else, if `cells`, the cells of [`CellSpec::for_joints`]
/// ([`crate::geodesic::logcells`]) when they do better; else that polynomial.
///
/// `label = "table"` asks for the cells, `auto` only from six joints
/// ([`crate::design::simulate::AUTO_CELLS_FROM_JOINTS`]): on `ur5_six` they reach about 1°
/// (`BENCHMARKS.md`), within the 1.5° the loop allows there, while on fewer joints `auto` holds
/// fits to 0.1° (cells would cost their build only to be rejected, and on `triple_pendulum` they
/// would move its pinned simulation outputs).
pub fn fit_label<'a>(
    chain: &'a Chain,
    q_eq: &DVector<f64>,
    ode: OdeSettings,
    extent: f64,
    check: &Fan,
    accept_deg: f64,
    cells: bool,
) -> Result<(LogFit<'a>, (f64, usize))> {
    let n = chain.dof();
    let frame = MetricFrame::new(&chain.mass_matrix(q_eq))?;
    let min_r = 0.05 * extent;
    let mut fit = LogFit::build(chain, q_eq, ode, LogFitSpec::for_joints(n, extent))?;
    let err = fit.label_error(&frame, check, min_r)?;
    if err.0 <= accept_deg || !cells {
        return Ok((fit, err));
    }
    let margin = LogFitSpec::for_joints(n, extent).margin;
    let mut cells = LogFit::build_cells(chain, q_eq, ode, extent, margin, CellSpec::for_joints(n))?;
    let cells_err = cells.label_error(&frame, check, min_r)?;
    Ok(if cells_err.0 < err.0 { (cells, cells_err) } else { (fit, err) })
}

impl LogField for LogFit<'_> {
    fn eval(&mut self, q: &[f64], out: &mut LogValue) -> Result<()> {
        if let Some((q0, value)) = &self.last
            && q0.as_slice() == q
        {
            out.v.copy_from_slice(&value.v);
            out.dvdq.copy_from_slice(&value.dvdq);
            return Ok(());
        }
        if !self.fitted(q, out) {
            self.last = None;
            return self.fallback.eval(q, out);
        }
        match &mut self.last {
            Some((q0, value)) => {
                q0.copy_from_slice(q);
                value.v.copy_from_slice(&out.v);
                value.dvdq.copy_from_slice(&out.dvdq);
            }
            None => self.last = Some((q.to_vec(), out.clone())),
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
