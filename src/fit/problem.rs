//! The fit as a linear least-squares problem in the stiffnesses.
//!
//! U_e = Σ kⱼ uⱼ(q) is linear in k, so every requirement is linear in k:
//!
//! * **Tangentiality rows**, one per training sample (γ, γ̇, s) and per column p of [γ̇]^⊥:
//!   ∂U/∂qᵀ M⁻¹ p = 0 with U = U_e + U_g, i.e. Σ kⱼ uⱼ′ (aⱼᵀ M⁻¹ p) = −∂U_g/∂qᵀ M⁻¹ p. For the
//!   exact potential v₁ = M⁻¹∇U = ω² s γ̇, so each row is divided by ω² s |γ̇|: a row's residual
//!   is then ≈ sin(residual angle), and every distance from q_eq counts the same — raw residuals
//!   would grow with s and let the outer samples dominate.
//! * **Equilibrium**: ∂U/∂q(q_eq) = 0 (n equations).
//! * **Normalisation**: tr(M(q_eq)⁻¹ ∇²U(q_eq)) = n ω² (without it k = 0 wins).
//! * **Hessian match** (optional): ∇²U(q_eq) = ω² M(q_eq) (n(n+1)/2 equations; it implies the
//!   normalisation, which is then left out): every small oscillation has frequency ω, and the
//!   residual angles near q_eq vanish.
//! * **Monotonicity** (optional): ∂U/∂q·γ̇ ≥ 0 on the samples (U grows along every geodesic).
//!
//! Equations are scaled so their entries are O(1) per unit of ω²·M: the solvers can then weigh
//! them against the rows with one well-defined number.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::elements::catalog::Candidate;
use crate::elements::catalog::{Catalog, TrimSpring};
use crate::geodesic::Fan;
use crate::model::Chain;
use crate::potential::SpringSet;
pub use crate::solve::LinearGroup;
pub use crate::solve::lsq::RowsOut;
use crate::solve::lsq::{Run, SparseRows};

/// The assembled fit problem.
#[derive(Debug, Clone)]
pub struct FitProblem {
    /// Weighted tangentiality rows (m × p), or none (0 × p) where the fit did not keep them: a
    /// large fit whose normal equations come from the rows' factors ([`RowFactors`]) needs them
    /// only for the tolerance-aware pass, and at seven joints they would take 1.7 GB (see
    /// [`FitProblem::has_rows`] and `Prepared::rows`).
    pub rows: DMatrix<f64>,
    /// Their right-hand side (gravity), m: always all of it.
    pub rhs: DVector<f64>,
    /// Equalities (equilibrium, normalisation or Hessian match).
    pub equalities: Vec<LinearGroup>,
    /// Inequalities G k ≥ h (monotonicity), if asked for.
    pub inequalities: Vec<LinearGroup>,
}

impl FitProblem {
    /// The number of tangentiality rows m, kept or not.
    pub fn row_count(&self) -> usize {
        self.rhs.len()
    }

    /// Whether [`FitProblem::rows`] holds the rows.
    pub fn has_rows(&self) -> bool {
        self.rows.nrows() == self.rhs.len()
    }
}

/// Which requirements to assemble.
#[derive(Debug, Clone, Copy)]
pub struct Requirements {
    /// Small-oscillation frequency ω in rad/s.
    pub omega: f64,
    /// Match the Hessian at q_eq to ω² M(q_eq) (else only the trace normalisation).
    pub hessian_match: bool,
    /// Add monotonicity inequalities on the samples.
    pub monotone: bool,
}

/// [γ̇]^⊥: an orthonormal basis (columns) of the Euclidean complement of `t`.
pub fn complement(t: &[f64]) -> DMatrix<f64> {
    let n = t.len();
    let norm = t.iter().map(|x| x * x).sum::<f64>().sqrt();
    if n == 2 {
        return DMatrix::from_column_slice(2, 1, &[-t[1] / norm, t[0] / norm]);
    }
    // Householder reflector H with H e_k = ±t/|t| for the largest |t_k|; its other columns span
    // the complement and are orthonormal.
    let k = (0..n).max_by(|&a, &b| t[a].abs().total_cmp(&t[b].abs())).unwrap_or(0);
    let mut v = DVector::from_iterator(n, t.iter().map(|x| x / norm));
    let sign = if v[k] >= 0.0 { 1.0 } else { -1.0 };
    v[k] += sign;
    let vv = v.dot(&v);
    let h = DMatrix::identity(n, n) - &v * v.transpose() * (2.0 / vv);
    let cols: Vec<DVector<f64>> = (0..n).filter(|&c| c != k).map(|c| h.column(c).into_owned()).collect();
    DMatrix::from_columns(&cols)
}

/// The samples of a training fan that give rows: (q, γ̇, s) in fan order, s = 0 skipped (the
/// tangent there carries no residual: both sides of a row vanish).
pub fn training_samples(fan: &Fan) -> impl Iterator<Item = (&[f64], &[f64], f64)> + '_ {
    fan.geodesics.iter().flat_map(|g| (0..g.len()).map(move |i| (g.q(i), g.qd(i), g.s(i)))).filter(|&(_, _, s)| s > 0.0)
}

/// What one training sample contributes to every row, whatever the springs: the directions
/// w_c = M(q)⁻¹ p_c for the columns p_c of [γ̇]^⊥ (none for one joint), the row weight
/// 1/(ω² s |γ̇|) and ∇U_g(q). A spring's entry in row c is u′ (a·w_c) · weight, gravity's right-hand
/// side −∇U_g·w_c · weight: [`assemble`] and [`crate::fit::robust::RowFrame`] both build on this.
pub struct SampleDirections {
    /// w_c = M(q)⁻¹ p_c, unweighted.
    pub directions: Vec<DVector<f64>>,
    /// 1/(ω² s |γ̇|).
    pub weight: f64,
    /// ∇U_g(q).
    pub gravity: DVector<f64>,
}

/// [`SampleDirections`] of the sample (q, γ̇, s) for ω² = `w2`.
pub fn sample_directions(chain: &Chain, q: &[f64], qd: &[f64], s: f64, w2: f64) -> SampleDirections {
    let n = chain.dof();
    let m = chain.mass_matrix(&DVector::from_column_slice(q));
    let chol = m.cholesky().expect("the model's mass matrix is positive definite");
    let perp = if n == 1 { DMatrix::zeros(1, 0) } else { complement(qd) };
    let speed = qd.iter().map(|x| x * x).sum::<f64>().sqrt();
    SampleDirections {
        directions: (0..perp.ncols()).map(|c| chol.solve(&perp.column(c).into_owned())).collect(),
        weight: 1.0 / (w2 * s * speed),
        gravity: chain.gravity_gradient(q),
    }
}

/// The distinct couplings of `candidates` (equal bits), in order of first appearance, and each
/// candidate's index among them: what depends on a·q only is computed once per coupling.
pub fn coupling_classes(candidates: &[Candidate]) -> (Vec<usize>, Vec<&[f64]>) {
    let mut index: std::collections::HashMap<Vec<u64>, usize> = std::collections::HashMap::new();
    let mut classes: Vec<&[f64]> = Vec::new();
    let class_of = candidates
        .iter()
        .map(|c| {
            let a = c.element.coupling.as_slice();
            *index.entry(a.iter().map(|x| x.to_bits()).collect()).or_insert_with(|| {
                classes.push(a);
                classes.len() - 1
            })
        })
        .collect();
    (class_of, classes)
}

/// The tangentiality rows' factors by coupling: each coupling's a·q at each sample and its
/// weighted a·w_c at each row; with them a candidate's slope at a sample is one evaluation of its
/// profile. Kept beside the rows so that the normal equations of a large fit cost one product per
/// sample rather than n − 1 ([`crate::solve::lsq::CoupledRows`]).
pub struct RowFactors {
    /// a·q of every coupling (outer) at every sample (inner).
    pub at_q: Vec<Vec<f64>>,
    /// a·w_c / (ω² s |γ̇|) of every coupling (outer) at every row (inner).
    pub factors: Vec<Vec<f64>>,
    /// Each candidate's coupling.
    pub class_of: Vec<usize>,
    /// Aᵀb of the rows A and right-hand side b as assembled, for [`RowsOut::ProductOnly`]: each
    /// entry the product `A.tr_mul(b)` would give, bit for bit.
    pub rows_times_rhs: Option<DVector<f64>>,
    /// The rows' non-zeros, for [`RowsOut::Sparse`].
    pub sparse: Option<SparseRows>,
}

impl RowFactors {
    /// u′(a·q − x₀) of candidate `j` at the samples `s0 ..`, into `out`: the value the rows were
    /// assembled with.
    pub fn slopes(&self, candidates: &[Candidate], j: usize, s0: usize, out: &mut [f64]) {
        let e = &candidates[j].element;
        let at_q = &self.at_q[self.class_of[j]][s0..s0 + out.len()];
        for (o, x) in out.iter_mut().zip(at_q) {
            *o = e.profile.slope(x - e.offset);
        }
    }
}

/// Assembles the problem from the training fan.
pub fn assemble(
    chain: &Chain,
    q_eq: &DVector<f64>,
    fan: &Fan,
    candidates: &[Candidate],
    req: Requirements,
) -> FitProblem {
    assemble_factored(chain, q_eq, fan, candidates, req, RowsOut::Dense).0
}

/// [`assemble`], and the rows' [`RowFactors`]; the rows themselves as `out` says.
pub fn assemble_factored(
    chain: &Chain,
    q_eq: &DVector<f64>,
    fan: &Fan,
    candidates: &[Candidate],
    req: Requirements,
    out: RowsOut,
) -> (FitProblem, RowFactors) {
    let n = chain.dof();
    let p = candidates.len();
    let w2 = req.omega * req.omega;
    let samples: Vec<(&[f64], &[f64], f64)> = training_samples(fan).collect();
    let m_rows = samples.len() * (n - 1).max(1);
    // What every row needs whatever the spring (a mass-matrix factorisation per sample), once.
    let frames: Vec<SampleDirections> =
        samples.par_iter().map(|&(q, qd, s)| sample_directions(chain, q, qd, s, w2)).collect();
    let mut rhs = DVector::zeros(m_rows);
    for (si, frame) in frames.iter().enumerate() {
        for (c, w) in frame.directions.iter().enumerate() {
            rhs[si * (n - 1) + c] = -frame.gravity.dot(w) * frame.weight;
        }
    }
    // Per coupling, a·q and a·w_c at every sample, once: every candidate on the coupling (a cam's
    // 64 columns, a crank's phases) reads them.
    let (class_of, classes) = coupling_classes(candidates);
    let tables: Vec<(Vec<f64>, Vec<f64>)> = classes
        .par_iter()
        .map(|a| {
            let at_q = samples.iter().map(|&(q, _, _)| a.iter().zip(q).map(|(a, q)| a * q).sum::<f64>()).collect();
            let mut aw = vec![0.0; m_rows];
            for (si, frame) in frames.iter().enumerate() {
                for (c, w) in frame.directions.iter().enumerate() {
                    aw[si * (n - 1) + c] = a.iter().zip(w.iter()).map(|(a, w)| a * w).sum();
                }
            }
            (at_q, aw)
        })
        .collect();
    // Column by column (a candidate's column is contiguous in the column-major matrix), in
    // parallel: every entry is the same product whatever the thread count, and each candidate's
    // slope is evaluated once per sample, not once per row.
    // Entry (row r of sample si, candidate j) from j's slope at si: every way of keeping the rows
    // writes this value.
    let entry = |slope: f64, aw: f64, weight: f64| if aw != 0.0 { slope * aw * weight } else { 0.0 };
    let column = |col: &mut [f64], cand: &Candidate, class: usize| {
        let e = &cand.element;
        let (at_q, aw) = &tables[class];
        for (si, frame) in frames.iter().enumerate() {
            // e.deflection(q), term for term.
            let slope = e.profile.slope(at_q[si] - e.offset);
            for c in 0..frame.directions.len() {
                let r = si * (n - 1) + c;
                col[r] = entry(slope, aw[r], frame.weight);
            }
        }
    };
    let (mut rows_times_rhs, mut sparse) = (None, None);
    let rows = match out {
        RowsOut::Dense => {
            let mut rows = DMatrix::zeros(m_rows, p);
            if m_rows > 0 {
                rows.as_mut_slice()
                    .par_chunks_mut(m_rows)
                    .zip(candidates.par_iter().zip(&class_of))
                    .for_each(|(col, (cand, &class))| column(col, cand, class));
            }
            rows
        }
        RowsOut::ProductOnly => {
            // One column at a time per thread, dotted with b as `tr_mul` dots each column.
            let products: Vec<f64> = candidates
                .par_iter()
                .zip(&class_of)
                .map_init(
                    || vec![0.0; m_rows],
                    |col, (cand, &class)| {
                        column(col, cand, class);
                        nalgebra::DVectorView::from_slice(col, col.len()).dot(&rhs)
                    },
                )
                .collect();
            rows_times_rhs = Some(DVector::from_vec(products));
            DMatrix::zeros(0, p)
        }
        RowsOut::Sparse => {
            // Sample by sample in parallel, collected in sample order: each candidate's slope
            // once per sample, each row's non-zeros in column order, and the sample's
            // consecutive rows of the same columns as one run.
            let runs: Vec<Vec<Run>> = (0..frames.len())
                .into_par_iter()
                .map(|si| {
                    let frame = &frames[si];
                    let slopes: Vec<f64> = candidates
                        .iter()
                        .zip(&class_of)
                        .map(|(cand, &class)| cand.element.profile.slope(tables[class].0[si] - cand.element.offset))
                        .collect();
                    let (mut start, mut flat) = (vec![0], Vec::new());
                    for c in 0..frame.directions.len() {
                        let r = si * (n - 1) + c;
                        for (j, (&slope, &class)) in slopes.iter().zip(&class_of).enumerate() {
                            let v = entry(slope, tables[class].1[r], frame.weight);
                            if v != 0.0 {
                                flat.push((j, v));
                            }
                        }
                        start.push(flat.len());
                    }
                    Run::of_rows(si * (n - 1), &start, &flat)
                })
                .collect();
            sparse = Some(SparseRows { rows: m_rows, columns: p, runs: runs.into_iter().flatten().collect() });
            DMatrix::zeros(0, p)
        }
    };
    let (mono, mono_rhs) = if req.monotone {
        // Scaled like the rows: ∇U·γ̇ ≈ ω² s for the exact potential.
        let mut mono = DMatrix::zeros(samples.len(), p);
        if !samples.is_empty() {
            mono.as_mut_slice().par_chunks_mut(samples.len()).zip(candidates.par_iter()).for_each(|(col, cand)| {
                let e = &cand.element;
                for (si, &(q, qd, s)) in samples.iter().enumerate() {
                    let at: f64 = e.coupling.iter().zip(qd.iter()).map(|(a, t)| a * t).sum();
                    col[si] = e.profile.slope(e.deflection(q)) * at * (1.0 / (w2 * s));
                }
            });
        }
        let mono_rhs = DVector::from_iterator(
            samples.len(),
            samples
                .iter()
                .zip(&frames)
                .map(|(&(_, qd, s), frame)| -frame.gravity.dot(&DVector::from_column_slice(qd)) * (1.0 / (w2 * s))),
        );
        (mono, mono_rhs)
    } else {
        (DMatrix::zeros(0, p), DVector::zeros(0))
    };

    // Equalities at q_eq, scaled by 1/(ω² · mean diagonal of M(q_eq)).
    let q0 = q_eq.as_slice();
    let m_eq = chain.mass_matrix(q_eq);
    let m_scale = m_eq.diagonal().mean();
    let scale = 1.0 / (w2 * m_scale);
    let grav_eq = chain.gravity_gradient(q0);
    let grav_hess = chain.gravity_hessian(q0);
    let mut equalities = Vec::new();
    let mut eq_grad = DMatrix::zeros(n, p);
    for (j, cand) in candidates.iter().enumerate() {
        let e = &cand.element;
        let slope = e.profile.slope(e.deflection(q0));
        for i in 0..n {
            eq_grad[(i, j)] = slope * e.coupling[i] * scale;
        }
    }
    equalities.push(LinearGroup {
        name: "equilibrium gradient".into(),
        description: "∂U/∂q(q_eq) = 0: the springs must hold the arm at the equilibrium".into(),
        matrix: eq_grad,
        rhs: -grav_eq * scale,
    });
    let m_inv = m_eq.clone().try_inverse().expect("M(q_eq) is invertible");
    if req.hessian_match {
        let pairs: Vec<(usize, usize)> = (0..n).flat_map(|i| (i..n).map(move |k| (i, k))).collect();
        let mut hm = DMatrix::zeros(pairs.len(), p);
        let mut hr = DVector::zeros(pairs.len());
        for (r, &(i, k)) in pairs.iter().enumerate() {
            for (j, cand) in candidates.iter().enumerate() {
                let e = &cand.element;
                let curv = e.profile.eval(e.deflection(q0)).2;
                hm[(r, j)] = curv * e.coupling[i] * e.coupling[k] * scale;
            }
            hr[r] = (w2 * m_eq[(i, k)] - grav_hess[(i, k)]) * scale;
        }
        equalities.push(LinearGroup {
            name: "Hessian match".into(),
            description: format!(
                "∇²U(q_eq) = ω² M(q_eq) with ω = {} rad/s: every small oscillation at frequency ω",
                req.omega
            ),
            matrix: hm,
            rhs: hr,
        });
    } else {
        let mut tr = DMatrix::zeros(1, p);
        for (j, cand) in candidates.iter().enumerate() {
            let e = &cand.element;
            let curv = e.profile.eval(e.deflection(q0)).2;
            let a = DVector::from_column_slice(&e.coupling);
            tr[(0, j)] = curv * a.dot(&(&m_inv * &a)) / (n as f64 * w2);
        }
        let target = (n as f64 * w2 - (&m_inv * &grav_hess).trace()) / (n as f64 * w2);
        equalities.push(LinearGroup {
            name: "normalisation".into(),
            description: format!("tr(M(q_eq)⁻¹ ∇²U(q_eq)) = n ω² with ω = {} rad/s", req.omega),
            matrix: tr,
            rhs: DVector::from_element(1, target),
        });
    }
    let inequalities = if req.monotone {
        vec![LinearGroup {
            name: "monotonicity".into(),
            description: "∂U/∂q·γ̇ ≥ 0 on every training sample: U grows along every geodesic".into(),
            matrix: mono,
            rhs: mono_rhs,
        }]
    } else {
        Vec::new()
    };
    // The tables become the factors in place (weighted): no second copy of them.
    let (at_q, factors): (Vec<Vec<f64>>, Vec<Vec<f64>>) = tables
        .into_iter()
        .map(|(at, mut aw)| {
            for (si, frame) in frames.iter().enumerate() {
                for c in 0..frame.directions.len() {
                    aw[si * (n - 1) + c] *= frame.weight;
                }
            }
            (at, aw)
        })
        .unzip();
    (FitProblem { rows, rhs, equalities, inequalities }, RowFactors { at_q, factors, class_of, rows_times_rhs, sparse })
}

/// Moves the contribution of elements whose stiffness is fixed (trim springs at mid-range: set
/// after the build, so not the fit's to choose) to the right-hand sides of `problem`, which was
/// assembled with the same fan and requirements: with the fixed elements' columns F and
/// stiffnesses k_f (the set `fixed`), rows A k ≈ b become A k ≈ b − F k_f, equalities E k = e become
/// E k = e − E_f k_f and inequalities G k ≥ h become G k ≥ h − G_f k_f. Everything solved
/// afterwards (the nominal fit, the tolerance-aware fit, the selection) then sees the fixed
/// elements. The preload bound needs no change for trims: they are relaxed at q_eq, so their
/// preload is zero.
pub fn fold_fixed(
    problem: &mut FitProblem,
    chain: &Chain,
    q_eq: &DVector<f64>,
    fan: &Fan,
    fixed: &SpringSet,
    req: Requirements,
) {
    if fixed.elements.is_empty() {
        return;
    }
    let columns: Vec<Candidate> = fixed.elements.iter().map(|e| Candidate::bare(e.clone())).collect();
    let f = assemble(chain, q_eq, fan, &columns, req);
    let k = DVector::from_column_slice(&fixed.stiffness);
    problem.rhs -= &f.rows * &k;
    for (g, gf) in problem.equalities.iter_mut().zip(&f.equalities) {
        g.rhs -= &gf.matrix * &k;
    }
    for (g, gf) in problem.inequalities.iter_mut().zip(&f.inequalities) {
        g.rhs -= &gf.matrix * &k;
    }
}

/// The arm a solve describes: the candidates with k > 0 and the trims at their fixed rates (the
/// fit was solved around them).
pub fn arm(candidates: &[Candidate], k: &[f64], trims: &SpringSet) -> SpringSet {
    let used: Vec<usize> = (0..k.len()).filter(|&j| k[j] > 0.0).collect();
    SpringSet {
        elements: used.iter().map(|&j| candidates[j].element.clone()).chain(trims.elements.iter().cloned()).collect(),
        stiffness: used.iter().map(|&j| k[j]).chain(trims.stiffness.iter().copied()).collect(),
    }
}

/// Preload per unit stiffness of each candidate: u′(a·q_eq − x₀), the torque on its coordinate
/// at the equilibrium (signed). The preload of an element is k times this.
pub fn unit_preloads(candidates: &[Candidate], q_eq: &[f64]) -> Vec<f64> {
    candidates.iter().map(|c| c.element.profile.slope(c.element.deflection(q_eq))).collect()
}

/// The catalogue's trim springs at their mid-range rates (room to trim both ways), relaxed at
/// q_eq: the part of the potential the fit holds fixed (see `fit::problem::fold_fixed`).
pub fn mid_range(catalog: &Catalog, q_eq: &[f64]) -> (Vec<TrimSpring>, SpringSet) {
    let trims = catalog.trims(q_eq);
    let springs = SpringSet {
        elements: trims.iter().map(|t| t.element.clone()).collect(),
        stiffness: trims.iter().map(|t| 0.5 * (t.range[0] + t.range[1])).collect(),
    };
    (trims, springs)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rows factor as the normal equations of a large fit assume: every entry is the
    /// candidate's slope at its sample times its coupling's factor at its row (three joints,
    /// cranks, linear and compression springs on joints, pairs and triples).
    #[test]
    fn the_rows_factor_by_coupling() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("designs/triple_pendulum.toml");
        let design = crate::design::Design::load(&path).unwrap();
        let catalog = Catalog::load(design.catalog.as_ref().unwrap(), design.dof()).unwrap();
        let q0 = design.q_eq.as_slice();
        let candidates = catalog.expand(q0, |_| (-1.0, 1.0));
        use crate::geodesic::{FanSpec, Stop};
        let spec = FanSpec { count: 12, phase: 0.0, stop: Stop::Arc(0.3), spacing: 0.05 };
        let training = Fan::trace(&design.chain, &design.q_eq, spec, design.geodesics.ode).unwrap();
        let req = Requirements { omega: design.fit.frequency, hessian_match: true, monotone: false };
        let (problem, factors) =
            assemble_factored(&design.chain, &design.q_eq, &training, &candidates, req, RowsOut::Dense);
        let per = design.dof() - 1;
        let samples = problem.rows.nrows() / per;
        assert!(
            factors.factors.len() > 3 && samples == 12 * 6,
            "{} couplings, {samples} samples",
            factors.factors.len()
        );
        let mut slope = vec![0.0; samples];
        for j in 0..candidates.len() {
            factors.slopes(&candidates, j, 0, &mut slope);
            for r in 0..problem.rows.nrows() {
                let want = problem.rows[(r, j)];
                let got = slope[r / per] * factors.factors[factors.class_of[j]][r];
                assert!((got - want).abs() <= 1e-15 * want.abs().max(1e-300), "{j} {r}: {got} {want}");
            }
        }
    }

    /// The rows written as their non-zeros are the dense rows, entry for entry, and give the
    /// same normal equations bit for bit, on a cam design of six joints (five rows per sample):
    /// the UR5 of `designs/ur5_six.toml` with the 40 cams of `catalogs/ur5_cams_pursuit.toml`
    /// (the withdrawn `ur5_six_cams` design).
    #[test]
    fn sparse_rows_are_the_dense_rows() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let design = crate::design::Design::load(&root.join("designs/ur5_six.toml")).unwrap();
        let catalog = Catalog::load(&root.join("catalogs/ur5_cams_pursuit.toml"), design.dof()).unwrap();
        let q0 = design.q_eq.as_slice();
        let candidates = catalog.expand(q0, |_| (-1.5, 1.5));
        use crate::geodesic::{FanSpec, Stop};
        let spec = FanSpec { count: 24, phase: 0.0, stop: Stop::Arc(0.6), spacing: 0.1 };
        let training = Fan::trace(&design.chain, &design.q_eq, spec, design.geodesics.ode).unwrap();
        let req = Requirements { omega: design.fit.frequency, hessian_match: true, monotone: false };
        let (dense, _) = assemble_factored(&design.chain, &design.q_eq, &training, &candidates, req, RowsOut::Dense);
        let (bare, mut f) =
            assemble_factored(&design.chain, &design.q_eq, &training, &candidates, req, RowsOut::Sparse);
        let sparse = f.sparse.take().unwrap();
        assert_eq!((bare.rows.nrows(), bare.row_count()), (0, dense.rows.nrows()));
        assert_eq!(bare.rhs, dense.rhs);
        let nnz = dense.rows.iter().filter(|v| **v != 0.0).count();
        assert!(nnz * 4 < dense.rows.len() && sparse.nnz() == nnz, "{nnz} of {}", dense.rows.len());
        assert!(sparse.runs.iter().any(|r| r.rows > 1), "no run of several rows");
        assert_eq!(sparse.to_dense(), dense.rows);
        let want = crate::solve::lsq::Gram::from_sparse_rows(&dense.rows, &dense.rhs);
        assert_eq!(crate::solve::lsq::Gram::from_sparse(&sparse, &dense.rhs), want);
    }

    #[test]
    fn complement_is_orthonormal() {
        for t in [vec![0.3, -0.8], vec![1.0, 2.0, -0.5], vec![0.0, 0.0, 1.0, 0.2]] {
            let c = complement(&t);
            assert_eq!(c.ncols(), t.len() - 1);
            let tv = DVector::from_column_slice(&t);
            assert!((c.transpose() * &tv).amax() < 1e-14);
            assert!((c.transpose() * &c - DMatrix::identity(t.len() - 1, t.len() - 1)).amax() < 1e-14);
        }
    }
}
