//! The files of the parts stage, written by `springfit parts` and by `fit` into its folder:
//! `parts.csv`, `parts.md` (the request for quotation) and a sketch per mechanism.

use serde::Serialize;

use super::output::OutputDir;
use crate::design::Design;
use crate::error::Result;
use crate::fit::mass::Floor;
use crate::parts::Parts;
use crate::residual::AngleStats;

/// The names the parts stage may write.
pub const FILES: &[&str] = &["cams/*", "parts.csv", "parts.md", "sketch_*.svg"];

/// What `summary.json` says of the realised design (`realised`).
#[derive(Debug, Clone, Serialize)]
pub struct RealisedSummary {
    /// Residual angles with each mechanism's own potential in place of the ideal element.
    pub residual_deg: AngleStats,
    /// p99 |residual angle| of the realised design less the ideal one's, degrees.
    pub p99_change_deg: f64,
    /// max |residual angle| of the realised design less the ideal one's, degrees.
    pub max_change_deg: f64,
    /// Elements with a part.
    pub parts: usize,
    /// The ids of the elements no spring meets (`parts.md` gives each one's limit).
    pub missing: Vec<String>,
    /// Parts ordered from a stock list.
    pub stock_parts: usize,
    /// Total mass of the springs, kg.
    pub spring_mass_kg: f64,
    /// The floor ρ·U*/u: the least spring steel that can store the potential, kg (docs/parts.md).
    pub floor_kg: f64,
    /// `spring_mass_kg` over `floor_kg`.
    pub mass_over_floor: f64,
    /// The wire every spring is wound from (a key of the material table).
    pub wire: String,
    /// Why that wire: the default for `[parts] cycles`, or set in `[parts] material`
    /// (`PartsSettings::material_choice`), so a reader of the summary sees a static grade chosen
    /// for many swings named as such.
    pub wire_choice: String,
}

impl RealisedSummary {
    /// The summary of `parts` wound as `settings` say, its mass against `floor`.
    pub fn new(parts: &Parts, floor: &Floor, settings: &crate::design::parts::PartsSettings) -> RealisedSummary {
        let mass = super::mass::spring_mass(parts);
        RealisedSummary {
            residual_deg: parts.realised,
            p99_change_deg: parts.realised.p99_abs - parts.ideal.p99_abs,
            max_change_deg: parts.realised.max_abs - parts.ideal.max_abs,
            parts: parts.elements.iter().filter(|e| e.part.is_ok()).count(),
            missing: parts.missing().map(|(e, _)| e.id.clone()).collect(),
            stock_parts: parts.elements.iter().filter(|e| e.stock.is_some()).count(),
            spring_mass_kg: mass,
            floor_kg: floor.mass,
            mass_over_floor: mass / floor.mass,
            wire: settings.material_key().to_string(),
            wire_choice: settings.material_choice(),
        }
    }
}

/// Writes `parts.csv`, `parts.md` and the sketches into `out`.
pub fn write(out: &OutputDir, design: &Design, parts: &Parts) -> Result<()> {
    let s = &design.parts;
    out.write("parts.csv", crate::files::parts::csv(parts, s.grade, s.safety_factor))?;
    out.write("parts.md", crate::files::parts::markdown(&design.name, parts, s))?;
    for e in &parts.elements {
        if let Ok(p) = &e.part {
            let title = format!("{} {}: {}", design.name, e.id, crate::parts::on_axis(&e.element.coupling));
            let order = match &e.stock {
                Some(row) => format!("stock part {} {}", row.vendor, row.part_number),
                None => "wound to this sheet".to_string(),
            };
            let sketch = crate::realise::sketch::svg(p, &title, s.grade, crate::parts::surface(s).name(), &order);
            out.write(&format!("sketch_{}.svg", e.id), sketch)?;
            // A cubic element's disc cam is drawn as the fitted cams are (their drawings are
            // written with the bill), so the maker has its pitch curve too.
            if let crate::realise::mechanism::Mechanism::CubicCam { .. } = p.mechanism {
                let (_, cam) = crate::parts::cubic_cam_profile(e.stiffness, e.element.offset, &e.duty);
                out.write(&format!("cams/{}.svg", e.id), crate::realise::cam::svg(&cam, &title))?;
            }
        }
    }
    Ok(())
}
