//! `springfit identify`: a built arm's spring rates, damping and friction from logged swings, or
//! (a plan) the releases to log.
//!
//! The feature's files: the settings `design/identify.rs`, the logs `files/log.rs`, the
//! identification `identify/` (its module doc lists the steps: the region check of the samples,
//! the filter, the regression, the estimate, the plan, the simulated swing), the files written
//! `report/identify.rs`, the command `cli/identify.rs`. `tune` reads the `identified.csv` it
//! writes.

use std::path::{Path, PathBuf};

use crate::design::Design;
use crate::error::Result;
use crate::fit::bill::BomRow;
use crate::identify::Identification;
use crate::identify::plan::Plan;
use crate::progress::Progress;
use crate::report::output::Claim;

/// What `identify` is asked beyond the design and the bill.
#[derive(Debug, Clone, Copy)]
pub enum IdentifyRequest<'a> {
    /// Propose releases to log (D-optimal), with the standard errors they would give.
    Plan,
    /// Identify from these logs of the arm's motion (CSV).
    Logs(&'a [PathBuf]),
}

impl IdentifyRequest<'_> {
    /// The names the run may write.
    pub fn files(&self) -> &'static [&'static str] {
        match self {
            IdentifyRequest::Plan => crate::report::identify::PLAN_FILES,
            IdentifyRequest::Logs(_) => crate::report::identify::FILES,
        }
    }
}

/// Identifies the arm of `design` built with the bill at `bom` from the request's logs, or plans
/// the releases to log.
pub fn identify(
    design: &Design,
    bom: &Path,
    request: IdentifyRequest<'_>,
    progress: Progress<'_>,
) -> Result<IdentifyRun> {
    let rows = crate::files::bom::read(bom)?;
    // A bill of another number of joints is refused by `identify::check_bill` in its own words.
    if rows.iter().all(|r| r.element.coupling.len() == design.dof()) {
        super::check_equilibrium(design, bom, &rows)?;
    }
    let made = match request {
        IdentifyRequest::Plan => {
            progress.stage("planning releases");
            Identified::Plan(crate::identify::plan::plan(design, bom, &rows)?)
        }
        IdentifyRequest::Logs(paths) => {
            let logs = paths.iter().map(|p| crate::files::log::read(p, design.dof())).collect::<Result<Vec<_>>>()?;
            progress.stage("identifying");
            Identified::Rates(crate::identify::identify(design, bom, &rows, &logs, &design.identify)?)
        }
    };
    Ok(IdentifyRun { rows, made })
}

/// What an identification made: the plan of releases, or the rates identified from the logs.
#[derive(Debug, Clone)]
pub enum Identified {
    /// The releases to log, and the standard errors they would give.
    Plan(Plan),
    /// The rates, damping and friction identified.
    Rates(Identification),
}

/// An identification: the bill it is about and what was made of it.
#[derive(Debug, Clone)]
pub struct IdentifyRun {
    /// The bill of the built arm.
    pub rows: Vec<BomRow>,
    /// The plan or the identification.
    pub made: Identified,
}

impl IdentifyRun {
    /// Writes `plan.md`, `plan.json`, `plan_rates` or `identify.md`, `identify.json`,
    /// `identified.csv`, `identify_torque`, `identify_rates`, and `report.html` into the claimed
    /// folder.
    pub fn write(&self, design: &Design, claim: Claim) -> Result<PathBuf> {
        let dir = claim.open()?;
        match &self.made {
            Identified::Plan(p) => crate::report::identify::write_plan(&dir, &design.name, p, &self.rows)?,
            Identified::Rates(id) => crate::report::identify::write(&dir, &design.name, id, &self.rows)?,
        }
        crate::report::html::write_identify(&dir, design)?;
        dir.commit()
    }
}
