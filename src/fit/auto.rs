//! The weights a design leaves to springfit (`tolerance_weight`, `trimmed_weight`, `mass_weight`,
//! `restarts` set to `"auto"`), chosen as the developers chose the shipped designs' by hand:
//! by the figures a build is judged by, measured, not by the objective (the objective is a
//! first-order model of the builds, and weights of smaller objective were measured to build
//! worse). This module holds the candidates in the order they are tried and the rule that picks
//! among them; the fit job ([`crate::jobs::fit`]) solves each candidate on one preparation,
//! chooses its parts and draws its builds, since those stages sit above the fit.
//!
//! **The candidates** (a fixed sequence, each stage starting from the best so far, stopped at
//! `[fit] auto_budget` fits, so the choice is the same on any machine and thread count):
//! 1. `tolerance_weight` on [`TOLERANCE_LADDER`] (the trims, when the catalogue has any, at
//!    [`TRIMMED_START`]; no mass weight; [`SEARCH_RESTARTS`] restarts);
//! 2. `trimmed_weight` on [`TRIMMED_LADDER`] at the best tolerance weight;
//! 3. `mass_weight` on [`MASS_LADDER`] at the best pair, lightest last, stopped at the first that
//!    is not [admissible](Choice::admissible) (a heavier weight only costs more accuracy);
//! 4. the winner with the default 128 restarts, which the rule keeps only if it measures
//!    better.
//!
//! A weight the design sets is never varied: its stage is skipped and every candidate carries it.
//!
//! **The rule.** Each candidate is measured by its nominal p99 on the held-out fan, the p95 over
//! builds of the untrimmed builds' p99, that of the trimmed builds (with trim springs) and the
//! springs' mass by the parts chosen. A candidate is *admissible* when each of its accuracy
//! figures x is within the slack of the best x any candidate reached:
//! x ≤ (1 + [`RELATIVE_SLACK`])·best + [`ABSOLUTE_SLACK_DEG`]. The relative slack is the
//! spread the hand grids showed between neighbouring weights' bills (10–20 %), the absolute one
//! what a p95 over 1,000 builds is known to (±0.05°): no closer can be told apart. The winner is
//! the lightest admissible candidate; when none is admissible (no candidate is best at every
//! figure and each loses more than the slack somewhere), the one whose worst excess over its
//! slack is least. Ties go to the earlier candidate.

use serde::Serialize;

use crate::design::fit::FitSettings;

/// `tolerance_weight`s tried, in order: the hand-chosen values of the shipped designs span
/// 0.002 (cams, where the trims do the work) to 1 (the expected residual over builds).
pub const TOLERANCE_LADDER: [f64; 4] = [0.03, 0.1, 0.3, 1.0];

/// `trimmed_weight` while the tolerance weight is chosen (designs with trims).
pub const TRIMMED_START: f64 = 0.2;

/// `trimmed_weight`s tried after the tolerance weight (with [`TRIMMED_START`] already measured).
pub const TRIMMED_LADDER: [f64; 2] = [0.05, 0.5];

/// `mass_weight`s tried, lightest bill last: at 0.00582 the default design's springs weigh a third
/// of the unweighted fit's. 0.0003, 0.001 and 0.003 on the weight's former scale (½‖b‖², issue
/// 44), converted by the default design's ½‖b‖²/m = 5.816·(1°)² (`fit::mass`).
pub const MASS_LADDER: [f64; 3] = [0.00174, 0.00582, 0.0174];

/// Factor by which the refining stage moves each weight about the most promising candidate:
/// half a step of [`TOLERANCE_LADDER`] (×√√10) on a log scale, so the refined points fall between
/// the ladder's.
pub const REFINE_FACTOR: f64 = 1.778_279_410_038_922_8;

/// Rounds of the refining stage: each round moves the weights about the candidate nearest the
/// aims so far by the square root of the previous round's factor (×1.78, ×1.33, ×1.15), a
/// compass search whose step halves on a log scale; the budget usually ends it first.
pub const REFINE_ROUNDS: u32 = 3;

/// Restarts of the selection during the search: 16 chose the same springs as 32–128 on the
/// default design and cost a third of the solve (docs/designs.md).
pub const SEARCH_RESTARTS: usize = 16;

/// Share by which a figure may exceed the best reached and still count as as good.
pub const RELATIVE_SLACK: f64 = 0.15;

/// Degrees by which a figure may exceed the best reached and still count as as good.
pub const ABSOLUTE_SLACK_DEG: f64 = 0.05;

/// The weights of one candidate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Weights {
    /// `tolerance_weight`.
    pub tolerance_weight: f64,
    /// `trimmed_weight`.
    pub trimmed_weight: f64,
    /// `mass_weight`.
    pub mass_weight: f64,
    /// `restarts`.
    pub restarts: usize,
}

impl Weights {
    /// The weights of `settings`.
    pub fn of(settings: &FitSettings) -> Weights {
        Weights {
            tolerance_weight: settings.tolerance_weight,
            trimmed_weight: settings.trimmed_weight,
            mass_weight: settings.mass_weight,
            restarts: settings.restarts,
        }
    }

    /// `settings` with these weights.
    pub fn apply(self, settings: &FitSettings) -> FitSettings {
        FitSettings {
            tolerance_weight: self.tolerance_weight,
            trimmed_weight: self.trimmed_weight,
            mass_weight: self.mass_weight,
            restarts: self.restarts,
            ..*settings
        }
    }
}

/// What a candidate measured.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Figures {
    /// p99 |residual angle| on the held-out fan, degrees.
    pub p99_deg: f64,
    /// p95 over the builds of their p99, untrimmed, degrees (None: no builds).
    pub built_p95_deg: Option<f64>,
    /// The same of the trimmed builds (None: no trims).
    pub trimmed_p95_deg: Option<f64>,
    /// The springs' mass by the parts chosen, kg.
    pub spring_mass_kg: f64,
    /// Elements in the bill.
    pub used: usize,
}

impl Figures {
    /// The accuracy figures, in the order of [`Figures`] (absent ones as None).
    fn accuracy(&self) -> [Option<f64>; 3] {
        [Some(self.p99_deg), self.built_p95_deg, self.trimmed_p95_deg]
    }
}

/// Which stage of the search a candidate belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Stage {
    /// The tolerance weight's ladder (or the design's weights when it sets them).
    Tolerance,
    /// The trimmed weight's ladder.
    Trimmed,
    /// Each chosen weight moved by [`REFINE_FACTOR`] either way about the most promising
    /// candidate (a small search in the plane of the two weights).
    Refine,
    /// The mass weight's ladder.
    Mass,
    /// The winner with the default restarts.
    Restarts,
}

/// One candidate tried and what it measured.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Tried {
    /// The stage that proposed it.
    pub stage: Stage,
    /// Its weights.
    pub weights: Weights,
    /// Its figures (None: its fit failed, e.g. infeasible at these weights).
    pub figures: Option<Figures>,
}

/// What the design states it needs (`[fit] aim_p99_deg`, `aim_untrimmed_p95_deg`,
/// `aim_trimmed_p95_deg`), in the order of the accuracy figures; None: no aim on that figure.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Aims {
    /// Nominal p99 on the held-out fan, degrees.
    pub p99_deg: Option<f64>,
    /// p95 over the builds of the untrimmed builds' p99, degrees.
    pub untrimmed_p95_deg: Option<f64>,
    /// The same of the trimmed builds, degrees.
    pub trimmed_p95_deg: Option<f64>,
}

impl Aims {
    /// The aims of `settings` (an aim of 0 is none).
    pub fn of(settings: &FitSettings) -> Aims {
        let aim = |x: f64| (x > 0.0).then_some(x);
        Aims {
            p99_deg: aim(settings.aim_p99_deg),
            untrimmed_p95_deg: aim(settings.aim_untrimmed_p95_deg),
            trimmed_p95_deg: aim(settings.aim_trimmed_p95_deg),
        }
    }

    /// Whether any aim is stated.
    pub fn any(&self) -> bool {
        self.array().iter().any(Option::is_some)
    }

    fn array(&self) -> [Option<f64>; 3] {
        [self.p99_deg, self.untrimmed_p95_deg, self.trimmed_p95_deg]
    }

    /// The worst relative excess of `f` over the aims, (x − aim)/aim: ≤ 0 when `f` meets every
    /// aim; +∞ when an aimed figure was not measured (e.g. an aim on the trimmed builds of a
    /// catalogue without trims); −∞ without aims.
    pub fn excess(&self, f: &Figures) -> f64 {
        self.array()
            .iter()
            .zip(f.accuracy())
            .filter_map(|(aim, x)| aim.map(|a| x.map_or(f64::INFINITY, |x| (x - a) / a)))
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// Whether `f` meets every aim stated (false without aims).
    pub fn met(&self, f: &Figures) -> bool {
        self.any() && self.excess(f) <= 0.0
    }
}

/// The candidates tried and the one chosen: what `fit` prints and reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Choice {
    /// Every candidate, in the order tried.
    pub tried: Vec<Tried>,
    /// Index into `tried` of the winner.
    pub chosen: usize,
    /// The most candidate fits allowed (`[fit] auto_budget`).
    pub budget: usize,
    /// The design's aims.
    pub aims: Aims,
    /// Whether the winner meets every aim (false without aims: chosen by the slack rule).
    pub aims_met: bool,
}

impl Choice {
    /// The rule that chose the winner, in words (what `fit` prints and `report.md` states).
    pub fn rule_phrase(&self) -> String {
        let slack = "the lightest within 15 % + 0.05° of the best of each figure";
        if !self.aims.any() {
            return slack.to_string();
        }
        let names = ["p99", "untrimmed p95", "trimmed p95"];
        let aims: Vec<String> =
            self.aims.array().iter().zip(names).filter_map(|(a, n)| a.map(|a| format!("{n} ≤ {a}°"))).collect();
        if self.aims_met {
            format!("the lightest meeting the design's aims {}", aims.join(", "))
        } else {
            format!("no candidate met the design's aims {}, so {slack}", aims.join(", "))
        }
    }

    /// The best of each accuracy figure over the candidates measured.
    fn best(tried: &[Tried]) -> [Option<f64>; 3] {
        let mut best = [None; 3];
        for f in tried.iter().filter_map(|t| t.figures) {
            for (b, x) in best.iter_mut().zip(f.accuracy()) {
                if let Some(x) = x {
                    *b = Some(b.map_or(x, |b: f64| b.min(x)));
                }
            }
        }
        best
    }

    /// The worst excess of `f`'s accuracy figures over their slack about `best`: ≤ 0 when
    /// admissible.
    fn excess(f: &Figures, best: &[Option<f64>; 3]) -> f64 {
        f.accuracy()
            .iter()
            .zip(best)
            .filter_map(|(x, b)| Some((x.as_ref()?, b.as_ref()?)))
            .map(|(&x, &b)| {
                let slack = RELATIVE_SLACK * b + ABSOLUTE_SLACK_DEG;
                (x - b - slack) / slack
            })
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// Whether `f` is admissible among `tried`: it meets the aims, or without aims (or while
    /// no candidate meets them) it is within the slack of the best.
    pub fn admissible(f: &Figures, tried: &[Tried], aims: &Aims) -> bool {
        if aims.any() && tried.iter().filter_map(|t| t.figures).any(|g| aims.met(&g)) {
            return aims.met(f);
        }
        Choice::excess(f, &Choice::best(tried)) <= 0.0
    }

    /// The winner among `tried` by the rule (None: no candidate measured): the lightest that
    /// meets every aim; without aims, or when none meets them, the lightest within the slack
    /// of the best of each figure.
    pub fn winner(tried: &[Tried], aims: &Aims) -> Option<usize> {
        let best = Choice::best(tried);
        let measured = || tried.iter().enumerate().filter_map(|(i, t)| t.figures.map(|f| (i, f)));
        let by_mass = |a: &(usize, Figures), b: &(usize, Figures)| {
            a.1.spring_mass_kg.total_cmp(&b.1.spring_mass_kg).then(a.0.cmp(&b.0))
        };
        if let Some((i, _)) = measured().filter(|(_, f)| aims.met(f)).min_by(by_mass) {
            return Some(i);
        }
        let lightest = measured()
            .filter(|(_, f)| Choice::excess(f, &best) <= 0.0)
            .min_by(|a, b| a.1.spring_mass_kg.total_cmp(&b.1.spring_mass_kg).then(a.0.cmp(&b.0)));
        lightest
            .or_else(|| {
                measured().min_by(|a, b| {
                    Choice::excess(&a.1, &best).total_cmp(&Choice::excess(&b.1, &best)).then(a.0.cmp(&b.0))
                })
            })
            .map(|(i, _)| i)
    }

    /// The most balanced candidate so far, the next stage's starting point: the least worst
    /// excess over the slack, mass aside; with aims, the least worst excess over the aims.
    fn centre(tried: &[Tried], aims: &Aims) -> Option<usize> {
        let best = Choice::best(tried);
        let key = |f: &Figures| if aims.any() { aims.excess(f) } else { Choice::excess(f, &best) };
        tried
            .iter()
            .enumerate()
            .filter_map(|(i, t)| t.figures.map(|f| (i, f)))
            .min_by(|a, b| key(&a.1).total_cmp(&key(&b.1)).then(a.0.cmp(&b.0)))
            .map(|(i, _)| i)
    }
}

/// The search: proposes the next candidate from what has been measured.
#[derive(Debug, Clone)]
pub struct Search {
    settings: FitSettings,
    trims: bool,
    tried: Vec<Tried>,
    queue: Vec<Weights>,
    stage: Option<Stage>,
    /// Refining rounds begun.
    refine_round: u32,
}

impl Search {
    /// A search for `settings` (whose `auto` says which weights to choose) on a catalogue with
    /// trim springs or not.
    pub fn new(settings: &FitSettings, trims: bool) -> Search {
        Search { settings: *settings, trims, tried: Vec::new(), queue: Vec::new(), stage: None, refine_round: 0 }
    }

    /// Whether the fit job should search at all: some weight is left to springfit and the fit
    /// is judged on builds (a tolerance and builds to draw). Otherwise the design's numbers (the
    /// defaults for the keys it leaves out) are fitted as they are.
    pub fn wanted(settings: &FitSettings) -> bool {
        use crate::design::tolerance::ToleranceSpec;
        settings.auto.any()
            && settings.builds > 0
            && !matches!(settings.tolerance, ToleranceSpec::None | ToleranceSpec::Parts)
    }

    /// The weights the search starts from: the design's where it sets them.
    fn start(&self) -> Weights {
        let (s, a) = (&self.settings, self.settings.auto);
        Weights {
            tolerance_weight: s.tolerance_weight,
            trimmed_weight: match (a.trimmed_weight, self.trims) {
                (true, true) => TRIMMED_START,
                (true, false) => 0.0,
                (false, _) => s.trimmed_weight,
            },
            mass_weight: if a.mass_weight { 0.0 } else { s.mass_weight },
            restarts: if a.restarts { SEARCH_RESTARTS } else { s.restarts },
        }
    }

    /// The candidates of `stage` from `from` (empty when the stage's weight is the design's).
    fn stage(&self, stage: Stage, from: Weights) -> Vec<Weights> {
        let a = self.settings.auto;
        match stage {
            Stage::Tolerance if a.tolerance_weight => {
                TOLERANCE_LADDER.iter().map(|&t| Weights { tolerance_weight: t, ..from }).collect()
            }
            Stage::Tolerance => vec![from],
            Stage::Trimmed if a.trimmed_weight && self.trims => {
                TRIMMED_LADDER.iter().map(|&w| Weights { trimmed_weight: w, ..from }).collect()
            }
            Stage::Refine if Aims::of(&self.settings).any() => {
                let mut q = Vec::new();
                let step = REFINE_FACTOR.powf(0.5f64.powi(self.refine_round as i32));
                for f in [step, 1.0 / step] {
                    if a.tolerance_weight {
                        q.push(Weights { tolerance_weight: round(from.tolerance_weight * f), ..from });
                    }
                    if a.trimmed_weight && self.trims && from.trimmed_weight > 0.0 {
                        q.push(Weights { trimmed_weight: round(from.trimmed_weight * f), ..from });
                    }
                }
                q
            }
            Stage::Mass if a.mass_weight => MASS_LADDER.iter().map(|&m| Weights { mass_weight: m, ..from }).collect(),
            Stage::Restarts if a.restarts => {
                vec![Weights { restarts: FitSettings::default().restarts, ..from }]
            }
            _ => Vec::new(),
        }
    }

    /// The next candidate to measure, None when done (every stage run or the budget spent).
    pub fn propose(&mut self) -> Option<(Stage, Weights)> {
        if self.tried.len() >= self.settings.auto_budget {
            return None;
        }
        let aims = Aims::of(&self.settings);
        // A mass weight that costs more than the slack (or misses the aims) ends its ladder:
        // heavier ones cost more.
        if self.stage == Some(Stage::Mass)
            && let Some(last) = self.tried.last()
            && last.stage == Stage::Mass
            && last.figures.is_none_or(|f| !Choice::admissible(&f, &self.tried, &aims))
        {
            self.queue.clear();
        }
        // Once a candidate meets the aims, the accuracy stages end: what is left to try is a
        // lighter bill that still meets them.
        let met = self.tried.iter().filter_map(|t| t.figures).any(|f| aims.met(&f));
        if met && matches!(self.stage, Some(Stage::Tolerance | Stage::Trimmed | Stage::Refine)) {
            self.queue.clear();
            self.stage = Some(Stage::Refine);
        }
        while self.queue.is_empty() {
            let next = match self.stage {
                None => Stage::Tolerance,
                Some(Stage::Tolerance) => Stage::Trimmed,
                Some(Stage::Trimmed) => Stage::Refine,
                Some(Stage::Refine)
                    if !met && self.refine_round + 1 < REFINE_ROUNDS && Aims::of(&self.settings).any() =>
                {
                    self.refine_round += 1;
                    Stage::Refine
                }
                Some(Stage::Refine) => Stage::Mass,
                // With the aims met, more restarts only cost: the selection's objective is not
                // what the aims measure.
                Some(Stage::Mass) if met => return None,
                Some(Stage::Mass) => Stage::Restarts,
                Some(Stage::Restarts) => return None,
            };
            let from = match next {
                Stage::Tolerance => Some(self.start()),
                // The mass and restart stages go on from the winner so far (the lightest
                // admissible), the others from the most balanced.
                Stage::Restarts => Choice::winner(&self.tried, &aims).map(|i| self.tried[i].weights),
                Stage::Mass if met => Choice::winner(&self.tried, &aims).map(|i| self.tried[i].weights),
                _ => Choice::centre(&self.tried, &aims).map(|i| self.tried[i].weights),
            };
            self.stage = Some(next);
            let from = from?;
            let mut q = self.stage(next, from);
            q.retain(|w| !self.tried.iter().any(|t| t.weights == *w));
            q.reverse();
            self.queue = q;
        }
        let w = self.queue.pop()?;
        Some((self.stage.unwrap_or(Stage::Tolerance), w))
    }

    /// Records what the last candidate proposed measured.
    pub fn record(&mut self, stage: Stage, weights: Weights, figures: Option<Figures>) {
        self.tried.push(Tried { stage, weights, figures });
    }

    /// The choice (None: no candidate could be fitted).
    pub fn finish(self) -> Option<Choice> {
        let aims = Aims::of(&self.settings);
        let chosen = Choice::winner(&self.tried, &aims)?;
        let aims_met = self.tried[chosen].figures.is_some_and(|f| aims.met(&f));
        Some(Choice { tried: self.tried, chosen, budget: self.settings.auto_budget, aims, aims_met })
    }
}

/// A weight rounded to three significant figures, so that the refined candidates print and
/// compare as the numbers a design file would hold.
fn round(x: f64) -> f64 {
    if x <= 0.0 {
        return x;
    }
    let scale = 10f64.powi(2 - x.log10().floor() as i32);
    (x * scale).round() / scale
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::fit::AutoWeights;
    use crate::design::tolerance::ToleranceSpec;

    fn figures(p99: f64, built: f64, trimmed: f64, mass: f64) -> Option<Figures> {
        Some(Figures {
            p99_deg: p99,
            built_p95_deg: Some(built),
            trimmed_p95_deg: Some(trimmed),
            spring_mass_kg: mass,
            used: 12,
        })
    }

    fn all_auto() -> FitSettings {
        let auto = AutoWeights { tolerance_weight: true, trimmed_weight: true, mass_weight: true, restarts: true };
        FitSettings { tolerance: ToleranceSpec::Fraction(0.05), auto, auto_budget: 64, ..FitSettings::default() }
    }

    /// A made-up design whose figures are known for every weight: accuracy best at a tolerance
    /// weight of 0.3 and a trimmed weight of 0.2, the mass halving per mass-weight step while
    /// the untrimmed p95 grows by 0.2° per step.
    fn measure(w: Weights) -> Option<Figures> {
        let t = (w.tolerance_weight.log10() - 0.3f64.log10()).abs();
        let m = MASS_LADDER.iter().position(|&x| x == w.mass_weight).map_or(0.0, |i| i as f64 + 1.0);
        let trim = if w.trimmed_weight == 0.2 { 0.8 } else { 0.9 };
        figures(0.3 + 0.2 * t, 2.0 + t + 0.2 * m, trim, 10.0 / 2f64.powf(m))
    }

    #[test]
    fn the_search_finds_the_known_best_and_the_lightest_within_the_slack() {
        let mut search = Search::new(&all_auto(), true);
        while let Some((stage, w)) = search.propose() {
            search.record(stage, w, measure(w));
        }
        let choice = search.finish().unwrap();
        let w = choice.tried[choice.chosen].weights;
        assert_eq!((w.tolerance_weight, w.trimmed_weight), (0.3, 0.2), "{choice:#?}");
        // 2.0 + 0.35 (the slack at best 2.0) admits one mass step (+0.2°), not two (+0.4°).
        assert_eq!(w.mass_weight, MASS_LADDER[0], "{choice:#?}");
        // The ladder stopped at the first mass weight that was not admissible.
        let masses = choice.tried.iter().filter(|t| t.stage == Stage::Mass).count();
        assert_eq!(masses, 2, "{choice:#?}");
        assert!(choice.tried.iter().any(|t| t.stage == Stage::Restarts));
    }

    #[test]
    fn the_rule_prefers_the_lighter_of_two_as_good_and_the_better_of_two_unequal() {
        let w = Weights { tolerance_weight: 0.1, trimmed_weight: 0.0, mass_weight: 0.0, restarts: 16 };
        let tried = |a, b| {
            vec![
                Tried { stage: Stage::Mass, weights: w, figures: a },
                Tried { stage: Stage::Mass, weights: w, figures: b },
            ]
        };
        // As good within the slack: the lighter wins.
        let none = Aims::default();
        assert_eq!(
            Choice::winner(&tried(figures(0.36, 2.4, 0.9, 12.0), figures(0.40, 2.5, 0.92, 3.0)), &none),
            Some(1)
        );
        // The lighter builds 1° worse: the heavier wins.
        assert_eq!(
            Choice::winner(&tried(figures(0.36, 2.4, 0.9, 12.0), figures(0.40, 3.4, 0.92, 3.0)), &none),
            Some(0)
        );
        // A failed candidate never wins.
        assert_eq!(Choice::winner(&tried(None, figures(0.40, 3.4, 0.92, 3.0)), &none), Some(1));
    }

    #[test]
    fn weights_the_design_sets_are_never_varied() {
        let settings = FitSettings {
            tolerance_weight: 0.17,
            trimmed_weight: 0.22,
            restarts: 16,
            auto: AutoWeights { mass_weight: true, ..AutoWeights::default() },
            ..all_auto()
        };
        let mut search = Search::new(&settings, true);
        while let Some((stage, w)) = search.propose() {
            assert_eq!((w.tolerance_weight, w.trimmed_weight, w.restarts), (0.17, 0.22, 16));
            search.record(stage, w, measure(w));
        }
        let choice = search.finish().unwrap();
        assert_eq!(choice.tried[0].weights.mass_weight, 0.0);
    }

    #[test]
    fn the_aims_take_a_candidate_that_meets_them_where_the_slack_rule_took_one_that_misses() {
        // The default design's case: the lightest within the slack builds at 2.6° untrimmed,
        // past the 2.5° the design needs; a heavier candidate meets every aim.
        let w = Weights { tolerance_weight: 0.1, trimmed_weight: 0.2, mass_weight: 0.0, restarts: 16 };
        let tried: Vec<Tried> =
            [figures(0.30, 2.60, 0.95, 10.0), figures(0.37, 2.37, 0.87, 12.0), figures(0.27, 2.73, 1.06, 8.0)]
                .into_iter()
                .map(|f| Tried { stage: Stage::Tolerance, weights: w, figures: f })
                .collect();
        assert_eq!(Choice::winner(&tried, &Aims::default()), Some(0));
        let aims = Aims { p99_deg: Some(0.4), untrimmed_p95_deg: Some(2.5), trimmed_p95_deg: Some(1.0) };
        assert_eq!(Choice::winner(&tried, &aims), Some(1));
        // Of two that meet them, the lighter.
        let mut lighter = tried.clone();
        lighter.push(Tried { figures: figures(0.39, 2.45, 0.99, 11.0), ..tried[0] });
        assert_eq!(Choice::winner(&lighter, &aims), Some(3));
        // An aim on a figure that was not measured is not met: the slack rule stands.
        let untrimmed_only: Vec<Tried> = tried
            .iter()
            .map(|t| Tried { figures: t.figures.map(|f| Figures { trimmed_p95_deg: None, ..f }), ..*t })
            .collect();
        assert_eq!(
            Choice::winner(&untrimmed_only, &aims),
            Some(2),
            "the 8 kg candidate is within the slack without the trimmed figure"
        );
    }

    #[test]
    fn the_refining_stage_finds_a_weight_between_the_rungs_and_the_search_stops_at_the_aims() {
        // The builds are best at a tolerance weight of 0.17, between the ladder's 0.1 and 0.3,
        // and only within about 0.1 decade of it do they meet the aim of 2.1°.
        let measure = |w: Weights| {
            let t = (w.tolerance_weight.log10() - 0.17f64.log10()).abs();
            figures(0.3 + 0.2 * t, 2.0 + t, 0.8, 10.0)
        };
        let settings = FitSettings {
            aim_p99_deg: 0.4,
            aim_untrimmed_p95_deg: 2.1,
            auto: AutoWeights { tolerance_weight: true, trimmed_weight: true, ..AutoWeights::default() },
            ..all_auto()
        };
        let mut search = Search::new(&settings, true);
        while let Some((stage, w)) = search.propose() {
            search.record(stage, w, measure(w));
        }
        let choice = search.finish().unwrap();
        assert!(choice.aims_met, "{choice:#?}");
        let winner = choice.tried[choice.chosen];
        assert_eq!(winner.stage, Stage::Refine, "{choice:#?}");
        assert_eq!(winner.weights.tolerance_weight, 0.178, "{choice:#?}");
        // The search stopped at the first candidate meeting the aims: no restarts stage.
        assert_eq!(choice.chosen, choice.tried.len() - 1, "{choice:#?}");
        assert!(choice.tried.iter().all(|t| t.stage != Stage::Restarts));
        assert!(choice.rule_phrase().starts_with("the lightest meeting"), "{}", choice.rule_phrase());
        // Without aims there is no refining stage, as before.
        let mut plain = Search::new(&FitSettings { aim_p99_deg: 0.0, aim_untrimmed_p95_deg: 0.0, ..settings }, true);
        while let Some((stage, w)) = plain.propose() {
            assert_ne!(stage, Stage::Refine);
            plain.record(stage, w, measure(w));
        }
    }

    #[test]
    fn aims_in_a_design_file_leave_the_weights_it_omits_to_springfit() {
        let table = |text: &str| toml::from_str::<toml::Table>(text).unwrap();
        let with_aims = table("aim_untrimmed_p95_deg = 2.5\ntrimmed_weight = 0.2\n");
        let a = AutoWeights::of_table(Some(&with_aims));
        assert!(a.tolerance_weight && !a.trimmed_weight && a.restarts && !a.mass_weight, "{a:?}");
        let without = table("trimmed_weight = 0.2\n");
        assert!(!AutoWeights::of_table(Some(&without)).any());
        let zero_aim = table("aim_p99_deg = 0\n");
        assert!(!AutoWeights::of_table(Some(&zero_aim)).any());
    }
}
