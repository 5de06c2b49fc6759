//! Fit time against the number of joints: planar chains of n = 2 … 7 links in gravity, the
//! n-joint catalogue (catalogs/chain.toml; at n = 2 without its families on adjacent triples,
//! which need three joints), ball r = 0.15, no element budget, no builds.
//!
//! `cargo bench --bench scaling`. `SCALING_MAX=n` stops at n joints (7 by default);
//! `SCALING_DIRECTIONS=t` fixes the training directions at t and the held-out at 5t (the
//! default: the design's own rule, 72 · 2^(n−2) training up to five joints, 576 from there on).
//! Each n is fitted once (the times are seconds, not microseconds): candidates, rows, the time
//! split, the springs used and the held-out p99, then the exponents of the fitted laws
//! time ∝ n^a and solve ∝ m^b.
//! `SCALING_COMPARE=n` also solves the QPs of the chains up to n joints both ways, Clarabel over
//! every candidate and the working set (`solve::screen`), and prints both times, the objectives
//! and the working set, then the Lawson–Hanson solve the fit now uses above 600 candidates
//! (`solve::lawson_hanson`) from the same start. `SCALING_CHECK=1` times only the region check
//! of each chain instead (the design's default count of directions, each with its n Jacobi
//! fields; the median of three runs), on one thread and on two. Figures in BENCHMARKS.md ("Fit
//! time against the number of joints").

use std::path::Path;
use std::time::Instant;

use springfit::design::Design;
use springfit::elements::catalog::Catalog;
use springfit::fit::Prepared;
use springfit::fit::run::fit;
use springfit::fit::solve::nnls_support;
use springfit::geodesic::region::check_region;
use springfit::solve::lawson_hanson::nnls_equalities;
use springfit::solve::qp::{QpSettings, qp};
use springfit::solve::screen::qp_screened;

/// The chain of `n` links: slender rods lighter and shorter towards the tip (link i: mass
/// 1.5 · 0.85^i kg, length 0.8 · 0.9^i m, centre of mass at mid-length, I = m l²/12), bent
/// equilibrium (−π/3 then π/6 per joint), gravity, the n-joint catalogue.
fn chain_design(n: usize, directions: Option<usize>) -> String {
    let mut s = format!("name = \"chain{n}\"\ncatalog = \"../catalogs/chain.toml\"\n[robot]\ngravity = [0.0, -9.81]\n");
    for i in 0..n {
        let (m, l) = (1.5 * 0.85f64.powi(i as i32), 0.8 * 0.9f64.powi(i as i32));
        s += &format!("[[robot.links]]\nmass = {m}\nlength = {l}\ncom = {}\ninertia = {}\n", l / 2.0, m * l * l / 12.0);
    }
    let q: Vec<&str> = (0..n).map(|i| if i == 0 { "\"-pi/3\"" } else { "\"pi/6\"" }).collect();
    s += &format!("[equilibrium]\nq = [{}]\n[region]\nkind = \"ball\"\nradius = 0.15\n", q.join(", "));
    s += "[fit]\nfrequency = 6.0\nsolver = \"qp\"\nmax_elements = 0\nbuilds = 0\n";
    if let Some(t) = directions {
        s += &format!("training_directions = {t}\nevaluation_directions = {}\n", 5 * t);
    }
    s
}

/// `catalogs/chain.toml` for `n` joints; for two, without its last two families (cranks and
/// compression springs on adjacent triples), which need three joints.
fn chain_catalog(path: &Path, n: usize) -> Catalog {
    let text = std::fs::read_to_string(path).unwrap();
    let text = if n < 3 { &text[..text.find("[[family]]\nname = \"triple crank\"").unwrap()] } else { &text[..] };
    Catalog::parse(path, text, n).unwrap()
}

/// The exponent a of y ∝ x^a by least squares on the logarithms.
fn exponent(points: &[(f64, f64)]) -> f64 {
    let lx: Vec<f64> = points.iter().map(|p| p.0.ln()).collect();
    let ly: Vec<f64> = points.iter().map(|p| p.1.ln()).collect();
    let (mx, my) = (lx.iter().sum::<f64>() / lx.len() as f64, ly.iter().sum::<f64>() / ly.len() as f64);
    let sxy: f64 = lx.iter().zip(&ly).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = lx.iter().map(|x| (x - mx).powi(2)).sum();
    sxy / sxx
}

/// The fit's QP of `design` (no budget, every candidate, no stiffness bounds) by Clarabel over
/// every candidate and on the working set from the weighted NNLS support, as `fit::solve` starts
/// it: the two times, the relative difference of the objectives and the working set's size.
fn compare(design: &Design, catalog: &Catalog) {
    let prepared = Prepared::new(design, catalog, &design.fit, springfit::progress::Progress::none()).unwrap();
    let (problem, gram) = (prepared.problem(), prepared.gram());
    let p = gram.dim();
    let upper = vec![None; p];
    let l1 = design.fit.l1;
    let objective = |k: &nalgebra::DVector<f64>| gram.objective(k) + 2.0 * l1 * k.sum();
    let t0 = Instant::now();
    let full = qp(gram, &problem.equalities, &problem.inequalities, &upper, l1, &QpSettings::default()).unwrap();
    let t_full = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let start = nnls_support(gram, &problem.equalities, problem.row_count(), &design.fit).unwrap();
    let s = qp_screened(gram, &problem.equalities, &problem.inequalities, &upper, l1, &QpSettings::default(), &start)
        .unwrap();
    let t_screen = t1.elapsed().as_secs_f64();
    let t2 = Instant::now();
    let lh = nnls_equalities(gram, &problem.equalities, l1, &start);
    let t_lh = t2.elapsed().as_secs_f64();
    match &lh {
        Some(lh) => println!(
            "  Lawson–Hanson from the same start: {t_lh:.2} s, objective {:.6e} (relative to Clarabel over all {:.1e}), max |Δk| / max k {:.1e}; equality residuals {:.1e} (Lawson–Hanson), {:.1e} (Clarabel over all), {:.1e} (working set)",
            objective(&lh.k),
            (objective(&lh.k) - objective(&full.k)) / objective(&full.k),
            (&lh.k - &full.k).amax() / full.k.amax(),
            lh.max_equality_residual,
            full.max_equality_residual,
            s.solution.max_equality_residual
        ),
        None => println!("  Lawson–Hanson from the same start: no answer it could vouch for ({t_lh:.2} s)"),
    }
    let (fo, so) = (objective(&full.k), objective(&s.solution.k));
    println!(
        "  QP of {} candidates: Clarabel over all {t_full:.2} s, working set {t_screen:.2} s ({} rounds, |W| {} from an NNLS start of {}, violation left {:.1e}); objectives {fo:.6e} and {so:.6e} (relative difference {:.1e}), max |Δk| / max k {:.1e}",
        p,
        s.rounds,
        s.working.len(),
        start.len(),
        s.violation,
        (so - fo) / fo,
        (&s.solution.k - &full.k).amax() / full.k.amax()
    );
}

/// The region check of the chains of 2 … `max` links: its directions and the median of three
/// runs on one thread and on two.
fn region_checks(root: &Path, max: usize) {
    println!("region check of the planar chains, r = 0.15 (median of three runs)");
    println!("| n | directions | 1 thread s | 2 threads s |");
    for n in 2..=max {
        let path = root.join(format!("designs/chain{n}.toml"));
        let design = Design::parse(&path, &chain_design(n, None)).unwrap();
        let time = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut t: Vec<f64> = (0..3)
                .map(|_| {
                    let t0 = Instant::now();
                    pool.install(|| check_region(&design.chain, &design.q_eq, &design.region, &design.geodesics))
                        .unwrap();
                    t0.elapsed().as_secs_f64()
                })
                .collect();
            t.sort_by(f64::total_cmp);
            t[1]
        };
        println!("| {n} | {} | {:.2} | {:.2} |", design.geodesics.check_count(n), time(1), time(2));
    }
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let max: usize = std::env::var("SCALING_MAX").ok().and_then(|v| v.parse().ok()).unwrap_or(7);
    if std::env::var("SCALING_CHECK").is_ok_and(|v| v == "1") {
        region_checks(root, max);
        return;
    }
    let directions: Option<usize> = std::env::var("SCALING_DIRECTIONS").ok().and_then(|v| v.parse().ok());
    let compare_to: usize = std::env::var("SCALING_COMPARE").ok().and_then(|v| v.parse().ok()).unwrap_or(0);
    let sampling = directions.map_or("the default sampling".to_string(), |t| format!("{t} training directions"));
    println!("fit time against n: planar chains, r = 0.15, no budget, {sampling} (one fit per n)");
    println!("| n | candidates m | rows | geodesics s | assemble s | solve s | evaluate s | total s | springs | p99 |");
    let (mut by_n, mut by_m) = (Vec::new(), Vec::new());
    for n in 2..=max {
        let path = root.join(format!("designs/chain{n}.toml"));
        let design = Design::parse(&path, &chain_design(n, directions)).unwrap();
        let catalog = chain_catalog(design.catalog.as_ref().unwrap(), n);
        let t0 = Instant::now();
        let o = fit(&design, &catalog, &design.fit, springfit::progress::Progress::none()).unwrap();
        let wall = t0.elapsed().as_secs_f64();
        let t = o.timings;
        let samples: usize = o.training.geodesics.iter().map(|g| g.len()).sum();
        let m = o.candidates - o.dropped;
        println!(
            "| {n} | {m} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {wall:.2} | {} | {:.4}° |",
            samples * (n - 1),
            t.geodesics,
            t.assemble,
            t.solve,
            t.evaluate,
            o.used(),
            o.metrics.stats.p99_abs
        );
        if n <= compare_to {
            compare(&design, &catalog);
        }
        by_n.push((n as f64, wall));
        by_m.push((m as f64, t.solve.max(1e-6)));
    }
    if by_n.len() >= 2 {
        println!(
            "fitted laws: total ∝ n^{:.2}, solve ∝ m^{:.2} (least squares on the logarithms)",
            exponent(&by_n),
            exponent(&by_m)
        );
    }
}
