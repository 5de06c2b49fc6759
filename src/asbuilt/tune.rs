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
//!    step followed by (1) and (2) again and kept only if the residual falls, **down to the drawn
//!    design's own residual on the same fan and no further**: tune restores what the build lost,
//!    it does not redesign. The fit chose the stiffnesses (and the catalogue the offsets) for
//!    more than this fan's residual — the builds' spread, the trims, the mass — which tune cannot
//!    see; below the drawing's residual every offset it moved would trade those for a few
//!    hundredths of a degree on its own fan, and a build measured as drawn would be handed a
//!    dozen settings to make for nothing it lost (issue 42 item 11). The last step that crosses
//!    the drawing's residual is shortened (bisection along it) to the least move that reaches it.
//!
//! The outcome says which ranges bind when (1) or (2) cannot be met.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::design::Design;
use crate::design::tolerance::TrimRule;
use crate::elements::trim::TrimSolution;
use crate::error::Result;
use crate::fit::bill::BomRow;
use crate::geodesic::{Fan, FanSpec, Stop};
use crate::potential::{Potential, SpringSet};

/// |∇U(q_eq)| (N·m) below which the equilibrium counts as restored, relative to the largest
/// element torque scale (1 + max k): where step 1's Gauss–Newton iteration stops.
const GRADIENT_TOLERANCE: f64 = 1e-12;

/// |∇U(q_eq)| relative to the same scale below which the outcome reports the equilibrium
/// restored: looser than [`GRADIENT_TOLERANCE`], since step 1 may stop a little short of that
/// when its line search runs out ([`SMALLEST_STEP`]) and step 3 only keeps steps that leave the
/// constraints no worse.
const RESTORED_TOLERANCE: f64 = 1e-9;

/// Gauss–Newton iterations of step 1 at most. The offsets enter ∇U through smooth profiles, so
/// near the solution a few iterations converge; the cap only ends an iteration that stalls
/// against the bounds.
const EQUILIBRIUM_ITERATIONS: usize = 60;

/// The step fraction at which step 1's backtracking line search (halving from the full step)
/// gives up: the clamped step is then taken as it is and the iteration ends, since the gradient
/// no longer falls along the bounded direction.
const SMALLEST_STEP: f64 = 1e-6;

/// How near (rad) a bound an offset must sit to count as held there when its step pushes
/// outward in step 1: round-off only, so an offset clamped to its bound is held.
const AT_BOUND: f64 = 1e-15;

/// How near a bound a variable counts as at it in step 3: such a variable is left out of the
/// step (clamping would undo its move).
const AT_LIMIT: f64 = 1e-12;

/// How near a bound, as a fraction of its range, a setting is reported `at_limit` ("at the end
/// of its range"): no screw or trim is set to a millionth of its travel, so an offset the
/// iteration left 3.5e-9 rad short of its ±0.2 rad end is at the end for whoever sets it
/// (issue 42 item 11), while step 3 still treats it as free ([`AT_LIMIT`]).
const REPORTED_AT_LIMIT: f64 = 1e-6;

/// The settings of step 3's Levenberg–Marquardt loop ([`LM`]).
struct LevenbergMarquardt {
    /// Steps at most. Each must lower the residual and the fit has already put the designed arm
    /// at its optimum, so the measured arm's is near: a dozen steps take what the freedom left
    /// gives, and bound the cost (every try re-runs steps 1 and 2).
    iterations: usize,
    /// Tries of one step with a growing damping before the loop stops: six tries raise μ by
    /// `damping_up`⁶ = 10⁶ over where the last taken step left it, from a near Gauss–Newton step
    /// to a short gradient step.
    tries: usize,
    /// The damping μ of the first try (added to AᵀA, A the residual's Jacobian in rad per unit
    /// of the variables): small, a near Gauss–Newton step first.
    damping_start: f64,
    /// The factor μ grows by after a refused try (a shorter step, nearer the gradient's
    /// direction).
    damping_up: f64,
    /// The factor μ shrinks by after a taken step (nearer Gauss–Newton again).
    damping_down: f64,
    /// The least μ, so that AᵀA + μ I stays invertible where A loses rank.
    damping_floor: f64,
}

/// Step 3's loop as tune runs it.
const LM: LevenbergMarquardt = LevenbergMarquardt {
    iterations: 12,
    tries: 6,
    damping_start: 1e-3,
    damping_up: 10.0,
    damping_down: 0.3,
    damping_floor: 1e-9,
};

/// Relative step of the constraints' forward differences, h = this × (1 + |z|): offsets in rad
/// and rates in N·m/rad are of order one or more, and the constraints (∇U and ∇²U at q_eq) are
/// smooth, so a step near √ε balances truncation against round-off.
const DIFFERENCE_STEP: f64 = 1e-6;

/// The constraint violation a step may always reach: a step must leave the constraints no
/// worse than they are, but when they already hold to round-off, round-off must not refuse
/// every step.
const FEASIBILITY_FLOOR: f64 = 1e-12;

/// How far above the drawing's residual on tune's fan (relative, squared angles) a build that
/// holds q_eq still counts as drawn ([`Problem::as_drawn`]): round-off of the same sums only.
const AS_DRAWN: f64 = 1e-9;

/// Bisections of [`Problem::shorten`]: the step fraction to 2⁻¹⁰ of the step, far finer than
/// any screw is set.
const SHORTEN_BISECTIONS: usize = 10;

/// Geodesics of the fan from q_eq on which tune judges and lowers the residual: fewer than a
/// fit's default training fan (72 for two joints), since every try of step 3 evaluates the
/// residual on all of them.
const FAN_DIRECTIONS: usize = 48;

/// Samples along each geodesic of that fan: its spacing is the region's extent over this.
const FAN_SAMPLES: f64 = 20.0;

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
    /// The built arm as measured, before any setting is made.
    pub before: State,
    /// The arm with the offsets and trim rates of `settings` made.
    pub after: State,
    /// Offsets and trim rates to set, in BOM order.
    pub settings: Vec<Setting>,
    /// Whether the equilibrium is back at q_eq (|∇U(q_eq)| within tolerance).
    pub equilibrium_restored: bool,
    /// Whether the build lost nothing, so nothing was set: it holds q_eq and its residual on
    /// tune's fan is the drawing's (a build measured as drawn). Every setting is then its
    /// starting value and the trims stay as measured.
    pub as_drawn: bool,
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

/// What step 2 solves with: the Hessian at q_eq without the trims (gravity included), the mass
/// matrix there, and the trims' couplings.
type TrimProblem = (DMatrix<f64>, DMatrix<f64>, Vec<Vec<f64>>);

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
    /// The drawn bill's squared residual angles on `fan` (rates, offsets and trims as designed):
    /// where step 3 stops.
    designed_objective: f64,
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
        for _ in 0..EQUILIBRIUM_ITERATIONS {
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
                    if (z[a] + step[a] > hi && z[a] >= hi - AT_BOUND) || (z[a] + step[a] < lo && z[a] <= lo + AT_BOUND)
                    {
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
                if self.gradient(&trial)?.norm() < before || t < SMALLEST_STEP {
                    z.copy_from_slice(&trial);
                    break;
                }
                t *= 0.5;
            }
            if t < SMALLEST_STEP {
                return Ok(());
            }
        }
        Ok(())
    }

    /// The arm's Hessian without its trims (gravity included), the mass matrix at q_eq and the
    /// trims' couplings: what step 2 solves with.
    fn trim_problem(&self, s: &SpringSet) -> Result<TrimProblem> {
        let q = self.design.q_eq.as_slice();
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
        Ok((h_rest, m, couplings))
    }

    /// The build as it stands when it lost nothing: it holds q_eq (to [`RESTORED_TOLERANCE`])
    /// and its residual on tune's fan is no more than the drawing's ([`AS_DRAWN`]). Then nothing
    /// is set — step 2 would re-set the trims by the rule on tune's fan, which is not the fit's,
    /// and step 3 has nothing to restore — and the trims' w² and mismatch are those they have
    /// (their ranges pinned to their rates, so none binds). None when the build lost something.
    fn as_drawn(&self, z: &[f64]) -> Result<Option<TrimSolution>> {
        if self.gradient(z)?.amax() >= RESTORED_TOLERANCE * self.scale()
            || self.objective(z)? > self.designed_objective * (1.0 + AS_DRAWN)
        {
            return Ok(None);
        }
        let (h_rest, m, couplings) = self.trim_problem(&self.springs(z))?;
        let na = self.adjustable.len();
        let rates = &z[na..];
        let pinned: Vec<[f64; 2]> = rates.iter().map(|&k| [k, k]).collect();
        let mut sol = crate::elements::trim::solve(&h_rest, &m, &couplings, &pinned, rates);
        sol.binding.clear();
        Ok(Some(sol))
    }

    /// Step 2: trim rates by the design's rule.
    fn restore_hessian(&self, z: &mut [f64]) -> Result<TrimSolution> {
        let na = self.adjustable.len();
        let s = self.springs(z);
        let (h_rest, m, couplings) = self.trim_problem(&s)?;
        let ranges: Vec<[f64; 2]> = (0..self.trims.len()).map(|i| self.bounds(na + i)).collect();
        let nominal: Vec<f64> = self.trims.iter().map(|&j| self.bom[j].stiffness).collect();
        // The row frame is there exactly under the residual rule with trims.
        let sol = match &self.row_frame {
            Some(frame) => {
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
        residual_on(self.design, &self.fan, &self.springs(z))
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

/// Whether `value` is at an end of [lo, hi] as a setting is reported: within
/// [`REPORTED_AT_LIMIT`] of the range's width (an empty range: always).
/// Residual angles (rad) of `springs` on `fan`.
fn residual_on(design: &Design, fan: &Fan, springs: &SpringSet) -> Result<DVector<f64>> {
    let a = crate::residual::fan_angles(&design.chain, fan, &springs.grouped())?;
    Ok(DVector::from_iterator(a.len(), a.iter().map(|x| x.angle_deg.to_radians())))
}

fn at_end(value: f64, lo: f64, hi: f64) -> bool {
    let slack = REPORTED_AT_LIMIT * (hi - lo);
    value <= lo + slack || value >= hi - slack
}

/// Tunes a built arm. `bom` is the bill of materials as designed; `measured[j]` the measured
/// rate of row j (None: as designed). A trim's measured rate is where tuning starts (the
/// `before` figures use it); tune then sets the trim's rate.
///
/// The steps of the module's documentation in order: the equilibrium (1), the trims (2), then
/// the residual (3) with (1) and (2) redone after every step; the outcome says what binds.
pub fn tune(design: &Design, bom: &[BomRow], measured: &[Option<f64>]) -> Result<TuneOutcome> {
    let region = design.valid_region()?;
    let extent = region.extent;
    let p = Problem::new(design, bom, measured, extent)?;
    let mut z = p.start(measured);
    let before = state(design, extent, &p.springs(&z))?;
    if let Some(sol) = p.as_drawn(&z)? {
        let mut o = p.outcome(&z, &sol, before, extent, measured)?;
        o.as_drawn = true;
        return Ok(o);
    }
    p.restore_equilibrium(&mut z)?;
    let sol = p.restore_hessian(&mut z)?;
    let sol = p.lower_residual(&mut z, sol)?;
    p.outcome(&z, &sol, before, extent, measured)
}

/// Step 3's linearisation at z: the free variables (those not at a bound), the residual r₀, the
/// residual's Jacobian restricted to the null space of the constraints' (A = J_r N) and that
/// null space N (its last row is w², which the residual does not see).
struct Linearised {
    free: Vec<usize>,
    r0: DVector<f64>,
    a: DMatrix<f64>,
    null: DMatrix<f64>,
}

impl<'a> Problem<'a> {
    /// The problem of tuning `bom` as measured: the adjustable elements and trims, and the
    /// training fan from q_eq (with the trims' rows under the residual rule).
    fn new(design: &'a Design, bom: &'a [BomRow], measured: &[Option<f64>], extent: f64) -> Result<Problem<'a>> {
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
            FanSpec { count: FAN_DIRECTIONS, phase: 0.0, stop, spacing: extent / FAN_SAMPLES },
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
        let designed_objective = residual_on(design, &fan, &designed)?.norm_squared();
        Ok(Problem { design, bom, k, adjustable, trims, fan, trim_columns, row_frame, designed_objective })
    }
}

impl Problem<'_> {
    /// Number of variables.
    fn variables(&self) -> usize {
        self.adjustable.len() + self.trims.len()
    }

    /// The arm as built: no offset moved, the trims at their measured rates (as designed when
    /// not measured).
    fn start(&self, measured: &[Option<f64>]) -> Vec<f64> {
        (0..self.adjustable.len())
            .map(|_| 0.0)
            .chain(self.trims.iter().map(|&j| measured[j].unwrap_or(self.bom[j].stiffness)))
            .collect()
    }

    /// Whether variable v is reported at an end of its range: within [`REPORTED_AT_LIMIT`] of
    /// its range's width (what the settings and the binding ranges say).
    fn reported_at_limit(&self, z: &[f64], v: usize) -> bool {
        let [lo, hi] = self.bounds(v);
        at_end(z[v], lo, hi)
    }

    /// The squared residual angles on the training fan: what step 3 lowers.
    fn objective(&self, z: &[f64]) -> Result<f64> {
        Ok(self.residual(z)?.norm_squared())
    }

    /// The largest constraint violation at z with w².
    fn violation(&self, z: &[f64], w2: f64) -> Result<f64> {
        Ok(self.constraints(z, w2)?.amax())
    }

    /// Step 3: Levenberg–Marquardt steps on the residual within the constraints' null space,
    /// each followed by steps 1 and 2 and taken only when the residual falls and the
    /// constraints get no worse. Returns the trim solution at the final z.
    ///
    /// Stops at the drawn design's residual ([`Problem::designed_objective`]): a step that
    /// crosses it is shortened to the least move along it that reaches it.
    fn lower_residual(&self, z: &mut Vec<f64>, mut sol: TrimSolution) -> Result<TrimSolution> {
        let target = self.designed_objective;
        let mut best = self.objective(z)?;
        let mut mu = LM.damping_start;
        for _ in 0..LM.iterations {
            if best <= target {
                break;
            }
            let Some(lin) = self.linearise(z, &sol)? else { break };
            let Some((trial, tsol, obj)) = self.try_steps(z, &sol, &lin, best, &mut mu)? else { break };
            let (trial, tsol, obj) =
                if obj < target { self.shorten(z, &sol, trial, tsol, obj, target)? } else { (trial, tsol, obj) };
            *z = trial;
            sol = tsol;
            best = obj;
        }
        Ok(sol)
    }

    /// The least fraction t of the step z → `trial` (whose objective `obj` is below `target`)
    /// whose point, with steps 1 and 2 redone, reaches `target`: bisection on t with the end
    /// that reaches it kept, so the result always does and its constraints are no worse than
    /// z's. Points between z and a trial within the bounds stay within them.
    fn shorten(
        &self,
        z: &[f64],
        sol: &TrimSolution,
        trial: Vec<f64>,
        tsol: TrimSolution,
        obj: f64,
        target: f64,
    ) -> Result<(Vec<f64>, TrimSolution, f64)> {
        let allowed = self.violation(z, sol.w2)?.max(FEASIBILITY_FLOOR);
        let mut hi = (trial, tsol, obj);
        let (mut t_lo, mut t_hi) = (0.0, 1.0);
        let end = hi.0.clone();
        for _ in 0..SHORTEN_BISECTIONS {
            let t = 0.5 * (t_lo + t_hi);
            let mut point: Vec<f64> = z.iter().zip(&end).map(|(a, b)| a + t * (b - a)).collect();
            self.restore_equilibrium(&mut point)?;
            let psol = self.restore_hessian(&mut point)?;
            let pobj = self.objective(&point)?;
            if pobj <= target && self.violation(&point, psol.w2)? <= allowed {
                hi = (point, psol, pobj);
                t_hi = t;
            } else {
                t_lo = t;
            }
        }
        Ok(hi)
    }

    /// Step 3's linearisation at z, or None when nothing can move (no variable, every variable at
    /// a bound, or the constraints leave no freedom).
    fn linearise(&self, z: &[f64], sol: &TrimSolution) -> Result<Option<Linearised>> {
        let nv = self.variables();
        if nv == 0 {
            return Ok(None);
        }
        // Free variables: those not at a bound.
        let free: Vec<usize> = (0..nv)
            .filter(|&v| {
                let [lo, hi] = self.bounds(v);
                z[v] > lo + AT_LIMIT && z[v] < hi - AT_LIMIT
            })
            .collect();
        if free.is_empty() {
            return Ok(None);
        }
        let r0 = self.residual(z)?;
        let c0 = self.constraints(z, sol.w2)?;
        // The residual's columns analytically, the constraints' (∇U and ∇²U at q_eq: cheap) by
        // forward differences; the last column is w², which the residual does not see.
        let jr = self.residual_jacobian(z, &free)?.insert_column(free.len(), 0.0);
        let jc = self.constraint_jacobian(z, &free, sol.w2, &c0)?;
        let Some((_, null)) = crate::elements::trim::min_residual(&jc, &c0) else { return Ok(None) };
        if null.ncols() == 0 {
            return Ok(None);
        }
        let a = &jr * &null;
        Ok(Some(Linearised { free, r0, a, null }))
    }

    /// ∂(constraints)/∂(z_free, w²) by forward differences (the variables are offsets in rad and
    /// rates in N·m/rad; w² enters the Hessian constraints only), `c0` the constraints at z.
    fn constraint_jacobian(&self, z: &[f64], free: &[usize], w2: f64, c0: &DVector<f64>) -> Result<DMatrix<f64>> {
        let mut jc = DMatrix::zeros(c0.len(), free.len() + 1);
        for (c, &v) in free.iter().enumerate() {
            let h = DIFFERENCE_STEP * (1.0 + z[v].abs());
            let mut zt = z.to_vec();
            zt[v] += h;
            jc.set_column(c, &((self.constraints(&zt, w2)? - c0) / h));
        }
        let h = DIFFERENCE_STEP * (1.0 + w2.abs());
        jc.set_column(free.len(), &((self.constraints(z, w2 + h)? - c0) / h));
        Ok(jc)
    }

    /// Up to `LM.tries` tries of one step from z, the damping `mu` raised after each refused
    /// one and lowered after the taken one: the new z, its trim solution and objective, or None
    /// when no try lowers the residual.
    fn try_steps(
        &self,
        z: &[f64],
        sol: &TrimSolution,
        lin: &Linearised,
        best: f64,
        mu: &mut f64,
    ) -> Result<Option<(Vec<f64>, TrimSolution, f64)>> {
        let Linearised { free, r0, a, null } = lin;
        for _ in 0..LM.tries {
            let lhs = a.transpose() * a + DMatrix::identity(null.ncols(), null.ncols()) * *mu;
            let Some(y) = lhs.lu().solve(&(-(a.transpose() * r0))) else { break };
            let dz = null * y;
            let mut trial = z.to_vec();
            for (c, &v) in free.iter().enumerate() {
                let [lo, hi] = self.bounds(v);
                trial[v] = (z[v] + dz[c]).clamp(lo, hi);
            }
            self.restore_equilibrium(&mut trial)?;
            let tsol = self.restore_hessian(&mut trial)?;
            let obj = self.objective(&trial)?;
            if obj < best && self.violation(&trial, tsol.w2)? <= self.violation(z, sol.w2)?.max(FEASIBILITY_FLOOR) {
                *mu = (*mu * LM.damping_down).max(LM.damping_floor);
                return Ok(Some((trial, tsol, obj)));
            }
            *mu *= LM.damping_up;
        }
        Ok(None)
    }

    /// The outcome at the tuned z: the figures after, whether each step reached its aim (and
    /// what binds when not), the settings to make and the tuned bill.
    fn outcome(
        &self,
        z: &[f64],
        sol: &TrimSolution,
        before: State,
        extent: f64,
        measured: &[Option<f64>],
    ) -> Result<TuneOutcome> {
        let design = self.design;
        let tuned = self.springs(z);
        let after = state(design, extent, &tuned)?;
        let g = self.gradient(z)?;
        let equilibrium_restored = g.amax() < RESTORED_TOLERANCE * self.scale();
        let hessian_restored = self.trims.is_empty() || sol.restored();
        let trims_reached = self.trims.is_empty() || super::trims_reached(design, sol);
        let mut binding = Vec::new();
        if !equilibrium_restored {
            binding.push(self.equilibrium_binding(z, g.norm(), after.shift_rad));
        }
        binding.extend(self.trim_binding(sol, trims_reached, hessian_restored));
        Ok(TuneOutcome {
            before,
            after,
            settings: self.settings(z),
            equilibrium_restored,
            as_drawn: false,
            trim_rule: design.fit.trim_rule,
            hessian_restored,
            trims_reached,
            w2: sol.w2,
            binding,
            measured_trims: self.measured_trims(z, measured),
            bom: self.tuned_bom(&tuned),
        })
    }

    /// Why the equilibrium is not back: no adjustable element, couplings that span too few
    /// directions, or offset ranges that bind (`gradient` = |∇U(q_eq)|, `shift` the arm's
    /// distance to q_eq).
    fn equilibrium_binding(&self, z: &[f64], gradient: f64, shift: f64) -> String {
        let na = self.adjustable.len();
        let held: Vec<String> = (0..na)
            .filter(|&v| self.reported_at_limit(z, v))
            .map(|v| self.bom[self.adjustable[v].0].id.clone())
            .collect();
        if na == 0 {
            format!(
                "no adjustable element: |∇U(q_eq)| = {gradient:.3e} N·m stays (the arm rests {shift:.2e} rad from q_eq)"
            )
        } else if held.is_empty() {
            format!(
                "the adjustable elements' couplings cannot cancel |∇U(q_eq)| = {gradient:.3e} N·m (they span too few directions)"
            )
        } else {
            format!(
                "the offset ranges of {} bind: |∇U(q_eq)| = {gradient:.3e} N·m remains (the arm rests {shift:.2e} rad from q_eq)",
                held.join(", ")
            )
        }
    }

    /// Why the trims did not reach what the design's rule sets them for: the trim ranges that
    /// bind (none when they did).
    fn trim_binding(&self, sol: &TrimSolution, trims_reached: bool, hessian_restored: bool) -> Option<String> {
        let rule = self.design.fit.trim_rule;
        let names = || -> Vec<String> { sol.binding.iter().map(|&i| self.bom[self.trims[i]].id.clone()).collect() };
        if !trims_reached && rule == TrimRule::Residual {
            return Some(format!(
                "the trim ranges of {} bind: the least-squares residual wants rates beyond them (∇²U(q_eq) − w² M(q_eq) at {:.2e} of ‖M‖)",
                names().join(", "),
                sol.mismatch
            ));
        }
        if !hessian_restored && rule == TrimRule::Hessian {
            let names = names();
            return Some(if names.is_empty() {
                format!("the trims cannot reach ∇²U(q_eq) = w² M(q_eq): mismatch {:.2e} remains", sol.mismatch)
            } else {
                format!(
                    "the trim ranges of {} bind: ∇²U(q_eq) − w² M(q_eq) stays at {:.2e} of ‖M‖",
                    names.join(", "),
                    sol.mismatch
                )
            });
        }
        None
    }

    /// The offsets and trim rates to set, in variable order (the bill's order within each).
    fn settings(&self, z: &[f64]) -> Vec<Setting> {
        let (bom, na) = (self.bom, self.adjustable.len());
        (0..self.variables())
            .map(|v| {
                if v < na {
                    let j = self.adjustable[v].0;
                    Setting {
                        id: bom[j].id.clone(),
                        kind: "offset",
                        designed: bom[j].element.offset,
                        set: bom[j].element.offset + z[v],
                        at_limit: self.reported_at_limit(z, v),
                    }
                } else {
                    let j = self.trims[v - na];
                    Setting {
                        id: bom[j].id.clone(),
                        kind: "trim rate",
                        designed: bom[j].stiffness,
                        set: z[v],
                        at_limit: self.reported_at_limit(z, v),
                    }
                }
            })
            .collect()
    }

    /// The bill as tuned: measured rates, new offsets and trim rates.
    fn tuned_bom(&self, tuned: &SpringSet) -> Vec<BomRow> {
        self.bom
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
            .collect()
    }

    /// One sentence per trim given a measured rate: that rate is the arm before tuning, and the
    /// rate to set.
    fn measured_trims(&self, z: &[f64], measured: &[Option<f64>]) -> Vec<String> {
        let na = self.adjustable.len();
        self.trims
            .iter()
            .enumerate()
            .filter_map(|(i, &j)| {
                measured[j].map(|k| {
                    format!(
                        "{} is a trim: its measured {:.6} N·m/rad is the arm before tuning; set it to {:.6}",
                        self.bom[j].id,
                        k,
                        z[na + i]
                    )
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Issue 42 item 11: an offset 3.5e-9 rad short of its +0.2 rad end is reported at the end;
    /// one a thousandth of its range inside is not.
    #[test]
    fn an_offset_a_hair_from_its_end_is_at_the_end() {
        assert!(at_end(0.2 - 3.5e-9, -0.2, 0.2));
        assert!(at_end(-0.2 + 3.5e-9, -0.2, 0.2));
        assert!(!at_end(0.2 - 4e-4, -0.2, 0.2));
        assert!(!at_end(0.0, -0.2, 0.2));
        assert!(at_end(0.0, 0.0, 0.0));
    }

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
            designed_objective: 0.0,
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
