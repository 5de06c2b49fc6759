//! `springfit compare` and `springfit pareto` (the jobs: [`springfit::jobs::compare`]).

use std::path::{Path, PathBuf};

use anyhow::Result;
use springfit::design::Design;
use springfit::elements::catalog::Catalog;
use springfit::error::Error;
use springfit::files::fit_folder::load_fit_dir;
use springfit::jobs::compare::{self, Comparison, ParetoJob, ParetoRequest};
use springfit::studies::compare::FitRecord;

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
    compare::inputs(inputs.len())?;
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
        let file = compare::exact_file(read.iter().map(|r| match r {
            Input::Fitted(r) => r.design_file.as_deref(),
            Input::Design(p, _) => Some(p.as_path()),
        }))
        .map_err(|e| super::flag(e, "exact", "--exact"))?;
        Some((file.clone(), super::load_design(&file, progress)?.0))
    } else {
        None
    };
    let mut records: Vec<FitRecord> = Vec::new();
    for input in read {
        records.push(match input {
            Input::Fitted(r) => *r,
            Input::Design(path, dc) => {
                let (design, catalog) = &*dc;
                progress.run(|p| compare::fitted(design, catalog, &path, p)).map_err(|e| super::in_design(design, e))?
            }
        });
    }
    if let Some((file, design)) = exact_design {
        records.push(progress.run(|p| compare::exact(&design, &file, p)).map_err(|e| super::in_design(&design, e))?);
    }
    let comparison = Comparison::new(records)?;
    let written = comparison.write(claim)?;
    let records = &comparison.records;
    for r in records {
        progress.say(format!(
            "{}: {} springs, p99 {}, max {}{}{}",
            r.label,
            r.used,
            springfit::report::deg(r.stats.p99_abs),
            springfit::report::deg(r.stats.max_abs),
            match (r.spring_mass_kg, r.mass_over_floor) {
                (Some(m), Some(f)) => format!(", springs {m:.3} kg ({f:.1}× the floor)"),
                _ => String::new(),
            },
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

/// The arguments of `springfit pareto`.
pub struct ParetoArgs {
    pub path: PathBuf,
    pub out: Option<PathBuf>,
    pub k_max: Option<usize>,
    pub radii: Option<Vec<f64>>,
    pub axis: Option<Vec<super::AxisArg>>,
    pub masses: Option<Vec<f64>>,
}

pub fn pareto(args: ParetoArgs, session: &Session) -> Result<()> {
    use springfit::jobs::compare::ParetoAxis;
    let ParetoArgs { path, out, k_max, radii, axis, masses } = args;
    let progress = &session.progress;
    let (design, catalog) = load_design_catalog(&path, progress)?;
    let target = out.unwrap_or_else(|| PathBuf::from("out").join(format!("{}_pareto", design.name)));
    let plan = session.plan_for(&design, "pareto", springfit::report::compare::PARETO_FILES.iter().copied());
    let claim = springfit::report::output::check(&target, &plan)?;
    // The job's arguments as the command line names them.
    let options = |e| {
        let e = super::flag(super::flag(e, "k_max", "--k-max"), "radii", "--radii");
        super::flag(super::flag(e, "masses", "--masses"), "axes", "--axis")
    };
    let axes = axis.map(|a| {
        a.iter()
            .map(|a| match a {
                super::AxisArg::Budget => ParetoAxis::Budget,
                super::AxisArg::Radius => ParetoAxis::Radius,
                super::AxisArg::Mass => ParetoAxis::Mass,
            })
            .collect()
    });
    let job = ParetoJob::new(&design, &catalog, ParetoRequest { k_max, radii, axes, masses }).map_err(options)?;
    let run = progress.run(|p| job.run(p)).map_err(|e| super::in_design(&design, options(e)))?;
    run.feasible()?;
    let written = run.write(&design, claim)?;
    let (curve, rcurve) = (&run.budgets, &run.radii);
    if !curve.is_empty() {
        print_budgets(curve, progress);
    }
    if !rcurve.is_empty() {
        progress.say("radius: springs used, p99, max");
        for r in rcurve {
            match &r.infeasible {
                None => progress
                    .say(format!("  {:.2}: {:>3}  {:.4}°  {:.4}°", r.radius, r.used, r.stats.p99_abs, r.stats.max_abs)),
                Some(why) => progress.say(format!("  {:.2}: infeasible ({why})", r.radius)),
            }
        }
    }
    if let Some(m) = &run.mass {
        progress.say(format!(
            "spring mass (floor {:.3} kg, arm {:.3} kg): max_spring_mass: springs used, p99, max; model mass, parts' mass (× floor)",
            m.floor_kg, m.arm_mass_kg
        ));
        for p in &m.points {
            let budget = p.max_spring_mass_kg.map(|b| format!("{b} kg")).unwrap_or_else(|| "none".into());
            match &p.infeasible {
                None => {
                    let parts = p.realised.and_then(|r| r.spring_mass_kg);
                    progress.say(format!(
                        "  {budget:>10}: {:>3}  {:.4}°  {:.4}°  {:.3} kg  {}",
                        p.used,
                        p.stats.p99_abs,
                        p.stats.max_abs,
                        p.model_mass_kg.unwrap_or(f64::NAN),
                        parts
                            .map(|v| format!("{v:.3} kg ({:.1}×)", v / m.floor_kg))
                            .unwrap_or_else(|| "no parts".into())
                    ))
                }
                Some(why) => progress.say(format!("  {budget:>10}: infeasible ({why})")),
            }
        }
    }
    progress.say(format!("wrote {}", written.display()));
    Ok(())
}

/// The budget curve as `pareto` prints it.
fn print_budgets(curve: &[springfit::studies::compare::BudgetPoint], progress: &Progress) {
    progress.say("budget K: springs used, p99, max; as built p99 p50 / p95 over builds (untrimmed; trimmed)");
    for b in curve {
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
    if let Some(best) = springfit::studies::compare::best_as_built(curve) {
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
}
