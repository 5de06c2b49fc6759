//! `springfit export`: the design and its springs for another simulator (MuJoCo's MJCF; the job:
//! [`springfit::jobs::export`]).

use std::path::PathBuf;

use anyhow::Result;
use springfit::design::Design;
use springfit::elements::catalog::Catalog;
use springfit::error::Error;
use springfit::jobs::export::{self, ExportSprings};

use super::Session;

pub struct ExportArgs {
    pub design: PathBuf,
    pub bom: Option<PathBuf>,
    pub out: Option<PathBuf>,
}

pub fn run(args: ExportArgs, session: &Session) -> Result<()> {
    let progress = &session.progress;
    let design = Design::load(&args.design)?;
    let target = args.out.clone().unwrap_or_else(|| PathBuf::from("out").join(format!("{}_mujoco", design.name)));
    // Refuse a folder springfit may not write into before fitting anything.
    let xml_name = format!("{}.xml", design.name);
    let plan = session.plan_for(&design, "export", export::files(&design));
    let claim = springfit::report::output::check(&target, &plan)?;
    let catalog: Catalog;
    let springs = match &args.bom {
        Some(path) => ExportSprings::Bom(path),
        None => {
            let catalog_path = design.catalog.clone().ok_or_else(|| {
                Error::invalid(&design.path, "catalog", "the design names no spring catalogue; give --bom")
            })?;
            catalog = Catalog::load_for(&catalog_path, &design.chain.joint_names())?;
            ExportSprings::Fit(&catalog)
        }
    };
    let run = progress.run(|p| export::export(&design, springs, p))?;
    if let Some(outcome) = &run.fit {
        progress.say(format!("fitted {} springs (p99 residual {:.4}°)", outcome.used(), outcome.metrics.stats.p99_abs));
    }
    let (model, written) = run.write(&design, claim)?;
    progress.say(format!(
        "{}: {} springs for MuJoCo, {} exact, {} by passive-force callback; RK4 at {} s",
        design.name,
        model.elements.len(),
        model.exact_count(),
        model.callback_count(),
        model.timestep
    ));
    progress.say(format!("wrote {} ({xml_name}, elements.md, bom.csv)", written.display()));
    Ok(())
}
