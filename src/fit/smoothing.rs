//! The smoothing of groups: each part's roughness (a cam's ∫V‴² dx, the torque's curvature) as
//! rows of the least-squares problem, with the family's weight or, for `smoothing = "auto"`, the
//! weight with the smallest p99 residual on validation geodesics between the training and the
//! held-out ones.

use nalgebra::{DMatrix, DVector};

use super::problem::FitProblem;
use super::problem::arm;
use super::solve::solve_gram;
use crate::design::Design;
use crate::design::fit::{FitSettings, SolverKind};
use crate::elements::catalog::{Candidate, Catalog, Smoothing};
use crate::elements::group::Grouping;
use crate::error::{Error, Result};
use crate::geodesic::{Fan, FanSpec, Stop};
use crate::potential::SpringSet;
use crate::residual::{fan_angles, stats};
use crate::solve::lsq::Gram;

/// Weight of the ridge Σ (cⱼ/(ω² m̄))² on group coefficients (relative like the smoothing
/// weight).
pub const GROUP_RIDGE: f64 = 1e-9;

/// Smoothing weights tried by `smoothing = "auto"`, relative to the tangentiality rows.
pub const AUTO_SMOOTHING: [f64; 5] = [1e-7, 1e-6, 1e-5, 1e-4, 1e-3];

/// The most directions of the validation fan: the held-out count of three joints. It ranks five
/// weights by one statistic, which 72 000 samples estimate well; the held-out fan of five and
/// more joints (2880 directions; 5760 at six joints when this was measured) would trace and
/// judge four to eight times as many geodesics five times over for the choice (the six-joint
/// UR5's cams: 15 s less, held-out p99 1.4567° against 1.4578°).
pub const MAX_VALIDATION_DIRECTIONS: usize = 720;

/// What the smoothing choice works on: the design, its catalogue and the fit settings, the
/// candidates with their grouping, the problem assembled on the training fan with its normal
/// equations, the trims it was solved around, and the region's arc length from q_eq.
pub struct SmoothingInputs<'a> {
    /// The design: its chain, q_eq and M(q_eq) (for m̄), its region and ODE settings (the
    /// validation fan).
    pub design: &'a Design,
    /// The catalogue: each group's family gives its smoothing weight or `"auto"`.
    pub catalog: &'a Catalog,
    /// The fit settings: ω, the solver (NNLS adds the group ridge), the held-out fan's size.
    pub settings: &'a FitSettings,
    /// The candidate elements, one per column of the problem.
    pub candidates: &'a [Candidate],
    /// Which candidates are one part (a cam's coefficients): the groups smoothed.
    pub grouping: &'a Grouping,
    /// The problem on the training fan: its row count scales the penalty, `"auto"` solves it.
    pub problem: &'a FitProblem,
    /// The problem's normal equations, to which `"auto"` adds each trial weight's rows.
    pub gram: &'a Gram,
    /// The trim springs at mid-range the problem was solved around, part of every trial arm.
    pub trims: &'a SpringSet,
    /// The region's arc length from q_eq (the region check's, which the fit has already made).
    pub extent: f64,
}

/// The groups' smoothing penalty (a cam's ∫V‴² dx, see [`crate::elements::group::Shape`]) as rows
/// (rhs 0) for the chosen weights. Each group's penalty is scaled by 1/(ω² m̄)² (m̄ the mean
/// diagonal of M(q_eq)), by the number of tangentiality rows and by the family's weight λ, so
/// λ = 1 weighs ∫(V‴/(ω² m̄))² dx like all the rows together. Families with `smoothing = "auto"`
/// share one weight, the one of [`AUTO_SMOOTHING`] with the smallest p99 residual on a
/// *validation* fan (as many directions as the held-out fan, at most
/// [`MAX_VALIDATION_DIRECTIONS`], shifted by a quarter of their spacing: apart from both the
/// training and the held-out fans), judged on the dense fit (without `max_elements`).
pub fn group_smoothing(inputs: &SmoothingInputs) -> Result<(DMatrix<f64>, DVector<f64>)> {
    let SmoothingInputs { design, settings, candidates, grouping, problem, .. } = *inputs;
    let m_bar = design.chain.mass_matrix(&design.q_eq).diagonal().mean();
    let base = (problem.row_count().max(1) as f64).sqrt() / (settings.frequency.powi(2) * m_bar);
    let blocks = roughness_blocks(inputs, base);
    // A tiny ridge on every group column. Cams on four or more couplings can cancel each other
    // over the whole region (x₁², x₂², (x₁+x₂)² and (x₁−x₂)² are dependent, and so are the
    // linear functions of any three couplings): without the ridge the solve may pick large
    // antagonistic cams, accurate as drawn, whose one-δ-per-cam rate errors un-cancel in every
    // build (measured: cams4 as built p99 p95 4.8° with the ridge, 15.6° without). At this
    // weight it costs nothing measurable as drawn.
    // The QP's signed unknowns need no ridge (and it moves the QP's optimum: with it the 16-cam
    // window design turned a mode over on the held-out fan); NNLS's ± pairs keep it.
    let ridge = settings.solver == SolverKind::Nnls;
    let group_columns: Vec<usize> =
        if ridge { (0..candidates.len()).filter(|&j| grouping.of[j].is_some()).collect() } else { Vec::new() };
    let build = |auto: f64| -> (DMatrix<f64>, DVector<f64>) {
        let rows: usize = blocks.iter().map(|b| b.0.nrows()).sum::<usize>() + group_columns.len();
        let mut m = DMatrix::zeros(rows, candidates.len());
        let mut r0 = 0;
        for (block, w) in &blocks {
            let w = w.unwrap_or(auto).sqrt();
            m.view_mut((r0, 0), block.shape()).copy_from(&(block * w));
            r0 += block.nrows();
        }
        if ridge {
            for (i, &j) in group_columns.iter().enumerate() {
                m[(r0 + i, j)] = GROUP_RIDGE.sqrt() * base;
            }
        }
        (m, DVector::zeros(rows))
    };
    if blocks.iter().all(|b| b.1.is_some()) {
        return Ok(build(0.0));
    }
    let w = auto_weight(inputs, &build)?;
    Ok(build(w))
}

/// Per group: its penalty rows over all candidates scaled by `base`, and its family's weight
/// (None: "auto").
fn roughness_blocks(inputs: &SmoothingInputs, base: f64) -> Vec<(DMatrix<f64>, Option<f64>)> {
    let SmoothingInputs { catalog, candidates, grouping, .. } = *inputs;
    let coefficient = grouping.coefficient_of();
    let mut blocks: Vec<(DMatrix<f64>, Option<f64>)> = Vec::new();
    for group in &grouping.groups {
        let family = &catalog.families[candidates[group.columns[0]].family];
        let d = group.roughness_rows();
        let mut block = DMatrix::zeros(d.len(), candidates.len());
        for &j in &group.columns {
            let Some((c, negative)) = coefficient[j] else { continue };
            let sign = if negative { -1.0 } else { 1.0 };
            for (r, row) in d.iter().enumerate() {
                block[(r, j)] = sign * row[c] * base;
            }
        }
        let weight = match family.smoothing() {
            Smoothing::Weight(w) => Some(w),
            Smoothing::Auto => None,
        };
        blocks.push((block, weight));
    }
    blocks
}

/// The weight of [`AUTO_SMOOTHING`] whose dense fit (the penalty rows `build` gives for it
/// added) has the smallest p99 residual on the validation fan.
fn auto_weight(inputs: &SmoothingInputs, build: &dyn Fn(f64) -> (DMatrix<f64>, DVector<f64>)) -> Result<f64> {
    let SmoothingInputs { design, settings, candidates, grouping, problem, gram, trims, extent, .. } = *inputs;
    let stop = Stop::Region { region: &design.region, max_arc: design.geodesics.max_arc };
    let validation = Fan::trace(
        &design.chain,
        &design.q_eq,
        FanSpec {
            count: settings.evaluation_count(design.dof()).min(MAX_VALIDATION_DIRECTIONS),
            phase: 0.25,
            stop,
            spacing: extent / settings.evaluation_samples as f64,
        },
        design.geodesics.ode,
    )?;
    let mut best: Option<(f64, f64)> = None;
    for &w in &AUTO_SMOOTHING {
        let (rows, rhs) = build(w);
        let mut trial = gram.clone();
        trial.add_sparse_rows(&rows, &rhs);
        // A weight whose solve fails (infeasible, numerical trouble) is simply not chosen.
        // Chosen on the dense fit (every element allowed): a sparse selection per weight would
        // cost the selection five times over, and the weight only tempers each part's wiggle.
        let dense = FitSettings { max_elements: 0, ..*settings };
        // Signed unknowns here whatever the solver: one linear solve per weight, and the
        // validation residual does not see the cancelling components the pairs keep small.
        let columns = (candidates, grouping);
        let Ok((k, _)) = solve_gram(problem, trial, columns, design.q_eq.as_slice(), &dense, true) else {
            continue;
        };
        // The problem was solved around the trims at mid-range: judge the arm with them.
        let springs = arm(candidates, &k, trims);
        let p99 = stats(&fan_angles(&design.chain, &validation, &springs.grouped())?).p99_abs;
        if best.is_none_or(|(_, b)| p99 < b) {
            best = Some((w, p99));
        }
    }
    let (w, _) = best.ok_or_else(|| Error::Infeasible {
        constraint: "smoothing".into(),
        reason: "no smoothing weight of the automatic choice gave a solvable fit".into(),
    })?;
    Ok(w)
}

/// Appends rows (and their right-hand side) to the tangentiality rows of a problem; to the
/// right-hand side alone where the problem keeps no rows ([`FitProblem::has_rows`]).
pub fn append_rows(problem: &mut FitProblem, extra: &(DMatrix<f64>, DVector<f64>)) {
    let (m, p) = (problem.row_count(), problem.rows.ncols());
    let r = extra.0.nrows();
    let kept = problem.has_rows();
    let mut rows = DMatrix::zeros(if kept { m + r } else { 0 }, p);
    if kept {
        rows.view_mut((0, 0), (m, p)).copy_from(&problem.rows);
        rows.view_mut((m, 0), (r, p)).copy_from(&extra.0);
    }
    let mut rhs = DVector::zeros(m + r);
    rhs.rows_mut(0, m).copy_from(&problem.rhs);
    rhs.rows_mut(m, r).copy_from(&extra.1);
    problem.rows = rows;
    problem.rhs = rhs;
}
