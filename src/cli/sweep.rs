//! `springfit sweep`: parasitic springs, manufacturing tolerance and stock rates.

use std::path::{Path, PathBuf};

use anyhow::Result;
use serde::{Deserialize, Serialize};
use springfit::catalog::Catalog;
use springfit::design::Design;
use springfit::error::Error;
use springfit::fit::run::{FitOutcome, fit};
use springfit::report::output::OutputDir;
use springfit::scenario::label_source;
use springfit::simulate::ElasticPotential;
use springfit::sweep::{ItemResult, SweepContext, kappa, parse_shard, plan, shard_indices, tables};

use super::progress::Progress;

pub struct SweepArgs {
    pub design: PathBuf,
    pub out: Option<PathBuf>,
    pub shard: Option<String>,
    pub merge: Vec<PathBuf>,
    pub builds: Option<usize>,
    pub seed: Option<u64>,
}

/// A shard's results (`sweep_shard.json`).
#[derive(Serialize, Deserialize)]
struct ShardFile {
    design: String,
    /// Identifies the inputs: shards of different inputs must not be merged.
    fingerprint: String,
    shard: (usize, usize),
    items: usize,
    results: Vec<ItemResult>,
}

/// FNV-1a over everything that determines the results.
fn fingerprint(parts: &[&str]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for p in parts {
        for b in p.bytes().chain([0xff]) {
            h ^= b as u64;
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    format!("{h:016x}")
}

pub fn run(args: SweepArgs, progress: &Progress) -> Result<()> {
    let design = Design::load(&args.design)?;
    let mut settings = design.file.sweep.clone();
    if let Some(b) = args.builds {
        settings.builds = b;
    }
    if let Some(s) = args.seed {
        settings.seed = s;
    }
    let catalog_path = design
        .catalog
        .clone()
        .ok_or_else(|| Error::invalid(&design.path, "catalog", "the design names no spring catalogue to sweep"))?;
    let catalog = Catalog::load(&catalog_path, design.dof())?;
    let design_text = std::fs::read_to_string(&design.path).map_err(|e| Error::io(&design.path, e))?;
    let catalog_text = std::fs::read_to_string(&catalog_path).map_err(|e| Error::io(&catalog_path, e))?;
    let print =
        format!("{} {} {}", serde_json::to_string(&settings)?, builds_note(&settings), env!("CARGO_PKG_VERSION"));
    let fp = fingerprint(&[&design_text, &catalog_text, &print]);

    let step = progress.step("fitting the springs");
    let outcome = fit(&design, &catalog, &design.fit, &|_| {});
    step.finish();
    let outcome = outcome?;
    let has_stock = outcome.bom.iter().any(|r| r.stock_rate.is_some());
    let items = plan(&settings, has_stock);

    if !args.merge.is_empty() {
        let mut results: Vec<ItemResult> = Vec::new();
        for dir in &args.merge {
            let path = dir.join("sweep_shard.json");
            let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
            let shard: ShardFile = serde_json::from_str(&text).map_err(|e| Error::Parse {
                path: path.clone(),
                line: e.line(),
                column: e.column(),
                message: e.to_string(),
            })?;
            if shard.fingerprint != fp || shard.items != items.len() {
                return Err(Error::invalid(
                    &path,
                    "fingerprint",
                    format!(
                        "this shard was computed from other inputs (design, catalogue or sweep settings) than {}",
                        design.path.display()
                    ),
                )
                .into());
            }
            results.extend(shard.results);
        }
        results.sort_by_key(|r| r.index);
        let before = results.len();
        results.dedup_by_key(|r| r.index);
        if results.len() != before {
            return Err(Error::Setting {
                field: "--merge".into(),
                reason: "two shards computed the same items".into(),
            }
            .into());
        }
        let missing: Vec<usize> =
            (0..items.len()).filter(|i| results.binary_search_by_key(i, |r| r.index).is_err()).collect();
        if !missing.is_empty() {
            return Err(Error::Setting {
                field: "--merge".into(),
                reason: format!(
                    "{} of {} items are missing (first: item {}); merge every shard",
                    missing.len(),
                    items.len(),
                    missing[0]
                ),
            }
            .into());
        }
        return finish(&design, &outcome, &settings, &results, args.out, progress);
    }

    let step = progress.step("preparing the mode label");
    let label = label_source(&design, &design.simulate);
    step.finish();
    let (label, _) = label?;
    let index = design.file.scenario.iter().position(|s| s.name == settings.scenario).ok_or_else(|| {
        Error::invalid(
            &design.path,
            "sweep.scenario",
            format!("no [[scenario]] named `{}` in the design", settings.scenario),
        )
    })?;
    let nominal = ElasticPotential::Springs(outcome.springs.clone());
    let base = {
        let q_eq = design.q_eq.as_slice().to_vec();
        let springs = outcome.springs.clone();
        let chain = &design.chain;
        let u = |q: &[f64]| {
            springs.elements.iter().zip(&springs.stiffness).map(|(e, k)| k * e.value(q)).sum::<f64>()
                + chain.gravity_potential(q)
        };
        let u0 = u(&q_eq);
        let mut energy_at = |q: &[f64]| -> springfit::Result<f64> { Ok(u(q) - u0) };
        design.file.scenario[index].resolve(index, &design, &mut energy_at)?.runs.remove(0)
    };
    let ctx = SweepContext {
        design: &design,
        fit: &outcome,
        label: &label,
        sim: design.simulate,
        controllers: design.controllers,
        settings: settings.clone(),
        kappa: kappa(&design, &outcome.springs, &outcome),
        base,
        nominal,
    };
    let shard = args.shard.as_deref().map(parse_shard).transpose()?;
    let indices = match shard {
        Some(s) => shard_indices(items.len(), s),
        None => (0..items.len()).collect(),
    };
    let step = progress.step(&format!("running {} of {} items", indices.len(), items.len()));
    let results = ctx.run(&items, &indices);
    let secs = step.finish();
    let results = results?;
    progress.say(format!("{} items in {secs:.1} s", results.len()));
    if let Some((i, n)) = shard {
        let target =
            args.out.unwrap_or_else(|| PathBuf::from("out").join(format!("{}_sweep_shard_{i}_of_{n}", design.name)));
        let dir = OutputDir::create(&target)?;
        let file =
            ShardFile { design: design.name.clone(), fingerprint: fp, shard: (i, n), items: items.len(), results };
        dir.write("sweep_shard.json", serde_json::to_string(&file)?)?;
        let written = dir.commit()?;
        progress.say(format!(
            "wrote shard {i}/{n} to {}; join the shards with `springfit sweep {} --merge DIR...`",
            written.display(),
            design.path.display()
        ));
        return Ok(());
    }
    finish(&design, &outcome, &settings, &results, args.out, progress)
}

fn builds_note(s: &springfit::sweep::SweepSettings) -> String {
    format!("{}:{}", s.builds, s.seed)
}

fn finish(
    design: &Design,
    outcome: &FitOutcome,
    settings: &springfit::sweep::SweepSettings,
    results: &[ItemResult],
    out: Option<PathBuf>,
    progress: &Progress,
) -> Result<()> {
    let t = tables(settings, results);
    let target = out.unwrap_or_else(|| PathBuf::from("out").join(format!("{}_sweep", design.name)));
    let dir = OutputDir::create(&target)?;
    springfit::report::sweep::write(&dir, &design.name, &t, results, &outcome.bom)?;
    let written = dir.commit()?;
    progress.say("parasitic springs (ε: ∫|P_Ũ|, ∫|P_θ|, ∫|P_E| in J; actuator share):");
    for r in &t.parasitic {
        progress.say(format!(
            "  {:>5}: {:8.2} {:7.2} {:7.2}  {:.3} %",
            r.eps,
            r.flux_potential,
            r.flux_mode,
            r.flux_energy,
            100.0 * r.actuator_share
        ));
    }
    for l in &t.tolerance_levels {
        progress.say(format!(
            "tolerance {}: {} builds; actuator share p50 {:.3} %, p95 {:.3} %; residual p99 p50 {:.3}°, p95 {:.3}°; equilibrium shift p50 {:.4} rad",
            l.tolerance.map(|t| format!("±{} %", 100.0 * t)).unwrap_or_else(|| "of the catalogue".into()),
            l.builds,
            100.0 * l.actuator_share_p50,
            100.0 * l.actuator_share_p95,
            l.residual_p99_deg_p50,
            l.residual_p99_deg_p95,
            l.equilibrium_shift_rad_p50
        ));
        if let (Some(a), Some(b)) = (l.trimmed_residual_p99_deg_p50, l.trimmed_residual_p99_deg_p95) {
            progress.say(format!("  trimmed: residual p99 p50 {a:.3}°, p95 {b:.3}°"));
        }
    }
    if let Some(s) = &t.stock {
        progress.say(format!(
            "stock rates: residual p99 {:.3}° → {:.3}°, actuator share {:.3} % → {:.3} %",
            s.residual_p99_deg_before,
            s.residual_p99_deg_after,
            100.0 * s.actuator_share_before,
            100.0 * s.actuator_share_after
        ));
    }
    progress.say(format!("wrote {}", show(&written)));
    Ok(())
}

fn show(p: &Path) -> String {
    p.display().to_string()
}
