//! `springfit sweep` and Python's `Design.sweep()`: parasitic springs, manufacturing tolerance and
//! stock rates, in one process, as one shard of several, or merged from shards.
//!
//! The feature's files: the settings `design/sweep.rs`, the items and tables `studies/sweep.rs`
//! (which reruns `dynamics/` and `asbuilt/` per item), the files written `report/sweep.rs`, the
//! command `cli/sweep.rs`.

use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Instant;

use serde::{Deserialize, Serialize};

use crate::design::Design;
use crate::design::sweep::SweepSettings;
use crate::dynamics::scenario::label_source;
use crate::elements::catalog::Catalog;
use crate::error::{Error, Result};
use crate::fit::FitOutcome;
use crate::progress::Progress;
use crate::report::output::Claim;
use crate::studies::sweep::{ItemResult, SweepContext, SweepTables, plan, shard_indices, tables};

/// What a sweep is asked beyond the design's `[sweep]`.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SweepRequest {
    /// Replaces `[sweep] builds` (Monte Carlo builds per tolerance level, at least 1).
    pub builds: Option<usize>,
    /// Replaces `[sweep] seed`.
    pub seed: Option<u64>,
    /// Join the shards written into these folders instead of running items.
    pub merge: Vec<PathBuf>,
}

/// A shard's results (`sweep_shard.json`).
#[derive(Debug, Clone, Serialize, Deserialize)]
struct ShardFile {
    design: String,
    /// Identifies the inputs: shards of different inputs must not be merged.
    fingerprint: String,
    shard: (usize, usize),
    items: usize,
    results: Vec<ItemResult>,
}

/// A sweep checked and ready to run.
#[derive(Debug)]
pub struct SweepJob<'a> {
    design: &'a Design,
    catalog: &'a Catalog,
    settings: SweepSettings,
    request: SweepRequest,
    shard: Option<(usize, usize)>,
}

impl<'a> SweepJob<'a> {
    /// Checks `request` against `design` and its validated `catalog`: the replaced settings, a
    /// catalogue, and the `[sweep]` scenario every item reruns.
    pub fn new(design: &'a Design, catalog: Option<&'a Catalog>, request: SweepRequest) -> Result<SweepJob<'a>> {
        let mut settings = design.sweep.clone();
        if let Some(b) = request.builds {
            if b == 0 {
                return Err(Error::Setting {
                    field: "builds".into(),
                    reason: "must be at least 1 (Monte Carlo builds per tolerance level)".into(),
                });
            }
            settings.builds = b;
        }
        if let Some(s) = request.seed {
            settings.seed = s;
        }
        let catalog = catalog
            .ok_or_else(|| Error::invalid(&design.path, "catalog", "the design names no spring catalogue to sweep"))?;
        if design.scenarios.is_empty() {
            return Err(Error::invalid(
                &design.path,
                "scenario",
                "the design declares no [[scenario]]: a sweep reruns the [sweep] scenario for every item",
            ));
        }
        crate::design::validate::sweep_scenario(design)?;
        Ok(SweepJob { design, catalog, settings, request, shard: None })
    }

    /// The job that computes only shard i of N of the items (1-based; None: every item), for
    /// a later merge.
    pub fn with_shard(self, shard: Option<(usize, usize)>) -> SweepJob<'a> {
        SweepJob { shard, ..self }
    }

    /// The sweep's settings with the request's replacements.
    pub fn settings(&self) -> &SweepSettings {
        &self.settings
    }

    /// The names the sweep's output folder may hold: a shard's file, or the tables.
    pub fn files(&self) -> &'static [&'static str] {
        if self.shard.is_some() { crate::report::sweep::SHARD_FILES } else { crate::report::sweep::FILES }
    }

    /// Which tolerances the builds use, when that may surprise: the design's levels replace the
    /// catalogue's own, or neither states one.
    pub fn tolerance_note(&self) -> Option<String> {
        let stated: Vec<String> = self
            .catalog
            .families
            .iter()
            .filter(|f| f.tolerance > 0.0)
            .map(|f| format!("{} ±{} %", f.name, 100.0 * f.tolerance))
            .collect();
        let levels = &self.settings.tolerances;
        if !levels.is_empty() && !stated.is_empty() {
            Some(format!(
                "note: [sweep] tolerances = [{}] replace the catalogue's per-family tolerances ({}); set tolerances = [] to build each spring with its own",
                levels.iter().map(|t| format!("±{} %", 100.0 * t)).collect::<Vec<_>>().join(", "),
                stated.join(", ")
            ))
        } else if levels.is_empty() && stated.is_empty() {
            Some("note: the catalogue states no tolerance and [sweep] tolerances is empty: the builds deviate by ±0 %; set tolerances = [0.05, 0.1] to sweep levels".into())
        } else {
            None
        }
    }

    /// Fits the springs and, unless shards are merged, prepares the mode label alongside (the
    /// label does not depend on the springs, and the fit's selection leaves a core idle at
    /// times); then runs the items (all, or the request's shard) or merges the shards.
    pub fn run(self, progress: Progress<'_>) -> Result<SweepRun> {
        let (design, catalog) = (self.design, self.catalog);
        let fit = || {
            super::fit::springs_of(design, catalog, &design.fit, Progress::none())
                .map_err(|e| crate::fit::hints::explain(design, &design.fit, catalog, design.fit.max_elements, e))
        };
        let sharded = self.shard.is_some() || !self.request.merge.is_empty();
        let fingerprint = if sharded { self.fingerprint()? } else { String::new() };
        if !self.request.merge.is_empty() {
            // A shard missing is found before the fit, not after its seconds of work.
            if let Some(dir) = self.request.merge.iter().find(|d| !d.join("sweep_shard.json").is_file()) {
                return Err(Error::Setting {
                    field: "--merge".into(),
                    reason: format!(
                        "{} holds no sweep_shard.json: give the output folders of `springfit sweep --shard i/N`",
                        dir.display()
                    ),
                });
            }
            progress.stage("fitting the springs");
            let fit = fit()?;
            let items = plan(&self.settings, fit.bom.iter().any(|r| r.stock_rate.is_some())).len();
            let results = self.merge(&fingerprint, items)?;
            let made = Made::Tables(Box::new(tables(&self.settings, &results)));
            return Ok(SweepRun { fit, settings: self.settings, items, results, seconds: None, made });
        }
        progress.stage("fitting the springs, preparing the mode label");
        let (fit, label) = rayon::join(fit, || label_source(design, &design.simulate));
        let fit = fit?;
        let (label, _) = label?;
        let items = plan(&self.settings, fit.bom.iter().any(|r| r.stock_rate.is_some()));
        let ctx = SweepContext::new(design, &fit, &label, self.settings.clone())?;
        let indices = match self.shard {
            Some(s) => shard_indices(items.len(), s),
            None => (0..items.len()).collect(),
        };
        let what = if indices.len() == items.len() {
            "sweep items".to_string()
        } else {
            format!("sweep items (this shard's share of {})", items.len())
        };
        progress.counted(&what, indices.len());
        let t = Instant::now();
        let results = ctx.run(&items, &indices, progress)?;
        let seconds = Some(t.elapsed().as_secs_f64());
        let made = match self.shard {
            Some(shard) => Made::Shard(Shard { shard, fingerprint }),
            None => Made::Tables(Box::new(tables(&self.settings, &results))),
        };
        let items = items.len();
        Ok(SweepRun { fit, settings: self.settings, items, results, seconds, made })
    }

    /// FNV-1a over everything that determines the results: the design's and the catalogue's
    /// text, the settings, the springfit version.
    fn fingerprint(&self) -> Result<String> {
        let design_text = std::fs::read_to_string(&self.design.path).map_err(|e| Error::io(&self.design.path, e))?;
        let path = &self.catalog.path;
        let catalog_text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let settings = serde_json::to_string(&self.settings)
            .map_err(|e| Error::invalid(&self.design.path, "sweep", format!("cannot be written as JSON: {e}")))?;
        let s = &self.settings;
        let print = format!("{settings} {}:{} {}", s.builds, s.seed, env!("CARGO_PKG_VERSION"));
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for p in [&design_text, &catalog_text, &print] {
            for b in p.bytes().chain([0xff]) {
                h ^= b as u64;
                h = h.wrapping_mul(0x0000_0100_0000_01b3);
            }
        }
        Ok(format!("{h:016x}"))
    }

    /// The results of the shards in the request's folders, checked to come from these inputs
    /// and to hold every one of the `items` once.
    fn merge(&self, fingerprint: &str, items: usize) -> Result<Vec<ItemResult>> {
        let mut results: Vec<ItemResult> = Vec::new();
        let mut source: HashMap<usize, &PathBuf> = HashMap::new();
        for dir in &self.request.merge {
            let path = dir.join("sweep_shard.json");
            let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
            let shard: ShardFile = serde_json::from_str(&text).map_err(|e| Error::Parse {
                path: path.clone(),
                line: e.line(),
                column: e.column(),
                message: e.to_string(),
            })?;
            if shard.fingerprint != fingerprint || shard.items != items {
                return Err(Error::invalid(
                    &path,
                    "fingerprint",
                    format!(
                        "this shard was computed from other inputs (design, catalogue or sweep settings) than {}",
                        self.design.path.display()
                    ),
                ));
            }
            for r in shard.results {
                if let Some(first) = source.insert(r.index, dir) {
                    return Err(Error::Setting {
                        field: "merge".into(),
                        reason: format!(
                            "{} and {} both computed item {} (the same shard given twice?): merge each shard once",
                            first.display(),
                            dir.display(),
                            r.index
                        ),
                    });
                }
                results.push(r);
            }
        }
        results.sort_by_key(|r| r.index);
        let before = results.len();
        results.dedup_by_key(|r| r.index);
        if results.len() != before {
            return Err(Error::Setting { field: "merge".into(), reason: "two shards computed the same items".into() });
        }
        let missing: Vec<usize> =
            (0..items).filter(|i| results.binary_search_by_key(i, |r| r.index).is_err()).collect();
        if let Some(first) = missing.first() {
            return Err(Error::Setting {
                field: "merge".into(),
                reason: format!(
                    "{} of {items} items are missing (first: item {first}); merge every shard",
                    missing.len()
                ),
            });
        }
        Ok(results)
    }
}

/// Which shard a sharded run computed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Shard {
    /// i of N (1-based).
    pub shard: (usize, usize),
    /// The inputs' fingerprint the merge checks.
    pub fingerprint: String,
}

/// What a sweep made of its results: the tables, or a shard's share for the merge.
#[derive(Debug, Clone)]
pub enum Made {
    /// The tables of every item.
    Tables(Box<SweepTables>),
    /// One shard's results (the merge makes the tables).
    Shard(Shard),
}

/// A sweep: the fit, every item's result, and what was made of them.
#[derive(Debug, Clone)]
pub struct SweepRun {
    /// The nominal fit.
    pub fit: FitOutcome,
    /// `[sweep]` as run.
    pub settings: SweepSettings,
    /// The number of items of the whole sweep.
    pub items: usize,
    /// The results computed here (a shard's share) or merged, in item order.
    pub results: Vec<ItemResult>,
    /// Seconds the items took (None when merged).
    pub seconds: Option<f64>,
    /// The tables, or the shard computed.
    pub made: Made,
}

impl SweepRun {
    /// Writes what `springfit sweep` writes into the claimed folder: a shard's
    /// `sweep_shard.json`, or the tables' files (`sweep.csv`, `sweep.json`, `tolerance.md`,
    /// plots, `bom_stock.csv` when stock rates apply, `report.html`).
    pub fn write(&self, design: &Design, claim: Claim) -> Result<PathBuf> {
        match &self.made {
            Made::Shard(s) => {
                let dir = claim.open()?;
                let file = ShardFile {
                    design: design.name.clone(),
                    fingerprint: s.fingerprint.clone(),
                    shard: s.shard,
                    items: self.items,
                    results: self.results.clone(),
                };
                let text = serde_json::to_string(&file)
                    .map_err(|e| Error::invalid(&design.path, "sweep", format!("cannot be written as JSON: {e}")))?;
                dir.write("sweep_shard.json", text)?;
                dir.commit()
            }
            Made::Tables(t) => crate::report::sweep::write_folder(claim, design, t, &self.results, &self.fit.bom),
        }
    }
}
