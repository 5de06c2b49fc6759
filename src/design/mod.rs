//! Design files: the robot, the equilibrium, the region and the settings of every step.
//!
//! A design is a TOML file read in two steps: [`DesignFile`] mirrors the file exactly
//! (`deny_unknown_fields` everywhere, so a misspelt key is an error, not a silent default), then
//! [`Design::from_file`] validates it and resolves it into the types the library computes with.
//! Every error names the file and the field (or the line and column for TOML syntax).
//!
//! ```toml
//! name = "double_pendulum"
//! catalog = "../catalogs/paper.toml"   # relative to this file
//!
//! [robot]
//! gravity = [0.0, 0.0]                 # m/s², in the plane of the arm
//! [[robot.links]]
//! mass = 1.0                           # kg
//! length = 2.0                         # m
//! com = 1.0                            # m from the joint
//! inertia = 1.0                        # kg·m² about the centre of mass
//! [[robot.links]]
//! mass = 1.0
//! length = 2.0
//! com = 1.0
//! inertia = 1.0
//!
//! [equilibrium]
//! q = [0.0, "pi/2"]                    # rad
//!
//! [region]
//! kind = "ball"                        # or "box" with lower = [...], upper = [...]
//! radius = 2.0
//! ```

pub mod controllers;
pub mod file;
pub mod fit;
pub mod identify;
pub mod parts;
pub mod scenario;
pub mod simulate;
pub mod sweep;
pub mod tolerance;
pub mod validate;

pub use file::{DesignFile, EquilibriumSpec, LinkSpec, RegionKind, RegionSpec, RobotSpec};

use std::path::{Path, PathBuf};

use nalgebra::DVector;

use crate::design::controllers::ControllerSettings;
use crate::design::fit::FitSettings;
use crate::design::identify::IdentifySettings;
use crate::design::parts::PartsSettings;
use crate::design::scenario::ScenarioSpec;
use crate::design::simulate::SimSettings;
use crate::design::sweep::SweepSettings;
use crate::error::{Error, Result};
use crate::geodesic::region::{JointLimits, check_region_within};
use crate::geodesic::{GeodesicSettings, Region, RegionReport};
/// For callers that edit a design's text before [`Design::parse`] (the Python package's keyword
/// overrides), with the errors the design loader gives.
///
pub use crate::input::{parse_toml, read_text};
use crate::limits::{MAX_GRAVITY, MAX_INERTIA_KGM2, MAX_LENGTH_M, MAX_LINKS, MAX_MASS_KG, within};
use crate::model::urdf::JointRange;
use crate::model::{Chain, Link, PlanarChain, SpatialChain};
use crate::units::Angle;

/// The default `[equilibrium] bill_tolerance`, rad: how far a bill's springs may miss q_eq, as
/// |∇U(q_eq)| (springs and gravity) over the design's stiffness ‖ω²M(q_eq)‖. Every fitted bill
/// of the shipped designs holds q_eq to 1e-5 or better (the QP to round-off, NNLS by its weighted
/// equalities), while one offset typed in degrees misses it by tenths of a radian or more.
pub const BILL_TOLERANCE: f64 = 1e-3;

/// A validated design, ready to compute with.
#[derive(Debug, Clone)]
pub struct Design {
    /// Where it was read from (for messages).
    pub path: PathBuf,
    /// Fingerprint of the text it was parsed from (FNV-1a, 64-bit, as 16 hexadecimal digits; empty for a
    /// design built from a parsed [`DesignFile`]): output folders record it so that another
    /// design does not replace a design's results.
    pub fingerprint: String,
    /// Name for outputs.
    pub name: String,
    /// One line about it.
    pub description: String,
    /// Resolved catalogue path, if the design names one.
    pub catalog: Option<PathBuf>,
    /// The arm.
    pub chain: Chain,
    /// The equilibrium.
    pub q_eq: DVector<f64>,
    /// What each moving joint's `<limit>` allows (a planar arm's joints turn freely).
    pub joint_ranges: Vec<JointRange>,
    /// The region.
    pub region: Region,
    /// Geodesic settings.
    pub geodesics: GeodesicSettings,
    /// Fit settings.
    pub fit: FitSettings,
    /// Simulation settings.
    pub simulate: SimSettings,
    /// Controller gains.
    pub controllers: ControllerSettings,
    /// `[[scenario]]`: the simulation scenarios, in file order (resolved against the fit when
    /// one runs, since starts and energies may depend on the fitted potential).
    pub scenarios: Vec<ScenarioSpec>,
    /// `[sweep]`: what the sensitivity sweeps vary.
    pub sweep: SweepSettings,
    /// Whether the file has a `[sweep]` table: a sweep scenario the user named and the design
    /// lacks is an error, the default one missing only a warning (a design may never be swept).
    pub sweep_given: bool,
    /// `[identify]`: how a built arm is identified from logged motion.
    pub identify: IdentifySettings,
    /// `[parts]`: how the fitted elements become springs to wind or order.
    pub parts: PartsSettings,
    /// `[equilibrium] bill_tolerance`: how far, in rad at the design's stiffness, the springs of
    /// a bill a command reads may miss q_eq ([`crate::jobs::check_equilibrium`]).
    pub bill_tolerance: f64,
    /// The last region check, with what it was computed from (see [`Design::region_report`]).
    region_memo: std::sync::OnceLock<RegionMemo>,
}

/// A region report and the inputs it depends on besides the arm: the chain is fixed once a design
/// is loaded, while a caller may change the region on a copy (e.g. to probe a larger radius).
#[derive(Debug, Clone)]
struct RegionMemo {
    q_eq: DVector<f64>,
    region: Region,
    geodesics: GeodesicSettings,
    report: RegionReport,
}

impl Design {
    /// Reads and validates a design file.
    pub fn load(path: &Path) -> Result<Design> {
        Design::parse(path, &read_text(path)?)
    }

    /// Parses and validates the text of a design file (what [`Design::load`] does once the file
    /// is read). `path` is used for messages and to resolve the catalogue. Never panics: every
    /// problem in `text` is an [`Error`].
    pub fn parse(path: &Path, text: &str) -> Result<Design> {
        let mut file: DesignFile = parse_toml(path, text)?;
        let table = toml::from_str::<toml::Table>(text).ok();
        file.sweep_given = table.as_ref().is_some_and(|t| t.contains_key("sweep"));
        file.fit.auto = crate::design::fit::AutoWeights::of_table(
            table.as_ref().and_then(|t| t.get("fit")).and_then(|f| f.as_table()),
        );
        let given = crate::design::fit::GivenWeights::of_table(
            table.as_ref().and_then(|t| t.get("fit")).and_then(|f| f.as_table()),
        );
        let mut design = Design::from_file(path, file)?;
        design.fingerprint = crate::input::fingerprint(text.as_bytes());
        // The weights' defaults depend on whether the catalogue has trim springs. A catalogue
        // that does not load is reported by `validate`, which every command runs next.
        let trims = design.catalog.as_ref().is_some_and(|c| {
            crate::elements::catalog::Catalog::load_for(c, &design.chain.joint_names())
                .is_ok_and(|c| c.families.iter().any(|f| f.trim_range.is_some()))
        });
        design.fit = design.fit.with_trim_defaults(given, trims);
        Ok(design)
    }

    /// Validates a parsed design file. `path` is used for messages and to resolve the catalogue.
    pub fn from_file(path: &Path, file: DesignFile) -> Result<Design> {
        let (chain, q_eq, ranges) = if file.robot.urdf.is_some() {
            let (chain, q_eq, ranges) = urdf_robot(path, &file)?;
            (Chain::Spatial(chain), q_eq, ranges)
        } else {
            let (chain, q_eq) = planar_robot(path, &file)?;
            let n = chain.dof();
            (Chain::Planar(chain), q_eq, vec![JointRange::Unlimited; n])
        };
        Design::with_robot(path, file, chain, q_eq, ranges)
    }

    /// The rest of the validation, the same for every kind of robot: region and settings.
    fn with_robot(
        path: &Path,
        file: DesignFile,
        chain: Chain,
        q_eq: DVector<f64>,
        joint_ranges: Vec<JointRange>,
    ) -> Result<Design> {
        let invalid = |field: &str, reason: String| Error::invalid(path, field, reason);
        let names = chain.joint_names();
        check_equilibrium_within(path, &q_eq, &joint_ranges, &names)?;
        let region = region(path, file.region.as_ref(), chain.dof(), &q_eq)?;
        let region = within_limits(path, file.region.as_ref(), region, &joint_ranges, &names)?;
        file.geodesics.validate().map_err(|(field, reason)| invalid(&field, reason))?;
        if let Some(radius) = region.radius() {
            // Geodesics are traced no further than max_arc: a larger ball cannot be checked or
            // fitted, and tracing towards it would run for minutes before failing.
            if radius > file.geodesics.max_arc {
                return Err(invalid(
                    "region.radius",
                    format!(
                        "{radius:e} is beyond geodesics.max_arc = {} (the longest geodesic springfit traces); a region \
                         is a few units of metric arc length (the paper's is 2)",
                        file.geodesics.max_arc
                    ),
                ));
            }
        }
        check_sections(path, &file, &chain, &q_eq)?;
        let bill_tolerance = file.equilibrium.bill_tolerance.unwrap_or(BILL_TOLERANCE);
        if !(bill_tolerance.is_finite() && bill_tolerance > 0.0) {
            return Err(invalid(
                "equilibrium.bill_tolerance",
                format!("{bill_tolerance} must be a positive angle in rad (default {BILL_TOLERANCE})"),
            ));
        }
        let name = file.name.clone().unwrap_or_else(|| {
            path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "design".into())
        });
        if name.is_empty() || name.contains(['/', '\\']) || name == "." || name == ".." {
            return Err(invalid("name", format!("`{name}` cannot name an output folder")));
        }
        let catalog = file.catalog.as_ref().map(|c| path.parent().unwrap_or(Path::new(".")).join(c));
        let mut controllers = file.controllers.clone();
        controllers.derive_from_arm(&controllers::ArmScale {
            mass: chain.mass_matrix(&q_eq).transpose().as_slice().to_vec(),
            omega: file.fit.frequency,
            energy: scenario::gain_energy(&file.scenario),
            paper_form: match controllers.inertia {
                controllers::ModeInertia::Paper => true,
                controllers::ModeInertia::Consistent => false,
                controllers::ModeInertia::Auto => scenario::theta_law(chain.dof(), &file.scenario),
            },
        });
        Ok(Design {
            path: path.to_path_buf(),
            fingerprint: String::new(),
            name,
            description: file.description.clone().unwrap_or_default(),
            catalog,
            chain,
            q_eq,
            joint_ranges,
            region,
            geodesics: file.geodesics,
            fit: file.fit,
            simulate: file.simulate,
            controllers,
            scenarios: file.scenario,
            sweep: file.sweep,
            sweep_given: file.sweep_given,
            identify: file.identify,
            parts: file.parts,
            bill_tolerance,
            region_memo: std::sync::OnceLock::new(),
        })
    }

    /// Whether this is the paper's arm (its double pendulum without gravity, at the paper's
    /// equilibrium q = (0, π/2)): only then do the paper's own figures compare with ours.
    pub fn is_paper_arm(&self) -> bool {
        let paper = crate::model::PlanarChain::paper_double_pendulum();
        let same_arm =
            self.chain.planar().is_some_and(|c| c.links() == paper.links() && c.gravity() == paper.gravity());
        same_arm && self.q_eq.as_slice() == [0.0, std::f64::consts::FRAC_PI_2]
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.chain.dof()
    }

    /// Checks the region: where exp is one-to-one and the largest valid geodesic-ball radius.
    ///
    /// The check traces Jacobi fields over the whole region (about 0.1 s for the default design)
    /// and the fit, the label, `tune` and every build of a sweep ask for it, so the first report
    /// is kept and handed out again while q_eq, the region and the geodesic settings are those
    /// it was computed from (a copy with another region checks afresh).
    pub fn region_report(&self) -> Result<RegionReport> {
        if let Some(m) = self.region_memo.get()
            && m.q_eq == self.q_eq
            && m.region == self.region
            && m.geodesics == self.geodesics
        {
            return Ok(m.report.clone());
        }
        // A numerical failure deep in the check (Jacobi fields, the integrator) names the design
        // and the step, so the message says what it concerns.
        let limits = self.joint_limits();
        let report = check_region_within(&self.chain, &self.q_eq, &self.region, &self.geodesics, limits.as_ref())
            .map_err(|e| match e {
                Error::Numerical { context, reason } => Error::Numerical {
                    context: format!("{}: region check ({})", self.path.display(), self.region.describe()),
                    reason: format!("{context}: {reason}"),
                },
                other => other,
            })?;
        let _ = self.region_memo.set(RegionMemo {
            q_eq: self.q_eq.clone(),
            region: self.region.clone(),
            geodesics: self.geodesics,
            report: report.clone(),
        });
        Ok(report)
    }

    /// The moving joints' limits, when any joint has one (None for an arm that turns freely).
    pub fn joint_limits(&self) -> Option<JointLimits> {
        if !self.joint_ranges.iter().any(|r| matches!(r, JointRange::Limited { .. })) {
            return None;
        }
        let (lower, upper): (Vec<f64>, Vec<f64>) = self.joint_ranges.iter().map(JointRange::bounds).unzip();
        Some(JointLimits {
            lower: DVector::from_vec(lower),
            upper: DVector::from_vec(upper),
            names: self.chain.joint_names(),
        })
    }

    /// The region report, or an error naming the region field when the region is not valid.
    pub fn valid_region(&self) -> Result<RegionReport> {
        let report = self.region_report()?;
        self.ensure_valid(&report)?;
        Ok(report)
    }

    /// An error naming the region field when `report` says the region is not valid.
    pub fn ensure_valid(&self, report: &RegionReport) -> Result<()> {
        if report.valid {
            return Ok(());
        }
        let field = match self.region {
            Region::Ball { .. } | Region::Clipped { .. } => "region.radius",
            Region::Box { .. } => "region",
        };
        Err(Error::invalid(&self.path, field, format!("the region is not valid: {}", report.reason)))
    }
}

/// A planar arm typed into the design: its links checked one by one, the chain, its mass
/// matrix finite and invertible at zero, and the equilibrium with the mass matrix finite and
/// invertible there too.
fn planar_robot(path: &Path, file: &DesignFile) -> Result<(PlanarChain, DVector<f64>)> {
    let invalid = |field: &str, reason: String| Error::invalid(path, field, reason);
    if !file.robot.joints.is_empty() || !file.robot.locked.is_empty() {
        let field = if file.robot.joints.is_empty() { "robot.locked" } else { "robot.joints" };
        return Err(invalid(field, "names URDF joints: it needs robot.urdf".into()));
    }
    let gravity = match file.robot.gravity[..] {
        [] => [0.0, 0.0],
        [x, y] => [x, y],
        _ => {
            return Err(invalid(
                "robot.gravity",
                format!("has {} numbers: a planar arm takes 2 (in its plane)", file.robot.gravity.len()),
            ));
        }
    };
    let links = &file.robot.links;
    check_links(path, links)?;
    for (k, g) in file.robot.gravity.iter().enumerate() {
        within(*g, MAX_GRAVITY, " m/s²").map_err(|r| invalid(&format!("robot.gravity[{k}]"), r))?;
    }
    let n = links.len();
    let chain = PlanarChain::new(
        links.iter().map(|l| Link { mass: l.mass, length: l.length, com: l.com, inertia: l.inertia }).collect(),
        gravity,
    );
    // The gravity potential, torque and Hessian are bounded by this (with room for their sums).
    if !(16.0 * chain.gravity_bound()).is_finite() {
        return Err(invalid(
            "robot.gravity",
            "the gravity potential overflows: gravity times the links' masses and lengths is too large".into(),
        ));
    }
    let m = chain.mass_matrix(&DVector::zeros(n));
    check_mass_matrix(path, &m)?;
    let scale = m.amax();
    if m.clone().cholesky().is_none() || m.symmetric_eigen().eigenvalues.min() <= 1e-12 * scale {
        return Err(singular_mass_matrix(path));
    }
    let q = &file.equilibrium.q;
    if q.len() != n {
        return Err(invalid("equilibrium.q", format!("has {} angles but the robot has {n} joints", q.len())));
    }
    let q_eq = DVector::from_iterator(n, q.iter().map(|a| a.0));
    // M and U_g take sums of joint angles: finite angles of 1e308 rad still overflow.
    if !chain.link_angles(q_eq.as_slice()).iter().all(|phi| phi.is_finite()) {
        return Err(invalid("equilibrium.q", "the angles are too large: their sums overflow".into()));
    }
    // Everything downstream starts at the equilibrium: M must be finite and invertible there too.
    let m_eq = chain.mass_matrix(&q_eq);
    check_mass_matrix(path, &m_eq)?;
    if m_eq.cholesky().is_none() {
        return Err(singular_mass_matrix(path));
    }
    Ok((chain, q_eq))
}

/// A planar arm's links: one to MAX_LINKS of them, each with finite values within the limits,
/// a positive mass and length and an inertia ≥ 0.
fn check_links(path: &Path, links: &[LinkSpec]) -> Result<()> {
    let invalid = |field: &str, reason: String| Error::invalid(path, field, reason);
    if links.is_empty() {
        return Err(invalid(
            "robot.links",
            "at least one link is needed ([[robot.links]] with mass, length, com, inertia)".into(),
        ));
    }
    if links.len() > MAX_LINKS {
        return Err(invalid(
            "robot.links",
            format!("{} links: springfit handles chains of up to {MAX_LINKS} links", links.len()),
        ));
    }
    for (i, l) in links.iter().enumerate() {
        let f = |name: &str| format!("robot.links[{i}].{name}");
        let finite = |v: f64, name: &str| -> Result<()> {
            if v.is_finite() { Ok(()) } else { Err(invalid(&f(name), format!("must be a finite number, got {v}"))) }
        };
        finite(l.mass, "mass")?;
        finite(l.length, "length")?;
        finite(l.com, "com")?;
        finite(l.inertia, "inertia")?;
        for (name, v, max, unit) in [
            ("mass", l.mass, MAX_MASS_KG, " kg"),
            ("length", l.length, MAX_LENGTH_M, " m"),
            ("com", l.com, MAX_LENGTH_M, " m"),
            ("inertia", l.inertia, MAX_INERTIA_KGM2, " kg·m²"),
        ] {
            within(v, max, unit).map_err(|r| invalid(&f(name), r))?;
        }
        if l.mass <= 0.0 {
            return Err(invalid(&f("mass"), format!("must be positive (kg), got {}", l.mass)));
        }
        if l.length <= 0.0 {
            return Err(invalid(&f("length"), format!("must be positive (m), got {}", l.length)));
        }
        if l.inertia < 0.0 {
            return Err(invalid(&f("inertia"), format!("must be ≥ 0 (kg·m²), got {}", l.inertia)));
        }
    }
    Ok(())
}

/// Finite inputs can still overflow: M holds products such as mass·length², so a link of
/// 1e160 m has an infinite mass matrix.
fn check_mass_matrix(path: &Path, m: &nalgebra::DMatrix<f64>) -> Result<()> {
    if !m.iter().all(|x| x.is_finite()) {
        return Err(Error::invalid(
            path,
            "robot.links",
            "the mass matrix overflows: the links' masses, lengths, centres of mass or inertias are too large",
        ));
    }
    Ok(())
}

/// A link with zero inertia and its centre of mass on the joint axis adds nothing to M; the
/// outermost such link would make M singular.
fn singular_mass_matrix(path: &Path) -> Error {
    Error::invalid(
        path,
        "robot.links",
        "the mass matrix is singular: a link has neither inertia nor a centre of mass off its joint axis",
    )
}

/// The region of `[region]` for an arm of n joints: a ball of positive radius, or a box of n angles a side whose
/// corners are within ±10⁴ rad, below one another and around the equilibrium.
fn region(path: &Path, spec: Option<&RegionSpec>, n: usize, q_eq: &DVector<f64>) -> Result<Region> {
    let invalid = |field: &str, reason: String| Error::invalid(path, field, reason);
    let spec = spec.ok_or_else(|| {
        invalid(
            "region",
            "missing: add [region] with kind = \"ball\" and radius, or kind = \"box\" with lower and upper".into(),
        )
    })?;
    match spec.kind {
        RegionKind::Ball => {
            if spec.lower.is_some() || spec.upper.is_some() {
                return Err(invalid("region", "lower/upper belong to kind = \"box\"; a ball has only radius".into()));
            }
            let r = spec.radius.ok_or_else(|| invalid("region.radius", "required for kind = \"ball\"".into()))?;
            if !(r.is_finite() && r > 0.0) {
                return Err(invalid("region.radius", format!("must be positive, got {r}")));
            }
            Ok(Region::Ball { radius: r })
        }
        RegionKind::Box => {
            if spec.radius.is_some() {
                return Err(invalid("region.radius", "belongs to kind = \"ball\"; a box has lower and upper".into()));
            }
            let get = |v: &Option<Vec<Angle>>, name: &str| -> Result<DVector<f64>> {
                let v = v
                    .as_ref()
                    .ok_or_else(|| invalid(&format!("region.{name}"), "required for kind = \"box\"".into()))?;
                if v.len() != n {
                    return Err(invalid(
                        &format!("region.{name}"),
                        format!("has {} angles but the robot has {n} joints", v.len()),
                    ));
                }
                Ok(DVector::from_iterator(n, v.iter().map(|a| a.0)))
            };
            let (lower, upper) = (get(&spec.lower, "lower")?, get(&spec.upper, "upper")?);
            check_box(path, &lower, &upper, q_eq)?;
            Ok(Region::Box { lower, upper })
        }
    }
}

/// A box's corners, joint by joint: within ±10⁴ rad, lower below upper, the equilibrium
/// strictly between them.
fn check_box(path: &Path, lower: &DVector<f64>, upper: &DVector<f64>, q_eq: &DVector<f64>) -> Result<()> {
    let invalid = |field: &str, reason: String| Error::invalid(path, field, reason);
    for i in 0..lower.len() {
        if lower[i].abs() > 1e4 || upper[i].abs() > 1e4 {
            return Err(invalid(
                &format!("region.lower[{i}]"),
                format!("box corners beyond ±10⁴ rad ({} … {}) are not a region of an arm", lower[i], upper[i]),
            ));
        }
        if lower[i] >= upper[i] {
            return Err(invalid(
                &format!("region.lower[{i}]"),
                format!("must be below region.upper[{i}] ({} ≥ {})", lower[i], upper[i]),
            ));
        }
        if !(lower[i] < q_eq[i] && q_eq[i] < upper[i]) {
            return Err(invalid(
                &format!("equilibrium.q[{i}]"),
                format!(
                    "{} lies outside the region: q{} must be strictly between {} and {}",
                    q_eq[i],
                    i + 1,
                    lower[i],
                    upper[i]
                ),
            ));
        }
    }
    Ok(())
}

/// Every settings section checked by its own `validate` (the controllers' torque limits against
/// the torque that holds the arm at q_eq), and the scenarios' names unique.
fn check_sections(path: &Path, file: &DesignFile, chain: &Chain, q_eq: &DVector<f64>) -> Result<()> {
    let invalid = |field: &str, reason: String| Error::invalid(path, field, reason);
    file.fit.validate().map_err(|(field, reason)| invalid(&field, reason))?;
    file.simulate.validate().map_err(|(field, reason)| invalid(&field, reason))?;
    file.controllers.validate().map_err(|(field, reason)| invalid(&field, reason))?;
    let mut holding = vec![0.0; chain.dof()];
    chain.gravity_gradient_into(q_eq.as_slice(), &mut holding);
    file.controllers.check_max_torque(&holding).map_err(|(field, reason)| invalid(&field, reason))?;
    file.sweep.validate().map_err(|(field, reason)| invalid(&field, reason))?;
    file.identify.validate().map_err(|(field, reason)| invalid(&field, reason))?;
    file.parts.validate().map_err(|(field, reason)| invalid(&field, reason))?;
    let mut names = std::collections::HashSet::new();
    for (i, sc) in file.scenario.iter().enumerate() {
        if !names.insert(sc.name.clone()) {
            return Err(invalid(
                &format!("scenario[{i}].name"),
                format!("`{}` is used by an earlier scenario", sc.name),
            ));
        }
    }
    Ok(())
}

/// `[robot] urdf = …`: reads the URDF (relative to the design file) and checks the equilibrium.
/// Kept apart from the planar links' validation: the two kinds of robot share only what follows.
fn urdf_robot(path: &Path, file: &DesignFile) -> Result<(SpatialChain, DVector<f64>, Vec<JointRange>)> {
    let invalid = |field: &str, reason: String| Error::invalid(path, field, reason);
    let robot = &file.robot;
    if !robot.links.is_empty() {
        return Err(invalid("robot.links", "a design takes robot.urdf or [[robot.links]], not both".into()));
    }
    if robot.joints.is_empty() {
        return Err(invalid("robot.joints", "name the URDF joints that move, from the base outwards".into()));
    }
    if robot.joints.len() > MAX_LINKS {
        return Err(invalid(
            "robot.joints",
            format!("{} joints: springfit handles chains of up to {MAX_LINKS} joints", robot.joints.len()),
        ));
    }
    let gravity = match robot.gravity[..] {
        [] => [0.0; 3],
        [x, y, z] => [x, y, z],
        _ => {
            return Err(invalid(
                "robot.gravity",
                format!(
                    "has {} numbers: with robot.urdf gravity is 3 numbers in the URDF's base frame (m/s², e.g. [0, 0, -9.81])",
                    robot.gravity.len()
                ),
            ));
        }
    };
    for (k, g) in gravity.iter().enumerate() {
        within(*g, MAX_GRAVITY, " m/s²").map_err(|r| invalid(&format!("robot.gravity[{k}]"), r))?;
    }
    let urdf_path = path.parent().unwrap_or(Path::new(".")).join(robot.urdf.as_deref().unwrap_or_default());
    let locked: Vec<(String, f64)> = robot.locked.iter().map(|(k, v)| (k.clone(), v.0)).collect();
    let (chain, ranges) = crate::model::urdf::load_with_ranges(&urdf_path, &robot.joints, &locked, gravity)?;
    if !(16.0 * chain.gravity_bound()).is_finite() {
        return Err(invalid(
            "robot.gravity",
            "the gravity potential overflows: gravity times the masses is too large".into(),
        ));
    }
    let n = chain.dof();
    let q = &file.equilibrium.q;
    if q.len() != n {
        return Err(invalid("equilibrium.q", format!("has {} angles but robot.joints names {n} joints", q.len())));
    }
    let q_eq = DVector::from_iterator(n, q.iter().map(|a| a.0));
    for (at, name) in [(DVector::zeros(n), "at q = 0"), (q_eq.clone(), "at the equilibrium")] {
        let m = chain.mass_matrix(&at);
        if !m.iter().all(|x| x.is_finite()) || m.clone().cholesky().is_none() {
            return Err(invalid(
                "robot.joints",
                format!(
                    "the mass matrix {name} is not positive definite: a moving joint carries no mass off its axis and no inertia about it ({})",
                    urdf_path.display()
                ),
            ));
        }
    }
    Ok((chain, q_eq, ranges))
}

/// The equilibrium strictly within every moving joint's `<limit>`: springs cannot hold an arm at
/// a pose it cannot take, and modes swing both ways from it (so a clipped region has room on
/// every side).
fn check_equilibrium_within(path: &Path, q_eq: &DVector<f64>, ranges: &[JointRange], names: &[String]) -> Result<()> {
    for (i, range) in ranges.iter().enumerate() {
        if let JointRange::Limited { lower, upper } = *range
            && !(lower < q_eq[i] && q_eq[i] < upper)
        {
            return Err(Error::invalid(
                path,
                format!("equilibrium.q[{i}]"),
                format!(
                    "{} rad is not inside joint `{}`'s <limit> [{lower}, {upper}] rad (at or beyond a stop): put the equilibrium within the joint's limits (the middle, {:.4}, leaves the most room)",
                    q_eq[i],
                    names.get(i).map_or("?", String::as_str),
                    0.5 * (lower + upper)
                ),
            ));
        }
    }
    Ok(())
}

/// The region against the joint limits: `within_joint_limits = true` turns a ball into the ball
/// ∩ the limits and clips a box to them; otherwise a box corner beyond a limit is refused here
/// (a ball is judged by the region check, which knows how far its geodesics reach).
fn within_limits(
    path: &Path,
    spec: Option<&RegionSpec>,
    region: Region,
    ranges: &[JointRange],
    names: &[String],
) -> Result<Region> {
    let clip = spec.is_some_and(|s| s.within_joint_limits);
    let limited = ranges.iter().any(|r| matches!(r, JointRange::Limited { .. }));
    if clip && !limited {
        return Err(Error::invalid(
            path,
            "region.within_joint_limits",
            "no moving joint has a <limit> range (a planar arm, or continuous joints): there is nothing to stay within; leave it out",
        ));
    }
    let (lo, hi): (Vec<f64>, Vec<f64>) = ranges.iter().map(JointRange::bounds).unzip();
    match region {
        Region::Ball { radius } if clip => {
            Ok(Region::Clipped { radius, lower: DVector::from_vec(lo), upper: DVector::from_vec(hi) })
        }
        Region::Box { mut lower, mut upper } => {
            for i in 0..lower.len() {
                for (corner, bound, side, field) in
                    [(&mut lower[i], lo[i], "lower", "lower"), (&mut upper[i], hi[i], "upper", "upper")]
                {
                    let beyond = if side == "lower" { *corner < bound } else { *corner > bound };
                    if !beyond {
                        continue;
                    }
                    if clip {
                        *corner = bound;
                    } else {
                        return Err(Error::invalid(
                            path,
                            format!("region.{field}[{i}]"),
                            format!(
                                "{} rad is beyond joint `{}`'s {side} limit {bound} rad (the URDF's <limit>): keep the box within the limits, or set region.within_joint_limits = true to clip it there",
                                corner,
                                names.get(i).map_or("?", String::as_str)
                            ),
                        ));
                    }
                }
            }
            Ok(Region::Box { lower, upper })
        }
        other => Ok(other),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PAPER: &str = r#"
name = "t"
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
q = [0, "pi/2"]
[region]
kind = "ball"
radius = 2.0
"#;

    fn load(text: &str) -> Result<Design> {
        Design::parse(Path::new("designs/test.toml"), text)
    }

    #[test]
    fn loads_the_paper_design() {
        let d = load(PAPER).unwrap();
        assert_eq!(d.dof(), 2);
        assert!((d.q_eq[1] - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
        assert_eq!(d.region, Region::Ball { radius: 2.0 });
        let m = d.chain.mass_matrix(&d.q_eq);
        assert!((m[(0, 0)] - 8.0).abs() < 1e-12);
    }

    #[test]
    fn a_kept_region_report_serves_only_the_region_it_was_computed_for() {
        let d = load(PAPER).unwrap();
        let first = d.region_report().unwrap();
        assert!(first.valid, "{}", first.reason);
        assert_eq!(d.region_report().unwrap(), first);
        // A copy probing a ball far past the largest valid radius must be checked afresh.
        let mut wide = d.clone();
        wide.region = Region::Ball { radius: 9.0 };
        let report = wide.region_report().unwrap();
        assert!(!report.valid, "{}", report.reason);
        assert_eq!(report, check_region_within(&wide.chain, &wide.q_eq, &wide.region, &wide.geodesics, None).unwrap());
        assert_eq!(d.region_report().unwrap(), first);
    }

    #[test]
    fn errors_name_the_field_or_position() {
        let cases: Vec<(String, &str)> = vec![
            (
                PAPER.replace(
                    "mass = 1.0\nlength = 2.0\ncom = 1.0\ninertia = 1.0\n[equilibrium]",
                    "mass = -1.0\nlength = 2.0\ncom = 1.0\ninertia = 1.0\n[equilibrium]",
                ),
                "robot.links[1].mass",
            ),
            (PAPER.replace("q = [0, \"pi/2\"]", "q = [0]"), "equilibrium.q"),
            (PAPER.replace("radius = 2.0", "radius = 2.0\nfoo = 1"), "unknown field `foo`"),
            (
                PAPER.replace("kind = \"ball\"\nradius = 2.0", "kind = \"box\"\nlower = [-1, 2]\nupper = [1, 3]"),
                "equilibrium.q[1]",
            ),
            (PAPER.replace("q = [0, \"pi/2\"]", "q = [0, \"pie\"]"), "not an angle"),
            (PAPER.replace("radius = 2.0", "radius = \"big\""), "test.toml:"),
            (PAPER.replace("[equilibrium]", "[equilibrium"), "test.toml:"),
            (PAPER.replace("radius = 2.0", "radius = nan"), "region.radius"),
        ];
        for (text, expected) in cases {
            let err = load(&text).unwrap_err().to_string();
            assert!(err.contains(expected), "expected `{expected}` in `{err}`");
            assert!(err.contains("designs/test.toml"), "{err}");
        }
    }

    #[test]
    fn type_errors_name_the_field_with_its_table() {
        let err = load(&PAPER.replacen("com = 1.0", "com = \"x\"", 2)).unwrap_err().to_string();
        assert!(err.contains("field `robot.links[0].com`"), "{err}");
        let text = PAPER.replace("com = 1.0\ninertia = 1.0\n[equilibrium]", "com = [1]\ninertia = 1.0\n[equilibrium]");
        let err = load(&text).unwrap_err().to_string();
        assert!(err.contains("field `robot.links[1].com`"), "{err}");
    }

    /// Inputs run through the fuzz target fuzz/fuzz_targets/design.rs by hand: each must be an
    /// error naming the field, never a design with a non-finite equilibrium or mass matrix.
    #[test]
    fn non_finite_angles_and_overflowing_links_are_errors() {
        let cases = [
            (PAPER.replace("q = [0, \"pi/2\"]", "q = [nan, \"pi/2\"]"), "equilibrium.q", "not a finite angle"),
            (PAPER.replace("q = [0, \"pi/2\"]", "q = [-inf, \"pi/2\"]"), "equilibrium.q", "not a finite angle"),
            (
                PAPER.replace("kind = \"ball\"\nradius = 2.0", "kind = \"box\"\nlower = [-inf, 0]\nupper = [1, 3]"),
                "region.lower",
                "not a finite angle",
            ),
            (
                PAPER.replacen("mass = 1.0\nlength = 2.0", "mass = 1e300\nlength = 1e300", 1),
                "robot.links[0].mass",
                "1e6 kg",
            ),
            (PAPER.replacen("com = 1.0", "com = 1e160", 1), "robot.links[0].com", "1000 m"),
            (PAPER.replacen("mass = 1.0", "mass = 1e200", 1), "robot.links[0].mass", "1e200"),
        ];
        for (text, field, reason) in cases {
            let err = load(&text).unwrap_err().to_string();
            assert!(err.contains(field) && err.contains(reason), "expected {field} / {reason} in {err}");
        }
        // Angles up to the limit are fine, beyond it refused with the limit.
        assert!(load(&PAPER.replace("q = [0, \"pi/2\"]", "q = [999, \"pi/2\"]")).is_ok());
        let err = load(&PAPER.replace("q = [0, \"pi/2\"]", "q = [1.7e308, 1.7e308]")).unwrap_err().to_string();
        assert!(err.contains("equilibrium.q") && err.contains("1000 rad"), "{err}");
        let err = load(&PAPER.replace("[robot]", "[robot]\ngravity = [0, -1e307]")).unwrap_err().to_string();
        assert!(err.contains("robot.gravity[1]") && err.contains("1000 m/s²"), "{err}");
        assert!(load(&PAPER.replace("[robot]", "[robot]\ngravity = [0, -999]")).is_ok());
    }

    #[test]
    fn line_and_column_of_syntax_errors() {
        let err = load(&PAPER.replace("radius = 2.0", "radius = = 2.0")).unwrap_err();
        match err {
            Error::Parse { line, column, .. } => {
                assert_eq!(line, 18);
                assert!(column > 1);
            }
            e => panic!("{e}"),
        }
    }
}
