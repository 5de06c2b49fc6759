//! `springfit fit`: the main job.

use std::path::{Path, PathBuf};

use anyhow::Result;
use springfit::asbuilt::AsBuilt;
use springfit::design::fit::FitSettings;
use springfit::design::fit::SolverKind;
use springfit::design::tolerance::TrimRule;
use springfit::jobs::fit::{FitJob, FitRequest, FitRun};
use springfit::jobs::{Topic, about};
use springfit::realise::cam::FittedCam;

use super::Session;
use super::progress::Progress;

pub struct FitArgs {
    pub design: PathBuf,
    pub out: Option<PathBuf>,
    pub exact: bool,
    pub solver: Option<SolverKind>,
    pub max_elements: Option<usize>,
}

pub fn run(args: FitArgs, session: &Session) -> Result<()> {
    let progress = &session.progress;
    let (design, validated) = super::load_design(&args.design, progress)?;
    let request = FitRequest { exact: args.exact, solver: args.solver, max_elements: args.max_elements };
    let job = FitJob::new(&design, validated.catalog.as_ref(), request)?;
    let settings = *job.settings();
    let default_name = if args.exact { format!("{}_exact", design.name) } else { design.name.clone() };
    let target = args.out.clone().unwrap_or_else(|| PathBuf::from("out").join(default_name));
    let plan = session.plan_for(&design, "fit", request.files());
    let claim = springfit::report::output::check(&target, &plan)?;
    let run = progress.run(|p| job.run(p)).map_err(|e| super::in_design(&design, e))?;
    let step = progress.step("writing outputs");
    let written = run.write(&design, claim);
    step.finish();
    let written = written?;
    say_fit(&run, &settings, progress);
    for (i, cam) in run.outcome.cams.iter().enumerate() {
        say_cam(cam, about(&run.warnings, &Topic::Cam(i)), progress);
    }
    if let Some(choice) = &run.outcome.auto {
        progress.say(format!(
            "weights chosen by springfit ({} candidates, budget {}; {}):",
            choice.tried.len(),
            choice.budget,
            choice.rule_phrase()
        ));
        progress.say(
            "  stage      tolerance trimmed  mass     restarts  p99      built p95  trimmed p95  springs    elements",
        );
        for row in springfit::report::fit::auto_rows(choice) {
            progress.say(format!(
                "{} {:<10} {:<9} {:<8} {:<8} {:<9} {:<8} {:<10} {:<12} {:<10} {}",
                if row[0].is_empty() { " " } else { "*" },
                row[1],
                row[2],
                row[3],
                row[4],
                row[5],
                row[6],
                row[7],
                row[8],
                row[9],
                row[10]
            ));
        }
    }
    match (&run.as_built, args.exact) {
        (Some(ab), _) => say_as_built(ab, run.as_built_seconds, progress),
        (None, false) => progress.say(
            "as built: skipped (tolerance \"none\" and no catalogue tolerance, or builds = 0); set [fit] tolerance = 0.05 for ±5 % builds",
        ),
        (None, true) => {}
    }
    if let Some(p) = &run.parts {
        super::parts::say(p, &design.parts, &run.warnings, session);
        if let Some(m) = springfit::report::mass::MassSummary::new(&design, &run.outcome, Some(p)) {
            progress.say(m.line());
        }
    }
    let files = if args.exact {
        "summary.json, residuals.csv, histogram, potential, report.md, report.html"
    } else {
        "bom.csv, bom.md, parts.csv, parts.md, summary.json, residuals.csv, histogram, potential, report.md, report.html"
    };
    let files = if run.outcome.cams.is_empty() { files.to_string() } else { format!("{files}, cams/") };
    progress.say(format!("wrote {} ({files})", display(&written)));
    Ok(())
}

/// The fit's lines: what was fitted, the residual angles, the equalities, the verdict; with the
/// warnings about the equalities and the bill.
fn say_fit(run: &FitRun, settings: &FitSettings, progress: &Progress) {
    let (outcome, warnings) = (&run.outcome, &run.warnings);
    let st = &outcome.metrics.stats;
    if run.exact {
        progress.say(format!("{}: exact potential ½ω²r² (ω = {} rad/s)", outcome.design, settings.frequency));
    } else {
        progress.say(format!(
            "{}: {} {} from {} candidates of catalogue {} ({} never engage, {} enter the fit); solver {} ({})",
            outcome.design,
            outcome.used(),
            outcome.used_noun(),
            outcome.candidates,
            outcome.catalog,
            outcome.dropped,
            outcome.candidates - outcome.dropped,
            outcome.solve.solver,
            outcome.solve.status
        ));
    }
    if let Some(b) = outcome.solve.budget_met_at {
        progress.say(format!(
            "budget {}: the selection found no set of {} elements that meets every constraint; the answer is the best set of at most {b} (the search at budget {b}; trims come on top)",
            settings.max_elements, settings.max_elements
        ));
    }
    progress.say(format!(
        "residual angle on {} held-out samples: median {:.4}°, p95 {:.4}°, p99 {:.4}°, max {:.4}°",
        st.count, st.median_abs, st.p95_abs, st.p99_abs, st.max_abs
    ));
    progress.say(format!(
        "|∇U(q_eq)| = {:.2e} N·m, Hessian relative error {:.2e}, monotonicity violations {}; {:.2} s",
        outcome.metrics.equilibrium_gradient_norm,
        outcome.metrics.hessian_rel_error,
        outcome.metrics.monotone_violations,
        outcome.timings.total
    ));
    for w in about(warnings, &Topic::Equalities) {
        progress.warn(w);
    }
    // With parts the verdict judges what would be built (the realised design, every element
    // with a part); the exact reference has only its ideal figure.
    let verdict = match &run.parts {
        Some(parts) => parts.verdict(settings.accept_p99_deg),
        None => springfit::fit::outcome::Verdict::ideal(st.p99_abs, settings.accept_p99_deg),
    };
    if let Some(d) = &outcome.dropped_without_part {
        progress.say(d.sentence());
    }
    if let Some(r) = run.parts.as_ref().and_then(|p| p.placement.rounds.as_ref()) {
        progress.say(r.sentence());
    }
    progress.say(if verdict.acceptable() {
        format!("verdict: acceptable ({})", verdict.reason())
    } else if !verdict.ideal_passes() {
        format!(
            "verdict: poor ({}): released on a geodesic, the arm drifts off it; {}",
            verdict.reason(),
            springfit::fit::hints::poor_fit_advice(&outcome.region)
        )
    } else {
        format!(
            "verdict: poor ({}): the ideal elements pass, what is built does not; parts.md gives each element's limit and its fitted against realised rate",
            verdict.reason()
        )
    });
    if let Some(d) = &outcome.diagnosis {
        progress.say(format!(
            "diagnosis ({} profiles on couplings the catalogue lacks, each added to a refit of the catalogue, {:.2} s):",
            d.screened, d.seconds
        ));
        for line in d.lines() {
            progress.say(format!("  {line}"));
        }
    }
    for w in about(warnings, &Topic::Bill) {
        progress.warn(w);
    }
}

/// A cam's drawing in one line, then the warnings about it.
fn say_cam<'a>(cam: &FittedCam, warnings: impl Iterator<Item = &'a str>, progress: &Progress) {
    let r = &cam.realisation;
    progress.say(format!(
            "cam {} on ({}): follower {:.3} N/mm preloaded {:.2} mm, gear ratio {:.4}, max pressure angle {:.1}°, smallest convex pitch radius of curvature {:.1} mm",
            cam.id,
            cam.coupling.iter().map(|a| springfit::elements::fmt_number(*a)).collect::<Vec<_>>().join(", "),
            r.build.follower_rate,
            r.build.preload,
            r.build.gear_ratio,
            r.max_pressure_angle,
            r.min_convex_curvature
        ));
    for w in warnings {
        progress.warn(w);
    }
}

/// The as-built figures: untrimmed, trimmed, with the cams' preloads re-set. A percentile among
/// the builds without a figure reads "beyond X" (see [`springfit::asbuilt::Spread::text`]).
fn say_as_built(ab: &AsBuilt, secs: f64, progress: &Progress) {
    let pair = |sp: &springfit::asbuilt::Spread, digits: usize, unit: &str| {
        format!("{} / {}", sp.text(sp.p50, digits, unit), sp.text(sp.p95, digits, unit))
    };
    progress.say(format!(
        "as built ({} at {} tolerance, {}; about each build's own equilibrium), p50 / p95 over builds: p99 {} (p95 {} at 95 % confidence), max {}, shift {} rad (Euclidean), {} (metric); {:.2} s",
        plural(ab.builds, "build"),
        ab.tolerance.label(),
        ab.distribution.name(),
        pair(&ab.p99_deg, 3, "°"),
        ab.p99_deg.p95_interval_phrase(3, "°"),
        pair(&ab.max_deg, 3, "°"),
        pair(&ab.shift_rad, 4, ""),
        pair(&ab.shift_metric, 4, ""),
        secs
    ));
    if let Some(t) = &ab.trimmed {
        progress.say(format!(
            "as built and trimmed: p99 {} (p95 {}), max {}; largest trim change {} N·m/rad; {} {}",
            pair(&t.p99_deg, 3, "°"),
            t.p99_deg.p95_interval_phrase(3, "°"),
            pair(&t.max_deg, 3, "°"),
            pair(&t.trim_change_nm_per_rad, 3, ""),
            plural(t.builds_not_restored, "build"),
            match t.rule {
                TrimRule::Hessian => "not fully restored",
                TrimRule::Residual => "with a trim at the end of its range",
            }
        ));
        if t.p99_deg.without > 0 {
            progress.say(format!(
                "{} of {} builds ({:.1} %) have no stable equilibrium once trimmed (counted as the worst)",
                t.p99_deg.without,
                ab.builds,
                100.0 * t.p99_deg.without as f64 / ab.builds.max(1) as f64,
            ));
        }
    }
    if let Some(t) = &ab.preload_trimmed {
        progress.say(format!(
            "as built, each cam's follower preload re-set to the drawing's force{}: p99 {} (p95 {}), max {}",
            if ab.trimmed.is_some() { " and the trims re-set" } else { "" },
            pair(&t.p99_deg, 3, "°"),
            t.p99_deg.p95_interval_phrase(3, "°"),
            pair(&t.max_deg, 3, "°"),
        ));
    }
    if let Some(w) = ab.shift_model.and_then(|m| m.warning()) {
        progress.warn(w);
    }
    if ab.builds_without_equilibrium > 0 {
        progress.say(format!(
            "{} no stable equilibrium within 0.5 rad of q_eq ({:.1} % of {}, counted as the worst)",
            if ab.builds_without_equilibrium == 1 {
                "1 build has".to_string()
            } else {
                format!("{} builds have", ab.builds_without_equilibrium)
            },
            100.0 * ab.builds_without_equilibrium as f64 / ab.builds.max(1) as f64,
            ab.builds
        ));
    }
}

fn display(p: &Path) -> String {
    p.display().to_string()
}

/// `1 build`, `2 builds`.
pub fn plural(n: usize, word: &str) -> String {
    if n == 1 { format!("1 {word}") } else { format!("{n} {word}s") }
}
