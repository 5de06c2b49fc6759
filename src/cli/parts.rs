//! `springfit parts`: a spring for every element of a fitted bill, checked for stress, fatigue
//! and fit, ordered from stock where the design's stock list has one; the realised design judged
//! like the ideal one. `fit` runs the same stage into its own folder.

use std::path::{Path, PathBuf};

use anyhow::Result;
use springfit::design::Design;
use springfit::error::Error;
use springfit::parts::{Parts, StockPart};

use super::Session;

/// The stock list `[parts] stock` names, read before any work ([`springfit::files::stock::of_design`]).
pub fn load_stock(design: &Design) -> springfit::Result<Vec<StockPart>> {
    springfit::files::stock::of_design(design)
}

/// The lines `parts` and `fit` print about the parts.
pub fn say(parts: &Parts, session: &Session) {
    let progress = &session.progress;
    let found = parts.elements.iter().filter(|e| e.part.is_ok()).count();
    let stock = parts.elements.iter().filter(|e| e.stock.is_some()).count();
    let mass: f64 = parts.elements.iter().filter_map(|e| e.part.as_ref().ok()).map(|p| p.mass).sum();
    progress.say(format!(
        "parts: {found} of {} elements have a part ({stock} from stock), springs {mass:.3} kg; realised design: p99 {:.4}°, max {:.4}° (ideal elements: p99 {:.4}°, max {:.4}°)",
        parts.elements.len(),
        parts.realised.p99_abs,
        parts.realised.max_abs,
        parts.ideal.p99_abs,
        parts.ideal.max_abs
    ));
    for (e, l) in parts.missing() {
        progress.warn(springfit::parts::limit_message(e, l));
    }
}

pub fn run(design: &Path, bom: Option<PathBuf>, out: Option<PathBuf>, session: &Session) -> Result<()> {
    let progress = &session.progress;
    let (design, validated) = super::load_design(design, progress)?;
    let target = out.unwrap_or_else(|| PathBuf::from("out").join(format!("{}_parts", design.name)));
    let plan = session.plan_for(&design, "parts", springfit::report::parts::FILES.iter().copied());
    let claim = springfit::report::output::check(&target, &plan)?;
    let stock = load_stock(&design)?;
    let settings = design.fit;
    let Some(catalog) = &validated.catalog else {
        return Err(Error::invalid(
            &design.path,
            "catalog",
            "the design names no spring catalogue: there is nothing to realise",
        )
        .into());
    };
    let (bom, cams, evaluation, ideal) = match bom {
        Some(path) => {
            let mut rows = springfit::files::bom::read(&path)?;
            if rows.first().is_some_and(|r| r.element.coupling.len() != design.dof()) {
                return Err(Error::invalid(
                    &path,
                    "line 2: coupling",
                    format!(
                        "has {} entries but the design's robot has {} joints",
                        rows[0].element.coupling.len(),
                        design.dof()
                    ),
                )
                .into());
            }
            let step = progress.step("tracing the held-out geodesics");
            let fans = springfit::fit::prepare::fans(&design, &settings);
            step.finish();
            let (_, _, evaluation) =
                fans.map_err(|e| anyhow::Error::new(e).context(design.path.display().to_string()))?;
            let cams = springfit::fit::bill::realise_parts(catalog, &mut rows, &evaluation, design.q_eq.as_slice());
            (rows, cams, evaluation, None)
        }
        None => {
            let outcome = springfit::fit::run::fit(&design, catalog, &settings, &|_| {})
                .map_err(|e| super::fit_failed(&design, &settings, Some(catalog), e))?;
            (outcome.bom, outcome.cams, outcome.evaluation, Some(outcome.metrics.stats))
        }
    };
    let step = progress.step("choosing parts");
    let parts = springfit::parts::choose(&design, &bom, &cams, &evaluation, settings.frequency, &stock, ideal);
    step.finish();
    let parts = parts.map_err(|e| anyhow::Error::new(e).context(design.path.display().to_string()))?;
    let dir = claim.open()?;
    springfit::report::parts::write(&dir, &design, &parts)?;
    let written = dir.commit()?;
    say(&parts, session);
    progress.say(format!("wrote {} (parts.csv, parts.md, sketch_*.svg)", written.display()));
    if let Some((e, l)) = parts.missing().next() {
        return Err(Error::NoPart { path: design.path.clone(), reason: springfit::parts::limit_message(e, l) }.into());
    }
    Ok(())
}
