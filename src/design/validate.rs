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

use crate::design::FitSettings;
use std::path::Path;

use crate::design::Design;
use crate::design::scenario::ModeSpec;
use crate::design::tolerance::ToleranceSpec;
use crate::elements::catalog::Catalog;
use crate::error::{Error, Result};
use crate::geodesic::Region;

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
        crate::design::validate::check_trimmed_weight(design, c, &design.fit)?;
        check_fit_memory(design, c, crate::limits::available_memory())?;
    }
    for (i, sc) in design.scenarios.iter().enumerate() {
        sc.check(i, design)?;
    }
    // The sweep scenario a `[sweep]` table names must exist; without the table the default one
    // (`sensitivity`) missing is only worth a warning: the design may never be swept, and
    // `springfit sweep` refuses it with the same message.
    let mut warnings = Vec::new();
    if !design.scenarios.is_empty()
        && let Err(e) = sweep_scenario(design)
    {
        if design.sweep_given {
            return Err(e);
        }
        warnings.push(Warning {
                path: design.path.clone(),
                field: "sweep.scenario".into(),
                message: format!(
                    "no [[scenario]] named `{}`: `springfit sweep` will refuse this design until a [sweep] table names one of its scenarios",
                    design.sweep.scenario
                ),
            });
    }
    suspicious(design, &mut warnings);
    Ok(Validated { catalog, warnings })
}

/// Bytes the fit's problem takes at most, and what they are, in words for the error. With the
/// rows kept: the weighted rows (one per training sample and direction of [γ̇]^⊥, n − 1 per
/// sample) × the candidates twice (the rows, and the tables or transpose the normal equations are
/// formed from), and the Gram matrix, in f64. `ur5_six` with 1152 training directions: 4.33 GiB
/// by this count, 4.28 GiB peak resident measured when the rows were still copied. Where the
/// normal equations come from the rows' factors and nothing reads the rows
/// ([`crate::solve::lsq::RowsOut::for_fit`], the rule the fit keeps them by): one factor per
/// row and coupling of the catalogue, and the Gram matrix with the
/// [`crate::solve::lsq::GRAM_WAVE`] partial sums and the copy it is formed in. Cams without a
/// tolerance: the rows' non-zeros
/// ([`Catalog::row_nonzero_bound`] per row) with their column indices. An upper bound each way
/// (every coupling counted once per family that names it).
pub fn fit_memory(design: &Design, catalog: &Catalog) -> (u64, &'static str, String) {
    use crate::solve::lsq::{GRAM_WAVE, RowsOut};
    let s = &design.fit;
    let (n, per) = (design.dof(), design.dof().max(2) as u64 - 1);
    let rows = (s.training_count(n) as u64) * (s.training_samples as u64 + 1) * per;
    let columns = catalog.candidate_bound as u64;
    let grouped = catalog.families.iter().any(|f| f.cam.is_some());
    let trims = catalog.families.iter().any(|f| f.trim_range.is_some());
    let sizes =
        format!("{} training directions × {} samples × {per} rows per sample", s.training_count(n), s.training_samples);
    let of = format!("of {}", catalog.path.display());
    let out = RowsOut::for_fit(n, rows as usize, grouped, trims, s.tolerance != ToleranceSpec::None);
    if out == RowsOut::ProductOnly {
        let couplings = (catalog.families.iter().map(|f| f.couplings.len()).sum::<usize>() as u64).min(columns);
        let bytes = 8 * (rows * couplings + (2 + GRAM_WAVE as u64) * columns * columns);
        let details = format!(
            "{sizes} × up to {couplings} couplings, and {} matrices of {columns} × {columns} candidates {of}, 8 bytes each",
            2 + GRAM_WAVE
        );
        return (bytes, "row factors and normal equations", details);
    }
    if out == RowsOut::Sparse {
        // Written as their non-zeros (a value and a column index each); the Gram matrix twice.
        let nonzeros = catalog.row_nonzero_bound.min(catalog.candidate_bound) as u64;
        let bytes = 16 * rows * nonzeros + 16 * columns * columns;
        let details = format!(
            "{sizes} × up to {nonzeros} non-zero of {columns} candidates {of}, 16 bytes each, and the normal equations"
        );
        return (bytes, "sparse rows", details);
    }
    let bytes = 8 * (2 * rows * columns + columns * columns);
    let details = format!(
        "{sizes} × up to {columns} candidates {of}, 8 bytes each, held twice while the normal equations are formed"
    );
    (bytes, "dense rows", details)
}

/// Refuses a design whose fit would not fit in `available` bytes, naming the keys that size it.
pub fn check_fit_memory(design: &Design, catalog: &Catalog, available: u64) -> Result<()> {
    let (need, what, details) = fit_memory(design, catalog);
    if need > available {
        let gib = |b: u64| format!("{:.1} GiB", b as f64 / (1u64 << 30) as f64);
        return Err(Error::invalid(
            &design.path,
            "fit.training_samples",
            format!(
                "the fit's {what} would take {} ({details}) and this machine has {} available: lower fit.training_directions or fit.training_samples, or use a smaller catalogue",
                gib(need),
                gib(available)
            ),
        ));
    }
    Ok(())
}

/// The index of the `[sweep] scenario`, or an error listing the scenarios the design has.
pub fn sweep_scenario(design: &Design) -> Result<usize> {
    let name = &design.sweep.scenario;
    design.scenarios.iter().position(|s| &s.name == name).ok_or_else(|| {
        let have: Vec<&str> = design.scenarios.iter().map(|s| s.name.as_str()).collect();
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
    // The path as the design file wrote it: the design resolved it against its own folder.
    let folder = design.path.parent().unwrap_or(Path::new("."));
    let written = path.strip_prefix(folder).unwrap_or(path).display();
    if path.is_dir() {
        return Err(Error::invalid(
            &design.path,
            "catalog",
            format!("`{written}` is a folder ({}): name the catalogue's TOML file in it", path.display()),
        ));
    }
    if !path.is_file() {
        return Err(Error::invalid(
            &design.path,
            "catalog",
            format!(
                "`{written}` names no file ({} does not exist; the path is relative to the design file)",
                path.display()
            ),
        ));
    }
    let catalog = Catalog::load_for(path, &design.chain.joint_names())?;
    // A tendon family's stocked pulleys must be ones the design's `[parts]` allows.
    let p = &design.parts;
    catalog.check_pulleys(p.min_pulley_radius_mm, p.max_pulley_radius_mm, p.max_joints_crossed)?;
    Ok(catalog)
}

/// A link heavier than this per metre of its length is heavier than a solid steel bar 0.18 m
/// across (7850 kg/m³), far beyond an arm one balances with springs: probably grams typed as
/// kilograms, or millimetres as metres.
pub const MAX_PLAUSIBLE_KG_PER_M: f64 = 200.0;

/// Warnings about a planar link's units, as `q = 90` is warned about: a mass too heavy for its
/// length, an inertia about the centre of mass above m·L² (a thin ring of radius L has m·L²;
/// a rod m·L²/12), which usually means g·cm² or kg·mm² typed as kg·m², or an inertia about the
/// joint given where the centre of mass's is read.
fn implausible_units(i: usize, l: &crate::model::Link, warn: &mut impl FnMut(String, String)) {
    let per_m = l.mass / l.length;
    if per_m > MAX_PLAUSIBLE_KG_PER_M {
        warn(
            format!("robot.links[{i}].mass"),
            format!(
                "{} kg for a link {} m long is {per_m:.0} kg per metre, heavier than a solid steel bar 0.18 m across: \
                 masses are in kg and lengths in m (grams or millimetres typed?)",
                l.mass, l.length
            ),
        );
    }
    let ml2 = l.mass * l.length * l.length;
    if l.inertia > ml2 {
        warn(
            format!("robot.links[{i}].inertia"),
            format!(
                "{} kg·m² about the centre of mass is above m·L² = {ml2:.4} kg·m² (a rod has m·L²/12 = {:.4}): \
                 inertia is in kg·m² about the centre of mass (g·cm² or kg·mm² typed?)",
                l.inertia,
                ml2 / 12.0
            ),
        );
    }
}

/// Legal input that is probably a mistake.
fn suspicious(design: &Design, out: &mut Vec<Warning>) {
    let mut warn = |field: String, message: String| {
        out.push(Warning { path: design.path.clone(), field, message });
    };
    let turns = |a: f64| a.abs() / std::f64::consts::TAU;
    let names = design.chain.joint_names();
    for (i, range) in design.joint_ranges.iter().enumerate() {
        if *range == crate::model::urdf::JointRange::Unstated {
            warn(
                format!("robot.joints[{i}]"),
                format!(
                    "joint `{}` is revolute but its <limit> gives no range (lower = upper): springfit assumes it turns without a stop; add lower and upper to the URDF's <limit> if it has one, so the region is checked against them",
                    names.get(i).map_or("?", String::as_str)
                ),
            );
        }
    }
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
        Region::Ball { radius } | Region::Clipped { radius, .. } => {
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
    let links = design.chain.planar().map(|c| c.links()).unwrap_or_default();
    for (i, l) in links.iter().enumerate() {
        implausible_units(i, l, &mut warn);
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
    if design.chain.spatial().is_some_and(|c| c.gravity() == [0.0; 3]) {
        warn(
            "robot.gravity".into(),
            "is missing or zero: the URDF's arm runs in zero gravity; give the base frame's acceleration, e.g. \
             gravity = [0.0, 0.0, -9.81] for z up (set [0.0, 0.0, 0.0] and ignore this for an arm in free fall)"
                .into(),
        );
    }
    for (k, sc) in design.scenarios.iter().enumerate() {
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
            if let ModeSpec::Angle(a) = m
                && a.abs() > MANY_TURNS_RAD
            {
                warn(
                    format!("scenario[{k}].{f}"),
                    format!("the mode angle θ = {a} rad is {:.1} turns: angles are in radians", turns(*a)),
                );
            }
        }
        if let Some(s) = sc.step
            && s.0.abs() > MANY_TURNS_RAD
        {
            warn(
                format!("scenario[{k}].step"),
                format!("{} rad is {:.1} turns: angles are in radians", s.0, turns(s.0)),
            );
        }
    }
}

/// `trimmed_weight` weighs trimmed builds: refused (naming the field) when the catalogue has no
/// trim springs, where there is nothing to trim. `springfit check` refuses it too.
pub fn check_trimmed_weight(design: &Design, catalog: &Catalog, settings: &FitSettings) -> Result<()> {
    if settings.trimmed_weight > 0.0 && !catalog.families.iter().any(|f| f.trim_range.is_some()) {
        return Err(Error::invalid(
            &design.path,
            "fit.trimmed_weight",
            format!(
                "weighs trimmed builds, but the catalogue {} has no trim springs (`trim = true`): set it to 0 or add trims",
                catalog.path.display()
            ),
        ));
    }
    Ok(())
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

    /// The fit's memory is judged before any work: the default design's ~2900 rows × ~420
    /// candidates are about 10 MB; the same design at 100 000 × 20 samples with a budget of 1
    /// GiB is refused, naming the keys.
    #[test]
    fn a_fit_too_large_for_the_memory_is_refused_with_its_size() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let design = Design::load(&root.join("designs/double_pendulum.toml")).unwrap();
        let catalog = Catalog::load(design.catalog.as_ref().unwrap(), 2).unwrap();
        let (need, _, _) = fit_memory(&design, &catalog);
        assert!(need > 5_000_000 && need < 50_000_000, "{need}");
        check_fit_memory(&design, &catalog, 1 << 30).unwrap();
        let mut big = design.clone();
        big.fit.training_directions = 100_000;
        big.fit.training_samples = 20;
        let err = check_fit_memory(&big, &catalog, 1 << 30).unwrap_err().to_string();
        assert!(
            err.contains("fit.training_samples") && err.contains("GiB") && err.contains("1.0 GiB available"),
            "{err}"
        );
    }

    /// Where the normal equations come from the rows' factors and nothing reads the rows, the fit
    /// keeps no dense rows and the check counts the factors (and for cams the non-zeros): the six-joint UR5 at its 576 × 41
    /// samples × 5 rows needs a fifth of a GiB (0.37 GB peak resident measured for the whole
    /// fit), not the 2.4 GiB of its dense rows, which a tolerance-aware fit still keeps.
    #[test]
    fn a_fit_from_the_rows_factors_is_judged_by_them() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let design = Design::load(&root.join("designs/ur5_six.toml")).unwrap();
        let catalog = Catalog::load(design.catalog.as_ref().unwrap(), 6).unwrap();
        let (factored, what, _) = fit_memory(&design, &catalog);
        assert_eq!(what, "row factors and normal equations");
        assert!(factored > 100 << 20 && factored < 300 << 20, "{factored}");
        let mut tolerant = design.clone();
        tolerant.fit.tolerance = ToleranceSpec::Fraction(0.05);
        let (dense, what, _) = fit_memory(&tolerant, &catalog);
        assert_eq!(what, "dense rows");
        assert!(dense > 8 * factored, "{dense} against {factored}");
        let err = check_fit_memory(&design, &catalog, 100 << 20).unwrap_err().to_string();
        assert!(err.contains("row factors") && err.contains("156 couplings"), "{err}");
        // Forty cams: 8 of each cam's 64 columns are non-zero in a row (0.73 GB peak measured
        // for the whole fit, against 4.6 GiB of dense rows counted twice).
        // (The UR5 of `ur5_six.toml` with the cams of the withdrawn `ur5_six_cams` design.)
        let design = Design::load(&root.join("designs/ur5_six.toml")).unwrap();
        let catalog = Catalog::load(&root.join("catalogs/ur5_cams_pursuit.toml"), 6).unwrap();
        assert_eq!((catalog.candidate_bound, catalog.row_nonzero_bound), (2560, 320));
        let (sparse, what, _) = fit_memory(&design, &catalog);
        assert_eq!(what, "sparse rows");
        assert!(sparse > 400 << 20 && sparse < 800 << 20, "{sparse}");
    }
}
