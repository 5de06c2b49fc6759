//! Issue 44's test line, the parts `tests/mass.rs` leaves to the binary or states less strictly:
//! a fit with `max_spring_mass` below the floor refused by `springfit fit` (exit 2) before any
//! work with the floor in the message; `mass_weight = 0` in the file giving the bill of the file
//! without the key, bit for bit, and a budget that does not bind leaving NNLS's bill bit for bit;
//! the solvers' optimality conditions with the mass term written out with their multipliers
//! (k ≥ 0 bounds and the mass budget's); the mass model against the part chooser on every
//! shipped design of fewer than five joints; and `springfit pareto --axis mass`.

mod util;

use std::time::Instant;

use nalgebra::{DMatrix, DVector};
use springfit::design::Design;
use springfit::design::fit::{FitSettings, SolverKind};
use springfit::elements::Profile;
use springfit::elements::catalog::{Candidate, Catalog};
use springfit::fit::mass::MassModel;
use springfit::fit::run::fit;
use springfit::parts::lightest_of_fit;
use springfit::progress::Progress;
use springfit::solve::constraint::LinearGroup;
use springfit::solve::lsq::Gram;
use springfit::solve::nnls::{NnlsSettings, nnls};
use springfit::solve::qp::{QpSettings, qp_signed};
use util::{design_variant, shipped, springfit, springfit_threads, temp_dir};

/// The default design written into `dir` with test-sized fit settings (12 directions per joint,
/// 10 samples, 2 restarts, no builds) and the keys `more`.
fn quick(dir: &std::path::Path, more: &[(&str, toml::Value)]) -> std::path::PathBuf {
    let mut keys = vec![
        ("fit.training_directions", toml::Value::Integer(24)),
        ("fit.training_samples", toml::Value::Integer(10)),
        ("fit.evaluation_directions", toml::Value::Integer(24)),
        ("fit.evaluation_samples", toml::Value::Integer(10)),
        ("fit.builds", toml::Value::Integer(0)),
        ("fit.restarts", toml::Value::Integer(2)),
    ];
    keys.extend_from_slice(more);
    design_variant(dir, "double_pendulum", &keys)
}

/// `springfit fit` with `max_spring_mass` below the floor: exit 2, one error line naming the
/// file, the key and the floor, in well under the time of any geodesic, and no output folder.
#[test]
fn fit_refuses_a_budget_below_the_floor_before_any_work() {
    let dir = temp_dir("mass-floor");
    let design = quick(&dir, &[("fit.max_spring_mass", toml::Value::Float(0.05))]);
    let t = Instant::now();
    let run = springfit(&dir, &["fit", design.to_str().unwrap(), "--out", "f"]);
    let took = t.elapsed().as_secs_f64();
    let run = run.fails(2, &["double_pendulum.toml", "fit.max_spring_mass", "0.05 kg is below the floor of 0.162 kg"]);
    assert!(took < 2.0, "took {took} s\n{}", run.report());
    assert!(!dir.join("f").exists(), "{}", run.report());
    // The same floor bounds pareto's mass budgets, named by their flag.
    let run =
        springfit(&dir, &["pareto", design.to_str().unwrap(), "--axis", "mass", "--masses", "1,0.1", "--out", "p"]);
    run.fails(2, &["--masses[1]", "0.1 kg is below the floor of 0.162 kg"]);
    assert!(!dir.join("p").exists());
}

/// A design without `mass_weight` fits at the documented default (0.001,
/// `FitSettings::DEFAULT_MASS_WEIGHT`), and `max_spring_mass = 0` is no budget: the file without
/// the keys and the file with `mass_weight = 0.001` and `max_spring_mass = 0` give the same bill,
/// bit for bit (bom.csv and parts.csv compared as bytes).
#[test]
fn a_design_without_the_mass_keys_fits_at_the_default_weight() {
    let dir = temp_dir("mass-default");
    let plain = quick(&dir.join("a"), &[]);
    // The default design pins `mass_weight = 0`: take the key out, as a user's file leaves it.
    let text = std::fs::read_to_string(&plain).unwrap();
    let mut table: toml::Table = toml::from_str(&text).unwrap();
    table["fit"].as_table_mut().unwrap().remove("mass_weight");
    std::fs::write(&plain, toml::to_string(&table).unwrap()).unwrap();
    let written = quick(
        &dir.join("b"),
        &[("fit.mass_weight", toml::Value::Float(0.001)), ("fit.max_spring_mass", toml::Value::Float(0.0))],
    );
    springfit(&dir, &["fit", plain.to_str().unwrap(), "--out", "plain"]).ok();
    springfit(&dir, &["fit", written.to_str().unwrap(), "--out", "written"]).ok();
    for f in ["bom.csv", "parts.csv"] {
        let (a, b) =
            (std::fs::read(dir.join("plain").join(f)).unwrap(), std::fs::read(dir.join("written").join(f)).unwrap());
        assert!(a == b, "{f} differs");
    }
}

/// A budget above what NNLS's fit weighs never binds: NNLS solves once without the mass term's
/// shift (λ = 0) and the bill is the fit's without the key, bit for bit.
#[test]
fn a_budget_that_does_not_bind_leaves_nnls_bit_for_bit() {
    let (design, catalog) = shipped("double_pendulum");
    let settings = FitSettings {
        solver: SolverKind::Nnls,
        training_directions: 24,
        evaluation_directions: 24,
        restarts: 2,
        tolerance: Default::default(),
        ..design.fit
    };
    let plain = fit(&design, &catalog, &settings, Progress::none()).unwrap();
    let bounded =
        fit(&design, &catalog, &FitSettings { max_spring_mass: 1000.0, ..settings }, Progress::none()).unwrap();
    assert_eq!(plain.bom, bounded.bom);
}

/// A random least-squares problem ‖Ak − b‖² (40 rows, 12 springs, entries normal) with masses
/// per unit stiffness c in [0.5, 1), from springfit's own generator.
fn problem(seed: u64) -> (Gram, DVector<f64>, DMatrix<f64>, DVector<f64>) {
    let mut rng = springfit::numerics::rng::SplitMix64::new(seed);
    let a = DMatrix::from_fn(40, 12, |_, _| rng.normal());
    let b = DVector::from_fn(40, |_, _| 3.0 * rng.normal());
    let c = DVector::from_fn(12, |_, _| 0.5 + 0.5 * rng.uniform());
    (Gram::from_rows(&a, &b), c, a, b)
}

/// The KKT conditions of min ½‖Ak − b‖² + λcᵀk over k ≥ 0 (and cᵀk ≤ M with multiplier ν when
/// given): μ = Aᵀ(Ak − b) + (λ + ν)c is the bounds' multiplier, so μ ≥ 0, and μᵢkᵢ = 0 (μ = 0
/// wherever k > 0: stationarity). Returns the largest violation, relative to ‖Aᵀb‖∞.
fn kkt_violation(a: &DMatrix<f64>, b: &DVector<f64>, c: &DVector<f64>, lambda: f64, nu: f64, k: &DVector<f64>) -> f64 {
    let mu = a.transpose() * (a * k - b) + c * (lambda + nu);
    let scale = (a.transpose() * b).amax();
    let kscale = k.amax().max(1e-12);
    let mut worst = 0.0_f64;
    for j in 0..k.len() {
        worst = worst.max(-k[j] / kscale); // primal: k ≥ 0
        worst = worst.max(-mu[j] / scale); // dual: μ ≥ 0
        worst = worst.max((mu[j] * k[j]).abs() / (scale * kscale)); // complementary slackness
    }
    worst
}

/// The solvers with the mass term, on a small problem, meet the KKT conditions written out with
/// their multipliers: NNLS and the QP at λ ∈ {0, 0.5, 2, 8}; then the QP with the mass budget
/// cᵀk ≤ M at half the unbounded solution's mass: the budget binds (cᵀk = M), its multiplier ν,
/// read off the support, is positive and the same on every spring of the support, the bounds'
/// multipliers are ≥ 0; and NNLS at λ + ν (the weight the fit's NNLS bisects for) finds the
/// same springs at the same mass: the bisection on λ and the QP's row are one problem.
#[test]
fn kkt_with_the_mass_term_and_the_budgets_multiplier() {
    let (gram, c, a, b) = problem(11);
    let p = c.len();
    let qp = |g: &Gram, ineq: &[LinearGroup]| {
        qp_signed(g, &[], ineq, &vec![None; p], &vec![false; p], 0.0, &QpSettings::default()).unwrap().k
    };
    let shifted = |lambda: f64| {
        let mut g = gram.clone();
        g.c -= &c * lambda;
        g
    };
    for lambda in [0.0, 0.5, 2.0, 8.0] {
        let g = shifted(lambda);
        let k_nnls = nnls(&g, 0.0, &NnlsSettings::default()).unwrap().k;
        let k_qp = qp(&g, &[]);
        let (vn, vq) = (kkt_violation(&a, &b, &c, lambda, 0.0, &k_nnls), kkt_violation(&a, &b, &c, lambda, 0.0, &k_qp));
        eprintln!("λ = {lambda}: KKT violation NNLS {vn:.1e}, QP {vq:.1e}, mass {:.4}", c.dot(&k_nnls));
        assert!(vn < 1e-9, "NNLS λ = {lambda}: {vn}");
        assert!(vq < 1e-5, "QP λ = {lambda}: {vq}");
    }
    let lambda = 0.5;
    let g = shifted(lambda);
    let free_mass = c.dot(&nnls(&g, 0.0, &NnlsSettings::default()).unwrap().k);
    let budget = 0.5 * free_mass;
    // cᵀk ≤ M as the fit writes it: −cᵀk/M ≥ −1.
    let row = LinearGroup {
        name: "spring mass budget".into(),
        description: format!("Σ cᵢ kᵢ ≤ {budget} kg"),
        matrix: DMatrix::from_fn(1, p, |_, j| -c[j] / budget),
        rhs: DVector::from_element(1, -1.0),
    };
    let k = qp(&g, std::slice::from_ref(&row));
    let mass = c.dot(&k);
    assert!((mass - budget).abs() < 1e-6 * budget, "the budget binds: {mass} against {budget}");
    let grad = a.transpose() * (&a * &k - &b) + &c * lambda;
    let support: Vec<usize> = (0..p).filter(|&j| k[j] > 1e-7 * k.amax()).collect();
    assert!(support.len() >= 2, "{k}");
    let nus: Vec<f64> = support.iter().map(|&j| -grad[j] / c[j]).collect();
    let nu = nus.iter().sum::<f64>() / nus.len() as f64;
    let spread = nus.iter().map(|v| (v - nu).abs()).fold(0.0, f64::max);
    eprintln!(
        "budget {budget:.4} (half of {free_mass:.4}): ν = {nu:.6}, spread over the support {spread:.1e}, {} springs",
        support.len()
    );
    assert!(nu > 0.0, "the budget's multiplier is positive where it binds: {nu}");
    assert!(spread < 1e-5 * nu.max(1.0), "one multiplier for every spring of the support: {nus:?}");
    let violation = kkt_violation(&a, &b, &c, lambda, nu, &k);
    assert!(violation < 1e-5, "{violation}");
    let k_nnls = nnls(&shifted(lambda + nu), 0.0, &NnlsSettings::default()).unwrap().k;
    let gap = (&k_nnls - &k).amax() / k.amax();
    eprintln!("NNLS at λ + ν: mass {:.6} against {budget:.6}, springs within {gap:.1e}", c.dot(&k_nnls));
    assert!((c.dot(&k_nnls) - budget).abs() < 1e-4 * budget);
    assert!(gap < 1e-4, "{gap}");
}

/// The fit settings of the model-against-parts comparison: the design's own with 12 directions
/// per joint, 10 samples and 2 restarts, nominal only (as `tests/cli_all_designs.rs` reduces).
fn reduced(design: &Design) -> FitSettings {
    let directions = 12 * design.dof();
    FitSettings {
        training_directions: directions,
        evaluation_directions: directions,
        training_samples: 10,
        evaluation_samples: 10,
        restarts: 2,
        tolerance: Default::default(),
        ..design.fit
    }
}

/// How the mass model agrees with the part chooser on one design's reduced fit: per element
/// that both size (no trims, cams or cubics), cᵢkᵢ over the chosen part's mass.
struct Agreement {
    parts: usize,
    by_model: f64,
    by_parts: f64,
    median: f64,
    lowest: f64,
    highest: f64,
    /// The worst ratio (farthest from 1 either way) among parts of 2 % of the bill's mass or more.
    worst_heavy: f64,
}

fn agreement(design: &Design, catalog: &Catalog) -> Option<Agreement> {
    let settings = reduced(design);
    let outcome = fit(design, catalog, &settings, Progress::none()).unwrap();
    let parts = lightest_of_fit(design, &outcome, settings.frequency, &[]).unwrap();
    let rows: Vec<_> = outcome
        .bom
        .iter()
        .filter(|r| r.adjust.trim_range.is_none() && !matches!(r.element.profile, Profile::Spline(_) | Profile::Cubic))
        .collect();
    let candidates: Vec<Candidate> = rows.iter().map(|r| Candidate::bare(r.element.clone())).collect();
    let model = MassModel::new(design, &candidates, &outcome.evaluation, settings.frequency);
    let mut pairs = Vec::new();
    for (i, r) in rows.iter().enumerate() {
        let Some(part) = parts.elements.iter().find(|e| e.id == r.id).and_then(|e| e.part.as_ref().ok()) else {
            continue;
        };
        if model.from_parts[i] && part.mass > 0.0 {
            pairs.push((part.mass, model.mass_at(i, r.stiffness)));
        }
    }
    if pairs.is_empty() {
        return None;
    }
    let by_parts: f64 = pairs.iter().map(|p| p.0).sum();
    let by_model: f64 = pairs.iter().map(|p| p.1).sum();
    let mut ratios: Vec<f64> = pairs.iter().map(|p| p.1 / p.0).collect();
    ratios.sort_by(f64::total_cmp);
    let worst_heavy = pairs
        .iter()
        .filter(|p| p.0 >= 0.02 * by_parts)
        .map(|p| p.1 / p.0)
        .fold(1.0, |w: f64, r| if (r.ln()).abs() > w.ln().abs() { r } else { w });
    Some(Agreement {
        parts: pairs.len(),
        by_model,
        by_parts,
        median: ratios[ratios.len() / 2],
        lowest: ratios[0],
        highest: ratios[ratios.len() - 1],
        worst_heavy,
    })
}

/// The mass model against the part chooser on every shipped design of fewer than five joints
/// (from five, even a reduced fit takes most of a minute: `tests/cli_all_designs.rs`), on
/// reduced fits, nominal only: per design the model's total Σ mᵢ(kᵢ) over the chosen parts' total
/// (the elements both size: no trims, cams or cubics), the median ratio per part, the range, and
/// the worst ratio among parts of 2 % of the bill's mass or more, printed as a table. Measured
/// with the mass curve (one thread, 1,050 s under load): totals 0.968 (triple_pendulum) to 1.088
/// (ur10_lift_elbow_wrist), and 1.323 for double_pendulum_cams' one spring; medians 0.977–1.136
/// (1.323); the default design 12 parts, 12.49 kg by the model against 12.58 kg, median 1.003.
/// With a straight line through one part (before the curve) totals were 0.70–1.34 and the big
/// cranks read 0.55–0.6 of their parts: the envelope makes a crank heavier per unit stiffness as
/// it grows. Small parts are not smooth in k (the least wire and coils a maker winds). Held:
/// every total within 0.6–1.5 and every median within 0.8–2.5 (the model steers the fit's mass
/// term and budget; every mass a report gives is the parts').
#[test]
#[ignore = "a reduced fit and its parts for each of 16 shipped designs: minutes of CPU"]
fn the_mass_model_agrees_with_the_part_chooser_on_every_shipped_design() {
    let mut names = util::shipped_names();
    if let Ok(only) = std::env::var("SPRINGFIT_DESIGNS") {
        names.retain(|n| only.split(',').any(|o| o.trim() == n));
    }
    let mut failures = Vec::new();
    eprintln!("design | parts | model kg | parts kg | total ratio | median | range | worst ≥ 2 %");
    for name in &names {
        let (design, catalog) = shipped(name);
        if design.dof() >= 5 {
            eprintln!("{name} | {} joints: not fitted", design.dof());
            continue;
        }
        let Some(a) = agreement(&design, &catalog) else {
            eprintln!("{name} | no element both size (cams only)");
            continue;
        };
        let total = a.by_model / a.by_parts;
        eprintln!(
            "{name} | {} | {:.3} | {:.3} | {total:.3} | {:.3} | {:.3}–{:.3} | {:.3}",
            a.parts, a.by_model, a.by_parts, a.median, a.lowest, a.highest, a.worst_heavy
        );
        if !(0.6..1.5).contains(&total) || !(0.8..2.5).contains(&a.median) {
            failures.push(format!("{name}: total {total:.3}, median {:.3}", a.median));
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}

/// `springfit pareto --axis mass` on a quick default design with two budgets: the two rows and
/// the fit without a budget, each within its budget by the model and by its parts, the floor and the arm on every
/// row, the JSON and the figure, and the same bytes on one thread and on two.
#[test]
fn pareto_draws_the_mass_axis() {
    let dir = temp_dir("pareto-mass");
    let design = quick(&dir, &[]);
    let d = design.to_str().unwrap();
    let args = |out: &'static str| vec!["pareto", d, "--axis", "mass", "--masses", "3,1", "--out", out];
    let run = springfit(&dir, &args("p2")).ok();
    assert!(run.stdout().contains("spring mass (floor 0.162 kg, arm 2.000 kg)"), "{}", run.report());
    for f in ["pareto_mass.csv", "pareto_mass.json", "pareto_mass.svg", "pareto_mass.png", "pareto.md", "report.html"] {
        assert!(dir.join("p2").join(f).is_file(), "missing {f}\n{}", run.report());
    }
    assert!(!dir.join("p2/pareto.csv").exists(), "no budget or radius curve was asked");
    let csv = std::fs::read_to_string(dir.join("p2/pareto_mass.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("{name}: {header:?}"));
    let rows: Vec<Vec<String>> = lines.map(|l| springfit::files::split_csv_line(l).unwrap()).collect();
    assert_eq!(rows.len(), 3, "{csv}");
    assert_eq!(rows[0][col("max_spring_mass_kg")], "1");
    assert_eq!(rows[1][col("max_spring_mass_kg")], "3");
    assert_eq!(rows[2][col("max_spring_mass_kg")], "", "the last row is the fit without a budget");
    for r in &rows {
        assert_eq!(r[col("infeasible")], "", "{csv}");
        let model: f64 = r[col("model_mass_kg")].parse().unwrap();
        let parts: f64 = r[col("spring_mass_kg")].parse().unwrap();
        if let Ok(budget) = r[col("max_spring_mass_kg")].parse::<f64>() {
            assert!(model <= 1.02 * budget, "{model} kg over {budget} kg\n{csv}");
            // Parts that broke the budget are solved again on the cranks as built (as `fit`).
            assert!(parts <= 1.02 * budget, "parts {parts} kg over {budget} kg\n{csv}");
        }
        assert!(parts > 0.0 && r[col("p99_abs_deg")].parse::<f64>().unwrap() > 0.0, "{csv}");
        assert!((r[col("floor_kg")].parse::<f64>().unwrap() - 0.162).abs() < 5e-4, "{csv}");
        assert_eq!(r[col("arm_mass_kg")], "2");
    }
    let p99 = |i: usize| rows[i][col("p99_abs_deg")].parse::<f64>().unwrap();
    assert!(p99(0) >= p99(1), "a larger mass budget may not be worse: {csv}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("p2/pareto_mass.json")).unwrap()).unwrap();
    assert_eq!(json["points"].as_array().unwrap().len(), 3);
    assert!(json["points"][2]["max_spring_mass_kg"].is_null());
    let md = std::fs::read_to_string(dir.join("p2/pareto.md")).unwrap();
    assert!(md.contains("## Best residual per spring mass") && !md.contains("per spring budget"), "{md}");
    // Deterministic whatever the thread count.
    springfit_threads(&dir, &args("p1"), 1).ok();
    for f in ["pareto_mass.csv", "pareto_mass.json"] {
        assert!(
            std::fs::read(dir.join("p1").join(f)).unwrap() == std::fs::read(dir.join("p2").join(f)).unwrap(),
            "{f} differs between one thread and two"
        );
    }
    // Points of a curve not asked for are refused, naming the flag.
    springfit(&dir, &["pareto", d, "--axis", "mass", "--radii", "1", "--out", "p3"])
        .fails(2, &["--radii", "add radius"]);
}

/// A budget that binds with a selection of at most 12 (the default design's, reduced, QP): the
/// selection chooses again with every support refitted within the budget, and the chosen
/// support is solved at the least mass weight that brings it within. The bill is within the
/// budget by the model, and the same on one thread and on two.
#[test]
fn a_binding_budget_is_held_by_the_selection_at_equal_mass() {
    let (design, catalog) = shipped("double_pendulum");
    let settings = FitSettings { max_elements: 12, ..reduced(&design) };
    let mass_of = |o: &springfit::FitOutcome| {
        // The fitted springs: the trims are held at mid-range, not fitted, and the fit does not
        // weigh them.
        let rows: Vec<_> = o.bom.iter().filter(|r| r.adjust.trim_range.is_none()).collect();
        let candidates: Vec<Candidate> = rows.iter().map(|r| Candidate::bare(r.element.clone())).collect();
        let model = MassModel::new(&design, &candidates, &o.evaluation, settings.frequency);
        rows.iter().enumerate().map(|(i, r)| model.mass_at(i, r.stiffness)).sum::<f64>()
    };
    let plain = fit(&design, &catalog, &settings, Progress::none()).unwrap();
    let budget = 0.4 * mass_of(&plain);
    let bounded = FitSettings { max_spring_mass: budget, ..settings };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| fit(&design, &catalog, &bounded, Progress::none()).unwrap())
    };
    let (one, two) = (run(1), run(2));
    let held = mass_of(&two);
    eprintln!(
        "unbounded {:.3} kg at p99 {:.3}°; budget {budget:.3} kg: {held:.3} kg at p99 {:.3}°, {} springs",
        mass_of(&plain),
        plain.metrics.stats.p99_abs,
        two.metrics.stats.p99_abs,
        two.bom.iter().filter(|r| r.adjust.trim_range.is_none()).count()
    );
    assert!(held <= budget * (1.0 + 1e-6), "{held} kg over {budget} kg");
    assert_eq!(one.bom, two.bom, "the bill depends on the thread count");
}
