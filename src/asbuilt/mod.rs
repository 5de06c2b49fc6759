//! As-built figures: how a design does once it is built, not as drawn.
//!
//! A build scales each stiffness, k_j → k_j (1 + δ_j), δ_j drawn at the design's tolerance
//! (`[fit] tolerance`, `distribution`; see [`crate::design::tolerance`]). The built springs no longer
//! cancel their preloads at q_eq, so the arm rests at its own equilibrium q′; a build is judged
//! about q′, as it behaves: residual angles on held-out geodesics traced from q′ (p99 and max),
//! and how far q′ is from q_eq — Euclidean |q′ − q_eq|₂ in rad, and the metric distance
//! sqrt(Δqᵀ M(q_eq) Δq) (√(kg·m²)·rad, the arc length a small shift takes in the inertia metric).
//!
//! With trim springs in the design (see [`crate::elements::trim`]) each build is also trimmed as a builder
//! would: the trims are re-relaxed at the equilibrium of the other built springs and their rates
//! set by `[fit] trim_rule` there, or (residual rule) clamped with the preload that puts the
//! equilibrium back at q_eq and their rates set there ([`clamp_at_design`]), whichever the
//! builder measures best; the trimmed build is judged the same way.
//!
//! A cam's basis columns are one part, a cam on one follower spring: they share one δ per build
//! ([`factors`]). Designs with cams are also built *preload-trimmed* ([`preload`]): each
//! follower's preload screw set to the drawing's force on the base circle, which removes the
//! part of the cam's error its preload carries.
//!
//! Every build draws from its own SplitMix64 stream (seed, build index), and builds run in
//! parallel with results collected in build order, so the figures do not depend on the thread
//! count. The sweep judges its tolerance builds with the same functions.

pub mod preload;
pub mod sizing;
pub mod tune;

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use serde::Serialize;

use crate::design::Design;
use crate::design::tolerance::{Distribution, ToleranceSpec, TrimRule};
use crate::error::Result;
use crate::fit::bill::BomRow;
use crate::geodesic::{Fan, FanSpec, Region, Stop};
use crate::numerics::ode::OdeSettings;
use crate::numerics::rng::SplitMix64;
use crate::potential::{Potential, SpringSet};
use crate::residual::{percentile, percentile_interval};

/// Held-out geodesics per build (traced from the build's own equilibrium). A build's figures
/// are percentiles over its samples, and the design's figures percentiles over builds: the Monte
/// Carlo error of the latter (a p95 over 1,000 builds is known to about ±0.05°) is what limits
/// them, not the resolution of each build. On the default design, 60 geodesics × 50 samples
/// give each of 1,000 builds a p99 within 0.1° of the one 120 × 50 give (0.097° untrimmed,
/// 0.057° trimmed at most) and move the p95 over builds by 0.018° (untrimmed) and 0.005°
/// (trimmed), at half the cost; `tests/asbuilt_tune.rs` checks the 0.1°.
pub const DIRECTIONS: usize = 60;
/// Samples per geodesic per build.
pub const SAMPLES: usize = 50;
/// The loosest ODE tolerance (rtol and atol) a build's geodesics are traced with: the design's
/// `[geodesics] ode` if tighter. Geodesics traced at 1e-7 instead of 1e-10 move no build's p99 of
/// the default design by 1e-4° (over 1,000 builds) and take a quarter less time.
pub const ODE_TOLERANCE: f64 = 1e-7;

/// The ODE settings of a build's geodesics: the design's, loosened to [`ODE_TOLERANCE`].
pub fn build_ode(design: &Design) -> OdeSettings {
    let ode = design.geodesics.ode;
    OdeSettings { rtol: ode.rtol.max(ODE_TOLERANCE), atol: ode.atol.max(ODE_TOLERANCE), ..ode }
}

/// The equilibrium of a spring set (plus gravity) nearest the design's, by Newton's method on
/// ∇U = 0 from q_eq; None if it does not converge to a minimum within 0.5 rad.
pub fn equilibrium(design: &Design, springs: &SpringSet) -> Option<DVector<f64>> {
    stationary_point(design, springs, None)
}

/// A point where ∇U of `springs` (plus gravity) vanishes, by Newton's method from q_eq, that is a
/// minimum once `stiffening` (a constant Hessian added by elements relaxed at the point itself,
/// such as trims: no torque there) is added; None if Newton fails or strays beyond 0.5 rad.
///
/// The steps use the Hessian of `springs` alone, whose zero-gradient point is sought: the rest of
/// a trimmed arm may be unstable on its own (trims of 2 N·m/rad on a wrist whose whole stiffness
/// is ω² M ≈ 0.5 N·m/rad), and steps with the stiffening added then shrink the gradient by too
/// little per step, or grow it, so that no build of such an arm found its point.
pub fn stationary_point(
    design: &Design,
    springs: &SpringSet,
    stiffening: Option<&DMatrix<f64>>,
) -> Option<DVector<f64>> {
    let chain = &design.chain;
    let mut q = design.q_eq.clone();
    let scale = 1.0 + springs.stiffness.iter().fold(0.0f64, |a, k| a.max(*k));
    let grouped = springs.grouped();
    for _ in 0..50 {
        let g = grouped.gradient(q.as_slice()).ok()? + chain.gravity_gradient(q.as_slice());
        let h = grouped.hessian(q.as_slice()).ok()? + chain.gravity_hessian(q.as_slice());
        if g.amax() < 1e-12 * scale {
            let stiffened = match stiffening {
                Some(s) => h + s,
                None => h,
            };
            return stiffened.cholesky().is_some().then_some(q);
        }
        let step = h.lu().solve(&g)?;
        q -= step;
        if (&q - &design.q_eq).amax() > 0.5 || q.iter().any(|v| !v.is_finite()) {
            return None;
        }
    }
    None
}

/// Residual angles of `springs` on held-out geodesics traced from `q0` (the equilibrium the
/// springs actually have, ODE settings [`build_ode`]): p99 and max of |angle|, degrees.
pub fn residual_about(
    design: &Design,
    extent: f64,
    directions: usize,
    samples: usize,
    springs: &SpringSet,
    q0: &DVector<f64>,
) -> Result<(f64, f64)> {
    let fan = held_out_fan(design, extent, directions, samples, q0)?;
    residual_on(design, &fan, springs)
}

/// The held-out fan [`residual_about`] judges a build on, traced from `q0`.
fn held_out_fan(design: &Design, extent: f64, directions: usize, samples: usize, q0: &DVector<f64>) -> Result<Fan> {
    Fan::trace(
        &design.chain,
        q0,
        FanSpec { count: directions, phase: 0.5, stop: region_stop(design), spacing: extent / samples as f64 },
        build_ode(design),
    )
}

/// p99 and max |residual angle| of `springs` on `fan` (a [`held_out_fan`]), degrees.
fn residual_on(design: &Design, fan: &Fan, springs: &SpringSet) -> Result<(f64, f64)> {
    let angles = crate::residual::fan_angle_values(&design.chain, fan, &springs.grouped())?;
    let st = crate::residual::stats_of(&angles);
    Ok((st.p99_abs, st.max_abs))
}

/// The p99 residual angle of a built spring set about the equilibrium it actually has, and how
/// far (Euclidean, rad) that is from the nominal one; NaN if the built arm has no stable
/// equilibrium near q_eq. Deviating stiffnesses no longer cancel their preloads at q_eq, so
/// judging the modes about the old q_eq would charge the shift, not the shape of the potential,
/// to every sample near it.
pub fn residual_about_own_equilibrium(
    design: &Design,
    extent: f64,
    directions: usize,
    samples: usize,
    built: &SpringSet,
) -> Result<(f64, f64)> {
    let Some(q) = equilibrium(design, built) else { return Ok((f64::NAN, f64::NAN)) };
    let (p99, _) = residual_about(design, extent, directions, samples, built, &q)?;
    Ok((p99, (&q - &design.q_eq).norm()))
}

/// The figures of one build (NaN where the build has no stable equilibrium near q_eq).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Build {
    /// p99 |residual angle| about the build's own equilibrium, degrees.
    pub p99_deg: f64,
    /// max |residual angle|, degrees.
    pub max_deg: f64,
    /// |q′ − q_eq|₂, rad.
    pub shift_rad: f64,
    /// sqrt(Δqᵀ M(q_eq) Δq), the metric length of the shift, √(kg·m²)·rad.
    pub shift_metric: f64,
    /// After trimming (with trims in the design): p99 and max, degrees.
    pub trimmed: Option<(f64, f64)>,
    /// After trimming: largest |trim rate − nominal| over the trims, N·m/rad.
    pub trim_change: Option<f64>,
    /// After trimming: whether the trims restored ∇²U = w² M within their ranges.
    pub trim_restored: bool,
}

/// p50 and p95 over builds, each with its 95 % confidence interval: how far the percentile of
/// these builds may be from that of all builds the tolerance allows (Monte Carlo noise: the
/// default design's p95 moved by about ±0.3° from one draw of 200 builds to the next).
///
/// A build without a figure (no stable equilibrium near q_eq, or a trimmed arm that is not
/// stable) counts as the worst: a percentile that falls among those builds has no number, only a
/// bound — it lies beyond the worst build that has one (`beyond`). Such a percentile is null in
/// JSON and written "beyond X" in text ([`Spread::text`]), never NaN or ∞.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Spread {
    /// The median over the builds, in the unit of the figure summarised.
    pub p50: f64,
    /// The 95th percentile over the builds, same unit.
    pub p95: f64,
    /// 95 % confidence interval of the p50 (distribution-free, from order statistics; see
    /// [`crate::residual::percentile_interval`]).
    pub p50_ci: [f64; 2],
    /// 95 % confidence interval of the p95 (with fewer than about 60 builds it has no upper end:
    /// null in JSON).
    pub p95_ci: [f64; 2],
    /// Builds without a figure, counted as the worst (absent from JSON when none).
    #[serde(skip_serializing_if = "is_zero")]
    pub without: usize,
    /// The largest figure of the builds that have one: what a percentile among the builds
    /// without one lies beyond (absent from JSON when every build has a figure, or none has).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub beyond: Option<f64>,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

/// Confidence of the intervals of [`Spread`].
pub const CONFIDENCE: f64 = 0.95;

impl Spread {
    /// Percentiles of `values`; NaN or ±∞ (a build without a figure) counts as the worst.
    pub fn of(values: impl Iterator<Item = f64>) -> Spread {
        let mut v: Vec<f64> = values.map(|x| if x.is_finite() { x } else { f64::INFINITY }).collect();
        v.sort_by(f64::total_cmp);
        let without = v.iter().filter(|x| x.is_infinite()).count();
        let largest = v.iter().copied().filter(|x| x.is_finite()).reduce(f64::max);
        Spread {
            p50: percentile(&v, 50.0),
            p95: percentile(&v, 95.0),
            p50_ci: percentile_interval(&v, 50.0, CONFIDENCE),
            p95_ci: percentile_interval(&v, 95.0, CONFIDENCE),
            without,
            beyond: if without > 0 { largest } else { None },
        }
    }

    /// A percentile of this spread as text with `digits` after the point and `unit`: the number,
    /// or "beyond X" (X the worst build with a figure) when it falls among the builds without
    /// one, or "none" when no build has one.
    pub fn text(&self, x: f64, digits: usize, unit: &str) -> String {
        match self.beyond {
            _ if x.is_finite() => format!("{x:.digits$}{unit}"),
            Some(b) => format!("beyond {b:.digits$}{unit}"),
            None => "none".into(),
        }
    }

    /// The p95's interval as text: `2.21–2.52`, digits after the point as given; an end among the
    /// builds without a figure, or beyond the last build, as "beyond X" or "open".
    pub fn p95_interval(&self, digits: usize) -> String {
        let end = |x: f64| {
            if x.is_finite() {
                format!("{x:.digits$}")
            } else if x < 0.0 || self.without == 0 {
                "open".into()
            } else {
                self.text(x, digits, "")
            }
        };
        let (lo, hi) = (end(self.p95_ci[0]), end(self.p95_ci[1]));
        // Both ends among the builds without a figure: one bound, not "beyond X–beyond X".
        if lo == hi { lo } else { format!("{lo}–{hi}") }
    }

    /// The p95's interval as a phrase with `unit`: `within 2.21–2.52°`, or `beyond 121.458°`
    /// when both ends fall among the builds without a figure.
    pub fn p95_interval_phrase(&self, digits: usize, unit: &str) -> String {
        let interval = self.p95_interval(digits);
        if interval.starts_with("beyond") && !interval.contains('–') {
            format!("{interval}{unit}")
        } else {
            format!("within {interval}{unit}")
        }
    }
}

/// The trimmed part of the as-built figures.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Trimmed {
    /// What each build's trims were set for (`[fit] trim_rule`).
    pub rule: TrimRule,
    /// The trimmed builds' p99 |residual angle| about their own equilibrium, degrees.
    pub p99_deg: Spread,
    /// The trimmed builds' max |residual angle|, degrees.
    pub max_deg: Spread,
    /// Largest |trim rate − nominal| per build, N·m/rad.
    pub trim_change_nm_per_rad: Spread,
    /// Builds whose trims could not reach what the rule sets them for within their ranges
    /// (∇²U = w² M, or the least-squares minimum: a range binds).
    pub builds_not_restored: usize,
}

/// The preload-trimmed part of the as-built figures (designs with cams; see [`preload`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PreloadTrimmed {
    /// The builds' p99 |residual angle| with the cam preloads (and trims) re-set, degrees.
    pub p99_deg: Spread,
    /// Their max |residual angle|, degrees.
    pub max_deg: Spread,
}

/// `"as_built"` of `summary.json`: p50 and p95 over the builds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AsBuilt {
    /// `"catalogue"` or the ± fraction the builds were drawn at.
    pub tolerance: ToleranceSpec,
    /// `uniform` or `normal`.
    pub distribution: Distribution,
    /// Number of builds drawn (`[fit] builds`).
    pub builds: usize,
    /// Seed of the builds.
    pub seed: u64,
    /// Builds with no stable equilibrium within 0.5 rad of q_eq (counted as the worst).
    pub builds_without_equilibrium: usize,
    /// p99 |residual angle| of each build about its own equilibrium, degrees.
    pub p99_deg: Spread,
    /// max |residual angle| of each build, degrees.
    pub max_deg: Spread,
    /// Euclidean |q′ − q_eq|₂, rad.
    pub shift_rad: Spread,
    /// sqrt(Δqᵀ M(q_eq) Δq), the metric length of the shift, √(kg·m²)·rad.
    pub shift_metric: Spread,
    /// After each build's trim (designs with trim springs only).
    pub trimmed: Option<Trimmed>,
    /// After each cam's preload is re-set (and the trims, if any): designs with cams only.
    pub preload_trimmed: Option<PreloadTrimmed>,
    /// The first-order model of the equilibrium's shift (absent from JSON when not computed).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shift_model: Option<ShiftModel>,
}

/// The tolerance the as-built figures are drawn at: the fit's, or — when the fit is for the
/// drawing only (`"none"`) — the catalogue's if any element states one. None: nothing to draw.
pub fn effective_tolerance(spec: ToleranceSpec, bom: &[BomRow]) -> Option<ToleranceSpec> {
    match spec {
        ToleranceSpec::None if bom.iter().any(|r| r.tolerance > 0.0) => Some(ToleranceSpec::Catalogue),
        ToleranceSpec::None => None,
        ToleranceSpec::Fraction(0.0) => None,
        ToleranceSpec::Catalogue if bom.iter().all(|r| r.tolerance == 0.0) => None,
        s => Some(s),
    }
}

/// How to draw and judge builds.
#[derive(Debug, Clone, Copy)]
pub struct BuildSettings {
    /// Tolerance (not `None`).
    pub tolerance: ToleranceSpec,
    /// How each δ is drawn within the tolerance.
    pub distribution: Distribution,
    /// Number of builds.
    pub builds: usize,
    /// Seed: build i draws from the stream (seed, i), whatever the thread count.
    pub seed: u64,
    /// Arc length of the region from q_eq (sample spacing).
    pub extent: f64,
    /// Held-out geodesics per build.
    pub directions: usize,
    /// Samples per geodesic.
    pub samples: usize,
}

/// The stiffness factors 1 + δ_j of build `index` (every spring row draws, trims included, so
/// the streams do not depend on which rows are trims; a cam draws once, see [`factors`]).
pub fn draw(bom: &[BomRow], s: &BuildSettings, index: usize) -> Vec<f64> {
    let mut rng = SplitMix64::stream(s.seed, index as u64);
    factors(bom, |r| s.tolerance.for_element(r.tolerance), s.distribution, &mut rng)
}

/// The part each BOM row belongs to (numbered in order of appearance), None for a row that is a
/// part of its own: rows of one family on one coupling with one shape
/// ([`crate::elements::group::Grouping`]), a cam's coefficient rows.
pub fn bom_groups(bom: &[BomRow]) -> Vec<Option<usize>> {
    crate::elements::group::Grouping::new(bom.iter().map(|r| (r.family.as_str(), &r.element))).of
}

/// The stiffness factors 1 + t_j u of one build, rows in order, u ∈ [−1, 1] drawn from `rng` by
/// `distribution` and t_j = `tolerance(row)`. A spring draws its own u; a cam's rows (its basis
/// columns) share one u, drawn at the cam's first row: the follower spring's rate error scales
/// the whole cam. Without cams this is one draw per row, as before cams existed.
pub fn factors(
    bom: &[BomRow],
    tolerance: impl Fn(&BomRow) -> f64,
    distribution: Distribution,
    rng: &mut SplitMix64,
) -> Vec<f64> {
    let groups = bom_groups(bom);
    let mut drawn: Vec<Option<f64>> = Vec::new();
    bom.iter()
        .zip(&groups)
        .map(|(r, g)| {
            let u = match *g {
                None => distribution.draw_unit(rng),
                Some(g) => {
                    if drawn.len() <= g {
                        drawn.resize(g + 1, None);
                    }
                    *drawn[g].get_or_insert_with(|| distribution.draw_unit(rng))
                }
            };
            1.0 + tolerance(r) * u
        })
        .collect()
}

/// A trimmed build: the spring set, its equilibrium and the trims' settings.
pub type TrimmedBuild = (SpringSet, DVector<f64>, crate::elements::trim::TrimSolution);

/// Trims a built spring set. Returns the trimmed set, its equilibrium and the trim solution;
/// None if no way of trimming leaves the arm an equilibrium near q_eq.
///
/// The trims (rows with a trim range) are re-relaxed at the equilibrium of the other built
/// springs and their rates set by the design's `[fit] trim_rule` (`relax_at_rest`): on a
/// two-joint arm three trims restore ∇²U = w² M exactly there. From three joints on, the trims
/// carry much of the net stiffness of the light joints (2 N·m/rad of trim on a wrist whose whole
/// stiffness ω² M is about 0.5 N·m/rad), so the other springs alone are soft or unstable and their
/// equilibrium moves by radians with a 5 % rate error: on `panda_three` with a trim per joint,
/// 901 of 1,000 builds had no stable equilibrium once trimmed so, and the rest were worse than
/// untrimmed. With the residual rule (the default) a builder therefore also tries the trims
/// where they were assembled (relaxed at q_eq, rates unchanged: the untrimmed build) and with
/// their rates re-set at the build's own equilibrium, the arm then settling where they hold it,
/// and clamped with the preload that puts the equilibrium back at q_eq, their rates set there
/// ([`clamp_at_design`]: the one way that undoes the shift a light wrist's builds suffer), and
/// keeps whichever of the four leaves the smallest residual rows on the trim fan traced
/// from its own equilibrium ([`trim_fan`]: what a builder measures, not the held-out figures).
/// Trimming so never makes a build worse by what the builder measures, and every build with an
/// equilibrium has a trimmed figure.
pub fn trim_build(design: &Design, bom: &[BomRow], built: &SpringSet) -> Option<TrimmedBuild> {
    trim_build_with(design, bom, built, &TrimShared::of(design), equilibrium(design, built))
}

/// What the trim step of every build of a design shares, traced once per Monte Carlo rather
/// than once per build: the rows frame of the trims' fan from q_eq ([`trim_fan`]), on which
/// [`clamp_at_design`] sets the clamped trims (None when that fan cannot be traced, as a build
/// then found it).
pub struct TrimShared {
    at_design: Option<crate::fit::robust::RowFrame>,
}

impl TrimShared {
    /// The shared part of the trim step of `design`'s builds.
    pub fn of(design: &Design) -> TrimShared {
        let at_design = trim_fan(design, &design.q_eq)
            .ok()
            .map(|fan| crate::fit::robust::RowFrame::new(&design.chain, &fan, design.fit.frequency));
        TrimShared { at_design }
    }
}

/// [`trim_build`] with the builds' shared frame and the built arm's own equilibrium
/// (`q_built`, [`equilibrium`] of `built`) given: the same trimmed build, bit for bit, without
/// tracing what every build of the design or this build's untrimmed figures already traced.
pub fn trim_build_with(
    design: &Design,
    bom: &[BomRow],
    built: &SpringSet,
    shared: &TrimShared,
    q_built: Option<DVector<f64>>,
) -> Option<TrimmedBuild> {
    let trims: Vec<usize> = (0..bom.len()).filter(|&j| bom[j].adjust.trim_range.is_some()).collect();
    if trims.is_empty() {
        return None;
    }
    let relaxed = relax_at_rest(design, bom, built);
    if design.fit.trim_rule != TrimRule::Residual {
        return relaxed.map(|r| r.0);
    }
    let frame_rows = |set: &SpringSet, q: &DVector<f64>| -> Option<f64> {
        let fan = trim_fan(design, q).ok()?;
        let frame = crate::fit::robust::RowFrame::new(&design.chain, &fan, design.fit.frequency);
        Some(frame.rows(set).norm())
    };
    let mut best: Option<(f64, TrimmedBuild)> = None;
    let mut offer = |measured: Option<f64>, candidate: TrimmedBuild| {
        if let Some(v) = measured.filter(|v| v.is_finite())
            && best.as_ref().is_none_or(|(b, _)| v < *b)
        {
            best = Some((v, candidate));
        }
    };
    if let Some(((set, q, sol), frame)) = relaxed {
        // Measured on the fan the rates were set on (the same trace from the same point).
        let measured = frame.map(|f| f.rows(&set).norm());
        offer(measured, (set, q, sol));
    }
    // The trims as assembled (relaxed at q_eq), at the build's own equilibrium.
    if let Some(q_b) = q_built {
        let couplings: Vec<Vec<f64>> = trims.iter().map(|&j| bom[j].element.coupling.clone()).collect();
        let ranges: Vec<[f64; 2]> = trims.iter().map(|&j| bom[j].adjust.trim_range.unwrap_or([0.0, 0.0])).collect();
        let nominal: Vec<f64> = trims.iter().map(|&j| built.stiffness[j]).collect();
        let rest = without(built, &trims);
        let h_rest = rest.hessian(q_b.as_slice()).ok().map(|h| h + design.chain.gravity_hessian(q_b.as_slice()));
        let fan = trim_fan(design, &q_b).ok();
        if let (Some(h_rest), Some(fan)) = (h_rest, fan) {
            let m = design.chain.mass_matrix(&q_b);
            let (columns, r0) = trim_rows(design, &fan, built, &trims);
            // Kept: the rates as assembled (a range of one point each), nothing binding.
            let kept = crate::elements::trim::at_rates(&h_rest, &m, &couplings, &nominal);
            let kept_rows = (&r0 + &columns * DVector::from_column_slice(&nominal)).norm();
            offer(Some(kept_rows), (built.clone(), q_b.clone(), kept));
            // Re-set: the rates for the residual rows at q_b; the arm then rests where they hold it.
            let sol = crate::elements::trim::solve_rows(&h_rest, &m, &couplings, (&columns, &r0), &ranges, &nominal);
            let mut reset = built.clone();
            for (i, &j) in trims.iter().enumerate() {
                reset.stiffness[j] = sol.rates[i];
            }
            if let Some(q) = equilibrium(design, &reset) {
                offer(frame_rows(&reset, &q), (reset, q, sol));
            }
        }
    }
    // Clamped so the arm rests at q_eq again, the rates set there.
    if let Some(frame) = &shared.at_design
        && let Some((measured, clamped)) = clamp_on(design, frame, bom, built, &trims)
    {
        offer(Some(measured), clamped);
    }
    best.map(|b| b.1)
}

/// The trims clamped so that the built arm rests at q_eq again, their rates set by the residual
/// rule there; None if the trims cannot carry the torque the build lost at q_eq (a joint no trim
/// with a positive rate turns) or the arm so trimmed is not stable at q_eq.
///
/// A build's rate errors leave a torque g = ∇U_built(q_eq) that moves its equilibrium by
/// H⁻¹g: on a light wrist by a good part of the region (0.13 rad of a 0.26 ball on the Panda),
/// and no rate of a trim relaxed where the build rests brings it back, so the trimmed build was
/// still judged about a point the design was not made for. A trim clamped a deflection dᵢ away
/// from relaxed at q_eq carries the preload pᵢ = kᵢ dᵢ there: trims whose preloads sum to
/// Σ pᵢ aᵢ = −g put the equilibrium back at q_eq, and their rates, relaxed-at-q_eq rows plus the
/// preloads' constant torque, are then set by the rows of a fan from q_eq. The preloads' rows
/// depend only on their sum −g, so the rates are solved with the least-norm preloads and the
/// preloads then split over the trims the rates leave positive with the smallest deflections
/// (least Σ dᵢ², dᵢ = pᵢ/kᵢ): p = K² Aᵀ (A K² Aᵀ)⁻¹ (−g), A the couplings as columns.
///
/// Returns, with the trimmed build, the norm of its rows on that fan: what the builder measures
/// (the fan is traced from q_eq, where the trimmed arm rests).
pub fn clamp_at_design(
    design: &Design,
    bom: &[BomRow],
    built: &SpringSet,
    trims: &[usize],
) -> Option<(f64, TrimmedBuild)> {
    let frame = TrimShared::of(design).at_design?;
    clamp_on(design, &frame, bom, built, trims)
}

/// [`clamp_at_design`] on `frame`, the rows frame of the trims' fan from q_eq.
fn clamp_on(
    design: &Design,
    frame: &crate::fit::robust::RowFrame,
    bom: &[BomRow],
    built: &SpringSet,
    trims: &[usize],
) -> Option<(f64, TrimmedBuild)> {
    let q_eq = &design.q_eq;
    let n = design.dof();
    let rest = without(built, trims);
    let g = rest.gradient(q_eq.as_slice()).ok()? + design.chain.gravity_gradient(q_eq.as_slice());
    let a = DMatrix::from_fn(n, trims.len(), |i, c| built.elements[trims[c]].coupling[i]);
    // The least-norm preloads, for the rates' rows.
    let (p0, _) = crate::elements::trim::min_residual(&a, &(-&g))?;
    if (&a * &p0 + &g).amax() > 1e-9 * (1.0 + g.amax()) {
        return None;
    }
    let (relaxed, columns, unit_preload) = relaxed_trims(frame, built, trims, q_eq.as_slice());
    let preload_rows = unit_preload * &p0;
    let r0 = rows_without_trims(frame, &relaxed, trims) + preload_rows;
    let couplings: Vec<Vec<f64>> = trims.iter().map(|&j| bom[j].element.coupling.clone()).collect();
    let ranges: Vec<[f64; 2]> = trims.iter().map(|&j| bom[j].adjust.trim_range.unwrap_or([0.0, 0.0])).collect();
    let nominal: Vec<f64> = trims.iter().map(|&j| built.stiffness[j]).collect();
    let h_rest = rest.hessian(q_eq.as_slice()).ok()? + design.chain.gravity_hessian(q_eq.as_slice());
    let m = design.chain.mass_matrix(q_eq);
    let sol = crate::elements::trim::solve_rows(&h_rest, &m, &couplings, (&columns, &r0), &ranges, &nominal);
    // The preloads split over the trims by their rates: least Σ (pᵢ/kᵢ)².
    let k2 = DMatrix::from_diagonal(&DVector::from_iterator(trims.len(), sol.rates.iter().map(|k| k * k)));
    let gram = &a * &k2 * a.transpose();
    let y = gram.lu().solve(&(-&g))?;
    let p = &k2 * a.transpose() * y;
    if (&a * &p + &g).amax() > 1e-9 * (1.0 + g.amax()) {
        return None;
    }
    let mut set = relaxed;
    for (i, &j) in trims.iter().enumerate() {
        set.stiffness[j] = sol.rates[i];
        if sol.rates[i] > 0.0 {
            set.elements[j].offset -= p[i] / sol.rates[i];
        }
    }
    let q = equilibrium(design, &set)?;
    let measured = frame.rows(&set).norm();
    ((&q - q_eq).amax() < 1e-6).then_some((measured, (set, q, sol)))
}

/// `set` with its trims relaxed at q_eq (as a bill writes them), their rows at unit rate on
/// `frame`, and the rows a unit preload adds (each trim clamped one radian further, less its
/// relaxed rows): the trimmed rows are linear in the trims' rates and preloads on these two
/// bases, which the trim step ([`clamp_at_design`]) and the sizing ([`sizing`]) both solve on.
fn relaxed_trims(
    frame: &crate::fit::robust::RowFrame,
    set: &SpringSet,
    trims: &[usize],
    q_eq: &[f64],
) -> (SpringSet, DMatrix<f64>, DMatrix<f64>) {
    let mut relaxed = set.clone();
    for &j in trims {
        let e = &mut relaxed.elements[j];
        e.offset = e.coupling.iter().zip(q_eq).map(|(a, q)| a * q).sum();
    }
    let columns = frame.columns(trims.iter().map(|&j| &relaxed.elements[j]));
    let shifted: Vec<crate::elements::Element> = trims
        .iter()
        .map(|&j| {
            let mut e = relaxed.elements[j].clone();
            e.offset -= 1.0;
            e
        })
        .collect();
    let unit_preload = frame.columns(shifted.iter()) - &columns;
    (relaxed, columns, unit_preload)
}

/// The springs of `set` but its rows `trims`.
fn without(set: &SpringSet, trims: &[usize]) -> SpringSet {
    let kept = || (0..set.elements.len()).filter(|j| !trims.contains(j));
    SpringSet {
        elements: kept().map(|j| set.elements[j].clone()).collect(),
        stiffness: kept().map(|j| set.stiffness[j]).collect(),
    }
}

/// The trims re-relaxed at the equilibrium of the other built springs and their rates set by the
/// design's `[fit] trim_rule` there ([`crate::elements::trim::solve`] against the design's ω, or
/// the residual rows); None if the other springs hold no equilibrium near q_eq. With the residual
/// rule, also the rows frame of the trims' fan the rates were set on.
fn relax_at_rest(
    design: &Design,
    bom: &[BomRow],
    built: &SpringSet,
) -> Option<(TrimmedBuild, Option<crate::fit::robust::RowFrame>)> {
    let trims: Vec<usize> = (0..bom.len()).filter(|&j| bom[j].adjust.trim_range.is_some()).collect();
    let rest = without(built, &trims);
    let couplings: Vec<Vec<f64>> = trims.iter().map(|&j| bom[j].element.coupling.clone()).collect();
    let ranges: Vec<[f64; 2]> = trims.iter().map(|&j| bom[j].adjust.trim_range.unwrap_or([0.0, 0.0])).collect();
    let nominal: Vec<f64> = trims.iter().map(|&j| bom[j].stiffness).collect();
    let n = design.dof();
    let mut stiff = DMatrix::zeros(n, n);
    for (a, k) in couplings.iter().zip(&nominal) {
        let av = DVector::from_column_slice(a);
        stiff += &av * av.transpose() * *k;
    }
    let q = stationary_point(design, &rest, Some(&stiff))?;
    let h_rest = rest.hessian(q.as_slice()).ok()? + design.chain.gravity_hessian(q.as_slice());
    let m = design.chain.mass_matrix(&q);
    let mut trimmed = built.clone();
    for &j in &trims {
        let e = &mut trimmed.elements[j];
        e.offset = e.coupling.iter().zip(q.iter()).map(|(a, q)| a * q).sum();
    }
    let (sol, frame) = match design.fit.trim_rule {
        TrimRule::Hessian => (crate::elements::trim::solve(&h_rest, &m, &couplings, &ranges, &nominal), None),
        TrimRule::Residual => {
            let fan = trim_fan(design, &q).ok()?;
            let frame = crate::fit::robust::RowFrame::new(&design.chain, &fan, design.fit.frequency);
            let (columns, r0) = (
                frame.columns(trims.iter().map(|&j| &trimmed.elements[j])),
                rows_without_trims(&frame, &trimmed, &trims),
            );
            (
                crate::elements::trim::solve_rows(&h_rest, &m, &couplings, (&columns, &r0), &ranges, &nominal),
                Some(frame),
            )
        }
    };
    for (i, &j) in trims.iter().enumerate() {
        trimmed.stiffness[j] = sol.rates[i];
    }
    Some(((trimmed, q, sol), frame))
}

/// Geodesics of the fan a residual trim is fitted on ([`TrimRule::Residual`]): traced from the
/// build's equilibrium in directions of their own (phase 0, where the held-out fan of
/// [`DIRECTIONS`] uses phase ½), so the figures judge the trims on geodesics they were not set
/// on. On the default design 12 directions × 20 samples set the trims as well as 48 × 20 to
/// 0.01° in the trimmed p95 over 1,000 builds (0.870° against 0.862°). That is two joints'
/// count (directions on a circle); see [`trim_directions`] for more.
pub const TRIM_DIRECTIONS: usize = 12;

/// Directions of the trims' fan for an arm of `dof` joints: [`TRIM_DIRECTIONS`] on two joints,
/// TRIM_DIRECTIONS·(n − 1)² beyond (directions on a sphere: as many per unit of its area as a
/// circle of 12), at most the held-out fan's [`DIRECTIONS`]. On three joints, 12 directions
/// let the trims fit their fan and miss between its geodesics: on `panda_three` (trims sized by
/// the bill) the trims clamped at the design left the builds' rows on their fan at 0.083 per
/// build against the drawing's 0.080, yet the held-out trimmed p95 was 3.7° against a drawn
/// p99 of 1.0°.
pub fn trim_directions(dof: usize) -> usize {
    let across = dof.saturating_sub(1).max(1);
    (TRIM_DIRECTIONS * across * across).min(DIRECTIONS.max(TRIM_DIRECTIONS))
}
/// Samples per geodesic of the trims' fan.
pub const TRIM_SAMPLES: usize = 20;

/// The fan a residual trim is fitted on, from `q0` (see [`trim_directions`]).
pub fn trim_fan(design: &Design, q0: &DVector<f64>) -> Result<Fan> {
    let extent = design.valid_region()?.extent;
    Fan::trace(
        &design.chain,
        q0,
        FanSpec {
            count: trim_directions(design.dof()),
            phase: 0.0,
            stop: region_stop(design),
            spacing: extent / TRIM_SAMPLES as f64,
        },
        build_ode(design),
    )
}

/// The tangentiality rows (weighted as in the fit) on `fan` of each trim (rows `trims` of
/// `springs`) at rate 1, as columns, and of everything else at its rate, gravity included.
pub fn trim_rows(design: &Design, fan: &Fan, springs: &SpringSet, trims: &[usize]) -> (DMatrix<f64>, DVector<f64>) {
    let frame = crate::fit::robust::RowFrame::new(&design.chain, fan, design.fit.frequency);
    (frame.columns(trims.iter().map(|&j| &springs.elements[j])), rows_without_trims(&frame, springs, trims))
}

/// The rows on `frame` of everything but the trims (rows `trims` of `springs`), gravity included.
pub fn rows_without_trims(frame: &crate::fit::robust::RowFrame, springs: &SpringSet, trims: &[usize]) -> DVector<f64> {
    let mut rest = springs.clone();
    for &j in trims {
        rest.stiffness[j] = 0.0;
    }
    frame.rows(&rest)
}

/// Where a held-out or trim geodesic stops: the ball's radius, or the region's boundary.
fn region_stop(design: &Design) -> Stop<'_> {
    match &design.region {
        Region::Ball { radius } => Stop::Arc(*radius),
        region => Stop::Region { region, max_arc: design.geodesics.max_arc },
    }
}

/// Whether a build's trims reached what `[fit] trim_rule` sets them for within their ranges:
/// ∇²U = w² M restored ([`TrimRule::Hessian`]), or the rows' least-squares minimum with no range
/// binding ([`TrimRule::Residual`]).
pub fn trims_reached(design: &Design, sol: &crate::elements::trim::TrimSolution) -> bool {
    match design.fit.trim_rule {
        TrimRule::Hessian => sol.restored(),
        TrimRule::Residual => sol.binding.is_empty(),
    }
}

/// Runs one build.
pub fn run_build(
    design: &Design,
    bom: &[BomRow],
    springs: &SpringSet,
    s: &BuildSettings,
    index: usize,
) -> Result<Build> {
    run_build_with(design, bom, springs, s, index, &TrimShared::of(design))
}

/// [`run_build`] with the trim step's shared frame (traced once for all builds).
fn run_build_with(
    design: &Design,
    bom: &[BomRow],
    springs: &SpringSet,
    s: &BuildSettings,
    index: usize,
    shared: &TrimShared,
) -> Result<Build> {
    let built = springs.scaled(&draw(bom, s, index));
    let nan = Build {
        p99_deg: f64::NAN,
        max_deg: f64::NAN,
        shift_rad: f64::NAN,
        shift_metric: f64::NAN,
        trimmed: None,
        trim_change: None,
        trim_restored: false,
    };
    let mut b = nan;
    let q_built = equilibrium(design, &built);
    // The untrimmed build's held-out fan: a trimmed build that rests at the same point (its
    // trims kept as assembled) is judged on it again rather than on a new trace of it.
    let mut untrimmed_fan = None;
    if let Some(q) = &q_built {
        let fan = held_out_fan(design, s.extent, s.directions, s.samples, q)?;
        let (p99, max) = residual_on(design, &fan, &built)?;
        untrimmed_fan = Some(fan);
        let dq = q - &design.q_eq;
        let m = design.chain.mass_matrix(&design.q_eq);
        b = Build {
            p99_deg: p99,
            max_deg: max,
            shift_rad: dq.norm(),
            shift_metric: dq.dot(&(&m * &dq)).max(0.0).sqrt(),
            ..nan
        };
    }
    if bom.iter().any(|r| r.adjust.trim_range.is_some()) {
        b.trimmed = Some((f64::NAN, f64::NAN));
        if let Some((trimmed, q, sol)) = trim_build_with(design, bom, &built, shared, q_built.clone()) {
            // The trimmed arm rests at q (trims add no torque there) if its Hessian is positive.
            let h = trimmed.hessian(q.as_slice())? + design.chain.gravity_hessian(q.as_slice());
            if h.cholesky().is_some() {
                b.trimmed = Some(match (&q_built, &untrimmed_fan) {
                    (Some(at), Some(fan)) if *at == q => residual_on(design, fan, &trimmed)?,
                    _ => residual_about(design, s.extent, s.directions, s.samples, &trimmed, &q)?,
                });
            }
            let nominal = bom.iter().filter(|r| r.adjust.trim_range.is_some()).map(|r| r.stiffness);
            b.trim_change = Some(sol.rates.iter().zip(nominal).map(|(k, k0)| (k - k0).abs()).fold(0.0, f64::max));
            b.trim_restored = trims_reached(design, &sol);
        }
    }
    Ok(b)
}

/// Runs `s.builds` builds of `springs` (the BOM's stiffnesses) in parallel; results in build
/// order.
pub fn run_builds(design: &Design, bom: &[BomRow], springs: &SpringSet, s: &BuildSettings) -> Result<Vec<Build>> {
    let shared = TrimShared::of(design);
    let out: Vec<Result<Build>> =
        (0..s.builds).into_par_iter().map(|i| run_build_with(design, bom, springs, s, i, &shared)).collect();
    out.into_iter().collect()
}

/// The summary over builds whose trims (if any) were set by `rule`.
pub fn summarise(s: &BuildSettings, builds: &[Build], rule: TrimRule) -> AsBuilt {
    let trimmed = builds.first().and_then(|b| b.trimmed).map(|_| Trimmed {
        rule,
        p99_deg: Spread::of(builds.iter().map(|b| b.trimmed.map_or(f64::NAN, |t| t.0))),
        max_deg: Spread::of(builds.iter().map(|b| b.trimmed.map_or(f64::NAN, |t| t.1))),
        trim_change_nm_per_rad: Spread::of(builds.iter().map(|b| b.trim_change.unwrap_or(f64::NAN))),
        builds_not_restored: builds.iter().filter(|b| !b.trim_restored).count(),
    });
    AsBuilt {
        tolerance: s.tolerance,
        distribution: s.distribution,
        builds: builds.len(),
        seed: s.seed,
        builds_without_equilibrium: builds.iter().filter(|b| b.shift_rad.is_nan()).count(),
        p99_deg: Spread::of(builds.iter().map(|b| b.p99_deg)),
        max_deg: Spread::of(builds.iter().map(|b| b.max_deg)),
        shift_rad: Spread::of(builds.iter().map(|b| b.shift_rad)),
        shift_metric: Spread::of(builds.iter().map(|b| b.shift_metric)),
        trimmed,
        preload_trimmed: None,
        shift_model: None,
    }
}

/// The first-order model of how far a build's equilibrium moves (see `fit::robust`): a build
/// scales spring i by 1 + δᵢ, its gradient at q_eq changes by Σᵢ δᵢ kᵢ gᵢ (gᵢ = ∇uᵢ(q_eq) at
/// unit rate: the preload spring i carries there) and, H = ∇²U(q_eq) being its stiffness, its
/// equilibrium by
///
/// Δq = −H⁻¹ Σᵢ δᵢ kᵢ gᵢ,
///
/// with covariance C = H⁻¹ (Σ_parts σ² p pᵀ) H⁻¹ (p the preload of one part: a cam's columns
/// share one δ). The shift is large where little net stiffness holds much preload: the softest
/// direction v (H's smallest eigenvalue, unit v) carries vᵀ H v of stiffness against the
/// preload's spread √(Σ σ² (vᵀp)²) and the gravity torque |vᵀ∇U_g| the springs hold there.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ShiftModel {
    /// √E‖Δq‖², rad (the Monte Carlo builds' RMS |q′ − q_eq|₂, to first order).
    pub rms_rad: f64,
    /// The joint (1-based) that moves most along the softest direction.
    pub soft_joint: usize,
    /// Net stiffness along it, vᵀ H v, N·m/rad.
    pub soft_stiffness_nm_per_rad: f64,
    /// The preload error's spread along it, √(Σ σ² (vᵀp)²), N·m.
    pub soft_preload_spread_nm: f64,
    /// The gravity torque along it that the springs carry at q_eq, |vᵀ ∇U_g(q_eq)|, N·m.
    pub soft_gravity_nm: f64,
    /// The RMS shift along the softest direction alone, rad: spread / stiffness.
    pub soft_rms_rad: f64,
}

/// RMS equilibrium shift (rad) above which the shift model warns: twice it (about a p95) is
/// 0.2 rad, where builds begin to lose the equilibrium within 0.5 rad of q_eq that
/// [`equilibrium`] looks for (the default design's RMS is about 0.05 rad; the three-joint arm of
/// issue 46, whose 7 in 1,000 builds lost it, above 0.1).
pub const SHIFT_WARNING_RAD: f64 = 0.1;

impl ShiftModel {
    /// The warning when the modelled shift exceeds [`SHIFT_WARNING_RAD`]: the softest
    /// direction's net stiffness against the preload spread and the gravity it carries.
    pub fn warning(&self) -> Option<String> {
        (self.rms_rad > SHIFT_WARNING_RAD).then(|| {
            format!(
                "a build's equilibrium moves by {:.3} rad RMS (first order, at the build tolerance; above {SHIFT_WARNING_RAD} rad builds begin to lose their equilibrium): the softest direction (mostly joint {}) has {:.3} N·m/rad of net stiffness against a preload error of {:.3} N·m RMS, the springs carrying {:.3} N·m of gravity along it ({:.3} rad RMS from it alone); raise fit.frequency, tighten the tolerance or move q_eq where gravity loads that direction less",
                self.rms_rad,
                self.soft_joint,
                self.soft_stiffness_nm_per_rad,
                self.soft_preload_spread_nm,
                self.soft_gravity_nm,
                self.soft_rms_rad
            )
        })
    }
}

/// [`ShiftModel`] of `springs` (the bill's, rows `bom`) at the build settings' tolerance; None if
/// the springs' Hessian at q_eq is not positive definite (no nominal equilibrium to move).
pub fn shift_model(
    design: &Design,
    bom: &[BomRow],
    springs: &SpringSet,
    s: &BuildSettings,
) -> Result<Option<ShiftModel>> {
    let q = design.q_eq.as_slice();
    let n = design.dof();
    let h = springs.hessian(q)? + design.chain.gravity_hessian(q);
    let Some(chol) = h.clone().cholesky() else { return Ok(None) };
    // One preload per part: a cam's rows share one δ (see `factors`).
    let groups = bom_groups(bom);
    let mut parts: Vec<(f64, DVector<f64>)> = Vec::new();
    let mut part_of: Vec<Option<usize>> = Vec::new();
    for (j, (row, g)) in bom.iter().zip(&groups).enumerate() {
        let p = springs.elements[j].gradient(q) * springs.stiffness[j];
        let sigma2 = s.distribution.variance(s.tolerance.for_element(row.tolerance));
        match *g {
            Some(g) => {
                if part_of.len() <= g {
                    part_of.resize(g + 1, None);
                }
                match part_of[g] {
                    Some(at) => parts[at].1 += p,
                    None => {
                        part_of[g] = Some(parts.len());
                        parts.push((sigma2, p));
                    }
                }
            }
            None => parts.push((sigma2, p)),
        }
    }
    let mut cov_g = DMatrix::zeros(n, n);
    for (sigma2, p) in &parts {
        cov_g += p * p.transpose() * *sigma2;
    }
    let h_inv = chol.inverse();
    let cov = &h_inv * &cov_g * &h_inv;
    let eig = h.clone().symmetric_eigen();
    let soft = (0..n).min_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b])).unwrap_or(0);
    let v = eig.eigenvectors.column(soft).into_owned();
    let stiffness = v.dot(&(&h * &v));
    let spread = v.dot(&(&cov_g * &v)).max(0.0).sqrt();
    let gravity = v.dot(&design.chain.gravity_gradient(q)).abs();
    Ok(Some(ShiftModel {
        rms_rad: cov.trace().max(0.0).sqrt(),
        soft_joint: 1 + v.iamax(),
        soft_stiffness_nm_per_rad: stiffness,
        soft_preload_spread_nm: spread,
        soft_gravity_nm: gravity,
        soft_rms_rad: spread / stiffness,
    }))
}

/// The p99 figures compare and pareto list: (untrimmed p50, p95), and trimmed (p50, p95) if any.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Brief {
    /// [`AsBuilt::p99_deg`], degrees.
    pub p99_deg: Spread,
    /// The trimmed builds' p99 (designs with trim springs), degrees.
    pub trimmed_p99_deg: Option<Spread>,
}

impl Brief {
    /// From the summary.
    pub fn of(ab: &AsBuilt) -> Brief {
        Brief { p99_deg: ab.p99_deg, trimmed_p99_deg: ab.trimmed.map(|t| t.p99_deg) }
    }

    /// From the `"as_built"` object of a `summary.json` (None if absent or null).
    pub fn from_json(v: &serde_json::Value) -> Option<Brief> {
        let spread = |v: &serde_json::Value| -> Option<Spread> {
            let num = |k: &str| v.get(k).map(|x| x.as_f64().unwrap_or(f64::INFINITY));
            let ci = |k: &str| -> [f64; 2] {
                let at = |i: usize, missing: f64| {
                    v.get(k).and_then(|x| x.get(i)).map_or(missing, |x| x.as_f64().unwrap_or(missing))
                };
                [at(0, f64::NEG_INFINITY), at(1, f64::INFINITY)]
            };
            let without = v.get("without").and_then(|x| x.as_u64()).map_or(0, |x| x as usize);
            let beyond = v.get("beyond").and_then(|x| x.as_f64());
            Some(Spread {
                p50: num("p50")?,
                p95: num("p95")?,
                p50_ci: ci("p50_ci"),
                p95_ci: ci("p95_ci"),
                without,
                beyond,
            })
        };
        let ab = v.get("as_built").filter(|x| !x.is_null())?;
        Some(Brief {
            p99_deg: spread(ab.get("p99_deg")?)?,
            trimmed_p99_deg: ab.get("trimmed").and_then(|t| t.get("p99_deg")).and_then(spread),
        })
    }
}

/// The builds of a fit at its tolerance settings (`[fit] tolerance`, `distribution`, `builds`,
/// `seed`); None when there is nothing to draw (tolerance `"none"` and no catalogue tolerance,
/// `builds = 0`, or an empty bill).
pub fn build_settings(fit: &crate::fit::FitOutcome) -> Option<BuildSettings> {
    let st = &fit.settings;
    let tolerance = effective_tolerance(st.tolerance, &fit.bom)?;
    if st.builds == 0 || fit.bom.is_empty() {
        return None;
    }
    Some(BuildSettings {
        tolerance,
        distribution: st.distribution,
        builds: st.builds,
        seed: st.seed,
        extent: fit.region.extent,
        directions: DIRECTIONS,
        samples: SAMPLES,
    })
}

/// The as-built figures of a fit at the fit's tolerance settings (`[fit] tolerance`,
/// `distribution`, `builds`, `seed`); None when there is nothing to draw (tolerance `"none"` and
/// no catalogue tolerance, or `builds = 0`).
pub fn of_fit(design: &Design, fit: &crate::fit::FitOutcome) -> Result<Option<AsBuilt>> {
    let Some(s) = build_settings(fit) else { return Ok(None) };
    let builds = run_builds(design, &fit.bom, &fit.springs, &s)?;
    let mut ab = summarise(&s, &builds, design.fit.trim_rule);
    ab.shift_model = shift_model(design, &fit.bom, &fit.springs, &s)?;
    if !fit.cams.is_empty() {
        let terms: Vec<preload::PreloadTerm> = fit.cams.iter().map(preload::term).collect();
        let shared = TrimShared::of(design);
        let out: Vec<Result<(f64, f64)>> = (0..s.builds)
            .into_par_iter()
            .map(|i| preload::run_build(design, &fit.bom, &fit.springs, &terms, &s, (i, &shared)))
            .collect();
        let out: Vec<(f64, f64)> = out.into_iter().collect::<Result<_>>()?;
        ab.preload_trimmed = Some(PreloadTrimmed {
            p99_deg: Spread::of(out.iter().map(|o| o.0)),
            max_deg: Spread::of(out.iter().map(|o| o.1)),
        });
    }
    Ok(Some(ab))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::elements::{Element, Profile};

    /// The default design's bill (three trims on (1, 0), (0, 1), (1, 1)), fitted on a small fan,
    /// its trims' ranges opened wide so that no range binds.
    fn bill(design: &Design) -> Vec<BomRow> {
        let catalog = crate::elements::catalog::Catalog::load(design.catalog.as_ref().unwrap(), design.dof()).unwrap();
        let settings = crate::design::fit::FitSettings {
            training_directions: 24,
            training_samples: 12,
            evaluation_directions: 12,
            evaluation_samples: 8,
            builds: 0,
            ..design.fit
        };
        let mut bom = crate::fit::run::fit(design, &catalog, &settings, crate::progress::Progress::none()).unwrap().bom;
        for r in &mut bom {
            if r.adjust.trim_range.is_some() {
                r.adjust.trim_range = Some([-1e3, 1e3]);
            }
        }
        bom
    }

    /// A known case the trims restore exactly: a two-joint arm whose build differs from the
    /// drawing by a linear spring on joint 1 relaxed away from q_eq (a rate error ε of such a
    /// spring: a rate ε on (1, 0) and a preload ε (q_eq,1 − x₀) at q_eq). Clamped at the design,
    /// the (1, 0) trim takes back the rate ε and the preload, so the trimmed arm rests at q_eq
    /// and its potential's gradient is the drawing's everywhere, the other trims unmoved.
    #[test]
    fn trims_clamped_at_the_design_restore_a_build_they_can_reach() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let design = Design::load(&root.join("designs/double_pendulum.toml")).unwrap();
        let bom = bill(&design);
        let trims: Vec<usize> = (0..bom.len()).filter(|&j| bom[j].adjust.trim_range.is_some()).collect();
        assert_eq!(trims.len(), 3);
        let joint1 = trims.iter().position(|&j| bom[j].element.coupling == [1.0, 0.0]).unwrap();
        // The drawing with its trims where the rule sets them at q_eq (the reference).
        let drawn = crate::fit::bill::spring_set(&bom);
        let (_, (drawn, q0, _)) = clamp_at_design(&design, &bom, &drawn, &trims).unwrap();
        assert!((&q0 - &design.q_eq).amax() < 1e-9);
        // The build: one linear spring more, rate ε on joint 1, relaxed 0.3 rad from q_eq.
        let eps = 0.7;
        let mut built = drawn.clone();
        built.elements.push(Element {
            profile: Profile::Linear,
            coupling: vec![1.0, 0.0],
            offset: design.q_eq[0] + 0.3,
        });
        built.stiffness.push(eps);
        let g = built.gradient(design.q_eq.as_slice()).unwrap() + design.chain.gravity_gradient(design.q_eq.as_slice());
        assert!(g.amax() > 0.1, "the build rests elsewhere: |∇U(q_eq)| = {}", g.amax());
        let untrimmed = equilibrium(&design, &built).unwrap();
        assert!((&untrimmed - &design.q_eq).amax() > 1e-3);
        let (measured, (trimmed, q, sol)) = clamp_at_design(&design, &bom, &built, &trims).unwrap();
        assert!((&q - &design.q_eq).amax() < 1e-9, "rests at {q} instead of q_eq");
        assert!(sol.binding.is_empty());
        for (i, &j) in trims.iter().enumerate() {
            let expected = drawn.stiffness[j] - if i == joint1 { eps } else { 0.0 };
            assert!(
                (trimmed.stiffness[j] - expected).abs() < 1e-6 * (1.0 + expected.abs()),
                "trim {i}: {} against {expected}",
                trimmed.stiffness[j]
            );
        }
        // The trimmed potential's gradient is the drawing's, over the region.
        let scale = 1.0 + drawn.stiffness.iter().fold(0.0f64, |a, k| a.max(k.abs()));
        for s in 0..20 {
            let t = s as f64;
            let p = [design.q_eq[0] + 0.6 * (0.7 * t).sin(), design.q_eq[1] + 0.6 * (1.3 * t).cos()];
            let d = trimmed.gradient(&p).unwrap() - drawn.gradient(&p).unwrap();
            assert!(d.amax() < 1e-9 * scale, "at {p:?}: gradients differ by {:e}", d.amax());
        }
        // What the builder measures is the drawing's rows again.
        let fan = trim_fan(&design, &design.q_eq).unwrap();
        let frame = crate::fit::robust::RowFrame::new(&design.chain, &fan, design.fit.frequency);
        let drawn_rows = frame.rows(&drawn).norm();
        assert!((measured - drawn_rows).abs() < 1e-9 * (1.0 + drawn_rows), "{measured} against {drawn_rows}");
        // trim_build keeps it: no other way of trimming measures smaller.
        let (_, q_kept, _) = trim_build(&design, &bom, &built).unwrap();
        assert!((&q_kept - &design.q_eq).amax() < 1e-9);
    }
}
