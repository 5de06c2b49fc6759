//! The bill of materials: the fitted springs as a CSV a workshop can build from and springfit can
//! read back to rebuild the potential exactly.
//!
//! Columns: `id,family,profile,side,coupling,offset_rad,stiffness,unit,max_torque_nm,
//! max_deflection_rad,stock_rate,tolerance,adjust_range_rad,trim_min,trim_max`. The last three
//! say what can be set after assembly (empty when nothing): an adjustable offset's ± range and a
//! trim spring's rate range (see [`crate::trim`]); files with the first twelve columns only (older
//! springfit) are read as before. `coupling` is the vector a with entries joined by
//! `;` (`1;-2`), `side` is `+`, `-` or empty. Numbers are written with Rust's shortest
//! round-trip formatting, so reading the file back gives bit-identical stiffnesses and offsets.

use std::path::Path;

use crate::design::{MAX_LINKS, read_text};
use crate::elements::{Element, Profile, fmt_number};
use crate::error::{Error, Result};
use crate::potential::SpringSet;

/// The CSV header.
pub const HEADER: &str = "id,family,profile,side,coupling,offset_rad,stiffness,unit,max_torque_nm,max_deflection_rad,stock_rate,tolerance,adjust_range_rad,trim_min,trim_max";

/// The header of bills of materials written before the after-assembly columns existed.
const HEADER_12: &str =
    "id,family,profile,side,coupling,offset_rad,stiffness,unit,max_torque_nm,max_deflection_rad,stock_rate,tolerance";

/// What can be set on an element after assembly.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Adjustment {
    /// ± rad the offset x₀ can be moved (an adjustable family), None if fixed.
    pub adjust_range: Option<f64>,
    /// The rate range [lo, hi] of a trim spring, N·m/rad; None if not a trim.
    pub trim_range: Option<[f64; 2]>,
}

/// One row of the bill of materials.
#[derive(Debug, Clone, PartialEq)]
pub struct BomRow {
    /// `S01`, `S02`, …
    pub id: String,
    /// The catalogue family's name.
    pub family: String,
    /// The element.
    pub element: Element,
    /// Fitted stiffness in the profile's unit.
    pub stiffness: f64,
    /// Largest torque on the element's transmission coordinate over the region, N·m.
    pub max_torque_nm: f64,
    /// Largest deflection |x − x₀| while engaged over the region, rad.
    pub max_deflection_rad: f64,
    /// The nearest stock rate the catalogue offers, if it lists any.
    pub stock_rate: Option<f64>,
    /// ± fraction the built element may deviate.
    pub tolerance: f64,
    /// What can be set after assembly.
    pub adjust: Adjustment,
}

/// Quotes a CSV field if it needs it.
pub fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) { format!("\"{}\"", s.replace('"', "\"\"")) } else { s.to_string() }
}

/// Splits one CSV line into fields (RFC 4180 quoting).
pub fn split_csv_line(line: &str) -> std::result::Result<Vec<String>, String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut chars = line.chars().peekable();
    let mut quoted = false;
    let mut at_start = true;
    while let Some(c) = chars.next() {
        if quoted {
            if c == '"' {
                if chars.peek() == Some(&'"') {
                    cur.push('"');
                    chars.next();
                } else {
                    quoted = false;
                }
            } else {
                cur.push(c);
            }
        } else if c == '"' && at_start {
            quoted = true;
            at_start = false;
        } else if c == ',' {
            out.push(std::mem::take(&mut cur));
            at_start = true;
        } else {
            cur.push(c);
            at_start = false;
        }
    }
    if quoted {
        return Err("unterminated quoted field".into());
    }
    out.push(cur);
    Ok(out)
}

/// Writes the rows as CSV text.
pub fn to_csv(rows: &[BomRow]) -> String {
    let mut s = String::from(HEADER);
    s.push('\n');
    for r in rows {
        let e = &r.element;
        let fields = [
            csv_field(&r.id),
            csv_field(&r.family),
            e.profile.name().to_string(),
            e.profile.side().to_string(),
            e.coupling_text(),
            format!("{}", e.offset),
            format!("{}", r.stiffness),
            e.profile.unit().to_string(),
            format!("{}", r.max_torque_nm),
            format!("{}", r.max_deflection_rad),
            r.stock_rate.map(|x| format!("{x}")).unwrap_or_default(),
            format!("{}", r.tolerance),
            r.adjust.adjust_range.map(|x| format!("{x}")).unwrap_or_default(),
            r.adjust.trim_range.map(|x| format!("{}", x[0])).unwrap_or_default(),
            r.adjust.trim_range.map(|x| format!("{}", x[1])).unwrap_or_default(),
        ];
        s.push_str(&fields.join(","));
        s.push('\n');
    }
    s
}

/// Reads a bill of materials. Every problem names the line and the column.
pub fn read(path: &Path) -> Result<Vec<BomRow>> {
    parse(path, &read_text(path)?)
}

/// Parses bill-of-materials text (see [`read`]).
pub fn parse(path: &Path, text: &str) -> Result<Vec<BomRow>> {
    let bad = |line: usize, field: &str, reason: String| Error::invalid(path, format!("line {line}: {field}"), reason);
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let (_, header) = lines.next().ok_or_else(|| bad(1, "header", "the file is empty".into()))?;
    let header = header.trim_start_matches('\u{feff}').trim();
    let width = if header == HEADER {
        15
    } else if header == HEADER_12 {
        12
    } else {
        return Err(bad(1, "header", format!("expected `{HEADER}`")));
    };
    let mut rows = Vec::new();
    let mut dof = None;
    for (idx, line) in lines {
        let ln = idx + 1;
        let f = split_csv_line(line).map_err(|e| bad(ln, "row", e))?;
        if f.len() != width {
            return Err(bad(ln, "row", format!("has {} fields, expected {width}", f.len())));
        }
        let num = |i: usize, name: &str| -> Result<f64> {
            let v: f64 = f[i].trim().parse().map_err(|_| bad(ln, name, format!("`{}` is not a number", f[i])))?;
            if !v.is_finite() {
                return Err(bad(ln, name, format!("`{}` is not a finite number", f[i])));
            }
            Ok(v)
        };
        let profile = Profile::parse(f[2].trim(), f[3].trim()).map_err(|e| bad(ln, "profile", e))?;
        let coupling: Vec<f64> = f[4]
            .split(';')
            .map(|x| x.trim().parse::<f64>().ok().filter(|v| v.is_finite()))
            .collect::<Option<Vec<_>>>()
            .ok_or_else(|| bad(ln, "coupling", format!("`{}` is not a list of numbers joined by `;`", f[4])))?;
        if coupling.len() > MAX_LINKS {
            return Err(bad(
                ln,
                "coupling",
                format!("has {} entries: springfit handles chains of up to {MAX_LINKS} joints", coupling.len()),
            ));
        }
        if coupling.iter().all(|a| *a == 0.0) {
            return Err(bad(ln, "coupling", "a coupling of all zeros moves nothing".into()));
        }
        match dof {
            None => dof = Some(coupling.len()),
            Some(d) if d != coupling.len() => {
                return Err(bad(ln, "coupling", format!("has {} entries but earlier rows have {d}", coupling.len())));
            }
            _ => {}
        }
        let stiffness = num(6, "stiffness")?;
        if stiffness < 0.0 {
            return Err(bad(ln, "stiffness", format!("must be ≥ 0, got {stiffness}")));
        }
        if f[7].trim() != profile.unit() {
            return Err(bad(
                ln,
                "unit",
                format!("a {} element's stiffness is in {}, not `{}`", profile.name(), profile.unit(), f[7]),
            ));
        }
        let stock_rate = if f[10].trim().is_empty() { None } else { Some(num(10, "stock_rate")?) };
        let tolerance = num(11, "tolerance")?;
        if !(0.0..1.0).contains(&tolerance) {
            return Err(bad(ln, "tolerance", format!("must be a fraction in [0, 1), got {tolerance}")));
        }
        let mut adjust = Adjustment::default();
        if width == 15 {
            if !f[12].trim().is_empty() {
                let r = num(12, "adjust_range_rad")?;
                if !(r > 0.0 && r <= std::f64::consts::PI) {
                    return Err(bad(ln, "adjust_range_rad", format!("must be in (0, π] rad, got {r}")));
                }
                adjust.adjust_range = Some(r);
            }
            match (f[13].trim().is_empty(), f[14].trim().is_empty()) {
                (true, true) => {}
                (false, false) => {
                    let (lo, hi) = (num(13, "trim_min")?, num(14, "trim_max")?);
                    if !(lo >= 0.0 && hi > lo) {
                        return Err(bad(
                            ln,
                            "trim_max",
                            format!("a trim range needs 0 ≤ trim_min < trim_max, got [{lo}, {hi}]"),
                        ));
                    }
                    if profile != Profile::Linear {
                        return Err(bad(ln, "trim_min", "only linear springs can be trims".into()));
                    }
                    adjust.trim_range = Some([lo, hi]);
                }
                _ => return Err(bad(ln, "trim_max", "trim_min and trim_max are given together or not at all".into())),
            }
        }
        rows.push(BomRow {
            id: f[0].clone(),
            family: f[1].clone(),
            element: Element { profile, coupling, offset: num(5, "offset_rad")? },
            stiffness,
            max_torque_nm: num(8, "max_torque_nm")?,
            max_deflection_rad: num(9, "max_deflection_rad")?,
            stock_rate,
            tolerance,
            adjust,
        });
    }
    if rows.is_empty() {
        return Err(bad(1, "rows", "the bill of materials lists no element".into()));
    }
    Ok(rows)
}

/// The spring set a bill of materials describes.
pub fn spring_set(rows: &[BomRow]) -> SpringSet {
    SpringSet {
        elements: rows.iter().map(|r| r.element.clone()).collect(),
        stiffness: rows.iter().map(|r| r.stiffness).collect(),
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

/// The bill of materials as a Markdown table with totals per unit.
pub fn to_markdown(title: &str, rows: &[BomRow]) -> String {
    let mut s = format!("# Bill of materials: {title}\n\n");
    s.push_str("| id | family | profile | coupling a | offset x₀ (rad) | stiffness | unit | max torque (N·m) | max deflection (rad) | stock rate | tolerance | after assembly |\n");
    s.push_str("| --- | --- | --- | --- | ---: | ---: | --- | ---: | ---: | ---: | ---: | --- |\n");
    for r in rows {
        let e = &r.element;
        s.push_str(&format!(
            "| {} | {} | {}{} | ({}) | {:.4} | {:.4} | {} | {:.3} | {:.3} | {} | ±{}% | {} |\n",
            r.id,
            r.family.replace('|', "/"),
            e.profile.name(),
            if e.profile.side().is_empty() { String::new() } else { format!(" {}", e.profile.side()) },
            e.coupling.iter().map(|a| fmt_number(*a)).collect::<Vec<_>>().join(", "),
            e.offset,
            r.stiffness,
            e.profile.unit(),
            r.max_torque_nm,
            r.max_deflection_rad,
            r.stock_rate.map(|x| format!("{x}")).unwrap_or_else(|| "–".into()),
            fmt_number(r.tolerance * 100.0),
            after_assembly(&r.adjust),
        ));
    }
    s.push_str(&format!("\n**{} elements.** Total stiffness per unit:\n\n", rows.len()));
    let mut units: Vec<&str> = rows.iter().map(|r| r.element.profile.unit()).collect();
    units.sort_unstable();
    units.dedup();
    for u in units {
        let (count, total) =
            rows.iter().filter(|r| r.element.profile.unit() == u).fold((0, 0.0), |(c, t), r| (c + 1, t + r.stiffness));
        s.push_str(&format!("- {u}: {total:.4} over {count} element(s)\n"));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::elements::Side;

    fn rows() -> Vec<BomRow> {
        vec![
            BomRow {
                id: "S01".into(),
                family: "bevel, crank".into(),
                element: Element { profile: Profile::Crank, coupling: vec![1.0, -2.0], offset: 0.1 + 0.2 },
                stiffness: 1.0 / 3.0,
                max_torque_nm: 0.25,
                max_deflection_rad: 1.5,
                stock_rate: None,
                tolerance: 0.05,
                adjust: Adjustment { adjust_range: Some(0.3), trim_range: None },
            },
            BomRow {
                id: "S02".into(),
                family: "stop \"A\"".into(),
                element: Element { profile: Profile::Compression(Side::Minus), coupling: vec![0.0, 1.0], offset: -0.7 },
                stiffness: 12.5,
                max_torque_nm: 3.0,
                max_deflection_rad: 0.2,
                stock_rate: Some(12.0),
                tolerance: 0.1,
                adjust: Adjustment::default(),
            },
            BomRow {
                id: "S03".into(),
                family: "trim".into(),
                element: Element { profile: Profile::Linear, coupling: vec![1.0, 1.0], offset: 1.5 },
                stiffness: 2.0,
                max_torque_nm: 1.0,
                max_deflection_rad: 0.5,
                stock_rate: None,
                tolerance: 0.0,
                adjust: Adjustment { adjust_range: None, trim_range: Some([0.5, 3.5]) },
            },
        ]
    }

    #[test]
    fn round_trips_bit_for_bit() {
        let text = to_csv(&rows());
        let back = parse(Path::new("bom.csv"), &text).unwrap();
        assert_eq!(back, rows());
        assert!(to_markdown("t", &rows()).contains("N*m/rad: 14.5000 over 2 element(s)"));
        assert!(to_markdown("t", &rows()).contains("trim: rate 0.5 to 3.5 N·m/rad"));
        // A twelve-column file of an older springfit still reads.
        let old = format!("{HEADER_12}\nS01,a,linear,,1;0,0,1,N*m/rad,1,1,,0\n");
        assert_eq!(parse(Path::new("bom.csv"), &old).unwrap()[0].adjust, Adjustment::default());
    }

    #[test]
    fn nonsense_is_reported_with_line_and_field() {
        let good = to_csv(&rows());
        let cases = [
            (good.replace("12.5,", "-12.5,"), "line 3: stiffness"),
            (good.replace("1;-2", "1;x"), "line 2: coupling"),
            (good.replace("0;1", "0;1;0"), "line 3: coupling"),
            (good.replace("crank", "spiral"), "line 2: profile"),
            (good.replace(",N*m,", ",N*m/rad,"), "line 2: unit"),
            (good.replace("0.25,", "NaN,"), "line 2: max_torque_nm"),
            (HEADER.to_string(), "rows"),
            (String::new(), "header"),
            (good.replacen("id,", "ident,", 1), "header"),
            (good.replace("S01,", "S01,extra,"), "line 2: row"),
            (good.replace(",0.5,3.5", ",3.5,0.5"), "line 4: trim_max"),
            (good.replace(",0.5,3.5", ",0.5,"), "line 4: trim_max"),
            (good.replace(",0.3,,", ",-1,,"), "line 2: adjust_range_rad"),
        ];
        for (text, expected) in cases {
            let err = parse(Path::new("bom.csv"), &text).unwrap_err().to_string();
            assert!(err.contains(expected), "expected `{expected}` in `{err}`");
        }
    }

    /// A bill of materials is read back into a spring set whose Hessian is n × n per element: a
    /// coupling of thousands of entries (run through fuzz/fuzz_targets/bom.rs) made
    /// evaluating it take seconds. No design has more than eight joints.
    #[test]
    fn couplings_longer_than_the_longest_chain_are_errors() {
        let row = |coupling: &str| format!("{HEADER}\nS01,a,linear,,{coupling},0,1,N*m/rad,1,1,,0,,,\n");
        let wide = vec!["1"; 2000].join(";");
        let err = parse(Path::new("bom.csv"), &row(&wide)).unwrap_err().to_string();
        assert!(err.contains("bom.csv") && err.contains("line 2: coupling") && err.contains("2000 entries"), "{err}");
        assert!(parse(Path::new("bom.csv"), &row(&["1"; 9].join(";"))).is_err());
        let rows = parse(Path::new("bom.csv"), &row(&["1"; 8].join(";"))).unwrap();
        assert_eq!(rows[0].element.coupling.len(), 8);
    }

    #[test]
    fn csv_quoting() {
        assert_eq!(split_csv_line("a,\"b,c\",\"d\"\"e\",").unwrap(), vec!["a", "b,c", "d\"e", ""]);
        assert!(split_csv_line("\"open").is_err());
    }
}
