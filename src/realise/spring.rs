//! Helical springs by EN 13906: torsion springs (part 3), compression springs (part 1) and
//! extension springs (part 2), with their stresses, limits, fatigue and rate tolerance.
//!
//! Units: mm, N, N·mm, MPa. w = D/d is the spring index (D the mean coil diameter, d the wire).
//!
//! - Torsion: rate M/α = E d⁴ / (64 D n) per rad (E d⁴ / (3667 D n) N·mm/°), bending stress
//!   σ = q · 32 M / (π d³) with q = (w + 0.07)/(w − 0.75); allowed σ ≤ 0.7 R_m (EN 13906-3).
//! - Compression and extension: rate F/s = G d⁴ / (8 D³ n), shear stress τ = k · 8 F D / (π d³)
//!   with k = (w + 0.5)/(w − 0.75); allowed τ ≤ 0.5 R_m (compression, EN 13906-1) and
//!   τ ≤ 0.45 R_m (extension, EN 13906-2).
//! - Fatigue: a Goodman line through the material's endurance for repeated stress (zero to
//!   maximum) at the required cycles, as a fraction of R_m, and its ultimate strength (shear
//!   0.67 R_m, bending R_m): Budynas & Nisbett, *Shigley's Mechanical Engineering Design*
//!   (9th ed.) §10-9, Table 10-8 (compression: 36 / 33 / 30 % of R_m at 10⁵ / 10⁶ / 10⁷ cycles,
//!   not shot-peened) and §10-12, Table 10-10 (torsion: 53 / 50 % at 10⁵ / 10⁶, extrapolated
//!   log-linearly beyond), Eq. 10-30 (S_su = 0.67 S_ut). The same fractions are used for
//!   extension spring bodies (the hooks, which usually fail first, are for the maker to check).
//! - Rate tolerance: EN 15800's load tolerance A_F = ±(α_F k_F + 1.5 F/100) Q with
//!   α_F = 65.92 d^3.3 / D^1.6 · (−0.84 (w/10)³ + 3.781 (w/10)² − 4.244 (w/10) + 2.274),
//!   k_F = 1/(3 n²) + 8/(5 n) + 0.803 and Q = 0.63 / 1 / 1.6 for grades 1 / 2 / 3 (as
//!   springone's EN15800 module implements the standard); springfit states it as a fraction of
//!   the load at the largest working point and uses that as the rate tolerance.

use std::f64::consts::PI;

use super::material::Material;

/// The spring index range EN 13906 and EN 15800 apply to.
pub const INDEX_RANGE: (f64, f64) = (4.0, 20.0);

/// Fewest active coils a maker winds reliably.
pub const MIN_COILS: f64 = 2.0;

/// Arbor diameter as a fraction of the torsion spring's smallest inner diameter (about 10 %
/// clearance, as spring catalogues size their mandrels).
pub const ARBOR_FRACTION: f64 = 0.9;

/// Stress correction factor of a torsion spring (EN 13906-3).
pub fn torsion_q(w: f64) -> f64 {
    (w + 0.07) / (w - 0.75)
}

/// Stress correction factor of a compression or extension spring (EN 13906-1, -2; Bergsträsser).
pub fn shear_k(w: f64) -> f64 {
    (w + 0.5) / (w - 0.75)
}

/// How the wire is stressed: the two Goodman lines.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Loading {
    /// Torsion of the wire (compression and extension springs).
    Shear,
    /// Bending of the wire (torsion springs, leaf springs).
    Bending,
}

impl Loading {
    /// Endurance for repeated stress (zero to maximum) at `cycles`, as a fraction of R_m.
    pub fn repeated_fraction(self, cycles: f64) -> f64 {
        let table: &[(f64, f64)] = match self {
            Loading::Shear => &[(5.0, 0.36), (6.0, 0.33), (7.0, 0.30)],
            Loading::Bending => &[(5.0, 0.53), (6.0, 0.50)],
        };
        let x = cycles.max(1.0).log10().max(table[0].0);
        let (a, b) = if x <= table[table.len() - 1].0 {
            let i = table.iter().rposition(|p| p.0 <= x).unwrap_or(0).min(table.len() - 2);
            (table[i], table[i + 1])
        } else {
            (table[table.len() - 2], table[table.len() - 1])
        };
        a.1 + (b.1 - a.1) * (x - a.0) / (b.0 - a.0)
    }

    /// Ultimate strength of this loading, MPa.
    pub fn ultimate(self, rm: f64) -> f64 {
        match self {
            Loading::Shear => 0.67 * rm,
            Loading::Bending => rm,
        }
    }

    /// Goodman utilisation of a stress cycle between `lo` and `hi` (MPa) at `cycles`:
    /// σ_a / S_e + σ_m / S_u, where S_e is the fully reversed endurance on the line through the
    /// repeated-stress point. 1 is the limit.
    pub fn goodman(self, rm: f64, lo: f64, hi: f64, cycles: f64) -> f64 {
        let su = self.ultimate(rm);
        let half = 0.5 * self.repeated_fraction(cycles) * rm;
        let se = half / (1.0 - half / su);
        let (a, m) = (0.5 * (hi - lo).abs(), 0.5 * (hi + lo));
        a / se + m.max(0.0) / su
    }

    /// Largest number of cycles (10⁵ to 10⁸, to 1e-10 in the exponent) whose Goodman utilisation
    /// stays ≤ `limit`; 0 when even 10⁵ fails. The utilisation grows with the cycles, so a
    /// bisection on the exponent finds it. Fine enough that a part within its fatigue limit at
    /// N cycles (utilisation ≤ 1) reports a life of at least N: a bracket of 1 % in the exponent
    /// once reported 991,046 cycles for a part at 0.999 of its limit at 10⁶.
    pub fn life(self, rm: f64, lo: f64, hi: f64, limit: f64) -> f64 {
        let ok = |x: f64| self.goodman(rm, lo, hi, 10f64.powf(x)) <= limit;
        if !ok(5.0) {
            return 0.0;
        }
        if ok(8.0) {
            return 1e8;
        }
        let (mut a, mut b) = (5.0, 8.0);
        while b - a > 1e-10 {
            let m = 0.5 * (a + b);
            if ok(m) { a = m } else { b = m }
        }
        10f64.powf(a)
    }
}

/// The most elastic energy a unit volume of `material`'s wire can store in a helical extension
/// or compression spring under the checks this module applies, J/m³: round wire in torsion holds
/// u = τ²/(4G) at a uniform shear stress τ, and τ is at most the endurance for repeated stress at
/// `cycles` (and the static limit 0.45 R_m, whichever is lower) over `safety`, on the strongest
/// (thinnest) wire of the material. No part does better (the stress correction factor and the
/// cycle's mean stress only lower it), so U*/u·ρ is a lower bound on the mass of any springs that
/// store the energy U*: the floor `[fit] max_spring_mass` is checked against and that `fit`
/// reports its mass over (docs/parts.md, "The floor").
pub fn usable_energy_density(material: &Material, cycles: f64, safety: f64) -> f64 {
    let fraction = Loading::Shear.repeated_fraction(cycles).min(0.45);
    material
        .sizes()
        .iter()
        .filter_map(|&d| material.tensile_strength(d))
        .map(|rm| {
            let tau = fraction * rm / safety.max(1.0);
            tau * tau / (4.0 * material.g) * 1e6
        })
        .fold(0.0, f64::max)
}

/// The EN 15800 rate tolerance (± fraction) of a helical spring of wire `d`, mean diameter `dm`
/// and `n` active coils at the working load `force` (N), for quality grade 1, 2 or 3.
pub fn rate_tolerance(d: f64, dm: f64, n: f64, force: f64, grade: u8) -> f64 {
    let w = dm / d;
    let x = w / 10.0;
    let alpha = 65.92 * d.powf(3.3) / dm.powf(1.6) * (-0.84 * x.powi(3) + 3.781 * x * x - 4.244 * x + 2.274);
    let kf = 1.0 / (3.0 * n * n) + 8.0 / (5.0 * n) + 0.803;
    let q = match grade {
        1 => 0.63,
        2 => 1.0,
        _ => 1.6,
    };
    let af = (alpha * kf + 1.5 * force.abs() / 100.0) * q;
    af / force.abs().max(1e-9)
}

/// A helical torsion spring, close wound, with straight legs (EN 13906-3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TorsionSpring {
    /// The wire's material.
    pub material: &'static Material,
    /// Wire diameter d, mm.
    pub d: f64,
    /// Mean coil diameter D, mm.
    pub dm: f64,
    /// Active coils n.
    pub n: f64,
    /// Length of each leg from the coil axis, mm.
    pub leg: f64,
}

impl TorsionSpring {
    /// Rate in N·mm/rad: E d⁴ / (64 D n).
    pub fn rate(&self) -> f64 {
        self.material.e * self.d.powi(4) / (64.0 * self.dm * self.n)
    }

    /// Rate in N·mm/°, the maker's unit.
    pub fn rate_per_degree(&self) -> f64 {
        self.rate() * PI / 180.0
    }

    /// Bending stress at torque `m` (N·mm), MPa.
    pub fn stress(&self, m: f64) -> f64 {
        torsion_q(self.dm / self.d) * 32.0 * m.abs() / (PI * self.d.powi(3))
    }

    /// Allowed static stress 0.7 R_m, MPa.
    pub fn allowed(&self) -> f64 {
        0.7 * self.rm()
    }

    /// R_m of the wire, MPa.
    pub fn rm(&self) -> f64 {
        self.material.tensile_strength(self.d).unwrap_or(0.0)
    }

    /// Outer diameter unloaded, mm.
    pub fn outer_diameter(&self) -> f64 {
        self.dm + self.d
    }

    /// Body length wound by `angle` rad: (n + 1.5 + α/2π) d (each turn wound adds one wire).
    pub fn body_length(&self, angle: f64) -> f64 {
        (self.n + 1.5 + angle.max(0.0) / (2.0 * PI)) * self.d
    }

    /// Inner diameter wound by `angle` rad: the mean diameter shrinks to D n / (n + α/2π).
    pub fn inner_diameter(&self, angle: f64) -> f64 {
        self.dm * self.n / (self.n + angle.max(0.0) / (2.0 * PI)) - self.d
    }

    /// The arbor it may be wound on at `angle`: [`ARBOR_FRACTION`] of the inner diameter.
    pub fn arbor(&self, angle: f64) -> f64 {
        ARBOR_FRACTION * self.inner_diameter(angle)
    }

    /// Mass of the coils and both legs, kg.
    pub fn mass(&self) -> f64 {
        let length = PI * self.dm * self.n + 2.0 * self.leg;
        self.material.density * PI * self.d * self.d / 4.0 * length * 1e-9
    }
}

/// A helical compression or extension spring (EN 13906-1, -2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HelicalSpring {
    /// The wire's material.
    pub material: &'static Material,
    /// Wire diameter d, mm.
    pub d: f64,
    /// Mean coil diameter D, mm.
    pub dm: f64,
    /// Active coils n.
    pub n: f64,
}

impl HelicalSpring {
    /// Rate in N/mm: G d⁴ / (8 D³ n).
    pub fn rate(&self) -> f64 {
        self.material.g * self.d.powi(4) / (8.0 * self.dm.powi(3) * self.n)
    }

    /// Shear stress at force `f` (N), MPa.
    pub fn stress(&self, f: f64) -> f64 {
        shear_k(self.dm / self.d) * 8.0 * f.abs() * self.dm / (PI * self.d.powi(3))
    }

    /// R_m of the wire, MPa.
    pub fn rm(&self) -> f64 {
        self.material.tensile_strength(self.d).unwrap_or(0.0)
    }

    /// Outer diameter, mm.
    pub fn outer_diameter(&self) -> f64 {
        self.dm + self.d
    }

    /// Solid length of a compression spring with closed and ground ends: (n + 2) d.
    pub fn solid_length(&self) -> f64 {
        (self.n + 2.0) * self.d
    }

    /// Sum of the smallest gaps EN 13906-1 asks for at the largest working deflection:
    /// S_a = n (0.0015 D²/d + 0.1 d).
    pub fn min_gaps(&self) -> f64 {
        self.n * (0.0015 * self.dm * self.dm / self.d + 0.1 * self.d)
    }

    /// The deflection at which a compression spring of free length `l0` buckles, with seating
    /// coefficient `nu` (0.5: both ends on parallel, guided plates), EN 13906-1:
    /// s_K = L₀ · 0.5/(1 − G/E) · [1 − sqrt(1 − (1 − G/E)/(0.5 + G/E) · (π D/(ν L₀))²)].
    /// None when the root is imaginary: the spring cannot buckle.
    pub fn buckling_deflection(&self, l0: f64, nu: f64) -> Option<f64> {
        let ge = self.material.g / self.material.e;
        let r = 1.0 - (1.0 - ge) / (0.5 + ge) * (PI * self.dm / (nu * l0)).powi(2);
        (r >= 0.0).then(|| l0 * 0.5 / (1.0 - ge) * (1.0 - r.sqrt()))
    }

    /// Body length of a close-wound extension spring: (n + 1) d.
    pub fn body_length(&self) -> f64 {
        (self.n + 1.0) * self.d
    }

    /// Free length of an extension spring with a full loop at each end (each loop adds its inner
    /// diameter), mm.
    pub fn extension_free_length(&self) -> f64 {
        self.body_length() + 2.0 * (self.dm - self.d)
    }

    /// Initial tension an extension spring is wound with, N: the middle of the preferred range
    /// of uncorrected initial stress τ_i = 231 e^(−0.105 w) MPa (Shigley, 9th ed., Eq. 10-51;
    /// the range is ±6.9 (4 − (w − 3)/6.5) MPa about it), F₀ = τ_i π d³ / (8 D).
    pub fn initial_tension(&self) -> f64 {
        let w = self.dm / self.d;
        231.0 * (-0.105 * w).exp() * PI * self.d.powi(3) / (8.0 * self.dm)
    }

    /// Mass of the active coils, kg (end turns and loops add a little).
    pub fn mass(&self) -> f64 {
        let coils = self.n + 2.0;
        self.material.density * PI * self.d * self.d / 4.0 * PI * self.dm * coils * 1e-9
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The floor's energy density for the default material and duty: the design notes' figure
    /// (about 0.9 MJ/m³ for extension springs at 10⁶ cycles over a safety factor of 1.1) within a
    /// factor of two, and lower for more cycles and a larger safety factor.
    #[test]
    fn usable_energy_density_is_the_order_of_a_megajoule_per_cubic_metre() {
        let m = crate::realise::material::by_key("EN10270-1-SM").unwrap();
        let u = usable_energy_density(m, 1e6, 1.1);
        assert!((0.45e6..1.8e6).contains(&u), "{u}");
        assert!(usable_energy_density(m, 1e7, 1.1) < u);
        assert!(usable_energy_density(m, 1e6, 1.5) < u);
    }
    use crate::realise::material::by_key;

    /// The correction factors are the standards' closed forms (EN 13906-3's q and the
    /// Bergsträsser k of EN 13906-1/-2, which is Shigley's K_B = (4C + 2)/(4C − 3)).
    #[test]
    fn correction_factors() {
        for w in [4.0, 6.0, 10.0, 20.0] {
            assert!((shear_k(w) - (4.0 * w + 2.0) / (4.0 * w - 3.0)).abs() < 1e-12);
        }
        assert!((torsion_q(10.0) - 10.07 / 9.25).abs() < 1e-12);
        assert!((shear_k(6.0) - 6.5 / 5.25).abs() < 1e-12);
    }

    /// The torsion rate per degree is E d⁴ / (3667 D n), the form EN 13906-3 writes.
    #[test]
    fn torsion_rate_in_the_makers_unit() {
        let m = by_key("EN10270-1-SM").unwrap();
        let s = TorsionSpring { material: m, d: 2.0, dm: 16.0, n: 6.5, leg: 20.0 };
        let en = m.e * 16.0 / (3667.0 * 16.0 * 6.5);
        assert!((s.rate_per_degree() / en - 1.0).abs() < 1e-4, "{} vs {en}", s.rate_per_degree());
        // Winding one turn closes the coil diameter by D/(n + 1) and adds a wire to the body.
        assert!((s.inner_diameter(2.0 * PI) - (16.0 * 6.5 / 7.5 - 2.0)).abs() < 1e-12);
        assert!((s.body_length(2.0 * PI) - s.body_length(0.0) - 2.0).abs() < 1e-12);
    }

    /// Goodman: a static stress uses the ultimate line, a repeated one lands on 1 at the
    /// tabulated endurance, more cycles allow less.
    #[test]
    fn goodman_and_life() {
        let rm = 1600.0;
        let sr = 0.33 * rm;
        assert!((Loading::Shear.goodman(rm, 0.0, sr, 1e6) - 1.0).abs() < 1e-12);
        assert!((Loading::Shear.goodman(rm, 500.0, 500.0, 1e6) - 500.0 / (0.67 * rm)).abs() < 1e-12);
        assert!(Loading::Shear.goodman(rm, 0.0, sr, 1e7) > 1.0);
        assert!((Loading::Bending.repeated_fraction(3e5) - (0.53 - 0.03 * 3f64.log10())).abs() < 1e-12);
        assert!((Loading::Bending.repeated_fraction(1e7) - 0.47).abs() < 1e-12);
        let life = Loading::Shear.life(rm, 0.0, sr, 1.0);
        assert!((life.log10() - 6.0).abs() <= 1e-9, "{life}");
        // Just within the limit at 10⁶: a life of at least 10⁶.
        assert!(Loading::Shear.life(rm, 0.0, 0.999 * sr, 1.0) >= 1e6);
        assert_eq!(Loading::Shear.life(rm, 0.0, rm, 1.0), 0.0);
    }

    /// EN 15800: the tolerance narrows with the grade in the ratios 0.63 : 1 : 1.6.
    #[test]
    fn grades_scale_the_load_tolerance() {
        let t: Vec<f64> = (1..=3).map(|g| rate_tolerance(2.0, 16.0, 8.0, 100.0, g)).collect();
        assert!((t[0] / t[1] - 0.63).abs() < 1e-12 && (t[2] / t[1] - 1.6).abs() < 1e-12);
        assert!(t[1] > 0.015 && t[1] < 0.2, "{t:?}");
    }

    /// Buckling: a short, wide spring cannot buckle; a slender one buckles below its length.
    #[test]
    fn buckling() {
        let m = by_key("EN10270-1-SM").unwrap();
        let s = HelicalSpring { material: m, d: 2.0, dm: 20.0, n: 5.0 };
        assert_eq!(s.buckling_deflection(30.0, 0.5), None);
        let sk = s.buckling_deflection(300.0, 0.5).unwrap();
        assert!(sk > 0.0 && sk < 300.0, "{sk}");
        // Rate and stress are the closed forms.
        assert!((s.rate() - 81_500.0 * 16.0 / (8.0 * 8000.0 * 5.0)).abs() < 1e-9);
        assert!((s.stress(100.0) - shear_k(10.0) * 8.0 * 100.0 * 20.0 / (PI * 8.0)).abs() < 1e-9);
    }
}
