//! `springfit tune`: offsets and trim rates to set on a built arm from its measured rates.

use std::path::{Path, PathBuf};

use anyhow::Result;
use springfit::asbuilt::tune::{State, TuneOutcome, tune};
use springfit::design::tolerance::TrimRule;
use springfit::files::bom::load_measured;
use springfit::units::sci;

use super::Session;

/// The names `springfit tune` may write: the tuned bill (with its cams' files) and the reports.
const FILES: &[&str] = &["bom_tuned.csv", "cams/*", "tune.json", "tune.md"];

pub fn run(design: &Path, measured: &Path, out: Option<PathBuf>, session: &Session) -> Result<()> {
    let progress = &session.progress;
    // The same validation every command runs first, and the output folder checked before any work.
    let (design, _) = super::load_design(design, progress)?;
    let target = out.unwrap_or_else(|| PathBuf::from("out").join(format!("{}_tune", design.name)));
    let plan = session.plan_for(&design, "tune", FILES.iter().copied());
    let claim = springfit::report::output::check(&target, &plan)?;
    let (bom, rates) = load_measured(measured)?;
    if bom.first().is_some_and(|r| r.element.coupling.len() != design.dof()) {
        return Err(springfit::Error::invalid(
            measured,
            "line 2: coupling",
            format!("has {} entries but the design's robot has {} joints", bom[0].element.coupling.len(), design.dof()),
        )
        .into());
    }
    let step = progress.step("tuning");
    let outcome = tune(&design, &bom, &rates);
    step.finish();
    let outcome = outcome.map_err(|e| anyhow::Error::new(e).context(design.path.display().to_string()))?;
    let step = progress.step("writing outputs");
    let dir = claim.open()?;
    springfit::files::bom::write(&dir, "bom_tuned.csv", &outcome.bom)?;
    dir.write("tune.json", serde_json::to_string_pretty(&outcome)? + "\n")?;
    dir.write("tune.md", markdown(&design.name, &outcome))?;
    let written = dir.commit();
    step.finish();
    let written = written?;
    for line in summary_lines(&outcome) {
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
        if o.equilibrium_restored { "restored at q_eq" } else { "NOT restored" },
        trims_sentence(o, true)
    ));
    v.extend(o.binding.iter().cloned());
    v.extend(o.measured_trims.iter().cloned());
    v
}

/// What the trims were set for and how near ∇²U(q_eq) = w² M(q_eq) the arm is.
fn trims_sentence(o: &TuneOutcome, loud: bool) -> String {
    let not = if loud { "NOT restored" } else { "not restored" };
    match o.trim_rule {
        TrimRule::Hessian => {
            format!(
                "∇²U(q_eq) = w² M(q_eq) {} (w² = {:.4} (rad/s)²)",
                if o.hessian_restored { "holds" } else { not },
                o.w2
            )
        }
        TrimRule::Residual => format!(
            "trims set for the least-squares residual{} (∇²U(q_eq) is w² M(q_eq) to {} of ‖w² M‖, w² = {:.4} (rad/s)²)",
            if o.trims_reached { "" } else { ", a range binding" },
            sci(o.after.hessian_mismatch, 2),
            o.w2
        ),
    }
}

fn markdown(name: &str, o: &TuneOutcome) -> String {
    let mut s = format!(
        "# springfit tune: {name}\n\n| | p99 | max | shift (rad) | Hessian mismatch |\n| --- | ---: | ---: | ---: | ---: |\n"
    );
    for (label, st) in [("before", &o.before), ("after", &o.after)] {
        s.push_str(&format!(
            "| {label} | {:.4}° | {:.4}° | {} | {} |\n",
            st.p99_deg,
            st.max_deg,
            sci(st.shift_rad, 3),
            sci(st.hessian_mismatch, 2)
        ));
    }
    s.push_str("\nResidual angles on held-out geodesics from the arm's own equilibrium; shift |q′ − q_eq|₂.\n\n## Settings to make\n\n| id | what | designed | set | at the end of its range |\n| --- | --- | ---: | ---: | --- |\n");
    for st in &o.settings {
        s.push_str(&format!(
            "| {} | {} | {:.6} | {:.6} | {} |\n",
            st.id,
            st.kind,
            st.designed,
            st.set,
            if st.at_limit { "yes" } else { "no" }
        ));
    }
    s.push_str(&format!(
        "\nOffsets in rad, trim rates in N·m/rad. Equilibrium {}; {}.\n",
        if o.equilibrium_restored { "restored" } else { "not restored" },
        trims_sentence(o, false)
    ));
    for b in o.binding.iter().chain(&o.measured_trims) {
        s.push_str(&format!("\n- {b}\n"));
    }
    s
}
