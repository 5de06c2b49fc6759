//! Settings of the fit: the design's `[fit]` section.

use serde::{Deserialize, Serialize};

use crate::design::tolerance::{Distribution, ToleranceSpec, TrimRule};

/// Growth per joint beyond the second of the default training and held-out counts: doubled.
/// Measured on `ur5_pan_lift_elbow` (three joints, 16 springs): 108 training and 540 held-out
/// directions (3/2 per joint) reach p99 0.366°, their double 0.137°; 144 / 720 (doubling) reach
/// 0.13735° and their double 0.13732°.
const FAN_GROWTH: (usize, usize) = (2, 1);

/// The default counts stop growing at this many joints: 576 training and 2880 held-out
/// directions from five joints on. Measured on planar chains of four to seven links (ball
/// r = 0.15, the n-joint catalogue, 2880 held-out directions from five links on): doubling the
/// training directions from the default moves the held-out p99 by 6.2 % (n = 4), 4.7 % (5),
/// 5.0 % (6) and 2.7 % (7), while each doubling doubles the rows, their memory and the assembly.
/// Past a few hundred directions the error is the element class's, not the gaps between samples.
const FAN_GROWTH_UNTIL: usize = 5;

/// Which solver computes the stiffnesses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SolverKind {
    /// Lawson–Hanson non-negative least squares; equalities by heavy weighting.
    Nnls,
    /// Clarabel quadratic program; equalities, bounds and monotonicity exact.
    Qp,
}

impl SolverKind {
    /// The name used in files.
    pub fn name(self) -> &'static str {
        match self {
            SolverKind::Nnls => "nnls",
            SolverKind::Qp => "qp",
        }
    }
}

/// `[fit]`: how stiffnesses are fitted and evaluated.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FitSettings {
    /// Small-oscillation frequency ω in rad/s: the potential is normalised so that
    /// tr(M(q_eq)⁻¹∇²U(q_eq)) = n ω² (and ∇²U(q_eq) = ω² M(q_eq) with `hessian_match`).
    pub frequency: f64,
    /// `nnls` or `qp`.
    pub solver: SolverKind,
    /// Training geodesics (equally spaced directions on the metric unit circle, or a
    /// low-discrepancy set on the sphere for three or more joints); 0: chosen from the number of
    /// joints, [`FitSettings::training_count`].
    pub training_directions: usize,
    /// Samples per training geodesic, evenly spaced in arc length out to the region's boundary.
    pub training_samples: usize,
    /// Held-out evaluation geodesics, in directions between the training ones; 0: chosen from
    /// the number of joints, [`FitSettings::evaluation_count`].
    pub evaluation_directions: usize,
    /// Samples per evaluation geodesic.
    pub evaluation_samples: usize,
    /// Require ∇²U(q_eq) = ω² M(q_eq) (exactly with `qp`, by weighting with `nnls`).
    pub hessian_match: bool,
    /// Require ∂U/∂q·γ̇ ≥ 0 on the training samples (needs `qp`).
    pub monotone: bool,
    /// Use at most this many elements (0: no limit).
    pub max_elements: usize,
    /// L1 weight λ on Σ k in units of the scaled problem (0: none). Promotes sparsity
    /// without a hard limit.
    pub l1: f64,
    /// Weight of the equalities relative to the tangentiality rows with `nnls` and inside the
    /// sparse selection (which refits thousands of subsets with NNLS).
    pub equality_weight: f64,
    /// Most passes of exchange moves in the sparse selection.
    pub swap_passes: usize,
    /// Random restarts of the sparse selection's local search: steps of iterated local search in
    /// 8 chains, each replacing 1 to ⌈K/2⌉ elements of its chain's best support at random (seeded
    /// by `seed`). 0 with `pair_swaps = false` is the single exchange search of springfit before
    /// restarts. `"auto"`: chosen by the fit job.
    #[serde(deserialize_with = "restarts_or_auto")]
    pub restarts: usize,
    /// Try 2-for-2 swaps in the sparse selection when no single exchange improves.
    pub pair_swaps: bool,
    /// An element counts as used when its peak torque over the region exceeds this fraction of
    /// the largest element's peak torque. An unlimited `qp` fit without cams whose bill, so
    /// thinned, would miss its equalities lists every element of k > 0 instead (`fit::run`).
    pub used_threshold: f64,
    /// Distance bands from q_eq for the residual statistics.
    pub bands: usize,
    /// The rate tolerance to design for and to judge builds at: `"none"` (the drawing only),
    /// `"catalogue"` (each family's `tolerance`) or a ± fraction for every element.
    pub tolerance: ToleranceSpec,
    /// How build deviations are drawn: `uniform` in ±t or `normal` with σ = t/3 clipped at ±t.
    pub distribution: Distribution,
    /// Monte Carlo builds behind the as-built figures (0: none). 1,000 by default: the p95 over
    /// builds is then known to about ±0.05° on the default design (200 left it ±0.1–0.3°).
    pub builds: usize,
    /// Seed of the as-built builds and of the selection's restarts (each build and each restart
    /// has its own stream, so results do not depend on the thread count).
    pub seed: u64,
    /// Verdict threshold, degrees: a fit whose p99 residual angle on the held-out geodesics is at
    /// most this is "acceptable", above it "poor" (printed and in summary.json).
    pub accept_p99_deg: f64,
    /// With a tolerance: weight λ of the expected spread of the builds, ‖A k − b‖² + λ Σ Dᵢᵢ kᵢ²
    /// (1: the expected residual over builds; less trades as-built accuracy for nominal
    /// accuracy). `"auto"`: chosen by the fit job ([`AutoWeights`]). A design file that leaves
    /// it out while its catalogue has trim springs gets [`FitSettings::TRIMMED_TOLERANCE_WEIGHT`]
    /// ([`FitSettings::with_trim_defaults`]).
    #[serde(deserialize_with = "tolerance_weight_or_auto")]
    pub tolerance_weight: f64,
    /// With a tolerance and trim springs in the catalogue: weight of the expected spread of the
    /// *trimmed* builds (each build's trims re-relaxed at its equilibrium and re-set by
    /// `trim_rule`), added to `tolerance_weight`'s untrimmed term. 0: off. `"auto"`: chosen by
    /// the fit job.
    #[serde(deserialize_with = "trimmed_weight_or_auto")]
    pub trimmed_weight: f64,
    /// What each build's trims are set for (the as-built figures, `sweep` and `tune`):
    /// `"residual"` (default: the least-squares residual of a training fan from the build's
    /// equilibrium) or `"hessian"` (∇²U = w² M at that equilibrium). The trim-aware fit models the
    /// same rule.
    pub trim_rule: TrimRule,
    /// With a tolerance: weight w of the expected equilibrium shift, w · m · E‖Δq‖²_M(q_eq) added
    /// to the expected residual (m training rows; a metric shift of 1 costs as much as a residual
    /// of 1 ≈ sin(angle) on every row). 0: off (tuning after the build can restore q_eq).
    pub shift_weight: f64,
    /// With a tolerance: a bound on the builds' RMS metric equilibrium shift √E‖Δq‖²_M(q_eq) at
    /// the design's tolerance, held by the QP as a second-order cone (`fit::robust`,
    /// [`MaxShift`]): a build whose rest position moves far loses its stable equilibrium or
    /// judges the whole region from the wrong point. Off by default (`"none"`): where it acted
    /// on an arm measured, the cone's interior-point answer spread the stiffness over most of
    /// the catalogue and the builds got worse ([`MaxShift::DEFAULT_FRACTION`]). `"default"`
    /// bounds it at that fraction of the region's extent, a number at that shift.
    #[serde(deserialize_with = "max_shift_or_none")]
    pub max_shift: MaxShift,
    /// Upper bound on the total preload Σ|τᵢ(q_eq)| in N·m (0: none). Exact with `qp`; with
    /// `nnls` a fit exceeding it is reported infeasible.
    pub max_preload: f64,
    /// Upper bound on each spring's largest torque on its coordinate over the region, N·m (0:
    /// none): its stiffness is capped at this torque over its largest |u′|. The bound that keeps
    /// a part possible when `springfit parts` finds no spring for an element.
    pub max_element_torque: f64,
    /// Weight of the springs' mass in the objective (0: none; default
    /// [`FitSettings::DEFAULT_MASS_WEIGHT`]): a bill of the floor's mass (the least steel that
    /// stores U* = ½ω²r², docs/parts.md) costs this many times a residual of 1° on every training
    /// row, so one weight means the same on every arm, gravity or none (`fit::mass`). `"auto"`:
    /// chosen by the fit job.
    #[serde(deserialize_with = "mass_weight_or_auto")]
    pub mass_weight: f64,
    /// Upper bound on the springs' mass Σ mᵢ(kᵢ) in kg by the part chooser's mass curves (0:
    /// none), met by raising the mass weight with the selection redone at each weight, so that
    /// the selection honours it (`fit::mass`). Below the floor it is refused before any work.
    pub max_spring_mass: f64,
    /// Most candidate fits the automatic choice of the weights may run (each a solve on the
    /// one preparation, its parts and its as-built builds): a count, not seconds, so the choice
    /// is the same on any machine and thread count. Default 8.
    pub auto_budget: usize,
    /// What the design needs of its drawing: an aim on the nominal p99 residual angle on the
    /// held-out fan, degrees (0, the default: none). With any aim stated, the automatic choice
    /// takes the lightest candidate that meets every aim ([`crate::fit::auto`]), and the
    /// weights the design leaves out are chosen ([`AutoWeights::of_table`]).
    pub aim_p99_deg: f64,
    /// An aim on the p95 over the builds of the untrimmed builds' p99, degrees (0: none): see
    /// `aim_p99_deg`.
    pub aim_untrimmed_p95_deg: f64,
    /// An aim on the p95 over the builds of the trimmed builds' p99 (with cams and no trims,
    /// the builds with the followers' preloads re-set), degrees (0: none): see `aim_p99_deg`.
    pub aim_trimmed_p95_deg: f64,
    /// Most fits on the arm carrying its parts (0, the default: none): after the parts are
    /// chosen, their masses on moving links ([`crate::realise::placement`]) are added to the
    /// arm's links, the metric rebuilt and the design fitted again, until the springs' mass
    /// changes by less than 1 % or this many rounds. Off by default: each round is a whole fit
    /// (the geodesics, the solve, the parts), and on the shipped designs the parts on moving links
    /// move the bill little (docs/parts.md, "Where the parts sit").
    pub placement_rounds: usize,
    /// Which of the weights the design left to the fit job (`"auto"`): set from the
    /// file by [`crate::design::Design::parse`]; none in [`FitSettings::default`], so a fit
    /// called from code runs with exactly the numbers it is given.
    #[serde(skip)]
    pub auto: AutoWeights,
}

/// The `[fit]` weights a design may leave to springfit: the keys it sets to `"auto"`.
/// The fit job ([`crate::jobs::fit`]) then chooses them by measured figures
/// ([`crate::fit::auto`]); every other caller uses the numbers in [`FitSettings`] (the
/// defaults, or the choice a fit job made).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct AutoWeights {
    /// `tolerance_weight` is chosen.
    pub tolerance_weight: bool,
    /// `trimmed_weight` is chosen.
    pub trimmed_weight: bool,
    /// `mass_weight` is chosen.
    pub mass_weight: bool,
    /// `restarts` is chosen.
    pub restarts: bool,
}

impl AutoWeights {
    /// The keys the `[fit]` table of a design file (None: no `[fit]` table) sets to `"auto"`.
    /// When the table states an aim (`aim_p99_deg`, `aim_untrimmed_p95_deg` or
    /// `aim_trimmed_p95_deg` above 0), `tolerance_weight`, `trimmed_weight` and `restarts` left
    /// out are chosen too: the design has said what it needs, and the weights are how springfit
    /// gets there. Without an aim a key left out keeps its default number
    /// ([`FitSettings::default`]), so the designs written before the choice existed fit as they
    /// did. `mass_weight` left out keeps its default either way.
    pub fn of_table(fit: Option<&toml::Table>) -> AutoWeights {
        let value = |key: &str| fit.and_then(|t| t.get(key));
        let auto = |key: &str| value(key).is_some_and(|v| v.as_str() == Some("auto"));
        let aims = ["aim_p99_deg", "aim_untrimmed_p95_deg", "aim_trimmed_p95_deg"].iter().any(|k| {
            value(k).and_then(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64))).is_some_and(|x| x > 0.0)
        });
        let chosen = |key: &str| auto(key) || (aims && value(key).is_none());
        AutoWeights {
            tolerance_weight: chosen("tolerance_weight"),
            trimmed_weight: chosen("trimmed_weight"),
            mass_weight: auto("mass_weight"),
            restarts: chosen("restarts"),
        }
    }

    /// Whether any weight is left to springfit.
    pub fn any(self) -> bool {
        self.tolerance_weight || self.trimmed_weight || self.mass_weight || self.restarts
    }
}

/// `[fit] max_shift`: the bound on the builds' RMS metric equilibrium shift (rad·√(kg·m²), the
/// unit of the region's radius).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MaxShift {
    /// [`MaxShift::DEFAULT_FRACTION`] of the region's extent (`"default"`).
    Default,
    /// No bound (`"none"`, the default).
    None,
    /// This RMS metric shift.
    Metric(f64),
}

impl MaxShift {
    /// The default bound as a fraction of the region's extent r: a guard against builds whose
    /// rest position moves by a tenth of the region they are judged over (RMS, first order).
    /// Measured at ±5 % (1,000 builds): `double_pendulum`, `double_pendulum_cams` and
    /// `double_pendulum_trim` stay below 5 % of r and keep their bills; at 5 % the bound acted on
    /// `panda_three` and `ur10_lift_elbow_wrist` given `tolerance = 0.05` (first-order shift
    /// 8.7 % → 5 % of r, and 6.9 % → 5 %) and cost accuracy there for nothing (drawn p99
    /// 1.60° → 2.28° and 0.43° → 0.52°, as built p95 11.2° → 12.1° and 3.89° → 4.00°; no
    /// build lost its equilibrium either way).
    /// The planar three-link arm of `springfit init` whose builds do lose it (19 of 1,000) has a
    /// first-order shift of only 1.6 % of r: those builds fail beyond first order. Holding it
    /// at 1.1 % of r made it worse (188 of 1,000 builds without an equilibrium; the cone's
    /// interior-point answer spreads the stiffness over 377 of 387 candidates), and 0.6 % is
    /// infeasible. On the Unitree Z1 from `springfit init` (radius 0.12, `tolerance = 0.05`)
    /// the bound acted (shift 20 % of r held at 10 %) and the fit spread over 308 springs whose
    /// preloads cancel: realised p99 9.09°, 41.9 kg of springs, 589 of 1,000 builds without an
    /// equilibrium, against 144 springs, 0.27°, 4.8 kg and 50 without the bound. So the bound
    /// is off unless a design asks for it (`"default"` or a number).
    pub const DEFAULT_FRACTION: f64 = 0.10;

    /// The bound for a region of extent `extent`; None when off.
    pub fn bound(self, extent: f64) -> Option<f64> {
        match self {
            MaxShift::Default => Some(MaxShift::DEFAULT_FRACTION * extent),
            MaxShift::None => None,
            MaxShift::Metric(s) => Some(s),
        }
    }
}

fn max_shift_or_none<'de, D: serde::Deserializer<'de>>(d: D) -> Result<MaxShift, D::Error> {
    match NumberOrAuto::<f64>::deserialize(d)? {
        NumberOrAuto::Number(x) => Ok(MaxShift::Metric(x)),
        NumberOrAuto::Word(w) if w == "none" => Ok(MaxShift::None),
        NumberOrAuto::Word(w) if w == "default" => Ok(MaxShift::Default),
        NumberOrAuto::Word(w) => {
            Err(serde::de::Error::custom(format!("\"{w}\": expected a positive metric shift, \"default\" or \"none\"")))
        }
    }
}

/// A number, or the word `"auto"` (the default's value stands in until the fit job chooses).
#[derive(Deserialize)]
#[serde(untagged)]
enum NumberOrAuto<T> {
    Number(T),
    Word(String),
}

fn number_or_auto<'de, D: serde::Deserializer<'de>, T: serde::Deserialize<'de>>(
    d: D,
    default: T,
) -> Result<T, D::Error> {
    match NumberOrAuto::<T>::deserialize(d)? {
        NumberOrAuto::Number(x) => Ok(x),
        NumberOrAuto::Word(w) if w == "auto" => Ok(default),
        NumberOrAuto::Word(w) => Err(serde::de::Error::custom(format!("\"{w}\": expected a number or \"auto\""))),
    }
}

fn tolerance_weight_or_auto<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    number_or_auto(d, FitSettings::default().tolerance_weight)
}

fn trimmed_weight_or_auto<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    number_or_auto(d, FitSettings::default().trimmed_weight)
}

fn mass_weight_or_auto<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    number_or_auto(d, FitSettings::default().mass_weight)
}

fn restarts_or_auto<'de, D: serde::Deserializer<'de>>(d: D) -> Result<usize, D::Error> {
    number_or_auto(d, FitSettings::default().restarts)
}

/// Whether a design file sets `tolerance_weight` (a number or `"auto"`), whose default depends on
/// the catalogue: see [`FitSettings::with_trim_defaults`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GivenWeights {
    /// The file sets `tolerance_weight`.
    pub tolerance_weight: bool,
}

impl GivenWeights {
    /// The keys the `[fit]` table of a design file (None: no `[fit]` table) sets.
    pub fn of_table(fit: Option<&toml::Table>) -> GivenWeights {
        GivenWeights { tolerance_weight: fit.is_some_and(|t| t.contains_key("tolerance_weight")) }
    }
}

impl FitSettings {
    /// `tolerance_weight` of a design with a tolerance and trim springs in its catalogue that
    /// leaves the key out: 0. Every build is trimmed, so the untrimmed builds' spread is the
    /// wrong thing to pay for: it spends the drawing on Hessian errors the trims remove (the
    /// weight `springfit init` wrote into every design until it became this default). Measured
    /// (`springfit --threads 1 fit`, 1,000 builds at ±5 %): `panda_three` p99 0.949° drawn,
    /// trimmed p95 2.038°; `ur10_lift_elbow_wrist` 0.278°, 1.435°. `trimmed_weight` keeps its
    /// default 0: at 1 (the expected residual of trimmed builds) the trimmed p95 fell to 1.726°
    /// and 1.077° but the drawing rose to 1.315° and 0.699° (docs/designs.md).
    pub const TRIMMED_TOLERANCE_WEIGHT: f64 = 0.0;

    /// These settings with the default of a design whose catalogue has trim springs (`trims`)
    /// and that designs for a tolerance: a `tolerance_weight` the file leaves out (`given`)
    /// is [`FitSettings::TRIMMED_TOLERANCE_WEIGHT`]. Without trims, with
    /// `tolerance = "none"`, or with the key set, the settings are returned as they are.
    pub fn with_trim_defaults(self, given: GivenWeights, trims: bool) -> FitSettings {
        if !trims || self.tolerance == ToleranceSpec::None || given.tolerance_weight {
            return self;
        }
        FitSettings { tolerance_weight: Self::TRIMMED_TOLERANCE_WEIGHT, ..self }
    }
}

impl Default for FitSettings {
    fn default() -> Self {
        FitSettings {
            frequency: 1.0,
            solver: SolverKind::Qp,
            training_directions: 0,
            training_samples: 40,
            evaluation_directions: 0,
            evaluation_samples: 100,
            hessian_match: true,
            monotone: false,
            max_elements: 0,
            l1: 0.0,
            equality_weight: 30.0,
            swap_passes: 50,
            restarts: 128,
            pair_swaps: true,
            used_threshold: 1e-6,
            bands: 4,
            tolerance: ToleranceSpec::None,
            distribution: Distribution::Uniform,
            builds: 1000,
            seed: 1,
            accept_p99_deg: 2.0,
            tolerance_weight: 1.0,
            trimmed_weight: 0.0,
            trim_rule: TrimRule::Residual,
            shift_weight: 0.0,
            max_shift: MaxShift::None,
            max_preload: 0.0,
            max_element_torque: 0.0,
            mass_weight: FitSettings::DEFAULT_MASS_WEIGHT,
            max_spring_mass: 0.0,
            auto_budget: 8,
            aim_p99_deg: 0.0,
            aim_untrimmed_p95_deg: 0.0,
            aim_trimmed_p95_deg: 0.0,
            placement_rounds: 0,
            auto: AutoWeights::default(),
        }
    }
}

impl FitSettings {
    /// The default `[fit] mass_weight`: a little weight on the springs' mass, so that an arm
    /// nobody tuned gets a bill it can carry. Without it the fit minimises the ideal springs'
    /// residual alone and buys it with springs whose preloads cancel at q_eq, which their parts
    /// do not keep: on a random three-joint arm (`random_arm.py --seed 57`) the unweighted fit
    /// gave 148 springs of 7.10 kg, 1.18× the arm, at a realised p99 of 1.508° (drawn 0.331°);
    /// at 0.001, 88 springs of 2.40 kg at 0.957° (drawn 0.900°), in 31 s of CPU instead of 69.
    /// On `panda_three` and `ur10_lift_elbow_wrist` as `springfit init` writes them the springs
    /// come out at 0.21× and 0.13× the arm's moving mass with p99 under 1°, drawn and realised,
    /// and no build of 1,000 without an equilibrium. Designs whose figures were measured without
    /// a weight set `mass_weight = 0.0` (docs/designs.md).
    pub const DEFAULT_MASS_WEIGHT: f64 = 0.001;

    /// The training geodesics of an arm of `n` joints: `training_directions`, or when it is 0
    /// 72 doubled for every joint beyond the second up to the fifth (`FAN_GROWTH`,
    /// `FAN_GROWTH_UNTIL`): 72, 144, 288, 576, then 576.
    pub fn training_count(&self, n: usize) -> usize {
        if self.training_directions == 0 {
            crate::geodesic::directions::directions_for_joints(72, n.min(FAN_GROWTH_UNTIL), FAN_GROWTH)
        } else {
            self.training_directions
        }
    }

    /// The held-out geodesics of an arm of `n` joints: `evaluation_directions`, or when it is 0
    /// 360 doubled for every joint beyond the second up to the fifth: 360, 720, 1440, 2880, then
    /// 2880 (five times the training fan throughout).
    pub fn evaluation_count(&self, n: usize) -> usize {
        if self.evaluation_directions == 0 {
            crate::geodesic::directions::directions_for_joints(360, n.min(FAN_GROWTH_UNTIL), FAN_GROWTH)
        } else {
            self.evaluation_directions
        }
    }

    /// Checks the settings, naming the bad field.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let err = |f: &str, r: &str| Err((format!("fit.{f}"), r.to_string()));
        if !(self.frequency.is_finite() && self.frequency > 0.0) {
            return err("frequency", "must be a positive number of rad/s");
        }
        if self.frequency > crate::limits::MAX_FREQUENCY {
            return err(
                "frequency",
                &format!("must be at most {} rad/s (the largest springfit accepts)", crate::limits::MAX_FREQUENCY),
            );
        }
        if self.training_directions != 0 && !(4..=100_000).contains(&self.training_directions) {
            return err("training_directions", "must be 0 (chosen from the number of joints) or 4 to 100000");
        }
        if !(2..=100_000).contains(&self.training_samples) {
            return err("training_samples", "must be 2 to 100000");
        }
        if self.evaluation_directions != 0 && !(4..=100_000).contains(&self.evaluation_directions) {
            return err("evaluation_directions", "must be 0 (chosen from the number of joints) or 4 to 100000");
        }
        if !(2..=100_000).contains(&self.evaluation_samples) {
            return err("evaluation_samples", "must be 2 to 100000");
        }
        if self.training_directions * self.training_samples > 2_000_000 {
            return err(
                "training_samples",
                "training_directions × training_samples must stay below 2·10⁶ (each sample is a row of the fit)",
            );
        }
        if self.evaluation_directions * self.evaluation_samples > 20_000_000 {
            return err("evaluation_samples", "evaluation_directions × evaluation_samples must stay below 2·10⁷");
        }
        if self.swap_passes > 100_000 {
            return err("swap_passes", "must be at most 100000");
        }
        if self.monotone && self.solver == SolverKind::Nnls {
            return err("monotone", "monotonicity constraints need solver = \"qp\" (NNLS handles only k ≥ 0)");
        }
        if !(self.l1.is_finite() && self.l1 >= 0.0) {
            return err("l1", "must be ≥ 0");
        }
        if !(self.equality_weight.is_finite() && self.equality_weight > 0.0) {
            return err("equality_weight", "must be positive");
        }
        if !(self.used_threshold.is_finite() && (0.0..1.0).contains(&self.used_threshold)) {
            return err("used_threshold", "must be a fraction in [0, 1)");
        }
        if self.bands == 0 || self.bands > 100 {
            return err("bands", "must be 1 to 100");
        }
        if let Err(reason) = self.tolerance.validate() {
            return err("tolerance", &reason);
        }
        if self.restarts > 10_000 {
            return err("restarts", "must be at most 10000");
        }
        if !(self.tolerance_weight.is_finite() && self.tolerance_weight >= 0.0) {
            return err("tolerance_weight", "must be ≥ 0");
        }
        if !(self.trimmed_weight.is_finite() && self.trimmed_weight >= 0.0) {
            return err("trimmed_weight", "must be ≥ 0");
        }
        if !(self.shift_weight.is_finite() && self.shift_weight >= 0.0) {
            return err("shift_weight", "must be ≥ 0");
        }
        if let MaxShift::Metric(s) = self.max_shift
            && !(s.is_finite() && s > 0.0)
        {
            return err(
                "max_shift",
                "must be a positive RMS metric shift (rad·√(kg·m²), the unit of the region's radius) or \"none\"",
            );
        }
        if !(self.max_preload.is_finite() && self.max_preload >= 0.0) {
            return err("max_preload", "must be ≥ 0 N·m (0: no bound)");
        }
        if !(self.max_element_torque.is_finite() && self.max_element_torque >= 0.0) {
            return err("max_element_torque", "must be ≥ 0 N·m (0: no bound)");
        }
        if !(self.mass_weight.is_finite() && self.mass_weight >= 0.0) {
            return err("mass_weight", "must be ≥ 0 (0: the mass is not weighed)");
        }
        if !(self.max_spring_mass.is_finite() && self.max_spring_mass >= 0.0) {
            return err("max_spring_mass", "must be ≥ 0 kg (0: no bound)");
        }
        if self.placement_rounds > 3 {
            return err("placement_rounds", "must be 0 to 3 fits on the arm carrying its parts (0: none)");
        }
        if !(1..=64).contains(&self.auto_budget) {
            return err("auto_budget", "must be 1 to 64 candidate fits");
        }
        for (field, aim) in [
            ("aim_p99_deg", self.aim_p99_deg),
            ("aim_untrimmed_p95_deg", self.aim_untrimmed_p95_deg),
            ("aim_trimmed_p95_deg", self.aim_trimmed_p95_deg),
        ] {
            if !(aim.is_finite() && (0.0..=180.0).contains(&aim)) {
                return err(field, "must be an angle in degrees from 0 (no aim) to 180");
            }
        }
        if self.builds > 100_000 {
            return err("builds", "must be at most 100000");
        }
        if !(self.accept_p99_deg.is_finite() && self.accept_p99_deg > 0.0 && self.accept_p99_deg <= 180.0) {
            return err("accept_p99_deg", "must be a positive angle in degrees, at most 180");
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_fans_double_per_joint_until_five_joints() {
        let s = FitSettings::default();
        let training: Vec<usize> = (2..=7).map(|n| s.training_count(n)).collect();
        assert_eq!(training, [72, 144, 288, 576, 576, 576]);
        for n in 2..=7 {
            assert_eq!(s.evaluation_count(n), 5 * s.training_count(n));
        }
        let set = FitSettings { training_directions: 1152, evaluation_directions: 999, ..s };
        assert_eq!((set.training_count(6), set.evaluation_count(6)), (1152, 999));
    }
}
