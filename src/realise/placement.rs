//! Where the parts sit: each element's spring, pulleys and cable placed on the base or on a moving
//! link, with their masses, so that the arm the fit designs for can carry them (docs/parts.md,
//! "Where the parts sit").
//!
//! The rule, by transmission ([`super::transmission`]):
//!
//! - `joint`: the spring (a torsion pair or stop, a crank, a drum stop, a trim, a cam's follower)
//!   sits on its joint's axis, fixed to the link before the joint: every joint before it moves it,
//!   its own joint does not. Joint 1's sits on the base. Its mass is a point on the joint axis
//!   ([`crate::model::Chain::joint_mount`]).
//! - `bevel differential`: at the first (most proximal) of its two joints, as a joint's part.
//! - `tendon`: the spring and its drum on the base; a pulley per cable at every joint the tendon
//!   crosses, on that joint's axis (an aluminium disc of the pulley's radius and a groove
//!   [`PULLEY_WIDTH_CABLES`] cables wide); the cable along every link from the base to the most
//!   distal joint it crosses, its mass at the link's middle ([`CABLE_MASS`]).
//!
//! The masses are points: a spring's or pulley's own inertia about its centre is left out (a
//! disc of 40 mm radius and 50 g has 4·10⁻⁵ kg·m², against 5·10⁻³ kg·m² for the same mass
//! 0.3 m from the axis), and so is the cable's about its middle (a few grams a metre). The
//! cranks' and drums' other hardware (the crank arm, the fairlead, the drum, a cam's disc) is
//! not in the parts' masses and so not placed either.

use crate::model::{Chain, PointMass};
use crate::realise::transmission::{Kind, Transmission};
use crate::residual::AngleStats;

/// Density of the pulleys' aluminium, kg/m³: 6061-T6, 2.70 g/cm³ (ASM Aerospace Specification
/// Metals, "Aluminum 6061-T6; 6061-T651", physical properties).
pub const ALUMINIUM_DENSITY: f64 = 2700.0;

/// A pulley's width in cable diameters: the groove and its two flanges (a single-groove sheave
/// is about three cable diameters wide).
pub const PULLEY_WIDTH_CABLES: f64 = 3.0;

/// The narrowest pulley, mm: below it the flanges are too thin to machine.
pub const MIN_PULLEY_WIDTH_MM: f64 = 4.0;

/// Pounds per 100 ft to kg/m.
const LB_PER_100FT: f64 = 0.453_592_37 / 30.48;

/// Mass of the transmission's cables ([`super::transmission::CABLES`], by name), kg/m: the
/// weights per 100 ft of MIL-DTL-83420 corrosion-resistant cable as the FAA's AC 43.13-1B,
/// table 7-3, lists them beside the breaking strengths.
pub const CABLE_MASS: [(&str, f64); 9] = [
    ("3x7, 1/32 in", 0.16 * LB_PER_100FT),
    ("7x7, 3/64 in", 0.42 * LB_PER_100FT),
    ("7x7, 1/16 in", 0.75 * LB_PER_100FT),
    ("7x19, 3/32 in", 1.60 * LB_PER_100FT),
    ("7x19, 1/8 in", 2.90 * LB_PER_100FT),
    ("7x19, 5/32 in", 4.50 * LB_PER_100FT),
    ("7x19, 3/16 in", 6.50 * LB_PER_100FT),
    ("7x19, 7/32 in", 8.60 * LB_PER_100FT),
    ("7x19, 1/4 in", 11.00 * LB_PER_100FT),
];

/// What a placed mass is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Piece {
    /// The element's springs (a part's `mass`).
    Spring,
    /// One pulley of a tendon.
    Pulley,
    /// A tendon's cable along one link.
    Cable,
}

impl Piece {
    /// The word for it in reports.
    pub fn name(self) -> &'static str {
        match self {
            Piece::Spring => "spring",
            Piece::Pulley => "pulley",
            Piece::Cable => "cable",
        }
    }
}

/// One placed mass of an element's part.
#[derive(Debug, Clone, PartialEq)]
pub struct Placed {
    /// The element's id (`S03`, `C01`).
    pub id: String,
    /// What it is.
    pub piece: Piece,
    /// Its mass, kg.
    pub mass: f64,
    /// Where it rides: None on the base (it adds nothing to the arm's inertia), else the link
    /// and the point ([`PointMass`]).
    pub on: Option<PointMass>,
}

/// The placement of a design's parts, and the fit's rounds with it when it was iterated.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Placement {
    /// Every placed mass, element by element.
    pub placed: Vec<Placed>,
    /// The fit's rounds with the parts' masses on the arm (None: not iterated, `[fit]
    /// placement_rounds = 0`).
    pub rounds: Option<Rounds>,
}

/// What iterating the fit with the parts' masses on the arm did (`summary.json`'s `placement`).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Rounds {
    /// Fits on the arm carrying the previous fit's parts (0 when the first fit's parts move
    /// nothing: every part on the base).
    pub rounds: usize,
    /// Whether the springs' mass changed by less than [`CONVERGED`] in the last round.
    pub converged: bool,
    /// The springs' mass of each fit, kg: the first without placed masses, then each round's.
    pub spring_mass_kg: Vec<f64>,
    /// The moving mass placed for each round, kg (the previous fit's parts on links).
    pub placed_mass_kg: Vec<f64>,
    /// The first fit (without placed masses) judged on the arm carrying its own parts: the
    /// ideal elements' residual angles and the realised design's, degrees. The error a builder
    /// meets who builds the fit made without placement. Null when no part moved.
    pub unplaced_on_placed: Option<(AngleStats, AngleStats)>,
}

/// The relative change of the springs' mass between rounds below which the design is taken as
/// consistent with its parts' placement.
pub const CONVERGED: f64 = 0.01;

impl Rounds {
    /// The rounds in one sentence, as `springfit fit` prints them.
    pub fn sentence(&self) -> String {
        let kg = |v: &[f64]| v.iter().map(|m| format!("{m:.3}")).collect::<Vec<_>>().join(" → ");
        let first = self
            .unplaced_on_placed
            .map(|(ideal, realised)| {
                format!(
                    "; the fit without them, on the arm carrying its parts: p99 {:.4}° as drawn, {:.4}° realised",
                    ideal.p99_abs, realised.p99_abs
                )
            })
            .unwrap_or_default();
        format!(
            "placement: {} round(s) on the arm carrying its parts ({} kg on moving links), springs {} kg, {}{first}",
            self.rounds,
            kg(&self.placed_mass_kg),
            kg(&self.spring_mass_kg),
            if self.converged { "converged (< 1 %)" } else { "not converged within placement_rounds" }
        )
    }
}

impl Placement {
    /// The parts' masses on moving links, kg.
    pub fn moving_mass(&self) -> f64 {
        self.placed.iter().filter_map(|p| p.on.map(|m| m.mass)).sum()
    }

    /// The masses on moving links, as the chain takes them.
    pub fn point_masses(&self) -> Vec<PointMass> {
        self.placed.iter().filter_map(|p| p.on).collect()
    }
}

/// The mass of `cable` per metre, kg/m (0 for a name not in [`CABLE_MASS`]).
pub fn cable_mass(name: &str) -> f64 {
    CABLE_MASS.iter().find(|(n, _)| *n == name).map_or(0.0, |(_, m)| *m)
}

/// A pulley of `radius_mm` for a cable of `cable_mm`, aluminium, solid: kg. A solid disc is the
/// upper bound of a webbed sheave's mass.
pub fn pulley_mass(radius_mm: f64, cable_mm: f64) -> f64 {
    let width = (PULLEY_WIDTH_CABLES * cable_mm).max(MIN_PULLEY_WIDTH_MM) * 1e-3;
    let r = radius_mm.abs() * 1e-3;
    ALUMINIUM_DENSITY * std::f64::consts::PI * r * r * width
}

/// The placed masses of one element of coupling `a`, whose springs weigh `spring_mass` kg, on
/// `transmission`, on `chain`'s links (see the module doc for the rule).
pub fn place(chain: &Chain, id: &str, a: &[f64], spring_mass: f64, transmission: &Transmission) -> Vec<Placed> {
    let joints: Vec<usize> = a.iter().enumerate().filter(|(_, c)| **c != 0.0).map(|(i, _)| i).collect();
    let at_joint =
        |i: usize, mass: f64| chain.joint_mount(i).map(|(link, position)| PointMass { link, position, mass });
    let piece = |piece: Piece, mass: f64, on: Option<PointMass>| Placed { id: id.to_string(), piece, mass, on };
    let mut out = Vec::new();
    match (transmission.kind, &transmission.tendon) {
        (Kind::Tendon, Some(t)) => {
            out.push(piece(Piece::Spring, spring_mass, None));
            let cables = if t.pair { 2 } else { 1 };
            for (i, r) in t.radii_mm.iter().enumerate().filter(|(_, r)| **r != 0.0) {
                let m = cables as f64 * pulley_mass(*r, t.cable.diameter_mm);
                out.push(piece(Piece::Pulley, m, at_joint(i, m)));
            }
            let per_metre = cables as f64 * cable_mass(t.cable.name);
            let last = joints.last().copied().unwrap_or(0);
            for link in 0..last {
                let end = chain.link_end(link);
                let length = end.iter().map(|x| x * x).sum::<f64>().sqrt();
                let m = per_metre * length;
                let position = [end[0] / 2.0, end[1] / 2.0, end[2] / 2.0];
                out.push(piece(Piece::Cable, m, Some(PointMass { link, position, mass: m })));
            }
        }
        // A joint's part on its axis, a differential's at its first joint.
        _ => {
            let first = joints.first().copied().unwrap_or(0);
            out.push(piece(Piece::Spring, spring_mass, at_joint(first, spring_mass)));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Link;
    use crate::realise::transmission::{CABLES, Tendon};

    fn chain() -> Chain {
        let link = Link { mass: 1.0, length: 0.5, com: 0.25, inertia: 0.02 };
        Chain::new(vec![link; 3], [0.0, -9.81])
    }

    #[test]
    fn a_joint_part_rides_on_the_link_before_its_joint() {
        let joint = Transmission { kind: Kind::Joint, tendon: None };
        let on_base = place(&chain(), "S01", &[1.0, 0.0, 0.0], 0.2, &joint);
        assert_eq!(on_base[0].on, None);
        let on_link = place(&chain(), "S02", &[0.0, 0.0, 1.0], 0.2, &joint);
        assert_eq!(on_link[0].on, Some(PointMass { link: 1, position: [0.5, 0.0, 0.0], mass: 0.2 }));
        let bevel = Transmission { kind: Kind::BevelDifferential, tendon: None };
        let diff = place(&chain(), "S03", &[0.0, 1.0, 2.0], 0.3, &bevel);
        assert_eq!(diff[0].on.map(|p| p.link), Some(0));
    }

    #[test]
    fn a_tendon_puts_its_spring_on_the_base_and_its_pulleys_and_cable_on_the_links() {
        let cable = CABLES[4];
        let tendon = Tendon {
            radii_mm: vec![40.0, 0.0, -20.0],
            scale_mm: 40.0,
            pair: true,
            preload_n: 10.0,
            peak_tension_n: 30.0,
            cable,
        };
        let t = Transmission { kind: Kind::Tendon, tendon: Some(tendon) };
        let placed = place(&chain(), "S04", &[1.0, 0.0, -0.5], 0.2, &t);
        let spring = &placed[0];
        assert_eq!((spring.piece, spring.on), (Piece::Spring, None));
        let pulleys: Vec<&Placed> = placed.iter().filter(|p| p.piece == Piece::Pulley).collect();
        assert_eq!(pulleys.len(), 2);
        assert_eq!(pulleys[0].on, None, "joint 1's pulley sits on the base");
        let width = (3.0 * cable.diameter_mm).max(4.0) * 1e-3;
        let m = 2.0 * 2700.0 * std::f64::consts::PI * 0.02 * 0.02 * width;
        assert!((pulleys[1].mass - m).abs() < 1e-15);
        assert_eq!(pulleys[1].on.map(|p| (p.link, p.position)), Some((1, [0.5, 0.0, 0.0])));
        let cables: Vec<&Placed> = placed.iter().filter(|p| p.piece == Piece::Cable).collect();
        assert_eq!(cables.len(), 2, "the cable runs along links 1 and 2 to joint 3");
        assert!((cables[0].mass - 2.0 * 0.5 * 2.90 * 0.453_592_37 / 30.48).abs() < 1e-12);
        assert_eq!(cables[0].on.map(|p| p.position), Some([0.25, 0.0, 0.0]));
        let moving = pulleys[1].mass + cables[0].mass + cables[1].mass;
        let placement = Placement { placed: placed.clone(), rounds: None };
        assert!((placement.moving_mass() - moving).abs() < 1e-15);
    }

    #[test]
    fn every_cable_has_a_mass() {
        for c in CABLES {
            assert!(cable_mass(c.name) > 0.0, "{}", c.name);
        }
    }
}
