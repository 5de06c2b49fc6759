//! The files `springfit tune` writes: the tuned bill, `tune.json` and `tune.md`.

use super::output::OutputDir;
use crate::asbuilt::tune::TuneOutcome;
use crate::design::tolerance::TrimRule;
use crate::error::{Error, Result};
use crate::units::sci;

/// The names `springfit tune` may write: the tuned bill (with its cams' files) and the reports.
pub const FILES: &[&str] = &["bom_tuned.csv", "cams/*", "tune.json", "tune.md"];

/// Writes `bom_tuned.csv` (with its cams' files), `tune.json` and `tune.md` of the design named
/// `name` into `out`.
pub fn write(out: &OutputDir, name: &str, o: &TuneOutcome) -> Result<()> {
    crate::files::bom::write(out, "bom_tuned.csv", &o.bom)?;
    let json = serde_json::to_string_pretty(o)
        .map_err(|e| Error::io(out.path("tune.json"), std::io::Error::other(e.to_string())))?;
    out.write("tune.json", json + "\n")?;
    out.write("tune.md", markdown(name, o))
}

/// What the trims were set for and how near ∇²U(q_eq) = w² M(q_eq) the arm is; `loud` writes
/// a failure in capitals (the command's lines), else in lower case (`tune.md`).
pub fn trims_sentence(o: &TuneOutcome, loud: bool) -> String {
    let not = if loud { "NOT restored" } else { "not restored" };
    if o.as_drawn {
        return format!(
            "the build lost nothing (it holds q_eq with the drawing's residual on tune's fan): every setting stays as it is, trims included (w² = {:.4} (rad/s)²)",
            o.w2
        );
    }
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

/// `tune.md`: the arm before and after, and the settings to make.
pub fn markdown(name: &str, o: &TuneOutcome) -> String {
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
        if o.as_drawn {
            "holds"
        } else if o.equilibrium_restored {
            "restored"
        } else {
            "not restored"
        },
        trims_sentence(o, false)
    ));
    for b in o.binding.iter().chain(&o.measured_trims) {
        s.push_str(&format!("\n- {b}\n"));
    }
    s
}
