//! `springfit compare` and `springfit pareto`.

use std::path::{Path, PathBuf};

use anyhow::Result;
use springfit::catalog::Catalog;
use springfit::compare::{FitRecord, budget_curve, disambiguate, load_fit_dir, radius_curve, record_of};
use springfit::design::Design;
use springfit::error::Error;
use springfit::fit::run::{exact_reference, fit};
use springfit::report::output::OutputDir;

use super::progress::Progress;

fn load_design_catalog(path: &Path) -> Result<(Design, Catalog)> {
    let design = Design::load(path)?;
    let catalog_path = design
        .catalog
        .clone()
        .ok_or_else(|| Error::invalid(&design.path, "catalog", "the design names no spring catalogue"))?;
    let catalog = Catalog::load(&catalog_path, design.dof())?;
    Ok((design, catalog))
}

pub fn compare(inputs: &[PathBuf], out: Option<PathBuf>, exact: bool, progress: &Progress) -> Result<()> {
    if inputs.is_empty() {
        return Err(Error::Setting {
            field: "inputs".into(),
            reason: "give fit output folders or design files to compare".into(),
        }
        .into());
    }
    let mut records: Vec<FitRecord> = Vec::new();
    for input in inputs {
        let record = if input.extension().is_some_and(|e| e == "toml") && input.is_file() {
            let step = progress.step(&format!("fitting {}", input.display()));
            let (design, catalog) = load_design_catalog(input)?;
            let outcome = fit(&design, &catalog, &design.fit, &|_| {}).and_then(|o| {
                let ab = springfit::asbuilt::of_fit(&design, &o)?;
                Ok((o, ab))
            });
            step.finish();
            let (outcome, ab) = outcome?;
            let mut r = record_of(&outcome, input);
            r.as_built = ab.as_ref().map(springfit::asbuilt::Brief::of);
            r
        } else {
            load_fit_dir(input)?
        };
        records.push(record);
    }
    if exact {
        let file = records.iter().find_map(|r| r.design_file.clone()).ok_or_else(|| Error::Setting {
            field: "--exact".into(),
            reason:
                "no input names its design file (fit folders of older springfit versions do not): add a design file"
                    .into(),
        })?;
        let design = Design::load(&file)?;
        let step = progress.step("evaluating the exact potential");
        let outcome = exact_reference(&design, &design.fit, &|_| {});
        step.finish();
        let mut r = record_of(&outcome?, &file);
        r.design = "exact ½ω²r²".to_string();
        r.label = r.design.clone();
        records.push(r);
    }
    disambiguate(&mut records);
    let target = out.unwrap_or_else(|| PathBuf::from("out").join("compare"));
    let dir = OutputDir::create(&target)?;
    // Two-joint residual angles are signed; three or more are unsigned (all ≥ 0).
    let signed = records.iter().any(|r| r.angles.iter().any(|a| *a < 0.0));
    springfit::report::compare::write_compare(&dir, &records, signed)?;
    let written = dir.commit()?;
    for r in &records {
        progress.say(format!(
            "{}: {} springs, p99 {:.4}°, max {:.4}°{}",
            r.label,
            r.used,
            r.stats.p99_abs,
            r.stats.max_abs,
            r.actuator_share.map(|a| format!(", actuator share {:.3} %", 100.0 * a)).unwrap_or_default()
        ));
        if let Some(b) = &r.as_built {
            progress.say(format!(
                "  as built p99 (p50 / p95 over builds): {}{}",
                springfit::compare::spread_md(Some(b.p99_deg)),
                b.trimmed_p99_deg
                    .map(|t| format!("; trimmed {}", springfit::compare::spread_md(Some(t))))
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
    progress: &Progress,
) -> Result<()> {
    let (design, catalog) = load_design_catalog(path)?;
    let k_max = k_max.unwrap_or(design.fit.max_elements.max(16));
    if k_max < 2 {
        return Err(Error::Setting { field: "--k-max".into(), reason: "must be at least 2".into() }.into());
    }
    let budgets: Vec<usize> = (2..=k_max).collect();
    let step = progress.step(&format!("budgets 2 … {k_max}"));
    let curve = budget_curve(&design, &catalog, &design.fit, &budgets, &|_| {});
    step.finish();
    let curve = curve?;
    let radii = match radii {
        Some(r) => r,
        None => {
            let report = design.region_report()?;
            let top = report.largest_radius;
            let n = 8;
            (0..n)
                .map(|i| 0.5 + (top - 0.5) * i as f64 / (n - 1) as f64)
                .map(|r| (r * 100.0).round() / 100.0)
                .filter(|r| *r < top)
                .collect()
        }
    };
    for (i, r) in radii.iter().enumerate() {
        if !(r.is_finite() && *r > 0.0) {
            return Err(Error::Setting {
                field: format!("--radii[{i}]"),
                reason: format!("must be positive, got {r}"),
            }
            .into());
        }
    }
    let step = progress.step("region sizes");
    let rcurve = radius_curve(&design, &catalog, &design.fit, &radii, &|_| {});
    step.finish();
    let rcurve = rcurve?;
    let target = out.unwrap_or_else(|| PathBuf::from("out").join(format!("{}_pareto", design.name)));
    let dir = OutputDir::create(&target)?;
    springfit::report::compare::write_pareto(&dir, &design.name, &curve, &rcurve, design.fit.max_elements)?;
    let written = dir.commit()?;
    progress.say("budget K: springs used, p99, max; as built p99 p50 / p95 over builds (untrimmed; trimmed)");
    for b in &curve {
        progress.say(format!(
            "  {:>3}: {:>3}  {:.4}°  {:.4}°  {}{}",
            b.budget,
            b.used,
            b.stats.p99_abs,
            b.stats.max_abs,
            springfit::compare::spread_md(b.as_built.map(|a| a.p99_deg)),
            b.as_built
                .and_then(|a| a.trimmed_p99_deg)
                .map(|t| format!("; {}", springfit::compare::spread_md(Some(t))))
                .unwrap_or_default()
        ));
    }
    if let Some(best) = springfit::compare::best_as_built(&curve) {
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
        progress.say(format!("  {:.2}: {:>3}  {:.4}°  {:.4}°", r.radius, r.used, r.stats.p99_abs, r.stats.max_abs));
    }
    progress.say(format!("wrote {}", written.display()));
    Ok(())
}
