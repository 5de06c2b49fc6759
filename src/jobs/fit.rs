//! `springfit fit` and Python's `Design.fit()`: the fit with its parts (or the exact reference),
//! then the as-built builds.
//!
//! The feature's files: the settings `design/fit.rs` and `design/tolerance.rs`, the fit itself
//! `fit/` (`fit/run.rs` fits once; `parts::fit_with_parts` refits at the parts' tolerances), the
//! parts `parts/` and `realise/`, the builds `asbuilt/`, the files `files/bom.rs`, `files/cam.rs`
//! and `report/fit.rs`, the command `cli/fit.rs`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use super::{Topic, Warning};
use crate::asbuilt::AsBuilt;
use crate::design::Design;
use crate::design::fit::{FitSettings, SolverKind};
use crate::elements::catalog::Catalog;
use crate::error::{Error, Result};
use crate::fit::FitOutcome;
use crate::fit::Prepared;
use crate::fit::auto::{Figures, Search};
use crate::fit::hints;
use crate::fit::outcome::RefitComparison;
use crate::parts::Parts;
use crate::progress::Progress;
use crate::realise::placement;
use crate::report::output::Claim;
use crate::studies::compare::FitRecord;

/// What a fit is asked beyond the design: the command's options.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FitRequest {
    /// The exact potential ½ω²r² (the physical limit) instead of springs (`--exact`).
    pub exact: bool,
    /// Replaces `[fit] solver`.
    pub solver: Option<SolverKind>,
    /// Replaces `[fit] max_elements` (0: no limit).
    pub max_elements: Option<usize>,
}

impl FitRequest {
    /// The design's `[fit]` with the request's replacements, checked.
    pub fn settings(&self, design: &Design) -> Result<FitSettings> {
        let mut settings = design.fit;
        if let Some(s) = self.solver {
            settings.solver = s;
        }
        if let Some(k) = self.max_elements {
            settings.max_elements = k;
        }
        settings.validate().map_err(|(field, reason)| Error::Setting { field, reason })?;
        Ok(settings)
    }

    /// The names the fit's output folder may hold (for its [`crate::report::output::Plan`]).
    pub fn files(&self) -> Vec<&'static str> {
        crate::report::fit::files(!self.exact)
    }
}

/// A fit whose settings are checked, ready to run.
#[derive(Debug)]
pub struct FitJob<'a> {
    design: &'a Design,
    catalog: Option<&'a Catalog>,
    settings: FitSettings,
    exact: bool,
}

impl<'a> FitJob<'a> {
    /// Checks the settings `request` gives `design`. The stock list and the catalogue are
    /// checked when the job runs, after the command has claimed its output folder: a refused
    /// folder is the first error, as it always was.
    pub fn new(design: &'a Design, catalog: Option<&'a Catalog>, request: FitRequest) -> Result<FitJob<'a>> {
        let settings = request.settings(design)?;
        Ok(FitJob { design, catalog, settings, exact: request.exact })
    }

    /// The settings the fit runs with.
    pub fn settings(&self) -> &FitSettings {
        &self.settings
    }

    /// Reads the stock list `[parts] stock` names and fits (the parts are chosen with the fit:
    /// `tolerance = "parts"` refits at their tolerances), then draws the as-built builds; or
    /// evaluates the exact reference. An infeasible fit's error names the key to change
    /// ([`hints::explain`]).
    pub fn run(self, progress: Progress<'_>) -> Result<FitRun> {
        let (design, settings) = (self.design, &self.settings);
        let catalog = match (self.exact, self.catalog) {
            (true, _) => None,
            (false, catalog) => {
                let stock = crate::files::stock::of_design(design)?;
                let Some(catalog) = catalog else {
                    return Err(Error::invalid(
                        &design.path,
                        "catalog",
                        "the design names no spring catalogue (catalog = \"../catalogs/paper.toml\"); `springfit fit --exact` needs none",
                    ));
                };
                Some((catalog, stock))
            }
        };
        // The catalogue with its trims' ranges sized by the bill, when a family asks for it: the
        // fit, parts, builds and warnings from here on are of that catalogue.
        let mut sized_catalog = None;
        let (mut outcome, parts, chosen, placed) = match &catalog {
            None => (crate::fit::run::exact_reference(design, settings, progress)?, None, None, None),
            Some((catalog, stock)) => {
                let (fitted, sized) = fit_sized(design, catalog, settings, stock, progress)?;
                sized_catalog = sized;
                let catalog = sized_catalog.as_ref().unwrap_or(catalog);
                let ((o, p, c), placed) =
                    placement_rounds(design, (catalog, stock.as_slice()), settings, progress, fitted)?;
                (o, Some(p), c, placed)
            }
        };
        let catalog = catalog.map(|(c, stock)| (sized_catalog.as_ref().unwrap_or(c), stock));
        // With placement rounds, the arm that carries its parts is the design from here on: the
        // fit was made for it, and its builds and diagnosis are of it.
        let design = placed.as_ref().unwrap_or(design);
        if let Some((catalog, _)) = &catalog
            && !crate::fit::outcome::Verdict::ideal(outcome.metrics.stats.p99_abs, settings.accept_p99_deg)
                .residual_passes()
        {
            progress.stage("diagnosing the poor fit");
            // The trims are held at their billed rates: the screened springs answer the rest.
            let trims: Vec<usize> =
                (0..outcome.bom.len()).filter(|&j| outcome.bom[j].adjust.trim_range.is_some()).collect();
            let held = crate::potential::SpringSet {
                elements: trims.iter().map(|&j| outcome.springs.elements[j].clone()).collect(),
                stiffness: trims.iter().map(|&j| outcome.springs.stiffness[j]).collect(),
            };
            let mut d = crate::fit::diagnosis::diagnose(
                design,
                catalog,
                settings,
                (&outcome.springs, &held),
                &outcome.training,
            )?;
            d.needed_omega = super::init::stiffness(design).ok().map(|s| s.needed_omega);
            outcome.diagnosis = Some(d);
        }
        let t = Instant::now();
        let as_built = match (&catalog, chosen) {
            (None, _) => None,
            // The chosen candidate's builds were drawn while choosing.
            (Some(_), Some(as_built)) => as_built,
            (Some(_), None) => {
                progress.stage("as-built Monte Carlo builds");
                crate::asbuilt::of_fit(design, &outcome)?
            }
        };
        let as_built_seconds = t.elapsed().as_secs_f64();
        let warnings = catalog
            .map(|(c, _)| warnings(design, settings, c, (&outcome, as_built.as_ref()), parts.as_ref()))
            .unwrap_or_default();
        Ok(FitRun { outcome, parts, as_built, as_built_seconds, exact: self.exact, warnings })
    }
}

/// A fit and its parts, and the as-built builds when the weights were chosen (they were drawn
/// while choosing).
type Fitted = (FitOutcome, Parts, Option<Option<AsBuilt>>);

/// The fit of springs with its parts: with weights set to `"auto"` the choice over candidates
/// ([`choose_weights`]), else [`crate::parts::fit_with_parts`]. An infeasible fit's error
/// names the key to change ([`hints::explain`]).
fn fit_springs(
    design: &Design,
    catalog: &Catalog,
    settings: &FitSettings,
    stock: &[crate::parts::StockPart],
    progress: Progress<'_>,
) -> Result<Fitted> {
    let fitted = if Search::wanted(settings) {
        choose_weights(design, catalog, settings, stock, progress).map(|(o, p, ab)| (o, p, Some(ab)))
    } else {
        crate::parts::fit_with_parts(design, catalog, settings, stock, progress).map(|(o, p)| (o, p, None))
    };
    fitted.map_err(|e| hints::explain(design, settings, catalog, settings.max_elements, e))
}

/// [`fit_springs`] with the trims' ranges sized by the bill ([`crate::asbuilt::sizing`]) when a
/// catalogue family asks for it (`trim_sized = true`): the first fit's bill gives the rates the
/// builds' trims need; when that changes a range, the design is fitted again with the sized
/// catalogue (its trims at their new mid-range rates; the weights the first fit chose, if it
/// chose them, are kept), so the bill, the trims' parts, their mass and the builds are of the
/// sized ranges. That refit is kept only when its p99, drawn and realised with its parts, is no
/// worse than the first fit's by more than [`crate::fit::outcome::REFIT_SLACK`] ([`RefitComparison`]); otherwise the first fit stands with the
/// ranges it started from (trims at a new mid-range leave the other springs a different
/// potential to make: on a planar three-link arm in gravity the refit's drawn p99 was 17.4°
/// against the first's 1.56°). Returns the fit and, when the refit is kept, the sized
/// catalogue. The sizing and the comparison are recorded in [`FitOutcome::trim_sizing`].
fn fit_sized(
    design: &Design,
    catalog: &Catalog,
    settings: &FitSettings,
    stock: &[crate::parts::StockPart],
    progress: Progress<'_>,
) -> Result<(Fitted, Option<Catalog>)> {
    let mut fitted = fit_springs(design, catalog, settings, stock, progress)?;
    let Some((mut sizing, sized)) = size_trims(design, catalog, &fitted.0, progress)? else {
        return Ok((fitted, None));
    };
    let Some(sized) = sized else {
        fitted.0.trim_sizing = Some(sizing);
        return Ok((fitted, None));
    };
    progress.stage("the fit again, around the trims' sized ranges");
    // The weights as the first fit had them (chosen or not): only the trims changed.
    let here = FitSettings { auto: Default::default(), ..fitted.0.settings };
    let auto = fitted.0.auto.take();
    let first_time = fitted.0.timings.total;
    let (mut outcome, parts) = crate::parts::fit_with_parts(design, &sized, &here, stock, progress)
        .map_err(|e| hints::explain(design, &here, &sized, here.max_elements, e))?;
    let p99 = |o: &FitOutcome, p: &Parts| [o.metrics.stats.p99_abs, p.realised.p99_abs];
    let comparison = RefitComparison::of(p99(&fitted.0, &fitted.1), p99(&outcome, &parts));
    sizing.refit = Some(comparison);
    if !comparison.kept {
        fitted.0.auto = auto;
        fitted.0.timings.total += outcome.timings.total;
        fitted.0.trim_sizing = Some(sizing);
        return Ok((fitted, None));
    }
    outcome.auto = auto;
    outcome.timings.total += first_time;
    sizing.refitted = true;
    outcome.trim_sizing = Some(sizing);
    Ok(((outcome, parts, None), Some(sized)))
}

/// The trims' sizing of a fit ([`crate::asbuilt::sizing::size`]) and the catalogue with the sized
/// ranges (None when no range changed); None when no family asks for it or the fit draws no
/// builds (tolerance `"none"` without catalogue tolerances, `builds = 0`): the ranges then stay
/// the catalogue's.
fn size_trims(
    design: &Design,
    catalog: &Catalog,
    outcome: &FitOutcome,
    progress: Progress<'_>,
) -> Result<Option<(crate::fit::outcome::TrimSizing, Option<Catalog>)>> {
    if !catalog.families.iter().any(|f| f.trim_sized) {
        return Ok(None);
    }
    let Some(s) = crate::asbuilt::build_settings(outcome) else { return Ok(None) };
    progress.stage("sizing the trims by the bill");
    let families: Vec<crate::asbuilt::sizing::TrimFamily<'_>> =
        catalog.families.iter().filter_map(|f| f.trim_range.map(|r| (f.name.as_str(), r, f.trim_sized))).collect();
    let (sizing, ranges) = crate::asbuilt::sizing::size(design, &outcome.bom, &outcome.springs, &s, &families)?;
    if families.iter().zip(&ranges).all(|(f, r)| f.1 == *r) {
        return Ok(Some((sizing, None)));
    }
    let mut sized = catalog.clone();
    for f in sized.families.iter_mut() {
        if let Some(at) = families.iter().position(|x| x.0 == f.name) {
            f.trim_range = Some(ranges[at]);
        }
    }
    Ok(Some((sizing, Some(sized))))
}

/// The placed masses' rounds (`[fit] placement_rounds`, docs/parts.md "Where the parts sit"): the
/// parts' masses on moving links ([`crate::realise::placement`]) are added to the design's arm,
/// whose metric and gravity change with them, and the design fitted again on that arm with its
/// parts chosen again, until the springs' mass changes by less than
/// [`placement::CONVERGED`] or `placement_rounds` fits. Each round places the previous fit's
/// parts on the bare arm (the masses are not added twice). The first fit is also judged on the
/// arm carrying its own parts (the error a builder of the fit without placement meets). Returns
/// the last fit, its parts with the rounds in [`crate::parts::Parts::placement`], and the arm
/// it was fitted for (None without rounds, or when no part rides on a moving link).
fn placement_rounds(
    design: &Design,
    (catalog, stock): (&Catalog, &[crate::parts::StockPart]),
    settings: &FitSettings,
    progress: Progress<'_>,
    fitted: Fitted,
) -> Result<(Fitted, Option<Design>)> {
    let (mut outcome, mut parts, mut chosen) = fitted;
    if settings.placement_rounds == 0 {
        return Ok(((outcome, parts, chosen), None));
    }
    let mass = |p: &Parts| p.elements.iter().filter_map(|e| e.part.as_ref().ok()).map(|p| p.mass).sum::<f64>();
    let mut rounds = placement::Rounds {
        rounds: 0,
        converged: false,
        spring_mass_kg: vec![mass(&parts)],
        placed_mass_kg: Vec::new(),
        unplaced_on_placed: None,
    };
    let mut arm = None;
    for round in 1..=settings.placement_rounds {
        let masses = parts.placement.point_masses();
        if masses.is_empty() {
            rounds.converged = true;
            break;
        }
        let moving = parts.placement.moving_mass();
        let mut placed = design.clone();
        placed.chain = design.chain.with_point_masses(&masses);
        progress.stage(&format!("placement round {round}: the fit on the arm carrying {moving:.3} kg of its parts"));
        let (o, p, c) = fit_springs(&placed, catalog, settings, stock, progress)?;
        if round == 1 {
            let judged = crate::parts::choose(
                &placed,
                &outcome.bom,
                &outcome.cams,
                &o.evaluation,
                settings.frequency,
                stock,
                None,
            )?;
            rounds.unplaced_on_placed = Some((judged.ideal, judged.realised));
        }
        let before = mass(&parts);
        (outcome, parts, chosen) = (o, p, c);
        let after = mass(&parts);
        rounds.rounds = round;
        rounds.placed_mass_kg.push(moving);
        rounds.spring_mass_kg.push(after);
        arm = Some(placed);
        if (after - before).abs() < placement::CONVERGED * before {
            rounds.converged = true;
            break;
        }
    }
    parts.placement.rounds = Some(rounds);
    Ok(((outcome, parts, chosen), arm))
}

/// The warning of a bound on the builds' equilibrium shift that acted (it costs accuracy as
/// drawn) or could not be held, with what the builds' shift model says of the softest direction
/// (its net stiffness against the preload error and the gravity it carries) when there are
/// builds; None when the bound was inactive.
fn shift_warning(b: &crate::fit::outcome::ShiftBound, as_built: Option<&AsBuilt>) -> Option<String> {
    use crate::fit::outcome::ShiftAction;
    let what = match &b.action {
        ShiftAction::Inactive => return None,
        ShiftAction::Held => format!(
            "fit.max_shift held the builds' RMS metric equilibrium shift at {:.4} (the fit without it: {:.4}), at {:.3}× the expected squared residual over builds",
            b.rms, b.unbounded_rms, b.objective_ratio
        ),
        ShiftAction::NotMet(reason) => format!(
            "fit.max_shift = {:.4} is not held: the builds' RMS metric equilibrium shift stays {:.4} ({reason})",
            b.bound, b.rms
        ),
    };
    let soft = as_built.and_then(|ab| ab.shift_model).map(|m| {
        format!(
            "; the softest direction (mostly joint {}) has {:.3} N·m/rad of net stiffness against a preload error of {:.3} N·m RMS, the springs carrying {:.3} N·m of gravity along it: raise fit.frequency, tighten the tolerance or move q_eq where gravity loads that direction less",
            m.soft_joint, m.soft_stiffness_nm_per_rad, m.soft_preload_spread_nm, m.soft_gravity_nm
        )
    });
    Some(what + &soft.unwrap_or_default())
}

/// The springs of `design` as `springfit fit` fits them, for the commands that fit a design
/// themselves (`simulate`, `sweep`, `compare`, `export`; `parts` without a bill does not, as
/// `jobs/parts.rs` is what this file takes its warnings from): with weights
/// set to `"auto"` the same choice over candidates (its parts and builds included, so it costs
/// what `fit` costs), otherwise one fit with `settings`. Without this, those commands would fit
/// the default numbers in place of `"auto"` and simulate other springs than `fit` wrote.
pub fn springs_of(
    design: &Design,
    catalog: &Catalog,
    settings: &FitSettings,
    progress: Progress<'_>,
) -> Result<FitOutcome> {
    if catalog.families.iter().any(|f| f.trim_sized) {
        // The trims sized as `fit` sizes them: the same springs.
        let stock = crate::files::stock::of_design(design)?;
        fit_sized(design, catalog, settings, &stock, progress).map(|((outcome, _, _), _)| outcome)
    } else if Search::wanted(settings) {
        let stock = crate::files::stock::of_design(design)?;
        choose_weights(design, catalog, settings, &stock, progress).map(|(outcome, _, _)| outcome)
    } else {
        crate::fit::run::fit(design, catalog, settings, progress)
    }
}

/// The fit with the weights the design leaves to springfit chosen ([`crate::fit::auto`]): every
/// candidate the search proposes is solved on one preparation (the fans, candidates, rows and
/// mass model are shared: only the solve is repeated), its parts are chosen and its builds
/// drawn, and the chosen candidate's outcome, parts and builds are returned, with the choice in
/// [`FitOutcome::auto`]. A candidate infeasible at its weights is recorded as such; only when
/// every one is does the first such error stand.
fn choose_weights(
    design: &Design,
    catalog: &Catalog,
    settings: &FitSettings,
    stock: &[crate::parts::StockPart],
    progress: Progress<'_>,
) -> Result<(FitOutcome, Parts, Option<AsBuilt>)> {
    let t0 = Instant::now();
    let mut prepared = Prepared::new(design, catalog, settings, progress)?;
    let trims = catalog.families.iter().any(|f| f.trim_range.is_some());
    let mut search = Search::new(settings, trims);
    let mut measured = Vec::new();
    let mut first_error = None;
    while let Some((stage, weights)) = search.propose() {
        progress.stage(&format!(
            "choosing the weights: candidate {} (at most {})",
            measured.len() + 1,
            settings.auto_budget
        ));
        let here = weights.apply(settings);
        let fitted = match prepared.solve(&here, progress) {
            Ok(outcome) => {
                let parts = crate::parts::of_fit(design, &outcome, here.frequency, stock)?;
                // Each candidate is judged on the elements that can be built.
                let choose = |o: &FitOutcome| crate::parts::of_fit(design, o, here.frequency, stock);
                let verdict = |p: &Parts| p.verdict(here.accept_p99_deg);
                let (outcome, parts) = prepared.drop_unbuildable(&here, progress, (outcome, parts), choose, verdict)?;
                let as_built = crate::asbuilt::of_fit(design, &outcome)?;
                Some((outcome, parts, as_built))
            }
            Err(e @ Error::Infeasible { .. }) => {
                first_error.get_or_insert(e);
                None
            }
            Err(e) => return Err(e),
        };
        search.record(stage, weights, fitted.as_ref().map(|(o, p, ab)| figures(o, p, ab.as_ref())));
        measured.push(fitted);
    }
    let Some(choice) = search.finish() else {
        return Err(first_error.unwrap_or_else(|| Error::numerical("fit", "no candidate weights were tried")));
    };
    let Some((mut outcome, parts, as_built)) = measured.swap_remove(choice.chosen) else {
        return Err(Error::numerical("fit", "the chosen candidate has no fit"));
    };
    outcome.timings.total = t0.elapsed().as_secs_f64();
    outcome.auto = Some(choice);
    Ok((outcome, parts, as_built))
}

/// What the rule of [`crate::fit::auto`] judges a candidate by.
fn figures(outcome: &FitOutcome, parts: &Parts, as_built: Option<&AsBuilt>) -> Figures {
    Figures {
        p99_deg: outcome.metrics.stats.p99_abs,
        built_p95_deg: as_built.map(|ab| ab.p99_deg.p95),
        // The trims' figure, or with cams and no trims the followers' preloads re-set.
        trimmed_p95_deg: as_built
            .and_then(|ab| ab.trimmed.map(|t| t.p99_deg.p95).or(ab.preload_trimmed.map(|t| t.p99_deg.p95))),
        spring_mass_kg: parts.elements.iter().filter_map(|e| e.part.as_ref().ok()).map(|p| p.mass).sum(),
        used: outcome.used(),
    }
}

/// A fit run: the outcome, the parts of its bill, its as-built figures and its warnings.
#[derive(Debug, Clone)]
pub struct FitRun {
    /// The fit (or the exact reference).
    pub outcome: FitOutcome,
    /// The parts of the fitted bill (None for the exact reference).
    pub parts: Option<Parts>,
    /// The as-built figures (None for the exact reference, without a tolerance, or with
    /// `builds = 0`).
    pub as_built: Option<AsBuilt>,
    /// Seconds the as-built builds took.
    pub as_built_seconds: f64,
    /// Whether it is the exact reference.
    pub exact: bool,
    /// What the fit's result warns of, in the order the command prints them.
    pub warnings: Vec<Warning>,
}

impl FitRun {
    /// Writes every file `springfit fit` writes into the claimed folder (see
    /// [`crate::report::fit::write_folder`]); returns the folder.
    pub fn write(&self, design: &Design, claim: Claim) -> Result<PathBuf> {
        crate::report::fit::write_folder(claim, design, &self.outcome, self.as_built.as_ref(), self.parts.as_ref())
    }

    /// The fit as `compare` records it, with its as-built brief.
    pub fn record(&self, design_file: &Path) -> FitRecord {
        let mut r = crate::studies::compare::record_of(&self.outcome, design_file);
        r.as_built = self.as_built.as_ref().map(crate::asbuilt::Brief::of);
        r
    }
}

/// The warnings of a fit of springs: its equalities as evaluated, the bound on the builds'
/// equilibrium shift where it acted or could not be held, its bill against the catalogue, each
/// cam's drawing, the elements no part meets.
fn warnings(
    design: &Design,
    settings: &FitSettings,
    catalog: &Catalog,
    (outcome, as_built): (&FitOutcome, Option<&AsBuilt>),
    parts: Option<&Parts>,
) -> Vec<Warning> {
    let mut out = Vec::new();
    let mut push = |topic: Topic, message: String| out.push(Warning { topic, message });
    if let Some(w) = hints::fit_equality_warning(design, settings, &outcome.metrics) {
        push(Topic::Equalities, w);
    }
    if let Some(w) = outcome.solve.shift_bound.as_ref().and_then(|b| shift_warning(b, as_built)) {
        push(Topic::Equalities, w);
    }
    let fraction = match settings.tolerance {
        crate::design::tolerance::ToleranceSpec::Fraction(t) => Some(t),
        _ => None,
    };
    if let Some(w) =
        outcome.trim_sizing.as_ref().and_then(|s| crate::asbuilt::sizing::kept_ranges_reason(design, s, fraction))
    {
        push(Topic::Bill, w);
    }
    for w in hints::bom_warnings(catalog, &outcome.bom) {
        push(Topic::Bill, w);
    }
    for (i, cam) in outcome.cams.iter().enumerate() {
        for v in &cam.realisation.violations {
            push(Topic::Cam(i), format!("cam {}: {v}", cam.id));
        }
    }
    out.extend(parts.map(super::parts::warnings).unwrap_or_default());
    out
}
