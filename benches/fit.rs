//! Benchmarks of the fit: the library call per design and `springfit fit` end to end.
//!
//! `cargo bench --bench fit`. Figures are recorded in BENCHMARKS.md. `FIT_BENCH_ONLY=word` runs
//! only the cases whose label contains the word (`selection`, `end to end`, `parts ur10`, a design
//! name).

mod common;

use std::hint::black_box;
use std::path::Path;
use std::process::Command;

use springfit::design::Design;
use springfit::elements::catalog::Catalog;
use springfit::fit::run::fit;

use common::{ms, time};

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    println!("springfit fit benchmarks (median / min over repeats)");
    let only = std::env::var("FIT_BENCH_ONLY").ok();
    let want = |label: &str| only.as_deref().is_none_or(|o| label.contains(o));
    for name in [
        "double_pendulum",
        "double_pendulum_dense",
        "double_pendulum_dense_robust",
        "double_pendulum_workshop",
        "double_pendulum_paper_window",
        "ur5_pan_lift_elbow",
        "double_pendulum_paper_window_cams",
        "double_pendulum_paper_window_built",
    ] {
        if !want(&format!("fit {name}")) {
            continue;
        }
        let design = Design::load(&root.join(format!("designs/{name}.toml"))).unwrap();
        let catalog = Catalog::load(design.catalog.as_ref().unwrap(), design.dof()).unwrap();
        let mut last = None;
        let (med, min) = time(5, || {
            last = Some(black_box(fit(&design, &catalog, &design.fit, springfit::progress::Progress::none()).unwrap()));
        });
        let o = last.unwrap();
        let t = o.timings;
        println!(
            "fit {name}: {:.0} ms / {:.0} ms (geodesics {:.0}, assemble {:.0}, solve {:.0}, evaluate {:.0} ms); {} springs, p99 {:.4}°, max {:.4}°",
            ms(med),
            ms(min),
            t.geodesics * 1e3,
            t.assemble * 1e3,
            t.solve * 1e3,
            t.evaluate * 1e3,
            o.used(),
            o.metrics.stats.p99_abs,
            o.metrics.stats.max_abs
        );
    }
    // The as-built Monte Carlo builds of the default design alone (`asbuilt::of_fit`: each build's
    // equilibrium, trim and two fans of held-out geodesics), at the design's `[fit] builds`.
    if want("as-built") {
        let design = Design::load(&root.join("designs/double_pendulum.toml")).unwrap();
        let catalog = Catalog::load(design.catalog.as_ref().unwrap(), design.dof()).unwrap();
        let o = fit(&design, &catalog, &design.fit, springfit::progress::Progress::none()).unwrap();
        let mut last = None;
        let (med, min) = time(3, || {
            last = Some(black_box(springfit::asbuilt::of_fit(&design, &o).unwrap().unwrap()));
        });
        let ab = last.unwrap();
        let t = ab.trimmed.unwrap().p99_deg;
        println!(
            "as-built builds double_pendulum ({} builds, {} geodesics × {} samples per fan): {:.0} ms / {:.0} ms ({:.2} ms per build); p99 p95 {:.3}° ({}), trimmed {:.3}° ({})",
            ab.builds,
            springfit::asbuilt::DIRECTIONS,
            springfit::asbuilt::SAMPLES,
            ms(med),
            ms(min),
            ms(med) / ab.builds as f64,
            ab.p99_deg.p95,
            ab.p99_deg.p95_interval(3),
            t.p95,
            t.p95_interval(3)
        );
    }
    // The part chooser on a user's arm: the UR10's fit with its parts at `mass_weight = 0.003`
    // (issue 46), where the mass model (every candidate's part searched at three rates, more
    // where one fails) and the bill's parts are most of the fit's CPU.
    if want("parts ur10") {
        let design = Design::load(&root.join("designs/ur10_lift_elbow_wrist.toml")).unwrap();
        let catalog = Catalog::load(design.catalog.as_ref().unwrap(), design.dof()).unwrap();
        let stock = springfit::files::stock::of_design(&design).unwrap();
        let settings = springfit::design::fit::FitSettings { mass_weight: 0.003, ..design.fit };
        let mut last = None;
        let (med, min) = time(1, || {
            let none = springfit::progress::Progress::none();
            last =
                Some(black_box(springfit::parts::fit_with_parts(&design, &catalog, &settings, &stock, none).unwrap()));
        });
        let (o, parts) = last.unwrap();
        let kg: f64 = parts.elements.iter().filter_map(|e| e.part.as_ref().ok()).map(|p| p.mass).sum();
        println!(
            "parts ur10_lift_elbow_wrist (mass_weight 0.003, fit with its parts): {:.0} ms / {:.0} ms (solve {:.0} ms); {} springs, p99 {:.4}°, springs {:.3} kg",
            ms(med),
            ms(min),
            o.timings.solve * 1e3,
            o.used(),
            o.metrics.stats.p99_abs,
            kg
        );
    }
    // The sparse selection on the nominal objective (tolerance "none"): restarts (the default
    // number), pair swaps and bounded exchange moves against the single exchange search of
    // earlier versions. Target: the selection with restarts ≤ 5 s (the "solve" figure).
    let design = Design::load(&root.join("designs/double_pendulum.toml")).unwrap();
    let catalog = Catalog::load(design.catalog.as_ref().unwrap(), design.dof()).unwrap();
    for k in [8, 10, 12] {
        if !want("selection") {
            break;
        }
        let restarts_default = springfit::design::fit::FitSettings::default().restarts;
        for (label, restarts, pair_swaps) in
            [("single exchange search", 0, false), ("restarts + pair swaps", restarts_default, true)]
        {
            let settings = springfit::design::fit::FitSettings {
                tolerance: springfit::design::tolerance::ToleranceSpec::None,
                max_elements: k,
                restarts,
                pair_swaps,
                ..design.fit
            };
            let mut last = None;
            let (med, min) = time(3, || {
                last =
                    Some(black_box(fit(&design, &catalog, &settings, springfit::progress::Progress::none()).unwrap()));
            });
            let o = last.unwrap();
            println!(
                "selection K = {k}, {label}: fit {:.0} ms / {:.0} ms, solve (selection + QP) {:.0} ms, {} refits; p99 {:.4}°, max {:.4}°",
                ms(med),
                ms(min),
                o.timings.solve * 1e3,
                o.solve.selection_evaluations,
                o.metrics.stats.p99_abs,
                o.metrics.stats.max_abs
            );
        }
    }
    // The main job as a user runs it: process start, fit, plots and files.
    let out = std::env::temp_dir().join(format!("springfit-bench-{}", std::process::id()));
    if !want("end to end") {
        return;
    }
    let (med, min) = time(5, || {
        let status = Command::new(env!("CARGO_BIN_EXE_springfit"))
            .args(["--quiet", "fit", "--out"])
            .arg(&out)
            .current_dir(root)
            .status()
            .unwrap();
        assert!(status.success());
    });
    println!(
        "springfit fit (default design: ±5 % fit and 1,000 as-built builds, end to end with outputs): {:.0} ms / {:.0} ms",
        ms(med),
        ms(min)
    );
    // The spatial arm from its URDF, end to end (target ≤ 5 s).
    let (med, min) = time(3, || {
        let status = Command::new(env!("CARGO_BIN_EXE_springfit"))
            .args(["--quiet", "fit", "designs/ur5_pan_lift_elbow.toml", "--out"])
            .arg(&out)
            .current_dir(root)
            .status()
            .unwrap();
        assert!(status.success());
    });
    println!(
        "springfit fit designs/ur5_pan_lift_elbow.toml (URDF, end to end with outputs): {:.0} ms / {:.0} ms",
        ms(med),
        ms(min)
    );
    // The paper's window with eight cams, end to end (target ≤ 3 s): the fit, the automatic
    // smoothing choice, the cams' realisation and the as-built builds at catalogue tolerance.
    let (med, min) = time(3, || {
        let status = Command::new(env!("CARGO_BIN_EXE_springfit"))
            .args(["--quiet", "fit", "designs/double_pendulum_paper_window_cams.toml", "--out"])
            .arg(&out)
            .current_dir(root)
            .status()
            .unwrap();
        assert!(status.success());
    });
    println!(
        "springfit fit designs/double_pendulum_paper_window_cams.toml (8 cams, end to end with outputs): {:.0} ms / {:.0} ms",
        ms(med),
        ms(min)
    );
    let _ = std::fs::remove_dir_all(&out);
}
