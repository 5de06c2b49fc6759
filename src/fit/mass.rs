//! The springs' mass in the fit: a mass per unit stiffness for every candidate, taken from the
//! part chooser itself, the floor no layout can go below, and the term and budget the solvers
//! see (`[fit] mass_weight`, `[fit] max_spring_mass`).
//!
//! **The model.** For a mechanism of fixed geometry a spring's volume goes with the energy it
//! stores, and the energy goes with its stiffness, so the mass of candidate i's part is close to
//! aᵢ·kᵢ for small parts; bigger ones meet the envelope (lever, diameter, length) and grow faster
//! than their stiffness, so the model is the curve mᵢ(k) = aᵢk + bᵢk². It is read off the parts
//! [`crate::realise::mechanism::spring_element`] chooses over the candidate's own duty (its
//! deflections over the held-out fan, preload included, and the scenarios' swing for fatigue):
//! at a reference stiffness k_ref, at 4·k_ref (2·k_ref where 4× has no part) and at 16·k_ref
//! (8·k_ref), the curve fitted to them in relative terms with aᵢ, bᵢ ≥ 0 (`curve`: a straight
//! line where the larger parts are lighter per unit stiffness). The third read is where the fits
//! go: a curve through k_ref and 4·k_ref alone was extrapolated beyond, and a mass budget's
//! selection found the supports it under-read (`tests/mass_range.rs` measures the model against
//! the parts at k_ref·{¼, 1, 4, 16}). k_ref gives the element a peak torque over the region of a
//! quarter of the potential's boundary torque (2U*/r), the size of the elements real fits choose;
//! where no part exists there, k_ref is halved until one does. The wire comes in discrete sizes
//! and the geometry is searched, so the curve is not exact: `tests/mass.rs` measures how close on
//! the shipped designs (the module's tests state it for the paper's arm). With the straight line
//! alone (bᵢ = 0) the default design's big preloaded cranks weighed 0.58–0.79 of their parts, so
//! a mass weight kept the big cranks and gave up small ones. A candidate no spring realises at any
//! tried stiffness falls back to the floor's density: aᵢ = ρ·eᵢ/u with eᵢ its largest energy per
//! unit stiffness over the region.
//!
//! **Cams and cubic elements** are disc cams on a roller follower's compression springs, and the
//! follower is what weighs. It stores V − min V over a stroke S from a preload p₀ = f·S at the base
//! circle (f the family's `preload_fraction`): the cam's work over its range is ΔV = ½k_f((p₀ + S)²
//! − p₀²) = ½k_f S²(1 + 2f), while the spring, compressed p₀ + S from free at the top, holds
//! ½k_f(p₀ + S)² = ΔV·(1 + f)²/(1 + 2f) (1.8× at f = 2): the preload that keeps contact costs
//! steel. Its mass is therefore read off the part chooser's follower ([`follower`]) at the
//! family's stroke and preload, for a reference range of a quarter of U* (halved until a follower
//! exists), as kg per joule of the cam's range (the fatigue swing from p₀ to p₀ + S, the Goodman
//! line, is in it; ρ(1 + f)²/((1 + 2f)u) is the fallback). A cubic's range over the region is
//! its largest energy, so its charge is that times its energy per unit stiffness. A cam's range
//! is not linear in its coefficients, but it is sub-additive: range(Σⱼ cⱼBⱼ) ≤ Σⱼ |cⱼ|·range(Bⱼ),
//! so each basis column (a ± pair, one non-negative unknown each under NNLS) is charged the
//! follower's kg per joule times its own range over the duty (2/3 for an interior cubic B-spline):
//! exact for one bump, an upper bound for a wide profile, and Σ|cⱼ| under its free constant is
//! what the term lowers (a flatter cam). The QP's signed coefficients would make it |cⱼ|, not
//! linear, so the QP leaves cams uncharged (the cam designs fit with NNLS). `tests/mass.rs`
//! states the ratio to the followers chosen on the cam designs.
//!
//! **The floor.** Any layout stores at least the potential's range, U* = ½ω²r² at the region's
//! boundary, and spring steel stores at most u per unit volume
//! ([`crate::realise::spring::usable_energy_density`]), so no bill weighs less than ρ·U*/u.
//!
//! **In the solvers.** λ·Σ(aᵢkᵢ + bᵢkᵢ²) is a convex quadratic in k: in the Gram form
//! ½kᵀGk − cᵀk every solver works on it moves c to c − λa and adds 2λbᵢ to G's diagonal, so
//! NNLS, the QP and the selection of at most K all minimise the same objective, which stays
//! convex. λ = `mass_weight` · ½m·θ₁² / floor, m the training rows and θ₁ = 1° (in radians): a
//! bill of the floor's mass costs what a residual of 1° on every row would (each row is the sine of
//! its residual angle for the right gradient magnitude, docs/theory.md "Rows and their
//! weighting"). Per row the objective is then ½·mean sin²θ + ½·`mass_weight`·(1°)²·(mass / floor):
//! angles against mass in floors, both free of the arm's size and of its gravity, so one weight
//! means the same on every arm; and every fit has rows. The scale was ½‖b‖², the residual of no
//! springs: 0 on arms without gravity or fixed trims (the window designs), where the weight did
//! nothing, and per row 1.8e-3 on the default design (its trims at mid-range) against 0.92 on the
//! triple pendulum (gravity), 500× apart. 1° is the unit every residual is reported in; on the
//! default design a weight is 5.82× its former number (½‖b‖²/m = 1.77e-3 = 5.82·(1°)²), by which
//! [`crate::fit::auto::MASS_LADDER`] was converted. The budget Σ mᵢ(kᵢ) ≤ M is met by raising λ (a bisection on the
//! multiplier: the budget's KKT conditions), which the selection sees too; with a straight-line
//! model only (every bᵢ = 0) the QP holds it as one more linear inequality instead. M is
//! `max_spring_mass` less the trims' parts ([`trims_mass`]): the trims are not fitted (held at
//! mid-range) but weigh like any spring, so the budget holds every spring the arm carries, as
//! `fit` reports them (the default design's three trims weigh 0.222 kg, which a budget on the
//! fitted springs alone left over: 2.375 kg of parts at `max_spring_mass = 2.12`).
//!

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::design::Design;
use crate::design::fit::FitSettings;
use crate::elements::Profile;
use crate::elements::catalog::{Candidate, Catalog};
use crate::error::{Error, Result};
use crate::geodesic::{Fan, Region};
use crate::realise::cam::DEFAULT_REALISATION;
use crate::realise::duty::{duty, requirements, spans, swing};
use crate::realise::material::Material;
use crate::realise::mechanism::{Duty, MAX_ROLLER_DEPARTURE, Requirements, follower, part_mass, trim};
use crate::realise::spring::usable_energy_density;

/// Fraction of the potential's boundary torque 2U*/r a candidate carries at the reference
/// stiffness its mass per unit stiffness is read at.
const REFERENCE_TORQUE: f64 = 0.25;

/// Multiples of the reference stiffness (the first that has a part) at which further parts are
/// read for the curvature of the candidate's mass, each with a fallback where it has no part:
/// the fits' bills carry well beyond four times the reference stiffness on one part (a 55 N·m
/// crank of 2.19 kg at about 7× in a budgeted bill of the default design), and the envelope
/// makes those parts heavier per unit stiffness. Two reads (at k_ref and 4·k_ref) put the curve
/// through both and extrapolated it beyond: that bill weighed 4.16 kg by its parts for 1.9 kg by
/// the curve, a budget held by the model and not by the parts.
const CURVE_READS: [[f64; 2]; 2] = [[4.0, 2.0], [16.0, 8.0]];

/// A mass curve m(k) = a·k + b·k²: (a, b).
type Curve = (f64, f64);

/// Halvings of the reference stiffness tried before a candidate falls back to the floor density.
const HALVINGS: usize = 8;

/// The residual angle per row a bill of the floor's mass costs at `mass_weight = 1`, degrees: the
/// unit residuals are reported in (module documentation).
pub const REFERENCE_ANGLE_DEG: f64 = 1.0;

/// Fraction of U* a cam follower's range is read at for its kg per joule: the size a cam of a
/// fit that shares the potential among a few of them carries.
const REFERENCE_ENERGY: f64 = 0.25;

/// A cam follower as a family builds it: largest stroke (mm) and preload at the base circle as a
/// fraction of it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FollowerSpec {
    /// Largest stroke S, mm.
    pub stroke: f64,
    /// Preload p₀ = f·S at the base circle: f.
    pub preload_fraction: f64,
}

impl FollowerSpec {
    /// What a cubic element's disc cam and a cam outside any catalogue are built with
    /// ([`DEFAULT_REALISATION`]).
    pub const DEFAULT: FollowerSpec =
        FollowerSpec { stroke: DEFAULT_REALISATION.1, preload_fraction: DEFAULT_REALISATION.2 };

    /// The follower's mass per joule of the cam's range, kg/J, from the part chooser's follower
    /// at a range of `energy` J (halved until one exists; None: none at any).
    fn per_joule(self, energy: f64, req: &Requirements) -> Option<f64> {
        let (s, f) = (self.stroke, self.preload_fraction);
        let mut e = energy;
        for _ in 0..=HALVINGS {
            // ΔV = ½ k S² (1 + 2f), k in N/m and S in m; the follower takes N/mm and mm.
            let rate = 2.0 * e / ((s * 1e-3).powi(2) * (1.0 + 2.0 * f)) * 1e-3;
            if let Ok(part) = follower(rate, f * s, s, req) {
                return Some(part.mass / e);
            }
            e *= 0.5;
        }
        None
    }

    /// ρ(1 + f)²/((1 + 2f)u), kg/J: the follower's least steel per joule of the cam's range.
    fn by_density(self, req: &Requirements, floor: &Floor) -> f64 {
        let f = self.preload_fraction;
        req.material.density * (1.0 + f).powi(2) / ((1.0 + 2.0 * f) * floor.density)
    }
}

/// The least spring mass that can store the potential.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Floor {
    /// U* = ½ω²r² at the region's boundary, J.
    pub energy: f64,
    /// The material's usable energy density u, J/m³.
    pub density: f64,
    /// ρ·U*/u, kg.
    pub mass: f64,
}

impl Floor {
    /// The floor of `design` at `frequency` on a region whose farthest point is `radius` from
    /// q_eq (metric arc length).
    pub fn new(design: &Design, frequency: f64, radius: f64) -> Floor {
        let req = requirements(&design.parts, "");
        let energy = 0.5 * frequency * frequency * radius * radius;
        // With a list of wires (`[parts] material`) any spring may be wound from any of them, so
        // the floor is that of the wire storing a joule in the least mass.
        let per_joule = |m: &Material| m.density / usable_energy_density(m, req.cycles, req.safety, req.surface);
        let material = req.wires().min_by(|a, b| per_joule(a).total_cmp(&per_joule(b))).unwrap_or(req.material);
        let density = usable_energy_density(material, req.cycles, req.safety, req.surface);
        Floor { energy, density, mass: material.density * energy / density }
    }

    /// The floor before any work: a ball's radius is in the design (a box's farthest point is
    /// known only once its geodesics are traced: None).
    pub fn before_work(design: &Design, frequency: f64) -> Option<Floor> {
        match design.region {
            Region::Ball { radius } => Some(Floor::new(design, frequency, radius)),
            _ => None,
        }
    }

    /// The floor on the region `fan` covers: its longest geodesic is the farthest point.
    pub fn on(design: &Design, frequency: f64, fan: &Fan) -> Floor {
        let radius = fan.geodesics.iter().map(|g| g.length()).fold(0.0, f64::max);
        Floor::new(design, frequency, radius)
    }

    /// Refuses a `max_spring_mass` below the floor, naming it.
    pub fn check(&self, design: &Design, settings: &FitSettings) -> Result<()> {
        let budget = settings.max_spring_mass;
        if budget > 0.0 && budget < self.mass {
            return Err(Error::invalid(
                &design.path,
                "fit.max_spring_mass",
                format!(
                    "{budget} kg is below the floor of {:.3} kg: any springs that hold the potential store at least U* = ½ω²r² = {:.2} J, and the wire stores at most {:.3} MJ/m³ (docs/parts.md, \"The floor\"); raise it above the floor",
                    self.mass,
                    self.energy,
                    self.density / 1e6
                ),
            ));
        }
        Ok(())
    }
}

/// Every candidate's spring mass per unit stiffness, and the floor.
#[derive(Debug, Clone, PartialEq)]
pub struct MassModel {
    /// aᵢ, kg per unit of the candidate's stiffness: the linear part of its mass curve.
    pub per_stiffness: Vec<f64>,
    /// bᵢ, kg per unit of stiffness squared: the curve's bend, m(k) = aᵢk + bᵢk² (0 where one
    /// part was read, and for cams and cubic elements, which are charged by their range).
    pub per_stiffness_squared: Vec<f64>,
    /// Whether the curve is the part chooser's (false: the floor density's fallback).
    pub from_parts: Vec<bool>,
    /// The curve (aᵢ, bᵢ) of a crank built within the rollers' bound
    /// ([`crate::realise::mechanism::MAX_ROLLER_DEPARTURE`]), the geometry `parts::choose`
    /// rebuilds a bill's cranks on when the lightest ones realise the design more than
    /// `ROLLER_SLACK_DEG` off its ideal elements; equal to the plain curve for every other
    /// candidate, and for every candidate when the design's cranks run without rollers
    /// (`[parts] pulley_radius_mm = 0`). What a budget is held by ([`MassModel::budget_curve`]).
    /// None where the model was read without it ([`MassModel::of_catalog_lightest`]: a fit whose
    /// budget is not held on the bounded cranks, where these reads were a second crank search
    /// per candidate for nothing).
    pub bounded: Option<Vec<(f64, f64)>>,
    /// The floor.
    pub floor: Floor,
    /// The trims' parts, kg: each trim's part as the part chooser builds it at mid-range over its
    /// duty ([`trims_mass`]), fixed whatever the fit chooses (0 without a catalogue: a bill's rows
    /// read back).
    pub trims: f64,
    /// The trims' parts as the part chooser's accurate pass builds them (their geared cranks
    /// within [`crate::realise::mechanism::TRIM_LAW_DEPARTURE`] of linear, else a leaf), kg:
    /// what a budget holds once the parts of a budgeted fit broke it (with the bounded cranks,
    /// [`MassModel::budget_curve`]), since that pass rebuilds the trims with the cranks. None
    /// where the model was read without the bounded parts ([`MassModel::of_catalog_lightest`]).
    pub trims_bounded: Option<f64>,
}

impl MassModel {
    /// The model of `candidates` over the held-out fan `evaluation` at `frequency`, in parallel
    /// (each candidate's part searched on its own, the results in the candidates' order), with
    /// every cam's follower as [`FollowerSpec::DEFAULT`] builds it (candidates outside a catalogue,
    /// such as a bill's rows read back: [`MassModel::of_catalog`] has the families').
    pub fn new(design: &Design, candidates: &[Candidate], evaluation: &Fan, frequency: f64) -> MassModel {
        MassModel::with_followers(design, candidates, |_| FollowerSpec::DEFAULT, evaluation, frequency, true)
    }

    /// The budget `max_spring_mass` leaves the fitted springs, kg: the trims are springs the arm
    /// carries too, so their parts' mass ([`MassModel::trims`]) is taken off it (0: no budget).
    /// A budget the trims alone fill is infeasible (a point of `pareto`'s mass curve, as a budget
    /// no set meets), naming the key and the trims' mass.
    /// `bounded`: the budget is held on the parts as the accurate pass builds them (the trims'
    /// [`MassModel::trims_bounded`]), once the lightest ones' parts broke it (an error where the
    /// model was read without them).
    pub fn budget(&self, settings: &FitSettings, bounded: bool) -> Result<f64> {
        let budget = settings.max_spring_mass;
        if budget <= 0.0 {
            return Ok(0.0);
        }
        let trims = if bounded {
            self.trims_bounded.ok_or_else(|| {
                Error::numerical("fit.max_spring_mass", "the mass model was read without the bounded trims")
            })?
        } else {
            self.trims
        };
        let left = budget - trims;
        if left <= 0.0 {
            return Err(Error::Infeasible {
                constraint: format!("fit.max_spring_mass ({budget} kg, the trims included)"),
                reason: format!(
                    "the catalogue's trims weigh {trims:.3} kg by their parts at mid-range{}, so nothing is left for the fitted springs; raise max_spring_mass above that",
                    if bounded {
                        format!(
                            " as the part chooser builds them once the lightest parts broke the budget (geared cranks within {} % of linear, else leaves)",
                            crate::realise::mechanism::TRIM_LAW_DEPARTURE * 100.0
                        )
                    } else {
                        String::new()
                    }
                ),
            });
        }
        Ok(left)
    }

    /// [`MassModel::new`] with each cam's follower as its family in `catalog` builds it (a
    /// cubic element's is the default's, as the part chooser builds it).
    pub fn of_catalog(
        design: &Design,
        catalog: &Catalog,
        candidates: &[Candidate],
        evaluation: &Fan,
        frequency: f64,
    ) -> MassModel {
        MassModel::of_catalog_reading(design, catalog, candidates, evaluation, frequency, true)
    }

    /// [`MassModel::of_catalog`] without the parts built within the rollers' bound
    /// ([`MassModel::bounded`] and [`MassModel::trims_bounded`] None): what every fit reads
    /// but a budget that the parts broke (`fit::prepare`), its other figures the same bits.
    pub fn of_catalog_lightest(
        design: &Design,
        catalog: &Catalog,
        candidates: &[Candidate],
        evaluation: &Fan,
        frequency: f64,
    ) -> MassModel {
        MassModel::of_catalog_reading(design, catalog, candidates, evaluation, frequency, false)
    }

    fn of_catalog_reading(
        design: &Design,
        catalog: &Catalog,
        candidates: &[Candidate],
        evaluation: &Fan,
        frequency: f64,
        read_bounded: bool,
    ) -> MassModel {
        let spec = |c: &Candidate| match (c.element.profile, catalog.families.get(c.family).and_then(|f| f.cam)) {
            (Profile::Spline(_), Some(cam)) => {
                FollowerSpec { stroke: cam.max_stroke, preload_fraction: cam.preload_fraction }
            }
            _ => FollowerSpec::DEFAULT,
        };
        let trims = trims_mass(design, catalog, evaluation, frequency);
        let trims_bounded =
            read_bounded.then(|| trims_mass_within(design, catalog, evaluation, frequency, Some(MAX_ROLLER_DEPARTURE)));
        MassModel {
            trims,
            trims_bounded,
            ..MassModel::with_followers(design, candidates, spec, evaluation, frequency, read_bounded)
        }
    }

    fn with_followers(
        design: &Design,
        candidates: &[Candidate],
        spec: impl Fn(&Candidate) -> FollowerSpec + Sync,
        evaluation: &Fan,
        frequency: f64,
        read_bounded: bool,
    ) -> MassModel {
        let floor = Floor::on(design, frequency, evaluation);
        let (_, radius) = swing(design, evaluation, frequency);
        let spans =
            spans(candidates.iter().map(|c| &c.element.coupling[..]), design.q_eq.as_slice(), evaluation, radius);
        let req = requirements(&design.parts, "");
        let extent = evaluation.geodesics.iter().map(|g| g.length()).fold(0.0, f64::max).max(1e-9);
        let torque = REFERENCE_TORQUE * 2.0 * floor.energy / extent;
        let energy = REFERENCE_ENERGY * floor.energy;
        // Each follower spec's kg per joule, read once (a catalogue has a handful of cam families).
        let mut specs: Vec<FollowerSpec> = Vec::new();
        for c in candidates.iter().filter(|c| matches!(c.element.profile, Profile::Spline(_) | Profile::Cubic)) {
            let s = spec(c);
            if !specs.contains(&s) {
                specs.push(s);
            }
        }
        let per_joule: Vec<(FollowerSpec, Option<f64>)> =
            specs.par_iter().map(|&s| (s, s.per_joule(energy, &req))).collect();
        // The cranks' rollers bounded as `parts::choose` bounds them when the realised design needs
        // it: only where the cranks run over rollers.
        let rollers = (read_bounded && req.pulley_radius > 0.0)
            .then_some(Requirements { roller_departure: Some(MAX_ROLLER_DEPARTURE), ..req });
        let read: Vec<(Curve, bool, Curve)> = candidates
            .par_iter()
            .map(|c| {
                let duty = duty(&spans, &c.element);
                let profile = c.element.profile;
                match profile {
                    Profile::Spline(_) | Profile::Cubic => {
                        let s = spec(c);
                        let read = per_joule.iter().find(|p| p.0 == s).and_then(|p| p.1);
                        let kg_per_joule = read.unwrap_or_else(|| s.by_density(&req, &floor));
                        let ab = (kg_per_joule * energy_range(profile, &duty), 0.0);
                        (ab, read.is_some(), ab)
                    }
                    _ => {
                        let Some((k, ab)) =
                            parts_curve(profile, torque / peak_slope(profile, &duty).max(1e-9), &duty, &req)
                        else {
                            let by_density = req.material.density * largest_energy(profile, &duty) / floor.density;
                            return ((by_density, 0.0), false, (by_density, 0.0));
                        };
                        // A crank within the rollers' bound, read from the same reference stiffness
                        // (the plain curve where no bounded geometry is found).
                        let bounded = match (&rollers, profile) {
                            (Some(r), Profile::Crank) => parts_curve(profile, k, &duty, r).map_or(ab, |b| b.1),
                            _ => ab,
                        };
                        (ab, true, bounded)
                    }
                }
            })
            .collect();
        let (per_stiffness, per_stiffness_squared) = read.iter().map(|r| r.0).unzip();
        let from_parts = read.iter().map(|r| r.1).collect();
        let bounded = read_bounded.then(|| read.iter().map(|r| r.2).collect());
        let trims_bounded = read_bounded.then_some(0.0);
        MassModel { per_stiffness, per_stiffness_squared, from_parts, bounded, floor, trims: 0.0, trims_bounded }
    }

    /// The curves a budget is held by, (aᵢ, bᵢ) per candidate: the cranks' within the rollers'
    /// bound ([`MassModel::bounded`]). `parts::choose` builds a bill's cranks on the lightest
    /// geometry and rebuilds them within the bound where that realised design is more than
    /// `ROLLER_SLACK_DEG` off its ideal elements: a budget read on the lightest geometry held the
    /// model and not the parts there (the default design at `max_spring_mass = 2.126`: 1.904 kg by
    /// the model, 3.145 kg of parts). Read on the bounded cranks, the parts are within it whichever
    /// geometry the chooser keeps. A mass weight keeps the plain curves (a trade, not a promise).
    /// None where the model was read without them ([`MassModel::of_catalog_lightest`]).
    pub fn budget_curve(&self) -> Option<(Vec<f64>, Vec<f64>)> {
        self.bounded.as_ref().map(|b| b.iter().copied().unzip())
    }

    /// Candidate `i`'s mass at stiffness `k` by the model, aᵢk + bᵢk², kg.
    pub fn mass_at(&self, i: usize, k: f64) -> f64 {
        self.per_stiffness[i] * k + self.per_stiffness_squared[i] * k * k
    }
}

/// The curve of a spring candidate's parts ([`curve`]) read from stiffness `k` (halved until a
/// part exists, at most [`HALVINGS`] times) and at the [`CURVE_READS`] multiples of the first
/// that has one: that reference stiffness and the curve, None where no part exists.
fn parts_curve(profile: Profile, k: f64, duty: &Duty, req: &Requirements) -> Option<(f64, (f64, f64))> {
    let mut k = k;
    for _ in 0..=HALVINGS {
        if let Some(mass) = part_mass(profile, k, duty, req) {
            let mut reads = vec![(k, mass)];
            reads.extend(CURVE_READS.iter().filter_map(|multiples| {
                multiples.iter().find_map(|&f| part_mass(profile, f * k, duty, req).map(|m| (f * k, m)))
            }));
            return Some((k, curve(&reads)));
        }
        k *= 0.5;
    }
    None
}

/// The mass of the catalogue's trims by their parts, kg: each trim's bill row as the fit writes
/// it (at mid-range, [`crate::fit::bill::append`]) and its part as the part chooser builds it
/// ([`trim`], over the same duty: the held-out fan and the scenarios' swing), so the figure is the
/// parts' `fit` reports unless a trim snaps to a listed stock spring. A trim no part realises
/// weighs nothing here, as in the bill's total.
pub fn trims_mass(design: &Design, catalog: &Catalog, evaluation: &Fan, frequency: f64) -> f64 {
    trims_mass_within(design, catalog, evaluation, frequency, None)
}

/// [`trims_mass`] with the part chooser's bound on the cranks (`roller_departure`, a share of k;
/// None: the lightest geometry), which also keeps a trim's geared crank within
/// [`crate::realise::mechanism::TRIM_LAW_DEPARTURE`] of its linear law: the trims as the accurate
/// pass of `parts::choose` builds them.
pub fn trims_mass_within(
    design: &Design,
    catalog: &Catalog,
    evaluation: &Fan,
    frequency: f64,
    roller_departure: Option<f64>,
) -> f64 {
    let mut rows = Vec::new();
    crate::fit::bill::append(design, catalog, &mut rows, evaluation);
    let (_, radius) = swing(design, evaluation, frequency);
    let spans = spans(rows.iter().map(|r| &r.element.coupling[..]), design.q_eq.as_slice(), evaluation, radius);
    rows.iter()
        .filter_map(|r| {
            let range = r.adjust.trim_range?;
            let req = Requirements { roller_departure, ..requirements(&design.parts, &r.id) };
            trim(range, r.stiffness, &duty(&spans, &r.element), &req).ok().map(|p| p.mass)
        })
        .sum()
}

/// The mass curve m(k) = a·k + b·k², a, b ≥ 0, fitted to the parts `reads` (kᵢ, mᵢ) in relative
/// terms: the least Σ((a·kᵢ + b·kᵢ²)/mᵢ − 1)², so a small part's 10 % counts as much as a big
/// one's and the curve holds over the whole range the reads span (k_ref to 16·k_ref), not only
/// between its first two. Two reads are met exactly where the curve through them bends up; where
/// the best curve would have a < 0 or b < 0 (the larger parts lighter per unit stiffness, or much
/// heavier) it is the better of the best straight line (b = 0) and the best parabola through the
/// origin (a = 0). Non-negative a and b keep the mass convex in k, which keeps every solver exact
/// (module documentation, "In the solvers").
fn curve(reads: &[(f64, f64)]) -> (f64, f64) {
    // Per read x = k/m and y = k²/m: the normal equations of the relative fit.
    let (mut xx, mut xy, mut yy, mut x1, mut y1) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &(k, m) in reads {
        let (x, y) = (k / m, k * k / m);
        (xx, xy, yy, x1, y1) = (xx + x * x, xy + x * y, yy + y * y, x1 + x, y1 + y);
    }
    let det = xx * yy - xy * xy;
    if det > 1e-12 * xx * yy {
        let (a, b) = ((yy * x1 - xy * y1) / det, (xx * y1 - xy * x1) / det);
        if a >= 0.0 && b >= 0.0 {
            return (a, b);
        }
    }
    // On the boundary: the better of the straight line and the parabola through the origin (the
    // fit's residual is n − x1²/xx and n − y1²/yy); one read is met exactly by both, the line kept.
    if x1 * x1 / xx >= y1 * y1 / yy { (x1 / xx, 0.0) } else { (0.0, y1 / yy) }
}

/// The largest |u′(d)| over the duty's range: the peak torque per unit stiffness.
fn peak_slope(profile: Profile, duty: &Duty) -> f64 {
    sample(duty).map(|d| profile.slope(d).abs()).fold(0.0, f64::max)
}

/// The largest u(d) over the duty's range: the energy per unit stiffness the element's potential
/// holds (its spring's preload aside).
fn largest_energy(profile: Profile, duty: &Duty) -> f64 {
    sample(duty).map(|d| profile.eval(d).0.abs()).fold(0.0, f64::max)
}

/// max u(d) − min u(d) over the duty's range: the range of the potential per unit stiffness (a
/// cubic's largest energy, a cam basis function's own range).
fn energy_range(profile: Profile, duty: &Duty) -> f64 {
    let (lo, hi) = sample(duty)
        .map(|d| profile.eval(d).0)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), u| (lo.min(u), hi.max(u)));
    (hi - lo).max(0.0)
}

/// 201 deflections across the duty's range, both ends included.
fn sample(duty: &Duty) -> impl Iterator<Item = f64> + '_ {
    (0..=200).map(move |i| duty.range[0] + (duty.range[1] - duty.range[0]) * f64::from(i) / 200.0)
}

/// What the solvers add for the mass: the linear term λ·cᵀk (λ in the objective's units per kg)
/// and the budget cᵀk ≤ M.
#[derive(Debug, Clone, Copy)]
pub struct MassTerm<'a> {
    /// aᵢ, kg per unit stiffness.
    pub per_stiffness: &'a [f64],
    /// bᵢ, kg per unit stiffness squared (empty: none).
    pub per_stiffness_squared: &'a [f64],
    /// λ, objective per kg (0: none).
    pub weight: f64,
    /// M, kg (0: none).
    pub budget: f64,
}

impl MassTerm<'_> {
    /// λ from `[fit] mass_weight` for a fit of `rows` training rows: `mass_weight` times the
    /// objective of a residual of 1° on every row ([`MassTerm::residual_scale`]), per floor mass.
    pub fn weight(settings: &FitSettings, rows: usize, floor: &Floor) -> f64 {
        settings.mass_weight * MassTerm::residual_scale(rows) / floor.mass.max(f64::MIN_POSITIVE)
    }

    /// ½·rows·θ₁², θ₁ = [`REFERENCE_ANGLE_DEG`]: the objective ½‖A k − b‖² of a residual of θ₁ on
    /// every one of `rows` rows (each row ≈ the sine of its residual angle).
    pub fn residual_scale(rows: usize) -> f64 {
        0.5 * rows as f64 * REFERENCE_ANGLE_DEG.to_radians().powi(2)
    }

    /// λ·c, what the linear term takes off the right-hand side c = Aᵀb of the normal equations.
    pub fn shift(&self, weight: f64) -> DVector<f64> {
        DVector::from_iterator(self.per_stiffness.len(), self.per_stiffness.iter().map(|c| weight * c))
    }

    /// Whether any candidate's mass bends up with its stiffness (a quadratic term, which the
    /// QP's linear budget row cannot hold).
    pub fn curved(&self) -> bool {
        self.per_stiffness_squared.iter().any(|&b| b > 0.0)
    }

    /// λ·Σ bᵢkᵢ² in the Gram form ½kᵀGk: 2λbᵢ on G's diagonal.
    pub fn bend(&self, weight: f64, g: &mut DMatrix<f64>) {
        for (j, b) in self.per_stiffness_squared.iter().enumerate() {
            g[(j, j)] += 2.0 * weight * b;
        }
    }

    /// Σ aᵢkᵢ + bᵢkᵢ², kg.
    pub fn mass(&self, k: &[f64]) -> f64 {
        let linear: f64 = self.per_stiffness.iter().zip(k).map(|(c, k)| c * k).sum();
        linear + self.per_stiffness_squared.iter().zip(k).map(|(b, k)| b * k * k).sum::<f64>()
    }
}
