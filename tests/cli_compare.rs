//! `springfit compare` and `springfit pareto` through the binary.

mod util;

use util::{springfit, temp_dir, write};

#[test]
fn compare_refuses_a_folder_that_is_not_a_fit_output() {
    let dir = temp_dir("compare-refuse");
    write(&dir, "notafit/readme.txt", "hello");
    springfit(&dir, &["compare", "notafit", "--out", "cmp"])
        .fails(2, &["notafit", "not an output folder of `springfit fit`", "summary.json"]);
    springfit(&dir, &["compare", "nowhere", "--out", "cmp"]).fails(2, &["nowhere", "no such folder"]);
    assert!(!dir.join("cmp").exists());
}

#[test]
fn compare_takes_solvers_catalogues_and_designs_together() {
    let dir = temp_dir("compare-mixed");
    // Without the Monte Carlo builds: the table's as-built columns are not what is tested here.
    let design = util::with_builds(&dir, "double_pendulum", 0);
    let d = design.to_str().unwrap();
    springfit(&dir, &["fit", d, "--solver", "nnls", "--out", "nnls"]).ok();
    springfit(&dir, &["fit", d, "--solver", "qp", "--out", "qp"]).ok();
    let workshop = util::with_builds(&dir, "double_pendulum_workshop", 0);
    let run = springfit(&dir, &["compare", "nnls", "qp", workshop.to_str().unwrap(), "--exact", "--out", "cmp"]).ok();
    for f in ["compare.csv", "compare.md", "compare.svg", "compare.png"] {
        assert!(dir.join("cmp").join(f).is_file(), "missing {f}\n{}", run.report());
    }
    let csv = std::fs::read_to_string(dir.join("cmp/compare.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert_eq!(rows.len(), 4, "{csv}");
    assert!(
        rows[0].contains("nnls")
            && rows[1].contains(",qp,")
            && rows[2].contains("workshop")
            && rows[3].contains("exact"),
        "{csv}"
    );
    // The two fits of one design get distinct labels.
    let fields: Vec<Vec<String>> = rows.iter().map(|r| springfit::files::split_csv_line(r).unwrap()).collect();
    assert_ne!(fields[0][0], fields[1][0]);
    assert_eq!(fields[0][3], "nnls");
    assert_eq!(fields[1][3], "qp");
    let exact_p99: f64 = fields[3][8].parse().unwrap();
    assert!(exact_p99 < 1e-3);
    // Issue 44 item 4: the springs' mass beside the residuals, from a fit folder's summary.json
    // and from a design fitted on the fly; none for the exact reference.
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let (mass, ratio) = (
        header.iter().position(|h| *h == "spring_mass_kg").unwrap(),
        header.iter().position(|h| *h == "mass_over_floor").unwrap(),
    );
    for r in &fields[..3] {
        let (m, f): (f64, f64) = (r[mass].parse().unwrap(), r[ratio].parse().unwrap());
        assert!(m > 0.0 && f > 1.0, "{r:?}");
    }
    assert_eq!((fields[3][mass].as_str(), fields[3][ratio].as_str()), ("", ""));
    let qp_summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("qp/summary.json")).unwrap()).unwrap();
    assert_eq!(fields[1][mass].parse::<f64>().ok(), qp_summary["mass"]["spring_mass_kg"].as_f64());
    let md = std::fs::read_to_string(dir.join("cmp/compare.md")).unwrap();
    assert!(md.contains("spring mass (× floor)") && md.contains(" kg ("), "{md}");
    assert!(run.stdout().contains("× the floor)"), "{}", run.report());
}

#[test]
fn pareto_tables_budgets_and_radii() {
    let dir = temp_dir("pareto");
    let design = util::with_builds(&dir, "double_pendulum_workshop", 20);
    springfit(&dir, &["pareto", design.to_str().unwrap(), "--k-max", "5", "--radii", "1.0,2.0", "--out", "p"]).ok();
    let csv = std::fs::read_to_string(dir.join("p/pareto.csv")).unwrap();
    let budget_rows: Vec<&str> = csv.lines().filter(|l| l.starts_with("budget,")).collect();
    assert_eq!(budget_rows.len(), 4);
    let p99: Vec<f64> = budget_rows.iter().map(|r| r.split(',').nth(6).unwrap().parse().unwrap()).collect();
    assert!(p99.windows(2).all(|w| w[1] <= w[0]), "a larger budget may not be worse: {p99:?}");
    assert_eq!(csv.lines().filter(|l| l.starts_with("radius,")).count(), 2);
    assert!(dir.join("p/pareto.png").is_file());
}

#[test]
fn compare_shows_an_actuator_share_only_from_a_simulation_of_the_same_springs() {
    let dir = temp_dir("compare-share");
    let design = util::with_builds(&dir, "double_pendulum", 0);
    let d = design.to_str().unwrap();
    springfit(&dir, &["fit", d, "--out", "dp"]).ok();
    // simulate fits the design itself: the same springs, so the same fingerprint.
    springfit(&dir, &["simulate", d, "--scenario", "sensitivity", "--out", "dp_simulate"]).ok();
    let read = |p: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.join(p)).unwrap()).unwrap()
    };
    let fit_print = read("dp/summary.json")["spring_set"].as_str().unwrap().to_string();
    assert_eq!(read("dp_simulate/sim_sensitivity.json")["spring_set"].as_str(), Some(fit_print.as_str()));
    let run = springfit(&dir, &["compare", "dp", "--out", "c1"]).ok();
    assert!(run.stdout().contains("actuator share"), "{}", run.report());
    let csv = std::fs::read_to_string(dir.join("c1/compare.csv")).unwrap();
    let column = csv.lines().next().unwrap().split(',').position(|h| h == "actuator_share").unwrap();
    let share: f64 = csv.lines().nth(1).unwrap().split(',').nth(column).unwrap().parse().unwrap();
    assert!(share > 0.0 && share < 0.05, "{csv}");
    // The exact potential simulated into the same folder: no share, and the note says why.
    springfit(&dir, &["simulate", d, "--scenario", "sensitivity", "--exact", "--out", "dp_simulate"]).ok();
    assert!(read("dp_simulate/sim_sensitivity.json")["spring_set"].is_null());
    let run = springfit(&dir, &["compare", "dp", "--out", "c2"]).ok();
    assert!(!run.stdout().contains("actuator share"), "{}", run.report());
    let md = std::fs::read_to_string(dir.join("c2/compare.md")).unwrap();
    assert!(md.contains("no actuator share") && md.contains("another spring set"), "{md}");
    let csv = std::fs::read_to_string(dir.join("c2/compare.csv")).unwrap();
    let column = csv.lines().next().unwrap().split(',').position(|h| h == "actuator_share").unwrap();
    assert_eq!(csv.lines().nth(1).unwrap().split(',').nth(column), Some(""), "{csv}");
}
