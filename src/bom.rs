//! The bill of materials: the fitted springs as a CSV a workshop can build from and springfit can
//! read back to rebuild the potential exactly.
//!
//! Columns: `id,family,profile,side,coupling,offset_rad,stiffness,unit,max_torque_nm,
//! max_deflection_rad,stock_rate,tolerance,preload_nm,adjust_range_rad,trim_min,trim_max`.
//! `coupling` is the vector a with entries joined by `;` (`1;-2`), `side` is `+`, `-` or empty,
//! `preload_nm` the element's torque on its coordinate at the equilibrium (signed; empty when
//! unknown). The last three say what can be set after assembly (empty when nothing): an adjustable
//! offset's ± range and a trim spring's rate range (see [`crate::trim`]). Files of older springfit
//! versions (twelve columns, ending at `tolerance`, or thirteen, ending at `preload_nm`) are read
//! as well. Numbers are written with Rust's shortest
//! round-trip formatting, so reading the file back gives bit-identical stiffnesses and offsets.

use std::path::Path;

use crate::design::{MAX_LINKS, read_text};
use crate::elements::{Element, Profile, fmt_number};
use crate::error::{Error, Result};
use crate::potential::SpringSet;

/// The CSV header.
pub const HEADER: &str = "id,family,profile,side,coupling,offset_rad,stiffness,unit,max_torque_nm,max_deflection_rad,stock_rate,tolerance,preload_nm,adjust_range_rad,trim_min,trim_max";

/// The header of files with the preload but before the after-assembly columns (still read).
const HEADER_13: &str = "id,family,profile,side,coupling,offset_rad,stiffness,unit,max_torque_nm,max_deflection_rad,stock_rate,tolerance,preload_nm";

/// The header of files written before the `preload_nm` column (still read).
pub const HEADER_WITHOUT_PRELOAD: &str =
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
    /// Torque on the element's coordinate at the equilibrium, k·u′(a·q_eq − x₀), N·m (signed).
    /// None when read from a file without the column.
    pub preload_nm: Option<f64>,
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
            r.preload_nm.map(|x| format!("{x}")).unwrap_or_default(),
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
    let columns = if header == HEADER {
        16
    } else if header == HEADER_13 {
        13
    } else if header == HEADER_WITHOUT_PRELOAD {
        12
    } else {
        return Err(bad(
            1,
            "header",
            format!("expected `{HEADER}` (or an older file's first 12 or 13 of those columns)"),
        ));
    };
    let mut rows = Vec::new();
    let mut dof = None;
    for (idx, line) in lines {
        let ln = idx + 1;
        let f = split_csv_line(line).map_err(|e| bad(ln, "row", e))?;
        if f.len() != columns {
            return Err(bad(ln, "row", format!("has {} fields, expected {columns}", f.len())));
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
        let preload_nm = if columns < 13 || f[12].trim().is_empty() { None } else { Some(num(12, "preload_nm")?) };
        let mut adjust = Adjustment::default();
        if columns == 16 {
            if !f[13].trim().is_empty() {
                let r = num(13, "adjust_range_rad")?;
                if !(r > 0.0 && r <= std::f64::consts::PI) {
                    return Err(bad(ln, "adjust_range_rad", format!("must be in (0, π] rad, got {r}")));
                }
                adjust.adjust_range = Some(r);
            }
            match (f[14].trim().is_empty(), f[15].trim().is_empty()) {
                (true, true) => {}
                (false, false) => {
                    let (lo, hi) = (num(14, "trim_min")?, num(15, "trim_max")?);
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
            preload_nm,
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
    s.push_str("| id | family | profile | coupling a | offset x₀ (rad) | stiffness | unit | max torque (N·m) | max deflection (rad) | stock rate | tolerance | preload (N·m) | after assembly |\n");
    s.push_str("| --- | --- | --- | --- | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | --- |\n");
    for r in rows {
        let e = &r.element;
        s.push_str(&format!(
            "| {} | {} | {}{} | ({}) | {:.4} | {:.4} | {} | {:.3} | {:.3} | {} | {} | {} | {} |\n",
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
            // A catalogue that states no tolerance is not one of ±0 %.
            if r.tolerance == 0.0 {
                "not stated".to_string()
            } else {
                format!("±{} %", fmt_number(r.tolerance * 100.0))
            },
            r.preload_nm.map(|x| format!("{x:.3}")).unwrap_or_else(|| "–".into()),
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
    if rows.iter().all(|r| r.preload_nm.is_some()) {
        let total: f64 = rows.iter().filter_map(|r| r.preload_nm).map(f64::abs).sum();
        s.push_str(&format!(
            "\n**Total preload** Σ|τ(q_eq)| = {total:.3} N·m (torques the elements hold against each other at the equilibrium; a rate error un-cancels them)\n"
        ));
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
                preload_nm: Some(-0.125),
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
                preload_nm: Some(2.5),
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
                preload_nm: Some(0.0),
            },
        ]
    }

    #[test]
    fn round_trips_bit_for_bit() {
        let text = to_csv(&rows());
        let back = parse(Path::new("bom.csv"), &text).unwrap();
        assert_eq!(back, rows());
        let md = to_markdown("t", &rows());
        assert!(md.contains("N*m/rad: 14.5000 over 2 element(s)"));
        assert!(md.contains("Σ|τ(q_eq)| = 2.625 N·m"), "{md}");
    }

    /// Files written before the preload column are still read (preload unknown), and a
    /// preload that is not a number is reported.
    #[test]
    fn files_without_the_preload_column_are_read() {
        let mut old = String::from(HEADER_WITHOUT_PRELOAD);
        old.push('\n');
        for line in to_csv(&rows()).lines().skip(1) {
            // Drop the four newer columns (preload, adjust range, trim range) from the end.
            old.push_str(line.rsplitn(5, ',').last().unwrap());
            old.push('\n');
        }
        let back = parse(Path::new("bom.csv"), &old).unwrap();
        let want: Vec<BomRow> =
            rows().into_iter().map(|r| BomRow { preload_nm: None, adjust: Adjustment::default(), ..r }).collect();
        assert_eq!(back, want);
        assert!(!to_markdown("t", &back).contains("Total preload"));
        let bad = to_csv(&rows()).replace(",-0.125", ",x");
        assert!(parse(Path::new("bom.csv"), &bad).unwrap_err().to_string().contains("line 2: preload_nm"));
        // Old rows under the new header have a field too few.
        let mixed = old.replacen(HEADER_WITHOUT_PRELOAD, HEADER, 1);
        assert!(parse(Path::new("bom.csv"), &mixed).unwrap_err().to_string().contains("expected 16"));
        assert!(to_markdown("t", &rows()).contains("trim: rate 0.5 to 3.5 N·m/rad"));
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
        let row = |coupling: &str| format!("{HEADER}\nS01,a,linear,,{coupling},0,1,N*m/rad,1,1,,0,,,,\n");
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
