//! `springfit sweep`: parasitic springs, manufacturing tolerance and stock rates.

use std::path::{Path, PathBuf};

use anyhow::Result;
use serde::{Deserialize, Serialize};
use springfit::design::Design;
use springfit::dynamics::scenario::label_source;
use springfit::error::Error;
use springfit::fit::FitOutcome;
use springfit::fit::run::fit;
use springfit::studies::sweep::{ItemResult, SweepContext, parse_shard, plan, shard_indices, tables};

use super::Session;
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

pub fn run(args: SweepArgs, session: &Session) -> Result<()> {
    let progress = &session.progress;
    let (design, validated) = super::load_design(&args.design, progress)?;
    let mut settings = design.file.sweep.clone();
    if let Some(b) = args.builds {
        if b == 0 {
            return Err(Error::Setting {
                field: "--builds".into(),
                reason: "must be at least 1 (Monte Carlo builds per tolerance level)".into(),
            }
            .into());
        }
        settings.builds = b;
    }
    if let Some(s) = args.seed {
        settings.seed = s;
    }
    let catalog = validated
        .catalog
        .as_ref()
        .ok_or_else(|| Error::invalid(&design.path, "catalog", "the design names no spring catalogue to sweep"))?;
    let catalog_path = catalog.path.clone();
    if design.file.scenario.is_empty() {
        return Err(Error::invalid(
            &design.path,
            "scenario",
            "the design declares no [[scenario]]: a sweep reruns the [sweep] scenario for every item",
        )
        .into());
    }
    springfit::design::validate::sweep_scenario(&design)?;
    // Say which tolerances the builds use: the design's levels replace the catalogue's own.
    let stated: Vec<String> = catalog
        .families
        .iter()
        .filter(|f| f.tolerance > 0.0)
        .map(|f| format!("{} ±{} %", f.name, 100.0 * f.tolerance))
        .collect();
    if !settings.tolerances.is_empty() && !stated.is_empty() {
        progress.say(format!(
            "note: [sweep] tolerances = [{}] replace the catalogue's per-family tolerances ({}); set tolerances = [] to build each spring with its own",
            settings.tolerances.iter().map(|t| format!("±{} %", 100.0 * t)).collect::<Vec<_>>().join(", "),
            stated.join(", ")
        ));
    } else if settings.tolerances.is_empty() && stated.is_empty() {
        progress.say("note: the catalogue states no tolerance and [sweep] tolerances is empty: the builds deviate by ±0 %; set tolerances = [0.05, 0.1] to sweep levels");
    }
    let design_text = std::fs::read_to_string(&design.path).map_err(|e| Error::io(&design.path, e))?;
    let catalog_text = std::fs::read_to_string(&catalog_path).map_err(|e| Error::io(&catalog_path, e))?;
    let print =
        format!("{} {} {}", serde_json::to_string(&settings)?, builds_note(&settings), env!("CARGO_PKG_VERSION"));
    let fp = fingerprint(&[&design_text, &catalog_text, &print]);
    let shard = args.shard.as_deref().map(parse_shard).transpose()?;
    let target = args.out.clone().unwrap_or_else(|| {
        let name = match shard {
            Some((i, n)) => format!("{}_sweep_shard_{i}_of_{n}", design.name),
            None => format!("{}_sweep", design.name),
        };
        PathBuf::from("out").join(name)
    });
    let files = if shard.is_some() { springfit::report::sweep::SHARD_FILES } else { springfit::report::sweep::FILES };
    let outputs = session.plan_for(&design, "sweep", files.iter().copied());
    let claim = springfit::report::output::check(&target, &outputs)?;

    // The mode label does not depend on the springs: it is prepared alongside the fit (whose
    // selection leaves a core idle at times), unless shards are merged and no item runs.
    let merging = !args.merge.is_empty();
    let step =
        progress.step(if merging { "fitting the springs" } else { "fitting the springs, preparing the mode label" });
    let (outcome, label) = if merging {
        (fit(&design, catalog, &design.fit, &|_| {}), None)
    } else {
        let (outcome, label) =
            rayon::join(|| fit(&design, catalog, &design.fit, &|_| {}), || label_source(&design, &design.simulate));
        (outcome, Some(label))
    };
    step.finish();
    let outcome = outcome.map_err(|e| super::fit_failed(&design, &design.fit, Some(catalog), e))?;
    let has_stock = outcome.bom.iter().any(|r| r.stock_rate.is_some());
    let items = plan(&settings, has_stock);

    if !args.merge.is_empty() {
        let mut results: Vec<ItemResult> = Vec::new();
        let mut source: std::collections::HashMap<usize, &PathBuf> = std::collections::HashMap::new();
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
            for r in shard.results {
                if let Some(first) = source.insert(r.index, dir) {
                    return Err(Error::Setting {
                        field: "--merge".into(),
                        reason: format!(
                            "{} and {} both computed item {} (the same shard given twice?): merge each shard once",
                            first.display(),
                            dir.display(),
                            r.index
                        ),
                    }
                    .into());
                }
                results.push(r);
            }
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
        return finish(&design, &outcome, &settings, &results, claim, progress);
    }

    let (label, _) = label.expect("prepared unless merging")?;
    let ctx = SweepContext::new(&design, &outcome, &label, settings.clone())?;
    let indices = match shard {
        Some(s) => shard_indices(items.len(), s),
        None => (0..items.len()).collect(),
    };
    let what = if indices.len() == items.len() {
        "sweep items".to_string()
    } else {
        format!("sweep items (this shard's share of {})", items.len())
    };
    let step = progress.counted(&what, indices.len() as u64);
    let results = ctx.run_observed(&items, &indices, &|| step.inc());
    let secs = step.finish();
    let results = results?;
    progress.say(format!("{} items in {secs:.1} s", results.len()));
    if let Some((i, n)) = shard {
        let dir = claim.open()?;
        let file =
            ShardFile { design: design.name.clone(), fingerprint: fp, shard: (i, n), items: items.len(), results };
        dir.write("sweep_shard.json", serde_json::to_string(&file)?)?;
        let written = dir.commit()?;
        progress.say(format!(
            "wrote shard {i}/{n} to {}; join the shards with `springfit sweep {}{} --merge DIR...`",
            written.display(),
            design.path.display(),
            // The shards' fingerprint includes these: the merge must repeat them.
            args.builds.map(|b| format!(" --builds {b}")).unwrap_or_default()
                + &args.seed.map(|s| format!(" --seed {s}")).unwrap_or_default()
        ));
        return Ok(());
    }
    finish(&design, &outcome, &settings, &results, claim, progress)
}

fn builds_note(s: &springfit::design::sweep::SweepSettings) -> String {
    format!("{}:{}", s.builds, s.seed)
}

fn finish(
    design: &Design,
    outcome: &FitOutcome,
    settings: &springfit::design::sweep::SweepSettings,
    results: &[ItemResult],
    claim: springfit::report::output::Claim,
    progress: &Progress,
) -> Result<()> {
    let t = tables(settings, results);
    let written = springfit::report::sweep::write_folder(claim, design, &t, results, &outcome.bom)?;
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
            "tolerance {}: {} builds, as built (untuned); actuator share p50 {:.3} %, p95 {:.3} %; residual p99 p50 {}, p95 {}; equilibrium shift p50 {}",
            l.tolerance.map(|t| format!("±{} %", 100.0 * t)).unwrap_or_else(|| "of the catalogue".into()),
            l.builds,
            100.0 * l.actuator_share_p50,
            100.0 * l.actuator_share_p95,
            or_none(l.residual_p99_deg_p50, "°", 3),
            or_none(l.residual_p99_deg_p95, "°", 3),
            or_none(l.equilibrium_shift_rad_p50, " rad", 4)
        ));
        if let (Some(a), Some(b)) = (l.trimmed_residual_p99_deg_p50, l.trimmed_residual_p99_deg_p95) {
            progress.say(format!("  trimmed: residual p99 p50 {a:.3}°, p95 {b:.3}°"));
        }
        if let Some(u) = &l.tuned {
            progress.say(format!(
                "  tuned after the build (offsets and trims set from the measured rates, as `springfit tune`; the first {} of the {} builds): actuator share p50 {:.3} %, p95 {:.3} %; residual p99 p50 {}, p95 {}; equilibrium shift p50 {}",
                u.builds,
                l.builds,
                100.0 * u.actuator_share.p50,
                100.0 * u.actuator_share.p95,
                or_none(u.residual_p99_deg.p50, "°", 3),
                or_none(u.residual_p99_deg.p95, "°", 3),
                or_none(u.equilibrium_shift_rad.p50, " rad", 4)
            ));
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
    if t.stock.is_none() {
        progress.say("stock rates: the catalogue lists none for the fitted springs, so the stock step is skipped and no bom_stock.csv is written");
    }
    progress.say(format!("wrote {}", show(&written)));
    Ok(())
}

fn show(p: &Path) -> String {
    p.display().to_string()
}

/// A percentile over builds, or why there is none: a build whose springs hold no equilibrium
/// near the design's has no residual and no shift (NaN in the tables, null in sweep.json).
fn or_none(x: f64, unit: &str, digits: usize) -> String {
    if x.is_finite() {
        format!("{x:.digits$}{unit}")
    } else {
        "none (some builds have no equilibrium near q_eq)".into()
    }
}
