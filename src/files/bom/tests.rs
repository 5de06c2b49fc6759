//! Tests of `bom`.

use super::*;
use crate::elements::Side;
use crate::fit::bill::{fingerprint, spring_set};
use crate::realise::cam::CamBuild;

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
            cam: None,
            pulleys_mm: None,
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
            cam: None,
            pulleys_mm: None,
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
            cam: None,
            pulleys_mm: None,
        },
    ]
}

#[test]
fn round_trips_bit_for_bit() {
    let text = to_csv(&rows());
    let back = parse(Path::new("bom.csv"), &text).unwrap();
    assert_eq!(back, rows());
    let md = to_markdown("t", &rows());
    assert!(md.contains("N·m/rad: 14.5000 over 2 elements"));
    assert!(md.contains("Σ|τ(q_eq)| = 2.625 N·m"), "{md}");
}

/// Files written before the preload column are still read (preload unknown), and a
/// preload that is not a number is reported.
#[test]
fn files_without_the_preload_column_are_read() {
    let mut old = String::from(HEADER_WITHOUT_PRELOAD);
    old.push('\n');
    for line in to_csv(&rows()).lines().skip(1) {
        // Drop the six newer columns (preload, adjust range, trim range, gear ratio, file).
        old.push_str(line.rsplitn(7, ',').last().unwrap());
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
    assert!(parse(Path::new("bom.csv"), &mixed).unwrap_err().to_string().contains("expected 18"));
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
    let row = |coupling: &str| format!("{HEADER}\nS01,a,linear,,{coupling},0,1,N*m/rad,1,1,,0,,,,,,\n");
    let wide = vec!["1"; 2000].join(";");
    let err = parse(Path::new("bom.csv"), &row(&wide)).unwrap_err().to_string();
    assert!(err.contains("bom.csv") && err.contains("line 2: coupling") && err.contains("2000 entries"), "{err}");
    assert!(parse(Path::new("bom.csv"), &row(&["1"; 9].join(";"))).is_err());
    let rows = parse(Path::new("bom.csv"), &row(&["1"; 8].join(";"))).unwrap();
    assert_eq!(rows[0].element.coupling.len(), 8);
}

/// A fresh folder for one test.
fn folder(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("springfit-bom-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn write_files(dir: &Path, name: &str, rows: &[BomRow]) {
    for (path, text) in files(name, rows) {
        let p = dir.join(path);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, text).unwrap();
    }
}

/// The rows of a spring, a cam and two springs: the cam as a fit makes it, one row per
/// non-zero coefficient, the basis negated where cⱼ < 0.
fn rows_with_cam() -> Vec<BomRow> {
    let knots = Knots { lo: -0.3, width: 0.1 + 0.2, count: 5 };
    let c: [f64; 7] = [1.0 / 3.0, 0.0, -2.5, 1e-17, -0.0, 7.25, -1.0 / 7.0];
    let build =
        CamBuild { follower_rate: 12.345, preload: 4.0, gear_ratio: 0.7, base_radius: 40.0, roller_radius: 8.0 };
    let summary = CamSummary { build, max_torque_nm: 3.5, preload_nm: Some(-0.25) };
    let cam = c.iter().enumerate().filter(|(_, c)| **c != 0.0).map(|(j, &cj)| BomRow {
        id: format!("C01.{j:02}{}", if cj < 0.0 { "-" } else { "+" }),
        family: "disc, cam".into(),
        element: Element {
            profile: Profile::Spline(knots.basis(j, cj < 0.0)),
            coupling: vec![1.0, -1.0],
            offset: knots.lo,
        },
        stiffness: cj.abs(),
        max_torque_nm: 3.5,
        max_deflection_rad: knots.hi() - knots.lo,
        stock_rate: None,
        tolerance: 0.05,
        preload_nm: None,
        adjust: Adjustment::default(),
        cam: Some(summary),
        pulleys_mm: None,
    });
    let mut all = rows();
    all.splice(1..1, cam);
    all
}

#[test]
fn a_cam_is_one_row_and_a_file_and_comes_back_bit_for_bit() {
    let dir = folder("cam");
    let rows = rows_with_cam();
    write_files(&dir, "bom.csv", &rows);
    let text = std::fs::read_to_string(dir.join("bom.csv")).unwrap();
    assert_eq!(text.lines().count(), 1 + 4, "{text}");
    let cam_line = text.lines().nth(2).unwrap();
    assert!(cam_line.starts_with("C01,\"disc, cam\",cam,,1;-1,-0.3,12.345,N/mm,3.5,"), "{cam_line}");
    assert!(cam_line.ends_with(",0.05,-0.25,,,,0.7,cams/C01.toml"), "{cam_line}");
    let back = read(&dir.join("bom.csv")).unwrap();
    assert_eq!(back, rows);
    assert_eq!(fingerprint(&spring_set(&back)), fingerprint(&spring_set(&rows)));
    let md = to_markdown("t", &rows);
    assert!(md.contains("| C01 | disc, cam | cam, gear ratio 0.7000, cams/C01.toml | (1, -1) |"), "{md}");
    assert!(md.contains("**4 elements.**") && md.contains("N/mm: 12.3450 over 1 element"), "{md}");
    // Beside another bill of materials the cam's file has that one's name in it.
    assert_eq!(files("bom_tuned.csv", &rows)[1].0, "cams/C01_bom_tuned.toml");
    // An older file, one row per signed coefficient (side `±j/N/h`, stiffness in J), is read
    // into the same spring set.
    let mut old = format!("{HEADER_16}\n");
    for r in &rows {
        let e = &r.element;
        old.push_str(&format!(
            "{},{},{},{},{},{},{},{},1,1,,0.05,,,,\n",
            r.id,
            csv_field(&r.family),
            e.profile.name(),
            e.profile.side(),
            e.coupling_text(),
            e.offset,
            r.stiffness,
            e.profile.unit()
        ));
    }
    let old_rows = parse(&dir.join("old.csv"), &old).unwrap();
    assert_eq!(spring_set(&old_rows), spring_set(&rows));
    assert!(old_rows.iter().all(|r| r.cam.is_none()));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_cam_file_that_disagrees_or_is_missing_is_one_error_naming_it() {
    let dir = folder("cam-errors");
    let rows = rows_with_cam();
    let csv = files("bom.csv", &rows)[0].1.clone();
    let toml = files("bom.csv", &rows)[1].1.clone();
    let bom = dir.join("bom.csv");
    let cases: [(String, String, &[&str]); 8] = [
        (
            csv.clone(),
            toml.replace("knots = 5", "knots = 6"),
            &["C01.toml", "coefficients_j", "has 7 values, expected knots + 2 = 8"],
        ),
        (
            csv.clone(),
            toml.replace("coupling = [1.0, -1.0]", "coupling = [1.0, 1.0]"),
            &["C01.toml", "coupling", "(1;1) disagrees with coupling = (1;-1) of row C01 (line 3)"],
        ),
        (
            csv.replace(",12.345,", ",12.5,"),
            toml.clone(),
            &["C01.toml", "realisation.follower_rate_n_per_mm", "stiffness = 12.5"],
        ),
        (csv.replace(",-0.3,", ",-0.25,"), toml.clone(), &["C01.toml", "first_knot_rad"]),
        (csv.replace(",0.7,", ",0.75,"), toml.clone(), &["C01.toml", "realisation.gear_ratio"]),
        (csv.replace("7.25", "inf"), toml.replace("7.25", "inf"), &["C01.toml", "coefficients_j", "c_5 = inf"]),
        (csv.replace(",cams/C01.toml", ","), toml.clone(), &["bom.csv", "line 3: file"]),
        (csv.replace(",N/mm,", ",J,"), toml.clone(), &["bom.csv", "line 3: unit"]),
    ];
    for (c, t, needles) in cases {
        std::fs::create_dir_all(dir.join("cams")).unwrap();
        std::fs::write(&bom, &c).unwrap();
        std::fs::write(dir.join("cams/C01.toml"), &t).unwrap();
        let err = read(&bom).unwrap_err().to_string();
        for n in needles {
            assert!(err.contains(n), "expected `{n}` in `{err}`");
        }
    }
    std::fs::write(&bom, &csv).unwrap();
    std::fs::remove_file(dir.join("cams/C01.toml")).unwrap();
    let err = read(&bom).unwrap_err().to_string();
    assert!(err.contains("line 3: file") && err.contains("C01.toml does not exist"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn csv_quoting() {
    assert_eq!(split_csv_line("a,\"b,c\",\"d\"\"e\",").unwrap(), vec!["a", "b,c", "d\"e", ""]);
    assert!(split_csv_line("\"open").is_err());
}

#[test]
fn measured_column_is_found_anywhere_and_checked() {
    let h = HEADER;
    let text = format!(
        "{h},measured_stiffness\nS01,a,linear,,1;0,0,10,N*m/rad,1,1,,0,,0.2,,,,,10.4\nS02,b,linear,,0;1,1.5,5,N*m/rad,1,1,,0,,,,,,,\n"
    );
    let (rows, m) = read_measured(std::path::Path::new("m.csv"), &text).unwrap();
    assert_eq!(rows.len(), 2);
    assert_eq!(m, vec![Some(10.4), None]);
    assert_eq!(rows[0].adjust.adjust_range, Some(0.2));
    let bad = text.replace("10.4", "-1");
    let err = read_measured(std::path::Path::new("m.csv"), &bad).unwrap_err().to_string();
    assert!(err.contains("m.csv") && err.contains("line 2: measured_stiffness"), "{err}");
    let none = read_measured(std::path::Path::new("m.csv"), &to_csv(&rows)).unwrap_err().to_string();
    assert!(none.contains("no measured_stiffness column"), "{none}");
}
