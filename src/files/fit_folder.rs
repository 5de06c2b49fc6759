//! Reading the output folder of `springfit fit` back into a [`FitRecord`] for `compare`: its
//! summary, residual angles and bill of materials, and the actuator share of a simulation of
//! the same springs beside it.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::files::bom;
use crate::residual::stats;
use crate::studies::compare::{FitRecord, totals};

/// Reads the output folder of `springfit fit`. A folder without `summary.json` and
/// `residuals.csv` is refused with a message saying so.
pub fn load_fit_dir(dir: &Path) -> Result<FitRecord> {
    // The hint never suggests fitting into an existing folder: that folder is someone else's.
    let not_fit = |what: &str| {
        Error::invalid(
            dir,
            "folder",
            format!(
                "is not an output folder of `springfit fit`: {what} (give a fit output folder or a design file; \
                 `springfit fit DESIGN --out NEW_FOLDER` writes one)"
            ),
        )
    };
    if !dir.is_dir() {
        return Err(Error::invalid(
            dir,
            "folder",
            format!(
                "no such folder (give a design file, or fit one first: `springfit fit DESIGN --out {}`)",
                dir.display()
            ),
        ));
    }
    if let Some(m) = crate::report::output::Manifest::read(dir)?
        && m.command != "fit"
    {
        return Err(not_fit(&format!("it was written by `springfit {}`", m.command)));
    }
    let summary_path = dir.join("summary.json");
    let residuals_path = dir.join("residuals.csv");
    if !summary_path.is_file() {
        return Err(not_fit("it has no summary.json"));
    }
    if !residuals_path.is_file() {
        return Err(not_fit("it has no residuals.csv"));
    }
    let text = std::fs::read_to_string(&summary_path).map_err(|e| Error::io(&summary_path, e))?;
    let summary: serde_json::Value = serde_json::from_str(&text).map_err(|e| Error::Parse {
        path: summary_path.clone(),
        line: e.line(),
        column: e.column(),
        message: e.to_string(),
    })?;
    let field = |k: &str| {
        summary
            .get(k)
            .ok_or_else(|| Error::invalid(&summary_path, k, "missing: not a summary written by `springfit fit`"))
    };
    let design = field("design")?.as_str().unwrap_or("?").to_string();
    let text = std::fs::read_to_string(&residuals_path).map_err(|e| Error::io(&residuals_path, e))?;
    let mut lines = text.lines();
    let header = lines.next().unwrap_or("");
    if !header.starts_with("direction,s,") || !header.ends_with(",angle_deg") {
        return Err(Error::invalid(&residuals_path, "header", "expected `direction,s,q…,angle_deg`"));
    }
    let mut angles = Vec::new();
    for (i, line) in lines.enumerate() {
        let v = line.rsplit(',').next().and_then(|x| x.trim().parse::<f64>().ok()).ok_or_else(|| {
            Error::invalid(&residuals_path, format!("line {}", i + 2), "the last field is not a number")
        })?;
        angles.push(v);
    }
    let samples: Vec<crate::residual::AngleSample> = angles
        .iter()
        .map(|&a| crate::residual::AngleSample { direction: 0, s: 0.0, q: Vec::new(), angle_deg: a })
        .collect();
    let bom_path = dir.join("bom.csv");
    let rows = if bom_path.is_file() { bom::read(&bom_path)? } else { Vec::new() };
    let fingerprint = summary.get("spring_set").and_then(|v| v.as_str()).map(str::to_string);
    let (actuator_share, savings, share_note) = match simulation_share(dir, fingerprint.as_deref()) {
        Ok((share, savings)) => (Some(share), savings, None),
        Err(note) => (None, None, Some(note)),
    };
    Ok(FitRecord {
        label: design.clone(),
        design,
        design_file: summary.get("design_file").and_then(|v| v.as_str()).map(PathBuf::from),
        catalog: field("catalog")?.as_str().unwrap_or("?").to_string(),
        solver: field("solver")?.as_str().unwrap_or("?").to_string(),
        used: field("used")?.as_u64().unwrap_or(0) as usize,
        stats: stats(&samples),
        angles,
        totals: totals(&rows),
        actuator_share,
        savings,
        share_note,
        source: dir.to_path_buf(),
        as_built: crate::asbuilt::Brief::from_json(&summary),
        spring_mass_kg: mass_figure(&summary, "spring_mass_kg"),
        mass_over_floor: mass_figure(&summary, "mass_over_floor"),
    })
}

/// A figure of the springs' mass from `summary.json`: its `mass` section, else (a folder from
/// before that section) its `realised` one, which has the same two keys.
fn mass_figure(summary: &serde_json::Value, key: &str) -> Option<f64> {
    ["mass", "realised"].iter().find_map(|section| summary.get(section)?.get(key)?.as_f64())
}

/// The actuator share of the design's `sensitivity` (else `switch`) scenario from the
/// simulation folder next to a fit folder (`<folder>_simulate`), with the same run's savings
/// against the arm without springs (None from a simulation that predates them), only when that
/// simulation ran the fit's own springs (the same `spring_set` fingerprint); else why there is
/// none.
fn simulation_share(
    dir: &Path,
    fingerprint: Option<&str>,
) -> std::result::Result<(f64, Option<crate::dynamics::scenario::Savings>), String> {
    let Some(fingerprint) = fingerprint else {
        return Err(
            "the fit's summary.json has no spring_set fingerprint (the exact reference, or an older springfit)".into(),
        );
    };
    let name = dir.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let sim = dir.with_file_name(format!("{name}_simulate"));
    let mut other = None;
    for scenario in ["sensitivity", "switch"] {
        let path = sim.join(format!("sim_{scenario}.json"));
        let Ok(text) = std::fs::read_to_string(&path) else { continue };
        let Ok(json) = serde_json::from_str::<serde_json::Value>(&text) else { continue };
        if json["spring_set"].as_str() != Some(fingerprint) {
            other = Some(path);
            continue;
        }
        let run = json["runs"].as_object().and_then(|runs| runs.values().next());
        if let Some(share) = run.and_then(|r| r["actuator_share"].as_f64()) {
            let savings = run.and_then(|r| serde_json::from_value(r["savings"].clone()).ok());
            return Ok((share, savings));
        }
    }
    Err(match other {
        Some(p) => format!("{} simulated another spring set (--exact, --bom or another fit)", p.display()),
        None => format!("no simulation of these springs in {}", sim.display()),
    })
}
