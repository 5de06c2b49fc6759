//! The pipelines users run, one home each: what `springfit <command>` and the Python package's
//! calls do between reading their arguments and showing the result.
//!
//! A job takes a design (loaded and validated: [`crate::design::validate`]) and a typed request
//! (the command's options as data), runs the stages below it in order (reporting them to a
//! [`Progress`](crate::progress::Progress)), and returns a typed run result with a `write`
//! method that writes the command's output folder into a claimed folder
//! ([`crate::report::output::check`]). It prints nothing: what the command line prints is read
//! from the result, and a warning is a [`Warning`] in it. The command line (`src/cli/`) and the
//! Python package (`python/src/`) only convert arguments, call a job and show its result, so
//! neither holds a step the other lacks.
//!
//! | job | command | stages it runs |
//! | --- | --- | --- |
//! | [`fit`] | `fit` | the fit with its parts (`parts::fit_with_parts`) or the exact reference, the as-built builds (`asbuilt::of_fit`) |
//! | [`parts`] | `parts` | a fit or a bill read back, the parts (`parts::choose`) |
//! | [`simulate`] | `simulate` | the springs (given, exact or fitted), the mode label, the scenarios, the backbone |
//! | [`sweep`] | `sweep` | the fit and the label, the sweep's items (all, a shard, or shards merged), the tables |
//! | [`compare`] | `compare`, `pareto` | fits of designs with their as-built builds, the exact reference; the budget and radius curves |
//! | [`export`] | `export --mujoco` | a fit or a bill read back, the MuJoCo model |
//! | [`tune`] | `tune` | the measured bill, offsets and trims (`asbuilt::tune`) |
//! | [`identify`] | `identify` | the logs, the identified rates (`identify`), or the plan of releases (`identify::plan`) |
//! | [`geodesics`] | `geodesics` | the region check and the fan |
//! | [`init`] | `init` | the arm read, its region checked against what limits it, ω from gravity, the design written |
//!
//! `springfit check` is no job: it reports the design itself ([`crate::design::Design`]).
//!
//! **One feature, its files.** A job names the folders its feature spans, e.g. identification:
//! the settings `design/identify.rs`, the logs `files/log.rs`, the maths `identify/` (the
//! estimate, the filter, the plan), the files written `report/identify.rs`, the job
//! `jobs/identify.rs` and the command `cli/identify.rs`. Each job file's first lines list its
//! feature's files the same way.

pub mod compare;
pub mod export;
pub mod fit;
pub mod geodesics;
pub mod identify;
pub mod init;
pub mod parts;
pub mod simulate;
pub mod sweep;
pub mod tune;

/// What a warning is about, so that a caller can show it beside the line it concerns (the CLI
/// prints the fit's Hessian warning after the equilibrium line, a cam's after the cam's).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Topic {
    /// The fit's equalities at q_eq (∇U = 0, ∇²U = ω²M) as evaluated.
    Equalities,
    /// The bill of materials against its catalogue.
    Bill,
    /// The cam of this index in the fit's cams.
    Cam(usize),
    /// The parts of the bill (an element no spring meets).
    Parts,
}

/// A warning a job found about the input or its result: shown, not fatal (the CLI prints
/// `springfit: warning: <message>` on stderr).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Warning {
    /// What it is about.
    pub topic: Topic,
    /// The sentence shown.
    pub message: String,
}

/// The messages of the warnings in `warnings` about `topic`, in order.
pub fn about<'a>(warnings: &'a [Warning], topic: &'a Topic) -> impl Iterator<Item = &'a str> + 'a {
    warnings.iter().filter(move |w| w.topic == *topic).map(|w| w.message.as_str())
}

/// Refuses a bill read from `path` whose couplings do not have one entry per joint of the design,
/// in the wording `how` each command has always used.
pub fn check_couplings(
    design: &crate::design::Design,
    path: &std::path::Path,
    rows: &[crate::fit::bill::BomRow],
    how: Couplings,
) -> crate::Result<()> {
    let n = design.dof();
    let bad = match how {
        Couplings::First | Couplings::Line2 => rows.first().filter(|r| r.element.coupling.len() != n),
        Couplings::Any => rows.iter().find(|r| r.element.coupling.len() != n),
    };
    let Some(r) = bad else { return Ok(()) };
    let m = r.element.coupling.len();
    Err(match how {
        Couplings::First => {
            crate::Error::invalid(path, "coupling", format!("the springs act on {m} joints but the design has {n}"))
        }
        Couplings::Any => crate::Error::invalid(
            path,
            "coupling",
            format!("{}: the springs act on {m} joints but the design has {n}", r.id),
        ),
        Couplings::Line2 => crate::Error::invalid(
            path,
            "line 2: coupling",
            format!("has {m} entries but the design's robot has {n} joints"),
        ),
    })
}

/// Refuses a bill read from `path` whose springs do not hold the design's equilibrium: the
/// torque |∇U(q_eq)| of its springs and gravity, over the design's stiffness ‖ω²M(q_eq)‖ (an
/// angle in rad: about how far the springs would move the arm from q_eq), above `[equilibrium]
/// bill_tolerance`. Every command that reads a bill runs it after [`check_couplings`]: a bill
/// that does not hold q_eq gives a simulation of another arm and an identification whose rates
/// absorb the miss with small standard errors, so it is refused, not warned about.
pub fn check_equilibrium(
    design: &crate::design::Design,
    path: &std::path::Path,
    rows: &[crate::fit::bill::BomRow],
) -> crate::Result<()> {
    let q = design.q_eq.as_slice();
    let mut springs = vec![0.0; q.len()];
    crate::fit::bill::spring_set(rows).gradient_into(q, &mut springs);
    let mut gravity = vec![0.0; q.len()];
    design.chain.gravity_gradient_into(q, &mut gravity);
    let torque = springs.iter().zip(&gravity).map(|(s, g)| (s + g) * (s + g)).sum::<f64>().sqrt();
    let stiffness = design.chain.mass_matrix(&design.q_eq).norm() * design.fit.frequency.powi(2);
    let miss = torque / stiffness.max(f64::MIN_POSITIVE);
    let tolerance = design.bill_tolerance;
    if miss.is_finite() && miss <= tolerance {
        return Ok(());
    }
    Err(crate::Error::invalid(
        path,
        "offset_rad",
        format!(
            "the bill's springs do not hold the equilibrium of {}: |∇U(q_eq)| = {torque:.3e} N·m with gravity, {miss:.2e} \
             rad at the design's stiffness ‖ω²M(q_eq)‖ = {stiffness:.3e} N·m/rad, above equilibrium.bill_tolerance = \
             {tolerance:e} rad. Typically an offset typed in degrees (offset_rad is in radians), the bill of another \
             design, or a design changed since the fit: refit, or raise equilibrium.bill_tolerance in the design",
            design.path.display()
        ),
    ))
}

/// How a command checks a bill's couplings against the design (see [`check_couplings`]): the
/// wordings users and tests know.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Couplings {
    /// The first row, `coupling`: "the springs act on m joints but the design has n" (`simulate`).
    First,
    /// Every row, `coupling`: "`<id>`: the springs act on …" (`export`).
    Any,
    /// The first row, `line 2: coupling`: "has m entries but the design's robot has n joints"
    /// (`parts`, `tune`).
    Line2,
}
