//! Parts for a fitted bill of materials: every element becomes a mechanism with a spring a maker
//! can wind (or a buyer can order from a stock list), checked for stress, fatigue and fit, and
//! the realised mechanisms are judged like the ideal elements on the held-out geodesics.
//!
//! The stage sits above the fit: it reads a bill (`fit::bill::BomRow`), the held-out fan the
//! fit was judged on and the design's `[parts]` settings, and hands back one [`ElementPart`] per
//! element and the realised residual angles. The mechanisms and the EN 13906 calculations are
//! `realise::mechanism` and `realise::spring`; this stage only says which element gets which
//! mechanism, over which deflections, in which envelope, and whether a stock part will do.

use nalgebra::{DMatrix, DVector};

use crate::design::Design;
use crate::design::parts::PartsSettings;
use crate::elements::{Element, Profile, Side};
use crate::error::{Error, Result};
use crate::fit::bill::{BomRow, spring_set};
use crate::geodesic::Fan;
use crate::potential::{GroupedSet, Potential, SpringSet};
use crate::realise::cam::FittedCam;
use crate::realise::material::by_key;
use crate::realise::mechanism::{self, Duty, Limit, Part, Requirements, Spring};
use crate::residual::{AngleStats, fan_angles, stats};

/// One row of a stock list: a spring a vendor sells, as the vendor publishes it.
#[derive(Debug, Clone, PartialEq)]
pub struct StockPart {
    /// Vendor.
    pub vendor: String,
    /// The vendor's part number.
    pub part_number: String,
    /// `torsion`, `compression` or `extension`.
    pub kind: String,
    /// Material as the vendor names it.
    pub material: String,
    /// Wire diameter, mm.
    pub d: f64,
    /// Mean coil diameter, mm.
    pub dm: f64,
    /// Active coils.
    pub n: f64,
    /// Free length (compression, extension) or leg length (torsion), mm.
    pub length: f64,
    /// Rate in N·mm/° (torsion) or N/mm.
    pub rate: f64,
    /// Largest deflection: ° (torsion) or mm.
    pub max_deflection: f64,
    /// Largest load: N·mm (torsion) or N.
    pub max_load: f64,
    /// Where the row comes from (URL, catalogue page).
    pub source: String,
}

/// What became of one element of the bill.
#[derive(Debug, Clone, PartialEq)]
pub struct ElementPart {
    /// The element's id in the bill (`S03`; a cam's `C01`).
    pub id: String,
    /// Catalogue family.
    pub family: String,
    /// The element (a cam: its coupling, profile `cam`).
    pub element: Element,
    /// Fitted stiffness in the profile's unit (a cam: the follower's rate is the part's).
    pub stiffness: f64,
    /// Deflections x − x₀ it sees.
    pub duty: Duty,
    /// The part, or the limit no spring meets.
    pub part: std::result::Result<Part, Limit>,
    /// The stock part ordered instead of winding one, if a stock list has one within tolerance.
    pub stock: Option<StockPart>,
    /// A cam's follower: its rate (N/mm), preload and largest stroke (mm) as the cam's family
    /// sets them (None for springs).
    pub follower: Option<[f64; 3]>,
}

impl ElementPart {
    /// The mounting in words: where the spring sits and its geometry.
    pub fn geometry(&self) -> String {
        let on = on_axis(&self.element.coupling);
        let Ok(p) = &self.part else { return on };
        match p.mechanism {
            mechanism::Mechanism::TorsionPair { preload } => format!(
                "{on}: two torsion springs wound against each other, each preloaded {:.1}° at x₀ = {:.4} rad; the preload screw turns both stops together",
                preload.to_degrees(),
                self.element.offset
            ),
            mechanism::Mechanism::TorsionStop { plus } => format!(
                "{on}: torsion spring, free leg meets a stop at the engagement angle x₀ = {:.4} rad ({:.2}°) and winds for x {} x₀",
                self.element.offset,
                self.element.offset.to_degrees(),
                if plus { ">" } else { "<" }
            ),
            mechanism::Mechanism::Crank { r, big_r, pulley, phase } => format!(
                "{on}: crank pin at radius r = {r} mm, at the phase x₀ {:+.5} rad = {:.4} rad; cable over a fairlead of two rollers (radius {pulley} mm) at R = {big_r} mm from the axis, spring beyond it (k_s·r·R = k); keep the cable plane clear of the shaft end",
                phase,
                self.element.offset + phase
            ),
            mechanism::Mechanism::Leaf { lever, gear } => {
                let Spring::Leaf { lengths, lowest_rate, .. } = p.spring else { return on };
                format!(
                    "{on}: leaf spring loaded at its tip by a lever of {lever} mm on a shaft geared {gear:.2} : 1 down from x; the sliding clamp sets the free length from {:.1} mm (highest rate) to {:.1} mm (lowest, {:.3} N·m/rad), {:.1} mm at mid-range: an adjustment of {:.1} mm",
                    lengths[0],
                    lengths[1],
                    lowest_rate,
                    lengths[2],
                    lengths[1] - lengths[0]
                )
            }
            mechanism::Mechanism::Follower => {
                format!("{on}: the cam's roller follower, pressed by a compression spring")
            }
        }
    }
}

/// Where an element's coordinate x = a·q is: a joint axis, or a bevel-gear differential's output.
pub fn on_axis(a: &[f64]) -> String {
    let used: Vec<(usize, f64)> = a.iter().copied().enumerate().filter(|(_, c)| *c != 0.0).collect();
    match used.as_slice() {
        [(i, c)] if *c == 1.0 => format!("on joint {}'s axis", i + 1),
        [(i, c)] => format!("on joint {}'s axis, geared {} : 1", i + 1, crate::elements::fmt_number(*c)),
        _ => format!(
            "on the output of a bevel-gear differential, x = {}",
            used.iter()
                .map(|(i, c)| format!("{}·q{}", crate::elements::fmt_number(*c), i + 1))
                .collect::<Vec<_>>()
                .join(" + ")
                .replace("+ -", "− ")
        ),
    }
}

/// The parts of a bill and what the realised mechanisms cost.
#[derive(Debug, Clone)]
pub struct Parts {
    /// One per spring element and one per cam.
    pub elements: Vec<ElementPart>,
    /// Residual angles of the realised design on the held-out fan.
    pub realised: AngleStats,
    /// The same of the ideal elements (the fit's figures), for comparison.
    pub ideal: AngleStats,
    /// Largest energy of the design's scenarios, J, and the swing radius it gives.
    pub swing: (f64, f64),
}

impl Parts {
    /// The elements no spring could be found for.
    pub fn missing(&self) -> impl Iterator<Item = (&ElementPart, &Limit)> {
        self.elements.iter().filter_map(|e| e.part.as_ref().err().map(|l| (e, l)))
    }
}

/// The requirements of element `id` from `[parts]` (its `[[parts.element]]` overrides).
pub fn requirements(s: &PartsSettings, id: &str) -> Requirements {
    let over = s.element.iter().find(|e| e.id == id);
    Requirements {
        material: by_key(&s.material).expect("validated: a material of the table"),
        grade: s.grade,
        cycles: s.cycles,
        safety: s.safety_factor,
        max_outer_diameter: over.and_then(|e| e.max_outer_diameter_mm).unwrap_or(s.max_outer_diameter_mm),
        max_length: over.and_then(|e| e.max_length_mm).unwrap_or(s.max_length_mm),
        max_lever: over.and_then(|e| e.max_lever_mm).unwrap_or(s.max_lever_mm),
        shaft_diameter: s.shaft_diameter_mm,
        pulley_radius: s.pulley_radius_mm,
    }
}

/// The largest energy any scenario of the design starts from or aims at, J (None without
/// scenarios): the swing fatigue is judged at.
pub fn scenario_energy(design: &Design) -> Option<f64> {
    use crate::design::scenario::EnergySpec;
    let mut e: Option<f64> = None;
    let mut see = |v: f64| e = Some(e.map_or(v, |m: f64| m.max(v)));
    for s in &design.file.scenario {
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

/// Deflections of `e` at q_eq, over the fan, and over the samples within `swing` arc length.
fn duty(e: &Element, q_eq: &[f64], fan: &Fan, swing: f64) -> Duty {
    let at_eq = e.deflection(q_eq);
    let (mut range, mut sw) = ([at_eq, at_eq], [at_eq, at_eq]);
    for g in &fan.geodesics {
        for i in 0..g.len() {
            let d = e.deflection(g.q(i));
            range = [range[0].min(d), range[1].max(d)];
            if g.s(i) <= swing {
                sw = [sw[0].min(d), sw[1].max(d)];
            }
        }
    }
    Duty { at_eq, range, swing: sw }
}

/// The parts of a fit's bill, over its evaluation fan, judged against its residual angles:
/// what `springfit fit` and the Python package's `fit()` both write.
pub fn of_fit(design: &Design, outcome: &crate::fit::FitOutcome, frequency: f64, stock: &[StockPart]) -> Result<Parts> {
    choose(design, &outcome.bom, &outcome.cams, &outcome.evaluation, frequency, stock, Some(outcome.metrics.stats))
}

/// Chooses the parts of `bom` (the fit's rows, trims included) and its realised `cams`, and
/// judges the realised design on `evaluation` beside the ideal elements' figures (`ideal`, the
/// fit's when it has just been judged on the same fan; computed when None).
pub fn choose(
    design: &Design,
    bom: &[BomRow],
    cams: &[FittedCam],
    evaluation: &Fan,
    frequency: f64,
    stock: &[StockPart],
    ideal: Option<AngleStats>,
) -> Result<Parts> {
    let s = &design.file.parts;
    s.validate().map_err(|(f, r)| Error::invalid(&design.path, f, r))?;
    let q_eq = design.q_eq.as_slice();
    let energy = scenario_energy(design);
    let extent = evaluation.geodesics.iter().map(|g| g.length()).fold(0.0, f64::max);
    let radius = energy.map_or(extent, |e| ((2.0 * e).sqrt() / frequency).min(extent));
    let mut elements = Vec::new();
    for r in bom.iter().filter(|r| !matches!(r.element.profile, Profile::Spline(_))) {
        let req = requirements(s, &r.id);
        let duty = duty(&r.element, q_eq, evaluation, radius);
        let k = r.stiffness;
        // The fitted elements' mechanisms, as functions of the stiffness (for the bound below).
        let design_at = |k: f64| match r.element.profile {
            Profile::Linear => mechanism::linear(k, &duty, &req),
            Profile::Compression(side) => mechanism::stop(k, side == Side::Plus, &duty, &req),
            _ => mechanism::crank(k, &duty, &req),
        };
        let part = match (r.element.profile, r.adjust.trim_range) {
            (Profile::Linear, Some(range)) => mechanism::leaf(range, k, &duty, &req),
            (Profile::Linear | Profile::Compression(_) | Profile::Crank, _) => {
                design_at(k).map_err(|l| Limit { torque_bound: torque_bound(&r.element, k, &duty, design_at), ..l })
            }
            (Profile::Cubic, _) => Err(Limit {
                check: mechanism::Check { name: "mechanism", value: 1.0, limit: 0.0, unit: "", upper: true },
                best: "a hardening (cubic) element has no spring mechanism here: realise it as a cam (a cam family in the catalogue)".into(),
                torque_bound: None,
            }),
            (Profile::Spline(_), _) => unreachable!("filtered above"),
        };
        let (part, stock) = snap(part, stock);
        elements.push(ElementPart {
            id: r.id.clone(),
            family: r.family.clone(),
            element: r.element.clone(),
            stiffness: k,
            duty,
            part,
            stock,
            follower: None,
        });
    }
    for cam in cams {
        let req = requirements(s, &cam.id);
        let b = cam.realisation.build;
        let stroke = cam.realisation.points.iter().map(|p| p.stroke).fold(0.0, f64::max);
        let element = Element { profile: Profile::Linear, coupling: cam.coupling.clone(), offset: cam.knots.lo };
        let duty = duty(&element, q_eq, evaluation, radius);
        let part = mechanism::follower(b.follower_rate, b.preload, stroke, &req);
        let (part, stock) = snap(part, stock);
        elements.push(ElementPart {
            id: cam.id.clone(),
            family: cam.family.clone(),
            element,
            stiffness: b.follower_rate,
            duty,
            part,
            stock,
            follower: Some([b.follower_rate, b.preload, stroke]),
        });
    }
    let realised = RealisedSet::new(bom, &elements);
    let residuals = fan_angles(&design.chain, evaluation, &realised)?;
    let ideal = match ideal {
        Some(s) => s,
        None => stats(&fan_angles(&design.chain, evaluation, &spring_set(bom).grouped())?),
    };
    Ok(Parts { elements, realised: stats(&residuals), ideal, swing: (energy.unwrap_or(0.0), radius) })
}

/// The largest torque on x (N·m) element `e` of stiffness `k` may carry and still get a part:
/// bisection on a factor of its stiffness (its peak torque over the region scales with it), as
/// `[fit] max_element_torque` caps it. None when even a thousandth of `k` gets no part.
fn torque_bound(
    e: &Element,
    k: f64,
    duty: &Duty,
    design_at: impl Fn(f64) -> std::result::Result<Part, Limit>,
) -> Option<f64> {
    let (mut lo, mut hi) = (1e-3, 1.0);
    design_at(k * lo).ok()?;
    for _ in 0..14 {
        let mid = (lo * hi).sqrt();
        if design_at(k * mid).is_ok() { lo = mid } else { hi = mid }
    }
    // The peak |u′| over the region, as the fit's bound computes it.
    let peak = (0..=200)
        .map(|i| duty.range[0] + (duty.range[1] - duty.range[0]) * f64::from(i) / 200.0)
        .map(|d| e.profile.slope(d).abs())
        .fold(0.0, f64::max);
    Some(k * lo * peak)
}

/// A stock part instead of the wound one when the list has a spring of the same kind whose rate
/// is within the part's grade tolerance of the one the element needs and whose largest
/// deflection and load cover the part's working points. The realised rate becomes the stock
/// spring's.
fn snap(
    part: std::result::Result<Part, Limit>,
    stock: &[StockPart],
) -> (std::result::Result<Part, Limit>, Option<StockPart>) {
    let Ok(mut p) = part else { return (part, None) };
    let (need, _) = p.spring.maker_rate();
    // The deflection of each working point: a torsion spring's wind angle (°), a helical
    // spring's length change from free (mm).
    let deflection = |position: f64| match p.spring {
        Spring::Torsion(_) | Spring::Leaf { .. } => position,
        Spring::Extension(s, _) => position - s.extension_free_length(),
        Spring::Compression(_, l0) => l0 - position,
    };
    let most = p.points.iter().fold((0.0f64, 0.0f64), |(a, b), w| (a.max(deflection(w.position)), b.max(w.load)));
    let kind = p.spring.kind();
    let fits = |s: &&StockPart| {
        s.kind == kind
            && (s.rate / need - 1.0).abs() <= p.tolerance.max(1e-9)
            && s.max_load >= most.1
            && s.max_deflection >= most.0
    };
    let Some(best) =
        stock.iter().filter(fits).min_by(|a, b| (a.rate / need - 1.0).abs().total_cmp(&(b.rate / need - 1.0).abs()))
    else {
        return (Ok(p), None);
    };
    p.realised_rate *= best.rate / need;
    (Ok(p), Some(best.clone()))
}

/// The realised design's potential: every element with a part by its mechanism's potential
/// ([`Part::potential`]), cams by their fitted profile (the follower stores V exactly), elements
/// without a part as fitted.
pub struct RealisedSet {
    terms: Vec<(Vec<f64>, f64, Part)>,
    rest: GroupedSet,
}

impl RealisedSet {
    /// The realised set of `bom` with the parts of `elements`.
    pub fn new(bom: &[BomRow], elements: &[ElementPart]) -> RealisedSet {
        let mut terms = Vec::new();
        let mut rest = SpringSet { elements: Vec::new(), stiffness: Vec::new() };
        for r in bom {
            let part = elements.iter().find(|e| e.id == r.id).and_then(|e| e.part.as_ref().ok());
            match part {
                Some(p) if !matches!(r.element.profile, Profile::Spline(_)) => {
                    terms.push((r.element.coupling.clone(), r.element.offset, p.clone()));
                }
                _ => {
                    rest.elements.push(r.element.clone());
                    rest.stiffness.push(r.stiffness);
                }
            }
        }
        RealisedSet { terms, rest: rest.grouped() }
    }

    fn each(&self, q: &[f64], mut f: impl FnMut(&[f64], (f64, f64, f64))) {
        for (a, x0, p) in &self.terms {
            let d = a.iter().zip(q).map(|(a, q)| a * q).sum::<f64>() - x0;
            f(a, p.potential(d));
        }
    }
}

impl Potential for RealisedSet {
    fn dof(&self) -> usize {
        self.terms.first().map(|t| t.0.len()).unwrap_or_else(|| self.rest.dof())
    }

    fn value(&self, q: &[f64]) -> Result<f64> {
        let mut u = self.rest.value(q)?;
        self.each(q, |_, (v, _, _)| u += v);
        Ok(u)
    }

    fn gradient(&self, q: &[f64]) -> Result<DVector<f64>> {
        let mut g = self.rest.gradient(q)?;
        self.each(q, |a, (_, t, _)| {
            for (gi, ai) in g.iter_mut().zip(a) {
                *gi += t * ai;
            }
        });
        Ok(g)
    }

    fn hessian(&self, q: &[f64]) -> Result<DMatrix<f64>> {
        let mut h = self.rest.hessian(q)?;
        self.each(q, |a, (_, _, c)| {
            let a = DVector::from_column_slice(a);
            h += &a * a.transpose() * c;
        });
        Ok(h)
    }
}

/// The sentence for an element no spring meets: the limit, by how much, the best candidate and,
/// when the limit scales with the load, the `[fit] max_element_torque` that keeps a part possible.
pub fn limit_message(e: &ElementPart, l: &Limit) -> String {
    let c = &l.check;
    let mut m = if c.name == "mechanism" {
        format!("{} ({}): {}", e.id, e.element.label(), l.best)
    } else {
        format!(
            "{} ({}): no spring meets `{}`: the best candidate ({}) reaches {:.4} {} against {:.4} {} ({:.2}× the limit)",
            e.id,
            e.element.label(),
            c.name,
            l.best,
            c.value,
            c.unit,
            c.limit,
            c.unit,
            c.ratio()
        )
    };
    if let Some(t) = l.torque_bound {
        m.push_str(&format!(
            "; set [fit] max_element_torque = {:.3} (N·m) to keep a part possible, or widen [parts] (max_outer_diameter_mm, max_length_mm, max_lever_mm, safety_factor)",
            t
        ));
    } else if let Some([rate, preload, stroke]) = e.follower {
        m.push_str(&format!(
            "; the cam's follower has rate {rate:.3} N/mm, preload {preload:.2} mm and stroke {stroke:.2} mm: a longer stroke (the cam family's `max_stroke`) stores the same energy in a softer spring, or widen [parts] for {}",
            e.id
        ));
    } else if c.name != "mechanism" {
        m.push_str(&format!(
            "; widen [parts] (max_outer_diameter_mm, max_length_mm, max_lever_mm; [[parts.element]] id = \"{}\") for this element",
            e.id
        ));
    }
    m
}
