//! The diagnosis of a poor fit: which additions to the catalogue would lower the residual most,
//! and whether ω is the cause.
//!
//! A fit is poor when the catalogue cannot shape ½ω²r² − U_g on the region; what is missing is
//! a profile on a coupling the catalogue does not offer (a crank on joints 1 − 2, a triple
//! coupling), or a budget too small for what it does offer, or an ω so low that gravity dominates
//! the potential the springs must draw. Finding that by hand took `scripts/ur5_couplings.py` a
//! search of fits; this module screens instead, at the cost of a few least-squares projections:
//!
//! - **Additions.** On the training rows R = A k + g (the tangentiality rows the fit minimises,
//!   see [`crate::fit::robust::RowFrame`]; every k-th geodesic, [`ROWS`] at most) the whole
//!   catalogue is refitted by non-negative least squares with the equalities at q_eq weighted
//!   to hold (no budget, no tolerance weighting: what the catalogue can do at best), then again
//!   with one group added, a profile on a coupling the catalogue does not offer (every joint,
//!   pair and triple; the group at the offsets a catalogue would give it), warm-started from
//!   the catalogue's support. The share of the catalogue's ‖R‖² the group removes ranks it.
//!   A projection of R on the new columns alone (the billed springs held) ranked nothing above
//!   1 % on `planar_three` with pair families only (p99 25.4°), although a crank on (1, 1, 1)
//!   added to that catalogue brings the fit to 2.03°: it helps only with pair elements the first
//!   fit had left at zero, so the screen refits the whole catalogue (it ranks that crank third,
//!   −55 %). When the catalogue's refit is far below the fit's own ‖R‖², the budget or the
//!   tolerance weighting is the cause instead, and the diagnosis says so.
//! - **Frequency.** The billed elements are refitted (least squares, signs free, the equalities
//!   ∇U(q_eq) = −∇U_g and ∇²U(q_eq) = ω²M − ∇²U_g weighted to hold) at ω and at 2ω on the same
//!   geodesics; the rows are angles (each divided by ω² s|γ̇|), so the two norms compare. When the
//!   residual at 2ω is well below that at ω, gravity's share of the potential is what the springs
//!   cannot draw, and raising ω helps (the second new user of issue 46: 21.7° → 6.3° by doubling
//!   ω).
//!
//! Every group is screened on its own and the results are collected in order, so the ranking
//! does not depend on the thread count. The rows are only those of the training fan and the
//! equalities are weighted rather than exact, so the shares rank additions; the fit with the
//! chosen family added is what measures it.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use serde::Serialize;

use crate::design::Design;
use crate::design::fit::FitSettings;
use crate::elements::catalog::Catalog;
use crate::elements::{Element, Profile, Side};
use crate::error::{Error, Result};
use crate::fit::robust::RowFrame;
use crate::geodesic::Fan;
use crate::potential::SpringSet;

/// Additions listed, best first.
pub const SHOWN: usize = 5;
/// Crank phases screened per coupling (every 30°, as the shipped catalogues offer them).
pub const PHASES: usize = 12;
/// Compression-spring offsets screened per coupling and side, evenly over the range a·q takes.
pub const GRID: usize = 9;
/// About this many training rows are screened at most (every k-th geodesic of the fan): the
/// ranking needs the residual's shape, not every row, and the six-joint fans of 1,152
/// geodesics would otherwise cost more than the fit.
pub const ROWS: usize = 6000;
/// Weight of the screen's equality rows against its tangentiality rows, relative to their
/// norms (see `System`).
pub const EQUALITY_WEIGHT: f64 = 1.0;
/// A catalogue refit that leaves the equalities further off than this (relative) is said to
/// be unable to meet them.
pub const EQUALITY_WARNING: f64 = 1e-3;
/// A refit at 2ω whose residual is below this share of the one at ω names ω as a cause.
pub const FREQUENCY_CAUSE: f64 = 0.5;

/// One screened addition: a profile on a coupling.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Addition {
    /// The profile, as a catalogue names it (`linear`, `cubic`, `crank`, `compression`).
    pub profile: String,
    /// The coupling a (x = a·q).
    pub coupling: Vec<f64>,
    /// `new coupling` (no family of the catalogue is on it), `new profile` (the catalogue is on
    /// the coupling with other profiles) or `budget` (the catalogue offers it; the fit did not
    /// bill it).
    pub kind: String,
    /// Share of the catalogue's ‖R‖² (`Diagnosis::catalogue_rows`) a refit of the catalogue with
    /// this group added removes (0–1).
    pub share: f64,
}

impl Addition {
    /// The addition in words: `crank on (1, -1, 1) (new coupling): −38 % of the residual`.
    pub fn text(&self) -> String {
        let a: Vec<String> = self.coupling.iter().map(|x| crate::elements::fmt_number(*x)).collect();
        format!(
            "{} on ({}) ({}): −{:.0} % of the catalogue's ‖R‖²",
            self.profile,
            a.join(", "),
            self.kind,
            100.0 * self.share
        )
    }
}

/// The billed elements refitted at ω and 2ω.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FrequencyCheck {
    /// The design's ω, rad/s.
    pub omega: f64,
    /// ‖R‖ of the refit at ω (rows in radians, summed over the screened samples).
    pub residual_at_omega: f64,
    /// ‖R‖ of the refit at 2ω.
    pub residual_at_double: f64,
    /// residual_at_double / residual_at_omega.
    pub ratio: f64,
    /// Whether ω is named as a cause (ratio below [`FREQUENCY_CAUSE`]).
    pub cause: bool,
}

/// What a poor fit's diagnosis found (`"diagnosis"` of `summary.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Diagnosis {
    /// Groups screened (profiles × couplings the catalogue does not offer).
    pub screened: usize,
    /// ‖R‖² of the fitted springs on the screened rows.
    pub fitted_rows: f64,
    /// ‖R‖² of the whole catalogue refitted on them (non-negative least squares, the equalities
    /// weighted, no budget, no tolerance): well below `fitted_rows`, the budget or the
    /// tolerance weighting is what the fit gave up, not the catalogue.
    pub catalogue_rows: f64,
    /// The best additions, best first (at most [`SHOWN`]).
    pub additions: Vec<Addition>,
    /// Screened groups whose refit did not solve (left out of the ranking).
    pub unsolved: usize,
    /// Share of the catalogue's ‖R‖² the listed additions remove together (None when that
    /// refit did not solve, or nothing is listed); at least the first addition's share.
    pub together: Option<f64>,
    /// ‖E k − f‖ / ‖f‖ of the catalogue's refit: how far it leaves the equalities at q_eq
    /// (gradient and Hessian), which the refits weight rather than hold exactly.
    pub equality_error: f64,
    /// The frequency check (None when the refits could not be solved).
    pub frequency: Option<FrequencyCheck>,
    /// The smallest ω that keeps gravity's stiffness below ω²M and a ±5 % build's rest position
    /// within 1° (what `springfit check` prints; set by the fit job), rad/s.
    pub needed_omega: Option<f64>,
    /// Seconds the diagnosis took.
    pub seconds: f64,
}

impl Diagnosis {
    /// The lines `springfit fit` prints: the additions, then ω.
    pub fn lines(&self) -> Vec<String> {
        let mut out = Vec::new();
        if self.catalogue_rows < 0.5 * self.fitted_rows {
            out.push(format!(
                "the catalogue refitted without budget or tolerance weighting leaves {:.0} % of the fit's ‖R‖²: the budget (fit.max_elements) or the tolerance weighting gave up the rest",
                100.0 * self.catalogue_rows / self.fitted_rows.max(f64::MIN_POSITIVE)
            ));
        }
        if self.equality_error > EQUALITY_WARNING {
            out.push(format!(
                "the catalogue refitted leaves the equilibrium's gradient and Hessian {:.1} % off: it cannot meet them with non-negative rates",
                100.0 * self.equality_error
            ));
        }
        if self.unsolved > 0 {
            out.push(format!(
                "{} of the {} groups screened did not solve and are not ranked",
                self.unsolved, self.screened
            ));
        }
        match (self.additions.len(), self.together) {
            (0, _) => out.push("no addition could be screened".into()),
            (count, Some(t)) => {
                out.push(format!("the {count} additions below together: −{:.0} % of the catalogue's ‖R‖²", 100.0 * t))
            }
            (count, None) => out.push(format!("the {count} additions below together: their refit did not solve")),
        }
        for (i, a) in self.additions.iter().enumerate() {
            out.push(format!("{}. {}", i + 1, a.text()));
        }
        if let Some(f) = &self.frequency {
            out.push(format!(
                "ω: the billed springs refitted at 2ω = {:.3} rad/s leave {:.0} % of the residual they leave at ω{}",
                2.0 * f.omega,
                100.0 * f.ratio,
                match (f.cause, self.needed_omega) {
                    (true, Some(w)) if w > f.omega =>
                        format!(": ω is a cause, raise fit.frequency (gravity needs at least {w:.3} rad/s)"),
                    (true, _) => ": ω is a cause, raise fit.frequency".into(),
                    (false, Some(w)) if w > f.omega => {
                        format!(" (gravity needs at least {w:.3} rad/s: raise fit.frequency)")
                    }
                    (false, _) => ": ω is not the cause".into(),
                }
            ));
        }
        out
    }
}

/// The couplings screened for an arm of `n` joints: every joint, every pair with the ratios
/// 1:1, 1:−1, 1:2, 2:1, 1:−2, 2:−1, and every triple with unit entries (first entry +1: a
/// coupling and its negative give the same elements).
pub fn couplings(n: usize) -> Vec<Vec<f64>> {
    let mut out = Vec::new();
    let unit = |i: usize| -> Vec<f64> { (0..n).map(|k| if k == i { 1.0 } else { 0.0 }).collect() };
    for i in 0..n {
        out.push(unit(i));
    }
    for i in 0..n {
        for j in i + 1..n {
            for (a, b) in [(1.0, 1.0), (1.0, -1.0), (1.0, 2.0), (2.0, 1.0), (1.0, -2.0), (2.0, -1.0)] {
                let mut v = vec![0.0; n];
                v[i] = a;
                v[j] = b;
                out.push(v);
            }
        }
    }
    for i in 0..n {
        for j in i + 1..n {
            for k in j + 1..n {
                for (b, c) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
                    let mut v = vec![0.0; n];
                    v[i] = 1.0;
                    v[j] = b;
                    v[k] = c;
                    out.push(v);
                }
            }
        }
    }
    out
}

/// Whether two couplings give the same elements (equal, or one the negative of the other).
fn same_coupling(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len()
        && (a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12) || a.iter().zip(b).all(|(x, y)| (x + y).abs() < 1e-12))
}

/// The screened profiles, by the name a catalogue gives them.
const PROFILES: [&str; 4] = ["linear", "cubic", "crank", "compression"];

/// Whether `profile` (a name of [`PROFILES`]) is `p`.
fn is_profile(profile: &str, p: Profile) -> bool {
    matches!(
        (profile, p),
        ("linear", Profile::Linear)
            | ("cubic", Profile::Cubic)
            | ("crank", Profile::Crank)
            | ("compression", Profile::Compression(_))
    )
}

/// The elements of one group: `profile` on `a`, at the offsets a catalogue gives it (the
/// equilibrium for linear and cubic springs, [`PHASES`] crank phases, [`GRID`] offsets over
/// `range` on both sides for compression springs).
fn group(profile: &str, a: &[f64], q_eq: &[f64], range: (f64, f64)) -> Vec<Element> {
    let at_eq: f64 = a.iter().zip(q_eq).map(|(a, q)| a * q).sum();
    let element = |profile, offset| Element { profile, coupling: a.to_vec(), offset };
    match profile {
        "linear" => vec![element(Profile::Linear, at_eq)],
        "cubic" => vec![element(Profile::Cubic, at_eq)],
        "crank" => (0..PHASES)
            .map(|k| element(Profile::Crank, at_eq + std::f64::consts::TAU * k as f64 / PHASES as f64))
            .collect(),
        _ => {
            let (lo, hi) = range;
            (0..GRID)
                .map(|k| lo + (hi - lo) * k as f64 / (GRID - 1) as f64)
                .flat_map(|x| {
                    [element(Profile::Compression(Side::Plus), x), element(Profile::Compression(Side::Minus), x)]
                })
                .collect()
        }
    }
}

/// Every `step`-th geodesic of `fan`, so that at most about [`ROWS`] rows are screened.
fn thinned(fan: &Fan) -> Fan {
    let per_geodesic = fan.geodesics.first().map_or(1, |g| g.len()) * fan.q_eq.len().saturating_sub(1).max(1);
    let keep = (ROWS / per_geodesic.max(1)).max(8);
    let step = fan.geodesics.len().div_ceil(keep).max(1);
    Fan {
        q_eq: fan.q_eq.clone(),
        frame_directions: fan.frame_directions.iter().step_by(step).cloned().collect(),
        geodesics: fan.geodesics.iter().step_by(step).cloned().collect(),
    }
}

/// The diagnosis of a fit of `design` with `catalog` and `settings`: `springs` the fitted set,
/// `held` its trims (held at their billed rates), `training` the fit's training fan (see the
/// module documentation). `needed_omega` is left for the caller (the fit job) to set.
pub fn diagnose(
    design: &Design,
    catalog: &Catalog,
    settings: &FitSettings,
    (springs, held): (&SpringSet, &SpringSet),
    training: &Fan,
) -> Result<Diagnosis> {
    let t0 = std::time::Instant::now();
    let n = design.dof();
    let q_eq = design.q_eq.as_slice();
    let omega = settings.frequency;
    let fan = thinned(training);
    let frame = RowFrame::new(&design.chain, &fan, omega);
    if frame.is_empty() {
        return Err(Error::numerical("fit diagnosis", "the training fan has no rows to screen (one joint?)"));
    }
    let fitted = frame.rows(springs).norm_squared();
    // The range a·q sweeps on the training fan (grid offsets).
    let samples: Vec<&[f64]> = crate::fit::problem::training_samples(&fan).map(|(q, _, _)| q).collect();
    let range = |a: &[f64]| {
        samples
            .iter()
            .map(|q| a.iter().zip(q.iter()).map(|(a, q)| a * q).sum::<f64>())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| (lo.min(x), hi.max(x)))
    };
    let catalogue: Vec<Element> = catalog.expand(q_eq, range).into_iter().map(|c| c.element).collect();
    let system = System::new(design, &frame, held, omega, settings.hessian_match, &catalogue);
    let Some(base) = system.refit(None, &[]) else {
        return Err(Error::numerical("fit diagnosis", "the catalogue's refit did not converge"));
    };
    let equality_error = {
        let k = DVector::from_column_slice(&base.1);
        (&system.base_eq * k - &system.targets).norm() / system.targets.norm().max(f64::MIN_POSITIVE)
    };
    let passive: Vec<usize> = (0..catalogue.len()).filter(|&j| base.1[j] > 0.0).collect();
    let offered = |profile: &str, a: &[f64]| {
        catalog.families.iter().filter(|f| f.trim_range.is_none()).any(|f| {
            f.couplings.iter().any(|c| same_coupling(c, a))
                && (f.cam.is_some() || f.profiles.iter().any(|&p| is_profile(profile, p)))
        })
    };
    let on_coupling = |a: &[f64]| catalog.families.iter().any(|f| f.couplings.iter().any(|c| same_coupling(c, a)));
    let groups: Vec<(&str, Vec<f64>, &str)> = couplings(n)
        .into_iter()
        .flat_map(|a| PROFILES.iter().map(move |&p| (p, a.clone())))
        .filter(|(p, a)| !offered(p, a))
        .map(|(p, a)| {
            let kind = if on_coupling(&a) { "new profile" } else { "new coupling" };
            (p, a, kind)
        })
        .collect();
    // A superset's optimum is at most the catalogue's: a share below 0 is the solver's rounding.
    let share = |rows: f64| if base.0 > 0.0 { (1.0 - rows / base.0).max(0.0) } else { 0.0 };
    let shares: Vec<Option<f64>> = groups
        .par_iter()
        .map(|(p, a, _)| {
            let extra = system.columns(&group(p, a, q_eq, range(a)));
            system.refit(Some(&extra), &passive).map(|(rows, _)| share(rows))
        })
        .collect();
    let unsolved = shares.iter().filter(|s| s.is_none()).count();
    let mut ranked: Vec<Addition> = groups
        .iter()
        .zip(&shares)
        .filter_map(|((p, a, kind), share)| {
            share.map(|share| Addition { profile: (*p).into(), coupling: a.clone(), kind: (*kind).into(), share })
        })
        .collect();
    // Stable: equal shares keep the order of `couplings` and `PROFILES`.
    ranked.sort_by(|x, y| y.share.total_cmp(&x.share));
    ranked.truncate(SHOWN);
    // The best groups together (every group at once would be a catalogue of thousands),
    // warm-started from the catalogue's support.
    let best: Vec<Element> =
        ranked.iter().flat_map(|a| group(&a.profile, &a.coupling, q_eq, range(&a.coupling))).collect();
    let together = if ranked.is_empty() {
        None
    } else {
        system.refit(Some(&system.columns(&best)), &passive).map(|(rows, _)| share(rows))
    };
    let frequency = frequency_check(design, settings, springs, &fan)?;
    Ok(Diagnosis {
        screened: groups.len(),
        fitted_rows: fitted,
        catalogue_rows: base.0,
        additions: ranked,
        unsolved,
        together,
        equality_error,
        frequency,
        needed_omega: None,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// The screening's non-negative least squares: the rows R = A k + g on the screened fan and the
/// equalities at q_eq (∇U = −∇U_g, and ∇²U = ω²M − ∇²U_g entry by entry or in trace) as rows
/// weighted by [`EQUALITY_WEIGHT`] ‖A‖/‖E‖, so that they hold wherever they can: without them the
/// homogeneous rows would be met by no springs at all.
///
/// Why that weight and not more: the solve works on the normal equations, where the weighted
/// targets enter bᵀb squared. An earlier screen weighted the equalities a thousand times the rows:
/// bᵀb was then about 10¹⁶ times the rows' ‖R‖², the rows sat at the last digits of a double, and
/// refits with more columns came back worse than the catalogue alone (a random planar arm: five
/// additions of −14 % … −1 % each and "−0 %" together, the catalogue's refit above the fit's own
/// ‖R‖²; `planar_three` with pair families: the best addition ranked third, −55 % where it removes
/// 99 %). At the rows' own scale the equalities still hold to 10⁻¹³ where the catalogue can meet
/// them (that `planar_three`), the refits agree with an exact-equality Lawson–Hanson solve where it
/// converges (the random arm: the same five additions to the percent), and a superset's refit is
/// never worse than its subset's.
struct System<'a> {
    design: &'a Design,
    frame: &'a RowFrame,
    hessian_match: bool,
    omega: f64,
    /// Right-hand side of the rows: −(gravity and held trims).
    rhs: DVector<f64>,
    /// The equalities' targets, less what gravity and the held trims give.
    targets: DVector<f64>,
    /// The catalogue's columns: rows, equality rows, and the rows' normal equations.
    base: DMatrix<f64>,
    base_eq: DMatrix<f64>,
    base_gram: DMatrix<f64>,
    /// Aᵀb of the catalogue's columns.
    base_c: DVector<f64>,
    /// The equality rows' weight, [`EQUALITY_WEIGHT`] ‖A‖/‖E‖ of the catalogue.
    weight: f64,
}

impl<'a> System<'a> {
    fn new(
        design: &'a Design,
        frame: &'a RowFrame,
        held: &SpringSet,
        omega: f64,
        hessian_match: bool,
        catalogue: &[Element],
    ) -> System<'a> {
        let q = design.q_eq.as_slice();
        let chain = &design.chain;
        // The targets less what gravity and the held trims already give.
        let mut target_h = chain.mass_matrix(&design.q_eq) * (omega * omega) - chain.gravity_hessian(q);
        let mut target_g = -chain.gravity_gradient(q);
        for (el, k) in held.elements.iter().zip(&held.stiffness) {
            target_h -= el.hessian(q) * *k;
            target_g -= el.gradient(q) * *k;
        }
        let base = frame.columns(catalogue.iter());
        let (base_eq, _) = equality_rows(design, catalogue, omega, hessian_match);
        let base_gram = base.tr_mul(&base);
        let rhs = -frame.rows(held);
        let base_c = base.tr_mul(&rhs);
        let weight = EQUALITY_WEIGHT * base.norm().max(f64::MIN_POSITIVE) / base_eq.norm().max(f64::MIN_POSITIVE);
        System {
            design,
            frame,
            hessian_match,
            omega,
            rhs,
            targets: equality_targets(&target_g, &target_h, hessian_match),
            base,
            base_eq,
            base_gram,
            base_c,
            weight,
        }
    }

    /// The rows' and the equality rows' columns of `elements`.
    fn columns(&self, elements: &[Element]) -> (DMatrix<f64>, DMatrix<f64>) {
        (self.frame.columns(elements.iter()), equality_rows(self.design, elements, self.omega, self.hessian_match).0)
    }

    /// The catalogue (and `extra`, if any) refitted by non-negative least squares, warm-started
    /// with `passive`: the rows' ‖R‖² and the stiffnesses; None if the solve fails.
    fn refit(&self, extra: Option<&(DMatrix<f64>, DMatrix<f64>)>, passive: &[usize]) -> Option<(f64, Vec<f64>)> {
        let p = self.base.ncols();
        let x = extra.map_or(0, |(m, _)| m.ncols());
        // The rows' normal equations (the catalogue's block kept from `new`), then the weighted
        // equality rows added: ‖A k − b‖² + w²‖E k − f‖².
        let mut g = DMatrix::zeros(p + x, p + x);
        g.view_mut((0, 0), (p, p)).copy_from(&self.base_gram);
        let mut c = DVector::zeros(p + x);
        c.rows_mut(0, p).copy_from(&self.base_c);
        let mut e = DMatrix::zeros(self.base_eq.nrows(), p + x);
        e.columns_mut(0, p).copy_from(&self.base_eq);
        if let Some((m, m_eq)) = extra {
            let cross = self.base.tr_mul(m);
            g.view_mut((0, p), (p, x)).copy_from(&cross);
            g.view_mut((p, 0), (x, p)).copy_from(&cross.transpose());
            g.view_mut((p, p), (x, x)).copy_from(&m.tr_mul(m));
            c.rows_mut(p, x).copy_from(&m.tr_mul(&self.rhs));
            e.columns_mut(p, x).copy_from(m_eq);
        }
        let w2 = self.weight * self.weight;
        let gram = crate::solve::lsq::Gram {
            g: g + e.tr_mul(&e) * w2,
            c: c + e.tr_mul(&self.targets) * w2,
            bb: self.rhs.norm_squared() + w2 * self.targets.norm_squared(),
        };
        let settings = crate::solve::nnls::NnlsSettings::default();
        let k = crate::solve::nnls::nnls_warm(&gram, 0.0, &settings, passive).ok()?.k;
        let mut r = &self.base * k.rows(0, p) - &self.rhs;
        if let Some((m, _)) = extra {
            r += m * k.rows(p, x);
        }
        let rows = r.norm_squared();
        rows.is_finite().then(|| (rows, k.iter().copied().collect()))
    }
}

/// The equality rows of `elements` at q_eq (E, one column per element: ∇u, then the Hessian's
/// upper triangle or its trace) and the targets for the bare arm (f: −∇U_g, ω²M − ∇²U_g).
fn equality_rows(
    design: &Design,
    elements: &[Element],
    omega: f64,
    hessian_match: bool,
) -> (DMatrix<f64>, DVector<f64>) {
    let chain = &design.chain;
    let q = design.q_eq.as_slice();
    let n = design.dof();
    let grads: Vec<DVector<f64>> = elements.iter().map(|el| el.gradient(q)).collect();
    let hessians: Vec<DMatrix<f64>> = elements.iter().map(|el| el.hessian(q)).collect();
    let count = n + if hessian_match { n * (n + 1) / 2 } else { 1 };
    let entry = |r: usize, g: &DVector<f64>, h: &DMatrix<f64>| -> f64 {
        if r < n {
            return g[r];
        }
        if !hessian_match {
            return h.trace();
        }
        let (i, k) = upper_index(n, r - n);
        h[(i, k)]
    };
    let e = DMatrix::from_fn(count, elements.len(), |r, c| entry(r, &grads[c], &hessians[c]));
    let target_h = chain.mass_matrix(&design.q_eq) * (omega * omega) - chain.gravity_hessian(q);
    (e, equality_targets(&-chain.gravity_gradient(q), &target_h, hessian_match))
}

/// The equality rows' targets: the gradient's, then the Hessian's upper triangle or trace.
fn equality_targets(gradient: &DVector<f64>, hessian: &DMatrix<f64>, hessian_match: bool) -> DVector<f64> {
    let n = gradient.len();
    let mut f: Vec<f64> = gradient.iter().copied().collect();
    if hessian_match {
        f.extend((0..n * (n + 1) / 2).map(|r| {
            let (i, k) = upper_index(n, r);
            hessian[(i, k)]
        }));
    } else {
        f.push(hessian.trace());
    }
    DVector::from_vec(f)
}

/// The (i, k), i ≤ k, of the r-th entry of an n × n upper triangle read row by row.
fn upper_index(n: usize, r: usize) -> (usize, usize) {
    let mut r = r;
    for i in 0..n {
        if r < n - i {
            return (i, i + r);
        }
        r -= n - i;
    }
    (n - 1, n - 1)
}

/// The billed elements refitted at ω and at 2ω (see the module documentation); None when a
/// refit has no solution (no elements, or a singular system).
fn frequency_check(
    design: &Design,
    settings: &FitSettings,
    springs: &SpringSet,
    fan: &Fan,
) -> Result<Option<FrequencyCheck>> {
    let omega = settings.frequency;
    let elements = &springs.elements;
    if elements.is_empty() {
        return Ok(None);
    }
    let at = |w: f64| refit_residual(design, elements, fan, w, settings.hessian_match);
    let (Some(r1), Some(r2)) = (at(omega), at(2.0 * omega)) else { return Ok(None) };
    if !(r1 > 0.0 && r1.is_finite() && r2.is_finite()) {
        return Ok(None);
    }
    let ratio = r2 / r1;
    Ok(Some(FrequencyCheck {
        omega,
        residual_at_omega: r1,
        residual_at_double: r2,
        ratio,
        cause: ratio < FREQUENCY_CAUSE,
    }))
}

/// ‖R‖ of `elements` refitted at `omega` on `fan`: least squares on the rows, signs free, with
/// the equalities at q_eq (the equilibrium gradient, and the Hessian's n(n+1)/2 entries or its
/// trace alone) weighted a thousand times the rows so that they hold wherever they can.
fn refit_residual(design: &Design, elements: &[Element], fan: &Fan, omega: f64, hessian_match: bool) -> Option<f64> {
    let frame = RowFrame::new(&design.chain, fan, omega);
    let a = frame.columns(elements.iter());
    let empty = SpringSet { elements: Vec::new(), stiffness: Vec::new() };
    let g = frame.rows(&empty);
    let (e, f) = equality_rows(design, elements, omega, hessian_match);
    let weight = 1e3 * a.norm().max(f64::MIN_POSITIVE) / e.norm().max(f64::MIN_POSITIVE);
    let m = a.nrows();
    let stacked =
        DMatrix::from_fn(m + e.nrows(), elements.len(), |r, c| if r < m { a[(r, c)] } else { weight * e[(r - m, c)] });
    let rhs = DVector::from_iterator(m + e.nrows(), (-&g).iter().copied().chain(f.iter().map(|x| weight * x)));
    let k = stacked.svd(true, true).solve(&rhs, 1e-12).ok()?;
    Some((&a * k + g).norm())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn couplings_of_three_joints() {
        let c = couplings(3);
        // 3 joints, 3 pairs × 6 ratios, 1 triple × 4 signs.
        assert_eq!(c.len(), 3 + 18 + 4);
        assert!(c.iter().all(|a| a.iter().find(|x| **x != 0.0).is_some_and(|x| *x > 0.0)));
        assert!(same_coupling(&[1.0, -1.0, 0.0], &[-1.0, 1.0, 0.0]));
        assert!(!same_coupling(&[1.0, 1.0, 0.0], &[1.0, -1.0, 0.0]));
    }

    #[test]
    fn upper_triangle_order() {
        assert_eq!(upper_index(3, 0), (0, 0));
        assert_eq!(upper_index(3, 2), (0, 2));
        assert_eq!(upper_index(3, 3), (1, 1));
        assert_eq!(upper_index(3, 5), (2, 2));
    }
}
