//! The springs' mass in every report (`mass` in `summary.json`, the "Mass" section of
//! `report.md` and so `report.html`, the line `fit` prints, the column of `compare`): the figures
//! that say whether a bill is heavy because the potential needs it or because its elements fight
//! each other.
//!
//! Three ratios answer that. The springs' mass over the arm's moving mass says what the arm
//! carries. The mass over the floor ρ·U*/u ([`crate::fit::mass::Floor`], docs/parts.md) says how
//! far the bill is from the least steel that can store the potential at all. The elements' stored
//! energy over U* says why: a layout whose elements are set against each other (preloads that
//! cancel at q_eq) stores many times the potential's range, and its steel goes with what it
//! stores; the total |preload| at q_eq measures the same cancellation as a torque.

use serde::Serialize;

use crate::design::Design;
use crate::fit::FitOutcome;
use crate::fit::bill::BomRow;
use crate::fit::mass::Floor;
use crate::model::Chain;
use crate::parts::Parts;

/// `mass` in `summary.json` (null for the exact reference, which has no springs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MassSummary {
    /// Total mass of the chosen springs, kg (null when no parts were chosen).
    pub spring_mass_kg: Option<f64>,
    /// The arm's moving mass: the sum of its links' (bodies') masses, kg.
    pub arm_mass_kg: f64,
    /// `spring_mass_kg` over `arm_mass_kg`.
    pub mass_over_arm: Option<f64>,
    /// The floor ρ·U*/u, kg: the least spring steel that stores the potential.
    pub floor_kg: f64,
    /// `spring_mass_kg` over `floor_kg`.
    pub mass_over_floor: Option<f64>,
    /// U* = ½ω²r² at the region's boundary (r: the held-out fan's longest geodesic), J.
    pub potential_energy_j: f64,
    /// The material's usable energy density u the floor divides by, J/m³.
    pub energy_density_j_m3: f64,
    /// Σ over parts of the largest energy the part's potential holds over the held-out fan (above
    /// its lowest value there or zero, whichever is lower), J.
    pub stored_energy_j: f64,
    /// `stored_energy_j` over `potential_energy_j`: 1 when no element stores more than the
    /// potential needs; cancelling elements make it larger.
    pub stored_energy_over_potential: f64,
    /// Σ over parts of |torque on the part's coordinate at q_eq|, N·m: what cancels at the
    /// equilibrium (the elements' torques there sum to ∇U(q_eq) = 0 joint by joint).
    pub preload_total_nm: f64,
}

impl MassSummary {
    /// The mass figures of a fit of springs (None for the exact reference), with the parts'
    /// masses when parts were chosen.
    pub fn new(design: &Design, o: &FitOutcome, parts: Option<&Parts>) -> Option<MassSummary> {
        if o.solve.solver == crate::fit::Solver::Exact {
            return None;
        }
        let floor = Floor::on(design, o.settings.frequency, &o.evaluation);
        let spring_mass = parts.map(spring_mass);
        let arm = arm_mass(&design.chain);
        let samples: Vec<&[f64]> = o.metrics.residuals.iter().map(|r| &r.q[..]).collect();
        let (stored, preload) = energy_and_preload(&o.bom, design.q_eq.as_slice(), &samples);
        Some(MassSummary {
            spring_mass_kg: spring_mass,
            arm_mass_kg: arm,
            mass_over_arm: spring_mass.map(|m| m / arm),
            floor_kg: floor.mass,
            mass_over_floor: spring_mass.map(|m| m / floor.mass),
            potential_energy_j: floor.energy,
            energy_density_j_m3: floor.density,
            stored_energy_j: stored,
            stored_energy_over_potential: stored / floor.energy,
            preload_total_nm: preload,
        })
    }

    /// The figures in one line (what `fit` prints).
    pub fn line(&self) -> String {
        let springs = match (self.spring_mass_kg, self.mass_over_arm, self.mass_over_floor) {
            (Some(m), Some(a), Some(f)) => format!(
                "springs {m:.3} kg: {a:.2}× the arm's moving {:.3} kg, {f:.1}× the floor of {:.3} kg",
                self.arm_mass_kg, self.floor_kg
            ),
            _ => format!("springs: no parts chosen; the floor is {:.3} kg", self.floor_kg),
        };
        format!(
            "{springs} (U* = ½ω²r² = {:.1} J over {:.2} MJ/m³ of steel); the elements store {:.1}× U* ({:.1} J), total |preload| at q_eq {:.1} N·m",
            self.potential_energy_j,
            self.energy_density_j_m3 / 1e6,
            self.stored_energy_over_potential,
            self.stored_energy_j,
            self.preload_total_nm
        )
    }

    /// The "Mass" section of `report.md`.
    pub fn markdown(&self) -> String {
        let opt = |x: Option<f64>, digits: usize, unit: &str| {
            x.map(|v| format!("{v:.digits$}{unit}")).unwrap_or_else(|| "– (no parts chosen)".into())
        };
        format!(
            "## Mass\n\nThe springs' mass against what the arm carries and against the least steel that can store the potential; the stored energy and the preloads say how much of it the elements spend cancelling each other (docs/outputs.md, \"Mass\").\n\n| figure | value |\n| --- | ---: |\n| springs (the chosen parts) | {} |\n| arm's moving mass | {:.3} kg |\n| springs / arm | {} |\n| floor ρ·U*/u (U* = {:.2} J, u = {:.3} MJ/m³) | {:.3} kg |\n| springs / floor | {} |\n| elements' stored energy / U* | {:.2}× ({:.2} J) |\n| total \\|preload\\| at q_eq | {:.2} N·m |\n\n",
            opt(self.spring_mass_kg, 3, " kg"),
            self.arm_mass_kg,
            opt(self.mass_over_arm, 2, "×"),
            self.potential_energy_j,
            self.energy_density_j_m3 / 1e6,
            self.floor_kg,
            opt(self.mass_over_floor, 1, "×"),
            self.stored_energy_over_potential,
            self.stored_energy_j,
            self.preload_total_nm
        )
    }
}

/// The chosen parts' total mass, kg (elements without a part add nothing).
pub fn spring_mass(parts: &Parts) -> f64 {
    parts.elements.iter().filter_map(|e| e.part.as_ref().ok()).map(|p| p.mass).sum()
}

/// The arm's moving mass: every link's (body's) mass, kg.
pub fn arm_mass(chain: &Chain) -> f64 {
    match chain {
        Chain::Planar(c) => c.links().iter().map(|l| l.mass).sum(),
        Chain::Spatial(c) => c.bodies().iter().map(|b| b.mass).sum(),
    }
}

/// The parts' stored energy over `samples` (q_eq included) and their total |preload| at `q_eq`.
/// A part is a bill row, or all the coefficient rows of one cam (a cam's coefficients share one
/// follower, so its energy and torque are their sum, and a coefficient's own would count the
/// cancelling bumps of one cam as if they were springs).
fn energy_and_preload(bom: &[BomRow], q_eq: &[f64], samples: &[&[f64]]) -> (f64, f64) {
    let mut parts: Vec<(&str, Vec<&BomRow>)> = Vec::new();
    for row in bom {
        let key = if row.cam.is_some() { row.id.split('.').next().unwrap_or(&row.id) } else { row.id.as_str() };
        match parts.iter_mut().find(|(k, _)| *k == key) {
            Some((_, rows)) => rows.push(row),
            None => parts.push((key, vec![row])),
        }
    }
    let mut stored = 0.0;
    let mut preload = 0.0;
    for (_, rows) in &parts {
        let energy = |q: &[f64]| rows.iter().map(|r| r.stiffness * r.element.value(q)).sum::<f64>();
        let (lo, hi) = samples
            .iter()
            .copied()
            .chain(std::iter::once(q_eq))
            .map(energy)
            .fold((0.0_f64, f64::NEG_INFINITY), |(lo, hi), e| (lo.min(e), hi.max(e)));
        stored += (hi - lo).max(0.0);
        preload += rows.iter().map(|r| r.element.preload(r.stiffness, q_eq)).sum::<f64>().abs();
    }
    (stored, preload)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::elements::{Element, Profile};

    /// A one-joint row of `profile` at `offset` with rate `k`, made from the first row of the
    /// shipped test bill (its other columns do not enter these figures).
    fn row(id: &str, profile: Profile, offset: f64, k: f64) -> BomRow {
        let bill = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/double_pendulum_bom.csv");
        let template = crate::files::bom::read(&bill).unwrap().swap_remove(0);
        let element = Element { profile, coupling: vec![1.0], offset };
        BomRow { id: id.into(), element, stiffness: k, preload_nm: None, cam: None, ..template }
    }

    /// Two linear springs set against each other hold q = 0 with ±k·x₀ each: the preloads add in
    /// the total, and each stores ½k(q − x₀)², so together they store far more than the ½·2k·q²
    /// their sum holds.
    #[test]
    fn antagonists_store_and_preload_more_than_their_sum() {
        let (k, x0) = (10.0, 0.5);
        let bom = [row("S01", Profile::Linear, x0, k), row("S02", Profile::Linear, -x0, k)];
        let qs: Vec<Vec<f64>> = (-10..=10).map(|i| vec![0.1 * f64::from(i)]).collect();
        let samples: Vec<&[f64]> = qs.iter().map(|q| &q[..]).collect();
        let (stored, preload) = energy_and_preload(&bom, &[0.0], &samples);
        assert!((preload - 2.0 * k * x0).abs() < 1e-12, "{preload}");
        // Each stores ½k(1.5)² at its far end of q ∈ [−1, 1].
        assert!((stored - 2.0 * 0.5 * k * 1.5 * 1.5).abs() < 1e-9, "{stored}");
        let sum = 0.5 * 2.0 * k * 1.0;
        assert!(stored / sum > 2.0);
    }

    #[test]
    fn a_spring_at_rest_at_q_eq_has_no_preload() {
        let bom = [row("S01", Profile::Crank, 0.0, 3.0)];
        let (stored, preload) = energy_and_preload(&bom, &[0.0], &[&[0.5][..]]);
        assert_eq!(preload, 0.0);
        assert!((stored - 3.0 * (1.0 - 0.5_f64.cos())).abs() < 1e-12);
    }
}
