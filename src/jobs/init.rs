//! `springfit init`: a design a user can run, written from an arm alone, and the figures that
//! choose its frequency and radius (which `springfit check` prints for any design).
//!
//! Its feature's files: the joint limits `model/urdf.rs`, the region and its limits
//! `geodesic/region.rs`, the design's `[region]` `design/mod.rs`, the command `cli/init.rs`, the
//! figures printed by `cli/check.rs`.

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use crate::design::Design;
use crate::error::{Error, Result};

/// The relative rate error a build's springs are assumed to carry when choosing ω: the ±5 %
/// of EN 15800 grade 2 wire springs, the tolerance the shipped designs' Monte Carlo uses.
pub const RATE_ERROR: f64 = 0.05;

/// How far that error may move a build's rest position (rad, 1°): beyond it the as-built arm's
/// modes no longer start where the fit put them, and trims must carry the difference.
pub const SHIFT_BUDGET_RAD: f64 = std::f64::consts::PI / 180.0;

/// Gravity against the stiffness ω²M the springs and gravity give together at the equilibrium:
/// what decides whether an ω is enough for an arm in gravity.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Stiffness {
    /// The design's ω (rad/s).
    pub omega: f64,
    /// The largest |eigenvalue| of M⁻¹·∇²U_g at q_eq over ω²: gravity's stiffness against the
    /// net stiffness ω²M (above 1 the springs must also cancel a gravity stiffer than the target).
    pub gravity_ratio: f64,
    /// The softest direction of ω²M (unit joint-space vector, the eigenvector of M's smallest
    /// eigenvalue).
    pub soft_direction: Vec<f64>,
    /// The net stiffness along it, ω²·λ_min(M) (N·m/rad).
    pub soft_stiffness: f64,
    /// The gravity torque the springs carry along it, |v·∇U_g(q_eq)| (N·m).
    pub soft_load: f64,
    /// How far a build whose springs are all RATE_ERROR too stiff moves its rest position:
    /// RATE_ERROR·max|(ω²M)⁻¹∇U_g| (rad).
    pub shift: f64,
    /// The smallest ω that keeps `shift` within SHIFT_BUDGET_RAD and gravity's stabilising
    /// stiffness below ω²M, so the springs' own stiffness ω²M − ∇²U_g stays positive (rad/s).
    pub needed_omega: f64,
}

/// [`Stiffness`] of a design at its equilibrium.
pub fn stiffness(design: &Design) -> Result<Stiffness> {
    let q = design.q_eq.as_slice();
    let m = design.chain.mass_matrix(&design.q_eq);
    let torque = design.chain.gravity_gradient(q);
    let hessian = design.chain.gravity_hessian(q);
    let omega = design.fit.frequency;
    stiffness_of(&m, &torque, &hessian, omega).ok_or_else(|| {
        Error::invalid(&design.path, "robot", "the mass matrix at the equilibrium is not positive definite")
    })
}

/// [`stiffness`] from the mass matrix, gravity's torque and Hessian at q_eq; None when M is not
/// positive definite.
pub fn stiffness_of(m: &DMatrix<f64>, torque: &DVector<f64>, hessian: &DMatrix<f64>, omega: f64) -> Option<Stiffness> {
    let chol = m.clone().cholesky()?;
    // M⁻¹ᐟ²-like congruence: L⁻¹ H L⁻ᵀ has the eigenvalues of M⁻¹H and is symmetric.
    let l_inv = chol.l().try_inverse()?;
    let reduced = &l_inv * hessian * l_inv.transpose();
    let reduced = (&reduced + reduced.transpose()) * 0.5;
    let eigenvalues = reduced.symmetric_eigen().eigenvalues;
    let gravity_max = eigenvalues.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    // Only a stabilising gravity (positive stiffness) can exceed ω²M and leave the springs a
    // negative stiffness to supply; a destabilising one only adds to what they carry.
    let gravity_stiffest = eigenvalues.iter().fold(0.0f64, |a, &x| a.max(x));
    let eig = m.clone().symmetric_eigen();
    let k = eig.eigenvalues.imin();
    let lambda_min = eig.eigenvalues[k];
    let v = eig.eigenvectors.column(k).into_owned();
    let w2 = omega * omega;
    let per_error = chol.solve(torque).amax();
    let shift = RATE_ERROR * per_error / w2;
    let for_shift = (RATE_ERROR * per_error / SHIFT_BUDGET_RAD).sqrt();
    let for_gravity = gravity_stiffest.sqrt();
    Some(Stiffness {
        omega,
        gravity_ratio: gravity_max / w2,
        soft_direction: v.iter().copied().collect(),
        soft_stiffness: w2 * lambda_min,
        soft_load: v.dot(torque).abs(),
        shift,
        needed_omega: for_shift.max(for_gravity),
    })
}

/// The arm `springfit init` starts from.
#[derive(Debug, Clone)]
pub enum InitArm {
    /// A URDF (path as given, resolved from the current folder), the joints that move from the
    /// base outwards, the other joints held (name, value), gravity in the base frame.
    Urdf {
        /// The URDF file, as given (resolved from the current folder).
        urdf: std::path::PathBuf,
        /// The URDF joints that move, from the base outwards.
        joints: Vec<String>,
        /// The other joints held, with their values (rad, or m for a prismatic joint).
        locked: Vec<(String, f64)>,
        /// Gravity in the URDF's base frame, m/s².
        gravity: [f64; 3],
    },
    /// A planar arm's links (mass kg, length m, centre of mass m from the joint, inertia kg·m²
    /// about it) in a plane with this gravity.
    Planar {
        /// Per link: mass kg, length m, centre of mass m from the joint, inertia kg·m² about it.
        links: Vec<[f64; 4]>,
        /// Gravity in the arm's plane, m/s².
        gravity: [f64; 2],
    },
}

/// What `springfit init` is asked for.
#[derive(Debug, Clone)]
pub struct InitRequest {
    /// The arm.
    pub arm: InitArm,
    /// The design file to write (its catalogue is written beside it as `<stem>_catalog.toml`).
    pub out: std::path::PathBuf,
    /// The equilibrium, if the user chose it (rad); otherwise chosen within the limits.
    pub q_eq: Option<Vec<f64>>,
}

/// What `springfit init` found and wrote: the design's text and its catalogue's, with the
/// figures behind each choice.
#[derive(Debug, Clone)]
pub struct InitRun {
    /// The design file to write.
    pub design_path: std::path::PathBuf,
    /// Its text.
    pub design_text: String,
    /// The catalogue file beside it.
    pub catalog_path: std::path::PathBuf,
    /// Its text.
    pub catalog_text: String,
    /// Why each value was chosen, one line each (also written into the design as comments).
    pub notes: Vec<String>,
}

/// The catalogue `init` writes: the shipped `catalogs/chain.toml` (the paper's element kinds on
/// every joint, pair and adjacent triple; what the shipped gravity arms learned to need), its
/// triple families left out for an arm of fewer than three joints.
const CHAIN_CATALOG: &str = include_str!("../../catalogs/chain.toml");

/// The share of the target stiffness ω²M by which a trim spring at the top of its range may
/// stiffen any direction (see [`trim_text`]).
const TRIM_SHARE: f64 = 0.2;

/// The ball `init` probes first, in units of √λ_max(M) (metric arc length per radian of the
/// heaviest direction): the check then looks out to PROBE_FACTOR times it for what limits the region.
const PROBE_RADIUS: f64 = 0.5;
const PROBE_FACTOR: f64 = 8.0;

/// A joint's equilibrium when the user gives none: the URDF's zero when it lies inside the
/// limits at least a tenth of the range from either stop, else the middle of the limits.
fn equilibrium(ranges: &[crate::model::urdf::JointRange]) -> Vec<f64> {
    use crate::model::urdf::JointRange;
    ranges
        .iter()
        .map(|r| match *r {
            JointRange::Limited { lower, upper } => {
                let room = 0.1 * (upper - lower);
                if lower + room <= 0.0 && 0.0 <= upper - room { 0.0 } else { 0.5 * (lower + upper) }
            }
            JointRange::Unlimited | JointRange::Unstated => 0.0,
        })
        .collect()
}

/// An equilibrium given with `--q`: one angle per moving joint, each strictly inside its
/// `<limit>`, refused naming `--q` (the design file it would go into does not exist yet).
fn check_given_equilibrium(q: &[f64], ranges: &[crate::model::urdf::JointRange], names: &[String]) -> Result<()> {
    use crate::model::urdf::JointRange;
    let setting = |reason: String| Error::Setting { field: "--q".into(), reason };
    if q.len() != ranges.len() {
        return Err(setting(format!("{} angles for {} moving joints: give one per joint", q.len(), ranges.len())));
    }
    for (i, (range, &x)) in ranges.iter().zip(q).enumerate() {
        if let JointRange::Limited { lower, upper } = *range
            && !(lower < x && x < upper)
        {
            let name = names.get(i).map_or_else(|| format!("{}", i + 1), |n| format!("`{n}`"));
            return Err(setting(format!(
                "angle {} is {x} rad, not inside joint {name}'s <limit> [{lower}, {upper}] rad: give an equilibrium within the limits (the middle, {:.4}, leaves the most room), or leave --q out and init chooses one",
                i + 1,
                0.5 * (lower + upper)
            )));
        }
    }
    Ok(())
}

/// `to` relative to the folder `from` (both made absolute), for the paths a design names.
fn relative(to: &std::path::Path, from: &std::path::Path) -> std::path::PathBuf {
    let abs = |p: &std::path::Path| {
        let p = if p.is_absolute() { p.to_path_buf() } else { std::env::current_dir().unwrap_or_default().join(p) };
        p.components().fold(std::path::PathBuf::new(), |mut acc, c| {
            match c {
                std::path::Component::ParentDir => {
                    acc.pop();
                }
                std::path::Component::CurDir => {}
                other => acc.push(other),
            }
            acc
        })
    };
    let (to, from) = (abs(to), abs(from));
    let common = to.components().zip(from.components()).take_while(|(a, b)| a == b).count();
    // Sharing only the root: the absolute path says more than a climb to it.
    if common <= 1 {
        return to;
    }
    let mut out = std::path::PathBuf::new();
    for _ in from.components().skip(common) {
        out.push("..");
    }
    for c in to.components().skip(common) {
        out.push(c);
    }
    out
}

/// The robot section and the equilibrium's angles of the design text.
fn robot_text(arm: &InitArm, out: &std::path::Path) -> String {
    let folder = out.parent().unwrap_or(std::path::Path::new("."));
    match arm {
        InitArm::Urdf { urdf, joints, locked, gravity } => {
            let names: Vec<String> = joints.iter().map(|j| format!("{j:?}")).collect();
            let mut text = format!(
                "[robot]\nurdf = {:?}\njoints = [{}]\ngravity = [{}, {}, {}]   # m/s², in the URDF's base frame\n",
                relative(urdf, folder).to_string_lossy(),
                names.join(", "),
                gravity[0],
                gravity[1],
                gravity[2]
            );
            if !locked.is_empty() {
                text.push_str("[robot.locked]   # rad: the joints that do not move\n");
                for (name, value) in locked {
                    text.push_str(&format!("{name:?} = {value}\n"));
                }
            }
            text
        }
        InitArm::Planar { links, gravity } => {
            let mut text =
                format!("[robot]\ngravity = [{}, {}]   # m/s², in the plane of the arm\n", gravity[0], gravity[1]);
            for [mass, length, com, inertia] in links {
                text.push_str(&format!(
                    "\n[[robot.links]]\nmass = {mass}\nlength = {length}\ncom = {com}\ninertia = {inertia}\n"
                ));
            }
            text
        }
    }
}

/// The design text with the given equilibrium, radius and ω (None: left to the default).
fn design_text(
    name: &str,
    robot: &str,
    q: &[f64],
    radius: f64,
    omega: Option<f64>,
    built: bool,
    notes: &[String],
) -> String {
    let mut text = String::from("# Written by `springfit init`: a starting point to fit as it is, then to refine.\n");
    for n in notes {
        text.push_str(&format!("# {n}\n"));
    }
    let angles: Vec<String> = q.iter().map(|x| format!("{x}")).collect();
    text.push_str(&format!(
        "name = {name:?}\ncatalog = {:?}\n\n{robot}\n[equilibrium]\nq = [{}]   # rad\n\n[region]\nkind = \"ball\"\nradius = {radius}\n",
        format!("{name}_catalog.toml"),
        angles.join(", ")
    ));
    if omega.is_some() || built {
        text.push_str("\n[fit]\n");
    }
    if let Some(w) = omega {
        text.push_str(&format!("frequency = {w}   # rad/s\n"));
    }
    if built {
        text.push_str(&format!(
            "tolerance = {RATE_ERROR}   # ± rate error of every spring: the as-built figures over 1,000 builds, untrimmed and trimmed\n"
        ));
    }
    text
}

/// The trim springs `init` adds to the catalogue: one per joint, then one per pair of joints
/// turned together (adjacent pairs first), at most [`crate::limits::MAX_TRIMS`]. On up to three
/// joints they span every entry of the Hessian, so a build's stiffness error can be set back
/// in every direction; beyond, the joints and their neighbours' pairs.
fn trim_couplings(n: usize) -> Vec<Vec<f64>> {
    let unit = |i: usize| (0..n).map(|j| if j == i { 1.0 } else { 0.0 }).collect::<Vec<f64>>();
    let mut couplings: Vec<Vec<f64>> = (0..n).map(unit).collect();
    let mut pairs: Vec<(usize, usize)> = (0..n).flat_map(|i| (i + 1..n).map(move |j| (i, j))).collect();
    pairs.sort_by_key(|&(i, j)| j - i);
    couplings.extend(pairs.into_iter().map(|(i, j)| {
        let mut a = unit(i);
        a[j] = 1.0;
        a
    }));
    couplings.truncate(crate::limits::MAX_TRIMS);
    couplings
}

/// The trim families' text: one family per coupling a (a family has one range), its rate
/// from 0 to TRIM_SHARE·ω²/(aᵀM⁻¹a) at q_eq. That bound is the largest rate k with
/// k·aaᵀ ≤ TRIM_SHARE·ω²M: a trim may stiffen no direction by more than that share of the
/// target stiffness, however light the joints it turns (a range by ω²·aᵀMa instead lets a trim
/// over the heavy and the light joints, at mid-range, stiffen the light wrist several times
/// over, and the other springs' preloads must cancel it: measured, the drawn p99 of a
/// human-like planar arm went from 1.5° to 33°).
fn trim_text(m: &DMatrix<f64>, omega: f64) -> String {
    let n = m.nrows();
    let Some(chol) = m.clone().cholesky() else { return String::new() };
    let mut text = String::from(
        "\n# Trim springs written by `springfit init`: linear, relaxed at the equilibrium, rate set on each\n\
         # build after assembly within trim_range (not fit candidates: the fit places them at mid-range).\n\
         # Each range is TRIM_SHARE·ω²/(aᵀM⁻¹a) at q_eq: no trim stiffens a direction by more than that\n\
         # share of the target stiffness ω²M. With trim_sized = true that range is where the fit\n\
         # starts: the fit sizes it by the bill to hold the rates the builds' trims need, and keeps\n\
         # the fit around the sized ranges only when it is no worse drawn and realised (2 %)\n\
         # (docs/catalogue.md); `trim_sized = false` keeps the range as written.\n",
    );
    for a in trim_couplings(n) {
        let v = DVector::from_column_slice(&a);
        let dual = v.dot(&chol.solve(&v));
        let hi = round_down(TRIM_SHARE * omega * omega / dual);
        let numbers: Vec<String> = a.iter().map(|x| format!("{x}")).collect();
        text.push_str(&format!(
            "\n[[family]]\nname = \"trim spring ({})\"\nprofile = \"linear\"\nunit = \"N*m/rad\"\ncouplings = [[{}]]\noffsets = \"equilibrium\"\ntrim = true\ntrim_range = [0.0, {hi}]\ntrim_sized = true\n",
            numbers.join(", "),
            numbers.join(", ")
        ));
    }
    text
}

/// Rounds up to two significant digits (a value a user reads and edits).
fn round_up(x: f64) -> f64 {
    two_digits(x, f64::ceil)
}

/// Rounds down to two significant digits (a radius that stays inside what limits it).
fn round_down(x: f64) -> f64 {
    two_digits(x, f64::floor)
}

/// `x` to two significant digits by `round`, printed and read back so that the file shows
/// 9.2, not 9.200000000000001.
fn two_digits(x: f64, round: fn(f64) -> f64) -> f64 {
    if !(x.is_finite() && x > 0.0) {
        return x;
    }
    let exponent = x.log10().floor() as i32 - 1;
    let rounded = round(x / 10f64.powi(exponent)) * 10f64.powi(exponent);
    let decimals = usize::try_from(-exponent).unwrap_or(0);
    format!("{rounded:.decimals$}").parse().unwrap_or(rounded)
}

/// Writes nothing: reads the arm, chooses the equilibrium, the radius (a margin inside what
/// limits the ball: a conjugate point, crossing geodesics or a joint limit) and ω (gravity's
/// load and stiffness against ω²M), and returns the design and catalogue texts.
pub fn run(request: &InitRequest) -> Result<InitRun> {
    let out = &request.out;
    let stem = out.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "arm".into());
    let robot = robot_text(&request.arm, out);
    let (ranges, names) = match &request.arm {
        InitArm::Urdf { urdf, joints, locked, gravity } => {
            (crate::model::urdf::load_with_ranges(urdf, joints, locked, *gravity)?.1, joints.clone())
        }
        InitArm::Planar { links, .. } => (vec![crate::model::urdf::JointRange::Unlimited; links.len()], Vec::new()),
    };
    let n = ranges.len();
    let q = match &request.q_eq {
        Some(q) => {
            check_given_equilibrium(q, &ranges, &names)?;
            q.clone()
        }
        None => equilibrium(&ranges),
    };
    // A first design to measure the arm with: a small ball, probed far.
    let probe_text = design_text(&stem, &robot, &q, 1.0, None, false, &[]);
    let mut design = Design::parse(out, &probe_text)?;
    let m = design.chain.mass_matrix(&design.q_eq);
    let heavy = m.clone().symmetric_eigen().eigenvalues.max().max(0.0).sqrt();
    design.region = crate::geodesic::Region::Ball { radius: PROBE_RADIUS * heavy };
    design.geodesics.probe_factor = PROBE_FACTOR;
    let report = design.region_report()?;
    let mut notes = Vec::new();
    let suggested = report.suggested_radius();
    let radius = round_down(suggested.map_or(crate::geodesic::region::MODE_LIMIT_SHARE * report.probe_radius, |s| s.0));
    notes.push(match suggested {
        Some((_, f)) => format!(
            "region.radius {radius}: {:.0} % of the {} at {:.4} ({})",
            100.0 * f.suggested_share(),
            f.kind(),
            f.radius(),
            f.describe()
        ),
        None => {
            format!("region.radius {radius}: nothing limits the ball up to the probe radius {:.4}", report.probe_radius)
        }
    });
    let s = stiffness(&design)?;
    let omega = (s.needed_omega > design.fit.frequency).then(|| round_up(s.needed_omega));
    notes.push(match omega {
        Some(w) => format!(
            "fit.frequency {w} rad/s: keeps the rest position of springs {:.0} % off their rates within {:.0}° (gravity's load {:.4} N·m on the softest direction) and gravity's stiffness below ω²M",
            100.0 * RATE_ERROR,
            SHIFT_BUDGET_RAD.to_degrees(),
            s.soft_load
        ),
        None => format!("fit.frequency left to its default {} rad/s: gravity needs no more", design.fit.frequency),
    });
    notes.push(format!(
        "equilibrium: {}",
        match (&request.q_eq, &request.arm) {
            (Some(_), _) => "as given",
            (None, InitArm::Urdf { .. }) => "the URDF's zero where it lies well inside the limits, else their middle",
            (None, InitArm::Planar { .. }) => "every joint at 0 (give --q for another pose)",
        }
    ));
    // A joint whose URDF states no range: the region check treats it as free, which a real
    // joint rarely is; the assumption is written where the user reads the design.
    for (name, range) in names.iter().zip(&ranges) {
        if *range == crate::model::urdf::JointRange::Unstated {
            notes.push(format!(
                "assumed: joint `{name}` turns freely (its URDF <limit> gives no range); give it lower and upper limits in the URDF if it stops somewhere"
            ));
        }
    }
    let text = design_text(&stem, &robot, &q, radius, omega, true, &notes);
    // What is written must load and pass its region check as written.
    let check = Design::parse(out, &text)?;
    check.valid_region()?;
    let mut catalog_text = if n >= 3 {
        CHAIN_CATALOG.to_string()
    } else {
        // The triple families are the file's last two; an arm of fewer joints has no triples.
        CHAIN_CATALOG.split("\n[[family]]\nname = \"triple crank\"").next().unwrap_or(CHAIN_CATALOG).to_string()
    };
    catalog_text.push_str(&trim_text(&m, omega.unwrap_or(design.fit.frequency)));
    Ok(InitRun {
        design_path: out.clone(),
        design_text: text,
        catalog_path: out.with_file_name(format!("{stem}_catalog.toml")),
        catalog_text,
        notes,
    })
}

impl InitRun {
    /// Writes the design and its catalogue; refuses to replace either.
    pub fn write(&self) -> Result<()> {
        for (path, text) in [(&self.design_path, &self.design_text), (&self.catalog_path, &self.catalog_text)] {
            if path.exists() {
                return Err(Error::io(
                    path,
                    std::io::Error::other("exists already: springfit init writes a new design and never replaces one"),
                ));
            }
            if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
            }
            std::fs::write(path, text).map_err(|e| Error::io(path, e))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_are_rounded_to_two_digits_in_the_safe_direction() {
        assert_eq!(round_up(9.1234), 9.2);
        assert_eq!(round_up(9.2), 9.2);
        assert_eq!(round_down(0.26107), 0.26);
        assert_eq!(round_down(123.0), 120.0);
    }

    #[test]
    fn the_equilibrium_is_zero_well_inside_the_limits_else_their_middle() {
        use crate::model::urdf::JointRange;
        let q = equilibrium(&[
            JointRange::Limited { lower: -1.0, upper: 1.0 },
            JointRange::Limited { lower: -3.0, upper: -0.1 },
            JointRange::Limited { lower: -0.01, upper: 3.0 },
            JointRange::Unlimited,
        ]);
        assert_eq!(q, vec![0.0, -1.55, 1.495, 0.0]);
    }

    #[test]
    fn trims_span_the_hessian_on_three_joints_and_stay_within_the_limit_beyond() {
        let c = trim_couplings(3);
        assert_eq!(c.len(), 6);
        assert_eq!(c[3], vec![1.0, 1.0, 0.0]);
        assert_eq!(c[5], vec![1.0, 0.0, 1.0]);
        assert_eq!(trim_couplings(5).len(), crate::limits::MAX_TRIMS);
        // A heavy joint and a light one: the pair's trim is bounded by the light joint.
        let m = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, 0.01]);
        let text = trim_text(&m, 10.0);
        let ranges: Vec<&str> = text.lines().filter(|l| l.starts_with("trim_range")).collect();
        assert_eq!(ranges, ["trim_range = [0.0, 20]", "trim_range = [0.0, 0.2]", "trim_range = [0.0, 0.19]"]);
    }

    #[test]
    fn gravity_figures_of_a_hanging_and_a_held_pendulum() {
        // One joint, M = 1 kg·m², gravity torque 2 N·m and stiffness 3 N·m/rad, ω = 2 rad/s.
        let m = DMatrix::from_element(1, 1, 1.0);
        let s = stiffness_of(&m, &DVector::from_element(1, 2.0), &DMatrix::from_element(1, 1, 3.0), 2.0).unwrap();
        assert!((s.gravity_ratio - 0.75).abs() < 1e-12);
        assert!((s.shift - RATE_ERROR * 2.0 / 4.0).abs() < 1e-12);
        assert!((s.soft_stiffness - 4.0).abs() < 1e-12 && (s.soft_load - 2.0).abs() < 1e-12);
        // ω needed: the shift RATE_ERROR·2/ω² within a degree.
        assert!((s.needed_omega - (RATE_ERROR * 2.0 / SHIFT_BUDGET_RAD).sqrt()).abs() < 1e-12);
    }
}
