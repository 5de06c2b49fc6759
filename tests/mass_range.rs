//! The mass model against the part chooser over the stiffness range the fits use (issue 44): for
//! every spring candidate of the default design (no cams or cubic elements, whose followers
//! `tests/mass.rs` compares), the model's mass mᵢ(k) against the mass of the part the chooser
//! sizes at k = k_ref·{¼, 1, 4, 16} (k_ref the model's reference stiffness, a peak torque of a
//! quarter of the boundary torque 2U*/r), where the part exists.

mod util;

use springfit::elements::Profile;
use springfit::elements::catalog::Candidate;
use springfit::fit::mass::MassModel;
use springfit::fit::prepare::fans;
use springfit::realise::duty::{duty, requirements, spans, swing};
use springfit::realise::mechanism::spring_element;
use util::shipped;

/// The multiples of k_ref compared.
const MULTIPLES: [f64; 4] = [0.25, 1.0, 4.0, 16.0];

/// The default design's spring candidates, per multiple of k_ref: the median, lowest and highest
/// ratio of the model's mass to the part's, and the model's total over the parts' total.
/// Printed for the curve through k_ref and 4·k_ref (before) and the relative fit over k_ref,
/// 4·k_ref and 16·k_ref (now); measured (one thread, load 12–15, 290 s) with the fit: 408
/// candidates, medians 0.981 / 0.995 / 1.003 / 1.000 at ¼ / 1 / 4 / 16·k_ref, every part within
/// 0.82–1.24 from k_ref up; the curve through two reads 0.36–1.64 at 16·k_ref (36 of 297 outside
/// 0.8–1.25). docs/parts.md, "The mass model". Held: the medians from k_ref up within 15 %.
#[test]
#[ignore = "four part searches for each of some hundred candidates, and the model's own: minutes of CPU"]
fn the_mass_model_holds_over_the_range_the_fits_use() {
    let (design, catalog) = shipped("double_pendulum");
    let settings = design.fit;
    let (_, _, evaluation) = fans(&design, &settings).unwrap();
    let q_eq = design.q_eq.as_slice();
    let range = |a: &[f64]| {
        let at = |q: &[f64]| a.iter().zip(q).map(|(a, q)| a * q).sum::<f64>();
        let mut lo_hi = (at(q_eq), at(q_eq));
        for g in &evaluation.geodesics {
            for i in 0..g.len() {
                let x = at(g.q(i));
                lo_hi = (lo_hi.0.min(x), lo_hi.1.max(x));
            }
        }
        lo_hi
    };
    let candidates: Vec<Candidate> = catalog
        .expand(q_eq, range)
        .into_iter()
        .filter(|c| !matches!(c.element.profile, Profile::Spline(_) | Profile::Cubic))
        .collect();
    let model = MassModel::new(&design, &candidates, &evaluation, settings.frequency);
    let (_, radius) = swing(&design, &evaluation, settings.frequency);
    let spans = spans(candidates.iter().map(|c| &c.element.coupling[..]), q_eq, &evaluation, radius);
    let req = requirements(&design.parts, "");
    let extent = evaluation.geodesics.iter().map(|g| g.length()).fold(0.0, f64::max);
    let torque = 0.25 * 2.0 * model.floor.energy / extent;
    // Per multiple: (model, part) of every candidate with a part there.
    let mut pairs: Vec<Vec<(f64, f64)>> = vec![Vec::new(); MULTIPLES.len()];
    let mut olds = pairs.clone();
    for (i, c) in candidates.iter().enumerate() {
        if !model.from_parts[i] {
            continue;
        }
        let d = duty(&spans, &c.element);
        let slope = (0..=200)
            .map(|s| d.range[0] + (d.range[1] - d.range[0]) * f64::from(s) / 200.0)
            .map(|x| c.element.profile.slope(x).abs())
            .fold(0.0, f64::max);
        let mut k_ref = torque / slope.max(1e-9);
        for _ in 0..=8 {
            if spring_element(c.element.profile, k_ref, &d, &req).is_ok() {
                break;
            }
            k_ref *= 0.5;
        }
        let mass = |k: f64| spring_element(c.element.profile, k, &d, &req).ok().map(|p| p.mass);
        // The curve before the third read: through k_ref and 4·k_ref (2·k_ref where 4× has none).
        let first = mass(k_ref).map(|m| (k_ref, m));
        let larger = [4.0, 2.0].iter().find_map(|&f| mass(f * k_ref).map(|m| (f * k_ref, m)));
        let before = first.map(|p| two_point_curve(p, larger));
        for ((slot, old), f) in pairs.iter_mut().zip(olds.iter_mut()).zip(MULTIPLES) {
            if let Some(part) = mass(f * k_ref) {
                slot.push((model.mass_at(i, f * k_ref), part));
                if let Some((a, b)) = before {
                    let k = f * k_ref;
                    old.push((a * k + b * k * k, part));
                }
            }
        }
    }
    eprintln!("{} spring candidates", candidates.len());
    for (name, table) in [("two reads (before)", &olds), ("three reads (now)", &pairs)] {
        eprintln!("{name}:");
        for (f, slot) in MULTIPLES.iter().zip(table) {
            let Some(median) = summary(*f, slot) else { continue };
            // Where the fits go (k_ref to 16·k_ref) the model reads its parts: the median within 15 %.
            if *f >= 1.0 && std::ptr::eq(table, &pairs) {
                assert!((0.85..1.15).contains(&median), "{f}·k_ref: median {median}");
            }
        }
    }
}

/// Prints one multiple's (model, part) pairs: the median, range and 10th–90th percentile of
/// model/part, how many within 0.8–1.25, and the totals; returns the median (None: no parts).
fn summary(f: f64, slot: &[(f64, f64)]) -> Option<f64> {
    let mut ratios: Vec<f64> = slot.iter().map(|p| p.0 / p.1).collect();
    ratios.sort_by(f64::total_cmp);
    let n = ratios.len();
    if n == 0 {
        eprintln!("{f}·k_ref: no parts");
        return None;
    }
    let (by_model, by_parts) = slot.iter().fold((0.0, 0.0), |s, p| (s.0 + p.0, s.1 + p.1));
    let within = ratios.iter().filter(|r| (0.8..1.25).contains(*r)).count();
    eprintln!(
        "{f}·k_ref: {n} parts, model/part median {:.3}, range {:.3}–{:.3}, 10th–90th {:.3}–{:.3}, {within} within 0.8–1.25, totals {by_model:.2} kg / {by_parts:.2} kg = {:.3}",
        ratios[n / 2],
        ratios[0],
        ratios[n - 1],
        ratios[n / 10],
        ratios[(9 * n) / 10],
        by_model / by_parts
    );
    Some(ratios[n / 2])
}

/// The model's curve before the third read (`fit::mass` until issue 44's range measurement):
/// through the part at k₁ and the larger part at k₂, a straight line through the first where the
/// second is lighter per unit stiffness or missing, through the second alone where the linear
/// part would be negative.
fn two_point_curve((k1, m1): (f64, f64), larger: Option<(f64, f64)>) -> (f64, f64) {
    let Some((k2, m2)) = larger else { return (m1 / k1, 0.0) };
    let b = (m2 / k2 - m1 / k1) / (k2 - k1);
    if b <= 0.0 {
        (m1 / k1, 0.0)
    } else if m1 / k1 - b * k1 < 0.0 {
        (0.0, m2 / (k2 * k2))
    } else {
        (m1 / k1 - b * k1, b)
    }
}
