//! `springfit check`: validate a design and say what it describes.

use std::path::Path;

use anyhow::Result;
use springfit::design::Design;
use springfit::geodesic::Region;

use super::progress::Progress;

pub fn run(path: &Path, json: bool, progress: &Progress) -> Result<()> {
    // The same validation every command runs first: what passes here is not rejected later for
    // a reason visible in the files.
    let (design, validated) = super::load_design(path, progress)?;
    if json {
        return run_json(&design);
    }
    let n = design.dof();
    if let Some(chain) = design.chain.planar() {
        progress.say(format!(
            "design {} ({}): {n} links, gravity {:?} m/s²",
            design.name,
            design.path.display(),
            chain.gravity()
        ));
        for (i, l) in chain.links().iter().enumerate() {
            progress.say(format!(
                "  link {}: mass {} kg, length {} m, com {} m, inertia {} kg·m²",
                i + 1,
                l.mass,
                l.length,
                l.com,
                l.inertia
            ));
        }
    }
    if let Some(chain) = design.chain.spatial() {
        progress.say(format!(
            "design {} ({}): {n} joints of a spatial chain, gravity {:?} m/s² in the base frame",
            design.name,
            design.path.display(),
            chain.gravity()
        ));
        for b in chain.bodies() {
            progress.say(format!(
                "  joint {}: axis {} moves {} kg (held joints and fixed links merged), com {} m",
                b.joint,
                fmt_vec(b.axis.as_slice()),
                b.mass,
                fmt_vec(b.com.as_slice())
            ));
        }
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

/// `--json`: one object on stdout; an invalid region is reported in it and then as an error.
fn run_json(design: &Design) -> Result<()> {
    let q = design.q_eq.as_slice();
    let m = design.chain.mass_matrix(&design.q_eq);
    let report = design.region_report()?;
    let rows: Vec<Vec<f64>> = m.row_iter().map(|r| r.iter().copied().collect()).collect();
    let object = serde_json::json!({
        "design": design.name,
        "dof": design.dof(),
        "joints": design.chain.joint_names(),
        "q_eq": q,
        "mass_matrix": rows,
        "gravity_torque": design.chain.gravity_gradient(q).as_slice(),
        "region": report,
    });
    // A closed stdout (`| head`) is not an error worth a panic: the reader has what it wanted.
    {
        use std::io::Write;
        let _ = writeln!(std::io::stdout(), "{}", serde_json::to_string_pretty(&object)?);
    }
    design.ensure_valid(&report)?;
    Ok(())
}

pub fn fmt_vec(v: &[f64]) -> String {
    format!("({})", v.iter().map(|x| format!("{x:.4}")).collect::<Vec<_>>().join(", "))
}
