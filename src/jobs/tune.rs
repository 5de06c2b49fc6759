//! `springfit tune` and Python's `Design.tune()`: the offsets and trim rates to set on a built
//! arm, from its measured spring rates.
//!
//! The feature's files: the tune `asbuilt/tune.rs` (on the builds of `asbuilt/mod.rs` and the
//! trims of `elements/trim.rs`), the measured bill `files/bom.rs` (`load_measured`), the files
//! written `report/tune.rs`, the command `cli/tune.rs`. `identify` measures the rates.

use std::path::{Path, PathBuf};

use super::{Couplings, check_couplings, check_equilibrium};
use crate::asbuilt::tune::TuneOutcome;
use crate::design::Design;
use crate::error::Result;
use crate::progress::Progress;
use crate::report::output::Claim;

/// The names `springfit tune` may write.
pub const FILES: &[&str] = crate::report::tune::FILES;

/// Tunes the arm of `design` built with the bill at `measured` (the fit's `bom.csv` with a
/// `measured_stiffness` column).
pub fn tune(design: &Design, measured: &Path, progress: Progress<'_>) -> Result<TuneRun> {
    let (bom, rates) = crate::files::bom::load_measured(measured)?;
    check_couplings(design, measured, &bom, Couplings::Line2)?;
    check_equilibrium(design, measured, &bom)?;
    progress.stage("tuning");
    Ok(TuneRun { outcome: crate::asbuilt::tune::tune(design, &bom, &rates)? })
}

/// A tune: the settings to make and the arm before and after.
#[derive(Debug, Clone)]
pub struct TuneRun {
    /// The tune.
    pub outcome: TuneOutcome,
}

impl TuneRun {
    /// Writes `bom_tuned.csv`, `tune.json` and `tune.md` into the claimed folder.
    pub fn write(&self, design: &Design, claim: Claim) -> Result<PathBuf> {
        let dir = claim.open()?;
        crate::report::tune::write(&dir, &design.name, &self.outcome)?;
        dir.commit()
    }
}
