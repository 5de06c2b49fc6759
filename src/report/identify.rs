//! The files `springfit identify` writes: `identify.md` and `identify.json` (the estimates with
//! their standard errors, the groups of rates the logs cannot tell apart, damping and friction),
//! `identified.csv` (the bill with `measured_stiffness` filled in, for `tune`), and two figures:
//! the torques the motion shows against the identified model's, and the δ estimates with their
//! error bars. With `--plan`, `plan.md` and `plan.json` instead, and the predicted error bars.

use std::fmt::Write as _;

use serde::Serialize;

use super::output::OutputDir;
use super::plot::{BoxItem, Figure, Layer, Panel, Style, palette, render};
use crate::error::Result;
use crate::fit::bill::BomRow;
use crate::identify::plan::Plan;
use crate::identify::{CombinationReport, Identification, Source, Status};

/// The file names of an identification.
pub const FILES: &[&str] = &[
    "identify.md",
    "identify.json",
    "identified.csv",
    "identified_parts.csv",
    "cams/*",
    "identify_torque.svg",
    "identify_torque.png",
    "identify_rates.svg",
    "identify_rates.png",
    "report.html",
];

/// The file names of a plan.
pub const PLAN_FILES: &[&str] = &["plan.md", "plan.json", "plan_rates.svg", "plan_rates.png", "report.html"];

/// `identify.json`.
#[derive(Serialize)]
struct Json<'a> {
    design: &'a str,
    #[serde(flatten)]
    identification: &'a Identification,
}

/// `plan.json`.
#[derive(Serialize)]
struct PlanJson<'a> {
    design: &'a str,
    #[serde(flatten)]
    plan: &'a Plan,
}

/// A combination Σ wᵢ δ(idᵢ) in words: `0.589 δ(S08) − 0.199 δ(S09)`.
pub fn combination_text(c: &CombinationReport) -> String {
    let mut s = String::new();
    for (k, (id, w)) in c.weights.iter().enumerate() {
        let sign = if *w < 0.0 { "−" } else { "+" };
        match k {
            0 if *w < 0.0 => s.push_str(&format!("−{:.3} δ({id})", w.abs())),
            0 => s.push_str(&format!("{w:.3} δ({id})")),
            _ => s.push_str(&format!(" {sign} {:.3} δ({id})", w.abs())),
        }
    }
    s
}

fn pct(x: f64) -> String {
    if x.is_finite() { format!("{:+.3} %", 100.0 * x) } else { "–".into() }
}

/// A standard error in percent; one the logs do not bound (a rate they cannot see) is said in
/// words: a report never prints ∞ or NaN.
fn se_pct(x: f64) -> String {
    if x.is_finite() { format!("{:.3} %", 100.0 * x) } else { "unbounded".into() }
}

/// The table of rate estimates and the groups, shared by `identify.md` and `plan.md`.
fn rates_md(id: &Identification, bom: &[BomRow], s: &mut String) {
    s.push_str(
        "| part | family | δ | standard error | | rate as designed | rate identified | unit |\n| --- | --- | ---: | ---: | --- | ---: | ---: | --- |\n",
    );
    for r in &id.rates {
        let row = &bom[r.rows[0]];
        let (designed, unit) = match row.cam {
            Some(c) => (c.build.follower_rate, crate::files::bom::CAM_UNIT),
            None => (row.stiffness, row.element.profile.unit()),
        };
        let (verdict, delta, identified) = match r.status {
            Status::Identified => {
                ("identified".to_string(), pct(r.delta), format!("{:.6}", designed * (1.0 + r.for_tuning)))
            }
            Status::Group(g) => (
                format!("not identified (group {})", g + 1),
                "–".into(),
                if r.source == Source::Combination {
                    format!("{:.6} (from the group's combinations)", designed * (1.0 + r.for_tuning))
                } else {
                    "as designed".into()
                },
            ),
        };
        let _ = writeln!(
            s,
            "| {}{} | {} | {delta} | {} | {verdict} | {designed:.6} | {identified} | {unit} |",
            r.id,
            if r.trim { " (trim)" } else { "" },
            r.family.replace('|', "/"),
            se_pct(r.standard_error),
        );
    }
    if !id.groups.is_empty() {
        s.push_str("\n### Rates these logs cannot tell apart\n\n");
        for (g, group) in id.groups.iter().enumerate() {
            let _ = writeln!(s, "**Group {}: {}.** {}.\n", g + 1, group.members.join(", "), group.reason);
            for c in &group.identified {
                let _ = writeln!(
                    s,
                    "- identified: {} = {} ± {}",
                    combination_text(c),
                    pct(c.value),
                    se_pct(c.standard_error)
                );
            }
            if !group.identified.is_empty() {
                s.push('\n');
            }
        }
        s.push_str(
            "`identified.csv` gives such a part the rate its group's identified combinations imply (what the logs leave \
             open stays as designed); a part the logs never engage keeps its design rate.\n",
        );
    }
}

/// `identify.md`.
pub fn markdown(design: &str, id: &Identification, bom: &[BomRow]) -> String {
    let mut s = format!("# springfit identify: {design}\n\n");
    let seconds: f64 = id.runs.iter().map(|r| r.seconds).sum();
    let _ = writeln!(
        s,
        "{} runs, {:.1} s of log; {} regression rows for {} unknowns (rank {}, condition {}). Low-pass of both sides at \
         {:.3} Hz, encoder smoothing at {} Hz. A rate counts as identified when the standard error of its δ is at most \
         {} % of it: **{} of {} parts identified**.\n",
        id.runs.len(),
        seconds,
        id.rows,
        id.unknowns,
        id.rank,
        if id.condition.is_finite() { format!("{:.3e}", id.condition) } else { "unbounded: rank-deficient".into() },
        id.cutoff_hz,
        id.smoothing_hz,
        100.0 * id.max_standard_error,
        id.identified_count(),
        id.rates.len()
    );
    s.push_str("## Rate errors\n\nδ = built rate / designed rate − 1, with its standard error (Newey–West, from the residual).\n\n");
    rates_md(id, bom, &mut s);
    s.push_str("\n![rate errors](identify_rates.svg)\n\n## Damping and friction\n\n| joint | damping (N·m·s/rad) | standard error | Coulomb friction (N·m) | standard error |\n| --- | ---: | ---: | ---: | ---: |\n");
    let cell = |v: Option<crate::identify::Value>| match v {
        Some(v) if v.standard_error.is_finite() => (format!("{:.5}", v.value), format!("{:.2e}", v.standard_error)),
        Some(_) => ("not identified".into(), "unbounded".into()),
        None => ("not estimated".into(), "–".into()),
    };
    for j in &id.joints {
        let (d, ds) = cell(j.damping);
        let (f, fs) = cell(j.friction);
        let _ = writeln!(s, "| {} | {d} | {ds} | {f} | {fs} |", j.joint);
    }
    s.push_str("\n## Fit\n\n| joint | residual rms (N·m) | elements' torque rms (N·m) |\n| --- | ---: | ---: |\n");
    for (j, (e, t)) in id.residual_rms_nm.iter().zip(&id.torque_rms_nm).enumerate() {
        let _ = writeln!(s, "| q{} | {e:.4e} | {t:.4} |", j + 1);
    }
    s.push_str("\n![torques](identify_torque.svg)\n\n## Logs\n\n| file | run | samples | seconds | rate (Hz) | torques | rows |\n| --- | --- | ---: | ---: | ---: | --- | ---: |\n");
    for r in &id.runs {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.3} | {:.1} | {} | {} |",
            r.file,
            if r.run.is_empty() { "–" } else { &r.run },
            r.samples,
            r.seconds,
            r.rate_hz,
            if r.driven { "yes" } else { "no (free swing)" },
            r.rows
        );
    }
    s.push_str("\n`identified.csv` is the bill of materials with `measured_stiffness` filled in: `springfit tune DESIGN --measured identified.csv` sets the offsets and trims from it.\n");
    s
}

/// `plan.md`.
pub fn plan_markdown(design: &str, plan: &Plan, bom: &[BomRow]) -> String {
    let mut s = format!("# springfit identify --plan: {design}\n\n");
    let _ = writeln!(
        s,
        "{} releases from rest, {:.0} s of log at {} Hz in all, chosen from {} candidates ({} dropped: their swings leave \
         the region) by the criterion: {}. Predicted with a {}-bit encoder ({} counts rms of noise before quantisation).\n",
        plan.releases.iter().map(|r| r.releases).sum::<usize>(),
        plan.total_seconds,
        plan.rate_hz,
        plan.candidates,
        plan.dropped,
        plan.criterion,
        plan.encoder_bits,
        plan.encoder_noise_counts
    );
    if plan.complete {
        s.push_str("**Every rate comes out identified.**\n\n");
    } else {
        let _ = writeln!(
            s,
            "**{} of {} parts come out identified**: the groups below say which the releases cannot tell apart (log \
             driven excitation as well, or accept their combinations).\n",
            plan.predicted.identified_count(),
            plan.predicted.rates.len()
        );
    }
    let n = plan.releases.first().map_or(0, |r| r.q0.len());
    s.push_str("## Releases\n\n| # | hold at q (rad) | metric distance | energy (J) | releases | log each (s) |\n| ---: | --- | ---: | ---: | ---: | ---: |\n");
    for (i, r) in plan.releases.iter().enumerate() {
        let q: Vec<String> = r.q0.iter().map(|x| format!("{x:.4}")).collect();
        let _ = writeln!(
            s,
            "| {} | ({}) | {:.3} | {:.3} | {} | {} |",
            i + 1,
            q.join(", "),
            r.distance,
            r.energy_j,
            r.releases,
            r.seconds
        );
    }
    let _ = writeln!(
        s,
        "\nHold the arm still at q (joints q1 … q{n}), release it, log {} s; repeat as listed.\n",
        plan.releases.first().map_or(0.0, |r| r.seconds)
    );
    s.push_str("## Predicted rate errors\n\nThe releases simulated as designed and read through the encoder, identified as `identify` would: the standard errors to expect (the δ themselves are those of the simulated noise, about 0).\n\n");
    rates_md(&plan.predicted, bom, &mut s);
    s.push_str("\n![predicted](plan_rates.svg)\n");
    s
}

/// The δ estimates with error bars: a box of ±1 standard error and whiskers of ±2 around each
/// identified δ; parts not identified are marked on the zero line.
pub fn rates_figure(id: &Identification, title: &str) -> Figure {
    let mut items = Vec::new();
    let mut open = Vec::new();
    for (i, r) in id.rates.iter().enumerate() {
        let colour = if r.trim { palette(1) } else { palette(0) };
        match r.status {
            Status::Identified => {
                let (d, s) = (100.0 * r.delta, 100.0 * r.standard_error);
                items.push(BoxItem {
                    label: r.id.clone(),
                    five: [d - 2.0 * s, d - s, d, d + s, d + 2.0 * s],
                    color: colour,
                });
            }
            Status::Group(_) => {
                items.push(BoxItem { label: r.id.clone(), five: [0.0; 5], color: (170, 170, 170) });
                open.push((i as f64, 0.0));
            }
        }
    }
    let mut layers =
        vec![Layer::HLine { y: 0.0, style: Style::line((120, 120, 120), 1).dashed() }, Layer::Boxes { items }];
    if !open.is_empty() {
        layers.push(Layer::Points {
            points: open,
            style: Style::fill((200, 60, 60), 1.0),
            size: 5,
            label: Some("not identified (see the groups)".into()),
        });
    }
    Figure::single(
        Panel {
            title: title.into(),
            x_label: "part".into(),
            y_label: "δ = built / designed rate − 1 (%)".into(),
            legend: true,
            notes: vec!["box ±1 standard error".into(), "whiskers ±2 standard errors".into()],
            layers,
            ..Panel::default()
        },
        1200,
        520,
    )
}

/// Per joint: the torque the motion shows (elements, damping and friction), the identified
/// model's and the design's, all through the regression's low-pass.
pub fn torque_figure(id: &Identification) -> Option<Figure> {
    let trace = id.trace.as_ref()?;
    let n = trace.measured.len();
    let panels = (0..n)
        .map(|j| {
            let line = |v: &[f64]| vec![trace.t.iter().zip(v).map(|(t, y)| (*t, *y)).collect::<Vec<_>>()];
            Panel {
                title: format!("joint q{}: {}", j + 1, trace.run),
                x_label: "t (s)".into(),
                y_label: "torque (N·m)".into(),
                legend: j == 0,
                layers: vec![
                    Layer::Lines {
                        lines: line(&trace.designed[j]),
                        style: Style::line(palette(6), 1).dashed(),
                        label: Some("as designed".into()),
                    },
                    Layer::Lines {
                        lines: line(&trace.measured[j]),
                        style: Style::line(palette(0), 3),
                        label: Some("from the motion".into()),
                    },
                    Layer::Lines {
                        lines: line(&trace.predicted[j]),
                        style: Style::line(palette(1), 1),
                        label: Some("identified model".into()),
                    },
                ],
                notes: vec![format!("residual rms {:.3e} N·m", id.residual_rms_nm[j])],
                ..Panel::default()
            }
        })
        .collect();
    Some(Figure {
        title: Some("Elements, damping and friction: torque from the motion against the models".into()),
        width: 1200,
        height: 300 * n as u32 + 60,
        rows: n,
        cols: 1,
        panels,
    })
}

/// `identified_parts.csv`: per part, where the rate in `identified.csv` comes from (`measured`:
/// its own δ; `combination`: inferred from its group's identified combinations; `as designed`:
/// the logs fix nothing about it), with δ, its standard error and the δ `tune` gets. The bill
/// itself keeps its columns, which `tune` reads.
pub fn parts_csv(id: &Identification) -> String {
    let mut s = String::from("id,family,trim,source,group,delta,standard_error,delta_for_tune\n");
    let num = |x: f64| if x.is_finite() { format!("{x}") } else { String::new() };
    for r in &id.rates {
        let group = match r.status {
            Status::Identified => String::new(),
            Status::Group(g) => format!("{}", g + 1),
        };
        let delta = if r.status == Status::Identified { num(r.delta) } else { String::new() };
        let _ = writeln!(
            s,
            "{},{},{},{},{group},{delta},{},{}",
            crate::csv::csv_field(&r.id),
            crate::csv::csv_field(&r.family),
            r.trim,
            r.source.word(),
            num(r.standard_error),
            num(r.for_tuning)
        );
    }
    s
}

/// Writes the files of an identification into `out` (`report.html` is the caller's).
pub fn write(out: &OutputDir, design: &str, id: &Identification, bom: &[BomRow]) -> Result<()> {
    out.write("identify.md", markdown(design, id, bom))?;
    out.write(
        "identify.json",
        serde_json::to_string_pretty(&Json { design, identification: id }).expect("serialises") + "\n",
    )?;
    for (path, text) in crate::files::bom::files_measured("identified.csv", bom, &id.measured) {
        out.write(&path, text)?;
    }
    out.write("identified_parts.csv", parts_csv(id))?;
    render(&rates_figure(id, &format!("{design}: rate errors identified from the logs")), &out.path("identify_rates"))?;
    if let Some(fig) = torque_figure(id) {
        render(&fig, &out.path("identify_torque"))?;
    }
    Ok(())
}

/// Writes the files of a plan into `out` (`report.html` is the caller's).
pub fn write_plan(out: &OutputDir, design: &str, plan: &Plan, bom: &[BomRow]) -> Result<()> {
    out.write("plan.md", plan_markdown(design, plan, bom))?;
    out.write("plan.json", serde_json::to_string_pretty(&PlanJson { design, plan }).expect("serialises") + "\n")?;
    render(
        &rates_figure(&plan.predicted, &format!("{design}: standard errors the plan predicts")),
        &out.path("plan_rates"),
    )?;
    Ok(())
}
