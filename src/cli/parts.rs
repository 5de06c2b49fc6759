//! `springfit parts`: a spring for every element of a fitted bill, checked for stress, fatigue
//! and fit, ordered from stock where the design's stock list has one; the realised design judged
//! like the ideal one (the job: [`springfit::jobs::parts`]). `fit` prints the same lines about
//! the parts it chose.

use std::path::{Path, PathBuf};

use anyhow::Result;
use springfit::design::parts::PartsSettings;
use springfit::jobs::{Topic, Warning, about};
use springfit::parts::Parts;

use super::Session;

/// The lines `parts` and `fit` print about the parts, with the warnings about them: the wire
/// first (which one and why, and the key that overrides it: a static grade chosen for many
/// swings is named as such), then what was found.
pub fn say(parts: &Parts, settings: &PartsSettings, warnings: &[Warning], session: &Session) {
    let progress = &session.progress;
    let key = if settings.material.is_some() { "" } else { "; [parts] material overrides it" };
    progress.say(format!("wire: {} ({}{key})", settings.material_key(), settings.material_choice()));
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
    for w in about(warnings, &Topic::Parts) {
        progress.warn(w);
    }
}

pub fn run(design: &Path, bom: Option<PathBuf>, out: Option<PathBuf>, session: &Session) -> Result<()> {
    let progress = &session.progress;
    let (design, validated) = super::load_design(design, progress)?;
    let target = out.unwrap_or_else(|| PathBuf::from("out").join(format!("{}_parts", design.name)));
    let plan = session.plan_for(&design, "parts", springfit::jobs::parts::FILES.iter().copied());
    let claim = springfit::report::output::check(&target, &plan)?;
    let run = progress
        .run(|p| springfit::jobs::parts::parts(&design, validated.catalog.as_ref(), bom.as_deref(), p))
        .map_err(|e| super::in_design(&design, e))?;
    let written = run.write(&design, claim)?;
    say(&run.parts, &design.parts, &run.warnings, session);
    progress.say(format!("wrote {} (parts.csv, parts.md, sketch_*.svg)", written.display()));
    run.missing(&design)?;
    Ok(())
}
