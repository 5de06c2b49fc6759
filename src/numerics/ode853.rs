//! Dormand–Prince 8(5,3): an eighth-order embedded Runge–Kutta method for point-to-point
//! integrations at tight tolerances.
//!
//! The log map integrates a geodesic with its Jacobi fields from q_eq to one point, several times
//! per Newton solve, at rtol = atol = 1e-10. At that tolerance the eighth-order method takes
//! roughly a fifth of the steps of Dormand–Prince 5(4) and about half its right-hand-side
//! evaluations. No dense output is needed there, so this integrator has none (the fans, which
//! sample and locate events, use [`crate::numerics::ode::Dopri5`]). Coefficients: Hairer, Nørsett & Wanner,
//! *Solving ODEs I*, §II.10 (as tabulated in the Fortran DOP853 and in SciPy); error estimate
//! with the combined fifth- and third-order embedded formulas of the same reference.

// The tableau is kept with the published digits so it can be checked against the reference.
#![allow(clippy::excessive_precision)]

use crate::numerics::ode::{OdeFailure, OdeSettings};

const S: usize = 12;

const C: [f64; S] = [
    0.0,
    0.526001519587677318785587544488e-01,
    0.789002279381515978178381316732e-01,
    0.118350341907227396726757197510,
    0.281649658092772603273242802490,
    0.333333333333333333333333333333,
    0.25,
    0.307692307692307692307692307692,
    0.651282051282051282051282051282,
    0.6,
    0.857142857142857142857142857142,
    1.0,
];

/// Stage coefficients a[i][j], j < i (rows 0…11) and the eighth-order weights (row 12).
const A: [[f64; S]; S + 1] = {
    let mut a = [[0.0; S]; S + 1];
    a[1][0] = 5.26001519587677318785587544488e-2;
    a[2][0] = 1.97250569845378994544595329183e-2;
    a[2][1] = 5.91751709536136983633785987549e-2;
    a[3][0] = 2.95875854768068491816892993775e-2;
    a[3][2] = 8.87627564304205475450678981324e-2;
    a[4][0] = 2.41365134159266685502369798665e-1;
    a[4][2] = -8.84549479328286085344864962717e-1;
    a[4][3] = 9.24834003261792003115737966543e-1;
    a[5][0] = 3.7037037037037037037037037037e-2;
    a[5][3] = 1.70828608729473871279604482173e-1;
    a[5][4] = 1.25467687566822425016691814123e-1;
    a[6][0] = 3.7109375e-2;
    a[6][3] = 1.70252211019544039314978060272e-1;
    a[6][4] = 6.02165389804559606850219397283e-2;
    a[6][5] = -1.7578125e-2;
    a[7][0] = 3.70920001185047927108779319836e-2;
    a[7][3] = 1.70383925712239993810214054705e-1;
    a[7][4] = 1.07262030446373284651809199168e-1;
    a[7][5] = -1.53194377486244017527936158236e-2;
    a[7][6] = 8.27378916381402288758473766002e-3;
    a[8][0] = 6.24110958716075717114429577812e-1;
    a[8][3] = -3.36089262944694129406857109825;
    a[8][4] = -8.68219346841726006818189891453e-1;
    a[8][5] = 2.75920996994467083049415600797e1;
    a[8][6] = 2.01540675504778934086186788979e1;
    a[8][7] = -4.34898841810699588477366255144e1;
    a[9][0] = 4.77662536438264365890433908527e-1;
    a[9][3] = -2.48811461997166764192642586468;
    a[9][4] = -5.90290826836842996371446475743e-1;
    a[9][5] = 2.12300514481811942347288949897e1;
    a[9][6] = 1.52792336328824235832596922938e1;
    a[9][7] = -3.32882109689848629194453265587e1;
    a[9][8] = -2.03312017085086261358222928593e-2;
    a[10][0] = -9.3714243008598732571704021658e-1;
    a[10][3] = 5.18637242884406370830023853209;
    a[10][4] = 1.09143734899672957818500254654;
    a[10][5] = -8.14978701074692612513997267357;
    a[10][6] = -1.85200656599969598641566180701e1;
    a[10][7] = 2.27394870993505042818970056734e1;
    a[10][8] = 2.49360555267965238987089396762;
    a[10][9] = -3.0467644718982195003823669022;
    a[11][0] = 2.27331014751653820792359768449;
    a[11][3] = -1.05344954667372501984066689879e1;
    a[11][4] = -2.00087205822486249909675718444;
    a[11][5] = -1.79589318631187989172765950534e1;
    a[11][6] = 2.79488845294199600508499808837e1;
    a[11][7] = -2.85899827713502369474065508674;
    a[11][8] = -8.87285693353062954433549289258;
    a[11][9] = 1.23605671757943030647266201528e1;
    a[11][10] = 6.43392746015763530355970484046e-1;
    a[12][0] = 5.42937341165687622380535766363e-2;
    a[12][5] = 4.45031289275240888144113950566;
    a[12][6] = 1.89151789931450038304281599044;
    a[12][7] = -5.8012039600105847814672114227;
    a[12][8] = 3.1116436695781989440891606237e-1;
    a[12][9] = -1.52160949662516078556178806805e-1;
    a[12][10] = 2.01365400804030348374776537501e-1;
    a[12][11] = 4.47106157277725905176885569043e-2;
    a
};

/// Fifth-order error weights over the 12 stages and the final derivative.
const E5: [f64; S + 1] = [
    0.1312004499419488073250102996e-1,
    0.0,
    0.0,
    0.0,
    0.0,
    -0.1225156446376204440720569753e1,
    -0.4957589496572501915214079952,
    0.1664377182454986536961530415e1,
    -0.3503288487499736816886487290,
    0.3341791187130174790297318841,
    0.8192320648511571246570742613e-1,
    -0.2235530786388629525884427845e-1,
    0.0,
];

/// Third-order error weights: b minus the third-order embedded weights (bhh).
const E3: [f64; S + 1] = {
    let mut e = [0.0; S + 1];
    let mut i = 0;
    while i < S {
        e[i] = A[S][i];
        i += 1;
    }
    e[0] -= 0.244094488188976377952755905512;
    e[8] -= 0.733846688281611857341361741547;
    e[11] -= 0.220588235294117647058823529412e-1;
    e
};

/// A DOP853 integrator without dense output, reusable across integrations of one dimension.
#[derive(Debug, Clone)]
pub struct Dop853 {
    settings: OdeSettings,
    dim: usize,
    error_dim: usize,
    k: Vec<Vec<f64>>,
    y: Vec<f64>,
    y_stage: Vec<f64>,
    y_new: Vec<f64>,
    steps: usize,
}

impl Dop853 {
    /// An integrator for systems of dimension `dim`.
    pub fn new(dim: usize, settings: OdeSettings) -> Self {
        Dop853 {
            settings,
            dim,
            error_dim: dim,
            k: vec![vec![0.0; dim]; S + 1],
            y: vec![0.0; dim],
            y_stage: vec![0.0; dim],
            y_new: vec![0.0; dim],
            steps: 0,
        }
    }

    /// Restricts step-size control to the first `k` components (see
    /// [`crate::numerics::ode::Dopri5::with_error_components`]).
    pub fn with_error_components(mut self, k: usize) -> Self {
        self.error_dim = k.clamp(1, self.dim);
        self
    }

    /// Changes the largest step (0: no limit).
    pub fn set_max_step(&mut self, h: f64) {
        self.settings.max_step = h;
    }

    /// Steps (accepted and rejected) of the last integration.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// The state at the end of the last integration.
    pub fn y(&self) -> &[f64] {
        &self.y
    }

    /// Integrates from (0, y0) to `t_end` > 0.
    pub fn integrate<F>(&mut self, rhs: &mut F, y0: &[f64], t_end: f64) -> Result<(), OdeFailure>
    where
        F: FnMut(f64, &[f64], &mut [f64]) -> bool,
    {
        let n = self.dim;
        self.y.copy_from_slice(y0);
        self.steps = 0;
        let mut t = 0.0;
        if !rhs(t, &self.y, &mut self.k[0]) {
            return Err(OdeFailure::RhsFailed { t });
        }
        let st = self.settings;
        let ne = self.error_dim;
        let sc = |y: f64, yn: f64| st.atol + st.rtol * y.abs().max(yn.abs());
        // Initial step from the derivative's size (Hairer's heuristic, simplified).
        let d0 = (self.y[..ne].iter().map(|v| (v / sc(*v, *v)).powi(2)).sum::<f64>() / ne as f64).sqrt();
        let d1 = (self.k[0][..ne].iter().zip(&self.y).map(|(f, v)| (f / sc(*v, *v)).powi(2)).sum::<f64>() / ne as f64)
            .sqrt();
        let mut h = if d0 < 1e-5 || d1 < 1e-5 { 1e-6 } else { 0.01 * d0 / d1 };
        h = (h * 100.0).min(t_end);
        if st.max_step > 0.0 {
            h = h.min(st.max_step);
        }
        let mut last_rejected = false;
        loop {
            if self.steps >= st.max_steps {
                return Err(OdeFailure::TooManySteps { t });
            }
            let remaining = t_end - t;
            let last = h >= remaining * (1.0 - 1e-12);
            if last {
                h = remaining;
            }
            if h < st.min_step && !last {
                return Err(OdeFailure::StepSizeUnderflow { t });
            }
            self.steps += 1;
            for s in 1..S {
                for i in 0..n {
                    let mut acc = 0.0;
                    for (j, kj) in self.k.iter().enumerate().take(s) {
                        acc += A[s][j] * kj[i];
                    }
                    self.y_stage[i] = self.y[i] + h * acc;
                }
                let (head, tail) = self.k.split_at_mut(s);
                let _ = head;
                if !rhs(t + C[s] * h, &self.y_stage, &mut tail[0]) {
                    return Err(OdeFailure::RhsFailed { t });
                }
            }
            for i in 0..n {
                let mut acc = 0.0;
                for (j, kj) in self.k.iter().enumerate().take(S) {
                    acc += A[S][j] * kj[i];
                }
                self.y_new[i] = self.y[i] + h * acc;
            }
            if !rhs(t + h, &self.y_new, &mut self.k[S]) {
                return Err(OdeFailure::RhsFailed { t });
            }
            let (mut err5, mut err3) = (0.0, 0.0);
            for i in 0..ne {
                let s = sc(self.y[i], self.y_new[i]);
                let (mut e5, mut e3) = (0.0, 0.0);
                for j in 0..=S {
                    e5 += E5[j] * self.k[j][i];
                    e3 += E3[j] * self.k[j][i];
                }
                err5 += (e5 / s).powi(2);
                err3 += (e3 / s).powi(2);
            }
            let err =
                if err5 == 0.0 && err3 == 0.0 { 0.0 } else { h * err5 / ((err5 + 0.01 * err3) * ne as f64).sqrt() };
            if !err.is_finite() {
                h *= 0.1;
                last_rejected = true;
                continue;
            }
            let fac = if err == 0.0 { 10.0 } else { (0.9 * err.powf(-1.0 / 8.0)).clamp(0.2, 10.0) };
            if err <= 1.0 {
                t = if last { t_end } else { t + h };
                std::mem::swap(&mut self.y, &mut self.y_new);
                self.k.swap(0, S);
                if last {
                    if self.y.iter().any(|v| !v.is_finite()) {
                        return Err(OdeFailure::NonFinite { t });
                    }
                    return Ok(());
                }
                h *= if last_rejected { fac.min(1.0) } else { fac };
                if st.max_step > 0.0 {
                    h = h.min(st.max_step);
                }
                last_rejected = false;
            } else {
                h *= fac.min(1.0);
                last_rejected = true;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eighth_order_accuracy_and_efficiency() {
        // y' = -2ty → exp(-t²).
        let run = |tol: f64| {
            let mut f = |t: f64, y: &[f64], dy: &mut [f64]| {
                dy[0] = -2.0 * t * y[0];
                true
            };
            let mut ode = Dop853::new(1, OdeSettings { rtol: tol, atol: tol, ..Default::default() });
            ode.integrate(&mut f, &[1.0], 2.0).unwrap();
            ((ode.y()[0] - (-4f64).exp()).abs(), ode.steps())
        };
        let (e1, n1) = run(1e-6);
        let (e2, n2) = run(1e-12);
        assert!(e1 < 1e-5 && e2 < 1e-11, "{e1} {e2}");
        // Steps grow like tol^(-1/8): 10⁶ tighter → ≈ 5.6× more steps.
        let ratio = n2 as f64 / n1 as f64;
        assert!(ratio > 2.5 && ratio < 10.0, "step ratio {ratio} ({n1} → {n2})");
    }

    #[test]
    fn harmonic_oscillator() {
        let mut f = |_: f64, y: &[f64], dy: &mut [f64]| {
            dy[0] = y[1];
            dy[1] = -y[0];
            true
        };
        let mut ode = Dop853::new(2, OdeSettings { rtol: 1e-12, atol: 1e-12, ..Default::default() });
        ode.integrate(&mut f, &[1.0, 0.0], 20.0).unwrap();
        assert!((ode.y()[0] - 20f64.cos()).abs() < 1e-9 && (ode.y()[1] + 20f64.sin()).abs() < 1e-9);
    }
}
