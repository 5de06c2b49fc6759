//! The tolerance-aware fit, the preload bound and the nominal fit's reproducibility, through the
//! library on the paper's arm.

use std::path::Path;

use nalgebra::DVector;
use springfit::asbuilt::trim_build;
use springfit::design::Design;
use springfit::design::fit::{FitSettings, SolverKind};
use springfit::design::tolerance::{Distribution, ToleranceSpec, TrimRule};
use springfit::elements::catalog::{Candidate, Catalog};
use springfit::files::bom;
use springfit::fit::evaluate::evaluate;
use springfit::fit::problem::{Requirements, assemble};
use springfit::fit::robust::{BuildPenalty, base_jacobian, retrace, rows_of, spread, spread_with, trimmed_spread};
use springfit::fit::run::fit;
use springfit::geodesic::Fan;
use springfit::numerics::rng::SplitMix64;
use springfit::potential::SpringSet;
use springfit::progress::Progress;

fn repo(p: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn load(name: &str) -> (Design, Catalog) {
    let design = Design::load(&repo(&format!("designs/{name}.toml"))).unwrap();
    let catalog = Catalog::load(design.catalog.as_ref().unwrap(), design.dof()).unwrap();
    (design, catalog)
}

fn quick(design: &Design) -> FitSettings {
    FitSettings {
        training_directions: 24,
        training_samples: 12,
        evaluation_directions: 24,
        evaluation_samples: 12,
        ..design.fit
    }
}

/// The parts among `candidates` (every candidate in one family: a cam's columns are one part).
fn grouping_of(candidates: &[Candidate]) -> springfit::elements::group::Grouping {
    springfit::elements::group::Grouping::new(candidates.iter().map(|c| (c.family, &c.element)))
}

/// The figures a cross-version comparison of two fits reads: the training objective ‖A k − b‖²
/// on `training` plus `spread` (the tolerance-aware fit's expected spread of the builds, 0
/// without a tolerance), and on `evaluation` the held-out statistics (p50, p95, p99, max in
/// degrees) and the equalities (|∇U(q_eq)| in N·m, the Hessian's relative error).
struct Figures {
    objective: f64,
    stats: [f64; 4],
    gradient: f64,
    hessian: f64,
}

impl Figures {
    fn of(design: &Design, training: &Fan, evaluation: &Fan, springs: &SpringSet, spread: f64) -> Figures {
        let omega = design.fit.frequency;
        let e = evaluate(design, omega, design.fit.bands, springs, evaluation).unwrap();
        let s = &e.stats;
        Figures {
            objective: rows_of(&design.chain, training, springs, omega).norm_squared() + spread,
            stats: [s.median_abs, s.p95_abs, s.p99_abs, s.max_abs],
            gradient: e.equilibrium_gradient_norm,
            hessian: e.hessian_rel_error,
        }
    }

    /// The objective at most `objective` times `reference`'s and each statistic at most `stats`
    /// times (a fit may come out better than the reference; a search is judged by how much worse
    /// it may come out), and the equalities met to [`EQUALITIES`] whatever the reference's.
    fn at_most(&self, objective: f64, stats: f64, reference: &Figures) {
        let show = format!(
            "objective {:.6e} vs {:.6e}; stats {:?} vs {:?}",
            self.objective, reference.objective, self.stats, reference.stats
        );
        assert!(self.objective <= objective * reference.objective, "{show}");
        for (a, b) in self.stats.iter().zip(&reference.stats) {
            assert!(*a <= stats * b, "{show}");
        }
        assert!(
            self.gradient <= EQUALITIES && self.hessian <= EQUALITIES,
            "|∇U| {:e}, Hessian {:e}",
            self.gradient,
            self.hessian
        );
    }

    /// Each figure within `relative` of `reference`'s, both ways.
    fn within(&self, relative: f64, reference: &Figures) {
        let close = |a: f64, b: f64| (a - b).abs() <= relative * b.abs();
        let show = format!(
            "objective {:.12e} vs {:.12e}; stats {:?} vs {:?}",
            self.objective, reference.objective, self.stats, reference.stats
        );
        assert!(close(self.objective, reference.objective), "{show}");
        assert!(self.stats.iter().zip(&reference.stats).all(|(a, b)| close(*a, *b)), "{show}");
        assert!(
            self.gradient <= EQUALITIES && self.hessian <= EQUALITIES,
            "|∇U| {:e}, Hessian {:e}",
            self.gradient,
            self.hessian
        );
    }
}

/// The bound on a QP fit's |∇U(q_eq)| (N·m) and Hessian error: they hold to round-off (1e-14 on
/// the default design); one part in 10⁸ of error in its largest stiffness alone gives 3e-7 N·m.
const EQUALITIES: f64 = 1e-9;

/// How far a rounding change moves a convex solve on a fixed support: its figures and
/// stiffnesses agree to ~1e-10 (perturbing ω by 1e-10 moves them by 5e-10); 1e-6 is far above
/// that and far below what a wrong row, weight or solver does (a 0.1 % error in one stiffness
/// moves the objective by 4×, the p99 by 3×).
const CONVEX: f64 = 1e-6;

/// A catalogue of exactly the elements of the bill `bom` (each its own family with its
/// coupling and offset written out), with the trim springs of `catalogs/paper_trim.toml` when the
/// bill has trims: fitted without a budget, the same support solved again, a convex problem a
/// rounding change cannot divert (unlike the selection of the support).
fn support_of(bom: &str, dir: &Path) -> Catalog {
    use toml::Value;
    let mut lines = bom.lines().map(|l| springfit::files::split_csv_line(l).unwrap());
    let header = lines.next().unwrap();
    let trim = header.iter().position(|h| h == "trim_max");
    let mut families: Vec<Value> = Vec::new();
    for f in lines.filter(|f| trim.is_none_or(|t| f[t].is_empty())) {
        let mut family = toml::Table::new();
        family.insert("name".into(), Value::String(format!("{} {}", f[1], f[0])));
        family.insert("profile".into(), Value::String(f[2].clone()));
        if !f[3].is_empty() {
            family.insert("side".into(), Value::String(f[3].clone()));
        }
        family.insert("unit".into(), Value::String(f[7].clone()));
        let coupling = f[4].split(';').map(|a| Value::Integer(a.parse().unwrap())).collect();
        family.insert("couplings".into(), Value::Array(vec![Value::Array(coupling)]));
        family.insert("offsets".into(), Value::Array(vec![Value::Float(f[5].parse().unwrap())]));
        families.push(Value::Table(family));
    }
    if trim.is_some() {
        let paper_trim: toml::Table =
            toml::from_str(&std::fs::read_to_string(repo("catalogs/paper_trim.toml")).unwrap()).unwrap();
        let trims =
            paper_trim["family"].as_array().unwrap().iter().filter(|f| f.get("trim") == Some(&Value::Boolean(true)));
        families.extend(trims.cloned());
    }
    let mut catalog = toml::Table::new();
    catalog.insert("name".into(), Value::String("support".into()));
    catalog.insert("family".into(), Value::Array(families));
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join("support.toml");
    std::fs::write(&path, toml::to_string(&catalog).unwrap()).unwrap();
    let catalog = Catalog::load(&path, 2).unwrap();
    let _ = std::fs::remove_dir_all(dir);
    catalog
}

/// The reference bill `tests/data/<file>` as a spring set, and the fit with `settings` of exactly
/// its elements ([`support_of`]) without a budget.
fn reference_and_refit(design: &Design, file: &str, settings: &FitSettings) -> (SpringSet, springfit::fit::FitOutcome) {
    let text = std::fs::read_to_string(repo("tests/data").join(file)).unwrap();
    let reference = springfit::fit::bill::spring_set(&bom::parse(Path::new(file), &text).unwrap());
    let dir = std::env::temp_dir().join(format!("springfit-robust-{file}-{}", std::process::id()));
    let support = support_of(&text, &dir);
    let again = fit(design, &support, &FitSettings { max_elements: 0, ..*settings }, Progress::none()).unwrap();
    (reference, again)
}

/// `tolerance = "none"` with the single exchange search (`restarts = 0`, `pair_swaps = false`)
/// is the fit springfit made before the tolerance-aware fit and the restarts existed. Its bill
/// of the default design with the paper catalogue (`tests/data/double_pendulum_nominal_bom.csv`,
/// its first twelve columns, written by `springfit fit` at 805622f and rewritten once since, when
/// crank offsets were wrapped into (−π, π], which merged duplicate crank phases and so changed the
/// candidate set; reproduced byte for byte up to 2d98a71) is the reference, compared twice:
/// - the solve on its support: the reference's twelve elements fitted again without a budget
///   give its stiffnesses and figures within [`CONVEX`];
/// - the search: the fit over the whole catalogue keeps twelve springs, meets the equalities, and
///   its objective and held-out statistics are at most 3.5× and 1.8× the reference's. The single
///   exchange search is chaotic: perturbing ω or q_eq by 1e-16 to 1e-9 (17 runs) changed its
///   springs in 16, by up to 2.84× the reference's objective and 1.53× its p99, the reference
///   being the best of them. What the bounds catch is a search gone wrong: one pass of exchange
///   moves instead of fifty gives 4.5× the objective and 2.2× the p99, a 0.1 % error in the
///   largest stiffness 4.4× and 3.1×.
#[test]
fn tolerance_none_reproduces_the_nominal_fit() {
    // The reference was fitted with the paper catalogue, before the default design took the
    // catalogue with trim springs (`paper_trim`): fit with that catalogue.
    let (design, _) = load("double_pendulum");
    let catalog = Catalog::load(&repo("catalogs/paper.toml"), design.dof()).unwrap();
    let settings = FitSettings {
        tolerance: ToleranceSpec::None,
        restarts: 0,
        pair_swaps: false,
        trimmed_weight: 0.0,
        ..design.fit
    };
    let (reference, again) = reference_and_refit(&design, "double_pendulum_nominal_bom.csv", &settings);
    assert_eq!(again.springs.elements, reference.elements);
    for (k, r) in again.springs.stiffness.iter().zip(&reference.stiffness) {
        assert!((k - r).abs() <= CONVEX * r, "stiffness {k} against the reference's {r}");
    }
    let expected = Figures::of(&design, &again.training, &again.evaluation, &reference, 0.0);
    Figures::of(&design, &again.training, &again.evaluation, &again.springs, 0.0).within(CONVEX, &expected);

    let outcome = fit(&design, &catalog, &settings, Progress::none()).unwrap();
    assert!(outcome.solve.expected_build_spread.is_none());
    assert_eq!(outcome.springs.elements.len(), 12);
    let searched = Figures::of(&design, &outcome.training, &outcome.evaluation, &outcome.springs, 0.0);
    searched.at_most(3.5, 1.8, &Figures::of(&design, &outcome.training, &outcome.evaluation, &reference, 0.0));
}

/// The model of the tolerance-aware fit: to first order a build with kᵢ → kᵢ(1 + δᵢ), judged
/// about its own equilibrium, has E‖R‖² = ‖A k − b‖² + Σ Dᵢᵢ kᵢ². Checked against Monte Carlo
/// builds, each with its own equilibrium found by Newton's method and its training fan retraced
/// from there, at a small tolerance (the linearisation's domain).
#[test]
fn expected_objective_matches_monte_carlo_builds() {
    let (design, catalog) = load("double_pendulum");
    let settings = FitSettings {
        tolerance: ToleranceSpec::None,
        max_elements: 8,
        restarts: 0,
        pair_swaps: false,
        ..quick(&design)
    };
    let o = fit(&design, &catalog, &settings, Progress::none()).unwrap();
    let springs = &o.springs;
    let chain = &design.chain;
    let ode = design.geodesics.ode;
    let omega = settings.frequency;
    let spacing = o.region.extent / settings.training_samples as f64;
    let candidates: Vec<Candidate> = springs
        .elements
        .iter()
        .map(|e| Candidate { element: e.clone(), family: 0, max_stiffness: None, stock_rates: vec![], tolerance: 0.0 })
        .collect();
    let req = Requirements { omega, hessian_match: settings.hessian_match, monotone: false };
    let problem = assemble(chain, &design.q_eq, &o.training, &candidates, req);
    let k = DVector::from_column_slice(&springs.stiffness);
    let r0 = &problem.rows * &k - &problem.rhs;
    assert!((&r0 - rows_of(chain, &o.training, springs, omega)).amax() < 1e-12);

    let t = 0.01;
    let dist = Distribution::Uniform;
    let sigma2 = vec![dist.variance(t); candidates.len()];
    let sp = spread(
        chain,
        &o.training,
        spacing,
        (&candidates, &grouping_of(&candidates)),
        &problem.rows,
        springs,
        &sigma2,
        omega,
        ode,
    )
    .unwrap();
    let predicted: f64 = sp.rows.iter().zip(k.iter()).map(|(d, k)| d * k * k).sum();
    let expected = r0.norm_squared() + predicted;
    // The model the design notes warn against: rows about the old equilibrium.
    let naive: f64 = (0..k.len()).map(|i| sigma2[i] * problem.rows.column(i).norm_squared() * k[i] * k[i]).sum();

    let builds = 300;
    let (mut total, mut change) = (Vec::new(), Vec::new());
    for b in 0..builds {
        let mut rng = SplitMix64::stream(42, b);
        let scale: Vec<f64> = (0..k.len()).map(|_| 1.0 + t * dist.draw_unit(&mut rng)).collect();
        let built = springs.scaled(&scale);
        let q_b = springfit::studies::sweep::equilibrium(&design, &built)
            .expect("a build near the design has an equilibrium");
        let fan = retrace(chain, &q_b, &o.training, spacing, ode).unwrap();
        let r = rows_of(chain, &fan, &built, omega);
        total.push(r.norm_squared());
        change.push((&r - &r0).norm_squared());
    }
    let mean_se = |v: &[f64]| {
        let n = v.len() as f64;
        let m = v.iter().sum::<f64>() / n;
        let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0);
        (m, (var / n).sqrt())
    };
    let (m_change, se_change) = mean_se(&change);
    let (m_total, se_total) = mean_se(&total);
    eprintln!(
        "rows change: predicted {predicted:.4e}, measured {m_change:.4e} ± {se_change:.1e}; naive {naive:.4e}; \
         objective: expected {expected:.6e}, measured {m_total:.6e} ± {se_total:.1e}, nominal {:.6e}",
        r0.norm_squared()
    );
    assert!(predicted > 0.0);
    assert!((m_change - predicted).abs() <= 4.0 * se_change, "{m_change} vs {predicted} ± {se_change}");
    assert!((m_total - expected).abs() <= 4.0 * se_total, "{m_total} vs {expected} ± {se_total}");
    // Judged about the old equilibrium the spread would be far larger.
    assert!(naive > 3.0 * predicted, "naive {naive} vs {predicted}");
}

/// The same model with a cam: its basis columns all scale with one δ (the follower spring's rate
/// error), so its expected spread is a block σ² V_gᵀ V_g over its columns, not a diagonal. A
/// small problem (one cam on (1, 1) with 8 knots, linear springs on four couplings) fitted
/// nominally, then Monte Carlo builds with only the cam deviating, drawn as the as-built figures
/// draw them (`asbuilt::factors`: one δ per cam): the expected objective matches their mean
/// within sampling error, and charging each column its own δ (the diagonal) would not.
#[test]
fn expected_objective_with_a_cam_matches_monte_carlo_builds() {
    let (design, _) = load("double_pendulum");
    let dir = std::env::temp_dir().join(format!("springfit-robust-cam-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cat_path = dir.join("one_cam.toml");
    std::fs::write(
        &cat_path,
        r#"name = "one_cam"
description = "one cam and four linear springs"

[[family]]
name = "disc cam"
profile = "cam"
unit = "J"
couplings = [[1, 1]]
knots = 8
smoothing = 1e-5
tolerance = 0.05

[[family]]
name = "torsion spring"
profile = "linear"
unit = "N*m/rad"
couplings = [[1, 0], [0, 1], [1, 1], [1, -1]]
offsets = "equilibrium"
tolerance = 0.05
"#,
    )
    .unwrap();
    let catalog = Catalog::load(&cat_path, design.dof()).unwrap();
    let settings = FitSettings {
        tolerance: ToleranceSpec::None,
        solver: SolverKind::Nnls,
        max_elements: 0,
        monotone: false,
        builds: 0,
        trimmed_weight: 0.0,
        ..quick(&design)
    };
    let o = fit(&design, &catalog, &settings, Progress::none()).unwrap();
    let groups = springfit::asbuilt::bom_groups(&o.bom);
    let cam_rows = groups.iter().filter(|g| g.is_some()).count();
    assert!(cam_rows >= 4, "the cam uses {cam_rows} basis columns");
    assert!(groups.iter().flatten().all(|&g| g == 0), "one cam: {groups:?}");
    let springs = &o.springs;
    let chain = &design.chain;
    let ode = design.geodesics.ode;
    let omega = settings.frequency;
    let spacing = o.region.extent / settings.training_samples as f64;
    // Every element in one family index: cams are grouped by (family, coupling, knots), springs
    // never.
    let candidates: Vec<Candidate> = springs
        .elements
        .iter()
        .map(|e| Candidate { element: e.clone(), family: 0, max_stiffness: None, stock_rates: vec![], tolerance: 0.0 })
        .collect();
    let req = Requirements { omega, hessian_match: settings.hessian_match, monotone: false };
    let problem = assemble(chain, &design.q_eq, &o.training, &candidates, req);
    let k = DVector::from_column_slice(&springs.stiffness);
    let r0 = &problem.rows * &k - &problem.rhs;

    let t = 0.01;
    let dist = Distribution::Uniform;
    // Only the cam deviates, so that its share of the spread is all there is to see.
    let sigma2: Vec<f64> = groups.iter().map(|g| if g.is_some() { dist.variance(t) } else { 0.0 }).collect();
    let sp = spread(
        chain,
        &o.training,
        spacing,
        (&candidates, &grouping_of(&candidates)),
        &problem.rows,
        springs,
        &sigma2,
        omega,
        ode,
    )
    .unwrap();
    assert_eq!(sp.blocks.len(), 1);
    assert_eq!(sp.blocks[0].columns.len(), cam_rows);
    assert!(sp.blocks[0].columns.iter().all(|&j| sp.rows[j] == 0.0 && sp.shift[j] == 0.0));
    let predicted = BuildPenalty::of(&sp, 1.0, 0.0).value(k.as_slice());
    let expected = r0.norm_squared() + predicted;
    // Each cam column with its own δ: the diagonal of the block.
    let b = &sp.blocks[0];
    let per_column: f64 = b.columns.iter().enumerate().map(|(a, &j)| b.rows[(a, a)] * k[j] * k[j]).sum();

    let builds = 300;
    let (mut total, mut change) = (Vec::new(), Vec::new());
    for i in 0..builds {
        let mut rng = SplitMix64::stream(42, i);
        let scale =
            springfit::asbuilt::factors(&o.bom, |r| if r.id.starts_with('C') { t } else { 0.0 }, dist, &mut rng);
        for (a, &j) in b.columns.iter().enumerate().skip(1) {
            assert_eq!(scale[j], scale[b.columns[a - 1]], "one δ per cam");
        }
        let built = springs.scaled(&scale);
        let q_b = springfit::studies::sweep::equilibrium(&design, &built)
            .expect("a build near the design has an equilibrium");
        let fan = retrace(chain, &q_b, &o.training, spacing, ode).unwrap();
        let r = rows_of(chain, &fan, &built, omega);
        total.push(r.norm_squared());
        change.push((&r - &r0).norm_squared());
    }
    let mean_se = |v: &[f64]| {
        let n = v.len() as f64;
        let m = v.iter().sum::<f64>() / n;
        let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0);
        (m, (var / n).sqrt())
    };
    let (m_change, se_change) = mean_se(&change);
    let (m_total, se_total) = mean_se(&total);
    eprintln!(
        "with a cam: rows change predicted {predicted:.4e}, measured {m_change:.4e} ± {se_change:.1e}; per column \
         {per_column:.4e}; objective: expected {expected:.6e}, measured {m_total:.6e} ± {se_total:.1e}"
    );
    assert!(predicted > 0.0);
    assert!((m_change - predicted).abs() <= 4.0 * se_change, "{m_change} vs {predicted} ± {se_change}");
    assert!((m_total - expected).abs() <= 4.0 * se_total, "{m_total} vs {expected} ± {se_total}");
    assert!((m_change - per_column).abs() > 4.0 * se_change, "the diagonal model {per_column} fits {m_change} too");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `max_preload` bounds Σ|τᵢ(q_eq)| exactly with the QP while the equilibrium and Hessian still
/// hold; NNLS reports a fit that exceeds it as infeasible.
#[test]
fn the_preload_bound_holds() {
    let (design, catalog) = load("double_pendulum");
    let base = FitSettings { tolerance: ToleranceSpec::None, max_elements: 0, ..quick(&design) };
    let free = fit(&design, &catalog, &base, Progress::none()).unwrap();
    let total = |o: &springfit::fit::FitOutcome| o.bom.iter().map(|r| r.preload_nm.unwrap().abs()).sum::<f64>();
    let q_eq = design.q_eq.as_slice();
    for r in &free.bom {
        assert_eq!(r.preload_nm, Some(r.element.preload(r.stiffness, q_eq)));
    }
    let p_free = total(&free);
    assert!(p_free > 1.0, "{p_free}");
    let bound = 0.5 * p_free;
    let bounded = fit(&design, &catalog, &FitSettings { max_preload: bound, ..base }, Progress::none()).unwrap();
    assert!(total(&bounded) <= bound * (1.0 + 1e-6), "{} > {bound}", total(&bounded));
    assert!(bounded.metrics.equilibrium_gradient_norm < 1e-8);
    assert!(bounded.metrics.hessian_rel_error < 1e-8);
    assert!(bounded.metrics.stats.p99_abs >= free.metrics.stats.p99_abs * (1.0 - 1e-9));
    let nnls = FitSettings { solver: SolverKind::Nnls, max_preload: 1e-3, ..base };
    let err = fit(&design, &catalog, &nnls, Progress::none()).unwrap_err().to_string();
    assert!(err.contains("max_preload"), "{err}");
}

/// The tolerance-aware fit keeps the nominal equilibrium and Hessian exactly (QP), reports its
/// predicted spread of the builds, and gives the same springs on one thread and on two.
#[test]
fn the_tolerance_aware_fit_keeps_the_equalities_and_is_deterministic() {
    let (design, catalog) = load("double_pendulum");
    let settings =
        FitSettings { tolerance: ToleranceSpec::Fraction(0.05), max_elements: 8, restarts: 3, ..quick(&design) };
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| fit(&design, &catalog, &settings, Progress::none()).unwrap())
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(bom::to_csv(&a.bom), bom::to_csv(&b.bom));
    assert!(a.metrics.equilibrium_gradient_norm < 1e-8);
    assert!(a.metrics.hessian_rel_error < 1e-8);
    let spread = a.solve.expected_build_spread.unwrap();
    assert!(spread.is_finite() && spread > 0.0);
}

/// The trim-aware model (`robust::trimmed_spread`): a trimmed build — its trims re-relaxed at
/// the equilibrium q′ of the other built springs and re-set by the design's `trim_rule`, as
/// `asbuilt::trim_build` does — changes the rows about q′ by Σᵢ δᵢ kᵢ uᵢ to first order, so
/// E‖ΔR‖² = Σᵢ σᵢ² kᵢ² ‖uᵢ‖². Checked against Monte Carlo trimmed builds at a small tolerance,
/// for both rules, on the fan the rule is judged on: the fit's training fan for the Hessian rule
/// (the trims' setting does not depend on a fan), the trims' own fan for the residual rule (the
/// fan the build's least squares is solved on). The untrimmed model's prediction (`spread`, the
/// build's trims left relaxed at q_eq at their drawn rates) is far off for them, so the test
/// tells the two apart.
#[test]
fn trimmed_expected_spread_matches_monte_carlo_trimmed_builds() {
    trimmed_model_against_builds(TrimRule::Hessian);
    trimmed_model_against_builds(TrimRule::Residual);
}

fn trimmed_model_against_builds(rule: TrimRule) {
    let (mut design, catalog) = load("double_pendulum");
    design.fit.trim_rule = rule;
    let settings = FitSettings {
        tolerance: ToleranceSpec::None,
        max_elements: 8,
        restarts: 0,
        pair_swaps: false,
        builds: 0,
        ..quick(&design)
    };
    let o = fit(&design, &catalog, &settings, Progress::none()).unwrap();
    let is_trim: Vec<bool> = o.bom.iter().map(|r| r.adjust.trim_range.is_some()).collect();
    assert_eq!(is_trim.iter().filter(|t| **t).count(), 3, "the catalogue's three trims");
    let springs = &o.springs;
    let pick = |trim: bool| SpringSet {
        elements: (0..is_trim.len()).filter(|&j| is_trim[j] == trim).map(|j| springs.elements[j].clone()).collect(),
        stiffness: (0..is_trim.len()).filter(|&j| is_trim[j] == trim).map(|j| springs.stiffness[j]).collect(),
    };
    let (rest, trims) = (pick(false), pick(true));
    let chain = &design.chain;
    let ode = design.geodesics.ode;
    let omega = settings.frequency;
    let (training, spacing) = match rule {
        TrimRule::Hessian => (o.training.clone(), o.region.extent / settings.training_samples as f64),
        TrimRule::Residual => (
            springfit::asbuilt::trim_fan(&design, &design.q_eq).unwrap(),
            o.region.extent / springfit::asbuilt::TRIM_SAMPLES as f64,
        ),
    };
    let candidates: Vec<Candidate> = rest
        .elements
        .iter()
        .map(|e| Candidate { element: e.clone(), family: 0, max_stiffness: None, stock_rates: vec![], tolerance: 0.0 })
        .collect();
    let req = Requirements { omega, hessian_match: settings.hessian_match, monotone: false };
    let problem = assemble(chain, &design.q_eq, &training, &candidates, req);
    let k = DVector::from_column_slice(&rest.stiffness);

    let t = 0.01;
    let dist = Distribution::Uniform;
    let sigma2 = vec![dist.variance(t); candidates.len()];
    let jac = base_jacobian(chain, &training, spacing, springs, omega, ode).unwrap();
    let trimmed = trimmed_spread(
        chain,
        &training,
        (&candidates, &grouping_of(&candidates)),
        &problem.rows,
        &rest,
        &trims,
        &sigma2,
        omega,
        &jac,
        rule,
    )
    .unwrap();
    let untrimmed =
        spread_with(chain, &training, (&candidates, &grouping_of(&candidates)), &problem.rows, springs, &sigma2, &jac)
            .unwrap();
    let predicted = BuildPenalty::of(&trimmed, 1.0, 0.0).value(k.as_slice());
    let untrimmed_predicted = BuildPenalty::of(&untrimmed, 1.0, 0.0).value(k.as_slice());

    // The drawing trimmed (δ = 0): the reference the builds change from.
    let (set0, q0, sol0) = trim_build(&design, &o.bom, springs).unwrap();
    assert!(springfit::asbuilt::trims_reached(&design, &sol0) && (&q0 - &design.q_eq).amax() < 1e-9);
    let r1 = rows_of(chain, &retrace(chain, &q0, &training, spacing, ode).unwrap(), &set0, omega);
    let builds = 300;
    let mut change = Vec::new();
    for b in 0..builds {
        let mut rng = SplitMix64::stream(7, b);
        // Trims draw too (as `asbuilt::draw` does), though the trim resets their rates.
        let scale: Vec<f64> = (0..is_trim.len()).map(|_| 1.0 + t * dist.draw_unit(&mut rng)).collect();
        let built = springs.scaled(&scale);
        let (set, q_b, sol) = trim_build(&design, &o.bom, &built).expect("a build near the design trims");
        assert!(springfit::asbuilt::trims_reached(&design, &sol), "build {b}: {sol:?}");
        let fan = retrace(chain, &q_b, &training, spacing, ode).unwrap();
        change.push((rows_of(chain, &fan, &set, omega) - &r1).norm_squared());
    }
    let n = change.len() as f64;
    let m_change = change.iter().sum::<f64>() / n;
    let se = (change.iter().map(|x| (x - m_change).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
    eprintln!(
        "{rule:?} trimmed builds: rows change predicted {predicted:.4e}, measured {m_change:.4e} ± {se:.1e}; untrimmed model \
         {untrimmed_predicted:.4e}"
    );
    assert!(predicted > 0.0);
    assert!((m_change - predicted).abs() <= 4.0 * se, "{m_change} vs {predicted} ± {se}");
    assert!((m_change - untrimmed_predicted).abs() > 4.0 * se, "the untrimmed model {untrimmed_predicted} fits too");
}

/// `trimmed_weight = 0` (the default) leaves the tolerance-aware fit as it was before the
/// trimmed penalty existed. The reference is the bill `springfit fit` wrote at e501dd2 for the
/// default design fitted for ±5 % with its trims at quick settings (24 × 12 training and held-out
/// samples, λ = 0.2; `tests/data/double_pendulum_quick_tolerance_bom.csv`, its 16 columns extended
/// by the empty `gear_ratio,file` of springs), reproduced byte for byte up to 2d98a71, where the
/// fit reported its expected spread [`QUICK_SPREAD`]. Compared twice:
/// - the solve on its support: its twelve elements and the trims fitted again for ±5 % without a
///   budget give the figures that fit gave at 2d98a71 ([`QUICK_SUPPORT`]) within [`CONVEX`];
/// - the search: the fit over the whole catalogue keeps twelve springs and three trims, meets the
///   equalities, and its objective (the training rows plus its expected spread) and held-out
///   statistics are at most 1.05× the reference's. The reference is the worst the search reached
///   when ω or q_eq was perturbed by 1e-16 to 1e-9 (17 runs): those kept it or found a set 32–40 %
///   lower in objective with a p99 40–62 % lower, so a rounding change passes and a fit worse than
///   the reference fails.
///
/// A positive weight changes the fit; without trim springs in the catalogue it is refused,
/// naming the field.
#[test]
fn trimmed_weight_zero_leaves_the_bill_of_materials_unchanged() {
    let (design, catalog) = load("double_pendulum");
    // The weights the default design had when the reference was written.
    let settings = FitSettings { trimmed_weight: 0.0, tolerance_weight: 0.2, ..quick(&design) };
    let (reference, again) = reference_and_refit(&design, "double_pendulum_quick_tolerance_bom.csv", &settings);
    let spread = again.solve.expected_build_spread.unwrap();
    let figures = Figures::of(&design, &again.training, &again.evaluation, &again.springs, spread);
    figures.within(CONVEX, &QUICK_SUPPORT);

    let o = fit(&design, &catalog, &settings, Progress::none()).unwrap();
    assert_eq!(o.bom.len(), 15);
    let spread = o.solve.expected_build_spread.unwrap();
    let expected = Figures::of(&design, &o.training, &o.evaluation, &reference, QUICK_SPREAD);
    Figures::of(&design, &o.training, &o.evaluation, &o.springs, spread).at_most(1.05, 1.05, &expected);

    let weighted = fit(&design, &catalog, &FitSettings { trimmed_weight: 1.0, ..settings }, Progress::none()).unwrap();
    assert_ne!(weighted.springs, o.springs);
    assert!(weighted.solve.expected_build_spread.unwrap() > 0.0);
    let plain = Catalog::load(&repo("catalogs/paper.toml"), design.dof()).unwrap();
    let err = fit(&design, &plain, &FitSettings { trimmed_weight: 1.0, ..settings }, Progress::none())
        .unwrap_err()
        .to_string();
    assert!(err.contains("fit.trimmed_weight") && err.contains("trim"), "{err}");
}

/// The expected spread the fit that wrote `double_pendulum_quick_tolerance_bom.csv` reported for
/// it (at 2d98a71, which wrote that bill byte for byte).
const QUICK_SPREAD: f64 = 4.58151718242251e-3;

/// The figures of the quick tolerance-aware fit on the reference's support at 2d98a71 (perturbing
/// ω or q_eq by 1e-15 to 1e-11 moves them by at most 3e-11 relative: the solve is convex).
const QUICK_SUPPORT: Figures = Figures {
    objective: 1.02376752118724e-2,
    stats: [0.13322989461345192, 0.5472665346433688, 0.8084095224563186, 1.1206825367274686],
    gradient: 6.4e-15,
    hessian: 7.6e-17,
};

/// The trim-aware model with a cam: its columns share one δ, so the trimmed spread is a block
/// σ² U_gᵀ U_g over them. One cam on (1, 1), five linear springs and three trims, fitted
/// nominally; Monte Carlo builds with only the cam deviating (one δ per cam, as
/// `asbuilt::factors` draws), each trimmed as `asbuilt::trim_build` trims: the block's prediction
/// matches their mean change of the rows, the untrimmed block's does not.
#[test]
fn trimmed_expected_spread_with_a_cam_matches_monte_carlo_trimmed_builds() {
    let (mut design, _) = load("double_pendulum");
    let dir = std::env::temp_dir().join(format!("springfit-robust-trimcam-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cat_path = dir.join("one_cam_trims.toml");
    std::fs::write(
        &cat_path,
        r#"name = "one_cam_trims"
description = "one cam, five linear springs and three trims"

[[family]]
name = "disc cam"
profile = "cam"
unit = "J"
couplings = [[1, 1]]
knots = 8
smoothing = 1e-5
tolerance = 0.05

[[family]]
name = "torsion spring"
profile = "linear"
unit = "N*m/rad"
couplings = [[1, 0], [0, 1], [1, 1], [1, -1], [2, 1]]
offsets = "equilibrium"
tolerance = 0.05

[[family]]
name = "trim spring"
profile = "linear"
unit = "N*m/rad"
couplings = [[1, 0], [0, 1], [1, 1]]
offsets = "equilibrium"
trim = true
trim_range = [0.0, 4.0]
"#,
    )
    .unwrap();
    let catalog = Catalog::load(&cat_path, design.dof()).unwrap();
    // The cam's block does not depend on the rule (both rules are checked without a cam above).
    design.fit.trim_rule = TrimRule::Hessian;
    let settings = FitSettings {
        tolerance: ToleranceSpec::None,
        solver: SolverKind::Nnls,
        max_elements: 0,
        monotone: false,
        builds: 0,
        ..quick(&design)
    };
    let o = fit(&design, &catalog, &settings, Progress::none()).unwrap();
    let is_trim: Vec<bool> = o.bom.iter().map(|r| r.adjust.trim_range.is_some()).collect();
    assert_eq!(is_trim.iter().filter(|t| **t).count(), 3);
    let springs = &o.springs;
    let pick = |trim: bool| SpringSet {
        elements: (0..is_trim.len()).filter(|&j| is_trim[j] == trim).map(|j| springs.elements[j].clone()).collect(),
        stiffness: (0..is_trim.len()).filter(|&j| is_trim[j] == trim).map(|j| springs.stiffness[j]).collect(),
    };
    let (rest, trims) = (pick(false), pick(true));
    let groups = springfit::asbuilt::bom_groups(&o.bom);
    // The trims come last in the bill of materials: the rest's rows are its first rows.
    let cam: Vec<bool> = groups.iter().take(rest.elements.len()).map(|g| g.is_some()).collect();
    assert!(cam.iter().filter(|c| **c).count() >= 4, "the cam's basis columns: {groups:?}");
    let chain = &design.chain;
    let ode = design.geodesics.ode;
    let omega = settings.frequency;
    let spacing = o.region.extent / settings.training_samples as f64;
    let candidates: Vec<Candidate> = rest
        .elements
        .iter()
        .map(|e| Candidate { element: e.clone(), family: 0, max_stiffness: None, stock_rates: vec![], tolerance: 0.0 })
        .collect();
    let req = Requirements { omega, hessian_match: settings.hessian_match, monotone: false };
    let problem = assemble(chain, &design.q_eq, &o.training, &candidates, req);
    let k = DVector::from_column_slice(&rest.stiffness);
    let t = 0.01;
    let dist = Distribution::Uniform;
    let sigma2: Vec<f64> = cam.iter().map(|&c| if c { dist.variance(t) } else { 0.0 }).collect();
    let jac = base_jacobian(chain, &o.training, spacing, springs, omega, ode).unwrap();
    let trimmed = trimmed_spread(
        chain,
        &o.training,
        (&candidates, &grouping_of(&candidates)),
        &problem.rows,
        &rest,
        &trims,
        &sigma2,
        omega,
        &jac,
        TrimRule::Hessian,
    )
    .unwrap();
    let untrimmed = spread_with(
        chain,
        &o.training,
        (&candidates, &grouping_of(&candidates)),
        &problem.rows,
        springs,
        &sigma2,
        &jac,
    )
    .unwrap();
    assert_eq!(trimmed.blocks.len(), 1);
    let predicted = BuildPenalty::of(&trimmed, 1.0, 0.0).value(k.as_slice());
    let untrimmed_predicted = BuildPenalty::of(&untrimmed, 1.0, 0.0).value(k.as_slice());

    let (set0, q0, _) = trim_build(&design, &o.bom, springs).unwrap();
    let r1 = rows_of(chain, &retrace(chain, &q0, &o.training, spacing, ode).unwrap(), &set0, omega);
    let mut change = Vec::new();
    for b in 0..300 {
        let mut rng = SplitMix64::stream(42, b);
        let scale =
            springfit::asbuilt::factors(&o.bom, |r| if r.id.starts_with('C') { t } else { 0.0 }, dist, &mut rng);
        let built = springs.scaled(&scale);
        let (set, q_b, sol) = trim_build(&design, &o.bom, &built).expect("a build near the design trims");
        assert!(sol.restored(), "build {b}: mismatch {}", sol.mismatch);
        let fan = retrace(chain, &q_b, &o.training, spacing, ode).unwrap();
        change.push((rows_of(chain, &fan, &set, omega) - &r1).norm_squared());
    }
    let n = change.len() as f64;
    let m_change = change.iter().sum::<f64>() / n;
    let se = (change.iter().map(|x| (x - m_change).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
    eprintln!(
        "trimmed builds with a cam: rows change predicted {predicted:.4e}, measured {m_change:.4e} ± {se:.1e}; \
         untrimmed model {untrimmed_predicted:.4e}"
    );
    assert!(predicted > 0.0);
    assert!((m_change - predicted).abs() <= 4.0 * se, "{m_change} vs {predicted} ± {se}");
    assert!((m_change - untrimmed_predicted).abs() > 4.0 * se, "the untrimmed model {untrimmed_predicted} fits too");
    let _ = std::fs::remove_dir_all(&dir);
}

/// With a tolerance and trim springs in the catalogue, a design that leaves `tolerance_weight`
/// out is fitted with λ = 0 (`FitSettings::with_trim_defaults`): every build is trimmed, so the
/// untrimmed builds' spread is not paid for. A key it sets, a catalogue without trims or
/// `tolerance = "none"` keep the plain default λ = 1. Measured on Monte Carlo builds at ±5 %,
/// each trimmed as the as-built figures trim it: the default's mean squared rows about the
/// trimmed builds' equilibria are lower than those of λ = 1 (the expected residual of untrimmed
/// builds), which spends the drawing on Hessian errors the trims remove.
#[test]
fn default_tolerance_weight_with_trims_fits_for_the_trimmed_builds() {
    let text = std::fs::read_to_string(repo("designs/double_pendulum.toml")).unwrap();
    let keep = |t: &str, drop: &[&str]| -> String {
        t.lines().filter(|l| !drop.iter().any(|d| l.starts_with(d))).collect::<Vec<_>>().join("\n")
    };
    let left_out = keep(&text, &["tolerance_weight", "trimmed_weight"]);
    let path = repo("designs/left_out.toml");
    let weights = |t: &str| {
        let d = Design::parse(&path, t).unwrap();
        (d.fit.tolerance_weight, d.fit.trimmed_weight)
    };
    assert_eq!(weights(&left_out), (0.0, 0.0));
    assert_eq!(weights(&keep(&text, &["trimmed_weight"])), (0.17, 0.0));
    assert_eq!(weights(&keep(&text, &["tolerance_weight"])), (0.0, 0.22));
    assert_eq!(weights(&text), (0.17, 0.22));
    let plain = left_out.replace("../catalogs/paper_trim.toml", "../catalogs/paper.toml");
    assert_eq!(weights(&plain), (1.0, 0.0));
    assert_eq!(weights(&left_out.replace("tolerance = 0.05", "tolerance = \"none\"")), (1.0, 0.0));

    let design = Design::parse(&path, &left_out).unwrap();
    let catalog = Catalog::load(design.catalog.as_ref().unwrap(), design.dof()).unwrap();
    let settings = FitSettings { max_elements: 0, builds: 0, mass_weight: 0.0, ..quick(&design) };
    let (chain, ode, omega) = (&design.chain, design.geodesics.ode, settings.frequency);
    let t = 0.05;
    let dist = Distribution::Uniform;
    let trimmed_rows = |s: &FitSettings| -> f64 {
        let o = fit(&design, &catalog, s, Progress::none()).unwrap();
        let spacing = o.region.extent / s.training_samples as f64;
        let builds = 200;
        let mut sum = 0.0;
        for b in 0..builds {
            let mut rng = SplitMix64::stream(11, b);
            let scale: Vec<f64> = (0..o.bom.len()).map(|_| 1.0 + t * dist.draw_unit(&mut rng)).collect();
            let (set, q_b, _) = trim_build(&design, &o.bom, &o.springs.scaled(&scale)).expect("a trimmed build");
            let fan = retrace(chain, &q_b, &o.training, spacing, ode).unwrap();
            sum += rows_of(chain, &fan, &set, omega).norm_squared();
        }
        sum / builds as f64
    };
    let default = trimmed_rows(&settings);
    let untrimmed = trimmed_rows(&FitSettings { tolerance_weight: 1.0, ..settings });
    eprintln!("trimmed builds' mean squared rows: default (λ 0) {default:.4e}, λ 1 {untrimmed:.4e}");
    assert!(default < untrimmed, "{default} vs {untrimmed}");
}
