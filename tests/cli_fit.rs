//! `springfit fit` end to end through the binary: the default design, the exact reference, the
//! bill of materials read back, bad catalogues, atomic outputs.

mod util;

use std::path::Path;

use util::{design_text, design_text_anywhere, repo, springfit, temp_dir, write};

fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}

#[test]
fn the_default_design_meets_its_accuracy_targets() {
    let dir = temp_dir("fit-default");
    let run =
        springfit(&dir, &["fit", repo().join("designs/double_pendulum.toml").to_str().unwrap(), "--out", "result"])
            .ok();
    let out = dir.join("result");
    for f in [
        "bom.csv",
        "bom.md",
        "summary.json",
        "residuals.csv",
        "histogram.svg",
        "histogram.png",
        "potential.svg",
        "potential.png",
        "report.md",
    ] {
        assert!(out.join(f).is_file(), "missing {f}\n{}", run.report());
    }
    let s = summary(&out);
    for key in [
        "design",
        "dof",
        "catalog",
        "solver",
        "candidates",
        "dropped",
        "used",
        "frequency_rad_s",
        "residual_deg",
        "equilibrium_gradient_norm",
        "hessian_rel_error",
        "monotone_violations",
        "timings_s",
    ] {
        assert!(s.get(key).is_some(), "summary.json lacks {key}");
    }
    let r = &s["residual_deg"];
    // The shipped design is fitted for ±5 % builds (`tolerance = 0.05`, λ = 0.2) around three
    // trim springs at mid-range (0.39° p99 now): the acceptance figures of the tolerance and trim
    // issues bound the drawing, the builds as built and the builds after the trim.
    assert!(r["p99_abs"].as_f64().unwrap() <= 0.5, "{r}");
    assert!(r["max_abs"].as_f64().unwrap() <= 1.5, "{r}");
    // At most 12 fitted springs; the three trims are set after the build and not counted.
    let bom = std::fs::read_to_string(out.join("bom.csv")).unwrap();
    let header: Vec<&str> = bom.lines().next().unwrap().split(',').collect();
    let trim_col = header.iter().position(|h| *h == "trim_max").unwrap();
    let trims = bom.lines().skip(1).filter(|l| !l.split(',').nth(trim_col).unwrap().is_empty()).count();
    assert_eq!(trims, 3, "{bom}");
    assert!(s["used"].as_u64().unwrap() <= 12 + 3);
    let ab = &s["as_built"];
    assert!(ab["p99_deg"]["p95"].as_f64().unwrap() <= 2.5, "{ab}");
    assert!(ab["trimmed"]["p99_deg"]["p95"].as_f64().unwrap() <= 1.5, "{ab}");
    assert!(s["equilibrium_gradient_norm"].as_f64().unwrap() < 1e-9);
    assert_eq!(s["dof"], 2);
    assert!(run.stdout().contains("p99"), "{}", run.report());
    // The bill of materials lists as many rows as springs used.
    assert_eq!(bom.lines().count() as u64, 1 + s["used"].as_u64().unwrap());
    // Every element has a part (issue 22): its rate recomputed from the spring's geometry is the
    // fitted one within its EN 15800 grade, its stresses are within the limits and it survives
    // [parts] cycles (10⁶) at the scenarios' swing; the realised design stays within 0.1° of
    // the ideal one at p99.
    let parts = std::fs::read_to_string(out.join("parts.csv")).unwrap();
    let header: Vec<&str> = parts.lines().next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap_or_else(|| panic!("parts.csv lacks {n}"));
    let rows: Vec<Vec<String>> = parts.lines().skip(1).map(|l| springfit::files::split_csv_line(l).unwrap()).collect();
    assert_eq!(rows.len() as u64, s["used"].as_u64().unwrap(), "{parts}");
    let num = |r: &[String], n: &str| -> f64 { r[col(n)].parse().unwrap_or_else(|_| panic!("{n}: {:?}", r[col(n)])) };
    for r in &rows {
        assert!(r[col("limit")].is_empty(), "{}", r[col("limit")]);
        let (fitted, realised) = (num(r, "fitted_stiffness"), num(r, "realised_rate"));
        assert!((realised / fitted - 1.0).abs() <= num(r, "rate_tolerance"), "{}: {realised} vs {fitted}", r[0]);
        assert!(num(r, "static_utilisation") <= 1.0 && num(r, "fatigue_utilisation") <= 1.0, "{}", r[0]);
        assert!(num(r, "life_cycles") >= 1e6, "{}", r[0]);
        // Issue 45: every rate (a torsion spring's legs included) within 1.5 % of the element's,
        // and no static-grade wire at 10⁶ swings.
        assert!((realised / fitted - 1.0).abs() <= 0.015, "{}: {realised} vs {fitted}", r[0]);
        assert_ne!(r[col("material")], "EN10270-1-SM", "{}", r[0]);
    }
    // The shipped stock list is read by default: at least one crank is a military-standard part.
    assert!(rows.iter().any(|r| r[col("part_number")].starts_with("MS24586")), "{parts}");
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    let realised = &s["realised"];
    assert_eq!(realised["parts"].as_u64(), s["used"].as_u64(), "{realised}");
    assert!(realised["p99_change_deg"].as_f64().unwrap().abs() <= 0.1, "{realised}");
    assert!(run.stdout().contains("realised design: p99"), "{}", run.report());
    // Issue 44 item 4: the springs' mass against the arm and the floor, the stored energy over U*
    // and the total |preload| at q_eq, the same in summary.json, report.md and on stdout.
    let m = &s["mass"];
    let f = |k: &str| m[k].as_f64().unwrap_or_else(|| panic!("mass.{k} missing: {m}"));
    assert_eq!(m["spring_mass_kg"], realised["spring_mass_kg"], "{m}");
    assert!((f("arm_mass_kg") - 2.0).abs() < 1e-12, "{m}");
    assert!((f("mass_over_arm") - f("spring_mass_kg") / f("arm_mass_kg")).abs() < 1e-12, "{m}");
    assert!((f("mass_over_floor") - f("spring_mass_kg") / f("floor_kg")).abs() < 1e-9, "{m}");
    assert!((f("stored_energy_over_potential") - f("stored_energy_j") / f("potential_energy_j")).abs() < 1e-12, "{m}");
    assert!((f("floor_kg") - 7850.0 * f("potential_energy_j") / f("energy_density_j_m3")).abs() < 1e-3 * f("floor_kg"));
    // Every element stores at least what the potential spends along one geodesic, and the
    // preloads cancel joint by joint at q_eq (|∇U(q_eq)| ≈ 0) while their sum does not.
    assert!(f("stored_energy_over_potential") >= 1.0 && f("preload_total_nm") > 0.0, "{m}");
    assert!(report.contains("## Mass") && report.contains("| springs / floor |"), "{report}");
    assert!(run.stdout().contains("× the arm's moving 2.000 kg"), "{}", run.report());
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(html.contains("springs / floor"), "report.html lacks the mass table");
    // Its verdict against the design's threshold, and its sampling: two joints keep the counts of
    // before they grew with n (72 / 360 / 720 directions).
    assert!(run.stdout().contains("verdict: acceptable"), "{}", run.report());
    assert_eq!(s["verdict"], "acceptable");
    assert_eq!(s["accept_p99_deg"].as_f64(), Some(2.0));
    let sampling = &s["sampling"];
    let counts = ["training_directions", "evaluation_directions", "check_directions"].map(|k| sampling[k].as_u64());
    assert_eq!(counts, [Some(72), Some(360), Some(720)], "{sampling}");
    // stdout and report.md count candidates the same way.
    let line = run.stdout().lines().next().unwrap().to_string();
    let total = line.split(" candidates").next().unwrap().rsplit(' ').next().unwrap().to_string();
    assert!(report.contains(&format!("{total} candidates")), "{line}\n{report}");
}

#[test]
fn the_exact_reference_has_zero_residual() {
    let dir = temp_dir("fit-exact");
    let design = write(
        &dir,
        "small.toml",
        &design_text_anywhere("double_pendulum.toml")
            .replace("[fit]", "[fit]\nevaluation_directions = 24\nevaluation_samples = 10"),
    );
    springfit(&dir, &["fit", design.to_str().unwrap(), "--exact", "--out", "exact"]).ok();
    let s = summary(&dir.join("exact"));
    assert_eq!(s["solver"], "exact");
    assert!(s["residual_deg"]["max_abs"].as_f64().unwrap() < 1e-3, "{}", s["residual_deg"]);
    assert!(!dir.join("exact/bom.csv").exists());
    assert!(s["mass"].is_null(), "the exact reference has no springs to weigh: {}", s["mass"]);
}

#[test]
fn bad_catalogues_get_clear_errors() {
    let dir = temp_dir("fit-bad-catalog");
    let good_catalog = std::fs::read_to_string(repo().join("catalogs/workshop.toml")).unwrap();
    let cases: Vec<(&str, String, Vec<&str>)> = vec![
        (
            "unknown_profile",
            good_catalog.replacen("profile = \"linear\"", "profile = \"spiral\"", 1),
            vec!["family[0].profile", "unknown profile"],
        ),
        (
            "negative_bound",
            good_catalog.replacen("max_stiffness = 220.0", "max_stiffness = -5.0", 1),
            vec!["family[0].max_stiffness", "positive"],
        ),
        (
            "wrong_length",
            good_catalog.replacen("couplings = [[1, 0], [0, 1]]", "couplings = [[1, 0, 0], [0, 1]]", 1),
            vec!["family[2].couplings[0]", "3 entries"],
        ),
        ("empty", "name = \"empty\"\n".to_string(), vec!["family", "no candidate"]),
    ];
    for (name, text, needles) in cases {
        assert_ne!(text, good_catalog, "case {name} did not change the catalogue");
        write(&dir, &format!("catalogs/{name}.toml"), &text);
        let design = design_text("double_pendulum_workshop.toml")
            .replace("../catalogs/workshop.toml", &format!("../catalogs/{name}.toml"));
        let path = write(&dir, &format!("designs/{name}.toml"), &design);
        springfit(&dir, &["fit", path.to_str().unwrap(), "--out", "out"]).fails(2, &needles);
        assert!(!dir.join("out").exists(), "no output may be written on error");
    }
}

#[test]
fn an_infeasible_fit_exits_with_1_names_the_constraint_and_keeps_previous_results() {
    let dir = temp_dir("fit-infeasible");
    // Springs on single joints only: their Hessian at q_eq is diagonal, but ω² M(q_eq) is not.
    let catalog = "name = \"joint springs only\"\n[[family]]\nname = \"torsion\"\nprofile = \"linear\"\ncouplings = \"joints\"\noffsets = \"equilibrium\"\n";
    write(&dir, "catalogs/joints.toml", catalog);
    // No trims in that catalogue, so no trimmed builds to weigh.
    let design = design_text("double_pendulum.toml")
        .replace("../catalogs/paper_trim.toml", "../catalogs/joints.toml")
        .replace("trimmed_weight = 0.22", "trimmed_weight = 0.0");
    let path = write(&dir, "designs/infeasible.toml", &design);
    write(&dir, "out/bom.csv", "previous results");
    write(&dir, "out/.springfit-manifest.json", r#"{"springfit": "0.1.0", "command": "fit", "files": ["bom.csv"]}"#);
    for solver in ["qp", "nnls"] {
        springfit(&dir, &["fit", path.to_str().unwrap(), "--out", "out", "--solver", solver])
            .fails(1, &["infeasible", "Hessian match"]);
        assert_eq!(std::fs::read_to_string(dir.join("out/bom.csv")).unwrap(), "previous results");
        let leftovers: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().starts_with('.'))
            .collect();
        assert!(leftovers.is_empty(), "staging folders left behind: {leftovers:?}");
    }
}

/// Five springs (around the three trims) cannot follow the geodesics (p99 ≈ 5°): poor, with what
/// to try. (Four springs around the trims: the selected support cannot meet the Hessian match
/// exactly, and the QP reports the fit infeasible.) The acceptable verdict is the default
/// design's, above.
#[test]
fn a_poor_fit_gets_a_plain_verdict_against_the_design_threshold() {
    let dir = temp_dir("fit-verdict");
    let design = util::with_builds(&dir, "double_pendulum", 0);
    let few = springfit(&dir, &["fit", design.to_str().unwrap(), "--max-elements", "5", "--out", "few"]).ok();
    assert!(few.stdout().contains("verdict: poor") && few.stdout().contains("fit.max_elements"), "{}", few.report());
    let s = summary(&dir.join("few"));
    assert_eq!(s["verdict"], "poor");
    assert!(s["residual_deg"]["p99_abs"].as_f64().unwrap() > 2.0);
    assert!(std::fs::read_to_string(dir.join("few/report.md")).unwrap().contains("**Verdict: poor**"));
}

/// Issue 46: a URDF arm springfit ships no hand-tuned design for (the Franka Panda's three pitch
/// joints, 78 cranks whose preloads cancel on a small net torque), fitted with the defaults, is
/// realised within 1.5°: the lightest crank geometries realised it at 3.13° (their rollers'
/// small departures from k sin d add up), so the parts are chosen again with the rollers bounded
/// (`parts::ROLLER_SLACK_DEG`), while the default design, realised within 0.1° of its ideal
/// elements, keeps its light cranks.
#[test]
fn a_urdf_arm_is_realised_within_a_degree_and_a_half() {
    let dir = temp_dir("fit-panda-realised");
    let run =
        springfit(&dir, &["fit", repo().join("designs/panda_three.toml").to_str().unwrap(), "--out", "result"]).ok();
    let s = summary(&dir.join("result"));
    let ideal = s["residual_deg"]["p99_abs"].as_f64().unwrap();
    let realised = s["realised"]["residual_deg"]["p99_abs"].as_f64().unwrap();
    assert!(ideal <= 1.0 && realised <= 1.5, "ideal {ideal}°, realised {realised}°\n{}", run.report());
    let mass = s["mass"]["spring_mass_kg"].as_f64().unwrap();
    let arm = s["mass"]["arm_mass_kg"].as_f64().unwrap();
    assert!(mass <= arm, "springs {mass} kg on an arm of {arm} kg");
}
