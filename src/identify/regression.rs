//! The identification regression: the arm's equation of motion written linear in the unknowns.
//!
//! With measured angles q(t) and applied torques τ(t), the built arm obeys
//!
//! ```text
//! d/dt (M(q) q̇) − ∂T/∂q + ∂U_g/∂q + D q̇ + f_c sign(q̇) − τ = −Σᵢ kᵢ (1 + δᵢ) ∇uᵢ(q)
//! ```
//!
//! (T = ½ q̇ᵀ M q̇; the first two terms are M q̈ + C q̇ in Lagrange's form), linear in the rate
//! errors δᵢ (one per part: a spring, or a cam's coefficients together), the diagonal damping D
//! and the Coulomb friction f_c. Written as y = Φ θ per joint and sample:
//!
//! ```text
//! y = d/dt L[M q̇] + L[−∂T/∂q + ∂U_g/∂q − τ + Σᵢ kᵢ ∇uᵢ],
//! Φ = L[−kᵢ ∇uᵢ | −q̇ⱼ eⱼ | −sign(q̇ⱼ) eⱼ]
//! ```
//!
//! where L is one zero-phase low-pass applied to every term, so the equation holds for the
//! filtered terms exactly as for the raw ones: no acceleration is ever used unfiltered, and L
//! distorts nothing the two sides do not share. The angles are first smoothed by a second
//! zero-phase low-pass far above the motion (`smoothing_hz`, which removes the encoder's
//! quantisation steps), and the velocity is their central difference ([`central`]); the
//! smoothing's first and last [`LowPass::settle`] samples, which still carry how the angles were
//! extended, are dropped. The momentum's rate is the central difference of M q̇ (the momentum is
//! known two samples beyond each kept end, so every kept sample has one) and goes through L like
//! every other term: central differences and L are both linear and time-invariant, so in a run's
//! interior this is d/dt L[M q̇] exactly, the noise L removes the same. Every term is extended
//! even ([`Extension::Even`]) before L, so the equation still holds on the extensions, and the
//! filtered equation right up to the ends of what is kept (differentiating after an extension
//! would put a one-sided difference at each end, a bias of order Δt). Rows are taken every
//! `stride` samples: L leaves nothing above a few times its cut-off, so denser rows would repeat
//! the same information.
//!
//! Trim springs are known (their rates as the bill gives them, the rates the builder set) unless
//! `[identify] trims = "estimated"`: their torque then enters y at the design rate like every
//! other element's, and their δ is an unknown.

use rayon::prelude::*;

use super::filter::{Extension, LowPass, central, derivative};
use super::log::Run;
use crate::design::Design;
use crate::design::identify::{IdentifySettings, TrimRates};
use crate::fit::bill::BomRow;
use crate::potential::{GroupedSet, SpringSet};

/// What an unknown of the regression is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unknown {
    /// The rate error δ of part `part` (an index into [`Model::parts`]).
    Rate(usize),
    /// The viscous damping of a joint (0-based), N·m·s/rad.
    Damping(usize),
    /// The Coulomb friction of a joint (0-based), N·m.
    Friction(usize),
}

/// One physical part whose rate error the logs estimate: a spring, or a cam (its coefficient
/// rows share one δ: the follower spring's rate scales the whole cam).
#[derive(Debug, Clone)]
pub struct Part {
    /// The bill's id (`S01`), or the cam's (`C01`).
    pub id: String,
    /// Its catalogue family.
    pub family: String,
    /// Its rows in the bill of materials.
    pub rows: Vec<usize>,
    /// Whether it is a trim spring.
    pub trim: bool,
    /// The part's elements at their design rates, in evaluation form.
    set: GroupedSet,
}

/// What the regression knows of the arm as designed, and its unknowns.
#[derive(Debug, Clone)]
pub struct Model {
    /// Parts with an estimated rate, in bill order.
    pub parts: Vec<Part>,
    /// The unknowns: the parts' δ, then the damping, then the friction of each joint.
    pub unknowns: Vec<Unknown>,
    /// Every element of the bill at its design rate.
    designed: GroupedSet,
    /// The bill's elements with their rates, and each part's one element, when the bill has
    /// no cam (see [`Slopes`]).
    slopes: Option<Slopes>,
    dof: usize,
}

/// A bill without cams, evaluated once per sample for both the designed torque and the parts'
/// columns: each element's slope k u′(a·q − x₀) is the same number in both, so it is computed
/// once (on the Panda's 141 springs the two evaluations, a sine each, were a fifth of
/// `identify --plan`). The sums are [`GroupedSet::gradient_into`]'s, term by term in the bill's
/// order, so the rows are the same bit for bit.
#[derive(Debug, Clone)]
struct Slopes {
    /// Every row of the bill: its element and design rate, in order.
    rows: Vec<(crate::elements::Element, f64)>,
    /// Per part, its one row.
    part_row: Vec<usize>,
}

impl Slopes {
    /// The slopes of a bill whose parts are one row each and none of them a cam's coefficient.
    fn of(bom: &[BomRow], parts: &[Part]) -> Option<Slopes> {
        if bom.iter().any(|r| matches!(r.element.profile, crate::elements::Profile::Spline(_))) {
            return None;
        }
        let part_row: Option<Vec<usize>> =
            parts.iter().map(|p| if let [r] = p.rows[..] { Some(r) } else { None }).collect();
        Some(Slopes { rows: bom.iter().map(|r| (r.element.clone(), r.stiffness)).collect(), part_row: part_row? })
    }

    /// Each row's k u′ at `q` into `slope` (0 where k = 0, which the sums skip), and the designed
    /// gradient Σ k u′ a into `spring`.
    fn eval(&self, q: &[f64], slope: &mut [f64], spring: &mut [f64]) {
        spring.fill(0.0);
        for ((e, k), s) in self.rows.iter().zip(slope.iter_mut()) {
            if *k == 0.0 {
                *s = 0.0;
                continue;
            }
            *s = k * e.profile.slope(e.deflection(q));
            for (o, a) in spring.iter_mut().zip(&e.coupling) {
                *o += *s * a;
            }
        }
    }

    /// Part `part`'s gradient on joint `j` from the slopes: what its own set gives (a sum that
    /// starts at 0, hence the `0.0 +`, which turns a −0 into +0 as the sum does).
    fn part(&self, part: usize, j: usize, slope: &[f64]) -> f64 {
        let r = self.part_row[part];
        let (e, k) = &self.rows[r];
        if *k == 0.0 { 0.0 } else { 0.0 + slope[r] * e.coupling[j] }
    }
}

impl Model {
    /// The unknowns of a bill of materials under `settings`.
    pub fn new(bom: &[BomRow], dof: usize, settings: &IdentifySettings) -> Model {
        let groups = crate::asbuilt::bom_groups(bom);
        // (id, family, rows, trim) of each part, in the order of their first rows.
        let mut found: Vec<(String, String, Vec<usize>, bool)> = Vec::new();
        let mut of_group: Vec<Option<usize>> = Vec::new();
        for (j, (row, g)) in bom.iter().zip(&groups).enumerate() {
            let trim = row.adjust.trim_range.is_some();
            if trim && settings.trims == TrimRates::Known {
                continue;
            }
            match g.and_then(|g| of_group.get(g).copied().flatten()) {
                Some(p) => found[p].2.push(j),
                None => {
                    let id = match g {
                        Some(_) => row.id.split('.').next().unwrap_or(&row.id).to_string(),
                        None => row.id.clone(),
                    };
                    found.push((id, row.family.clone(), vec![j], trim));
                    if let Some(g) = *g {
                        if of_group.len() <= g {
                            of_group.resize(g + 1, None);
                        }
                        of_group[g] = Some(found.len() - 1);
                    }
                }
            }
        }
        let parts: Vec<Part> = found
            .into_iter()
            .map(|(id, family, rows, trim)| {
                let set = SpringSet {
                    elements: rows.iter().map(|&j| bom[j].element.clone()).collect(),
                    stiffness: rows.iter().map(|&j| bom[j].stiffness).collect(),
                }
                .grouped();
                Part { id, family, rows, trim, set }
            })
            .collect();
        let mut unknowns: Vec<Unknown> = (0..parts.len()).map(Unknown::Rate).collect();
        if settings.damping {
            unknowns.extend((0..dof).map(Unknown::Damping));
        }
        if settings.friction {
            unknowns.extend((0..dof).map(Unknown::Friction));
        }
        let slopes = Slopes::of(bom, &parts);
        Model { parts, unknowns, designed: crate::fit::bill::spring_set(bom).grouped(), slopes, dof }
    }

    /// A short name of unknown `u`: the part's id, `D1`, `fc2`.
    pub fn name(&self, u: usize) -> String {
        match self.unknowns[u] {
            Unknown::Rate(p) => self.parts[p].id.clone(),
            Unknown::Damping(j) => format!("D{}", j + 1),
            Unknown::Friction(j) => format!("fc{}", j + 1),
        }
    }
}

/// The filters of one sampling rate and where their rows lie.
#[derive(Debug, Clone)]
pub struct Filters {
    /// Smooths the encoder angles before the velocity is taken.
    pub smoothing: LowPass,
    /// L, applied to both sides of the regression.
    pub regression: LowPass,
    /// Samples dropped at each end of a run (where the smoothed angles still depend on how they
    /// were extended).
    pub edge: usize,
    /// Rows are taken every `stride` samples.
    pub stride: usize,
}

impl Filters {
    /// The filters for samples `dt` apart, with L at `cutoff_hz` and the smoothing at
    /// `smoothing_hz` (both below the Nyquist frequency 1/(2 dt); the caller checks).
    pub fn new(dt: f64, cutoff_hz: f64, smoothing_hz: f64) -> Filters {
        let rate = 1.0 / dt;
        let smoothing = LowPass::butterworth(smoothing_hz, rate);
        let regression = LowPass::butterworth(cutoff_hz, rate);
        let edge = smoothing.settle() + 2;
        // Ten rows per period of the cut-off: L passes nothing above a few times it.
        let stride = ((rate / (10.0 * cutoff_hz)).floor() as usize).max(1);
        Filters { smoothing, regression, edge, stride }
    }

    /// The shortest run the filters take, s: L's start transient must die out inside the
    /// extension, which is at most as long as what is kept.
    pub fn shortest_run(&self, dt: f64) -> f64 {
        (2 * self.edge + self.regression.settle() + 1) as f64 * dt
    }
}

/// Regression rows, row-major: one row per kept sample and joint.
#[derive(Debug, Clone, Default)]
pub struct Rows {
    /// Number of unknowns (columns).
    pub width: usize,
    /// y.
    pub y: Vec<f64>,
    /// Φ, `width` entries per row.
    pub phi: Vec<f64>,
    /// L[−Σ kᵢ ∇uᵢ]: the elements' torque on the row's joint as designed, N·m.
    pub designed: Vec<f64>,
    /// The row's joint (0-based).
    pub joint: Vec<usize>,
    /// The row's sample time, s.
    pub t: Vec<f64>,
    /// The row's run (an index over all runs of all logs).
    pub run: Vec<usize>,
    /// The row's position among its run's kept samples (rows of one sample share it).
    pub step: Vec<usize>,
    /// Seconds between consecutive steps, per run.
    pub step_seconds: Vec<f64>,
}

impl Rows {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.y.len()
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.y.is_empty()
    }

    /// Row `r` of Φ.
    pub fn row(&self, r: usize) -> &[f64] {
        &self.phi[r * self.width..(r + 1) * self.width]
    }

    /// Appends `other` (rows of further runs).
    fn append(&mut self, mut other: Rows) {
        self.width = other.width;
        self.y.append(&mut other.y);
        self.phi.append(&mut other.phi);
        self.designed.append(&mut other.designed);
        self.joint.append(&mut other.joint);
        self.t.append(&mut other.t);
        self.run.append(&mut other.run);
        self.step.append(&mut other.step);
        self.step_seconds.append(&mut other.step_seconds);
    }

    /// Appends the rows `rows` of a further run `run` ([`run_rows`] with the next index) and
    /// the seconds between its steps.
    pub(super) fn push_run(&mut self, rows: Rows, run: &Run, filters: &Filters) {
        self.append(rows);
        self.step_seconds.push(filters.stride as f64 * run.dt);
    }
}

/// Channel-major signals of one run: `channels` signals of `len` samples.
struct Signals {
    len: usize,
    data: Vec<Vec<f64>>,
}

impl Signals {
    fn new(channels: usize, len: usize) -> Signals {
        Signals { len, data: vec![vec![0.0; len]; channels] }
    }

    fn filtered(self, f: &LowPass, extension: Extension) -> Signals {
        let data = self.data.par_iter().map(|x| f.filtfilt_extended(x, extension)).collect();
        Signals { len: self.len, data }
    }
}

/// The rows of one run (index `run` over all runs), its angles already known to lie in the
/// region.
pub fn run_rows(design: &Design, model: &Model, run: &Run, index: usize, filters: &Filters) -> Rows {
    let n = model.dof;
    let dt = run.dt;
    let chain = &design.chain;
    // Smoothed angles and their velocity, without the smoothing's ends.
    let q: Vec<Vec<f64>> = (0..n)
        .map(|j| filters.smoothing.filtfilt(&(0..run.len()).map(|i| run.q[i * n + j]).collect::<Vec<_>>()))
        .collect();
    let qd: Vec<Vec<f64>> = q.iter().map(|x| derivative(x, dt)).collect();
    let keep = filters.edge..run.len().saturating_sub(filters.edge).max(filters.edge);
    let len = keep.len();
    // The momentum M q̇ two samples beyond each kept end, and its rate by central differences.
    let mut momentum = vec![vec![0.0; len + 4]; n];
    for (i, s) in (keep.start - 2..keep.end + 2).enumerate() {
        let qs = nalgebra::DVector::from_iterator(n, (0..n).map(|j| q[j][s]));
        let v = nalgebra::DVector::from_iterator(n, (0..n).map(|j| qd[j][s]));
        let p = chain.mass_matrix(&qs) * &v;
        for j in 0..n {
            momentum[j][i] = p[j];
        }
    }
    let mut momentum_rate = Signals::new(n, len);
    for j in 0..n {
        for i in 0..len {
            momentum_rate.data[j][i] = central(&momentum[j][i..i + 5], dt);
        }
    }
    // Per kept sample: the rest of y; the designed torque; the parts' columns.
    let parts = model.parts.len();
    let mut rest = Signals::new(n, len);
    let mut designed = Signals::new(n, len);
    let mut columns = Signals::new(parts * n, len);
    let mut damping = Signals::new(n, len);
    let mut friction = Signals::new(n, len);
    let mut qi = vec![0.0; n];
    let mut g = vec![0.0; n];
    let mut spring = vec![0.0; n];
    let mut slope = vec![0.0; model.slopes.as_ref().map_or(0, |s| s.rows.len())];
    for (i, s) in keep.clone().enumerate() {
        for j in 0..n {
            qi[j] = q[j][s];
        }
        let qv = nalgebra::DVector::from_column_slice(&qi);
        let v = nalgebra::DVector::from_iterator(n, (0..n).map(|j| qd[j][s]));
        let dm = chain.mass_matrix_derivatives(&qv);
        chain.gravity_gradient_into(&qi, &mut g);
        match &model.slopes {
            Some(slopes) => slopes.eval(&qi, &mut slope, &mut spring),
            None => model.designed.gradient_into(&qi, &mut spring),
        }
        for j in 0..n {
            let dt_dq = 0.5 * v.dot(&(&dm[j] * &v));
            let tau = run.tau.as_ref().map_or(0.0, |t| t[s * n + j]);
            rest.data[j][i] = -dt_dq + g[j] - tau + spring[j];
            designed.data[j][i] = -spring[j];
            damping.data[j][i] = -v[j];
            friction.data[j][i] = if v[j] == 0.0 { 0.0 } else { -v[j].signum() };
        }
        for (k, part) in model.parts.iter().enumerate() {
            if let Some(slopes) = &model.slopes {
                for j in 0..n {
                    columns.data[k * n + j][i] = -slopes.part(k, j, &slope);
                }
                continue;
            }
            part.set.gradient_into(&qi, &mut g);
            for j in 0..n {
                columns.data[k * n + j][i] = -g[j];
            }
        }
    }
    // L on every term, each extended even.
    let l = &filters.regression;
    let momentum_rate = momentum_rate.filtered(l, Extension::Even);
    let rest = rest.filtered(l, Extension::Even);
    let designed = designed.filtered(l, Extension::Even);
    let columns = columns.filtered(l, Extension::Even);
    let damping = damping.filtered(l, Extension::Even);
    let friction = friction.filtered(l, Extension::Even);

    let width = model.unknowns.len();
    let mut rows = Rows { width, ..Rows::default() };
    for (step, i) in (0..len).step_by(filters.stride).enumerate() {
        for j in 0..n {
            rows.y.push(momentum_rate.data[j][i] + rest.data[j][i]);
            for u in &model.unknowns {
                rows.phi.push(match *u {
                    Unknown::Rate(k) => columns.data[k * n + j][i],
                    Unknown::Damping(d) if d == j => damping.data[j][i],
                    Unknown::Friction(d) if d == j => friction.data[j][i],
                    _ => 0.0,
                });
            }
            rows.designed.push(designed.data[j][i]);
            rows.joint.push(j);
            rows.t.push(run.t[keep.start + i]);
            rows.run.push(index);
            rows.step.push(step);
        }
    }
    rows
}

/// The rows of every run, in order (runs in parallel; the result does not depend on the thread
/// count). `runs` pairs each run with its filters.
pub fn all_rows(design: &Design, model: &Model, runs: &[(&Run, Filters)]) -> Rows {
    let parts: Vec<Rows> =
        runs.par_iter().enumerate().map(|(k, (run, f))| run_rows(design, model, run, k, f)).collect();
    let mut rows = Rows { width: model.unknowns.len(), ..Rows::default() };
    for ((run, f), r) in runs.iter().zip(parts) {
        rows.push_run(r, run, f);
    }
    rows
}
