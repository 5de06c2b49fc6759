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
//! - Fatigue of compression and extension springs (shear): Goodman through Zimmerli's endurance
//!   data for spring steels under 10 mm (Budynas & Nisbett, *Shigley's Mechanical Engineering
//!   Design*, 9th ed., §10-9: unpeened S_sa = 241 MPa at S_sm = 379 MPa, shot-peened
//!   S_sa = 398 MPa at S_sm = 534 MPa, the same for every size, material and R_m: a thin wire's
//!   higher R_m does not raise them) to the ultimate strength in shear S_su = 0.67 R_m (Eq. 10-30):
//!   S_se = S_sa / (1 − S_sm/S_su), utilisation τ_a/S_se + τ_m/S_su. Zimmerli's data are for
//!   infinite life; below it the Table 10-8 fractions of R_m (36 / 33 / 30 % at 10⁵ / 10⁶ / 10⁷,
//!   not peened; 42 / 39 / 36 % peened) give the life, and the check takes the worse of the two.
//!   An extension spring's hook (a full loop, bent up from the end coil) is checked at its two
//!   critical sections, Shigley §10-10, Eqs. 10-34 to 10-37: bending at A,
//!   σ_A = F [(K)_A 16 D/(π d³) + 4/(π d²)], (K)_A = (4C₁² − C₁ − 1)/(4C₁(C₁ − 1)), C₁ = 2r₁/d
//!   (r₁ = D/2 for a full loop), and torsion at B, τ_B = (K)_B 8 F D/(π d³),
//!   (K)_B = (4C₂ − 1)/(4C₂ − 4), C₂ = 2r₂/d with the bend radius r₂ = 2d ([`HOOK_C2`]). Static
//!   limits from Shigley Table 10-7 (cold-drawn and music wire: torsion at the end 0.40 R_m,
//!   bending at the end 0.75 R_m); fatigue at B as the body, at A in bending with the endurance
//!   S_sa / 0.577 (distortion energy, as Shigley Example 10-8 does) against R_m.
//! - Fatigue of torsion springs (bending): a Goodman line through the endurance for repeated
//!   stress at the required cycles as a fraction of R_m and R_m itself: Shigley §10-12,
//!   Table 10-10 (A228 and 302 stainless: 53 / 50 % at 10⁵ / 10⁶ not peened, 62 / 60 % peened,
//!   extrapolated log-linearly beyond).
//! - Torsion legs: EN 13906-3 counts straight legs loaded as cantilevers by their bending, a
//!   third of their length each: the rate is E d⁴ / (64 D n_e) with n_e = n + (l₁ + l₂)/(3πD).
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

/// Zimmerli's endurance for unpeened springs (Shigley, 9th ed., §10-9): the alternating and mean
/// shear stress of the repeated-stress point, MPa.
pub const ZIMMERLI_UNPEENED: (f64, f64) = (241.0, 379.0);

/// Zimmerli's endurance for shot-peened springs (the same source), MPa.
pub const ZIMMERLI_PEENED: (f64, f64) = (398.0, 534.0);

/// C₂ = 2 r₂ / d of an extension spring's hook at its bend B: the bend radius r₂ = 2 d springfit
/// specifies (Shigley recommends C₂ > 4 be avoided below; 4 is the tightest bend it allows).
pub const HOOK_C2: f64 = 4.0;

/// The spring's surface: as wound, or shot-peened (a higher endurance, its own Zimmerli point).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Surface {
    /// As wound (stress-relieved), not peened.
    AsWound,
    /// Shot-peened.
    Peened,
}

impl Surface {
    /// `as wound` or `shot-peened`, as the bill and the sketches say it.
    pub fn name(self) -> &'static str {
        match self {
            Surface::AsWound => "as wound, not peened",
            Surface::Peened => "shot-peened",
        }
    }
}

/// How the wire is stressed: the two Goodman lines.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Loading {
    /// Torsion of the wire (compression and extension springs).
    Shear,
    /// Bending of the wire (torsion springs, leaf springs).
    Bending,
    /// Bending of an extension spring's hook at A: Zimmerli's shear endurance over 0.577 against R_m.
    HookBending,
}

impl Loading {
    /// Endurance for repeated stress (zero to maximum) at `cycles`, as a fraction of R_m
    /// (Shigley Tables 10-8 and 10-10).
    pub fn repeated_fraction(self, cycles: f64, surface: Surface) -> f64 {
        let table: &[(f64, f64)] = match (self, surface) {
            (Loading::Shear | Loading::HookBending, Surface::AsWound) => &[(5.0, 0.36), (6.0, 0.33), (7.0, 0.30)],
            (Loading::Shear | Loading::HookBending, Surface::Peened) => &[(5.0, 0.42), (6.0, 0.39), (7.0, 0.36)],
            (Loading::Bending, Surface::AsWound) => &[(5.0, 0.53), (6.0, 0.50)],
            (Loading::Bending, Surface::Peened) => &[(5.0, 0.62), (6.0, 0.60)],
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
            Loading::Bending | Loading::HookBending => rm,
        }
    }

    /// Goodman utilisation of a stress cycle between `lo` and `hi` (MPa) at `cycles`:
    /// σ_a / S_e + σ_m / S_u, where S_e is the fully reversed endurance on the line through the
    /// repeated-stress point. 1 is the limit. Shear (and the hook's bending) takes the worse of
    /// Zimmerli's infinite-life point and the Table 10-8 fraction at `cycles`.
    pub fn goodman(self, rm: f64, lo: f64, hi: f64, cycles: f64, surface: Surface) -> f64 {
        let su = self.ultimate(rm);
        let (a, m) = (0.5 * (hi - lo).abs(), 0.5 * (hi + lo));
        let line = |sa: f64, sm: f64| {
            let se = sa / (1.0 - sm / su).max(1e-9);
            a / se + m.max(0.0) / su
        };
        let half = 0.5 * self.repeated_fraction(cycles, surface) * rm;
        let table = match self {
            Loading::HookBending => line(half / 0.577, half / 0.577),
            _ => line(half, half),
        };
        let (za, zm) = match surface {
            Surface::AsWound => ZIMMERLI_UNPEENED,
            Surface::Peened => ZIMMERLI_PEENED,
        };
        match self {
            Loading::Shear => table.max(line(za, zm)),
            Loading::HookBending => table.max(line(za / 0.577, zm / 0.577)),
            Loading::Bending => table,
        }
    }

    /// Largest number of cycles (10⁵ to 10⁸, to 1e-10 in the exponent) whose Goodman utilisation
    /// stays ≤ `limit`; 0 when even 10⁵ fails. The utilisation grows with the cycles, so a
    /// bisection on the exponent finds it. Fine enough that a part within its fatigue limit at
    /// N cycles (utilisation ≤ 1) reports a life of at least N: a bracket of 1 % in the exponent
    /// once reported 991,046 cycles for a part at 0.999 of its limit at 10⁶.
    pub fn life(self, rm: f64, lo: f64, hi: f64, limit: f64, surface: Surface) -> f64 {
        let ok = |x: f64| self.goodman(rm, lo, hi, 10f64.powf(x), surface) <= limit;
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

/// Bending stress at the hook's section A of an extension spring with a full loop (r₁ = D/2) at
/// force `f` (N), MPa: Shigley Eq. 10-34/10-35.
pub fn hook_bending_stress(d: f64, dm: f64, f: f64) -> f64 {
    let c1 = dm / d;
    let ka = (4.0 * c1 * c1 - c1 - 1.0) / (4.0 * c1 * (c1 - 1.0));
    f.abs() * (ka * 16.0 * dm / (PI * d.powi(3)) + 4.0 / (PI * d * d))
}

/// Torsional stress at the hook's bend B (C₂ = [`HOOK_C2`]) at force `f` (N), MPa: Shigley
/// Eq. 10-36/10-37.
pub fn hook_torsion_stress(d: f64, dm: f64, f: f64) -> f64 {
    let kb = (4.0 * HOOK_C2 - 1.0) / (4.0 * HOOK_C2 - 4.0);
    kb * 8.0 * f.abs() * dm / (PI * d.powi(3))
}

/// The most elastic energy a unit volume of `material`'s wire can store in a helical extension
/// or compression spring under the checks this module applies, J/m³: round wire in torsion holds
/// u = τ²/(4G) at a uniform shear stress τ, and τ is at most the endurance for repeated stress at
/// `cycles` (and the static limit 0.45 R_m, whichever is lower) over `safety`, on the strongest
/// (thinnest) wire of the material, with the springs' `surface` (shot peening raises it). No part does better (the stress correction factor and the
/// cycle's mean stress only lower it), so U*/u·ρ is a lower bound on the mass of any springs that
/// store the energy U*: the floor `[fit] max_spring_mass` is checked against and that `fit`
/// reports its mass over (docs/parts.md, "The floor").
pub fn usable_energy_density(material: &Material, cycles: f64, safety: f64, surface: Surface) -> f64 {
    let fraction = Loading::Shear.repeated_fraction(cycles, surface).min(0.45);
    material
        .sizes()
        .iter()
        .filter_map(|&d| material.tensile_strength(d).map(|rm| (d, rm)))
        .map(|(d, rm)| {
            let tau = fraction * rm / safety.max(1.0);
            tau * tau / (4.0 * material.g_at(d)) * 1e6
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
    /// Rate in N·mm/rad with the legs' bending (EN 13906-3): E d⁴ / (64 D n_e),
    /// n_e = n + 2 l / (3πD) for two legs of length `leg` loaded as cantilevers.
    pub fn rate(&self) -> f64 {
        self.material.e_at(self.d) * self.d.powi(4) / (64.0 * self.dm * self.effective_coils())
    }

    /// n_e = n + (l₁ + l₂)/(3πD): the coils the legs' bending adds, EN 13906-3.
    pub fn effective_coils(&self) -> f64 {
        self.n + 2.0 * self.leg / (3.0 * PI * self.dm)
    }

    /// Active coils n for a rate `rate` (N·mm/rad) including the legs: n_e − 2l/(3πD).
    pub fn coils_for(material: &Material, d: f64, dm: f64, leg: f64, rate: f64) -> f64 {
        material.e_at(d) * d.powi(4) / (64.0 * dm * rate) - 2.0 * leg / (3.0 * PI * dm)
    }

    /// The part of a total wind angle `angle` (rad) the coils take (the rest bends the legs).
    pub fn body_angle(&self, angle: f64) -> f64 {
        angle * self.n / self.effective_coils()
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

    /// Body length wound by `angle` rad: (n + 1.5 + α_b/2π) d (each turn the coils are wound
    /// adds one wire; α_b = [`TorsionSpring::body_angle`], the legs take the rest).
    pub fn body_length(&self, angle: f64) -> f64 {
        (self.n + 1.5 + self.body_angle(angle.max(0.0)) / (2.0 * PI)) * self.d
    }

    /// Inner diameter wound by `angle` rad: the mean diameter shrinks to D n / (n + α_b/2π).
    pub fn inner_diameter(&self, angle: f64) -> f64 {
        self.dm * self.n / (self.n + self.body_angle(angle.max(0.0)) / (2.0 * PI)) - self.d
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
        self.material.g_at(self.d) * self.d.powi(4) / (8.0 * self.dm.powi(3) * self.n)
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
        let ge = self.material.g_at(self.d) / self.material.e_at(self.d);
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
        let u = usable_energy_density(m, 1e6, 1.1, Surface::AsWound);
        assert!((0.45e6..1.8e6).contains(&u), "{u}");
        assert!(usable_energy_density(m, 1e7, 1.1, Surface::AsWound) < u);
        assert!(usable_energy_density(m, 1e6, 1.5, Surface::AsWound) < u);
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
        let s = TorsionSpring { material: m, d: 2.0, dm: 16.0, n: 6.5, leg: 0.0 };
        let en = m.e * 16.0 / (3667.0 * 16.0 * 6.5);
        assert!((s.rate_per_degree() / en - 1.0).abs() < 1e-4, "{} vs {en}", s.rate_per_degree());
        // Winding one turn closes the coil diameter by D/(n + 1) and adds a wire to the body.
        assert!((s.inner_diameter(2.0 * PI) - (16.0 * 6.5 / 7.5 - 2.0)).abs() < 1e-12);
        assert!((s.body_length(2.0 * PI) - s.body_length(0.0) - 2.0).abs() < 1e-12);
    }

    /// Goodman in bending: a static stress uses the ultimate line, a repeated one lands on 1 at
    /// the tabulated endurance, more cycles allow less.
    #[test]
    fn goodman_and_life() {
        let rm = 1600.0;
        let aw = Surface::AsWound;
        let sr = 0.50 * rm;
        assert!((Loading::Bending.goodman(rm, 0.0, sr, 1e6, aw) - 1.0).abs() < 1e-12);
        assert!((Loading::Bending.goodman(rm, 500.0, 500.0, 1e6, aw) - 500.0 / rm).abs() < 1e-12);
        assert!(Loading::Bending.goodman(rm, 0.0, sr, 1e7, aw) > 1.0);
        assert!((Loading::Bending.repeated_fraction(3e5, aw) - (0.53 - 0.03 * 3f64.log10())).abs() < 1e-12);
        assert!((Loading::Bending.repeated_fraction(1e7, aw) - 0.47).abs() < 1e-12);
        let life = Loading::Bending.life(rm, 0.0, sr, 1.0, aw);
        assert!((life.log10() - 6.0).abs() <= 1e-9, "{life}");
        assert!(Loading::Bending.life(rm, 0.0, 0.999 * sr, 1.0, aw) >= 1e6);
        assert_eq!(Loading::Bending.life(rm, 0.0, rm, 1.0, aw), 0.0);
        // Peened torsion springs: Table 10-10's 60 % at 10⁶.
        assert!((Loading::Bending.goodman(rm, 0.0, 0.6 * rm, 1e6, Surface::Peened) - 1.0).abs() < 1e-12);
    }

    /// Zimmerli through Goodman in shear: the repeated-stress point (S_sm ± S_sa) is the limit
    /// whatever R_m (a thin wire's higher strength does not raise it beyond Zimmerli's point),
    /// peening raises it to its own point, and a static stress uses 0.67 R_m.
    #[test]
    fn zimmerli_goodman_in_shear() {
        for rm in [1400.0, 2000.0, 2600.0] {
            let (sa, sm) = ZIMMERLI_UNPEENED;
            let u = Loading::Shear.goodman(rm, sm - sa, sm + sa, 1e6, Surface::AsWound);
            // At Zimmerli's point exactly, unless Table 10-8's fraction of a weak wire is worse.
            let table = {
                let half = 0.5 * 0.33 * rm;
                let se = half / (1.0 - half / (0.67 * rm));
                sa / se + sm / (0.67 * rm)
            };
            assert!((u - table.max(1.0)).abs() < 1e-12, "R_m {rm}: {u}");
            let (pa, pm) = ZIMMERLI_PEENED;
            let p = Loading::Shear.goodman(rm, pm - pa, pm + pa, 1e7, Surface::Peened);
            assert!(p >= 1.0 - 1e-12, "{p}");
        }
        // 2000 MPa wire, 0 to 550 MPa: Table 10-8 alone (0.33 R_m = 660 MPa repeated) would pass
        // it; Zimmerli does not (S_se = 241/(1 − 379/1340) = 336 MPa: 275/336 + 275/1340 = 1.02).
        let u = Loading::Shear.goodman(2000.0, 0.0, 550.0, 1e6, Surface::AsWound);
        let se = 241.0 / (1.0 - 379.0 / 1340.0);
        assert!((u - (275.0 / se + 275.0 / 1340.0)).abs() < 1e-12 && u > 1.0, "{u}");
        assert!(Loading::Shear.goodman(2000.0, 0.0, 550.0, 1e6, Surface::Peened) < 1.0);
        assert!((Loading::Shear.goodman(2000.0, 500.0, 500.0, 1e6, Surface::AsWound) - 500.0 / 1340.0).abs() < 1e-12);
    }

    /// Shigley (9th ed.) Example 10-4: an unpeened music-wire compression spring, d = 0.092 in,
    /// OD = 9/16 in, loaded from 5 to 35 lbf; Zimmerli through Goodman. From the example's data
    /// (R_m = 201/0.092^0.145 kpsi, K_B of C = 5.115, S_se = 35/(1 − 55/S_su) kpsi) the Goodman
    /// factor of safety 1/u is 1.23 (recomputed here by hand from the example's data).
    #[test]
    fn shigley_example_10_4_zimmerli_goodman() {
        let kpsi = 6.894_757;
        let (d, od) = (0.092 * 25.4, 0.5625 * 25.4);
        let dm = od - d;
        let rm = 201.0 / 0.092f64.powf(0.145) * kpsi;
        let lbf = 4.448_222;
        let tau = |f: f64| shear_k(dm / d) * 8.0 * f * lbf * dm / (PI * d.powi(3));
        let u = Loading::Shear.goodman(rm, tau(5.0), tau(35.0), 1e7, Surface::AsWound);
        assert!((1.0 / u - 1.23).abs() < 0.01, "n_f = {}", 1.0 / u);
    }

    /// Shigley (9th ed.) Example 10-7: a hard-drawn extension spring, d = 0.035 in, OD = 0.248 in,
    /// hook radii r₁ = 0.106 in and r₂ = 0.089 in, at 5.25 lbf: the bending stress at A is
    /// 156.9 kpsi and the torsion at B 78.6 kpsi (recomputed from the example's data and its
    /// Eqs. 10-34 to 10-37; r₁ and r₂ are the example's, not springfit's defaults, so the
    /// factors are evaluated here with its C₁ and C₂).
    #[test]
    fn shigley_example_10_7_hook_stresses() {
        let (d, dm, f): (f64, f64, f64) = (0.035, 0.248 - 0.035, 5.25);
        let c1 = 2.0 * 0.106 / d;
        let ka = (4.0 * c1 * c1 - c1 - 1.0) / (4.0 * c1 * (c1 - 1.0));
        let sigma_a = f * (ka * 16.0 * dm / (PI * d.powi(3)) + 4.0 / (PI * d * d));
        assert!((sigma_a / 1000.0 - 156.9).abs() < 0.3, "{sigma_a}");
        let c2 = 2.0 * 0.089 / d;
        let kb = (4.0 * c2 - 1.0) / (4.0 * c2 - 4.0);
        let tau_b = kb * 8.0 * f * dm / (PI * d.powi(3));
        assert!((tau_b / 1000.0 - 78.6).abs() < 0.3, "{tau_b}");
        // springfit's full loop (r₁ = D/2) and bend (C₂ = 4) through the same equations.
        let ka_loop = (4.0 * (dm / d).powi(2) - dm / d - 1.0) / (4.0 * (dm / d) * (dm / d - 1.0));
        let expect = f * (ka_loop * 16.0 * dm / (PI * d.powi(3)) + 4.0 / (PI * d * d));
        assert!((hook_bending_stress(d, dm, f) - expect).abs() < 1e-9 * expect);
        assert!((hook_torsion_stress(d, dm, f) - 1.25 * 8.0 * f * dm / (PI * d.powi(3))).abs() < 1e-6);
    }

    /// EN 13906-3's legs: two legs of length l add 2l/(3πD) coils, and `coils_for` inverts it.
    #[test]
    fn torsion_legs_soften_the_rate() {
        let m = by_key("EN10270-1-DM").unwrap();
        let bare = TorsionSpring { material: m, d: 3.0, dm: 24.0, n: 3.0, leg: 0.0 };
        let legs = TorsionSpring { leg: 24.0, ..bare };
        let ne = 3.0 + 48.0 / (3.0 * PI * 24.0);
        assert!((legs.rate() / bare.rate() - 3.0 / ne).abs() < 1e-12);
        let n = TorsionSpring::coils_for(m, 3.0, 24.0, 24.0, bare.rate());
        assert!((TorsionSpring { n, ..legs }.rate() / bare.rate() - 1.0).abs() < 1e-12);
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
