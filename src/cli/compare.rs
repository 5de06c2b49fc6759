//! `springfit compare` and `springfit pareto`.

use std::path::{Path, PathBuf};

use anyhow::Result;
use springfit::design::Design;
use springfit::elements::catalog::Catalog;
use springfit::error::Error;
use springfit::files::fit_folder::load_fit_dir;
use springfit::fit::run::{exact_reference, fit};
use springfit::studies::compare::{FitRecord, budget_curve, disambiguate, radius_curve, record_of};

use super::Session;
use super::progress::Progress;

/// A design with its catalogue, validated before any work.
fn load_design_catalog(path: &Path, progress: &Progress) -> Result<(Design, Catalog)> {
    let (design, validated) = super::load_design(path, progress)?;
    let catalog = validated
        .catalog
        .ok_or_else(|| Error::invalid(&design.path, "catalog", "the design names no spring catalogue to fit"))?;
    Ok((design, catalog))
}

/// An input of `compare`, read and validated before anything is fitted.
enum Input {
    Fitted(Box<FitRecord>),
    Design(PathBuf, Box<(Design, Catalog)>),
}

pub fn compare(inputs: &[PathBuf], out: Option<PathBuf>, exact: bool, session: &Session) -> Result<()> {
    let progress = &session.progress;
    if inputs.is_empty() {
        return Err(Error::Setting {
            field: "inputs".into(),
            reason: "give fit output folders or design files to compare".into(),
        }
        .into());
    }
    let target = out.unwrap_or_else(|| PathBuf::from("out").join("compare"));
    let plan = session.plan("compare", springfit::report::compare::COMPARE_FILES.iter().copied());
    let claim = springfit::report::output::check(&target, &plan)?;
    // Every input is read and validated first, so a bad last input costs no fit of the first.
    let mut read = Vec::new();
    for input in inputs {
        read.push(if input.extension().is_some_and(|e| e == "toml") && input.is_file() {
            Input::Design(input.clone(), Box::new(load_design_catalog(input, progress)?))
        } else {
            Input::Fitted(Box::new(load_fit_dir(input)?))
        });
    }
    let exact_design = if exact {
        let file = read
            .iter()
            .find_map(|r| match r {
                Input::Fitted(r) => r.design_file.clone(),
                Input::Design(p, _) => Some(p.clone()),
            })
            .ok_or_else(|| Error::Setting {
                field: "--exact".into(),
                reason:
                    "no input names its design file (fit folders of older springfit versions do not): add a design file"
                        .into(),
            })?;
        Some((file.clone(), super::load_design(&file, progress)?.0))
    } else {
        None
    };
    let mut records: Vec<FitRecord> = Vec::new();
    for input in read {
        records.push(match input {
            Input::Fitted(r) => *r,
            Input::Design(path, dc) => {
                let (design, catalog) = *dc;
                let step = progress.step(&format!("fitting {}", path.display()));
                let outcome = fit(&design, &catalog, &design.fit, &|_| {})
                    .map_err(|e| super::fit_failed(&design, &design.fit, Some(&catalog), e));
                let as_built = match &outcome {
                    Ok(o) => springfit::asbuilt::of_fit(&design, o)?,
                    Err(_) => None,
                };
                step.finish();
                let mut r = record_of(&outcome?, &path);
                r.as_built = as_built.as_ref().map(springfit::asbuilt::Brief::of);
                r
            }
        });
    }
    if let Some((file, design)) = exact_design {
        let step = progress.step("evaluating the exact potential");
        let outcome = exact_reference(&design, &design.fit, &|_| {});
        step.finish();
        let mut r = record_of(&outcome.map_err(|e| super::fit_failed(&design, &design.fit, None, e))?, &file);
        r.design = "exact ½ω²r²".to_string();
        r.label = r.design.clone();
        records.push(r);
    }
    disambiguate(&mut records);
    let written = springfit::report::compare::write_compare_folder(claim, &records)?;
    for r in &records {
        progress.say(format!(
            "{}: {} springs, p99 {}, max {}{}",
            r.label,
            r.used,
            springfit::units::deg(r.stats.p99_abs),
            springfit::units::deg(r.stats.max_abs),
            r.actuator_share.map(|a| format!(", actuator share {:.3} %", 100.0 * a)).unwrap_or_default()
        ));
        if let Some(b) = &r.as_built {
            progress.say(format!(
                "  as built p99 (p50 / p95 over builds): {}{}",
                springfit::studies::compare::spread_md(Some(b.p99_deg)),
                b.trimmed_p99_deg
                    .map(|t| format!("; trimmed {}", springfit::studies::compare::spread_md(Some(t))))
                    .unwrap_or_default()
            ));
        }
    }
    progress.say(format!("wrote {} (compare.csv, compare.md, compare.svg, compare.png)", written.display()));
    Ok(())
}

pub fn pareto(
    path: &Path,
    out: Option<PathBuf>,
    k_max: Option<usize>,
    radii: Option<Vec<f64>>,
    session: &Session,
) -> Result<()> {
    let progress = &session.progress;
    let (design, catalog) = load_design_catalog(path, progress)?;
    let target = out.unwrap_or_else(|| PathBuf::from("out").join(format!("{}_pareto", design.name)));
    let plan = session.plan_for(&design, "pareto", springfit::report::compare::PARETO_FILES.iter().copied());
    let claim = springfit::report::output::check(&target, &plan)?;
    let k_max = k_max.unwrap_or(design.fit.max_elements.max(16));
    if k_max < 2 {
        return Err(Error::Setting { field: "--k-max".into(), reason: "must be at least 2".into() }.into());
    }
    if k_max > 1000 {
        return Err(Error::Setting { field: "--k-max".into(), reason: format!("at most 1000, got {k_max}") }.into());
    }
    for (i, r) in radii.iter().flatten().enumerate() {
        if !(r.is_finite() && *r > 0.0) {
            return Err(Error::Setting {
                field: format!("--radii[{i}]"),
                reason: format!("must be a positive geodesic-ball radius, got {r}"),
            }
            .into());
        }
    }
    // The radii are checked against the region check before any fit, so a radius past the
    // largest valid one is blamed on --radii, not on the design's region.radius.
    let radii = pareto_radii(&design, radii, progress)?;
    let budgets: Vec<usize> = (2..=k_max).collect();
    let step = progress.step(&format!("budgets 2 … {k_max}"));
    let curve = budget_curve(&design, &catalog, &design.fit, &budgets, &|_| {});
    step.finish();
    let curve = curve.map_err(|e| super::fit_failed(&design, &design.fit, Some(&catalog), e))?;
    let step = progress.step("region sizes");
    let rcurve = radius_curve(&design, &catalog, &design.fit, &radii, &|_| {});
    step.finish();
    let rcurve = rcurve.map_err(|e| super::fit_failed(&design, &design.fit, Some(&catalog), e))?;
    if curve.iter().all(|b| b.infeasible.is_some()) && rcurve.iter().all(|r| r.infeasible.is_some()) {
        let last = curve.last().and_then(|b| b.infeasible.clone()).unwrap_or_default();
        return Err(Error::Infeasible {
            constraint: format!("every budget K = 2 … {k_max} and every radius"),
            reason: last,
        }
        .into());
    }
    let dir = claim.open()?;
    springfit::report::compare::write_pareto(&dir, &design.name, &curve, &rcurve, design.fit.max_elements)?;
    springfit::report::html::write_pareto(&dir, &design)?;
    let written = dir.commit()?;
    progress.say("budget K: springs used, p99, max; as built p99 p50 / p95 over builds (untrimmed; trimmed)");
    for b in &curve {
        match &b.infeasible {
            None => progress.say(format!(
                "  {:>3}: {:>3}  {:.4}°  {:.4}°  {}{}",
                b.budget,
                b.used,
                b.stats.p99_abs,
                b.stats.max_abs,
                springfit::studies::compare::spread_md(b.as_built.map(|a| a.p99_deg)),
                b.as_built
                    .and_then(|a| a.trimmed_p99_deg)
                    .map(|t| format!("; {}", springfit::studies::compare::spread_md(Some(t))))
                    .unwrap_or_default()
            )),
            Some(why) => progress.say(format!("  {:>3}: infeasible ({why})", b.budget)),
        }
    }
    if let Some(best) = springfit::studies::compare::best_as_built(&curve) {
        progress.say(format!(
            "best as built: K = {} (as-built p95 of the p99 {:.3}°{})",
            best.budget,
            best.as_built.map(|a| a.trimmed_p99_deg.unwrap_or(a.p99_deg).p95).unwrap_or(f64::NAN),
            if best.as_built.is_some_and(|a| a.trimmed_p99_deg.is_some()) { ", trimmed" } else { "" }
        ));
    } else {
        progress
            .say("as built: no tolerance to draw builds at ([fit] tolerance = \"none\" and no catalogue tolerance)");
    }
    progress.say("radius: springs used, p99, max");
    for r in &rcurve {
        match &r.infeasible {
            None => progress
                .say(format!("  {:.2}: {:>3}  {:.4}°  {:.4}°", r.radius, r.used, r.stats.p99_abs, r.stats.max_abs)),
            Some(why) => progress.say(format!("  {:.2}: infeasible ({why})", r.radius)),
        }
    }
    progress.say(format!("wrote {}", written.display()));
    Ok(())
}

/// Number of radii of the default region-size curve.
const DEFAULT_RADII: usize = 8;

/// The radii of the region-size curve: the given ones, each checked against the largest valid
/// geodesic-ball radius, or [`DEFAULT_RADII`] evenly from 0.5 (less for small regions) up to the
/// largest valid radius.
fn pareto_radii(design: &Design, given: Option<Vec<f64>>, progress: &Progress) -> Result<Vec<f64>> {
    match given {
        Some(radii) => {
            let Some(top) = radii.iter().copied().reduce(f64::max) else {
                return Err(
                    Error::Setting { field: "--radii".into(), reason: "give at least one radius".into() }.into()
                );
            };
            let mut probe = design.clone();
            probe.region = springfit::geodesic::Region::Ball { radius: top };
            let step = progress.step("checking the largest radius");
            let report = probe.region_report();
            step.finish();
            let report = report?;
            if !report.valid {
                let i = radii.iter().position(|r| *r > report.largest_radius).unwrap_or(0);
                return Err(Error::Setting {
                    field: format!("--radii[{i}]"),
                    reason: format!(
                        "{} is past the largest valid geodesic-ball radius {:.4} of {}: {}",
                        radii[i],
                        report.largest_radius,
                        design.path.display(),
                        report.reason
                    ),
                }
                .into());
            }
            Ok(radii)
        }
        None => {
            let step = progress.step("checking the region");
            let report = design.region_report();
            step.finish();
            let report = report?;
            // A probed bound is itself valid; a conjugate point or a crossing is not: stay below.
            let top =
                if report.largest_radius_is_lower_bound { report.largest_radius } else { 0.98 * report.largest_radius };
            let top = (top * 100.0).floor() / 100.0;
            let start = 0.5_f64.min(top / 4.0);
            let mut radii: Vec<f64> = (0..DEFAULT_RADII)
                .map(|i| start + (top - start) * i as f64 / (DEFAULT_RADII - 1) as f64)
                .map(|r| (r * 100.0).round() / 100.0)
                .filter(|r| *r > 0.0 && *r <= top)
                .collect();
            radii.dedup();
            Ok(radii)
        }
    }
}
