//! Designing for the build: the expected residual over manufacturing deviations.
//!
//! A build scales each stiffness, kᵢ → kᵢ (1 + δᵢ), with δᵢ independent, mean 0 and variance
//! σᵢ² (see [`crate::design::tolerance`]), and it is judged about its *own* equilibrium: that is where
//! it rests and how `sweep` and the as-built figures judge it. To first order the build's
//! gradient at q_eq changes by Δg = Σᵢ δᵢ kᵢ gᵢ (gᵢ = ∇uᵢ(q_eq)), so its equilibrium moves by
//! Δq = −H⁻¹ Δg (H = ∇²U(q_eq), = ω² M(q_eq) with the Hessian match), and the training rows taken
//! about the moved equilibrium change by
//!
//! ΔR = Σᵢ δᵢ kᵢ (Aᵢ − J H⁻¹ gᵢ),
//!
//! where Aᵢ is candidate i's (weighted) column of the rows and J = ∂R/∂(base point) is how the
//! rows of the nominal potential change when the training fan starts elsewhere: the same
//! directions (in the metric frame of the new base point) and arc lengths, traced from
//! q_eq ± ε eⱼ, central differences. Hence
//!
//! E‖R(build)‖² ≈ ‖A k − b‖² + Σᵢ Dᵢᵢ kᵢ²,  Dᵢᵢ = σᵢ² ‖Aᵢ − J H⁻¹ gᵢ‖²:
//!
//! a diagonal added to the normal equations, which every solver and the sparse selection see as
//! one least-squares problem (equivalently extra rows √Dᵢᵢ eᵢ). Charging the rows about the *old*
//! equilibrium instead (Dᵢᵢ = σᵢ² ‖Aᵢ‖²) penalises every preloaded element for a shift the
//! build absorbs, and throws out the useful antagonistic pairs. The expected squared metric
//! shift of the equilibrium, E‖Δq‖²_M = Σᵢ σᵢ² kᵢ² ‖H⁻¹ gᵢ‖²_M, can be penalised as well (an
//! optional weight; tuning after the build can put the equilibrium back instead), or bounded:
//! `[fit] max_shift` holds √(kᵀSk) ≤ s as a second-order cone of the QP ([`ShiftCone`], on by
//! default, added only when the fit without it breaks the bound; see `fit::run`).
//!
//! **Cams.** A cam's potential Σⱼ cⱼ Bⱼ is stored by one follower spring: its rate error scales
//! the whole cam, so all the columns of cam g share one δ_g. With vᵢ = Aᵢ − J H⁻¹ gᵢ and V_g the
//! columns vᵢ of the cam, ΔR = Σ_g δ_g V_g k_g + Σ_springs δᵢ kᵢ vᵢ, and
//!
//! E‖ΔR‖² = Σ_springs σᵢ² ‖vᵢ‖² kᵢ² + Σ_g σ_g² k_gᵀ V_gᵀ V_g k_g:
//!
//! the diagonal of the springs plus, per cam, a block σ_g² V_gᵀ V_g over its columns (and the
//! shift term's block σ_g² (H⁻¹G_g)ᵀ M (H⁻¹G_g)). Charging each column its own δ instead would
//! underrate the spread: the columns of a fitted cam largely cancel, so their independent errors
//! average out where one shared error does not. Only the training rows count: rows appended
//! after them (the cams' smoothing penalty) are no residual of a build.
//!
//! **Trimmed builds.** With trim springs (see [`crate::elements::trim`]) a builder re-sets the trims on
//! every build, and the figures that count are the trimmed ones: weighting the spread above
//! spends nominal accuracy on Hessian errors the trims remove anyway. A trimmed build
//! (`asbuilt::trim_build`) rests where the gradient of the *rest* (everything but the trims)
//! vanishes — the trims are relaxed there — so its equilibrium moves by Δqᵢ = −H_rest⁻¹ gᵢ per
//! unit δᵢ kᵢ (H_rest = ∇²U_rest(q_eq), the Hessian without the trims: not H). Its rows about
//! the moved equilibrium change by
//!
//! uᵢ = Aᵢ + J_t Δqᵢ + Σⱼ Δtᵢⱼ A_trim,j,
//!
//! * J_t = J + Σⱼ t⁰ⱼ Dⱼ aⱼᵀ: J moves the base point with every element fixed (trims relaxed at
//!   q_eq); the trims are re-relaxed at the build's equilibrium, x₀ⱼ → x₀ⱼ + aⱼ·Δq, and
//!   Dⱼ = ∂(rows of trim j)/∂x₀ⱼ (exact by a difference: a linear spring's rows are linear in x₀);
//! * Δtᵢ: the trims re-set so that ∇²U_rest(q′) + Σⱼ tⱼ aⱼaⱼᵀ = w² M(q′) again. To first order
//!   the mismatch they answer is Eᵢ = Hᵢ + Σ_l (∂H_rest/∂q_l − w² ∂M/∂q_l) Δqᵢ\[l\] (Hᵢ = ∇²uᵢ(q_eq),
//!   derivatives by central differences), and the answer is linear in it: Δtᵢ =
//!   [`crate::elements::trim::interior_change`] (Σ Δtⱼ aⱼaⱼᵀ − Δw² M = −Eᵢ with the least ‖Δt‖, w² free;
//!   the ranges are ignored at first order); A_trim,j is trim j's column of the rows.
//!
//! That is the model of [`TrimRule::Hessian`]. With [`TrimRule::Residual`] (the default) the
//! trims are set for the least-squares rows instead: to first order they take out of the moved
//! rows Aᵢ + J_t Δqᵢ their projection on the trims' columns, uᵢ = (I − P_trim)(Aᵢ + J_t Δqᵢ),
//! P_trim the orthogonal projector on span{A_trim,j} (ranges again ignored).
//!
//! The trimmed spread is then Σ σᵢ² kᵢ² ‖uᵢ‖² over springs plus σ_g² k_gᵀ U_gᵀ U_g k_g per cam: the
//! same diagonal and blocks with other vectors ([`trimmed_spread`]), weighted by `trimmed_weight`
//! and added to the untrimmed term. Monte Carlo trimmed builds at ±1 % confirm it (the
//! untrimmed model overstates their spread eightfold; Δq with H instead of H_rest tenfold).

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use super::problem::{Requirements, assemble};
use crate::design::tolerance::TrimRule;
use crate::elements::Element;
use crate::elements::catalog::Candidate;
use crate::elements::group::Columns;
use crate::error::{Error, Result};
use crate::geodesic::{Fan, MetricFrame, Shooter, Stop};
use crate::model::Chain;
use crate::numerics::ode::OdeSettings;
use crate::potential::{Potential, SpringSet};

/// Step of the central differences in the base point, rad. The rows are smooth in the base
/// point; the geodesics are integrated to ≤ 1e-9, so the differences carry ~1e-5 of noise and
/// ~1e-8 of truncation error.
pub const BASE_STEP: f64 = 1e-4;

/// First-order effect of the deviations, per candidate and per unit kᵢ².
#[derive(Debug, Clone, PartialEq)]
pub struct Spread {
    /// Dᵢᵢ = σᵢ² ‖Aᵢ − J H⁻¹ gᵢ‖²: expected squared change of the training rows about the build's
    /// own equilibrium (0 for a cam's columns: their spread is in `blocks`).
    pub rows: DVector<f64>,
    /// σᵢ² ‖H⁻¹ gᵢ‖²_M(q_eq): expected squared metric shift of the equilibrium (rad²·kg·m²; 0 for
    /// a cam's columns).
    pub shift: DVector<f64>,
    /// One block per cam whose columns share one deviation.
    pub blocks: Vec<Block>,
}

/// The spread of one cam: all its columns scale with one δ, so its expected squared change is a
/// quadratic form kᵀ B k over its columns rather than a diagonal.
#[derive(Debug, Clone, PartialEq)]
pub struct Block {
    /// The candidates (columns) of the cam, ascending.
    pub columns: Vec<usize>,
    /// σ² V_gᵀ V_g, V_g the cam's columns of A − J H⁻¹ G.
    pub rows: DMatrix<f64>,
    /// σ² (H⁻¹ G_g)ᵀ M(q_eq) (H⁻¹ G_g): the expected squared metric shift of the equilibrium.
    pub shift: DMatrix<f64>,
    /// F = σ Cᵀ H⁻¹ G_g (n × columns, M(q_eq) = C Cᵀ): FᵀF = `shift`, the cam's rows of the
    /// shift cone's factor ([`ShiftForm`]).
    pub shift_factor: DMatrix<f64>,
}

/// The expected squared metric shift of a build's equilibrium as a sum of squares,
/// E‖Δq‖²_M = kᵀSk = ‖Lᵀk‖²: one row √Sᵢᵢ eᵢᵀ per spring (its own deviation) and n rows
/// σ_g Cᵀ H⁻¹ G_g per cam (one deviation per cam, M(q_eq) = C Cᵀ). Kept by part rather than as a
/// dense p × p factor: the fits of thousands of candidates restrict it to the few columns the
/// selection keeps ([`ShiftForm::factor_on`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ShiftForm {
    /// Sᵢᵢ of each spring (0 for a cam's columns).
    pub diagonal: DVector<f64>,
    /// (columns, F) per cam: FᵀF is its block of S.
    pub blocks: Vec<(Vec<usize>, DMatrix<f64>)>,
}

impl ShiftForm {
    /// The form of a spread's shift term.
    pub fn of(sp: &Spread) -> ShiftForm {
        ShiftForm {
            diagonal: sp.shift.clone(),
            blocks: sp.blocks.iter().map(|b| (b.columns.clone(), b.shift_factor.clone())).collect(),
        }
    }

    /// √(kᵀSk): the builds' RMS metric shift of the equilibrium (first order) at the stiffnesses
    /// `k` (all candidates).
    pub fn rms(&self, k: &[f64]) -> f64 {
        let diag: f64 = k.iter().zip(self.diagonal.iter()).map(|(k, d)| d * k * k).sum();
        let blocks: f64 = self
            .blocks
            .iter()
            .map(|(cols, f)| (f * DVector::from_iterator(cols.len(), cols.iter().map(|&j| k[j]))).norm_squared())
            .sum();
        (diag + blocks).max(0.0).sqrt()
    }

    /// Lᵀ restricted to the unknowns on `columns` (the solver's support: one unknown per entry,
    /// a cam's signed coefficient on its + column, whose shift is the − column's negated): rows
    /// that see none of them are left out.
    pub fn factor_on(&self, columns: &[usize]) -> DMatrix<f64> {
        let mut rows: Vec<DVector<f64>> = Vec::new();
        for (a, &j) in columns.iter().enumerate() {
            if self.diagonal[j] > 0.0 {
                let mut r = DVector::zeros(columns.len());
                r[a] = self.diagonal[j].sqrt();
                rows.push(r);
            }
        }
        for (cols, f) in &self.blocks {
            let at: Vec<(usize, usize)> = columns
                .iter()
                .enumerate()
                .filter_map(|(a, j)| cols.iter().position(|c| c == j).map(|c| (a, c)))
                .collect();
            if at.is_empty() {
                continue;
            }
            for i in 0..f.nrows() {
                let mut r = DVector::zeros(columns.len());
                for &(a, c) in &at {
                    r[a] = f[(i, c)];
                }
                rows.push(r);
            }
        }
        let mut l = DMatrix::zeros(rows.len(), columns.len());
        for (i, r) in rows.iter().enumerate() {
            l.set_row(i, &r.transpose());
        }
        l
    }
}

/// The bound the fit holds on the builds' RMS metric shift, ‖Lᵀk‖ ≤ `bound` (`[fit] max_shift`):
/// a second-order cone of the QP, added only when the fit without it breaks the bound.
#[derive(Debug, Clone, PartialEq)]
pub struct ShiftCone {
    /// The shift as a sum of squares.
    pub form: ShiftForm,
    /// The bound s on √(kᵀSk).
    pub bound: f64,
}

/// What the tolerance-aware fit adds to the normal equations: a diagonal (springs, each with its
/// own deviation) plus symmetric blocks over the columns of each cam (one deviation per cam);
/// and, where the fit bounds the builds' equilibrium shift, the cone the QP holds.
#[derive(Debug, Clone, PartialEq)]
pub struct BuildPenalty {
    /// Added to G's diagonal.
    pub diagonal: DVector<f64>,
    /// (columns, block) added to G over those columns.
    pub blocks: Vec<(Vec<usize>, DMatrix<f64>)>,
    /// The bound on the shift the QP holds as a cone (None: no bound in this solve).
    pub cone: Option<ShiftCone>,
}

impl BuildPenalty {
    /// `rows_weight` × the expected row spread + `shift_weight` × the expected shift.
    pub fn of(sp: &Spread, rows_weight: f64, shift_weight: f64) -> BuildPenalty {
        BuildPenalty {
            diagonal: &sp.rows * rows_weight + &sp.shift * shift_weight,
            blocks: sp
                .blocks
                .iter()
                .map(|b| (b.columns.clone(), &b.rows * rows_weight + &b.shift * shift_weight))
                .collect(),
            cone: None,
        }
    }

    /// The sum of two penalties over the same candidates (a cone from either).
    pub fn plus(mut self, other: BuildPenalty) -> BuildPenalty {
        self.diagonal += other.diagonal;
        self.blocks.extend(other.blocks);
        self.cone = self.cone.or(other.cone);
        self
    }

    /// Adds the penalty to a Gram matrix G (p × p over all candidates).
    pub fn add_to(&self, g: &mut DMatrix<f64>) {
        for j in 0..self.diagonal.len() {
            g[(j, j)] += self.diagonal[j];
        }
        for (cols, b) in &self.blocks {
            for (a, &i) in cols.iter().enumerate() {
                for (c, &j) in cols.iter().enumerate() {
                    g[(i, j)] += b[(a, c)];
                }
            }
        }
    }

    /// kᵀ P k: the penalty's value at the stiffnesses `k` (all candidates).
    pub fn value(&self, k: &[f64]) -> f64 {
        let diag: f64 = k.iter().zip(self.diagonal.iter()).map(|(k, d)| d * k * k).sum();
        let blocks: f64 = self
            .blocks
            .iter()
            .map(|(cols, b)| {
                let kg = DVector::from_iterator(cols.len(), cols.iter().map(|&j| k[j]));
                kg.dot(&(b * &kg))
            })
            .sum();
        diag + blocks
    }
}

/// The fan `nominal` traced again from `base`: the same directions in the metric frame at
/// `base`, the same arc lengths and sample spacing `spacing`. Sample i of geodesic d corresponds
/// to sample i of the nominal geodesic d.
pub fn retrace(chain: &Chain, base: &DVector<f64>, nominal: &Fan, spacing: f64, ode: OdeSettings) -> Result<Fan> {
    let frame = MetricFrame::new(&chain.mass_matrix(base))?;
    let results: Vec<Result<crate::geodesic::Geodesic>> = nominal
        .frame_directions
        .par_iter()
        .zip(nominal.geodesics.par_iter())
        .map_init(
            || Shooter::new(chain, base, ode),
            |shooter, (u, g)| {
                let t = shooter.trace(&frame.to_joint(u), Stop::Arc(g.length()), spacing)?;
                let same =
                    t.len() == g.len() && (0..t.len()).all(|i| (t.s(i) - g.s(i)).abs() <= 1e-9 * spacing.max(1.0));
                if !same {
                    return Err(Error::numerical(
                        "tolerance-aware fit",
                        format!(
                            "the training geodesic retraced from {:?} has {} samples where the nominal one has {}",
                            base.as_slice(),
                            t.len(),
                            g.len()
                        ),
                    ));
                }
                Ok(t)
            },
        )
        .collect();
    let geodesics = results.into_iter().collect::<Result<Vec<_>>>()?;
    Ok(Fan { q_eq: base.clone(), frame_directions: nominal.frame_directions.clone(), geodesics })
}

/// The training rows R = A k − b of a spring set on a fan (weighted as in the fit).
pub fn rows_of(chain: &Chain, fan: &Fan, springs: &SpringSet, omega: f64) -> DVector<f64> {
    let candidates: Vec<Candidate> = springs.elements.iter().map(|e| Candidate::bare(e.clone())).collect();
    let req = Requirements { omega, hessian_match: false, monotone: false };
    let problem = assemble(chain, &fan.q_eq, fan, &candidates, req);
    &problem.rows * DVector::from_column_slice(&springs.stiffness) - problem.rhs
}

/// The training rows of a fixed fan with everything but the springs done once: per sample the
/// weighted directions w = M⁻¹ (complement of γ̇) / (ω² s |γ̇|) of [`assemble`] and gravity's
/// share of each row, so that R = A k − b for any spring set on this fan costs one pass over its
/// elements (no mass matrix, no factorisation). `tune` evaluates the rows of its training fan
/// at every trial step; [`rows_of`] is the same sum, grouped by candidate.
pub struct RowFrame {
    /// Per sample: q, then its n − 1 (at least one) weighted directions.
    samples: Vec<(Vec<f64>, Vec<Vec<f64>>)>,
    /// Gravity's part of every row, ∇U_g · w.
    gravity: Vec<f64>,
}

impl RowFrame {
    /// The frame of `fan` for the frequency `omega` (the rows' weighting).
    pub fn new(chain: &Chain, fan: &Fan, omega: f64) -> RowFrame {
        let w2 = omega * omega;
        let mut samples = Vec::new();
        let mut gravity = Vec::new();
        for (q, qd, s) in crate::fit::problem::training_samples(fan) {
            let sample = crate::fit::problem::sample_directions(chain, q, qd, s, w2);
            let dirs: Vec<Vec<f64>> =
                sample.directions.iter().map(|w| (w * sample.weight).as_slice().to_vec()).collect();
            gravity.extend(dirs.iter().map(|w| sample.gravity.iter().zip(w).map(|(a, b)| a * b).sum::<f64>()));
            samples.push((q.to_vec(), dirs));
        }
        RowFrame { samples, gravity }
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.gravity.len()
    }

    /// Whether the frame has no rows (no samples, or one joint: no direction across γ̇).
    pub fn is_empty(&self) -> bool {
        self.gravity.is_empty()
    }

    /// The rows of each of `elements` at rate 1, gravity left out, as columns: uⱼ′(aⱼ·q − x₀ⱼ)
    /// (aⱼ·w) per row, the columns of A for these elements.
    pub fn columns<'e>(&self, elements: impl ExactSizeIterator<Item = &'e Element>) -> DMatrix<f64> {
        let mut a = DMatrix::zeros(self.len(), elements.len());
        for (j, e) in elements.enumerate() {
            let mut r = 0;
            for (q, dirs) in &self.samples {
                let slope = e.profile.slope(e.deflection(q));
                for w in dirs {
                    a[(r, j)] = slope * e.coupling.iter().zip(w).map(|(c, w)| c * w).sum::<f64>();
                    r += 1;
                }
            }
        }
        a
    }

    /// R = A k − b of `springs` on the frame's fan: (∇U_springs + ∇U_g) · w per row.
    pub fn rows(&self, springs: &SpringSet) -> DVector<f64> {
        let n = self.samples.first().map_or(0, |(q, _)| q.len());
        let mut grad = vec![0.0; n];
        let mut out = Vec::with_capacity(self.gravity.len());
        for (q, dirs) in &self.samples {
            springs.gradient_into(q, &mut grad);
            out.extend(dirs.iter().map(|w| grad.iter().zip(w).map(|(a, b)| a * b).sum::<f64>()));
        }
        for (r, g) in out.iter_mut().zip(&self.gravity) {
            *r += g;
        }
        DVector::from_vec(out)
    }
}

/// J = ∂R/∂(base point) (m × n) of the nominal spring set's rows, by central differences of fans
/// retraced from q_eq ± [`BASE_STEP`] eⱼ.
pub fn base_jacobian(
    chain: &Chain,
    training: &Fan,
    spacing: f64,
    nominal: &SpringSet,
    omega: f64,
    ode: OdeSettings,
) -> Result<DMatrix<f64>> {
    let n = chain.dof();
    let q_eq = &training.q_eq;
    let at_base = rows_of(chain, training, nominal, omega);
    let mut cols = Vec::with_capacity(n);
    for j in 0..n {
        let mut rows = Vec::with_capacity(2);
        for sign in [1.0, -1.0] {
            let mut base = q_eq.clone();
            base[j] += sign * BASE_STEP;
            let fan = retrace(chain, &base, training, spacing, ode)?;
            rows.push(rows_of(chain, &fan, nominal, omega));
        }
        cols.push(central_difference(&rows[0], &at_base, &rows[1]));
    }
    Ok(DMatrix::from_columns(&cols))
}

/// How many times the median row's change a row's two one-sided changes may differ by before
/// the row counts as not smooth in the base point. A smooth row's one-sided changes differ by its
/// curvature times [`BASE_STEP`]² (1e-8 of it), far below this; on `ur10_lift_elbow_wrist` the
/// last sample of one training geodesic (the wrist 2.4 rad out at arc 0.28) changed by 4e7
/// one way and 1e-2 the other, every shipped design's rows by less than 1e4 times the median.
pub const ROUGH_ROW: f64 = 1e6;

/// One column of J from the rows at the bases q_eq + h eⱼ (`plus`), q_eq and q_eq − h eⱼ
/// (`minus`): the central difference (plus − minus) / 2h, except on rows whose two one-sided
/// changes differ by more than [`ROUGH_ROW`] times the median row's |up| + |down|, which take
/// the smaller one-sided difference. Such a row is not smooth in the base point (a retraced
/// geodesic that leaves the smooth neighbourhood of the nominal one), and its central
/// difference (4e7 / 2e-4 on the UR10's arm) made the build penalty 4e12 times a candidate's
/// own column on every element that carries gravity: Clarabel then declared the tolerance-aware
/// fit infeasible at any tolerance.
fn central_difference(plus: &DVector<f64>, at: &DVector<f64>, minus: &DVector<f64>) -> DVector<f64> {
    let (up, down) = (plus - at, at - minus);
    let mut size: Vec<f64> = up.iter().zip(down.iter()).map(|(u, d)| u.abs() + d.abs()).collect();
    size.sort_by(f64::total_cmp);
    let median = size.get(size.len() / 2).copied().unwrap_or(0.0);
    DVector::from_iterator(
        up.len(),
        (0..up.len()).map(|i| {
            let (u, d) = (up[i], down[i]);
            if median > 0.0 && (u - d).abs() > ROUGH_ROW * median {
                if u.abs() < d.abs() { u / BASE_STEP } else { d / BASE_STEP }
            } else {
                (plus[i] - minus[i]) / (2.0 * BASE_STEP)
            }
        }),
    )
}

/// The first-order spread of every candidate (see the module docs). `rows` are the fit's
/// weighted rows (one column per candidate; rows past the training rows, such as the cams'
/// smoothing penalty, are ignored), `nominal` the nominal fit's spring set whose rows define J
/// and whose Hessian at q_eq is H, `sigma2[i]` the variance of candidate i's deviation. The
/// columns of one group (`grouping`) share one deviation, with the variance of its first column.
#[allow(clippy::too_many_arguments)]
pub fn spread(
    chain: &Chain,
    training: &Fan,
    spacing: f64,
    (candidates, grouping): Columns<'_>,
    rows: &DMatrix<f64>,
    nominal: &SpringSet,
    sigma2: &[f64],
    omega: f64,
    ode: OdeSettings,
) -> Result<Spread> {
    let jac = base_jacobian(chain, training, spacing, nominal, omega, ode)?;
    spread_with(chain, training, (candidates, grouping), rows, nominal, sigma2, &jac)
}

/// [`spread`] with J = [`base_jacobian`] of `nominal` already computed (the trimmed model shares
/// it).
pub fn spread_with(
    chain: &Chain,
    training: &Fan,
    (candidates, grouping): Columns<'_>,
    rows: &DMatrix<f64>,
    nominal: &SpringSet,
    sigma2: &[f64],
    jac: &DMatrix<f64>,
) -> Result<Spread> {
    let q_eq = training.q_eq.as_slice();
    let hess = nominal.hessian(q_eq)? + chain.gravity_hessian(q_eq);
    let h_inv = hess.clone().cholesky().map(|c| c.inverse()).ok_or_else(|| {
        Error::numerical(
            "tolerance-aware fit",
            "the nominal fit's Hessian at q_eq is not positive definite: a build has no nearby equilibrium to judge it about",
        )
    })?;
    let training_rows = training_rows(rows, jac)?;
    let jh = jac * &h_inv;
    let m_eq = chain.mass_matrix(&training.q_eq);
    // vᵢ = Aᵢ − J H⁻¹ gᵢ (Aᵢ alone when the element exerts no torque at q_eq) and hᵢ = H⁻¹ gᵢ.
    let column = |i: usize| -> (DVector<f64>, DVector<f64>) {
        let g = candidates[i].element.gradient(q_eq);
        let col = training_rows.column(i).into_owned();
        if g.iter().all(|v| *v == 0.0) {
            return (col, DVector::zeros(g.len()));
        }
        (col - &jh * &g, &h_inv * &g)
    };
    Ok(assemble_spread((candidates, grouping), sigma2, &m_eq, column))
}

/// The training rows of the fit's weighted rows (the rows J was taken of; later rows, such as
/// the cams' smoothing penalty, are no residual of a build).
fn training_rows(rows: &DMatrix<f64>, jac: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    if jac.nrows() > rows.nrows() {
        return Err(Error::numerical(
            "tolerance-aware fit",
            format!("{} retraced rows against {} training rows", jac.nrows(), rows.nrows()),
        ));
    }
    Ok(rows.rows(0, jac.nrows()).into_owned())
}

/// The diagonal and the cam blocks from each candidate's change of the rows per unit δᵢ kᵢ and
/// its shift of the equilibrium, `column(i)` = (uᵢ, H⁻¹ gᵢ).
fn assemble_spread(
    (candidates, grouping): Columns<'_>,
    sigma2: &[f64],
    m_eq: &DMatrix<f64>,
    column: impl Fn(usize) -> (DVector<f64>, DVector<f64>),
) -> Spread {
    let groups = &grouping.of;
    let mut d_rows = DVector::zeros(candidates.len());
    let mut d_shift = DVector::zeros(candidates.len());
    for (i, _) in candidates.iter().enumerate() {
        if sigma2[i] == 0.0 || groups[i].is_some() {
            continue;
        }
        let (v, h) = column(i);
        d_rows[i] = sigma2[i] * v.norm_squared();
        d_shift[i] = sigma2[i] * h.dot(&(m_eq * &h));
    }
    let mut blocks = Vec::new();
    // C of M(q_eq) = C Cᵀ for the cams' shift factors (M is positive definite; the identity if
    // rounding says otherwise, which only the factor's rows would see).
    let chol_t =
        m_eq.clone().cholesky().map_or_else(|| DMatrix::identity(m_eq.nrows(), m_eq.ncols()), |c| c.l().transpose());
    for group in &grouping.groups {
        let columns = group.columns.clone();
        let s2 = sigma2[columns[0]];
        if s2 == 0.0 {
            continue;
        }
        let (vs, hs): (Vec<DVector<f64>>, Vec<DVector<f64>>) = columns.iter().map(|&j| column(j)).unzip();
        let v = DMatrix::from_columns(&vs);
        let h = DMatrix::from_columns(&hs);
        // VᵀV by faer's triangular product: 1.7× nalgebra's on a cam's 8871 × 64 columns, and the
        // fits it feeds stay byte-identical (the block is small beside G).
        blocks.push(Block {
            rows: crate::solve::dense::gram_of(&v) * s2,
            shift: h.transpose() * m_eq * &h * s2,
            shift_factor: &chol_t * &h * s2.sqrt(),
            columns,
        });
    }
    Spread { rows: d_rows, shift: d_shift, blocks }
}

/// Step of the central differences of the rest's Hessian and of M in q, rad (third derivatives
/// of smooth elements; a cubic B-spline's curvature is piecewise linear, so the difference is
/// exact between knots).
pub const HESSIAN_STEP: f64 = 1e-5;

/// The first-order spread of every candidate in *trimmed* builds (see the module docs, "Trimmed
/// builds"). `rest` is the nominal fit's spring set without the trims (used candidates only),
/// `trims` the trim springs at their mid-range rates relaxed at q_eq, and `jac` the
/// [`base_jacobian`] of rest and trims together (trims relaxed at q_eq, not following the base).
/// The other arguments are those of [`spread`]; `omega` is the design's ω (the frequency the
/// nominal trimmed arm is solved for). The shift is the trimmed build's, −H_rest⁻¹ gᵢ.
#[allow(clippy::too_many_arguments)]
pub fn trimmed_spread(
    chain: &Chain,
    training: &Fan,
    (candidates, grouping): Columns<'_>,
    rows: &DMatrix<f64>,
    rest: &SpringSet,
    trims: &SpringSet,
    sigma2: &[f64],
    omega: f64,
    jac: &DMatrix<f64>,
    rule: TrimRule,
) -> Result<Spread> {
    let q0 = &training.q_eq;
    let q_eq = q0.as_slice();
    let n = chain.dof();
    let rest_hessian = |q: &DVector<f64>| -> Result<DMatrix<f64>> {
        Ok(rest.hessian(q.as_slice())? + chain.gravity_hessian(q.as_slice()))
    };
    let h_rest = rest_hessian(q0)?;
    let couplings: Vec<Vec<f64>> = trims.elements.iter().map(|e| e.coupling.clone()).collect();
    let mut h_nom = h_rest.clone();
    for (a, t) in couplings.iter().zip(&trims.stiffness) {
        let av = DVector::from_column_slice(a);
        h_nom += &av * av.transpose() * *t;
    }
    // A trimmed build rests where the gradient of the rest vanishes (the trims are relaxed
    // there) and is stable by the whole Hessian, trims included, as the as-built figures judge it
    // (`asbuilt::stationary_point`): the rest alone need only be invertible. On an arm whose
    // trims carry much of the stiffness (`panda_three`: trims of 0–26 N·m/rad) it is indefinite.
    if h_nom.clone().cholesky().is_none() {
        return Err(Error::numerical(
            "trim-aware fit",
            "the nominal fit with its trims at mid-range has no positive definite Hessian at q_eq: a trimmed build has no stable equilibrium nearby",
        ));
    }
    let h_inv = h_rest.clone().lu().try_inverse().filter(|h| h.iter().all(|v| v.is_finite())).ok_or_else(|| {
        Error::numerical(
            "trim-aware fit",
            "the nominal fit without its trims has a singular Hessian at q_eq: a trimmed build's equilibrium is not determined to first order",
        )
    })?;
    let training_rows = training_rows(rows, jac)?;
    let m_eq = chain.mass_matrix(q0);
    // w² of the nominal trimmed arm: ω² when the fit matches the Hessian exactly, else the trims'
    // answer to the nominal mismatch.
    let w2 = omega * omega
        + crate::elements::trim::interior_change(&(&h_nom - &m_eq * (omega * omega)), &m_eq, &couplings).1;
    // ∂H_rest/∂q_l − w² ∂M/∂q_l by central differences.
    let mut d_mismatch = Vec::with_capacity(n);
    for l in 0..n {
        let (mut qp, mut qm) = (q0.clone(), q0.clone());
        qp[l] += HESSIAN_STEP;
        qm[l] -= HESSIAN_STEP;
        let dh = (rest_hessian(&qp)? - rest_hessian(&qm)?) / (2.0 * HESSIAN_STEP);
        let dm = (chain.mass_matrix(&qp) - chain.mass_matrix(&qm)) / (2.0 * HESSIAN_STEP);
        d_mismatch.push(dh - dm * w2);
    }
    // Each trim's unit rows A_trim_j and D_j = ∂(its unit rows)/∂x₀ (exact: linear in x₀).
    let unit = |e: &crate::elements::Element| -> DVector<f64> {
        let c = [Candidate::bare(e.clone())];
        let req = Requirements { omega, hessian_match: false, monotone: false };
        assemble(chain, q0, training, &c, req).rows.column(0).rows(0, jac.nrows()).into_owned()
    };
    let mut a_trim = Vec::with_capacity(trims.elements.len());
    // J_t = J + Σⱼ t⁰ⱼ Dⱼ aⱼᵀ: the rows' change with the base point when the trims follow it.
    let mut jac_t = jac.clone();
    for (e, t) in trims.elements.iter().zip(&trims.stiffness) {
        a_trim.push(unit(e));
        let (mut ep, mut em) = (e.clone(), e.clone());
        ep.offset += 0.5;
        em.offset -= 0.5;
        let d = unit(&ep) - unit(&em);
        jac_t += d * DVector::from_column_slice(&e.coupling).transpose() * *t;
    }
    // An orthonormal basis of the trims' columns (the residual rule's projector).
    let trim_basis =
        (rule == TrimRule::Residual && !a_trim.is_empty()).then(|| DMatrix::from_columns(&a_trim).qr().q());
    // uᵢ = Aᵢ + J_t Δqᵢ + Σⱼ Δtᵢⱼ A_trim_j, Δqᵢ = −H_rest⁻¹ gᵢ, Δtᵢ the trims' answer to
    // Eᵢ = Hᵢ + Σ_l (∂H_rest/∂q_l − w² ∂M/∂q_l) Δqᵢ[l] (Hessian rule), or to the rows
    // (residual rule).
    let column = |i: usize| -> (DVector<f64>, DVector<f64>) {
        let e = &candidates[i].element;
        let h = &h_inv * e.gradient(q_eq);
        let dq = -&h;
        if let Some(basis) = &trim_basis {
            let u = training_rows.column(i) + &jac_t * &dq;
            let projection = basis * (basis.transpose() * &u);
            return (u - projection, h);
        }
        let mut mismatch = e.hessian(q_eq);
        for (l, d) in d_mismatch.iter().enumerate() {
            mismatch += d * dq[l];
        }
        let (dt, _) = crate::elements::trim::interior_change(&mismatch, &m_eq, &couplings);
        let mut u = training_rows.column(i) + &jac_t * &dq;
        for (a, t) in a_trim.iter().zip(&dt) {
            u += a * *t;
        }
        (u, h)
    };
    Ok(assemble_spread((candidates, grouping), sigma2, &m_eq, column))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Smooth rows keep the central difference bit for bit; a row that jumps on one side only
    /// (the UR10 arm's retraced geodesic, 4e7 one way) takes the other side's difference instead
    /// of a slope 1e11 that made the tolerance-aware fit infeasible.
    #[test]
    fn a_row_that_jumps_on_one_side_takes_the_other_sides_difference() {
        let h = BASE_STEP;
        // Rows R(q) = a q + c q² at q = 0, ± h: one-sided changes differ by 2 c h².
        let slopes = [0.3, -1.2, 0.0, 2.5, 1e-3];
        let row = |q: f64| DVector::from_iterator(5, slopes.iter().map(|a| a * q + 40.0 * q * q));
        let (plus, at, minus) = (row(h), row(0.0), row(-h));
        let central = central_difference(&plus, &at, &minus);
        assert_eq!(central, (&plus - &minus) / (2.0 * h));
        for (j, a) in central.iter().zip(slopes) {
            assert!((j - a).abs() < 1e-9, "{j} against {a}");
        }
        let mut jumped = plus.clone();
        jumped[3] = -4.135e7;
        let rough = central_difference(&jumped, &at, &minus);
        assert!((rough[3] - 2.5).abs() < 1e-2, "{}", rough[3]);
        for i in [0, 1, 2, 4] {
            assert_eq!(rough[i], central[i]);
        }
    }
}
