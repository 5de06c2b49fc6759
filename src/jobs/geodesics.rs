//! `springfit geodesics`: the fan of geodesics from the equilibrium, the region check and their
//! plots.
//!
//! The feature's files: the settings `design/mod.rs` (`[geodesics]`, `[region]`), the geodesics
//! `geodesic/` (shooting, the fan, the region check), the files written `report/geodesics.rs`
//! and `report/figures.rs`, the command `cli/geodesics.rs`.

use std::path::PathBuf;

use crate::design::Design;
use crate::error::Result;
use crate::geodesic::{Fan, FanSpec, RegionReport, Stop};
use crate::progress::Progress;
use crate::report::output::Claim;

/// The names `springfit geodesics` may write.
pub const FILES: &[&str] = crate::report::geodesics::FILES;

/// Checks the region of `design` and traces its fan (`[geodesics]` directions and samples).
pub fn geodesics(design: &Design, progress: Progress<'_>) -> Result<GeodesicsRun> {
    progress.stage("checking the region");
    let region = design.valid_region()?;
    progress.stage("tracing the fan");
    let spec = FanSpec {
        count: design.geodesics.directions,
        phase: 0.0,
        stop: Stop::Region { region: &design.region, max_arc: design.geodesics.max_arc },
        spacing: region.extent / design.geodesics.samples as f64,
    };
    let fan = Fan::trace(&design.chain, &design.q_eq, spec, design.geodesics.ode)?;
    Ok(GeodesicsRun { fan, region })
}

/// The fan and the region check.
#[derive(Debug, Clone)]
pub struct GeodesicsRun {
    /// The geodesics traced.
    pub fan: Fan,
    /// The region check.
    pub region: RegionReport,
}

impl GeodesicsRun {
    /// Writes `geodesics.csv`, `region.json` and `geodesics.svg`/`.png` into the claimed folder.
    pub fn write(&self, design: &Design, claim: Claim) -> Result<PathBuf> {
        let dir = claim.open()?;
        crate::report::geodesics::write(&dir, design, &self.fan, &self.region)?;
        dir.commit()
    }
}
