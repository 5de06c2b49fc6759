//! The bill of materials as springfit computes with it: one row per element the fit uses (a
//! cam as one row per non-zero signed B-spline coefficient, `C01.07+`, each carrying its cam's
//! summary), with what the builder needs (peak torque, deflection, tolerance, preload, what can be
//! set after assembly). `files::bom` writes it as `bom.csv` (a cam collapsed into one row and its
//! file) and reads it back bit for bit.

use super::problem::{coupling_classes, mid_range};
use crate::design::Design;
use crate::elements::catalog::{Candidate, Catalog};
use crate::elements::group::Grouping;
use crate::elements::spline::Knots;
use crate::elements::{Element, Profile};
use crate::geodesic::Fan;
use crate::potential::SpringSet;
use crate::realise::cam::{CamBuild, DEFAULT_REALISATION, FittedCam, Realisation, realise};
use rayon::prelude::*;

/// What can be set on an element after assembly.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Adjustment {
    /// ± rad the offset x₀ can be moved (an adjustable family), None if fixed.
    pub adjust_range: Option<f64>,
    /// The rate range [lo, hi] of a trim spring, N·m/rad; None if not a trim.
    pub trim_range: Option<[f64; 2]>,
}

/// What the bill of materials says about a whole cam, carried by each of its coefficient rows
/// (the figures of its one row in `bom.csv`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CamSummary {
    /// How it is built (follower rate, preload, gear ratio, radii).
    pub build: CamBuild,
    /// Largest |V′(x)| over the region, N·m.
    pub max_torque_nm: f64,
    /// V′ at the equilibrium, N·m (signed; None when unknown).
    pub preload_nm: Option<f64>,
}

/// One row of the bill of materials.
#[derive(Debug, Clone, PartialEq)]
pub struct BomRow {
    /// `S01`, `S02`, …; `C01.07+` for a cam's coefficient.
    pub id: String,
    /// The catalogue family's name.
    pub family: String,
    /// The element.
    pub element: Element,
    /// Fitted stiffness in the profile's unit.
    pub stiffness: f64,
    /// Largest torque on the element's transmission coordinate over the region, N·m (a cam
    /// coefficient read from a file: the cam's).
    pub max_torque_nm: f64,
    /// Largest deflection |x − x₀| while engaged over the region, rad (a cam coefficient read
    /// from a file: the knot span).
    pub max_deflection_rad: f64,
    /// The nearest stock rate the catalogue offers, if it lists any.
    pub stock_rate: Option<f64>,
    /// ± fraction the built element may deviate.
    pub tolerance: f64,
    /// Torque on the element's coordinate at the equilibrium, k·u′(a·q_eq − x₀), N·m (signed).
    /// None when read from a file without the column (and for a cam's coefficients read back).
    pub preload_nm: Option<f64>,
    /// What can be set after assembly.
    pub adjust: Adjustment,
    /// The cam this coefficient belongs to (None for springs and for cams of older files).
    pub cam: Option<CamSummary>,
    /// The signed pulley radii (mm, one per joint, 0 where the cable does not cross) of the
    /// tendon that makes the coupling, when a tendon family of the catalogue generated it
    /// ([`Catalog::pulleys`]); None otherwise. A bill read back from `bom.csv` gets them from
    /// the catalogue in [`realise_parts`], so choosing parts never reads the catalogue again.
    pub pulleys_mm: Option<Vec<f64>>,
}

/// The spring set a bill of materials describes.
pub fn spring_set(rows: &[BomRow]) -> SpringSet {
    SpringSet {
        elements: rows.iter().map(|r| r.element.clone()).collect(),
        stiffness: rows.iter().map(|r| r.stiffness).collect(),
    }
}

/// A fingerprint of a spring set: FNV-1a over every element's profile, coupling, offset and
/// stiffness, bit for bit, in order. A fit's `summary.json` and a simulation's `sim_<name>.json`
/// both carry it (`spring_set`), so `compare` can tell whether a simulation used the springs of
/// a fit (reading `bom.csv` back gives the same set bit for bit, hence the same fingerprint).
pub fn fingerprint(set: &SpringSet) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for b in bytes {
            h ^= *b as u64;
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    for (e, k) in set.elements.iter().zip(&set.stiffness) {
        eat(format!("{:?}", e.profile).as_bytes());
        for a in &e.coupling {
            eat(&a.to_bits().to_le_bytes());
        }
        eat(&e.offset.to_bits().to_le_bytes());
        eat(&k.to_bits().to_le_bytes());
        eat(&[0xff]);
    }
    format!("{h:016x}")
}

/// The cams of a bill of materials: rows `Cnn.jj±` grouped by `Cnn`, coefficients summed with
/// their signs, realised with their family's settings (defaults when the family is unknown, as
/// for a bill of materials read back without its catalogue).
pub fn fitted_cams(catalog: &Catalog, rows: &[BomRow]) -> Vec<FittedCam> {
    let mut cams = grouped(rows);
    for c in &mut cams {
        let spec = catalog.families.iter().find(|f| f.name == c.family).and_then(|f| f.cam);
        let (rate, stroke, preload, rb, rr, alpha) = spec.map_or(DEFAULT_REALISATION, |s| {
            (s.follower_rate, s.max_stroke, s.preload_fraction, s.base_radius, s.roller_radius, s.max_pressure_angle)
        });
        c.realisation = realise(&c.knots, &c.coefficients, rate, stroke, preload, rb, rr, alpha, 1000);
    }
    cams
}

/// The cams of a bill of materials grouped as in [`fitted_cams`], in order of first appearance,
/// not yet realised (`realisation.points` empty).
pub fn grouped(rows: &[BomRow]) -> Vec<FittedCam> {
    let mut cams: Vec<FittedCam> = Vec::new();
    for r in rows {
        let crate::elements::Profile::Spline(b) = r.element.profile else { continue };
        let id = r.id.split('.').next().unwrap_or(&r.id).to_string();
        let pos = match cams.iter().position(|c| c.id == id) {
            Some(p) => p,
            None => {
                let knots = Knots { lo: r.element.offset, width: b.width(), count: b.count };
                cams.push(FittedCam {
                    id,
                    family: r.family.clone(),
                    coupling: r.element.coupling.clone(),
                    knots,
                    coefficients: vec![0.0; knots.basis_count()],
                    realisation: Realisation {
                        build: CamBuild {
                            follower_rate: 0.0,
                            preload: 0.0,
                            gear_ratio: 1.0,
                            base_radius: 0.0,
                            roller_radius: 0.0,
                        },
                        points: Vec::new(),
                        max_pressure_angle: 0.0,
                        min_convex_curvature: 0.0,
                        violations: Vec::new(),
                    },
                });
                cams.len() - 1
            }
        };
        let c = &mut cams[pos];
        if let Some(cj) = c.coefficients.get_mut(usize::from(b.index)) {
            *cj += if b.negative { -r.stiffness } else { r.stiffness };
        }
    }
    cams
}

/// Appends the catalogue's trim springs, at mid-range, to a fitted bill of materials.
///
/// Trims are not fit candidates (their rate is set after assembly, so the fit must not choose
/// it), and the element budget counts the fitted elements, not the trims. The fit has already
/// been solved *around* them: their contribution at mid-range was moved to the right-hand sides
/// of the rows, the equalities and the inequalities before both the nominal and the
/// tolerance-aware solve (`fit::problem::fold_fixed`), so the other rows need no change here.
/// Peak torque and deflection are taken over the held-out fan `evaluation`, as the fit's.
pub fn append(design: &Design, catalog: &Catalog, bom: &mut Vec<BomRow>, evaluation: &Fan) {
    let (trims, springs) = mid_range(catalog, design.q_eq.as_slice());
    // Trims are numbered after the springs (a cam's rows keep their `Cnn.jj±` ids).
    let first = bom.iter().filter(|r| !matches!(r.element.profile, crate::elements::Profile::Spline(_))).count();
    for (i, t) in trims.iter().enumerate() {
        let f = &catalog.families[t.family];
        let stiffness = springs.stiffness[i];
        let e = &t.element;
        let (mut torque, mut defl) = (0.0f64, 0.0f64);
        let mut visit = |q: &[f64]| {
            let d = e.deflection(q);
            torque = torque.max((stiffness * e.profile.slope(d)).abs());
            defl = defl.max(d.abs());
        };
        visit(design.q_eq.as_slice());
        for g in &evaluation.geodesics {
            for s in 0..g.len() {
                visit(g.q(s));
            }
        }
        bom.push(BomRow {
            id: format!("S{:02}", first + i + 1),
            family: f.name.clone(),
            element: e.clone(),
            stiffness,
            max_torque_nm: torque,
            max_deflection_rad: defl,
            stock_rate: None,
            tolerance: f.tolerance,
            adjust: Adjustment { adjust_range: None, trim_range: Some(t.range) },
            // Relaxed at q_eq: no torque there.
            preload_nm: Some(e.preload(stiffness, design.q_eq.as_slice())),
            cam: None,
            pulleys_mm: catalog.pulleys(&f.name, &e.coupling).map(<[f64]>::to_vec),
        });
    }
}

/// The used elements as bill-of-materials rows: every element whose peak torque over the region
/// is above `threshold` × the largest, and every column of a group with k > 0 (a part's
/// columns only make sense together). Springs are numbered `S01`, …; a group's rows
/// `C01.07+` (the group's id, the coefficient, the sign).
pub fn bill_of_materials(
    catalog: &Catalog,
    candidates: &[Candidate],
    grouping: &Grouping,
    k: &[f64],
    evaluation: &Fan,
    q_eq: &[f64],
    threshold: f64,
) -> Vec<BomRow> {
    let k = signed_coefficients(grouping, k);
    let k = k.as_slice();
    let peaks = peaks(candidates, k, evaluation, q_eq);
    let max_peak = peaks.iter().map(|p| p.0).fold(0.0, f64::max);
    let in_group = |j: usize| grouping.of[j].is_some();
    let used: Vec<usize> =
        (0..candidates.len()).filter(|&j| k[j] > 0.0 && (in_group(j) || peaks[j].0 > threshold * max_peak)).collect();
    let coefficient = grouping.coefficient_of();
    // Springs are numbered S01, S02, … among themselves: a group's columns carry the group's id.
    let mut springs = 0;
    used.iter()
        .map(|&j| {
            let c = &candidates[j];
            let stock_rate = nearest(&c.stock_rates, k[j]);
            let id = match (grouping.of[j], coefficient[j]) {
                (Some(g), Some((c, negative))) => {
                    format!("{}.{c:02}{}", grouping.groups[g].id(g), if negative { "-" } else { "+" })
                }
                _ => {
                    springs += 1;
                    format!("S{springs:02}")
                }
            };
            let family = &catalog.families[c.family].name;
            BomRow {
                id,
                family: family.clone(),
                element: c.element.clone(),
                stiffness: k[j],
                max_torque_nm: peaks[j].0,
                max_deflection_rad: peaks[j].1,
                stock_rate,
                tolerance: c.tolerance,
                preload_nm: Some(c.element.preload(k[j], q_eq)),
                adjust: Adjustment { adjust_range: catalog.families[c.family].adjust_range, trim_range: None },
                cam: None,
                pulleys_mm: catalog.pulleys(family, &c.element.coupling).map(<[f64]>::to_vec),
            }
        })
        .collect()
}

/// A group's + and − columns as one signed coefficient cⱼ = k⁺ − k⁻ on the column of its sign,
/// as `bom.csv` writes it: the set evaluated from the bill is the one its files rebuild. (The
/// solve already leaves one of each pair at zero; then this changes no bit.)
fn signed_coefficients(grouping: &Grouping, k: &[f64]) -> Vec<f64> {
    let mut k = k.to_vec();
    for (j, n) in grouping.minus_of().into_iter().enumerate() {
        if let Some(n) = n
            && k[j] > 0.0
            && k[n] > 0.0
        {
            let c = k[j] - k[n];
            k[j] = c.max(0.0);
            k[n] = (-c).max(0.0);
        }
    }
    k
}

/// Peak torque on x and engaged deflection of each candidate over the region (the equilibrium
/// and the held-out samples), in parallel over the couplings (a·q at the held-out samples,
/// 10⁵–10⁶ of them for a whole arm, computed once per coupling for all its candidates). Only
/// used columns (k ≠ 0) are computed; an unused one adds nothing to the largest peak (its
/// torque is zero) and is left at (0, 0).
fn peaks(candidates: &[Candidate], k: &[f64], evaluation: &Fan, q_eq: &[f64]) -> Vec<(f64, f64)> {
    let (class_of, classes) = coupling_classes(candidates);
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); classes.len()];
    for (j, &class) in class_of.iter().enumerate() {
        if k[j] != 0.0 {
            members[class].push(j);
        }
    }
    let per_class: Vec<Vec<(usize, (f64, f64))>> = classes
        .par_iter()
        .zip(&members)
        .map(|(a, members)| {
            if members.is_empty() {
                return Vec::new();
            }
            let at = |q: &[f64]| a.iter().zip(q).map(|(a, q)| a * q).sum::<f64>();
            let at_q: Vec<f64> =
                evaluation.geodesics.iter().flat_map(|g| (0..g.len()).map(move |i| g.q(i))).map(at).collect();
            members.iter().map(|&j| (j, peak(&candidates[j].element, k[j], q_eq, &at_q))).collect()
        })
        .collect();
    let mut peaks = vec![(0.0, 0.0); candidates.len()];
    for (j, peak) in per_class.into_iter().flatten() {
        peaks[j] = peak;
    }
    peaks
}

/// An element's peak |torque| at rate `kj` and its largest engaged |deflection| over q_eq and
/// the samples where its coupling reads `at_q` (d = e.deflection(q), term for term); a
/// compression spring's deflection counts only where it pushes.
fn peak(e: &Element, kj: f64, q_eq: &[f64], at_q: &[f64]) -> (f64, f64) {
    let mut torque: f64 = 0.0;
    let mut defl: f64 = 0.0;
    let mut visit = |d: f64| {
        let slope = e.profile.slope(d);
        torque = torque.max((kj * slope).abs());
        if slope != 0.0 || !matches!(e.profile, crate::elements::Profile::Compression(_)) {
            defl = defl.max(d.abs());
        }
    };
    visit(e.deflection(q_eq));
    for &x in at_q {
        visit(x - e.offset);
    }
    (torque, defl)
}

/// The parts of a bill of materials realised (its cams: disc cams with their followers, from their
/// families' settings), each of their rows given its part's summary ([`summarise_cams`]) and, where
/// a tendon family made its coupling and the row does not carry them yet, its pulley radii.
pub fn realise_parts(catalog: &Catalog, bom: &mut [BomRow], evaluation: &Fan, q_eq: &[f64]) -> Vec<FittedCam> {
    for r in bom.iter_mut().filter(|r| r.pulleys_mm.is_none()) {
        r.pulleys_mm = catalog.pulleys(&r.family, &r.element.coupling).map(<[f64]>::to_vec);
    }
    let cams = fitted_cams(catalog, bom);
    summarise_cams(bom, &cams, evaluation, q_eq);
    cams
}

/// Gives each cam coefficient row its cam's [`CamSummary`]: the build, the largest
/// |V′| over the region (the equilibrium and every sample of `evaluation`) and V′ at q_eq.
pub fn summarise_cams(bom: &mut [BomRow], cams: &[FittedCam], evaluation: &Fan, q_eq: &[f64]) {
    // Each cam's peak over the held-out fan is its own: computed in parallel, assigned in order.
    let summaries: Vec<CamSummary> = cams
        .par_iter()
        .map(|cam| {
            let torque = |q: &[f64]| {
                let x: f64 = cam.coupling.iter().zip(q).map(|(a, q)| a * q).sum();
                cam.knots.eval(&cam.coefficients, x).1
            };
            let preload = torque(q_eq);
            let mut peak = preload.abs();
            for g in &evaluation.geodesics {
                for i in 0..g.len() {
                    peak = peak.max(torque(g.q(i)).abs());
                }
            }
            CamSummary { build: cam.realisation.build, max_torque_nm: peak, preload_nm: Some(preload) }
        })
        .collect();
    for (cam, summary) in cams.iter().zip(summaries) {
        for r in bom.iter_mut().filter(|r| {
            matches!(r.element.profile, Profile::Spline(_)) && r.id.split('.').next() == Some(cam.id.as_str())
        }) {
            r.cam = Some(summary);
        }
    }
}

/// The stock rate nearest to `k` in ratio (rates are usually geometric series).
pub fn nearest(rates: &[f64], k: f64) -> Option<f64> {
    rates.iter().copied().min_by(|a, b| (a / k).ln().abs().total_cmp(&(b / k).ln().abs()))
}
