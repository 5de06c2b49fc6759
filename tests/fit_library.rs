//! The fit through the library on the paper's arm: recovery of known stiffnesses by both
//! solvers from real geodesic rows, the bill of materials round trip, determinism.

use std::f64::consts::PI;
use std::path::Path;

use nalgebra::DVector;
use springfit::design::Design;
use springfit::design::fit::FitSettings;
use springfit::elements::catalog::{Candidate, Catalog};
use springfit::elements::{Element, Profile, Side};
use springfit::files::bom;
use springfit::fit::evaluate::evaluate;
use springfit::fit::problem::{Requirements, assemble};
use springfit::fit::run::fit;
use springfit::geodesic::{Fan, FanSpec, Stop};
use springfit::model::Chain;
use springfit::numerics::ode::OdeSettings;
use springfit::solve::lsq::Gram;
use springfit::solve::nnls::{NnlsSettings, nnls};
use springfit::solve::qp::{QpSettings, qp};

fn repo(p: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

#[test]
fn known_stiffnesses_are_recovered_by_both_solvers_from_geodesic_rows() {
    let chain = Chain::paper_double_pendulum();
    let q_eq = DVector::from_vec(vec![0.0, PI / 2.0]);
    let fan = Fan::trace(
        &chain,
        &q_eq,
        FanSpec { count: 24, phase: 0.0, stop: Stop::Arc(2.0), spacing: 0.1 },
        OdeSettings::default(),
    )
    .unwrap();
    let el = |profile, coupling: [f64; 2], offset| Candidate {
        element: Element { profile, coupling: coupling.to_vec(), offset },
        family: 0,
        max_stiffness: None,
        stock_rates: vec![],
        tolerance: 0.0,
    };
    let candidates = vec![
        el(Profile::Linear, [1.0, 0.0], 0.0),
        el(Profile::Linear, [0.0, 1.0], PI / 2.0),
        el(Profile::Crank, [1.0, 1.0], PI / 2.0),
        el(Profile::Cubic, [1.0, -1.0], -PI / 2.0),
        el(Profile::Compression(Side::Plus), [0.0, 1.0], 2.0),
        el(Profile::Compression(Side::Minus), [1.0, 2.0], 2.5),
        el(Profile::Crank, [2.0, -1.0], 1.0),
    ];
    let problem =
        assemble(&chain, &q_eq, &fan, &candidates, Requirements { omega: 2.0, hessian_match: true, monotone: false });
    let k_true = DVector::from_vec(vec![3.0, 0.0, 1.5, 0.7, 2.0, 0.0, 0.4]);
    // Right-hand sides that the known stiffnesses meet exactly.
    let b = &problem.rows * &k_true;
    let gram = Gram::from_rows(&problem.rows, &b);
    let eqs: Vec<_> = problem
        .equalities
        .iter()
        .map(|g| springfit::fit::problem::LinearGroup { rhs: &g.matrix * &k_true, ..g.clone() })
        .collect();
    let q = qp(&gram, &eqs, &[], &[None; 7], 0.0, &QpSettings::default()).unwrap();
    assert!((&q.k - &k_true).amax() < 1e-6, "QP {}", q.k);
    let mut weighted = gram.clone();
    for g in &eqs {
        weighted.add_weighted(&g.matrix, &g.rhs, 100.0);
    }
    let n = nnls(&weighted, 0.0, &NnlsSettings::default()).unwrap();
    assert!((&n.k - &k_true).amax() < 1e-6, "NNLS {}", n.k);
    assert!((&q.k - &n.k).amax() < 1e-6);
}

fn quick(design: &Design) -> FitSettings {
    FitSettings {
        training_directions: 36,
        training_samples: 20,
        evaluation_directions: 48,
        evaluation_samples: 20,
        ..design.fit
    }
}

#[test]
fn the_bill_of_materials_rebuilds_the_same_potential() {
    let design = Design::load(&repo("designs/double_pendulum_workshop.toml")).unwrap();
    let catalog = Catalog::load(design.catalog.as_ref().unwrap(), design.dof()).unwrap();
    let settings = quick(&design);
    let outcome = fit(&design, &catalog, &settings, springfit::progress::Progress::none()).unwrap();
    let text = bom::to_csv(&outcome.bom);
    let rows = bom::parse(Path::new("bom.csv"), &text).unwrap();
    let rebuilt = springfit::fit::bill::spring_set(&rows);
    assert_eq!(rebuilt, outcome.springs);
    let again = evaluate(&design, settings.frequency, settings.bands, &rebuilt, &outcome.evaluation).unwrap();
    assert_eq!(again.residuals, outcome.metrics.residuals);
    assert_eq!(again.stats, outcome.metrics.stats);
}

#[test]
fn the_fit_is_deterministic_across_thread_counts() {
    let design = Design::load(&repo("designs/double_pendulum.toml")).unwrap();
    let catalog = Catalog::load(design.catalog.as_ref().unwrap(), design.dof()).unwrap();
    let settings = quick(&design);
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| fit(&design, &catalog, &settings, springfit::progress::Progress::none()).unwrap())
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(bom::to_csv(&a.bom), bom::to_csv(&b.bom));
    assert_eq!(a.metrics.residuals, b.metrics.residuals);
}

/// A potential built from known cam coefficients on two couplings is recovered from real
/// geodesic rows by NNLS on the ± columns (k ≥ 0), up to each cam's free constant.
#[test]
fn known_cam_coefficients_are_recovered_from_geodesic_rows() {
    use springfit::elements::spline::Knots;
    let chain = Chain::paper_double_pendulum();
    let q_eq = DVector::from_vec(vec![0.0, PI / 2.0]);
    let fan = Fan::trace(
        &chain,
        &q_eq,
        FanSpec { count: 48, phase: 0.0, stop: Stop::Arc(1.5), spacing: 0.05 },
        OdeSettings::default(),
    )
    .unwrap();
    let couplings = [[1.0, 0.0], [1.0, -1.0]];
    let mut candidates = Vec::new();
    let mut k_true = Vec::new();
    let mut all_knots = Vec::new();
    for (ci, a) in couplings.iter().enumerate() {
        let at = |q: &[f64]| a[0] * q[0] + a[1] * q[1];
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for g in &fan.geodesics {
            for i in 0..g.len() {
                lo = lo.min(at(g.q(i)));
                hi = hi.max(at(g.q(i)));
            }
        }
        let knots = Knots::over(lo, hi, 8, 0.0);
        for j in 0..knots.basis_count() {
            let c = (j as f64 * 0.8 + ci as f64).sin() * 2.0;
            for negative in [false, true] {
                candidates.push(Candidate {
                    element: Element {
                        profile: Profile::Spline(knots.basis(j, negative)),
                        coupling: a.to_vec(),
                        offset: knots.lo,
                    },
                    family: 0,
                    max_stiffness: None,
                    stock_rates: vec![],
                    tolerance: 0.0,
                });
                k_true.push(if (c < 0.0) == negative { c.abs() } else { 0.0 });
            }
        }
        all_knots.push(knots);
    }
    let k_true = DVector::from_vec(k_true);
    let problem =
        assemble(&chain, &q_eq, &fan, &candidates, Requirements { omega: 2.0, hessian_match: false, monotone: false });
    let b = &problem.rows * &k_true;
    let sol = nnls(&Gram::from_rows(&problem.rows, &b), 0.0, &NnlsSettings::default()).unwrap();
    let per = all_knots[0].basis_count();
    for (ci, knots) in all_knots.iter().enumerate() {
        let coef = |k: &DVector<f64>| -> Vec<f64> {
            (0..per).map(|j| k[2 * (ci * per + j)] - k[2 * (ci * per + j) + 1]).collect()
        };
        let (truth, got) = (coef(&k_true), coef(&sol.k));
        // Torques agree across the span (constants are free).
        for i in 0..=50 {
            let x = knots.lo + (knots.hi() - knots.lo) * f64::from(i) / 50.0;
            let (t, g) = (knots.eval(&truth, x).1, knots.eval(&got, x).1);
            assert!((t - g).abs() < 1e-6 * (1.0 + t.abs()), "cam {ci} at x = {x}: {g} vs {t}");
        }
    }
}

/// The files of a fit with cams rebuild the potential it evaluated: identical residuals, and the
/// cams' CSV reproduces the coefficients' potential.
#[test]
fn a_fit_with_cams_round_trips_through_its_bill_of_materials() {
    let mut design = Design::load(&repo("designs/double_pendulum_paper_window_cams.toml")).unwrap();
    let text = "[[family]]\nname = \"disc cam\"\nprofile = \"cam\"\ncouplings = [[1, 0], [0, 1], [1, -1]]\nknots = 10\nsmoothing = 1e-5\n";
    let catalog = Catalog::parse(Path::new("cams.toml"), text, 2).unwrap();
    design.fit.solver = springfit::design::fit::SolverKind::Nnls;
    let settings = quick(&design);
    let outcome = fit(&design, &catalog, &settings, springfit::progress::Progress::none()).unwrap();
    assert_eq!(outcome.cams.len(), 3);
    // The files as the fit writes them: bom.csv with one row per cam, and cams/<id>.toml.
    let dir = std::env::temp_dir().join(format!("springfit-cam-round-trip-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let files = bom::files("bom.csv", &outcome.bom);
    assert_eq!(files.len(), 1 + 3);
    for (name, text) in &files {
        let p = dir.join(name);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, text).unwrap();
    }
    assert_eq!(files[0].1.lines().count(), 1 + 3, "{}", files[0].1);
    let rows = bom::read(&dir.join("bom.csv")).unwrap();
    let rebuilt = springfit::fit::bill::spring_set(&rows);
    assert_eq!(rebuilt, outcome.springs);
    assert_eq!(springfit::fit::bill::fingerprint(&rebuilt), springfit::fit::bill::fingerprint(&outcome.springs));
    // Written again, the rows read back give the same files.
    assert_eq!(bom::files("bom.csv", &rows), files);
    let _ = std::fs::remove_dir_all(&dir);
    let again = evaluate(&design, settings.frequency, settings.bands, &rebuilt, &outcome.evaluation).unwrap();
    assert_eq!(again.residuals, outcome.metrics.residuals);
    // The cams regrouped from the read-back rows are the same cams.
    assert_eq!(springfit::fit::bill::fitted_cams(&catalog, &rows), outcome.cams);
    for cam in &outcome.cams {
        assert!(cam.realisation.points.len() >= 1000);
        let csv = springfit::files::cam::csv(cam);
        assert!(csv.starts_with("x_rad,potential_j,torque_nm,follower_mm,radius_mm"));
        assert!(springfit::realise::cam::svg(&cam.realisation, &cam.id).contains("<path"));
    }
}

/// The chain of four links of `benches/scaling.rs` (slender rods lighter and shorter towards the
/// tip, gravity, `catalogs/chain.toml`, ball r = 0.15, no budget, 72 training directions): 614
/// candidates, above the switch to the large-problem solvers.
fn chain_of_four() -> Design {
    chain_of_four_sampled(Some(72))
}

/// [`chain_of_four`] with `training` directions (and five times as many held out), or the
/// default sampling.
fn chain_of_four_sampled(training: Option<usize>) -> Design {
    let mut s =
        "name = \"chain4\"\ncatalog = \"../catalogs/chain.toml\"\n[robot]\ngravity = [0.0, -9.81]\n".to_string();
    for i in 0..4 {
        let (m, l) = (1.5 * 0.85f64.powi(i), 0.8 * 0.9f64.powi(i));
        s += &format!("[[robot.links]]\nmass = {m}\nlength = {l}\ncom = {}\ninertia = {}\n", l / 2.0, m * l * l / 12.0);
    }
    s += "[equilibrium]\nq = [\"-pi/3\", \"pi/6\", \"pi/6\", \"pi/6\"]\n[region]\nkind = \"ball\"\nradius = 0.15\n";
    // The exact solves' own optimum, without the springs' mass in the objective.
    s += "[fit]\nfrequency = 6.0\nsolver = \"qp\"\nmax_elements = 0\nbuilds = 0\nmass_weight = 0.0\n";
    if let Some(t) = training {
        s += &format!("training_directions = {t}\nevaluation_directions = {}\n", 5 * t);
    }
    Design::parse(&repo("designs/chain4.toml"), &s).unwrap()
}

/// Hundreds of candidates and no constraint but k ≥ 0 and the equalities: the fit's exact
/// active-set solve (Lawson–Hanson on an updated factor) must meet the equalities to round-off
/// and reach the optimum that Clarabel's working set reaches, which a ridge too large or an early
/// stop misses by per cent (1e-10 of the unit diagonal: 14 % above it).
#[test]
fn the_large_unlimited_fit_is_exact_and_optimal() {
    use springfit::fit::Prepared;
    use springfit::fit::solve::nnls_support;
    use springfit::solve::lawson_hanson::nnls_equalities;
    use springfit::solve::screen::qp_screened;

    let design = chain_of_four();
    let catalog = Catalog::load(design.catalog.as_ref().unwrap(), design.dof()).unwrap();
    let o = fit(&design, &catalog, &design.fit, springfit::progress::Progress::none()).unwrap();
    assert!(o.candidates - o.dropped >= 600, "{} candidates: below the switch", o.candidates - o.dropped);
    assert!(o.metrics.equilibrium_gradient_norm < 1e-9, "|∇U(q_eq)| = {:e}", o.metrics.equilibrium_gradient_norm);
    assert!(o.metrics.hessian_rel_error < 1e-9, "Hessian error {:e}", o.metrics.hessian_rel_error);
    assert!(o.metrics.stats.p99_abs < 2.5, "p99 {}°", o.metrics.stats.p99_abs);

    // A bill that left out the elements under 5 % of the strongest's peak torque would miss the
    // equalities by far: every element of the fit is listed instead, and the bill holds them.
    let coarse = FitSettings { used_threshold: 0.05, ..design.fit };
    let c = fit(&design, &catalog, &coarse, springfit::progress::Progress::none()).unwrap();
    let peak = c.bom.iter().map(|r| r.max_torque_nm).fold(0.0, f64::max);
    assert!(c.bom.iter().any(|r| r.max_torque_nm < 0.05 * peak), "no weak element in the bill");
    assert!(c.metrics.equilibrium_gradient_norm < 1e-9, "|∇U(q_eq)| = {:e}", c.metrics.equilibrium_gradient_norm);
    assert!(c.metrics.hessian_rel_error < 1e-9, "Hessian error {:e}", c.metrics.hessian_rel_error);

    // The same problem by both large-problem solvers from the same start.
    let prepared = Prepared::new(&design, &catalog, &design.fit, springfit::progress::Progress::none()).unwrap();
    let (problem, gram) = (prepared.problem(), prepared.gram());
    let p = gram.dim();
    let start = nnls_support(gram, &problem.equalities, problem.row_count(), &design.fit).unwrap();
    let exact = nnls_equalities(gram, &problem.equalities, 0.0, &start).expect("an answer it vouches for");
    let screened =
        qp_screened(gram, &problem.equalities, &[], &vec![None; p], 0.0, &QpSettings::default(), &start).unwrap();
    assert!(exact.k.iter().all(|&k| k >= 0.0));
    assert!(exact.max_equality_residual < 1e-12, "equality residual {:e}", exact.max_equality_residual);
    let (a, b) = (gram.objective(&exact.k), gram.objective(&screened.solution.k));
    assert!((a - b).abs() < 2e-3 * b, "objectives {a:e} (Lawson–Hanson) and {b:e} (working set)");
}

/// Rounding can make the Lawson–Hanson iteration cycle: the chain of four at its default sampling
/// (34 560 rows, G from the rows' factors) returned to a passive set it had left and went round
/// until its step limit, leaving the answer to the working set. Once a passive set repeats, the
/// first eligible unknown enters (Bland's rule): it answers, meets the equalities to round-off
/// and reaches the working set's optimum.
#[test]
fn the_exact_solve_does_not_cycle() {
    use springfit::fit::Prepared;
    use springfit::fit::solve::nnls_support;
    use springfit::solve::lawson_hanson::nnls_equalities;
    use springfit::solve::screen::qp_screened;

    let design = chain_of_four_sampled(None);
    let catalog = Catalog::load(design.catalog.as_ref().unwrap(), design.dof()).unwrap();
    let prepared = Prepared::new(&design, &catalog, &design.fit, springfit::progress::Progress::none()).unwrap();
    let (problem, gram) = (prepared.problem(), prepared.gram());
    let p = gram.dim();
    assert!(p >= 600, "{p} candidates: below the switch");
    let start = nnls_support(gram, &problem.equalities, problem.row_count(), &design.fit).unwrap();
    let exact = nnls_equalities(gram, &problem.equalities, 0.0, &start).expect("an answer it vouches for");
    assert!(exact.iterations < 4 * p as u32, "{} steps", exact.iterations);
    assert!(exact.max_equality_residual < 1e-12, "equality residual {:e}", exact.max_equality_residual);
    let screened =
        qp_screened(gram, &problem.equalities, &[], &vec![None; p], 0.0, &QpSettings::default(), &start).unwrap();
    let (a, b) = (gram.objective(&exact.k), gram.objective(&screened.solution.k));
    assert!((a - b).abs() < 2e-3 * b, "objectives {a:e} (Lawson–Hanson) and {b:e} (working set)");
}
