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

/// The candidates tried and the one chosen: what `fit` prints and reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Choice {
    /// Every candidate, in the order tried.
    pub tried: Vec<Tried>,
    /// Index into `tried` of the winner.
    pub chosen: usize,
    /// The most candidate fits allowed (`[fit] auto_budget`).
    pub budget: usize,
}

impl Choice {
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

    /// Whether `f` is admissible among `tried`.
    pub fn admissible(f: &Figures, tried: &[Tried]) -> bool {
        Choice::excess(f, &Choice::best(tried)) <= 0.0
    }

    /// The winner among `tried` by the rule (None: no candidate measured).
    pub fn winner(tried: &[Tried]) -> Option<usize> {
        let best = Choice::best(tried);
        let measured = || tried.iter().enumerate().filter_map(|(i, t)| t.figures.map(|f| (i, f)));
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
    /// excess, mass aside.
    fn centre(tried: &[Tried]) -> Option<usize> {
        let best = Choice::best(tried);
        tried
            .iter()
            .enumerate()
            .filter_map(|(i, t)| t.figures.map(|f| (i, f)))
            .min_by(|a, b| Choice::excess(&a.1, &best).total_cmp(&Choice::excess(&b.1, &best)).then(a.0.cmp(&b.0)))
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
}

impl Search {
    /// A search for `settings` (whose `auto` says which weights to choose) on a catalogue with
    /// trim springs or not.
    pub fn new(settings: &FitSettings, trims: bool) -> Search {
        Search { settings: *settings, trims, tried: Vec::new(), queue: Vec::new(), stage: None }
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
        // A mass weight that costs more than the slack ends its ladder: heavier ones cost more.
        if self.stage == Some(Stage::Mass)
            && let Some(last) = self.tried.last()
            && last.stage == Stage::Mass
            && last.figures.is_none_or(|f| !Choice::admissible(&f, &self.tried))
        {
            self.queue.clear();
        }
        while self.queue.is_empty() {
            let next = match self.stage {
                None => Stage::Tolerance,
                Some(Stage::Tolerance) => Stage::Trimmed,
                Some(Stage::Trimmed) => Stage::Mass,
                Some(Stage::Mass) => Stage::Restarts,
                Some(Stage::Restarts) => return None,
            };
            let from = match next {
                Stage::Tolerance => Some(self.start()),
                // The mass and restart stages go on from the winner so far (the lightest
                // admissible), the others from the most balanced.
                Stage::Restarts => Choice::winner(&self.tried).map(|i| self.tried[i].weights),
                _ => Choice::centre(&self.tried).map(|i| self.tried[i].weights),
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
        let chosen = Choice::winner(&self.tried)?;
        Some(Choice { tried: self.tried, chosen, budget: self.settings.auto_budget })
    }
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
        assert_eq!(Choice::winner(&tried(figures(0.36, 2.4, 0.9, 12.0), figures(0.40, 2.5, 0.92, 3.0))), Some(1));
        // The lighter builds 1° worse: the heavier wins.
        assert_eq!(Choice::winner(&tried(figures(0.36, 2.4, 0.9, 12.0), figures(0.40, 3.4, 0.92, 3.0))), Some(0));
        // A failed candidate never wins.
        assert_eq!(Choice::winner(&tried(None, figures(0.40, 3.4, 0.92, 3.0))), Some(1));
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
}
