//! `springfit fit`: the main job.

use std::path::{Path, PathBuf};

use anyhow::Result;
use springfit::catalog::Catalog;
use springfit::design::Design;
use springfit::error::Error;
use springfit::fit::run::{exact_reference, fit};
use springfit::fit::settings::SolverKind;
use springfit::report::output::OutputDir;

use super::progress::Progress;

pub struct FitArgs {
    pub design: PathBuf,
    pub out: Option<PathBuf>,
    pub exact: bool,
    pub solver: Option<SolverKind>,
    pub max_elements: Option<usize>,
}

pub fn run(args: FitArgs, progress: &Progress) -> Result<()> {
    let design = Design::load(&args.design)?;
    let mut settings = design.fit;
    if let Some(s) = args.solver {
        settings.solver = s;
    }
    if let Some(k) = args.max_elements {
        settings.max_elements = k;
    }
    settings.validate().map_err(|(field, reason)| Error::Setting { field, reason })?;
    let default_name = if args.exact { format!("{}_exact", design.name) } else { design.name.clone() };
    let target = args.out.clone().unwrap_or_else(|| PathBuf::from("out").join(default_name));
    let outcome = {
        let step = std::cell::RefCell::new(None::<super::progress::Step>);
        let stage = |name: &str| {
            if let Some(s) = step.borrow_mut().take() {
                s.finish();
            }
            *step.borrow_mut() = Some(progress.step(name));
        };
        let result = if args.exact {
            exact_reference(&design, &settings, &stage)
        } else {
            let path = design.catalog.clone().ok_or_else(|| {
                Error::invalid(
                    &design.path,
                    "catalog",
                    "the design names no spring catalogue (catalog = \"../catalogs/paper.toml\")",
                )
            })?;
            let catalog = Catalog::load(&path, design.dof())?;
            fit(&design, &catalog, &settings, &stage)
        };
        // Infeasibility and numerical failures carry no file of their own: name the design.
        let result = result.map_err(|e| match e {
            Error::Infeasible { .. } | Error::Numerical { .. } => {
                anyhow::Error::new(e).context(design.path.display().to_string())
            }
            other => other.into(),
        });
        if let Some(s) = step.borrow_mut().take() {
            s.finish();
        }
        result?
    };
    let as_built = if args.exact {
        None
    } else {
        let step = progress.step("as-built Monte Carlo builds");
        let t = std::time::Instant::now();
        let ab = springfit::asbuilt::of_fit(&design, &outcome)
            .map_err(|e| anyhow::Error::new(e).context(design.path.display().to_string()))?;
        step.finish();
        Some((ab, t.elapsed().as_secs_f64()))
    };
    let step = progress.step("writing outputs");
    let dir = OutputDir::create(&target)?;
    springfit::report::fit::write_with_as_built(&dir, &design, &outcome, as_built.as_ref().and_then(|a| a.0.as_ref()))?;
    let written = dir.commit();
    step.finish();
    let written = written?;
    let st = &outcome.metrics.stats;
    if args.exact {
        progress.say(format!("{}: exact potential ½ω²r² (ω = {} rad/s)", outcome.design, settings.frequency));
    } else {
        progress.say(format!(
            "{}: {} springs from {} candidates of catalogue {} ({} never engage); solver {} ({})",
            outcome.design,
            outcome.used(),
            outcome.candidates - outcome.dropped,
            outcome.catalog,
            outcome.dropped,
            outcome.solve.solver,
            outcome.solve.status
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
    match &as_built {
        Some((Some(ab), secs)) => {
            progress.say(format!(
                "as built ({} builds at {} tolerance, {}; about each build's own equilibrium), p50 / p95 over builds: p99 {:.3}° / {:.3}°, max {:.3}° / {:.3}°, shift {:.4} / {:.4} rad (Euclidean), {:.4} / {:.4} (metric); {:.2} s",
                ab.builds,
                ab.tolerance.label(),
                ab.distribution.name(),
                ab.p99_deg.p50,
                ab.p99_deg.p95,
                ab.max_deg.p50,
                ab.max_deg.p95,
                ab.shift_rad.p50,
                ab.shift_rad.p95,
                ab.shift_metric.p50,
                ab.shift_metric.p95,
                secs
            ));
            if let Some(t) = &ab.trimmed {
                progress.say(format!(
                    "as built and trimmed: p99 {:.3}° / {:.3}°, max {:.3}° / {:.3}°; largest trim change {:.3} / {:.3} N·m/rad; {} builds not fully restored",
                    t.p99_deg.p50,
                    t.p99_deg.p95,
                    t.max_deg.p50,
                    t.max_deg.p95,
                    t.trim_change_nm_per_rad.p50,
                    t.trim_change_nm_per_rad.p95,
                    t.builds_not_restored
                ));
            }
            if ab.builds_without_equilibrium > 0 {
                progress.say(format!(
                    "{} builds have no stable equilibrium within 0.5 rad of q_eq (counted as the worst)",
                    ab.builds_without_equilibrium
                ));
            }
        }
        Some((None, _)) => progress.say(
            "as built: skipped (tolerance \"none\" and no catalogue tolerance, or builds = 0); set [fit] tolerance = 0.05 for ±5 % builds",
        ),
        None => {}
    }
    let files = if args.exact {
        "summary.json, residuals.csv, histogram, potential, report.md"
    } else {
        "bom.csv, bom.md, summary.json, residuals.csv, histogram, potential, report.md"
    };
    progress.say(format!("wrote {} ({files})", display(&written)));
    Ok(())
}

fn display(p: &Path) -> String {
    p.display().to_string()
}
