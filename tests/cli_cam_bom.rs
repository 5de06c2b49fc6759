//! A fit with cams as files: `bom.csv` lists each cam as one row naming its `cams/<id>.toml`,
//! and the folder alone rebuilds the potential the fit evaluated (the same spring set bit for
//! bit: `simulate --bom` reports the fit's fingerprint); broken cam files are one error naming
//! the file and the key (exit 2); a measured follower rate scales its whole cam in `tune`.

mod util;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use util::{repo, springfit, temp_dir, write};

/// The `spring_set` fingerprint a JSON output carries.
fn fingerprint(json: &Path) -> String {
    let text = std::fs::read_to_string(json).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["spring_set"].as_str().unwrap_or_else(|| panic!("no spring_set in {}", json.display())).to_string()
}

/// The `coefficients_j` of a cam file.
fn coefficients(path: &Path) -> Vec<f64> {
    let v: toml::Value = toml::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    v["coefficients_j"].as_array().unwrap().iter().map(|c| c.as_float().unwrap()).collect()
}

/// Copies the bill of materials and cam files of the fit folder `from` into `to`.
fn copy_bom(from: &Path, to: &Path) {
    std::fs::create_dir_all(to.join("cams")).unwrap();
    std::fs::copy(from.join("bom.csv"), to.join("bom.csv")).unwrap();
    for e in std::fs::read_dir(from.join("cams")).unwrap().flatten() {
        if e.path().extension().is_some_and(|x| x == "toml") {
            std::fs::copy(e.path(), to.join("cams").join(e.file_name())).unwrap();
        }
    }
}

/// The output folder of `springfit fit designs/double_pendulum_cams4.toml`, fitted once for the
/// tests of this file (which read it and copy what they change).
fn fitted() -> &'static Path {
    static FIT: OnceLock<PathBuf> = OnceLock::new();
    FIT.get_or_init(|| {
        let dir = temp_dir("cam-fit");
        let design = repo().join("designs/double_pendulum_cams4.toml");
        springfit(&dir, &["fit", design.to_str().unwrap(), "--out", "fit", "--threads", "2"]).ok();
        dir.join("fit")
    })
}

#[test]
fn a_fit_with_cams_is_rebuilt_from_its_folder() {
    let dir = temp_dir("cam-bom");
    let design = repo().join("designs/double_pendulum_cams4.toml");
    let d = design.to_str().unwrap();
    let fit = fitted();
    // One row per cam, each naming its file, which exists.
    let bom = std::fs::read_to_string(fit.join("bom.csv")).unwrap();
    let rows: Vec<&str> = bom.lines().skip(1).collect();
    assert_eq!(rows.len(), 4, "{bom}");
    for (i, row) in rows.iter().enumerate() {
        let id = format!("C{:02}", i + 1);
        assert!(row.starts_with(&format!("{id},")) && row.contains(",cam,,"), "{row}");
        assert!(row.ends_with(&format!(",cams/{id}.toml")), "{row}");
        assert!(row.contains(",N/mm,"), "{row}");
        assert!(fit.join(format!("cams/{id}.toml")).is_file());
    }
    // Only the files of the bill of materials, elsewhere: the simulation uses the fit's set.
    copy_bom(fit, &dir.join("parts"));
    springfit(&dir, &["simulate", d, "--scenario", "sensitivity", "--bom", "parts/bom.csv", "--out", "sim"]).ok();
    assert_eq!(fingerprint(&dir.join("sim/sim_sensitivity.json")), fingerprint(&fit.join("summary.json")));

    // Broken cam files: one error naming the file and the key, exit 2, no output folder.
    let broken = |name: &str, edit: &dyn Fn(&str) -> String, needles: &[&str]| {
        let bad = dir.join(name);
        copy_bom(fit, &bad);
        let cam = bad.join("cams/C02.toml");
        let text = std::fs::read_to_string(&cam).unwrap();
        let edited = edit(&text);
        assert_ne!(edited, text, "{name}: the edit changed nothing");
        if edited.is_empty() {
            std::fs::remove_file(&cam).unwrap();
        } else {
            write(&bad, "cams/C02.toml", &edited);
        }
        let bom = format!("{name}/bom.csv");
        let out = format!("{name}_sim");
        springfit(&dir, &["simulate", d, "--scenario", "sensitivity", "--bom", &bom, "--out", &out]).fails(2, needles);
        assert!(!dir.join(&out).exists());
    };
    broken(
        "short",
        &|t| {
            // The first coefficient left out.
            let i = t.find("coefficients_j = [").unwrap() + "coefficients_j = [".len();
            let j = i + t[i..].find(", ").unwrap() + 2;
            format!("{}{}", &t[..i], &t[j..])
        },
        &["C02.toml", "coefficients_j", "has 31 values, expected knots + 2 = 32"],
    );
    broken(
        "coupling",
        &|t| t.replacen("coupling = [2.0, -1.0]", "coupling = [2.0, 1.0]", 1),
        &["C02.toml", "coupling", "row C02 (line 3)"],
    );
    broken("missing", &|_| String::new(), &["bom.csv", "line 3: file", "C02.toml does not exist"]);
    broken("nan", &|t| t.replacen("knots = 30", "knots = nan", 1), &["C02.toml"]);
}

/// A follower spring measured 5 % stiff: tune scales that cam's coefficients by 1.05 (the other
/// cams as designed), and the arm leaves q_eq; measured as designed, it stays there.
#[test]
fn a_measured_follower_rate_scales_its_cam() {
    let dir = temp_dir("cam-tune");
    let design = repo().join("designs/double_pendulum_cams4.toml");
    let d = design.to_str().unwrap();
    let fit = fitted();
    let bom = std::fs::read_to_string(fit.join("bom.csv")).unwrap();
    let measured = |factor: f64| {
        let mut lines = bom.lines();
        let mut s = format!("{},measured_stiffness\n", lines.next().unwrap());
        for l in lines {
            let f: Vec<&str> = l.split(',').collect();
            let m = if f[0] == "C01" { format!("{}", f[6].parse::<f64>().unwrap() * factor) } else { String::new() };
            s.push_str(&format!("{l},{m}\n"));
        }
        s
    };
    copy_bom(fit, &dir.join("m"));
    write(&dir, "m/high.csv", &measured(1.05));
    write(&dir, "m/same.csv", &measured(1.0));
    let high = springfit(&dir, &["tune", d, "--measured", "m/high.csv", "--out", "high"]).ok();
    let same = springfit(&dir, &["tune", d, "--measured", "m/same.csv", "--out", "same"]).ok();
    let shift = |run: &util::Run| -> f64 {
        let out = run.stdout();
        let line = out.lines().find(|l| l.starts_with("before tuning")).unwrap_or_else(|| panic!("{}", run.report()));
        line.split("shift ").nth(1).and_then(|s| s.split(' ').next()).and_then(|s| s.parse().ok()).unwrap()
    };
    assert!(shift(&high) > 1e-4, "{}", high.report());
    assert!(shift(&same) < 1e-5, "{}", same.report());
    let designed = coefficients(&fit.join("cams/C01.toml"));
    let tuned = coefficients(&dir.join("high/cams/C01_bom_tuned.toml"));
    assert_eq!(designed.len(), tuned.len());
    for (c, t) in designed.iter().zip(&tuned) {
        assert!((t - 1.05 * c).abs() <= 1e-12 * c.abs(), "{t} vs 1.05 × {c}");
    }
    assert!(designed.iter().any(|c| *c != 0.0));
    assert_eq!(coefficients(&fit.join("cams/C02.toml")), coefficients(&dir.join("high/cams/C02_bom_tuned.toml")));
    // The tuned bill of materials is itself a folder springfit reads.
    let tuned_bom = std::fs::read_to_string(dir.join("high/bom_tuned.csv")).unwrap();
    assert!(tuned_bom.lines().nth(1).unwrap().ends_with(",cams/C01_bom_tuned.toml"), "{tuned_bom}");
    springfit(&dir, &["simulate", d, "--scenario", "sensitivity", "--bom", "high/bom_tuned.csv", "--out", "sim"]).ok();
}
