//! The bill of materials: the fitted springs and cams as a CSV a workshop can build from and
//! springfit can read back to rebuild the potential exactly.
//!
//! Columns: `id,family,profile,side,coupling,offset_rad,stiffness,unit,max_torque_nm,
//! max_deflection_rad,stock_rate,tolerance,preload_nm,adjust_range_rad,trim_min,trim_max,
//! gear_ratio,file`. `coupling` is the vector a with entries joined by `;` (`1;-2`), `side` is `+`,
//! `-` or empty, `preload_nm` the element's torque on its coordinate at the equilibrium (signed;
//! empty when unknown). `adjust_range_rad`, `trim_min`, `trim_max` say what can be set after
//! assembly (empty when nothing): an adjustable offset's ± range and a trim spring's rate range
//! (see [`crate::elements::trim`]).
//!
//! **Cams.** A cam is one row: profile `cam`, side empty, `offset_rad` its first knot,
//! `stiffness` its follower spring rate in N/mm (the rate the tolerance applies to: one δ per
//! cam), `max_torque_nm` the largest |V′| over the region, `max_deflection_rad` the knot span,
//! `preload_nm` V′ at the equilibrium, `gear_ratio` the cam's gearing and `file` its
//! `cams/<id>.toml` ([`crate::files::cam::CamFile`], relative to the bill of materials' folder) with the
//! coefficients. Inside springfit a cam stays what the fit solved for: one row per non-zero
//! signed B-spline coefficient (`C01.07+`, profile [`Profile::Spline`], stiffness |cⱼ|, the basis
//! negated when cⱼ < 0); [`parse`] expands a cam row into those rows and [`to_csv`] collapses
//! them, so reading a fit's files gives its spring set bit for bit.
//!
//! Files of older springfit versions are read as well: twelve columns (ending at `tolerance`),
//! thirteen (ending at `preload_nm`) or sixteen (ending at `trim_max`), with cams as one row per
//! signed coefficient (side `+j/N/h`, stiffness in J). Numbers are written with Rust's shortest
//! round-trip formatting, so reading the file back gives bit-identical stiffnesses and offsets.

use crate::csv::{csv_field, split_csv_line};
use crate::fit::bill::{Adjustment, BomRow, CamSummary};
use std::path::Path;

use crate::elements::spline::Knots;
use crate::elements::{Element, Profile, fmt_number};
use crate::error::{Error, Result};
use crate::files::cam::CamFile;
use crate::input::read_text;
use crate::limits::{MAX_ANGLE_RAD, MAX_COUPLING, MAX_LINKS, MAX_STIFFNESS, show, within};

/// The CSV header.
pub const HEADER: &str = "id,family,profile,side,coupling,offset_rad,stiffness,unit,max_torque_nm,max_deflection_rad,stock_rate,tolerance,preload_nm,adjust_range_rad,trim_min,trim_max,gear_ratio,file";

/// The header of files with the after-assembly columns but before cams were one row (still read).
const HEADER_16: &str = "id,family,profile,side,coupling,offset_rad,stiffness,unit,max_torque_nm,max_deflection_rad,stock_rate,tolerance,preload_nm,adjust_range_rad,trim_min,trim_max";

/// The header of files with the preload but before the after-assembly columns (still read).
const HEADER_13: &str = "id,family,profile,side,coupling,offset_rad,stiffness,unit,max_torque_nm,max_deflection_rad,stock_rate,tolerance,preload_nm";

/// The header of files written before the `preload_nm` column (still read).
pub const HEADER_WITHOUT_PRELOAD: &str =
    "id,family,profile,side,coupling,offset_rad,stiffness,unit,max_torque_nm,max_deflection_rad,stock_rate,tolerance";

/// The unit of a cam row's `stiffness` (its follower spring rate).
pub const CAM_UNIT: &str = "N/mm";

/// The path of cam `id`'s file, relative to the folder of the bill of materials `name`:
/// `cams/C01.toml` beside `bom.csv`, `cams/C01_bom_tuned.toml` beside `bom_tuned.csv`.
pub fn cam_file_name(name: &str, id: &str) -> String {
    // An id read from an older file could hold anything: only letters, digits, `_` and `-` make
    // a file name.
    let id: String = id.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' { c } else { '_' }).collect();
    match name.strip_suffix(".csv").unwrap_or(name) {
        "bom" => format!("cams/{id}.toml"),
        stem => format!("cams/{id}_{stem}.toml"),
    }
}

/// One line of the written bill of materials: a spring row as it is, a cam collapsed.
struct Line {
    id: String,
    family: String,
    profile: &'static str,
    side: String,
    coupling: Vec<f64>,
    offset: f64,
    stiffness: f64,
    unit: &'static str,
    max_torque_nm: f64,
    max_deflection_rad: f64,
    stock_rate: Option<f64>,
    tolerance: f64,
    preload_nm: Option<f64>,
    adjust: Adjustment,
    /// A cam: its file's name and content.
    cam: Option<(String, CamFile)>,
    /// The row it is written for (a cam's: its first coefficient row).
    row: usize,
}

/// The lines of a bill of materials written as `name`: each cam (its coefficient rows, grouped
/// by the `Cnn` of their ids) one line at the place of its first row, with the coefficients
/// summed with their signs and the build of its [`CamSummary`] (a default realisation when the
/// rows carry none, as rows of an older file).
fn lines(name: &str, rows: &[BomRow]) -> Vec<Line> {
    let cams = crate::fit::bill::grouped(rows);
    let mut done = vec![false; cams.len()];
    let mut out = Vec::new();
    for (row, r) in rows.iter().enumerate() {
        let e = &r.element;
        if !matches!(e.profile, Profile::Spline(_)) {
            out.push(Line {
                id: r.id.clone(),
                family: r.family.clone(),
                profile: e.profile.name(),
                side: e.profile.side(),
                coupling: e.coupling.clone(),
                offset: e.offset,
                stiffness: r.stiffness,
                unit: e.profile.unit(),
                max_torque_nm: r.max_torque_nm,
                max_deflection_rad: r.max_deflection_rad,
                stock_rate: r.stock_rate,
                tolerance: r.tolerance,
                preload_nm: r.preload_nm,
                adjust: r.adjust,
                cam: None,
                row,
            });
            continue;
        }
        let id = r.id.split('.').next().unwrap_or(&r.id);
        let Some(ci) = cams.iter().position(|c| c.id == id) else { continue };
        if std::mem::replace(&mut done[ci], true) {
            continue;
        }
        let c = &cams[ci];
        let summary = r.cam.unwrap_or_else(|| {
            let real = crate::realise::cam::realise_default(&c.knots, &c.coefficients);
            let max_torque = real.points.iter().map(|p| p.torque.abs()).fold(0.0, f64::max);
            CamSummary { build: real.build, max_torque_nm: max_torque, preload_nm: None }
        });
        out.push(Line {
            id: c.id.clone(),
            family: c.family.clone(),
            profile: "cam",
            side: String::new(),
            coupling: c.coupling.clone(),
            offset: c.knots.lo,
            stiffness: summary.build.follower_rate,
            unit: CAM_UNIT,
            max_torque_nm: summary.max_torque_nm,
            max_deflection_rad: c.knots.hi() - c.knots.lo,
            stock_rate: None,
            tolerance: r.tolerance,
            preload_nm: summary.preload_nm,
            adjust: r.adjust,
            cam: Some((
                cam_file_name(name, &c.id),
                CamFile::new(&c.coupling, &c.knots, &c.coefficients, &summary.build),
            )),
            row,
        });
    }
    out
}

/// One value of a line of `bom.csv` as data: what the Python package's `Fit.bom` hands over,
/// and what the CSV writes (text quoted where it must be, numbers in Rust's shortest round-trip
/// form, blanks empty).
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// Text: an id, a family, a profile, a side, a coupling `1;-2`, a unit, a file.
    Text(String),
    /// A number.
    Number(f64),
    /// Nothing: a column that does not apply to the line.
    Blank,
}

impl Value {
    fn csv(&self) -> String {
        match self {
            Value::Text(t) => csv_field(t),
            Value::Number(x) => format!("{x}"),
            Value::Blank => String::new(),
        }
    }
}

impl Line {
    /// The line's values, one per column of [`HEADER`].
    fn values(&self) -> Vec<Value> {
        let text = |t: &str| if t.is_empty() { Value::Blank } else { Value::Text(t.to_string()) };
        let number = |x: Option<f64>| x.map_or(Value::Blank, Value::Number);
        vec![
            text(&self.id),
            text(&self.family),
            text(self.profile),
            text(&self.side),
            text(&coupling_text(&self.coupling)),
            Value::Number(self.offset),
            Value::Number(self.stiffness),
            text(self.unit),
            Value::Number(self.max_torque_nm),
            Value::Number(self.max_deflection_rad),
            number(self.stock_rate),
            Value::Number(self.tolerance),
            number(self.preload_nm),
            number(self.adjust.adjust_range),
            number(self.adjust.trim_range.map(|x| x[0])),
            number(self.adjust.trim_range.map(|x| x[1])),
            number(self.cam.as_ref().map(|(_, f)| f.realisation.gear_ratio)),
            self.cam.as_ref().map_or(Value::Blank, |(p, _)| text(p)),
        ]
    }
}

/// The lines of `bom.csv` as data, without the CSV: per line the values of the columns of
/// [`HEADER`], in order (cams collapsed into one line each, as written).
pub fn records(rows: &[BomRow]) -> Vec<Vec<Value>> {
    lines("bom.csv", rows).iter().map(Line::values).collect()
}

/// A coupling as `bom.csv` writes it (as [`Element::coupling_text`]).
fn coupling_text(a: &[f64]) -> String {
    a.iter().map(|x| fmt_number(*x)).collect::<Vec<_>>().join(";")
}

/// The files of a bill of materials written as `name` (`bom.csv`): the CSV, then one
/// `cams/<id>.toml` per cam ([`cam_file_name`]); paths relative to the CSV's folder.
pub fn files(name: &str, rows: &[BomRow]) -> Vec<(String, String)> {
    let lines = lines(name, rows);
    let mut s = String::from(HEADER);
    s.push('\n');
    let mut cams = Vec::new();
    for l in &lines {
        let fields: Vec<String> = l.values().iter().map(Value::csv).collect();
        s.push_str(&fields.join(","));
        s.push('\n');
        if let Some((path, f)) = &l.cam {
            cams.push((path.clone(), f.to_toml(&format!("{} (family \"{}\")", l.id, l.family))));
        }
    }
    let mut out = vec![(name.to_string(), s)];
    out.extend(cams);
    out
}

/// The files of a bill of materials written as `name` with a last column `measured_stiffness`,
/// as [`read_measured`] reads it: `measured[j]` is row j's measured rate in its unit (None: blank,
/// as designed). A cam's line gets its follower spring's rate scaled as its first coefficient
/// row's rate is (one rate error per cam).
pub fn files_measured(name: &str, rows: &[BomRow], measured: &[Option<f64>]) -> Vec<(String, String)> {
    let lines = lines(name, rows);
    let mut out = files(name, rows);
    let mut text = String::new();
    for (k, line) in out[0].1.lines().enumerate() {
        text.push_str(line);
        if k == 0 {
            text.push_str(",measured_stiffness");
        } else if let Some(l) = lines.get(k - 1) {
            let r = &rows[l.row];
            let value = measured.get(l.row).copied().flatten().map(|m| match l.cam {
                Some(_) if r.stiffness > 0.0 => l.stiffness * (m / r.stiffness),
                _ => m,
            });
            text.push(',');
            if let Some(v) = value {
                text.push_str(&format!("{v}"));
            }
        }
        text.push('\n');
    }
    out[0].1 = text;
    out
}

/// The CSV text of `bom.csv` (its cams' files: [`files`]).
pub fn to_csv(rows: &[BomRow]) -> String {
    files("bom.csv", rows).swap_remove(0).1
}

/// Writes the bill of materials as `name` into `out`, with its cams' files.
pub fn write(out: &crate::report::output::OutputDir, name: &str, rows: &[BomRow]) -> Result<()> {
    for (path, text) in files(name, rows) {
        out.write(&path, text)?;
    }
    Ok(())
}

/// Reads a bill of materials (and the files of its cams, relative to its folder). Every
/// problem names the file, the line and the column.
pub fn read(path: &Path) -> Result<Vec<BomRow>> {
    parse(path, &read_text(path)?)
}

/// Parses bill-of-materials text (see [`read`]); cams' files are looked for beside `path`.
pub fn parse(path: &Path, text: &str) -> Result<Vec<BomRow>> {
    parse_lines(path, text).map(|(rows, _)| rows)
}

/// [`parse`], with the data line (0 = the first after the header) each row comes from: a cam's
/// coefficient rows all come from its one line.
///
/// The header says which columns the file has; each line is read into its rows (a cam's into
/// one per coefficient), ids checked unique across lines; last, every row must act on a robot
/// with as many joints as the others.
pub fn parse_lines(path: &Path, text: &str) -> Result<(Vec<BomRow>, Vec<usize>)> {
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let (_, header) = lines.next().ok_or_else(|| bad_line(path, 1, "header", "the file is empty"))?;
    let columns = header_columns(path, header)?;
    let mut rows = Vec::new();
    let mut origin = Vec::new();
    // Each row's line and coupling length (all rows act on one robot), and the ids seen.
    let mut lengths: Vec<(usize, usize)> = Vec::new();
    let mut ids: std::collections::HashMap<String, usize> = std::collections::HashMap::new();
    for (line_index, (idx, text)) in lines.enumerate() {
        let line = DataLine::split(path, idx + 1, text, columns)?;
        let line_rows = line.rows(columns, &mut ids, &mut lengths)?;
        origin.extend(std::iter::repeat_n(line_index, line_rows.len()));
        rows.extend(line_rows);
    }
    if rows.is_empty() {
        return Err(bad_line(path, 1, "rows", "the bill of materials lists no element"));
    }
    check_coupling_lengths(path, &lengths)?;
    Ok((rows, origin))
}

/// An error on line `line` of the bill of materials, in column `field`.
fn bad_line(path: &Path, line: usize, field: &str, reason: impl Into<String>) -> Error {
    Error::invalid(path, format!("line {line}: {field}"), reason)
}

/// The number of columns the header announces: this version's 18, or an older file's 16, 13 or
/// 12 (a byte-order mark and surrounding blanks ignored).
fn header_columns(path: &Path, header: &str) -> Result<usize> {
    let header = header.trim_start_matches('\u{feff}').trim();
    if header == HEADER {
        Ok(18)
    } else if header == HEADER_16 {
        Ok(16)
    } else if header == HEADER_13 {
        Ok(13)
    } else if header == HEADER_WITHOUT_PRELOAD {
        Ok(12)
    } else {
        Err(bad_line(
            path,
            1,
            "header",
            format!("expected `{HEADER}` (or an older file's first 12, 13 or 16 of those columns)"),
        ))
    }
}

/// Rows for a robot of another size: the line whose coupling length differs from most rows'
/// is the wrong one (`lengths`: each row's line and coupling length).
fn check_coupling_lengths(path: &Path, lengths: &[(usize, usize)]) -> Result<()> {
    let mut counts: Vec<(usize, usize)> = Vec::new();
    for &(_, len) in lengths {
        match counts.iter_mut().find(|(l, _)| *l == len) {
            Some(c) => c.1 += 1,
            None => counts.push((len, 1)),
        }
    }
    if counts.len() > 1 {
        let (usual, _) = counts.iter().copied().max_by_key(|&(len, n)| (n, std::cmp::Reverse(len))).unwrap_or((0, 0));
        if let Some(&(ln, len)) = lengths.iter().find(|(_, len)| *len != usual) {
            return Err(bad_line(
                path,
                ln,
                "coupling",
                format!("has {len} entries but the other rows have {usual} (one per joint)"),
            ));
        }
    }
    Ok(())
}

/// One data line of the bill of materials, split into its fields: errors name the file, the
/// line and the column.
struct DataLine<'a> {
    path: &'a Path,
    /// Line number, from 1.
    ln: usize,
    f: Vec<String>,
}

impl<'a> DataLine<'a> {
    /// Splits line `ln` and checks it has `columns` fields.
    fn split(path: &'a Path, ln: usize, text: &str, columns: usize) -> Result<DataLine<'a>> {
        let f = split_csv_line(text).map_err(|e| bad_line(path, ln, "row", e))?;
        if f.len() != columns {
            return Err(bad_line(path, ln, "row", format!("has {} fields, expected {columns}", f.len())));
        }
        Ok(DataLine { path, ln, f })
    }

    fn bad(&self, field: &str, reason: impl Into<String>) -> Error {
        bad_line(self.path, self.ln, field, reason)
    }

    /// Field i, a finite number.
    fn num(&self, i: usize, name: &str) -> Result<f64> {
        let f = &self.f;
        let v: f64 = f[i].trim().parse().map_err(|_| self.bad(name, format!("`{}` is not a number", f[i])))?;
        if !v.is_finite() {
            return Err(self.bad(name, format!("`{}` is not a finite number", f[i])));
        }
        Ok(v)
    }

    /// Field i, a finite number; empty: None.
    fn optional(&self, i: usize, name: &str) -> Result<Option<f64>> {
        if self.f[i].trim().is_empty() { Ok(None) } else { Some(self.num(i, name)).transpose() }
    }

    /// Field i, an angle within the limits, rad.
    fn angle(&self, i: usize, name: &str) -> Result<f64> {
        let v = self.num(i, name)?;
        within(v, MAX_ANGLE_RAD, " rad").map_err(|e| self.bad(name, e))?;
        Ok(v)
    }

    /// The line's rows: one for a spring, one per non-zero coefficient for a cam. Its id is
    /// recorded in `ids` (and must not be there yet), its coupling's length in `lengths`. The
    /// columns are checked in their order in the file.
    fn rows(
        &self,
        columns: usize,
        ids: &mut std::collections::HashMap<String, usize>,
        lengths: &mut Vec<(usize, usize)>,
    ) -> Result<Vec<BomRow>> {
        let (f, ln) = (&self.f, self.ln);
        // A cam as one row (side empty) or, in older files, one row per signed coefficient.
        let whole_cam = f[2].trim() == "cam" && f[3].trim().is_empty();
        let profile = if whole_cam {
            None
        } else {
            Some(Profile::parse(f[2].trim(), f[3].trim()).map_err(|e| self.bad("profile", e))?)
        };
        let coupling = self.coupling()?;
        lengths.push((ln, coupling.len()));
        if let Some(&first) = ids.get(f[0].trim()) {
            return Err(self.bad(
                "id",
                format!(
                    "`{}` is also the id of line {first}: every row needs its own id (a row copied twice?)",
                    f[0].trim()
                ),
            ));
        }
        ids.insert(f[0].trim().to_string(), ln);
        let stiffness = self.stiffness(profile)?;
        let stock_rate = self.optional(10, "stock_rate")?;
        let tolerance = self.num(11, "tolerance")?;
        if !(0.0..1.0).contains(&tolerance) {
            return Err(self.bad("tolerance", format!("must be a fraction in [0, 1), got {tolerance}")));
        }
        let preload_nm = if columns < 13 { None } else { self.optional(12, "preload_nm")? };
        let adjust = if columns >= 16 { self.adjustment(profile)? } else { Adjustment::default() };
        let (gear_ratio, file) =
            if columns == 18 { (self.optional(16, "gear_ratio")?, f[17].trim()) } else { (None, "") };
        let common = Common { stock_rate, tolerance, preload_nm, adjust };
        let Some(profile) = profile else {
            return self.cam_rows(coupling, stiffness, gear_ratio, file, common);
        };
        if gear_ratio.is_some() || !file.is_empty() {
            return Err(self.bad(
                if file.is_empty() { "gear_ratio" } else { "file" },
                "only a cam's row (profile `cam`, side empty) has a gear ratio and a file",
            ));
        }
        Ok(vec![BomRow {
            id: f[0].clone(),
            family: f[1].clone(),
            element: Element { profile, coupling, offset: self.angle(5, "offset_rad")? },
            stiffness,
            max_torque_nm: self.num(8, "max_torque_nm")?,
            max_deflection_rad: self.num(9, "max_deflection_rad")?,
            stock_rate,
            tolerance,
            preload_nm,
            adjust,
            cam: None,
            pulleys_mm: None,
        }])
    }

    /// The coupling: numbers joined by `;`, at most one per joint springfit handles, not all
    /// zero, each within the largest gear ratio.
    fn coupling(&self) -> Result<Vec<f64>> {
        let f = &self.f;
        let coupling: Vec<f64> = f[4]
            .split(';')
            .map(|x| x.trim().parse::<f64>().ok().filter(|v| v.is_finite()))
            .collect::<Option<Vec<_>>>()
            .ok_or_else(|| self.bad("coupling", format!("`{}` is not a list of numbers joined by `;`", f[4])))?;
        if coupling.len() > MAX_LINKS {
            return Err(self.bad(
                "coupling",
                format!("has {} entries: springfit handles chains of up to {MAX_LINKS} joints", coupling.len()),
            ));
        }
        if coupling.iter().all(|a| *a == 0.0) {
            return Err(self.bad("coupling", "a coupling of all zeros moves nothing"));
        }
        if let Some(a) = coupling.iter().find(|a| a.abs() > MAX_COUPLING) {
            return Err(self.bad(
                "coupling",
                format!(
                    "entry {} is beyond the largest gear ratio springfit accepts, {}",
                    show(*a),
                    show(MAX_COUPLING)
                ),
            ));
        }
        Ok(coupling)
    }

    /// The stiffness, ≥ 0 and within the limits, in the unit of the profile (a cam's follower
    /// rate: [`CAM_UNIT`]).
    fn stiffness(&self, profile: Option<Profile>) -> Result<f64> {
        let stiffness = self.num(6, "stiffness")?;
        if stiffness < 0.0 {
            return Err(self.bad("stiffness", format!("must be ≥ 0, got {}", show(stiffness))));
        }
        within(stiffness, MAX_STIFFNESS, "").map_err(|e| self.bad("stiffness", e))?;
        let unit = profile.map_or(CAM_UNIT, |p| p.unit());
        if self.f[7].trim() != unit {
            let what = profile.map_or("cam's follower rate", |p| p.name());
            return Err(self.bad("unit", format!("a {what} element's stiffness is in {unit}, not `{}`", self.f[7])));
        }
        Ok(stiffness)
    }

    /// What can be set after assembly (files of 16 columns or more): an adjustable offset's range
    /// in (0, π], a linear trim spring's rate range, both columns or neither.
    fn adjustment(&self, profile: Option<Profile>) -> Result<Adjustment> {
        let f = &self.f;
        let mut adjust = Adjustment::default();
        if !f[13].trim().is_empty() {
            let r = self.num(13, "adjust_range_rad")?;
            if !(r > 0.0 && r <= std::f64::consts::PI) {
                return Err(self.bad("adjust_range_rad", format!("must be in (0, π] rad, got {r}")));
            }
            adjust.adjust_range = Some(r);
        }
        match (f[14].trim().is_empty(), f[15].trim().is_empty()) {
            (true, true) => {}
            (false, false) => {
                let (lo, hi) = (self.num(14, "trim_min")?, self.num(15, "trim_max")?);
                if !(lo >= 0.0 && hi > lo) {
                    return Err(
                        self.bad("trim_max", format!("a trim range needs 0 ≤ trim_min < trim_max, got [{lo}, {hi}]"))
                    );
                }
                if profile != Some(Profile::Linear) {
                    return Err(self.bad("trim_min", "only linear springs can be trims"));
                }
                adjust.trim_range = Some([lo, hi]);
            }
            _ => return Err(self.bad("trim_max", "trim_min and trim_max are given together or not at all")),
        }
        Ok(adjust)
    }

    /// A cam's line: its file read and checked against the line, one row per non-zero
    /// coefficient.
    fn cam_rows(
        &self,
        coupling: Vec<f64>,
        follower_rate: f64,
        gear_ratio: Option<f64>,
        file: &str,
        common: Common,
    ) -> Result<Vec<BomRow>> {
        let cam = CamRowText {
            bom: self.path,
            line: self.ln,
            id: &self.f[0],
            coupling: &coupling,
            first_knot: self.angle(5, "offset_rad")?,
            follower_rate,
            gear_ratio,
            file,
        };
        if common.stock_rate.is_some() {
            return Err(self.bad("stock_rate", "a cam has no stock rate: leave it empty"));
        }
        // Written as the knot span; the file's knots say it exactly.
        self.num(9, "max_deflection_rad")?;
        let (coefficients, summary, span) = cam.load(self.num(8, "max_torque_nm")?, common.preload_nm)?;
        Ok(coefficients
            .into_iter()
            .map(|(elements, c)| BomRow {
                id: elements.0,
                family: self.f[1].clone(),
                element: elements.1,
                stiffness: c,
                max_torque_nm: summary.max_torque_nm,
                max_deflection_rad: span,
                stock_rate: None,
                tolerance: common.tolerance,
                preload_nm: None,
                adjust: common.adjust,
                cam: Some(summary),
                pulleys_mm: None,
            })
            .collect())
    }
}

/// The columns a spring's and a cam's line share, read.
struct Common {
    stock_rate: Option<f64>,
    tolerance: f64,
    preload_nm: Option<f64>,
    adjust: Adjustment,
}

/// A cam's row in `bom.csv`, read: what its file must agree with.
struct CamRowText<'a> {
    bom: &'a Path,
    line: usize,
    id: &'a str,
    coupling: &'a [f64],
    first_knot: f64,
    follower_rate: f64,
    gear_ratio: Option<f64>,
    file: &'a str,
}

/// A cam's coefficient rows: ((id, element), |cⱼ|).
type CoefficientRows = Vec<((String, Element), f64)>;

impl CamRowText<'_> {
    /// Reads the cam's file and checks it against the row: the coefficient rows (zero
    /// coefficients left out), the summary and the knot span.
    fn load(&self, max_torque_nm: f64, preload_nm: Option<f64>) -> Result<(CoefficientRows, CamSummary, f64)> {
        let ln = self.line;
        let bad = |field: &str, reason: String| Error::invalid(self.bom, format!("line {ln}: {field}"), reason);
        if self.id.contains('.') || self.id.trim().is_empty() {
            return Err(bad("id", format!("a cam's id is a name without `.` (C01), got `{}`", self.id)));
        }
        if self.file.is_empty() {
            return Err(bad(
                "file",
                "a cam's row (profile `cam`, side empty) names the file of its coefficients (cams/<id>.toml); \
                 files before springfit wrote one listed each coefficient as a row (side `+j/N/h`)"
                    .into(),
            ));
        }
        let cam_path = self.bom.parent().unwrap_or(Path::new("")).join(self.file);
        if !cam_path.is_file() {
            return Err(bad("file", format!("{} does not exist", cam_path.display())));
        }
        let cam = CamFile::read(&cam_path)?;
        let disagree = |field: &str, file_value: String, column: &str, row_value: String| {
            Error::invalid(
                &cam_path,
                field,
                format!(
                    "{file_value} disagrees with {column} = {row_value} of row {} (line {ln}) of {}",
                    self.id,
                    self.bom.display()
                ),
            )
        };
        if cam.coupling.len() != self.coupling.len() || cam.coupling.iter().zip(self.coupling).any(|(a, b)| a != b) {
            return Err(disagree(
                "coupling",
                format!("({})", coupling_text(&cam.coupling)),
                "coupling",
                format!("({})", coupling_text(self.coupling)),
            ));
        }
        if cam.first_knot_rad != self.first_knot {
            return Err(disagree(
                "first_knot_rad",
                format!("{}", cam.first_knot_rad),
                "offset_rad",
                format!("{}", self.first_knot),
            ));
        }
        let build = cam.realisation.build();
        if build.follower_rate != self.follower_rate {
            return Err(disagree(
                "realisation.follower_rate_n_per_mm",
                format!("{}", build.follower_rate),
                "stiffness",
                format!("{}", self.follower_rate),
            ));
        }
        if let Some(g) = self.gear_ratio.filter(|g| *g != build.gear_ratio) {
            return Err(disagree(
                "realisation.gear_ratio",
                format!("{}", build.gear_ratio),
                "gear_ratio",
                format!("{g}"),
            ));
        }
        let knots: Knots = cam.knot_vector();
        let coefficients = cam
            .coefficients_j
            .iter()
            .enumerate()
            .filter(|(_, c)| **c != 0.0)
            .map(|(j, &c)| {
                let negative = c < 0.0;
                let id = format!("{}.{j:02}{}", self.id, if negative { "-" } else { "+" });
                let element = Element {
                    profile: Profile::Spline(knots.basis(j, negative)),
                    coupling: self.coupling.to_vec(),
                    offset: self.first_knot,
                };
                ((id, element), c.abs())
            })
            .collect();
        Ok((coefficients, CamSummary { build, max_torque_nm, preload_nm }, knots.hi() - knots.lo))
    }
}

/// What a builder sets on an element after assembly, in words.
fn after_assembly(a: &Adjustment) -> String {
    match (a.trim_range, a.adjust_range) {
        (Some([lo, hi]), _) => format!("trim: rate {} to {} N·m/rad", fmt_number(lo), fmt_number(hi)),
        (None, Some(r)) => format!("offset ± {} rad", fmt_number(r)),
        (None, None) => "–".into(),
    }
}

/// The bill of materials as a Markdown table with totals per unit (a cam is one row, its
/// stiffness the follower rate).
pub fn to_markdown(title: &str, rows: &[BomRow]) -> String {
    let lines = lines("bom.csv", rows);
    let mut s = format!("# Bill of materials: {title}\n\n");
    s.push_str("| id | family | profile | coupling a | offset x₀ (rad) | stiffness | unit | max torque (N·m) | max deflection (rad) | stock rate | tolerance | preload (N·m) | after assembly |\n");
    s.push_str("| --- | --- | --- | --- | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | --- |\n");
    for l in &lines {
        let profile = match &l.cam {
            Some((path, f)) => format!("cam, gear ratio {:.4}, {path}", f.realisation.gear_ratio),
            None if l.side.is_empty() => l.profile.to_string(),
            None => format!("{} {}", l.profile, l.side),
        };
        s.push_str(&format!(
            "| {} | {} | {} | ({}) | {:.4} | {:.4} | {} | {:.3} | {:.3} | {} | {} | {} | {} |\n",
            l.id,
            l.family.replace('|', "/"),
            profile,
            l.coupling.iter().map(|a| fmt_number(*a)).collect::<Vec<_>>().join(", "),
            l.offset,
            l.stiffness,
            crate::units::shown(l.unit),
            l.max_torque_nm,
            l.max_deflection_rad,
            l.stock_rate.map(|x| format!("{x}")).unwrap_or_else(|| "–".into()),
            // A catalogue that states no tolerance is not one of ±0 %.
            if l.tolerance == 0.0 {
                "not stated".to_string()
            } else {
                format!("±{} %", fmt_number(l.tolerance * 100.0))
            },
            l.preload_nm.map(|x| format!("{x:.3}")).unwrap_or_else(|| "–".into()),
            after_assembly(&l.adjust),
        ));
    }
    s.push_str(&format!("\n**{} elements.** Total stiffness per unit:\n\n", lines.len()));
    let mut units: Vec<&str> = lines.iter().map(|l| l.unit).collect();
    units.sort_unstable();
    units.dedup();
    for u in units {
        let (count, total) = lines.iter().filter(|l| l.unit == u).fold((0, 0.0), |(c, t), l| (c + 1, t + l.stiffness));
        let noun = if count == 1 { "element" } else { "elements" };
        s.push_str(&format!("- {}: {total:.4} over {count} {noun}\n", crate::units::shown(u)));
    }
    if lines.iter().all(|l| l.preload_nm.is_some()) {
        let total: f64 = lines.iter().filter_map(|l| l.preload_nm).map(f64::abs).sum();
        s.push_str(&format!(
            "\n**Total preload** Σ|τ(q_eq)| = {total:.3} N·m (torques the elements hold against each other at the equilibrium; a rate error un-cancels them)\n"
        ));
    }
    s
}

/// Reads the file of [`read_measured`].
pub fn load_measured(path: &std::path::Path) -> Result<(Vec<BomRow>, Vec<Option<f64>>)> {
    read_measured(path, &crate::input::read_text(path)?)
}

/// Reads a bill of materials with a `measured_stiffness` column (anywhere; blank = as designed):
/// the rows and the measured rates. On a cam's line the measured value is its follower spring's
/// rate (N/mm); each of its coefficient rows gets its stiffness scaled by measured / designed.
pub fn read_measured(path: &std::path::Path, text: &str) -> Result<(Vec<BomRow>, Vec<Option<f64>>)> {
    use crate::error::Error;
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let Some((_, header)) = lines.next() else {
        return Err(Error::invalid(path, "line 1: header", "the file is empty"));
    };
    let names = split_csv_line(header.trim_start_matches('\u{feff}').trim())
        .map_err(|e| Error::invalid(path, "line 1: header", e))?;
    let col = names.iter().position(|n| n.trim() == "measured_stiffness").ok_or_else(|| {
        Error::invalid(
            path,
            "line 1: measured_stiffness",
            "the bill of materials has no measured_stiffness column: add one and fill in the rates from the spring tester (blank = as designed)",
        )
    })?;
    let strip = |f: Vec<String>| {
        f.into_iter().enumerate().filter(|(i, _)| *i != col).map(|(_, s)| csv_field(&s)).collect::<Vec<_>>().join(",")
    };
    let mut rest = strip(names.clone());
    rest.push('\n');
    let mut measured = Vec::new();
    for (idx, line) in lines {
        let ln = idx + 1;
        let f = split_csv_line(line).map_err(|e| Error::invalid(path, format!("line {ln}: row"), e))?;
        if f.len() != names.len() {
            return Err(Error::invalid(
                path,
                format!("line {ln}: row"),
                format!("has {} fields, the header {}", f.len(), names.len()),
            ));
        }
        let m = f[col].trim();
        measured.push(if m.is_empty() {
            None
        } else {
            let v: f64 = m.parse().map_err(|_| {
                Error::invalid(path, format!("line {ln}: measured_stiffness"), format!("`{m}` is not a number"))
            })?;
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::invalid(
                    path,
                    format!("line {ln}: measured_stiffness"),
                    format!("must be a finite rate ≥ 0, got {m}"),
                ));
            }
            Some(v)
        });
        rest.push_str(&strip(f));
        rest.push('\n');
    }
    let (rows, origin) = crate::files::bom::parse_lines(path, &rest)?;
    // A cam's line gives its follower spring's rate: measured / designed scales the whole cam,
    // every coefficient row, as the build does (one δ per cam).
    let measured = rows
        .iter()
        .zip(&origin)
        .map(|(r, &line)| {
            let m = measured[line]?;
            Some(match r.cam {
                Some(cam) => r.stiffness * (m / cam.build.follower_rate),
                None => m,
            })
        })
        .collect();
    Ok((rows, measured))
}

#[cfg(test)]
mod tests;
