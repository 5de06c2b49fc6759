//! `springfit parts`: a spring for every element of a fitted bill, checked for stress, fatigue
//! and fit, ordered from stock where the design's stock list has one; the realised design judged
//! like the ideal one. The fit job chooses the same parts with its fit.
//!
//! The feature's files: the settings `design/parts.rs`, the choice `parts/`, the mechanisms and
//! springs `realise/` (`mechanism.rs`, `spring.rs`, `material.rs`, `sketch.rs`), the stock list
//! `files/stock.rs` and `files/parts.rs`, the files written `report/parts.rs`, the command
//! `cli/parts.rs`.

use std::path::{Path, PathBuf};

use super::{Couplings, Topic, Warning, check_couplings, check_equilibrium};
use crate::design::Design;
use crate::elements::catalog::Catalog;
use crate::error::{Error, Result};
use crate::fit::hints;
use crate::parts::Parts;
use crate::progress::Progress;
use crate::report::output::Claim;

/// The names `springfit parts` may write.
pub const FILES: &[&str] = crate::report::parts::FILES;

/// Chooses the parts of `design`'s fit with `catalog`, or of the bill at `bom` (read back and
/// realised on the held-out fan). The stock list `[parts] stock` names is read first.
pub fn parts(
    design: &Design,
    catalog: Option<&Catalog>,
    bom: Option<&Path>,
    progress: Progress<'_>,
) -> Result<PartsRun> {
    let stock = crate::files::stock::of_design(design)?;
    let settings = design.fit;
    let Some(catalog) = catalog else {
        return Err(Error::invalid(
            &design.path,
            "catalog",
            "the design names no spring catalogue: there is nothing to realise",
        ));
    };
    let (bom, cams, evaluation, ideal) = match bom {
        Some(path) => {
            let mut rows = crate::files::bom::read(path)?;
            check_couplings(design, path, &rows, Couplings::Line2)?;
            check_equilibrium(design, path, &rows)?;
            progress.stage("tracing the held-out geodesics");
            let (_, _, evaluation) = crate::fit::prepare::fans(design, &settings)?;
            let cams = crate::fit::bill::realise_parts(catalog, &mut rows, &evaluation, design.q_eq.as_slice());
            (rows, cams, evaluation, None)
        }
        None => {
            let outcome = crate::fit::run::fit(design, catalog, &settings, Progress::none())
                .map_err(|e| hints::explain(design, &settings, catalog, settings.max_elements, e))?;
            (outcome.bom, outcome.cams, outcome.evaluation, Some(outcome.metrics.stats))
        }
    };
    progress.stage("choosing parts");
    let parts = crate::parts::choose(design, &bom, &cams, &evaluation, settings.frequency, &stock, ideal)?;
    let warnings = warnings(&parts);
    Ok(PartsRun { parts, warnings })
}

/// The parts of a bill and what they warn of.
#[derive(Debug, Clone)]
pub struct PartsRun {
    /// The parts, and the realised design's residual angles beside the ideal ones.
    pub parts: Parts,
    /// The elements no spring meets ([`Topic::Parts`]).
    pub warnings: Vec<Warning>,
}

impl PartsRun {
    /// Writes `parts.csv`, `parts.md` and the sketches into the claimed folder.
    pub fn write(&self, design: &Design, claim: Claim) -> Result<PathBuf> {
        let dir = claim.open()?;
        crate::report::parts::write(&dir, design, &self.parts)?;
        dir.commit()
    }

    /// The error of a bill with an element no spring meets (the first), after the files are
    /// written: the design as drawn cannot be built.
    pub fn missing(&self, design: &Design) -> Result<()> {
        match self.parts.missing().next() {
            Some((e, l)) => Err(Error::NoPart { path: design.path.clone(), reason: crate::parts::limit_message(e, l) }),
            None => Ok(()),
        }
    }
}

/// One warning per element no spring meets, naming the limit and the setting to widen.
pub fn warnings(parts: &Parts) -> Vec<Warning> {
    parts.missing().map(|(e, l)| Warning { topic: Topic::Parts, message: crate::parts::limit_message(e, l) }).collect()
}
