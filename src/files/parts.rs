//! `parts.csv` (one row per element's spring, every figure with its unit in the header) and
//! `parts.md` (a request for quotation: one block per spring with what a maker needs and the
//! assembly geometry of its element).

use std::fmt::Write as _;

use crate::csv::csv_field;
use crate::parts::{ElementPart, Parts, limit_message};
use crate::realise::mechanism::{Mechanism, Part, Spring};
use crate::realise::sketch::{lengths, units};

/// The header of `parts.csv`.
pub const HEADER: &str = "id,family,profile,coupling,offset_rad,transmission,pulley_radii_mm,mechanism,spring,quantity,material,grade,wire_d_mm,mean_D_mm,outer_D_mm,active_coils,free_length_mm,leg_mm,rate_maker,rate_maker_unit,fitted_stiffness,realised_rate,fit_unit,rate_tolerance,initial_tension_n,position_unit,load_unit,eq_position,eq_load,low_position,low_load,high_position,high_load,base_circle_position,base_circle_load,largest_stroke_position,largest_stroke_load,max_stress_mpa,allowed_stress_mpa,static_utilisation,fatigue_utilisation,life_cycles,mass_kg,vendor,part_number,source,geometry,limit";

/// The working points of `parts.csv`'s columns, in order: the element's (`eq_`, `low_`,
/// `high_`), then a cam follower's (`base_circle_`, `largest_stroke_`), as
/// `realise::mechanism` names them.
const POINTS: [&str; 5] = ["q_eq", "range low", "range high", "base circle", "largest stroke"];

fn mechanism_name(m: &Mechanism) -> &'static str {
    match m {
        Mechanism::TorsionPair { .. } => "torsion pair",
        Mechanism::TorsionStop { .. } => "torsion spring on a leg stop",
        Mechanism::DrumStop { .. } => "compression spring on a cable drum",
        Mechanism::TrimCrank { .. } => "geared crank, pin radius set by a screw",
        Mechanism::Crank { .. } => "zero-free-length crank",
        Mechanism::Leaf { .. } => "leaf spring in a sliding clamp",
        Mechanism::Follower => "cam follower spring",
        Mechanism::CubicCam { .. } => "disc cam of the cubic profile, follower spring",
    }
}

fn fit_unit(e: &ElementPart) -> &'static str {
    match e.part.as_ref().map(|p| p.mechanism) {
        Ok(Mechanism::Follower) => "N/mm",
        _ => e.element.profile.unit(),
    }
}

fn num(x: Option<f64>) -> String {
    x.map(|v| format!("{v}")).unwrap_or_default()
}

fn check<'a>(p: &'a Part, name: &str) -> Option<&'a crate::realise::mechanism::Check> {
    p.checks.iter().find(|c| c.name == name)
}

/// `parts.csv`.
/// `safety` is `[parts] safety_factor` (the checks carry it: the stress column is without it).
pub fn csv(parts: &Parts, grade: u8, safety: f64) -> String {
    let mut s = format!("{HEADER}\n");
    for e in &parts.elements {
        let head = [
            e.id.clone(),
            e.family.clone(),
            format!("{}{}", e.element.profile.name(), e.element.profile.side()),
            e.element.coupling_text(),
            format!("{}", e.element.offset),
            // What turns the joints into x, and a tendon's signed pulley radii (empty for a joint
            // or a differential, and for a coupling no transmission makes: its `limit` says why).
            e.transmission.as_ref().map(|t| t.kind.name().to_string()).unwrap_or_default(),
            e.transmission.as_ref().map(|t| t.radii_text()).unwrap_or_default(),
        ];
        let mut f: Vec<String> = head.to_vec();
        match &e.part {
            Ok(p) => {
                let (free, leg) = lengths(&p.spring);
                let (rate, unit) = p.spring.maker_rate();
                let (pu, lu) = units(p);
                // Each working point in the columns of its name, so that a column means one thing
                // for every mechanism: a cam follower's base circle and largest stroke are not
                // the element's q_eq and range ends.
                let at = |name: &str| p.points.iter().find(|w| w.at == name).map(|w| (w.position, w.load));
                let stress = check(p, "static stress");
                f.extend([
                    mechanism_name(&p.mechanism).to_string(),
                    p.spring.kind().to_string(),
                    p.quantity.to_string(),
                    p.spring.material().to_string(),
                    grade.to_string(),
                    format!("{}", p.spring.d()),
                    format!("{}", p.spring.dm()),
                    match p.spring {
                        Spring::Leaf { .. } => String::new(),
                        _ => format!("{}", p.spring.dm() + p.spring.d()),
                    },
                    num(p.spring.coils()),
                    num(free),
                    num(leg),
                    format!("{rate}"),
                    unit.to_string(),
                    format!("{}", e.stiffness),
                    format!("{}", p.realised_rate),
                    fit_unit(e).to_string(),
                    format!("{}", p.tolerance),
                    num(match p.spring {
                        Spring::Extension(_, f0) => Some(f0),
                        _ => None,
                    }),
                    pu.to_string(),
                    lu.to_string(),
                ]);
                for name in POINTS {
                    let (a, b) = at(name).map_or((None, None), |(a, b)| (Some(a), Some(b)));
                    f.push(num(a));
                    f.push(num(b));
                }
                f.extend([
                    num(stress.map(|c| c.value / safety)),
                    // What the stress may reach: the standard's allowed stress over the safety
                    // factor, so that `max_stress_mpa` ≤ it passes and their ratio is the
                    // utilisation.
                    num(stress.map(|c| c.limit / safety)),
                    num(stress.map(|c| c.ratio())),
                    // The worst fatigue check: the body's, or an extension spring's hook's.
                    num(p.checks.iter().filter(|c| c.name.contains("fatigue")).map(|c| c.ratio()).reduce(f64::max)),
                    format!("{}", p.life),
                    format!("{}", p.mass),
                    e.stock.as_ref().map(|s| s.vendor.clone()).unwrap_or_default(),
                    e.stock.as_ref().map(|s| s.part_number.clone()).unwrap_or_else(|| "custom".into()),
                    e.stock.as_ref().map(|s| s.source.clone()).unwrap_or_default(),
                    e.geometry(),
                    String::new(),
                ]);
            }
            Err(l) => {
                f.extend(std::iter::repeat_n(String::new(), HEADER.split(',').count() - head.len() - 1));
                f.push(limit_message(e, l));
            }
        }
        let line: Vec<String> = f.iter().map(|x| csv_field(x)).collect();
        s.push_str(&line.join(","));
        s.push('\n');
    }
    s
}

/// `parts.md`: the request for quotation.
pub fn markdown(design: &str, parts: &Parts, settings: &crate::design::parts::PartsSettings) -> String {
    let mut m = format!("# Parts: {design}\n\n");
    let _ = writeln!(
        m,
        "Request for quotation. Wire {} (EN 15800 grade {}; {}), surface {}, {} swings at the scenarios' amplitude (largest scenario energy {:.1} J, arc length {:.3} from q_eq), every stress limit divided by the safety factor {}.\n",
        settings.material_key(),
        settings.grade,
        settings.material_choice(),
        crate::parts::surface(settings).name(),
        settings.cycles,
        parts.swing.0,
        parts.swing.1,
        settings.safety_factor
    );
    let _ = writeln!(
        m,
        "**The realised design** (each mechanism's own potential in place of the ideal element): residual angle p99 {:.4}°, max {:.4}° on {} held-out samples; the ideal elements: p99 {:.4}°, max {:.4}°.\n",
        parts.realised.p99_abs, parts.realised.max_abs, parts.realised.count, parts.ideal.p99_abs, parts.ideal.max_abs
    );
    let missing: Vec<String> = parts.missing().map(|(e, l)| limit_message(e, l)).collect();
    if !missing.is_empty() {
        m.push_str("**No spring found for:**\n\n");
        for x in &missing {
            let _ = writeln!(m, "- {x}");
        }
        m.push('\n');
    }
    for e in &parts.elements {
        let _ = writeln!(
            m,
            "## {} — {} ({}, coupling ({}), x₀ = {:.4} rad)\n",
            e.id,
            e.family,
            e.element.profile.name(),
            e.element.coupling_text().replace(';', ", "),
            e.element.offset
        );
        if let Ok(p) = &e.part {
            part_section(&mut m, e, p, settings);
        }
        if let Some(note) = &e.stock_note {
            let _ = writeln!(m, "Stock: {note}; wound instead.\n");
        }
    }
    let _ = writeln!(
        m,
        "Stock rows examined for this bill: {} (the list indexed by type and rate: each element examines the rows near its rate).",
        parts.stock_examined
    );
    m
}

/// An element's part in `parts.md`: its geometry, how to order it, its figures, its working
/// points, its checks and its sketch (and a cam's drawing).
fn part_section(m: &mut String, e: &ElementPart, p: &Part, settings: &crate::design::parts::PartsSettings) {
    let _ = writeln!(m, "{}.\n", e.geometry());
    let order = match &e.stock {
        Some(s) => format!("stock part **{} {}** ({})", s.vendor, s.part_number, s.source),
        None => "to be wound to this specification".into(),
    };
    let _ = writeln!(m, "{} × {} spring, {order}.\n\n| figure | value |\n| --- | ---: |", p.quantity, p.spring.kind());
    for (k, v) in figures(e, p, settings) {
        let _ = writeln!(m, "| {k} | {v} |");
    }
    let (pu, lu) = units(p);
    let _ = writeln!(m, "\n| working point | position ({pu}) | load ({lu}) |\n| --- | ---: | ---: |");
    for w in &p.points {
        let _ = writeln!(m, "| {} | {:.2} | {:.2} |", w.at, w.position, w.load);
    }
    let _ = writeln!(m, "\n| check | value | limit | utilisation |\n| --- | ---: | ---: | ---: |");
    for c in &p.checks {
        let _ = writeln!(
            m,
            "| {} | {} | {} {:.4} {} | {:.3} |",
            c.name,
            check_value(c.value, c.unit),
            if c.upper { "≤" } else { "≥" },
            c.limit,
            c.unit,
            c.ratio()
        );
    }
    let _ = writeln!(m, "\n![{0}](sketch_{0}.svg)\n", e.id);
    if let Mechanism::CubicCam { .. } = p.mechanism {
        let _ = writeln!(m, "The disc cam, 1:1 in mm:\n\n![{0} cam](cams/{0}.svg)\n", e.id);
    }
}

/// The figures of a part, as (figure, value) rows of its table: the material, the spring's
/// dimensions (a leaf's or a coil's), lengths and initial tension where it has them, its rate,
/// the element's rate fitted and realised, its mass and its fatigue life.
fn figures(e: &ElementPart, p: &Part, settings: &crate::design::parts::PartsSettings) -> Vec<(&'static str, String)> {
    let (rate, unit) = p.spring.maker_rate();
    let (free, leg) = lengths(&p.spring);
    let mut rows = vec![("material", p.spring.material().to_string())];
    match p.spring {
        Spring::Leaf { t, b, lengths, lowest_rate } => {
            rows.push(("strip thickness × width", format!("{t} × {b} mm")));
            rows.push((
                "free length in the clamp (highest rate – lowest)",
                format!("{:.1} – {:.1} mm", lengths[0], lengths[1]),
            ));
            rows.push(("free length at mid-range", format!("{:.1} mm", lengths[2])));
            rows.push((
                "lowest rate in the clamp's travel",
                format!("{lowest_rate:.4} N·m/rad (below it: lift the leaf off)"),
            ));
        }
        _ => {
            rows.push(("wire diameter d", format!("{} mm", p.spring.d())));
            rows.push((
                "mean coil diameter D (outer)",
                format!("{:.2} mm ({:.2} mm)", p.spring.dm(), p.spring.dm() + p.spring.d()),
            ));
            rows.push(("active coils n", format!("{:.2}", p.spring.coils().unwrap_or(0.0))));
        }
    }
    if let Some(l) = free {
        rows.push(("free length", format!("{l:.1} mm")));
    }
    if let Some(l) = leg {
        rows.push(("leg length", format!("{l:.1} mm")));
    }
    if let Spring::Extension(_, f0) = p.spring {
        rows.push(("initial tension F₀", format!("{f0:.2} N")));
    }
    rows.push(("rate", format!("{rate:.4} {unit} (±{:.1} %, grade {})", 100.0 * p.tolerance, settings.grade)));
    rows.push((
        "element rate (fitted → realised)",
        format!("{:.4} → {:.4} {}", e.stiffness, p.realised_rate, fit_unit(e)),
    ));
    rows.push(("mass", format!("{:.3} kg", p.mass)));
    rows.push((
        "fatigue life at the swing",
        if p.life >= 1e8 { "≥ 10⁸ cycles".into() } else { format!("{:.3e} cycles", p.life) },
    ));
    rows
}

/// A check's value as parts.md prints it: an unbounded one (a compression spring too short to
/// buckle at any deflection has no buckling deflection) in words, never `inf`.
fn check_value(value: f64, unit: &str) -> String {
    if value.is_finite() { format!("{value:.4} {unit}") } else { "none (unbounded)".into() }
}

#[cfg(test)]
mod tests {
    #[test]
    fn an_unbounded_check_is_written_in_words() {
        assert_eq!(super::check_value(f64::INFINITY, "mm"), "none (unbounded)");
        assert_eq!(super::check_value(29.22364, "mm"), "29.2236 mm");
    }
}
