//! The log map fitted cell by cell: the fast label where one polynomial over the whole ball
//! misses (six joints).
//!
//! **Why cells.** On `ur5_six` the log map is smooth but far from polynomial over the ball: one
//! fit of degree 4 misses by 6.6°, degree 6 still by 2.0° ([`super::logfit`]), while the same
//! degree 4 over a quarter of the radius misses by 0.1°. So the ball (in the scaled metric frame
//! x = Lᵀ(q − q_eq)/R of [`super::logfit`]) is cut into boxes, each with its own polynomial of
//! low degree, and only where the held-out error asks for it: a k-d tree that splits the cell
//! whose held-out error exceeds the target along the widest axis of its samples, at their
//! median (so both halves keep the same number of samples), until every cell meets the target or
//! holds too few samples to be split again.
//!
//! **Data without Newton.** Every point of a geodesic t ↦ exp(t·u) has log = t·u, so the
//! training and held-out samples (x, w) are points of geodesics traced once from q_eq (one
//! integration each, no Jacobi fields, no Newton shooting). The samples of one geodesic are
//! taken at radii s_k = R·((k + φ)/K)^(1/p) (φ a golden-ratio phase per direction): p = n would
//! spread them evenly over the ball's volume, p < n keeps more towards the centre, where the
//! error is relative to a small |w| ([`CellSpec::radial_power`]).
//!
//! **What each cell fits.** w − x by a full polynomial of degree d in the cell's own coordinates
//! z = (x − centre)/half-width (well conditioned whatever the cell's size), least squares with
//! weights 1/|x| (the label is the direction of w, so the relative error is what counts, as in
//! [`super::logfit`]). The gradient ∂w/∂x of the label comes from differentiating the same
//! polynomial. The map is piecewise: across a cell face the label jumps by at most about the
//! two cells' error (held below the target).
//!
//! **Derivatives as data** ([`CellSpec::derivatives`], the default from six joints). The same geodesics can
//! be traced with their Jacobi fields, which give ∂w/∂x at every sample exactly (∂v/∂q = s·Φ_q⁻¹,
//! as in [`super::logfit`]): n more equations per sample and output, and what a cell's samples,
//! strung along few geodesics, do not tell on their own, the map's slope across them. A cell's
//! polynomial is then fitted to values and derivatives together (Hermite-type least squares,
//! `hermite_normal`), which makes cubic cells usable where cubic cells on values alone extrapolate
//! between their geodesics (15.9°). The Jacobi fields make a geodesic dearer (2n + 2n² states
//! instead of 2n: 84 against 12 for six joints). Measured on `ur5_six` (`measure_cells_on_ur5_six`, the check fan's
//! 3600 samples and 200 random interior points against Newton shooting; CPU of the whole
//! measurement under load average 16): cubic cells on 24 000 geodesics × 4 samples, at least
//! 100 samples a cell, 512 cells (2.2 MB), 1.00° on the fan and 0.46° at the random points,
//! 51 s; on 12 000 × 8, 1.58° (32 s); quadratic on 48 000 × 3, 4096 cells (6.2 MB), 0.94° and
//! 0.55° (89 s); quadratic on 24 000 × 6, 1.57°. More geodesics help more than more samples on
//! each. So the derivatives buy about a factor 1.8 against the cells on values alone (1.76°),
//! far from the factor 18 that 0.1° asks.
//!
//! **The inner ball** ([`CellSpec::inner`], six joints: a quarter of the radius). Where |w| is
//! small a cell's absolute error is a large angle, and few samples lie there: with the cells
//! alone the inner quarter of the extent missed by 0.3–1°. One polynomial w = x + P(x) through
//! q_eq with the identity slope there ([`super::logfit`]'s form, fitted over the small ball)
//! answers there instead: 0.025° in the inner quarter (`measure_cells_on_ur5_six`). The largest
//! error is then in the outer three quarters (0.58°, 0.68°, 1.00° by quarter on the check fan;
//! 0.46° at the random points), which only more samples would lower: spreading the same samples
//! evenly over the volume (radial power 6) made the second quarter worse (2.26°), 4.5 too
//! (1.03°). The loop needs less than 0.1°: a five-mode switch on `ur5_six` with these cells settles
//! every step by the exact label, so `auto` takes them within 1.5° from six joints
//! ([`crate::design::simulate::AUTO_LOOP_LABEL_MAX_ERROR_DEG`]).
//!
//! **Cost per call.** A descent of the tree (its depth, about log₂ of the cells) and one
//! polynomial with its gradient: (n + 1)·n·m multiply–adds for m = C(n + d, d) monomials (28
//! for six joints at degree 2), fewer than the global fit's. Build and memory are stated in
//! [`CellSpec::for_joints`] and measured in `BENCHMARKS.md`.
//!
//! **Determinism.** Geodesics are traced in parallel and collected in direction order; the
//! tree is grown level by level, the cells of a level fitted in parallel and collected in order,
//! and every split decided on the ordered results: the tree does not depend on the thread count.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::geodesic::polynomial::{fill_basis, mat_mul, monomial_count, monomials};
use crate::geodesic::{MetricFrame, Shooter, Stop, unit_vectors};
use crate::model::Chain;
use crate::numerics::ode::OdeSettings;

/// How a [`CellTree`] is built.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellSpec {
    /// Total degree of each cell's polynomial (≥ 1).
    pub degree: usize,
    /// Training geodesics.
    pub directions: usize,
    /// Held-out geodesics (a disjoint set of directions) the split decisions are judged on.
    pub held_out: usize,
    /// Samples taken from each geodesic.
    pub per_direction: usize,
    /// p of the sample radii s_k = R·((k + φ)/K)^(1/p) (module docs): n spreads the samples
    /// evenly over the ball, smaller values keep more near the centre.
    pub radial_power: f64,
    /// Largest doubled angle between the fitted and exact label lines a cell may keep on its
    /// held-out samples, degrees.
    pub target_deg: f64,
    /// Held-out samples nearer q_eq than this fraction of the ball's radius are not judged (the
    /// label is undefined at q_eq and the controller is off near it).
    pub min_r: f64,
    /// A cell is split only if it holds at least twice this many training samples.
    pub min_samples: usize,
    /// Ridge added to the equilibrated normal equations (unit diagonal): damps the directions
    /// of a cell's polynomial its few samples leave undetermined.
    pub ridge: f64,
    /// Fit each training sample's derivative ∂w/∂x as well as its value (Hermite-type least
    /// squares, module docs): the training geodesics are traced with their Jacobi fields.
    pub derivatives: bool,
    /// A cell holding more training samples than this is split without being fitted (its
    /// polynomial could not meet the target anyway; the fits of the top levels are the bulk of
    /// the build when each sample brings n + 1 equations).
    pub split_above: usize,
    /// Radius of the inner ball, as a fraction of the fitted ball's, served by one polynomial
    /// w = x + P(x) through q_eq with the identity slope there ([`super::logfit`]'s global form
    /// over the small ball) instead of the cells (0: cells everywhere). Why: a cell that holds
    /// q_eq or lies near it misses by a small absolute error, which is a large angle where |w|
    /// is small, and few samples fall there; the one polynomial is exact in value and slope at
    /// q_eq and converges fast over a small ball (0.096° over a quarter of the radius).
    pub inner: f64,
}

impl CellSpec {
    /// The default for `n` joints: cells judged at half of `label = "auto"`'s 0.1° (so that
    /// another held-out fan stays within it where the data suffice). Up to five joints,
    /// quadratic cells fitted to values, three samples per geodesic and many geodesics; from six,
    /// cubic cells fitted to values and derivatives (module docs) on 24 000 geodesics × 4, at
    /// least 100 samples a cell.
    ///
    /// Measured on `ur5_six` (`measure_cells_on_ur5_six`: the largest error on `simulate`'s
    /// check fan of 3600 samples; CPU seconds of the whole measurement, under load): on values
    /// alone, cubic cells on 24 000 geodesics of 12 samples 15.9° (a cell's samples lie on few
    /// geodesics, so its cubic is poorly determined across them), quadratic 2.83°, linear 20°;
    /// quadratic on 96 000 geodesics of 3 samples 1.19° (30 s), on 72 000 (the default before)
    /// 1.76° (26 s, 2048 cells, 3.1 MB). With derivatives, cubic on 24 000 × 4: 1.00° (51 s,
    /// 512 cells, 2.2 MB; the Jacobi samples take 37 MB while building). The error falls slowly
    /// with the data (a cell's polynomial misses by a power of its size, and the cells of a
    /// six-dimensional ball shrink as the sixth root of their number): 0.1° would take some
    /// hundred times the samples, beyond the build's budget of 60 s on one core and 200 MB. From
    /// six joints the inner quarter of the radius is one polynomial ([`CellSpec::inner`]: 0.025°
    /// there instead of 0.3–1°; 51.5 CPU s, peak 269 MB resident for the whole measurement).
    /// `label = "table"` builds cells for any number of joints, `auto` from six
    /// ([`super::logfit::fit_label`]). Fewer joints cover their sphere as densely with fewer
    /// directions; the derivatives were measured on six joints only.
    pub fn for_joints(n: usize) -> Self {
        let directions = match n {
            0..=3 => 4_000,
            4 => 16_000,
            5 => 40_000,
            _ => 24_000,
        };
        let (degree, per_direction, min_samples, derivatives, split_above) =
            if n >= 6 { (3, 4, 100, true, 2_000) } else { (2, 3, 3 * monomial_count(n, 2), false, usize::MAX) };
        CellSpec {
            degree,
            directions,
            held_out: directions / 4,
            per_direction,
            radial_power: (n as f64 / 2.0).max(1.0),
            target_deg: 0.05,
            min_r: 0.05,
            min_samples,
            ridge: 1e-10,
            derivatives,
            split_above,
            inner: if n >= 6 { 0.25 } else { 0.0 },
        }
    }
}

/// Exact samples (x, w) of the scaled log map, n coordinates each, flat, with ∂w/∂x (row-major
/// n × n each) when traced with Jacobi fields (else empty).
struct Samples {
    x: Vec<f64>,
    w: Vec<f64>,
    dw: Vec<f64>,
}

impl Samples {
    fn len(&self, n: usize) -> usize {
        self.x.len() / n
    }
}

/// One cell's polynomial: w − x ≈ Σ coef·monomial(z), z = (x − centre)·inv_half.
#[derive(Debug, Clone, PartialEq)]
struct Leaf {
    centre: Vec<f64>,
    inv_half: Vec<f64>,
    /// monomials × n.
    coef: DMatrix<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Node {
    /// x[axis] < at goes to `left`, else to `right`.
    Split {
        axis: usize,
        at: f64,
        left: usize,
        right: usize,
    },
    Leaf(usize),
}

/// The tree of cells (module docs), in the scaled metric frame.
#[derive(Debug, Clone, PartialEq)]
pub struct CellTree {
    n: usize,
    degree: usize,
    monomials: Vec<(usize, usize)>,
    nodes: Vec<Node>,
    leaves: Vec<Leaf>,
    /// The largest held-out error a leaf kept, degrees (above the target where a cell ran out
    /// of samples).
    worst_deg: f64,
    samples: usize,
}

/// Where one cell of the growing tree stands: its node and the samples inside it.
struct Pending {
    node: usize,
    train: Vec<u32>,
    held: Vec<u32>,
}

impl CellTree {
    /// Traces the samples and grows the tree. `lt` is Lᵀ/R row-major (x = lt·(q − q_eq)),
    /// `lt_inv` its inverse, `radius` R the ball's radius.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn build(
        chain: &Chain,
        q_eq: &DVector<f64>,
        ode: OdeSettings,
        frame: &MetricFrame,
        lt: &[f64],
        lt_inv: &[f64],
        radius: f64,
        spec: CellSpec,
    ) -> Result<CellTree> {
        let n = chain.dof();
        if spec.degree < 1
            || spec.directions == 0
            || spec.per_direction == 0
            || spec.radial_power <= 0.0
            || !(0.0..1.0).contains(&spec.inner)
        {
            return Err(Error::Setting {
                field: "label".into(),
                reason: format!(
                    "a cell-fitted label needs a degree ≥ 1, directions and samples and an inner ball in [0, 1), got {spec:?}"
                ),
            });
        }
        let scaled = Scaled { frame, lt, lt_inv, radius };
        let trace = |dirs: Vec<DVector<f64>>, derivatives: bool| {
            sample(chain, q_eq, ode, &scaled, &dirs, CellSpec { derivatives, ..spec })
        };
        let train = trace(unit_vectors(n, spec.directions, 0.0), spec.derivatives)?;
        // The held-out samples judge values only: no Jacobi fields.
        let held = trace(unit_vectors(n, spec.held_out.max(1), 0.5), false)?;
        let monomials = monomials(n, spec.degree);
        let mut nodes = vec![Node::Leaf(0)];
        let mut leaves = Vec::new();
        let mut worst: f64 = 0.0;
        let mut frontier = vec![Pending {
            node: 0,
            train: (0..train.len(n) as u32).collect(),
            held: (0..held.len(n) as u32).collect(),
        }];
        while !frontier.is_empty() {
            let fits: Vec<Option<(Leaf, f64)>> = frontier
                .par_iter()
                .map(|p| (p.train.len() <= spec.split_above).then(|| fit_cell(&monomials, &train, &held, p, spec, n)))
                .collect();
            let mut next = Vec::new();
            for (p, fit) in frontier.into_iter().zip(fits) {
                let err = fit.as_ref().map_or(f64::INFINITY, |f| f.1);
                if err > spec.target_deg && p.train.len() >= 2 * spec.min_samples {
                    let (axis, at) = median_split(&train.x, &p.train, n);
                    let side = |x: &[f64], ids: &[u32]| -> (Vec<u32>, Vec<u32>) {
                        ids.iter().partition(|&&k| x[k as usize * n + axis] < at)
                    };
                    let (tl, tr) = side(&train.x, &p.train);
                    let (hl, hr) = side(&held.x, &p.held);
                    if tl.len() >= spec.min_samples && tr.len() >= spec.min_samples {
                        let (left, right) = (nodes.len(), nodes.len() + 1);
                        nodes.push(Node::Leaf(0));
                        nodes.push(Node::Leaf(0));
                        nodes[p.node] = Node::Split { axis, at, left, right };
                        next.push(Pending { node: left, train: tl, held: hl });
                        next.push(Pending { node: right, train: tr, held: hr });
                        continue;
                    }
                }
                let (leaf, err) = match fit {
                    Some(f) => f,
                    None => fit_cell(&monomials, &train, &held, &p, spec, n),
                };
                worst = worst.max(err);
                nodes[p.node] = Node::Leaf(leaves.len());
                leaves.push(leaf);
            }
            frontier = next;
        }
        Ok(CellTree { n, degree: spec.degree, monomials, nodes, leaves, worst_deg: worst, samples: train.len(n) })
    }

    /// Each cell's polynomial degree.
    pub fn degree(&self) -> usize {
        self.degree
    }

    /// Monomials per cell.
    pub fn terms(&self) -> usize {
        self.monomials.len()
    }

    /// Number of cells.
    pub fn cells(&self) -> usize {
        self.leaves.len()
    }

    /// Training samples the cells were fitted to.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// The largest held-out error a cell kept when the tree stopped growing, degrees.
    pub fn build_error_deg(&self) -> f64 {
        self.worst_deg
    }

    /// Bytes the cells hold (coefficients, centres and scales, nodes).
    pub fn bytes(&self) -> usize {
        let per_leaf = (self.monomials.len() * self.n + 2 * self.n) * std::mem::size_of::<f64>();
        self.leaves.len() * per_leaf + self.nodes.len() * std::mem::size_of::<Node>()
    }

    /// w and ∂w/∂x (row-major n × n) at x, with `basis` (monomials × (n + 1)) and `product`
    /// (n × (n + 1)) as scratch.
    pub(crate) fn eval(
        &self,
        x: &[f64],
        basis: &mut DMatrix<f64>,
        product: &mut DMatrix<f64>,
        w: &mut [f64],
        dwdx: &mut [f64],
    ) {
        let n = self.n;
        let mut node = 0;
        let leaf = loop {
            match self.nodes[node] {
                Node::Split { axis, at, left, right } => node = if x[axis] < at { left } else { right },
                Node::Leaf(k) => break &self.leaves[k],
            }
        };
        let mut z = [0.0f64; 16];
        let z = &mut z[..n];
        for j in 0..n {
            z[j] = (x[j] - leaf.centre[j]) * leaf.inv_half[j];
        }
        fill_basis(&self.monomials, z, basis);
        product.gemm_tr(1.0, &leaf.coef, basis, 0.0);
        for i in 0..n {
            w[i] = x[i] + product[(i, 0)];
            for j in 0..n {
                let id = if i == j { 1.0 } else { 0.0 };
                dwdx[i * n + j] = id + product[(i, 1 + j)] * leaf.inv_half[j];
            }
        }
    }
}

/// The scaled metric frame the samples are taken in: the frame directions are drawn in, Lᵀ/R
/// and R·L⁻ᵀ row-major, and R.
struct Scaled<'f> {
    frame: &'f MetricFrame,
    lt: &'f [f64],
    lt_inv: &'f [f64],
    radius: f64,
}

/// The samples of the geodesics of frame directions `dirs` (module docs), in direction order;
/// with ∂w/∂x if `spec.derivatives`.
fn sample(
    chain: &Chain,
    q_eq: &DVector<f64>,
    ode: OdeSettings,
    scaled: &Scaled<'_>,
    dirs: &[DVector<f64>],
    spec: CellSpec,
) -> Result<Samples> {
    let n = chain.dof();
    let Scaled { frame, lt, lt_inv, radius } = *scaled;
    let k = spec.per_direction;
    // Trace samples 4 per target radius on average; each target takes the nearest.
    let fine = 4 * k;
    let spacing = radius / fine as f64;
    let golden = (5f64.sqrt() - 1.0) / 2.0;
    let stride = 2 * n + if spec.derivatives { n * n } else { 0 };
    let to_x = |q: &[f64], out: &mut Vec<f64>| {
        for r in 0..n {
            out.push((0..n).map(|c| lt[r * n + c] * (q[c] - q_eq[c])).sum());
        }
    };
    let per: Vec<Result<Vec<f64>>> = dirs
        .par_iter()
        .enumerate()
        .map_init(
            || Shooter::new(chain, q_eq, ode),
            |shooter, (i, u)| {
                let phase = (golden * i as f64).fract();
                let arcs: Vec<f64> =
                    (0..k).map(|j| radius * ((j as f64 + phase) / k as f64).powf(1.0 / spec.radial_power)).collect();
                let mut out = Vec::with_capacity(stride * k);
                if spec.derivatives {
                    // Exactly at the target radii, with Φ_q: ∂v/∂q = s Φ_q⁻¹ and
                    // ∂w/∂x = (Lᵀ/R) ∂v/∂q (R L⁻ᵀ), as in [`super::logfit`].
                    let arcs: Vec<f64> = arcs.into_iter().filter(|&s| s > 0.0).collect();
                    let traced = shooter.jacobi_samples(&frame.to_joint(u), &arcs)?;
                    let mut dvdq = vec![0.0; n * n];
                    let mut tmp = vec![0.0; n * n];
                    for ((q, phi), &s) in traced.iter().zip(&arcs) {
                        let inv = DMatrix::from_column_slice(n, n, phi).try_inverse().ok_or_else(|| {
                            Error::numerical(
                                "fitted label",
                                format!("d exp is singular at arc length {s:.4} (a conjugate point inside the ball)"),
                            )
                        })?;
                        for r in 0..n {
                            for c in 0..n {
                                dvdq[r * n + c] = s * inv[(r, c)];
                            }
                        }
                        to_x(q, &mut out);
                        out.extend(u.iter().map(|ur| s / radius * ur));
                        mat_mul(lt, &dvdq, n, &mut tmp);
                        let at = out.len();
                        out.resize(at + n * n, 0.0);
                        mat_mul(&tmp, lt_inv, n, &mut out[at..]);
                    }
                    return Ok(out);
                }
                let g = shooter.trace(&frame.to_joint(u), Stop::Arc(radius), spacing)?;
                let mut last = usize::MAX;
                for &s in &arcs {
                    let idx = ((s / spacing).round() as usize).clamp(1, g.len()) - 1;
                    if idx == last {
                        continue;
                    }
                    last = idx;
                    let (q, s) = (g.q(idx), g.s(idx));
                    to_x(q, &mut out);
                    // w = (s/R)·u: log(q) = s·(joint direction of u), in the scaled frame.
                    out.extend(u.iter().map(|ur| s / radius * ur));
                }
                Ok(out)
            },
        )
        .collect();
    let mut samples = Samples { x: Vec::new(), w: Vec::new(), dw: Vec::new() };
    for p in per {
        for one in p?.chunks_exact(stride) {
            samples.x.extend_from_slice(&one[..n]);
            samples.w.extend_from_slice(&one[n..2 * n]);
            samples.dw.extend_from_slice(&one[2 * n..]);
        }
    }
    Ok(samples)
}

/// The widest axis of the samples `ids` and their median along it.
fn median_split(x: &[f64], ids: &[u32], n: usize) -> (usize, f64) {
    let mut best = (0, -1.0);
    for axis in 0..n {
        let (lo, hi) = ids.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &k| {
            let v = x[k as usize * n + axis];
            (lo.min(v), hi.max(v))
        });
        if hi - lo > best.1 {
            best = (axis, hi - lo);
        }
    }
    let axis = best.0;
    let mut vals: Vec<f64> = ids.iter().map(|&k| x[k as usize * n + axis]).collect();
    let mid = vals.len() / 2;
    vals.select_nth_unstable_by(mid, f64::total_cmp);
    (axis, vals[mid])
}

/// Values of the monomials at z into `out` (the recursion of [`fill_basis`] without gradients).
fn monomial_values(monomials: &[(usize, usize)], z: &[f64], out: &mut [f64]) {
    out[0] = 1.0;
    for (k, &(p, var)) in monomials.iter().enumerate().skip(1) {
        out[k] = out[p] * z[var];
    }
}

/// Samples per block of the Hermite normal equations ([`hermite_normal`]).
const BLOCK: usize = 64;

/// The normal equations of one cell's Hermite-type least squares (module docs) into `normal`
/// (its upper triangle and more: the caller symmetrises from the upper one) and `rhs`: per
/// sample the value row, weight 1/|x|, and n derivative rows ∂P/∂z_j = (∂w/∂x − I)·half_j with
/// the same weight (an error ε of ∂P/∂z moves the value by about ε across the cell, as an
/// error ε of the value does). Accumulated by blocks of [`BLOCK`] samples through dense
/// products, in sample order.
#[allow(clippy::too_many_arguments)]
fn hermite_normal(
    monomials: &[(usize, usize)],
    train: &Samples,
    cell: &Pending,
    centre: &[f64],
    inv_half: &[f64],
    spec: CellSpec,
    n: usize,
    normal: &mut DMatrix<f64>,
    rhs: &mut DMatrix<f64>,
) {
    let terms = monomials.len();
    let rows = n + 1;
    let mut basis = DMatrix::<f64>::zeros(terms, rows);
    let mut z = vec![0.0; n];
    for block in cell.train.chunks(BLOCK) {
        // Rows of the design matrix as columns of `at` (terms × rows), targets in `y`.
        let mut at = DMatrix::<f64>::zeros(terms, block.len() * rows);
        let mut y = DMatrix::<f64>::zeros(block.len() * rows, n);
        for (b, &k) in block.iter().enumerate() {
            let k = k as usize;
            let (x, w, dw) = (&train.x[k * n..][..n], &train.w[k * n..][..n], &train.dw[k * n * n..][..n * n]);
            for j in 0..n {
                z[j] = (x[j] - centre[j]) * inv_half[j];
            }
            fill_basis(monomials, &z, &mut basis);
            let xn = x.iter().map(|v| v * v).sum::<f64>().sqrt();
            let wt = 1.0 / xn.max(spec.min_r);
            for r in 0..rows {
                let col = b * rows + r;
                for a in 0..terms {
                    at[(a, col)] = basis[(a, r)] * wt;
                }
            }
            for i in 0..n {
                y[(b * rows, i)] = (w[i] - x[i]) * wt;
                for j in 0..n {
                    let id = if i == j { 1.0 } else { 0.0 };
                    y[(b * rows + 1 + j, i)] = (dw[i * n + j] - id) / inv_half[j] * wt;
                }
            }
        }
        let a = at.transpose();
        normal.gemm(1.0, &at, &a, 1.0);
        rhs.gemm(1.0, &at, &y, 1.0);
    }
}

/// Fits one cell (module docs) and returns it with its largest held-out error, degrees (0 when
/// no held-out sample is judged in it).
fn fit_cell(
    monomials: &[(usize, usize)],
    train: &Samples,
    held: &Samples,
    cell: &Pending,
    spec: CellSpec,
    n: usize,
) -> (Leaf, f64) {
    let terms = monomials.len();
    let mut lo = vec![f64::INFINITY; n];
    let mut hi = vec![f64::NEG_INFINITY; n];
    for &k in &cell.train {
        for j in 0..n {
            let v = train.x[k as usize * n + j];
            lo[j] = lo[j].min(v);
            hi[j] = hi[j].max(v);
        }
    }
    let centre: Vec<f64> = (0..n).map(|j| 0.5 * (lo[j] + hi[j])).collect();
    let inv_half: Vec<f64> = (0..n).map(|j| 1.0 / (0.5 * (hi[j] - lo[j])).max(1e-9)).collect();
    let mut normal = DMatrix::<f64>::zeros(terms, terms);
    let mut rhs = DMatrix::<f64>::zeros(terms, n);
    let mut phi = vec![0.0; terms];
    let mut z = vec![0.0; n];
    if train.dw.is_empty() {
        for &k in &cell.train {
            let (x, w) = (&train.x[k as usize * n..][..n], &train.w[k as usize * n..][..n]);
            for j in 0..n {
                z[j] = (x[j] - centre[j]) * inv_half[j];
            }
            monomial_values(monomials, &z, &mut phi);
            let xn = x.iter().map(|v| v * v).sum::<f64>().sqrt();
            let wt2 = 1.0 / xn.max(spec.min_r).powi(2);
            for a in 0..terms {
                let pa = phi[a] * wt2;
                for b in a..terms {
                    normal[(a, b)] += pa * phi[b];
                }
                for i in 0..n {
                    rhs[(a, i)] += pa * (w[i] - x[i]);
                }
            }
        }
    } else {
        hermite_normal(monomials, train, cell, &centre, &inv_half, spec, n, &mut normal, &mut rhs);
    }
    // Symmetrise, equilibrate and solve with a tiny ridge: a cell of few samples in a thin
    // slab stays solvable (its error then decides whether it is split).
    let scale: Vec<f64> = (0..terms).map(|a| 1.0 / normal[(a, a)].max(1e-300).sqrt()).collect();
    for a in 0..terms {
        for b in a..terms {
            let v = normal[(a, b)] * scale[a] * scale[b];
            normal[(a, b)] = v;
            normal[(b, a)] = v;
        }
        normal[(a, a)] += spec.ridge;
        for i in 0..n {
            rhs[(a, i)] *= scale[a];
        }
    }
    let mut coef = match normal.cholesky() {
        Some(chol) => chol.solve(&rhs),
        None => DMatrix::zeros(terms, n),
    };
    for a in 0..terms {
        for i in 0..n {
            coef[(a, i)] *= scale[a];
        }
    }
    let mut worst: f64 = 0.0;
    let mut fitted = vec![0.0; n];
    for &k in &cell.held {
        let (x, w) = (&held.x[k as usize * n..][..n], &held.w[k as usize * n..][..n]);
        let wn = w.iter().map(|v| v * v).sum::<f64>().sqrt();
        // The inner ball's polynomial answers there (`CellSpec::inner`): not the cell's error.
        let xn = x.iter().map(|v| v * v).sum::<f64>().sqrt();
        if wn < spec.min_r || xn < spec.inner {
            continue;
        }
        for j in 0..n {
            z[j] = (x[j] - centre[j]) * inv_half[j];
        }
        monomial_values(monomials, &z, &mut phi);
        for i in 0..n {
            fitted[i] = x[i] + (0..terms).map(|a| coef[(a, i)] * phi[a]).sum::<f64>();
        }
        worst = worst.max(line_angle_deg(&fitted, w));
    }
    if !worst.is_finite() {
        worst = f64::INFINITY;
    }
    (Leaf { centre, inv_half, coef }, worst)
}

/// The doubled angle 2·∠(±a, b) between the lines of `a` and `b`, degrees (atan2 keeps small
/// angles accurate, where acos of a cosine near 1 would not).
pub fn line_angle_deg(a: &[f64], b: &[f64]) -> f64 {
    let na = a.iter().map(|v| v * v).sum::<f64>().sqrt();
    let nb = b.iter().map(|v| v * v).sum::<f64>().sqrt();
    let c: f64 = a.iter().zip(b).map(|(p, q)| p * q).sum::<f64>() / (na * nb);
    let perp = a.iter().zip(b).map(|(p, q)| (p / na - c * q / nb).powi(2)).sum::<f64>().sqrt();
    2.0 * perp.atan2(c.abs()).to_degrees()
}
