//! A swing of the arm simulated as an encoder would log it: what the excitation plan predicts
//! from, and the known answers of the tests.
//!
//! M q̈ + C q̇ + ∂U_g/∂q + ∂U_e/∂q + D q̇ + f_c sign(q̇) = τ(t), integrated by classical RK4 at the
//! log's rate from rest (or any start), sampled at every step. An encoder of b bits per turn
//! reads round((q + ν)/c)·c with c = 2π/2ᵇ and ν Gaussian noise of `noise` counts rms.

use super::log::Run;
use crate::design::Design;
use crate::numerics::rng::SplitMix64;
use crate::potential::SpringSet;

/// How the simulated arm dissipates and is driven.
pub struct Drive<'a> {
    /// Viscous damping per joint, N·m·s/rad.
    pub damping: &'a [f64],
    /// Coulomb friction per joint, N·m.
    pub friction: &'a [f64],
    /// The applied torque at time t (None: a free swing).
    pub torque: Option<&'a (dyn Fn(f64) -> Vec<f64> + Sync)>,
}

/// A run of `seconds` at `rate` Hz from rest at `q0`, with the springs `springs` (the arm as
/// built), exact angles; None if the integration fails (a singular mass matrix).
pub fn swing(design: &Design, springs: &SpringSet, drive: &Drive, q0: &[f64], seconds: f64, rate: f64) -> Option<Run> {
    let chain = &design.chain;
    let n = design.dof();
    let grouped = springs.grouped();
    let mut ws = chain.workspace();
    let h = 1.0 / rate;
    let steps = (seconds * rate).round() as usize;
    let rhs = |t: f64, y: &[f64], dy: &mut [f64], ws: &mut crate::model::Workspace| -> bool {
        let (q, qd) = y.split_at(n);
        let mut tau = vec![0.0; n];
        let mut g = vec![0.0; n];
        grouped.gradient_into(q, &mut g);
        let mut grav = vec![0.0; n];
        chain.gravity_gradient_into(q, &mut grav);
        let applied = drive.torque.map(|f| f(t));
        for j in 0..n {
            let sign = if qd[j] > 0.0 {
                1.0
            } else if qd[j] < 0.0 {
                -1.0
            } else {
                0.0
            };
            tau[j] = -g[j] - grav[j] - drive.damping[j] * qd[j] - drive.friction[j] * sign
                + applied.as_ref().map_or(0.0, |a| a[j]);
        }
        dy[..n].copy_from_slice(qd);
        chain.acceleration(ws, q, qd, &tau, &mut dy[n..])
    };
    let mut y: Vec<f64> = q0.iter().copied().chain(std::iter::repeat_n(0.0, n)).collect();
    let (mut k1, mut k2, mut k3, mut k4) = (vec![0.0; 2 * n], vec![0.0; 2 * n], vec![0.0; 2 * n], vec![0.0; 2 * n]);
    let mut tmp = vec![0.0; 2 * n];
    let mut run = Run {
        name: String::new(),
        t: Vec::with_capacity(steps + 1),
        q: Vec::with_capacity((steps + 1) * n),
        tau: drive.torque.map(|_| Vec::with_capacity((steps + 1) * n)),
        lines: Vec::with_capacity(steps + 1),
        dt: h,
    };
    for k in 0..=steps {
        let t = k as f64 * h;
        run.t.push(t);
        run.q.extend_from_slice(&y[..n]);
        run.lines.push(k + 2);
        if let (Some(f), Some(tau)) = (drive.torque, run.tau.as_mut()) {
            tau.extend(f(t));
        }
        if k == steps {
            break;
        }
        let ok = rhs(t, &y, &mut k1, &mut ws)
            && {
                tmp.iter_mut().zip(&y).zip(&k1).for_each(|((o, y), k)| *o = y + 0.5 * h * k);
                rhs(t + 0.5 * h, &tmp, &mut k2, &mut ws)
            }
            && {
                tmp.iter_mut().zip(&y).zip(&k2).for_each(|((o, y), k)| *o = y + 0.5 * h * k);
                rhs(t + 0.5 * h, &tmp, &mut k3, &mut ws)
            }
            && {
                tmp.iter_mut().zip(&y).zip(&k3).for_each(|((o, y), k)| *o = y + h * k);
                rhs(t + h, &tmp, &mut k4, &mut ws)
            };
        if !ok {
            return None;
        }
        for i in 0..2 * n {
            y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        if y.iter().any(|v| !v.is_finite()) {
            return None;
        }
    }
    Some(run)
}

/// The run as an encoder of `bits` per turn reads it, with `noise` counts rms of Gaussian noise
/// before quantisation, drawn from `rng`.
pub fn encoder_reading(run: &Run, bits: u32, noise: f64, rng: &mut SplitMix64) -> Run {
    let count = std::f64::consts::TAU / 2f64.powi(bits as i32);
    let q = run.q.iter().map(|q| ((q + noise * count * rng.normal()) / count).round() * count).collect();
    Run { q, ..run.clone() }
}
