//! `springfit export`: the design and its springs for another simulator (MuJoCo's MJCF).

use std::path::PathBuf;

use anyhow::Result;
use springfit::design::Design;
use springfit::elements::catalog::Catalog;
use springfit::error::Error;
use springfit::export::mujoco;
use springfit::files::bom;
use springfit::fit::run::fit;

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
    let plan = session.plan_for(&design, "export", mujoco::files(&design));
    let claim = springfit::report::output::check(&target, &plan)?;
    let (rows, from) = match &args.bom {
        Some(path) => {
            let rows = bom::read(path)?;
            if let Some(r) = rows.iter().find(|r| r.element.coupling.len() != design.dof()) {
                return Err(Error::invalid(
                    path,
                    "coupling",
                    format!(
                        "{}: the springs act on {} joints but the design has {}",
                        r.id,
                        r.element.coupling.len(),
                        design.dof()
                    ),
                )
                .into());
            }
            (rows, format!("the bill of materials {}", path.display()))
        }
        None => {
            let catalog_path = design.catalog.clone().ok_or_else(|| {
                Error::invalid(&design.path, "catalog", "the design names no spring catalogue; give --bom")
            })?;
            let catalog = Catalog::load_for(&catalog_path, &design.chain.joint_names())?;
            let step = progress.step("fitting the springs");
            let outcome = fit(&design, &catalog, &design.fit, &|_| {});
            step.finish();
            let outcome = outcome?;
            progress.say(format!(
                "fitted {} springs (p99 residual {:.4}°)",
                outcome.used(),
                outcome.metrics.stats.p99_abs
            ));
            (outcome.bom, format!("a fit of {} with catalogue {}", design.path.display(), outcome.catalog))
        }
    };
    let (model, written) = mujoco::write_folder(claim, &design, &rows, &from)?;
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
