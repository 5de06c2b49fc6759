//! Advice attached to results and errors: which design key to change, and why.
//!
//! An infeasible fit names the constraint group that fails (see `fit::qp`); this module adds what
//! a designer can do about it, derived from the design and the catalogue (an off-diagonal of M
//! that no element can match, a spring budget below the number of conditions).

use crate::design::Design;
use crate::design::fit::FitSettings;
use crate::elements::catalog::Catalog;
use crate::error::Error;
use crate::fit::outcome::Evaluation;
use crate::geodesic::region::RegionReport;

/// The advice for an infeasible fit, or `None` for other errors.
///
/// `budget` is the spring budget the fit ran with (0: none).
pub fn infeasible_hint(
    design: &Design,
    settings: &FitSettings,
    catalog: &Catalog,
    budget: usize,
    constraint: &str,
) -> String {
    let n = design.dof();
    let mut hints = Vec::new();
    let hessian = constraint.contains("Hessian match") || constraint.contains("constraints together");
    if settings.hessian_match && hessian {
        let m = design.chain.mass_matrix(&design.q_eq);
        let scale = m.amax();
        let off: Vec<String> = (0..n)
            .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
            .filter(|&(i, j)| m[(i, j)].abs() > 1e-9 * scale)
            .map(|(i, j)| format!("M{}{} = {:.4}", i + 1, j + 1, m[(i, j)]))
            .collect();
        let coupled =
            catalog.families.iter().any(|f| f.couplings.iter().any(|a| a.iter().filter(|x| **x != 0.0).count() > 1));
        let conditions = n * (n + 1) / 2;
        if !off.is_empty() && !coupled {
            hints.push(format!(
                "the off-diagonal of M(q_eq) ({}) can only be matched by elements that couple joints, and catalogue `{}` \
                 has none: add a family with couplings = {{ pairs = [[1, 1], [1, -1]] }}, or set `fit.hessian_match = false` \
                 (then only the trace normalisation is required)",
                off.join(", "),
                catalog.name
            ));
        } else if budget > 0 && budget < conditions {
            hints.push(format!(
                "matching ∇²U(q_eq) = ω² M(q_eq) fixes {conditions} entries for {n} joints, which {budget} springs generally cannot: \
                 allow more springs (`fit.max_elements`) or set `fit.hessian_match = false`"
            ));
        } else {
            hints.push(
                "set `fit.hessian_match = false` (then only the trace normalisation is required) or widen the catalogue"
                    .to_string(),
            );
        }
    }
    if constraint.contains("monotonicity") {
        hints.push("set `fit.monotone = false`".into());
    }
    if constraint.contains("max_stiffness") {
        hints.push("raise the families' `max_stiffness` in the catalogue".into());
    }
    if constraint.contains("equilibrium gradient") && design.chain.has_gravity() {
        hints.push(
            "the springs must also hold the arm against gravity at q_eq: offer families with offsets away from the \
             equilibrium (offsets = { grid = N }) so they can be preloaded"
                .into(),
        );
    }
    hints.join("; ")
}

/// Share of the largest valid radius from which a poor fit's advice puts the region first.
///
/// r² (the exact potential's) is singular at the conjugate point or crossing that sets the
/// largest valid radius, and every finite family of smooth potentials falls behind as the region
/// nears it. On the five-link pendulum (largest valid radius 0.526) the polynomials of degree 6
/// and its catalogue reach p99 0.51° / 0.75° at 57 % of it, 1.76° / 2.07° at 76 % and 6.7° /
/// 6.9° at 99 % (`scripts/radius_limit.py`, BENCHMARKS.md "Whole arms"): from about three
/// quarters on, more springs buy little and a smaller region a lot.
pub const NEAR_LIMIT: f64 = 0.75;

/// What to try after a poor fit, in the order most likely to help: the region first when it
/// reaches [`NEAR_LIMIT`] of a largest valid radius that a conjugate point or a crossing sets
/// (not the check's probe), else more springs, the Hessian match and the catalogue.
pub fn poor_fit_advice(region: &RegionReport) -> String {
    let springs = "allow more springs (fit.max_elements), keep fit.hessian_match = true or widen the catalogue";
    match (near_limit(region), &region.limit) {
        (Some(share), Some(limit)) => format!(
            "the region reaches {:.0} % of its largest valid radius {:.4}, set by {}; next to it no finite set of \
             smooth potentials holds the modes (docs/theory.md, \"The region check\"), so a smaller region \
             (region.radius) helps more than springs; else {springs}",
            100.0 * share,
            region.largest_radius,
            limit.describe()
        ),
        _ => springs.to_string(),
    }
}

/// The share of its largest valid radius that `region` reaches, when that is at least
/// [`NEAR_LIMIT`] and a conjugate point or a crossing (not the check's probe) sets the radius.
pub fn near_limit(region: &RegionReport) -> Option<f64> {
    // A joint limit is a stop of the arm, not a place where the modes themselves degrade: only a
    // conjugate point or crossing geodesics make the fit's error grow towards them.
    let failure = region
        .limited_by
        .iter()
        .chain(region.limit.iter())
        .find(|f| !matches!(f, crate::geodesic::region::RegionFailure::JointLimit { .. }))?;
    let share = region.extent / failure.radius();
    (share >= NEAR_LIMIT).then_some(share)
}

/// [`equality_warning`] for a fit of `design` that `metrics` judged, against the target
/// stiffness ‖ω²M(q_eq)‖.
pub fn fit_equality_warning(design: &Design, settings: &FitSettings, metrics: &Evaluation) -> Option<String> {
    let target = design.chain.mass_matrix(&design.q_eq).norm() * settings.frequency.powi(2);
    equality_warning(settings, metrics.equilibrium_gradient_norm, metrics.hessian_rel_error, target)
}

/// Largest relative miss of the QP's equalities (the equilibrium and, with `hessian_match`, the
/// Hessian) that passes without a warning. Clarabel and the polish hold them to about 1e-14 on
/// every shipped design; over a thousand or more candidates Clarabel has reported "solved" at
/// 1e-4, and a gradient left at q_eq spoils the residual angles next to it.
pub const EQUALITY_WARNING: f64 = 1e-6;

/// A warning when the QP, whose equalities should hold to round-off, missed them: the
/// equilibrium gradient relative to the target stiffness ‖ω²M(q_eq)‖ times one radian, and the
/// Hessian's relative error when it was matched. None for NNLS, which weighs its equalities
/// (and fails the fit beyond its own tolerance), and for a fit that holds them.
pub fn equality_warning(
    settings: &FitSettings,
    gradient_norm: f64,
    hessian_rel_error: f64,
    target_norm: f64,
) -> Option<String> {
    if settings.solver != crate::design::fit::SolverKind::Qp {
        return None;
    }
    let gradient = gradient_norm / target_norm.max(f64::MIN_POSITIVE);
    let hessian = if settings.hessian_match { hessian_rel_error } else { 0.0 };
    (gradient > EQUALITY_WARNING || hessian > EQUALITY_WARNING).then(|| {
        format!(
            "the QP missed its equalities (|∇U(q_eq)| = {gradient_norm:.2e} N·m, {gradient:.1e} of ‖ω²M(q_eq)‖·1 rad; Hessian relative error {hessian_rel_error:.2e}; both should be near 1e-14): the residual angles next to q_eq are spoiled. Fewer candidates (a smaller catalogue, or fit.max_elements) keep the QP small enough to hold them"
        )
    })
}

/// Warnings about a fitted bill of materials: a stiffness above the largest stock rate of its
/// family (snapping to stock will cap it and the residual grows) or above its `max_stiffness`
/// (the solvers enforce it as a bound, so this only flags a bound met to rounding).
pub fn bom_warnings(catalog: &Catalog, rows: &[crate::fit::bill::BomRow]) -> Vec<String> {
    let mut out = Vec::new();
    for r in rows {
        let Some(f) = catalog.families.iter().find(|f| f.name == r.family) else { continue };
        let unit = r.element.profile.unit();
        if let Some(top) = f.stock_rates.iter().copied().reduce(f64::max)
            && r.stiffness > top * (1.0 + 1e-9)
        {
            out.push(format!(
                    "{}: field `family` `{}`: {} has fitted stiffness {:.4} {unit}, above the family's largest stock rate {top} {unit}: snapping to stock rates (sweep) caps it at {top} and the residual grows; add larger stock rates or set max_stiffness = {top} so the fit stays within them",
                    catalog.path.display(),
                    f.name,
                    r.id,
                    r.stiffness
                ));
        }
        if let Some(max) = f.max_stiffness
            && r.stiffness > max * (1.0 + 1e-6)
        {
            out.push(format!(
                "{}: field `family` `{}`: {} has fitted stiffness {:.4} {unit}, above max_stiffness = {max} {unit}",
                catalog.path.display(),
                f.name,
                r.id,
                r.stiffness
            ));
        }
    }
    out
}

/// `e` with [`infeasible_hint`] appended to its reason when it is an infeasible fit.
pub fn explain(design: &Design, settings: &FitSettings, catalog: &Catalog, budget: usize, e: Error) -> Error {
    match e {
        Error::Infeasible { constraint, reason } => {
            let hint = infeasible_hint(design, settings, catalog, budget, &constraint);
            let reason = if hint.is_empty() { reason } else { format!("{reason}; to fix: {hint}") };
            Error::Infeasible { constraint, reason }
        }
        other => other,
    }
}

/// The text of an infeasible fit with its advice (see [`explain`]).
pub fn explain_infeasible(
    design: &Design,
    settings: &FitSettings,
    catalog: &Catalog,
    budget: usize,
    e: Error,
) -> String {
    explain(design, settings, catalog, budget, e).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::fit::SolverKind;

    /// The QP's equalities: round-off passes, the misses Clarabel reported as solved on the
    /// unlimited six-joint UR5 fits (gradient 1.9e-3 N·m against ‖ω²M‖ ≈ 60 N·m/rad, Hessian 1.9e-4)
    /// warn, and NNLS, whose equalities are weighted, never does.
    #[test]
    fn a_qp_that_misses_its_equalities_is_named() {
        let qp = FitSettings { solver: SolverKind::Qp, hessian_match: true, ..FitSettings::default() };
        assert_eq!(equality_warning(&qp, 2e-13, 5e-15, 60.0), None);
        let w = equality_warning(&qp, 1.9e-3, 5e-14, 60.0).expect("a gradient of 3e-5 relative warns");
        assert!(w.contains("1.90e-3 N·m") && w.contains("3.2e-5"), "{w}");
        assert!(equality_warning(&qp, 1e-13, 1.9e-4, 60.0).is_some());
        let loose = FitSettings { hessian_match: false, ..qp };
        assert_eq!(equality_warning(&loose, 1e-13, 1.9e-4, 60.0), None, "no Hessian equality without hessian_match");
        let nnls = FitSettings { solver: SolverKind::Nnls, ..qp };
        assert_eq!(equality_warning(&nnls, 1e-2, 1e-3, 60.0), None);
    }

    /// A poor fit's advice names the region when it nears a conjugate limit (the five-link
    /// pendulum's ball 0.52 of 0.5257), and not when it sits well inside one or when nothing
    /// failed up to the probe (then the largest radius is only a lower bound).
    #[test]
    fn a_poor_fit_next_to_the_conjugate_limit_is_told_to_shrink_the_region() {
        let report = |extent: f64, largest: f64, lower_bound: bool| RegionReport {
            valid: true,
            region: format!("geodesic ball of radius {extent}"),
            extent,
            largest_radius: largest,
            largest_radius_is_lower_bound: lower_bound,
            probe_radius: 2.0 * extent,
            limit: (!lower_bound).then(|| crate::geodesic::region::RegionFailure::Conjugate {
                s: largest,
                q: vec![0.0; 5],
                direction: 514,
            }),
            failure: None,
            limited_by: Vec::new(),
            reason: String::new(),
        };
        let near = poor_fit_advice(&report(0.52, 0.5257, false));
        assert!(near.contains("99 % of its largest valid radius 0.5257") && near.contains("region.radius"), "{near}");
        assert!(near.contains("conjugate point"), "{near}");
        for inside in [report(0.3, 0.5257, false), report(0.52, 1.04, true)] {
            let advice = poor_fit_advice(&inside);
            assert!(!advice.contains("region.radius") && advice.contains("fit.max_elements"), "{advice}");
        }
    }
}
