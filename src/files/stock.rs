//! Stock lists: springs a vendor sells, one per line, exactly as the vendor publishes them, each
//! row naming its source. `[parts] stock` names one; `springfit parts` and `fit` then order a
//! stock spring wherever one is within the part's grade tolerance of the rate it needs.
//!
//! ```text
//! vendor,part_number,type,material,d_mm,D_mm,n,length_mm,rate,rate_unit,max_deflection,max_deflection_unit,max_load,max_load_unit,source
//! ```
//!
//! `type` is `torsion`, `compression` or `extension`; `D_mm` the mean coil diameter; `length_mm`
//! the free length (compression, extension) or the leg length (torsion). The units are
//! columns of their own and must be the ones of the type: `N*mm/deg`, `deg`, `N*mm` for a
//! torsion spring, `N/mm`, `mm`, `N` otherwise. Optional columns: `initial_tension_N` (an
//! extension spring's F₀) and `rate_tolerance_pct` (the vendor's stated ± tolerance on the listed
//! rate, %, which caps the grade's when a listed spring is matched; unset: ±10 %). Every bad
//! row is refused with the file, its line and the field, before any work.

use std::path::Path;

use crate::csv::split_csv_line;
use crate::error::{Error, Result};
use crate::input::read_text;
use crate::parts::StockPart;

/// The header a stock list starts with.
pub const HEADER: &str = "vendor,part_number,type,material,d_mm,D_mm,n,length_mm,rate,rate_unit,max_deflection,max_deflection_unit,max_load,max_load_unit,source";

/// The stock list the design's `[parts] stock` names (relative to the design file; none: empty),
/// read before any work so that a missing file is refused first.
pub fn of_design(design: &crate::design::Design) -> Result<Vec<StockPart>> {
    let Some(name) = &design.parts.stock else {
        return if design.parts.prefer_stock { shipped() } else { Ok(Vec::new()) };
    };
    let path = design.path.parent().unwrap_or(Path::new(".")).join(name);
    if !path.is_file() {
        return Err(Error::invalid(
            &design.path,
            "parts.stock",
            format!(
                "`{name}` names no file ({} does not exist; the path is relative to the design file)",
                path.display()
            ),
        ));
    }
    read(&path)
}

/// The stock list springfit ships, compiled in: the military-standard springs of
/// `catalogs/stock/ms24585_ms24586.csv` (MS24585, MS24586 as the ODOP project lists them).
pub const SHIPPED: &str = include_str!("../../catalogs/stock/ms24585_ms24586.csv");

/// The list read when `[parts] stock` names none and `prefer_stock` is on: [`SHIPPED`].
pub fn shipped() -> Result<Vec<StockPart>> {
    parse(Path::new("catalogs/stock/ms24585_ms24586.csv"), SHIPPED)
}

/// Reads a stock list.
pub fn read(path: &Path) -> Result<Vec<StockPart>> {
    parse(path, &read_text(path)?)
}

/// Parses the text of a stock list (`path` for messages).
pub fn parse(path: &Path, text: &str) -> Result<Vec<StockPart>> {
    let bad = |line: usize, field: &str, reason: String| Error::invalid(path, format!("line {line}: {field}"), reason);
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty() && !l.starts_with('#'));
    let (_, header) = lines.next().ok_or_else(|| bad(1, "header", "the file is empty".into()))?;
    let names: Vec<String> =
        split_csv_line(header.trim_start_matches('\u{feff}').trim()).map_err(|e| bad(1, "header", e))?;
    let want: Vec<&str> = HEADER.split(',').collect();
    if let Some(missing) = want.iter().find(|w| !names.iter().any(|n| n.trim() == **w)) {
        return Err(bad(1, missing, format!("the column `{missing}` is missing: a stock list's header is `{HEADER}`")));
    }
    let col = |name: &str| names.iter().position(|n| n.trim() == name).expect("checked above");
    let mut out = Vec::new();
    for (i, line) in lines {
        let ln = i + 1;
        let f = split_csv_line(line).map_err(|e| bad(ln, "row", e))?;
        if f.len() != names.len() {
            return Err(bad(ln, "row", format!("has {} fields, the header {}", f.len(), names.len())));
        }
        let text = |name: &str| f[col(name)].trim().to_string();
        let num = |name: &str| -> Result<f64> {
            let v = text(name);
            match v.parse::<f64>() {
                Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
                _ => Err(bad(ln, name, format!("`{v}` is not a positive number"))),
            }
        };
        let kind = text("type");
        let units: [&str; 3] = match kind.as_str() {
            "torsion" => ["N*mm/deg", "deg", "N*mm"],
            "compression" | "extension" => ["N/mm", "mm", "N"],
            other => {
                return Err(bad(ln, "type", format!("`{other}`: expected torsion, compression or extension")));
            }
        };
        for (name, unit) in ["rate_unit", "max_deflection_unit", "max_load_unit"].into_iter().zip(units) {
            if text(name) != unit {
                return Err(bad(ln, name, format!("`{}`: a {kind} spring's is `{unit}`", text(name))));
            }
        }
        for name in ["vendor", "part_number", "source"] {
            if text(name).is_empty() {
                return Err(bad(ln, name, "is empty: every row names its vendor, part number and source".into()));
            }
        }
        let (d, dm) = (num("d_mm")?, num("D_mm")?);
        if dm <= d {
            return Err(bad(
                ln,
                "D_mm",
                format!(
                    "the mean coil diameter {dm} mm is not above the wire's d_mm = {d} mm: D_mm is the mean diameter, outside diameter less d"
                ),
            ));
        }
        out.push(StockPart {
            vendor: text("vendor"),
            part_number: text("part_number"),
            kind,
            material: text("material"),
            d,
            dm,
            n: num("n")?,
            length: num("length_mm")?,
            rate: num("rate")?,
            max_deflection: num("max_deflection")?,
            max_load: num("max_load")?,
            source: text("source"),
            rate_tolerance: match names.iter().position(|n| n.trim() == "rate_tolerance_pct") {
                Some(i) if !f[i].trim().is_empty() => match f[i].trim().parse::<f64>() {
                    Ok(x) if x.is_finite() && x > 0.0 && x < 100.0 => Some(x / 100.0),
                    _ => {
                        return Err(bad(
                            ln,
                            "rate_tolerance_pct",
                            format!("`{}` is not the vendor's rate tolerance in % (above 0, below 100)", f[i].trim()),
                        ));
                    }
                },
                _ => None,
            },
            initial_tension: match names.iter().position(|n| n.trim() == "initial_tension_N") {
                Some(i) if !f[i].trim().is_empty() => match f[i].trim().parse::<f64>() {
                    Ok(x) if x.is_finite() && x >= 0.0 => Some(x),
                    _ => {
                        return Err(bad(ln, "initial_tension_N", format!("`{}` is not a force in N", f[i].trim())));
                    }
                },
                _ => None,
            },
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const ROW: &str =
        "Example,EX-1,torsion,music wire,1,10,5,20,12.5,N*mm/deg,180,deg,2000,N*mm,invented for this test";

    #[test]
    fn reads_rows_and_names_bad_fields() {
        let p = Path::new("stock.csv");
        let rows = parse(p, &format!("{HEADER}\n{ROW}\n")).unwrap();
        assert_eq!(rows.len(), 1);
        assert_eq!((rows[0].part_number.as_str(), rows[0].rate), ("EX-1", 12.5));
        let err = |text: String, field: &str| {
            let e = parse(p, &text).unwrap_err().to_string();
            assert!(e.contains("stock.csv") && e.contains(field), "{e}");
        };
        err(format!("{}\n{ROW}\n", HEADER.replace(",max_load_unit", "")), "max_load_unit");
        err(format!("{HEADER}\n{}\n", ROW.replace("N*mm/deg", "N/mm")), "rate_unit");
        err(format!("{HEADER}\n{}\n", ROW.replace(",12.5,", ",fast,")), "rate");
        err(format!("{HEADER}\n{}\n", ROW.replace("torsion", "spiral")), "type");
    }

    /// Issue 45: each bad row refused with one clear message naming the file, the line and the
    /// field: a wrong unit string, a negative wire, coils not above 0, a mean diameter not above
    /// the wire, a missing part number or source, a vendor tolerance that is no percentage.
    #[test]
    fn each_bad_row_names_its_line_and_field() {
        let p = Path::new("stock.csv");
        let header = format!("{HEADER},rate_tolerance_pct");
        let good = format!("{ROW},10");
        let rows = parse(p, &format!("# a comment\n{header}\n{good}\n")).unwrap();
        assert_eq!(rows[0].rate_tolerance, Some(0.1));
        assert_eq!(parse(p, &format!("{HEADER}\n{ROW}\n")).unwrap()[0].rate_tolerance, None);
        for (row, field, words) in [
            (good.replace("N*mm/deg", "lbf*in/deg"), "rate_unit", "`lbf*in/deg`: a torsion spring's is `N*mm/deg`"),
            (good.replace(",180,deg,", ",180,rad,"), "max_deflection_unit", "`rad`"),
            (good.replace("music wire,1,", "music wire,-1,"), "d_mm", "`-1` is not a positive number"),
            (good.replace(",10,5,20,", ",10,0,20,"), "n", "`0` is not a positive number"),
            (good.replace(",1,10,5,", ",1,0.8,5,"), "D_mm", "not above the wire's d_mm"),
            (good.replace(",EX-1,", ",,"), "part_number", "is empty"),
            (good.replace("invented for this test", ""), "source", "is empty"),
            (format!("{ROW},ten"), "rate_tolerance_pct", "`ten`"),
        ] {
            let e = parse(p, &format!("# a comment\n{header}\n{row}\n")).unwrap_err().to_string();
            assert!(e.contains("stock.csv") && e.contains(&format!("line 3: {field}")) && e.contains(words), "{e}");
        }
    }
}
