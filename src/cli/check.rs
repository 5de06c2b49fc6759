//! `springfit check`: validate a design and say what it describes.

use std::path::Path;

use anyhow::Result;
use springfit::design::Design;
use springfit::geodesic::Region;
use springfit::geodesic::region::RegionReport;
use springfit::jobs::init::{RATE_ERROR, SHIFT_BUDGET_RAD, stiffness};
use springfit::model::urdf::JointRange;

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
                "  joint {}: axis {} in the joint's own frame (the URDF's <axis>), moves {} kg (held joints and fixed links merged), com {} m in that frame",
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
    progress.say(format!("region: {}", design.region.describe()));
    for (name, range) in design.chain.joint_names().iter().zip(&design.joint_ranges) {
        if let JointRange::Limited { lower, upper } = range {
            progress.say(format!("  joint {name}: <limit> [{lower}, {upper}] rad"));
        }
    }
    match &validated.catalog {
        Some(c) => {
            let n = c.families.len();
            let families = if n == 1 { "family" } else { "families" };
            progress.say(format!("catalogue: {} ({}, {n} {families})", c.path.display(), c.name))
        }
        None => progress.say("catalogue: none (fit, sweep and pareto need one; fit --exact and geodesics do not)"),
    }
    if design.scenarios.is_empty() {
        progress.say("scenarios: none (simulate and sweep need [[scenario]] tables)");
    } else {
        let names: Vec<&str> = design.scenarios.iter().map(|s| s.name.as_str()).collect();
        progress.say(format!("scenarios: {}; sweep runs `{}`", names.join(", "), design.sweep.scenario));
    }
    let step = progress.step("checking the region (fan with Jacobi fields)");
    let report = design.region_report();
    let secs = step.finish();
    let report = report?;
    let bound = if report.largest_radius_is_lower_bound { "≥ " } else { "" };
    progress.say(format!(
        "region check ({secs:.2} s, {} directions): largest valid geodesic-ball radius {bound}{:.4}",
        design.geodesics.check_count(design.dof()),
        report.largest_radius
    ));
    for line in limited_by(&report) {
        progress.say(line);
    }
    design.ensure_valid(&report)?;
    progress.say(format!("ok: {}", report.reason));
    for line in margins(&report) {
        progress.say(line);
    }
    for line in suggestions(&design, &report) {
        progress.say(line);
    }
    for line in gravity(&design)? {
        progress.say(line);
    }
    Ok(())
}

/// What limits the region, nearest first, and the radius to choose: a margin inside the nearest.
fn limited_by(report: &RegionReport) -> Vec<String> {
    let mut out: Vec<String> = report
        .limited_by
        .iter()
        .map(|f| format!("  limited by the {} at radius {:.4}: {}", f.kind(), f.radius(), f.describe()))
        .collect();
    match report.suggested_radius() {
        Some((radius, f)) => out.push(format!(
            "suggested region.radius: {radius:.4} ({:.0} % of the {} at {:.4}: a joint limit is kept at 80 %, a conjugate point or crossing at 40 %, where fits stay accurate)",
            100.0 * f.suggested_share(),
            f.kind(),
            f.radius()
        )),
        None => out.push(format!(
            "  nothing limits the region up to the probe radius {:.4} (geodesics.probe_factor times its extent)",
            report.probe_radius
        )),
    }
    out
}

/// The region's margin to each thing that limits it (the nearest of each kind: conjugate point,
/// crossing, joint limit), as a share of that thing's radius: a region at 60 % of its conjugate
/// radius reads "margin to the conjugate point: the region reaches 0.3154, 60 % of its radius
/// 0.5257 (40 % short of it)". A box or a clipped ball is measured by its longest trace.
fn margins(report: &RegionReport) -> Vec<String> {
    report
        .limited_by
        .iter()
        .filter(|f| f.radius() > 0.0 && f.radius().is_finite())
        .map(|f| {
            let share = report.extent / f.radius();
            format!(
                "margin to the {}: the region reaches {:.4}, {:.0} % of its radius {:.4} ({:.0} % short of it)",
                f.kind(),
                report.extent,
                100.0 * share,
                f.radius(),
                100.0 * (1.0 - share)
            )
        })
        .collect()
}

/// Gravity against the stiffness ω²M at the equilibrium, and the ω that carries it.
fn gravity(design: &Design) -> Result<Vec<String>> {
    if !design.chain.has_gravity() {
        return Ok(Vec::new());
    }
    let s = stiffness(design)?;
    let mut out = vec![format!(
        "gravity at the equilibrium: its stiffness is {:.3}×ω²M at most (ω = {} rad/s); the softest direction {} has a net stiffness ω²λ_min = {:.4} N·m/rad and carries {:.4} N·m of gravity, so springs {:.0} % off their rates move the rest position by up to {:.2}°",
        s.gravity_ratio,
        s.omega,
        fmt_vec(&s.soft_direction),
        s.soft_stiffness,
        s.soft_load,
        100.0 * RATE_ERROR,
        s.shift.to_degrees()
    )];
    if s.needed_omega > s.omega {
        out.push(format!(
            "suggested fit.frequency: at least {:.3} rad/s (keeps that shift within {:.0}° and gravity's stiffness below ω²M; a stiffer target also needs lighter springs per unit of gravity carried)",
            s.needed_omega,
            SHIFT_BUDGET_RAD.to_degrees()
        ));
    } else {
        out.push(format!(
            "fit.frequency ω = {} rad/s carries gravity: the shift stays within {:.0}° (ω ≥ {:.3} rad/s would do)",
            s.omega,
            SHIFT_BUDGET_RAD.to_degrees(),
            s.needed_omega
        ));
    }
    Ok(out)
}

/// What to choose for a new arm, from the exact potential U* = ½ω²r² the springs approach: every
/// mode reaches the energy ½ω²r² at metric distance r, so a scenario's energy E fits inside a
/// ball of radius R only if E ≤ ½ω²R², and the largest valid radius bounds R.
fn suggestions(design: &Design, report: &RegionReport) -> Vec<String> {
    let (largest, lower_bound) = (report.largest_radius, report.largest_radius_is_lower_bound);
    let omega = design.fit.frequency;
    let radius = match design.region {
        Region::Ball { radius } => radius,
        Region::Box { .. } | Region::Clipped { .. } => design.valid_region().map(|r| r.extent).unwrap_or(largest),
    };
    let bound = if lower_bound { "at least " } else { "" };
    let mut out = vec![format!(
        "for this arm: region.radius up to the largest valid radius, {bound}{largest:.4} (a fit is easier well inside it); at fit.frequency ω = {omega} rad/s a mode reaches ½ω²r² = {:.4} J at the region's edge r = {radius:.4}, and {:.4} J at r = {largest:.4}",
        0.5 * omega * omega * radius * radius,
        0.5 * omega * omega * largest * largest,
    )];
    if let Some(share) = springfit::fit::hints::near_limit(report) {
        out.push(format!(
            "the region reaches {:.0} % of the largest valid radius: towards it the error of every finite set of springs grows fast (docs/theory.md, \"The region check\"); scripts/radius_limit.py measures what a smaller region.radius buys",
            100.0 * share
        ));
    }
    let energies: Vec<(String, f64)> = design.scenarios.iter().enumerate().flat_map(|(i, s)| s.energies(i)).collect();
    if let Some((field, e)) = energies.iter().cloned().max_by(|a, b| a.1.total_cmp(&b.1)) {
        let reach = 0.5 * omega * omega * radius * radius;
        let needed_omega = (2.0 * e).sqrt() / radius;
        out.push(if e <= reach {
            format!(
                "the scenarios ask for at most {e} J ({field}): inside the region at this ω (ω ≥ {needed_omega:.4} rad/s puts it inside region.radius = {radius:.4})"
            )
        } else {
            format!(
                "the scenarios ask for up to {e} J ({field}), beyond the {reach:.4} J the region reaches at this ω: raise fit.frequency to at least {needed_omega:.4} rad/s, or region.radius to at least {:.4}{}, or lower the energy",
                (2.0 * e).sqrt() / omega,
                if (2.0 * e).sqrt() / omega > largest && !lower_bound { " (beyond the largest valid radius: raise ω)" } else { "" }
            )
        });
    }
    out
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
        "joint_ranges": design.joint_ranges,
        "region": report,
        "stiffness": stiffness(design)?,
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
