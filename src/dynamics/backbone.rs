//! The backbone: the period of each mode as a function of energy, from free runs.
//!
//! The exact potential ½ω²r² makes every geodesic from q_eq a strict mode on which the motion is
//! r(t) = r₀ cos ωt whatever the amplitude: it is isochronous, T = 2π/ω at every energy and on
//! every mode. A fitted potential only approximates it, and how far its periods stray from T₀ =
//! 2π/ω as the energy grows (the backbone curve eigenmanifold studies report) is a figure of merit
//! beside the residual angle: the isochrony error max |T/T₀ − 1| over modes and energies.
//!
//! Each point is a free run released from rest on a mode where U − U(q_eq) = E, with no damping
//! and no control, for [`PERIODS`] nominal periods. Its period is read from the passages through
//! q_eq's side: p(t) = (q(t) − q_eq)·(q₀ − q_eq) changes sign twice a period, and each crossing
//! is found on the cubic Hermite interpolant of p and ṗ = q̇·(q₀ − q_eq) between output samples
//! (error of order h⁴ in the sample interval h); T = 2 (t_last − t_first) / k over an even number
//! k of half periods, so the unequal halves of an asymmetric swing average out.

use rayon::prelude::*;
use serde::Serialize;

use crate::design::Design;
use crate::design::controllers::ControllerSettings;
use crate::design::scenario::{EnergySpec, ModeSpec, ScenarioKind};
use crate::design::simulate::SimSettings;
use crate::dynamics::scenario::{LabelSource, mode_direction, nominal_energy, start_on_mode};
use crate::dynamics::simulate::{Dynamics, ElasticPotential, RunSpec, Trace, run};
use crate::error::{Error, Result};
use crate::geodesic::MetricFrame;

/// Nominal periods 2π/ω each backbone run lasts.
pub const PERIODS: f64 = 10.0;

/// Fractions of the design's largest scenario energy at which the backbone is taken.
pub const ENERGY_FRACTIONS: [f64; 4] = [0.25, 0.5, 0.75, 1.0];

/// One point of a backbone: a mode at an energy and the period of the free motion there.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BackbonePoint {
    /// The mode: its angle θ (two joints) or its direction of joint velocities.
    pub mode: ModeSpec,
    /// U − U(q_eq) at the release, J.
    pub energy_j: f64,
    /// The period of the free motion, s (null: fewer than two passages through q_eq's side).
    pub period_s: Option<f64>,
    /// T/T₀ − 1.
    pub rel_error: Option<f64>,
}

/// The backbone of a design (`summary.json` of `simulate`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Backbone {
    /// ω of the design, rad/s.
    pub omega_rad_s: f64,
    /// T₀ = 2π/ω, s.
    pub nominal_period_s: f64,
    /// The energies, J.
    pub energies_j: Vec<f64>,
    /// Every mode at every energy it reaches inside the region.
    pub points: Vec<BackbonePoint>,
    /// (mode, energy) pairs left out: the potential does not rise that far along the mode inside
    /// the region.
    pub out_of_reach: Vec<(ModeSpec, f64)>,
    /// The isochrony error: the largest |T/T₀ − 1| over the points (null without a period).
    pub isochrony_error: Option<f64>,
}

/// The modes a backbone follows: for two joints the six of the paper's Fig. 5 (θ = kπ/3), for
/// more the joint axes.
pub fn backbone_modes(n: usize) -> Vec<ModeSpec> {
    if n == 2 {
        (0..6).map(|k| ModeSpec::Angle(k as f64 * std::f64::consts::FRAC_PI_3)).collect()
    } else {
        (0..n).map(|i| ModeSpec::Vector((0..n).map(|j| if i == j { 1.0 } else { 0.0 }).collect())).collect()
    }
}

/// The energies a backbone visits: [`ENERGY_FRACTIONS`] of the largest energy the design's
/// scenarios name (releases, a switch's energy, a swing-up's e0 and E_d; 10 J without any).
pub fn backbone_energies(design: &Design) -> Vec<f64> {
    let mut top = 0.0f64;
    for s in &design.scenarios {
        for r in &s.releases {
            top = top.max(r.energy);
        }
        match s.kind {
            ScenarioKind::Switch => top = top.max(s.energy.unwrap_or(10.0)),
            ScenarioKind::Swingup => {
                top = top.max(s.e0.unwrap_or(5.0));
                top = top.max(match s.ed.clone().unwrap_or(EnergySpec::Value(20.0)) {
                    EnergySpec::Value(v) => v,
                    EnergySpec::Steps(steps) => steps.iter().map(|p| p[1]).fold(0.0, f64::max),
                });
            }
            ScenarioKind::Free => {}
        }
    }
    if top <= 0.0 {
        top = 10.0;
    }
    ENERGY_FRACTIONS.iter().map(|f| f * top).collect()
}

/// The period of a free run released from rest at its first sample (see the module docs), s.
pub fn period(trace: &Trace, q_eq: &[f64]) -> Option<f64> {
    let n = trace.n;
    let d: Vec<f64> = (0..n).map(|i| trace.q[i] - q_eq[i]).collect();
    let p = |k: usize| (0..n).map(|i| (trace.q[k * n + i] - q_eq[i]) * d[i]).sum::<f64>();
    let pd = |k: usize| (0..n).map(|i| trace.qd[k * n + i] * d[i]).sum::<f64>();
    let mut crossings = Vec::new();
    for k in 0..trace.t.len().saturating_sub(1) {
        let (p0, p1) = (p(k), p(k + 1));
        if p0 == 0.0 || p0.signum() == p1.signum() {
            continue;
        }
        // Cubic Hermite on [t_k, t_k+1] in x ∈ [0, 1]; its root by bisection (p changes sign).
        let h = trace.t[k + 1] - trace.t[k];
        let (m0, m1) = (pd(k) * h, pd(k + 1) * h);
        let hermite = |x: f64| {
            let (x2, x3) = (x * x, x * x * x);
            (2.0 * x3 - 3.0 * x2 + 1.0) * p0 + (x3 - 2.0 * x2 + x) * m0 + (-2.0 * x3 + 3.0 * x2) * p1 + (x3 - x2) * m1
        };
        let (mut a, mut b) = (0.0, 1.0);
        for _ in 0..60 {
            let m = 0.5 * (a + b);
            if hermite(m).signum() == p0.signum() {
                a = m;
            } else {
                b = m;
            }
        }
        crossings.push(trace.t[k] + 0.5 * (a + b) * h);
    }
    if crossings.len() < 3 {
        return None;
    }
    let halves = (crossings.len() - 1) / 2 * 2;
    Some(2.0 * (crossings[halves] - crossings[0]) / halves as f64)
}

/// The backbone of `design` with the elastic potential `potential` on `modes` at `energies`:
/// one free run per reachable point, in parallel (each owns its label field, so the result does
/// not depend on the thread count).
pub fn backbone<'a>(
    design: &'a Design,
    potential: &'a ElasticPotential,
    label: &LabelSource<'a>,
    settings: &SimSettings,
    modes: &[ModeSpec],
    energies: &[f64],
) -> Result<Backbone> {
    let n = design.dof();
    let omega = design.fit.frequency;
    let t0 = 2.0 * std::f64::consts::PI / omega;
    let frame = MetricFrame::new(&design.chain.mass_matrix(&design.q_eq))?;
    let mut energy_at = nominal_energy(design, potential, label)?;
    let mut starts = Vec::new();
    let mut out_of_reach = Vec::new();
    for mode in modes {
        let u = mode_direction(mode, n, &frame)
            .map_err(|reason| Error::Setting { field: "backbone mode".into(), reason })?;
        for &e in energies {
            match start_on_mode(design, &u, e, &mut energy_at) {
                Ok(q0) => starts.push((mode.clone(), e, q0)),
                Err(_) => out_of_reach.push((mode.clone(), e)),
            }
        }
    }
    let points = starts
        .par_iter()
        .map(|(mode, e, q0)| {
            let spec = RunSpec {
                name: "backbone".into(),
                q0: q0.clone(),
                qd0: vec![0.0; n],
                duration: PERIODS * t0,
                damping: vec![0.0; n],
                mode: None,
                energy: None,
                parasitic: None,
                stiffness_scale: None,
                built: None,
            };
            let mut dynamics = Dynamics::new(
                &design.chain,
                &design.q_eq,
                potential,
                ControllerSettings::default(),
                &spec,
                Some(label.field()),
            )?;
            let result = run(&mut dynamics, settings)?;
            let period_s = period(&result.trace, design.q_eq.as_slice());
            Ok(BackbonePoint { mode: mode.clone(), energy_j: *e, period_s, rel_error: period_s.map(|t| t / t0 - 1.0) })
        })
        .collect::<Result<Vec<_>>>()?;
    let isochrony_error = points
        .iter()
        .filter_map(|p| p.rel_error)
        .map(f64::abs)
        .fold(None, |a: Option<f64>, x| Some(a.map_or(x, |a| a.max(x))));
    Ok(Backbone {
        omega_rad_s: omega,
        nominal_period_s: t0,
        energies_j: energies.to_vec(),
        points,
        out_of_reach,
        isochrony_error,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_period_of_a_sampled_swing_is_read_to_round_off() {
        // q(t) = q_eq + d (cos ωt + 0.3 cos 2ωt + 0.3): a swing of period 2π/ω with unequal halves
        // (p crosses zero off the quarter periods), sampled every 10 ms like `simulate`'s output.
        let (omega, q_eq, d) = (3.7f64, [0.2, 1.1], [0.4, -0.9]);
        let h = 0.01;
        let (mut t, mut q, mut qd) = (Vec::new(), Vec::new(), Vec::new());
        for k in 0..=1200 {
            let tk = k as f64 * h;
            let (c, dc) = (
                (omega * tk).cos() + 0.3 * (2.0 * omega * tk).cos() + 0.3,
                -omega * (omega * tk).sin() - 0.6 * omega * (2.0 * omega * tk).sin(),
            );
            t.push(tk);
            q.extend((0..2).map(|i| q_eq[i] + d[i] * c));
            qd.extend((0..2).map(|i| d[i] * dc));
        }
        let samples = t.len();
        let trace = Trace {
            n: 2,
            t,
            q,
            qd,
            tau: vec![0.0; samples * 12],
            energy: vec![0.0; samples],
            label: vec![f64::NAN; samples],
            label_target: vec![f64::NAN; samples],
            in_ball: vec![false; samples],
            geodesic_deviation: Vec::new(),
        };
        let t0 = 2.0 * std::f64::consts::PI / omega;
        let p = period(&trace, &q_eq).unwrap();
        // Linear interpolation between the samples would be off by about (ωh)² ≈ 1e-3 here; the
        // Hermite interpolant is what makes 1e-6 measurable.
        assert!((p / t0 - 1.0).abs() < 1e-7, "{p} against {t0}");
    }
}
