//! Sensitivity and manufacturability: parasitic springs, manufacturing tolerance, stock rates.
//!
//! A sweep is a list of independent *work items*, each a closed-loop run of the design's
//! sensitivity scenario (and, for builds, an evaluation of the residual angles) with the springs
//! perturbed one way:
//!
//! * **parasitic** (the paper's Table II): Ũ = U + ½ε(q − q_eq)ᵀdiag(κ)(q − q_eq) with
//!   κᵢ = max|∂U_e/∂qᵢ| / max|qᵢ − q_eq,ᵢ| over the region, for each ε;
//! * **tolerance**: a Monte Carlo build with each stiffness scaled by 1 + δ, δ uniform in
//!   ±tolerance or normal with σ = tolerance/3 truncated at ±tolerance (the catalogue's tolerance
//!   per element, or a level given in the sweep settings for all elements); a cam's basis rows
//!   share one δ (its follower spring);
//! * **stock**: each stiffness snapped to the nearest stock rate, largest torque first, the others
//!   refitted after each snap.
//!
//! In designs with trim springs or adjustable elements the first `tuned_builds` builds of each
//! level are also tuned as `springfit tune` would and run again: the tune and the second run cost
//! about twice the build, and the default 72 are the fewest builds whose tuned p95 has a bounded
//! 95 % interval.
//!
//! The controllers always use the nominal potential (the one the designer computed), as the
//! paper's sensitivity analysis does. Items are numbered; a build draws from its own random
//! stream, so any subset of items (a shard) gives the same numbers as in a full run, and merged
//! shards give the same tables bit for bit.

use crate::design::sweep::SweepSettings;
use serde::{Deserialize, Serialize};

use crate::design::Design;
use crate::design::controllers::ControllerSettings;
use crate::design::scenario::ScenarioKind;
use crate::design::simulate::SimSettings;
use crate::dynamics::scenario::{LabelSource, Savings, metrics};
use crate::dynamics::simulate::{Dynamics, ElasticPotential, Parasitic, RunSpec, SOURCES, run};
use crate::error::{Error, Result};
use crate::fit::FitOutcome;
use crate::fit::bill::nearest;
use crate::fit::refit::refit_with_fixed;
use crate::numerics::rng::SplitMix64;
use crate::potential::{Potential, SpringSet};
use crate::progress::Progress;
use crate::residual::{percentile, percentile_interval};

pub use crate::design::tolerance::Distribution;

/// One unit of work.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum WorkItem {
    /// Parasitic springs at scale `eps`.
    Parasitic {
        /// ε, the parasitic stiffness as a fraction of κ (dimensionless; `sweep.csv`'s `eps`).
        eps: f64,
    },
    /// Build `build` at tolerance level `level` (None: the catalogue's tolerances).
    Build {
        /// The ± tolerance as a fraction (0.05 = ±5 %), None for each element's catalogue
        /// tolerance (`sweep.csv`'s `tolerance`, `catalogue`).
        level: Option<f64>,
        /// The build's number within its level, 0-based: the first `tuned_builds` are also tuned,
        /// and with the seed and the item's index it picks the build's random stream (a shard
        /// draws the same build as a full run).
        build: usize,
    },
    /// Stock-rate snapping.
    Stock,
}

/// A time series kept for the parasitic runs' plots.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Series {
    /// Times.
    pub t: Vec<f64>,
    /// q₁, q₂ per sample (flat).
    pub q: Vec<f64>,
    /// Power per source per sample (flat, [`SOURCES`] order).
    pub power: Vec<f64>,
}

/// The result of one item.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ItemResult {
    /// Position in the plan.
    pub index: usize,
    /// What was run.
    pub item: WorkItem,
    /// ∫|P_Ũ|, J.
    pub flux_potential: f64,
    /// ∫|P_θ|, J.
    pub flux_mode: f64,
    /// ∫|P_E|, J.
    pub flux_energy: f64,
    /// (∫|P_θ| + ∫|P_E|)/∫|P_Ũ|.
    pub actuator_share: f64,
    /// p99 |residual angle| on the held-out geodesics, degrees (builds and stock: after).
    pub residual_p99_deg: f64,
    /// The same for the nominal springs (stock: before snapping).
    pub residual_p99_deg_before: Option<f64>,
    /// Actuator share with the nominal springs (stock: before snapping).
    pub actuator_share_before: Option<f64>,
    /// How far the built springs move the equilibrium, |q_eq′ − q_eq| in rad (builds, stock).
    pub equilibrium_shift_rad: Option<f64>,
    /// Builds of designs with trim springs: p99 |residual angle| after the trim a builder would
    /// make (see [`crate::asbuilt::trim_build`]), degrees.
    #[serde(default)]
    pub residual_p99_deg_trimmed: Option<f64>,
    /// Builds of designs with trim springs or adjustable elements: the build tuned as
    /// `springfit tune` would tune it with the build's rates measured exactly (adjustable offsets
    /// put the equilibrium back at q_eq, trims restore ∇²U = w² M): its actuator share from the
    /// same closed-loop run (controllers still nominal), its p99 residual (degrees) and its
    /// equilibrium shift (rad) about its own equilibrium. NaN when the tuning fails; None past
    /// the first `tuned_builds` builds of the level.
    #[serde(default)]
    pub tuned: Option<TunedBuild>,
    /// What the springs save on the item's closed-loop run against the arm without them (the
    /// same motion driven by the actuators alone; see [`Savings`]); with the nominal springs
    /// for stock snapping's `before`, see `savings_before`.
    #[serde(default)]
    pub savings: Option<Savings>,
    /// Stock only: the savings with the fitted springs before snapping.
    #[serde(default)]
    pub savings_before: Option<Savings>,
    /// Stiffnesses after snapping (stock only), in BOM order.
    pub stock_stiffness: Option<Vec<f64>>,
    /// Time series (parasitic only).
    pub series: Option<Series>,
}

/// A build after the builder's tuning (see [`ItemResult::tuned`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TunedBuild {
    /// (∫|P_θ| + ∫|P_E|)/∫|P_Ũ| of the tuned build.
    pub actuator_share: f64,
    /// p99 |residual angle| about the tuned build's own equilibrium, degrees.
    pub residual_p99_deg: f64,
    /// |q′ − q_eq|₂ of the tuned build, rad.
    pub equilibrium_shift_rad: f64,
}

/// Everything the items need, built once per process.
pub struct SweepContext<'a> {
    /// The design.
    pub design: &'a Design,
    /// The nominal fit.
    pub fit: &'a FitOutcome,
    /// Label for the mode controller.
    pub label: &'a LabelSource<'a>,
    /// Simulation settings.
    pub sim: SimSettings,
    /// Controller gains.
    pub controllers: ControllerSettings,
    /// Sweep settings.
    pub settings: SweepSettings,
    /// The run every item perturbs.
    pub base: RunSpec,
    /// κ per joint.
    pub kappa: Vec<f64>,
    /// The nominal potential.
    pub nominal: ElasticPotential,
}

/// The items of a sweep, in a fixed order: parasitic, then builds per level, then stock.
pub fn plan(settings: &SweepSettings, has_stock: bool) -> Vec<WorkItem> {
    let mut items: Vec<WorkItem> = settings.epsilons.iter().map(|&eps| WorkItem::Parasitic { eps }).collect();
    let levels: Vec<Option<f64>> = if settings.tolerances.is_empty() {
        vec![None]
    } else {
        settings.tolerances.iter().map(|t| Some(*t)).collect()
    };
    for level in levels {
        items.extend((0..settings.builds).map(|build| WorkItem::Build { level, build }));
    }
    if has_stock {
        items.push(WorkItem::Stock);
    }
    items
}

/// κᵢ = max|∂U_e/∂qᵢ| / max|qᵢ − q_eq,ᵢ| over the samples of the fit's evaluation fan.
pub fn kappa(design: &Design, springs: &SpringSet, fit: &FitOutcome) -> Vec<f64> {
    let n = design.dof();
    let (mut tau, mut dq) = (vec![0.0f64; n], vec![0.0f64; n]);
    let mut g = vec![0.0; n];
    let springs = springs.grouped();
    for geo in &fit.evaluation.geodesics {
        for k in 0..geo.len() {
            let q = geo.q(k);
            springs.gradient_into(q, &mut g);
            for i in 0..n {
                tau[i] = tau[i].max(g[i].abs());
                dq[i] = dq[i].max((q[i] - design.q_eq[i]).abs());
            }
        }
    }
    (0..n).map(|i| if dq[i] > 0.0 { tau[i] / dq[i] } else { 0.0 }).collect()
}

impl<'a> SweepContext<'a> {
    /// The context `springfit sweep` runs its items in: the fit's springs as the nominal
    /// potential, κ from its evaluation fan, the design's `[simulate]` and `[controllers]`, and as
    /// the base run the first run of the `[sweep]` scenario, started by the springs' energy.
    pub fn new(
        design: &'a Design,
        fit: &'a FitOutcome,
        label: &'a LabelSource<'a>,
        settings: SweepSettings,
    ) -> Result<SweepContext<'a>> {
        let index = crate::design::validate::sweep_scenario(design)?;
        let nominal = ElasticPotential::Springs(fit.springs.clone());
        let base = crate::dynamics::scenario::resolve_scenario(design, &nominal, label, index)?.runs.remove(0);
        Ok(SweepContext {
            design,
            fit,
            label,
            sim: SimSettings { rate: settings.rate.unwrap_or(design.simulate.rate / 2.0), ..design.simulate },
            controllers: design.controllers.clone(),
            settings,
            kappa: kappa(design, &fit.springs, fit),
            base,
            nominal,
        })
    }

    /// Runs the items `indices` of `items` in parallel; results in index order. `progress` hears
    /// of each item done (a count whose order depends on the threads; the results do not).
    pub fn run(&self, items: &[WorkItem], indices: &[usize], progress: Progress<'_>) -> Result<Vec<ItemResult>> {
        use rayon::prelude::*;
        let results: Vec<Result<ItemResult>> = indices
            .par_iter()
            .map(|&i| {
                let r = self.run_item(i, items[i]);
                progress.item_done();
                r
            })
            .collect();
        results.into_iter().collect()
    }

    fn springs(&self) -> &SpringSet {
        match &self.nominal {
            ElasticPotential::Springs(s) => s,
            ElasticPotential::Exact { .. } => unreachable!("sweeps perturb spring sets"),
        }
    }

    fn closed_loop(
        &self,
        potential: &ElasticPotential,
        spec: &RunSpec,
    ) -> Result<(crate::dynamics::simulate::RunResult, crate::dynamics::scenario::RunMetrics)> {
        let mut dynamics = Dynamics::new(
            &self.design.chain,
            &self.design.q_eq,
            potential,
            self.controllers.clone(),
            spec,
            Some(self.label.field()),
        )?;
        let result = run(&mut dynamics, &self.sim)?;
        let m = metrics(&result, spec, &self.controllers, ScenarioKind::Swingup);
        Ok((result, m))
    }

    /// The p99 residual angle of a built spring set about its own equilibrium and the shift
    /// (see [`crate::asbuilt::residual_about_own_equilibrium`]).
    fn residual_about_own_equilibrium(&self, built: &SpringSet) -> Result<(f64, f64)> {
        crate::asbuilt::residual_about_own_equilibrium(
            self.design,
            self.fit.region.extent,
            self.settings.evaluation_directions,
            self.settings.evaluation_samples,
            built,
        )
    }

    /// The p99 residual angle of a build after the trim a builder would make (designs with trim
    /// springs; NaN if the trimmed build has no stable equilibrium).
    fn trimmed_p99(&self, built: &SpringSet) -> Result<Option<f64>> {
        let bom = &self.fit.bom;
        if !bom.iter().any(|r| r.adjust.trim_range.is_some()) {
            return Ok(None);
        }
        let Some((trimmed, q, _)) = crate::asbuilt::trim_build(self.design, bom, built) else {
            return Ok(Some(f64::NAN));
        };
        let h = trimmed.hessian(q.as_slice())? + self.design.chain.gravity_hessian(q.as_slice());
        if h.cholesky().is_none() {
            return Ok(Some(f64::NAN));
        }
        let (p99, _) = crate::asbuilt::residual_about(
            self.design,
            self.fit.region.extent,
            self.settings.evaluation_directions,
            self.settings.evaluation_samples,
            &trimmed,
            &q,
        )?;
        Ok(Some(p99))
    }

    /// The build tuned after assembly, as `springfit tune` tunes it from exactly measured rates
    /// (designs with trim springs or adjustable elements only, the first `tuned_builds` builds of
    /// each level): the closed-loop run of `spec`
    /// with the tuned springs as the plant, the controllers unchanged. A build the tuning cannot
    /// handle (no equilibrium near q_eq, a failed solve) counts as NaN, the worst.
    fn tuned(&self, build: usize, built: &SpringSet, spec: &RunSpec) -> Result<Option<TunedBuild>> {
        let bom = &self.fit.bom;
        if !self.settings.tune_builds
            || build >= self.settings.tuned_builds
            || !bom.iter().any(|r| r.adjust.trim_range.is_some() || r.adjust.adjust_range.is_some())
        {
            return Ok(None);
        }
        let failed =
            TunedBuild { actuator_share: f64::NAN, residual_p99_deg: f64::NAN, equilibrium_shift_rad: f64::NAN };
        let measured: Vec<Option<f64>> = built.stiffness.iter().map(|k| Some(*k)).collect();
        let Ok(t) = crate::asbuilt::tune::tune(self.design, bom, &measured) else { return Ok(Some(failed)) };
        let tuned = crate::fit::bill::spring_set(&t.bom);
        // `tune` has judged the tuned arm about its own equilibrium already, on the fan the
        // sweep would trace when its evaluation settings are the as-built defaults.
        let (p99, shift) = if (self.settings.evaluation_directions, self.settings.evaluation_samples)
            == (crate::asbuilt::DIRECTIONS, crate::asbuilt::SAMPLES)
        {
            (t.after.p99_deg, t.after.shift_rad)
        } else {
            self.residual_about_own_equilibrium(&tuned)?
        };
        let mut spec = spec.clone();
        spec.name = format!("{}_tuned", spec.name);
        spec.stiffness_scale = None;
        spec.built = Some(tuned);
        let Ok((_, m)) = self.closed_loop(&self.nominal, &spec) else { return Ok(Some(failed)) };
        Ok(Some(TunedBuild { actuator_share: m.actuator_share, residual_p99_deg: p99, equilibrium_shift_rad: shift }))
    }

    fn run_item(&self, index: usize, item: WorkItem) -> Result<ItemResult> {
        match item {
            WorkItem::Parasitic { eps } => self.parasitic_item(index, item, eps),
            WorkItem::Build { level, build } => self.build_item(index, item, level, build),
            WorkItem::Stock => self.stock_item(index, item),
        }
    }

    /// The nominal arm with parasitic springs ε·κ at every joint, in closed loop: its fluxes and
    /// its path and power by source (for the figures).
    fn parasitic_item(&self, index: usize, item: WorkItem, eps: f64) -> Result<ItemResult> {
        let mut spec = self.base.clone();
        spec.name = format!("eps_{eps}");
        spec.parasitic = Some(Parasitic { eps, kappa: self.kappa.clone() });
        let (res, m) = self.closed_loop(&self.nominal, &spec)?;
        let mut r = ItemResult::of_run(index, item, &m);
        r.residual_p99_deg = self.fit.metrics.stats.p99_abs;
        let tr = &res.trace;
        let n = tr.n;
        let powers: Vec<Vec<f64>> = (0..SOURCES.len()).map(|s| tr.power(s)).collect();
        r.series = Some(Series {
            t: tr.t.clone(),
            q: (0..tr.t.len()).flat_map(|k| [tr.q[k * n], tr.q[k * n + 1.min(n - 1)]]).collect(),
            power: (0..tr.t.len()).flat_map(|k| powers.iter().map(move |p| p[k])).collect(),
        });
        Ok(r)
    }

    /// One Monte Carlo build at a tolerance level (None: each row's own): its residual about its
    /// own equilibrium, trimmed and tuned where the design can be, and its closed-loop run.
    fn build_item(&self, index: usize, item: WorkItem, level: Option<f64>, build: usize) -> Result<ItemResult> {
        let springs = self.springs();
        let mut rng = SplitMix64::stream(self.settings.seed, (index as u64) << 20 | build as u64);
        // One δ per spring, one per cam (all its basis rows).
        let scale = crate::asbuilt::factors(
            &self.fit.bom,
            |row| level.unwrap_or(row.tolerance),
            self.settings.distribution,
            &mut rng,
        );
        let built = springs.scaled(&scale);
        let (p99, shift) = self.residual_about_own_equilibrium(&built)?;
        let trimmed = self.trimmed_p99(&built)?;
        let mut spec = self.base.clone();
        spec.name = format!("build_{build}");
        spec.stiffness_scale = Some(scale);
        let tuned = self.tuned(build, &built, &spec)?;
        let (_, m) = self.closed_loop(&self.nominal, &spec)?;
        let mut r = ItemResult::of_run(index, item, &m);
        r.residual_p99_deg = p99;
        r.residual_p99_deg_trimmed = trimmed;
        r.equilibrium_shift_rad = Some(shift);
        r.tuned = tuned;
        Ok(r)
    }

    /// Every stiffness snapped to its family's nearest stock rate, the element carrying the
    /// largest torque first and the rest refitted after each snap (trim springs keep their
    /// rate: it is set after assembly, not bought); the arm before and after in closed loop.
    fn stock_item(&self, index: usize, item: WorkItem) -> Result<ItemResult> {
        let bom = &self.fit.bom;
        let elements: Vec<_> = bom.iter().map(|r| r.element.clone()).collect();
        // Trim springs keep their rate: it is set after assembly, not bought.
        let mut fixed: Vec<Option<f64>> = bom.iter().map(|r| r.adjust.trim_range.map(|_| r.stiffness)).collect();
        let mut k: Vec<f64> = bom.iter().map(|r| r.stiffness).collect();
        // Snap the element carrying the largest torque first; refit the rest each time.
        let mut order: Vec<usize> = (0..bom.len()).filter(|&j| bom[j].stock_rate.is_some()).collect();
        order.sort_by(|&a, &b| bom[b].max_torque_nm.total_cmp(&bom[a].max_torque_nm).then(a.cmp(&b)));
        let rates = |j: usize| -> Vec<f64> {
            let fam = &bom[j].family;
            // The catalogue's stock rates of the element's family, from the fit's rows.
            self.fit.stock_rates.get(fam).cloned().unwrap_or_default()
        };
        for &j in &order {
            let snapped = nearest(&rates(j), k[j].max(1e-300)).unwrap_or(k[j]);
            fixed[j] = Some(snapped);
            k = refit_with_fixed(self.design, &self.fit.settings, &self.fit.training, &elements, &fixed)?;
        }
        let snapped = SpringSet { elements, stiffness: k.clone() };
        let (p99, shift) = self.residual_about_own_equilibrium(&snapped)?;
        let (_, before) = self.closed_loop(&self.nominal, &self.base)?;
        let after_pot = ElasticPotential::Springs(snapped);
        let (_, after) = self.closed_loop(&after_pot, &self.base)?;
        let mut r = ItemResult::of_run(index, item, &after);
        r.residual_p99_deg = p99;
        r.equilibrium_shift_rad = Some(shift);
        r.residual_p99_deg_before = Some(self.fit.metrics.stats.p99_abs);
        r.actuator_share_before = Some(before.actuator_share);
        r.savings_before = Some(before.savings);
        r.stock_stiffness = Some(k);
        Ok(r)
    }
}

impl ItemResult {
    /// The result of item `index` with the fluxes and actuator share of its closed-loop run, the
    /// rest blank (NaN residual, nothing measured) for the item to fill in.
    fn of_run(index: usize, item: WorkItem, m: &crate::dynamics::scenario::RunMetrics) -> ItemResult {
        ItemResult {
            index,
            item,
            flux_potential: m.flux.potential,
            flux_mode: m.flux.mode,
            flux_energy: m.flux.energy,
            actuator_share: m.actuator_share,
            residual_p99_deg: f64::NAN,
            residual_p99_deg_before: None,
            actuator_share_before: None,
            equilibrium_shift_rad: None,
            residual_p99_deg_trimmed: None,
            tuned: None,
            savings: Some(m.savings),
            savings_before: None,
            stock_stiffness: None,
            series: None,
        }
    }
}

pub use crate::asbuilt::equilibrium;

/// One row of the parasitic table.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ParasiticRow {
    /// ε, the parasitic stiffness as a fraction of κ.
    pub eps: f64,
    /// ∫|P_Ũ| dt of the perturbed springs over the closed-loop run, J.
    pub flux_potential: f64,
    /// ∫|P_θ| dt of the mode controller, J.
    pub flux_mode: f64,
    /// ∫|P_E| dt of the energy controller, J.
    pub flux_energy: f64,
    /// (∫|P_θ| + ∫|P_E|) / ∫|P_Ũ|, a fraction: how much of the motion the actuators supply.
    pub actuator_share: f64,
    /// What the springs save on the same run against the arm without them (None: a result
    /// written before savings were reported).
    pub savings: Option<Savings>,
}

/// Percentiles of a tolerance level.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ToleranceSummary {
    /// The level (None: the catalogue's own tolerances).
    pub tolerance: Option<f64>,
    /// `uniform` or `normal`.
    pub distribution: Distribution,
    /// Builds drawn at this level.
    pub builds: usize,
    /// Median over the builds (as built, untuned) of the actuator share, a fraction.
    pub actuator_share_p50: f64,
    /// 95th percentile over the builds of the actuator share, a fraction.
    pub actuator_share_p95: f64,
    /// Median over the builds of the energy the springs save against the arm without them
    /// (`savings.energy_saved`), a fraction (NaN: no build reported savings).
    pub energy_saved_p50: f64,
    /// The fraction of energy saved that 95 % of the builds reach (their 5th percentile).
    pub energy_saved_p5: f64,
    /// Median over the builds of the peak actuator torque saved, a fraction.
    pub peak_torque_saved_p50: f64,
    /// Median over the builds of the copper losses saved, a fraction.
    pub copper_loss_saved_p50: f64,
    /// Median over the builds of their p99 |residual angle| about their own equilibrium, degrees.
    pub residual_p99_deg_p50: f64,
    /// 95th percentile over the builds of their p99 |residual angle|, degrees.
    pub residual_p99_deg_p95: f64,
    /// 95 % confidence interval of `residual_p99_deg_p95` (see [`crate::asbuilt::Spread`]).
    pub residual_p99_deg_p95_ci: [f64; 2],
    /// Median over the builds of how far the equilibrium moved, |q_eq′ − q_eq|, rad.
    pub equilibrium_shift_rad_p50: f64,
    /// 95th percentile over the builds of |q_eq′ − q_eq|, rad.
    pub equilibrium_shift_rad_p95: f64,
    /// Median over the builds of their p99 |residual angle| after the builder's trim, degrees
    /// (None: the design has no trim springs).
    pub trimmed_residual_p99_deg_p50: Option<f64>,
    /// 95th percentile of the same, degrees (None: no trim springs).
    pub trimmed_residual_p99_deg_p95: Option<f64>,
    /// 95 % confidence interval of `trimmed_residual_p99_deg_p95`.
    pub trimmed_residual_p99_deg_p95_ci: Option<[f64; 2]>,
    /// After each build's tuning (designs with trims or adjustable elements; see
    /// [`ItemResult::tuned`]): actuator share, p99 residual and equilibrium shift percentiles.
    pub tuned: Option<TunedSummary>,
}

/// Percentiles over the tuned builds of a tolerance level (a failed tuning, NaN, counts as the
/// worst).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TunedSummary {
    /// How many builds were tuned (the first `tuned_builds` of the level).
    pub builds: usize,
    /// The tuned builds' actuator share, a fraction (same closed-loop run, nominal controllers).
    pub actuator_share: crate::asbuilt::Spread,
    /// Their p99 |residual angle| about their own equilibrium, degrees.
    pub residual_p99_deg: crate::asbuilt::Spread,
    /// Their |q′ − q_eq|₂, rad (0 to solver accuracy when the offsets can restore q_eq).
    pub equilibrium_shift_rad: crate::asbuilt::Spread,
}

/// Stock snapping before and after.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StockSummary {
    /// p99 |residual angle| of the fitted springs, degrees.
    pub residual_p99_deg_before: f64,
    /// p99 |residual angle| after snapping every rate to stock (the rest refitted), degrees.
    pub residual_p99_deg_after: f64,
    /// Actuator share of the fitted springs, a fraction.
    pub actuator_share_before: f64,
    /// Actuator share with the stock rates, a fraction.
    pub actuator_share_after: f64,
    /// Energy saved against the arm without springs by the fitted springs, a fraction.
    pub energy_saved_before: f64,
    /// The same with the stock rates, a fraction.
    pub energy_saved_after: f64,
}

/// `sweep.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SweepTables {
    /// One row per ε, in the order of the plan.
    pub parasitic: Vec<ParasiticRow>,
    /// The first tolerance level (the schema's single object).
    pub tolerance: Option<ToleranceSummary>,
    /// Every tolerance level.
    pub tolerance_levels: Vec<ToleranceSummary>,
    /// Stock-rate snapping (None: no used element's family lists `stock_rates`).
    pub stock: Option<StockSummary>,
}

/// Builds the tables from the results of every item (in any order).
pub fn tables(settings: &SweepSettings, results: &[ItemResult]) -> SweepTables {
    let mut sorted: Vec<&ItemResult> = results.iter().collect();
    sorted.sort_by_key(|r| r.index);
    let parasitic = sorted
        .iter()
        .filter_map(|r| match r.item {
            WorkItem::Parasitic { eps } => Some(ParasiticRow {
                eps,
                flux_potential: r.flux_potential,
                flux_mode: r.flux_mode,
                flux_energy: r.flux_energy,
                actuator_share: r.actuator_share,
                savings: r.savings,
            }),
            _ => None,
        })
        .collect();
    let mut levels: Vec<Option<f64>> = Vec::new();
    for r in &sorted {
        if let WorkItem::Build { level, .. } = r.item
            && !levels.contains(&level)
        {
            levels.push(level);
        }
    }
    let tolerance_levels: Vec<ToleranceSummary> = levels
        .iter()
        .map(|level| {
            let builds: Vec<&&ItemResult> =
                sorted.iter().filter(|r| matches!(r.item, WorkItem::Build { level: l, .. } if l == *level)).collect();
            let mut share: Vec<f64> = builds.iter().map(|r| r.actuator_share).collect();
            let saved = |f: fn(&Savings) -> f64| {
                let mut v: Vec<f64> = builds.iter().map(|r| r.savings.as_ref().map_or(f64::NAN, f)).collect();
                v.sort_by(f64::total_cmp);
                v
            };
            let energy_saved = saved(|s| s.energy_saved);
            let mut resid: Vec<f64> = builds.iter().map(|r| r.residual_p99_deg).collect();
            let mut shift: Vec<f64> = builds.iter().map(|r| r.equilibrium_shift_rad.unwrap_or(f64::NAN)).collect();
            let trimmed = builds
                .iter()
                .all(|r| r.residual_p99_deg_trimmed.is_some())
                .then(|| {
                    crate::asbuilt::Spread::of(builds.iter().map(|r| r.residual_p99_deg_trimmed.unwrap_or(f64::NAN)))
                })
                .filter(|_| !builds.is_empty());
            let tuned_builds: Vec<&TunedBuild> = builds.iter().filter_map(|r| r.tuned.as_ref()).collect();
            let tuned = (!tuned_builds.is_empty()).then(|| {
                let of = |f: fn(&TunedBuild) -> f64| crate::asbuilt::Spread::of(tuned_builds.iter().map(|t| f(t)));
                TunedSummary {
                    builds: tuned_builds.len(),
                    actuator_share: of(|t| t.actuator_share),
                    residual_p99_deg: of(|t| t.residual_p99_deg),
                    equilibrium_shift_rad: of(|t| t.equilibrium_shift_rad),
                }
            });
            share.sort_by(f64::total_cmp);
            resid.sort_by(f64::total_cmp);
            shift.sort_by(f64::total_cmp);
            ToleranceSummary {
                tolerance: *level,
                distribution: settings.distribution,
                builds: builds.len(),
                actuator_share_p50: percentile(&share, 50.0),
                actuator_share_p95: percentile(&share, 95.0),
                energy_saved_p50: percentile(&energy_saved, 50.0),
                energy_saved_p5: percentile(&energy_saved, 5.0),
                peak_torque_saved_p50: percentile(&saved(|s| s.peak_torque_saved), 50.0),
                copper_loss_saved_p50: percentile(&saved(|s| s.copper_loss_saved), 50.0),
                residual_p99_deg_p50: percentile(&resid, 50.0),
                residual_p99_deg_p95: percentile(&resid, 95.0),
                residual_p99_deg_p95_ci: percentile_interval(&resid, 95.0, crate::asbuilt::CONFIDENCE),
                equilibrium_shift_rad_p50: percentile(&shift, 50.0),
                equilibrium_shift_rad_p95: percentile(&shift, 95.0),
                trimmed_residual_p99_deg_p50: trimmed.map(|t| t.p50),
                trimmed_residual_p99_deg_p95: trimmed.map(|t| t.p95),
                trimmed_residual_p99_deg_p95_ci: trimmed.map(|t| t.p95_ci),
                tuned,
            }
        })
        .collect();
    let stock = sorted.iter().find(|r| r.item == WorkItem::Stock).map(|r| StockSummary {
        residual_p99_deg_before: r.residual_p99_deg_before.unwrap_or(f64::NAN),
        residual_p99_deg_after: r.residual_p99_deg,
        actuator_share_before: r.actuator_share_before.unwrap_or(f64::NAN),
        actuator_share_after: r.actuator_share,
        energy_saved_before: r.savings_before.map_or(f64::NAN, |s| s.energy_saved),
        energy_saved_after: r.savings.map_or(f64::NAN, |s| s.energy_saved),
    });
    SweepTables { parasitic, tolerance: tolerance_levels.first().cloned(), tolerance_levels, stock }
}

/// Parses a shard specification `i/N` (1-based i).
pub fn parse_shard(text: &str) -> Result<(usize, usize)> {
    let bad = || Error::Setting {
        field: "--shard".into(),
        reason: format!("`{text}` is not of the form i/N with 1 ≤ i ≤ N"),
    };
    let (a, b) = text.split_once('/').ok_or_else(bad)?;
    let (i, n): (usize, usize) = (a.trim().parse().map_err(|_| bad())?, b.trim().parse().map_err(|_| bad())?);
    if n == 0 || i == 0 || i > n {
        return Err(bad());
    }
    Ok((i, n))
}

/// The item indices of shard i of N: every N-th item starting at i − 1, so expensive items of
/// one kind spread over the shards.
pub fn shard_indices(count: usize, shard: (usize, usize)) -> Vec<usize> {
    (shard.0 - 1..count).step_by(shard.1).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sweep judges builds on the as-built figures' fan by default, the fan whose resolution
    /// `asbuilt::DIRECTIONS` bounds and on which `tune` judges a tuned build.
    #[test]
    fn the_sweeps_builds_are_judged_on_the_as_built_fan() {
        let s = crate::design::sweep::SweepSettings::default();
        assert_eq!(
            (s.evaluation_directions, s.evaluation_samples),
            (crate::asbuilt::DIRECTIONS, crate::asbuilt::SAMPLES)
        );
    }

    #[test]
    fn shards_cover_every_item_once() {
        for n in 1..6 {
            let mut all: Vec<usize> = (1..=n).flat_map(|i| shard_indices(23, (i, n))).collect();
            all.sort_unstable();
            assert_eq!(all, (0..23).collect::<Vec<_>>());
        }
        assert_eq!(parse_shard("2/5").unwrap(), (2, 5));
        for bad in ["0/3", "4/3", "x/2", "3", "1/0"] {
            assert!(parse_shard(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn plan_orders_items() {
        let s = SweepSettings {
            epsilons: vec![0.0, 0.1],
            builds: 3,
            tolerances: vec![0.05, 0.1],
            ..SweepSettings::default()
        };
        let p = plan(&s, true);
        assert_eq!(p.len(), 2 + 6 + 1);
        assert_eq!(p[2], WorkItem::Build { level: Some(0.05), build: 0 });
        assert_eq!(p[8], WorkItem::Stock);
    }
}
