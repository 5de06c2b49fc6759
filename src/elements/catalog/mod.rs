//! Spring catalogues: families of elastic elements that expand into fit candidates.
//!
//! A catalogue is a TOML file with one `[[family]]` table per kind of element a workshop can
//! build or buy. A family fixes the profile, the couplings it can be mounted on and the offsets
//! it can be set to; each coupling × offset × side becomes one candidate element whose stiffness
//! the fit chooses.
//!
//! ```toml
//! name = "workshop"
//!
//! [[family]]
//! name = "joint torsion spring"
//! profile = "linear"              # linear | cubic | crank | compression
//! couplings = "joints"            # "joints", { pairs = [[1, 1]] }, { all_pairs = … }, { triples = … }, { runs = [4] }
//!                                 # (each optionally on = ["q2", "q3"]), { joints = ["q1"] } or [[1, -2]]
//! offsets = "equilibrium"         # "equilibrium", { grid = 9 }, { phases = 12 } or angles
//! unit = "N*m/rad"                # optional; must match the profile
//! max_stiffness = 40.0            # optional, in the profile's unit
//! stock_rates = [1, 2, 5, 10, 20] # optional: what the supplier sells, same unit
//! tolerance = 0.1                 # ± fraction of the stiffness a built spring may deviate
//! adjustable = true               # optional: the offset can be moved after assembly …
//! adjust_range = 0.2              # … by up to ± this many rad (a preload screw, a crank phase)
//! ```
//!
//! Compression springs also take `side = "+"`, `"-"` or `"both"`.
//!
//! A **trim** family (`trim = true`, `trim_range = [lo, hi]` in N·m/rad) lists linear springs
//! relaxed at the equilibrium whose rate is set after assembly (see [`crate::elements::trim`]). Trims are
//! not fit candidates: every listed coupling carries one, placed at the mid-range rate, and the
//! fit fits the other elements around them. With `trim_sized = true` the range is where the fit
//! starts: the fit job then sizes it by the bill ([`crate::asbuilt::sizing`]).

use std::collections::HashMap;
use std::path::PathBuf;

use serde::Serialize;

use crate::elements::spline::Knots;
use crate::elements::{Element, Profile, Side};

mod file;
mod resolve;

pub use file::{CatalogFile, CouplingSpec, FamilySpec, GroupKind, OffsetSpec, Smoothing, TendonSpec};
pub use resolve::numbered_joints;

/// A validated cam family's settings (see [`crate::elements::spline`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CamSpec {
    /// Knots N.
    pub knots: u16,
    /// Smoothing weight.
    pub smoothing: Smoothing,
    /// Margin as a fraction of x's range.
    pub margin: f64,
    /// Follower spring rate in N/mm, if fixed.
    pub follower_rate: Option<f64>,
    /// Largest stroke in mm.
    pub max_stroke: f64,
    /// Follower preload at the base circle as a fraction of the largest stroke.
    pub preload_fraction: f64,
    /// Base-circle radius in mm.
    pub base_radius: f64,
    /// Roller radius in mm.
    pub roller_radius: f64,
    /// Largest pressure angle in degrees.
    pub max_pressure_angle: f64,
}

/// A cam family's follower preload at the base circle, as a fraction of the largest stroke, when
/// it states none.
pub const DEFAULT_PRELOAD_FRACTION: f64 = 0.5;

/// Ratios (larger over smaller, in magnitude) at which two neighbouring joints drive one bevel-gear
/// differential: those one bevel-gear pair makes from whole tooth counts, from 1 : 1 (mitre gears)
/// to 1 : 5, beyond which a bevel pair needs a second stage. Any other ratio is a tendon's. Here,
/// below the transmissions (`realise::transmission`), so that a tendon family's `bevel = true`
/// lists the same ratios the parts stage recognises.
pub const BEVEL_RATIOS: [f64; 7] = [1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0];

/// A validated family.
#[derive(Debug, Clone)]
pub struct Family {
    /// Human name.
    pub name: String,
    /// Profiles (two for compression springs on both sides).
    pub profiles: Vec<Profile>,
    /// Coupling vectors, resolved for the robot.
    pub couplings: Vec<Vec<f64>>,
    /// Each coupling's signed pulley radii (mm, one per joint, 0 where the cable does not cross)
    /// when a tendon family generated it, parallel to `couplings`; None for every other coupling
    /// (a bevel differential's, any other family's): `parts` reports these radii.
    pub pulleys: Vec<Option<Vec<f64>>>,
    /// A tendon family's `couplings.tendons` as written (validated), for the check against a
    /// design's `[parts]` limits ([`Catalog::check_pulleys`]).
    pub tendons: Option<TendonSpec>,
    /// Offsets.
    pub offsets: OffsetSpec,
    /// Largest stiffness.
    pub max_stiffness: Option<f64>,
    /// Stock rates, ascending.
    pub stock_rates: Vec<f64>,
    /// ± fraction.
    pub tolerance: f64,
    /// Cam settings (`profile = "cam"`; `profiles` is then empty).
    pub cam: Option<CamSpec>,
    /// ± rad an adjustable element's offset can be moved after assembly (None: fixed).
    pub adjust_range: Option<f64>,
    /// A trim family's rate range [lo, hi], N·m/rad (None: not a trim family).
    pub trim_range: Option<[f64; 2]>,
    /// Whether the fit job sizes this trim family's range by the bill (`trim_sized = true`:
    /// `trim_range` is where the fit starts, see [`crate::asbuilt::sizing`]); false: the range is
    /// fixed as written.
    pub trim_sized: bool,
}

/// A trim spring the catalogue places on the design (see [`Catalog::trims`]).
#[derive(Debug, Clone, PartialEq)]
pub struct TrimSpring {
    /// Index of its family.
    pub family: usize,
    /// The element: linear, relaxed at the equilibrium.
    pub element: Element,
    /// Its rate range [lo, hi], N·m/rad.
    pub range: [f64; 2],
}

/// A validated catalogue for a robot with a given number of joints.
#[derive(Debug, Clone)]
pub struct Catalog {
    /// Where it was read from.
    pub path: PathBuf,
    /// Name.
    pub name: String,
    /// Families.
    pub families: Vec<Family>,
    /// At most this many candidates come out of [`Catalog::expand`] (each family's couplings ×
    /// offsets × sides or cam columns; duplicates are dropped later): what the fit's memory
    /// is judged by before any work.
    pub candidate_bound: usize,
    /// At most this many of those candidates are non-zero in one row of the fit: every column
    /// of a spring family, but of a cam's 2 (N + 2) B-spline columns only the 2 × 4 whose basis
    /// functions are non-zero at the sample's x. The memory of a cam fit's rows, which are
    /// written as their non-zeros.
    pub row_nonzero_bound: usize,
}

/// A fit candidate: an element and what its family says about building it.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// The element.
    pub element: Element,
    /// Index of its family in the catalogue.
    pub family: usize,
    /// Largest stiffness.
    pub max_stiffness: Option<f64>,
    /// Stock rates, ascending.
    pub stock_rates: Vec<f64>,
    /// ± fraction.
    pub tolerance: f64,
}

impl Candidate {
    /// An element taken as it is, outside any catalogue choice (a spring already fitted, a trim
    /// held at mid-range): only its rows are wanted, so no family, limit, stock rate or tolerance.
    pub fn bare(element: Element) -> Candidate {
        Candidate { element, family: 0, max_stiffness: None, stock_rates: Vec::new(), tolerance: 0.0 }
    }
}

impl Catalog {
    /// Expands the families into candidates. `q_eq` sets equilibrium offsets; `range(a)` gives
    /// the (min, max) of a·q over the region for grid offsets. Duplicates (the same profile,
    /// coupling and offset from two families) are kept once, the first family winning.
    pub fn expand(&self, q_eq: &[f64], range: impl Fn(&[f64]) -> (f64, f64)) -> Vec<Candidate> {
        let mut out: Vec<Candidate> = Vec::new();
        // Offsets kept so far per profile and coupling (bit patterns, −0 as 0): duplicates are
        // looked for among these only, not among all candidates.
        let mut kept: HashMap<(Profile, Vec<u64>), Vec<f64>> = HashMap::new();
        for (fi, f) in self.families.iter().enumerate().filter(|(_, f)| f.trim_range.is_none()) {
            for a in &f.couplings {
                if let Some(cam) = &f.cam {
                    // N + 2 basis functions, each as +Bⱼ and −Bⱼ (signed coefficients, k ≥ 0).
                    let (lo, hi) = range(a);
                    let knots = Knots::over(lo, hi, cam.knots, cam.margin);
                    for j in 0..knots.basis_count() {
                        for negative in [false, true] {
                            let profile = Profile::Spline(knots.basis(j, negative));
                            out.push(Candidate {
                                element: Element { profile, coupling: a.clone(), offset: knots.lo },
                                family: fi,
                                max_stiffness: f.max_stiffness,
                                stock_rates: Vec::new(),
                                tolerance: f.tolerance,
                            });
                        }
                    }
                    continue;
                }
                let at_eq: f64 = a.iter().zip(q_eq).map(|(a, q)| a * q).sum();
                let offsets: Vec<f64> = match &f.offsets {
                    OffsetSpec::Equilibrium => vec![at_eq],
                    OffsetSpec::List(l) => l.clone(),
                    OffsetSpec::Phases { count } => {
                        // A crank's torque is 2π-periodic in x − x₀: its offsets are written in
                        // (−π, π] (6.8068 rad reads as 0.5236). Other profiles keep theirs.
                        let periodic = f.profiles.iter().all(|p| matches!(p, Profile::Crank));
                        (0..*count)
                            .map(|k| at_eq + std::f64::consts::TAU * k as f64 / *count as f64)
                            .map(|x| if periodic { crate::geodesic::logmap::wrap_angle(x) } else { x })
                            .collect()
                    }
                    OffsetSpec::Grid { count, equilibrium } => {
                        let (lo, hi) = range(a);
                        let mut v: Vec<f64> = if *count == 1 {
                            vec![0.5 * (lo + hi)]
                        } else {
                            (0..*count).map(|k| lo + (hi - lo) * k as f64 / (*count - 1) as f64).collect()
                        };
                        if *equilibrium {
                            v.push(at_eq);
                        }
                        v
                    }
                };
                let key: Vec<u64> = a.iter().map(|x| if *x == 0.0 { 0 } else { x.to_bits() }).collect();
                for &x0 in &offsets {
                    for &profile in &f.profiles {
                        let seen = kept.entry((profile, key.clone())).or_default();
                        if seen.iter().any(|&x| same_offset(x, x0)) {
                            continue;
                        }
                        seen.push(x0);
                        let element = Element { profile, coupling: a.clone(), offset: x0 };
                        out.push(Candidate {
                            element,
                            family: fi,
                            max_stiffness: f.max_stiffness,
                            stock_rates: f.stock_rates.clone(),
                            tolerance: f.tolerance,
                        });
                    }
                }
            }
        }
        out
    }
}

impl Family {
    /// The smoothing weight of the family's parts (its cams' `smoothing`); `auto` for a family
    /// without parts (never asked).
    pub fn smoothing(&self) -> Smoothing {
        self.cam.map_or(Smoothing::Auto, |c| c.smoothing)
    }
}

impl Catalog {
    /// The trim springs of the catalogue's trim families: one per listed coupling, linear,
    /// relaxed at `q_eq`.
    pub fn trims(&self, q_eq: &[f64]) -> Vec<TrimSpring> {
        let mut out = Vec::new();
        for (fi, f) in self.families.iter().enumerate() {
            let Some(range) = f.trim_range else { continue };
            for a in &f.couplings {
                let offset = a.iter().zip(q_eq).map(|(a, q)| a * q).sum();
                out.push(TrimSpring {
                    family: fi,
                    element: Element { profile: Profile::Linear, coupling: a.clone(), offset },
                    range,
                });
            }
        }
        out
    }

    /// The family called `name`, if any.
    pub fn family(&self, name: &str) -> Option<&Family> {
        self.families.iter().find(|f| f.name == name)
    }

    /// The pulley radii (mm) of the tendon family `family`'s coupling `coupling`, if that family
    /// generated it (to 1e-12 in each entry): what `parts` reports as the tendon's radii.
    pub fn pulleys(&self, family: &str, coupling: &[f64]) -> Option<&[f64]> {
        let f = self.family(family)?;
        let same = |a: &[f64]| a.len() == coupling.len() && a.iter().zip(coupling).all(|(x, y)| (x - y).abs() <= 1e-12);
        f.couplings.iter().zip(&f.pulleys).find(|(a, _)| same(a)).and_then(|(_, r)| r.as_deref())
    }

    /// Checks every tendon family against a design's `[parts]` pulley limits: each stocked
    /// radius within [`min_mm`, `max_mm`] and `max_crossed` at most `max_joints`. Err: the field
    /// of the catalogue (`family[i].couplings.tendons.radii_mm[k]`) and the `[parts]` key it
    /// breaks, with both values.
    pub fn check_pulleys(&self, min_mm: f64, max_mm: f64, max_joints: usize) -> crate::error::Result<()> {
        for (i, f) in self.families.iter().enumerate() {
            let Some(t) = &f.tendons else { continue };
            let field = |key: &str| format!("family[{i}].couplings.tendons.{key}");
            for (k, r) in t.radii_mm.iter().enumerate() {
                let (key, limit, beyond) = if *r < min_mm * (1.0 - 1e-12) {
                    ("min_pulley_radius_mm", min_mm, "below")
                } else if *r > max_mm * (1.0 + 1e-12) {
                    ("max_pulley_radius_mm", max_mm, "above")
                } else {
                    continue;
                };
                return Err(crate::error::Error::invalid(
                    &self.path,
                    field(&format!("radii_mm[{k}]")),
                    format!("a pulley of {r} mm is {beyond} the design's `[parts] {key}` = {limit} mm"),
                ));
            }
            if t.max_crossed > max_joints {
                return Err(crate::error::Error::invalid(
                    &self.path,
                    field("max_crossed"),
                    format!(
                        "a tendon crossing {} joints is more than the design's `[parts] max_joints_crossed` = {max_joints}",
                        t.max_crossed
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// Whether a new offset `b` repeats a kept offset `a` (of the same profile and coupling).
fn same_offset(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * (1.0 + a.abs())
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::error::Result;

    fn load(text: &str, dof: usize) -> Result<Catalog> {
        Catalog::parse(Path::new("catalogs/test.toml"), text, dof)
    }

    const GOOD: &str = r#"
name = "t"
[[family]]
name = "torsion"
profile = "linear"
couplings = "joints"
offsets = "equilibrium"
unit = "N·m/rad"
[[family]]
name = "bevel crank"
profile = "crank"
couplings = { pairs = [[1, 1], [1, -1]] }
offsets = { grid = 3 }
max_stiffness = 10.0
stock_rates = [5, 1, 2]
tolerance = 0.1
[[family]]
name = "stops"
profile = "compression"
couplings = [[1, 0], [0, 2]]
offsets = [-0.5, "pi/4"]
[[family]]
name = "phased cranks"
profile = "crank"
couplings = [[0, 1]]
offsets = { phases = 4 }
"#;

    #[test]
    fn expands_families_into_candidates() {
        let c = load(GOOD, 2).unwrap();
        assert_eq!(c.families[1].stock_rates, vec![1.0, 2.0, 5.0]);
        let cands = c.expand(&[0.0, 1.0], |a| (-1.0 + a[1], 1.0 + a[1]));
        // 2 linear + 2 pairs × 3 offsets + 2 couplings × 2 offsets × 2 sides + 4 phases.
        assert_eq!(cands.len(), 2 + 6 + 8 + 4);
        let phased: Vec<f64> = cands[16..].iter().map(|c| c.element.offset).collect();
        let quarter = std::f64::consts::FRAC_PI_2;
        // Crank offsets are wrapped into (−π, π]: 1 + π and 1 + 3π/2 read as 1 − π and 1 − π/2.
        let pi = std::f64::consts::PI;
        let expected = [1.0, 1.0 + quarter, 1.0 + 2.0 * quarter - 2.0 * pi, 1.0 + 3.0 * quarter - 2.0 * pi];
        for (got, want) in phased.iter().zip(expected) {
            assert!((got - want).abs() < 1e-12 && -pi < *got && *got <= pi, "{phased:?}");
        }
        assert_eq!(cands[1].element.offset, 1.0);
        let crank: Vec<_> = cands.iter().filter(|c| c.element.profile == Profile::Crank).collect();
        assert_eq!(crank[0].element.coupling, vec![1.0, 1.0]);
        assert_eq!(crank.iter().map(|c| c.element.offset).collect::<Vec<_>>()[..3], [0.0, 1.0, 2.0]);
        assert_eq!(crank[0].max_stiffness, Some(10.0));
        // Three joints: pairs expand over both adjacent pairs.
        let text3 = GOOD
            .replace("couplings = [[1, 0], [0, 2]]", "couplings = [[1, 0, 0], [0, 2, 0]]")
            .replace("couplings = [[0, 1]]", "couplings = [[0, 1, 0]]");
        let c3 = load(&text3, 3).unwrap();
        let cands3 = c3.expand(&[0.0, 0.0, 0.0], |_| (-1.0, 1.0));
        assert_eq!(cands3.iter().filter(|c| c.element.profile == Profile::Crank).count(), 2 * 2 * 3 + 4);
    }

    /// Families for n joints: every joint, every pair, every adjacent triple, each among all
    /// joints or the ones `on` names (the arm's names or q1 … qn), with the vectors they stand for.
    #[test]
    fn group_families_expand_for_any_number_of_joints() {
        let couplings = |spec: &str, joints: &[&str]| -> Result<Vec<Vec<f64>>> {
            let text = format!(
                "[[family]]\nname = \"f\"\nprofile = \"linear\"\ncouplings = {spec}\noffsets = \"equilibrium\"\n"
            );
            let names: Vec<String> = joints.iter().map(|s| s.to_string()).collect();
            Ok(Catalog::parse_for(Path::new("catalogs/test.toml"), &text, &names)?.families[0].couplings.clone())
        };
        let five = ["q1", "q2", "q3", "q4", "q5"];
        let e = |i: usize| (0..5).map(|k| if k == i { 1.0 } else { 0.0 }).collect::<Vec<f64>>();
        assert_eq!(couplings("\"joints\"", &five).unwrap(), (0..5).map(e).collect::<Vec<_>>());
        // Adjacent triples of five joints: three of them per pattern, patterns outermost.
        let t = couplings("{ triples = [[1, -1, 1], [1, 2, 3]] }", &five).unwrap();
        assert_eq!(t.len(), 6);
        assert_eq!(t[0], vec![1.0, -1.0, 1.0, 0.0, 0.0]);
        assert_eq!(t[2], vec![0.0, 0.0, 1.0, -1.0, 1.0]);
        assert_eq!(t[4], vec![0.0, 1.0, 2.0, 3.0, 0.0]);
        // All pairs of five joints: ten.
        assert_eq!(couplings("{ all_pairs = [[1, 1]] }", &five).unwrap().len(), 10);
        // Among named joints, in the arm's order whatever the order written: pairs adjacent
        // among them (q2, q4) and (q4, q5).
        let urdf = ["pan", "lift", "elbow", "wrist_1", "wrist_2"];
        let p = couplings("{ pairs = [[1, 2]], on = [\"wrist_2\", \"lift\", \"q4\"] }", &urdf).unwrap();
        assert_eq!(p, vec![vec![0.0, 1.0, 0.0, 2.0, 0.0], vec![0.0, 0.0, 0.0, 1.0, 2.0]]);
        assert_eq!(couplings("{ joints = [\"elbow\"] }", &urdf).unwrap(), vec![vec![0.0, 0.0, 1.0, 0.0, 0.0]]);
        // Runs of adjacent joints turned together, shortest lengths first: two of four joints, one
        // of five; a length beyond the arm (6) gives none, so the family still serves five joints.
        let r = couplings("{ runs = [4, 5, 6] }", &five).unwrap();
        assert_eq!(r, vec![vec![1.0, 1.0, 1.0, 1.0, 0.0], vec![0.0, 1.0, 1.0, 1.0, 1.0], vec![1.0; 5]]);
        // Among named joints a run is of neighbours among them: (lift, wrist_1) skips the elbow.
        let r = couplings("{ runs = [2], on = [\"wrist_1\", \"lift\"] }", &urdf).unwrap();
        assert_eq!(r, vec![vec![0.0, 1.0, 0.0, 1.0, 0.0]]);
        // Refused, naming the entry: a joint the arm does not have, twice the same, too few joints
        // for the group, a zero ratio, `on` with "joints".
        let cases: [(&str, &[&str], &str, &str); 9] = [
            (
                "{ all_pairs = [[1, 1]], on = [\"lift\", \"wrist_3\"] }",
                &urdf,
                "couplings.on[1]",
                "`wrist_3` is not a joint",
            ),
            ("{ joints = [\"q6\"] }", &five, "couplings.joints[0]", "its joints are q1, q2, q3, q4, q5"),
            ("{ joints = [\"q2\", \"q2\"] }", &five, "couplings.joints[1]", "listed twice"),
            ("{ triples = [[1, 1, 1]] }", &five[..2], "family[0].couplings", "triples need at least 3 joints"),
            ("{ triples = [[1, 0, 1]] }", &five, "couplings.triples[0]", "non-zero"),
            ("{ joints = [\"q1\"], on = [\"q1\"] }", &five, "test.toml", "couplings must be"),
            ("{ runs = [3, 1] }", &five, "couplings.runs[1]", "a run is 2 to 8 adjacent joints, got 1"),
            ("{ runs = [6, 7] }", &five, "family[0].couplings", "the shortest run is 6 joints but the robot has 5"),
            ("{ runs = [2], pairs = [[1, 1]] }", &five, "test.toml", "couplings must be"),
        ];
        for (spec, joints, field, reason) in cases {
            let err = couplings(spec, joints).unwrap_err().to_string();
            assert!(err.contains(field) && err.contains(reason), "{spec}: expected {field} / {reason} in {err}");
        }
    }

    /// A tendon family over radii {10, 20} on three joints: per run of two, the directions
    /// (1, 1), (½, 1), (1, ½) on both sides (6; (10, 10) and (20, 20) are one, kept at 20 mm);
    /// per run of three, 7 directions × 4 sides (28); with `bevel`, each neighbour pair adds
    /// the 20 ratio couplings no tendon makes (1.5, 2.5, 3, 4, 5 both ways and sides).
    #[test]
    fn tendon_families_expand_into_what_their_pulleys_make() {
        let text = |spec: &str| {
            format!("[[family]]\nname = \"t\"\nprofile = \"linear\"\ncouplings = {spec}\noffsets = \"equilibrium\"\n")
        };
        let two = load(&text("{ tendons = { radii_mm = [20, 10], max_crossed = 2 } }"), 3).unwrap();
        let f = &two.families[0];
        assert_eq!((f.couplings.len(), f.pulleys.len()), (12, 12));
        assert_eq!(f.couplings[0], vec![1.0, 1.0, 0.0]);
        assert_eq!(f.pulleys[0].as_deref(), Some(&[20.0, 20.0, 0.0][..]), "the larger of (10, 10) and (20, 20)");
        assert_eq!(f.couplings[1], vec![1.0, -1.0, 0.0]);
        assert_eq!((f.couplings[2].clone(), f.pulleys[2].clone()), (vec![0.5, 1.0, 0.0], Some(vec![10.0, 20.0, 0.0])));
        assert_eq!(f.couplings[6], vec![0.0, 1.0, 1.0], "the second run after the first");
        // Every coupling carries radii ρ·a, its largest entry 1, the first crossing on the + side.
        for (a, r) in f.couplings.iter().zip(&f.pulleys) {
            let r = r.as_ref().unwrap();
            let rho = r.iter().fold(0.0, |m: f64, x| m.max(x.abs()));
            assert!(a.iter().zip(r).all(|(a, r)| (rho * a - r).abs() < 1e-12), "{a:?} {r:?}");
            assert!(a.iter().find(|x| **x != 0.0).is_some_and(|x| *x > 0.0));
        }
        assert_eq!(two.pulleys("t", &[0.5, 1.0, 0.0]), Some(&[10.0, 20.0, 0.0][..]));
        assert_eq!(two.pulleys("t", &[0.5, -1.0, 0.0]), Some(&[10.0, -20.0, 0.0][..]));
        assert_eq!(two.pulleys("t", &[1.0, 0.0, 1.0]), None, "not one of its couplings");
        let three = load(&text("{ tendons = { radii_mm = [10, 20], max_crossed = 3 } }"), 3).unwrap();
        assert_eq!(three.families[0].couplings.len(), 12 + 28);
        let bevel = load(&text("{ tendons = { radii_mm = [10, 20], max_crossed = 2, bevel = true } }"), 3).unwrap();
        let f = &bevel.families[0];
        assert_eq!(f.couplings.len(), 12 + 2 * 20);
        assert_eq!((f.couplings[12].clone(), f.pulleys[12].clone()), (vec![1.0, 1.0 / 1.5, 0.0], None));
        // The same file loads into the same couplings in the same order.
        let again = load(&text("{ tendons = { radii_mm = [10, 20], max_crossed = 2, bevel = true } }"), 3).unwrap();
        assert_eq!(again.families[0].couplings, f.couplings);
        // Refused, naming the field: no radius, a bad radius, more joints than the arm, one joint,
        // a tendon family with `on`, and the design's [parts] limits.
        let cases = [
            ("{ tendons = { radii_mm = [], max_crossed = 2 } }", "couplings.tendons.radii_mm", "no pulley"),
            ("{ tendons = { radii_mm = [10, -5], max_crossed = 2 } }", "couplings.tendons.radii_mm[1]", "positive"),
            ("{ tendons = { radii_mm = [10], max_crossed = 4 } }", "couplings.tendons.max_crossed", "2 to 3 joints"),
            ("{ tendons = { radii_mm = [10], max_crossed = 1 } }", "couplings.tendons.max_crossed", "got 1"),
            ("{ tendons = { radii_mm = [10], max_crossed = 2 }, on = [\"q1\"] }", "test.toml", "couplings must be"),
            ("{ tendons = { radii_mm = [10], max_crossed = 2, side = 1 } }", "test.toml", "couplings must be"),
        ];
        for (spec, field, reason) in cases {
            let err = load(&text(spec), 3).unwrap_err().to_string();
            assert!(err.contains(field) && err.contains(reason), "{spec}: expected {field} / {reason} in {err}");
        }
        let wide = load(&text("{ tendons = { radii_mm = [10, 50], max_crossed = 3 } }"), 3).unwrap();
        let err = wide.check_pulleys(10.0, 40.0, 5).unwrap_err().to_string();
        assert!(
            err.contains("family[0].couplings.tendons.radii_mm[1]")
                && err.contains("`[parts] max_pulley_radius_mm` = 40"),
            "{err}"
        );
        let err = wide.check_pulleys(10.0, 60.0, 2).unwrap_err().to_string();
        assert!(
            err.contains("family[0].couplings.tendons.max_crossed") && err.contains("max_joints_crossed` = 2"),
            "{err}"
        );
        assert!(wide.check_pulleys(5.0, 60.0, 3).is_ok());
        // Too many tendons before the repeats are removed: refused before any is built.
        let many: Vec<String> = (1..=40).map(|r| format!("{}", 10 + r)).collect();
        let spec = format!("{{ tendons = {{ radii_mm = [{}], max_crossed = 5 }} }}", many.join(", "));
        let err = load(&text(&spec), 6).unwrap_err().to_string();
        assert!(err.contains("family[0].couplings.tendons") && err.contains("more than 20000"), "{err}");
    }

    /// Inputs run through the fuzz target fuzz/fuzz_targets/catalog.rs by hand: a phase count
    /// of zero expanded into nothing, a huge one into an allocation of terabytes, and many
    /// couplings times a fine grid into a million candidates deduplicated in quadratic time.
    #[test]
    fn offset_counts_and_candidate_totals_are_bounded() {
        let family = |couplings: &str, offsets: &str| {
            format!("[[family]]\nname = \"x\"\nprofile = \"crank\"\ncouplings = {couplings}\noffsets = {offsets}\n")
        };
        // Repeated families need names of their own.
        let named = |text: String| -> String {
            let mut k = 0;
            text.lines()
                .map(|l| {
                    if l == "name = \"x\"" {
                        k += 1;
                        format!("name = \"x{k}\"")
                    } else {
                        l.to_string()
                    }
                })
                .collect::<Vec<_>>()
                .join("\n")
        };
        let many: Vec<String> = (1..=300).map(|r| format!("[1, {r}]")).collect();
        let many = format!("{{ all_pairs = [{}] }}", many.join(", "));
        let cases = [
            (family("\"joints\"", "{ phases = 0 }"), "family[0].offsets", "phases must be 1 to 1000"),
            (family("\"joints\"", "{ phases = 100000000000 }"), "family[0].offsets", "phases must be 1 to 1000"),
            (family("\"joints\"", "{ grid = 18446744073709551615 }"), "family[0].offsets", "grid must have 1 to 1000"),
            (family(&many, "{ grid = 1000 }"), "family[0]", "more than 20000 candidate elements"),
            (
                named(family("\"joints\"", "{ grid = 1000, equilibrium = true }").repeat(8)),
                "family[6]",
                "more than 20000 candidate elements",
            ),
        ];
        for (text, field, reason) in cases {
            let err = load(&text, 3).unwrap_err().to_string();
            assert!(err.contains(field) && err.contains(reason), "expected {field} / {reason} in {err}");
        }
        // Just under the bound: expands, and the repeated families add nothing.
        let text = named(family("\"joints\"", "{ grid = 1000 }").repeat(6));
        let c = load(&text, 3).unwrap();
        assert_eq!(c.expand(&[0.0; 3], |_| (-1.0, 1.0)).len(), 3000);
    }

    #[test]
    fn bad_catalogues_name_the_field() {
        let cases = [
            (GOOD.replacen("profile = \"linear\"", "profile = \"spiral\"", 1), "family[0].profile", "unknown profile"),
            (GOOD.replace("max_stiffness = 10.0", "max_stiffness = -1.0"), "family[1].max_stiffness", "positive"),
            (
                GOOD.replace("couplings = [[1, 0], [0, 2]]", "couplings = [[1, 0, 0]]"),
                "family[2].couplings[0]",
                "3 entries",
            ),
            ("name = \"empty\"".to_string(), "family", "no candidate"),
            (GOOD.replace("unit = \"N·m/rad\"", "unit = \"N*m\""), "family[0].unit", "N*m/rad"),
            (GOOD.replace("tolerance = 0.1", "tolerance = 1.5"), "family[1].tolerance", "fraction"),
            (
                GOOD.replace("offsets = { grid = 3 }", "offsets = { grid = 3, spacing = 1 }"),
                "test.toml:",
                "offsets must be",
            ),
            (
                GOOD.replace("stock_rates = [5, 1, 2]", "stock_rates = [5, 0, 2]"),
                "family[1].stock_rates[1]",
                "positive",
            ),
        ];
        for (text, field, reason) in cases {
            let err = load(&text, 2).unwrap_err().to_string();
            assert!(err.contains(field) && err.contains(reason), "expected {field} / {reason} in {err}");
        }
    }

    /// Trim families are never fit candidates, carry one trim per coupling relaxed at q_eq, and
    /// every inconsistent after-assembly key is an error naming the field.
    #[test]
    fn trim_and_adjustable_families() {
        let base =
            "[[family]]\nname = \"s\"\nprofile = \"linear\"\ncouplings = \"joints\"\noffsets = \"equilibrium\"\n";
        let text = format!(
            "{base}adjustable = true\nadjust_range = 0.2\n{}",
            base.replace("\"s\"", "\"t\"") + "trim = true\ntrim_range = [0.0, 6.0]\n"
        );
        let c = load(&text, 2).unwrap();
        assert_eq!(c.families[0].adjust_range, Some(0.2));
        let cand = c.expand(&[0.0, 1.0], |_| (-1.0, 1.0));
        assert!(cand.iter().all(|x| x.family == 0) && cand.len() == 2);
        let trims = c.trims(&[0.0, 1.0]);
        assert_eq!(trims.len(), 2);
        assert_eq!(trims[1].element.offset, 1.0);
        assert_eq!(trims[1].range, [0.0, 6.0]);
        for (extra, field) in [
            ("adjustable = true\n", "adjust_range"),
            ("adjust_range = 0.2\n", "adjust_range"),
            ("adjustable = true\nadjust_range = 5.0\n", "adjust_range"),
            ("trim = true\n", "trim_range"),
            ("trim = true\ntrim_range = [3.0, 1.0]\n", "trim_range"),
            ("trim = true\ntrim_range = [0.0, 1.0]\nmax_stiffness = 3.0\n", "trim_range"),
        ] {
            let err = load(&format!("{base}{extra}"), 2).unwrap_err().to_string();
            assert!(err.contains(&format!("family[0].{field}")), "{extra}: {err}");
        }
        let crank = base.replace("\"linear\"", "\"crank\"") + "trim = true\ntrim_range = [0.0, 1.0]\n";
        assert!(load(&crank, 2).unwrap_err().to_string().contains("family[0].profile"));
    }
}
