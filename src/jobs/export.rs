//! `springfit export --mujoco` and Python's `Design.export_mujoco()`: the arm and its springs as
//! a MuJoCo model (MJCF), to check the design in another simulator.
//!
//! The feature's files: the model `export/mujoco.rs` (its elements exact or by passive-force
//! callback), the bill read back `files/bom.rs`, the command `cli/export.rs`, the check against
//! `springfit simulate` `scripts/verify_mujoco.py`.

use std::path::{Path, PathBuf};

use super::{Couplings, check_couplings, check_equilibrium};
use crate::design::Design;
use crate::elements::catalog::Catalog;
use crate::error::Result;
use crate::export::mujoco::MujocoModel;
use crate::fit::FitOutcome;
use crate::fit::bill::BomRow;
use crate::progress::Progress;
use crate::report::output::Claim;

/// The springs exported.
#[derive(Debug, Clone, Copy)]
pub enum ExportSprings<'a> {
    /// The bill of materials at this path, read back.
    Bom(&'a Path),
    /// The bill of a fit already made.
    Fitted(&'a FitOutcome),
    /// Springs fitted now with this catalogue.
    Fit(&'a Catalog),
}

/// The names an export of `design` may write.
pub fn files(design: &Design) -> Vec<String> {
    crate::export::mujoco::files(design)
}

/// The bill an export of `design` writes, and where it came from: read back (its couplings
/// checked against the design's joints) or fitted.
pub fn export(design: &Design, springs: ExportSprings<'_>, progress: Progress<'_>) -> Result<ExportRun> {
    let fitted_from = |o: &FitOutcome| format!("a fit of {} with catalogue {}", design.path.display(), o.catalog);
    Ok(match springs {
        ExportSprings::Bom(path) => {
            let rows = crate::files::bom::read(path)?;
            check_couplings(design, path, &rows, Couplings::Any)?;
            check_equilibrium(design, path, &rows)?;
            ExportRun { rows, from: format!("the bill of materials {}", path.display()), fit: None }
        }
        ExportSprings::Fitted(o) => ExportRun { rows: o.bom.clone(), from: fitted_from(o), fit: None },
        ExportSprings::Fit(catalog) => {
            progress.stage("fitting the springs");
            let o = super::fit::springs_of(design, catalog, &design.fit, Progress::none())?;
            ExportRun { rows: o.bom.clone(), from: fitted_from(&o), fit: Some(o) }
        }
    })
}

/// The springs of an export.
#[derive(Debug, Clone)]
pub struct ExportRun {
    /// The bill exported.
    pub rows: Vec<BomRow>,
    /// Where it came from, as `elements.md` says.
    pub from: String,
    /// The fit, when the springs were fitted for the export.
    pub fit: Option<FitOutcome>,
}

impl ExportRun {
    /// Builds the model and writes `<design name>.xml`, `elements.md` and `bom.csv` into the
    /// claimed folder; returns the model and the folder.
    pub fn write(&self, design: &Design, claim: Claim) -> Result<(MujocoModel, PathBuf)> {
        crate::export::mujoco::write_folder(claim, design, &self.rows, &self.from)
    }
}
