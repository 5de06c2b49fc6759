//! The catalogue file as written: [`CatalogFile`] and its `[[family]]` tables mirror the TOML
//! (`deny_unknown_fields`), with the few values that take more than one form (couplings, offsets,
//! smoothing) read by hand; [`super::Catalog::from_file`] validates and resolves them.

use serde::{Deserialize, Deserializer, Serialize};

use crate::units::Angle;

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
    /// Cams: follower preload at the base circle as a fraction of the largest stroke (default
    /// 0.5; larger makes the preload screw a better trim, see docs/catalogue.md).
    #[serde(default)]
    pub preload_fraction: Option<f64>,
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
    /// Whether the fit job sizes a trim family's range by the bill (`trim_range` is then where
    /// the fit starts; see `asbuilt::sizing`). Default false: the range is the catalogue's.
    #[serde(default)]
    pub trim_sized: bool,
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

/// Where a family can be mounted.
#[derive(Debug, Clone, Serialize)]
pub enum CouplingSpec {
    /// A pattern of gear ratios put on every group of joints of one kind, among the joints `on`
    /// names (every joint of the arm when None), so a catalogue fits an arm of any size.
    Groups {
        /// Which groups of joints.
        kind: GroupKind,
        /// The gear-ratio patterns, one entry per joint of a group (`[1.0]` for single joints).
        ratios: Vec<Vec<f64>>,
        /// Joint names (the arm's, or `q1` … `qn`) the groups are taken among, in any order.
        on: Option<Vec<String>>,
    },
    /// Every run of `length` adjacent joints (among `on`) turned together, a = eᵢ + … + eᵢ₊ₗ₋₁, for
    /// each length listed: on a planar chain the run from the base is the absolute angle of a link
    /// (what gravity acts on) and a run inside the chain the angle between two links that are not
    /// neighbours (what the inertia depends on). Lengths beyond the arm give no run, so one
    /// catalogue serves arms of any size.
    Runs {
        /// Run lengths, each at least 2.
        lengths: Vec<usize>,
        /// Joint names the runs are taken among, as for [`CouplingSpec::Groups`].
        on: Option<Vec<String>>,
    },
    /// Every coupling a tendon over pulleys of the listed radii makes, plus bevel-gear
    /// differentials of neighbouring joints at the gear ratios (see [`TendonSpec`]).
    Tendons(TendonSpec),
    /// Explicit coupling vectors, one entry per joint.
    List(Vec<Vec<f64>>),
}

/// `couplings = { tendons = { radii_mm = [10, 20, 30, 40], max_crossed = 3, bevel = true } }`:
/// the couplings a workshop can build from the pulleys it stocks, expanded at load
/// (`resolve::tendon_couplings`). A tendon crosses a run of 2 to `max_crossed` consecutive
/// joints (a cable passes every joint between its ends), over a pulley of one of `radii_mm` at
/// each, on either side; its coupling is the radii over the largest, so it carries its radii to
/// `parts`. `bevel = true` adds every pair of neighbouring joints at a ratio a bevel-gear pair has.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TendonSpec {
    /// The pulley radii stocked, mm; within the design's `[parts]` pulley limits.
    pub radii_mm: Vec<f64>,
    /// Most joints one tendon crosses (2 to the arm's joints).
    pub max_crossed: usize,
    /// Also the bevel-gear differentials of neighbouring joints at every ratio of
    /// [`super::BEVEL_RATIOS`] (default false).
    #[serde(default)]
    pub bevel: bool,
}

/// The groups of joints a [`CouplingSpec::Groups`] family is put on; "adjacent" is among the
/// joints it is taken among, in the arm's order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum GroupKind {
    /// Every single joint (a = eᵢ).
    Joints,
    /// Every pair of adjacent joints (i, i+1): a = r₁ eᵢ + r₂ eᵢ₊₁.
    Pairs,
    /// Every pair of joints (i < j), adjacent or not.
    AllPairs,
    /// Every triple of adjacent joints (i, i+1, i+2): a = r₁ eᵢ + r₂ eᵢ₊₁ + r₃ eᵢ₊₂.
    Triples,
}

impl GroupKind {
    /// The key that writes it.
    pub fn key(self) -> &'static str {
        match self {
            GroupKind::Joints => "joints",
            GroupKind::Pairs => "pairs",
            GroupKind::AllPairs => "all_pairs",
            GroupKind::Triples => "triples",
        }
    }

    /// Joints in one group.
    pub fn size(self) -> usize {
        match self {
            GroupKind::Joints => 1,
            GroupKind::Pairs | GroupKind::AllPairs => 2,
            GroupKind::Triples => 3,
        }
    }
}

impl<'de> Deserialize<'de> for CouplingSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Table {
            joints: Option<Vec<String>>,
            pairs: Option<Vec<[f64; 2]>>,
            all_pairs: Option<Vec<[f64; 2]>>,
            triples: Option<Vec<[f64; 3]>>,
            runs: Option<Vec<usize>>,
            tendons: Option<TendonSpec>,
            on: Option<Vec<String>>,
        }
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Word(String),
            Table(Table),
            List(Vec<Vec<f64>>),
        }
        let msg = "couplings must be \"joints\", { joints = [\"name\", ...] } (these joints), \
                   { pairs = [[r1, r2], ...] } (adjacent joints), { all_pairs = [[r1, r2], ...] } (every pair), \
                   { triples = [[r1, r2, r3], ...] } (adjacent triples), { runs = [length, ...] } (adjacent \
                   joints turned together), each of the last four optionally with on = [\"name\", ...], \
                   { tendons = { radii_mm = [r, ...], max_crossed = N, bevel = true } } (what tendons over those \
                   pulleys make), or a list of coupling vectors such as [[1, 0], [1, -1]]";
        let bad = || serde::de::Error::custom(msg);
        let wide = |r: Vec<[f64; 2]>| r.into_iter().map(|r| r.to_vec()).collect::<Vec<_>>();
        match Raw::deserialize(d).map_err(|_| bad())? {
            Raw::Word(w) if w == "joints" => {
                Ok(CouplingSpec::Groups { kind: GroupKind::Joints, ratios: vec![vec![1.0]], on: None })
            }
            Raw::Word(_) => Err(bad()),
            Raw::Table(t) => {
                if let Some(spec) = t.tendons {
                    let others = t.joints.is_some() || t.pairs.is_some() || t.all_pairs.is_some();
                    if others || t.triples.is_some() || t.runs.is_some() || t.on.is_some() {
                        return Err(bad());
                    }
                    return Ok(CouplingSpec::Tendons(spec));
                }
                if let Some(lengths) = t.runs {
                    if t.joints.is_some() || t.pairs.is_some() || t.all_pairs.is_some() || t.triples.is_some() {
                        return Err(bad());
                    }
                    return Ok(CouplingSpec::Runs { lengths, on: t.on });
                }
                let (kind, ratios, on) = match (t.joints, t.pairs, t.all_pairs, t.triples, t.on) {
                    (Some(j), None, None, None, None) => (GroupKind::Joints, vec![vec![1.0]], Some(j)),
                    (None, Some(r), None, None, on) => (GroupKind::Pairs, wide(r), on),
                    (None, None, Some(r), None, on) => (GroupKind::AllPairs, wide(r), on),
                    (None, None, None, Some(r), on) => {
                        (GroupKind::Triples, r.into_iter().map(|r| r.to_vec()).collect(), on)
                    }
                    _ => return Err(bad()),
                };
                Ok(CouplingSpec::Groups { kind, ratios, on })
            }
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
    Grid {
        /// N, the grid points (`grid = N`, 1 to 1000; one point: the middle of the range).
        count: usize,
        /// `equilibrium = true`: a·q_eq added to the grid, so the element can also be relaxed at
        /// the equilibrium.
        equilibrium: bool,
    },
    /// `count` phases evenly spaced over one turn starting at the equilibrium:
    /// x₀ = a·q_eq + 2πk/count (for crank mechanisms, whose torque k sin(x − x₀) is periodic).
    Phases {
        /// N, the crank angles round the turn (`phases = N`, 1 to 1000).
        count: usize,
    },
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
