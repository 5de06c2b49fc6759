//! The mechanism behind each element: what a maker winds or a buyer orders, how it is mounted,
//! the checks it must pass, and the potential it really has (judged in place of the ideal one).
//!
//! | element | mechanism |
//! | --- | --- |
//! | linear (on a joint or, through a bevel-gear differential, on a coupling) | two equal torsion springs wound against each other, so neither leg ever leaves its stop: a rate k/2 each, preloaded by the largest deflection |
//! | one-sided compression | a torsion spring whose free leg meets a stop at the engagement angle x₀, or a compression spring pulled by a cable wound on a drum on x (taut from x₀): the lighter that passes, unless `[parts] stop_mechanism` forces one |
//! | crank | an extension spring in a zero-free-length arrangement: a cable from a pin at radius r on the crank over a fairlead of two rollers at distance R from the axis to the spring beyond it, k_s r R = k |
//! | trim | a leaf spring in a sliding clamp, loaded at its tip by a lever geared to x: the clamp position sets the rate; or an extension spring on a crank geared to x whose pin radius (a screw in a slot) sets the rate: the lighter that passes, unless `[parts] trim_mechanism` forces one |
//! | cam follower | a compression spring with the follower's rate, preload and stroke |
//!
//! Every design function searches the sizes of each wire the maker stocks ([`Requirements::wires`])
//! and spring indices for the lightest spring that meets the rate, the static and fatigue limits
//! and the envelope, or returns the [`Limit`] that the best candidate misses and by how much.

use std::f64::consts::PI;

use super::material::{Material, strip};
use super::spring::{
    HelicalSpring, INDEX_RANGE, Loading, MIN_COILS, Surface, TorsionSpring, hook_bending_stress, hook_torsion_stress,
    rate_tolerance,
};
use crate::elements::{Profile, Side};

/// Spring indices w = D/d tried, from [`INDEX_RANGE`]'s lower end up to 16.
fn indices() -> impl Iterator<Item = f64> {
    (0..=48).map(|i| INDEX_RANGE.0 + 0.25 * i as f64)
}

/// The helical springs of rate `rate` (N/mm) the search tries: every size of every wire of
/// [`Requirements::wires`], in their order, and spring index of [`indices`], the active coils
/// following from the rate (0.5 to 400 of them).
fn helical(rate: f64, req: &Requirements) -> impl Iterator<Item = HelicalSpring> + '_ {
    req.wires().flat_map(move |m| {
        m.sizes().into_iter().flat_map(move |d| {
            indices().filter_map(move |w| {
                let dm = w * d;
                let n = m.g_at(d) * d.powi(4) / (8.0 * dm.powi(3) * rate);
                (0.5..=400.0).contains(&n).then_some(HelicalSpring { material: m, d, dm, n })
            })
        })
    })
}

/// Crank radii tried, mm.
const CRANK_RADII: &[f64] = &[10.0, 15.0, 20.0, 25.0, 30.0, 40.0, 50.0, 60.0, 80.0, 100.0, 120.0, 150.0, 200.0];

/// Anchor distance over crank radius, R/r, tried.
const ANCHOR_RATIOS: &[f64] = &[1.5, 2.0, 2.5, 3.0, 4.0];

/// Largest lever angle of a trim's leaf (rad): its tip deflects at most this times the lever.
pub const LEAF_LEVER_ANGLE: f64 = 0.25;

/// Drum radii tried for a stop's cable drum, mm.
const DRUM_RADII: &[f64] = &[5.0, 8.0, 10.0, 15.0, 20.0, 25.0, 30.0, 40.0, 50.0, 60.0, 80.0, 100.0, 120.0, 150.0];

/// Largest crank angles (rad) tried for a trim's crank at the far end of the region: its shaft is
/// geared down from x so that the crank turns at most this far. A small angle keeps the crank's
/// law k g² (1 − cos(d/g)) close to the trim's ½ k d² (the torque short by 1 − sin(φ)/φ at the
/// end, 1.5 % at 0.3 rad, 13 % at 0.9 rad); a large one lets the spring store less besides the
/// element's energy (the zero-free-length spring's energy at the anchor line, ½ k_s (R − r)²).
/// The search takes the lightest; the realised residual judges the law, and where it fails the
/// part chooser's accurate pass (`req.roller_departure` set) takes only the angles within
/// [`TRIM_LAW_DEPARTURE`].
const TRIM_CRANK_ANGLES: &[f64] = &[0.3, 0.5, 0.7, 0.9];

/// How far a trim's crank may fall short of the trim's linear torque k·d at the far end of the
/// region in the part chooser's accurate pass, as a share of it (1 − sin φ/φ at the crank's
/// largest angle φ; 0.3 rad gives 1.49 %): the lightest geometry's 0.9 rad falls 13 % short, and
/// on the Panda's sized trims (joints 2 and 4 at 4.65 and 8.5 N·m/rad over ±0.9 and ±0.6 rad)
/// that alone took the realised p99 from 0.95° to 2.34°; within this share it is 0.97°. No crank
/// within it passes: the leaf, linear by construction, is the trim's part.
pub const TRIM_LAW_DEPARTURE: f64 = 0.015;

/// Which mechanism a one-sided compression element gets (`[parts] stop_mechanism`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopMechanism {
    /// The lighter of [`StopMechanism::Torsion`] and [`StopMechanism::Drum`] that passes every check.
    Lightest,
    /// A torsion spring whose leg meets a stop ([`stop`]).
    Torsion,
    /// A compression spring pulled by a cable wound on a drum ([`drum_stop`]).
    Drum,
}

/// Which mechanism a trim gets (`[parts] trim_mechanism`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrimMechanism {
    /// The lighter of [`TrimMechanism::Leaf`] and [`TrimMechanism::Crank`] that passes every check.
    Lightest,
    /// A leaf spring in a sliding clamp ([`leaf`]).
    Leaf,
    /// An extension spring on a geared crank whose pin radius sets the rate ([`trim_crank`]).
    Crank,
}

/// Most wires [`Wires`] holds: every wire of the material table once.
const MAX_WIRES: usize = crate::design::parts::MATERIALS.len();

/// The wires a maker stocks besides [`Requirements::material`], in its order (a fixed array, so
/// that [`Requirements`] stays `Copy`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wires([Option<&'static Material>; MAX_WIRES]);

impl Wires {
    /// No other wire: every spring from [`Requirements::material`].
    pub const NONE: Wires = Wires([None; MAX_WIRES]);

    /// The wires `list`, in its order; None when they are more than the table holds (a list
    /// checked by `PartsSettings::validate` names each wire once, so never).
    pub fn new(list: &[&'static Material]) -> Option<Wires> {
        let mut w = Wires::NONE;
        if list.len() > MAX_WIRES {
            return None;
        }
        for (slot, m) in w.0.iter_mut().zip(list) {
            *slot = Some(*m);
        }
        Some(w)
    }
}

/// What a part must meet: the `[parts]` settings resolved for one element.
#[derive(Debug, Clone, Copy)]
pub struct Requirements {
    /// The wire's material: the first wire the maker stocks (the fit's mass floor takes the
    /// lightest per joule of all of them, `fit::mass::Floor`).
    pub material: &'static Material,
    /// The other wires the maker stocks (`[parts] material` a list), in its order: every spring's
    /// search runs over the sizes of `material` and of these, and keeps the lightest part.
    pub also: Wires,
    /// EN 15800 quality grade, 1–3.
    pub grade: u8,
    /// Swings the part must survive.
    pub cycles: f64,
    /// Factor on every stress limit (static and fatigue).
    pub safety: f64,
    /// The springs' surface (shot-peened springs have a higher endurance).
    pub surface: Surface,
    /// Largest outer diameter, mm.
    pub max_outer_diameter: f64,
    /// Largest length (spring body, or spring and cable run beyond a crank's anchor), mm.
    pub max_length: f64,
    /// Largest lever or crank radius, mm.
    pub max_lever: f64,
    /// Shaft a torsion spring sits on, mm.
    pub shaft_diameter: f64,
    /// Radius of a crank cable's fairlead rollers, mm.
    pub pulley_radius: f64,
    /// The mechanism of a one-sided compression element.
    pub stop: StopMechanism,
    /// The mechanism of a trim.
    pub trim: TrimMechanism,
    /// How far a crank's rollers may make its torque depart from k sin d over the region, as a
    /// share of k; None: not bounded (the lightest geometry). The part chooser bounds it
    /// ([`MAX_ROLLER_DEPARTURE`]) only when the realised design needs it
    /// (`crate::parts::choose`): the bound costs steel, and only bills whose cranks' preloads
    /// cancel on a small net torque lose accuracy without it. Set, it also keeps a trim's crank
    /// within [`TRIM_LAW_DEPARTURE`] of the trim's linear law.
    pub roller_departure: Option<f64>,
}

impl Requirements {
    /// The wires a spring may be wound from: [`Requirements::material`], then
    /// [`Requirements::also`]. The searches try them in this order and replace their best part
    /// only by a strictly lighter one, so of two equally light springs the earlier wire's is
    /// kept, whatever the thread count.
    pub fn wires(&self) -> impl Iterator<Item = &'static Material> + '_ {
        std::iter::once(self.material).chain(self.also.0.iter().flatten().copied())
    }
}

/// The deflections an element sees, x − x₀ in rad: at the equilibrium, over the region, and over
/// the swings of the design's scenarios (for fatigue).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Duty {
    /// At q_eq.
    pub at_eq: f64,
    /// Smallest and largest over the region.
    pub range: [f64; 2],
    /// Smallest and largest over the scenarios' swings.
    pub swing: [f64; 2],
}

/// One check of a part: a utilisation (value / limit) that must be ≤ 1.
#[derive(Debug, Clone, PartialEq)]
pub struct Check {
    /// What is checked (`static stress`, `fatigue (Goodman)`, `outer diameter`, …).
    pub name: &'static str,
    /// The value, in `unit`.
    pub value: f64,
    /// Its limit, in `unit`.
    pub limit: f64,
    /// Unit of value and limit.
    pub unit: &'static str,
    /// True when a larger value is worse (stresses, sizes); false for minimums (coils, clearances).
    pub upper: bool,
}

impl Check {
    /// value / limit for an upper bound, limit / value for a lower bound: ≤ 1 passes.
    pub fn ratio(&self) -> f64 {
        if self.upper { self.value / self.limit } else { self.limit / self.value.max(1e-300) }
    }
}

/// The limit no spring meets: the best candidate's worst check.
#[derive(Debug, Clone, PartialEq)]
pub struct Limit {
    /// The check the best candidate fails.
    pub check: Check,
    /// The best candidate in words (`d = 8 mm, D = 64 mm, n = 7.7`).
    pub best: String,
    /// The torque on x the element must stay within to get a part that passes (the parts
    /// stage finds it by bisection on the element's stiffness); None when no stiffness gets a
    /// part (a geometric limit) or the element is no fit candidate (trims, cams).
    pub torque_bound: Option<TorqueBound>,
}

/// The peak torque on x (N·m) that keeps a part possible for an element that has none.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TorqueBound {
    /// At most this: the limit grows with the load (stress, fatigue, envelope), so a weaker
    /// element gets a part (`[fit] max_element_torque` caps it).
    AtMost(f64),
    /// At least this: the limit grows as the load falls (an extension spring's initial tension
    /// against a soft crank), so only a stronger element, or none, gets a part. `share` is that
    /// torque over the bill's largest peak torque (`[fit] used_threshold` drops the elements
    /// below it).
    AtLeast {
        /// The least peak torque, N·m.
        torque: f64,
        /// Its share of the bill's largest element peak torque.
        share: f64,
    },
}

/// The spring of a part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Spring {
    /// A helical torsion spring.
    Torsion(TorsionSpring),
    /// A helical extension spring with its initial tension F₀ (N).
    Extension(HelicalSpring, f64),
    /// A helical compression spring with its free length L₀ (mm).
    Compression(HelicalSpring, f64),
    /// A leaf: thickness t, width b and clamp positions (free lengths, mm) for the rate range
    /// and at mid-range.
    Leaf {
        /// Strip thickness, mm.
        t: f64,
        /// Strip width, mm.
        b: f64,
        /// Free length in the clamp, mm: at the highest rate, at the end of the clamp's travel
        /// (the lowest rate), and at mid-range (where the trim is drawn and fatigue is checked).
        lengths: [f64; 3],
        /// The stack's rate on x at the end of the clamp's travel, N·m/rad: below it the leaf
        /// must be lifted off.
        lowest_rate: f64,
    },
}

impl Spring {
    /// `torsion`, `extension`, `compression` or `leaf`.
    pub fn kind(&self) -> &'static str {
        match self {
            Spring::Torsion(_) => "torsion",
            Spring::Extension(..) => "extension",
            Spring::Compression(..) => "compression",
            Spring::Leaf { .. } => "leaf",
        }
    }

    /// Wire diameter (leaf: thickness), mm.
    pub fn d(&self) -> f64 {
        match self {
            Spring::Torsion(s) => s.d,
            Spring::Extension(s, _) | Spring::Compression(s, _) => s.d,
            Spring::Leaf { t, .. } => *t,
        }
    }

    /// Mean coil diameter (leaf: width), mm.
    pub fn dm(&self) -> f64 {
        match self {
            Spring::Torsion(s) => s.dm,
            Spring::Extension(s, _) | Spring::Compression(s, _) => s.dm,
            Spring::Leaf { b, .. } => *b,
        }
    }

    /// Active coils (leaf: none).
    pub fn coils(&self) -> Option<f64> {
        match self {
            Spring::Torsion(s) => Some(s.n),
            Spring::Extension(s, _) | Spring::Compression(s, _) => Some(s.n),
            Spring::Leaf { .. } => None,
        }
    }

    /// The spring's own rate in the maker's unit (N·mm/° torsion, N/mm otherwise) and the unit.
    pub fn maker_rate(&self) -> (f64, &'static str) {
        match self {
            Spring::Torsion(s) => (s.rate_per_degree(), "N*mm/deg"),
            Spring::Extension(s, _) | Spring::Compression(s, _) => (s.rate(), "N/mm"),
            Spring::Leaf { t, b, lengths, .. } => (strip().e * b * t.powi(3) / (4.0 * lengths[2].powi(3)), "N/mm"),
        }
    }

    /// The material's name.
    pub fn material(&self) -> &'static str {
        match self {
            Spring::Torsion(s) => s.material.key,
            Spring::Extension(s, _) | Spring::Compression(s, _) => s.material.key,
            Spring::Leaf { .. } => strip().key,
        }
    }
}

/// A working point of a part: where it is and what it carries.
#[derive(Debug, Clone, PartialEq)]
pub struct WorkingPoint {
    /// `q_eq`, `range low`, `range high`.
    pub at: &'static str,
    /// Wind angle (°) of a torsion spring, length (mm) of a helical spring, tip deflection
    /// (mm) of a leaf.
    pub position: f64,
    /// Torque (N·mm) or force (N).
    pub load: f64,
}

/// How the spring is mounted and its geometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Mechanism {
    /// Two equal torsion springs wound against each other; each is wound `preload` rad at
    /// x = x₀ and the pair's rate is twice one spring's.
    TorsionPair {
        /// Each spring's wind at x = x₀, rad: the largest deflection over the region, so that
        /// neither leg leaves its stop.
        preload: f64,
    },
    /// A torsion spring engaged for x − x₀ of the sign `plus` (true: x > x₀).
    TorsionStop {
        /// True: the leg meets its stop for x > x₀; false: for x < x₀.
        plus: bool,
    },
    /// A compression spring pulled by a cable wound on a drum of radius `drum` (mm) on x: the
    /// cable runs through the spring's bore to a washer at its far end and is just taut at x₀, so
    /// the spring is compressed by exactly `drum`·(x − x₀) on the side `plus` and the cable is
    /// slack on the other.
    DrumStop {
        /// True: the cable winds on for x > x₀; false: for x < x₀.
        plus: bool,
        /// Radius of the drum (to the cable's centre), mm.
        drum: f64,
    },
    /// A trim's crank: an extension spring on a cable from a pin on a crank geared `gear` : 1
    /// down from x, over a fairlead at `big_r` (mm) from the crank's axis. The pin sits in a slot
    /// along the crank arm and a screw sets its radius r, so the rate on x, k_s r R / g², runs
    /// from 0 (the pin on the axis) to the top of the trim's range; the crank is clamped to its
    /// shaft on the built arm with the pin on the fairlead's line (relaxed at the build's
    /// equilibrium), `phase` rad of the crank from it as the rollers ask.
    TrimCrank {
        /// Pin radius, mm: at the top of the trim's range and at mid-range (where the trim is
        /// drawn and judged).
        r: [f64; 2],
        /// Distance of the fairlead from the axis, mm.
        big_r: f64,
        /// Radius of the fairlead's rollers, mm.
        pulley: f64,
        /// Angle of the pin ahead of the fairlead's line at q_eq, rad of the crank.
        phase: f64,
        /// Reduction from x to the crank's shaft (≥ 1).
        gear: f64,
    },
    /// A crank of radius `r` and an anchor at `big_r` (mm) with fairlead rollers of radius
    /// `pulley`; the spring's extension is the cable path less F₀/k_s. The pin sits `phase` rad
    /// ahead of x₀ (set at assembly, with the spring's rate, so that the realised torque and
    /// stiffness at q_eq are the fitted element's).
    Crank {
        /// Radius of the crank pin, mm.
        r: f64,
        /// Distance of the fairlead from the axis, mm (k_s·r·R = k).
        big_r: f64,
        /// Radius of the fairlead's rollers, mm.
        pulley: f64,
        /// Angle of the pin ahead of x₀ at assembly, rad.
        phase: f64,
    },
    /// A leaf on a lever of radius `lever` (mm) geared `gear` : 1 down from x.
    Leaf {
        /// The lever's radius, mm: the leaf's tip deflects lever·(x − x₀)/gear.
        lever: f64,
        /// Reduction from x to the lever's shaft (≥ 1), so the lever turns at most
        /// [`LEAF_LEVER_ANGLE`] over the region.
        gear: f64,
    },
    /// A cam's follower spring.
    Follower,
    /// A hardening (cubic) element built as a disc cam storing k (x − x₀)⁴ / 4 over `span`
    /// (rad of x), geared `gear` : 1, its roller follower on the part's compression springs.
    CubicCam {
        /// The range of x the cam covers, rad: the element's over the region, x₀ included.
        span: [f64; 2],
        /// The gear ratio g: the cam turns by (x − `span[0]`)/g, [`super::cam::CAM_TURN_DEG`] over
        /// the span.
        gear: f64,
        /// Base-circle radius, mm.
        base_radius: f64,
        /// Largest |pressure angle| of the pitch curve, degrees.
        max_pressure_angle: f64,
    },
}

/// A realised element: its mechanism, the spring to order (and how many), its figures and checks.
#[derive(Debug, Clone, PartialEq)]
pub struct Part {
    /// The mechanism and its geometry.
    pub mechanism: Mechanism,
    /// The spring.
    pub spring: Spring,
    /// How many of it (2 for a torsion pair).
    pub quantity: usize,
    /// The element's realised rate in the fit's unit (N·m/rad; N·m for a crank: k_s r R; a trim's
    /// as set on the built arm).
    pub realised_rate: f64,
    /// Working points.
    pub points: Vec<WorkingPoint>,
    /// Every check with its utilisation.
    pub checks: Vec<Check>,
    /// EN 15800 rate tolerance of the grade (± fraction).
    pub tolerance: f64,
    /// Mass of the springs, kg.
    pub mass: f64,
    /// Fatigue life at the swing, cycles (10⁸ and above reported as 10⁸).
    pub life: f64,
}

impl Part {
    /// The worst utilisation among the checks.
    pub fn worst(&self) -> f64 {
        self.checks.iter().map(Check::ratio).fold(0.0, f64::max)
    }

    /// The potential of the mechanism on x at deflection d = x − x₀: (U in J, dU/dx in N·m,
    /// d²U/dx² in N·m/rad). For the crank this is the cable geometry's, not k (1 − cos d).
    pub fn potential(&self, d: f64) -> (f64, f64, f64) {
        let k = self.realised_rate;
        match self.mechanism {
            Mechanism::TorsionPair { .. } | Mechanism::Leaf { .. } | Mechanism::Follower => (0.5 * k * d * d, k * d, k),
            // The cam's profile is the cubic's; the follower's rate scales it.
            Mechanism::CubicCam { .. } => (0.25 * k * d.powi(4), k * d.powi(3), 3.0 * k * d * d),
            Mechanism::TorsionStop { plus } | Mechanism::DrumStop { plus, .. } => {
                let e = if plus { d.max(0.0) } else { d.min(0.0) };
                (0.5 * k * e * e, k * e, if e != 0.0 { k } else { 0.0 })
            }
            Mechanism::Crank { .. } | Mechanism::TrimCrank { .. } => {
                // The curvature by central differences of the exact torque (the roller's wrap
                // has a kink where the pin crosses the exit line, at d = phase + kπ).
                let h = 1e-4;
                let (u, t) = self.energy_torque(d);
                (u, t, (self.energy_torque(d + h).1 - self.energy_torque(d - h).1) / (2.0 * h))
            }
        }
    }

    /// (U, dU/dx) of [`Part::potential`] without the curvature: for the crank one evaluation of
    /// the cable path and its slope instead of three of the path. The realised residual angles
    /// need the torque at every held-out sample for every part, and there the three paths (each a
    /// sine, cosine, hypot, atan2 and acos) were half the run of a fit with hundreds of cranks.
    pub fn energy_torque(&self, d: f64) -> (f64, f64) {
        match self.mechanism {
            Mechanism::Crank { r, big_r, pulley, phase } => {
                crank_energy_torque(self.realised_rate, r, big_r, pulley, phase, 1.0, d)
            }
            // The crank's own stiffness is the trim's rate times g².
            // The crank's own stiffness k_s r R from its spring's geometry (the trim's rate times g²,
            // and the rollers' factor: the stiffness at the equilibrium is the trim's rate).
            Mechanism::TrimCrank { r, big_r, pulley, phase, gear } => {
                let k = match self.spring {
                    Spring::Extension(s, _) => s.rate() * r[1] * big_r / 1000.0,
                    _ => self.realised_rate * gear * gear,
                };
                crank_energy_torque(k, r[1], big_r, pulley, phase, gear, d)
            }
            _ => {
                let (u, t, _) = self.potential(d);
                (u, t)
            }
        }
    }
}

/// (U in J, dU/dx in N·m) of a crank of stiffness `k` (N·m, k_s r R) on a shaft geared `gear` : 1
/// down from x, at deflection `d` of x: the crank turns d/g, its spring stores ½ k_s ℓ² with ℓ
/// the cable path, and the torque on x is the crank's over g. The constant ½k_s (R − r)² is
/// dropped so that U(0) ≈ 0 like k g² (1 − cos(d/g)).
fn crank_energy_torque(k: f64, r: f64, big_r: f64, pulley: f64, phase: f64, gear: f64, d: f64) -> (f64, f64) {
    let ks = k_s(k, r, big_r);
    let (length, slope) = cable_path_slope(r, big_r, pulley, d / gear - phase);
    let base = 0.5 * ks * (big_r - r).powi(2) / 1000.0;
    (0.5 * ks * length * length / 1000.0 - base, ks * length * slope / 1000.0 / gear)
}

/// The crank's spring rate k_s (N/mm) that gives the element's rate k (N·m/rad) at small angles.
fn k_s(k: f64, r: f64, big_r: f64) -> f64 {
    k * 1000.0 / (r * big_r)
}

/// [`cable_path`] and its slope dL/dd, mm/rad. Straight: L² = r² + R² − 2rR cos d, so
/// L' = rR sin d / L. Over the roller (tangent length t = √(dist² − ρ²) plus the wrap ρ·(3π/2 − φ
/// − acos(ρ/dist))): L' = dist′·t/dist − ρ φ′, the wrap's and the tangent's changes through dist
/// cancelling in part. Where the pin crosses the exit line (sin d = 0) the slope is the mean of
/// its two sides, as a central difference would give it.
pub fn cable_path_slope(r: f64, big_r: f64, pulley: f64, d: f64) -> (f64, f64) {
    let (sin, cos) = (d.sin(), d.cos());
    let (px, py) = (r * cos, (r * sin).abs());
    if pulley <= 0.0 {
        let length = (px - big_r).hypot(py);
        return (length, if length > 0.0 { r * big_r * sin / length } else { 0.0 });
    }
    // The roller above the exit line (the lower one by symmetry); the cable leaves its bottom
    // point heading outwards, running counter-clockwise round it.
    let side = if sin > 0.0 {
        1.0
    } else if sin < 0.0 {
        -1.0
    } else {
        0.0
    };
    let (dpx, dpy) = (-r * sin, r * cos * side);
    let (vx, vy) = (px - big_r, py - pulley);
    let raw = vx.hypot(vy);
    let floor = pulley * (1.0 + 1e-12);
    let dist = raw.max(floor);
    let phi = vy.atan2(vx).rem_euclid(2.0 * PI);
    let wrap = 1.5 * PI - phi - (pulley / dist).acos();
    let tangent = (dist * dist - pulley * pulley).sqrt();
    let ddist = if raw > floor { (vx * dpx + vy * dpy) / raw } else { 0.0 };
    let dphi = (vx * dpy - vy * dpx) / (raw * raw);
    (tangent + pulley * wrap, ddist * tangent / dist - pulley * dphi)
}

/// Length of the cable from the crank pin at angle `d` (radius `r`) to where it leaves the
/// fairlead at distance `big_r`, over the roller (radius `pulley`) on the side the pin is on, mm.
/// With `pulley` = 0 it is the distance |P − A| of the ideal zero-free-length spring.
pub fn cable_path(r: f64, big_r: f64, pulley: f64, d: f64) -> f64 {
    cable_path_slope(r, big_r, pulley, d).0
}

/// The best candidate of a search: the lightest part that passes, else the one closest to passing.
struct Search {
    best_pass: Option<Part>,
    best_fail: Option<(f64, Part, String)>,
}

impl Search {
    fn new() -> Search {
        Search { best_pass: None, best_fail: None }
    }

    /// Offers the candidate `build` makes, of spring mass `mass`: skipped unbuilt when a lighter
    /// part already passes (most of a search, as sizes grow), which keeps it fast.
    fn consider(&mut self, mass: f64, build: impl FnOnce() -> Part, describe: impl FnOnce() -> String) {
        if self.best_pass.as_ref().is_some_and(|b| mass >= b.mass) {
            return;
        }
        self.offer(build(), describe);
    }

    /// [`Search::consider`] for a candidate whose part's worst utilisation is at least `floor()`
    /// (the largest ratio of some of its checks, computed as the part computes them), which is
    /// cheap where the part is not: skipped unbuilt also when that floor already fails and
    /// cannot beat what the search holds (a part that passes, or a failing one as close). So the
    /// result is [`Search::consider`]'s, bit for bit: a skipped part could neither pass nor
    /// replace the best failing one (which only a strictly smaller worst ratio does). Most of a
    /// crank's search fails its static checks (too few coils, a stress or an envelope broken),
    /// and its fatigue checks and working points are most of the cost of a part.
    fn consider_above(
        &mut self,
        mass: f64,
        floor: impl FnOnce() -> f64,
        build: impl FnOnce() -> Part,
        describe: impl FnOnce() -> String,
    ) {
        if self.best_pass.as_ref().is_some_and(|b| mass >= b.mass) {
            return;
        }
        let floor = floor();
        if floor > 1.0 && (self.best_pass.is_some() || self.best_fail.as_ref().is_some_and(|b| floor >= b.0)) {
            return;
        }
        self.offer(build(), describe);
    }

    fn offer(&mut self, part: Part, describe: impl FnOnce() -> String) {
        let worst = part.worst();
        if worst <= 1.0 {
            if self.best_pass.as_ref().is_none_or(|b| part.mass < b.mass) {
                self.best_pass = Some(part);
            }
        } else if self.best_fail.as_ref().is_none_or(|b| worst < b.0) {
            self.best_fail = Some((worst, part, describe()));
        }
    }

    /// The part, or the limit.
    fn finish(self) -> Result<Part, Limit> {
        if let Some(p) = self.best_pass {
            return Ok(p);
        }
        let Some((_, part, best)) = self.best_fail else {
            // No candidate was built at all, so there is no ratio to state (a check against a
            // zero limit would print NaN): the sentence is the whole message.
            return Err(Limit {
                check: Check { name: "mechanism", value: 0.0, limit: 0.0, unit: "mm", upper: true },
                best: "no wire size of the material winds a spring of this rate in the envelope (the rate is outside what the smallest and largest wires give); drop the element (raise [fit] used_threshold) or widen [parts]".into(),
                torque_bound: None,
            });
        };
        let check =
            part.checks.iter().max_by(|a, b| a.ratio().total_cmp(&b.ratio())).cloned().expect("a part has checks");
        Err(Limit { torque_bound: None, check, best })
    }
}

/// The lighter of two mechanisms' parts that pass; when neither does, the limit closer to being
/// met (a limit without a ratio, no candidate built at all, counts as the farthest).
fn lighter(a: Result<Part, Limit>, b: Result<Part, Limit>) -> Result<Part, Limit> {
    match (a, b) {
        (Ok(a), Ok(b)) => Ok(if b.mass < a.mass { b } else { a }),
        (Ok(p), Err(_)) | (Err(_), Ok(p)) => Ok(p),
        (Err(a), Err(b)) => {
            let ratio = |l: &Limit| if l.check.name == "mechanism" { f64::INFINITY } else { l.check.ratio() };
            Err(if ratio(&b) < ratio(&a) { b } else { a })
        }
    }
}

fn upper(name: &'static str, value: f64, limit: f64, unit: &'static str) -> Check {
    Check { name, value, limit, unit, upper: true }
}

fn lower(name: &'static str, value: f64, limit: f64, unit: &'static str) -> Check {
    Check { name, value, limit, unit, upper: false }
}

/// The checks every torsion spring gets at wind angles `wind` (rad: at q_eq, over the range, and
/// the swing's two ends) under torques `k · wind`: `k` (N·mm/rad) is the geometry's rate for a
/// wound spring, the vendor's listed rate for a stock one (the torque it really carries).
fn torsion_checks(s: &TorsionSpring, k: f64, wind: [f64; 2], swing: [f64; 2], req: &Requirements) -> (Vec<Check>, f64) {
    let rm = s.rm();
    let stress = s.stress(k * wind[1]) * req.safety;
    let (lo, hi) = (s.stress(k * swing[0]), s.stress(k * swing[1]));
    let fatigue = Loading::Bending.goodman(rm, lo, hi, req.cycles, req.surface) * req.safety;
    let life = Loading::Bending.life(rm, lo, hi, 1.0 / req.safety, req.surface);
    let checks = vec![
        lower("active coils", s.n, MIN_COILS, "coils"),
        upper("static stress", stress, s.allowed(), "MPa"),
        upper("fatigue (Goodman)", fatigue, 1.0, "utilisation"),
        upper("outer diameter", s.outer_diameter(), req.max_outer_diameter, "mm"),
        upper("body length wound", s.body_length(wind[1]), req.max_length, "mm"),
        lower("arbor clearance: shaft / arbor allowed when wound", s.arbor(wind[1]), req.shaft_diameter, "mm"),
    ];
    (checks, life)
}

/// Searches torsion springs of rate `rate` (N·mm/rad), `quantity` of them, wound `wind` =
/// [least, most] rad over the region and `swing` over the scenarios.
fn torsion(
    rate: f64,
    quantity: f64,
    wind: [f64; 2],
    swing: [f64; 2],
    req: &Requirements,
    build: impl Fn(TorsionSpring, Vec<Check>, f64) -> Part,
) -> Search {
    let mut search = Search::new();
    for m in req.wires() {
        for d in m.sizes() {
            for w in indices() {
                let dm = w * d;
                // Legs as long as the coil's mean diameter, their bending in the rate (EN 13906-3).
                let n = TorsionSpring::coils_for(m, d, dm, dm, rate);
                if !(0.5..=400.0).contains(&n) {
                    continue;
                }
                let s = TorsionSpring { material: m, d, dm, n, leg: dm };
                search.consider(
                    quantity * s.mass(),
                    || {
                        let (checks, life) = torsion_checks(&s, s.rate(), wind, swing, req);
                        build(s, checks, life)
                    },
                    || format!("d = {d} mm, D = {dm:.1} mm, n = {n:.2}"),
                );
            }
        }
    }
    search
}

fn tolerance_of_torsion(s: &TorsionSpring, torque: f64, grade: u8) -> f64 {
    // EN 15800 is written for compression springs: applied at the force on the leg's mean radius.
    rate_tolerance(s.d, s.dm, s.n, torque / (0.5 * s.dm), grade)
}

/// The part of a spring element of profile `profile` and stiffness `k` (the fit's unit): the one
/// dispatch from an element to its mechanism, shared by `springfit parts` (`parts::choose`) and
/// the fit's mass model (`fit::mass`), so that the mass the fit weighs is the mass of the part
/// the bill will get. Linear: [`linear`]; one-sided compression: [`stop`] or [`drum_stop`], the
/// lighter that passes (or the one `[parts] stop_mechanism` forces); anything else: [`crank`]. A
/// cubic's disc cam and a cam's follower are chosen by their own functions (they need the cam's
/// profile), and a trim by [`trim`] (it needs its rate range).
pub fn spring_element(profile: Profile, k: f64, duty: &Duty, req: &Requirements) -> Result<Part, Limit> {
    match profile {
        Profile::Linear => linear(k, duty, req),
        Profile::Compression(side) => {
            let plus = side == Side::Plus;
            match req.stop {
                StopMechanism::Torsion => stop(k, plus, duty, req),
                StopMechanism::Drum => drum_stop(k, plus, duty, req),
                StopMechanism::Lightest => lighter(stop(k, plus, duty, req), drum_stop(k, plus, duty, req)),
            }
        }
        _ => crank(k, duty, req),
    }
}

/// The mass (kg) of [`spring_element`]'s part, None when no spring meets the element: what the
/// fit's mass model reads. The answers are kept for the process ([`PART_MASSES_KEPT`] at most):
/// the search is a pure function of its arguments, and a `fit` asks the same questions more than
/// once (each preparation's mass model reads every candidate at the same stiffnesses: the refit
/// around the trims' sized ranges, the placement rounds, the weights' candidates), so a kept
/// answer is the one the search would give again, bit for bit.
pub fn part_mass(profile: Profile, k: f64, duty: &Duty, req: &Requirements) -> Option<f64> {
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};
    /// A part's mass by its profile and its arguments' exact bits.
    type Kept = HashMap<(Profile, Vec<u64>), Option<f64>>;
    static KEPT: OnceLock<Mutex<Kept>> = OnceLock::new();
    // The arguments' exact values.
    let mut bits = vec![k.to_bits()];
    duty_bits(duty, &mut bits);
    requirements_bits(req, &mut bits);
    let key = (profile, bits);
    let kept = KEPT.get_or_init(Default::default);
    if let Some(mass) = kept.lock().ok().and_then(|m| m.get(&key).copied()) {
        return mass;
    }
    let mass = spring_element(profile, k, duty, req).ok().map(|p| p.mass);
    if let Ok(mut m) = kept.lock() {
        if m.len() >= PART_MASSES_KEPT {
            m.clear();
        }
        m.insert(key, mass);
    }
    mass
}

/// A material's identity in the kept answers' keys: its address (a `&'static` material is never
/// freed, so one address is one material, and its values cannot change).
fn material_bits(m: &'static Material) -> u64 {
    std::ptr::from_ref(m) as usize as u64
}

/// `duty`'s exact values, appended to a kept answer's key.
fn duty_bits(duty: &Duty, out: &mut Vec<u64>) {
    let Duty { at_eq, range, swing } = *duty;
    out.extend([at_eq, range[0], range[1], swing[0], swing[1]].map(f64::to_bits));
}

/// `req`'s exact values (every field: a new field fails to compile here until it is keyed),
/// appended to a kept answer's key. Formatting them as text cost a few per cent of a fit: each
/// material's `Debug` writes its tables.
fn requirements_bits(req: &Requirements, out: &mut Vec<u64>) {
    let Requirements {
        material,
        also,
        grade,
        cycles,
        safety,
        surface,
        max_outer_diameter,
        max_length,
        max_lever,
        shaft_diameter,
        pulley_radius,
        stop,
        trim,
        roller_departure,
    } = *req;
    out.push(material_bits(material));
    out.extend(also.0.iter().map(|w| w.map_or(0, material_bits)));
    out.extend([u64::from(grade), surface as u64, stop as u64, trim as u64]);
    out.extend(
        [cycles, safety, max_outer_diameter, max_length, max_lever, shaft_diameter, pulley_radius].map(f64::to_bits),
    );
    match roller_departure {
        None => out.push(0),
        Some(x) => out.extend([1, x.to_bits()]),
    }
}

/// The most answers [`part_mass`] keeps (a few hundred bytes each); past it, it starts afresh. A
/// fit of a few hundred candidates asks a few thousand.
pub const PART_MASSES_KEPT: usize = 100_000;

/// The part of a trim of rates `range` set at `mid` (N·m/rad): [`leaf`] or [`trim_crank`], the
/// lighter that passes (or the one `[parts] trim_mechanism` forces).
pub fn trim(range: [f64; 2], mid: f64, duty: &Duty, req: &Requirements) -> Result<Part, Limit> {
    match req.trim {
        TrimMechanism::Leaf => leaf(range, mid, duty, req),
        TrimMechanism::Crank => trim_crank(range, mid, duty, req),
        TrimMechanism::Lightest => lighter(leaf(range, mid, duty, req), trim_crank(range, mid, duty, req)),
    }
}

/// A linear element of rate `k` (N·m/rad): two torsion springs of k/2 against each other.
pub fn linear(k: f64, duty: &Duty, req: &Requirements) -> Result<Part, Limit> {
    let (preload, wind, swing) = linear_span(duty);
    let rate = 0.5 * k * 1000.0;
    let search = torsion(rate, 2.0, wind, swing, req, |s, checks, life| {
        linear_part(s, s.rate(), preload, duty, req.grade, checks, life)
    });
    search.finish()
}

/// A torsion pair's preload and its springs' wind angles over the region and over the swing,
/// rad: each spring is wound by the preload ± d and must never unwind to its free position.
fn linear_span(duty: &Duty) -> (f64, [f64; 2], [f64; 2]) {
    let reach = duty.range[0].abs().max(duty.range[1].abs());
    let preload = reach * 1.1 + 0.05;
    let sw = duty.swing[0].abs().max(duty.swing[1].abs());
    (preload, [preload - reach, preload + reach], [preload - sw, preload + sw])
}

/// The torsion pair of springs `s` of rate `r` (N·mm/rad: the geometry's for a wound spring, the
/// listed one for a stock spring), preloaded `preload` rad, with its checks and life.
fn linear_part(s: TorsionSpring, r: f64, preload: f64, duty: &Duty, grade: u8, checks: Vec<Check>, life: f64) -> Part {
    let reach = duty.range[0].abs().max(duty.range[1].abs());
    let points = [("q_eq", duty.at_eq), ("range low", duty.range[0]), ("range high", duty.range[1])]
        .into_iter()
        .map(|(at, d)| WorkingPoint { at, position: (preload + d).to_degrees(), load: r * (preload + d) })
        .collect();
    Part {
        mechanism: Mechanism::TorsionPair { preload },
        spring: Spring::Torsion(s),
        quantity: 2,
        realised_rate: 2.0 * r / 1000.0,
        points,
        tolerance: tolerance_of_torsion(&s, r * (preload + reach), grade),
        mass: 2.0 * s.mass(),
        checks,
        life,
    }
}

/// A one-sided compression element of rate `k` (N·m/rad) engaged on side `plus`: a torsion
/// spring against a leg stop.
pub fn stop(k: f64, plus: bool, duty: &Duty, req: &Requirements) -> Result<Part, Limit> {
    let (wind, swing) = engaged_span(plus, duty);
    let rate = k * 1000.0;
    let search = torsion(rate, 1.0, wind, swing, req, |s, checks, life| {
        stop_part(s, s.rate(), plus, duty, req.grade, checks, life)
    });
    search.finish()
}

/// The torsion stop of spring `s` of rate `r` (N·mm/rad: the geometry's, or a stock spring's
/// listed one) engaged on side `plus`, with its checks and life.
fn stop_part(s: TorsionSpring, r: f64, plus: bool, duty: &Duty, grade: u8, checks: Vec<Check>, life: f64) -> Part {
    let engaged = |d: f64| engagement(plus, d);
    let (wind, _) = engaged_span(plus, duty);
    let points = [("q_eq", duty.at_eq), ("range low", duty.range[0]), ("range high", duty.range[1])]
        .into_iter()
        .map(|(at, d)| WorkingPoint { at, position: engaged(d).to_degrees(), load: r * engaged(d) })
        .collect();
    Part {
        mechanism: Mechanism::TorsionStop { plus },
        spring: Spring::Torsion(s),
        quantity: 1,
        realised_rate: r / 1000.0,
        points,
        tolerance: tolerance_of_torsion(&s, r * wind[1].max(1e-3), grade),
        mass: s.mass(),
        checks,
        life,
    }
}

/// How far a one-sided element engaged on side `plus` is engaged at deflection `d`, rad (0 on the
/// free side).
fn engagement(plus: bool, d: f64) -> f64 {
    if plus { d.max(0.0) } else { (-d).max(0.0) }
}

/// The least and largest engagement of a one-sided element over the region and over the swing,
/// rad: a range that straddles x₀ engages from 0.
fn engaged_span(plus: bool, duty: &Duty) -> ([f64; 2], [f64; 2]) {
    let span = |[a, b]: [f64; 2]| {
        let (ea, eb) = (engagement(plus, a), engagement(plus, b));
        if a < 0.0 && b > 0.0 { [0.0, ea.max(eb)] } else { [ea.min(eb), ea.max(eb)] }
    };
    (span(duty.range), span(duty.swing))
}

/// A one-sided compression element of rate `k` (N·m/rad) engaged on side `plus`: one to four
/// equal compression springs side by side, pulled by a cable wound on a drum of radius ρ on x
/// (through each spring's bore to a washer at its far end), just taut at x₀. The cable winds on
/// by ρ·(x − x₀) exactly, so the springs' rate ρ² k_s is the element's and the potential is
/// ½ k max(0, ±(x − x₀))² with no geometry error; the springs store the element's energy and
/// nothing else (no preload), where a torsion spring stores it in bending (σ²/8E per unit volume
/// against τ²/4G: about half as much at the standards' allowed stresses). The drum radius is
/// searched with the springs: a small drum asks a short stiff spring, a large one a long soft one
/// (buckling and the envelope decide).
pub fn drum_stop(k: f64, plus: bool, duty: &Duty, req: &Requirements) -> Result<Part, Limit> {
    let (range, swing) = engaged_span(plus, duty);
    let mut search = Search::new();
    for &drum in DRUM_RADII.iter().filter(|&&r| r <= req.max_lever) {
        // N/mm of all the springs together: k (N·mm/rad) = k_s ρ².
        let rate = k * 1000.0 / (drum * drum);
        let scale = |[a, b]: [f64; 2]| [a * drum, b * drum];
        compression(&mut search, rate, scale(range), scale(swing), req, |quantity, s, l0, checks, life| {
            let spring = Listed { quantity, rate: s.rate(), checks, life };
            drum_part(spring, s, l0, plus, drum, duty, req.grade)
        });
    }
    search.finish()
}

/// How many springs of a part, their rate in N/mm (or N·mm/rad: the geometry's for a wound spring,
/// the vendor's listed one for a stock spring), their checks and life: what the parts built
/// round a given spring share.
struct Listed {
    quantity: usize,
    rate: f64,
    checks: Vec<Check>,
    life: f64,
}

/// The drum stop of `spring.quantity` compression springs `s` of free length `l0` (mm) on a drum
/// of radius `drum` (mm) engaged on side `plus`.
fn drum_part(spring: Listed, s: HelicalSpring, l0: f64, plus: bool, drum: f64, duty: &Duty, grade: u8) -> Part {
    let (range, _) = engaged_span(plus, duty);
    let rate = spring.rate;
    let points = [("q_eq", duty.at_eq), ("range low", duty.range[0]), ("range high", duty.range[1])]
        .into_iter()
        .map(|(at, d)| {
            let c = drum * engagement(plus, d);
            WorkingPoint { at, position: l0 - c, load: rate * c }
        })
        .collect();
    let q = spring.quantity as f64;
    Part {
        mechanism: Mechanism::DrumStop { plus, drum },
        spring: Spring::Compression(s, l0),
        quantity: spring.quantity,
        realised_rate: q * rate * drum * drum / 1000.0,
        points,
        tolerance: rate_tolerance(s.d, s.dm, s.n, rate * drum * range[1].max(1e-3), grade),
        mass: q * s.mass(),
        checks: spring.checks,
        life: spring.life,
    }
}

/// Smallest and largest of `f` over [a, b] (sampled, with the ends).
fn extremes(a: f64, b: f64, f: impl Fn(f64) -> f64) -> [f64; 2] {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for i in 0..=400 {
        let v = f(a + (b - a) * i as f64 / 400.0);
        lo = lo.min(v);
        hi = hi.max(v);
    }
    [lo, hi]
}

/// A crank of stiffness `k` (N·m): an extension spring of rate k_s = k/(r R) on a cable.
///
/// Without a bound on the rollers' departure (`req.roller_departure` None) the lightest part
/// over every geometry. With one, the lightest part among the geometries whose rollers depart
/// from k sin d by at most that share of k. When none of those passes every other check (a weak element
/// whose spring would need more coils than any wire gives, an envelope that takes only a short
/// anchor), the lightest part of the geometry that departs least among those that can pass;
/// when no geometry passes at all, the limit of the whole search.
pub fn crank(k: f64, duty: &Duty, req: &Requirements) -> Result<Part, Limit> {
    let pulley = req.pulley_radius;
    let mut geometries: Vec<CrankSetting> = Vec::new();
    for &r in CRANK_RADII.iter().filter(|&&r| r <= req.max_lever) {
        for &ratio in ANCHOR_RATIOS {
            let big_r = ratio * r;
            if big_r - r < 2.0 * pulley + 2.0 {
                continue;
            }
            let (phase, scale) = compensate(k, r, big_r, pulley, duty.at_eq);
            let departure = roller_departure(r, big_r, pulley, phase, scale, duty.range);
            geometries.push(CrankSetting { r, big_r, phase, scale, departure });
        }
    }
    let Some(bound) = req.roller_departure else {
        return crank_search(k, duty, req, &geometries, f64::INFINITY);
    };
    let within: Vec<CrankSetting> = geometries.iter().copied().filter(|g| g.departure <= bound).collect();
    let bounded = crank_search(k, duty, req, &within, bound);
    if bounded.is_ok() {
        return bounded;
    }
    geometries.sort_by(|a, b| a.departure.total_cmp(&b.departure));
    for g in geometries.iter().filter(|g| g.departure > bound) {
        if let Ok(part) = crank_search(k, duty, req, std::slice::from_ref(g), g.departure) {
            return Ok(part);
        }
    }
    // No geometry passes the other checks: the limit over them all, as without the bound.
    crank_search(k, duty, req, &geometries, f64::INFINITY)
}

/// A crank geometry the search tries: radius, anchor distance (mm), the rollers' compensation
/// (phase, rate factor) and the departure it leaves ([`roller_departure`]).
#[derive(Clone, Copy)]
struct CrankSetting {
    r: f64,
    big_r: f64,
    phase: f64,
    scale: f64,
    departure: f64,
}

/// The lightest crank part over `geometries` and every spring of each, checked against the
/// departure `allowed` (a share of k; infinite: the departure is not checked).
fn crank_search(
    k: f64,
    duty: &Duty,
    req: &Requirements,
    geometries: &[CrankSetting],
    allowed: f64,
) -> Result<Part, Limit> {
    let mut search = Search::new();
    let pulley = req.pulley_radius;
    for &CrankSetting { r, big_r, phase, scale, departure } in geometries {
        let ks = k_s(scale * k, r, big_r);
        let path = |d: f64| cable_path(r, big_r, pulley, d - phase);
        // The cable path's extremes, traced when a spring of this geometry is first checked (a
        // geometry whose every spring is heavier than a part that passes needs none).
        let traced = std::cell::Cell::new(None);
        let geometry = || {
            let paths = traced.get().unwrap_or_else(|| {
                let [lmin, lmax] = extremes(duty.range[0], duty.range[1], path);
                let [smin, smax] = extremes(duty.swing[0], duty.swing[1], path);
                traced.set(Some([lmin, lmax, smin, smax]));
                [lmin, lmax, smin, smax]
            });
            CrankGeometry { r, big_r, pulley, phase, ks, paths }
        };
        // The rollers' check, where the search bounds them.
        let rollers = || allowed.is_finite().then(|| departure_check(departure, allowed));
        for s in helical(ks, req) {
            search.consider_above(
                s.mass(),
                || {
                    let fixed = crank_static_checks(&geometry(), req, s, s.initial_tension());
                    fixed.iter().chain(&rollers()).map(Check::ratio).fold(0.0, f64::max)
                },
                || {
                    let mut part = crank_part(&geometry(), duty, req, s, s.initial_tension(), &path);
                    part.checks.extend(rollers());
                    part
                },
                || format!("r = {r} mm, R = {big_r} mm, d = {} mm, D = {:.1} mm, n = {:.2}", s.d, s.dm, s.n),
            );
        }
    }
    search.finish()
}

/// Where a crank's spring works: crank radius, anchor distance, rollers, the pin's phase, the
/// spring rate k_s it must have and the cable path's extremes over the region and the swing.
#[derive(Clone, Copy)]
struct CrankGeometry {
    r: f64,
    big_r: f64,
    pulley: f64,
    phase: f64,
    ks: f64,
    /// Shortest and longest cable path over the region, then over the swing, mm.
    paths: [f64; 4],
}

/// The checks of [`crank_part`] that need neither its fatigue lines nor its working points
/// (coils, initial tension, static stresses, envelope), each as the part states it: what
/// [`crank_search`] screens a spring with before building its part.
fn crank_static_checks(g: &CrankGeometry, req: &Requirements, s: HelicalSpring, f0: f64) -> [Check; 8] {
    let CrankGeometry { r, ks, paths: [lmin, lmax, _, _], .. } = *g;
    let (d, dm, n) = (s.d, s.dm, s.n);
    // Extension beyond the free length: the cable path less F₀/k_s.
    let extension = lmax - f0 / ks;
    let rm = s.rm();
    let fmax = ks * lmax;
    [
        lower("active coils", n, MIN_COILS + 1.0, "coils"),
        upper("initial tension: F0 / (k_s · shortest cable path)", f0, ks * lmin, "N"),
        upper("static stress", s.stress(fmax) * req.safety, 0.45 * rm, "MPa"),
        upper("hook torsion at B (Shigley Eq. 10-36)", hook_torsion_stress(d, dm, fmax) * req.safety, 0.40 * rm, "MPa"),
        upper("hook bending at A (Shigley Eq. 10-34)", hook_bending_stress(d, dm, fmax) * req.safety, 0.75 * rm, "MPa"),
        upper("outer diameter", s.outer_diameter(), req.max_outer_diameter, "mm"),
        upper("length extended", s.extension_free_length() + extension, req.max_length, "mm"),
        upper("crank radius", r, req.max_lever, "mm"),
    ]
}

/// The crank part of spring `s` (initial tension `f0`, N) at `g`, with every check: the body's
/// and the loops' stresses, static and in fatigue, the envelope. `path` is the cable path at a
/// deflection.
fn crank_part(
    g: &CrankGeometry,
    duty: &Duty,
    req: &Requirements,
    s: HelicalSpring,
    f0: f64,
    path: &dyn Fn(f64) -> f64,
) -> Part {
    let CrankGeometry { r, big_r, pulley, phase, ks, paths: [_, lmax, smin, smax] } = *g;
    let (d, dm, n) = (s.d, s.dm, s.n);
    let rm = s.rm();
    let fmax = ks * lmax;
    let (fa, fb) = (ks * smin, ks * smax);
    let surface = req.surface;
    // Body and hook (torsion at B, bending at A): the life is the
    // shortest, the fatigue check the worst of the three.
    let lives = [
        Loading::Shear.life(rm, s.stress(fa), s.stress(fb), 1.0 / req.safety, surface),
        Loading::Shear.life(
            rm,
            hook_torsion_stress(d, dm, fa),
            hook_torsion_stress(d, dm, fb),
            1.0 / req.safety,
            surface,
        ),
        Loading::HookBending.life(
            rm,
            hook_bending_stress(d, dm, fa),
            hook_bending_stress(d, dm, fb),
            1.0 / req.safety,
            surface,
        ),
    ];
    let life = lives.into_iter().fold(f64::INFINITY, f64::min);
    let cycles = req.cycles;
    // A loop's fatigue check: its stress at the swing's two ends on its Goodman line.
    let hook_fatigue = |name, loading: Loading, stress: fn(f64, f64, f64) -> f64| {
        let u = loading.goodman(rm, stress(d, dm, fa), stress(d, dm, fb), cycles, surface);
        upper(name, u * req.safety, 1.0, "utilisation")
    };
    let [coils, tension, stress, torsion, bending, outer, length, radius] = crank_static_checks(g, req, s, f0);
    let checks = vec![
        coils,
        tension,
        stress,
        upper(
            "fatigue (Zimmerli-Goodman)",
            Loading::Shear.goodman(rm, s.stress(fa), s.stress(fb), cycles, surface) * req.safety,
            1.0,
            "utilisation",
        ),
        torsion,
        bending,
        hook_fatigue("hook fatigue, torsion at B (Zimmerli-Goodman)", Loading::Shear, hook_torsion_stress),
        hook_fatigue("hook fatigue, bending at A (Zimmerli-Goodman)", Loading::HookBending, hook_bending_stress),
        outer,
        length,
        radius,
    ];
    let points = [("q_eq", duty.at_eq), ("range low", duty.range[0]), ("range high", duty.range[1])]
        .into_iter()
        .map(|(at, d)| WorkingPoint { at, position: s.extension_free_length() + path(d) - f0 / ks, load: ks * path(d) })
        .collect();
    Part {
        mechanism: Mechanism::Crank { r, big_r, pulley, phase },
        spring: Spring::Extension(s, f0),
        quantity: 1,
        realised_rate: s.rate() * r * big_r / 1000.0,
        points,
        checks,
        tolerance: rate_tolerance(d, dm, n, fmax, req.grade),
        mass: s.mass(),
        life,
    }
}

/// A crank of stiffness `k` built round a given extension spring `s` of initial tension `f0`
/// (N), a stock part whose vendor lists the rate `listed` (N/mm): at each crank radius the
/// anchor distance R is set so that the spring's own rate gives the element's, k_s r R = k (with
/// the rollers' compensation, iterated), within the anchor ratios 1.5–4 R/r of the wound
/// search. The candidate that passes with the most margin, else the one closest to passing;
/// None when no radius takes the rate. The part's tolerance is its grade's capped at `cap`, the
/// vendor's stated tolerance; a listed rate that differs from the geometry's by more than that
/// fails a check of its own.
pub fn crank_round(
    k: f64,
    duty: &Duty,
    req: &Requirements,
    s: HelicalSpring,
    f0: f64,
    listed: f64,
    cap: f64,
) -> Option<Part> {
    let rate = s.rate();
    let mut best: Option<Part> = None;
    for (mut part, (r, big_r, phase, scale)) in crank_round_geometries(k, duty, req, s, f0) {
        part.tolerance = part.tolerance.min(cap);
        if let Some(allowed) = req.roller_departure {
            let departure = roller_departure(r, big_r, req.pulley_radius, phase, scale, duty.range);
            part.checks.push(departure_check(departure, allowed));
        }
        part.checks.push(upper("listed rate against the geometry's", (listed / rate - 1.0).abs(), part.tolerance, ""));
        if best.as_ref().is_none_or(|b| part.worst() < b.worst()) {
            best = Some(part);
        }
    }
    best
}

/// [`crank_round`]'s crank at each radius that takes the spring's rate, before the checks that
/// depend on the listing and on the rollers' bound: the part and its geometry (r, R, the pin's
/// phase, the rollers' rate factor). Its rollers compensated five times per radius, it is most
/// of a stock crank's search, and the part chooser asks it twice of every crank when it bounds
/// the rollers (a pass without the bound, one with; `parts::choose`): the answers are kept for
/// the process ([`CRANK_ROUNDS_KEPT`] at most), a pure function of the arguments but the bound,
/// which it does not read. A kept answer is the one the search would give again, bit for bit.
#[allow(clippy::type_complexity)]
fn crank_round_geometries(
    k: f64,
    duty: &Duty,
    req: &Requirements,
    s: HelicalSpring,
    f0: f64,
) -> Vec<(Part, (f64, f64, f64, f64))> {
    use std::collections::HashMap;
    use std::sync::{Arc, Mutex, OnceLock};
    type Kept = HashMap<Vec<u64>, Arc<Vec<(Part, (f64, f64, f64, f64))>>>;
    static KEPT: OnceLock<Mutex<Kept>> = OnceLock::new();
    // The arguments' exact values.
    let unbounded = Requirements { roller_departure: None, ..*req };
    let mut key = vec![k.to_bits(), f0.to_bits()];
    duty_bits(duty, &mut key);
    requirements_bits(&unbounded, &mut key);
    let HelicalSpring { material, d, dm, n } = s;
    key.extend([material_bits(material), d.to_bits(), dm.to_bits(), n.to_bits()]);
    let kept = KEPT.get_or_init(Default::default);
    if let Some(found) = kept.lock().ok().and_then(|m| m.get(&key).cloned()) {
        return found.as_ref().clone();
    }
    let pulley = req.pulley_radius;
    let rate = s.rate();
    let mut out = Vec::new();
    for &r in CRANK_RADII.iter().filter(|&&r| r <= req.max_lever) {
        let mut big_r = k * 1000.0 / (r * rate);
        let (lo, hi) = (ANCHOR_RATIOS[0] * r, ANCHOR_RATIOS[ANCHOR_RATIOS.len() - 1] * r);
        if !(lo..=hi).contains(&big_r) || big_r - r < 2.0 * pulley + 2.0 {
            continue;
        }
        let mut comp = compensate(k, r, big_r, pulley, duty.at_eq);
        for _ in 0..4 {
            big_r = comp.1 * k * 1000.0 / (r * rate);
            comp = compensate(k, r, big_r, pulley, duty.at_eq);
        }
        let (phase, scale) = comp;
        let ks = k_s(scale * k, r, big_r);
        let path = |d: f64| cable_path(r, big_r, pulley, d - phase);
        let [lmin, lmax] = extremes(duty.range[0], duty.range[1], path);
        let [smin, smax] = extremes(duty.swing[0], duty.swing[1], path);
        let geometry = CrankGeometry { r, big_r, pulley, phase, ks, paths: [lmin, lmax, smin, smax] };
        out.push((crank_part(&geometry, duty, &unbounded, s, f0, &path), (r, big_r, phase, scale)));
    }
    if let Ok(mut m) = kept.lock() {
        if m.len() >= CRANK_ROUNDS_KEPT {
            m.clear();
        }
        m.insert(key, Arc::new(out.clone()));
    }
    out
}

/// The most answers `crank_round_geometries` keeps (a few kilobytes each); past it, it starts
/// afresh.
pub const CRANK_ROUNDS_KEPT: usize = 20_000;

/// The rates (N/mm) of the extension springs [`crank_round`] can build a crank of stiffness `k`
/// round, one interval per crank radius: the anchor distance R = k/(r k_s) must lie within the
/// anchor ratios before the rollers' compensation (a few per cent) is iterated. Each interval is
/// widened by a part in 10⁹, so that a pre-filter on it never drops a spring `crank_round`
/// would take.
pub fn crank_rates(k: f64, req: &Requirements) -> Vec<[f64; 2]> {
    let (lo, hi) = (ANCHOR_RATIOS[0], ANCHOR_RATIOS[ANCHOR_RATIOS.len() - 1]);
    CRANK_RADII
        .iter()
        .filter(|&&r| r <= req.max_lever)
        .map(|&r| [k * 1000.0 / (r * hi * r) * (1.0 - 1e-9), k * 1000.0 / (r * lo * r) * (1.0 + 1e-9)])
        .collect()
}

/// A listed (stock) spring as the vendor publishes it: its geometry (a torsion spring's legs
/// its listed leg length, a compression spring's free length the listed one) and the vendor's
/// figures, in the maker's units (N·mm/°, °, N·mm for torsion; N/mm, mm, N otherwise).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StockSpring {
    /// The geometry: [`Spring::Torsion`] or [`Spring::Compression`] with its free length.
    pub spring: Spring,
    /// The listed rate.
    pub rate: f64,
    /// The listed largest deflection.
    pub max_deflection: f64,
    /// The listed largest load.
    pub max_load: f64,
    /// The vendor's stated rate tolerance (± fraction) that caps the grade's.
    pub cap: f64,
}

/// The part of `wound`'s mechanism, over the same working deflections (`duty`), built round a
/// listed spring instead of the wound one: the same checks a wound spring gets (static stress
/// and Goodman at its working points, the envelope; a compression spring's buckling and its
/// length at the largest compression against solid; a torsion spring's arbor), under the loads
/// of the vendor's listed rate (what the spring really carries), plus the stock row's own: its
/// rate within the element's by the part's tolerance, its listed rate within its geometry's by
/// the same, its listed largest deflection and load. The tolerance is EN 15800's for the
/// listed spring's geometry and grade, capped at the vendor's stated one: a listed spring is
/// not accepted further from the element than the vendor promises to hold it. The realised
/// rate is the listed one, and it must be within the wound spring's tolerance of the element's
/// too. None when the mechanism takes no spring of that kind (a crank, a
/// leaf; a torsion spring on a drum).
pub fn round_listed(wound: &Part, duty: &Duty, req: &Requirements, listed: StockSpring) -> Option<Part> {
    let rate = listed.rate;
    let mut part = match (wound.mechanism, listed.spring) {
        (Mechanism::TorsionPair { preload }, Spring::Torsion(s)) => {
            let r = rate.to_degrees();
            let (_, wind, swing) = linear_span(duty);
            let (checks, life) = torsion_checks(&s, r, wind, swing, req);
            linear_part(s, r, preload, duty, req.grade, checks, life)
        }
        (Mechanism::TorsionStop { plus }, Spring::Torsion(s)) => {
            let r = rate.to_degrees();
            let (wind, swing) = engaged_span(plus, duty);
            let (checks, life) = torsion_checks(&s, r, wind, swing, req);
            stop_part(s, r, plus, duty, req.grade, checks, life)
        }
        (Mechanism::DrumStop { plus, drum }, Spring::Compression(s, l0)) => {
            // The drum is machined for the spring it carries: its radius scales the element's
            // rate by its square (q k_s ρ²), so a drum of ρ √(k_wound / k_listed) gives the
            // element exactly the wound spring's rate with the listed one — the listed rate's
            // departure (within the checks below) costs a drum a few percent larger or smaller,
            // not the element's accuracy (issue 45: every spring's element within 1.5 %).
            let drum = drum * (wound.spring.maker_rate().0 / rate).sqrt();
            let (range, swing) = engaged_span(plus, duty);
            let loads = [rate * drum * swing[0], rate * drum * swing[1], rate * drum * range[1]];
            let (checks, life) = compression_checks(&s, l0, loads, drum * range[1], req);
            let spring = Listed { quantity: wound.quantity, rate, checks, life };
            drum_part(spring, s, l0, plus, drum, duty, req.grade)
        }
        (Mechanism::Follower | Mechanism::CubicCam { .. }, Spring::Compression(s, l0)) => {
            let Spring::Compression(w, l0w) = wound.spring else { return None };
            let [base, top] = [&wound.points[0], &wound.points[wound.points.len() - 1]];
            let span = [l0w - base.position, l0w - top.position];
            let loads = [rate * span[0], rate * span[1], rate * span[1]];
            let (checks, life) = compression_checks(&s, l0, loads, span[1], req);
            let spring = Listed { quantity: wound.quantity, rate, checks, life };
            let mut part = follower_part(spring, s, l0, span, req.grade);
            if let Mechanism::CubicCam { .. } = wound.mechanism {
                // The cam's rate scales with its follower springs' (the cam stores k (x − x₀)⁴/4
                // at the asked follower rate).
                part.realised_rate = wound.realised_rate * rate / w.rate();
                part.mechanism = wound.mechanism;
            }
            part
        }
        _ => return None,
    };
    let need = wound.spring.maker_rate().0;
    let (geometry, _) = listed.spring.maker_rate();
    part.tolerance = part.tolerance.min(listed.cap);
    // The deflection of each working point from free: a torsion spring's wind angle (°), a
    // compression spring's length change (mm).
    let deflection = |w: &WorkingPoint| match listed.spring {
        Spring::Compression(_, l0) => l0 - w.position,
        _ => w.position,
    };
    let most = part.points.iter().fold((0.0f64, 0.0f64), |(a, b), w| (a.max(deflection(w)), b.max(w.load)));
    let (du, lu) = if matches!(listed.spring, Spring::Torsion(_)) { ("°", "N·mm") } else { ("mm", "N") };
    // Never further from the element than the wound spring's own grade tolerance either: the
    // stock part replaces it, and is not to be held to a looser rate than it.
    let within = part.tolerance.min(wound.tolerance);
    part.checks.push(upper("stock rate against the element's", (rate / need - 1.0).abs(), within, ""));
    part.checks.push(upper("listed rate against the geometry's", (rate / geometry - 1.0).abs(), part.tolerance, ""));
    part.checks.push(upper("listed largest deflection", most.0, listed.max_deflection, du));
    part.checks.push(upper("listed largest load", most.1, listed.max_load, lu));
    if let Spring::Compression(s, l0) = listed.spring {
        // What the stroke needs, solid length + least gaps + largest compression, against the
        // listed free length (a wound spring's free length is this sum).
        part.checks.push(upper(
            "free length for the stroke (solid + least gaps + largest compression)",
            s.solid_length() + s.min_gaps() + most.0,
            l0,
            "mm",
        ));
    }
    Some(part)
}

/// Largest departure of a crank's realised torque over its rollers from the element's k sin d
/// over the region, as a share of k: the part chooser passes only geometries within it
/// (`roller_departure`). The rollers' compensation (`compensate`) makes torque and
/// stiffness exact at q_eq; away from it the cable's wrap round a roller of radius ρ leaves a
/// departure that falls about as (ρ / (R − r))² with the anchor distance. A bill of many cranks
/// whose preloads cancel at q_eq adds these departures up on a small net torque (the Panda's
/// three pitch joints: realised p99 3.13° from an ideal 0.16° with the lightest geometries, whose
/// departures reach 0.6 % of k); a few tenths of a percent of k are a few percent of the net.
/// Every crank radius has anchor ratios that keep 0.1 % over a ±0.3 rad range (R/r ≥ 2.5 from
/// r = 10 mm, R/r ≥ 2 from 50 mm), at the cost of more stored energy (the zero-free-length
/// spring's ½ k_s (R − r)² besides the element's).
pub const MAX_ROLLER_DEPARTURE: f64 = 0.001;

/// The check of a geometry's rollers' departure (a share of k) against `allowed`:
/// [`MAX_ROLLER_DEPARTURE`], or for a crank no geometry within it can build, the least departure
/// of the geometries that pass the other checks (what the part then reaches, stated in
/// `parts.csv`).
fn departure_check(departure: f64, allowed: f64) -> Check {
    upper("rollers' departure from k sin d over the region (share of k)", departure, allowed, "")
}

/// The largest |τ(d)/k − sin d| over the deflections `range` of a crank of radius `r`, anchor
/// `big_r` and rollers of radius `pulley` (mm) with the compensation's phase and rate factor:
/// the realised torque [`Part::energy_torque`] gives (k's realised rate is `scale` k), against
/// the element's. Linear in k, so evaluated at k = 1 on 101 deflections. 0 without rollers.
fn roller_departure(r: f64, big_r: f64, pulley: f64, phase: f64, scale: f64, range: [f64; 2]) -> f64 {
    if pulley <= 0.0 {
        return 0.0;
    }
    (0..=100)
        .map(|i| {
            let d = range[0] + (range[1] - range[0]) * i as f64 / 100.0;
            (crank_energy_torque(scale, r, big_r, pulley, phase, 1.0, d).1 - d.sin()).abs()
        })
        .fold(0.0, f64::max)
}

/// The pin's phase δ and the rate factor s that make the crank's cable geometry give the fitted
/// element's torque k sin d and stiffness k cos d at the equilibrium deflection `at_eq`: the
/// rollers bend the cable, so the realised torque s k_s ℓ(d − δ) ℓ′(d − δ) differs a little
/// from k sin d, and without this the equilibrium would move (the elements' preloads, which
/// cancel at q_eq, no longer would). Solved by Newton on δ, then s.
///
/// The torque is the part's own ([`cable_path_slope`], as [`Part::potential`] evaluates it), the
/// stiffness its central difference (step [`COMPENSATE_STEP`]), so g(δ) below is good to about
/// 1e-11 of its scale, and Newton stops once a step is under [`COMPENSATE_TOLERANCE`] (two or
/// three steps from δ = 0). Differences of differences of the path, as it was before, left a
/// noise of about 1e-6 relative in g: the steps never fell below it, and the phase wandered by
/// up to 3e-6 rad over 30 steps.
fn compensate(k: f64, r: f64, big_r: f64, pulley: f64, at_eq: f64) -> (f64, f64) {
    if pulley <= 0.0 {
        return (0.0, 1.0);
    }
    let ks = k_s(k, r, big_r);
    let h = COMPENSATE_STEP;
    let torque = |d: f64| {
        let (length, slope) = cable_path_slope(r, big_r, pulley, d);
        ks * length * slope / 1000.0
    };
    let stiffness = |d: f64| (torque(d + h) - torque(d - h)) / (2.0 * h);
    let (t, c) = (k * at_eq.sin(), k * at_eq.cos());
    // g(δ) = 0 ⇔ the torque/stiffness ratio at d − δ is the ideal one.
    let g = |delta: f64| torque(at_eq - delta) * c - stiffness(at_eq - delta) * t;
    let mut delta = 0.0;
    for _ in 0..30 {
        let slope = (g(delta + 1e-4) - g(delta - 1e-4)) / 2e-4;
        if slope == 0.0 || !slope.is_finite() {
            break;
        }
        let step = g(delta) / slope;
        delta -= step.clamp(-0.05, 0.05);
        if step.abs() < COMPENSATE_TOLERANCE {
            break;
        }
    }
    let scale = if t.abs() > c.abs() { t / torque(at_eq - delta) } else { c / stiffness(at_eq - delta) };
    if delta.is_finite() && scale.is_finite() && scale > 0.0 { (delta, scale) } else { (0.0, 1.0) }
}

/// The step of [`compensate`]'s central difference of the crank's torque, rad: its truncation
/// (h² of the torque's third derivative, about 1e-10 relative) and its rounding (1e-16 / h)
/// both near 1e-11 of the stiffness.
const COMPENSATE_STEP: f64 = 1e-5;

/// Where [`compensate`]'s Newton stops, rad of phase: 20× the largest step its noise floor
/// still makes (4.6e-11 rad, measured on a line-for-line Python replica of this iteration over 300
/// random geometries: r 20–100 mm, R 1.2–4 r, rollers 3–8 mm, q_eq within ±1.2 rad, 30 steps). A
/// phase of 1e-9 rad moves a 100 mm pin by 1e-7 mm.
const COMPENSATE_TOLERANCE: f64 = 1e-9;

/// A trim of rates `range` (N·m/rad) set at `mid` (N·m/rad): a leaf spring in a sliding clamp.
pub fn leaf(range: [f64; 2], mid: f64, duty: &Duty, req: &Requirements) -> Result<Part, Limit> {
    let m = strip();
    let reach = duty.range[0].abs().max(duty.range[1].abs()).max(1e-3);
    let gear = (reach / LEAF_LEVER_ANGLE).max(1.0);
    let mut search = Search::new();
    // A stack of up to four equal leaves in the one clamp, free to slide on each other, shares
    // the rate: each leaf is then longer for its rate, and its stress at a given tip swing falls
    // as quantity^(−2/3) (σ ∝ t δ / L², L ∝ (rate per leaf)^(−1/3)).
    for quantity in 1..=4usize {
        let q = quantity as f64;
        let (range, mid) = ([range[0] / q, range[1] / q], mid / q);
        let hi = range[1].max(mid) * 1000.0;
        for &lever in CRANK_RADII.iter().filter(|&&r| r <= req.max_lever) {
            for t in m.sizes() {
                for b in [10.0, 15.0, 20.0, 25.0, 30.0, 40.0, 50.0, 60.0, 80.0, 100.0, 120.0] {
                    // Rate on x: E b t³ r² / (4 L³ g²) (N·mm/rad), so L at a rate k is:
                    let length = |k: f64| (m.e * b * t.powi(3) * lever * lever / (4.0 * gear * gear * k)).cbrt();
                    let shortest = length(hi);
                    let longest = if range[0] > 0.0 { length(range[0] * 1000.0) } else { f64::INFINITY };
                    let travel_end = longest.min(req.max_length);
                    let lowest =
                        m.e * b * t.powi(3) * lever * lever / (4.0 * gear * gear * travel_end.powi(3)) / 1000.0;
                    let tip = lever * reach / gear;
                    let sigma = |l: f64, delta: f64| 1.5 * m.e * t * delta / (l * l);
                    let rm = m.tensile_strength(t).unwrap_or(0.0);
                    let tip_swing = lever * duty.swing[0].abs().max(duty.swing[1].abs()) / gear;
                    let mid_length = length(mid.max(lowest) * 1000.0);
                    // Static at the shortest setting; fatigue at mid-range, where the trim is drawn
                    // (a build moves it by a fraction of the range).
                    let swing_stress = sigma(mid_length, tip_swing);
                    let mut checks = vec![
                        upper("static stress", sigma(shortest, tip) * req.safety, 0.7 * rm, "MPa"),
                        upper(
                            "fatigue (Goodman)",
                            Loading::Bending.goodman(rm, -swing_stress, swing_stress, req.cycles, req.surface)
                                * req.safety,
                            1.0,
                            "utilisation",
                        ),
                        lower("leaf length / thickness at the highest rate", shortest / t, 10.0, ""),
                        upper("leaf width", b, req.max_outer_diameter, "mm"),
                    ];
                    if range[0] > 0.0 {
                        checks.push(upper("clamp travel to the lowest rate", longest, req.max_length, "mm"));
                    }
                    let life = Loading::Bending.life(rm, -swing_stress, swing_stress, 1.0 / req.safety, req.surface);
                    let points = [("q_eq", duty.at_eq), ("range low", duty.range[0]), ("range high", duty.range[1])]
                        .into_iter()
                        .map(|(at, d)| {
                            let delta = lever * d / gear;
                            WorkingPoint {
                                at,
                                position: delta,
                                load: 3.0 * m.e * b * t.powi(3) / 12.0 * delta / mid_length.powi(3),
                            }
                        })
                        .collect();
                    let part = Part {
                        mechanism: Mechanism::Leaf { lever, gear },
                        spring: Spring::Leaf {
                            t,
                            b,
                            lengths: [shortest, travel_end, mid_length],
                            lowest_rate: lowest * q,
                        },
                        quantity,
                        realised_rate: mid * q,
                        points,
                        checks,
                        // The clamp is set on the built arm: the leaf's own tolerance is tuned out.
                        tolerance: 0.0,
                        mass: q * m.density * b * t * (travel_end + 20.0) * 1e-9,
                        life,
                    };
                    search.offer(part, || {
                        format!("{quantity} × leaf on lever {lever} mm, gear {gear:.2}, t = {t} mm, b = {b} mm")
                    });
                }
            }
        }
    }
    search.finish()
}

/// A cam follower's compression springs: rate `rate` (N/mm) shared by one to four equal springs
/// round the stem, preload `preload` (mm) at the base circle and the cam's largest `stroke` (mm).
pub fn follower(rate: f64, preload: f64, stroke: f64, req: &Requirements) -> Result<Part, Limit> {
    let mut search = Search::new();
    let most = preload + stroke;
    // The cam's whole stroke is the swing: every turn runs the follower from base circle to top.
    compression(&mut search, rate, [preload, most], [preload, most], req, |quantity, s, l0, checks, life| {
        let part = follower_part(Listed { quantity, rate: s.rate(), checks, life }, s, l0, [preload, most], req.grade);
        // The loads are the follower's asked rate shared by the springs (the geometry's is that
        // rate to rounding).
        let per = rate / quantity as f64;
        let points = vec![
            WorkingPoint { at: "base circle", position: l0 - preload, load: per * preload },
            WorkingPoint { at: "largest stroke", position: l0 - most, load: per * most },
        ];
        Part { points, tolerance: rate_tolerance(s.d, s.dm, s.n, per * most, req.grade), ..part }
    });
    search.finish()
}

/// The follower of `spring.quantity` compression springs `s` of free length `l0` (mm), compressed
/// `[preload, most]` mm from free at the base circle and at the largest stroke.
fn follower_part(spring: Listed, s: HelicalSpring, l0: f64, [preload, most]: [f64; 2], grade: u8) -> Part {
    let q = spring.quantity as f64;
    let (f1, f2) = (spring.rate * preload, spring.rate * most);
    let points = vec![
        WorkingPoint { at: "base circle", position: l0 - preload, load: f1 },
        WorkingPoint { at: "largest stroke", position: l0 - most, load: f2 },
    ];
    Part {
        mechanism: Mechanism::Follower,
        spring: Spring::Compression(s, l0),
        quantity: spring.quantity,
        realised_rate: q * spring.rate,
        points,
        checks: spring.checks,
        tolerance: rate_tolerance(s.d, s.dm, s.n, f2, grade),
        mass: q * s.mass(),
        life: spring.life,
    }
}

/// Offers `search` one to four equal compression springs side by side sharing `rate` (N/mm),
/// compressed `range` = [least, most] mm from free over the region and `swing` over the swings:
/// closed and ground ends, free length l₀ = solid + the smallest gaps + the largest compression,
/// ends guided against buckling. `build` makes the part of `quantity` springs `s` of free length
/// l₀ from their checks and life.
fn compression(
    search: &mut Search,
    rate: f64,
    range: [f64; 2],
    swing: [f64; 2],
    req: &Requirements,
    build: impl Fn(usize, HelicalSpring, f64, Vec<Check>, f64) -> Part,
) {
    for quantity in 1..=4usize {
        let q = quantity as f64;
        let rate = rate / q;
        let (f1, f2) = (rate * swing[0], rate * swing[1]);
        let fmax = rate * range[1];
        for s in helical(rate, req) {
            let (d, dm, n) = (s.d, s.dm, s.n);
            search.consider(
                q * s.mass(),
                || {
                    let l0 = s.solid_length() + s.min_gaps() + range[1];
                    let (checks, life) = compression_checks(&s, l0, [f1, f2, fmax], range[1], req);
                    build(quantity, s, l0, checks, life)
                },
                || format!("{quantity} × d = {d} mm, D = {dm:.1} mm, n = {n:.2}"),
            );
        }
    }
}

/// The checks every compression spring `s` of free length `l0` (mm) gets under the loads
/// `[f1, f2, fmax]` (N: the swing's two ends and the largest over the region, at the largest
/// compression `most`, mm), and its fatigue life.
fn compression_checks(
    s: &HelicalSpring,
    l0: f64,
    [f1, f2, fmax]: [f64; 3],
    most: f64,
    req: &Requirements,
) -> (Vec<Check>, f64) {
    let rm = s.rm();
    let buckling = s.buckling_deflection(l0, 0.5).unwrap_or(f64::INFINITY);
    let checks = vec![
        lower("active coils", s.n, MIN_COILS, "coils"),
        upper("static stress", s.stress(fmax) * req.safety, 0.5 * rm, "MPa"),
        upper(
            "fatigue (Goodman)",
            Loading::Shear.goodman(rm, s.stress(f1), s.stress(f2), req.cycles, req.surface) * req.safety,
            1.0,
            "utilisation",
        ),
        upper("outer diameter", s.outer_diameter(), req.max_outer_diameter, "mm"),
        upper("free length", l0, req.max_length, "mm"),
        lower("buckling deflection (ends guided, ν = 0.5)", buckling, most, "mm"),
    ];
    let life = Loading::Shear.life(rm, s.stress(f1), s.stress(f2), 1.0 / req.safety, req.surface);
    (checks, life)
}

/// Fairlead distances over the pin's largest radius, R/r, tried for a trim's crank: the
/// zero-free-length spring is stretched by about R − r at the anchor line, energy it stores
/// besides the element's, so R close to r keeps the spring light (the rollers' clearance bounds it).
const TRIM_ANCHOR_RATIOS: &[f64] = &[1.1, 1.25, 1.5, 2.0, 3.0];

/// A trim of rates `range` (N·m/rad) set at `mid` as a crank: an extension spring of rate k_s on
/// a cable from a pin over a fairlead at R, the crank geared g : 1 down from x so that it turns
/// at most one of `TRIM_CRANK_ANGLES` over the region, its rate on x k_s r R / g². The pin
/// slides in a slot along the crank arm and a screw sets its radius r, so the rate is set in
/// proportion to r over the whole range, down to 0 with the pin on the axis (the spring, still
/// zero-free-length, then pulls the axis with k_s R and turns nothing). The spring is checked
/// statically at its longest cable path over every setting (R with the pin on the axis, or the
/// top of the range at the region's ends), in fatigue at mid-range (a build moves the setting by
/// a fraction of the range), its initial tension against the shortest path (the top of the
/// range at the anchor line). The crank is clamped to its shaft on the built arm with the pin on
/// the fairlead's line at the equilibrium, so the trim is relaxed there and its rate, like the
/// leaf's, is set on the built arm: no rate tolerance. The potential is the geared crank's,
/// rollers included ([`Part::potential`]), not ½ k d².
pub fn trim_crank(range: [f64; 2], mid: f64, duty: &Duty, req: &Requirements) -> Result<Part, Limit> {
    let reach = duty.range[0].abs().max(duty.range[1].abs()).max(1e-3);
    let pulley = req.pulley_radius;
    let clearance = 2.0 * pulley + 2.0;
    let top_rate = range[1].max(mid);
    let mut search = Search::new();
    if mid <= 0.0 {
        return search.finish();
    }
    // The accurate pass (a bound on the cranks' departures) keeps the crank's law within
    // TRIM_LAW_DEPARTURE of the trim's linear one.
    let within = |&&angle: &&f64| req.roller_departure.is_none() || 1.0 - angle.sin() / angle <= TRIM_LAW_DEPARTURE;
    for &angle in TRIM_CRANK_ANGLES.iter().filter(within) {
        let gear = (reach / angle).max(1.0);
        for &r_top in CRANK_RADII.iter().filter(|&&r| r <= req.max_lever) {
            let r = r_top * mid / top_rate;
            for &ratio in TRIM_ANCHOR_RATIOS {
                let big_r = ratio * r_top;
                if big_r - r_top < clearance {
                    continue;
                }
                // The crank's own stiffness k_s r R at mid-range is the trim's rate times g².
                let k_crank = mid * gear * gear;
                let (phase, scale) = compensate(k_crank, r, big_r, pulley, duty.at_eq / gear);
                let ks = k_s(scale * k_crank, r, big_r);
                let at = |radius: f64| move |d: f64| cable_path(radius, big_r, pulley, d / gear - phase);
                let path = at(r);
                let [lmin, top_max] = extremes(duty.range[0], duty.range[1], at(r_top));
                let lmax = top_max.max(big_r);
                let [smin, smax] = extremes(duty.swing[0], duty.swing[1], path);
                let geometry = CrankGeometry { r: r_top, big_r, pulley, phase, ks, paths: [lmin, lmax, smin, smax] };
                for s in helical(ks, req) {
                    search.consider(
                        s.mass(),
                        || {
                            let mut part = crank_part(&geometry, duty, req, s, s.initial_tension(), &path);
                            part.mechanism = Mechanism::TrimCrank { r: [r_top, r], big_r, pulley, phase, gear };
                            // The pin is set on the built arm for the trim's rate (the spring's own
                            // tolerance tuned out): its stiffness at the equilibrium, from the
                            // spring's geometry and the rollers' factor, is the trim's.
                            part.realised_rate = mid;
                            part.tolerance = 0.0;
                            part
                        },
                        || {
                            format!(
                                "crank geared {gear:.2} : 1, pin radius {r:.1} mm (up to {r_top} mm), R = {big_r} mm, d = {} mm, D = {:.1} mm, n = {:.2}",
                                s.d, s.dm, s.n
                            )
                        },
                    );
                }
            }
        }
    }
    search.finish()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::realise::material::by_key;

    fn req() -> Requirements {
        Requirements {
            material: by_key("EN10270-1-DM").unwrap(),
            also: Wires::NONE,
            grade: 2,
            cycles: 1e6,
            safety: 1.1,
            surface: Surface::AsWound,
            max_outer_diameter: 120.0,
            max_length: 400.0,
            max_lever: 100.0,
            shaft_diameter: 10.0,
            pulley_radius: 0.0,
            stop: StopMechanism::Lightest,
            trim: TrimMechanism::Lightest,
            roller_departure: None,
        }
    }

    /// Without rollers the cable is the straight line of the ideal zero-free-length spring, and
    /// the realised crank potential is exactly k (1 − cos d) (the closed form of the design notes).
    #[test]
    fn crank_without_rollers_is_the_closed_form() {
        let duty = Duty { at_eq: 0.4, range: [-2.5, 2.8], swing: [-1.0, 1.2] };
        let part = crank(20.0, &duty, &req()).expect("a spring");
        let Mechanism::Crank { r, big_r, .. } = part.mechanism else { panic!() };
        let k = part.realised_rate;
        for d in [-2.5, -1.0, 0.0, 0.3, 1.7, 2.8] {
            let (u, t, c) = part.potential(d);
            assert!((u - k * (1.0 - f64::cos(d))).abs() < 1e-9 * k, "U at {d}");
            assert!((t - k * d.sin()).abs() < 1e-6 * k, "torque at {d}: {t} vs {}", k * d.sin());
            assert!((c - k * d.cos()).abs() < 1e-3 * k, "stiffness at {d}");
        }
        assert!((k / 20.0 - 1.0).abs() < 1e-12 && r < big_r);
        assert!(part.worst() <= 1.0);
    }

    /// With rollers the pin's phase and the spring's rate are set so that the realised torque
    /// and stiffness at the equilibrium deflection are k sin d and k cos d, the fitted element's.
    #[test]
    fn a_crank_over_rollers_keeps_the_torque_and_stiffness_at_the_equilibrium() {
        let duty = Duty { at_eq: -1.1, range: [-3.0, 2.0], swing: [-2.0, 0.5] };
        let part = crank(15.0, &duty, &Requirements { pulley_radius: 5.0, ..req() }).expect("a spring");
        let Mechanism::Crank { phase, .. } = part.mechanism else { panic!() };
        assert!(phase != 0.0 && phase.abs() < 0.05, "{phase}");
        let (_, t, c) = part.potential(duty.at_eq);
        assert!((t - 15.0 * duty.at_eq.sin()).abs() < 1e-6 * 15.0, "{t}");
        assert!((c - 15.0 * duty.at_eq.cos()).abs() < 1e-3 * 15.0, "{c}");
        // Elsewhere the rollers show: close to, not equal to, the ideal torque.
        let (_, t2, _) = part.potential(1.5);
        let err = (t2 - 15.0 * 1.5f64.sin()).abs() / 15.0;
        assert!(err > 1e-6 && err < 0.02, "{err}");
    }

    /// The chooser keeps a crank's rollers within [`MAX_ROLLER_DEPARTURE`] of k sin d over the
    /// region where a geometry can: the short anchors the lightest springs would take depart
    /// more (r = 100 mm, R = 150 mm: 0.34 % of k over ±0.3 rad), the part chosen departs at most
    /// the bound over the whole range, and its check states it.
    #[test]
    fn a_crank_over_rollers_departs_from_k_sin_d_within_the_bound() {
        let duty = Duty { at_eq: 0.0, range: [-0.3, 0.3], swing: [-0.2, 0.2] };
        let rollers = Requirements { pulley_radius: 5.0, roller_departure: Some(MAX_ROLLER_DEPARTURE), ..req() };
        let (phase, scale) = compensate(1.0, 100.0, 150.0, 5.0, 0.0);
        let short = roller_departure(100.0, 150.0, 5.0, phase, scale, duty.range);
        assert!(short > 3.0 * MAX_ROLLER_DEPARTURE, "{short}");
        let k = 20.0;
        let part = crank(k, &duty, &rollers).expect("a spring");
        let worst = (0..=60)
            .map(|i| {
                let d = -0.3 + 0.01 * i as f64;
                (part.energy_torque(d).1 / k - d.sin()).abs()
            })
            .fold(0.0, f64::max);
        assert!(worst <= MAX_ROLLER_DEPARTURE * 1.001, "{worst}");
        let check = part.checks.iter().find(|c| c.name.starts_with("rollers' departure")).expect("the check");
        assert!(check.limit == MAX_ROLLER_DEPARTURE && check.value <= check.limit, "{check:?}");
        // Without rollers nothing departs: the bound changes nothing there.
        let ideal =
            crank(k, &duty, &Requirements { roller_departure: Some(MAX_ROLLER_DEPARTURE), ..req() }).expect("a spring");
        let check = ideal.checks.iter().find(|c| c.name.starts_with("rollers' departure")).expect("the check");
        assert_eq!(check.value, 0.0);
    }

    /// Rollers of radius ρ: the path is continuous across the exit line, equals the straight
    /// line there, and its derivative matches finite differences on either side.
    #[test]
    fn cable_over_rollers() {
        let (r, big_r, rho) = (40.0, 100.0, 8.0);
        assert!((cable_path(r, big_r, rho, 0.0) - 60.0).abs() < 1e-9);
        assert!((cable_path(r, big_r, rho, PI) - 140.0).abs() < 1e-9);
        let h = 1e-7;
        let slope = |d: f64| (cable_path(r, big_r, rho, d + h) - cable_path(r, big_r, rho, d - h)) / (2.0 * h);
        assert!(slope(1e-5).abs() < 1e-3 && (slope(1e-5) + slope(-1e-5)).abs() < 1e-9);
        // Longer than the straight line (the cable bends round the roller the line would cut),
        // by less than half the roller's circumference.
        for d in [0.5, 1.5, 2.5] {
            let straight = cable_path(r, big_r, 0.0, d);
            let over = cable_path(r, big_r, rho, d);
            assert!(over > straight && over < straight + rho * PI, "{d}: {over} vs {straight}");
        }
    }

    /// The path's exact slope against central differences of the path, straight and over
    /// rollers, on both sides of the exit line and round the far side; and the crank's torque
    /// against differences of its energy.
    #[test]
    fn the_cable_slope_and_the_crank_torque_are_the_derivatives() {
        let (r, big_r) = (40.0, 100.0);
        let h = 1e-6;
        for rho in [0.0, 8.0] {
            for d in [-3.0, -2.2, -1.0, -0.3, -1e-3, 1e-3, 0.2, 0.9, 1.6, 2.4, 3.1] {
                let (length, slope) = cable_path_slope(r, big_r, rho, d);
                assert!((length - cable_path(r, big_r, rho, d)).abs() < 1e-12 * length);
                let fd = (cable_path(r, big_r, rho, d + h) - cable_path(r, big_r, rho, d - h)) / (2.0 * h);
                assert!((slope - fd).abs() < 1e-6 * (1.0 + fd.abs()), "ρ = {rho}, d = {d}: {slope} vs {fd}");
            }
        }
        let duty = Duty { at_eq: -1.1, range: [-3.0, 2.0], swing: [-2.0, 0.5] };
        let part = crank(15.0, &duty, &Requirements { pulley_radius: 5.0, ..req() }).expect("a spring");
        for d in [-2.5, -1.1, 0.4, 1.9] {
            let (_, t) = part.energy_torque(d);
            let fd = (part.energy_torque(d + h).0 - part.energy_torque(d - h).0) / (2.0 * h);
            assert!((t - fd).abs() < 1e-6 * 15.0, "d = {d}: {t} vs {fd}");
            assert_eq!(part.potential(d).1, t);
        }
    }

    /// A torsion pair and a stop give their rate, and a torque too large for any wire in the
    /// envelope is refused with the stress limit and the largest torque that would fit.
    #[test]
    fn torsion_parts_and_their_limit() {
        let duty = Duty { at_eq: 0.0, range: [-0.8, 0.9], swing: [-0.5, 0.5] };
        let pair = linear(5.0, &duty, &req()).unwrap();
        assert!((pair.realised_rate / 5.0 - 1.0).abs() < 1e-12);
        let Spring::Torsion(s) = pair.spring else { panic!() };
        assert!((2.0 * s.rate() / 5000.0 - 1.0).abs() < 1e-12);
        let stop = stop(3.0, true, &duty, &req()).unwrap();
        assert_eq!(stop.potential(-0.3), (0.0, 0.0, 0.0));
        let small = Requirements { max_outer_diameter: 30.0, ..req() };
        let err = super::stop(400.0, true, &duty, &small).unwrap_err();
        assert_eq!(err.check.name, "outer diameter", "{err:?}");
        assert!(err.check.ratio() > 1.0 && err.best.contains("d = "), "{err:?}");
        // A crank so soft that every wire size would need more than 400 coils: no candidate is
        // built, and the limit is a sentence, not a check against a zero limit (a NaN ratio).
        let err = super::crank(1e-9, &duty, &req()).unwrap_err();
        assert_eq!(err.check.name, "mechanism", "{err:?}");
        assert!(err.best.contains("no wire size"), "{err:?}");
    }

    /// A stop on a cable drum: the spring is compressed by ρ·(x − x₀) exactly, so the realised
    /// potential is ½ k max(0, ±d)² with the springs' own rate, which is the element's within its
    /// grade; on a stop of the paper's size it is lighter than the torsion stop, and the chooser
    /// takes the lighter unless `[parts] stop_mechanism` forces one.
    #[test]
    fn a_drum_stop_has_the_exact_law_and_the_chooser_takes_the_lighter() {
        let duty = Duty { at_eq: 0.6, range: [-0.9, 2.1], swing: [-0.2, 1.4] };
        let drum = drum_stop(10.0, true, &duty, &req()).expect("a drum stop");
        assert!(drum.worst() <= 1.0);
        assert!((drum.realised_rate / 10.0 - 1.0).abs() <= drum.tolerance, "{}", drum.realised_rate);
        let Mechanism::DrumStop { plus: true, drum: radius } = drum.mechanism else { panic!("{:?}", drum.mechanism) };
        let Spring::Compression(s, l0) = drum.spring else { panic!() };
        let k = drum.realised_rate;
        assert!((k - drum.quantity as f64 * s.rate() * radius * radius / 1000.0).abs() < 1e-12 * k);
        for d in [-0.9f64, -0.1, 0.0, 0.4, 2.1] {
            let e = d.max(0.0);
            assert_eq!(drum.potential(d), (0.5 * k * e * e, k * e, if e > 0.0 { k } else { 0.0 }));
        }
        // The largest compression leaves the smallest gaps above solid.
        assert!((l0 - s.solid_length() - s.min_gaps() - radius * 2.1).abs() < 1e-9);
        let torsion = stop(10.0, true, &duty, &req()).expect("a torsion stop");
        assert!(drum.mass < torsion.mass, "drum {} kg, torsion {} kg", drum.mass, torsion.mass);
        let chosen =
            |stop| spring_element(Profile::Compression(Side::Plus), 10.0, &duty, &Requirements { stop, ..req() });
        assert_eq!(chosen(StopMechanism::Lightest).unwrap(), drum);
        assert_eq!(chosen(StopMechanism::Drum).unwrap(), drum);
        assert_eq!(chosen(StopMechanism::Torsion).unwrap(), torsion);
        // The mirror image engages on the other side.
        let minus =
            drum_stop(10.0, false, &Duty { at_eq: -0.6, range: [-2.1, 0.9], swing: [-1.4, 0.2] }, &req()).unwrap();
        assert_eq!(minus.mass, drum.mass);
        assert_eq!(minus.potential(-0.4).1, -drum.potential(0.4).1);
    }

    /// A trim's crank: its rate at mid-range is the trim's, the pin's radius sets it in
    /// proportion from 0 to the top of the range, and its potential is the geared crank's
    /// k g² (1 − cos(d/g)) (without rollers exactly; with them the torque and stiffness at the
    /// equilibrium are kept); the torque is the energy's slope.
    #[test]
    fn a_trim_crank_follows_the_geared_crank_law() {
        let duty = Duty { at_eq: 0.0, range: [-1.6, 1.4], swing: [-0.7, 0.7] };
        for pulley in [0.0, 5.0] {
            let req = Requirements { pulley_radius: pulley, max_lever: 150.0, ..req() };
            let part = trim_crank([0.0, 4.0], 2.0, &duty, &req).expect("a trim crank");
            assert!(part.worst() <= 1.0 && part.tolerance == 0.0);
            let Mechanism::TrimCrank { r, gear, .. } = part.mechanism else { panic!("{:?}", part.mechanism) };
            assert!((r[1] / r[0] - 0.5).abs() < 1e-12, "mid-range is half the top radius: {r:?}");
            let turn = 1.6 / gear;
            assert!(TRIM_CRANK_ANGLES.iter().any(|a| (a - turn).abs() < 1e-9) || gear == 1.0, "{gear}");
            let k = part.realised_rate;
            assert!((k / 2.0 - 1.0).abs() < 0.02, "{k}");
            let (_, t0, c0) = part.potential(0.0);
            assert!(t0.abs() < 1e-9 && (c0 / k - 1.0).abs() < 1e-3, "{t0} {c0}");
            let h = 1e-6;
            for d in [-1.5f64, -0.8, 0.3, 1.2] {
                let (u, t) = part.energy_torque(d);
                let fd = (part.energy_torque(d + h).0 - part.energy_torque(d - h).0) / (2.0 * h);
                assert!((t - fd).abs() < 1e-6 * k, "d = {d}: {t} vs {fd}");
                if pulley == 0.0 {
                    let g2 = gear * gear;
                    assert!((u - k * g2 * (1.0 - (d / gear).cos())).abs() < 1e-9 * k, "U at {d}");
                    assert!((t - k * gear * (d / gear).sin()).abs() < 1e-6 * k, "torque at {d}");
                }
                // Softer than ½ k d² away from x₀, by 1 − sin(φ)/φ at most.
                let angle = (d / gear).abs();
                assert!(t.abs() <= k * d.abs() * 1.001 && t.abs() >= k * d.abs() * (angle.sin() / angle) * 0.98);
            }
        }
    }

    /// The accurate pass (a bound on the cranks' departures) keeps a trim's crank within
    /// [`TRIM_LAW_DEPARTURE`] of the trim's linear torque k·d at the far end of a wide region,
    /// where the lightest geometry turns the crank 0.9 rad and falls 13 % short; the chooser
    /// then takes the lighter of that crank and the leaf, which is linear.
    #[test]
    fn the_accurate_pass_keeps_a_trim_crank_close_to_linear() {
        let duty = Duty { at_eq: 0.0, range: [-0.7, 0.92], swing: [-0.3, 0.3] };
        let shortfall = |p: &Part| 1.0 - p.energy_torque(0.92).1 / (p.realised_rate * 0.92);
        for pulley in [0.0, 5.0] {
            let req = Requirements { pulley_radius: pulley, max_lever: 100.0, ..req() };
            let light = trim_crank([0.0, 9.3], 4.65, &duty, &req).expect("a light trim crank");
            assert!(shortfall(&light) > 0.1, "the lightest crank: {}", shortfall(&light));
            let bound = Requirements { roller_departure: Some(MAX_ROLLER_DEPARTURE), ..req };
            let accurate = trim_crank([0.0, 9.3], 4.65, &duty, &bound).expect("an accurate trim crank");
            let Mechanism::TrimCrank { gear, .. } = accurate.mechanism else { panic!("{:?}", accurate.mechanism) };
            assert!(1.0 - (0.92 / gear).sin() / (0.92 / gear) <= TRIM_LAW_DEPARTURE, "gear {gear}");
            assert!(shortfall(&accurate).abs() <= TRIM_LAW_DEPARTURE + 0.005, "{}", shortfall(&accurate));
            assert!(accurate.mass >= light.mass);
            let chosen = trim([0.0, 9.3], 4.65, &duty, &bound).unwrap();
            let linear = leaf([0.0, 9.3], 4.65, &duty, &bound).unwrap();
            assert_eq!(chosen.mass, accurate.mass.min(linear.mass));
        }
    }

    /// The trim's chooser: the lighter of the leaf and the crank, or the one forced.
    #[test]
    fn the_trim_chooser_takes_the_lighter_or_the_forced() {
        let duty = Duty { at_eq: 0.0, range: [-1.6, 1.4], swing: [-0.7, 0.7] };
        let req = Requirements { max_lever: 150.0, pulley_radius: 5.0, ..req() };
        let leaf = leaf([0.0, 4.0], 2.0, &duty, &req).unwrap();
        let crank = trim_crank([0.0, 4.0], 2.0, &duty, &req).unwrap();
        let lightest = trim([0.0, 4.0], 2.0, &duty, &req).unwrap();
        assert_eq!(lightest.mass, leaf.mass.min(crank.mass));
        assert_eq!(trim([0.0, 4.0], 2.0, &duty, &Requirements { trim: TrimMechanism::Leaf, ..req }).unwrap(), leaf);
        assert_eq!(trim([0.0, 4.0], 2.0, &duty, &Requirements { trim: TrimMechanism::Crank, ..req }).unwrap(), crank);
        // Neither passes: the limit closer to being met, never the sentence without a ratio.
        let none = lighter(Err(super::Search::new().finish().unwrap_err()), leaf_limit());
        assert_eq!(none.unwrap_err().check.name, "static stress");
    }

    fn leaf_limit() -> Result<Part, Limit> {
        Err(Limit { check: upper("static stress", 2.0, 1.0, "MPa"), best: "a leaf".into(), torque_bound: None })
    }
}
