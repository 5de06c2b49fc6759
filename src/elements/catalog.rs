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
//! couplings = "joints"            # "joints", { pairs = [[1, 1]] }, { all_pairs = … } or [[1, -2]]
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
//! fit fits the other elements around them.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Deserializer, Serialize};

use crate::elements::spline::Knots;
use crate::elements::{Element, Profile, Side};
use crate::error::{Error, Result};
use crate::input::{parse_toml, read_text};
use crate::units::Angle;

/// Most offsets of one family per coupling (`{ grid = N }`, `{ phases = N }`).
pub const MAX_OFFSETS: usize = 1000;

/// Most trim springs one design may carry (the trim solve enumerates 3^m faces).
pub const MAX_TRIMS: usize = 9;

/// Most candidate elements a catalogue may expand into (the shipped catalogues have about 500).
pub const MAX_CANDIDATES: usize = 20_000;

/// The catalogue file as written.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CatalogFile {
    /// Catalogue name (default: the file name without extension).
    pub name: Option<String>,
    /// One line about it.
    pub description: Option<String>,
    /// The families.
    pub family: Vec<FamilySpec>,
}

/// `[[family]]`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FamilySpec {
    /// A human name, printed in the bill of materials.
    pub name: String,
    /// `linear`, `cubic`, `crank` or `compression`.
    pub profile: String,
    /// For compression springs: `+`, `-` or `both` (default `both`).
    #[serde(default)]
    pub side: Option<String>,
    /// Where the element can be mounted.
    pub couplings: CouplingSpec,
    /// Where its offset x₀ can be set (not for cams, whose knots follow the region).
    #[serde(default)]
    pub offsets: Option<OffsetSpec>,
    /// The stiffness unit, to make the file self-explaining; checked against the profile.
    #[serde(default)]
    pub unit: Option<String>,
    /// Largest stiffness the family can provide, in the profile's unit.
    #[serde(default)]
    pub max_stiffness: Option<f64>,
    /// Stiffness values a supplier sells, in the profile's unit.
    #[serde(default)]
    pub stock_rates: Vec<f64>,
    /// ± fraction by which a built element's stiffness may deviate (0.1 = ±10 %).
    #[serde(default)]
    pub tolerance: f64,
    /// Cams: number of uniform B-spline knots over the range x takes (default 30).
    #[serde(default)]
    pub knots: Option<usize>,
    /// Cams: weight of the smoothing penalty ∫V‴² dx, a number ≥ 0 or `"auto"` (default).
    #[serde(default)]
    pub smoothing: Option<Smoothing>,
    /// Cams: the knot span reaches this fraction of x's range beyond each end (default 0.05).
    #[serde(default)]
    pub margin: Option<f64>,
    /// Cams: follower spring rate in N/mm (default: chosen so the stroke is `max_stroke`).
    #[serde(default)]
    pub follower_rate: Option<f64>,
    /// Cams: largest follower stroke in mm when the rate is chosen (default 20).
    #[serde(default)]
    pub max_stroke: Option<f64>,
    /// Cams: base-circle radius in mm (default 40).
    #[serde(default)]
    pub base_radius: Option<f64>,
    /// Cams: roller radius in mm (default 8).
    #[serde(default)]
    pub roller_radius: Option<f64>,
    /// Cams: largest pressure angle in degrees (default 30).
    #[serde(default)]
    pub max_pressure_angle: Option<f64>,
    /// Whether the element's offset x₀ can be moved after assembly (needs `adjust_range`).
    #[serde(default)]
    pub adjustable: bool,
    /// ± range in rad by which an adjustable element's offset can be moved.
    #[serde(default)]
    pub adjust_range: Option<f64>,
    /// Whether the family lists trim springs: linear, relaxed at the equilibrium, rate set after
    /// assembly within `trim_range` (needs `trim_range`).
    #[serde(default)]
    pub trim: bool,
    /// [lo, hi] of a trim spring's rate, N·m/rad.
    #[serde(default)]
    pub trim_range: Option<[f64; 2]>,
}

/// The smoothing weight of a cam family: a number, or chosen on validation geodesics.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub enum Smoothing {
    /// Chosen among a few weights by the residuals on a validation fan (not the held-out one).
    Auto,
    /// This weight (relative: 1 weighs ∫(V‴/(ω² m̄))² dx over the span like all the tangentiality
    /// rows together).
    Weight(f64),
}

impl<'de> Deserialize<'de> for Smoothing {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Word(String),
            Number(f64),
        }
        let msg = "smoothing must be a number ≥ 0 or \"auto\"";
        match Raw::deserialize(d).map_err(|_| serde::de::Error::custom(msg))? {
            Raw::Word(w) if w == "auto" => Ok(Smoothing::Auto),
            Raw::Number(x) if x.is_finite() && x >= 0.0 => Ok(Smoothing::Weight(x)),
            _ => Err(serde::de::Error::custom(msg)),
        }
    }
}

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
    /// Base-circle radius in mm.
    pub base_radius: f64,
    /// Roller radius in mm.
    pub roller_radius: f64,
    /// Largest pressure angle in degrees.
    pub max_pressure_angle: f64,
}

/// Most knots of a cam.
pub const MAX_KNOTS: usize = 500;

/// Where a family can be mounted.
#[derive(Debug, Clone, Serialize)]
pub enum CouplingSpec {
    /// Every single joint (a = eᵢ).
    Joints,
    /// Every pair of adjacent joints (i, i+1) with each gear-ratio pattern (r₁, r₂):
    /// a = r₁ eᵢ + r₂ eᵢ₊₁.
    Pairs(Vec<[f64; 2]>),
    /// Every pair of joints (i < j), adjacent or not, with each ratio pattern.
    AllPairs(Vec<[f64; 2]>),
    /// Explicit coupling vectors, one entry per joint.
    List(Vec<Vec<f64>>),
}

impl<'de> Deserialize<'de> for CouplingSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct PairsTable {
            pairs: Vec<[f64; 2]>,
        }
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct AllPairsTable {
            all_pairs: Vec<[f64; 2]>,
        }
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Word(String),
            Pairs(PairsTable),
            AllPairs(AllPairsTable),
            List(Vec<Vec<f64>>),
        }
        let msg = "couplings must be \"joints\", { pairs = [[r1, r2], ...] } (adjacent joints), \
                   { all_pairs = [[r1, r2], ...] } (every pair) or a list of coupling vectors such as [[1, 0], [1, -1]]";
        match Raw::deserialize(d).map_err(|_| serde::de::Error::custom(msg))? {
            Raw::Word(w) if w == "joints" => Ok(CouplingSpec::Joints),
            Raw::Word(_) => Err(serde::de::Error::custom(msg)),
            Raw::Pairs(p) => Ok(CouplingSpec::Pairs(p.pairs)),
            Raw::AllPairs(p) => Ok(CouplingSpec::AllPairs(p.all_pairs)),
            Raw::List(l) => Ok(CouplingSpec::List(l)),
        }
    }
}

/// Where a family's offsets can be set.
#[derive(Debug, Clone, Serialize)]
pub enum OffsetSpec {
    /// x₀ = a·q_eq: the element is relaxed at the equilibrium.
    Equilibrium,
    /// `count` offsets evenly spaced over the range a·q takes in the region (ends included), plus
    /// the equilibrium's a·q_eq when `equilibrium` is set.
    Grid { count: usize, equilibrium: bool },
    /// `count` phases evenly spaced over one turn starting at the equilibrium:
    /// x₀ = a·q_eq + 2πk/count (for crank mechanisms, whose torque k sin(x − x₀) is periodic).
    Phases { count: usize },
    /// Explicit offsets in rad.
    List(Vec<f64>),
}

impl<'de> Deserialize<'de> for OffsetSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct GridTable {
            grid: usize,
            #[serde(default)]
            equilibrium: bool,
        }
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct PhasesTable {
            phases: usize,
        }
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Word(String),
            Grid(GridTable),
            Phases(PhasesTable),
            List(Vec<Angle>),
        }
        let msg = "offsets must be \"equilibrium\", { grid = N } (optionally with equilibrium = true), \
                   { phases = N } or a list of angles";
        match Raw::deserialize(d).map_err(|_| serde::de::Error::custom(msg))? {
            Raw::Word(w) if w == "equilibrium" => Ok(OffsetSpec::Equilibrium),
            Raw::Word(_) => Err(serde::de::Error::custom(msg)),
            Raw::Grid(g) => Ok(OffsetSpec::Grid { count: g.grid, equilibrium: g.equilibrium }),
            Raw::Phases(p) => Ok(OffsetSpec::Phases { count: p.phases }),
            Raw::List(l) => Ok(OffsetSpec::List(l.into_iter().map(|a| a.0).collect())),
        }
    }
}

/// A validated family.
#[derive(Debug, Clone)]
pub struct Family {
    /// Human name.
    pub name: String,
    /// Profiles (two for compression springs on both sides).
    pub profiles: Vec<Profile>,
    /// Coupling vectors, resolved for the robot.
    pub couplings: Vec<Vec<f64>>,
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
    /// Reads and validates a catalogue for a robot with `dof` joints.
    pub fn load(path: &Path, dof: usize) -> Result<Catalog> {
        Catalog::parse(path, &read_text(path)?, dof)
    }

    /// Parses and validates the text of a catalogue for a robot with `dof` joints (what
    /// [`Catalog::load`] does once the file is read). Never panics: every problem in `text` is
    /// an [`Error`].
    pub fn parse(path: &Path, text: &str, dof: usize) -> Result<Catalog> {
        let file: CatalogFile = parse_toml(path, text)?;
        Catalog::from_file(path, file, dof)
    }

    /// Validates a parsed catalogue.
    pub fn from_file(path: &Path, file: CatalogFile, dof: usize) -> Result<Catalog> {
        let invalid = |field: String, reason: String| Error::invalid(path, field, reason);
        if file.family.is_empty() {
            return Err(invalid(
                "family".into(),
                "the catalogue has no [[family]]: it yields no candidate element".into(),
            ));
        }
        let mut families = Vec::new();
        let mut candidates = 0usize;
        let mut trims = 0usize;
        for (i, f) in file.family.iter().enumerate() {
            let field = |name: &str| format!("family[{i}].{name}");
            let side = f.side.as_deref();
            let cam = cam_spec(path, f, &field)?;
            if cam.is_some() && side.is_some() {
                return Err(invalid(field("side"), "a cam has no side".into()));
            }
            let profiles = match (f.profile.as_str(), side) {
                ("cam", _) => Vec::new(),
                ("compression", None | Some("both")) => {
                    vec![Profile::Compression(Side::Plus), Profile::Compression(Side::Minus)]
                }
                ("compression", Some("+")) => vec![Profile::Compression(Side::Plus)],
                ("compression", Some("-")) => vec![Profile::Compression(Side::Minus)],
                ("compression", Some(s)) => {
                    return Err(invalid(field("side"), format!("must be \"+\", \"-\" or \"both\", got \"{s}\"")));
                }
                (p, None) => vec![Profile::parse(p, "").map_err(|e| invalid(field("profile"), e))?],
                (p, Some(_)) => {
                    let e =
                        Profile::parse(p, "").err().unwrap_or_else(|| "only compression springs have a side".into());
                    return Err(invalid(field(if e.contains("unknown profile") { "profile" } else { "side" }), e));
                }
            };
            if let Some(u) = &f.unit {
                let (expected, name) = profiles.first().map_or(("J", "cam"), |p| (p.unit(), p.name()));
                if normalise_unit(u) != normalise_unit(expected) {
                    return Err(invalid(
                        field("unit"),
                        format!("a {name} element's stiffness is in {expected}, not {u}"),
                    ));
                }
            }
            let couplings = match &f.couplings {
                CouplingSpec::Joints => {
                    (0..dof).map(|j| (0..dof).map(|k| if j == k { 1.0 } else { 0.0 }).collect()).collect()
                }
                CouplingSpec::Pairs(ratios) | CouplingSpec::AllPairs(ratios) => {
                    if dof < 2 {
                        return Err(invalid(field("couplings"), "pairs need at least two joints".into()));
                    }
                    let all = matches!(f.couplings, CouplingSpec::AllPairs(_));
                    let mut out = Vec::new();
                    for (k, r) in ratios.iter().enumerate() {
                        if !(r[0].is_finite() && r[1].is_finite()) || r[0] == 0.0 || r[1] == 0.0 {
                            let key = if all { "all_pairs" } else { "pairs" };
                            return Err(invalid(
                                format!("family[{i}].couplings.{key}[{k}]"),
                                "both gear ratios must be finite and non-zero".into(),
                            ));
                        }
                        for j in 0..dof - 1 {
                            let last = if all { dof - 1 } else { j + 1 };
                            for l in j + 1..=last {
                                let mut a = vec![0.0; dof];
                                a[j] = r[0];
                                a[l] = r[1];
                                out.push(a);
                            }
                        }
                    }
                    out
                }
                CouplingSpec::List(list) => {
                    for (k, a) in list.iter().enumerate() {
                        let fld = format!("family[{i}].couplings[{k}]");
                        if a.len() != dof {
                            return Err(invalid(
                                fld,
                                format!("has {} entries but the robot has {dof} joints", a.len()),
                            ));
                        }
                        if a.iter().any(|x| !x.is_finite()) {
                            return Err(invalid(fld, "entries must be finite".into()));
                        }
                        if a.iter().all(|x| *x == 0.0) {
                            return Err(invalid(fld, "a coupling of all zeros moves nothing".into()));
                        }
                    }
                    list.clone()
                }
            };
            if couplings.is_empty() {
                return Err(invalid(field("couplings"), "lists no coupling".into()));
            }
            let offset_spec = match (&f.offsets, &cam) {
                (Some(_), Some(_)) => {
                    return Err(invalid(
                        field("offsets"),
                        "a cam's knots follow the region: it takes no offsets".into(),
                    ));
                }
                (None, None) => {
                    return Err(invalid(field("offsets"), "missing: every spring family needs offsets".into()));
                }
                (Some(o), None) => o.clone(),
                (None, Some(_)) => OffsetSpec::Equilibrium,
            };
            let offsets = match &offset_spec {
                _ if cam.is_some() => 1,
                OffsetSpec::Grid { count, .. } if *count < 1 || *count > MAX_OFFSETS => {
                    return Err(invalid(
                        field("offsets"),
                        format!("grid must have 1 to {MAX_OFFSETS} points, got {count}"),
                    ));
                }
                OffsetSpec::Phases { count } if *count < 1 || *count > MAX_OFFSETS => {
                    return Err(invalid(
                        field("offsets"),
                        format!("phases must be 1 to {MAX_OFFSETS} per turn, got {count}"),
                    ));
                }
                OffsetSpec::List(l) if l.is_empty() => {
                    return Err(invalid(field("offsets"), "the list is empty".into()));
                }
                OffsetSpec::Equilibrium => 1,
                OffsetSpec::Grid { count, equilibrium } => count + usize::from(*equilibrium),
                OffsetSpec::Phases { count } => *count,
                OffsetSpec::List(l) => l.len(),
            };
            // Each coupling × offset × side is one candidate (a column of the fit): bound the total
            // before `expand` builds them.
            candidates = couplings
                .len()
                .checked_mul(offsets)
                .and_then(|c| c.checked_mul(cam.map_or(profiles.len(), |c| 2 * (usize::from(c.knots) + 2))))
                .and_then(|c| c.checked_add(candidates))
                .filter(|c| *c <= MAX_CANDIDATES)
                .ok_or_else(|| {
                    invalid(
                        format!("family[{i}]"),
                        format!(
                            "the catalogue expands into more than {MAX_CANDIDATES} candidate elements for a robot with \
                             {dof} joints: list fewer couplings or offsets"
                        ),
                    )
                })?;
            if let Some(k) = f.max_stiffness {
                if !(k.is_finite() && k > 0.0) {
                    return Err(invalid(field("max_stiffness"), format!("must be positive, got {k}")));
                }
            }
            let mut rates = f.stock_rates.clone();
            for (k, r) in rates.iter().enumerate() {
                if !(r.is_finite() && *r > 0.0) {
                    return Err(invalid(format!("family[{i}].stock_rates[{k}]"), format!("must be positive, got {r}")));
                }
            }
            rates.sort_by(f64::total_cmp);
            rates.dedup();
            if !(f.tolerance.is_finite() && (0.0..1.0).contains(&f.tolerance)) {
                return Err(invalid(field("tolerance"), format!("must be a fraction in [0, 1), got {}", f.tolerance)));
            }
            if f.name.trim().is_empty() {
                return Err(invalid(field("name"), "must not be empty".into()));
            }
            let adjust_range = match (f.adjustable, f.adjust_range) {
                (false, None) => None,
                (true, Some(r)) if r.is_finite() && r > 0.0 && r <= std::f64::consts::PI => Some(r),
                (true, Some(r)) => {
                    return Err(invalid(field("adjust_range"), format!("must be in (0, π] rad, got {r}")));
                }
                (true, None) => {
                    return Err(invalid(
                        field("adjust_range"),
                        "an adjustable family needs adjust_range (± rad the offset can be moved)".into(),
                    ));
                }
                (false, Some(_)) => {
                    return Err(invalid(field("adjust_range"), "is only meaningful with adjustable = true".into()));
                }
            };
            let trim_range = match (f.trim, f.trim_range) {
                (false, None) => None,
                (false, Some(_)) => {
                    return Err(invalid(field("trim_range"), "is only meaningful with trim = true".into()));
                }
                (true, None) => {
                    return Err(invalid(
                        field("trim_range"),
                        "a trim family needs trim_range = [lo, hi] (N·m/rad the rate can be set to)".into(),
                    ));
                }
                (true, Some([lo, hi])) => {
                    if !(lo.is_finite() && hi.is_finite() && lo >= 0.0 && hi > lo) {
                        return Err(invalid(
                            field("trim_range"),
                            format!("must be [lo, hi] with 0 ≤ lo < hi N·m/rad, got [{lo}, {hi}]"),
                        ));
                    }
                    if profiles != [Profile::Linear] {
                        return Err(invalid(field("profile"), "trim springs are linear".into()));
                    }
                    if !matches!(f.offsets, Some(OffsetSpec::Equilibrium)) {
                        return Err(invalid(
                            field("offsets"),
                            "trim springs are relaxed at the equilibrium: offsets = \"equilibrium\"".into(),
                        ));
                    }
                    if adjust_range.is_some() {
                        return Err(invalid(
                            field("adjustable"),
                            "a trim spring is re-relaxed when it is set; it takes no adjust_range".into(),
                        ));
                    }
                    if f.max_stiffness.is_some() || !f.stock_rates.is_empty() {
                        return Err(invalid(
                            field("trim_range"),
                            "a trim family's rates are its trim_range (no max_stiffness or stock_rates)".into(),
                        ));
                    }
                    Some([lo, hi])
                }
            };
            if trim_range.is_some() {
                trims += couplings.len();
                if trims > crate::elements::catalog::MAX_TRIMS {
                    return Err(invalid(
                        field("couplings"),
                        format!("the catalogue lists more than {} trim springs", crate::elements::catalog::MAX_TRIMS),
                    ));
                }
            }
            families.push(Family {
                name: f.name.clone(),
                profiles,
                couplings,
                offsets: offset_spec,
                max_stiffness: f.max_stiffness,
                stock_rates: rates,
                tolerance: f.tolerance,
                cam,
                adjust_range,
                trim_range,
            });
        }
        let name = file.name.clone().unwrap_or_else(|| {
            path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "catalog".into())
        });
        Ok(Catalog { path: path.to_path_buf(), name, families })
    }

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
}

/// Whether a new offset `b` repeats a kept offset `a` (of the same profile and coupling).
fn same_offset(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * (1.0 + a.abs())
}

/// The cam keys of a family: validated for `profile = "cam"`, refused for any other profile.
fn cam_spec(path: &Path, f: &FamilySpec, field: &dyn Fn(&str) -> String) -> Result<Option<CamSpec>> {
    let invalid = |name: &str, reason: String| Error::invalid(path, field(name), reason);
    let keys: [(&str, bool); 8] = [
        ("knots", f.knots.is_some()),
        ("smoothing", f.smoothing.is_some()),
        ("margin", f.margin.is_some()),
        ("follower_rate", f.follower_rate.is_some()),
        ("max_stroke", f.max_stroke.is_some()),
        ("base_radius", f.base_radius.is_some()),
        ("roller_radius", f.roller_radius.is_some()),
        ("max_pressure_angle", f.max_pressure_angle.is_some()),
    ];
    if f.profile != "cam" {
        if let Some((k, _)) = keys.iter().find(|(_, set)| *set) {
            return Err(invalid(k, format!("only cams (profile = \"cam\") take `{k}`")));
        }
        return Ok(None);
    }
    let knots = f.knots.unwrap_or(30);
    if !(4..=MAX_KNOTS).contains(&knots) {
        return Err(invalid("knots", format!("must be 4 to {MAX_KNOTS}, got {knots}")));
    }
    let positive = |name: &str, v: Option<f64>, default: f64| -> Result<f64> {
        let x = v.unwrap_or(default);
        if x.is_finite() && x > 0.0 { Ok(x) } else { Err(invalid(name, format!("must be positive, got {x}"))) }
    };
    let margin = f.margin.unwrap_or(0.05);
    if !(margin.is_finite() && (0.0..=1.0).contains(&margin)) {
        return Err(invalid("margin", format!("must be a fraction in [0, 1], got {margin}")));
    }
    let follower_rate = match f.follower_rate {
        Some(r) => Some(positive("follower_rate", Some(r), 1.0)?),
        None => None,
    };
    let angle = positive("max_pressure_angle", f.max_pressure_angle, 30.0)?;
    if angle >= 90.0 {
        return Err(invalid("max_pressure_angle", format!("must be below 90°, got {angle}")));
    }
    Ok(Some(CamSpec {
        knots: knots as u16,
        smoothing: f.smoothing.unwrap_or(Smoothing::Auto),
        margin,
        follower_rate,
        max_stroke: positive("max_stroke", f.max_stroke, 20.0)?,
        base_radius: positive("base_radius", f.base_radius, 40.0)?,
        roller_radius: positive("roller_radius", f.roller_radius, 8.0)?,
        max_pressure_angle: angle,
    }))
}

fn normalise_unit(u: &str) -> String {
    u.chars()
        .filter(|c| !c.is_whitespace())
        .map(|c| match c {
            '·' | '⋅' => '*',
            '³' => '3',
            c => c,
        })
        .collect::<String>()
        .replace("^", "")
        .to_lowercase()
}

#[cfg(test)]
mod tests {
    use super::*;

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

    /// Inputs run through the fuzz target fuzz/fuzz_targets/catalog.rs by hand: a phase count
    /// of zero expanded into nothing, a huge one into an allocation of terabytes, and many
    /// couplings times a fine grid into a million candidates deduplicated in quadratic time.
    #[test]
    fn offset_counts_and_candidate_totals_are_bounded() {
        let family = |couplings: &str, offsets: &str| {
            format!("[[family]]\nname = \"x\"\nprofile = \"crank\"\ncouplings = {couplings}\noffsets = {offsets}\n")
        };
        let many: Vec<String> = (1..=300).map(|r| format!("[1, {r}]")).collect();
        let many = format!("{{ all_pairs = [{}] }}", many.join(", "));
        let cases = [
            (family("\"joints\"", "{ phases = 0 }"), "family[0].offsets", "phases must be 1 to 1000"),
            (family("\"joints\"", "{ phases = 100000000000 }"), "family[0].offsets", "phases must be 1 to 1000"),
            (family("\"joints\"", "{ grid = 18446744073709551615 }"), "family[0].offsets", "grid must have 1 to 1000"),
            (family(&many, "{ grid = 1000 }"), "family[0]", "more than 20000 candidate elements"),
            (
                family("\"joints\"", "{ grid = 1000, equilibrium = true }").repeat(8),
                "family[6]",
                "more than 20000 candidate elements",
            ),
        ];
        for (text, field, reason) in cases {
            let err = load(&text, 3).unwrap_err().to_string();
            assert!(err.contains(field) && err.contains(reason), "expected {field} / {reason} in {err}");
        }
        // Just under the bound: expands, and the repeated families add nothing.
        let text = family("\"joints\"", "{ grid = 1000 }").repeat(6);
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
