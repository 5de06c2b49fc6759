//! Scenarios in motion: a scenario of the design file resolved into runs (start points on a
//! mode at an energy, the controllers' schedules), run in closed loop, and the metrics of each
//! run (geodesic deviation, label drift, settling, energy error, fluxes, actuator share).

use crate::design::scenario::{EnergySpec, EnergyTarget, ModeSpec, ScenarioKind, ScenarioSpec};
use nalgebra::DVector;
use serde::Serialize;

use crate::design::Design;
use crate::design::controllers::{ControllerSettings, EnergyLaw};
use crate::dynamics::simulate::{EnergyControl, ModeControl, ModeTarget, RunResult, RunSpec};
use crate::error::{Error, Result};
use crate::geodesic::logmap::wrap_angle;
use crate::geodesic::{MetricFrame, Shooter, Stop};

/// A scenario resolved into runs.
#[derive(Debug, Clone)]
pub struct Scenario {
    /// Name.
    pub name: String,
    /// Kind.
    pub kind: ScenarioKind,
    /// Its runs.
    pub runs: Vec<RunSpec>,
    /// How the scenario handles energy, in words (stated in the outputs).
    pub energy_handling: String,
    /// The releases the springs cannot reach inside the region (an energy the potential never
    /// rises to along its mode), each as its error's message: the limit depends on the springs,
    /// so the other runs go on and the command reports these as not met.
    pub unreached: Vec<String>,
}

/// The words of [`start_on_mode`]'s error for an energy the potential does not reach inside the
/// region: the jobs tell it (not met: it depends on the springs) from bad input by them.
pub const OUT_OF_REACH: &str = "is out of reach";

/// The metrics of one run (`sim_<name>.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunMetrics {
    /// Largest |label − label at start| outside the ε-ball, degrees (free runs). For two joints
    /// the label θ is unwrapped over the run first, so this is the label's *cumulative* drift: a
    /// motion that leaves its mode and turns round the equilibrium shows as such (past 360°).
    pub mode_drift_deg: Option<f64>,
    /// The same with every difference wrapped to (−180°, 180°]: how far the label ever is from
    /// the start's, whatever the turns (three or more joints: equal to `mode_drift_deg`).
    pub mode_drift_wrapped_deg: Option<f64>,
    /// How far q(t) leaves the geodesic of its start's mode (free runs): the headline figure.
    pub geodesic_deviation: Option<GeodesicDeviation>,
    /// Seconds from each mode step until |Δθ| < 3° for the rest of the step (None: never).
    pub settling_s: Vec<Option<f64>>,
    /// |mean E over the last 5 s − E_d| / E_d (runs with energy regulation).
    pub energy_rel_error_last5s: Option<f64>,
    /// (mean E over the last 5 s − E_d) / E_d: negative for a deficit.
    pub energy_signed_error_last5s: Option<f64>,
    /// Largest |E − E(0)| / |E(0)| (free runs).
    pub energy_drift_rel: Option<f64>,
    /// ∫|P| per source, J.
    pub flux: FluxSummary,
    /// (∫|P_θ| + ∫|P_E|) / ∫|P_U| over the whole run (the definition in `docs/theory.md`).
    pub actuator_share: f64,
    /// The same over the last 5 s (the steady state after a swing-up or a mode switch).
    pub actuator_share_last5s: f64,
    /// (∫|P_θ| + ∫|P_E| + ∫|P_comp|) / ∫|P_U|: with the damping compensation, which actuators
    /// deliver too (whole run).
    pub actuator_share_with_compensation: f64,
    /// Largest |τᵢ| per source, N·m.
    pub peak_torque_nm: PeakTorques,
    /// Largest |τ_θ,ᵢ + τ_E,ᵢ + τ_comp,ᵢ| over joints and time: what an actuator delivers, N·m.
    pub peak_actuator_torque_nm: f64,
    /// The same as the laws asked it before `[controllers] max_torque` saturated them, N·m
    /// (equal to the delivered peak without a limit).
    pub peak_demanded_torque_nm: f64,
    /// Seconds the controllers spent saturated by `max_torque` (0 without a limit).
    pub saturated_s: f64,
    /// What the springs save: the same trajectory driven by the actuators alone.
    pub savings: Savings,
}

/// The load on the actuators along one trajectory (see [`Savings`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct ActuatorLoad {
    /// ∫|τᵀq̇| dt, J: the mechanical energy through the actuators.
    pub energy_j: f64,
    /// Largest |τᵢ| over joints and samples, N·m.
    pub peak_torque_nm: f64,
    /// √(∫ Σᵢ τᵢ² dt / (n T)): the root mean square over joints and time, N·m.
    pub rms_torque_nm: f64,
    /// ∫ Σᵢ τᵢ²/k_m,ᵢ² dt, J: the copper losses (k_m from `[controllers] motor_constant`).
    pub copper_loss_j: f64,
}

/// What the springs save on a closed-loop run: the actuators' load with the springs
/// (τ_act = τ_θ + τ_E + τ_comp) against the load of the same motion q(t) on the arm without
/// springs, where the actuators must also supply what the springs gave, τ_rigid = τ_act + τ_spring
/// (τ_spring = −∂U_e/∂q, the `tau_spring` columns). Integrals are sums over the output samples
/// (left rectangles, as `sim_<name>.csv` holds them, so a hand computation from the CSV matches);
/// the fractions saved are 1 − with/without.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct Savings {
    /// The actuators with the springs.
    pub with_springs: ActuatorLoad,
    /// The actuators alone on the arm without springs, same motion.
    pub without_springs: ActuatorLoad,
    /// 1 − energy with / energy without.
    pub energy_saved: f64,
    /// 1 − peak with / peak without.
    pub peak_torque_saved: f64,
    /// 1 − RMS with / RMS without.
    pub rms_torque_saved: f64,
    /// 1 − copper losses with / without.
    pub copper_loss_saved: f64,
}

impl Savings {
    /// The columns of [`Savings::md_cells`], for a Markdown table's header (`sweep`'s
    /// `tolerance.md`, `compare.md`).
    pub const MD_HEADER: &'static str = "energy with / without (J) | saved | peak torque with / without (N·m) | saved | RMS torque saved | copper losses saved";

    /// The cells of one row of a savings table, `|`-separated (without the outer bars).
    pub fn md_cells(&self) -> String {
        let pct = |x: f64| if x.is_finite() { format!("{:.1} %", 100.0 * x) } else { "–".into() };
        format!(
            "{:.3} / {:.3} | {} | {:.2} / {:.2} | {} | {} | {}",
            self.with_springs.energy_j,
            self.without_springs.energy_j,
            pct(self.energy_saved),
            self.with_springs.peak_torque_nm,
            self.without_springs.peak_torque_nm,
            pct(self.peak_torque_saved),
            pct(self.rms_torque_saved),
            pct(self.copper_loss_saved)
        )
    }

    /// The savings of a run from its samples; `motor_constant` k_m per joint (N·m/√W).
    pub fn of(trace: &crate::dynamics::simulate::Trace, motor_constant: &[f64]) -> Savings {
        let n = trace.n;
        let w = crate::dynamics::simulate::SOURCES.len() * n;
        // Sources: 0 spring, 3 mode, 4 energy, 5 compensation.
        let actuator = |k: usize, i: usize| {
            let tau = &trace.tau[k * w..(k + 1) * w];
            tau[3 * n + i] + tau[4 * n + i] + tau[5 * n + i]
        };
        let spring = |k: usize, i: usize| trace.tau[k * w + i];
        let load = |with_springs: bool| {
            let torque = |k: usize, i: usize| actuator(k, i) + if with_springs { 0.0 } else { spring(k, i) };
            let (mut energy, mut peak, mut square, mut copper) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
            let samples = trace.t.len();
            for k in 0..samples {
                for i in 0..n {
                    peak = peak.max(torque(k, i).abs());
                }
                if k + 1 == samples {
                    break;
                }
                let dt = trace.t[k + 1] - trace.t[k];
                let power: f64 = (0..n).map(|i| torque(k, i) * trace.qd[k * n + i]).sum();
                energy += power.abs() * dt;
                square += (0..n).map(|i| torque(k, i).powi(2)).sum::<f64>() * dt;
                copper += (0..n).map(|i| (torque(k, i) / motor_constant[i]).powi(2)).sum::<f64>() * dt;
            }
            let span = trace.t.last().copied().unwrap_or(0.0) - trace.t.first().copied().unwrap_or(0.0);
            let rms = if span > 0.0 { (square / (n as f64 * span)).sqrt() } else { 0.0 };
            ActuatorLoad { energy_j: energy, peak_torque_nm: peak, rms_torque_nm: rms, copper_loss_j: copper }
        };
        let (with, without) = (load(true), load(false));
        let saved = |a: f64, b: f64| if b > 0.0 { 1.0 - a / b } else { 0.0 };
        Savings {
            with_springs: with,
            without_springs: without,
            energy_saved: saved(with.energy_j, without.energy_j),
            peak_torque_saved: saved(with.peak_torque_nm, without.peak_torque_nm),
            rms_torque_saved: saved(with.rms_torque_nm, without.rms_torque_nm),
            copper_loss_saved: saved(with.copper_loss_j, without.copper_loss_j),
        }
    }
}

/// The deviation of a free motion from the geodesic of its start's mode.
///
/// The mode through the start q₀ is the geodesic γ(s) = exp(s·u), u = log(q₀)/r₀, r₀ the metric
/// distance of q₀ from q_eq; a perfect potential keeps q(t) on it for ever. γ is traced both ways
/// to 1.5 r₀ every r₀/1000; the distance of a sample q to γ is the smallest √(ΔqᵀM(γ_k)Δq) over
/// the chords of the traced polyline (the local metric distance, exact to O(|Δq|² + spacing²)).
/// Units: √(kg·m²)·rad, the metric arc length of the region's radius.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GeodesicDeviation {
    /// r₀: metric distance of the start from q_eq, √(kg·m²)·rad.
    pub start_radius: f64,
    /// Largest distance from q(t) to the geodesic over the run, √(kg·m²)·rad.
    pub max: f64,
    /// `max` / r₀ (dimensionless: about the angle in rad between the motion and the mode at the
    /// swing's amplitude).
    pub max_rel: f64,
    /// Largest distance per swing, √(kg·m²)·rad; a swing runs from one passage of q_eq's side to
    /// the next (a sign change of the position along γ), so two swings make a period.
    pub per_swing: Vec<f64>,
}

/// Fluxes in the JSON.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FluxSummary {
    /// ∫|τᵀq̇| dt of the elastic potential (springs and parasitic springs) over the run, J.
    pub potential: f64,
    /// ∫|τ_θᵀq̇| dt of the mode selection, J.
    pub mode: f64,
    /// ∫|τ_Eᵀq̇| dt of the energy regulation, J.
    pub energy: f64,
    /// ∫|τᵀq̇| dt of the joint damping −D q̇, J.
    pub damping: f64,
    /// ∫|τᵀq̇| dt of the damping compensation +D q̇, J.
    pub compensation: f64,
    /// ∫|τᵀq̇| dt of gravity, J.
    pub gravity: f64,
}

/// Peak torques in the JSON.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PeakTorques {
    /// Largest |τᵢ| of the elastic potential over joints and the run (every integrator stage), N·m.
    pub spring: f64,
    /// Largest |τᵢ| of gravity, N·m.
    pub gravity: f64,
    /// Largest |τᵢ| of the joint damping, N·m.
    pub damping: f64,
    /// Largest |τᵢ| of the mode selection τ_θ, N·m.
    pub mode: f64,
    /// Largest |τᵢ| of the energy regulation τ_E, N·m.
    pub energy: f64,
    /// Largest |τᵢ| of the damping compensation, N·m.
    pub compensation: f64,
}

impl ScenarioSpec {
    /// Resolves the scenario into runs for `design`; errors name `scenario[index].field`.
    pub fn resolve(
        &self,
        index: usize,
        design: &Design,
        energy_at: &mut dyn FnMut(&[f64]) -> Result<f64>,
    ) -> Result<Scenario> {
        self.check(index, design)?;
        let base = RunBase {
            design,
            index,
            duration: self.duration_s(),
            damping: self.damping.unwrap_or(if self.kind == ScenarioKind::Swingup { 0.3 } else { 0.0 }),
            frame: MetricFrame::new(&design.chain.mass_matrix(&design.q_eq))?,
        };
        let mut unreached = Vec::new();
        let runs = match self.kind {
            ScenarioKind::Free => self.free_runs(&base, energy_at, &mut unreached)?,
            ScenarioKind::Switch => vec![self.switch_run(&base, energy_at)?],
            ScenarioKind::Swingup => self.swingup_runs(&base, energy_at)?,
        };
        Ok(Scenario {
            name: self.name.clone(),
            kind: self.kind,
            runs,
            energy_handling: self.energy_handling(),
            unreached,
        })
    }

    /// A free scenario's runs: each start as given, then each release placed on its mode at its
    /// energy; a release the springs cannot reach goes to `unreached` and the others still run.
    fn free_runs(
        &self,
        base: &RunBase,
        energy_at: &mut dyn FnMut(&[f64]) -> Result<f64>,
        unreached: &mut Vec<String>,
    ) -> Result<Vec<RunSpec>> {
        let n = base.design.dof();
        let mut runs = Vec::new();
        for (k, s) in self.starts.iter().enumerate() {
            runs.push(base.run(format!("start_{}", k + 1), s.iter().map(|a| a.0).collect()));
        }
        for (k, r) in self.releases.iter().enumerate() {
            let u = mode_direction(&r.mode, n, &base.frame).map_err(|e| base.bad(&format!("releases[{k}].mode"), e))?;
            match start_on_mode(base.design, &u, r.energy, energy_at) {
                Ok(q0) => runs.push(base.run(format!("release_{}", k + 1), q0)),
                Err(e) if e.contains(OUT_OF_REACH) => {
                    unreached.push(base.bad(&format!("releases[{k}].energy"), e).to_string())
                }
                Err(e) => return Err(base.bad(&format!("releases[{k}].energy"), e)),
            }
        }
        Ok(runs)
    }

    /// A switch scenario's run: started on the first mode at its energy, the mode stepped by
    /// `step` (or to the next of `modes`) every `every` seconds, the start energy held unless `energy_target = "none"`.
    fn switch_run(&self, base: &RunBase, energy_at: &mut dyn FnMut(&[f64]) -> Result<f64>) -> Result<RunSpec> {
        let every = self.every.unwrap_or(15.0);
        let energy = self.energy.unwrap_or(10.0);
        let n = base.design.dof();
        let steps = ((base.duration / every).ceil() as usize).max(1);
        let (u, schedule): (DVector<f64>, Vec<(f64, ModeTarget)>) = if self.modes.is_empty() {
            // The θ form (two joints; `check` refused a direction vector as its first mode).
            let theta0 = match self.mode.clone().unwrap_or(ModeSpec::Angle(0.0)) {
                ModeSpec::Angle(a) => a,
                ModeSpec::Vector(_) => 0.0,
            };
            let step = self.step.map(|a| a.0).unwrap_or(std::f64::consts::FRAC_PI_6);
            let u = mode_direction(&ModeSpec::Angle(theta0), n, &base.frame).map_err(|e| base.bad("mode", e))?;
            let schedule = (0..steps)
                .map(|k| (k as f64 * every, ModeTarget::Angle(wrap_angle(theta0 + step * k as f64))))
                .collect();
            (u, schedule)
        } else {
            // Directions on the metric's unit sphere, cycled over the run.
            let mut targets = Vec::with_capacity(self.modes.len());
            for (k, m) in self.modes.iter().enumerate() {
                let u = mode_direction(m, n, &base.frame).map_err(|e| base.bad(&format!("modes[{k}]"), e))?;
                targets.push((base.frame.to_frame(&u).normalize(), u));
            }
            let schedule = (0..steps)
                .map(|k| (k as f64 * every, ModeTarget::Direction(targets[k % targets.len()].0.clone())))
                .collect();
            (targets[0].1.clone(), schedule)
        };
        let q0 = start_on_mode(base.design, &u, energy, energy_at).map_err(|e| base.bad("energy", e))?;
        let mut run = base.run("switch".into(), q0);
        run.mode = Some(ModeControl { schedule });
        if self.energy_target.unwrap_or_default() == EnergyTarget::Hold {
            run.energy = Some(EnergyControl {
                law: EnergyLaw::Energy,
                schedule: vec![(0.0, energy)],
                compensate_damping: false,
            });
        }
        Ok(run)
    }

    /// A swing-up scenario's runs, one per variant: started on the mode at E0, the mode held and
    /// the energy law of the variant driving towards E_d (which must be reachable inside the
    /// region along the mode).
    fn swingup_runs(&self, base: &RunBase, energy_at: &mut dyn FnMut(&[f64]) -> Result<f64>) -> Result<Vec<RunSpec>> {
        let n = base.design.dof();
        let e0 = self.e0.unwrap_or(5.0);
        let schedule: Vec<(f64, f64)> = match self.ed.clone().unwrap_or(EnergySpec::Value(20.0)) {
            EnergySpec::Value(v) => vec![(0.0, v)],
            EnergySpec::Steps(s) => s.iter().map(|p| (p[0], p[1])).collect(),
        };
        let ed = schedule.iter().map(|s| s.1).fold(0.0, f64::max);
        let mode = self.mode.clone().unwrap_or(ModeSpec::Angle(0.0));
        let u = mode_direction(&mode, n, &base.frame).map_err(|e| base.bad("mode", e))?;
        let q0 = start_on_mode(base.design, &u, e0, energy_at).map_err(|e| base.bad("e0", e))?;
        // The energy target must be reachable inside the region along this mode.
        start_on_mode(base.design, &u, ed, energy_at).map_err(|e| base.bad("ed", e))?;
        let target = match (&mode, n) {
            (ModeSpec::Angle(a), 2) => ModeTarget::Angle(*a),
            _ => ModeTarget::Direction(base.frame.to_frame(&u).normalize()),
        };
        let variants: Vec<String> = if self.variants.is_empty() {
            vec!["energy".into(), "negative_damping".into(), "energy_compensated".into()]
        } else {
            self.variants.clone()
        };
        let mut runs = Vec::new();
        for v in &variants {
            let (law, compensate) = match v.as_str() {
                "energy" => (EnergyLaw::Energy, false),
                "negative_damping" => (EnergyLaw::NegativeDamping, false),
                // "energy_compensated": `check` refused any other name.
                _ => (EnergyLaw::Energy, true),
            };
            let mut run = base.run(v.clone(), q0.clone());
            run.mode = Some(ModeControl { schedule: vec![(0.0, target.clone())] });
            run.energy = Some(EnergyControl { law, schedule: schedule.clone(), compensate_damping: compensate });
            runs.push(run);
        }
        Ok(runs)
    }

    /// How the scenario handles energy, in words.
    fn energy_handling(&self) -> String {
        match self.kind {
            ScenarioKind::Free => "none: released without control".to_string(),
            ScenarioKind::Switch => match self.energy_target.unwrap_or_default() {
                EnergyTarget::Hold => format!(
                    "energy_target = \"hold\": τ_E holds the start energy E_d = {} J",
                    self.energy.unwrap_or(10.0)
                ),
                EnergyTarget::None => "energy_target = \"none\": no energy regulation".to_string(),
            },
            ScenarioKind::Swingup => "τ_E, τ_nD or τ_E + compensation towards E_d (per variant)".to_string(),
        }
    }
}

/// What every run of a scenario being resolved shares: the design, the metric frame at q_eq,
/// the duration and the damping; and the scenario's index, which errors name.
struct RunBase<'a> {
    design: &'a Design,
    index: usize,
    frame: MetricFrame,
    duration: f64,
    damping: f64,
}

impl RunBase<'_> {
    /// A run from rest at q0 without control, parasitic springs or a build.
    fn run(&self, name: String, q0: Vec<f64>) -> RunSpec {
        let n = self.design.dof();
        RunSpec {
            name,
            q0,
            qd0: vec![0.0; n],
            duration: self.duration,
            damping: vec![self.damping; n],
            mode: None,
            energy: None,
            parasitic: None,
            stiffness_scale: None,
            built: None,
        }
    }

    /// An error on the scenario's key `f`.
    fn bad(&self, f: &str, r: String) -> Error {
        let name = self.design.scenarios.get(self.index).map_or("", |s| s.name.as_str());
        Error::invalid(&self.design.path, format!("scenario[{}].{f}", self.index), format!("(scenario `{name}`) {r}"))
    }
}

/// The metric-unit joint velocity of a mode.
pub fn mode_direction(mode: &ModeSpec, n: usize, frame: &MetricFrame) -> std::result::Result<DVector<f64>, String> {
    let v = match mode {
        ModeSpec::Angle(theta) => {
            if n != 2 {
                return Err(format!(
                    "an angle names a mode of a two-joint arm; give a direction of {n} joint velocities"
                ));
            }
            DVector::from_vec(vec![(theta / 2.0).cos(), (theta / 2.0).sin()])
        }
        ModeSpec::Vector(v) => {
            if v.len() != n {
                return Err(format!("has {} entries but the robot has {n} joints", v.len()));
            }
            if v.iter().any(|x| !x.is_finite()) || v.iter().all(|x| *x == 0.0) {
                return Err("must be a finite, non-zero direction".into());
            }
            DVector::from_column_slice(v)
        }
    };
    let len = frame.to_frame(&v).norm();
    Ok(v / len)
}

/// At rest on the geodesic with unit initial velocity `u`, the point where U − U(q_eq) = `energy`
/// (the first such point along the geodesic, inside the region's probe radius).
pub fn start_on_mode(
    design: &Design,
    u: &DVector<f64>,
    energy: f64,
    energy_at: &mut dyn FnMut(&[f64]) -> Result<f64>,
) -> std::result::Result<Vec<f64>, String> {
    if !(energy.is_finite() && energy > 0.0) {
        return Err(format!("must be a positive energy (J), got {energy}"));
    }
    let mut shooter = Shooter::new(&design.chain, &design.q_eq, design.geodesics.ode);
    let extent = design.region.radius().unwrap_or(design.geodesics.max_arc);
    let stop = Stop::Region { region: &design.region, max_arc: extent };
    let geo = shooter.trace(u, stop, extent / 400.0).map_err(|e| e.to_string())?;
    let mut prev = (0.0, 0.0);
    for i in 0..geo.len() {
        let e = energy_at(geo.q(i)).map_err(|e| e.to_string())?;
        if e >= energy {
            // Bisection on the arc length between the bracketing samples, with exp.
            let (mut a, mut b) = (prev.0, geo.s(i));
            for _ in 0..60 {
                let m = 0.5 * (a + b);
                let q = shooter.exp(&(u * m)).map_err(|e| e.to_string())?;
                if energy_at(q.as_slice()).map_err(|e| e.to_string())? >= energy {
                    b = m;
                } else {
                    a = m;
                }
            }
            return Ok(shooter.exp(&(u * b)).map_err(|e| e.to_string())?.as_slice().to_vec());
        }
        prev = (geo.s(i), e);
    }
    Err(format!(
        "the potential rises only by {:.3} J along this mode inside the region: {energy} J {OUT_OF_REACH} (raise ω or enlarge the region)",
        prev.1
    ))
}

/// Metrics of a run. `controllers` gives ε (samples inside the ε-ball are skipped for labels).
pub fn metrics(result: &RunResult, spec: &RunSpec, controllers: &ControllerSettings, kind: ScenarioKind) -> RunMetrics {
    let tr = &result.trace;
    let deg = |x: f64| x.to_degrees();
    let two = tr.n == 2;
    let label_dev = |i: usize, reference: f64| -> f64 {
        if two { wrap_angle(tr.label[i] - reference).abs() } else { tr.label[i] - reference }
    };
    let outside: Vec<usize> = (0..tr.t.len()).filter(|&i| !tr.in_ball[i] && tr.label[i].is_finite()).collect();
    let mode_drift_deg = (kind == ScenarioKind::Free).then(|| {
        if two {
            let unwrapped = unwrap_angles(&tr.label);
            let start = outside.first().map(|&i| unwrapped[i]).unwrap_or(f64::NAN);
            outside.iter().map(|&i| deg((unwrapped[i] - start).abs())).fold(0.0, f64::max)
        } else {
            outside.iter().map(|&i| deg(label_dev(i, 0.0))).fold(0.0, f64::max)
        }
    });
    let mode_drift_wrapped_deg = (kind == ScenarioKind::Free).then(|| {
        let start = outside.first().map(|&i| tr.label[i]).unwrap_or(f64::NAN);
        outside.iter().map(|&i| deg(label_dev(i, if two { start } else { 0.0 }).abs())).fold(0.0, f64::max)
    });
    let mut settling_s = Vec::new();
    if let Some(mode) = &spec.mode
        && kind == ScenarioKind::Switch
    {
        let starts: Vec<f64> = mode.schedule.iter().map(|s| s.0).collect();
        settling_s = settling_times(&tr.t, &tr.label, &tr.label_target, &tr.in_ball, &starts, spec.duration, two);
    }
    let (mut energy_rel, mut energy_signed) = (None, None);
    if let Some(ec) = &spec.energy {
        let t_end = tr.t.last().copied().unwrap_or(0.0);
        let last: Vec<f64> = tr.t.iter().zip(&tr.energy).filter(|(t, _)| **t >= t_end - 5.0).map(|(_, e)| *e).collect();
        if !last.is_empty() {
            let mean = last.iter().sum::<f64>() / last.len() as f64;
            let target = ec.final_target();
            energy_rel = Some((mean - target).abs() / target);
            energy_signed = Some((mean - target) / target);
        }
    }
    let energy_drift_rel = (kind == ScenarioKind::Free).then(|| {
        let e0 = tr.energy.first().copied().unwrap_or(0.0);
        tr.energy.iter().map(|e| (e - e0).abs()).fold(0.0, f64::max) / e0.abs().max(1e-300)
    });
    let f = result.fluxes;
    let p = result.peak_torque;
    RunMetrics {
        mode_drift_deg,
        mode_drift_wrapped_deg,
        settling_s,
        energy_rel_error_last5s: energy_rel,
        energy_signed_error_last5s: energy_signed,
        energy_drift_rel,
        flux: FluxSummary {
            potential: f.potential,
            mode: f.mode,
            energy: f.energy,
            damping: f.damping,
            compensation: f.compensation,
            gravity: f.gravity,
        },
        actuator_share: (f.mode + f.energy) / f.potential.max(1e-300),
        actuator_share_last5s: {
            let from = tr.t.last().copied().unwrap_or(0.0) - 5.0;
            // Sources: 0 spring, 3 mode, 4 energy (see simulate::SOURCES).
            let actuators: f64 = [3, 4].iter().map(|&s| tr.flux_from(s, from)).sum();
            actuators / tr.flux_from(0, from).max(1e-300)
        },
        actuator_share_with_compensation: (f.mode + f.energy + f.compensation) / f.potential.max(1e-300),
        peak_torque_nm: PeakTorques {
            spring: p[0],
            gravity: p[1],
            damping: p[2],
            mode: p[3],
            energy: p[4],
            compensation: p[5],
        },
        peak_actuator_torque_nm: result.peak_actuator_torque,
        peak_demanded_torque_nm: result.peak_demanded_torque,
        saturated_s: result.saturated_s,
        geodesic_deviation: None,
        savings: Savings::of(tr, &controllers.motor_constants(tr.n)),
    }
}

/// Seconds from each mode step until the label stays within 3° of its target for the rest of
/// the step (None: never), from samples of a run: times `t`, labels and their targets (θ and θ_d
/// for two joints, NaN inside the ε-ball; Δ and 0 for more, see [`crate::dynamics::simulate::Trace`]),
/// whether each sample is in the ε-ball, the steps' start times, the run's duration and whether the
/// arm has two joints. Samples
/// in the ball do not count. The settling times of `sim_<name>.json`; a loop of one's own (a
/// MuJoCo model driven by [`crate::dynamics::control::Controller`]) is judged by the same rule.
pub fn settling_times(
    t: &[f64],
    label: &[f64],
    label_target: &[f64],
    in_ball: &[bool],
    starts: &[f64],
    duration: f64,
    two_joints: bool,
) -> Vec<Option<f64>> {
    let deg = |x: f64| x.to_degrees();
    let outside: Vec<usize> = (0..t.len()).filter(|&i| !in_ball[i] && label[i].is_finite()).collect();
    let mut settling = Vec::with_capacity(starts.len());
    for (k, t0) in starts.iter().enumerate() {
        let t1 = starts.get(k + 1).copied().unwrap_or(duration + 1e-9);
        let window: Vec<usize> = outside.iter().copied().filter(|&i| t[i] >= *t0 && t[i] < t1).collect();
        let ok = |i: usize| {
            let target = label_target[i];
            deg(if two_joints { wrap_angle(label[i] - target).abs() } else { label[i] }) < 3.0
        };
        // Settled from the earliest sample after which every sample of the step is within 3°.
        let mut settle = None;
        for &i in window.iter().rev() {
            if !ok(i) {
                break;
            }
            settle = Some(t[i] - t0);
        }
        settling.push(settle);
    }
    settling
}

/// Angles unwrapped into a continuous series: each finite value is moved by a multiple of 2π to
/// within π of the previous finite one (gaps of NaN, the ε-ball passages, are bridged); NaN stays.
pub fn unwrap_angles(angles: &[f64]) -> Vec<f64> {
    let mut prev: Option<f64> = None;
    angles
        .iter()
        .map(|&a| {
            if !a.is_finite() {
                return a;
            }
            let v = match prev {
                Some(p) => p + wrap_angle(a - p),
                None => a,
            };
            prev = Some(v);
            v
        })
        .collect()
}

/// The geodesic through q_eq and a start point sampled both ways (see [`GeodesicDeviation`]):
/// signed arc positions, points and mass matrices (row-major).
struct ModeGeodesic {
    s: Vec<f64>,
    q: Vec<Vec<f64>>,
    m: Vec<Vec<f64>>,
}

impl ModeGeodesic {
    fn trace(design: &Design, q0: &[f64]) -> Result<(ModeGeodesic, f64)> {
        use crate::geodesic::label::{ExactLog, LogField, LogValue};
        let n = design.dof();
        let mut log = ExactLog::new(&design.chain, &design.q_eq, design.geodesics.ode);
        let mut lv = LogValue::zeros(n);
        log.eval(q0, &mut lv)?;
        let v = DVector::from_column_slice(&lv.v);
        let r0 = v.dot(&(design.chain.mass_matrix(&design.q_eq) * &v)).sqrt();
        if !(r0.is_finite() && r0 > 0.0) {
            return Err(Error::numerical("geodesic deviation", "the start is the equilibrium: no mode to follow"));
        }
        let u = &v / r0;
        let mut shooter = Shooter::new(&design.chain, &design.q_eq, design.geodesics.ode);
        let spacing = r0 / 1000.0;
        let forward = shooter.trace(&u, Stop::Arc(1.5 * r0), spacing)?;
        let backward = shooter.trace(&(-&u), Stop::Arc(1.5 * r0), spacing)?;
        let mut g = ModeGeodesic { s: Vec::new(), q: Vec::new(), m: Vec::new() };
        let mut push = |s: f64, q: &[f64]| {
            let m = design.chain.mass_matrix(&DVector::from_column_slice(q));
            g.s.push(s);
            g.q.push(q.to_vec());
            g.m.push((0..n * n).map(|k| m[(k / n, k % n)]).collect());
        };
        for i in (1..backward.len()).rev() {
            push(-backward.s(i), backward.q(i));
        }
        for i in 0..forward.len() {
            push(forward.s(i), forward.q(i));
        }
        Ok((g, r0))
    }

    /// (metric distance, signed arc position) of the point of the polyline nearest to `q`.
    fn nearest(&self, q: &[f64]) -> (f64, f64) {
        let n = q.len();
        let norm2 = |m: &[f64], d: &[f64]| -> f64 {
            let mut r = 0.0;
            for i in 0..n {
                for j in 0..n {
                    r += d[i] * m[i * n + j] * d[j];
                }
            }
            r
        };
        let mut d = vec![0.0; n];
        let (mut best, mut kbest) = (f64::INFINITY, 0);
        for (k, p) in self.q.iter().enumerate() {
            for i in 0..n {
                d[i] = q[i] - p[i];
            }
            let v = norm2(&self.m[k], &d);
            if v < best {
                best = v;
                kbest = k;
            }
        }
        let mut out = (best.max(0.0).sqrt(), self.s[kbest]);
        // The chords on either side: minimise |a − λb|²_M over λ ∈ [0, 1], a = q − γ_k,
        // b = γ_j − γ_k, with M at γ_k.
        let mut b = vec![0.0; n];
        for j in [kbest.wrapping_sub(1), kbest + 1] {
            if j >= self.q.len() {
                continue;
            }
            for i in 0..n {
                d[i] = q[i] - self.q[kbest][i];
                b[i] = self.q[j][i] - self.q[kbest][i];
            }
            let m = &self.m[kbest];
            let bb = norm2(m, &b);
            if bb <= 0.0 {
                continue;
            }
            let mut ab = 0.0;
            for i in 0..n {
                for k in 0..n {
                    ab += d[i] * m[i * n + k] * b[k];
                }
            }
            let lambda = (ab / bb).clamp(0.0, 1.0);
            let dist2 = norm2(m, &d) - 2.0 * lambda * ab + lambda * lambda * bb;
            let dist = dist2.max(0.0).sqrt();
            if dist < out.0 {
                out = (dist, self.s[kbest] + lambda * (self.s[j] - self.s[kbest]));
            }
        }
        out
    }
}

/// The deviation of a run from the geodesic of its start's mode (see [`GeodesicDeviation`]) and
/// the distance per sample.
pub fn geodesic_deviation(
    design: &Design,
    trace: &crate::dynamics::simulate::Trace,
) -> Result<(GeodesicDeviation, Vec<f64>)> {
    let n = trace.n;
    let samples = trace.t.len();
    if samples == 0 {
        return Err(Error::numerical("geodesic deviation", "the run has no samples"));
    }
    let (geo, r0) = ModeGeodesic::trace(design, &trace.q[..n])?;
    let mut series = Vec::with_capacity(samples);
    let mut per_swing = Vec::new();
    let (mut swing_max, mut side) = (0.0f64, 0.0f64);
    for k in 0..samples {
        let (dist, s) = geo.nearest(&trace.q[k * n..(k + 1) * n]);
        let sign = if s > 0.0 {
            1.0
        } else if s < 0.0 {
            -1.0
        } else {
            side
        };
        if side != 0.0 && sign != side {
            per_swing.push(swing_max);
            swing_max = 0.0;
        }
        side = sign;
        swing_max = swing_max.max(dist);
        series.push(dist);
    }
    per_swing.push(swing_max);
    let max = series.iter().copied().fold(0.0, f64::max);
    Ok((GeodesicDeviation { start_radius: r0, max, max_rel: max / r0, per_swing }, series))
}

/// Where the mode label comes from during simulations.
#[derive(Clone)]
pub enum LabelSource<'a> {
    /// The tabulated log map (two joints).
    Table(crate::geodesic::label::LogTable<'a>),
    /// The fitted log map (three or more joints).
    Fit(Box<crate::geodesic::logfit::LogFit<'a>>),
    /// The exact log map.
    Exact(crate::geodesic::label::ExactLog<'a>),
}

impl<'a> LabelSource<'a> {
    /// A fresh field for one run (each run owns its warm-start state).
    pub fn field(&self) -> Box<dyn crate::geodesic::label::LogField + 'a> {
        match self {
            LabelSource::Table(t) => Box::new(t.clone()),
            LabelSource::Fit(f) => Box::new(f.as_ref().clone()),
            LabelSource::Exact(e) => Box::new(e.clone()),
        }
    }
}

/// The label chosen for a design: the source the runs use, its measured error and, when
/// `label = "auto"` measured a fitted log map and kept the exact one, that fit's error, so the
/// outputs can say why the label is slow instead of discarding the measurement.
pub struct LabelChoice<'a> {
    /// What the runs evaluate.
    pub source: LabelSource<'a>,
    /// The tabulated or fitted label's largest error against the exact label on held-out
    /// geodesics, degrees, and the number of samples compared (None for the exact label).
    pub error: Option<(f64, usize)>,
    /// The fitted log map `auto` built and rejected: its largest error, degrees, and the number
    /// of samples compared (None when no fit was rejected).
    pub rejected: Option<(f64, usize)>,
    /// The arm's joints (what `auto`'s bound depends on).
    pub joints: usize,
}

impl LabelChoice<'_> {
    /// `table` or `exact`, as the outputs name the label.
    pub fn name(&self) -> &'static str {
        if self.error.is_some() { "table" } else { "exact" }
    }

    /// Why `auto` took the exact log map, e.g. "fitted log map error 6.61° > 0.1°: exact log map
    /// used" (None when it did not reject a fit).
    pub fn note(&self) -> Option<String> {
        self.rejected.map(|(deg, _)| rejected_label_note(deg, self.joints))
    }
}

/// The note of a fitted log map of error `deg` (degrees) that `label = "auto"` rejected on an
/// arm of `joints` joints (the bound depends on them: [`crate::design::simulate::auto_label_bound`]).
pub fn rejected_label_note(deg: f64, joints: usize) -> String {
    format!(
        "fitted log map error {deg:.2}° > {}°: exact log map used",
        crate::design::simulate::auto_label_bound(joints)
    )
}

/// The label source for a design and, for a table, its largest error against the exact label on
/// held-out geodesics (degrees) and the number of samples compared: [`choose_label`] without
/// the rejected fit's error.
pub fn label_source<'a>(
    design: &'a Design,
    settings: &crate::design::simulate::SimSettings,
) -> Result<(LabelSource<'a>, Option<(f64, usize)>)> {
    let choice = choose_label(design, settings)?;
    Ok((choice.source, choice.error))
}

/// The label for a design. `[simulate] label`: `exact`, `table` (the grid for two joints, the
/// fitted log map for more: one polynomial, or cells where it misses, whichever errs less) or
/// `auto` (the table, except for three or more joints when the fit's error exceeds
/// [`crate::design::simulate::auto_label_bound`]: 0.1° for the one polynomial of three to five
/// joints; from six, where `auto` also builds the cells, 1.5°, half the settling band: then
/// exact, with the fit's error kept in [`LabelChoice::rejected`]; see
/// [`crate::geodesic::logfit::fit_label`]).
pub fn choose_label<'a>(
    design: &'a Design,
    settings: &crate::design::simulate::SimSettings,
) -> Result<LabelChoice<'a>> {
    use crate::design::simulate::{AUTO_CELLS_FROM_JOINTS, LabelKind, auto_label_bound};
    use crate::geodesic::label::{ExactLog, LogTable};
    use crate::geodesic::logfit::fit_label;
    use crate::geodesic::{Fan, FanSpec};
    let exact = ExactLog::new(&design.chain, &design.q_eq, design.geodesics.ode);
    let joints = design.dof();
    if settings.label == LabelKind::Exact {
        return Ok(LabelChoice { source: LabelSource::Exact(exact), error: None, rejected: None, joints });
    }
    let region = design.valid_region()?;
    let stop = Stop::Region { region: &design.region, max_arc: design.geodesics.max_arc };
    let ode = design.geodesics.ode;
    let n = design.dof();
    let check = Fan::trace(
        &design.chain,
        &design.q_eq,
        FanSpec { count: 36 * (n - 1).max(1), phase: 0.5, stop, spacing: region.extent / 20.0 },
        ode,
    )?;
    if n != 2 {
        let cells = settings.label == LabelKind::Table || n >= AUTO_CELLS_FROM_JOINTS;
        let bound = auto_label_bound(n);
        let (fit, err) = fit_label(&design.chain, &design.q_eq, ode, region.extent, &check, bound, cells)?;
        if settings.label == LabelKind::Auto && err.0 > bound {
            return Ok(LabelChoice { source: LabelSource::Exact(exact), error: None, rejected: Some(err), joints });
        }
        return Ok(LabelChoice { source: LabelSource::Fit(Box::new(fit)), error: Some(err), rejected: None, joints });
    }
    let fan = Fan::trace(
        &design.chain,
        &design.q_eq,
        FanSpec { count: 72, phase: 0.0, stop, spacing: region.extent / 40.0 },
        ode,
    )?;
    let nodes = settings.table_nodes;
    let mut table = LogTable::build(&design.chain, &design.q_eq, &fan, ode, nodes, nodes, 0.25)?;
    let err = table.label_error(&design.chain, &design.q_eq, &check, ode, 0.05 * region.extent)?;
    Ok(LabelChoice { source: LabelSource::Table(table), error: Some(err), rejected: None, joints })
}

/// One scenario's results.
pub struct ScenarioOutcome {
    /// The resolved scenario.
    pub scenario: Scenario,
    /// Per run: result and metrics, in run order.
    pub runs: Vec<(RunResult, RunMetrics)>,
}

/// U − U(q_eq) with the nominal potential `potential` as a function of q (through `label`'s log
/// field for the exact one): what places start points on a mode at an energy.
pub fn nominal_energy<'a>(
    design: &'a Design,
    potential: &'a crate::dynamics::simulate::ElasticPotential,
    label: &LabelSource<'a>,
) -> Result<impl FnMut(&[f64]) -> Result<f64> + 'a> {
    let mut energy_field = label.field();
    let mut lv = crate::geodesic::label::LogValue::zeros(design.dof());
    let chain = &design.chain;
    let mut nominal = move |q: &[f64]| -> Result<f64> {
        Ok(match potential {
            crate::dynamics::simulate::ElasticPotential::Springs(s) => {
                s.elements.iter().zip(&s.stiffness).map(|(e, k)| k * e.value(q)).sum::<f64>()
                    + chain.gravity_potential(q)
            }
            crate::dynamics::simulate::ElasticPotential::Exact { omega } => {
                energy_field.eval(q, &mut lv)?;
                let v = DVector::from_column_slice(&lv.v);
                0.5 * omega * omega * v.dot(&(chain.mass_matrix(&design.q_eq) * &v))
            }
        })
    };
    let u0 = nominal(design.q_eq.as_slice())?;
    Ok(move |q: &[f64]| -> Result<f64> { Ok(nominal(q)? - u0) })
}

/// Resolves scenario `index` of the design into its runs, with the start points placed by the
/// energy of the nominal potential `potential` (through `label`'s log field for the exact one).
pub fn resolve_scenario<'a>(
    design: &'a Design,
    potential: &'a crate::dynamics::simulate::ElasticPotential,
    label: &LabelSource<'a>,
    index: usize,
) -> Result<Scenario> {
    let mut energy_at = nominal_energy(design, potential, label)?;
    design.scenarios[index].resolve(index, design, &mut energy_at)
}

/// Resolves and runs scenario `index` of the design with the elastic potential `potential`.
/// Runs go in parallel; each owns its label field, so results do not depend on the thread count.
pub fn run_scenario<'a>(
    design: &'a Design,
    potential: &'a crate::dynamics::simulate::ElasticPotential,
    label: &LabelSource<'a>,
    settings: &crate::design::simulate::SimSettings,
    controllers: &ControllerSettings,
    index: usize,
) -> Result<ScenarioOutcome> {
    use rayon::prelude::*;
    let spec = &design.scenarios[index];
    let chain = &design.chain;
    let scenario = resolve_scenario(design, potential, label, index)?;
    let results: Vec<Result<(RunResult, RunMetrics)>> = scenario
        .runs
        .par_iter()
        .map(|run| {
            let mut dynamics = crate::dynamics::simulate::Dynamics::new(
                chain,
                &design.q_eq,
                potential,
                controllers.clone(),
                run,
                Some(label.field()),
            )?;
            let result = crate::dynamics::simulate::run(&mut dynamics, settings).map_err(|e| match e {
                Error::Numerical { context, reason } => {
                    Error::Numerical { context: format!("scenario {} run {}: {context}", spec.name, run.name), reason }
                }
                other => other,
            })?;
            let mut result = result;
            let mut m = metrics(&result, run, controllers, scenario.kind);
            if scenario.kind == ScenarioKind::Free {
                let (dev, series) = geodesic_deviation(design, &result.trace)?;
                m.geodesic_deviation = Some(dev);
                result.trace.geodesic_deviation = series;
            }
            Ok((result, m))
        })
        .collect();
    let runs = results.into_iter().collect::<Result<Vec<_>>>()?;
    Ok(ScenarioOutcome { scenario, runs })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unwrapping_carries_the_label_across_plus_minus_pi() {
        let pi = std::f64::consts::PI;
        let u = unwrap_angles(&[3.0, 3.1, -3.1, f64::NAN, -3.0, 3.1, -pi + 0.05]);
        let want = [3.0, 3.1, 2.0 * pi - 3.1, f64::NAN, 2.0 * pi - 3.0, 3.1, pi + 0.05];
        for (a, b) in u.iter().zip(want) {
            assert!(a.is_nan() && b.is_nan() || (a - b).abs() < 1e-12, "{u:?}");
        }
        // A steady turn keeps growing past ±π.
        let turning: Vec<f64> = (0..40).map(|k| wrap_angle(0.3 * k as f64)).collect();
        let u = unwrap_angles(&turning);
        assert!((u[39] - 0.3 * 39.0).abs() < 1e-9, "{}", u[39]);
    }
}
