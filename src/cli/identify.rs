//! `springfit identify`: a built arm's spring rates, damping and friction from logged swings, or
//! (`--plan`) the releases to log (the job: [`springfit::jobs::identify`]).

use std::path::{Path, PathBuf};

use anyhow::Result;
use springfit::identify::plan::Plan;
use springfit::identify::{Identification, Status};
use springfit::jobs::identify::{Identified, IdentifyRequest};

use super::Session;
use super::progress::Progress;

pub struct IdentifyArgs {
    pub design: PathBuf,
    pub bom: PathBuf,
    pub logs: Vec<PathBuf>,
    pub plan: bool,
    pub out: Option<PathBuf>,
}

pub fn run(args: IdentifyArgs, session: &Session) -> Result<()> {
    let progress = &session.progress;
    let (design, _) = super::load_design(&args.design, progress)?;
    let suffix = if args.plan { "identify_plan" } else { "identify" };
    let target = args.out.clone().unwrap_or_else(|| PathBuf::from("out").join(format!("{}_{suffix}", design.name)));
    let request = if args.plan { IdentifyRequest::Plan } else { IdentifyRequest::Logs(&args.logs) };
    let plan = session.plan_for(&design, "identify", request.files().iter().copied());
    let claim = springfit::report::output::check(&target, &plan)?;
    let run = progress.run(|p| springfit::jobs::identify::identify(&design, &args.bom, request, p))?;
    let written = run.write(&design, claim)?;
    match &run.made {
        Identified::Plan(proposal) => say_plan(proposal, &written, progress),
        Identified::Rates(outcome) => {
            say_identified(outcome, progress);
            let cams = if run.rows.iter().any(|r| r.cam.is_some()) { ", cams/" } else { "" };
            progress.say(format!(
                "wrote {} (identify.md, identify.json, identified.csv{cams}, identify_torque, identify_rates, report.html); \
                 next: springfit tune {} --measured {}",
                written.display(),
                args.design.display(),
                written.join("identified.csv").display()
            ));
        }
    }
    Ok(())
}

/// The releases to log.
fn say_plan(proposal: &Plan, written: &Path, progress: &Progress) {
    progress.say(format!(
        "plan: {} releases, {:.0} s of log at {} Hz, from {} candidates ({} leave the region); {}-bit encoder",
        proposal.releases.iter().map(|r| r.releases).sum::<usize>(),
        proposal.total_seconds,
        proposal.rate_hz,
        proposal.candidates,
        proposal.dropped,
        proposal.encoder_bits
    ));
    for (i, r) in proposal.releases.iter().enumerate() {
        let q: Vec<String> = r.q0.iter().map(|x| format!("{x:.4}")).collect();
        progress.say(format!(
            "  {}. hold at q = ({}) rad (distance {:.3}, {:.2} J), release {}×, log {} s each",
            i + 1,
            q.join(", "),
            r.distance,
            r.energy_j,
            r.releases,
            r.seconds
        ));
    }
    for line in rate_lines(&proposal.predicted, "predicted") {
        progress.say(line);
    }
    progress.say(format!("wrote {} (plan.md, plan.json, plan_rates, report.html)", written.display()));
}

/// The logs, the rates identified, and each joint's damping and friction.
fn say_identified(outcome: &Identification, progress: &Progress) {
    let seconds: f64 = outcome.runs.iter().map(|r| r.seconds).sum();
    progress.say(format!(
        "{} runs, {:.1} s of log, {} rows for {} unknowns; condition {}; low-pass {:.3} Hz",
        outcome.runs.len(),
        seconds,
        outcome.rows,
        outcome.unknowns,
        if outcome.condition.is_finite() { format!("{:.3e}", outcome.condition) } else { "∞ (rank short)".into() },
        outcome.cutoff_hz
    ));
    for line in rate_lines(outcome, "identified") {
        progress.say(line);
    }
    for j in &outcome.joints {
        let part = |name: &str, v: Option<springfit::identify::Value>, unit: &str| match v {
            Some(v) if v.standard_error.is_finite() => {
                format!("{name} {:.5} ± {:.2e} {unit}", v.value, v.standard_error)
            }
            Some(_) => format!("{name} not identified"),
            None => String::new(),
        };
        let d = part("damping", j.damping, "N·m·s/rad");
        let f = part("friction", j.friction, "N·m");
        if !d.is_empty() || !f.is_empty() {
            progress.say(format!("  {}: {d}{}{f}", j.joint, if d.is_empty() || f.is_empty() { "" } else { ", " }));
        }
    }
}

/// One line per part: δ ± standard error, or the group it is in; then each group's reason and
/// combinations.
fn rate_lines(id: &Identification, what: &str) -> Vec<String> {
    let mut out = vec![format!(
        "{what}: {} of {} parts (standard error ≤ {} % of the rate)",
        id.identified_count(),
        id.rates.len(),
        100.0 * id.max_standard_error
    )];
    for r in &id.rates {
        out.push(match r.status {
            Status::Identified => {
                format!("  {}: δ = {:+.3} % ± {:.3} %", r.id, 100.0 * r.delta, 100.0 * r.standard_error)
            }
            Status::Group(g) => format!("  {}: not identified (group {})", r.id, g + 1),
        });
    }
    for (g, group) in id.groups.iter().enumerate() {
        out.push(format!("  group {} ({}): {}", g + 1, group.members.join(", "), group.reason));
        for c in &group.identified {
            out.push(format!(
                "    identified: {} = {:+.3} % ± {:.3} %",
                springfit::report::identify::combination_text(c),
                100.0 * c.value,
                100.0 * c.standard_error
            ));
        }
    }
    out
}
