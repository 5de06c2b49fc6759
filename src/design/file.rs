//! The design file as written: [`DesignFile`] mirrors the TOML exactly (`deny_unknown_fields`
//! everywhere, so a misspelt key is an error, not a silent default); [`super::Design::from_file`]
//! validates it and resolves it into the types the library computes with.

use serde::{Deserialize, Serialize};

use super::controllers::ControllerSettings;
use super::fit::FitSettings;
use super::identify::IdentifySettings;
use super::scenario::ScenarioSpec;
use super::simulate::SimSettings;
use super::sweep::SweepSettings;
use crate::geodesic::GeodesicSettings;
/// The type of the file's angles (`equilibrium.q`, `region.lower`, `robot.locked`, …).
///
pub use crate::units::Angle;

/// The design file as written.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DesignFile {
    /// Name used for output folders and reports (default: the file name without extension).
    pub name: Option<String>,
    /// One line about the design.
    pub description: Option<String>,
    /// The spring catalogue, relative to the design file.
    pub catalog: Option<String>,
    /// The arm.
    pub robot: RobotSpec,
    /// Where the springs are relaxed.
    pub equilibrium: EquilibriumSpec,
    /// Where strict modes are wanted.
    pub region: Option<RegionSpec>,
    /// Geodesic, log-map and region-check settings.
    pub geodesics: GeodesicSettings,
    /// How stiffnesses are fitted and evaluated.
    pub fit: FitSettings,
    /// How simulations are integrated.
    pub simulate: SimSettings,
    /// Controller gains shared by the scenarios.
    pub controllers: ControllerSettings,
    /// Simulation scenarios.
    pub scenario: Vec<ScenarioSpec>,
    /// Sensitivity sweeps.
    pub sweep: SweepSettings,
    /// Identification of a built arm from logged motion.
    pub identify: IdentifySettings,
    /// How the fitted elements become springs to wind or order.
    pub parts: super::parts::PartsSettings,
    /// Whether the file has a `[sweep]` table (set by [`crate::design::Design::parse`]): a
    /// sweep scenario the user named and the design lacks is an error, the default one missing
    /// only a warning (a design may never be swept).
    #[serde(skip)]
    pub sweep_given: bool,
}

/// `[robot]`: links from the base outwards and gravity, or a URDF and the joints that move.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RobotSpec {
    /// Gravity, m/s² (default: none): 2 numbers in the plane of a planar arm, or with `urdf` 3
    /// numbers in the URDF's base frame (the physical acceleration, e.g. `[0, 0, -9.81]`).
    pub gravity: Vec<f64>,
    /// The links, base first (planar arm).
    pub links: Vec<LinkSpec>,
    /// A URDF file, relative to the design file (spatial arm; instead of `links`).
    pub urdf: Option<String>,
    /// The URDF joints that move and get springs, from the base outwards.
    pub joints: Vec<String>,
    /// The other URDF joints, held at these values (rad, or m for a prismatic joint; default 0).
    pub locked: std::collections::BTreeMap<String, Angle>,
}

/// `[[robot.links]]`.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinkSpec {
    /// kg, > 0.
    pub mass: f64,
    /// m, > 0.
    pub length: f64,
    /// Distance of the centre of mass from the joint, m (0 ≤ com ≤ length is typical but a
    /// counterweighted link may have its centre of mass behind the joint: any finite value).
    pub com: f64,
    /// Moment of inertia about the centre of mass, kg·m², ≥ 0.
    pub inertia: f64,
}

/// `[equilibrium]`.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EquilibriumSpec {
    /// Joint angles where the spring potential has its minimum, rad.
    pub q: Vec<Angle>,
    /// How far a bill's springs may miss q_eq before a command that reads the bill refuses it,
    /// rad (|∇U(q_eq)| with gravity over ‖ω²M(q_eq)‖; default [`super::BILL_TOLERANCE`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bill_tolerance: Option<f64>,
}

/// The kind of region.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RegionKind {
    /// A geodesic ball r(q) ≤ radius.
    Ball,
    /// A box in joint angles.
    Box,
}

/// `[region]`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionSpec {
    /// `"ball"` or `"box"`.
    pub kind: RegionKind,
    /// Geodesic-ball radius (kind = "ball"), in metric arc length √(kg·m²)·rad.
    pub radius: Option<f64>,
    /// Lower corner of the box (kind = "box"), rad.
    pub lower: Option<Vec<Angle>>,
    /// Upper corner of the box (kind = "box"), rad.
    pub upper: Option<Vec<Angle>>,
    /// Whether the region stops at the URDF's joint limits (a ball ∩ the limits, a box clipped
    /// to them) instead of being refused when it leaves them.
    #[serde(default)]
    pub within_joint_limits: bool,
}
