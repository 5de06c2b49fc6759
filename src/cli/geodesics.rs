//! `springfit geodesics`: the fan, the region check and their plots.

use std::path::{Path, PathBuf};

use anyhow::Result;
use springfit::geodesic::{Fan, FanSpec, Stop};

use super::Session;

pub fn run(path: &Path, out: Option<PathBuf>, session: &Session) -> Result<()> {
    let progress = &session.progress;
    let (design, _) = super::load_design(path, progress)?;
    let target = out.unwrap_or_else(|| PathBuf::from("out").join(format!("{}_geodesics", design.name)));
    let plan = session.plan_for(&design, "geodesics", springfit::report::geodesics::FILES.iter().copied());
    let claim = springfit::report::output::check(&target, &plan)?;
    let step = progress.step("checking the region");
    let region = design.valid_region();
    step.finish();
    let region = region?;
    let step = progress.step("tracing the fan");
    let spec = FanSpec {
        count: design.geodesics.directions,
        phase: 0.0,
        stop: Stop::Region { region: &design.region, max_arc: design.geodesics.max_arc },
        spacing: region.extent / design.geodesics.samples as f64,
    };
    let fan = Fan::trace(&design.chain, &design.q_eq, spec, design.geodesics.ode);
    step.finish();
    let fan = fan?;
    let step = progress.step("writing outputs");
    let dir = claim.open()?;
    springfit::report::geodesics::write(&dir, &design, &fan, &region)?;
    let written = dir.commit();
    step.finish();
    let written = written?;
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
