//! The files `springfit fit` writes.

use serde::Serialize;

use super::figures::{fmt_q, histogram_figure, potential_figure};
use super::output::OutputDir;
use super::plot::render;
use crate::design::Design;
use crate::design::tolerance::TrimRule;
use crate::error::Result;
use crate::files::bom;
use crate::fit::{FitOutcome, SolveStatus, Solver, Timings};
use crate::potential::{ExactPotential, Potential};
use crate::residual::{AngleSample, AngleStats, BandStats};

/// `summary.json`. Key order is fixed; everything but `timings_s` is deterministic.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// The design's name.
    pub design: String,
    /// The design file the fit came from (absolute when it could be resolved).
    pub design_file: String,
    /// The number of joints.
    pub dof: usize,
    /// The catalogue's name (`exact` for `--exact`).
    pub catalog: String,
    /// What found the stiffnesses: `qp`, `nnls` or `exact`.
    pub solver: Solver,
    /// Candidate elements after expanding the catalogue, before dropping those that never engage.
    pub candidates: usize,
    /// Candidates dropped because they never engage in the region.
    pub dropped: usize,
    /// Elements in the bill of materials (rows of `bom.csv`: a cam counts once).
    pub used: usize,
    /// The frequency ω of `[fit] frequency`, rad/s.
    pub frequency_rad_s: f64,
    /// Statistics of |residual angle| on the held-out fan, degrees.
    pub residual_deg: AngleStats,
    /// |∂U/∂q(q_eq)| of the total potential, N·m (0 when the springs hold the arm exactly at q_eq).
    pub equilibrium_gradient_norm: f64,
    /// ‖∇²U(q_eq) − ω²M(q_eq)‖_F / ‖ω²M(q_eq)‖_F, dimensionless.
    pub hessian_rel_error: f64,
    /// Held-out samples where U decreases along the geodesic (∂U/∂q·γ̇ < 0).
    pub monotone_violations: usize,
    /// Wall-clock per step, s; the only entries that differ between runs.
    pub timings_s: Timings,
    /// `solved`, `almost_solved` or `reference`.
    pub status: SolveStatus,
    /// The element budget (0: none).
    pub max_elements: usize,
    /// The smaller budget whose selection met every constraint when the search at
    /// `max_elements` found no set that does (null: met as asked).
    pub budget_met_at: Option<usize>,
    /// What the bound on the builds' equilibrium shift (`[fit] max_shift`) did (null: no bound,
    /// or no tolerance to bound).
    pub shift_bound: Option<crate::fit::outcome::ShiftBound>,
    /// Subset refits the sparse selection performed (0 without a budget).
    pub selection_evaluations: usize,
    /// Exchange moves the selection accepted.
    pub selection_swaps: usize,
    /// Residual statistics by distance band from q_eq.
    pub bands: Vec<BandStats>,
    /// The region the fit covers and its check.
    pub region: RegionSummary,
    /// The directions and samples the fit used (counts of 0 in the design resolved from the
    /// number of joints).
    pub sampling: Sampling,
    /// `acceptable` or `poor`: when parts were chosen, of the realised design (its p99 residual
    /// ≤ `accept_p99_deg` and a part for every element), else of the ideal elements (p99 ≤
    /// `accept_p99_deg`).
    pub verdict: String,
    /// The design the verdict judges: `realised` when parts were chosen, else `ideal`.
    pub verdict_judges: crate::fit::outcome::Judged,
    /// The verdict's reason in words, as `springfit fit` prints it: the judged p99 against the
    /// threshold, the ideal one beside it, the elements without a part with their limits.
    pub verdict_reason: String,
    /// The verdict on the ideal elements alone (`residual_deg.p99_abs` against the threshold),
    /// kept beside the realised design's.
    pub ideal_verdict: String,
    /// The verdict's threshold, degrees (`fit.accept_p99_deg`).
    pub accept_p99_deg: f64,
    /// Fingerprint of the fitted spring set (`fit::bill::fingerprint`; null for the exact reference).
    pub spring_set: Option<String>,
    /// Monte Carlo builds at the design's tolerance: p50 and p95 over builds (null when the
    /// fit is for the drawing only and no element states a tolerance, or `builds = 0`).
    pub as_built: Option<crate::asbuilt::AsBuilt>,
    /// The realised design: residual angles with each element's mechanism in place of the ideal
    /// element, and the parts found (null for the exact reference and when no parts were chosen).
    pub realised: Option<super::parts::RealisedSummary>,
    /// The springs' mass against the arm and the floor, their stored energy over U* and their
    /// total |preload| at q_eq (null for the exact reference; see [`super::mass`]).
    pub mass: Option<super::mass::MassSummary>,
    /// The weights springfit chose for the keys the design left out or set to `"auto"`: every
    /// candidate tried with its figures, and the one chosen (absent when the design's weights
    /// were fitted as they are).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub auto_weights: Option<crate::fit::auto::Choice>,
    /// A poor fit's diagnosis: the additions that lower the residual most and the frequency
    /// check (absent for an acceptable fit; see `fit::diagnosis`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub diagnosis: Option<crate::fit::diagnosis::Diagnosis>,
    /// The elements of the first bill no part realises, left out of the bill with the fit
    /// solved again without them: each with its id in that bill, its limit and peak torque, and
    /// the p99 as drawn and realised before and after (or why they were kept); absent when
    /// every element had a part.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dropped_without_part: Option<crate::fit::outcome::DroppedWithoutPart>,
    /// The trim ranges sized by the bill: each trim's start range, the rates the builds need and
    /// the range chosen (absent when no catalogue family has `trim_sized = true`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trim_sizing: Option<crate::fit::outcome::TrimSizing>,
    /// The chosen parts' mass on moving links, kg: springs on joints past the first, tendons'
    /// pulleys and cables (docs/parts.md, "Where the parts sit"); null without parts.
    pub placed_mass_kg: Option<f64>,
    /// Fits made on the arm carrying its parts (`[fit] placement_rounds`; 0: the fit is the
    /// bare arm's).
    pub placement_rounds: usize,
    /// With placement rounds: each round's placed mass and springs' mass, whether it converged,
    /// and the first fit judged on the arm carrying its parts (absent without rounds).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub placement: Option<crate::realise::placement::Rounds>,
}

/// The region part of the summary.
#[derive(Debug, Clone, Serialize)]
pub struct RegionSummary {
    /// The region in words.
    pub description: String,
    /// The largest arc length from q_eq inside the region, √(kg·m²)·rad.
    pub extent: f64,
    /// The largest valid geodesic-ball radius found, √(kg·m²)·rad.
    pub largest_radius: f64,
    /// True when nothing failed up to the probe radius (the valid ball may be larger than
    /// `largest_radius`).
    pub largest_radius_is_lower_bound: bool,
}

/// The sampling part of the summary: the fans as traced.
#[derive(Debug, Clone, Serialize)]
pub struct Sampling {
    /// Geodesics of the training fan the fit's rows come from.
    pub training_directions: usize,
    /// Samples along each training geodesic.
    pub training_samples: usize,
    /// Geodesics of the held-out fan the residuals are judged on.
    pub evaluation_directions: usize,
    /// Samples along each held-out geodesic.
    pub evaluation_samples: usize,
    /// Geodesics of the region check's fan.
    pub check_directions: usize,
}

impl Summary {
    /// The summary with the as-built figures and the realised design (its mass against the
    /// floor on the fit's held-out fan): what `summary.json` and the Python package's `summary`
    /// both say.
    pub fn with_parts(
        o: &FitOutcome,
        design: &Design,
        as_built: Option<&crate::asbuilt::AsBuilt>,
        parts: Option<&crate::parts::Parts>,
    ) -> Summary {
        let mut summary = Summary::new(o, design);
        summary.as_built = as_built.cloned();
        let floor = crate::fit::mass::Floor::on(design, o.settings.frequency, &o.evaluation);
        summary.realised = parts.map(|p| super::parts::RealisedSummary::new(p, &floor, &design.parts));
        summary.mass = super::mass::MassSummary::new(design, o, parts);
        if let Some(p) = parts {
            summary.set_verdict(&p.verdict(o.settings.accept_p99_deg));
            summary.placed_mass_kg = Some(p.placement.moving_mass());
            summary.placement = p.placement.rounds.clone();
            summary.placement_rounds = summary.placement.as_ref().map_or(0, |r| r.rounds);
        }
        summary
    }

    /// Writes `verdict` into the summary's verdict keys.
    fn set_verdict(&mut self, verdict: &crate::fit::outcome::Verdict) {
        self.verdict = verdict.word().to_string();
        self.verdict_judges = verdict.judged;
        self.verdict_reason = verdict.reason();
    }

    /// The summary of a fit of `design`.
    pub fn new(o: &FitOutcome, design: &Design) -> Summary {
        let design_file = &design.path;
        let ideal = crate::fit::outcome::Verdict::ideal(o.metrics.stats.p99_abs, o.settings.accept_p99_deg);
        Summary {
            design: o.design.clone(),
            design_file: std::fs::canonicalize(design_file)
                .unwrap_or_else(|_| design_file.to_path_buf())
                .display()
                .to_string(),
            dof: o.dof,
            catalog: o.catalog.clone(),
            solver: o.solve.solver,
            candidates: o.candidates,
            dropped: o.dropped,
            used: o.used(),
            frequency_rad_s: o.settings.frequency,
            residual_deg: o.metrics.stats,
            equilibrium_gradient_norm: o.metrics.equilibrium_gradient_norm,
            hessian_rel_error: o.metrics.hessian_rel_error,
            monotone_violations: o.metrics.monotone_violations,
            timings_s: o.timings,
            status: o.solve.status,
            max_elements: o.settings.max_elements,
            budget_met_at: o.solve.budget_met_at,
            shift_bound: o.solve.shift_bound.clone(),
            selection_evaluations: o.solve.selection_evaluations,
            selection_swaps: o.solve.selection_swaps,
            bands: o.metrics.bands.clone(),
            region: RegionSummary {
                description: o.region.region.clone(),
                extent: o.region.extent,
                largest_radius: o.region.largest_radius,
                largest_radius_is_lower_bound: o.region.largest_radius_is_lower_bound,
            },
            sampling: Sampling {
                training_directions: o.settings.training_count(o.dof),
                training_samples: o.settings.training_samples,
                evaluation_directions: o.settings.evaluation_count(o.dof),
                evaluation_samples: o.settings.evaluation_samples,
                check_directions: design.geodesics.check_count(o.dof),
            },
            verdict: ideal.word().to_string(),
            verdict_judges: ideal.judged,
            verdict_reason: ideal.reason(),
            ideal_verdict: ideal.word().to_string(),
            accept_p99_deg: o.settings.accept_p99_deg,
            spring_set: (o.solve.solver != Solver::Exact).then(|| crate::fit::bill::fingerprint(&o.springs)),
            as_built: None,
            realised: None,
            mass: None,
            auto_weights: o.auto.clone(),
            dropped_without_part: o.dropped_without_part.clone(),
            trim_sizing: o.trim_sizing.clone(),
            placed_mass_kg: None,
            placement_rounds: 0,
            placement: None,
            diagnosis: o.diagnosis.clone(),
        }
    }
}

/// `residuals.csv`: direction, s, q…, angle_deg.
pub fn residuals_csv(dof: usize, residuals: &[AngleSample]) -> String {
    let mut s = String::from("direction,s");
    for i in 1..=dof {
        s.push_str(&format!(",q{i}"));
    }
    s.push_str(",angle_deg\n");
    for r in residuals {
        s.push_str(&format!("{},{}", r.direction, r.s));
        for q in &r.q {
            s.push_str(&format!(",{q}"));
        }
        s.push_str(&format!(",{}\n", r.angle_deg));
    }
    s
}

/// The names `springfit fit` may write (see [`super::output::Plan`]), `report.html` included;
/// the bill of materials and its cams' files only when springs are fitted (not for `--exact`).
pub fn files(springs: bool) -> Vec<&'static str> {
    let bill = if springs { BILL_FILES } else { &[] };
    bill.iter().chain(FILES).copied().collect()
}

const BILL_FILES: &[&str] = &["bom.csv", "bom.md", "cams/*", "parts.csv", "parts.md", "sketch_*.svg"];

const FILES: &[&str] = &[
    "summary.json",
    "residuals.csv",
    "histogram.svg",
    "histogram.png",
    "potential.svg",
    "potential.png",
    "report.md",
    super::html::FILE,
];

/// Writes everything `springfit fit` writes into the folder `target`, under `plan` (see
/// [`files`]): the files of [`write_with_as_built`] and `report.html`, staged and committed at
/// once. The command and the Python package's `Fit.write` both go through here, so their
/// folders are the same file for file.
pub fn write_folder(
    claim: super::output::Claim,
    design: &Design,
    o: &FitOutcome,
    as_built: Option<&crate::asbuilt::AsBuilt>,
    parts: Option<&crate::parts::Parts>,
) -> Result<std::path::PathBuf> {
    let dir = claim.open()?;
    write_all(&dir, design, o, as_built, parts)?;
    super::html::write_fit(&dir, design)?;
    dir.commit()
}

/// Writes every output of a fit (or of the exact reference) into `out`.
pub fn write(out: &OutputDir, design: &Design, o: &FitOutcome) -> Result<()> {
    write_with_as_built(out, design, o, None)
}

/// Writes every output of a fit with its as-built figures (see [`crate::asbuilt`]) in
/// `summary.json`, `report.md` and the histogram (a band over the builds' p99).
pub fn write_with_as_built(
    out: &OutputDir,
    design: &Design,
    o: &FitOutcome,
    as_built: Option<&crate::asbuilt::AsBuilt>,
) -> Result<()> {
    write_all(out, design, o, as_built, None)
}

/// [`write_with_as_built`] and the parts of the fitted bill (`parts.csv`, `parts.md`, the
/// sketches, `realised` in `summary.json`).
pub fn write_all(
    out: &OutputDir,
    design: &Design,
    o: &FitOutcome,
    as_built: Option<&crate::asbuilt::AsBuilt>,
    parts: Option<&crate::parts::Parts>,
) -> Result<()> {
    if let Some(p) = parts {
        super::parts::write(out, design, p)?;
    }
    let exact = o.solve.solver == Solver::Exact;
    let label = if exact {
        format!("{} — exact ½ω²r²", o.design)
    } else {
        format!("{} — {} ({}), {} {}", o.design, o.catalog, o.solve.solver, o.used(), o.used_noun())
    };
    if !exact {
        bom::write(out, "bom.csv", &o.bom)?;
        out.write("bom.md", bom::to_markdown(&o.design, &o.bom))?;
        for cam in &o.cams {
            out.write(&format!("cams/{}.csv", cam.id), crate::files::cam::csv(cam))?;
            let title = format!(
                "{} {} on ({})",
                o.design,
                cam.id,
                cam.coupling.iter().map(|a| crate::elements::fmt_number(*a)).collect::<Vec<_>>().join(", ")
            );
            out.write(&format!("cams/{}.svg", cam.id), crate::realise::cam::svg(&cam.realisation, &title))?;
        }
    }
    let summary = Summary::with_parts(o, design, as_built, parts);
    let json = serde_json::to_string_pretty(&summary).expect("the summary serialises");
    out.write("summary.json", json + "\n")?;
    out.write("residuals.csv", residuals_csv(o.dof, &o.metrics.residuals))?;
    let signed = o.dof == 2;
    let mut histogram = histogram_figure(
        &o.metrics.residuals,
        &o.metrics.stats,
        &format!("Residual angles on held-out geodesics: {label}"),
        signed,
    );
    if let (Some(ab), Some(panel)) = (as_built, histogram.panels.first_mut()) {
        super::figures::add_as_built_band(panel, ab, signed);
    }
    render(&histogram, &out.path("histogram"))?;
    let has_potential_plot = o.dof >= 2;
    if has_potential_plot {
        let title = format!("Potential isolines and geodesics: {label}");
        let fig = if exact {
            let pot = ExactPotential::new(&design.chain, &design.q_eq, o.settings.frequency, design.geodesics.ode);
            potential_figure(design, &pot as &dyn Potential, &o.evaluation, o.settings.frequency, &title)?
        } else {
            potential_figure(design, &o.springs, &o.evaluation, o.settings.frequency, &title)?
        };
        render(&fig, &out.path("potential"))?;
    }
    out.write("report.md", report_md(design, o, &summary, has_potential_plot))?;
    Ok(())
}

/// The as-built section of `report.md`.
fn as_built_md(ab: Option<&crate::asbuilt::AsBuilt>, exact: bool, dof: usize) -> String {
    if exact {
        return String::new();
    }
    let Some(ab) = ab else {
        return "## As built\n\nNo as-built figures: the fit is for the drawing only (`[fit] tolerance = \"none\"`) and no element states a catalogue tolerance, or `builds = 0`.\n\n".into();
    };
    let mut r = format!(
        "## As built\n\n{} Monte Carlo builds (seed {}), every stiffness scaled by 1 + δ, δ {} within the tolerance ({}); each build judged about its own equilibrium on {} held-out geodesics. p50 / p95 over builds, with the 95 % confidence interval of the p95 (distribution-free, from order statistics: where the p95 of all builds the tolerance allows lies, given these):\n\n| figure | p50 | p95 | p95, 95 % interval |\n| --- | ---: | ---: | ---: |\n",
        ab.builds,
        ab.seed,
        ab.distribution.name(),
        ab.tolerance.label(),
        crate::asbuilt::DIRECTIONS
    );
    let row = |name: &str, sp: &crate::asbuilt::Spread, unit: &str, digits: usize| {
        format!(
            "| {name} | {} | {} | {}{unit} |\n",
            sp.text(sp.p50, digits, unit),
            sp.text(sp.p95, digits, unit),
            sp.p95_interval(digits)
        )
    };
    r.push_str(&row("p99 \\|residual angle\\|", &ab.p99_deg, "°", 3));
    r.push_str(&row("max \\|residual angle\\|", &ab.max_deg, "°", 3));
    r.push_str(&row("equilibrium shift \\|q′ − q_eq\\|₂ (rad)", &ab.shift_rad, "", 4));
    r.push_str(&row("equilibrium shift sqrt(Δqᵀ M Δq)", &ab.shift_metric, "", 4));
    if let Some(t) = &ab.trimmed {
        r.push_str(&row("trimmed: p99 \\|residual angle\\|", &t.p99_deg, "°", 3));
        r.push_str(&row("trimmed: max \\|residual angle\\|", &t.max_deg, "°", 3));
        r.push_str(&row("trimmed: largest \\|trim rate change\\| (N·m/rad)", &t.trim_change_nm_per_rad, "", 3));
        r.push_str(&match t.rule {
            TrimRule::Hessian => format!(
                "\nTrimmed: after each build the trim springs are re-relaxed at the equilibrium of the other springs and their rates set (within range) so that ∇²U = w² M holds there again; {} of {} builds could not be fully restored within the ranges.\n",
                t.builds_not_restored, ab.builds
            ),
            TrimRule::Residual => format!(
                "\nTrimmed: after each build the trim springs are re-relaxed at the equilibrium of the other springs and their rates set (within range) for the smallest least-squares residual on {} geodesics of their own from there (`trim_rule = \"residual\"`); in {} of {} builds a trim ends at the end of its range.\n",
                crate::asbuilt::trim_directions(dof), t.builds_not_restored, ab.builds
            ),
        });
    }
    if let Some(t) = &ab.preload_trimmed {
        r.push_str(&row("preloads re-set: p99 \\|residual angle\\|", &t.p99_deg, "°", 3));
        r.push_str(&row("preloads re-set: max \\|residual angle\\|", &t.max_deg, "°", 3));
        r.push_str(
            "\nPreloads re-set: the same builds with each cam follower's preload screw set so the follower presses the base circle with the drawing's force (which leaves δ · ½ k_f s² of a cam's error δ · (V − min V)), and the trim springs, if any, re-set after it.\n",
        );
    }
    if ab.builds_without_equilibrium > 0 {
        r.push_str(&format!(
            "\n{} builds ({:.1} %) have no stable equilibrium within 0.5 rad of q_eq (counted as the worst: a percentile among them lies beyond the worst build that has one).\n",
            ab.builds_without_equilibrium,
            100.0 * ab.builds_without_equilibrium as f64 / ab.builds.max(1) as f64
        ));
    }
    if let Some(w) = ab.shift_model.and_then(|m| m.warning()) {
        r.push_str(&format!("\nWarning: {w}.\n"));
    }
    if let Some(t) = ab.trimmed.filter(|t| t.p99_deg.without > 0) {
        r.push_str(&format!(
            "\n{} builds ({:.1} %) have no stable equilibrium once trimmed (counted as the worst).\n",
            t.p99_deg.without,
            100.0 * t.p99_deg.without as f64 / ab.builds.max(1) as f64
        ));
    }
    r.push('\n');
    r
}

/// The candidates of an automatic choice of the weights, one row of cells each: the winner
/// marked, the stage, the four weights, the nominal p99, the as-built p95 untrimmed and trimmed,
/// the springs' mass and the elements (what `report.md` tabulates and `springfit fit` prints).
pub fn auto_rows(choice: &crate::fit::auto::Choice) -> Vec<Vec<String>> {
    let deg = |x: Option<f64>| x.map_or("–".to_string(), |x| format!("{x:.3}°"));
    choice
        .tried
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let w = &t.weights;
            let mut row = vec![
                if i == choice.chosen { "chosen".to_string() } else { String::new() },
                format!("{:?}", t.stage).to_lowercase(),
                format!("{}", w.tolerance_weight),
                format!("{}", w.trimmed_weight),
                format!("{}", w.mass_weight),
                format!("{}", w.restarts),
            ];
            match &t.figures {
                Some(f) => row.extend([
                    deg(Some(f.p99_deg)),
                    deg(f.built_p95_deg),
                    deg(f.trimmed_p95_deg),
                    format!("{:.2} kg", f.spring_mass_kg),
                    f.used.to_string(),
                ]),
                None => row.extend(["infeasible", "", "", "", ""].map(String::from)),
            }
            row
        })
        .collect()
}

fn report_md(design: &Design, o: &FitOutcome, s: &Summary, potential_plot: bool) -> String {
    let exact = o.solve.solver == Solver::Exact;
    let mut r = format!("# springfit fit: {}\n\n", o.design);
    if !design.description.is_empty() {
        r.push_str(&format!("{}\n\n", design.description));
    }
    r.push_str(&format!(
        "- robot: {} joints; equilibrium q_eq = {}; region: {} (largest valid geodesic-ball radius {}{:.3})\n",
        o.dof,
        fmt_q(&design.q_eq),
        o.region.region,
        if o.region.largest_radius_is_lower_bound { "≥ " } else { "" },
        o.region.largest_radius
    ));
    if exact {
        r.push_str(&format!(
            "- potential: the exact reference U* = ½ω²r², ω = {} rad/s (evaluated through the log map)\n",
            o.settings.frequency
        ));
    } else {
        r.push_str(&format!(
            "- catalogue: {} ({} candidates, {} never engage, {} enter the fit); solver: {} ({}); element budget: {}\n- used elements: {}\n",
            o.catalog,
            o.candidates,
            o.dropped,
            o.candidates - o.dropped,
            o.solve.solver,
            o.solve.status,
            if o.settings.max_elements == 0 { "none".to_string() } else { o.settings.max_elements.to_string() },
            o.used()
        ));
    }
    r.push_str(&format!(
        "- frequency ω = {} rad/s; |∇U(q_eq)| = {:.3e} N·m; Hessian relative error {:.3e}; monotonicity violations {}\n\n",
        o.settings.frequency, s.equilibrium_gradient_norm, s.hessian_rel_error, s.monotone_violations
    ));
    r.push_str(&format!(
        "## Residual angles on held-out geodesics\n\n{} samples on {} geodesics between the training directions.\n\n| band (arc length) | samples | median | p95 | p99 | max |\n| --- | ---: | ---: | ---: | ---: | ---: |\n",
        s.residual_deg.count,
        o.evaluation.geodesics.len()
    ));
    for b in &s.bands {
        r.push_str(&format!(
            "| {:.2}–{:.2} | {} | {:.4}° | {:.4}° | {:.4}° | {:.4}° |\n",
            b.from, b.to, b.stats.count, b.stats.median_abs, b.stats.p95_abs, b.stats.p99_abs, b.stats.max_abs
        ));
    }
    let st = &s.residual_deg;
    r.push_str(&format!(
        "| **all** | {} | {:.4}° | {:.4}° | {:.4}° | {:.4}° |\n\n**Verdict: {}** ({}){}.\n\n![histogram](histogram.svg)\n\n",
        st.count,
        st.median_abs,
        st.p95_abs,
        st.p99_abs,
        st.max_abs,
        s.verdict,
        s.verdict_reason,
        match s.verdict_judges {
            crate::fit::outcome::Judged::Realised => format!(
                ": judged on the realised design (see Parts below); the ideal elements alone are {}",
                s.ideal_verdict
            ),
            crate::fit::outcome::Judged::Ideal => String::new(),
        }
    ));
    if let Some(d) = &s.dropped_without_part {
        r.push_str(&format!("Built without what cannot be built: {}.\n\n", d.sentence()));
    }
    if let Some(d) = &s.diagnosis {
        r.push_str(&diagnosis_md(d));
    }
    r.push_str(&as_built_md(s.as_built.as_ref(), exact, s.dof));
    if let Some(choice) = &s.auto_weights {
        r.push_str(&format!(
            "## Weights chosen by springfit\n\nThe design leaves these weights to springfit: {} candidates fitted (budget {}), each judged by its measured figures; chosen: {} (docs/theory.md, \"Weights chosen by springfit\").\n\n| | stage | tolerance_weight | trimmed_weight | mass_weight | restarts | p99 | as built p95 | trimmed p95 | springs | elements |\n| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n",
            choice.tried.len(),
            choice.budget,
            choice.rule_phrase()
        ));
        for line in auto_rows(choice) {
            r.push_str(&format!("| {} |\n", line.join(" | ")));
        }
        r.push('\n');
    }
    if potential_plot {
        r.push_str("## Potential\n\n![potential](potential.svg)\n\n");
    }
    if !exact {
        r.push_str("## Bill of materials\n\nSee [bom.md](bom.md) (table) and [bom.csv](bom.csv) (machine-readable; `springfit` rebuilds the potential from it).\n\n");
    }
    if let Some(p) = &s.realised {
        r.push_str(&format!(
            "## Parts\n\n{} elements have a part ([parts.md](parts.md), [parts.csv](parts.csv)){}. Their springs weigh {:.3} kg, {:.1}× the floor of {:.3} kg (the least steel that stores U* = ½ω²r²; see docs/parts.md). With each mechanism's own potential in place of the ideal element the residual angle is p99 {:.4}° ({:+.4}°), max {:.4}° ({:+.4}°).\n\n",
            p.parts,
            if p.missing.is_empty() { String::new() } else { format!("; no spring found for {}", p.missing.join(", ")) },
            p.spring_mass_kg,
            p.mass_over_floor,
            p.floor_kg,
            p.residual_deg.p99_abs,
            p.p99_change_deg,
            p.residual_deg.max_abs,
            p.max_change_deg
        ));
    }
    if let Some(m) = &s.mass {
        r.push_str(&m.markdown());
    }
    r.push_str(&format!(
        "## Files\n\n- [summary.json](summary.json): the figures above\n- [residuals.csv](residuals.csv): every evaluated sample\n\nTimings: geodesics {:.3} s, assemble {:.3} s, solve {:.3} s, evaluate {:.3} s, total {:.3} s.\n",
        s.timings_s.geodesics, s.timings_s.assemble, s.timings_s.solve, s.timings_s.evaluate, s.timings_s.total
    ));
    r
}

/// The diagnosis section of `report.md`: the ranked additions and the frequency check.
fn diagnosis_md(d: &crate::fit::diagnosis::Diagnosis) -> String {
    let mut r = format!(
        "## Diagnosis\n\nThe fit is poor. Of {} profiles on couplings the catalogue lacks, each added to a refit of the whole catalogue on the training rows (non-negative least squares, the equalities weighted; the shares rank, a fit measures), these lower the rows' ‖R‖² most (docs/guide.md, \"When the fit is poor\"):\n\n",
        d.screened
    );
    for line in d.lines() {
        r.push_str(&format!("- {line}\n"));
    }
    r.push('\n');
    r
}
