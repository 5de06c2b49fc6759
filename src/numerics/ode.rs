//! An adaptive Dormand–Prince 5(4) integrator with dense output.
//!
//! Written here rather than taken from a crate because springfit needs three things together
//! that the maintained ODE crates do not offer in one allocation-free package: (1) right-hand
//! sides on plain slices, so the geodesic, its Jacobi fields and the closed-loop dynamics share
//! one integrator without generic state types; (2) dense output, so geodesics are sampled at exact
//! arc lengths and stopped *at* the region boundary (event location on the interpolant, not
//! overshoot); (3) bit-for-bit determinism, so a fan integrated on any number of threads gives
//! the same samples. The method is Dormand & Prince (1980) with the 4th-order continuous
//! extension of Hairer, Nørsett & Wanner, *Solving ODEs I*, §II.6, and a PI step-size controller.

use serde::{Deserialize, Serialize};

/// Tolerances and limits of the adaptive integrator.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OdeSettings {
    /// Relative tolerance of the local error estimate.
    pub rtol: f64,
    /// Absolute tolerance of the local error estimate.
    pub atol: f64,
    /// Largest step allowed (0: no limit).
    pub max_step: f64,
    /// Steps below this size count as an underflow: the integration fails instead of crawling.
    pub min_step: f64,
    /// Most steps (accepted or rejected) one integration may take.
    pub max_steps: usize,
}

impl Default for OdeSettings {
    fn default() -> Self {
        OdeSettings { rtol: 1e-10, atol: 1e-10, max_step: 0.0, min_step: 1e-12, max_steps: 100_000 }
    }
}

impl OdeSettings {
    /// Checks the settings; `prefix` names the section in messages (e.g. `geodesics.ode`).
    pub fn validate(&self, prefix: &str) -> Result<(), (String, String)> {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        if !pos(self.rtol) || self.rtol > 1e-2 {
            return Err((format!("{prefix}.rtol"), "must be in (0, 1e-2]".into()));
        }
        if !pos(self.atol) {
            return Err((format!("{prefix}.atol"), "must be positive".into()));
        }
        if !(self.max_step.is_finite() && self.max_step >= 0.0) {
            return Err((format!("{prefix}.max_step"), "must be ≥ 0 (0: no limit)".into()));
        }
        if !pos(self.min_step) {
            return Err((format!("{prefix}.min_step"), "must be positive".into()));
        }
        if self.max_steps == 0 {
            return Err((format!("{prefix}.max_steps"), "must be at least 1".into()));
        }
        Ok(())
    }
}

/// Why an integration stopped early.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OdeFailure {
    /// The step size fell below `min_step` at time `t`.
    StepSizeUnderflow {
        /// Where: the independent variable (time in s for the arm's motion, arc length in
        /// √(kg·m²)·rad along a geodesic).
        t: f64,
    },
    /// The right-hand side could not be evaluated at time `t` (e.g. a singular mass matrix).
    RhsFailed {
        /// Where: the independent variable (time in s for the arm's motion, arc length in
        /// √(kg·m²)·rad along a geodesic).
        t: f64,
    },
    /// More than `max_steps` steps.
    TooManySteps {
        /// How far it got, in the independent variable's unit.
        t: f64,
    },
    /// The state became non-finite at time `t`.
    NonFinite {
        /// Where: the independent variable (time in s for the arm's motion, arc length in
        /// √(kg·m²)·rad along a geodesic).
        t: f64,
    },
}

impl std::fmt::Display for OdeFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            OdeFailure::StepSizeUnderflow { t } => write!(f, "step size underflow at t = {t:.6}"),
            OdeFailure::RhsFailed { t } => {
                write!(f, "the mass matrix is not positive definite at t = {t:.6}")
            }
            OdeFailure::TooManySteps { t } => write!(f, "too many steps (stopped at t = {t:.6})"),
            OdeFailure::NonFinite { t } => write!(f, "the state became non-finite at t = {t:.6}"),
        }
    }
}

// Dormand–Prince 5(4) tableau.
const C2: f64 = 1.0 / 5.0;
const C3: f64 = 3.0 / 10.0;
const C4: f64 = 4.0 / 5.0;
const C5: f64 = 8.0 / 9.0;
const A21: f64 = 1.0 / 5.0;
const A31: f64 = 3.0 / 40.0;
const A32: f64 = 9.0 / 40.0;
const A41: f64 = 44.0 / 45.0;
const A42: f64 = -56.0 / 15.0;
const A43: f64 = 32.0 / 9.0;
const A51: f64 = 19372.0 / 6561.0;
const A52: f64 = -25360.0 / 2187.0;
const A53: f64 = 64448.0 / 6561.0;
const A54: f64 = -212.0 / 729.0;
const A61: f64 = 9017.0 / 3168.0;
const A62: f64 = -355.0 / 33.0;
const A63: f64 = 46732.0 / 5247.0;
const A64: f64 = 49.0 / 176.0;
const A65: f64 = -5103.0 / 18656.0;
const A71: f64 = 35.0 / 384.0;
const A73: f64 = 500.0 / 1113.0;
const A74: f64 = 125.0 / 192.0;
const A75: f64 = -2187.0 / 6784.0;
const A76: f64 = 11.0 / 84.0;
// Error estimate: 5th-order minus embedded 4th-order weights.
const E1: f64 = 71.0 / 57600.0;
const E3: f64 = -71.0 / 16695.0;
const E4: f64 = 71.0 / 1920.0;
const E5: f64 = -17253.0 / 339200.0;
const E6: f64 = 22.0 / 525.0;
const E7: f64 = -1.0 / 40.0;
// Dense output (continuous extension of order 4).
const D1: f64 = -12715105075.0 / 11282082432.0;
const D3: f64 = 87487479700.0 / 32700410799.0;
const D4: f64 = -10690763975.0 / 1880347072.0;
const D5: f64 = 701980252875.0 / 199316789632.0;
const D6: f64 = -1453857185.0 / 822651844.0;
const D7: f64 = 69997945.0 / 29380423.0;

/// The state of a Dormand–Prince integration: current point, the last step's dense output and
/// the step-size controller. Reused across integrations of the same dimension without allocating.
#[derive(Debug, Clone)]
pub struct Dopri5 {
    settings: OdeSettings,
    dim: usize,
    t: f64,
    t_old: f64,
    h: f64,
    y: Vec<f64>,
    k: [Vec<f64>; 7],
    y_stage: Vec<f64>,
    y_new: Vec<f64>,
    /// Dense-output coefficients of the last accepted step (5 × dim).
    cont: [Vec<f64>; 5],
    err_old: f64,
    steps: usize,
    rejected: usize,
    /// Only the first `error_dim` components enter the local error estimate.
    error_dim: usize,
    /// The previous attempt was rejected: the next accepted step may not grow (Hairer's rule,
    /// which avoids oscillating between rejection and over-long steps).
    last_rejected: bool,
}

impl Dopri5 {
    /// An integrator for systems of dimension `dim`.
    pub fn new(dim: usize, settings: OdeSettings) -> Self {
        let v = || vec![0.0; dim];
        Dopri5 {
            settings,
            dim,
            t: 0.0,
            t_old: 0.0,
            h: 0.0,
            y: v(),
            k: [v(), v(), v(), v(), v(), v(), v()],
            y_stage: v(),
            y_new: v(),
            cont: [v(), v(), v(), v(), v()],
            err_old: 1e-4,
            steps: 0,
            rejected: 0,
            last_rejected: false,
            error_dim: dim,
        }
    }

    /// Restricts step-size control to the first `k` components. The remaining components ride
    /// along on the same steps: used for the Jacobi fields, which are linear in themselves and
    /// driven by the geodesic, so steps that resolve the geodesic resolve them to the same order
    /// (as sensitivity solvers such as CVODES do with error control on sensitivities off).
    pub fn with_error_components(mut self, k: usize) -> Self {
        self.error_dim = k.clamp(1, self.dim);
        self
    }

    /// Changes the largest step (0: no limit) for the next integrations.
    pub fn set_max_step(&mut self, h: f64) {
        self.settings.max_step = h;
    }

    /// Current time.
    pub fn t(&self) -> f64 {
        self.t
    }

    /// Time at the start of the last accepted step.
    pub fn t_old(&self) -> f64 {
        self.t_old
    }

    /// Current state.
    pub fn y(&self) -> &[f64] {
        &self.y
    }

    /// Derivative at the current state (first-same-as-last stage).
    pub fn dy(&self) -> &[f64] {
        &self.k[0]
    }

    /// Steps taken (accepted and rejected) since [`Dopri5::start`].
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Rejected steps since [`Dopri5::start`].
    pub fn rejected(&self) -> usize {
        self.rejected
    }

    /// Starts an integration at (t0, y0). `direction_hint` is the time span expected (used for the
    /// initial step guess).
    pub fn start<F>(&mut self, rhs: &mut F, t0: f64, y0: &[f64], span: f64) -> Result<(), OdeFailure>
    where
        F: FnMut(f64, &[f64], &mut [f64]) -> bool,
    {
        debug_assert_eq!(y0.len(), self.dim);
        self.t = t0;
        self.t_old = t0;
        self.y.copy_from_slice(y0);
        self.steps = 0;
        self.rejected = 0;
        self.last_rejected = false;
        self.err_old = 1e-4;
        if !rhs(t0, &self.y, &mut self.k[0]) {
            return Err(OdeFailure::RhsFailed { t: t0 });
        }
        self.h = self.initial_step(rhs, span)?;
        Ok(())
    }

    /// Hairer's starting step: a step whose explicit Euler error would be about the tolerance.
    fn initial_step<F>(&mut self, rhs: &mut F, span: f64) -> Result<f64, OdeFailure>
    where
        F: FnMut(f64, &[f64], &mut [f64]) -> bool,
    {
        let s = &self.settings;
        let sc = |y: f64| s.atol + s.rtol * y.abs();
        let rms = |v: &[f64], y: &[f64]| {
            (v.iter().zip(y).map(|(a, b)| (a / sc(*b)).powi(2)).sum::<f64>() / v.len() as f64).sqrt()
        };
        let d0 = rms(&self.y, &self.y);
        let d1 = rms(&self.k[0], &self.y);
        let mut h0 = if d0 < 1e-5 || d1 < 1e-5 { 1e-6 } else { 0.01 * d0 / d1 };
        h0 = h0.min(span.abs());
        for i in 0..self.dim {
            self.y_stage[i] = self.y[i] + h0 * self.k[0][i];
        }
        if !rhs(self.t + h0, &self.y_stage, &mut self.k[1]) {
            return Err(OdeFailure::RhsFailed { t: self.t });
        }
        let d2 = self.k[1]
            .iter()
            .zip(&self.k[0])
            .zip(&self.y)
            .map(|((a, b), y)| ((a - b) / sc(*y)).powi(2))
            .sum::<f64>()
            .sqrt()
            / (self.dim as f64).sqrt()
            / h0;
        let h1 = if d1.max(d2) <= 1e-15 { (h0 * 1e-3).max(1e-6) } else { (0.01 / d1.max(d2)).powf(1.0 / 5.0) };
        let mut h = (100.0 * h0).min(h1).min(span.abs());
        if self.settings.max_step > 0.0 {
            h = h.min(self.settings.max_step);
        }
        Ok(h.max(self.settings.min_step))
    }

    /// Takes one accepted step towards `t_end` (never past it) and prepares dense output on
    /// [t_old, t]. Returns `Ok(true)` once `t_end` is reached.
    pub fn step<F>(&mut self, rhs: &mut F, t_end: f64) -> Result<bool, OdeFailure>
    where
        F: FnMut(f64, &[f64], &mut [f64]) -> bool,
    {
        let n = self.dim;
        loop {
            if self.steps >= self.settings.max_steps {
                return Err(OdeFailure::TooManySteps { t: self.t });
            }
            let remaining = t_end - self.t;
            let mut h = self.h.min(remaining);
            if self.settings.max_step > 0.0 {
                h = h.min(self.settings.max_step);
            }
            // Avoid a sliver of a last step.
            let last = h >= remaining * (1.0 - 1e-12) || remaining - h < self.settings.min_step;
            if last {
                h = remaining;
            }
            if h < self.settings.min_step && !last {
                return Err(OdeFailure::StepSizeUnderflow { t: self.t });
            }
            self.steps += 1;
            let t = self.t;
            let y = &self.y;
            let [k1, k2, k3, k4, k5, k6, k7] = &mut self.k;
            let ys = &mut self.y_stage;
            for i in 0..n {
                ys[i] = y[i] + h * A21 * k1[i];
            }
            if !rhs(t + C2 * h, ys, k2) {
                return Err(OdeFailure::RhsFailed { t });
            }
            for i in 0..n {
                ys[i] = y[i] + h * (A31 * k1[i] + A32 * k2[i]);
            }
            if !rhs(t + C3 * h, ys, k3) {
                return Err(OdeFailure::RhsFailed { t });
            }
            for i in 0..n {
                ys[i] = y[i] + h * (A41 * k1[i] + A42 * k2[i] + A43 * k3[i]);
            }
            if !rhs(t + C4 * h, ys, k4) {
                return Err(OdeFailure::RhsFailed { t });
            }
            for i in 0..n {
                ys[i] = y[i] + h * (A51 * k1[i] + A52 * k2[i] + A53 * k3[i] + A54 * k4[i]);
            }
            if !rhs(t + C5 * h, ys, k5) {
                return Err(OdeFailure::RhsFailed { t });
            }
            for i in 0..n {
                ys[i] = y[i] + h * (A61 * k1[i] + A62 * k2[i] + A63 * k3[i] + A64 * k4[i] + A65 * k5[i]);
            }
            if !rhs(t + h, ys, k6) {
                return Err(OdeFailure::RhsFailed { t });
            }
            let yn = &mut self.y_new;
            for i in 0..n {
                yn[i] = y[i] + h * (A71 * k1[i] + A73 * k3[i] + A74 * k4[i] + A75 * k5[i] + A76 * k6[i]);
            }
            if !rhs(t + h, yn, k7) {
                return Err(OdeFailure::RhsFailed { t });
            }
            let mut err = 0.0;
            let ne = self.error_dim;
            for i in 0..ne {
                let e = h * (E1 * k1[i] + E3 * k3[i] + E4 * k4[i] + E5 * k5[i] + E6 * k6[i] + E7 * k7[i]);
                let sc = self.settings.atol + self.settings.rtol * y[i].abs().max(yn[i].abs());
                err += (e / sc) * (e / sc);
            }
            let err = (err / ne as f64).sqrt();
            if !err.is_finite() {
                // A blown-up stage: retry with a much smaller step.
                self.rejected += 1;
                self.h = h * 0.1;
                if self.h < self.settings.min_step {
                    return Err(OdeFailure::NonFinite { t });
                }
                continue;
            }
            // PI controller (Gustafsson), as in Hairer's DOPRI5: β = 0.04.
            const SAFETY: f64 = 0.9;
            let fac = if err == 0.0 {
                10.0
            } else {
                (SAFETY * err.powf(-0.2 + 0.04 * 0.75) * self.err_old.powf(0.04)).clamp(0.2, 10.0)
            };
            if err <= 1.0 {
                // Dense output coefficients.
                for i in 0..n {
                    let ydiff = yn[i] - y[i];
                    let bspl = h * k1[i] - ydiff;
                    self.cont[0][i] = y[i];
                    self.cont[1][i] = ydiff;
                    self.cont[2][i] = bspl;
                    self.cont[3][i] = ydiff - h * k7[i] - bspl;
                    self.cont[4][i] = h * (D1 * k1[i] + D3 * k3[i] + D4 * k4[i] + D5 * k5[i] + D6 * k6[i] + D7 * k7[i]);
                }
                self.err_old = err.max(1e-4);
                self.t_old = t;
                self.t = if last { t_end } else { t + h };
                std::mem::swap(&mut self.y, &mut self.y_new);
                self.k.swap(0, 6);
                self.h = h * if self.last_rejected { fac.min(1.0) } else { fac };
                self.last_rejected = false;
                if self.y.iter().any(|v| !v.is_finite()) {
                    return Err(OdeFailure::NonFinite { t: self.t });
                }
                return Ok(last);
            }
            self.rejected += 1;
            self.last_rejected = true;
            self.h = h * fac.min(1.0);
            if self.h < self.settings.min_step {
                return Err(OdeFailure::StepSizeUnderflow { t });
            }
        }
    }

    /// Dense output: the state at time `t` within the last accepted step [t_old, t].
    pub fn dense(&self, t: f64, out: &mut [f64]) {
        let h = self.t - self.t_old;
        let theta = if h == 0.0 { 1.0 } else { (t - self.t_old) / h };
        let theta1 = 1.0 - theta;
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.cont[0][i]
                + theta
                    * (self.cont[1][i]
                        + theta1 * (self.cont[2][i] + theta * (self.cont[3][i] + theta1 * self.cont[4][i])));
        }
    }

    /// Dense output of one component.
    pub fn dense_component(&self, t: f64, i: usize) -> f64 {
        let h = self.t - self.t_old;
        let theta = if h == 0.0 { 1.0 } else { (t - self.t_old) / h };
        let theta1 = 1.0 - theta;
        self.cont[0][i]
            + theta
                * (self.cont[1][i] + theta1 * (self.cont[2][i] + theta * (self.cont[3][i] + theta1 * self.cont[4][i])))
    }
}

/// Finds a root of `f` in [a, b] given f(a) and f(b) of opposite signs (Illinois-modified regula
/// falsi, robust and fast for the smooth event functions used here). Returns the bracket end on
/// the side where f(a) has its sign closest to the root within `tol`.
pub fn find_root<F: FnMut(f64) -> f64>(mut f: F, mut a: f64, mut b: f64, mut fa: f64, mut fb: f64, tol: f64) -> f64 {
    if fa == 0.0 {
        return a;
    }
    if fb == 0.0 {
        return b;
    }
    let mut side = 0i8;
    for _ in 0..200 {
        if (b - a).abs() <= tol {
            break;
        }
        let c = (a * fb - b * fa) / (fb - fa);
        let c = if c.is_finite() && c > a.min(b) && c < a.max(b) { c } else { 0.5 * (a + b) };
        let fc = f(c);
        if fc == 0.0 {
            return c;
        }
        if (fc > 0.0) == (fb > 0.0) {
            b = c;
            fb = fc;
            if side == -1 {
                fa *= 0.5;
            }
            side = -1;
        } else {
            a = c;
            fa = fc;
            if side == 1 {
                fb *= 0.5;
            }
            side = 1;
        }
    }
    // Report the point on f(a)'s side (the inside of the region for event functions).
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    fn integrate<F: FnMut(f64, &[f64], &mut [f64]) -> bool>(
        mut f: F,
        y0: &[f64],
        t_end: f64,
        s: OdeSettings,
    ) -> (Vec<f64>, usize) {
        let mut ode = Dopri5::new(y0.len(), s);
        ode.start(&mut f, 0.0, y0, t_end).unwrap();
        while !ode.step(&mut f, t_end).unwrap() {}
        (ode.y().to_vec(), ode.steps())
    }

    #[test]
    fn harmonic_oscillator_to_tolerance() {
        let s = OdeSettings { rtol: 1e-11, atol: 1e-11, ..Default::default() };
        let (y, _) = integrate(
            |_, y, dy| {
                dy[0] = y[1];
                dy[1] = -y[0];
                true
            },
            &[1.0, 0.0],
            10.0,
            s,
        );
        assert!((y[0] - 10f64.cos()).abs() < 1e-9);
        assert!((y[1] + 10f64.sin()).abs() < 1e-9);
    }

    #[test]
    fn error_scales_with_tolerance_like_fifth_order() {
        // y' = -2 t y, y(0) = 1 → exp(-t²)
        let run = |tol: f64| {
            let s = OdeSettings { rtol: tol, atol: tol, ..Default::default() };
            let (y, steps) = integrate(
                |t, y, dy| {
                    dy[0] = -2.0 * t * y[0];
                    true
                },
                &[1.0],
                2.0,
                s,
            );
            ((y[0] - (-4f64).exp()).abs(), steps)
        };
        let (e1, n1) = run(1e-6);
        let (e2, n2) = run(1e-10);
        assert!(e1 < 1e-5 && e2 < 1e-9, "{e1} {e2}");
        // Steps grow like tol^(-1/5): 10⁴ tighter → ≈ 6.3× more steps.
        let ratio = n2 as f64 / n1 as f64;
        assert!(ratio > 3.0 && ratio < 12.0, "step ratio {ratio}");
    }

    #[test]
    fn dense_output_is_accurate_inside_steps() {
        let s = OdeSettings { rtol: 1e-10, atol: 1e-10, ..Default::default() };
        let mut f = |_: f64, y: &[f64], dy: &mut [f64]| {
            dy[0] = y[1];
            dy[1] = -y[0];
            true
        };
        let mut ode = Dopri5::new(2, s);
        ode.start(&mut f, 0.0, &[0.0, 1.0], 5.0).unwrap();
        let mut worst: f64 = 0.0;
        let mut out = [0.0; 2];
        loop {
            let done = ode.step(&mut f, 5.0).unwrap();
            for j in 1..10 {
                let t = ode.t_old() + (ode.t() - ode.t_old()) * j as f64 / 10.0;
                ode.dense(t, &mut out);
                worst = worst.max((out[0] - t.sin()).abs()).max((out[1] - t.cos()).abs());
                assert_eq!(ode.dense_component(t, 0), out[0]);
            }
            if done {
                break;
            }
        }
        assert!(worst < 1e-8, "dense error {worst}");
    }

    #[test]
    fn reports_failing_rhs_and_underflow() {
        let s = OdeSettings::default();
        let mut ode = Dopri5::new(1, s);
        let mut f = |t: f64, _: &[f64], dy: &mut [f64]| {
            dy[0] = 1.0;
            t < 0.5
        };
        ode.start(&mut f, 0.0, &[0.0], 1.0).unwrap();
        let mut res = Ok(false);
        while let Ok(false) = res {
            res = ode.step(&mut f, 1.0);
        }
        assert!(matches!(res, Err(OdeFailure::RhsFailed { .. })));
        // Finite-time blow-up y' = y², y(0) = 1 at t = 1.
        let mut g = |_: f64, y: &[f64], dy: &mut [f64]| {
            dy[0] = y[0] * y[0];
            true
        };
        let mut ode = Dopri5::new(1, s);
        ode.start(&mut g, 0.0, &[1.0], 2.0).unwrap();
        let mut res = Ok(false);
        while let Ok(false) = res {
            res = ode.step(&mut g, 2.0);
        }
        assert!(res.is_err(), "{res:?}");
    }

    #[test]
    fn root_finder() {
        let r = find_root(|x| x * x - 2.0, 0.0, 2.0, -2.0, 2.0, 1e-14);
        assert!((r - 2f64.sqrt()).abs() < 1e-13);
    }
}
