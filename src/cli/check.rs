//! `springfit check`: validate a design and say what it describes.

use std::path::Path;

use anyhow::Result;
use springfit::geodesic::Region;

use super::progress::Progress;

pub fn run(path: &Path, progress: &Progress) -> Result<()> {
    // The same validation every command runs first: what passes here is not rejected later for
    // a reason visible in the files.
    let (design, validated) = super::load_design(path, progress)?;
    let n = design.dof();
    progress.say(format!(
        "design {} ({}): {n} links, gravity {:?} m/s²",
        design.name,
        design.path.display(),
        design.chain.gravity()
    ));
    for (i, l) in design.chain.links().iter().enumerate() {
        progress.say(format!(
            "  link {}: mass {} kg, length {} m, com {} m, inertia {} kg·m²",
            i + 1,
            l.mass,
            l.length,
            l.com,
            l.inertia
        ));
    }
    progress.say(format!("equilibrium q = {}", fmt_vec(design.q_eq.as_slice())));
    let m = design.chain.mass_matrix(&design.q_eq);
    let rows: Vec<String> = m.row_iter().map(|r| fmt_vec(&r.iter().copied().collect::<Vec<_>>())).collect();
    progress.say(format!("mass matrix at the equilibrium: {}", rows.join(" ")));
    match &design.region {
        Region::Ball { radius } => progress.say(format!("region: geodesic ball of radius {radius}")),
        Region::Box { .. } => progress.say(format!("region: {}", design.region.describe())),
    }
    match &validated.catalog {
        Some(c) => progress.say(format!("catalogue: {} ({}, {} families)", c.path.display(), c.name, c.families.len())),
        None => progress.say("catalogue: none (fit, sweep and pareto need one; fit --exact and geodesics do not)"),
    }
    if design.file.scenario.is_empty() {
        progress.say("scenarios: none (simulate and sweep need [[scenario]] tables)");
    } else {
        let names: Vec<&str> = design.file.scenario.iter().map(|s| s.name.as_str()).collect();
        progress.say(format!("scenarios: {}; sweep runs `{}`", names.join(", "), design.file.sweep.scenario));
    }
    let step = progress.step("checking the region (fan with Jacobi fields)");
    let report = design.region_report();
    let secs = step.finish();
    let report = report?;
    let bound = if report.largest_radius_is_lower_bound { "≥ " } else { "" };
    progress.say(format!(
        "region check ({secs:.2} s, {} directions): largest valid geodesic-ball radius {bound}{:.4}",
        design.geodesics.check_directions, report.largest_radius
    ));
    design.ensure_valid(&report)?;
    progress.say(format!("ok: {}", report.reason));
    Ok(())
}

pub fn fmt_vec(v: &[f64]) -> String {
    format!("({})", v.iter().map(|x| format!("{x:.4}")).collect::<Vec<_>>().join(", "))
}
