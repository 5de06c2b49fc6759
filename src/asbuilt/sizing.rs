//! Trim ranges sized by the bill: the rates the builds' trims need, once the fit has chosen its
//! springs.
//!
//! A trim family's range written before the fit (`springfit init` writes TRIM_SHARE·ω²/(aᵀM⁻¹a)
//! at q_eq) cannot know what the builds will need: that is set by the bill. A build scales
//! spring j by 1 + δⱼ; its trims are then clamped so the arm rests at q_eq again and their rates
//! set by the residual rows of the trim fan from q_eq ([`super::clamp_at_design`]). There the
//! rows are linear in everything: with C the trims' unit rows, R the other springs' unit rows,
//! g their unit gradients at q_eq, A the trims' couplings and P the rows of a unit preload on
//! each trim, a build's rows without the trims are
//!
//! r₀(δ) = r_nom + (R − P A⁺ G) diag(k) δ − P A⁺ g_nom,
//!
//! (the preloads Σ pᵢaᵢ = −g put the equilibrium back at q_eq; their rows depend only on that
//! sum) and the rates its trims need, ranges aside, are k_t(δ) = −C⁺ r₀(δ). The same draws as the
//! as-built builds ([`super::draw`]) give each trim's needed rate on every build, exactly for that
//! rule and at the cost of a few matrix products per build. A range that holds [`COVER`] of them
//! (the quantiles (1 ∓ COVER)/2) and keeps the fit's rate inside is the trim's sized range; a
//! trim whose builds need it softer than a spring can be (below 0 N·m/rad about the fit's rate)
//! gets a higher rate, so that the fit, solved again around it, leaves it room both ways.
//!
//! On `panda_three` (joints 2, 4, 6, `mass_weight = 0.001`) the springs carrying the wrist have
//! 32 N·m/rad gross on joint 6 against ω²M₆₆ = 4.4: at ±5 % the builds need the joint-6 trim
//! set up to 4.6× the half-range the ω²M rule gives it, while on the UR10 the same rule's ranges
//! are wider than needed. A range by ω²M alone is too narrow on one arm and too wide on the other.

use nalgebra::{DMatrix, DVector};

use super::{BuildSettings, draw, relaxed_trims, rows_without_trims, trim_fan, without};
use crate::design::Design;
use crate::error::{Error, Result};
use crate::fit::bill::BomRow;
use crate::fit::outcome::{SizedTrim, TrimSizing};
use crate::potential::{Potential, SpringSet};

/// The share of builds whose needed rate a sized range holds, each trim on its own (the rates
/// between the (1 − COVER)/2 and (1 + COVER)/2 quantiles over the builds).
pub const COVER: f64 = 0.99;

/// How much of the trimmed builds' rows (mean square, on the trim fan from q_eq) the sizing may
/// give up for smaller ranges: the weakest directions of the trims' changes are not sized for
/// while what they would take off stays within this share of what every trim left free leaves.
/// A guard against directions the rows hardly see; measured on the UR10 with the 12-direction
/// trim fan it dropped none (the shoulder trim still sized to 0–310 N·m/rad): what brought the
/// ranges down there was the trim fan of [`super::trim_directions`] (0–110 N·m/rad).
pub const SHARE: f64 = 0.01;

/// Each trim's needed rates over the builds `s` draws of the bill `bom` (its spring set
/// `springs`): per trim row of the bill (in bill order), the rate the residual rule clamped at
/// q_eq sets on each build, ranges ignored, but for the directions of the trims' changes that
/// matter least: with `share` = 0 exactly the rates [`super::clamp_at_design`] sets given ranges
/// that never bind. The rows' least squares over the trims is solved by SVD of their unit rows
/// (each trim's change in units of the target stiffness along its coupling, ω²/(aᵀM⁻¹a) at
/// q_eq); its weakest directions are left at the fitted rates while the mean square they would
/// take off the builds' rows stays within `share` of the mean square every trim left free leaves
/// ([`SHARE`]). Err when the trims cannot carry the preload a build
/// needs at q_eq (their couplings span no joint some spring turns) or the rows are not finite.
pub fn needed_rates(
    design: &Design,
    bom: &[BomRow],
    springs: &SpringSet,
    s: &BuildSettings,
    share: f64,
) -> Result<Vec<Vec<f64>>> {
    let trims: Vec<usize> = (0..bom.len()).filter(|&j| bom[j].adjust.trim_range.is_some()).collect();
    let others: Vec<usize> = (0..bom.len()).filter(|j| !trims.contains(j)).collect();
    if trims.is_empty() {
        return Ok(Vec::new());
    }
    let q_eq = &design.q_eq;
    let q = q_eq.as_slice();
    let n = design.dof();
    let fan = trim_fan(design, q_eq)?;
    let frame = crate::fit::robust::RowFrame::new(&design.chain, &fan, design.fit.frequency);
    // The trims relaxed at q_eq (as the bill writes them), their unit rows, and a unit preload's.
    let (relaxed, c, unit_preload) = relaxed_trims(&frame, springs, &trims, q);
    let a = DMatrix::from_fn(n, trims.len(), |i, t| relaxed.elements[trims[t]].coupling[i]);
    let numerical = |what: &str| Error::numerical("trim sizing", what);
    let a_pinv = a.clone().pseudo_inverse(1e-12).map_err(|_| numerical("the trims' couplings"))?;
    if (&a * &a_pinv - DMatrix::identity(n, n)).amax() > 1e-9 {
        return Err(numerical(
            "the trims' couplings turn fewer joints than the arm has: no preload puts a build back at q_eq",
        ));
    }
    // The nominal rows and gradient of everything but the trims, gravity included, and the
    // trims at their fitted rates.
    let rest = without(&relaxed, &trims);
    let g_nom = rest.gradient(q)? + design.chain.gravity_gradient(q);
    let fitted = DVector::from_iterator(trims.len(), trims.iter().map(|&j| relaxed.stiffness[j]));
    let to_preload = &unit_preload * &a_pinv;
    let base = rows_without_trims(&frame, &relaxed, &trims) - &to_preload * &g_nom + &c * &fitted;
    // Per other spring at its fitted rate: its rows and, through the preload it leaves at q_eq,
    // the trims' preloads' rows.
    let rows = frame.columns(others.iter().map(|&j| &relaxed.elements[j]));
    let mut grads = DMatrix::zeros(n, others.len());
    for (o, &j) in others.iter().enumerate() {
        grads.set_column(o, &relaxed.elements[j].gradient(q));
    }
    let k = DMatrix::from_diagonal(&DVector::from_iterator(others.len(), others.iter().map(|&j| relaxed.stiffness[j])));
    let per_delta = (rows - &to_preload * grads) * k;
    // Each build's rows with the trims at their fitted rates, as columns.
    let mut r = DMatrix::zeros(base.len(), s.builds);
    for b in 0..s.builds {
        let f = draw(bom, s, b);
        let delta = DVector::from_iterator(others.len(), others.iter().map(|&j| f[j] - 1.0));
        r.set_column(b, &(&base + &per_delta * delta));
    }
    // The trims' changes in units of the target stiffness along their couplings,
    // ω²/(aᵀM⁻¹a) at q_eq, so that the directions below compare like with like.
    let m_inv = design.chain.mass_matrix(q_eq).try_inverse().ok_or_else(|| numerical("the mass matrix at q_eq"))?;
    let w2 = design.fit.frequency * design.fit.frequency;
    let scale: Vec<f64> = (0..trims.len()).map(|t| w2 / a.column(t).dot(&(&m_inv * a.column(t)))).collect();
    let scaled = DMatrix::from_fn(c.nrows(), c.ncols(), |i, t| c[(i, t)] * scale[t]);
    let svd = scaled.svd(true, true);
    let (u, v_t) = match (svd.u, svd.v_t) {
        (Some(u), Some(v_t)) => (u, v_t),
        _ => return Err(numerical("the trims' rows")),
    };
    let sigma = svd.singular_values;
    let z = u.transpose() * &r;
    let builds = s.builds.max(1) as f64;
    let gain: Vec<f64> = (0..sigma.len()).map(|i| z.row(i).norm_squared() / builds).collect();
    let left = (r.norm_squared() / builds - gain.iter().sum::<f64>()).max(0.0);
    // Directions of the trims' changes, weakest first, dropped while what they would take off
    // the rows stays within `share` of what every trim left free leaves.
    let mut order: Vec<usize> = (0..sigma.len()).collect();
    order.sort_by(|&x, &y| sigma[x].total_cmp(&sigma[y]));
    let floor = 1e-12 * sigma.max();
    let mut kept = vec![true; sigma.len()];
    let mut dropped = 0.0;
    for &i in &order {
        if sigma[i] <= floor || dropped + gain[i] <= share * left {
            kept[i] = false;
            dropped += gain[i];
        } else {
            break;
        }
    }
    let mut out = vec![Vec::with_capacity(s.builds); trims.len()];
    for b in 0..s.builds {
        let mut x = DVector::zeros(trims.len());
        for i in (0..sigma.len()).filter(|&i| kept[i]) {
            x -= v_t.row(i).transpose() * (z[(i, b)] / sigma[i]);
        }
        for t in 0..trims.len() {
            out[t].push(fitted[t] + scale[t] * x[t]);
        }
    }
    if out.iter().flatten().any(|x| !x.is_finite()) {
        return Err(numerical("the trims' needed rates are not finite"));
    }
    Ok(out)
}

/// The sized range of a trim whose fit placed it at `rate` and whose builds need rates between
/// `needed` = [lo, hi] (the [`COVER`] quantiles): the half-width h covering both sides of
/// `rate`, about `rate` when the range then stays at or above 0 N·m/rad, else about h (a stiffer
/// trim, which the fit is solved around again). The ends are rounded outwards to two
/// significant digits (a range a builder reads).
pub fn sized_range(rate: f64, needed: [f64; 2]) -> [f64; 2] {
    let h = (needed[1] - rate).max(rate - needed[0]).max(1e-6 * rate.abs()).max(f64::MIN_POSITIVE);
    let centre = rate.max(h);
    let lo = centre - h;
    [if lo <= 1e-9 * centre { 0.0 } else { round(lo, f64::floor) }, round(centre + h, f64::ceil)]
}

/// `x` > 0 to two significant digits by `how` (printed and read back, so a file shows 9.2, not
/// 9.200000000000001).
fn round(x: f64, how: fn(f64) -> f64) -> f64 {
    if !(x.is_finite() && x > 0.0) {
        return x;
    }
    let exponent = x.log10().floor() as i32 - 1;
    let step = 10f64.powi(exponent);
    let rounded = how(x / step) * step;
    let decimals = usize::try_from(-exponent).unwrap_or(0);
    format!("{rounded:.decimals$}").parse().unwrap_or(rounded)
}

/// The (1 − [`COVER`])/2 and (1 + COVER)/2 quantiles of `v`.
fn quantiles(v: &[f64]) -> [f64; 2] {
    let mut v: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    [crate::residual::percentile(&v, 50.0 * (1.0 - COVER)), crate::residual::percentile(&v, 50.0 * (1.0 + COVER))]
}

/// Why the trims keep the ranges they started from, when the fit around the sized ranges was
/// not kept (`refit.kept` false; None otherwise): the trim whose builds need the widest change
/// against the target stiffness along its coupling, ω²/(aᵀM⁻¹a) at q_eq. A trim that must
/// soften a build by h needs a rate of at least h to soften from; placed there, it stiffens the
/// drawing by h along its coupling, and where h is more than the target stiffness the other
/// springs, being non-negative, cannot take that back (on the planar three-link arm of
/// `tests/cli_init.rs`: joint 3's trim ±0.77 N·m/rad against a target of 0.26, the fit around
/// the sized ranges 17.4° drawn against 1.56°). The needs grow in proportion to the rate
/// tolerance `tolerance` (a ± fraction, when every spring has the same one): the message then
/// gives the tolerance at which the widest need equals the target stiffness. Measured: at that
/// tolerance the needs were that (planar arm ±1.5 %: ±0.266 against 0.263; `init` on the random
/// arm of seed 61 at ±3 %: ±1.316 against 1.323), but the refit was still refused (6.48° against
/// 1.56° drawn; 5.25° against 2.00°): the room the other springs leave is below the target.
pub fn kept_ranges_reason(design: &Design, sizing: &TrimSizing, tolerance: Option<f64>) -> Option<String> {
    let refit = sizing.refit.filter(|r| !r.kept)?;
    let mut text = format!(
        "the trims keep the ranges the catalogue writes: the fit around the ranges their builds need (trim_sized) reached p99 {:.2}° drawn and {:.2}° realised against the first fit's {:.2}° and {:.2}°, so the builds are trimmed within the ranges written",
        refit.refit_p99_deg[0], refit.refit_p99_deg[1], refit.first_p99_deg[0], refit.first_p99_deg[1]
    );
    let q = &design.q_eq;
    let m_inv = design.chain.mass_matrix(q).try_inverse()?;
    let w2 = design.fit.frequency * design.fit.frequency;
    let widest = sizing
        .trims
        .iter()
        .filter_map(|t| {
            let a = DVector::from_column_slice(&t.coupling);
            let target = w2 / a.dot(&(&m_inv * &a));
            let h = (t.needed[1] - t.fitted_rate).max(t.fitted_rate - t.needed[0]);
            (target.is_finite() && target > 0.0 && h.is_finite()).then_some((t, h, target))
        })
        .max_by(|x, y| (x.1 / x.2).total_cmp(&(y.1 / y.2)));
    if let Some((t, h, target)) = widest {
        let ratio = h / target;
        text += &format!(
            "; the builds need trim {} ({}) between {:.3} and {:.3} N·m/rad about its fitted {:.3} ({}–{} written): a change of ±{:.3}, {:.1}× the target stiffness ω²/(aᵀM⁻¹a) = {:.3} N·m/rad along it",
            t.id,
            t.family,
            t.needed[0],
            t.needed[1],
            t.fitted_rate,
            t.start_range[0],
            t.start_range[1],
            h,
            ratio,
            target
        );
        if ratio > 1.0 {
            text += ", more than the other springs can leave room for (a trim must sit at least that stiff to soften a build by it)";
            if let Some(tol) = tolerance.filter(|t| *t > 0.0) {
                text += &format!(
                    "; the needs grow in proportion to the rate tolerance: at about ±{:.1} % (now ±{:.1} %) the widest would equal the target stiffness (a bound: the fit around the ranges may need less), and a higher fit.frequency raises the target (with ω²)",
                    100.0 * tol / ratio,
                    100.0 * tol
                );
            }
        }
    }
    Some(text)
}

/// A trim family as the sizing sees it: its name, its range and whether it is sized by the bill.
pub type TrimFamily<'a> = (&'a str, [f64; 2], bool);

/// The sizing of the trim families `families` marks sized (the others keep their range): each
/// such family's range is the envelope of its trims' sized ranges ([`sized_range`] of the rates
/// [`needed_rates`] finds). Returns the record and each family's range after sizing, in the
/// order of `families`.
pub fn size(
    design: &Design,
    bom: &[BomRow],
    springs: &SpringSet,
    s: &BuildSettings,
    families: &[TrimFamily<'_>],
) -> Result<(TrimSizing, Vec<[f64; 2]>)> {
    let needed = needed_rates(design, bom, springs, s, SHARE)?;
    let trims: Vec<&BomRow> = bom.iter().filter(|r| r.adjust.trim_range.is_some()).collect();
    let mut ranges: Vec<Option<[f64; 2]>> = vec![None; families.len()];
    let mut found = Vec::new();
    for (row, need) in trims.iter().zip(&needed) {
        let Some(f) = families.iter().position(|(name, _, _)| *name == row.family) else { continue };
        let need = quantiles(need);
        if families[f].2 {
            let r = sized_range(row.stiffness, need);
            ranges[f] = Some(ranges[f].map_or(r, |[lo, hi]| [lo.min(r[0]), hi.max(r[1])]));
        }
        found.push((row, f, need));
    }
    let ranges: Vec<[f64; 2]> = ranges.iter().zip(families).map(|(r, f)| r.unwrap_or(f.1)).collect();
    let trims = found
        .into_iter()
        .map(|(row, f, needed)| SizedTrim {
            id: row.id.clone(),
            family: row.family.clone(),
            coupling: row.element.coupling.clone(),
            fitted_rate: row.stiffness,
            start_range: families[f].1,
            needed,
            range: ranges[f],
            sized: families[f].2,
        })
        .collect();
    Ok((TrimSizing { cover: COVER, builds: s.builds, trims, refitted: false, refit: None }, ranges))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::outcome::RefitComparison;

    /// A sizing record on the default design's arm: trim `S1` on joint 1 and `S2` on joint 2,
    /// each fitted at 0.1·target and needing `down` target stiffnesses below and `up` above it.
    fn record(design: &Design, needs: [[f64; 2]; 2], kept: bool) -> (TrimSizing, [f64; 2]) {
        let m_inv = design.chain.mass_matrix(&design.q_eq).try_inverse().unwrap();
        let w2 = design.fit.frequency * design.fit.frequency;
        let target = [0, 1].map(|i| w2 / m_inv[(i, i)]);
        let trims = (0..2)
            .map(|i| {
                let rate = 0.1 * target[i];
                let mut coupling = vec![0.0, 0.0];
                coupling[i] = 1.0;
                SizedTrim {
                    id: format!("S{}", i + 1),
                    family: format!("trim on joint {}", i + 1),
                    coupling,
                    fitted_rate: rate,
                    start_range: [0.0, 2.0 * rate],
                    needed: [rate - needs[i][0] * target[i], rate + needs[i][1] * target[i]],
                    range: [0.0, 2.0 * rate],
                    sized: true,
                }
            })
            .collect();
        let refit = RefitComparison { first_p99_deg: [1.5, 1.8], refit_p99_deg: [17.4, 16.2], kept };
        (TrimSizing { cover: COVER, builds: 1000, trims, refitted: kept, refit: Some(refit) }, target)
    }

    #[test]
    fn a_refused_refit_names_the_trim_whose_builds_need_most_against_the_target_stiffness() {
        let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"));
        let design = Design::load(&root.join("designs/double_pendulum.toml")).unwrap();
        // Joint 1's trim needs half its target, joint 2's three times it (downwards).
        let (sizing, target) = record(&design, [[0.5, 0.2], [3.0, 1.0]], false);
        let text = kept_ranges_reason(&design, &sizing, Some(0.05)).unwrap();
        assert!(text.contains("p99 17.40° drawn"), "{text}");
        assert!(text.contains("trim S2 (trim on joint 2)"), "{text}");
        assert!(text.contains(&format!("±{:.3}, 3.0× the target stiffness", 3.0 * target[1])), "{text}");
        assert!(text.contains(&format!("= {:.3} N·m/rad", target[1])), "{text}");
        // Needs in proportion to the tolerance: ±5 % / 3.
        assert!(text.contains("about ±1.7 % (now ±5.0 %)"), "{text}");
        // Both within their targets: the figures, no claim the springs cannot make room.
        let (sizing, _) = record(&design, [[0.5, 0.2], [0.3, 0.9]], false);
        let text = kept_ranges_reason(&design, &sizing, Some(0.05)).unwrap();
        assert!(text.contains("trim S2") && text.contains("0.9× the target"), "{text}");
        assert!(!text.contains("leave room") && !text.contains("about ±"), "{text}");
        // A kept refit needs no reason.
        let (sizing, _) = record(&design, [[0.5, 0.2], [3.0, 1.0]], true);
        assert_eq!(kept_ranges_reason(&design, &sizing, Some(0.05)), None);
    }
}
