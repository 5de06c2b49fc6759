//! What an element's part must carry and meet: its deflections over the region and the
//! scenarios' swings ([`Duty`], read off the span of its coupling) and the `[parts]` settings
//! resolved for it ([`Requirements`]). `springfit parts` (`parts::choose`) and the fit's mass
//! model (`fit::mass`) both size parts from these, so the mass the fit weighs is that of the part
//! the bill gets.

use rayon::prelude::*;

use super::material::by_key;
use super::mechanism::{Duty, Requirements, StopMechanism, TrimMechanism, Wires};
use super::spring::Surface;
use crate::design::Design;
use crate::design::parts::PartsSettings;
use crate::elements::Element;
use crate::geodesic::Fan;

/// The springs' surface `[parts] shot_peened` asks for.
pub fn surface(s: &PartsSettings) -> Surface {
    if s.shot_peened { Surface::Peened } else { Surface::AsWound }
}

/// The requirements of element `id` from `[parts]` (its `[[parts.element]]` overrides).
pub fn requirements(s: &PartsSettings, id: &str) -> Requirements {
    let over = s.element.iter().find(|e| e.id == id);
    let wires: Vec<_> =
        s.material_keys().into_iter().map(|k| by_key(k).expect("validated: a material of the table")).collect();
    let (first, rest) = wires.split_first().expect("validated: at least one wire");
    Requirements {
        material: first,
        also: Wires::new(rest).expect("validated: each wire once"),
        grade: s.grade,
        cycles: s.cycles,
        safety: s.safety_factor,
        surface: surface(s),
        max_outer_diameter: over.and_then(|e| e.max_outer_diameter_mm).unwrap_or(s.max_outer_diameter_mm),
        max_length: over.and_then(|e| e.max_length_mm).unwrap_or(s.max_length_mm),
        max_lever: over.and_then(|e| e.max_lever_mm).unwrap_or(s.max_lever_mm),
        shaft_diameter: s.shaft_diameter_mm,
        pulley_radius: s.pulley_radius_mm,
        stop: match s.stop_mechanism.as_str() {
            "torsion" => StopMechanism::Torsion,
            "drum" => StopMechanism::Drum,
            _ => StopMechanism::Lightest,
        },
        trim: match s.trim_mechanism.as_str() {
            "leaf" => TrimMechanism::Leaf,
            "crank" => TrimMechanism::Crank,
            _ => TrimMechanism::Lightest,
        },
        roller_departure: None,
    }
}

/// The largest energy any scenario of the design starts from or aims at, J (None without
/// scenarios): the swing fatigue is judged at.
pub fn scenario_energy(design: &Design) -> Option<f64> {
    use crate::design::scenario::EnergySpec;
    let mut e: Option<f64> = None;
    let mut see = |v: f64| e = Some(e.map_or(v, |m: f64| m.max(v)));
    for s in &design.scenarios {
        s.releases.iter().for_each(|r| see(r.energy));
        s.energy.into_iter().chain(s.e0).for_each(&mut see);
        match &s.ed {
            Some(EnergySpec::Value(v)) => see(*v),
            Some(EnergySpec::Steps(steps)) => steps.iter().for_each(|st| see(st[1])),
            None => {}
        }
    }
    e
}

/// The largest scenario energy (J, None without scenarios) and the arc length from q_eq its swing
/// reaches on `fan` at `frequency`: √(2E)/ω, at most the fan's longest geodesic (the whole
/// region without scenarios). Fatigue is judged over the swing.
pub fn swing(design: &Design, fan: &Fan, frequency: f64) -> (Option<f64>, f64) {
    let energy = scenario_energy(design);
    let extent = fan.geodesics.iter().map(|g| g.length()).fold(0.0, f64::max);
    (energy, energy.map_or(extent, |e| ((2.0 * e).sqrt() / frequency).min(extent)))
}

/// a·q of one coupling a: at q_eq, its extremes over the fan, and over the samples within the
/// swing's arc length. The elements on a coupling (a crank's phases, a grid of offsets) share
/// them: every deflection a·q − x₀ is read off by subtracting the element's x₀.
pub struct Span {
    coupling: Vec<f64>,
    at_eq: f64,
    range: [f64; 2],
    swing: [f64; 2],
}

impl Span {
    /// The span of `coupling` on `fan`, its swing over the samples within arc length `swing`.
    pub fn new(coupling: &[f64], q_eq: &[f64], fan: &Fan, swing: f64) -> Span {
        // a·q term for term, as `Element::deflection` sums it.
        let at = |q: &[f64]| coupling.iter().zip(q).map(|(a, q)| a * q).sum::<f64>();
        let (mut range, mut sw) = ([f64::INFINITY, f64::NEG_INFINITY], [f64::INFINITY, f64::NEG_INFINITY]);
        for g in &fan.geodesics {
            for i in 0..g.len() {
                let x = at(g.q(i));
                range = [range[0].min(x), range[1].max(x)];
                if g.s(i) <= swing {
                    sw = [sw[0].min(x), sw[1].max(x)];
                }
            }
        }
        Span { coupling: coupling.to_vec(), at_eq: at(q_eq), range, swing: sw }
    }

    /// The deflections of an element on this coupling with offset `x0`. Subtracting x₀ rounds
    /// monotonically, so the extremes are the bits the samples' own deflections would give.
    pub fn duty(&self, x0: f64) -> Duty {
        let at_eq = self.at_eq - x0;
        let span = |[lo, hi]: [f64; 2]| [at_eq.min(lo - x0), at_eq.max(hi - x0)];
        Duty { at_eq, range: span(self.range), swing: span(self.swing) }
    }
}

/// The spans of every distinct coupling in `couplings`, in parallel (their order of first
/// appearance).
pub fn spans<'a>(couplings: impl Iterator<Item = &'a [f64]>, q_eq: &[f64], fan: &Fan, swing: f64) -> Vec<Span> {
    let mut distinct: Vec<&[f64]> = Vec::new();
    for a in couplings {
        if !distinct.contains(&a) {
            distinct.push(a);
        }
    }
    distinct.par_iter().map(|a| Span::new(a, q_eq, fan, swing)).collect()
}

/// The duty of `e` from the spans of its coupling.
pub fn duty(spans: &[Span], e: &Element) -> Duty {
    spans.iter().find(|s| s.coupling == e.coupling).expect("a span for every coupling").duty(e.offset)
}

#[cfg(test)]
mod tests {
    use nalgebra::DVector;

    use super::*;
    use crate::elements::Profile;

    /// The duty read off a coupling's span is, bit for bit, the extremes of the deflections of
    /// the element's own samples, for several offsets on one coupling and a swing that cuts the
    /// geodesics part-way.
    #[test]
    fn a_span_gives_each_element_its_deflections() {
        use crate::geodesic::{FanSpec, Stop};
        use crate::model::Chain;
        use crate::numerics::ode::OdeSettings;
        let chain = Chain::paper_double_pendulum();
        let q_eq = DVector::from_vec(vec![0.0, std::f64::consts::FRAC_PI_2]);
        let spec = FanSpec { count: 12, phase: 0.1, stop: Stop::Arc(1.5), spacing: 0.1 };
        let fan = Fan::trace(&chain, &q_eq, spec, OdeSettings::default()).unwrap();
        let coupling = vec![1.0, -2.0];
        let spans = spans([&coupling[..]].into_iter(), q_eq.as_slice(), &fan, 0.7);
        assert_eq!(spans.len(), 1);
        for offset in [-0.3, 0.0, 0.37, 1.9] {
            let e = Element { profile: Profile::Linear, coupling: coupling.clone(), offset };
            let at_eq = e.deflection(q_eq.as_slice());
            let (mut range, mut swing) = ([at_eq, at_eq], [at_eq, at_eq]);
            for g in &fan.geodesics {
                for i in 0..g.len() {
                    let d = e.deflection(g.q(i));
                    range = [range[0].min(d), range[1].max(d)];
                    if g.s(i) <= 0.7 {
                        swing = [swing[0].min(d), swing[1].max(d)];
                    }
                }
            }
            assert!(swing[1] - swing[0] < range[1] - range[0], "the swing cuts the fan");
            assert_eq!(duty(&spans, &e), Duty { at_eq, range, swing });
        }
    }
}
