//! The transmission behind an element's coupling x = a·q: what turns the joints' angles into the
//! one coordinate its spring (or cam) sees, with the dimensions a builder needs.
//!
//! | coupling | transmission | dimensions |
//! | --- | --- | --- |
//! | one joint (a = c·eᵢ) | `joint`: the spring on the joint's axis, geared c : 1 where c ≠ 1 | none |
//! | two neighbouring joints at a ratio of [`BEVEL_RATIOS`] | `bevel differential`: the spring on the output of a bevel-gear differential | none |
//! | any other | `tendon`: a cable over a pulley of radius rᵢ = ρ·\|aᵢ\| at each joint it crosses, on the side sᵢ = sign aᵢ | the radii, the cable, its preload and peak tension |
//!
//! A cable over a pulley of radius rᵢ at each joint it crosses changes length by Σ sᵢ rᵢ qᵢ = ρ·x
//! (the design notes, §6), so a coupling is a set of radii in proportion to |a| and the spring at
//! the cable's end sees x through a drum of radius ρ. The chooser takes the largest scale ρ the
//! pulley limits allow ([`Limits`]): the largest radius is `max_pulley_radius_mm`, which gives the
//! least tension for the element's torque, so the thinnest and lightest cable and the least
//! stretch. A coupling whose smallest radius then falls below `min_pulley_radius_mm`, or that
//! crosses more joints than `max_joints_crossed`, has no transmission: its element gets no part and
//! the reason names the limit.
//!
//! A tendon only pulls. An element whose torque on x keeps one sign over the region needs one
//! cable; one whose torque changes sign (a linear spring or a crank about its offset) needs an
//! antagonistic pair, two cables on opposite sides of every pulley, each preloaded to T₀. With
//! both taut the torque ρ(T₁ − T₂) = τ splits as T₁,₂ = T₀ ± τ/(2ρ), so both stay taut over the
//! region when T₀ ≥ max|τ|/(2ρ); the preload is that bound with [`PRELOAD_MARGIN`] on top, and the
//! peak tension T₀ + max|τ|/(2ρ) sizes the cable from [`CABLES`] with [`CABLE_SAFETY_FACTOR`].
//!
//! The pair's preload adds no torque on x and no stiffness: each cable's tension changes the
//! pulley torque by ±ρT₀, and the two cables sit on opposite sides of every pulley, so the
//! preloads cancel at every angle (the pair is symmetric); a rigid cable leaves U unchanged.

use crate::realise::mechanism::{Check, Limit};

/// The ratios at which two neighbouring joints drive one bevel-gear differential (defined with
/// the catalogues, whose tendon families list them too).
pub use crate::elements::catalog::BEVEL_RATIOS;

/// Share added to the least preload max|τ|/(2ρ) that keeps an antagonistic pair taut: the cables'
/// stretch and the springs' rate tolerance move the tensions by a few percent, and a cable that
/// goes slack at the region's edge jumps off its pulley.
pub const PRELOAD_MARGIN: f64 = 0.25;

/// Factor on the peak tension a cable's minimum breaking strength must carry: the design factor
/// usually applied to running wire rope, which bends over pulleys at every swing (the breaking
/// strength is a static figure; bending fatigue over small sheaves is what the factor covers).
pub const CABLE_SAFETY_FACTOR: f64 = 5.0;

/// A cable size: corrosion-resistant steel aircraft control cable.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cable {
    /// Construction and nominal diameter as sold (`7x19, 1/8 in`).
    pub name: &'static str,
    /// Nominal diameter, mm.
    pub diameter_mm: f64,
    /// Minimum breaking strength, N.
    pub breaking_n: f64,
}

/// Pounds-force to newtons.
const LBF: f64 = 4.448_221_615_260_5;

/// The cable sizes, thinnest first: MIL-DTL-83420 (wire rope, flexible, for aircraft control),
/// type I (bare), composition B (corrosion-resistant steel), its table of minimum breaking
/// strengths in pounds (converted here), the sizes cable makers stock. Each value checked against
/// the FAA's AC 43.13-1B (1998), table 7-3, column "MIL-W-83420 comp B (CRES)".
pub const CABLES: [Cable; 9] = [
    Cable { name: "3x7, 1/32 in", diameter_mm: 0.79375, breaking_n: 110.0 * LBF },
    Cable { name: "7x7, 3/64 in", diameter_mm: 1.190_625, breaking_n: 270.0 * LBF },
    Cable { name: "7x7, 1/16 in", diameter_mm: 1.5875, breaking_n: 480.0 * LBF },
    Cable { name: "7x19, 3/32 in", diameter_mm: 2.381_25, breaking_n: 920.0 * LBF },
    Cable { name: "7x19, 1/8 in", diameter_mm: 3.175, breaking_n: 1760.0 * LBF },
    Cable { name: "7x19, 5/32 in", diameter_mm: 3.968_75, breaking_n: 2400.0 * LBF },
    Cable { name: "7x19, 3/16 in", diameter_mm: 4.7625, breaking_n: 3700.0 * LBF },
    Cable { name: "7x19, 7/32 in", diameter_mm: 5.556_25, breaking_n: 5000.0 * LBF },
    Cable { name: "7x19, 1/4 in", diameter_mm: 6.35, breaking_n: 6400.0 * LBF },
];

/// The cable makers' stretch factor G of 7x19 corrosion-resistant steel cable: elastic stretch in
/// % of length = W·G/D² (W the load in lbf, D the nominal diameter in inches), G = 0.0000162 for
/// "7X19SS" (Aero Assemblies' elastic stretch calculator, which derives it from the modulus of the
/// rope; the same formula and table as Loos & Co.'s). So EA = 100·D²/G lbf: 429 kN for 1/8 in, an
/// effective modulus of 54 GPa on the nominal section. Taken for every listed size: 7x7 and 3x7,
/// with fewer and thicker wires, stretch less, so their stretch is overestimated, never missed.
pub const STRETCH_FACTOR_G: f64 = 1.62e-5;

impl Cable {
    /// Axial stiffness EA, N (per unit strain): 100·D²/G lbf ([`STRETCH_FACTOR_G`]).
    pub fn axial_stiffness_n(&self) -> f64 {
        let d_in = self.diameter_mm / 25.4;
        100.0 * d_in * d_in / STRETCH_FACTOR_G * LBF
    }
}

/// The `[parts]` limits on a tendon.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Smallest pulley radius, mm (`min_pulley_radius_mm`).
    pub min_radius_mm: f64,
    /// Largest pulley radius, mm (`max_pulley_radius_mm`).
    pub max_radius_mm: f64,
    /// Most joints one cable crosses (`max_joints_crossed`).
    pub max_joints: usize,
}

impl Limits {
    /// The limits a design's `[parts]` sets.
    pub fn of(s: &crate::design::parts::PartsSettings) -> Limits {
        Limits {
            min_radius_mm: s.min_pulley_radius_mm,
            max_radius_mm: s.max_pulley_radius_mm,
            max_joints: s.max_joints_crossed,
        }
    }
}

/// Which transmission a coupling has.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// The spring on one joint's axis.
    Joint,
    /// The spring on a bevel-gear differential's output, two neighbouring joints in.
    BevelDifferential,
    /// A cable over pulleys at the joints it crosses.
    Tendon,
}

impl Kind {
    /// The name in `parts.csv`'s `transmission` column.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Joint => "joint",
            Kind::BevelDifferential => "bevel differential",
            Kind::Tendon => "tendon",
        }
    }
}

/// A tendon's dimensions.
#[derive(Debug, Clone, PartialEq)]
pub struct Tendon {
    /// Signed pulley radius at each joint, mm: ρ·aᵢ, 0 where the cable does not cross, the sign
    /// the side it crosses on.
    pub radii_mm: Vec<f64>,
    /// The scale ρ, mm: the radius of the drum on x at the cable's end (x turns it by ΔL/ρ).
    pub scale_mm: f64,
    /// An antagonistic pair (the torque changes sign over the region), else one cable.
    pub pair: bool,
    /// Each cable's preload T₀, N (0 for one cable).
    pub preload_n: f64,
    /// The largest tension in a cable over the region, N.
    pub peak_tension_n: f64,
    /// The thinnest cable of [`CABLES`] whose breaking strength carries the peak with
    /// [`CABLE_SAFETY_FACTOR`] (when none does, the coupling has no transmission).
    pub cable: Cable,
}

impl Tendon {
    /// The cables' stiffness on x for one metre of cable, N·m²/rad: a cable of length L stretches
    /// by δ = ρ(x − θ) between the joints' side (x) and the drum (θ), so it pulls with
    /// (EA/L)·ρ·δ and holds x with (EA/L)·ρ² N·m/rad; a pair's two taut cables hold it twice.
    /// Divide by the cable's length (m) for k_c; the element's spring k on the drum then acts on
    /// x in series: k·k_c/(k + k_c) ([`series_rate`]).
    pub fn stretch_rate_per_m(&self) -> f64 {
        let cables = if self.pair { 2.0 } else { 1.0 };
        let rho = self.scale_mm * 1e-3;
        cables * self.cable.axial_stiffness_n() * rho * rho
    }
}

/// A rate `k` in series with a cable's `k_c` (both N·m/rad on x): k·k_c/(k + k_c), what the joints
/// feel of the element's spring through a stretching cable.
pub fn series_rate(k: f64, k_c: f64) -> f64 {
    k * k_c / (k + k_c)
}

/// An element's transmission.
#[derive(Debug, Clone, PartialEq)]
pub struct Transmission {
    /// Its kind.
    pub kind: Kind,
    /// A tendon's dimensions (None for a joint or a differential).
    pub tendon: Option<Tendon>,
}

impl Transmission {
    /// `parts.csv`'s `pulley_radii_mm`: a tendon's signed radii joined by `;` (empty otherwise).
    pub fn radii_text(&self) -> String {
        self.tendon
            .as_ref()
            .map(|t| t.radii_mm.iter().map(|r| format!("{r}")).collect::<Vec<_>>().join(";"))
            .unwrap_or_default()
    }
}

/// The joints a coupling turns (its non-zero entries), with their entries.
fn used(a: &[f64]) -> Vec<(usize, f64)> {
    a.iter().copied().enumerate().filter(|(_, c)| *c != 0.0).collect()
}

/// The kind of transmission a coupling takes, before any limit: one joint, two neighbouring
/// joints at a ratio of [`BEVEL_RATIOS`] (to 1e-9), or a tendon.
pub fn kind(a: &[f64]) -> Kind {
    match used(a).as_slice() {
        [_] | [] => Kind::Joint,
        [(i, ci), (j, cj)] if j - i == 1 => {
            let ratio = ci.abs().max(cj.abs()) / ci.abs().min(cj.abs());
            if BEVEL_RATIOS.iter().any(|r| (ratio - r).abs() <= 1e-9 * r) {
                Kind::BevelDifferential
            } else {
                Kind::Tendon
            }
        }
        _ => Kind::Tendon,
    }
}

/// A tendon's scale ρ (mm) for coupling `a` within `limits`: the largest radius at the largest
/// pulley limit. Err: the limit the coupling exceeds, in words with its `[parts]` key, and the
/// check.
pub fn scale(a: &[f64], limits: &Limits) -> std::result::Result<f64, Limit> {
    let used = used(a);
    let fail = |check: Check, best: String| Err(Limit { check, best, torque_bound: None });
    if used.len() > limits.max_joints {
        return fail(
            Check {
                name: "mechanism",
                value: used.len() as f64,
                limit: limits.max_joints as f64,
                unit: "joints",
                upper: true,
            },
            format!(
                "no transmission: a tendon for this coupling crosses {} joints, more than `[parts] max_joints_crossed` = {}",
                used.len(),
                limits.max_joints
            ),
        );
    }
    let big = used.iter().map(|(_, c)| c.abs()).fold(0.0, f64::max);
    let small = used.iter().map(|(_, c)| c.abs()).fold(f64::INFINITY, f64::min);
    let rho = limits.max_radius_mm / big;
    let smallest = rho * small;
    if smallest < limits.min_radius_mm * (1.0 - 1e-12) {
        return fail(
            Check { name: "mechanism", value: smallest, limit: limits.min_radius_mm, unit: "mm", upper: false },
            format!(
                "no transmission: a tendon's pulleys in proportion to this coupling span {:.3} : 1, so with the largest at `[parts] max_pulley_radius_mm` = {} mm the smallest is {smallest:.3} mm, below `[parts] min_pulley_radius_mm` = {} mm (the limits allow {:.3} : 1)",
                big / small,
                limits.max_radius_mm,
                limits.min_radius_mm,
                limits.max_radius_mm / limits.min_radius_mm
            ),
        );
    }
    Ok(rho)
}

/// The transmission for coupling `a` of an element whose torque on x (N·m) spans `torque` =
/// [least, largest] over the region, within `limits`. `pulleys`: the signed radii (mm) a tendon
/// family gave the coupling (`elements::catalog::Family::pulleys`), which the tendon then has
/// exactly (its drum ρ = max|rᵢ| / max|aᵢ|, so ρ·a = r) instead of the chooser's scale; None:
/// the kind and scale follow from `a` alone. Err: no transmission makes it (a tendon beyond the
/// pulley or joint limits, or one whose peak tension no listed cable carries).
pub fn transmission(
    a: &[f64],
    pulleys: Option<&[f64]>,
    torque: [f64; 2],
    limits: &Limits,
) -> std::result::Result<Transmission, Limit> {
    let kind = if pulleys.is_some() { Kind::Tendon } else { kind(a) };
    if kind != Kind::Tendon {
        return Ok(Transmission { kind, tendon: None });
    }
    let rho = match pulleys {
        Some(r) => given_scale(a, r, limits)?,
        None => scale(a, limits)?,
    };
    let rho_m = rho * 1e-3;
    let pair = torque[0] < 0.0 && torque[1] > 0.0;
    let peak_torque = torque[0].abs().max(torque[1].abs());
    let (preload, peak) = if pair {
        let least = peak_torque / (2.0 * rho_m);
        let t0 = least * (1.0 + PRELOAD_MARGIN);
        (t0, t0 + least)
    } else {
        (0.0, peak_torque / rho_m)
    };
    let need = CABLE_SAFETY_FACTOR * peak;
    let Some(cable) = CABLES.iter().find(|c| c.breaking_n >= need).copied() else {
        let last = CABLES[CABLES.len() - 1];
        return Err(Limit {
            check: Check { name: "mechanism", value: need, limit: last.breaking_n, unit: "N", upper: true },
            best: format!(
                "no transmission: the tendon's peak tension {peak:.0} N (ρ = {rho:.2} mm at `[parts] max_pulley_radius_mm` = {} mm) needs a breaking strength of {need:.0} N with the safety factor {CABLE_SAFETY_FACTOR}, beyond the strongest listed cable ({}, {:.0} N)",
                limits.max_radius_mm, last.name, last.breaking_n
            ),
            torque_bound: None,
        });
    };
    let radii_mm = match pulleys {
        Some(r) => r.to_vec(),
        None => a.iter().map(|c| if *c == 0.0 { 0.0 } else { rho * c }).collect(),
    };
    Ok(Transmission {
        kind,
        tendon: Some(Tendon { radii_mm, scale_mm: rho, pair, preload_n: preload, peak_tension_n: peak, cable }),
    })
}

/// The drum radius ρ (mm) of a tendon over the given signed pulley radii `r` for coupling `a`:
/// max|rᵢ| / max|aᵢ|. Err: the radii are not ρ·a (to 1e-9 of the largest), or one lies outside
/// the `[parts]` pulley limits, or the cable crosses more joints than `max_joints_crossed` (a
/// catalogue checked against the design's `[parts]` never gives those; a bill read with another
/// design's `[parts]` may).
fn given_scale(a: &[f64], r: &[f64], limits: &Limits) -> std::result::Result<f64, Limit> {
    let big_a = a.iter().fold(0.0, |m: f64, x| m.max(x.abs()));
    let big_r = r.iter().fold(0.0, |m: f64, x| m.max(x.abs()));
    let rho = big_r / big_a;
    let fail = |check: Check, best: String| Err(Limit { check, best, torque_bound: None });
    let off = a.len() != r.len() || a.iter().zip(r).any(|(a, r)| (rho * a - r).abs() > 1e-9 * big_r);
    if big_a == 0.0 || off {
        let check = Check { name: "mechanism", value: 0.0, limit: 0.0, unit: "mm", upper: true };
        return fail(check, "no transmission: the tendon's pulley radii are not in proportion to its coupling".into());
    }
    let crossed = r.iter().filter(|x| **x != 0.0).count();
    if crossed > limits.max_joints {
        return fail(
            Check {
                name: "mechanism",
                value: crossed as f64,
                limit: limits.max_joints as f64,
                unit: "joints",
                upper: true,
            },
            format!(
                "no transmission: the tendon crosses {crossed} joints, more than `[parts] max_joints_crossed` = {}",
                limits.max_joints
            ),
        );
    }
    for x in r.iter().map(|x| x.abs()).filter(|x| *x != 0.0) {
        let below = x < limits.min_radius_mm * (1.0 - 1e-12);
        if below || x > limits.max_radius_mm * (1.0 + 1e-12) {
            let (key, limit) = if below {
                ("min_pulley_radius_mm", limits.min_radius_mm)
            } else {
                ("max_pulley_radius_mm", limits.max_radius_mm)
            };
            return fail(
                Check { name: "mechanism", value: x, limit, unit: "mm", upper: !below },
                format!("no transmission: the tendon's pulley of {x} mm is outside `[parts] {key}` = {limit} mm"),
            );
        }
    }
    Ok(rho)
}

/// How much a cable over pulleys of signed radii `radii_mm` lengthens (mm) when the joints turn
/// from 0 to `q` (rad): Σ sᵢ rᵢ qᵢ.
pub fn length_change(radii_mm: &[f64], q: &[f64]) -> f64 {
    radii_mm.iter().zip(q).map(|(r, q)| r * q).sum()
}

/// The two tensions (N) of an antagonistic pair preloaded to `preload` (N) on a drum of radius
/// `scale_mm` carrying the torque `torque` (N·m) on x: T₀ ± τ/(2ρ).
pub fn pair_tensions(preload: f64, scale_mm: f64, torque: f64) -> (f64, f64) {
    let half = torque / (2.0 * scale_mm * 1e-3);
    (preload + half, preload - half)
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMITS: Limits = Limits { min_radius_mm: 10.0, max_radius_mm: 40.0, max_joints: 5 };

    #[test]
    fn kinds_follow_the_coupling() {
        assert_eq!(kind(&[0.0, 2.0, 0.0]), Kind::Joint);
        assert_eq!(kind(&[1.0, -2.0, 0.0]), Kind::BevelDifferential);
        assert_eq!(kind(&[0.0, 1.0, 1.0]), Kind::BevelDifferential);
        assert_eq!(kind(&[1.0, 0.0, 1.0]), Kind::Tendon, "not neighbours");
        assert_eq!(kind(&[1.0, 0.7, 0.0]), Kind::Tendon, "no bevel ratio");
        assert_eq!(kind(&[1.0, 1.0, 1.0]), Kind::Tendon);
        let t = transmission(&[0.0, 1.0, -1.0], None, [-1.0, 1.0], &LIMITS).unwrap();
        assert_eq!((t.kind.name(), t.radii_text()), ("bevel differential", String::new()));
    }

    /// A tendon's length change is Σ sᵢ rᵢ qᵢ = ρ·(a·q) for its radii, at any angles.
    #[test]
    fn a_tendons_length_change_follows_its_pulley_radii() {
        let a = [0.5, 0.0, -1.0, 0.25];
        let t = transmission(&a, None, [0.2, 3.0], &LIMITS).unwrap().tendon.unwrap();
        assert_eq!(t.scale_mm, 40.0);
        assert_eq!(t.radii_mm, [20.0, 0.0, -40.0, 10.0]);
        for q in [[0.1, -0.4, 0.3, 1.2], [-1.0, 2.0, 0.7, -0.2], [0.0, 0.0, 0.0, 0.0]] {
            let x: f64 = a.iter().zip(&q).map(|(a, q)| a * q).sum();
            // By hand: 20 q1 − 40 q3 + 10 q4.
            let by_hand = 20.0 * q[0] - 40.0 * q[2] + 10.0 * q[3];
            assert!((length_change(&t.radii_mm, &q) - by_hand).abs() < 1e-12);
            assert!((length_change(&t.radii_mm, &q) - t.scale_mm * x).abs() < 1e-12);
        }
        // One-sided torque: one cable, no preload, the peak tension τ/ρ.
        assert!(!t.pair);
        assert_eq!(t.preload_n, 0.0);
        assert!((t.peak_tension_n - 3.0 / 0.04).abs() < 1e-9);
    }

    /// An antagonistic pair's cables both stay taut at every torque the region gives, and its
    /// cable carries the peak tension with the safety factor.
    #[test]
    fn an_antagonistic_pairs_tensions_stay_positive_over_the_region() {
        let torque = [-12.0, 7.5];
        let t = transmission(&[1.0, 1.0, 1.0], None, torque, &LIMITS).unwrap().tendon.unwrap();
        assert!(t.pair);
        assert!((t.preload_n - 1.25 * 12.0 / (2.0 * 0.04)).abs() < 1e-9);
        let mut peak = 0.0f64;
        for i in 0..=100 {
            let tau = torque[0] + (torque[1] - torque[0]) * f64::from(i) / 100.0;
            let (t1, t2) = pair_tensions(t.preload_n, t.scale_mm, tau);
            assert!(t1 > 0.0 && t2 > 0.0, "τ = {tau}: {t1}, {t2}");
            // The pair's net torque is the element's.
            assert!((t.scale_mm * 1e-3 * (t1 - t2) - tau).abs() < 1e-12);
            peak = peak.max(t1).max(t2);
        }
        assert!((peak - t.peak_tension_n).abs() < 1e-9);
        assert!(t.cable.breaking_n >= CABLE_SAFETY_FACTOR * t.peak_tension_n);
        let thinner = CABLES.iter().take_while(|c| c.name != t.cable.name).last().unwrap();
        assert!(thinner.breaking_n < CABLE_SAFETY_FACTOR * t.peak_tension_n, "the thinnest that carries it");
    }

    /// Every coupling a tendon family generates gets a transmission part: a tendon over exactly
    /// the radii it carries (within the limits the design's `[parts]` checked), or for the
    /// family's bevel couplings a bevel differential.
    #[test]
    fn every_coupling_of_a_tendon_family_gets_a_transmission() {
        let text = "[[family]]\nname = \"t\"\nprofile = \"linear\"\noffsets = \"equilibrium\"\n\
                    couplings = { tendons = { radii_mm = [10, 20, 30, 40], max_crossed = 3, bevel = true } }\n";
        let path = std::path::Path::new("catalogs/test.toml");
        let c = crate::elements::catalog::Catalog::parse(path, text, 6).unwrap();
        c.check_pulleys(LIMITS.min_radius_mm, LIMITS.max_radius_mm, LIMITS.max_joints).unwrap();
        let f = &c.families[0];
        let (mut tendons, mut bevels) = (0, 0);
        for (a, r) in f.couplings.iter().zip(&f.pulleys) {
            let t = transmission(a, r.as_deref(), [-2.0, 3.0], &LIMITS).unwrap();
            match (t.kind, r, &t.tendon) {
                (Kind::Tendon, Some(r), Some(t)) => {
                    assert_eq!(&t.radii_mm, r);
                    assert!(t.pair, "the torque changes sign: an antagonistic pair");
                    tendons += 1;
                }
                (Kind::BevelDifferential, None, None) => bevels += 1,
                other => panic!("{a:?}: {other:?}"),
            }
        }
        assert_eq!(tendons + bevels, f.couplings.len());
        assert!(tendons > 0 && bevels > 0, "{tendons} tendons, {bevels} differentials");
    }

    /// The cable's stretch: EA from the stretch factor (1/8 in 7x19: 100·0.125²/G lbf), and a
    /// pair's stiffness on x per metre twice one cable's.
    #[test]
    fn cable_stretch_is_a_series_compliance() {
        let eighth = CABLES[4];
        assert!((eighth.axial_stiffness_n() - 100.0 * 0.015625 / 1.62e-5 * LBF).abs() < 1e-6);
        assert!((eighth.axial_stiffness_n() / 1e3 - 429.0).abs() < 1.0);
        let mut t = transmission(&[1.0, 1.0, 1.0], None, [-12.0, 7.5], &LIMITS).unwrap().tendon.unwrap();
        let pair = t.stretch_rate_per_m();
        assert!((pair - 2.0 * t.cable.axial_stiffness_n() * 0.04 * 0.04).abs() < 1e-9);
        t.pair = false;
        assert!((t.stretch_rate_per_m() - pair / 2.0).abs() < 1e-9);
        assert!((series_rate(10.0, 90.0) - 9.0).abs() < 1e-12);
    }

    /// A coupling whose pulleys would fall outside the limits, or that crosses too many joints,
    /// has no transmission, and the reason names the `[parts]` key.
    #[test]
    fn a_coupling_beyond_the_pulley_limits_has_no_transmission() {
        let e = transmission(&[0.08, 1.0, 0.0, -0.29], None, [-1.0, 1.0], &LIMITS).unwrap_err();
        assert!(e.best.contains("`[parts] min_pulley_radius_mm` = 10 mm"), "{}", e.best);
        assert!(e.best.contains("3.200 mm"), "{}", e.best);
        let e = transmission(&[1.0; 6], None, [-1.0, 1.0], &LIMITS).unwrap_err();
        assert!(e.best.contains("`[parts] max_joints_crossed` = 5"), "{}", e.best);
        let e = transmission(&[1.0, 0.0, 1.0], None, [-1e5, 1e5], &LIMITS).unwrap_err();
        assert!(e.best.contains("strongest listed cable"), "{}", e.best);
        // Within the limits at the edge: 1 : 4 is what 10–40 mm allows.
        assert!(transmission(&[0.25, 0.0, 1.0], None, [-1.0, 1.0], &LIMITS).is_ok());
        // Given radii are kept exactly (the chooser would scale (10, 30) to (13.33, 40)), and a
        // given pulley beyond the limits names it.
        let t = transmission(&[1.0 / 3.0, -1.0, 0.0], Some(&[10.0, -30.0, 0.0]), [-1.0, 1.0], &LIMITS).unwrap();
        let t = t.tendon.unwrap();
        assert_eq!((t.radii_mm.clone(), t.scale_mm), (vec![10.0, -30.0, 0.0], 30.0));
        let t = transmission(&[1.0, 0.5, 0.0], Some(&[40.0, 20.0, 0.0]), [-1.0, 1.0], &LIMITS).unwrap();
        assert_eq!(t.kind, Kind::Tendon, "a tendon family's coupling stays a tendon at a bevel ratio");
        let e = transmission(&[1.0, 0.1, 0.0], Some(&[50.0, 5.0, 0.0]), [-1.0, 1.0], &LIMITS).unwrap_err();
        assert!(
            e.best.contains("`[parts] min_pulley_radius_mm` = 10 mm") || e.best.contains("max_pulley"),
            "{}",
            e.best
        );
    }
}
