//! Geodesics of the inertia metric from the equilibrium: the candidate strict modes.
//!
//! A geodesic solves M q̈ + C(q, q̇) q̇ = 0. Started at q_eq with a metric unit velocity, its time
//! is its arc length s. [`shoot`] traces single geodesics (with their Jacobi fields when needed),
//! [`fan`] traces many in parallel, [`logmap`] inverts exp by Newton shooting, and [`region`]
//! checks where exp is one-to-one.

pub mod directions;
pub mod fan;
pub mod label;
pub mod logcells;
pub mod logfit;
pub mod logmap;
pub mod polynomial;
pub mod region;
pub mod shoot;

use nalgebra::DVector;
use serde::{Deserialize, Serialize};

use crate::numerics::ode::{Dopri5, OdeSettings, find_root};

pub use directions::{MetricFrame, unit_vectors};
pub use fan::{Fan, FanSpec};
pub use logmap::{LogMap, LogPoint};
pub use region::{RegionFailure, RegionReport};
pub use shoot::{Shooter, Stop};

/// The region of configuration space where strict modes are wanted.
#[derive(Debug, Clone, PartialEq)]
pub enum Region {
    /// The geodesic ball r(q) ≤ radius around the equilibrium.
    Ball {
        /// The ball's radius in metric arc length from q_eq, √(kg·m²)·rad (`[region] radius`).
        radius: f64,
    },
    /// A box lower ≤ q ≤ upper in joint angles (rad); geodesics stop at its boundary.
    Box {
        /// The lower bound of each joint angle, rad (`[region] lower`).
        lower: DVector<f64>,
        /// The upper bound of each joint angle, rad (`[region] upper`).
        upper: DVector<f64>,
    },
    /// The geodesic ball r(q) ≤ radius cut by the joints' limits lower ≤ q ≤ upper (infinite
    /// bounds for joints without a stop): each geodesic stops at the radius or at the first limit
    /// it meets, whichever comes first. A real arm's ball where one light joint would swing past
    /// its stop long before the others reach the radius.
    Clipped {
        /// The ball's radius in metric arc length from q_eq, √(kg·m²)·rad (`[region] radius`).
        radius: f64,
        /// Each joint's lower limit, rad (−∞ for a joint without a stop).
        lower: DVector<f64>,
        /// Each joint's upper limit, rad (+∞ for a joint without a stop).
        upper: DVector<f64>,
    },
}

impl Region {
    /// Whether q is strictly outside the region's coordinate box (always false for a ball, whose
    /// boundary is reached by arc length).
    pub fn outside(&self, q: &[f64]) -> bool {
        match self {
            Region::Ball { .. } => false,
            Region::Box { lower, upper } | Region::Clipped { lower, upper, .. } => {
                q.iter().zip(lower.iter().zip(upper.iter())).any(|(x, (lo, hi))| x < lo || x > hi)
            }
        }
    }

    /// The earliest time within the integrator's last step at which the trace crosses a face of
    /// the box (event location on the dense output). Call only after a step ended outside.
    fn exit_time(&self, ode: &Dopri5, n: usize) -> f64 {
        let (Region::Box { lower, upper } | Region::Clipped { lower, upper, .. }) = self else {
            return ode.t();
        };
        let (t0, t1) = (ode.t_old(), ode.t());
        let mut best = t1;
        let y1 = ode.y();
        for i in 0..n {
            for (bound, sign) in [(lower[i], -1.0), (upper[i], 1.0)] {
                // g > 0 outside this face.
                let g1 = sign * (y1[i] - bound);
                if g1 > 0.0 {
                    let g0 = sign * (ode.dense_component(t0, i) - bound);
                    if g0 <= 0.0 {
                        let t = find_root(|t| sign * (ode.dense_component(t, i) - bound), t0, t1, g0, g1, 1e-14);
                        best = best.min(t);
                    }
                }
            }
        }
        best
    }

    /// A short description for messages and reports.
    pub fn describe(&self) -> String {
        match self {
            Region::Ball { radius } => format!("geodesic ball of radius {radius}"),
            Region::Box { lower, upper } => format!("box {}", describe_bounds(lower, upper)),
            Region::Clipped { radius, lower, upper } => {
                format!("geodesic ball of radius {radius} within the joint limits {}", describe_bounds(lower, upper))
            }
        }
    }

    /// The radius of a ball, clipped or not (None for a box).
    pub fn radius(&self) -> Option<f64> {
        match self {
            Region::Ball { radius } | Region::Clipped { radius, .. } => Some(*radius),
            Region::Box { .. } => None,
        }
    }
}

/// `q1 ∈ [lo, hi], …`, leaving out joints without bounds.
fn describe_bounds(lower: &DVector<f64>, upper: &DVector<f64>) -> String {
    lower
        .iter()
        .zip(upper.iter())
        .enumerate()
        .filter(|(_, (lo, hi))| lo.is_finite() || hi.is_finite())
        .map(|(i, (lo, hi))| format!("q{} ∈ [{lo}, {hi}]", i + 1))
        .collect::<Vec<_>>()
        .join(", ")
}

/// How a traced geodesic ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GeodesicEnd {
    /// It reached the requested arc length (for a ball: the boundary r = R).
    Arc,
    /// It left the region's box; the last sample lies on the boundary.
    Boundary,
}

/// A geodesic sampled in arc length: samples (γ, γ̇, s) stored flat for cache-friendly loops.
#[derive(Debug, Clone, PartialEq)]
pub struct Geodesic {
    n: usize,
    /// Initial velocity (metric unit length).
    pub direction: DVector<f64>,
    s: Vec<f64>,
    q: Vec<f64>,
    qd: Vec<f64>,
    /// How it ended.
    pub end: GeodesicEnd,
}

impl Geodesic {
    fn new(n: usize, direction: DVector<f64>) -> Self {
        Geodesic { n, direction, s: Vec::new(), q: Vec::new(), qd: Vec::new(), end: GeodesicEnd::Arc }
    }

    fn push(&mut self, s: f64, y: &[f64]) {
        self.s.push(s);
        self.q.extend_from_slice(&y[..self.n]);
        self.qd.extend_from_slice(&y[self.n..2 * self.n]);
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.s.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.s.is_empty()
    }

    /// Arc length of sample i.
    pub fn s(&self, i: usize) -> f64 {
        self.s[i]
    }

    /// Configuration γ of sample i.
    pub fn q(&self, i: usize) -> &[f64] {
        &self.q[i * self.n..(i + 1) * self.n]
    }

    /// Unit tangent γ̇ of sample i.
    pub fn qd(&self, i: usize) -> &[f64] {
        &self.qd[i * self.n..(i + 1) * self.n]
    }

    /// Arc length of the last sample.
    pub fn length(&self) -> f64 {
        self.s.last().copied().unwrap_or(0.0)
    }
}

/// Settings of the geodesic computations (the design's `[geodesics]` section).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GeodesicSettings {
    /// Directions in the fan of the `geodesics` command (its CSV and plots).
    pub directions: usize,
    /// Directions in the region check's fan. More directions resolve crossings of geodesics more
    /// finely. 0: chosen from the number of joints, [`GeodesicSettings::check_count`].
    pub check_directions: usize,
    /// Samples per geodesic across the region (the sample spacing is the region's extent in arc
    /// length divided by this).
    pub samples: usize,
    /// The region check searches for the largest valid geodesic-ball radius up to this multiple of
    /// the region's extent in arc length.
    pub probe_factor: f64,
    /// A geodesic that has not left a box region after this arc length is an error.
    pub max_arc: f64,
    /// Integrator tolerances (rtol, atol ≤ 1e-9 keep metric speed to ~1e-10).
    pub ode: OdeSettings,
}

impl Default for GeodesicSettings {
    fn default() -> Self {
        GeodesicSettings {
            directions: 360,
            check_directions: 0,
            samples: 100,
            probe_factor: 2.0,
            max_arc: 1000.0,
            ode: OdeSettings::default(),
        }
    }
}

impl GeodesicSettings {
    /// The region check's directions for an arm of `n` joints: `check_directions`, or when it is
    /// 0 720 times 3/2 for every joint beyond the second (720 for two joints). Slower growth than
    /// the fit's fans: every direction carries n Jacobi fields (at six joints 3645 directions
    /// take 11 s of CPU).
    pub fn check_count(&self, n: usize) -> usize {
        if self.check_directions == 0 {
            directions::directions_for_joints(720, n, (3, 2))
        } else {
            self.check_directions
        }
    }

    /// Checks the settings, naming the bad field.
    pub fn validate(&self) -> Result<(), (String, String)> {
        // Upper limits keep a typo (directions = 3600000) from exhausting memory later.
        if !(8..=100_000).contains(&self.directions) {
            return Err(("geodesics.directions".into(), "must be 8 to 100000".into()));
        }
        if self.check_directions != 0 && !(8..=100_000).contains(&self.check_directions) {
            return Err((
                "geodesics.check_directions".into(),
                "must be 0 (chosen from the number of joints) or 8 to 100000".into(),
            ));
        }
        if !(4..=100_000).contains(&self.samples) {
            return Err(("geodesics.samples".into(), "must be 4 to 100000".into()));
        }
        if self.directions * self.samples > 50_000_000 || self.check_directions * self.samples > 50_000_000 {
            return Err(("geodesics.samples".into(), "directions × samples must stay below 5·10⁷".into()));
        }
        if !(self.probe_factor.is_finite() && self.probe_factor >= 1.0) {
            return Err(("geodesics.probe_factor".into(), "must be a number ≥ 1".into()));
        }
        if !(self.max_arc.is_finite() && self.max_arc > 0.0) {
            return Err(("geodesics.max_arc".into(), "must be positive".into()));
        }
        self.ode.validate("geodesics.ode")
    }
}
