//! What a fit returns: the bill of materials and spring set, the evaluation on held-out
//! geodesics, how the solve went and how long each step took.

use serde::Serialize;

use crate::design::fit::{FitSettings, SolverKind};
use crate::elements::group::Grouping;
use crate::fit::bill::BomRow;
use crate::geodesic::{Fan, RegionReport};
use crate::potential::SpringSet;
use crate::residual::{AngleSample, AngleStats, BandStats};
use crate::solve::qp::QpStatus;

/// Wall-clock seconds per step.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Timings {
    /// Region check and fans.
    pub geodesics: f64,
    /// Candidates and problem assembly.
    pub assemble: f64,
    /// Solve and selection.
    pub solve: f64,
    /// Evaluation on the held-out fan.
    pub evaluate: f64,
    /// Everything.
    pub total: f64,
}

/// What found the stiffnesses: one of the solvers `[fit] solver` names, or none (the exact
/// reference ½ω²r², which has no stiffnesses). Written as `nnls`, `qp` or `exact` (its
/// `Display` and serde form, the text of `summary.json` and the command's lines).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Solver {
    /// Lawson–Hanson non-negative least squares.
    Nnls,
    /// The Clarabel quadratic program.
    Qp,
    /// No solve: the exact potential evaluated as a reference.
    Exact,
}

impl From<SolverKind> for Solver {
    fn from(kind: SolverKind) -> Solver {
        match kind {
            SolverKind::Nnls => Solver::Nnls,
            SolverKind::Qp => Solver::Qp,
        }
    }
}

impl std::fmt::Display for Solver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Solver::Nnls => SolverKind::Nnls.name(),
            Solver::Qp => SolverKind::Qp.name(),
            Solver::Exact => "exact",
        })
    }
}

/// How the solve ended. Written as `solved`, `almost_solved` or `reference` (its `Display` and
/// serde form).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SolveStatus {
    /// Solved to tolerance (NNLS always; the QP when Clarabel says so).
    Solved,
    /// The QP solved to Clarabel's reduced accuracy.
    AlmostSolved,
    /// No solve: the exact potential evaluated as a reference.
    Reference,
}

impl From<QpStatus> for SolveStatus {
    fn from(status: QpStatus) -> SolveStatus {
        match status {
            QpStatus::Solved => SolveStatus::Solved,
            QpStatus::AlmostSolved => SolveStatus::AlmostSolved,
        }
    }
}

impl std::fmt::Display for SolveStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SolveStatus::Solved => "solved",
            SolveStatus::AlmostSolved => "almost_solved",
            SolveStatus::Reference => "reference",
        })
    }
}

/// How the stiffnesses were found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SolveReport {
    /// The solver (`exact` for the reference).
    pub solver: Solver,
    /// How it ended (`reference` for the exact potential).
    pub status: SolveStatus,
    /// Sparse selection: subset refits performed (0 without a limit).
    pub selection_evaluations: usize,
    /// Sparse selection: exchange moves accepted.
    pub selection_swaps: usize,
    /// QP: cutting-plane rounds for monotonicity.
    pub cut_rounds: usize,
    /// With a tolerance: the term the tolerance-aware fit adds for the final stiffnesses,
    /// λ (Σᵢ Dᵢᵢ kᵢ² + Σ_cams k_gᵀ B_g k_g) (+ the shift penalty); with λ = 1 and no shift weight, the predicted mean
    /// squared change of the training rows of a build about its own equilibrium. None without
    /// a tolerance.
    pub expected_build_spread: Option<f64>,
    /// With `max_elements = K`: the budget whose selection met every constraint when the search
    /// at K itself found no set that does (then the best set of at most K found has fewer
    /// elements); None when the budget K was met as asked, or without a budget.
    pub budget_met_at: Option<usize>,
    /// With a tolerance and `max_shift`: what the bound on the builds' equilibrium shift did.
    pub shift_bound: Option<ShiftBound>,
}

/// What the fit's bound on the builds' RMS metric equilibrium shift (`[fit] max_shift`) did:
/// the fit is solved as without it first, and the cone is added only when that fit breaks it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ShiftBound {
    /// The bound s, rad·√(kg·m²) (the unit of the region's radius).
    pub bound: f64,
    /// √(kᵀSk) of the fit without the bound.
    pub unbounded_rms: f64,
    /// √(kᵀSk) of the fit returned.
    pub rms: f64,
    /// The expected squared residual over builds (the objective the fit minimises, equalities
    /// aside) of the fit returned over that of the fit without the bound: 1 when inactive.
    pub objective_ratio: f64,
    /// What happened.
    pub action: ShiftAction,
}

/// Whether the shift bound acted.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ShiftAction {
    /// The fit without the bound meets it: nothing changed.
    Inactive,
    /// The fit was solved again with the cone and holds it.
    Held,
    /// The bound could not be held (the reason): the fit without it is returned.
    NotMet(String),
}

/// How well a potential does on the held-out evaluation fan.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    /// Residual angles on the evaluation fan.
    pub residuals: Vec<AngleSample>,
    /// Their statistics.
    pub stats: AngleStats,
    /// Statistics by distance band.
    pub bands: Vec<BandStats>,
    /// |∂U/∂q(q_eq)| in N·m (total potential).
    pub equilibrium_gradient_norm: f64,
    /// ‖∇²U(q_eq) − ω² M(q_eq)‖_F / ‖ω² M(q_eq)‖_F.
    pub hessian_rel_error: f64,
    /// Evaluation samples where U decreases along the geodesic (∂U/∂q·γ̇ < 0).
    pub monotone_violations: usize,
}

/// The outcome of a fit.
#[derive(Debug, Clone)]
pub struct FitOutcome {
    /// Design name.
    pub design: String,
    /// Joints.
    pub dof: usize,
    /// Catalogue name (`exact` for the reference).
    pub catalog: String,
    /// Settings used.
    pub settings: FitSettings,
    /// Candidates after expansion (before dropping).
    pub candidates: usize,
    /// Candidates dropped because they never engage in the region.
    pub dropped: usize,
    /// The bill of materials (empty for the exact reference).
    pub bom: Vec<BomRow>,
    /// Stock rates the catalogue offers, by family name (for snapping).
    pub stock_rates: std::collections::BTreeMap<String, Vec<f64>>,
    /// The fitted spring set (the BOM's elements and stiffnesses).
    pub springs: SpringSet,
    /// The fitted cams, realised (empty without cams).
    pub cams: Vec<crate::realise::cam::FittedCam>,
    /// Residuals and checks on the held-out fan.
    pub metrics: Evaluation,
    /// How the solve went.
    pub solve: SolveReport,
    /// Time per step.
    pub timings: Timings,
    /// The region check.
    pub region: RegionReport,
    /// The training fan.
    pub training: Fan,
    /// The held-out evaluation fan.
    pub evaluation: Fan,
    /// The weights springfit chose, with every candidate tried (None: the design's weights were
    /// fitted as they are; set by the fit job, [`crate::jobs::fit`]).
    pub auto: Option<super::auto::Choice>,
    /// What would lower the residual most, for a poor fit (set by the fit job; None for an
    /// acceptable fit, the exact reference and fits run outside the job).
    pub diagnosis: Option<crate::fit::diagnosis::Diagnosis>,
    /// The elements left out of the bill because no part realises them, and what that cost
    /// ([`crate::fit::Prepared::drop_unbuildable`]); None when every element of the first bill
    /// has a part, when no parts were chosen, and for the exact reference.
    pub dropped_without_part: Option<DroppedWithoutPart>,
    /// The trim ranges sized by the bill (catalogue families with `trim_sized = true`; set by
    /// the fit job, [`crate::asbuilt::sizing`]); None when no family asks for it.
    pub trim_sizing: Option<TrimSizing>,
}

/// How the fit job sized the trims' ranges by the bill (`"trim_sizing"` of `summary.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TrimSizing {
    /// The share of builds whose needed rate each sized range holds.
    pub cover: f64,
    /// Builds the needed rates were taken over (the as-built builds' draws).
    pub builds: usize,
    /// Each trim of the first fit's bill.
    pub trims: Vec<SizedTrim>,
    /// Whether the bill is the fit solved again around the sized ranges (their mid-range rates):
    /// false when no range changed, or when that fit was worse than the first and the first was
    /// kept with the ranges it started from (see `refit`).
    pub refitted: bool,
    /// The fit around the sized ranges against the first, when it was solved (a range changed).
    pub refit: Option<RefitComparison>,
}

/// The fit around the trims' sized ranges against the first fit: p99 of the residual angle (°)
/// drawn and realised with its parts, each fit's. The refit is kept only when neither is worse
/// than the first's by more than [`REFIT_SLACK`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RefitComparison {
    /// The first fit (the trims' ranges as the catalogue writes them): drawn, realised.
    pub first_p99_deg: [f64; 2],
    /// The fit around the sized ranges: drawn, realised.
    pub refit_p99_deg: [f64; 2],
    /// Whether the refit was kept (its bill is the one written).
    pub kept: bool,
}

/// How much worse (a share of the first fit's p99, drawn and realised) the fit around the trims'
/// sized ranges may be and still be kept: what the sizing buys is the trimmed builds. On the
/// UR10 (`designs/ur10_lift_elbow_wrist.toml`) the refit is 0.9 % worse drawn (0.2782° against
/// 0.2758°) and 0.6 % realised, for a trimmed p95 of 1.44° against 1.50° (686 builds at a
/// range end against 15); on the planar three-link arm of `tests/cli_init.rs` it is 11× worse.
pub const REFIT_SLACK: f64 = 0.02;

impl RefitComparison {
    /// The comparison of the first fit's and the refit's (drawn, realised) p99 (°): the refit
    /// is kept when neither is worse than the first's by more than [`REFIT_SLACK`] of it.
    pub fn of(first: [f64; 2], refit: [f64; 2]) -> RefitComparison {
        let kept = (0..2).all(|i| refit[i] <= first[i] * (1.0 + REFIT_SLACK));
        RefitComparison { first_p99_deg: first, refit_p99_deg: refit, kept }
    }
}

/// One trim's sizing.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SizedTrim {
    /// Its id in the first fit's bill.
    pub id: String,
    /// Its family.
    pub family: String,
    /// Its coupling a.
    pub coupling: Vec<f64>,
    /// Its rate in the first fit's bill (the start range's middle), N·m/rad.
    pub fitted_rate: f64,
    /// The range the fit started from (the catalogue's `trim_range`), N·m/rad.
    pub start_range: [f64; 2],
    /// The rates the builds need, ranges aside: the (1 − cover)/2 and (1 + cover)/2 quantiles
    /// over the builds, N·m/rad.
    pub needed: [f64; 2],
    /// The range after sizing (its family's: the envelope of its trims'), N·m/rad.
    pub range: [f64; 2],
    /// Whether its family is sized by the bill (false: the catalogue's range is kept).
    pub sized: bool,
}

/// An element of a fit's first bill that no part realises and that the fit left out.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DroppedElement {
    /// Its id in the bill it was missing a part in (`S140`): the refit's bill numbers its
    /// elements afresh.
    pub id: String,
    /// The element in words (`linear on q2 at x₀ = 0.1`).
    pub element: String,
    /// Its catalogue family.
    pub family: String,
    /// Its peak torque over the region in that bill, N·m.
    pub max_torque_nm: f64,
    /// The limit no spring meets, by how much, and what keeps a part possible (the verdict's
    /// words, [`WithoutPart::reason`]).
    pub reason: String,
}

/// What became of the elements no part realises: an element that cannot be built has no place
/// in the bill (its ideal potential would be judged as if it were built), so the fit is solved
/// again without it, on the same preparation and settings, and the parts chosen again. The
/// figures before and after say what the drop cost.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DroppedWithoutPart {
    /// The elements left out, in the order they were found (empty when `kept` says why none
    /// could be).
    pub elements: Vec<DroppedElement>,
    /// Refits solved (each drops the elements the previous bill's parts could not realise).
    pub rounds: usize,
    /// The ideal elements' p99 |residual angle| before the drop, degrees (as drawn).
    pub p99_deg_before: f64,
    /// The same after, degrees: the bill's.
    pub p99_deg_after: f64,
    /// The realised design's p99 before the drop, degrees (the missing elements counted at
    /// their ideal potential, as the parts stage evaluates them).
    pub realised_p99_deg_before: f64,
    /// The realised design's p99 after, degrees: what the verdict judges.
    pub realised_p99_deg_after: f64,
    /// Why the elements without a part were kept in the bill after all (the refit without them
    /// cannot hold the equilibrium equalities, or found no solution): then the bill is the
    /// first one and the verdict names them as before. None when they were dropped.
    pub kept: Option<String>,
}

impl FitOutcome {
    /// Number of elements used: the rows of `bom.csv`, a part (a cam) counting as one (as for
    /// `max_elements`) however many coefficients it has.
    pub fn used(&self) -> usize {
        let grouping = Grouping::new(self.bom.iter().map(|r| (r.family.as_str(), &r.element)));
        grouping.of.iter().filter(|g| g.is_none()).count() + grouping.groups.len()
    }

    /// What [`FitOutcome::used`] counts, in words: `springs`, or `elements (N cams)` with cams.
    pub fn used_noun(&self) -> String {
        if self.cams.is_empty() { "springs".into() } else { format!("elements ({} cams)", self.cams.len()) }
    }
}

impl DroppedWithoutPart {
    /// What happened, in one sentence (what `springfit fit` prints and `report.md` says): the
    /// elements dropped with their limits and peak torques, the p99 as drawn and realised
    /// before and after; or why they were kept.
    pub fn sentence(&self) -> String {
        let n = self.elements.len();
        let mut r = String::new();
        if n > 0 {
            let named: Vec<String> = self
                .elements
                .iter()
                .map(|e| {
                    // The limit only: the remedy it carries is moot once the element is gone.
                    let limit = e.reason.split("; ").next().unwrap_or(&e.reason);
                    format!("{} ({}, peak {:.4} N·m: {limit})", e.id, e.element, e.max_torque_nm)
                })
                .collect();
            r = format!(
                "{n} element{} without a part left out of the bill and the fit solved again without {} ({} refit{}): {}; p99 as drawn {:.4}° → {:.4}°, realised {:.4}° → {:.4}°",
                if n == 1 { "" } else { "s" },
                if n == 1 { "it" } else { "them" },
                self.rounds,
                if self.rounds == 1 { "" } else { "s" },
                named.join(", "),
                self.p99_deg_before,
                self.p99_deg_after,
                self.realised_p99_deg_before,
                self.realised_p99_deg_after
            );
        }
        if let Some(why) = &self.kept {
            let kept = format!("the elements without a part stay in the bill: {why}");
            r = if r.is_empty() { kept } else { format!("{r}; {kept}") };
        }
        r
    }
}

/// Which design a [`Verdict`] judges. Written as `ideal` or `realised` (its serde form, the
/// text of `summary.json`'s `verdict_judges`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Judged {
    /// The fitted elements as the catalogue defines them: all there is before parts are chosen
    /// (the exact reference, `compare`'s and `pareto`'s budgets).
    Ideal,
    /// Each element's part (its mechanism's own potential) in place of the ideal element: what
    /// would be built. A fit whose parts are chosen is judged on this, since the ideal figure
    /// says nothing of an arm that cannot be built or whose parts move the residual.
    Realised,
}

/// An element of a realised design that no part meets, as the verdict names it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WithoutPart {
    /// The element's id in the bill (`S57`).
    pub id: String,
    /// The limit no spring meets, by how much, and the bound that keeps a part possible, in
    /// words (the parts stage's sentence, shortened).
    pub reason: String,
    /// Whether only a stronger element would get a part (the limit bounds the element's torque
    /// from below: arbor clearance, initial tension, no wire that winds so soft a rate). Such
    /// an element carries less torque than any part can, so the fit can leave it out at a cost
    /// it measures; a strong element without a part is a design problem named to the user.
    #[serde(skip)]
    pub too_weak: bool,
}

/// The plain verdict on a fit: `acceptable` when the judged design's p99 residual angle on the
/// held-out geodesics is at most `[fit] accept_p99_deg` and (for a realised design) every
/// element has a part; else `poor`. The ideal figure is kept beside the realised one so that a
/// reader sees what the parts cost.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Verdict {
    /// The design judged.
    pub judged: Judged,
    /// Its p99 |residual angle|, degrees.
    pub p99_deg: f64,
    /// The ideal elements' p99 |residual angle|, degrees (the same as `p99_deg` for
    /// [`Judged::Ideal`]).
    pub ideal_p99_deg: f64,
    /// The threshold, degrees (`[fit] accept_p99_deg`).
    pub accept_p99_deg: f64,
    /// The elements no part meets (a realised design with any is poor: it cannot be built).
    pub without_part: Vec<WithoutPart>,
}

impl Verdict {
    /// The verdict on the ideal elements alone (no parts were chosen).
    pub fn ideal(p99_deg: f64, accept_p99_deg: f64) -> Verdict {
        Verdict { judged: Judged::Ideal, p99_deg, ideal_p99_deg: p99_deg, accept_p99_deg, without_part: Vec::new() }
    }

    /// Whether the residual passes (p99 ≤ the threshold); the parts aside.
    pub fn residual_passes(&self) -> bool {
        self.p99_deg <= self.accept_p99_deg
    }

    /// Whether the ideal elements' residual passes.
    pub fn ideal_passes(&self) -> bool {
        self.ideal_p99_deg <= self.accept_p99_deg
    }

    /// True when the judged design passes: its residual, and a part for every element.
    pub fn acceptable(&self) -> bool {
        self.residual_passes() && self.without_part.is_empty()
    }

    /// `acceptable` or `poor`.
    pub fn word(&self) -> &'static str {
        if self.acceptable() { "acceptable" } else { "poor" }
    }

    /// Why, in words: the judged figure against the threshold (`p99 0.3687° ≤ fit.accept_p99_deg
    /// = 2°`), for a realised design with the ideal figure beside it, and the elements without
    /// a part with their limits.
    pub fn reason(&self) -> String {
        let sign = if self.residual_passes() { "≤" } else { ">" };
        let mut r = match self.judged {
            Judged::Ideal => format!("p99 {:.4}° {sign} fit.accept_p99_deg = {}°", self.p99_deg, self.accept_p99_deg),
            Judged::Realised => format!(
                "realised design p99 {:.4}° {sign} fit.accept_p99_deg = {}°; ideal elements p99 {:.4}°",
                self.p99_deg, self.accept_p99_deg, self.ideal_p99_deg
            ),
        };
        if !self.without_part.is_empty() {
            let n = self.without_part.len();
            let missing = format!(
                "{n} element{} without a part: {}",
                if n == 1 { "" } else { "s" },
                self.without_part.iter().map(|w| format!("{} ({})", w.id, w.reason)).collect::<Vec<_>>().join(", ")
            );
            // When the residual passes, the missing parts are why the design is poor: say so first.
            r = if self.residual_passes() { format!("{missing}; {r}") } else { format!("{r}; {missing}") };
        }
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The realised design is judged on its own p99 and on having every part: an element without
    /// one makes it poor even when both residuals pass, and the reason keeps the ideal figure.
    #[test]
    fn a_realised_design_needs_its_residual_and_every_part() {
        let ideal = Verdict::ideal(1.69, 2.0);
        assert_eq!((ideal.word(), ideal.reason().as_str()), ("acceptable", "p99 1.6900° ≤ fit.accept_p99_deg = 2°"));
        let realised = Verdict { judged: Judged::Realised, p99_deg: 4.01, ..ideal.clone() };
        assert_eq!(realised.word(), "poor");
        assert!(realised.ideal_passes() && !realised.residual_passes());
        assert_eq!(
            realised.reason(),
            "realised design p99 4.0100° > fit.accept_p99_deg = 2°; ideal elements p99 1.6900°"
        );
        let missing = Verdict {
            judged: Judged::Realised,
            p99_deg: 1.0,
            without_part: vec![WithoutPart {
                id: "S57".into(),
                reason: "`initial tension` 1.29× the limit".into(),
                too_weak: true,
            }],
            ..ideal
        };
        assert!(missing.residual_passes() && !missing.acceptable());
        // The residual passes, so the missing part leads the reason.
        assert!(
            missing.reason().starts_with(
                "1 element without a part: S57 (`initial tension` 1.29× the limit); realised design p99 1.0000° ≤"
            ),
            "{}",
            missing.reason()
        );
    }
}
