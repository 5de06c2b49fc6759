//! `springfit tune`: offsets and trim rates to set on a built arm from its measured rates (the
//! job: [`springfit::jobs::tune`]).

use std::path::{Path, PathBuf};

use anyhow::Result;
use springfit::asbuilt::tune::{State, TuneOutcome};
use springfit::report::sci;

use super::Session;

pub fn run(design: &Path, measured: &Path, out: Option<PathBuf>, session: &Session) -> Result<()> {
    let progress = &session.progress;
    // The same validation every command runs first, and the output folder checked before any work.
    let (design, _) = super::load_design(design, progress)?;
    let target = out.unwrap_or_else(|| PathBuf::from("out").join(format!("{}_tune", design.name)));
    let plan = session.plan_for(&design, "tune", springfit::jobs::tune::FILES.iter().copied());
    let claim = springfit::report::output::check(&target, &plan)?;
    let run = progress
        .run(|p| springfit::jobs::tune::tune(&design, measured, p))
        .map_err(|e| super::in_design(&design, e))?;
    let step = progress.step("writing outputs");
    let written = run.write(&design, claim);
    step.finish();
    let written = written?;
    let outcome = &run.outcome;
    for line in summary_lines(outcome) {
        progress.say(line);
    }
    let cams = if outcome.bom.iter().any(|r| r.cam.is_some()) { ", cams/" } else { "" };
    progress.say(format!("wrote {} (bom_tuned.csv{cams}, tune.json, tune.md)", written.display()));
    Ok(())
}

fn state_line(name: &str, s: &State) -> String {
    format!(
        "{name}: p99 {:.4}°, max {:.4}° about its own equilibrium; shift {} rad; Hessian mismatch {}",
        s.p99_deg,
        s.max_deg,
        sci(s.shift_rad, 3),
        sci(s.hessian_mismatch, 2)
    )
}

fn summary_lines(o: &TuneOutcome) -> Vec<String> {
    let mut v = vec![state_line("before tuning", &o.before), state_line("after tuning ", &o.after)];
    for s in &o.settings {
        v.push(format!(
            "  set {} {}: {:.6} (designed {:.6}){}",
            s.id,
            s.kind,
            s.set,
            s.designed,
            if s.at_limit { ", at the end of its range" } else { "" }
        ));
    }
    if o.settings.is_empty() {
        v.push("  nothing to set: the bill of materials has no adjustable element and no trim spring".into());
    }
    v.push(format!(
        "equilibrium {}; {}",
        if o.as_drawn {
            "holds at q_eq"
        } else if o.equilibrium_restored {
            "restored at q_eq"
        } else {
            "NOT restored"
        },
        springfit::report::tune::trims_sentence(o, true)
    ));
    v.extend(o.binding.iter().cloned());
    v.extend(o.measured_trims.iter().cloned());
    v
}
