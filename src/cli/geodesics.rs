//! `springfit geodesics`: the fan, the region check and their plots (the job:
//! [`springfit::jobs::geodesics`]).

use std::path::{Path, PathBuf};

use super::Session;
use anyhow::Result;

pub fn run(path: &Path, out: Option<PathBuf>, session: &Session) -> Result<()> {
    let progress = &session.progress;
    let (design, _) = super::load_design(path, progress)?;
    let target = out.unwrap_or_else(|| PathBuf::from("out").join(format!("{}_geodesics", design.name)));
    let plan = session.plan_for(&design, "geodesics", springfit::jobs::geodesics::FILES.iter().copied());
    let claim = springfit::report::output::check(&target, &plan)?;
    let run = progress.run(|p| springfit::jobs::geodesics::geodesics(&design, p))?;
    let step = progress.step("writing outputs");
    let written = run.write(&design, claim);
    step.finish();
    let written = written?;
    let (fan, region) = (&run.fan, &run.region);
    let bound = if region.largest_radius_is_lower_bound { "≥ " } else { "" };
    progress.say(format!(
        "{}: {} geodesics, {} samples; largest valid geodesic-ball radius {bound}{:.4}",
        design.name,
        fan.geodesics.len(),
        fan.sample_count(),
        region.largest_radius
    ));
    progress.say(format!("wrote {} (geodesics.csv, region.json, geodesics.svg, geodesics.png)", written.display()));
    Ok(())
}
