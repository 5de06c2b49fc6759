//! The excitation plan: releases from rest that make every rate identifiable, chosen before the
//! arm is logged.
//!
//! **Candidates.** Releases from rest at exp(f·ℓ·u): `directions` metric unit vectors u at q_eq
//! (for two joints over half a turn: u and −u swing on the same mode) and each distance fraction
//! f of `radii` of the region's extent ℓ along u. Each is simulated as designed (nominal rates,
//! with the `expected_damping` and `expected_friction` of every joint) for `release_seconds` at
//! `rate_hz` ([`super::swing`]); a candidate whose swing leaves the region is dropped.
//!
//! **Criterion: D-optimal.** The regression of a candidate's noise-free swing gives its
//! information Φᵀ Φ about the unknowns (δ of every part, damping, friction). Releases are added
//! one at a time, each the candidate that most increases log det of the summed information
//! (with unit-scaled unknowns and a tiny ridge, so that unknowns no candidate excites do not
//! make every determinant zero); a candidate may be chosen again (another release there). The
//! D-optimal design minimises the volume of the estimates' confidence ellipsoid, so it does not
//! favour any one unknown.
//!
//! **Predicted standard errors.** After each addition the chosen releases are read through a
//! simulated encoder (`encoder_bits` per turn, `encoder_noise_counts` rms before quantisation,
//! seeded) and identified exactly as `identify` would identify real logs; the plan stops when
//! every rate is identified or the total log reaches `max_log_seconds`, and reports what that
//! identification found: the standard error every rate would get, and which rates no release
//! within the region can tell apart. An identification is skipped, but for the last, while a
//! rate is not estimable from the readings so far (decided on their ΦᵀΦ summed reading by
//! reading, by the test the identification itself makes): it could not find every rate identified, so
//! it could not end the loop. On a bill of 141 parts that is every identification but the last.

use nalgebra::DMatrix;
use rayon::prelude::*;
use serde::Serialize;

use super::log::Run;
use super::regression::{Filters, Model, Rows};
use super::swing::{Drive, encoder_reading, swing};
use super::{Identification, Status};
use crate::design::Design;
use crate::error::{Error, Result};
use crate::fit::bill::BomRow;
use crate::geodesic::{Fan, FanSpec, Region, Stop};
use crate::numerics::rng::SplitMix64;
use crate::potential::{Potential, SpringSet};

/// One proposed release.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Release {
    /// Where to hold the arm before letting go, rad.
    pub q0: Vec<f64>,
    /// The release direction in the metric frame at q_eq (unit vector).
    pub direction: Vec<f64>,
    /// Its metric distance from q_eq, √(kg·m²)·rad.
    pub distance: f64,
    /// The potential energy it starts with, U(q0) − U(q_eq), J.
    pub energy_j: f64,
    /// How many times to release it.
    pub releases: usize,
    /// Log length of each release, s.
    pub seconds: f64,
}

/// The plan.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Plan {
    /// The criterion, in words.
    pub criterion: String,
    /// Candidates considered, and how many were dropped because their swing leaves the region.
    pub candidates: usize,
    /// Candidates dropped because their swing leaves the region.
    pub dropped: usize,
    /// The releases, in the order they were chosen (a repeated choice adds to `releases`).
    pub releases: Vec<Release>,
    /// Total log length, s.
    pub total_seconds: f64,
    /// Log rate and encoder the prediction assumes.
    pub rate_hz: f64,
    /// The simulated encoder's resolution, bits per turn.
    pub encoder_bits: u32,
    /// The simulated encoder's rms noise before quantisation, counts.
    pub encoder_noise_counts: f64,
    /// Whether every rate comes out identified.
    pub complete: bool,
    /// The identification of the simulated logs of the plan.
    pub predicted: Identification,
}

/// A candidate release with its simulated swing and the rows it gives.
struct Candidate {
    q0: Vec<f64>,
    direction: Vec<f64>,
    distance: f64,
    energy: f64,
    run: Run,
    information: DMatrix<f64>,
}

/// Proposes releases for identifying `bom` (read from `bom_path`) on `design`: the candidate
/// release points, each simulated (those that leave the region dropped), then the D-optimal
/// choice among them until the simulated logs identify every rate or the log budget is spent.
pub fn plan(design: &Design, bom_path: &std::path::Path, bom: &[BomRow]) -> Result<Plan> {
    let settings = &design.identify;
    super::check_bill(design, bom_path, bom)?;
    let n = design.dof();
    let springs = crate::fit::bill::spring_set(bom);
    let model = Model::new(bom, n, settings);
    let cutoff = settings.cutoff(design.fit.frequency);
    let filters = Filters::new(1.0 / settings.rate_hz, cutoff, settings.smoothing_hz);
    if settings.release_seconds < filters.shortest_run(1.0 / settings.rate_hz) {
        return Err(Error::invalid(
            &design.path,
            "identify.release_seconds",
            format!(
                "{} s is shorter than the filters need at a cut-off of {cutoff:.3} Hz ({:.3} s)",
                settings.release_seconds,
                filters.shortest_run(1.0 / settings.rate_hz)
            ),
        ));
    }
    let points = release_points(design)?;
    let (candidates, dropped) = simulate_candidates(design, &springs, &model, &filters, &points)?;
    if candidates.is_empty() {
        return Err(Error::invalid(
            &design.path,
            "identify.radii",
            "every candidate release swings out of the region: choose smaller identify.radii".to_string(),
        ));
    }
    let (chosen, predicted) = choose(design, bom_path, bom, &candidates, model.unknowns.len())?;
    Ok(Plan {
        criterion: "D-optimal: each release the candidate that most increases log det of the information ΦᵀΦ".into(),
        candidates: candidates.len() + dropped,
        dropped,
        total_seconds: chosen.len() as f64 * settings.release_seconds,
        releases: releases(&candidates, &chosen, settings.release_seconds),
        rate_hz: settings.rate_hz,
        encoder_bits: settings.encoder_bits,
        encoder_noise_counts: settings.encoder_noise_counts,
        complete: predicted.rates.iter().all(|r| r.status == Status::Identified),
        predicted,
    })
}

/// A candidate release point: where to let go, the direction in the metric frame at q_eq and
/// the metric distance along it.
type ReleasePoint = (Vec<f64>, Vec<f64>, f64);

/// Candidate release points along a fan of geodesics to the region's boundary, at each
/// fraction of `radii` of each geodesic's length (for two joints only one of u and −u: they
/// swing on the same mode).
fn release_points(design: &Design) -> Result<Vec<ReleasePoint>> {
    let settings = &design.identify;
    let n = design.dof();
    let extent = design.region.radius().unwrap_or(design.geodesics.max_arc);
    let stop = match &design.region {
        Region::Ball { radius } => Stop::Arc(*radius),
        region => Stop::Region { region, max_arc: design.geodesics.max_arc },
    };
    let count = if n == 2 { 2 * settings.directions } else { settings.directions };
    let fan = Fan::trace(
        &design.chain,
        &design.q_eq,
        FanSpec { count, phase: 0.0, stop, spacing: extent / 400.0 },
        design.geodesics.ode,
    )?;
    let mut points = Vec::new();
    for (g, u) in fan.geodesics.iter().zip(&fan.frame_directions) {
        // Two joints: u and −u swing on the same mode.
        if n == 2 && (u[1] < -1e-12 || (u[1].abs() <= 1e-12 && u[0] < 0.0)) {
            continue;
        }
        for &f in &settings.radii {
            let target = f * g.length();
            let i = (0..g.len()).min_by(|&a, &b| (g.s(a) - target).abs().total_cmp(&(g.s(b) - target).abs()));
            if let Some(i) = i.filter(|&i| i > 0) {
                points.push((g.q(i).to_vec(), u.iter().copied().collect::<Vec<_>>(), g.s(i)));
            }
        }
    }
    Ok(points)
}

/// Each release point's swing simulated as designed (with the expected damping and friction) and its
/// information: the candidates, and how many were dropped because their swing leaves the
/// region.
fn simulate_candidates(
    design: &Design,
    springs: &SpringSet,
    model: &Model,
    filters: &Filters,
    points: &[ReleasePoint],
) -> Result<(Vec<Candidate>, usize)> {
    let settings = &design.identify;
    let u_eq = springs.value(design.q_eq.as_slice())? + design.chain.gravity_potential(design.q_eq.as_slice());
    // The damping and friction the built arm is expected to have: they shorten a swing and
    // leave the friction's reversals in the logs, so a plan without them over-promises.
    let damping = vec![settings.expected_damping; design.dof()];
    let friction = vec![settings.expected_friction; design.dof()];
    let drive = Drive { damping: &damping, friction: &friction, torque: None };
    let test = super::region::RegionTest::new(design, settings.region_margin);
    let simulated: Vec<Option<Candidate>> = points
        .par_iter()
        .map(|(q0, direction, distance)| {
            let run = swing(design, springs, &drive, q0, settings.release_seconds, settings.rate_hz)?;
            if test.first_outside(&run.q).ok()?.is_some() {
                return None;
            }
            let rows = super::regression::run_rows(design, model, &run, 0, filters);
            let energy = springs.value(q0).ok()? + design.chain.gravity_potential(q0) - u_eq;
            Some(Candidate {
                q0: q0.clone(),
                direction: direction.clone(),
                distance: *distance,
                energy,
                run,
                information: information(&rows),
            })
        })
        .collect();
    let dropped = simulated.iter().filter(|c| c.is_none()).count();
    Ok((simulated.into_iter().flatten().collect(), dropped))
}

/// The D-optimal choice: releases added one at a time, each the candidate that most increases
/// log det of the summed information (unknowns scaled to unit information over all
/// candidates, plus a tiny ridge), each read through the simulated encoder and the readings so
/// far identified (unless a rate is not estimable from them yet: see the module's doc); it stops
/// when every rate is identified or the log budget is spent. Returns
/// the choices as (candidate, repeat) and the last identification.
fn choose(
    design: &Design,
    bom_path: &std::path::Path,
    bom: &[BomRow],
    candidates: &[Candidate],
    p: usize,
) -> Result<(Vec<(usize, usize)>, Identification)> {
    let settings = &design.identify;
    // Unit scaling of the unknowns over all candidates, and the ridge.
    let total: DMatrix<f64> = candidates.iter().fold(DMatrix::zeros(p, p), |a, c| a + &c.information);
    let scale: Vec<f64> = (0..p).map(|k| if total[(k, k)] > 0.0 { 1.0 / total[(k, k)].sqrt() } else { 1.0 }).collect();
    let scaled = |m: &DMatrix<f64>| DMatrix::from_fn(p, p, |a, b| m[(a, b)] * scale[a] * scale[b]);
    let infos: Vec<DMatrix<f64>> = candidates.iter().map(|c| scaled(&c.information)).collect();
    let ridge = 1e-9 * (0..p).map(|k| scaled(&total)[(k, k)]).sum::<f64>().max(1e-300) / p as f64;
    let mut sum = DMatrix::<f64>::identity(p, p) * ridge;
    let mut chosen: Vec<(usize, usize)> = Vec::new(); // (candidate, repeat)
    let mut repeats = vec![0usize; candidates.len()];
    // Each reading is checked and turned into rows once, not at every identification.
    let mut readings =
        super::Readings::new(design, bom_path, bom, settings, std::path::Path::new("(the plan's simulated releases)"))?;
    let budget = (settings.max_log_seconds / settings.release_seconds).floor().max(1.0) as usize;
    let mut predicted = None;
    while chosen.len() < budget {
        let Some(best) = (0..candidates.len())
            .max_by(|&a, &b| log_det(&(&sum + &infos[a])).total_cmp(&log_det(&(&sum + &infos[b]))))
        else {
            break;
        };
        sum += &infos[best];
        chosen.push((best, repeats[best]));
        let mut rng = SplitMix64::stream(settings.seed, (best * 1000 + repeats[best]) as u64);
        repeats[best] += 1;
        let mut reading =
            encoder_reading(&candidates[best].run, settings.encoder_bits, settings.encoder_noise_counts, &mut rng);
        reading.name = format!("release {}", chosen.len());
        readings.add(reading)?;
        // An identification that cannot find every rate identified cannot end the loop: only
        // the last one, the prediction, is needed then.
        if chosen.len() < budget && !readings.may_identify_every_rate() {
            continue;
        }
        let id = readings.identify()?;
        let complete = id.rates.iter().all(|r| r.status == Status::Identified);
        predicted = Some(id);
        if complete {
            break;
        }
    }
    // The budget is at least one release and there is a candidate: one was identified.
    let predicted = predicted.ok_or_else(|| Error::numerical("identify plan", "no release was chosen"))?;
    Ok((chosen, predicted))
}

/// The chosen releases in the order first chosen, a repeated choice adding to `releases`.
fn releases(candidates: &[Candidate], chosen: &[(usize, usize)], seconds: f64) -> Vec<Release> {
    let mut releases: Vec<Release> = Vec::new();
    let mut placed: Vec<Option<usize>> = vec![None; candidates.len()];
    for &(c, _) in chosen {
        match placed[c] {
            Some(i) => releases[i].releases += 1,
            None => {
                let k = &candidates[c];
                placed[c] = Some(releases.len());
                releases.push(Release {
                    q0: k.q0.clone(),
                    direction: k.direction.clone(),
                    distance: k.distance,
                    energy_j: k.energy,
                    releases: 1,
                    seconds,
                });
            }
        }
    }
    releases
}

/// ΦᵀΦ of a candidate's rows.
fn information(rows: &Rows) -> DMatrix<f64> {
    super::estimate::Gram::of(rows).full()
}

/// log det of a symmetric positive definite matrix (−∞ if it is not).
fn log_det(m: &DMatrix<f64>) -> f64 {
    match m.clone().cholesky() {
        Some(c) => 2.0 * c.l().diagonal().iter().map(|d| d.ln()).sum::<f64>(),
        None => f64::NEG_INFINITY,
    }
}
