//! Tuning after the build: with the measured rates, set the adjustable offsets and the trim
//! rates so the built arm rests at q_eq again with its trims set by the design's rule (the
//! least-squares residual, or ∇²U(q_eq) = w² M(q_eq)), then with the freedom left make the
//! residual of the measured set as small as possible.
//!
//! Unknowns: an offset change Δx₀ ∈ [−r, r] per element of an adjustable family (a preload
//! screw, a crank phase), a rate k ∈ [lo, hi] per trim spring (relaxed at q_eq: no torque there),
//! and the squared frequency w² (free). In order of priority:
//!
//! 1. **Equilibrium**: ∇U(q_eq) = Σⱼ kⱼ τⱼ(aⱼ·q_eq − x₀ⱼ − Δx₀ⱼ) aⱼ + ∇U_g = 0. For a linear element
//!    the torque change −kⱼ Δx₀ⱼ aⱼ is linear in Δx₀ⱼ; cranks and the others are linearised and
//!    iterated (Gauss–Newton with the smallest step, bounded: an offset that reaches the end of
//!    its range is held there and the others take over).
//! 2. **Trims**, by the design's `[fit] trim_rule`: with `"residual"` (the default) the trim
//!    rates within their ranges that make the tangentiality rows of the training fan from q_eq
//!    smallest in least squares ([`crate::elements::trim::fit_rows`]); with `"hessian"` the rates
//!    from [`crate::elements::trim::solve`] that give ∇²U(q_eq) = w² M(q_eq). Either with the tuned,
//!    measured elements (an offset change alters a crank's curvature).
//! 3. **Residual**: Levenberg–Marquardt steps on the residual angles of the training fan,
//!    restricted to the null space of (1) — and of (2) under the Hessian rule — linearised, each
//!    step followed by (1) and (2) again and kept only if the residual falls.
//!
//! The outcome says which ranges bind when (1) or (2) cannot be met.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::design::Design;
use crate::design::tolerance::TrimRule;
use crate::error::Result;
use crate::fit::bill::BomRow;
use crate::geodesic::{Fan, FanSpec, Stop};
use crate::potential::{Potential, SpringSet};

/// |∇U(q_eq)| (N·m) below which the equilibrium counts as restored, relative to the largest
/// element torque scale (1 + max k).
const GRADIENT_TOLERANCE: f64 = 1e-12;

/// Figures of the built arm before or after tuning.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct State {
    /// p99 |residual angle| on held-out geodesics from the arm's own equilibrium, degrees.
    pub p99_deg: f64,
    /// max |residual angle|, degrees.
    pub max_deg: f64,
    /// |q′ − q_eq|₂ of its own equilibrium, rad (NaN: none within 0.5 rad).
    pub shift_rad: f64,
    /// ‖∇²U(q′) − w² M(q′)‖_F / ‖w² M(q′)‖_F with the best w² (least squares).
    pub hessian_mismatch: f64,
}

/// One setting to make.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Setting {
    /// BOM id.
    pub id: String,
    /// `offset` or `trim rate`.
    pub kind: &'static str,
    /// Value as designed (offset rad, or the trim's nominal rate N·m/rad).
    pub designed: f64,
    /// Value to set.
    pub set: f64,
    /// Whether the value sits at an end of its range.
    pub at_limit: bool,
}

/// The outcome of `tune`.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TuneOutcome {
    pub before: State,
    pub after: State,
    /// Offsets and trim rates to set, in BOM order.
    pub settings: Vec<Setting>,
    /// Whether the equilibrium is back at q_eq (|∇U(q_eq)| within tolerance).
    pub equilibrium_restored: bool,
    /// What the trims were set for (`[fit] trim_rule`).
    pub trim_rule: TrimRule,
    /// Whether ∇²U(q_eq) = w² M(q_eq) holds again (trims; to [`crate::elements::trim::RESTORED`]).
    /// Under the residual rule the trims trade the Hessian match for the residual farther out,
    /// so it is not expected to hold; `after.hessian_mismatch` says how near it is.
    pub hessian_restored: bool,
    /// Whether the trims reached what the rule sets them for within their ranges (no trim range
    /// binds); true without trims.
    pub trims_reached: bool,
    /// w² of the tuned arm, (rad/s)².
    pub w2: f64,
    /// What binds, in words (empty when everything was restored).
    pub binding: Vec<String>,
    /// Trims given a measured rate: tune starts from it (the `before` figures are the arm with
    /// its trims as measured) and sets a new rate; one sentence per trim.
    pub measured_trims: Vec<String>,
    /// The tuned bill of materials: measured rates, new offsets and trim rates.
    #[serde(skip)]
    pub bom: Vec<BomRow>,
}

/// The tuning problem.
struct Problem<'a> {
    design: &'a Design,
    bom: &'a [BomRow],
    /// Measured rates (trims: their nominal rate).
    k: Vec<f64>,
    /// Indices of adjustable (non-trim) elements and their ranges.
    adjustable: Vec<(usize, f64)>,
    /// Indices of trims.
    trims: Vec<usize>,
    /// Training fan from q_eq for the residual.
    fan: Fan,
    /// The trims' unit rows on `fan` (residual rule): fixed, since the trims stay relaxed at
    /// q_eq whatever the offsets.
    trim_columns: DMatrix<f64>,
    /// `fan`'s rows with the model's part done once (residual rule with trims only): the trim
    /// solve of every trial step evaluates the other springs' rows on it.
    row_frame: Option<crate::fit::robust::RowFrame>,
}

/// Variables: Δx₀ per adjustable element, then the trim rates.
impl Problem<'_> {
    fn springs(&self, z: &[f64]) -> SpringSet {
        let mut s =
            SpringSet { elements: self.bom.iter().map(|r| r.element.clone()).collect(), stiffness: self.k.clone() };
        for (a, &(j, _)) in self.adjustable.iter().enumerate() {
            s.elements[j].offset += z[a];
        }
        let na = self.adjustable.len();
        for (i, &j) in self.trims.iter().enumerate() {
            s.stiffness[j] = z[na + i];
        }
        s
    }

    fn bounds(&self, v: usize) -> [f64; 2] {
        let na = self.adjustable.len();
        if v < na {
            let r = self.adjustable[v].1;
            [-r, r]
        } else {
            self.bom[self.trims[v - na]].adjust.trim_range.unwrap_or([0.0, 0.0])
        }
    }

    fn gradient(&self, z: &[f64]) -> Result<DVector<f64>> {
        let q = self.design.q_eq.as_slice();
        Ok(self.springs(z).gradient(q)? + self.design.chain.gravity_gradient(q))
    }

    fn scale(&self) -> f64 {
        1.0 + self.k.iter().fold(0.0f64, |a, k| a.max(*k))
    }

    /// Step 1: offsets that zero ∇U(q_eq), bounded Gauss–Newton with the smallest steps.
    fn restore_equilibrium(&self, z: &mut [f64]) -> Result<()> {
        let na = self.adjustable.len();
        if na == 0 {
            return Ok(());
        }
        let q = self.design.q_eq.as_slice();
        let n = self.design.dof();
        for _ in 0..60 {
            let g = self.gradient(z)?;
            if g.amax() < GRADIENT_TOLERANCE * self.scale() {
                return Ok(());
            }
            let s = self.springs(z);
            // ∂g/∂Δx₀ⱼ = −kⱼ u″ⱼ aⱼ; offsets held at a bound (pushing outward) are left out.
            let free: Vec<usize> = (0..na).collect();
            let jac = DMatrix::from_fn(n, na, |i, a| {
                let j = self.adjustable[a].0;
                let e = &s.elements[j];
                -self.k[j] * e.profile.eval(e.deflection(q)).2 * e.coupling[i]
            });
            let mut active: Vec<bool> = vec![true; na];
            let mut step = DVector::zeros(na);
            for _ in 0..=na {
                let cols: Vec<usize> = free.iter().copied().filter(|&a| active[a]).collect();
                if cols.is_empty() {
                    break;
                }
                let sub = DMatrix::from_fn(n, cols.len(), |i, c| jac[(i, cols[c])]);
                let Some((dz, _)) = crate::elements::trim::min_residual(&sub, &(-&g)) else { break };
                step.fill(0.0);
                for (c, &a) in cols.iter().enumerate() {
                    step[a] = dz[c];
                }
                // Hold offsets that would leave their range at the bound.
                let mut changed = false;
                for &a in &cols {
                    let [lo, hi] = self.bounds(a);
                    if (z[a] + step[a] > hi && z[a] >= hi - 1e-15) || (z[a] + step[a] < lo && z[a] <= lo + 1e-15) {
                        active[a] = false;
                        changed = true;
                    }
                }
                if !changed {
                    break;
                }
            }
            let before = g.norm();
            let mut t = 1.0;
            loop {
                let trial: Vec<f64> = (0..na)
                    .map(|a| {
                        let [lo, hi] = self.bounds(a);
                        (z[a] + t * step[a]).clamp(lo, hi)
                    })
                    .chain(z[na..].iter().copied())
                    .collect();
                if self.gradient(&trial)?.norm() < before || t < 1e-6 {
                    z.copy_from_slice(&trial);
                    break;
                }
                t *= 0.5;
            }
            if t < 1e-6 {
                return Ok(());
            }
        }
        Ok(())
    }

    /// Step 2: trim rates by the design's rule.
    fn restore_hessian(&self, z: &mut [f64]) -> Result<crate::elements::trim::TrimSolution> {
        let q = self.design.q_eq.as_slice();
        let na = self.adjustable.len();
        let s = self.springs(z);
        let rest = SpringSet {
            elements: (0..s.elements.len())
                .filter(|j| !self.trims.contains(j))
                .map(|j| s.elements[j].clone())
                .collect(),
            stiffness: (0..s.elements.len()).filter(|j| !self.trims.contains(j)).map(|j| s.stiffness[j]).collect(),
        };
        let h_rest = rest.hessian(q)? + self.design.chain.gravity_hessian(q);
        let m = self.design.chain.mass_matrix(&self.design.q_eq);
        let couplings: Vec<Vec<f64>> = self.trims.iter().map(|&j| self.bom[j].element.coupling.clone()).collect();
        let ranges: Vec<[f64; 2]> = (0..self.trims.len()).map(|i| self.bounds(na + i)).collect();
        let nominal: Vec<f64> = self.trims.iter().map(|&j| self.bom[j].stiffness).collect();
        let sol = match self.design.fit.trim_rule {
            TrimRule::Residual if !self.trims.is_empty() => {
                let frame = self.row_frame.as_ref().expect("built with the residual rule's trims");
                let r0 = crate::asbuilt::rows_without_trims(frame, &s, &self.trims);
                let rows = (&self.trim_columns, &r0);
                crate::elements::trim::solve_rows(&h_rest, &m, &couplings, rows, &ranges, &nominal)
            }
            // Without trims the Hessian rule's solve still gives the arm's w² (and its mismatch).
            _ => crate::elements::trim::solve(&h_rest, &m, &couplings, &ranges, &nominal),
        };
        if !self.trims.is_empty() {
            z[na..].copy_from_slice(&sol.rates);
        }
        Ok(sol)
    }

    /// Residual angles (rad) on the training fan from q_eq.
    fn residual(&self, z: &[f64]) -> Result<DVector<f64>> {
        let s = self.springs(z);
        let a = crate::residual::fan_angles(&self.design.chain, &self.fan, &s.grouped())?;
        Ok(DVector::from_iterator(a.len(), a.iter().map(|x| x.angle_deg.to_radians())))
    }

    /// ∂(residual angles)/∂z_v on the training fan for the variables `free`, in the row order of
    /// [`Problem::residual`]. Analytic: a variable moves one element only, so ∂∇U/∂z_v is that
    /// element's coupling a times −k u″(a·q − x₀) (an offset) or u′(a·q − x₀) (a trim's rate), and
    /// ∂θ/∂z_v = (M⁻¹ ∂θ/∂w) · ∂∇U/∂z_v with w = M⁻¹ ∇U. One pass over the fan instead of one
    /// residual evaluation per variable (the forward differences this replaced were three
    /// quarters of a tuned sweep build's cost).
    fn residual_jacobian(&self, z: &[f64], free: &[usize]) -> Result<DMatrix<f64>> {
        let chain = &self.design.chain;
        let n = chain.dof();
        let springs = self.springs(z);
        let grouped = springs.grouped();
        let na = self.adjustable.len();
        let element = |v: usize| if v < na { self.adjustable[v].0 } else { self.trims[v - na] };
        let per: Vec<Result<Vec<f64>>> = self
            .fan
            .geodesics
            .par_iter()
            .map(|g| {
                let mut ws = chain.workspace();
                let (mut grad, mut grav, mut dtheta) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
                let mut rows = Vec::with_capacity(g.len() * free.len());
                for i in 0..g.len() {
                    let q = g.q(i);
                    Potential::gradient_into(&grouped, q, &mut grad)?;
                    chain.gravity_gradient_into(q, &mut grav);
                    for (a, b) in grad.iter_mut().zip(&grav) {
                        *a += b;
                    }
                    if !chain.factor_mass(&mut ws, q) {
                        // The residual is NaN there; the sample gives no direction.
                        rows.extend(std::iter::repeat_n(0.0, free.len()));
                        continue;
                    }
                    ws.solve(&mut grad);
                    crate::residual::angle_gradient(&grad, g.qd(i), &mut dtheta);
                    ws.solve(&mut dtheta);
                    for &v in free {
                        let e = &springs.elements[element(v)];
                        let (_, slope, curvature) = e.profile.eval(e.deflection(q));
                        let along: f64 = e.coupling.iter().zip(&dtheta).map(|(a, d)| a * d).sum();
                        rows.push(if v < na {
                            -springs.stiffness[element(v)] * curvature * along
                        } else {
                            slope * along
                        });
                    }
                }
                Ok(rows)
            })
            .collect();
        let rows: Vec<f64> = per.into_iter().collect::<Result<Vec<_>>>()?.into_iter().flatten().collect();
        Ok(DMatrix::from_row_slice(rows.len() / free.len().max(1), free.len(), &rows))
    }

    /// Constraint values: ∇U(q_eq)/scale and vech(∇²U − w² M) (w² from the trim solve).
    fn constraints(&self, z: &[f64], w2: f64) -> Result<DVector<f64>> {
        let q = self.design.q_eq.as_slice();
        let s = self.springs(z);
        let g = self.gradient(z)? / self.scale();
        let mut v: Vec<f64> = g.iter().copied().collect();
        if !self.trims.is_empty() && self.design.fit.trim_rule == TrimRule::Hessian {
            let m = self.design.chain.mass_matrix(&self.design.q_eq);
            let h = s.hessian(q)? + self.design.chain.gravity_hessian(q) - &m * w2;
            let n = h.nrows();
            for i in 0..n {
                for k in i..n {
                    v.push(h[(i, k)] / m.norm());
                }
            }
        }
        Ok(DVector::from_vec(v))
    }
}

/// Own-equilibrium figures of a spring set.
fn state(design: &Design, extent: f64, springs: &SpringSet) -> Result<State> {
    let nan = State { p99_deg: f64::NAN, max_deg: f64::NAN, shift_rad: f64::NAN, hessian_mismatch: f64::NAN };
    let Some(q) = crate::asbuilt::equilibrium(design, springs) else { return Ok(nan) };
    let (p99, max) = crate::asbuilt::residual_about(
        design,
        extent,
        crate::asbuilt::DIRECTIONS,
        crate::asbuilt::SAMPLES,
        springs,
        &q,
    )?;
    let h = springs.hessian(q.as_slice())? + design.chain.gravity_hessian(q.as_slice());
    let m = design.chain.mass_matrix(&q);
    let w2 = (h.dot(&m)) / m.dot(&m);
    let mismatch = (&h - &m * w2).norm() / (&m * w2).norm();
    Ok(State { p99_deg: p99, max_deg: max, shift_rad: (&q - &design.q_eq).norm(), hessian_mismatch: mismatch })
}

/// Tunes a built arm. `bom` is the bill of materials as designed; `measured[j]` the measured
/// rate of row j (None: as designed). A trim's measured rate is where tuning starts (the
/// `before` figures use it); tune then sets the trim's rate.
pub fn tune(design: &Design, bom: &[BomRow], measured: &[Option<f64>]) -> Result<TuneOutcome> {
    let region = design.valid_region()?;
    let extent = region.extent;
    let trims: Vec<usize> = (0..bom.len()).filter(|&j| bom[j].adjust.trim_range.is_some()).collect();
    let k: Vec<f64> = bom
        .iter()
        .zip(measured)
        .map(|(r, m)| if r.adjust.trim_range.is_some() { r.stiffness } else { m.unwrap_or(r.stiffness) })
        .collect();
    let adjustable: Vec<(usize, f64)> = (0..bom.len())
        .filter(|&j| bom[j].adjust.trim_range.is_none())
        .filter_map(|j| bom[j].adjust.adjust_range.map(|r| (j, r)))
        .collect();
    let stop = match &design.region {
        crate::geodesic::Region::Ball { radius } => Stop::Arc(*radius),
        region => Stop::Region { region, max_arc: design.geodesics.max_arc },
    };
    let fan = Fan::trace(
        &design.chain,
        &design.q_eq,
        FanSpec { count: 48, phase: 0.0, stop, spacing: extent / 20.0 },
        design.geodesics.ode,
    )?;
    let designed = crate::fit::bill::spring_set(bom);
    let row_frame = (design.fit.trim_rule == TrimRule::Residual && !trims.is_empty())
        .then(|| crate::fit::robust::RowFrame::new(&design.chain, &fan, design.fit.frequency));
    // The trims' own rows: they sit relaxed at q_eq whatever tune sets, so their columns are fixed.
    let trim_columns = match &row_frame {
        Some(frame) => frame.columns(trims.iter().map(|&j| &designed.elements[j])),
        None => DMatrix::zeros(0, 0),
    };
    let p = Problem { design, bom, k, adjustable, trims, fan, trim_columns, row_frame };
    let na = p.adjustable.len();
    let nv = na + p.trims.len();
    let mut z: Vec<f64> =
        (0..na).map(|_| 0.0).chain(p.trims.iter().map(|&j| measured[j].unwrap_or(bom[j].stiffness))).collect();
    let before = state(design, extent, &p.springs(&z))?;

    p.restore_equilibrium(&mut z)?;
    let mut sol = p.restore_hessian(&mut z)?;
    let objective = |z: &[f64]| -> Result<f64> { Ok(p.residual(z)?.norm_squared()) };
    let mut best = objective(&z)?;
    let feasible = |z: &[f64], w2: f64| -> Result<f64> { Ok(p.constraints(z, w2)?.amax()) };
    let mut mu = 1e-3;
    for _ in 0..12 {
        if nv == 0 {
            break;
        }
        // Free variables: those not at a bound.
        let free: Vec<usize> = (0..nv)
            .filter(|&v| {
                let [lo, hi] = p.bounds(v);
                z[v] > lo + 1e-12 && z[v] < hi - 1e-12
            })
            .collect();
        if free.is_empty() {
            break;
        }
        let r0 = p.residual(&z)?;
        let c0 = p.constraints(&z, sol.w2)?;
        // Forward differences (the variables are offsets in rad and rates in N·m/rad).
        // The residual's columns analytically, the constraints' (∇U and ∇²U at q_eq: cheap) by
        // forward differences; the last column is w², which the residual does not see.
        let jr = p.residual_jacobian(&z, &free)?.insert_column(free.len(), 0.0);
        let mut jc = DMatrix::zeros(c0.len(), free.len() + 1);
        for (c, &v) in free.iter().enumerate() {
            let h = 1e-6 * (1.0 + z[v].abs());
            let mut zt = z.clone();
            zt[v] += h;
            jc.set_column(c, &((p.constraints(&zt, sol.w2)? - &c0) / h));
        }
        // w² enters the Hessian constraints only.
        let h = 1e-6 * (1.0 + sol.w2.abs());
        jc.set_column(free.len(), &((p.constraints(&z, sol.w2 + h)? - &c0) / h));
        let Some((_, null)) = crate::elements::trim::min_residual(&jc, &c0) else { break };
        if null.ncols() == 0 {
            break;
        }
        let a = &jr * &null;
        let mut improved = false;
        for _ in 0..6 {
            let lhs = a.transpose() * &a + DMatrix::identity(null.ncols(), null.ncols()) * mu;
            let Some(y) = lhs.lu().solve(&(-(a.transpose() * &r0))) else { break };
            let dz = &null * y;
            let mut trial = z.clone();
            for (c, &v) in free.iter().enumerate() {
                let [lo, hi] = p.bounds(v);
                trial[v] = (z[v] + dz[c]).clamp(lo, hi);
            }
            p.restore_equilibrium(&mut trial)?;
            let tsol = p.restore_hessian(&mut trial)?;
            let obj = objective(&trial)?;
            if obj < best && feasible(&trial, tsol.w2)? <= feasible(&z, sol.w2)?.max(1e-12) {
                z = trial;
                sol = tsol;
                best = obj;
                mu = (mu * 0.3).max(1e-9);
                improved = true;
                break;
            }
            mu *= 10.0;
        }
        if !improved {
            break;
        }
    }

    let tuned = p.springs(&z);
    let after = state(design, extent, &tuned)?;
    let g = p.gradient(&z)?;
    let equilibrium_restored = g.amax() < 1e-9 * p.scale();
    let hessian_restored = p.trims.is_empty() || sol.restored();
    let trims_reached = p.trims.is_empty() || super::trims_reached(design, &sol);
    let mut binding = Vec::new();
    let at_limit = |v: usize| {
        let [lo, hi] = p.bounds(v);
        z[v] <= lo + 1e-12 || z[v] >= hi - 1e-12
    };
    if !equilibrium_restored {
        let held: Vec<String> = (0..na).filter(|&v| at_limit(v)).map(|v| bom[p.adjustable[v].0].id.clone()).collect();
        binding.push(if na == 0 {
            format!(
                "no adjustable element: |∇U(q_eq)| = {:.3e} N·m stays (the arm rests {:.2e} rad from q_eq)",
                g.norm(),
                after.shift_rad
            )
        } else if held.is_empty() {
            format!(
                "the adjustable elements' couplings cannot cancel |∇U(q_eq)| = {:.3e} N·m (they span too few directions)",
                g.norm()
            )
        } else {
            format!(
                "the offset ranges of {} bind: |∇U(q_eq)| = {:.3e} N·m remains (the arm rests {:.2e} rad from q_eq)",
                held.join(", "),
                g.norm(),
                after.shift_rad
            )
        });
    }
    if !trims_reached && design.fit.trim_rule == TrimRule::Residual {
        let names: Vec<String> = sol.binding.iter().map(|&i| bom[p.trims[i]].id.clone()).collect();
        binding.push(format!(
            "the trim ranges of {} bind: the least-squares residual wants rates beyond them (∇²U(q_eq) − w² M(q_eq) at {:.2e} of ‖M‖)",
            names.join(", "),
            sol.mismatch
        ));
    }
    if !hessian_restored && design.fit.trim_rule == TrimRule::Hessian {
        let names: Vec<String> = sol.binding.iter().map(|&i| bom[p.trims[i]].id.clone()).collect();
        binding.push(if names.is_empty() {
            format!("the trims cannot reach ∇²U(q_eq) = w² M(q_eq): mismatch {:.2e} remains", sol.mismatch)
        } else {
            format!(
                "the trim ranges of {} bind: ∇²U(q_eq) − w² M(q_eq) stays at {:.2e} of ‖M‖",
                names.join(", "),
                sol.mismatch
            )
        });
    }
    let settings: Vec<Setting> = (0..nv)
        .map(|v| {
            if v < na {
                let j = p.adjustable[v].0;
                Setting {
                    id: bom[j].id.clone(),
                    kind: "offset",
                    designed: bom[j].element.offset,
                    set: bom[j].element.offset + z[v],
                    at_limit: at_limit(v),
                }
            } else {
                let j = p.trims[v - na];
                Setting {
                    id: bom[j].id.clone(),
                    kind: "trim rate",
                    designed: bom[j].stiffness,
                    set: z[v],
                    at_limit: at_limit(v),
                }
            }
        })
        .collect();
    let tuned_bom: Vec<BomRow> = bom
        .iter()
        .enumerate()
        .map(|(j, r)| {
            let mut row = r.clone();
            row.element = tuned.elements[j].clone();
            row.stiffness = tuned.stiffness[j];
            // A cam as built: the same profile, its follower spring at the measured rate.
            if let Some(cam) = row.cam.as_mut().filter(|_| r.stiffness > 0.0) {
                let ratio = tuned.stiffness[j] / r.stiffness;
                cam.build.follower_rate *= ratio;
                cam.max_torque_nm *= ratio;
                cam.preload_nm = cam.preload_nm.map(|p| p * ratio);
            }
            row
        })
        .collect();
    let measured_trims = p
        .trims
        .iter()
        .enumerate()
        .filter_map(|(i, &j)| {
            measured[j].map(|k| {
                format!(
                    "{} is a trim: its measured {:.6} N·m/rad is the arm before tuning; set it to {:.6}",
                    bom[j].id,
                    k,
                    z[na + i]
                )
            })
        })
        .collect();
    Ok(TuneOutcome {
        before,
        after,
        settings,
        equilibrium_restored,
        trim_rule: design.fit.trim_rule,
        hessian_restored,
        trims_reached,
        w2: sol.w2,
        binding,
        measured_trims,
        bom: tuned_bom,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default design's bill (twelve adjustable elements, three trims), fitted on a small fan.
    fn default_bill(design: &Design) -> Vec<BomRow> {
        let catalog = crate::elements::catalog::Catalog::load(design.catalog.as_ref().unwrap(), design.dof()).unwrap();
        let settings = crate::design::fit::FitSettings {
            training_directions: 36,
            training_samples: 20,
            evaluation_directions: 24,
            evaluation_samples: 10,
            builds: 0,
            ..design.fit
        };
        crate::fit::run::fit(design, &catalog, &settings, crate::progress::Progress::none()).unwrap().bom
    }

    /// The analytic residual Jacobian against central differences of the residual itself, on the
    /// default design's bill (twelve adjustable elements, three trims) at a point off the
    /// designed one (offsets moved, trims away from their mid-range).
    #[test]
    fn residual_jacobian_matches_finite_differences() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let design = Design::load(&root.join("designs/double_pendulum.toml")).unwrap();
        let bom = default_bill(&design);
        let trims: Vec<usize> = (0..bom.len()).filter(|&j| bom[j].adjust.trim_range.is_some()).collect();
        let adjustable: Vec<(usize, f64)> = (0..bom.len())
            .filter(|&j| bom[j].adjust.trim_range.is_none())
            .filter_map(|j| bom[j].adjust.adjust_range.map(|r| (j, r)))
            .collect();
        assert!(adjustable.len() >= 10 && trims.len() == 3, "{} adjustable, {} trims", adjustable.len(), trims.len());
        let fan = Fan::trace(
            &design.chain,
            &design.q_eq,
            FanSpec { count: 12, phase: 0.0, stop: Stop::Arc(2.0), spacing: 0.2 },
            design.geodesics.ode,
        )
        .unwrap();
        let k = bom.iter().map(|r| r.stiffness * 1.03).collect();
        let p = Problem {
            design: &design,
            bom: &bom,
            k,
            adjustable,
            trims,
            fan,
            trim_columns: DMatrix::zeros(0, 0),
            row_frame: None,
        };
        let nv = p.adjustable.len() + p.trims.len();
        let z: Vec<f64> = (0..nv)
            .map(|v| {
                if v < p.adjustable.len() { 0.05 * ((v as f64) * 0.7).sin() } else { 1.0 + 0.4 * v as f64 / nv as f64 }
            })
            .collect();
        let free: Vec<usize> = (0..nv).collect();
        let jr = p.residual_jacobian(&z, &free).unwrap();
        let r0 = p.residual(&z).unwrap();
        assert_eq!((jr.nrows(), jr.ncols()), (r0.len(), nv));
        for v in 0..nv {
            let h = 1e-6;
            let (mut zp, mut zm) = (z.clone(), z.clone());
            zp[v] += h;
            zm[v] -= h;
            let fd = (p.residual(&zp).unwrap() - p.residual(&zm).unwrap()) / (2.0 * h);
            let err = (jr.column(v) - &fd).amax();
            assert!(err < 1e-6 * (1.0 + fd.amax()), "variable {v}: |analytic − FD| = {err:.3e} of {:.3e}", fd.amax());
        }
    }

    /// The row frame gives the rows `rows_of` assembles, for any spring set on the same fan.
    #[test]
    fn row_frame_rows_equal_the_assembled_rows() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let design = Design::load(&root.join("designs/double_pendulum.toml")).unwrap();
        let bom = default_bill(&design);
        let fan = Fan::trace(
            &design.chain,
            &design.q_eq,
            FanSpec { count: 12, phase: 0.0, stop: Stop::Arc(2.0), spacing: 0.2 },
            design.geodesics.ode,
        )
        .unwrap();
        let omega = design.fit.frequency;
        let frame = crate::fit::robust::RowFrame::new(&design.chain, &fan, omega);
        let mut springs = crate::fit::bill::spring_set(&bom);
        for (j, k) in springs.stiffness.iter_mut().enumerate() {
            *k *= 1.0 + 0.1 * (j as f64).sin();
        }
        let assembled = crate::fit::robust::rows_of(&design.chain, &fan, &springs, omega);
        let framed = frame.rows(&springs);
        assert_eq!(assembled.len(), framed.len());
        assert!((&assembled - &framed).amax() <= 1e-12 * assembled.amax(), "{:e}", (&assembled - &framed).amax());
        // Its columns are the assembled matrix A (one per element, gravity left out).
        let candidates: Vec<crate::elements::catalog::Candidate> =
            springs.elements.iter().map(|e| crate::elements::catalog::Candidate::bare(e.clone())).collect();
        let req = crate::fit::problem::Requirements { omega, hessian_match: false, monotone: false };
        let a = crate::fit::problem::assemble(&design.chain, &design.q_eq, &fan, &candidates, req).rows;
        let columns = frame.columns(springs.elements.iter());
        assert_eq!(a.shape(), columns.shape());
        assert!(a.amax() > 0.0 && (&a - &columns).amax() <= 1e-12 * a.amax(), "{:e}", (&a - &columns).amax());
    }
}
