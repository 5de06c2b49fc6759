//! Reading a catalogue: every family of the file validated (one error naming the file, the
//! family and the key) and resolved for the robot (couplings for its joints, offsets, cam
//! settings, trim ranges).

use crate::limits::{
    MAX_CANDIDATES, MAX_COUPLING, MAX_KNOTS, MAX_LINKS as MAX_RUN, MAX_OFFSETS, MAX_STIFFNESS, show, within,
};
use std::path::Path;

use super::file::{CatalogFile, CouplingSpec, FamilySpec, GroupKind, OffsetSpec, Smoothing, TendonSpec};
use super::*;
use crate::error::{Error, Result};
use crate::input::{parse_toml, read_text};

/// The joint names `q1` … `qn` every arm answers to.
pub fn numbered_joints(dof: usize) -> Vec<String> {
    (1..=dof).map(|i| format!("q{i}")).collect()
}

impl Catalog {
    /// Reads and validates a catalogue for a robot with `dof` joints named `q1` … `qn`.
    pub fn load(path: &Path, dof: usize) -> Result<Catalog> {
        Catalog::load_for(path, &numbered_joints(dof))
    }

    /// Reads and validates a catalogue for a robot with these joints (base first; a design's
    /// [`crate::model::Chain::joint_names`]), which families may name.
    pub fn load_for(path: &Path, joints: &[String]) -> Result<Catalog> {
        Catalog::parse_for(path, &read_text(path)?, joints)
    }

    /// Parses and validates the text of a catalogue for a robot with `dof` joints (what
    /// [`Catalog::load`] does once the file is read). Never panics: every problem in `text` is
    /// an [`Error`].
    pub fn parse(path: &Path, text: &str, dof: usize) -> Result<Catalog> {
        Catalog::parse_for(path, text, &numbered_joints(dof))
    }

    /// [`Catalog::parse`] for a robot with these joints.
    pub fn parse_for(path: &Path, text: &str, joints: &[String]) -> Result<Catalog> {
        let file: CatalogFile = parse_toml(path, text)?;
        Catalog::from_file_for(path, file, joints)
    }

    /// Validates a parsed catalogue for a robot with `dof` joints named `q1` … `qn`.
    pub fn from_file(path: &Path, file: CatalogFile, dof: usize) -> Result<Catalog> {
        Catalog::from_file_for(path, file, &numbered_joints(dof))
    }

    /// Validates a parsed catalogue for a robot with these joints: each family in turn (the
    /// first problem is the error), the running totals bounded as they grow.
    pub fn from_file_for(path: &Path, file: CatalogFile, joints: &[String]) -> Result<Catalog> {
        if file.family.is_empty() {
            return Err(Error::invalid(
                path,
                "family",
                "the catalogue has no [[family]]: it yields no candidate element",
            ));
        }
        let mut totals = Totals::default();
        let mut families = Vec::new();
        for (i, f) in file.family.iter().enumerate() {
            let at = At { path, i, joints };
            families.push(family(&at, f, &file.family[..i], &mut totals)?);
        }
        let name = file.name.clone().unwrap_or_else(|| {
            path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "catalog".into())
        });
        Ok(Catalog {
            path: path.to_path_buf(),
            name,
            families,
            candidate_bound: totals.candidates,
            row_nonzero_bound: totals.row_nonzeros,
        })
    }
}

/// Where a family sits, so that every error names the file and the family's key: the file, the
/// family's index and the robot's joints (which `couplings` may name).
struct At<'a> {
    path: &'a Path,
    i: usize,
    joints: &'a [String],
}

impl At<'_> {
    /// The family's key `name`, as errors name it: `family[i].name`.
    fn field(&self, name: &str) -> String {
        format!("family[{}].{name}", self.i)
    }

    /// An error on the family's key `name`.
    fn invalid(&self, name: &str, reason: impl Into<String>) -> Error {
        Error::invalid(self.path, self.field(name), reason)
    }
}

/// What the families so far add up to, bounded as each family is added so that `expand` never
/// builds more than the limits allow.
#[derive(Default)]
struct Totals {
    /// Candidate elements (columns of the fit).
    candidates: usize,
    /// Non-zeros of one row of the fit over all candidates.
    row_nonzeros: usize,
    /// Trim springs.
    trims: usize,
}

impl Totals {
    /// Adds a family's candidates: each coupling × offset × side (or cam coefficient) is one.
    fn add_candidates(
        &mut self,
        at: &At,
        couplings: usize,
        offsets: usize,
        profiles: usize,
        cam: Option<CamSpec>,
    ) -> Result<()> {
        let dof = at.joints.len();
        // Each coupling × offset × side is one candidate (a column of the fit): bound the total
        // before `expand` builds them.
        self.candidates = couplings
            .checked_mul(offsets)
            .and_then(|c| c.checked_mul(cam.map_or(profiles, |c| 2 * (usize::from(c.knots) + 2))))
            .and_then(|c| c.checked_add(self.candidates))
            .filter(|c| *c <= MAX_CANDIDATES)
            .ok_or_else(|| {
                Error::invalid(
                    at.path,
                    format!("family[{}]", at.i),
                    format!(
                        "the catalogue expands into more than {MAX_CANDIDATES} candidate elements for a robot with \
                         {dof} joints: list fewer couplings or offsets"
                    ),
                )
            })?;
        // Within MAX_CANDIDATES, as the count above.
        self.row_nonzeros += couplings * offsets * cam.map_or(profiles, |c| 8.min(2 * (usize::from(c.knots) + 2)));
        Ok(())
    }

    /// Adds a trim family's springs, one per coupling.
    fn add_trims(&mut self, at: &At, couplings: usize) -> Result<()> {
        self.trims += couplings;
        if self.trims > crate::limits::MAX_TRIMS {
            return Err(at.invalid(
                "couplings",
                format!("the catalogue lists more than {} trim springs", crate::limits::MAX_TRIMS),
            ));
        }
        Ok(())
    }
}

/// One family validated, key by key in the order the checks have always run (so the first
/// problem of a file is always the one reported), and added to the totals.
fn family(at: &At, f: &FamilySpec, earlier: &[FamilySpec], totals: &mut Totals) -> Result<Family> {
    let cam = cam_spec(at.path, f, &|name| at.field(name))?;
    let profiles = profiles(at, f, cam.is_some())?;
    check_unit(at, f, &profiles)?;
    let (couplings, pulleys) = couplings(at, &f.couplings)?;
    let (offset_spec, offsets) = offsets(at, f, cam.is_some())?;
    totals.add_candidates(at, couplings.len(), offsets, profiles.len(), cam)?;
    let stock_rates = stock_rates(at, f)?;
    check_tolerance_and_name(at, f, earlier)?;
    let adjust_range = adjust_range(at, f)?;
    let trim_range = trim_range(at, f, &profiles, adjust_range)?;
    if trim_range.is_some() {
        totals.add_trims(at, couplings.len())?;
    }
    Ok(Family {
        name: f.name.clone(),
        profiles,
        couplings,
        pulleys,
        tendons: match &f.couplings {
            CouplingSpec::Tendons(t) => Some(t.clone()),
            _ => None,
        },
        offsets: offset_spec,
        max_stiffness: f.max_stiffness,
        stock_rates,
        tolerance: f.tolerance,
        cam,
        adjust_range,
        trim_range,
        trim_sized: f.trim_sized,
    })
}

/// The family's profiles: none for a cam, one or two (`side`) for compression springs, the
/// named one otherwise.
fn profiles(at: &At, f: &FamilySpec, is_cam: bool) -> Result<Vec<Profile>> {
    let side = f.side.as_deref();
    if is_cam && side.is_some() {
        return Err(at.invalid("side", "a cam has no side"));
    }
    Ok(match (f.profile.as_str(), side) {
        ("cam", _) => Vec::new(),
        ("compression", None | Some("both")) => {
            vec![Profile::Compression(Side::Plus), Profile::Compression(Side::Minus)]
        }
        ("compression", Some("+")) => vec![Profile::Compression(Side::Plus)],
        ("compression", Some("-")) => vec![Profile::Compression(Side::Minus)],
        ("compression", Some(s)) => {
            return Err(at.invalid("side", format!("must be \"+\", \"-\" or \"both\", got \"{s}\"")));
        }
        (p, None) => vec![Profile::parse(p, "").map_err(|e| at.invalid("profile", e))?],
        (p, Some(_)) => {
            let e = Profile::parse(p, "").err().unwrap_or_else(|| "only compression springs have a side".into());
            return Err(at.invalid(if e.contains("unknown profile") { "profile" } else { "side" }, e));
        }
    })
}

/// An optional `unit` must be the profile's (spelt with `*`, `·` or `^` as the user likes).
fn check_unit(at: &At, f: &FamilySpec, profiles: &[Profile]) -> Result<()> {
    if let Some(u) = &f.unit {
        let (expected, name) = profiles.first().map_or(("J", "cam"), |p| (p.unit(), p.name()));
        if normalise_unit(u) != normalise_unit(expected) {
            return Err(at.invalid("unit", format!("a {name} element's stiffness is in {expected}, not {u}")));
        }
    }
    Ok(())
}

/// A coupling's signed pulley radii, mm, when a tendon family generated it
/// ([`Family::pulleys`]).
type Pulleys = Option<Vec<f64>>;

/// The family's coupling vectors resolved for the robot, at least one, and each one's pulley
/// radii when a tendon family generated it.
fn couplings(at: &At, spec: &CouplingSpec) -> Result<(Vec<Vec<f64>>, Vec<Pulleys>)> {
    let out = match spec {
        CouplingSpec::Groups { kind, ratios, on } => grouped_couplings(at, *kind, ratios, on.as_deref())?,
        CouplingSpec::Runs { lengths, on } => run_couplings(at, lengths, on.as_deref())?,
        CouplingSpec::List(list) => listed_couplings(at, list)?,
        CouplingSpec::Tendons(t) => return Ok(tendon_couplings(at, t)?.into_iter().unzip()),
    };
    if out.is_empty() {
        return Err(at.invalid("couplings", "lists no coupling"));
    }
    let none = vec![None; out.len()];
    Ok((out, none))
}

/// Largest stocked pulley radius a tendon family may list, mm: a sanity bound (a pulley of a metre
/// is a typing error), the design's `[parts]` limits being checked when a design loads the
/// catalogue ([`Catalog::check_pulleys`]).
const MAX_PULLEY_MM: f64 = 1000.0;

/// `tendons`: every coupling a cable over pulleys of the stocked radii makes, with its signed
/// radii, then the bevel differentials of neighbours when asked (radii None).
///
/// A tendon crosses a run of m consecutive joints (2 ≤ m ≤ `max_crossed`), base first, over one
/// stocked radius rᵢ at each, on side sᵢ: its length changes by Σ sᵢ rᵢ qᵢ, so its coupling is
/// a = (sᵢ rᵢ) / maxᵢ rᵢ (largest entry 1, the scale of a joint's spring). A coupling and its
/// negative are one element (x and −x; the offsets, sides and cam coefficients cover both), so the
/// first crossing is on the + side. Radii sets in proportion ((10, 20) and (20, 40)) make one
/// coupling: kept once, at its first place in the order, with the largest radii (the least cable
/// tension for the element's torque). The order: runs by length, then by first joint; within a
/// run the radii as an odometer over `radii_mm` sorted (the last joint fastest), then the sides.
/// `bevel = true` then adds, for every pair of neighbours, (1, ±1/r) and (1/r, ±1) at each ratio r
/// of [`BEVEL_RATIOS`], unless a tendon already makes that coupling.
fn tendon_couplings(at: &At, t: &TendonSpec) -> Result<Vec<(Vec<f64>, Pulleys)>> {
    let n = at.joints.len();
    if t.radii_mm.is_empty() {
        return Err(at.invalid("couplings.tendons.radii_mm", "lists no pulley radius"));
    }
    for (k, r) in t.radii_mm.iter().enumerate() {
        if !(r.is_finite() && *r > 0.0 && *r <= MAX_PULLEY_MM) {
            return Err(at.invalid(
                &format!("couplings.tendons.radii_mm[{k}]"),
                format!("a pulley radius must be positive and at most {} mm, got {}", show(MAX_PULLEY_MM), show(*r)),
            ));
        }
    }
    if !(2..=n).contains(&t.max_crossed) {
        return Err(at.invalid(
            "couplings.tendons.max_crossed",
            format!("a tendon crosses 2 to {n} joints (the arm's), got {}", t.max_crossed),
        ));
    }
    let mut radii = t.radii_mm.clone();
    radii.sort_by(f64::total_cmp);
    radii.dedup();
    // Tendons before removing the repeats, bounded before any is built.
    let total = (2..=t.max_crossed).try_fold(0usize, |sum, m| {
        let per_run = radii.len().checked_pow(m as u32)?.checked_mul(1usize << (m - 1))?;
        sum.checked_add(per_run.checked_mul(n + 1 - m)?)
    });
    if total.is_none_or(|t| t > MAX_CANDIDATES) {
        return Err(at.invalid(
            "couplings.tendons",
            format!(
                "the tendons over {} radii crossing up to {} of {n} joints number more than {MAX_CANDIDATES}: list fewer radii or lower max_crossed",
                radii.len(),
                t.max_crossed
            ),
        ));
    }
    let mut out: Vec<(Vec<f64>, Pulleys)> = Vec::new();
    let mut seen: HashMap<Vec<i64>, usize> = HashMap::new();
    // The direction of a coupling, up to scale: its entries over the largest, rounded to 1e-9.
    let key = |a: &[f64]| -> Vec<i64> { a.iter().map(|x| (x * 1e9).round() as i64).collect() };
    for m in 2..=t.max_crossed {
        for first in 0..=n - m {
            let mut pick = vec![0usize; m];
            loop {
                let big = pick.iter().map(|&p| radii[p]).fold(0.0, f64::max);
                for sides in 0..1usize << (m - 1) {
                    let mut r = vec![0.0; n];
                    for (k, &p) in pick.iter().enumerate() {
                        let minus = k > 0 && sides >> (k - 1) & 1 == 1;
                        r[first + k] = if minus { -radii[p] } else { radii[p] };
                    }
                    let a: Vec<f64> = r.iter().map(|x| x / big).collect();
                    match seen.get(&key(&a)) {
                        Some(&i) => {
                            let kept =
                                out[i].1.as_ref().map_or(0.0, |r| r.iter().fold(0.0, |m: f64, x| m.max(x.abs())));
                            if big > kept {
                                out[i].1 = Some(r);
                            }
                        }
                        None => {
                            seen.insert(key(&a), out.len());
                            out.push((a, Some(r)));
                        }
                    }
                }
                // The next radii, the last joint's fastest.
                let Some(k) = (0..m).rev().find(|&k| pick[k] + 1 < radii.len()) else { break };
                pick[k] += 1;
                pick[k + 1..].iter_mut().for_each(|p| *p = 0);
            }
        }
    }
    if t.bevel {
        for first in 0..n - 1 {
            for ratio in BEVEL_RATIOS {
                let orders: &[[f64; 2]] =
                    if ratio == 1.0 { &[[1.0, 1.0]] } else { &[[1.0, 1.0 / ratio], [1.0 / ratio, 1.0]] };
                for [c1, c2] in orders {
                    for sign in [1.0, -1.0] {
                        let mut a = vec![0.0; n];
                        a[first] = *c1;
                        a[first + 1] = sign * c2;
                        if let std::collections::hash_map::Entry::Vacant(v) = seen.entry(key(&a)) {
                            v.insert(out.len());
                            out.push((a, None));
                        }
                    }
                }
            }
        }
    }
    Ok(out)
}

/// The joints a coupling key ranges over: all of the robot's, or those `on` names (an error
/// names `key[k]` for the k-th bad name).
fn among(at: &At, on: Option<&[String]>, key: &str) -> Result<Vec<usize>> {
    match on {
        None => Ok((0..at.joints.len()).collect()),
        Some(list) => {
            named_joints(list, at.joints).map_err(|(k, reason)| at.invalid(&format!("couplings.{key}[{k}]"), reason))
        }
    }
}

/// `joints`, `pairs`, `all_pairs` or `triples`: every ratio on every group of its kind.
fn grouped_couplings(at: &At, kind: GroupKind, ratios: &[Vec<f64>], on: Option<&[String]>) -> Result<Vec<Vec<f64>>> {
    let key = kind.key();
    let among = among(at, on, if kind == GroupKind::Joints { key } else { "on" })?;
    let size = kind.size();
    if among.len() < size {
        let whose = if on.is_some() { "`on` names" } else { "the robot has" };
        return Err(at.invalid("couplings", format!("{key} need at least {size} joints but {whose} {}", among.len())));
    }
    let mut out = Vec::new();
    for (k, r) in ratios.iter().enumerate() {
        if r.iter().any(|x| !x.is_finite() || *x == 0.0 || x.abs() > MAX_COUPLING) {
            return Err(at.invalid(
                &format!("couplings.{key}[{k}]"),
                format!("every gear ratio must be finite and non-zero, at most {} in magnitude", show(MAX_COUPLING)),
            ));
        }
        for group in groups(kind, &among) {
            let mut a = vec![0.0; at.joints.len()];
            for (&j, &x) in group.iter().zip(r) {
                a[j] = x;
            }
            out.push(a);
        }
    }
    Ok(out)
}

/// `runs`: every run of adjacent joints of each length, all at ratio 1.
fn run_couplings(at: &At, lengths: &[usize], on: Option<&[String]>) -> Result<Vec<Vec<f64>>> {
    let among = among(at, on, "on")?;
    if lengths.is_empty() {
        return Err(at.invalid("couplings.runs", "lists no run length"));
    }
    let mut out = Vec::new();
    for (k, &length) in lengths.iter().enumerate() {
        if !(2..=MAX_RUN).contains(&length) {
            return Err(at.invalid(
                &format!("couplings.runs[{k}]"),
                format!("a run is 2 to {MAX_RUN} adjacent joints, got {length}"),
            ));
        }
        for run in among.windows(length) {
            let mut a = vec![0.0; at.joints.len()];
            for &j in run {
                a[j] = 1.0;
            }
            out.push(a);
        }
    }
    if out.is_empty() {
        let whose = if on.is_some() { "`on` names" } else { "the robot has" };
        let shortest = lengths.iter().min().copied().unwrap_or(2);
        return Err(
            at.invalid("couplings", format!("the shortest run is {shortest} joints but {whose} {}", among.len()))
        );
    }
    Ok(out)
}

/// Coupling vectors written out: one entry per joint, finite, within the largest gear ratio,
/// not all zero.
fn listed_couplings(at: &At, list: &[Vec<f64>]) -> Result<Vec<Vec<f64>>> {
    let dof = at.joints.len();
    for (k, a) in list.iter().enumerate() {
        let fld = format!("couplings[{k}]");
        if a.len() != dof {
            return Err(at.invalid(&fld, format!("has {} entries but the robot has {dof} joints", a.len())));
        }
        if a.iter().any(|x| !x.is_finite()) {
            return Err(at.invalid(&fld, "entries must be finite"));
        }
        if let Some(x) = a.iter().find(|x| x.abs() > MAX_COUPLING) {
            return Err(at.invalid(
                &fld,
                format!(
                    "entry {} is beyond the largest gear ratio springfit accepts, {}",
                    show(*x),
                    show(MAX_COUPLING)
                ),
            ));
        }
        if a.iter().all(|x| *x == 0.0) {
            return Err(at.invalid(&fld, "a coupling of all zeros moves nothing"));
        }
    }
    Ok(list.to_vec())
}

/// The family's offsets and how many each coupling takes: a spring family must list them, a
/// cam takes none (its knots follow the region: one "offset", the equilibrium).
fn offsets(at: &At, f: &FamilySpec, is_cam: bool) -> Result<(OffsetSpec, usize)> {
    let spec = match (&f.offsets, is_cam) {
        (Some(_), true) => {
            return Err(at.invalid("offsets", "a cam's knots follow the region: it takes no offsets"));
        }
        (None, false) => {
            return Err(at.invalid("offsets", "missing: every spring family needs offsets"));
        }
        (Some(o), false) => o.clone(),
        (None, true) => OffsetSpec::Equilibrium,
    };
    let count = match &spec {
        _ if is_cam => 1,
        OffsetSpec::Grid { count, .. } if *count < 1 || *count > MAX_OFFSETS => {
            return Err(at.invalid("offsets", format!("grid must have 1 to {MAX_OFFSETS} points, got {count}")));
        }
        OffsetSpec::Phases { count } if *count < 1 || *count > MAX_OFFSETS => {
            return Err(at.invalid("offsets", format!("phases must be 1 to {MAX_OFFSETS} per turn, got {count}")));
        }
        OffsetSpec::List(l) if l.is_empty() => {
            return Err(at.invalid("offsets", "the list is empty"));
        }
        OffsetSpec::Equilibrium => 1,
        OffsetSpec::Grid { count, equilibrium } => count + usize::from(*equilibrium),
        OffsetSpec::Phases { count } => *count,
        OffsetSpec::List(l) => l.len(),
    };
    Ok((spec, count))
}

/// The optional `max_stiffness` checked, and the stock rates checked, ascending and without
/// repeats.
fn stock_rates(at: &At, f: &FamilySpec) -> Result<Vec<f64>> {
    if let Some(k) = f.max_stiffness {
        if !(k.is_finite() && k > 0.0) {
            return Err(at.invalid("max_stiffness", format!("must be positive, got {}", show(k))));
        }
        within(k, MAX_STIFFNESS, "").map_err(|e| at.invalid("max_stiffness", e))?;
    }
    let mut rates = f.stock_rates.clone();
    for (k, r) in rates.iter().enumerate() {
        let field = format!("stock_rates[{k}]");
        if !(r.is_finite() && *r > 0.0) {
            return Err(at.invalid(&field, format!("must be positive, got {}", show(*r))));
        }
        within(*r, MAX_STIFFNESS, "").map_err(|e| at.invalid(&field, e))?;
    }
    rates.sort_by(f64::total_cmp);
    rates.dedup();
    Ok(rates)
}

/// The tolerance is a fraction; the name is set and no earlier family's (the bill of materials
/// tells families apart by name).
fn check_tolerance_and_name(at: &At, f: &FamilySpec, earlier: &[FamilySpec]) -> Result<()> {
    if !(f.tolerance.is_finite() && (0.0..1.0).contains(&f.tolerance)) {
        return Err(at.invalid("tolerance", format!("must be a fraction in [0, 1), got {}", f.tolerance)));
    }
    if f.name.trim().is_empty() {
        return Err(at.invalid("name", "must not be empty"));
    }
    if let Some(j) = earlier.iter().position(|g| g.name.trim() == f.name.trim()) {
        return Err(at.invalid(
            "name",
            format!("`{}` is also the name of family[{j}]: the bill of materials tells families apart by name", f.name),
        ));
    }
    Ok(())
}

/// ± rad an adjustable family's offset can be moved: required with `adjustable`, refused
/// without.
fn adjust_range(at: &At, f: &FamilySpec) -> Result<Option<f64>> {
    match (f.adjustable, f.adjust_range) {
        (false, None) => Ok(None),
        (true, Some(r)) if r.is_finite() && r > 0.0 && r <= std::f64::consts::PI => Ok(Some(r)),
        (true, Some(r)) => Err(at.invalid("adjust_range", format!("must be in (0, π] rad, got {r}"))),
        (true, None) => {
            Err(at.invalid("adjust_range", "an adjustable family needs adjust_range (± rad the offset can be moved)"))
        }
        (false, Some(_)) => Err(at.invalid("adjust_range", "is only meaningful with adjustable = true")),
    }
}

/// A trim family's rate range: required with `trim`, refused without; a trim family is linear,
/// relaxed at the equilibrium, not adjustable, and its rates are the range alone.
fn trim_range(at: &At, f: &FamilySpec, profiles: &[Profile], adjust_range: Option<f64>) -> Result<Option<[f64; 2]>> {
    if f.trim_sized && !f.trim {
        return Err(at.invalid("trim_sized", "is only meaningful with trim = true"));
    }
    let [lo, hi] = match (f.trim, f.trim_range) {
        (false, None) => return Ok(None),
        (false, Some(_)) => return Err(at.invalid("trim_range", "is only meaningful with trim = true")),
        (true, None) => {
            return Err(
                at.invalid("trim_range", "a trim family needs trim_range = [lo, hi] (N·m/rad the rate can be set to)")
            );
        }
        (true, Some(range)) => range,
    };
    if !(lo.is_finite() && hi.is_finite() && lo >= 0.0 && hi > lo) {
        return Err(at.invalid(
            "trim_range",
            format!("must be [lo, hi] with 0 ≤ lo < hi N·m/rad, got [{}, {}]", show(lo), show(hi)),
        ));
    }
    within(hi, MAX_STIFFNESS, " N·m/rad").map_err(|e| at.invalid("trim_range", format!("the upper rate {e}")))?;
    if profiles != [Profile::Linear] {
        return Err(at.invalid("profile", "trim springs are linear"));
    }
    if !matches!(f.offsets, Some(OffsetSpec::Equilibrium)) {
        return Err(at.invalid("offsets", "trim springs are relaxed at the equilibrium: offsets = \"equilibrium\""));
    }
    if adjust_range.is_some() {
        return Err(at.invalid("adjustable", "a trim spring is re-relaxed when it is set; it takes no adjust_range"));
    }
    if f.max_stiffness.is_some() || !f.stock_rates.is_empty() {
        return Err(
            at.invalid("trim_range", "a trim family's rates are its trim_range (no max_stiffness or stock_rates)")
        );
    }
    Ok(Some([lo, hi]))
}

/// The cam keys of a family: validated for `profile = "cam"`, refused for any other profile.
fn cam_spec(path: &Path, f: &FamilySpec, field: &dyn Fn(&str) -> String) -> Result<Option<CamSpec>> {
    let invalid = |name: &str, reason: String| Error::invalid(path, field(name), reason);
    let keys: [(&str, bool); 9] = [
        ("knots", f.knots.is_some()),
        ("smoothing", f.smoothing.is_some()),
        ("margin", f.margin.is_some()),
        ("follower_rate", f.follower_rate.is_some()),
        ("max_stroke", f.max_stroke.is_some()),
        ("preload_fraction", f.preload_fraction.is_some()),
        ("base_radius", f.base_radius.is_some()),
        ("roller_radius", f.roller_radius.is_some()),
        ("max_pressure_angle", f.max_pressure_angle.is_some()),
    ];
    if f.profile != "cam" {
        if let Some((k, _)) = keys.iter().find(|(_, set)| *set) {
            return Err(invalid(k, format!("only cams (profile = \"cam\") take `{k}`")));
        }
        return Ok(None);
    }
    let knots = f.knots.unwrap_or(30);
    if !(4..=MAX_KNOTS).contains(&knots) {
        return Err(invalid("knots", format!("must be 4 to {MAX_KNOTS}, got {knots}")));
    }
    let positive = |name: &str, v: Option<f64>, default: f64| -> Result<f64> {
        let x = v.unwrap_or(default);
        if x.is_finite() && x > 0.0 { Ok(x) } else { Err(invalid(name, format!("must be positive, got {x}"))) }
    };
    let margin = f.margin.unwrap_or(0.05);
    if !(margin.is_finite() && (0.0..=1.0).contains(&margin)) {
        return Err(invalid("margin", format!("must be a fraction in [0, 1], got {margin}")));
    }
    let follower_rate = match f.follower_rate {
        Some(r) => Some(positive("follower_rate", Some(r), 1.0)?),
        None => None,
    };
    let angle = positive("max_pressure_angle", f.max_pressure_angle, 30.0)?;
    if angle >= 90.0 {
        return Err(invalid("max_pressure_angle", format!("must be below 90°, got {angle}")));
    }
    let preload_fraction = positive("preload_fraction", f.preload_fraction, super::DEFAULT_PRELOAD_FRACTION)?;
    if preload_fraction > 20.0 {
        return Err(invalid(
            "preload_fraction",
            format!("must be at most 20 (a preload of 20 strokes), got {preload_fraction}"),
        ));
    }
    Ok(Some(CamSpec {
        knots: knots as u16,
        smoothing: f.smoothing.unwrap_or(Smoothing::Auto),
        margin,
        follower_rate,
        max_stroke: positive("max_stroke", f.max_stroke, 20.0)?,
        preload_fraction,
        base_radius: positive("base_radius", f.base_radius, 40.0)?,
        roller_radius: positive("roller_radius", f.roller_radius, 8.0)?,
        max_pressure_angle: angle,
    }))
}

fn normalise_unit(u: &str) -> String {
    u.chars()
        .filter(|c| !c.is_whitespace())
        .map(|c| match c {
            '·' | '⋅' => '*',
            '³' => '3',
            c => c,
        })
        .collect::<String>()
        .replace("^", "")
        .to_lowercase()
}

/// The arm's indices of the joints `list` names (the arm's names or `q1` … `qn`), in the arm's
/// order; or the index in `list` of the first bad name and why.
fn named_joints(list: &[String], joints: &[String]) -> std::result::Result<Vec<usize>, (usize, String)> {
    let numbered = numbered_joints(joints.len());
    let mut out = Vec::with_capacity(list.len());
    for (k, name) in list.iter().enumerate() {
        let j = joints.iter().position(|n| n == name).or_else(|| numbered.iter().position(|n| n == name));
        let Some(j) = j else {
            let mut names = joints.to_vec();
            if joints != numbered.as_slice() {
                names.push(format!("or q1 … q{}", joints.len()));
            }
            return Err((k, format!("`{name}` is not a joint of the arm; its joints are {}", names.join(", "))));
        };
        if out.contains(&j) {
            return Err((k, format!("`{name}` is listed twice")));
        }
        out.push(j);
    }
    out.sort_unstable();
    Ok(out)
}

/// The groups of joint indices of `kind` among `among` (ascending): adjacent ones are
/// neighbours in `among`.
fn groups(kind: GroupKind, among: &[usize]) -> Vec<Vec<usize>> {
    match kind {
        GroupKind::Joints => among.iter().map(|&j| vec![j]).collect(),
        GroupKind::Pairs => among.windows(2).map(<[usize]>::to_vec).collect(),
        GroupKind::Triples => among.windows(3).map(<[usize]>::to_vec).collect(),
        GroupKind::AllPairs => {
            let mut out = Vec::new();
            for (t, &j) in among.iter().enumerate() {
                for &l in &among[t + 1..] {
                    out.push(vec![j, l]);
                }
            }
            out
        }
    }
}
