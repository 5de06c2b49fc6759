//! Where strict modes everywhere can hold: the region check.
//!
//! A region is valid when exp is one-to-one on it: no conjugate point (det d exp > 0 along every
//! geodesic from q_eq) and no two geodesics from q_eq crossing. The check traces a fan with its
//! Jacobi fields out to `probe_factor` times the region's extent, so besides *valid / invalid*
//! it reports the largest valid geodesic-ball radius.
//!
//! Crossings are found on the sampled fan. For n = 2 they are segment intersections between the
//! traced polylines, located exactly on the segments. For n ≥ 3 curves in general position never
//! meet exactly, so two samples count as a crossing when they lie within half a sample step of
//! each other in joint space while their initial velocities s·u differ by much more than the
//! fan's resolution (a sampled test of injectivity; more directions make it finer).

use nalgebra::DVector;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::HashMap;

use super::directions::{MetricFrame, unit_vectors};
use super::fan::{Fan, FanSpec};
use super::shoot::{JacobiTrace, Shooter, Stop};
use super::{GeodesicSettings, Region};
use crate::error::Result;
use crate::model::Chain;

/// What makes a region invalid (or limits the largest valid radius).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum RegionFailure {
    /// d exp becomes singular on the geodesic in direction `direction` at arc length `s`.
    Conjugate {
        /// Arc length from q_eq where d exp is singular, √(kg·m²)·rad.
        s: f64,
        /// The configuration there (near the conjugate point), rad.
        q: Vec<f64>,
        /// Index of the geodesic in the region check's fan, 0-based.
        direction: usize,
    },
    /// Geodesics `directions` meet at `q`, reached at arc lengths `s`.
    Crossing {
        /// Arc lengths at which each of the two geodesics reaches `q`, √(kg·m²)·rad.
        s: [f64; 2],
        /// Where they meet, rad.
        q: Vec<f64>,
        /// Indices of the two geodesics in the region check's fan, 0-based.
        directions: [usize; 2],
    },
    /// The geodesic in direction `direction` reaches joint `joint`'s (index `index`) limit
    /// `bound` at arc length `s`, at `q`: a ball beyond `s` asks the arm for a pose it cannot take.
    JointLimit {
        /// Arc length from q_eq where the limit is reached, √(kg·m²)·rad.
        s: f64,
        /// The configuration there, rad.
        q: Vec<f64>,
        /// Index of the geodesic in the region check's fan, 0-based.
        direction: usize,
        /// The joint's name.
        joint: String,
        /// The joint's index, 0-based from the base.
        index: usize,
        /// The limit reached, rad.
        bound: f64,
    },
}

impl RegionFailure {
    /// The geodesic-ball radius at which this failure enters.
    pub fn radius(&self) -> f64 {
        match self {
            RegionFailure::Conjugate { s, .. } | RegionFailure::JointLimit { s, .. } => *s,
            RegionFailure::Crossing { s, .. } => s[0].max(s[1]),
        }
    }

    /// The share of this failure's radius a suggested region uses.
    pub fn suggested_share(&self) -> f64 {
        match self {
            RegionFailure::JointLimit { .. } => JOINT_LIMIT_SHARE,
            RegionFailure::Conjugate { .. } | RegionFailure::Crossing { .. } => MODE_LIMIT_SHARE,
        }
    }

    /// What kind of limit this is, in a few words (for `check`'s list of what limits the region).
    pub fn kind(&self) -> &'static str {
        match self {
            RegionFailure::Conjugate { .. } => "conjugate point",
            RegionFailure::Crossing { .. } => "crossing geodesics (exp not one-to-one)",
            RegionFailure::JointLimit { .. } => "joint limit",
        }
    }

    /// A sentence for messages.
    pub fn describe(&self) -> String {
        let fmt_q = |q: &[f64]| q.iter().map(|x| format!("{x:.3}")).collect::<Vec<_>>().join(", ");
        match self {
            RegionFailure::Conjugate { s, q, .. } => {
                format!("a conjugate point (d exp singular) at arc length {s:.3}, q = ({})", fmt_q(q))
            }
            RegionFailure::Crossing { s, q, .. } => format!(
                "two geodesics from the equilibrium cross at q = ({}), at arc lengths {:.3} and {:.3}",
                fmt_q(q),
                s[0],
                s[1]
            ),
            RegionFailure::JointLimit { s, q, joint, bound, .. } => format!(
                "joint `{joint}` reaches its limit {bound:.4} rad (the URDF's <limit>) at arc length {s:.3}, q = ({})",
                fmt_q(q)
            ),
        }
    }
}

/// The moving joints' limits a region must keep within (from the URDF's `<limit>`; infinite
/// bounds for joints that turn freely), with the joints' names for messages.
#[derive(Debug, Clone, PartialEq)]
pub struct JointLimits {
    /// Lower limits, rad.
    pub lower: DVector<f64>,
    /// Upper limits, rad.
    pub upper: DVector<f64>,
    /// The joints' names, in chain order.
    pub names: Vec<String>,
}

impl JointLimits {
    /// The first point where a traced geodesic leaves the limits, interpolated between its
    /// samples on the joint that leaves first: (arc length, q, joint index, bound).
    fn first_exit(&self, g: &crate::geodesic::Geodesic) -> Option<(f64, Vec<f64>, usize, f64)> {
        let outside = |q: &[f64]| (0..q.len()).find(|&j| q[j] < self.lower[j] || q[j] > self.upper[j]);
        let k = (0..g.len()).find(|&k| outside(g.q(k)).is_some())?;
        if k == 0 {
            let j = outside(g.q(0))?;
            let bound = if g.q(0)[j] < self.lower[j] { self.lower[j] } else { self.upper[j] };
            return Some((g.s(0), g.q(0).to_vec(), j, bound));
        }
        let (a, b) = (g.q(k - 1), g.q(k));
        // The joint whose limit is crossed earliest between the two samples.
        let mut best: Option<(f64, usize, f64)> = None;
        for j in 0..a.len() {
            for bound in [self.lower[j], self.upper[j]] {
                let crosses = (a[j] - bound) * (b[j] - bound) <= 0.0 && bound.is_finite() && a[j] != b[j];
                if crosses {
                    let t = ((bound - a[j]) / (b[j] - a[j])).clamp(0.0, 1.0);
                    if best.is_none_or(|(tb, _, _)| t < tb) {
                        best = Some((t, j, bound));
                    }
                }
            }
        }
        let (t, j, bound) = best?;
        let q: Vec<f64> = a.iter().zip(b).map(|(x, y)| x + t * (y - x)).collect();
        Some((g.s(k - 1) + t * (g.s(k) - g.s(k - 1)), q, j, bound))
    }
}

/// The outcome of a region check.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RegionReport {
    /// Whether exp is one-to-one on the region.
    pub valid: bool,
    /// The region, in words.
    pub region: String,
    /// Largest arc length from q_eq inside the region (R for a ball, the longest trace for a box).
    pub extent: f64,
    /// The largest valid geodesic-ball radius found (or the probe radius if none was limiting).
    pub largest_radius: f64,
    /// Whether `largest_radius` is only a lower bound (nothing failed up to the probe radius).
    pub largest_radius_is_lower_bound: bool,
    /// How far the check looked.
    pub probe_radius: f64,
    /// What limits the largest radius.
    pub limit: Option<RegionFailure>,
    /// What makes the region invalid (None when valid).
    pub failure: Option<RegionFailure>,
    /// The nearest failure of each kind found (conjugate point, crossing, joint limit), nearest
    /// first: what limits the region, and what would next.
    pub limited_by: Vec<RegionFailure>,
    /// Why, in one sentence.
    pub reason: String,
}

/// Checks `region` around `q_eq` (which the caller has checked to lie inside it).
pub fn check_region(
    chain: &Chain,
    q_eq: &DVector<f64>,
    region: &Region,
    settings: &GeodesicSettings,
) -> Result<RegionReport> {
    check_region_within(chain, q_eq, region, settings, None)
}

/// [`check_region`] on an arm whose joints stop at `limits`: a ball that reaches a limit is
/// invalid, and the joint limit is one more thing that bounds the largest valid radius (a
/// clipped ball and a box honour the limits by their shape and are not judged by them).
pub fn check_region_within(
    chain: &Chain,
    q_eq: &DVector<f64>,
    region: &Region,
    settings: &GeodesicSettings,
    limits: Option<&JointLimits>,
) -> Result<RegionReport> {
    let n = chain.dof();
    let count = settings.check_count(n);
    // Extent and per-direction exit arc lengths.
    let exits: Vec<f64> = match region {
        Region::Ball { radius } => vec![*radius; if n == 1 { 2 } else { count }],
        Region::Box { .. } | Region::Clipped { .. } => {
            let spec = FanSpec {
                count,
                phase: 0.0,
                stop: Stop::Region { region, max_arc: settings.max_arc },
                spacing: settings.max_arc,
            };
            Fan::trace(chain, q_eq, spec, settings.ode)?.geodesics.iter().map(|g| g.length()).collect()
        }
    };
    let extent = exits.iter().cloned().fold(0.0, f64::max);
    let probe = settings.probe_factor * extent;
    let spacing = extent / settings.samples as f64;

    let frame = MetricFrame::new(&chain.mass_matrix(q_eq))?;
    let dirs = unit_vectors(n, count, 0.0);
    let traces: Vec<Result<JacobiTrace>> = dirs
        .par_iter()
        .map_init(
            || Shooter::new(chain, q_eq, settings.ode),
            |shooter, u| shooter.trace_jacobi(&frame.to_joint(u), probe, spacing),
        )
        .collect();
    let traces = traces.into_iter().collect::<Result<Vec<_>>>()?;

    let mut failures: Vec<(RegionFailure, bool)> = Vec::new();
    // Conjugate points.
    for (i, t) in traces.iter().enumerate() {
        if let Some(s) = t.conjugate {
            let k = ((s / spacing).round() as usize).min(t.geodesic.len() - 1);
            let q = t.geodesic.q(k.saturating_sub(1)).to_vec();
            failures.push((RegionFailure::Conjugate { s, q, direction: i }, s <= exits[i]));
        }
    }
    // Crossings.
    let crossings = match n {
        1 => Vec::new(),
        2 => planar_crossings(&traces, spacing),
        _ => sampled_crossings(&traces, &dirs, spacing, count),
    };
    for c in crossings {
        let inside = match &c {
            RegionFailure::Crossing { s, directions, .. } => {
                s[0] <= exits[directions[0]] && s[1] <= exits[directions[1]]
            }
            RegionFailure::Conjugate { .. } | RegionFailure::JointLimit { .. } => false,
        };
        failures.push((c, inside));
    }
    // The joint limits, for a plain ball: the earliest exit over all directions.
    if let (Some(limits), Region::Ball { .. }) = (limits, region) {
        let first = traces
            .iter()
            .enumerate()
            .filter_map(|(i, t)| limits.first_exit(&t.geodesic).map(|e| (i, e)))
            .min_by(|a, b| a.1.0.total_cmp(&b.1.0));
        if let Some((direction, (s, q, index, bound))) = first {
            let joint = limits.names.get(index).cloned().unwrap_or_else(|| format!("q{}", index + 1));
            failures.push((RegionFailure::JointLimit { s, q, direction, joint, index, bound }, s <= exits[direction]));
        }
    }
    // The first failure of each kind, nearest first: what limits the region.
    let mut limited_by: Vec<RegionFailure> = Vec::new();
    for (f, _) in &failures {
        match limited_by.iter_mut().find(|g| g.kind() == f.kind()) {
            Some(g) if f.radius() < g.radius() => *g = f.clone(),
            Some(_) => {}
            None => limited_by.push(f.clone()),
        }
    }
    limited_by.sort_by(|a, b| a.radius().total_cmp(&b.radius()));
    let limit = failures.iter().map(|(f, _)| f).min_by(|a, b| a.radius().total_cmp(&b.radius())).cloned();
    let failure = failures
        .iter()
        .filter(|(_, inside)| *inside)
        .map(|(f, _)| f)
        .min_by(|a, b| a.radius().total_cmp(&b.radius()))
        .cloned();
    let (largest_radius, lower_bound) = match &limit {
        Some(f) => (f.radius(), false),
        None => (probe, true),
    };
    let valid = failure.is_none();
    let radius_text = if lower_bound {
        format!("no failure up to the probe radius {probe:.3}")
    } else {
        format!("the largest valid geodesic-ball radius is {largest_radius:.3}")
    };
    let reason = match &failure {
        None => format!("exp is one-to-one on the {}; {radius_text}", region.describe()),
        Some(f @ RegionFailure::JointLimit { s, .. }) => format!(
            "{} inside the {}: a ball within the joint limits has radius below {s:.4} (region.radius = {:.4} keeps a {:.0} % margin), or set region.within_joint_limits = true to stop the region at the limits; {radius_text}",
            f.describe(),
            region.describe(),
            JOINT_LIMIT_SHARE * s,
            100.0 * (1.0 - JOINT_LIMIT_SHARE)
        ),
        Some(f) => format!("{} inside the {}; {radius_text}", f.describe(), region.describe()),
    };
    Ok(RegionReport {
        valid,
        region: region.describe(),
        extent,
        largest_radius,
        largest_radius_is_lower_bound: lower_bound,
        probe_radius: probe,
        limit,
        failure,
        limited_by,
        reason,
    })
}

/// The share of a joint limit's radius a suggested region uses: a hard stop that a built arm's
/// equilibrium shift and its swing past the region's edge must not reach.
pub const JOINT_LIMIT_SHARE: f64 = 0.8;

/// The share of a conjugate point's or a crossing's radius a suggested region uses: the error of
/// every finite set of springs grows fast towards them (the five-link pendulum's catalogue gives
/// p99 0.51° at 57 % of its largest valid radius, 1.76° at 76 % and 6.7° at 99 %,
/// `scripts/radius_limit.py`; a planar three-link arm in gravity with `catalogs/chain.toml`
/// 3.5° at 55 % and 1.0° at 36 %), so a starting region stays well inside half of it.
pub const MODE_LIMIT_SHARE: f64 = 0.4;

impl RegionReport {
    /// The radius to suggest: the smallest over what limits the region of its radius times its
    /// share (JOINT_LIMIT_SHARE, MODE_LIMIT_SHARE), with the failure that sets it; None when
    /// nothing limits the region up to the probe.
    pub fn suggested_radius(&self) -> Option<(f64, &RegionFailure)> {
        self.limited_by.iter().map(|f| (f.suggested_share() * f.radius(), f)).min_by(|a, b| a.0.total_cmp(&b.0))
    }
}

/// Segment intersections between the traced polylines of a planar fan. Segments starting within
/// two sample spacings of q_eq are skipped: every geodesic starts there, and exp is a local
/// diffeomorphism near 0, so no true crossing can be there.
fn planar_crossings(traces: &[JacobiTrace], spacing: f64) -> Vec<RegionFailure> {
    struct Seg {
        dir: usize,
        k: usize,
        a: [f64; 2],
        b: [f64; 2],
        sa: f64,
        sb: f64,
    }
    let mut segs = Vec::new();
    let mut max_len: f64 = 0.0;
    for (dir, t) in traces.iter().enumerate() {
        let g = &t.geodesic;
        for k in 0..g.len().saturating_sub(1) {
            if g.s(k) < 2.0 * spacing {
                continue;
            }
            let (a, b) = (g.q(k), g.q(k + 1));
            let seg = Seg { dir, k, a: [a[0], a[1]], b: [b[0], b[1]], sa: g.s(k), sb: g.s(k + 1) };
            max_len = max_len.max((seg.b[0] - seg.a[0]).hypot(seg.b[1] - seg.a[1]));
            segs.push(seg);
        }
    }
    if segs.is_empty() || max_len == 0.0 {
        return Vec::new();
    }
    let cell = max_len;
    let key = |x: f64, y: f64| ((x / cell).floor() as i64, (y / cell).floor() as i64);
    let mut grid: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for (idx, s) in segs.iter().enumerate() {
        let (x0, y0) = key(s.a[0].min(s.b[0]), s.a[1].min(s.b[1]));
        let (x1, y1) = key(s.a[0].max(s.b[0]), s.a[1].max(s.b[1]));
        for x in x0..=x1 {
            for y in y0..=y1 {
                grid.entry((x, y)).or_default().push(idx);
            }
        }
    }
    // Keep, per pair of directions, the crossing of smallest radius; walk cells in a fixed order
    // so the result is deterministic.
    let mut cells: Vec<_> = grid.into_iter().collect();
    cells.sort_unstable_by_key(|(k, _)| *k);
    let mut best: HashMap<(usize, usize), RegionFailure> = HashMap::new();
    for (_, members) in &cells {
        for (i, &ia) in members.iter().enumerate() {
            for &ib in &members[i + 1..] {
                let (p, q) = (&segs[ia], &segs[ib]);
                if p.dir == q.dir && p.k.abs_diff(q.k) <= 1 {
                    continue;
                }
                if let Some((t, u)) = intersect(p.a, p.b, q.a, q.b) {
                    let sp = p.sa + t * (p.sb - p.sa);
                    let sq = q.sa + u * (q.sb - q.sa);
                    let at = [p.a[0] + t * (p.b[0] - p.a[0]), p.a[1] + t * (p.b[1] - p.a[1])];
                    let (key, f) = if p.dir <= q.dir {
                        (
                            (p.dir, q.dir),
                            RegionFailure::Crossing { s: [sp, sq], q: at.to_vec(), directions: [p.dir, q.dir] },
                        )
                    } else {
                        (
                            (q.dir, p.dir),
                            RegionFailure::Crossing { s: [sq, sp], q: at.to_vec(), directions: [q.dir, p.dir] },
                        )
                    };
                    let better = best.get(&key).is_none_or(|old| f.radius() < old.radius());
                    if better {
                        best.insert(key, f);
                    }
                }
            }
        }
    }
    let mut out: Vec<_> = best.into_values().collect();
    out.sort_by(|a, b| a.radius().total_cmp(&b.radius()));
    out
}

/// Proper intersection of segments ab and cd: parameters (t, u) ∈ [0, 1]² along each.
fn intersect(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> Option<(f64, f64)> {
    let r = [b[0] - a[0], b[1] - a[1]];
    let s = [d[0] - c[0], d[1] - c[1]];
    let denom = r[0] * s[1] - r[1] * s[0];
    if denom.abs() < 1e-300 {
        return None;
    }
    let ca = [c[0] - a[0], c[1] - a[1]];
    let t = (ca[0] * s[1] - ca[1] * s[0]) / denom;
    let u = (ca[0] * r[1] - ca[1] * r[0]) / denom;
    ((0.0..=1.0).contains(&t) && (0.0..=1.0).contains(&u)).then_some((t, u))
}

/// The sampled injectivity test for n ≥ 3 (see the module docs).
fn sampled_crossings(traces: &[JacobiTrace], dirs: &[DVector<f64>], spacing: f64, count: usize) -> Vec<RegionFailure> {
    let n = dirs[0].len();
    // Typical joint-space step between samples.
    let mut step: f64 = 0.0;
    for t in traces {
        let g = &t.geodesic;
        for k in 1..g.len() {
            let d: f64 = g.q(k).iter().zip(g.q(k - 1)).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt();
            step = step.max(d);
        }
    }
    if step == 0.0 {
        return Vec::new();
    }
    // Angular resolution of the fan on the sphere of directions.
    let area = match n {
        3 => 4.0 * std::f64::consts::PI,
        _ => 2.0 * std::f64::consts::PI.powf(n as f64 / 2.0) / gamma_half(n),
    };
    let resolution = (area / count as f64).powf(1.0 / (n as f64 - 1.0));
    let near = 0.5 * step;
    let key = |q: &[f64]| q.iter().map(|x| (x / near).floor() as i64).collect::<Vec<_>>();
    let mut grid: HashMap<Vec<i64>, Vec<(usize, usize)>> = HashMap::new();
    for (dir, t) in traces.iter().enumerate() {
        let g = &t.geodesic;
        for k in 0..g.len() {
            if g.s(k) < 2.0 * spacing {
                continue;
            }
            grid.entry(key(g.q(k))).or_default().push((dir, k));
        }
    }
    let mut cells: Vec<_> = grid.into_iter().collect();
    cells.sort_unstable_by(|a, b| a.0.cmp(&b.0));
    let mut out: Vec<RegionFailure> = Vec::new();
    for (_, members) in &cells {
        for (i, &(da, ka)) in members.iter().enumerate() {
            for &(db, kb) in &members[i + 1..] {
                if da == db {
                    continue;
                }
                let (ga, gb) = (&traces[da].geodesic, &traces[db].geodesic);
                let (sa, sb) = (ga.s(ka), gb.s(kb));
                let dq: f64 = ga.q(ka).iter().zip(gb.q(kb)).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt();
                if dq > near {
                    continue;
                }
                let dv = (&dirs[da] * sa - &dirs[db] * sb).norm();
                let tolerance = 10.0 * (spacing + sa.max(sb) * resolution);
                if dv > tolerance {
                    out.push(RegionFailure::Crossing { s: [sa, sb], q: ga.q(ka).to_vec(), directions: [da, db] });
                }
            }
        }
    }
    out.sort_by(|a, b| a.radius().total_cmp(&b.radius()));
    out.truncate(16);
    out
}

/// Γ(n/2) for the area of the unit sphere in ℝⁿ.
fn gamma_half(n: usize) -> f64 {
    // Γ(1/2) = √π, Γ(1) = 1, Γ(x + 1) = x Γ(x).
    let (mut x, mut g) = if n.is_multiple_of(2) { (1.0, 1.0) } else { (0.5, std::f64::consts::PI.sqrt()) };
    while x < n as f64 / 2.0 {
        g *= x;
        x += 1.0;
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn settings() -> GeodesicSettings {
        GeodesicSettings { directions: 360, ..Default::default() }
    }

    #[test]
    fn paper_ball_of_radius_two_is_valid() {
        let chain = Chain::paper_double_pendulum();
        let q_eq = DVector::from_vec(vec![0.0, PI / 2.0]);
        let report = check_region(&chain, &q_eq, &Region::Ball { radius: 2.0 }, &settings()).unwrap();
        assert!(report.valid, "{}", report.reason);
        assert!(report.largest_radius > 2.0);
    }

    #[test]
    fn stretched_arm_radius_is_limited_by_the_conjugate_point_or_earlier() {
        // From (0, 0) the geodesic along q₁ meets a conjugate point at 2π, so no ball larger than
        // 2π can be valid; crossings may limit it earlier.
        let chain = Chain::paper_double_pendulum();
        let q_eq = DVector::from_vec(vec![0.0, 0.0]);
        let report = check_region(&chain, &q_eq, &Region::Ball { radius: 4.0 }, &settings()).unwrap();
        assert!(!report.largest_radius_is_lower_bound);
        assert!(report.largest_radius <= 2.0 * PI + 1e-6, "{}", report.largest_radius);
    }

    #[test]
    fn rejects_a_region_past_the_largest_valid_radius() {
        // Far beyond the largest valid radius (2π, the conjugate point along q₁).
        let chain = Chain::paper_double_pendulum();
        let q_eq = DVector::from_vec(vec![0.0, 0.0]);
        let report = check_region(&chain, &q_eq, &Region::Ball { radius: 9.0 }, &settings()).unwrap();
        assert!(!report.valid);
        let failure = report.failure.clone().unwrap();
        assert!(failure.radius() <= 9.0);
        assert!(report.reason.contains("largest valid geodesic-ball radius"), "{}", report.reason);
        // A ball just inside the reported radius passes.
        let ok =
            check_region(&chain, &q_eq, &Region::Ball { radius: 0.95 * report.largest_radius }, &settings()).unwrap();
        assert!(ok.valid, "{}", ok.reason);
    }

    /// Two synthetic traces that cross (an X) and one that does not.
    #[test]
    fn planar_crossings_are_found_between_traced_curves() {
        use crate::geodesic::Geodesic;
        let trace = |dir: [f64; 2], offset: [f64; 2]| {
            let mut g = Geodesic::new(2, DVector::from_vec(dir.to_vec()));
            for k in 0..=20 {
                let s = k as f64 * 0.1;
                g.push(s, &[offset[0] + s * dir[0], offset[1] + s * dir[1], dir[0], dir[1]]);
            }
            JacobiTrace { geodesic: g, det: vec![1.0; 21], conjugate: None }
        };
        // Lines y = x − 1 and y = 1 − x (from s = 0 at x = 0) cross at (1, 0), reached at s = √2.
        let a = trace([std::f64::consts::FRAC_1_SQRT_2, std::f64::consts::FRAC_1_SQRT_2], [0.0, -1.0]);
        let b = trace([std::f64::consts::FRAC_1_SQRT_2, -std::f64::consts::FRAC_1_SQRT_2], [0.0, 1.0]);
        let c = trace([1.0, 0.0], [0.0, 5.0]);
        let found = planar_crossings(&[a, b, c], 0.05);
        assert_eq!(found.len(), 1);
        match &found[0] {
            RegionFailure::Crossing { s, q, directions } => {
                assert_eq!(directions, &[0, 1]);
                assert!((s[0] - 2f64.sqrt()).abs() < 1e-12 && (s[1] - 2f64.sqrt()).abs() < 1e-12);
                assert!((q[0] - 1.0).abs() < 1e-12 && q[1].abs() < 1e-12);
            }
            f => panic!("{f:?}"),
        }
    }

    #[test]
    fn geodesics_past_the_conjugate_point_cross() {
        // From (0, 0) the geodesics near the q₁ axis focus at s = 2π and cross beyond it: the
        // crossing test finds them, none before the conjugate point.
        let chain = Chain::paper_double_pendulum();
        let q_eq = DVector::from_vec(vec![0.0, 0.0]);
        let frame = MetricFrame::new(&chain.mass_matrix(&q_eq)).unwrap();
        let mut shooter = Shooter::new(&chain, &q_eq, Default::default());
        let traces: Vec<JacobiTrace> = unit_vectors(2, 180, 0.0)
            .iter()
            .map(|u| shooter.trace_jacobi(&frame.to_joint(u), 8.5, 0.05).unwrap())
            .collect();
        let crossings = planar_crossings(&traces, 0.05);
        assert!(!crossings.is_empty());
        assert!(crossings[0].radius() > 2.0 * PI - 0.05, "first crossing at {}", crossings[0].radius());
    }

    #[test]
    fn segment_intersection() {
        assert_eq!(intersect([0.0, 0.0], [1.0, 1.0], [0.0, 1.0], [1.0, 0.0]), Some((0.5, 0.5)));
        assert_eq!(intersect([0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]), None);
        assert_eq!(intersect([0.0, 0.0], [1.0, 0.0], [2.0, -1.0], [2.0, 1.0]), None);
    }

    #[test]
    fn sphere_area_constant() {
        // Area of S³ = 2π².
        assert!((2.0 * PI.powf(2.0) / gamma_half(4) - 2.0 * PI * PI).abs() < 1e-12);
        assert!((gamma_half(5) - 0.75 * PI.sqrt()).abs() < 1e-12);
    }
}
