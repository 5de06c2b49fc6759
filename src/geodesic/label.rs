//! Mode labels: which strict mode a configuration lies on.
//!
//! Every configuration q in the region lies on exactly one geodesic from q_eq, the one with
//! initial velocity v = log(q). The mode is the direction of v up to sign. Controllers need the
//! label and its gradient, and both follow from v(q) and ∂v/∂q = (d exp_v)⁻¹, so this module
//! provides that pair as a [`LogField`] in two flavours:
//!
//! * [`ExactLog`]: Newton shooting ([`LogMap`]), warm-started from the previous query — exact to
//!   the integrator's tolerance, tens of microseconds per query;
//! * [`LogTable`]: for two joints, v tabulated on a grid over the region with its exact
//!   derivatives and interpolated by bicubic Hermite patches — C¹, about a microsecond per
//!   query. Its error against the exact label is measured when it is built
//!   ([`LogTable::label_error`]) and reported.
//!
//! From v: the angle label θ = 2·atan2(v₂, v₁) for two joints ([`angle_label`]); for three or
//! more joints the mode is the line ±u of u = Lᵀv/|Lᵀv| in the metric frame at q_eq, and the
//! distance to a desired mode u_d is Δ = 2·∠(±u, u_d) ∈ [0, π] ([`sphere_distance`]) — the
//! same doubling that makes θ a function of the line ±v. The exact potential ½ω²r² also
//! follows: r² = vᵀ M(q_eq) v.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::geodesic::logmap::{LogMap, LogSettings, wrap_angle};
use crate::geodesic::{Fan, MetricFrame, Shooter};
use crate::model::Chain;
use crate::numerics::ode::OdeSettings;

/// v = log(q) and ∂v/∂q (row-major n × n: dvdq[i·n + j] = ∂vᵢ/∂qⱼ).
#[derive(Debug, Clone, PartialEq)]
pub struct LogValue {
    /// The initial velocity of the geodesic through q.
    pub v: Vec<f64>,
    /// Its derivative with respect to q.
    pub dvdq: Vec<f64>,
}

impl LogValue {
    /// Zeros for n joints.
    pub fn zeros(n: usize) -> Self {
        LogValue { v: vec![0.0; n], dvdq: vec![0.0; n * n] }
    }
}

/// Something that evaluates v = log(q) and ∂v/∂q.
pub trait LogField: Send {
    /// Evaluates at q into `out`.
    fn eval(&mut self, q: &[f64], out: &mut LogValue) -> Result<()>;
}

/// The exact log map with warm starts.
#[derive(Clone)]
pub struct ExactLog<'a> {
    log: LogMap<'a>,
    shooter: Shooter<'a>,
    last: Option<(DVector<f64>, DVector<f64>, DMatrix<f64>)>,
}

impl<'a> ExactLog<'a> {
    /// The exact log map of `q_eq`.
    pub fn new(chain: &'a Chain, q_eq: &DVector<f64>, ode: OdeSettings) -> Self {
        let log = LogMap::new(chain, q_eq, ode, LogSettings::default());
        let shooter = log.shooter();
        ExactLog { log, shooter, last: None }
    }
}

impl ExactLog<'_> {
    /// The exact log map at q with Newton started from `guess` (e.g. a table's value).
    pub fn eval_from(&mut self, q: &[f64], guess: &[f64], out: &mut LogValue) -> Result<()> {
        let qv = DVector::from_column_slice(q);
        let p = self.log.solve(&mut self.shooter, &qv, Some(&DVector::from_column_slice(guess)))?;
        self.store(qv, p, out)
    }

    fn store(&mut self, qv: DVector<f64>, p: crate::geodesic::LogPoint, out: &mut LogValue) -> Result<()> {
        let n = qv.len();
        let inv = p
            .jacobian
            .clone()
            .try_inverse()
            .ok_or_else(|| Error::numerical("mode label", "d exp is singular (a conjugate point)"))?;
        out.v.copy_from_slice(p.v.as_slice());
        for i in 0..n {
            for j in 0..n {
                out.dvdq[i * n + j] = inv[(i, j)];
            }
        }
        self.last = Some((qv, p.v, p.jacobian));
        Ok(())
    }
}

impl LogField for ExactLog<'_> {
    fn eval(&mut self, q: &[f64], out: &mut LogValue) -> Result<()> {
        let n = q.len();
        let qv = DVector::from_column_slice(q);
        // The same point twice in a row (the potential and the mode controller of one
        // right-hand side both ask): reuse.
        if let Some((q0, v0, j0)) = &self.last
            && q0 == &qv
            && let Some(inv) = j0.clone().try_inverse()
        {
            out.v.copy_from_slice(v0.as_slice());
            for i in 0..n {
                for j in 0..n {
                    out.dvdq[i * n + j] = inv[(i, j)];
                }
            }
            return Ok(());
        }
        if (&qv - self.log.q_eq()).amax() == 0.0 {
            out.v.fill(0.0);
            out.dvdq.fill(0.0);
            for i in 0..n {
                out.dvdq[i * n + i] = 1.0;
            }
            return Ok(());
        }
        // Warm start from the previous query: v + (d exp)⁻¹ Δq, if it was close.
        let guess = self.last.as_ref().and_then(|(q0, v0, j0)| {
            let dq = &qv - q0;
            (dq.amax() < 0.2).then(|| j0.clone().lu().solve(&dq).map(|dv| v0 + dv)).flatten()
        });
        let p = self.log.solve(&mut self.shooter, &qv, guess.as_ref())?;
        self.store(qv, p, out)
    }
}

/// The log map of a two-joint arm tabulated on a grid and interpolated by bicubic Hermite
/// patches from the exact values and derivatives at the nodes (cross derivatives by central
/// differences of the node derivatives). Queries outside the grid fall back to the exact log map.
#[derive(Clone)]
pub struct LogTable<'a> {
    x: Vec<f64>,
    y: Vec<f64>,
    /// Per node: v₁, v₂, ∂v/∂q₁ (2), ∂v/∂q₂ (2), ∂²v/∂q₁∂q₂ (2); NaN where the log map failed.
    nodes: Vec<[f64; 8]>,
    /// Per cell (i, j) at j·(nx − 1) + i: whether its four nodes are finite (else the exact log
    /// map answers there), decided once here rather than at every evaluation.
    finite_cells: Vec<bool>,
    fallback: ExactLog<'a>,
}

impl<'a> LogTable<'a> {
    /// Tabulates the log map over the bounding box of `fan` (the region) enlarged by `margin`
    /// (a fraction of its size) on a grid of `nx` × `ny` nodes. Rows are computed in parallel,
    /// each sweeping its nodes with warm starts; the result does not depend on the thread count.
    pub fn build(
        chain: &'a Chain,
        q_eq: &DVector<f64>,
        fan: &Fan,
        ode: OdeSettings,
        nx: usize,
        ny: usize,
        margin: f64,
    ) -> Result<LogTable<'a>> {
        if chain.dof() != 2 {
            return Err(Error::Setting {
                field: "label".into(),
                reason: "a tabulated label needs two joints; use the exact label".into(),
            });
        }
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for g in &fan.geodesics {
            for i in 0..g.len() {
                for k in 0..2 {
                    lo[k] = lo[k].min(g.q(i)[k]);
                    hi[k] = hi[k].max(g.q(i)[k]);
                }
            }
        }
        for k in 0..2 {
            let pad = margin * (hi[k] - lo[k]);
            lo[k] -= pad;
            hi[k] += pad;
        }
        let grid =
            |n: usize, a: f64, b: f64| (0..n).map(|i| a + (b - a) * i as f64 / (n - 1) as f64).collect::<Vec<_>>();
        let (x, y) = (grid(nx.max(4), lo[0], hi[0]), grid(ny.max(4), lo[1], hi[1]));
        let rows: Vec<Vec<[f64; 6]>> = y
            .par_iter()
            .map(|&yy| {
                // Sweep outward from the node nearest q₁ = q_eq,₁ so warm starts stay short.
                let mut field = ExactLog::new(chain, q_eq, ode);
                let mut out = LogValue::zeros(2);
                let start = x
                    .iter()
                    .enumerate()
                    .min_by(|a, b| (a.1 - q_eq[0]).abs().total_cmp(&(b.1 - q_eq[0]).abs()))
                    .map(|(i, _)| i)
                    .unwrap_or(0);
                let mut row = vec![[f64::NAN; 6]; x.len()];
                let order: Vec<usize> = (start..x.len()).chain((0..start).rev()).collect();
                for (k, &i) in order.iter().enumerate() {
                    if k > 0 && i + 1 == start {
                        field.last = None;
                    }
                    if field.eval(&[x[i], yy], &mut out).is_ok() {
                        row[i] = [out.v[0], out.v[1], out.dvdq[0], out.dvdq[2], out.dvdq[1], out.dvdq[3]];
                    } else {
                        field.last = None;
                    }
                }
                row
            })
            .collect();
        let (nxx, nyy) = (x.len(), y.len());
        let mut nodes = vec![[f64::NAN; 8]; nxx * nyy];
        for j in 0..nyy {
            for i in 0..nxx {
                let r = rows[j][i];
                // ∂²v/∂q₁∂q₂ from the q₂-derivatives of ∂v/∂q₁ at the neighbours.
                let (ja, jb) = (j.saturating_sub(1), (j + 1).min(nyy - 1));
                let a = rows[ja][i];
                let b = rows[jb][i];
                let dy = y[jb] - y[ja];
                nodes[j * nxx + i] = [r[0], r[1], r[2], r[3], r[4], r[5], (b[2] - a[2]) / dy, (b[3] - a[3]) / dy];
            }
        }
        let finite = |k: usize| nodes[k].iter().all(|v| v.is_finite());
        let finite_cells = (0..nyy - 1)
            .flat_map(|j| (0..nxx - 1).map(move |i| (i, j)))
            .map(|(i, j)| {
                finite(j * nxx + i)
                    && finite(j * nxx + i + 1)
                    && finite((j + 1) * nxx + i)
                    && finite((j + 1) * nxx + i + 1)
            })
            .collect();
        Ok(LogTable { x, y, nodes, finite_cells, fallback: ExactLog::new(chain, q_eq, ode) })
    }

    /// Largest |θ_table − θ_exact| in degrees over the samples of `fan` farther than `min_r`
    /// from q_eq (the label is undefined at q_eq), and the number of samples compared.
    pub fn label_error(
        &mut self,
        chain: &Chain,
        q_eq: &DVector<f64>,
        fan: &Fan,
        ode: OdeSettings,
        min_r: f64,
    ) -> Result<(f64, usize)> {
        let mut exact = ExactLog::new(chain, q_eq, ode);
        let (mut a, mut b) = (LogValue::zeros(2), LogValue::zeros(2));
        let mut worst: f64 = 0.0;
        let mut count = 0;
        for g in &fan.geodesics {
            for i in 0..g.len() {
                if g.s(i) < min_r {
                    continue;
                }
                self.eval(g.q(i), &mut a)?;
                exact.eval(g.q(i), &mut b)?;
                let ta = angle_label(&a).0;
                let tb = angle_label(&b).0;
                worst = worst.max(wrap_angle(ta - tb).abs().to_degrees());
                count += 1;
            }
        }
        Ok((worst, count))
    }

    /// The exact log map at q, Newton started from the table's value: one integration with the
    /// Jacobi fields per point inside the table (the table's error, ~1e-7, is below the
    /// Newton shortcut's threshold), Newton from the usual guess outside it.
    pub fn exact(&mut self, q: &[f64], out: &mut LogValue) -> Result<()> {
        let mut guess = LogValue::zeros(q.len());
        if self.cell(q).is_some() && self.eval(q, &mut guess).is_ok() {
            self.fallback.eval_from(q, &guess.v, out)
        } else {
            self.fallback.eval(q, out)
        }
    }

    fn cell(&self, q: &[f64]) -> Option<(usize, usize, f64, f64)> {
        let (x, y) = (&self.x, &self.y);
        if !(q[0] >= x[0] && q[0] <= x[x.len() - 1] && q[1] >= y[0] && q[1] <= y[y.len() - 1]) {
            return None;
        }
        let hx = x[1] - x[0];
        let hy = y[1] - y[0];
        let i = (((q[0] - x[0]) / hx).floor() as usize).min(x.len() - 2);
        let j = (((q[1] - y[0]) / hy).floor() as usize).min(y.len() - 2);
        Some((i, j, (q[0] - x[i]) / hx, (q[1] - y[j]) / hy))
    }
}

/// Cubic Hermite basis values and derivatives at t ∈ [0, 1].
#[inline]
fn hermite(t: f64) -> ([f64; 4], [f64; 4]) {
    let (t2, t3) = (t * t, t * t * t);
    (
        [2.0 * t3 - 3.0 * t2 + 1.0, t3 - 2.0 * t2 + t, -2.0 * t3 + 3.0 * t2, t3 - t2],
        [6.0 * t2 - 6.0 * t, 3.0 * t2 - 4.0 * t + 1.0, -6.0 * t2 + 6.0 * t, 3.0 * t2 - 2.0 * t],
    )
}

impl LogField for LogTable<'_> {
    fn eval(&mut self, q: &[f64], out: &mut LogValue) -> Result<()> {
        let Some((i, j, tx, ty)) = self.cell(q) else { return self.fallback.eval(q, out) };
        let nx = self.x.len();
        if !self.finite_cells[j * (nx - 1) + i] {
            return self.fallback.eval(q, out);
        }
        let corners = [
            &self.nodes[j * nx + i],
            &self.nodes[j * nx + i + 1],
            &self.nodes[(j + 1) * nx + i],
            &self.nodes[(j + 1) * nx + i + 1],
        ];
        let (hx, hy) = (self.x[1] - self.x[0], self.y[1] - self.y[0]);
        let (bx, dbx) = hermite(tx);
        let (by, dby) = hermite(ty);
        // Corner a = (ci, cj) ∈ {0, 1}²: value weight h0/h2, derivative weight h1/h3 (× h).
        for comp in 0..2 {
            let (mut f, mut fx, mut fy) = (0.0, 0.0, 0.0);
            for (k, c) in corners.iter().enumerate() {
                let (ci, cj) = (k % 2, k / 2);
                let (val, dx, dy, dxy) = (c[comp], c[2 + comp], c[4 + comp], c[6 + comp]);
                let (wx, wdx) = (bx[2 * ci], bx[2 * ci + 1] * hx);
                let (wy, wdy) = (by[2 * cj], by[2 * cj + 1] * hy);
                let (gx, gdx) = (dbx[2 * ci] / hx, dbx[2 * ci + 1]);
                let (gy, gdy) = (dby[2 * cj] / hy, dby[2 * cj + 1]);
                f += val * wx * wy + dx * wdx * wy + dy * wx * wdy + dxy * wdx * wdy;
                fx += val * gx * wy + dx * gdx * wy + dy * gx * wdy + dxy * gdx * wdy;
                fy += val * wx * gy + dx * wdx * gy + dy * wx * gdy + dxy * wdx * gdy;
            }
            out.v[comp] = f;
            out.dvdq[comp * 2] = fx;
            out.dvdq[comp * 2 + 1] = fy;
        }
        Ok(())
    }
}

/// θ = 2·atan2(v₂, v₁) wrapped to (−π, π] and ∂θ/∂q, for two joints.
pub fn angle_label(l: &LogValue) -> (f64, [f64; 2]) {
    let (v1, v2) = (l.v[0], l.v[1]);
    let rho2 = (v1 * v1 + v2 * v2).max(1e-300);
    let (d1, d2) = (-2.0 * v2 / rho2, 2.0 * v1 / rho2);
    let theta = wrap_angle(2.0 * v2.atan2(v1));
    (theta, [d1 * l.dvdq[0] + d2 * l.dvdq[2], d1 * l.dvdq[1] + d2 * l.dvdq[3]])
}

/// The distance Δ = 2·∠(±u, u_d) ∈ [0, π] between the mode of q and a desired mode `u_d` (a
/// unit vector in the metric frame), and ∂Δ/∂q; u = Lᵀv/|Lᵀv|.
pub fn sphere_distance(l: &LogValue, frame: &MetricFrame, u_d: &DVector<f64>) -> (f64, Vec<f64>) {
    let n = l.v.len();
    let w = frame.to_frame(&DVector::from_column_slice(&l.v));
    let norm = w.norm().max(1e-300);
    let u = &w / norm;
    let c = u.dot(u_d);
    let sign = if c >= 0.0 { 1.0 } else { -1.0 };
    let cabs = (c * sign).clamp(-1.0, 1.0);
    let delta = 2.0 * cabs.acos();
    // dΔ/du = −2/√(1−c²) · sign · u_d (projected on the tangent of the sphere at u).
    let s = (1.0 - cabs * cabs).max(1e-24).sqrt();
    let du = (u_d - &u * c) * (-2.0 * sign / s);
    // u = w/|w|, w = Lᵀ v: du/dw = (I − u uᵀ)/|w|, dw/dq = Lᵀ ∂v/∂q.
    let dw: DVector<f64> = &du / norm;
    let dw = &dw - &u * u.dot(&dw);
    // dΔ/dv = Lᵀᵀ dw = L dw: use the frame's inverse map transpose.
    let dv = frame.to_frame_transpose(&dw);
    let grad: Vec<f64> = (0..n).map(|j| (0..n).map(|i| dv[i] * l.dvdq[i * n + j]).sum()).collect();
    (delta, grad)
}

/// The mode error of an n-joint arm on the unit sphere of the metric at q_eq, in the tangent
/// space of the current direction (see [`sphere_error`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SphereError {
    /// Δ = 2·∠(±u, u_d) ∈ [0, π]: the doubled angle between the label and the target line.
    pub delta: f64,
    /// The error vector e in frame coordinates, tangent to the sphere at ±u, |e| = Δ, pointing
    /// away from the target (so that −k e pulls towards it).
    pub error: Vec<f64>,
    /// J = 2 (I − uuᵀ) Lᵀ (∂v/∂q) / |Lᵀv| (row-major n × n, frame rows, joint columns): the rate
    /// of the doubled direction, J q̇ = d(2u)/dt.
    pub jacobian: Vec<f64>,
}

impl SphereError {
    /// Zeros for n joints.
    pub fn zeros(n: usize) -> Self {
        SphereError { delta: 0.0, error: vec![0.0; n], jacobian: vec![0.0; n * n] }
    }
}

/// The mode error of q's label against a target line ±`u_d` (a unit vector in the metric frame),
/// as a tangent vector on the metric's unit sphere, with the Jacobian of the label direction.
///
/// Why a vector and not the scalar Δ: for three or more joints the modes form a sphere of
/// dimension n − 1 ≥ 2, and Δ is a cone around the target (its gradient has unit length and
/// turns with the approach direction), so a law on Δ alone damps only the radial part of the
/// error and lets the label circle round the target. The tangent vector e = log_{±u}(u_d), doubled,
/// is smooth through the target (½|e|² = ½Δ²), and J pulls it back to joint space through
/// d(log) = ∂v/∂q. For two joints with the Euclidean frame it is the paper's Δθ along the circle's
/// tangent, and J = t ∂θ/∂q: the paper's law exactly (see `dynamics::control`).
pub fn sphere_error(l: &LogValue, frame: &MetricFrame, u_d: &DVector<f64>, out: &mut SphereError) {
    let n = l.v.len();
    let w = frame.to_frame(&DVector::from_column_slice(&l.v));
    let norm = w.norm().max(1e-300);
    let u = &w / norm;
    let c = u.dot(u_d);
    let sign = if c >= 0.0 { 1.0 } else { -1.0 };
    let a = (c * sign).clamp(-1.0, 1.0);
    let alpha = a.acos();
    out.delta = 2.0 * alpha;
    let sin = (1.0 - a * a).max(0.0).sqrt();
    // 2α/sin α → 2 at the target: the error is smooth there.
    let factor = if sin > 1e-9 { 2.0 * alpha / sin } else { 2.0 };
    for i in 0..n {
        out.error[i] = -factor * (sign * u_d[i] - a * u[i]);
    }
    // J = 2/|w| (I − uuᵀ) Lᵀ ∂v/∂q, column by column.
    for j in 0..n {
        let col = frame.to_frame(&DVector::from_iterator(n, (0..n).map(|i| l.dvdq[i * n + j])));
        let along = u.dot(&col);
        for i in 0..n {
            out.jacobian[i * n + j] = 2.0 * (col[i] - along * u[i]) / norm;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geodesic::{FanSpec, Stop};
    use std::f64::consts::PI;

    fn setup() -> (Chain, DVector<f64>) {
        (Chain::paper_double_pendulum(), DVector::from_vec(vec![0.0, PI / 2.0]))
    }

    #[test]
    fn table_matches_the_exact_log_map() {
        let (chain, q_eq) = setup();
        let ode = OdeSettings::default();
        let fan = Fan::trace(&chain, &q_eq, FanSpec { count: 36, phase: 0.5, stop: Stop::Arc(2.0), spacing: 0.1 }, ode)
            .unwrap();
        let mut table = LogTable::build(&chain, &q_eq, &fan, ode, 61, 61, 0.1).unwrap();
        let (err, count) = table.label_error(&chain, &q_eq, &fan, ode, 0.2).unwrap();
        assert!(count > 500);
        assert!(err < 0.01, "label error {err}°");
        // Newton from the table's value lands on the exact log map.
        let mut refined = LogValue::zeros(2);
        let mut cold = ExactLog::new(&chain, &q_eq, ode);
        let mut reference = LogValue::zeros(2);
        for q in [[0.21, 1.63], [-0.3, 2.6]] {
            table.exact(&q, &mut refined).unwrap();
            cold.eval(&q, &mut reference).unwrap();
            for k in 0..2 {
                assert!((refined.v[k] - reference.v[k]).abs() < 1e-9, "{} vs {}", refined.v[k], reference.v[k]);
            }
        }
        // Values and gradients of v against the exact field at off-grid points.
        let mut exact = ExactLog::new(&chain, &q_eq, ode);
        let (mut a, mut b) = (LogValue::zeros(2), LogValue::zeros(2));
        for q in [[0.13, 1.77], [-0.41, 2.3], [0.52, 0.4]] {
            table.eval(&q, &mut a).unwrap();
            exact.eval(&q, &mut b).unwrap();
            for k in 0..2 {
                assert!((a.v[k] - b.v[k]).abs() < 1e-6, "v {k}: {} vs {}", a.v[k], b.v[k]);
            }
            for k in 0..4 {
                assert!((a.dvdq[k] - b.dvdq[k]).abs() < 1e-3, "dv {k}: {} vs {}", a.dvdq[k], b.dvdq[k]);
            }
        }
    }

    #[test]
    fn label_gradient_and_sphere_distance_agree_for_two_joints() {
        let (chain, q_eq) = setup();
        let frame = MetricFrame::new(&chain.mass_matrix(&q_eq)).unwrap();
        let mut exact = ExactLog::new(&chain, &q_eq, OdeSettings::default());
        let mut l = LogValue::zeros(2);
        let q = [0.35, 1.95];
        exact.eval(&q, &mut l).unwrap();
        let (theta, grad) = angle_label(&l);
        // A desired direction in joint coordinates at angle θ_d/2 from q₁, mapped to the frame.
        let theta_d = theta - 0.4;
        let vd = DVector::from_vec(vec![(theta_d / 2.0).cos(), (theta_d / 2.0).sin()]);
        let ud = frame.to_frame(&vd).normalize();
        let (delta, dgrad) = sphere_distance(&l, &frame, &ud);
        assert!(delta > 0.0);
        // Finite differences of Δ.
        let h = 1e-6;
        for k in 0..2 {
            let mut qp = q;
            let mut qm = q;
            qp[k] += h;
            qm[k] -= h;
            let mut lp = LogValue::zeros(2);
            let mut lm = LogValue::zeros(2);
            exact.eval(&qp, &mut lp).unwrap();
            exact.eval(&qm, &mut lm).unwrap();
            let fd = (sphere_distance(&lp, &frame, &ud).0 - sphere_distance(&lm, &frame, &ud).0) / (2.0 * h);
            assert!((fd - dgrad[k]).abs() < 1e-5 * (1.0 + fd.abs()), "{fd} vs {}", dgrad[k]);
            let fdt = wrap_angle(angle_label(&lp).0 - angle_label(&lm).0) / (2.0 * h);
            assert!((fdt - grad[k]).abs() < 1e-5 * (1.0 + fdt.abs()), "{fdt} vs {}", grad[k]);
        }
    }
}
