//! Spring materials: elastic moduli, density and the tensile strength R_m of the wire (or strip)
//! as a function of its size, each value with the source it was read from.
//!
//! Allowable stresses are fractions of R_m (see [`crate::realise::spring`]), so R_m at the wire's
//! own diameter is what decides whether a spring holds: thin wire is drawn harder than thick.
//! The EN 10270-1 table lists the minimum R_m at each nominal diameter the standard tabulates;
//! springfit designs only with those diameters (they are the sizes wire is sold in) and reads the
//! minimum, never an interpolated value.

/// How R_m depends on the size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Strength {
    /// Minimum R_m (MPa) at each nominal diameter (mm), as tabulated.
    Table(&'static [(f64, f64)]),
    /// R_m = A / d^m (MPa, d in mm) over a diameter range, with the sizes to design with.
    Power {
        /// A, MPa·mm^m: R_m of a 1 mm wire.
        a: f64,
        /// The exponent m, dimensionless.
        m: f64,
        /// The wire diameters designed with, mm, thinnest first: the first and last bound the
        /// range the formula holds over.
        sizes: &'static [f64],
    },
    /// R_m = A / d^m piece by piece: `(upper diameter, A, m)` from the thinnest piece up, each
    /// piece reaching from the previous piece's upper diameter (or the first size) to its own;
    /// a diameter on a boundary takes the thinner piece, as the source's ranges are written.
    PowerPieces {
        /// `(upper diameter in mm, A in MPa·mm^m, m)` per piece, thinnest first.
        pieces: &'static [(f64, f64, f64)],
        /// The wire diameters designed with, mm, thinnest first.
        sizes: &'static [f64],
    },
    /// One R_m (MPa) for every thickness in the listed sizes (mm): strip.
    Constant {
        /// R_m, MPa.
        rm: f64,
        /// The strip thicknesses designed with, mm.
        sizes: &'static [f64],
    },
}

/// A spring material.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    /// The key written in `[parts] material`.
    pub key: &'static str,
    /// What a spring maker calls it.
    pub name: &'static str,
    /// Young's modulus E, MPa.
    pub e: f64,
    /// Shear modulus G, MPa: the value at every size unless `moduli_by_size` says otherwise.
    pub g: f64,
    /// `(upper diameter mm, E MPa, G MPa)` by size range, thinnest first, where the source states
    /// the moduli by size (music wire: Shigley's Table 10-5, whose G spans 80.0–82.7 GPa, 3.4 %,
    /// enough to move a thin spring's rate by 2 %); empty when `e` and `g` hold at every size.
    /// A size on a boundary takes the thinner range; above the last, the last range holds.
    pub moduli_by_size: &'static [(f64, f64, f64)],
    /// Density, kg/m³.
    pub density: f64,
    /// R_m by size.
    pub strength: Strength,
    /// Where every value above comes from.
    pub source: &'static str,
}

impl Material {
    /// The sizes (wire diameters or strip thicknesses, mm) springfit designs with, thinnest first.
    pub fn sizes(&self) -> Vec<f64> {
        match self.strength {
            Strength::Table(t) => t.iter().map(|r| r.0).collect(),
            Strength::Power { sizes, .. } | Strength::PowerPieces { sizes, .. } | Strength::Constant { sizes, .. } => {
                sizes.to_vec()
            }
        }
    }

    /// Young's modulus E (MPa) of wire of size `d` (mm).
    pub fn e_at(&self, d: f64) -> f64 {
        self.moduli_at(d).map_or(self.e, |m| m.1)
    }

    /// Shear modulus G (MPa) of wire of size `d` (mm).
    pub fn g_at(&self, d: f64) -> f64 {
        self.moduli_at(d).map_or(self.g, |m| m.2)
    }

    fn moduli_at(&self, d: f64) -> Option<(f64, f64, f64)> {
        let ranges = self.moduli_by_size;
        ranges.iter().find(|r| d <= r.0 + 1e-9).or(ranges.last()).copied()
    }

    /// Minimum tensile strength R_m at size `d` (mm), MPa; None outside the tabulated sizes.
    pub fn tensile_strength(&self, d: f64) -> Option<f64> {
        match self.strength {
            Strength::Table(t) => t.iter().find(|r| (r.0 - d).abs() < 1e-9).map(|r| r.1),
            Strength::Power { a, m, sizes } => {
                let (lo, hi) = (sizes[0], sizes[sizes.len() - 1]);
                (lo - 1e-9..=hi + 1e-9).contains(&d).then(|| a / d.powf(m))
            }
            Strength::PowerPieces { pieces, sizes } => {
                let inside = (sizes[0] - 1e-9..=pieces[pieces.len() - 1].0 + 1e-9).contains(&d);
                let piece = pieces.iter().find(|p| d <= p.0 + 1e-9);
                piece.filter(|_| inside).map(|&(_, a, m)| a / d.powf(m))
            }
            Strength::Constant { rm, sizes } => sizes.iter().any(|s| (s - d).abs() < 1e-9).then_some(rm),
        }
    }
}

/// EN 10270-1 grade SM (and DM, which the standard gives the same R_m): the lower bound of the
/// R_m range at each nominal diameter 0.3–20 mm. The row for 15.0 mm, published as 1160–1260
/// (above its neighbours 1130 at 14 mm and 1090 at 16 mm, a misprint), is left out.
const EN10270_1_SM: &[(f64, f64)] = &[
    (0.3, 2370.0),
    (0.4, 2270.0),
    (0.5, 2200.0),
    (0.6, 2140.0),
    (0.7, 2090.0),
    (0.8, 2050.0),
    (0.9, 2010.0),
    (1.0, 1980.0),
    (1.1, 1950.0),
    (1.2, 1920.0),
    (1.3, 1900.0),
    (1.4, 1870.0),
    (1.5, 1850.0),
    (1.6, 1830.0),
    (1.7, 1810.0),
    (1.8, 1790.0),
    (1.9, 1770.0),
    (2.0, 1760.0),
    (2.1, 1740.0),
    (2.4, 1700.0),
    (2.5, 1690.0),
    (2.6, 1670.0),
    (2.8, 1650.0),
    (3.0, 1630.0),
    (3.2, 1610.0),
    (3.4, 1590.0),
    (3.5, 1580.0),
    (3.6, 1570.0),
    (3.8, 1550.0),
    (4.0, 1530.0),
    (4.5, 1500.0),
    (5.0, 1460.0),
    (5.5, 1430.0),
    (6.0, 1400.0),
    (6.5, 1380.0),
    (7.0, 1350.0),
    (7.5, 1330.0),
    (8.0, 1310.0),
    (8.5, 1290.0),
    (9.0, 1270.0),
    (9.5, 1260.0),
    (10.0, 1240.0),
    (10.5, 1220.0),
    (11.0, 1210.0),
    (12.0, 1180.0),
    (12.5, 1170.0),
    (13.0, 1160.0),
    (14.0, 1130.0),
    (16.0, 1090.0),
    (17.0, 1070.0),
    (18.0, 1050.0),
    (19.0, 1030.0),
    (20.0, 1020.0),
];

/// Music-wire sizes (mm) inside the range of the A228 fit (0.10–6.5 mm).
const MUSIC_WIRE_SIZES: &[f64] = &[
    0.2, 0.25, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.2, 1.4, 1.6, 1.8, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 5.5, 6.0,
    6.5,
];

/// Stainless wire sizes (mm) inside the range of the A313 fit (0.3–10 mm).
const STAINLESS_WIRE_SIZES: &[f64] = &[
    0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.2, 1.4, 1.6, 1.8, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 5.5, 6.0, 7.0, 8.0,
    9.0, 10.0,
];

/// Shigley's Table 10-5 for A228 music wire: (upper diameter mm, E MPa, G MPa). The table's ranges
/// (< 0.032, 0.033–0.063, 0.064–0.125, > 0.125 in) leave gaps of 0.001 in, split at their middle.
const A228_MODULI: &[(f64, f64, f64)] = &[
    (0.0325 * 25.4, 203_400.0, 82_700.0),
    (0.0635 * 25.4, 200_000.0, 81_700.0),
    (0.125 * 25.4, 196_500.0, 81_000.0),
    (f64::INFINITY, 193_000.0, 80_000.0),
];

/// Shigley's fit of ASTM A313 type 302 by diameter range: (upper diameter mm, A MPa·mm^m, m).
const A313_302_PIECES: &[(f64, f64, f64)] = &[(2.5, 1867.0, 0.146), (5.0, 2065.0, 0.263), (10.0, 2911.0, 0.478)];

/// Oil-tempered wire sizes (mm) inside the range of Shigley's A229 fit (0.5–12.7 mm).
const OIL_TEMPERED_SIZES: &[f64] = &[
    0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.2, 1.4, 1.6, 1.8, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 5.5, 6.0, 7.0, 8.0, 9.0, 10.0,
    11.0, 12.0,
];

/// Chrome-vanadium wire sizes (mm) inside the range of Shigley's A232 fit (0.8–11.1 mm).
const CHROME_VANADIUM_SIZES: &[f64] =
    &[0.8, 0.9, 1.0, 1.2, 1.4, 1.6, 1.8, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 5.5, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0];

/// Chrome-silicon wire sizes (mm) inside the range of Shigley's A401 fit (1.6–9.5 mm).
const CHROME_SILICON_SIZES: &[f64] = &[1.6, 1.8, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 5.5, 6.0, 7.0, 8.0, 9.0, 9.5];

/// Where the constants of Shigley's Tables 10-4 and 10-5 for the oil-tempered and alloy wires
/// were checked, value by value, besides the book's own Table 10-5 page: two public programs that
/// encode the 9th edition's SI columns (read, not used as code). A macro, so that `concat!` can
/// append it to each wire's `source`.
macro_rules! shigley_alloy_checks {
    () => {
        "; every constant checked against github.com/the-faboratory/SpringSensorDesignTool \
         (materialPropertySelector.m, Tables 10-4 and 10-5 combined: d range, A, m, E, G) and \
         github.com/ahmedbma/clnew (spring-math.js, Table 10-4: A, m, largest d; G), and Table 10-5 against the \
         book's p. 526 (the copy at digilib.universitaspertamina.ac.id, page552.html)"
    };
}

/// Where `ASTM-A229`'s values come from (the EN 10270-2 oil-tempered table could not be read).
const A229_SOURCE: &str = concat!(
    "Budynas & Nisbett, Shigley's Mechanical Engineering Design (9th ed.), Table 10-4: R_m = A/d^m, \
     A = 1855 MPa·mm^m, m = 0.187 for OQ&T wire A229, 0.5–12.7 mm; Table 10-5 (p. 526): E = 196.5 GPa, \
     G = 77.2 GPa; density of steel 7850 kg/m³. Shigley's values, not EN 10270-2's (whose R_m table \
     for the oil-hardened and tempered grades could not be read in full)",
    shigley_alloy_checks!()
);

/// Where `ASTM-A232`'s values come from.
const A232_SOURCE: &str = concat!(
    "Budynas & Nisbett, Shigley's Mechanical Engineering Design (9th ed.), Table 10-4: R_m = A/d^m, \
     A = 2005 MPa·mm^m, m = 0.168 for chrome-vanadium wire A232, 0.8–11.1 mm; Table 10-5 (p. 526): \
     E = 203.4 GPa, G = 77.2 GPa; density of steel 7850 kg/m³",
    shigley_alloy_checks!()
);

/// Where `ASTM-A401`'s values come from (EN 10270-2's VDSiCr rows could not be read in full).
const A401_SOURCE: &str = concat!(
    "Budynas & Nisbett, Shigley's Mechanical Engineering Design (9th ed.), Table 10-4: R_m = A/d^m, \
     A = 1974 MPa·mm^m, m = 0.108 for chrome-silicon wire A401, 1.6–9.5 mm; Table 10-5 (p. 526): \
     E = 203.4 GPa, G = 77.2 GPa; density of steel 7850 kg/m³. Shigley's values, not EN 10270-2's \
     VDSiCr table (only its 0.5–0.7 mm rows could be read)",
    shigley_alloy_checks!()
);

/// Strip thicknesses (mm) within the range EN 10132-4 states R_m for (0.3 ≤ t < 3 mm).
const STRIP_SIZES: &[f64] = &[0.3, 0.4, 0.5, 0.6, 0.8, 1.0, 1.2, 1.5, 2.0, 2.5];

/// A wire whose R_m is Shigley's Table 10-4 fit A/d^m over its diameter range and whose moduli
/// are Table 10-5's one E and G: `(key, name)`, `(E, G, A, m, sizes)` (MPa, MPa, MPa·mm^m, –, mm) and
/// the source.
const fn shigley_wire(
    (key, name): (&'static str, &'static str),
    (e, g, a, m, sizes): (f64, f64, f64, f64, &'static [f64]),
    source: &'static str,
) -> Material {
    Material {
        key,
        name,
        e,
        g,
        density: 7850.0,
        moduli_by_size: &[],
        strength: Strength::Power { a, m, sizes },
        source,
    }
}

/// The material table.
pub const MATERIALS: &[Material] = &[
    Material {
        key: "EN10270-1-SM",
        name: "patented cold-drawn unalloyed spring steel wire EN 10270-1 grade SM (static)",
        e: 206_000.0,
        g: 81_500.0,
        density: 7850.0,
        moduli_by_size: &[],
        strength: Strength::Table(EN10270_1_SM),
        source: "EN 10270-1 grade SM: density 7.85 kg/dm³, E = 206 kN/mm², G = 81.5 kN/mm² and the R_m ranges by \
                 diameter as published by Mollificio Modenese, https://www.mollificiomodenese.it/en/glossary/\
                 acciaio-uni-en-10270-1-scarbon-steel-uni-en-10270-1-sm-sh-dhm-sh-dh/ (lower bounds used); DM has the \
                 same R_m (EN 10270-1 table as published by Hengming, https://hengmingsteelwire.com/\
                 patented-cold-drawn-unalloyed-spring-steel-wire.html)",
    },
    Material {
        key: "EN10270-1-DM",
        name: "patented cold-drawn unalloyed spring steel wire EN 10270-1 grade DM (dynamic, medium)",
        e: 206_000.0,
        g: 81_500.0,
        density: 7850.0,
        moduli_by_size: &[],
        strength: Strength::Table(EN10270_1_SM),
        source: "EN 10270-1 grade DM: the standard gives DM the R_m ranges of SM at every diameter, as published by \
                 Hengming, https://hengmingsteelwire.com/patented-cold-drawn-unalloyed-spring-steel-wire.html, and by \
                 Durofer, https://durofer.ch/en/products/wire/spring-wire (lower bounds used; the table is SM's, \
                 from Mollificio Modenese); E, G and density as for SM. DM is the dynamic grade (cleaner steel, \
                 Cu ≤ 0.12 %): its fatigue is judged by Zimmerli's data, which do not depend on R_m",
    },
    Material {
        key: "ASTM-A228",
        name: "music wire ASTM A228",
        e: 196_500.0,
        g: 81_000.0,
        density: 7850.0,
        moduli_by_size: A228_MODULI,
        strength: Strength::Power { a: 2211.0, m: 0.145, sizes: MUSIC_WIRE_SIZES },
        source: "Budynas & Nisbett, Shigley's Mechanical Engineering Design (9th ed.), Table 10-4: R_m = A/d^m, \
                 A = 2211 MPa·mm^m, m = 0.145 for A228 music wire 0.10–6.5 mm; Table 10-5: E and G by diameter \
                 (< 0.032 in: 203.4 / 82.7 GPa; 0.033–0.063 in: 200 / 81.7; 0.064–0.125 in: 196.5 / 81.0; \
                 > 0.125 in: 193 / 80.0), the gaps between its ranges split at their middle; `e` and `g` are \
                 the 0.064–0.125 in row, for what has no size; density of steel 7850 kg/m³",
    },
    Material {
        key: "ASTM-A313-302",
        name: "stainless spring wire ASTM A313 type 302 (X10CrNi18-8, 1.4310, the steel of EN 10270-3 grade NS)",
        e: 193_000.0,
        g: 69_000.0,
        density: 7900.0,
        moduli_by_size: &[],
        strength: Strength::PowerPieces { pieces: A313_302_PIECES, sizes: STAINLESS_WIRE_SIZES },
        source: "Budynas & Nisbett, Shigley's Mechanical Engineering Design (9th ed.), Table 10-4: R_m = A/d^m for \
                 A313 302 stainless, 0.3–2.5 mm A = 1867 MPa·mm^m, m = 0.146; 2.5–5 mm A = 2065, m = 0.263; 5–10 mm \
                 A = 2911, m = 0.478; Table 10-5: E = 193 GPa, G = 69.0 GPa; density 7.9 kg/dm³ (EN 10088-1 for \
                 X10CrNi18-8); 1.4310 = AISI 302 (EN 10270-3 grades as published by Metalle Schmidt, \
                 https://metalleschmidt.de/en/wire/stainless-steel). EN 10270-3's own R_m table is not reproduced: \
                 the A313 fit is what springfit designs with",
    },
    shigley_wire(
        ("ASTM-A229", "oil-quenched and tempered carbon spring wire ASTM A229 (OQ&T)"),
        (196_500.0, 77_200.0, 1855.0, 0.187, OIL_TEMPERED_SIZES),
        A229_SOURCE,
    ),
    shigley_wire(
        ("ASTM-A232", "chrome-vanadium valve-spring-quality wire ASTM A232 (AISI 6150)"),
        (203_400.0, 77_200.0, 2005.0, 0.168, CHROME_VANADIUM_SIZES),
        A232_SOURCE,
    ),
    shigley_wire(
        ("ASTM-A401", "chrome-silicon alloy spring wire ASTM A401 (AISI 9254, oil-tempered)"),
        (203_400.0, 77_200.0, 1974.0, 0.108, CHROME_SILICON_SIZES),
        A401_SOURCE,
    ),
    Material {
        key: "EN10132-4-C67S",
        name: "spring steel strip EN 10132-4 C67S, hardened and tempered",
        e: 206_000.0,
        g: 81_500.0,
        density: 7850.0,
        moduli_by_size: &[],
        strength: Strength::Constant { rm: 1200.0, sizes: STRIP_SIZES },
        source: "EN 10132-4 C67S after hardening and tempering, 0.3 ≤ t < 3 mm: R_m 1200–1700 MPa (lower bound used), \
                 as published by Akrostal, https://akrostal.pl/cs/?p=2577; E, G and density as for EN 10270-1 steel",
    },
];

/// The wire materials a spring may be wound from (the strip is for leaf springs only).
pub fn wire_keys() -> Vec<&'static str> {
    MATERIALS.iter().filter(|m| !matches!(m.strength, Strength::Constant { .. })).map(|m| m.key).collect()
}

/// The material of `key`, or None.
pub fn by_key(key: &str) -> Option<&'static Material> {
    MATERIALS.iter().find(|m| m.key == key)
}

/// The strip for leaf springs.
pub fn strip() -> &'static Material {
    by_key("EN10132-4-C67S").expect("the table has the strip")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thin_wire_is_stronger_and_lookups_are_exact() {
        for m in MATERIALS {
            let sizes = m.sizes();
            assert!(sizes.windows(2).all(|w| w[0] < w[1]), "{}: sizes ascend", m.key);
            let rm: Vec<f64> = sizes.iter().map(|&d| m.tensile_strength(d).unwrap()).collect();
            assert!(rm.windows(2).all(|w| w[0] >= w[1]), "{}: R_m falls with size: {rm:?}", m.key);
        }
        let sm = by_key("EN10270-1-SM").unwrap();
        assert_eq!(sm.tensile_strength(1.0), Some(1980.0));
        assert_eq!(sm.tensile_strength(1.05), None, "only tabulated diameters");
        // Shigley's fit at 1 mm is A itself.
        assert_eq!(by_key("ASTM-A228").unwrap().tensile_strength(1.0), Some(2211.0));
        // Shigley's A313 pieces meet within 1 % at 2.5 and 5 mm, and a boundary takes the thinner piece.
        let ss = by_key("ASTM-A313-302").unwrap();
        assert!((ss.tensile_strength(2.5).unwrap() - 1867.0 / 2.5f64.powf(0.146)).abs() < 1e-9);
        assert!((ss.tensile_strength(3.0).unwrap() - 2065.0 / 3.0f64.powf(0.263)).abs() < 1e-9);
        for (d, lo, hi) in [(2.5, (1867.0, 0.146), (2065.0, 0.263)), (5.0, (2065.0, 0.263), (2911.0, 0.478))] {
            let (a, b) = (lo.0 / f64::powf(d, lo.1), hi.0 / f64::powf(d, hi.1));
            assert!((a - b).abs() / a < 0.01, "pieces meet at {d} mm: {a} vs {b}");
        }
        assert_eq!(ss.tensile_strength(10.5), None);
        // The oil-tempered and alloy wires of Shigley's Table 10-4: A at 1 mm where 1 mm is in the
        // range, the formula at the range's ends, nothing outside it, the moduli of Table 10-5.
        for (key, a, m, lo, hi, e) in [
            ("ASTM-A229", 1855.0, 0.187, 0.5, 12.0, 196_500.0),
            ("ASTM-A232", 2005.0, 0.168, 0.8, 11.0, 203_400.0),
            ("ASTM-A401", 1974.0, 0.108, 1.6, 9.5, 203_400.0),
        ] {
            let w = by_key(key).unwrap();
            assert_eq!((w.e_at(2.0), w.g_at(2.0)), (e, 77_200.0), "{key}: Table 10-5");
            for d in [lo, hi] {
                assert!((w.tensile_strength(d).unwrap() - a / f64::powf(d, m)).abs() < 1e-9, "{key} at {d} mm");
            }
            assert_eq!(w.tensile_strength(lo - 0.1), None, "{key}: below its range");
            assert_eq!(w.tensile_strength(hi + 0.1), None, "{key}: above its range");
            assert!(lo > 1.0 || w.tensile_strength(1.0) == Some(a), "{key}: A is R_m at 1 mm");
        }
        assert_eq!(wire_keys(), crate::design::parts::MATERIALS, "the design file accepts exactly the table's wires");
    }
}
