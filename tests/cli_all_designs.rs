//! Every shipped design through the binary.
//!
//! Four designs that between them reach every kind of input springfit takes run every command,
//! and each command's output is checked for values that could be wrong (not only that a file
//! exists):
//! - `double_pendulum`, the default: the paper catalogue's springs and cranks around three trims,
//!   fitted for ±5 % builds, on a geodesic ball;
//! - `double_pendulum_cams`: B-spline cams beside linear springs and trims, fitted by NNLS for
//!   trimmed builds (the cam rows of `bom.csv` and their `cams/` files);
//! - `ur5_pan_lift_elbow`: three joints of a URDF arm with non-parallel axes in gravity (the
//!   spatial model, URDF joint names in the MuJoCo export);
//! - `double_pendulum_paper_window`: the paper's box window instead of a ball (geodesics stopped
//!   at its faces, the region-size curve of `pareto`), no budget: 70 springs.
//!
//! Every other design in `designs/` (read from the folder, so a new design is tested without
//! being named here) passes `check` and a reduced `fit` whose bill meets the equalities when read
//! back; the arms of five joints or more only `check`, with a coarser region check, since even a
//! reduced fit of theirs takes most of a minute. The full matrix, every command on every design
//! of up to four joints with its shipped settings and the shipped `check` of the others, is
//! `#[ignore]`d: `cargo test --release --locked -- --ignored` (which `.ci/run` runs after the
//! README's command).

mod util;

use std::path::{Path, PathBuf};

use nalgebra::DVector;
use springfit::design::Design;
use springfit::potential::Potential;
use util::{Run, repo, springfit, temp_dir};

/// The designs that run every command in the default suite.
const EVERY_COMMAND: [&str; 4] =
    ["double_pendulum", "double_pendulum_cams", "ur5_pan_lift_elbow", "double_pendulum_paper_window"];

/// From this many joints a design only runs `check`: even the [`reduced`] fit of the five-link
/// pendulum takes 53 s of CPU, of the six-joint UR5 36 s (sampling and the solve for n joints are
/// later work).
const CHECK_ONLY_FROM_JOINTS: usize = 5;

fn design_path(name: &str) -> PathBuf {
    repo().join("designs").join(format!("{name}.toml"))
}

fn json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn num(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

/// A CSV file as its header and rows of fields.
fn csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines().map(|l| springfit::files::split_csv_line(l).unwrap());
    let header = lines.next().unwrap_or_else(|| panic!("{} is empty", path.display()));
    (header, lines.collect())
}

fn column(header: &[String], name: &str) -> usize {
    header.iter().position(|h| h == name).unwrap_or_else(|| panic!("no column {name} in {header:?}"))
}

/// |∇U(q_eq)| in N·m and ‖∇²U(q_eq) − ω²M(q_eq)‖_F / ‖ω²M(q_eq)‖_F of the bill of materials at
/// `bom` (springs and gravity), computed here from the file as written, not taken from the fit.
fn equalities(design: &Design, bom: &Path) -> (f64, f64) {
    let rows = springfit::files::bom::read(bom).unwrap_or_else(|e| panic!("{e}"));
    let springs = springfit::fit::bill::spring_set(&rows);
    let q = design.q_eq.as_slice();
    let gradient = springs.gradient(q).unwrap() + design.chain.gravity_gradient(q);
    let target = design.chain.mass_matrix(&design.q_eq) * design.fit.frequency.powi(2);
    let hessian = springs.hessian(q).unwrap() + design.chain.gravity_hessian(q);
    (gradient.norm(), (hessian - &target).norm() / target.norm())
}

/// Bounds on a fit's equalities (|∇U(q_eq)| in N·m, the Hessian's relative error). The QP meets
/// them to round-off (1e-14 here): 1e-9 fails a bill whose largest stiffness is off by one part
/// in 10⁸. NNLS weights them (`equality_weight`): the shipped cam designs reach 2.2e-5 N·m and
/// 3.9e-8, at their own settings or reduced.
fn equality_bounds(summary: &serde_json::Value) -> (f64, f64) {
    if summary["solver"] == "qp" { (1e-9, 1e-9) } else { (1e-4, 1e-6) }
}

/// How far from q_eq the bill as fitted may hold the arm, rad: round-off with the QP; the
/// weighted equalities of NNLS leave up to 1e-5 N·m (the cam design: 1.5e-5 N·m, 6.9e-7 rad).
fn shift_bound(summary: &serde_json::Value) -> f64 {
    if summary["solver"] == "qp" { 1e-9 } else { 1e-5 }
}

/// The residual statistics of summary.json are ordered, finite and agree with the equalities
/// computed from the bill as written.
fn check_fit(design: &Design, fit: &Path, run: &Run) -> serde_json::Value {
    let s = json(&fit.join("summary.json"));
    let r = &s["residual_deg"];
    let stats = ["median_abs", "p95_abs", "p99_abs", "max_abs"].map(|k| num(&r[k]));
    assert!(stats.windows(2).all(|w| w[0] <= w[1]) && stats[3].is_finite(), "{r}\n{}", run.report());
    assert!(r["count"].as_u64().unwrap() > 0, "{r}");
    let (gradient, hessian) = equalities(design, &fit.join("bom.csv"));
    let (g_bound, h_bound) = equality_bounds(&s);
    assert!(gradient <= g_bound && hessian <= h_bound, "|∇U| {gradient:e}, Hessian {hessian:e}\n{}", run.report());
    // The fit's own figures are those of the bill it wrote.
    let reported = (num(&s["equilibrium_gradient_norm"]), num(&s["hessian_rel_error"]));
    assert!((reported.0 - gradient).abs() <= 1e-9 + 1e-6 * gradient, "{reported:?} vs {gradient:e}");
    assert!((reported.1 - hessian).abs() <= 1e-12 + 1e-6 * hessian, "{reported:?} vs {hessian:e}");
    // The bill lists what the fit used, within its budget (trims are set after the build and not
    // counted), and reads back to the spring set the fit evaluated.
    let (header, rows) = csv(&fit.join("bom.csv"));
    let trim = column(&header, "trim_max");
    let trims = rows.iter().filter(|r| !r[trim].is_empty()).count();
    assert_eq!(rows.len() as u64, s["used"].as_u64().unwrap(), "{s}");
    let budget = design.fit.max_elements;
    assert!(budget == 0 || rows.len() - trims <= budget, "{} elements for a budget of {budget}", rows.len() - trims);
    let read = springfit::files::bom::read(&fit.join("bom.csv")).unwrap();
    assert_eq!(
        s["spring_set"].as_str(),
        Some(springfit::fit::bill::fingerprint(&springfit::fit::bill::spring_set(&read)).as_str())
    );
    s
}

/// Every sample of geodesics.csv moves at unit metric speed (q̇ᵀ M(q) q̇ = 1: the fan is traced
/// by arc length), and region.json says the design's region is valid.
fn check_geodesics(design: &Design, folder: &Path) {
    let (header, rows) = csv(&folder.join("geodesics.csv"));
    let n = design.dof();
    let (q0, qd0) = (column(&header, "q1"), column(&header, "qd1"));
    assert!(rows.len() > 100, "{} samples", rows.len());
    for row in rows.iter().step_by(7) {
        let f = |i: usize| -> f64 { row[i].parse().unwrap() };
        let q = DVector::from_iterator(n, (0..n).map(|i| f(q0 + i)));
        let qd = DVector::from_iterator(n, (0..n).map(|i| f(qd0 + i)));
        let speed = (qd.transpose() * design.chain.mass_matrix(&q) * &qd)[(0, 0)];
        assert!((speed - 1.0).abs() < 1e-6, "metric speed² {speed} at {row:?}");
    }
    let region = json(&folder.join("region.json"));
    assert_eq!(region["valid"], true, "{region}");
}

/// The figures the docs quote for a design's fit (`docs/guide.md`, README.md; summary.json as JSON
/// pointers) and the bound each must stay within. A selection of at most K springs is a search
/// whose path a rounding change can divert: perturbing ω or q_eq by 1e-15 moved the default
/// design's held-out p99 by up to 53 % with the single exchange search and 34 % with restarts,
/// so a selected fit's bound is about 1.5× its quoted figure (the default design's p99 0.369° is
/// bounded at 0.5°); a fit without a budget is a convex QP whose figures move by round-off, bounded
/// at the same margin. The default design's figures are checked in tests/cli_fit.rs.
fn quoted(name: &str) -> &'static [(&'static str, f64)] {
    match name {
        // p99 0.0158° as drawn; trimmed at ±5 % p95 over builds of the p99 0.579°.
        "double_pendulum_cams" => &[("/residual_deg/p99_abs", 0.02), ("/as_built/trimmed/p99_deg/p95", 1.0)],
        // 0.137° with its 4 restarts.
        "ur5_pan_lift_elbow" => &[("/residual_deg/p99_abs", 0.2)],
        // 9.34° / 22.5°: the hard case.
        "double_pendulum_paper_window" => &[("/residual_deg/p99_abs", 12.0), ("/residual_deg/max_abs", 30.0)],
        "double_pendulum_dense" => &[("/residual_deg/p99_abs", 0.01)],
        "double_pendulum_dense_robust" => &[("/residual_deg/p99_abs", 0.35)],
        "double_pendulum_workshop" => &[("/residual_deg/p99_abs", 1.1)],
        "triple_pendulum" => &[("/residual_deg/p99_abs", 2.5)],
        "double_pendulum_cams4" => &[("/residual_deg/p99_abs", 0.15)],
        // The window built untrimmed (issue 24), at 13.3 kg since issue 44: as drawn p99 0.566°,
        // max 1.82°; at ±5 % the p95 over builds of the p99 1.82° untrimmed, 1.45° with the
        // followers' preloads re-set. The bounds are issue 24's acceptance.
        "double_pendulum_paper_window_built" => &[
            ("/residual_deg/p99_abs", 0.6),
            ("/residual_deg/max_abs", 2.0),
            ("/as_built/p99_deg/p95", 3.0),
            ("/as_built/preload_trimmed/p99_deg/p95", 1.5),
            // Issue 44: 13.3 kg by the parts chosen (45.2 kg before), bounded 5 % above; every
            // cam within its pressure angle is the `warning: cam` check above.
            ("/mass/spring_mass_kg", 14.0),
        ],
        _ => &[],
    }
}

/// Every command on one design, each output checked.
fn every_command(name: &str) {
    let dir = temp_dir(&format!("all-{name}"));
    let path = design_path(name);
    let d = path.to_str().unwrap();
    let design = Design::load(&path).unwrap();
    check(&dir, &path, &catalog_name(&design));

    springfit(&dir, &["geodesics", d, "--out", "geo"]).ok();
    check_geodesics(&design, &dir.join("geo"));

    let fit = springfit(&dir, &["fit", d, "--out", "fit"]).ok();
    assert!(fit.stdout().contains("held-out samples"), "{}", fit.report());
    assert!(!fit.stderr().contains("warning: cam"), "a cam beyond its limits\n{}", fit.report());
    let summary = check_fit(&design, &dir.join("fit"), &fit);
    let p99 = num(&summary["residual_deg"]["p99_abs"]);
    for (pointer, bound) in quoted(name) {
        let figure = summary.pointer(pointer).map(num).unwrap_or_else(|| panic!("no {pointer} in {summary}"));
        assert!(figure <= *bound, "{pointer}: {figure} above {bound}\n{}", fit.report());
    }

    if design.scenarios.is_empty() {
        // A design `springfit init` wrote declares no scenario: `simulate` says so (and `sweep`,
        // which runs one).
        springfit(&dir, &["simulate", d, "--bom", "fit/bom.csv", "--out", "sim"])
            .fails(2, &["field `scenario`", "declares no [[scenario]]"]);
    } else {
        scenarios_with_the_fitted_springs(&dir, d, &summary);
    }

    // tune on the bill as designed (a blank measured_stiffness column: every rate as designed):
    // the arm rests at q_eq as the fit left it and as tuned, and tuning moves no rate but the
    // trims', each within its range.
    let bom = std::fs::read_to_string(dir.join("fit/bom.csv")).unwrap();
    let measured: String = bom
        .lines()
        .enumerate()
        .map(|(i, l)| if i == 0 { format!("{l},measured_stiffness\n") } else { format!("{l},\n") })
        .collect();
    // Beside bom.csv, where a cam row finds its `cams/` file.
    std::fs::write(dir.join("fit/measured.csv"), measured).unwrap();
    let tune = springfit(&dir, &["tune", d, "--measured", "fit/measured.csv", "--out", "tune"]).ok();
    let tj = json(&dir.join("tune/tune.json"));
    let shift = (num(&tj["before"]["shift_rad"]), num(&tj["after"]["shift_rad"]));
    assert!(shift.0 <= shift_bound(&summary) && shift.1 <= shift_bound(&summary), "{tj}\n{}", tune.report());
    let ((header, fitted), (_, tuned)) = (csv(&dir.join("fit/bom.csv")), csv(&dir.join("tune/bom_tuned.csv")));
    let (k, lo, hi) = (column(&header, "stiffness"), column(&header, "trim_min"), column(&header, "trim_max"));
    assert_eq!(fitted.len(), tuned.len());
    for (f, t) in fitted.iter().zip(&tuned) {
        if f[hi].is_empty() {
            assert_eq!(f[k], t[k], "{}: a rate that is not a trim's changed", f[0]);
        } else {
            let (rate, lo, hi): (f64, f64, f64) =
                (t[k].parse().unwrap(), f[lo].parse().unwrap(), f[hi].parse().unwrap());
            assert!((lo..=hi).contains(&rate), "{}: trim rate {rate} outside [{lo}, {hi}]", f[0]);
        }
    }
    let trims = fitted.iter().filter(|r| !r[hi].is_empty()).count();

    // The MuJoCo export carries every row of the bill, each either exactly or by callback.
    let export = springfit(&dir, &["export", d, "--bom", "fit/bom.csv", "--mujoco", "--out", "mj"]).ok();
    let xml = std::fs::read_to_string(dir.join("mj").join(format!("{name}.xml"))).unwrap();
    let md = std::fs::read_to_string(dir.join("mj/elements.md")).unwrap();
    // Hinges q1 … qn, each named after its URDF joint on a URDF arm.
    let urdf = design.chain.spatial().is_some();
    for (i, joint) in design.chain.joint_names().iter().enumerate() {
        let q = format!("q{}", i + 1);
        assert!(xml.contains(&format!("<joint name=\"{q}\"")), "no hinge {q}\n{}", export.report());
        assert!(!urdf || md.contains(&format!("`{q}` = `{joint}`")), "{q} is not named {joint}\n{md}");
    }
    for row in &fitted {
        assert_eq!(md.matches(&format!("| {} |", row[0])).count(), 1, "{} in elements.md\n{md}", row[0]);
    }
    assert!(export.stdout().contains(&format!("{} springs for MuJoCo", fitted.len())), "{}", export.report());

    // compare reads the fit's figures back.
    springfit(&dir, &["compare", "fit", "--out", "cmp"]).ok();
    let (header, rows) = csv(&dir.join("cmp/compare.csv"));
    assert_eq!(rows.len(), 1);
    assert_eq!(rows[0][column(&header, "p99_abs_deg")].parse::<f64>().unwrap(), p99);

    // Budgets 2 and 3 and one radius, each fitted at reduced settings: a row each. A budget too
    // small for the equalities is infeasible and says why; a larger budget is never worse; each
    // fit keeps to its budget.
    let quick = reduced(&dir, name, design.dof());
    // Radius 0.5, or less where the design's ball is small (a URDF arm's joint limits bound it).
    let radius = match &design.region {
        springfit::geodesic::Region::Ball { radius } | springfit::geodesic::Region::Clipped { radius, .. } => {
            (0.75 * radius).min(0.5)
        }
        _ => 0.5,
    };
    let radius = format!("{radius:.3}");
    let pareto =
        springfit(&dir, &["pareto", quick.to_str().unwrap(), "--k-max", "3", "--radii", &radius, "--out", "pareto"])
            .ok();
    let (header, rows) = csv(&dir.join("pareto/pareto.csv"));
    assert_eq!(rows.len(), 2 + 1, "{rows:?}\n{}", pareto.report());
    let (p99_col, used, infeasible) =
        (column(&header, "p99_abs_deg"), column(&header, "used"), column(&header, "infeasible"));
    let mut last = f64::INFINITY;
    for r in &rows[..2] {
        let budget: usize = r[1].parse().unwrap();
        if r[infeasible].is_empty() {
            let p99: f64 = r[p99_col].parse().unwrap();
            assert!(p99 <= last && r[used].parse::<usize>().unwrap() <= budget + trims, "{r:?}");
            last = p99;
        } else {
            let why = format!("no set of at most {budget} springs: the fit is infeasible");
            assert!(r[infeasible].contains(&why), "{r:?}");
        }
    }
    let radius = &rows[2];
    assert!(radius[infeasible].is_empty() && radius[p99_col].parse::<f64>().unwrap().is_finite(), "{radius:?}");
    let budget = design.fit.max_elements;
    assert!(budget == 0 || radius[used].parse::<usize>().unwrap() <= budget + trims, "{radius:?}");
}

/// The fitted springs simulated and swept (a design with scenarios).
fn scenarios_with_the_fitted_springs(dir: &Path, d: &str, summary: &serde_json::Value) {
    // The fitted springs simulated: the same set (its fingerprint), and the energy controller
    // holds the sweep's scenario at its target with the springs doing most of the work (the
    // shipped designs: within 0.3 % of the target energy over the last 5 s, actuator shares from
    // 0.001 % to 7 %, the triple pendulum's).
    let sim =
        springfit(dir, &["simulate", d, "--scenario", "sensitivity", "--bom", "fit/bom.csv", "--out", "sim"]).ok();
    let sj = json(&dir.join("sim/sim_sensitivity.json"));
    assert_eq!(sj["spring_set"], summary["spring_set"], "{}", sim.report());
    for (variant, m) in sj["runs"].as_object().unwrap() {
        assert!(num(&m["energy_rel_error_last5s"]) < 0.05, "{variant}: {m}");
        let share = num(&m["actuator_share"]);
        assert!(share > 0.0 && share < 0.2, "{variant}: actuator share {share}");
    }

    // Parasitic damping costs the actuators: each ε > 0 more than none (not monotonically beyond
    // that: the triple pendulum's share falls from 3.0 at ε = 0.1 to 0.7 at 0.5).
    let sweep = springfit(dir, &["sweep", d, "--builds", "1", "--out", "sweep"]).ok();
    let sw = json(&dir.join("sweep/sweep.json"));
    let shares: Vec<f64> = sw["parasitic"].as_array().unwrap().iter().map(|r| num(&r["actuator_share"])).collect();
    assert!(shares.len() >= 2 && shares[1..].iter().all(|s| *s > shares[0]), "{shares:?}\n{}", sweep.report());
    assert!(num(&sw["tolerance"]["residual_p99_deg_p50"]).is_finite(), "{}", sw["tolerance"]);
}

/// `springfit check` on a design file passes without a warning and names its catalogue.
fn check(dir: &Path, design: &Path, catalog: &str) {
    let run = springfit(dir, &["check", design.to_str().unwrap()]).ok();
    assert!(run.stdout().contains("ok:") && run.stdout().contains(&format!("({catalog}, ")), "{}", run.report());
    assert!(!run.stderr().contains("warning"), "a shipped design draws a warning\n{}", run.report());
}

/// The name a design's catalogue gives itself (`check` prints it).
fn catalog_name(design: &Design) -> String {
    let path = design.catalog.as_ref().unwrap();
    springfit::elements::catalog::Catalog::load(path, design.dof()).unwrap().name
}

/// `check` and a [`reduced`] fit of a shipped design. From [`CHECK_ONLY_FROM_JOINTS`] joints `check` only,
/// with 360 directions in the region check instead of the 2430 (five joints) or 3645 (six) it
/// takes as shipped (11 s of CPU each for the UR5's six joints; the full matrix checks them as
/// shipped).
fn check_and_reduced_fit(dir: &Path, name: &str) {
    let path = design_path(name);
    let design = Design::load(&path).unwrap();
    let catalog = catalog_name(&design);
    if design.dof() >= CHECK_ONLY_FROM_JOINTS {
        let fewer = util::design_variant(dir, name, &[("geodesics.check_directions", toml::Value::Integer(360))]);
        check(dir, &fewer, &catalog);
        return;
    }
    check(dir, &path, &catalog);
    let out = format!("fit-{name}");
    let fit = springfit(dir, &["fit", reduced(dir, name, design.dof()).to_str().unwrap(), "--out", &out]).ok();
    check_fit(&design, &dir.join(&out), &fit);
}

/// The shipped design `name` of `n` joints with reduced fit settings, written into `dir`: 12
/// training and held-out directions per joint, 10 samples each, 20 builds, 2 restarts (the
/// default design's fit in a tenth of its time).
fn reduced(dir: &Path, name: &str, n: usize) -> PathBuf {
    let directions = toml::Value::Integer(12 * n as i64);
    util::design_variant(
        dir,
        name,
        &[
            ("fit.training_directions", directions.clone()),
            ("fit.training_samples", toml::Value::Integer(10)),
            ("fit.evaluation_directions", directions),
            ("fit.evaluation_samples", toml::Value::Integer(10)),
            ("fit.builds", toml::Value::Integer(20)),
            ("fit.restarts", toml::Value::Integer(2)),
        ],
    )
}

#[test]
fn double_pendulum() {
    every_command("double_pendulum");
}

#[test]
fn double_pendulum_cams() {
    every_command("double_pendulum_cams");
}

#[test]
fn ur5_pan_lift_elbow() {
    every_command("ur5_pan_lift_elbow");
}

#[test]
fn double_pendulum_paper_window() {
    every_command("double_pendulum_paper_window");
}

/// The shipped designs in `designs/`, sorted.
fn shipped() -> Vec<String> {
    util::shipped_names()
}

#[test]
fn every_other_shipped_design_checks_and_fits() {
    let dir = temp_dir("all-reduced");
    let names: Vec<String> = shipped().into_iter().filter(|n| !EVERY_COMMAND.contains(&n.as_str())).collect();
    assert!(names.len() >= 10, "{names:?}");
    for name in &names {
        check_and_reduced_fit(&dir, name);
    }
}

#[test]
#[ignore = "the full matrix: every command on every design (check only from five joints), 450 s of CPU"]
fn full_matrix_every_command_on_every_design() {
    let mut names = shipped();
    // `SPRINGFIT_DESIGNS=a,b` keeps only those: the matrix rerun on the designs a change concerns.
    if let Ok(only) = std::env::var("SPRINGFIT_DESIGNS") {
        names.retain(|n| only.split(',').any(|o| o.trim() == n));
    }
    // Two designs at a time (each command runs on two threads); every design runs whatever
    // another's failure, and the failures are listed at the end (their messages above).
    let queue = std::sync::Mutex::new(names.into_iter());
    let failed = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..2 {
            s.spawn(|| {
                loop {
                    let next = queue.lock().unwrap().next();
                    let Some(name) = next else { break };
                    let design = Design::load(&design_path(&name)).unwrap();
                    let run = || {
                        if design.dof() < CHECK_ONLY_FROM_JOINTS {
                            every_command(&name);
                        } else {
                            check(&temp_dir(&format!("all-{name}")), &design_path(&name), &catalog_name(&design));
                        }
                    };
                    if std::panic::catch_unwind(run).is_err() {
                        failed.lock().unwrap().push(name);
                    }
                }
            });
        }
    });
    let failed = failed.into_inner().unwrap();
    assert!(failed.is_empty(), "every command did not pass on {failed:?}");
}
