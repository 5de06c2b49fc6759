//! One validation of the whole design, before any work.
//!
//! [`Design::load`] checks the design file on its own (the robot, the equilibrium, the region,
//! the settings sections). [`validate`] adds everything the later steps read: the catalogue the
//! design names (it exists, parses and fits the robot), every `[[scenario]]` as far as it can be
//! checked without springs (durations, damping, step times, energy schedules, modes, variants),
//! and the `[sweep]` scenario. Every command calls it right after loading the design, and
//! `springfit check` runs exactly the same function, so a design `check` passes is not rejected
//! later for a reason that was visible in its files. (What needs the fitted springs, such as an
//! energy the potential cannot reach inside the region, is still checked when the scenario is
//! resolved.)
//!
//! It also returns [`Warning`]s: input that is legal but probably not what was meant (angles of
//! many turns, a centre of mass beyond the link's end). The library never prints them; the CLI
//! shows them as `springfit: warning: …`.

use std::path::Path;

use crate::catalog::Catalog;
use crate::design::Design;
use crate::error::{Error, Result};
use crate::geodesic::Region;
use crate::scenario::{EnergySpec, ModeSpec, ScenarioKind, ScenarioSpec};

/// Angles beyond this many radians (two full turns) are probably degrees or a typo.
pub const MANY_TURNS_RAD: f64 = 4.0 * std::f64::consts::PI;

/// Input that is legal but probably not what was meant.
#[derive(Debug, Clone, PartialEq)]
pub struct Warning {
    /// The file the warning is about.
    pub path: std::path::PathBuf,
    /// The field (`equilibrium.q[1]`).
    pub field: String,
    /// What looks wrong and why it is only a warning.
    pub message: String,
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: field `{}`: {}", self.path.display(), self.field, self.message)
    }
}

/// What [`validate`] found: the catalogue (loaded once, for the command to use) and warnings.
#[derive(Debug, Clone)]
pub struct Validated {
    /// The design's catalogue, if it names one.
    pub catalog: Option<Catalog>,
    /// Legal but suspicious input.
    pub warnings: Vec<Warning>,
}

/// Validates everything of `design` that can be checked before any work (see the module
/// documentation). Errors name the file and the field.
pub fn validate(design: &Design) -> Result<Validated> {
    let catalog = match &design.catalog {
        Some(path) => Some(load_catalog(design, path)?),
        None => None,
    };
    if let Some(c) = &catalog {
        crate::fit::run::check_trimmed_weight(design, c, &design.fit)?;
    }
    for (i, sc) in design.file.scenario.iter().enumerate() {
        check_scenario(design, i, sc)?;
    }
    // The sweep scenario a `[sweep]` table names must exist; without the table the default one
    // (`sensitivity`) missing is only worth a warning: the design may never be swept, and
    // `springfit sweep` refuses it with the same message.
    let mut warnings = Vec::new();
    if !design.file.scenario.is_empty() {
        if let Err(e) = sweep_scenario(design) {
            if design.file.sweep_given {
                return Err(e);
            }
            warnings.push(Warning {
                path: design.path.clone(),
                field: "sweep.scenario".into(),
                message: format!(
                    "no [[scenario]] named `{}`: `springfit sweep` will refuse this design until a [sweep] table names one of its scenarios",
                    design.file.sweep.scenario
                ),
            });
        }
    }
    suspicious(design, &mut warnings);
    Ok(Validated { catalog, warnings })
}

/// The index of the `[sweep] scenario`, or an error listing the scenarios the design has.
pub fn sweep_scenario(design: &Design) -> Result<usize> {
    let name = &design.file.sweep.scenario;
    design.file.scenario.iter().position(|s| &s.name == name).ok_or_else(|| {
        let have: Vec<&str> = design.file.scenario.iter().map(|s| s.name.as_str()).collect();
        let have = if have.is_empty() { "none".to_string() } else { have.join(", ") };
        Error::invalid(
            &design.path,
            "sweep.scenario",
            format!(
                "no [[scenario]] named `{name}` (the design has: {have}); name one of them in [sweep] scenario = \"…\" \
                 or add a scenario `{name}` (a swingup with both controllers, e0 = ed, damping = 0)"
            ),
        )
    })
}

fn load_catalog(design: &Design, path: &Path) -> Result<Catalog> {
    if !path.is_file() {
        let written = design.file.catalog.as_deref().unwrap_or_default();
        return Err(Error::invalid(
            &design.path,
            "catalog",
            format!(
                "`{written}` names no file ({} does not exist; the path is relative to the design file)",
                path.display()
            ),
        ));
    }
    Catalog::load(path, design.dof())
}

/// The checks of [`ScenarioSpec::resolve`] that need no springs.
fn check_scenario(design: &Design, index: usize, sc: &ScenarioSpec) -> Result<()> {
    let n = design.dof();
    let bad = |f: &str, r: String| Error::invalid(&design.path, format!("scenario[{index}].{f}"), r);
    if sc.name.trim().is_empty() || sc.name.contains(['/', '\\']) {
        return Err(bad("name", format!("`{}` cannot name an output file", sc.name)));
    }
    let kind = match sc.kind {
        ScenarioKind::Free => "free",
        ScenarioKind::Switch => "switch",
        ScenarioKind::Swingup => "swingup",
    };
    let unused = |f: &str, present: bool| -> Result<()> {
        if present { Err(bad(f, format!("does not apply to kind = \"{kind}\""))) } else { Ok(()) }
    };
    let duration = sc.duration.unwrap_or(if sc.kind == ScenarioKind::Switch { 100.0 } else { 20.0 });
    if !(duration.is_finite() && duration > 0.0 && duration <= 1e5) {
        return Err(bad("duration", format!("must be positive and at most 100000 (s), got {duration}")));
    }
    if let Some(d) = sc.damping {
        if !(d.is_finite() && d >= 0.0) {
            return Err(bad("damping", format!("must be ≥ 0 (N·m·s/rad), got {d}")));
        }
    }
    let energy = |f: &str, e: f64| -> Result<()> {
        if e.is_finite() && e > 0.0 { Ok(()) } else { Err(bad(f, format!("must be a positive energy (J), got {e}"))) }
    };
    let mode = |f: &str, m: &ModeSpec| -> Result<()> {
        match m {
            ModeSpec::Angle(a) if n != 2 => Err(bad(
                f,
                format!("an angle ({a}) names a mode of a two-joint arm; give a direction of {n} joint velocities"),
            )),
            ModeSpec::Angle(a) if !a.is_finite() => Err(bad(f, format!("must be finite, got {a}"))),
            ModeSpec::Angle(_) => Ok(()),
            ModeSpec::Vector(v) if v.len() != n => {
                Err(bad(f, format!("has {} entries but the robot has {n} joints", v.len())))
            }
            ModeSpec::Vector(v) if v.iter().any(|x| !x.is_finite()) || v.iter().all(|x| *x == 0.0) => {
                Err(bad(f, "must be a finite, non-zero direction".into()))
            }
            ModeSpec::Vector(_) => Ok(()),
        }
    };
    match sc.kind {
        ScenarioKind::Free => {
            unused("mode", sc.mode.is_some())?;
            unused("energy", sc.energy.is_some())?;
            unused("step", sc.step.is_some())?;
            unused("every", sc.every.is_some())?;
            unused("energy_target", sc.energy_target.is_some())?;
            unused("e0", sc.e0.is_some())?;
            unused("ed", sc.ed.is_some())?;
            unused("variants", !sc.variants.is_empty())?;
            if sc.starts.is_empty() && sc.releases.is_empty() {
                return Err(bad(
                    "releases",
                    "a free scenario needs releases = [{ mode, energy }] or starts = [[…]]".into(),
                ));
            }
            for (k, s) in sc.starts.iter().enumerate() {
                if s.len() != n {
                    return Err(bad(
                        &format!("starts[{k}]"),
                        format!("has {} angles but the robot has {n} joints", s.len()),
                    ));
                }
                if let Some(a) = s.iter().find(|a| !a.0.is_finite()) {
                    return Err(bad(&format!("starts[{k}]"), format!("angles must be finite, got {}", a.0)));
                }
            }
            for (k, r) in sc.releases.iter().enumerate() {
                mode(&format!("releases[{k}].mode"), &r.mode)?;
                energy(&format!("releases[{k}].energy"), r.energy)?;
            }
        }
        ScenarioKind::Switch => {
            unused("starts", !sc.starts.is_empty())?;
            unused("releases", !sc.releases.is_empty())?;
            unused("e0", sc.e0.is_some())?;
            unused("ed", sc.ed.is_some())?;
            unused("variants", !sc.variants.is_empty())?;
            if n != 2 {
                return Err(bad("kind", format!("mode switching by θ steps needs two joints; this arm has {n}")));
            }
            if let Some(m) = &sc.mode {
                if matches!(m, ModeSpec::Vector(_)) {
                    return Err(bad("mode", "give the first mode of a switch scenario as an angle θ".into()));
                }
                mode("mode", m)?;
            }
            if let Some(s) = sc.step {
                if !s.0.is_finite() {
                    return Err(bad("step", format!("must be finite, got {}", s.0)));
                }
            }
            let every = sc.every.unwrap_or(15.0);
            if !(every.is_finite() && every > 0.0) {
                return Err(bad("every", format!("must be positive (s), got {every}")));
            }
            if duration / every > 10_000.0 {
                return Err(bad(
                    "every",
                    format!("{every} s makes {:.0} mode steps in {duration} s; at most 10000", duration / every),
                ));
            }
            energy("energy", sc.energy.unwrap_or(10.0))?;
        }
        ScenarioKind::Swingup => {
            unused("starts", !sc.starts.is_empty())?;
            unused("releases", !sc.releases.is_empty())?;
            unused("energy", sc.energy.is_some())?;
            unused("step", sc.step.is_some())?;
            unused("every", sc.every.is_some())?;
            unused("energy_target", sc.energy_target.is_some())?;
            energy("e0", sc.e0.unwrap_or(5.0))?;
            let schedule: Vec<(f64, f64)> = match sc.ed.clone().unwrap_or(EnergySpec::Value(20.0)) {
                EnergySpec::Value(v) => vec![(0.0, v)],
                EnergySpec::Steps(s) => s.iter().map(|p| (p[0], p[1])).collect(),
            };
            if schedule.is_empty() || schedule[0].0 != 0.0 || schedule.windows(2).any(|w| w[1].0 <= w[0].0) {
                return Err(bad("ed", "steps must start at t = 0 and increase in time".into()));
            }
            for (t, e) in &schedule {
                if !(e.is_finite() && *e > 0.0 && t.is_finite()) {
                    return Err(bad("ed", format!("energies must be positive (J), got {e} at t = {t}")));
                }
            }
            if let Some(m) = &sc.mode {
                mode("mode", m)?;
            }
            for (k, v) in sc.variants.iter().enumerate() {
                if !["energy", "negative_damping", "energy_compensated"].contains(&v.as_str()) {
                    return Err(bad(
                        &format!("variants[{k}]"),
                        format!("unknown variant `{v}`: expected energy, negative_damping or energy_compensated"),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// Legal input that is probably a mistake.
fn suspicious(design: &Design, out: &mut Vec<Warning>) {
    let mut warn = |field: String, message: String| {
        out.push(Warning { path: design.path.clone(), field, message });
    };
    let turns = |a: f64| a.abs() / std::f64::consts::TAU;
    for (i, q) in design.q_eq.iter().enumerate() {
        if q.abs() > MANY_TURNS_RAD {
            warn(
                format!("equilibrium.q[{i}]"),
                format!("{q} rad is {:.1} turns: angles are in radians (write \"pi/2\" or 1.5708 for 90°)", turns(*q)),
            );
        }
    }
    match &design.region {
        Region::Box { lower, upper } => {
            for i in 0..lower.len() {
                let span = upper[i] - lower[i];
                if span > MANY_TURNS_RAD {
                    warn(
                        format!("region.upper[{i}]"),
                        format!(
                            "the box spans {span} rad ({:.1} turns) of joint {}: angles are in radians",
                            turns(span),
                            i + 1
                        ),
                    );
                }
            }
        }
        Region::Ball { radius } => {
            // The smallest inertia direction moves furthest in joint angle per unit of arc length.
            let m = design.chain.mass_matrix(&design.q_eq);
            let lambda_min = m.symmetric_eigen().eigenvalues.min();
            if lambda_min > 0.0 {
                let reach = radius / lambda_min.sqrt();
                if reach > MANY_TURNS_RAD {
                    warn(
                        "region.radius".into(),
                        format!(
                            "a geodesic ball of radius {radius} reaches about {reach:.1} rad ({:.1} turns) of joint angle \
                             from the equilibrium; the radius is metric arc length, √(kg·m²)·rad",
                            turns(reach)
                        ),
                    );
                }
            }
        }
    }
    for (i, l) in design.file.robot.links.iter().enumerate() {
        if l.com > l.length {
            warn(
                format!("robot.links[{i}].com"),
                format!(
                    "the centre of mass, {} m from the joint, lies beyond the link's end (length {} m); a link that \
                     reaches past the next joint is possible, so this is only a warning: check for a typo",
                    l.com, l.length
                ),
            );
        }
    }
    for (k, sc) in design.file.scenario.iter().enumerate() {
        for (j, s) in sc.starts.iter().enumerate() {
            if let Some((i, a)) = s.iter().enumerate().find(|(_, a)| a.0.abs() > MANY_TURNS_RAD) {
                warn(
                    format!("scenario[{k}].starts[{j}][{i}]"),
                    format!("{} rad is {:.1} turns: angles are in radians", a.0, turns(a.0)),
                );
            }
        }
        let modes = sc
            .mode
            .iter()
            .map(|m| ("mode".to_string(), m))
            .chain(sc.releases.iter().enumerate().map(|(j, r)| (format!("releases[{j}].mode"), &r.mode)));
        for (f, m) in modes {
            if let ModeSpec::Angle(a) = m {
                if a.abs() > MANY_TURNS_RAD {
                    warn(
                        format!("scenario[{k}].{f}"),
                        format!("the mode angle θ = {a} rad is {:.1} turns: angles are in radians", turns(*a)),
                    );
                }
            }
        }
        if let Some(s) = sc.step {
            if s.0.abs() > MANY_TURNS_RAD {
                warn(
                    format!("scenario[{k}].step"),
                    format!("{} rad is {:.1} turns: angles are in radians", s.0, turns(s.0)),
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn design(text: &str) -> Result<Design> {
        Design::parse(Path::new("t.toml"), text)
    }

    const BASE: &str = r#"
[robot]
[[robot.links]]
mass = 1.0
length = 2.0
com = 1.0
inertia = 1.0
[[robot.links]]
mass = 1.0
length = 2.0
com = 1.0
inertia = 1.0
[equilibrium]
q = [0.0, "pi/2"]
[region]
kind = "ball"
radius = 2.0
"#;

    #[test]
    fn scenarios_are_checked_without_springs() {
        let cases = [
            ("[[scenario]]\nname = \"s\"\nkind = \"switch\"\nevery = 0.0\n", "scenario[0].every"),
            (
                "[[scenario]]\nname = \"s\"\nkind = \"free\"\nduration = 0.0\nstarts = [[0.0, 1.0]]\n",
                "scenario[0].duration",
            ),
            ("[[scenario]]\nname = \"s\"\nkind = \"swingup\"\nvariants = [\"fast\"]\n", "scenario[0].variants[0]"),
            ("[[scenario]]\nname = \"s\"\nkind = \"swingup\"\nmode = [1.0, 0.0, 0.0]\n", "scenario[0].mode"),
            (
                "[[scenario]]\nname = \"s\"\nkind = \"free\"\nreleases = [{ mode = 0.0, energy = -1.0 }]\n",
                "releases[0].energy",
            ),
            // `energy_target` belongs to switch scenarios only (resolve refused it; check missed it).
            ("[[scenario]]\nname = \"s\"\nkind = \"swingup\"\nenergy_target = \"none\"\n", "scenario[0].energy_target"),
        ];
        for (scenario, field) in cases {
            let d = design(&format!("{BASE}{scenario}[sweep]\nscenario = \"s\"\n")).unwrap();
            let err = validate(&d).unwrap_err().to_string();
            assert!(err.contains(field), "{scenario}: {err}");
        }
    }

    #[test]
    fn a_missing_sweep_scenario_lists_the_ones_there_are() {
        let free = "[[scenario]]\nname = \"free\"\nkind = \"free\"\nstarts = [[0.0, 1.0]]\n";
        let d = design(&format!("{BASE}{free}[sweep]\nbuilds = 10\n")).unwrap();
        let err = validate(&d).unwrap_err().to_string();
        assert!(err.contains("sweep.scenario") && err.contains("`sensitivity`") && err.contains("has: free"), "{err}");
        // Without a [sweep] table the default scenario missing is a warning: fit and simulate run.
        let v = validate(&design(&format!("{BASE}{free}")).unwrap()).unwrap();
        assert!(v.warnings.iter().any(|w| w.field == "sweep.scenario" && w.message.contains("springfit sweep")));
        // Without scenarios there is nothing to sweep and nothing to check.
        assert!(validate(&design(BASE).unwrap()).is_ok());
    }

    #[test]
    fn a_missing_catalogue_names_the_design_field() {
        let d = design(&format!("catalog = \"nowhere.toml\"\n{BASE}")).unwrap();
        let err = validate(&d).unwrap_err().to_string();
        assert!(err.contains("t.toml") && err.contains("field `catalog`") && err.contains("nowhere.toml"), "{err}");
    }

    #[test]
    fn degrees_typed_as_radians_and_a_far_centre_of_mass_are_warned() {
        let text = BASE
            .replace("q = [0.0, \"pi/2\"]", "q = [0.0, 90.0]")
            .replace("com = 1.0\ninertia = 1.0\n[equilibrium]", "com = 5.0\ninertia = 1.0\n[equilibrium]");
        let d = design(&text).unwrap();
        let w = validate(&d).unwrap().warnings;
        let fields: Vec<&str> = w.iter().map(|w| w.field.as_str()).collect();
        assert!(fields.contains(&"equilibrium.q[1]"), "{w:?}");
        assert!(fields.contains(&"robot.links[1].com"), "{w:?}");
        assert!(validate(&design(BASE).unwrap()).unwrap().warnings.is_empty());
    }
}
