//! `springfit sweep`: parasitic springs, manufacturing tolerance and stock rates (the job:
//! [`springfit::jobs::sweep`]).

use std::path::{Path, PathBuf};

use anyhow::Result;
use springfit::jobs::sweep::{Made, SweepJob, SweepRequest};
use springfit::studies::sweep::{SweepTables, parse_shard};

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

pub fn run(args: SweepArgs, session: &Session) -> Result<()> {
    let progress = &session.progress;
    let (design, validated) = super::load_design(&args.design, progress)?;
    let request = SweepRequest { builds: args.builds, seed: args.seed, merge: args.merge.clone() };
    let job = SweepJob::new(&design, validated.catalog.as_ref(), request)
        .map_err(|e| super::flag(e, "builds", "--builds"))?;
    if let Some(note) = job.tolerance_note() {
        progress.say(note);
    }
    let shard = args.shard.as_deref().map(parse_shard).transpose()?;
    let job = job.with_shard(shard);
    let target = args.out.clone().unwrap_or_else(|| {
        let name = match shard {
            Some((i, n)) => format!("{}_sweep_shard_{i}_of_{n}", design.name),
            None => format!("{}_sweep", design.name),
        };
        PathBuf::from("out").join(name)
    });
    let outputs = session.plan_for(&design, "sweep", job.files().iter().copied());
    let claim = springfit::report::output::check(&target, &outputs)?;
    let run =
        progress.run(|p| job.run(p)).map_err(|e| super::in_design(&design, super::flag(e, "merge", "--merge")))?;
    if let Some(secs) = run.seconds {
        progress.say(format!("{} items in {secs:.1} s", run.results.len()));
    }
    let written = run.write(&design, claim)?;
    match &run.made {
        Made::Shard(s) => {
            let (i, n) = s.shard;
            progress.say(format!(
                "wrote shard {i}/{n} to {}; join the shards with `springfit sweep {}{} --merge DIR...`",
                written.display(),
                design.path.display(),
                // The shards' fingerprint includes these: the merge must repeat them.
                args.builds.map(|b| format!(" --builds {b}")).unwrap_or_default()
                    + &args.seed.map(|s| format!(" --seed {s}")).unwrap_or_default()
            ));
        }
        Made::Tables(t) => say_tables(t, &written, progress),
    }
    Ok(())
}

/// The tables' lines: parasitic springs, tolerance levels (as built, trimmed, tuned), stock rates.
fn say_tables(t: &SweepTables, written: &Path, progress: &Progress) {
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
    progress.say(format!("wrote {}", written.display()));
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
