//! `[[scenario]]`: named simulation set-ups declared in the design file, checked before any work
//! (resolving them into runs is `dynamics::scenario`).
//!
//! ```toml
//! [[scenario]]
//! name = "free"            # releases from rest, no control (the paper's Fig. 5)
//! kind = "free"
//! releases = [{ mode = 0.0, energy = 10.0 }, { mode = "pi/3", energy = 10.0 }]
//! starts = [[0.3, 1.9]]    # and/or explicit configurations
//!
//! [[scenario]]
//! name = "switch"          # θ_d raised by `step` every `every` seconds (Fig. 6)
//! kind = "switch"
//! mode = 0.0
//! energy = 10.0
//! energy_target = "hold"   # τ_E holds the start energy (default); "none": no energy control
//!
//! [[scenario]]
//! name = "swingup"         # from E0 to E_d against joint damping (Fig. 7)
//! kind = "swingup"
//! mode = "pi/4"
//! ```
//!
//! A mode is an angle θ (two joints; the initial joint velocity direction (cos θ/2, sin θ/2), as
//! the paper's label) or a direction vector of joint velocities (any number of joints). Starting
//! points "on a mode at energy E" are found by the tool: at rest on the geodesic of that mode where
//! U − U(q_eq) = E.

use serde::{Deserialize, Serialize};

use crate::design::Design;
use crate::error::{Error, Result};
use crate::units::Angle;

/// The kind of scenario.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ScenarioKind {
    /// Releases from rest without control.
    Free,
    /// Mode switching with the mode controller.
    Switch,
    /// Swing-up against damping with energy regulation, in several controller variants.
    Swingup,
}

/// A mode as written: an angle θ or a direction of joint velocities.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum ModeSpec {
    /// θ (two joints).
    Angle(f64),
    /// A direction of joint velocities.
    Vector(Vec<f64>),
}

impl<'de> Deserialize<'de> for ModeSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Vector(Vec<f64>),
            Angle(Angle),
        }
        match Raw::deserialize(d).map_err(|_| {
            serde::de::Error::custom(
                "a mode is an angle θ (\"pi/4\", 0.5) or a direction of joint velocities ([1.0, 0.0, -0.5])",
            )
        })? {
            Raw::Vector(v) => Ok(ModeSpec::Vector(v)),
            Raw::Angle(a) => Ok(ModeSpec::Angle(a.0)),
        }
    }
}

/// A target energy as written: one value or steps `[[t, E], …]`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum EnergySpec {
    /// A constant E_d.
    Value(f64),
    /// (start time, E_d) steps.
    Steps(Vec<[f64; 2]>),
}

impl<'de> Deserialize<'de> for EnergySpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Value(f64),
            Steps(Vec<[f64; 2]>),
        }
        match Raw::deserialize(d).map_err(|_| {
            serde::de::Error::custom("an energy target is a number of joules or steps [[t, E], …] from t = 0")
        })? {
            Raw::Value(v) => Ok(EnergySpec::Value(v)),
            Raw::Steps(s) => Ok(EnergySpec::Steps(s)),
        }
    }
}

/// Energy handling of a switch scenario.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum EnergyTarget {
    /// τ_E holds the start energy (E_d = the scenario's `energy`): the mode controller's damping
    /// term takes energy out at every step, and without a target the swing would fade.
    #[default]
    Hold,
    /// No energy regulation (the mode controller alone).
    None,
}

/// A release: at rest on a mode where the potential has risen by `energy`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Release {
    /// The mode.
    pub mode: ModeSpec,
    /// U − U(q_eq) at the release point, J.
    pub energy: f64,
}

/// `[[scenario]]` as written. Fields a kind does not use are errors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioSpec {
    /// Name (outputs are `sim_<name>.*`).
    pub name: String,
    /// `free`, `switch` or `swingup`.
    pub kind: ScenarioKind,
    /// Duration, s (default: free 20, switch 100, swingup 20).
    #[serde(default)]
    pub duration: Option<f64>,
    /// Joint damping D = d·I, N·m·s/rad (default: 0; swingup 0.3).
    #[serde(default)]
    pub damping: Option<f64>,
    /// free: explicit start configurations (rad).
    #[serde(default)]
    pub starts: Vec<Vec<Angle>>,
    /// free: releases on modes at energies.
    #[serde(default)]
    pub releases: Vec<Release>,
    /// switch, swingup: the (first) desired mode, also where the arm starts (default θ = 0).
    #[serde(default)]
    pub mode: Option<ModeSpec>,
    /// switch: energy of the start point, J (default 10).
    #[serde(default)]
    pub energy: Option<f64>,
    /// switch: increment of θ_d (default π/6; two joints, with `mode`).
    #[serde(default)]
    pub step: Option<Angle>,
    /// switch: the desired modes in turn, one per step of `every` seconds (directions of joint
    /// velocity at q_eq in joint order, or angles θ on two joints), cycled if the run outlasts
    /// them; the arm starts on the first. Any number of joints; needed from three on.
    #[serde(default)]
    pub modes: Vec<ModeSpec>,
    /// switch: seconds between increments (default 15).
    #[serde(default)]
    pub every: Option<f64>,
    /// switch: `hold` (τ_E holds the start energy, default) or `none`.
    #[serde(default)]
    pub energy_target: Option<EnergyTarget>,
    /// swingup: start energy E0, J (default 5).
    #[serde(default)]
    pub e0: Option<f64>,
    /// swingup: target energy E_d, J (default 20), or a schedule of steps `[[t, E_d], …]`
    /// starting at t = 0.
    #[serde(default)]
    pub ed: Option<EnergySpec>,
    /// swingup: variants to run among `energy`, `negative_damping`, `energy_compensated`
    /// (default all three).
    #[serde(default)]
    pub variants: Vec<String>,
}

impl ScenarioSpec {
    /// Every check of the scenario that needs no springs: names, kinds and the keys each kind
    /// takes, durations, damping, step times, energy schedules, modes and variants. `check`
    /// (through [`crate::design::validate::validate`]) runs it before any work and [`ScenarioSpec::resolve`]
    /// runs it first, so the two cannot drift apart; what needs the fitted potential (an energy
    /// reachable inside the region) is left to `resolve`. Errors name `scenario[index].field`.
    pub fn check(&self, index: usize, design: &Design) -> Result<()> {
        let sc = self;
        let at = ScenarioAt { path: &design.path, index, name: &sc.name, n: design.dof(), kind: kind_name(sc.kind) };
        if sc.name.trim().is_empty() || sc.name.contains(['/', '\\']) {
            return Err(at.bad("name", format!("`{}` cannot name an output file", sc.name)));
        }
        let duration = sc.duration_s();
        if !(duration.is_finite() && duration > 0.0 && duration <= 1e5) {
            return Err(at.bad("duration", format!("must be positive and at most 100000 (s), got {duration}")));
        }
        if let Some(d) = sc.damping
            && !(d.is_finite() && d >= 0.0)
        {
            return Err(at.bad("damping", format!("must be ≥ 0 (N·m·s/rad), got {d}")));
        }
        match sc.kind {
            ScenarioKind::Free => sc.check_free(&at),
            ScenarioKind::Switch => sc.check_switch(&at, duration),
            ScenarioKind::Swingup => sc.check_swingup(&at),
        }
    }

    /// A free scenario: releases or starts (each start one finite angle per joint, each release a
    /// mode and a positive energy), none of the other kinds' keys.
    fn check_free(&self, at: &ScenarioAt) -> Result<()> {
        let sc = self;
        at.unused("mode", sc.mode.is_some())?;
        at.unused("energy", sc.energy.is_some())?;
        at.unused("step", sc.step.is_some())?;
        at.unused("every", sc.every.is_some())?;
        at.unused("energy_target", sc.energy_target.is_some())?;
        at.unused("e0", sc.e0.is_some())?;
        at.unused("ed", sc.ed.is_some())?;
        at.unused("variants", !sc.variants.is_empty())?;
        at.unused("modes", !sc.modes.is_empty())?;
        if sc.starts.is_empty() && sc.releases.is_empty() {
            return Err(
                at.bad("releases", "a free scenario needs releases = [{ mode, energy }] or starts = [[…]]".into())
            );
        }
        let n = at.n;
        for (k, s) in sc.starts.iter().enumerate() {
            if s.len() != n {
                return Err(
                    at.bad(&format!("starts[{k}]"), format!("has {} angles but the robot has {n} joints", s.len()))
                );
            }
            if let Some(a) = s.iter().find(|a| !a.0.is_finite()) {
                return Err(at.bad(&format!("starts[{k}]"), format!("angles must be finite, got {}", a.0)));
            }
        }
        for (k, r) in sc.releases.iter().enumerate() {
            at.mode(&format!("releases[{k}].mode"), &r.mode)?;
            at.energy(&format!("releases[{k}].energy"), r.energy)?;
        }
        Ok(())
    }

    /// A switch scenario: either `modes` (any number of joints, each a valid mode, without `mode`
    /// and `step`) or, on two joints only, a first mode θ and finite steps; a positive interval
    /// making at most 10000 steps, a positive energy; no starts, releases or swing-up keys.
    fn check_switch(&self, at: &ScenarioAt, duration: f64) -> Result<()> {
        let sc = self;
        at.unused("starts", !sc.starts.is_empty())?;
        at.unused("releases", !sc.releases.is_empty())?;
        at.unused("e0", sc.e0.is_some())?;
        at.unused("ed", sc.ed.is_some())?;
        at.unused("variants", !sc.variants.is_empty())?;
        if !sc.modes.is_empty() {
            // The n-joint form: a list of modes; `mode` and `step` belong to the θ form.
            if sc.mode.is_some() {
                return Err(at.bad("mode", "give either modes = [[…], …] or mode and step, not both".into()));
            }
            if sc.step.is_some() {
                return Err(at.bad("step", "give either modes = [[…], …] or mode and step, not both".into()));
            }
            for (k, m) in sc.modes.iter().enumerate() {
                at.mode(&format!("modes[{k}]"), m)?;
            }
        } else if at.n != 2 {
            return Err(at.bad(
                "modes",
                format!(
                    "a switch on a {}-joint arm needs modes = [[…], …]: one direction of {} joint velocities per step (mode and step by θ are for two joints)",
                    at.n, at.n
                ),
            ));
        } else if let Some(m) = &sc.mode {
            if matches!(m, ModeSpec::Vector(_)) {
                return Err(at.bad(
                    "mode",
                    "give the first mode of a θ switch as an angle θ, or the steps' directions as modes = [[…], …]"
                        .into(),
                ));
            }
            at.mode("mode", m)?;
        }
        if let Some(s) = sc.step
            && !s.0.is_finite()
        {
            return Err(at.bad("step", format!("must be finite, got {}", s.0)));
        }
        let every = sc.every.unwrap_or(15.0);
        if !(every.is_finite() && every > 0.0) {
            return Err(at.bad("every", format!("must be positive (s), got {every}")));
        }
        if duration / every > 10_000.0 {
            return Err(at.bad(
                "every",
                format!("{every} s makes {:.0} mode steps in {duration} s; at most 10000", duration / every),
            ));
        }
        at.energy("energy", sc.energy.unwrap_or(10.0))
    }

    /// A swing-up scenario: positive start and target energies (the target's steps from t = 0
    /// on, increasing in time), a valid mode, known variants; no starts, releases or switch keys.
    fn check_swingup(&self, at: &ScenarioAt) -> Result<()> {
        let sc = self;
        at.unused("starts", !sc.starts.is_empty())?;
        at.unused("releases", !sc.releases.is_empty())?;
        at.unused("energy", sc.energy.is_some())?;
        at.unused("step", sc.step.is_some())?;
        at.unused("every", sc.every.is_some())?;
        at.unused("energy_target", sc.energy_target.is_some())?;
        at.unused("modes", !sc.modes.is_empty())?;
        at.energy("e0", sc.e0.unwrap_or(5.0))?;
        let schedule: Vec<(f64, f64)> = match sc.ed.clone().unwrap_or(EnergySpec::Value(20.0)) {
            EnergySpec::Value(v) => vec![(0.0, v)],
            EnergySpec::Steps(s) => s.iter().map(|p| (p[0], p[1])).collect(),
        };
        if schedule.is_empty() || schedule[0].0 != 0.0 || schedule.windows(2).any(|w| w[1].0 <= w[0].0) {
            return Err(at.bad("ed", "steps must start at t = 0 and increase in time".into()));
        }
        for (t, e) in &schedule {
            if !(e.is_finite() && *e > 0.0 && t.is_finite()) {
                return Err(at.bad("ed", format!("energies must be positive (J), got {e} at t = {t}")));
            }
        }
        if let Some(m) = &sc.mode {
            at.mode("mode", m)?;
        }
        for (k, v) in sc.variants.iter().enumerate() {
            if !["energy", "negative_damping", "energy_compensated"].contains(&v.as_str()) {
                return Err(at.bad(
                    &format!("variants[{k}]"),
                    format!("unknown variant `{v}`: expected energy, negative_damping or energy_compensated"),
                ));
            }
        }
        Ok(())
    }
}

/// Which scenario a check is on, so that every error names `scenario[index].field` in the
/// design file: the file, the index, the robot's joints and the scenario's kind.
struct ScenarioAt<'a> {
    path: &'a std::path::Path,
    index: usize,
    name: &'a str,
    n: usize,
    kind: &'static str,
}

impl ScenarioAt<'_> {
    fn bad(&self, f: &str, r: String) -> Error {
        Error::invalid(self.path, format!("scenario[{}].{f}", self.index), format!("(scenario `{}`) {r}", self.name))
    }

    /// A key given that the scenario's kind does not take.
    fn unused(&self, f: &str, present: bool) -> Result<()> {
        if present { Err(self.bad(f, format!("does not apply to kind = \"{}\"", self.kind))) } else { Ok(()) }
    }

    /// A positive energy, J.
    fn energy(&self, f: &str, e: f64) -> Result<()> {
        if e.is_finite() && e > 0.0 {
            Ok(())
        } else {
            Err(self.bad(f, format!("must be a positive energy (J), got {e}")))
        }
    }

    /// A mode: an angle θ of a two-joint arm, or a finite non-zero direction of n joint
    /// velocities.
    fn mode(&self, f: &str, m: &ModeSpec) -> Result<()> {
        let n = self.n;
        match m {
            ModeSpec::Angle(a) if n != 2 => Err(self.bad(
                f,
                format!("an angle ({a}) names a mode of a two-joint arm; give a direction of {n} joint velocities"),
            )),
            ModeSpec::Angle(a) if !a.is_finite() => Err(self.bad(f, format!("must be finite, got {a}"))),
            ModeSpec::Angle(_) => Ok(()),
            ModeSpec::Vector(v) if v.len() != n => {
                Err(self.bad(f, format!("has {} entries but the robot has {n} joints", v.len())))
            }
            ModeSpec::Vector(v) if v.iter().any(|x| !x.is_finite()) || v.iter().all(|x| *x == 0.0) => {
                Err(self.bad(f, "must be a finite, non-zero direction".into()))
            }
            ModeSpec::Vector(_) => Ok(()),
        }
    }
}

impl ScenarioSpec {
    /// The run's duration, s: `duration`, or by default 20 s; a switch 100 s, or with `modes`
    /// one `every` per mode (15 s each by default), so that each mode is visited once.
    pub fn duration_s(&self) -> f64 {
        self.duration.unwrap_or(match self.kind {
            ScenarioKind::Switch if !self.modes.is_empty() => self.modes.len() as f64 * self.every.unwrap_or(15.0),
            ScenarioKind::Switch => 100.0,
            _ => 20.0,
        })
    }

    /// The energies (U − U(q_eq), J) the scenario asks for, each with the field that asks:
    /// release energies, a switch's energy, a swing-up's start and target energies (defaults
    /// included, as `resolve` uses them).
    pub fn energies(&self, index: usize) -> Vec<(String, f64)> {
        let f = |name: &str| format!("scenario[{index}].{name}");
        match self.kind {
            ScenarioKind::Free => {
                self.releases.iter().enumerate().map(|(k, r)| (f(&format!("releases[{k}].energy")), r.energy)).collect()
            }
            ScenarioKind::Switch => vec![(f("energy"), self.energy.unwrap_or(10.0))],
            ScenarioKind::Swingup => {
                let ed = match &self.ed {
                    None => 20.0,
                    Some(EnergySpec::Value(v)) => *v,
                    Some(EnergySpec::Steps(steps)) => steps.iter().map(|p| p[1]).fold(0.0, f64::max),
                };
                vec![(f("e0"), self.e0.unwrap_or(5.0)), (f("ed"), ed)]
            }
        }
    }
}

/// The energy the gains a design leaves out are sized for
/// ([`crate::design::controllers::ControllerSettings::derive_from_arm`]), J: the largest energy a
/// switch or swing-up scenario names (defaults included: those run the controllers), else the
/// largest release energy, else none. The largest, because β_E = ω/(πE) then never pushes harder
/// than the top of the swing-up needs and k_θ = E/2 holds the most energetic swing's mode.
pub fn gain_energy(scenarios: &[ScenarioSpec]) -> Option<f64> {
    let largest = |controlled: bool| {
        scenarios
            .iter()
            .enumerate()
            .filter(|(_, s)| (s.kind != ScenarioKind::Free) == controlled)
            .flat_map(|(i, s)| s.energies(i))
            .map(|(_, e)| e)
            .filter(|e| e.is_finite() && *e > 0.0)
            .fold(None, |m: Option<f64>, e| Some(m.map_or(e, |m| m.max(e))))
    };
    largest(true).or_else(|| largest(false))
}

/// Whether the mode law of a design's switches is the two-joint θ law (rather than the law on
/// the sphere of modes): two joints and no switch given by `modes`.
pub fn theta_law(dof: usize, scenarios: &[ScenarioSpec]) -> bool {
    dof == 2 && !scenarios.iter().any(|s| s.kind == ScenarioKind::Switch && !s.modes.is_empty())
}

fn kind_name(k: ScenarioKind) -> &'static str {
    match k {
        ScenarioKind::Free => "free",
        ScenarioKind::Switch => "switch",
        ScenarioKind::Swingup => "swingup",
    }
}
